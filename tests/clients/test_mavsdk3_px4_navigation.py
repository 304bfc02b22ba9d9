"""PX4's multicopter Goto, Return, parameter-FTP and failure-injection
integration tests, re-expressed with MAVSDK-Python 3.x (a real MAVSDK 3
core in mavsdk_server) against the rotorpilot binary flying on its
navigation filter (RP_NAV_SRC 1, preset in the state directory), in the
style of test_mavsdk3_px4_failsafe.py (whose `Watch`, `wait_until_ready`
and `arm` this file uses).

The cases, each a TEST_CASE of PX4-Autopilot's test/mavsdk_tests (the
docstrings name the file and the line of the TEST_CASE):

* test_multicopter_goto.cpp: DO_REPOSITION on a multicopter switches to
  PX4's Goto mode (nav state GOTO, custom mode AUTO sub-mode 21) and flies
  there; a reposition with no position pauses it into Hold; one without the
  change-mode flag, sent in Hold, flies there in Hold; DO_CHANGE_SPEED in
  Goto slows it down (AutopilotTesterGoto, AutopilotTesterLoiter);
* test_multicopter_rtl.cpp: RTL_TYPE 6 with no battery time estimate,
  returning home or to the closest rally point (AutopilotTesterRtl);
* test_multicopter_rtl_with_geofence.cpp: a direct Return that must detour
  around an exclusion polygon of the uploaded geofence, PX4's
  test/mavsdk_tests/multicopter_mission_geofence_avoid.plan (its mission and
  fence are held below as PLAN, moved to where the vehicle stands as PX4's
  load_qgc_mission_and_geofence_here moves them);
* test_param_ftp.cpp: @PARAM/param.pck downloaded over MAVLink FTP and
  compared bit for bit with the PARAM_VALUE list, and a packed file uploaded;
* test_multicopter_failure_injection.cpp: failure injection refused
  (MAVSDK's Result.DISABLED) while SYS_FAILURE_EN is 0, mid-air and (a
  case of the file's revision 06f69cd) before arming.

The stored revisions of PX4's files differ; the line numbers are those of
the newest revision found of each (the Goto tests and helpers of commit
74e479d, "Return" spelt out in the Return tests, the failure-injection file
that sets SYS_FAILURE_EN 0 itself). Each case that fails for a difference
from PX4 is marked xfail (strict) with what rotorpilot does, what PX4 does
and where PX4 does it.

Wire details PX4's C++ tester gets from MAVSDK plugins MAVSDK-Python has
not: AutopilotTesterLoiter sends DO_REPOSITION through MavlinkPassthrough
with NaN parameters, which MAVSDK 3's MavlinkDirect (fields as JSON) cannot
carry, so `CommandLink` sends that COMMAND_INT with pymavlink on the same
API link; HEARTBEAT's custom_mode (the nav state) is read through
MavlinkDirect. And mavsdk_server makes its Failure plugin on first use,
where PX4's tester makes it at connection (see `connect_failure_plugin`).

Clocks. PX4's AutopilotTester measures poll_condition_with_timeout and
sleep_for on the autopilot's clock (the attitude's time stamp), so those are
simulated seconds here too (`Watch.until`, `sleep_for`), each with a
wall-clock bound so a stalled vehicle fails the test rather than hangs it.
A few helpers PX4 times on the host's steady clock: AutopilotTesterGoto's
wait_until_nav_state and wait_until_reaches, and the 60 s of
start_and_wait_for_mission_sequence_raw. PX4's CI runs them at 10x, as the
vehicle runs here, so they wait SPEED times their seconds of vehicle time
(`wall_as_vehicle_s`): a loaded machine neither shortens nor stretches them.
(That also keeps them clear of a rotorpilot difference: its HEARTBEAT,
which carries the mode, goes out once a second of wall time, ten seconds of
vehicle time at 10x, where PX4 SITL's goes out once a simulated second.)

Rates. PX4's monitors ask for LOCAL_POSITION_NED at 10 Hz and the ground
truth at 15 Hz; PX4 SITL counts rates in simulated time, rotorpilot in wall
time, so they are asked for at SPEED times those rates here, the same
samples per simulated second as in PX4's CI.

Catch2's CHECK records a failure and goes on; REQUIRE stops the case.
`Checks` does the same: `require` raises at once, `check` is collected and
the case fails at its end with every failed CHECK listed.

Run with the mavsdk<4 venv, in a network namespace of its own (PX4's fixed
ports): `unshare -n bash -c 'ip link set lo up && python -m pytest
tests/clients/test_mavsdk3_px4_navigation.py'`.
"""

import asyncio
import json
import math
import os
import socket
import struct
import sys
import tempfile
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE / "mavsdk_examples"))
from harness import Vehicle  # noqa: E402
from test_mavsdk3 import free_tcp_port  # noqa: E402
from test_mavsdk3_px4_failsafe import SPEED, Watch, arm, boot_params, wait_until_ready  # noqa: E402

import common  # noqa: E402
from mavsdk import System  # noqa: E402
from pymavlink.dialects.v20 import common as mavlink2  # noqa: E402
from mavsdk.action import ActionError  # noqa: E402
from mavsdk.failure import FailureError, FailureType, FailureUnit  # noqa: E402
from mavsdk.mission_raw import MissionItem as RawItem  # noqa: E402
from mavsdk.offboard import OffboardError, PositionNedYaw  # noqa: E402
from mavsdk.telemetry import LandedState  # noqa: E402

# px4_custom_mode.h, as test_multicopter_goto.cpp spells them
PX4_CUSTOM_MAIN_MODE_AUTO = 4
PX4_CUSTOM_SUB_MODE_AUTO_LOITER = 3
PX4_CUSTOM_SUB_MODE_GOTO = 21
MAV_CMD_DO_REPOSITION = 192
MAV_FRAME_GLOBAL_INT = 5
MAV_FRAME_GLOBAL_RELATIVE_ALT = 3
MAV_CMD_NAV_RALLY_POINT = 5100
MAV_MISSION_TYPE_RALLY = 2
INT32_MAX = 2**31 - 1
# AutopilotTesterGoto/Loiter's POSITION_RATE_HZ and request_ground_truth's rate
POSITION_RATE_HZ = 10.0
GROUND_TRUTH_RATE_HZ = 15.0
# MAVSDK's geometry::CoordinateTransformation
WORLD_RADIUS_M = 6371000.0


