"""The native MAVSDK 4 binding (`mavsdk` 4.x on PyPI: the MAVSDK C++ core
through ctypes, no mavsdk_server) against the rotorpilot binary: connect as a
ground station with udpin://0.0.0.0:14540+N, wait for health, params, arm,
take off, goto (MAVSDK 4 sends DO_REPOSITION in frame 0), offboard position
and velocity, offboard refusal without setpoints, land.

Run with the mavsdk 4.x venv: `python -m pytest tests/clients/test_mavsdk4.py`.
"""

import math
import sys
import time
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from harness import Vehicle  # noqa: E402

from mavsdk import ComponentType, Configuration, Mavsdk  # noqa: E402
from mavsdk.plugins.action import Action, ActionError  # noqa: E402
from mavsdk.plugins.offboard import Offboard, OffboardError, PositionNedYaw, VelocityNedYaw  # noqa: E402
from mavsdk.plugins.param import Param  # noqa: E402
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


def test_version_and_identity(drone):
    assert drone.mavsdk.version().startswith("v4")
    assert drone.system.has_autopilot()


def test_params(drone):
    all_params = drone.param.get_all_params()
    names = [p.name for p in all_params.int_params] + [p.name for p in all_params.float_params]
    assert "MIS_TAKEOFF_ALT" in names and "SYS_FAILURE_EN" in names
    assert len(set(names)) == len(names)
    drone.param.set_param_float("MIS_TAKEOFF_ALT", 3.5)
    assert drone.param.get_param_float("MIS_TAKEOFF_ALT") == pytest.approx(3.5)
    drone.param.set_param_int("SYS_FAILURE_EN", 1)
    assert drone.param.get_param_int("SYS_FAILURE_EN") == 1
    # an unknown parameter fails at once (PARAM_ERROR), not after MAVSDK's 3 s timeout
    t0 = time.monotonic()
    with pytest.raises(Exception):
        drone.param.get_param_float("NO_SUCH_PARAM")
    print(f"unknown parameter refused in {time.monotonic() - t0:.2f} s")


def test_offboard_refused_without_setpoints(drone):
    drone.action.arm()
    with pytest.raises(OffboardError):
        # MAVSDK refuses on its own side before any setpoint (NoSetpointSet)
        drone.offboard.start()
    drone.action.disarm()


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
    with pytest.raises(ActionError):
        drone.action.disarm()
    assert drone.telemetry.armed()
    drone.action.land()
    until("landed", lambda: not drone.telemetry.in_air(), 60)
