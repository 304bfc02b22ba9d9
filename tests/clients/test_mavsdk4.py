"""The native MAVSDK 4 binding (`mavsdk` 4.x on PyPI: the MAVSDK C++ core
through ctypes, no mavsdk_server) against the rotorpilot binary: connect as a
ground station with udpin://0.0.0.0:14540+N, wait for health, params, arm,
take off, goto (MAVSDK 4 sends DO_REPOSITION in frame 0), offboard position
and velocity, the vehicle's own refusals (an unknown or out-of-range parameter,
offboard without setpoints, sent past MAVSDK's own check) read off its answers, land; and a three-waypoint
mission uploaded, read back and flown at 1x and 20x.

Run with the mavsdk 4.x venv: `python -m pytest tests/clients/test_mavsdk4.py`.
"""

import json
import math
import sys
import time
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from harness import Vehicle  # noqa: E402

from mavsdk import ComponentType, Configuration, Mavsdk  # noqa: E402
from mavsdk.plugins.action import Action, ActionError, ActionResult  # noqa: E402
from mavsdk.plugins.events import Events, EventsError  # noqa: E402
from mavsdk.plugins.mavlink_direct import MavlinkDirect, MavlinkMessage  # noqa: E402
from mavsdk.plugins.mission import Mission, MissionItem, MissionPlan  # noqa: E402
from mavsdk.plugins.offboard import Offboard, PositionNedYaw, VelocityNedYaw  # noqa: E402
from mavsdk.plugins.param import Param, ParamError, ParamResult  # noqa: E402
from mavsdk.plugins.telemetry import FlightMode, Telemetry  # noqa: E402

SPEED = 5.0
# Scripts written for real time run unchanged with the vehicle at 20x: the
# flight test below runs at both speeds (every wait here is in wall time and
# generous enough for 5x; timers that wait for a client run on the wall clock
# above 1x, so the vehicle does not disarm or leave offboard under a script
# that thinks in real time).
FAST = 20.0