def wall_as_vehicle_s(wall_s):
    """A timeout PX4's tester measures on the host's steady clock, as vehicle
    seconds at the speed PX4's CI runs it (and this vehicle runs): SPEED x."""
    return wall_s * SPEED


class CoordinateTransformation:
    """MAVSDK's geometry::CoordinateTransformation (azimuthal equidistant
    projection around a reference, on a sphere of 6371 km)."""

    def __init__(self, lat_deg, lon_deg):
        self.lat = math.radians(lat_deg)
        self.lon = math.radians(lon_deg)

    def local_from_global(self, lat_deg, lon_deg):
        lat, lon = math.radians(lat_deg), math.radians(lon_deg)
        cos_d_lon = math.cos(lon - self.lon)
        arg = math.sin(self.lat) * math.sin(lat) + math.cos(self.lat) * math.cos(lat) * cos_d_lon
        c = math.acos(max(-1.0, min(1.0, arg)))
        k = 1.0 if abs(c) < sys.float_info.epsilon else c / math.sin(c)
        north = k * (math.cos(self.lat) * math.sin(lat) - math.sin(self.lat) * math.cos(lat) * cos_d_lon)
        north *= WORLD_RADIUS_M
        east = k * math.cos(lat) * math.sin(lon - self.lon) * WORLD_RADIUS_M
        return north, east

    def global_from_local(self, north_m, east_m):
        x, y = north_m / WORLD_RADIUS_M, east_m / WORLD_RADIUS_M
        c = math.hypot(x, y)
        if c == 0:
            return math.degrees(self.lat), math.degrees(self.lon)
        sin_c, cos_c = math.sin(c), math.cos(c)
        lat = math.asin(cos_c * math.sin(self.lat) + x * sin_c * math.cos(self.lat) / c)
        lon = self.lon + math.atan2(y * sin_c, c * math.cos(self.lat) * cos_c - x * math.sin(self.lat) * sin_c)
        return math.degrees(lat), math.degrees(lon)


class Checks:
    """Catch2's CHECK (recorded, the case goes on) and REQUIRE (stops it)."""

    def __init__(self):
        self.failed = []

    def check(self, ok, what):
        if not ok:
            self.failed.append(what)
        return ok

    @staticmethod
    def require(ok, what):
        if not ok:
            raise AssertionError(f"REQUIRE failed: {what}")

    def done(self, w=None):
        if self.failed:
            more = f"; modes {[m.name for m in w.modes]}; texts {w.texts[-12:]}" if w is not None else ""
            raise AssertionError(f"{len(self.failed)} CHECK failed: " + " | ".join(self.failed[:8]) + more)


class NavWatch(Watch):
    """`Watch` plus what these cases read: the local position and velocity
    (PositionVelocityNed, with a list of monitors called on each sample), the
    landed state, the estimated home, and, MissionRaw's progress, and, straight
    off the wire through MAVSDK's MavlinkDirect, HEARTBEAT's custom_mode
    (PX4's nav state, which AutopilotTesterGoto reads the same way)."""

    def __init__(self, uav, vehicle):
        super().__init__(uav)
        self.vehicle = vehicle
        self.sysid = vehicle.sysid
        self.raw_progress = (0, 0)
        self.link = None
        self.pos = None
        self.landed = None
        self.home = None
        self.custom_mode = None
        self.custom_modes = []
        self.acks = []
        self.monitors = []
        self.checks = Checks()
        self.home_truth = None

    def keep(self, stream, f):
        async def run():
            async for x in stream:
                f(x)

        self.tasks.append(asyncio.ensure_future(run()))

    def start(self):
        super().start()
        t = self.uav.telemetry
        self.keep(t.position_velocity_ned(), self._on_pos)
        self.keep(t.landed_state(), lambda s: setattr(self, "landed", s))
        self.keep(t.home(), lambda h: setattr(self, "home", h))
        self.keep(self.uav.mission_raw.mission_progress(),
                  lambda p: setattr(self, "raw_progress", (p.current, p.total)))
        self.keep(self.uav.mavlink_direct.message("HEARTBEAT"), self._on_heartbeat)
        return self

    def _on_pos(self, p):
        self.pos = p
        for f in list(self.monitors):
            f(p)

    def _on_heartbeat(self, m):
        if m.system_id != self.sysid or m.component_id != 1:
            return
        mode = json.loads(m.fields_json)["custom_mode"]
        if mode != self.custom_mode:
            self.custom_modes.append((self.now_s, nav_state_name(mode)))
        self.custom_mode = mode

    async def sleep_for(self, sim_s):
        """AutopilotTester::sleep_for: `sim_s` of the vehicle's time."""
        await self.until(lambda: True, 1, "the vehicle's clock")
        end = self.now_s + sim_s
        await self.until(lambda: self.now_s >= end, sim_s + 1, f"{sim_s} s of vehicle time")

    def disarmed(self, since):
        """Armed false (HEARTBEAT: once a second of wall time here), or the
        disarm's own STATUSTEXT, which comes at once."""
        return self.armed is False or any("Disarmed" in t for t in self.texts[since:])


def nav_state_name(custom_mode):
    main, sub = (custom_mode >> 16) & 0xFF, (custom_mode >> 24) & 0xFF
    return f"{main}.{sub}"


def fly(scenario, wall_limit, params=None):
    """As test_mavsdk3_px4_failsafe.fly, with a NavWatch and PX4's monitor
    rates: boot a vehicle on the filter (plus `params`), run
    `scenario(watch)` within `wall_limit` s; server and vehicle stopped
    whatever happens."""
    with Vehicle(speed=SPEED, params={**boot_params(None), **(params or {})}) as v:

        async def main():
            uav = System(port=free_tcp_port())
            await uav.connect(system_address=f"udpin://0.0.0.0:{v.api_port}")
            w = NavWatch(uav, v)
            try:
                await common.next_matching(uav.core.connection_state(), lambda c: c.is_connected, 20, "heartbeat")
                await uav.telemetry.set_rate_ground_truth(GROUND_TRUTH_RATE_HZ * SPEED)
                await uav.telemetry.set_rate_position_velocity_ned(POSITION_RATE_HZ * SPEED)
                w.start()
                await asyncio.wait_for(scenario(w), wall_limit)
                w.checks.done(w)
            finally:
                uav._stop_mavsdk_server()
                await w.stop()
                if w.link is not None:
                    w.link.close()

        return asyncio.run(main())


# ---------------------------------------------------------------------------
# AutopilotTester's helpers (autopilot_tester.cpp / .h)


async def store_home(w):
    """The ground truth where the vehicle stands (10 s), as PX4 keeps it."""
    ok = True
    try:
        await w.until(lambda: w.truth is not None and math.isfinite(w.truth.latitude_deg), 10, "ground truth")
    except AssertionError:
        ok = False
    w.checks.check(ok, "store_home: no ground truth within 10 s")
    w.home_truth = w.truth


async def coordinate_transformation(w):
    """get_coordinate_transformation: around the vehicle's home position."""
    await w.until(lambda: w.home is not None and math.isfinite(w.home.latitude_deg), 10, "home position")
    return CoordinateTransformation(w.home.latitude_deg, w.home.longitude_deg)


async def set_takeoff_altitude(w, alt_m):
    """set_takeoff_altitude: set, then read back (CHECKs, as PX4's)."""
    try:
        await w.uav.action.set_takeoff_altitude(alt_m)
        got = await w.uav.action.get_takeoff_altitude()
    except ActionError as e:
        w.checks.check(False, f"takeoff altitude {alt_m}: {e}")
        return
    w.checks.check(abs(got - alt_m) < 1e-4 * max(1.0, alt_m), f"takeoff altitude reads {got}, set {alt_m}")


async def takeoff(w):
    try:
        await w.uav.action.takeoff()
    except ActionError as e:
        Checks.require(False, f"takeoff: {e}")


async def execute_rtl(w):
    try:
        await w.uav.action.return_to_launch()
    except ActionError as e:
        Checks.require(False, f"return_to_launch: {e}")


async def require_within(w, cond, sim_s, what):
    """REQUIRE(poll_condition_with_timeout(cond, sim_s))."""
    try:
        return await w.until(cond, sim_s, what)
    except AssertionError as e:
        acks = f"; command acks {[(round(t or 0, 1), c, r) for t, c, r in w.acks]}" if w.acks else ""
        raise AssertionError(f"REQUIRE failed: {e}; modes {[m.name for m in w.modes]}{acks}; texts {w.texts[-10:]}") \
            from None


async def wait_until_hovering(w):
    """wait_for_landed_state(IN_AIR, 45 s)."""
    await require_within(w, lambda: w.landed == LandedState.IN_AIR, 45, "landed state IN_AIR")


async def wait_until_altitude(w, rel_alt_m, sim_s, delta=1.0):
    await require_within(w, lambda: w.pos is not None and abs(rel_alt_m + w.pos.position.down_m) <= delta, sim_s,
                         f"altitude {rel_alt_m} +- {delta} m (local position)")


async def wait_until_disarmed(w, sim_s, since=0):
    await require_within(w, lambda: w.disarmed(since), sim_s, "disarm")


def truth_distance_m(w, lat_deg, lon_deg):
    """Horizontal distance of the ground truth from a point (MAVSDK's
    projection around that point, as ground_truth_horizontal_position_close_to)."""
    n, e = CoordinateTransformation(lat_deg, lon_deg).local_from_global(w.truth.latitude_deg, w.truth.longitude_deg)
    return math.hypot(n, e)


def check_home_within(w, radius_m):
    d = truth_distance_m(w, w.home_truth.latitude_deg, w.home_truth.longitude_deg)
    print(f"ground truth {d:.2f} m from home")
    w.checks.check(d < radius_m, f"ground truth {d:.2f} m from home, not within {radius_m} m")


def check_home_not_within(w, min_m):
    d = truth_distance_m(w, w.home_truth.latitude_deg, w.home_truth.longitude_deg)
    w.checks.check(d > min_m, f"ground truth {d:.2f} m from home, not farther than {min_m} m")


async def offboard_goto(w, target, acceptance_m, sim_s):
    """offboard_goto: set the setpoint, start offboard (retried as
    start_offboard_with_retry does), CHECK that the estimate comes within
    `acceptance_m` (3D) within `sim_s`."""
    await w.uav.offboard.set_position_ned(target)
    last = None
    for _ in range(10):
        try:
            await w.uav.offboard.start()
            last = None
            break
        except OffboardError as e:
            last = e
            await w.uav.offboard.set_position_ned(target)
            await asyncio.sleep(0.02)
    Checks.require(last is None, f"offboard start: {last}")

    def close():
        p = w.pos.position
        return math.dist((p.north_m, p.east_m, p.down_m), (target.north_m, target.east_m, target.down_m)) < acceptance_m

    try:
        took = await w.until(lambda: w.pos is not None and close(), sim_s, "offboard target")
        print(f"offboard target reached after {took:.1f} s")
    except AssertionError as e:
        p = w.pos.position
        speed = math.hypot(w.pos.velocity.north_m_s, w.pos.velocity.east_m_s)
        w.checks.check(False, f"offboard_goto: {e} (then at {p.north_m:.0f} m N {p.east_m:.0f} m E "
                              f"{-p.down_m:.0f} m up, {speed:.1f} m/s)")


# ---------------------------------------------------------------------------
# test_multicopter_goto.cpp (AutopilotTesterGoto, AutopilotTesterLoiter)

TAKEOFF_ALTITUDE = 10.0  # kTakeoffAltitude


async def arm_takeoff_hold(w):
    await wait_until_ready(w)
    await store_home(w)
    await set_takeoff_altitude(w, TAKEOFF_ALTITUDE)
    await w.sleep_for(1)
    await arm(w)
    await takeoff(w)
    await wait_until_hovering(w)
    await wait_until_altitude(w, TAKEOFF_ALTITUDE, 15, 0.5)
    await w.sleep_for(2)  # let the takeoff overshoot settle


class CommandLink:
    """MavlinkPassthrough::send_command_int's COMMAND_INT, on the vehicle's API
    link from a socket of its own (pymavlink, MAVLink 2): MAVSDK's
    MavlinkDirect takes its fields as JSON, which has no NaN, and PX4's
    tester sends NaN (yaw unchanged; "hold here": altitude unchanged). Sent as
    MAVSDK's system (245) from another component (191); the vehicle's
    COMMAND_ACKs to it are kept, for the failure messages."""

    def __init__(self, w):
        self.w = w
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setblocking(False)
        self.sock.bind(("127.0.0.1", 0))
        self.mav = mavlink2.MAVLink(None, srcSystem=245, srcComponent=191)
        self.mav.robust_parsing = True
        self.task = asyncio.ensure_future(self._read())
        w.tasks.append(self.task)

    def send(self, msg):
        self.sock.sendto(msg.pack(self.mav), ("127.0.0.1", self.w.vehicle.api_bind))

    async def _read(self):
        while True:
            try:
                data = self.sock.recv(4096)
            except BlockingIOError:
                await asyncio.sleep(0.01)
                continue
            for m in self.mav.parse_buffer(data) or []:
                if m.get_type() == "COMMAND_ACK":
                    self.w.acks.append((self.w.now_s, m.command, m.result))

    def close(self):
        self.sock.close()