def until(what, cond, timeout):
    """Poll cond() every 50 ms until it returns something truthy."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        v = cond()
        if v:
            return v
        time.sleep(0.05)
    pytest.fail(f"timed out waiting for {what}")


class Drone:
    def __init__(self, vehicle):
        self.mavsdk = Mavsdk(Configuration.create_with_component_type(ComponentType.GROUND_STATION))
        self.mavsdk.add_any_connection(f"udpin://0.0.0.0:{vehicle.api_port}")
        self.system = self.mavsdk.first_autopilot(10.0)
        assert self.system is not None, "first_autopilot timed out"
        self.telemetry = Telemetry(self.system)
        self.action = Action(self.system)
        self.offboard = Offboard(self.system)
        self.param = Param(self.system)
        self.sysid = vehicle.sysid

    def healthy(self):
        h = self.telemetry.health()
        return h.is_global_position_ok and h.is_home_position_ok and h.is_armable

    def ned(self):
        return self.telemetry.position_velocity_ned()


@pytest.fixture(params=[SPEED], ids=lambda s: f"x{s:g}")
def drone(request):
    with Vehicle(speed=request.param) as v:
        d = Drone(v)
        until("health", d.healthy, 20)
        yield d
        d.mavsdk.destroy()


def test_identity(drone):
    assert drone.system.has_autopilot()


def test_arming_check_report(drone):
    """MAVSDK's Events plugin reads the arming checks as PX4 sends them
    (component metadata over MAVLink FTP, then the report's EVENTs): ready
    in Hold, Hold can be armed; the other modes' problems are listed."""
    events = Events(drone.system)

    def report():
        try:
            return events.get_health_and_arming_checks_report()
        except EventsError:
            return None

    r = until("an arming-check report", report, 20)
    mode = r.current_mode_intention
    assert (mode.mode_name, mode.can_arm_or_run, mode.problems) == ("Hold", True, [])
    assert {"No valid mission", "No manual control input"} <= {p.message for p in r.all_problems}
    present = {c.name for c in r.health_components if c.is_present and not c.has_error}
    assert {"gps", "motors_escs", "battery"} <= present


def refused(call):
    """Run call(), which must raise; the error and how long the answer took."""
    t0 = time.monotonic()
    try:
        call()
    except ParamError as e:
        return e, time.monotonic() - t0
    pytest.fail(f"{call} was not refused")


def test_params(drone):
    all_params = drone.param.get_all_params()
    names = [p.name for p in all_params.int_params] + [p.name for p in all_params.float_params]
    assert "MIS_TAKEOFF_ALT" in names and "SYS_FAILURE_EN" in names
    assert len(set(names)) == len(names)
    drone.param.set_param_float("MIS_TAKEOFF_ALT", 3.5)
    assert drone.param.get_param_float("MIS_TAKEOFF_ALT") == pytest.approx(3.5)
    drone.param.set_param_int("SYS_FAILURE_EN", 1)
    assert drone.param.get_param_int("SYS_FAILURE_EN") == 1
    # The vehicle's answers, as MAVSDK reports them: an unknown name gets
    # PARAM_ERROR DOES_NOT_EXIST and a value out of range PARAM_ERROR
    # VALUE_OUT_OF_RANGE, each at once (MAVSDK's own timeout would report
    # TIMEOUT after seconds); the refused value changes nothing.
    e, took = refused(lambda: drone.param.get_param_float("NO_SUCH_PARAM"))
    assert e.result == ParamResult.DOES_NOT_EXIST, e
    assert took < 1.0, f"unknown parameter answered after {took:.2f} s"
    e, took = refused(lambda: drone.param.set_param_float("MIS_TAKEOFF_ALT", -1.0))
    assert e.result == ParamResult.VALUE_OUT_OF_RANGE, e
    assert took < 1.0, f"refused set answered after {took:.2f} s"
    assert drone.param.get_param_float("MIS_TAKEOFF_ALT") == pytest.approx(3.5)


def test_offboard_refused_by_the_vehicle(drone):
    """MAVSDK refuses offboard on its own side until a setpoint is set
    (NO_SETPOINT_SET: a test of MAVSDK), and once one is set it streams it,
    so the vehicle never refuses. Here the mode change goes to the vehicle
    itself through MavlinkDirect (DO_SET_MODE to PX4's OFFBOARD, no setpoint
    ever sent) and its answers are read off the wire: COMMAND_ACK
    TEMPORARILY_REJECTED at once, PX4's STATUSTEXT, still in Hold."""
    direct = MavlinkDirect(drone.system)
    acks, texts = [], []
    direct.subscribe_message("COMMAND_ACK", lambda m, _: acks.append((time.monotonic(), json.loads(m.fields_json))))
    direct.subscribe_message("STATUSTEXT", lambda m, _: texts.append(json.loads(m.fields_json)["text"]))
    fields = {"target_system": drone.sysid, "target_component": 1, "command": 176, "confirmation": 0,
              "param1": 129.0, "param2": 6.0, "param3": 0.0, "param4": 0.0, "param5": 0.0, "param6": 0.0,
              "param7": 0.0}
    t0 = time.monotonic()
    direct.send_message(MavlinkMessage("COMMAND_LONG", 0, 0, drone.sysid, 1, json.dumps(fields)))
    t, ack = until("COMMAND_ACK of DO_SET_MODE", lambda: next((a for a in acks if a[1]["command"] == 176), None), 3)
    assert ack["result"] == 1, ack  # MAV_RESULT_TEMPORARILY_REJECTED
    assert t - t0 < 1.0, f"answered after {t - t0:.2f} s"
    until("the refusal's text", lambda: "Switching to Offboard denied: no offboard signal" in texts, 2)
    time.sleep(0.5)
    assert drone.telemetry.flight_mode() == FlightMode.HOLD


@pytest.mark.parametrize("drone", [SPEED, FAST], ids=lambda s: f"x{s:g}", indirect=True)
def test_takeoff_goto_offboard_land(drone):
    home = drone.telemetry.home()
    drone.action.arm()
    # a script written for real time looks around for a second before taking
    # off: 20 s of simulated time at 20x, twice COM_DISARM_PRFLT, which counts
    # on the wall clock above 1x, so the vehicle is still armed
    time.sleep(1.0)
    assert drone.telemetry.armed(), "disarmed before takeoff"
    drone.action.takeoff()
    until("in air", drone.telemetry.in_air, 20)
    until("hold after takeoff", lambda: drone.telemetry.flight_mode() == FlightMode.HOLD, 20)
    assert drone.telemetry.position().relative_altitude_m == pytest.approx(2.5, abs=0.3)

    # goto: MAVSDK 4 sends DO_REPOSITION in frame 0, altitude AMSL, yaw in rad
    lat, lon = 47.398039, 8.545594  # 33 m north of home
    alt = home.absolute_altitude_m + 10.0
    drone.action.goto_location(lat, lon, alt, 90.0)

    def arrived():
        p = drone.telemetry.position()
        north = (p.latitude_deg - lat) * 111_195.0
        east = (p.longitude_deg - lon) * 111_195.0 * math.cos(math.radians(lat))
        return math.hypot(north, east) < 1.0 and abs(p.absolute_altitude_m - alt) < 0.5

    until("goto target", arrived, 40)
    until("heading east", lambda: abs(drone.telemetry.attitude_euler().yaw_deg - 90.0) < 5.0, 20)

    # offboard position, then velocity
    here = drone.ned().position
    drone.offboard.set_position_ned(PositionNedYaw(here.north_m, here.east_m, here.down_m, 90.0))
    drone.offboard.start()
    until("offboard mode", lambda: drone.telemetry.flight_mode() == FlightMode.OFFBOARD, 5)
    target = (here.north_m + 3.0, here.east_m - 2.0, here.down_m + 2.0)
    drone.offboard.set_position_ned(PositionNedYaw(*target, 0.0))

    def at_target():
        p = drone.ned().position
        return math.dist((p.north_m, p.east_m, p.down_m), target) < 0.3

    until("offboard position", at_target, 30)
    drone.offboard.set_velocity_ned(VelocityNedYaw(1.0, 0.0, 0.0, 0.0))
    until("1 m/s north", lambda: abs(drone.ned().velocity.north_m_s - 1.0) < 0.1, 20)
    drone.offboard.stop()
    until("hold after offboard stop", lambda: drone.telemetry.flight_mode() == FlightMode.HOLD, 5)

    # land, auto-disarm
    drone.action.land()
    until("landed", lambda: not drone.telemetry.in_air(), 60)
    until("disarmed", lambda: not drone.telemetry.armed(), 20)


def test_disarm_in_air_refused(drone):
    drone.action.arm()
    drone.action.takeoff()
    until("in air", drone.telemetry.in_air, 20)
    # the vehicle's TEMPORARILY_REJECTED (MAVSDK reports COMMAND_DENIED), at once, not a timeout
    t0 = time.monotonic()
    with pytest.raises(ActionError) as e:
        drone.action.disarm()
    took = time.monotonic() - t0
    assert e.value.result == ActionResult.COMMAND_DENIED, e.value
    assert took < 1.0, f"disarm refusal answered after {took:.2f} s"
    assert drone.telemetry.armed()
    drone.action.land()
    until("landed", lambda: not drone.telemetry.in_air(), 60)


def mission_item(lat, lon, alt, speed):
    """A fly-through waypoint; the optional fields as MAVSDK reads them back."""
    return MissionItem(latitude_deg=lat, longitude_deg=lon, relative_altitude_m=alt, speed_m_s=speed,
                       is_fly_through=True, camera_photo_interval_s=1.0, acceptance_radius_m=2.0)


def item_difference(a, b):
    for f in ("latitude_deg", "longitude_deg", "relative_altitude_m", "speed_m_s", "is_fly_through",
              "acceptance_radius_m", "camera_action", "vehicle_action", "loiter_time_s", "yaw_deg"):
        x, y = getattr(a, f), getattr(b, f)
        if isinstance(x, float) and math.isnan(x):
            ok = isinstance(y, float) and math.isnan(y)
        elif f in ("latitude_deg", "longitude_deg"):
            ok = abs(x - y) < 1.01e-7
        elif isinstance(x, float):
            ok = abs(x - y) < 1e-4
        else:
            ok = x == y
        if not ok:
            return f"{f}: {x!r} != {y!r}"
    return None


@pytest.mark.parametrize("speed", [1.0, FAST], ids=["x1", "x20"])
def test_three_waypoint_mission(speed):
    """The MAVSDK 3 mission test's three waypoints (8, 3 and 5 m/s, RTL after)
    through the native core: upload, read back equal, fly to the end, land at
    home, disarm."""
    with Vehicle(speed=speed, params={"RTL_RETURN_ALT": 10.0, "RTL_DESCEND_ALT": 10.0}) as v:
        d = Drone(v)
        try:
            until("health", d.healthy, 20)
            mission = Mission(d.system)
            home = d.telemetry.home()
            lat0, lon0 = home.latitude_deg, home.longitude_deg
            m_lon = 111_195.0 * math.cos(math.radians(lat0))
            wps = [(lat0 + 15 / 111_195.0, lon0), (lat0 + 15 / 111_195.0, lon0 + 30 / m_lon), (lat0, lon0 + 30 / m_lon)]
            plan = MissionPlan(mission_items=[mission_item(la, lo, 8.0, s) for (la, lo), s in zip(wps, (8.0, 3.0, 5.0))])
            mission.set_return_to_launch_after_mission(True)
            mission.upload_mission(plan)
            got = mission.download_mission().mission_items
            assert len(got) == 3
            for k, (a, b) in enumerate(zip(plan.mission_items, got)):
                assert item_difference(a, b) is None, f"item {k}: {item_difference(a, b)}"
            assert mission.get_return_to_launch_after_mission()
            assert not mission.is_mission_finished()

            # every progress report, from MAVSDK's thread (polling the latest
            # value can miss a leg that lasts a fifth of a second at 20x)
            seen = set()
            handle = mission.subscribe_mission_progress(lambda p, _: seen.add((p.current, p.total)))
            d.action.arm()
            mission.start_mission()
            until("in air", d.telemetry.in_air, 30)
            t0 = time.monotonic()
            until("mission finished", mission.is_mission_finished, 30 + 120 / speed)
            mission.unsubscribe_mission_progress(handle)
            until("landed", lambda: not d.telemetry.in_air(), 30 + 60 / speed)
            until("disarmed", lambda: not d.telemetry.armed(), 20)
            p = d.telemetry.position()
            gap = math.hypot((p.latitude_deg - lat0) * 111_195.0, (p.longitude_deg - lon0) * m_lon)
            print(f"flown in {time.monotonic() - t0:.1f} s wall; progress {sorted(seen)}; landed {gap:.2f} m from home")
            assert gap < 1.5
            assert (3, 3) in seen and {c for c, _ in seen} >= {1, 2, 3}
        finally:
            d.mavsdk.destroy()