async def send_command_int(w, command, param1, param2, param3, param4, x, y, z):
    """MavlinkPassthrough::send_command_int: fire and forget, as PX4's tester sends it."""
    if w.link is None:
        w.link = CommandLink(w)
    w.link.send(mavlink2.MAVLink_command_int_message(w.sysid, 1, MAV_FRAME_GLOBAL_INT, command, 0, 0, param1, param2,
                                                     param3, param4, x, y, z))


async def command_reposition(w, target, rel_alt_m, change_mode=True):
    """AutopilotTesterLoiter::command_reposition: DO_REPOSITION to a point
    north/east of home, `rel_alt_m` above the home ground truth, default
    speed, yaw unchanged, the change-mode flag as asked."""
    lat, lon = (await coordinate_transformation(w)).global_from_local(*target)
    await send_command_int(w, MAV_CMD_DO_REPOSITION, -1.0, 1.0 if change_mode else 0.0, 0.0, float("nan"),
                           int(lat * 1e7), int(lon * 1e7), w.home_truth.absolute_altitude_m + rel_alt_m)


async def command_hold_here(w):
    """AutopilotTesterLoiter::command_hold_here: DO_REPOSITION with no
    position (x, y INT32_MAX, z NaN) and the change-mode flag."""
    await send_command_int(w, MAV_CMD_DO_REPOSITION, -1.0, 1.0, 0.0, float("nan"), INT32_MAX, INT32_MAX,
                           float("nan"))


async def wait_until_nav_state(w, main, sub, wall_s):
    """AutopilotTesterGoto::wait_until_nav_state: HEARTBEAT's custom_mode
    (PX4 waits `wall_s` of its host's clock; vehicle time here, see the module doc)."""
    want = (main << 16) | (sub << 24)
    try:
        await w.until(lambda: w.custom_mode == want, wall_as_vehicle_s(wall_s), f"nav state {main}.{sub}")
    except AssertionError:
        raise AssertionError(
            f"REQUIRE failed: nav state {main}.{sub} not reached within {wall_s} s ({wall_as_vehicle_s(wall_s):.0f} s "
            f"of vehicle time); custom modes seen {w.custom_modes}; DO_REPOSITION acks "
            f"{[(round(t or 0, 1), r) for t, c, r in w.acks if c == MAV_CMD_DO_REPOSITION]}; "
            f"texts {w.texts[-8:]}") from None


def local_position(w):
    """current_local_position: north, east of the local position estimate."""
    return w.pos.position.north_m, w.pos.position.east_m


def horizontal_distance(sample, point):
    return math.hypot(sample.position.north_m - point[0], sample.position.east_m - point[1])


async def wait_until_reaches(w, target, radius_m, wall_s):
    """AutopilotTesterGoto::wait_until_reaches: a local position sample
    within `radius_m` of `target` (PX4: `wall_s` of its host's clock)."""
    took = await require_within(w, lambda: w.pos is not None and horizontal_distance(w.pos, target) <= radius_m,
                                wall_as_vehicle_s(wall_s), f"{target} within {radius_m} m")
    print(f"reached {target} after {took:.1f} s of vehicle time")


async def monitored(w, check, sim_s):
    """Run `check(sample)` on every local position sample for `sim_s` of
    vehicle time (the trajectory monitors' subscribe, sleep_for, unsubscribe)."""
    w.monitors.append(check)
    try:
        await w.sleep_for(sim_s)
    finally:
        w.monitors.remove(check)


async def check_stays_within(w, center, radius_m, sim_s):
    worst = [0.0]

    def check(s):
        d = horizontal_distance(s, center)
        worst[0] = max(worst[0], d)
        w.checks.check(d <= radius_m, f"{d:.1f} m from {center}, over {radius_m} m")

    await monitored(w, check, sim_s)
    print(f"stayed within {worst[0]:.2f} m of {center} for {sim_s} s")


async def check_never_reaches(w, point, min_m, sim_s):
    closest = [math.inf]

    def check(s):
        d = horizontal_distance(s, point)
        closest[0] = min(closest[0], d)
        w.checks.check(d >= min_m, f"{d:.1f} m from {point}, under {min_m:.1f} m")

    await monitored(w, check, sim_s)
    print(f"came no closer than {closest[0]:.2f} m to {point} in {sim_s} s")


# PX4's Goto mode (nav state 16, AUTO sub mode 21) and these tests of it come
# from a PX4 branch no release has: every PX4 release up to v1.18 flies a
# multicopter DO_REPOSITION with the change-mode flag in Hold (AUTO.LOITER,
# 4.3), and MAVSDK reports sub mode 21 as UNKNOWN. rotorpilot flies it in Hold
# as the releases do, so a script written for a released PX4 SITL sees HOLD.
GOTO_MODE_UNRELEASED = pytest.mark.xfail(strict=True, reason=(
    "Goto mode (AUTO sub mode 21) exists only in an unreleased PX4 branch (src/modules/navigator/goto_mode.cpp, "
    "Goto::on_activation / publishGotoSetpoint); rotorpilot flies a multicopter DO_REPOSITION with the "
    "change-mode flag in Hold (4.3) as every PX4 release to v1.18 does. The flight itself passes when Hold "
    "stands in for Goto"))


async def check_max_horizontal_speed(w, max_m_s, sim_s):
    fastest = [0.0]

    def check(s):
        v = math.hypot(s.velocity.north_m_s, s.velocity.east_m_s)
        fastest[0] = max(fastest[0], v)
        w.checks.check(v <= max_m_s, f"horizontal speed {v:.2f} m/s over {max_m_s} m/s")

    await monitored(w, check, sim_s)
    print(f"fastest {fastest[0]:.2f} m/s over {sim_s} s")


@GOTO_MODE_UNRELEASED
def test_goto_reposition_flies_to_and_holds_at_the_target():
    """PX4-Autopilot test/mavsdk_tests/test_multicopter_goto.cpp:69, TEST_CASE
    "Goto: reposition on a multicopter flies to and holds at the target":
    takeoff to 10 m, DO_REPOSITION (change-mode flag) 50 m north at 10 m;
    the vehicle must switch to Goto (AUTO sub-mode 21) within 5 s, come
    within 2 m of the target within 60 s and stay within 2 m for 10 s."""

    async def scenario(w):
        await arm_takeoff_hold(w)
        target = (50.0, 0.0)
        await command_reposition(w, target, TAKEOFF_ALTITUDE)
        await wait_until_nav_state(w, PX4_CUSTOM_MAIN_MODE_AUTO, PX4_CUSTOM_SUB_MODE_GOTO, 5)
        await wait_until_reaches(w, target, 2.0, 60)
        await check_stays_within(w, target, 2.0, 10)

    fly(scenario, 150)


@GOTO_MODE_UNRELEASED
def test_goto_pausing_mid_reposition_switches_to_hold_near_the_pause_point():
    """PX4-Autopilot test/mavsdk_tests/test_multicopter_goto.cpp:82, TEST_CASE
    "Goto: pausing mid-reposition switches to Hold near the pause point":
    reposition 200 m north, Goto within 5 s, 3 s of flight, then a
    reposition with no position (hold here): Hold within 5 s; for 10 s the
    vehicle never comes back within (its distance at the pause - 2 m) of the
    point it left, and for 5 s stays within 15 m of the pause point."""

    async def scenario(w):
        await arm_takeoff_hold(w)
        hold_position = local_position(w)
        far_target = (200.0, 0.0)
        await command_reposition(w, far_target, TAKEOFF_ALTITUDE)
        await wait_until_nav_state(w, PX4_CUSTOM_MAIN_MODE_AUTO, PX4_CUSTOM_SUB_MODE_GOTO, 5)
        await w.sleep_for(3)  # fly toward it, but nowhere near reaching it
        pause_position = local_position(w)
        await command_hold_here(w)
        await wait_until_nav_state(w, PX4_CUSTOM_MAIN_MODE_AUTO, PX4_CUSTOM_SUB_MODE_AUTO_LOITER, 5)
        dist_at_pause = math.dist(pause_position, hold_position)
        print(f"paused {dist_at_pause:.1f} m from the hold point")
        await check_never_reaches(w, hold_position, dist_at_pause - 2.0, 10)
        await check_stays_within(w, pause_position, 15.0, 5)

    fly(scenario, 150)


def test_goto_in_place_reposition_while_in_hold_stays_in_hold_and_flies_there():
    """PX4-Autopilot test/mavsdk_tests/test_multicopter_goto.cpp:106, TEST_CASE
    "Goto: in-place reposition while already in Hold stays in Hold and flies
    there": in Hold after the takeoff (5 s), a DO_REPOSITION 30 m north
    without the change-mode flag; the vehicle comes within 2 m within 60 s
    and is still in Hold (1 s)."""

    async def scenario(w):
        await arm_takeoff_hold(w)
        await wait_until_nav_state(w, PX4_CUSTOM_MAIN_MODE_AUTO, PX4_CUSTOM_SUB_MODE_AUTO_LOITER, 5)
        target = (30.0, 0.0)
        await command_reposition(w, target, TAKEOFF_ALTITUDE, change_mode=False)
        await wait_until_reaches(w, target, 2.0, 60)
        await wait_until_nav_state(w, PX4_CUSTOM_MAIN_MODE_AUTO, PX4_CUSTOM_SUB_MODE_AUTO_LOITER, 1)

    fly(scenario, 150)


@GOTO_MODE_UNRELEASED
def test_goto_speed_change_while_flying_is_applied():
    """PX4-Autopilot test/mavsdk_tests/test_multicopter_goto.cpp:120, TEST_CASE
    "Goto: speed change while flying is applied": reposition 200 m north,
    Goto within 5 s, 5 s to reach the cruise speed, DO_CHANGE_SPEED 2 m/s
    (Action.set_current_speed), 4 s to slow down, then for 5 s no sample
    over 2.5 m/s horizontally, and still in Goto (1 s)."""

    async def scenario(w):
        await arm_takeoff_hold(w)
        far_target = (200.0, 0.0)
        await command_reposition(w, far_target, TAKEOFF_ALTITUDE)
        await wait_until_nav_state(w, PX4_CUSTOM_MAIN_MODE_AUTO, PX4_CUSTOM_SUB_MODE_GOTO, 5)
        await w.sleep_for(5)  # accelerate to the default cruise speed
        slow = 2.0
        try:
            await w.uav.action.set_current_speed(slow)
        except ActionError as e:
            Checks.require(False, f"set_current_speed: {e}")
        await w.sleep_for(4)  # decelerate
        await check_max_horizontal_speed(w, slow + 0.5, 5)
        await wait_until_nav_state(w, PX4_CUSTOM_MAIN_MODE_AUTO, PX4_CUSTOM_SUB_MODE_GOTO, 1)

    fly(scenario, 150)


# ---------------------------------------------------------------------------
# test_multicopter_rtl.cpp (AutopilotTesterRtl)


async def set_param_int(w, name, value):
    """AutopilotTester::set_param_int and the tester's set_rtl_type & co.: a CHECK."""
    try:
        await w.uav.param.set_param_int(name, value)
    except Exception as e:  # noqa: BLE001 - ParamError: CHECK, as PX4
        w.checks.check(False, f"set {name} {value}: {e}")


def rally_item(seq, lat, lon):
    """AutopilotTesterRtl::add_local_rally_point's item: NAV_RALLY_POINT,
    relative altitude frame, z 0, current set on the first."""
    return RawItem(seq, MAV_FRAME_GLOBAL_RELATIVE_ALT, MAV_CMD_NAV_RALLY_POINT, 1 if seq == 0 else 0, 0, 0.0, 0.0,
                   0.0, 0.0, int(lat * 1e7), int(lon * 1e7), 0.0, MAV_MISSION_TYPE_RALLY)


async def upload_rally_points(w, local_points):
    ct = await coordinate_transformation(w)
    items = [rally_item(i, *ct.global_from_local(*p)) for i, p in enumerate(local_points)]
    await w.uav.mission_raw.upload_rally_points(items)
    return items


def check_rally_point_within(w, local_points, radius_m):
    """Within `radius_m` of one of the rally points (placed around the
    stored home ground truth, as PX4's check places them)."""
    ct = CoordinateTransformation(w.home_truth.latitude_deg, w.home_truth.longitude_deg)
    ds = [truth_distance_m(w, *ct.global_from_local(*p)) for p in local_points]
    print(f"ground truth {', '.join(f'{d:.2f}' for d in ds)} m from the rally points")
    w.checks.check(any(d < radius_m for d in ds), f"ground truth {ds} m from the rally points, none within {radius_m}")


async def rtl_type_6(w, rally_points=(), offboard_target=None, disarm_s=90):
    await wait_until_ready(w)
    await store_home(w)
    await set_param_int(w, "RTL_TYPE", 6)
    if rally_points:
        await upload_rally_points(w, rally_points)
    await arm(w)
    await takeoff(w)
    await wait_until_hovering(w)
    if offboard_target is not None:
        await offboard_goto(w, offboard_target, 5.0, 60)
    said = len(w.texts)
    await execute_rtl(w)
    took = await w.until(lambda: w.disarmed(said), disarm_s, "disarm")
    print(f"disarmed {took:.1f} s of vehicle time after the Return; modes {[m.name for m in w.modes]}")


def test_rtl_type_6_time_remaining_nan_with_no_rally_points():
    """PX4-Autopilot test/mavsdk_tests/test_multicopter_rtl.cpp:43, TEST_CASE
    "RTL_TYPE=6 time_remaining_s NaN with no rally points": RTL_TYPE 6,
    takeoff, Return; disarmed within 90 s, landed within 5 m of home."""

    async def scenario(w):
        await rtl_type_6(w)
        check_home_within(w, 5.0)

    fly(scenario, 120)


def test_rtl_type_6_time_remaining_nan_with_rally_points_and_home_is_closest():
    """PX4-Autopilot test/mavsdk_tests/test_multicopter_rtl.cpp:58, TEST_CASE
    "RTL_TYPE=6 time_remaining_s NaN with rally points and home is closest":
    a rally point 100 m north, 100 m west; takeoff over home, Return;
    disarmed within 90 s within 5 m of home (home is the closer)."""

    async def scenario(w):
        await rtl_type_6(w, rally_points=[(100.0, -100.0)])
        check_home_within(w, 5.0)

    fly(scenario, 120)


def test_rtl_type_6_time_remaining_nan_with_rally_points_and_home_is_not_closest():
    """PX4-Autopilot test/mavsdk_tests/test_multicopter_rtl.cpp:76, TEST_CASE
    "RTL_TYPE=6 time_remaining_s NaN with rally points and home is not
    closest": a rally point 300 m north; takeoff, offboard to 400 m north at
    20 m (5 m, 60 s), Return; disarmed within 150 s within 5 m of the rally
    point and farther than 20 m from home."""
    rally = [(300.0, 0.0)]

    async def scenario(w):
        await rtl_type_6(w, rally_points=rally, offboard_target=PositionNedYaw(400.0, 0.0, -20.0, 0.0),
                         disarm_s=150)
        check_rally_point_within(w, rally, 5.0)
        check_home_not_within(w, 20.0)

    fly(scenario, 180)


# ---------------------------------------------------------------------------
# test_multicopter_rtl_with_geofence.cpp

# test/mavsdk_tests/multicopter_mission_geofence_avoid.plan: its mission (a
# takeoff, three waypoints at 20 m, RTL) and geofence (an exclusion circle,
# an exclusion and an inclusion polygon), in QGroundControl's plan format
PLAN = {
    "fileType": "Plan", "groundStation": "QGroundControl", "version": 1,
    "geoFence": {
        "version": 2,
        "circles": [{"circle": {"center": [47.395306422855064, 8.54286777893347], "radius": 111.05361447891983},
                     "inclusion": False, "version": 1}],
        "polygons": [
            {"inclusion": False, "version": 1, "polygon": [
                [47.3991036, 8.5368519], [47.3985883, 8.543435299999999], [47.3967667, 8.544253699999999],
                [47.3968827, 8.541781799999999]]},
            {"inclusion": True, "version": 1, "polygon": [
                [47.39999163985872, 8.535047740378417], [47.39994510029728, 8.545445143543049],
                [47.39274987948735, 8.551976999573185], [47.39365751759516, 8.53812458836515]]},
        ],
    },
    "mission": {
        "cruiseSpeed": 15, "firmwareType": 12, "globalPlanAltitudeMode": 1, "hoverSpeed": 5, "vehicleType": 2,
        "version": 2, "plannedHomePosition": [47.3977444, 8.5455918, 489.338],
        "items": [
            {"autoContinue": True, "command": cmd, "doJumpId": i + 1, "frame": frame, "groupTag": 0,
             "params": params, "type": "SimpleItem", "AltitudeMode": 1, "Altitude": 20, "AMSLAltAboveTerrain": None}
            for i, (cmd, frame, params) in enumerate([
                (22, 3, [0, 0, 0, None, 47.3977508, 8.5456074, 20]),
                (16, 3, [0, 0, 0, None, 47.396545599479346, 8.544490781870365, 20]),
                (16, 3, [0, 0, 0, None, 47.39635128979426, 8.53915466175144, 20]),
                (16, 3, [0, 0, 0, None, 47.39446602392638, 8.540564444881795, 20]),
                (20, 2, [0, 0, 0, 0, 0, 0, 0]),
            ])
        ],
    },
    "rallyPoints": {"points": [], "version": 2},
}
GLOBAL_FRAMES = {0, 5, 3, 6, 10, 11}  # MAV_FRAME_GLOBAL(_INT), _RELATIVE_ALT(_INT), _TERRAIN_ALT(_INT)


def point_in_polygon(n, e, poly):
    inside = False
    j = len(poly) - 1
    for i in range(len(poly)):
        (ni, ei), (nj, ej) = poly[i], poly[j]
        if (ei > e) != (ej > e) and n < (nj - ni) * (e - ei) / (ej - ei) + ni:
            inside = not inside
        j = i
    return inside


def breaches(n, e, shape):
    """AutopilotTesterRtl::point_breaches_shape."""
    kind, geometry = shape
    if kind in (5001, 5002):  # polygon inclusion, exclusion
        inside = len(geometry) >= 3 and point_in_polygon(n, e, geometry)
        return inside if kind == 5002 else (len(geometry) >= 3 and not inside)
    (cn, ce), radius = geometry
    d = math.hypot(n - cn, e - ce)
    return d < radius if kind == 5004 else d > radius


async def load_qgc_mission_and_geofence_here(w):
    """AutopilotTesterRtl::load_qgc_mission_and_geofence_here: import the
    plan (MAVSDK's QGC importer), move mission and fence together so the
    first item is where the vehicle is, upload both, parse the fence into
    shapes around home, then 1 s."""
    data = await w.uav.mission_raw.import_qgroundcontrol_mission_from_string(json.dumps(PLAN))
    Checks.require(len(data.mission_items) > 0, "the plan has mission items")
    pos = await common.sample(w.uav.telemetry.position(), "position")
    Checks.require(math.isfinite(pos.latitude_deg) and math.isfinite(pos.longitude_deg), "a position")
    dx = data.mission_items[0].x - int(1e7 * pos.latitude_deg)
    dy = data.mission_items[0].y - int(1e7 * pos.longitude_deg)
    for item in data.mission_items + data.geofence_items:
        if item.frame in GLOBAL_FRAMES:
            item.x -= dx
            item.y -= dy
    await w.uav.mission_raw.upload_mission(data.mission_items)
    shapes = []
    if data.geofence_items:
        await w.uav.mission_raw.upload_geofence(data.geofence_items)
        ct = await coordinate_transformation(w)
        open_kind, vertices, target = None, [], 0
        for item in data.geofence_items:
            local = ct.local_from_global(item.x / 1e7, item.y / 1e7)
            if item.command in (5001, 5002):
                if not vertices or open_kind != item.command or len(vertices) >= target:
                    if vertices:
                        shapes.append((open_kind, vertices))
                    open_kind, vertices, target = item.command, [], int(item.param1)
                vertices.append(local)
            elif item.command in (5003, 5004):
                if vertices:
                    shapes.append((open_kind, vertices))
                open_kind, vertices = None, []
                shapes.append((item.command, (local, item.param1)))
        if vertices:
            shapes.append((open_kind, vertices))
    await w.sleep_for(1)
    return shapes


def test_return_direct_with_geofence_obstruction():
    """PX4-Autopilot test/mavsdk_tests/test_multicopter_rtl_with_geofence.cpp:43,
    TEST_CASE "Return direct with geofence obstruction": PX4's plan
    multicopter_mission_geofence_avoid.plan (mission and fence, moved here),
    GF_ACTION 1 (warn only), RTL_TYPE 0 (direct), RTL_APPR_FORCE 0, 3 s, arm;
    a ground-truth breach monitor runs from arming to disarm; start the
    mission, Return once it is at item 3, from where the straight line home
    crosses the exclusion polygon; disarmed within 400 s, no breach of any
    fence shape on the way, landed within 5 m of home."""

    async def scenario(w):
        await wait_until_ready(w)
        await store_home(w)
        shapes = await load_qgc_mission_and_geofence_here(w)
        print(f"fence shapes (local, around home): {[(k, len(g) if k in (5001, 5002) else g[1]) for k, g in shapes]}")
        await set_param_int(w, "GF_ACTION", 1)
        await set_param_int(w, "RTL_TYPE", 0)
        await set_param_int(w, "RTL_APPR_FORCE", 0)
        await w.sleep_for(3)
        await arm(w)
        Checks.require(len(shapes) > 0, "fence shapes")
        ct = await coordinate_transformation(w)
        breached = []

        async def monitor():
            last = None
            while True:
                g = w.truth
                if g is not None and g is not last and math.isfinite(g.latitude_deg):
                    n, e = ct.local_from_global(g.latitude_deg, g.longitude_deg)
                    for i, s in enumerate(shapes):
                        if breaches(n, e, s) and not breached:
                            breached.append((i, round(n, 1), round(e, 1), w.modes[-1].name if w.modes else None))
                    last = g
                await asyncio.sleep(0.005)

        task = asyncio.ensure_future(monitor())
        try:
            # execute_rtl_when_reaching_mission_sequence(3)
            try:
                await w.uav.mission_raw.start_mission()
            except Exception as e:  # noqa: BLE001 - MissionRawError
                Checks.require(False, f"start_mission: {e}")
            await require_within(w, lambda: w.raw_progress[0] >= 3, wall_as_vehicle_s(60), "mission item 3")
            said = len(w.texts)
            await execute_rtl(w)
            took = await w.until(lambda: w.disarmed(said), 400, "disarm")
            print(f"disarmed {took:.1f} s of vehicle time after the Return; modes {[m.name for m in w.modes]}")
        finally:
            task.cancel()
        w.checks.check(not breached, f"geofence breach (shape, north, east, mode): {breached}")
        check_home_within(w, 5.0)

    fly(scenario, 240)


# ---------------------------------------------------------------------------
# test_param_ftp.cpp


def decode_param_pck(f):
    """decode_param_pck: (num, total, {name: (type, value bits)}) or None."""
    if len(f) < 6:
        return None
    magic, num, total = struct.unpack_from("<HHH", f, 0)
    if magic not in (0x671B, 0x671C):
        return None
    out, prev, i = {}, "", 6
    while i < len(f):
        if f[i] == 0:
            i += 1
            continue
        if i + 2 > len(f):
            return None
        kind, has_default = f[i] & 0x0F, (f[i] >> 4) & 0x01
        common_len, name_len = f[i + 1] & 0x0F, (f[i + 1] >> 4) + 1
        i += 2
        if common_len > len(prev) or common_len + name_len > 16 or i + name_len + 4 > len(f):
            return None
        name = prev[:common_len] + f[i:i + name_len].decode()
        i += name_len
        bits = struct.unpack_from("<I", f, i)[0]
        i += 4
        if has_default:
            if i + 4 > len(f):
                return None
            i += 4
        out[name] = (kind, bits)
        prev = name
    return (num, total, out) if len(out) == num else None


def encode_one_float(name, value):
    """encode_one_float: a param.pck with one float."""
    body = bytes([4, (len(name) - 1) << 4]) + name.encode() + struct.pack("<f", value)
    return struct.pack("<HHH", 0x671B, 1, 6 + len(body)) + body


def connect_only(scenario):
    """The FTP cases only connect (no readiness, no flight)."""
    fly(scenario, 120)


def test_parameters_download_via_mavlink_ftp():
    """PX4-Autopilot test/mavsdk_tests/test_param_ftp.cpp:136, TEST_CASE
    "Parameters download via MAVLink FTP": the PARAM_VALUE list (over 100),
    then @PARAM/param.pck?withdefaults=1 over FTP (burst) within 60 s, saved
    as "param.pck?withdefaults=1"; it decodes, num == total, every listed
    parameter (but _HASH_CHECK) is in it with its type (3 int32, 4 float) and
    the same 32 bits, and nothing else is."""

    async def scenario(w):
        every = await w.uav.param.get_all_params()
        Checks.require(len(every.int_params) + len(every.float_params) > 100, "over 100 parameters")
        with tempfile.TemporaryDirectory() as d:
            async def download():
                async for _ in w.uav.ftp.download("@PARAM/param.pck?withdefaults=1", d, True):
                    pass

            try:
                await asyncio.wait_for(download(), 60)
            except Exception as e:  # noqa: BLE001 - FtpError or a timeout: REQUIRE
                Checks.require(False, f"FTP download: {e!r}")
            path = os.path.join(d, "param.pck?withdefaults=1")
            Checks.require(os.path.exists(path), f"{path} (there: {os.listdir(d)})")
            data = open(path, "rb").read()
        decoded = decode_param_pck(data)
        Checks.require(decoded is not None, "param.pck decodes")
        num, total, packed = decoded
        w.checks.check(num == total, f"num {num} != total {total}")
        compared = 0
        for p in every.int_params:
            if p.name == "_HASH_CHECK":
                continue
            Checks.require(p.name in packed, f"{p.name} in param.pck")
            w.checks.check(packed[p.name][0] == 3, f"{p.name}: type {packed[p.name][0]}, not 3")
            w.checks.check(packed[p.name][1] == p.value & 0xFFFFFFFF, f"{p.name}: {packed[p.name][1]:#x} != {p.value}")
            compared += 1
        for p in every.float_params:
            Checks.require(p.name in packed, f"{p.name} in param.pck")
            bits = struct.unpack("<I", struct.pack("<f", p.value))[0]
            w.checks.check(packed[p.name][0] == 4, f"{p.name}: type {packed[p.name][0]}, not 4")
            w.checks.check(packed[p.name][1] == bits, f"{p.name}: {packed[p.name][1]:#x} != {bits:#x} ({p.value})")
            compared += 1
        w.checks.check(compared == len(packed), f"compared {compared}, packed {len(packed)}")
        print(f"Compared {compared} parameters, {len(data)} bytes packed")

    connect_only(scenario)


def test_parameters_upload_via_mavlink_ftp():
    """PX4-Autopilot test/mavsdk_tests/test_param_ftp.cpp:224, TEST_CASE
    "Parameters upload via MAVLink FTP": the first float parameter of the
    list plus 1, packed alone into param.pck and uploaded to @PARAM within
    60 s; the parameter then reads the new value; the original set back."""

    async def scenario(w):
        every = await w.uav.param.get_all_params()
        Checks.require(len(every.float_params) > 0, "float parameters")
        name, original = every.float_params[0].name, every.float_params[0].value
        updated = original + 1.0
        print(f"{name}: {original} -> {updated}")
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "param.pck")
            open(path, "wb").write(encode_one_float(name, updated))

            async def upload():
                async for _ in w.uav.ftp.upload(path, "@PARAM"):
                    pass

            try:
                await asyncio.wait_for(upload(), 60)
            except Exception as e:  # noqa: BLE001 - FtpError or a timeout: REQUIRE
                Checks.require(False, f"FTP upload: {e!r}")
        got = await w.uav.param.get_param_float(name)
        w.checks.check(got == pytest.approx(updated), f"{name} reads {got} after uploading {updated}")
        await w.uav.param.set_param_float(name, original)

    connect_only(scenario)


# ---------------------------------------------------------------------------
# test_multicopter_failure_injection.cpp (AutopilotTesterFailure)


async def inject_failure(w, unit, kind, instance, expected):
    """CHECK(inject(unit, kind, instance) == expected): MAVSDK-Python raises
    for every result but SUCCESS."""
    try:
        await w.uav.failure.inject(unit, kind, instance)
        got = "SUCCESS"
    except FailureError as e:
        got = e._result.result.name
    w.checks.check(got == expected, f"inject {unit.name} {kind.name} {instance}: {got}, expected {expected}")
    return got


async def connect_failure_plugin(w):
    """PX4's AutopilotTesterFailure::connect makes MAVSDK's Failure plugin at
    connection, which reads SYS_FAILURE_EN then and follows its changes, so
    an injection while it is 0 is refused by MAVSDK itself (DISABLED).
    mavsdk_server makes its plugins on their first call: the first call here
    is that connection, an injection that changes nothing (gyro OK, instance
    0) which, before MAVSDK has read the parameter, goes to the vehicle and is
    refused there (DENIED, PX4's mavlink_receiver.cpp answer while
    SYS_FAILURE_EN is 0); then a second for MAVSDK's own reading."""
    for _ in range(2):
        try:
            await w.uav.failure.inject(FailureUnit.SENSOR_GYRO, FailureType.OK, 0)
            got = "SUCCESS"
        except FailureError as e:
            got = e._result.result.name
        print(f"failure plugin connected: {got}")
        await w.sleep_for(1)


def test_failure_injection_reject_mid_air_when_it_is_disabled():
    """PX4-Autopilot test/mavsdk_tests/test_multicopter_failure_injection.cpp:39,
    TEST_CASE "Failure Injection - Reject mid-air when it is disabled":
    SYS_FAILURE_EN 0, takeoff; a motor-off injection (instance 1) answered
    DISABLED; Return, disarmed within 180 s."""

    async def scenario(w):
        await connect_failure_plugin(w)
        await wait_until_ready(w)
        await set_param_int(w, "SYS_FAILURE_EN", 0)
        await arm(w)
        await takeoff(w)
        await wait_until_hovering(w)
        got = await inject_failure(w, FailureUnit.SYSTEM_MOTOR, FailureType.OFF, 1, "DISABLED")
        print(f"motor 1 off while SYS_FAILURE_EN 0: {got}")
        said = len(w.texts)
        await execute_rtl(w)
        await wait_until_disarmed(w, 180, said)

    fly(scenario, 120)


def test_failure_injection_reject_before_arming():
    """PX4-Autopilot test/mavsdk_tests/test_multicopter_failure_injection.cpp:54
    at commit 06f69cd469695bd46967d7338818570ab15fe010 (a revision of the
    file with a second multicopter case; the revision above sets
    SYS_FAILURE_EN 0 itself and has only the mid-air one), TEST_CASE
    "Failure Injection - Reject before arming": ready, then a motor-off
    injection (instance 1) answered DISABLED (SYS_FAILURE_EN at its default, 0)."""

    async def scenario(w):
        await connect_failure_plugin(w)
        await wait_until_ready(w)
        got = await inject_failure(w, FailureUnit.SYSTEM_MOTOR, FailureType.OFF, 1, "DISABLED")
        print(f"motor 1 off on the ground, SYS_FAILURE_EN at its default: {got}")

    fly(scenario, 90)
