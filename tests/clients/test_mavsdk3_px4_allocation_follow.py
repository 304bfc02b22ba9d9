"""PX4's multicopter control-allocation and follow-target integration tests,
re-expressed with MAVSDK-Python 3.x (a real MAVSDK 3 core in mavsdk_server)
against the rotorpilot binary flying on its navigation filter (RP_NAV_SRC 1,
preset in the state directory), in the style of test_mavsdk3_px4_failsafe.py
(whose `wait_until_ready` and `arm` this file uses) and
test_mavsdk3_px4_navigation.py (whose `NavWatch`, `Checks` and tester
helpers it uses).

The cases, each a TEST_CASE of PX4-Autopilot's test/mavsdk_tests (the
docstrings name the file and the line of the TEST_CASE):

* test_multicopter_control_allocation.cpp (tag [controlallocation], PX4's
  CI flies it with a hexacopter, typhoon_h480; AutopilotTesterFailure of
  autopilot_tester_failure.cpp): a motor switched off in a hover with
  SYS_FAILURE_EN, FD_ACT_EN, MC_AIRMODE and CA_FAILURE_MODE 1, then the
  square mission of prepare_square_mission (20 m legs at 10 m, no return)
  flown within a 5 m corridor and 4 m of the height of the failure, and a
  Return or a landing; two motors off; every motor off and back in turn;
  COM_ACT_FAIL_ACT 3 (Return) and 4 (Terminate);
* test_multicopter_follow_me.cpp (AutopilotTesterFollowMe of
  autopilot_tester_follow_me.cpp): a target simulated 1 Hz on a straight
  line north, streamed as positions, or positions and velocities, while the
  follow angle goes round behind, in front, front right and front left;
  velocities alone, which must not move the vehicle; RC sticks
  (ManualControl) moving the follow height, distance and angle of a still
  target.

The line numbers are those of the newest stored revision of each file:
test_multicopter_control_allocation.cpp of commit 88e4834 (which checks
ACTUATOR_OUTPUT_STATUS after the first failure), test_multicopter_follow_me.cpp
of commit 1bbd116. The helpers are those of the same era:
autopilot_tester_failure.cpp of commit 0a07855 (MC_AIRMODE set as one INT32,
as the PX4 whose parameters rotorpilot carries names it; later revisions
split it into MC_AIRMODE_LIM and MC_AIRMODE_YAW), autopilot_tester.cpp of
commit 0148665 (execute_mission: MISSION_START retried for 3 s, the mission
finished within 500 s of vehicle time) and autopilot_tester_follow_me.cpp of
commit 25ed6b6. Each case that fails for a difference from PX4 is marked
xfail (strict) with what rotorpilot does, what PX4 does and where PX4 does it.

The airframe. The control-allocation cases fly the stock `hexa`, a hexa-X
with alternating spins as PX4's typhoon_h480 is. Its motors carry PX4's
hexa-X numbers (1 right, 2 left, 3 front left, 4 rear right, 5 front right,
6 rear left: opposite pairs), so PX4's instances are sent as they are, as a
script written for PX4 SITL sends them. Without any one motor its hover
with zero yaw torque is on the edge of what the others give, and without
motors 1 and 2 the four left have rank 3: in both it flies on with its
heading free, as PX4 flies on with what its allocator gives (docs/failures.md).

Wire details. MAVSDK's FollowMe sends target locations only once a HEARTBEAT
has shown AUTO.FOLLOW_TARGET (set_target_location answers NOT_ACTIVE until
then); rotorpilot's HEARTBEAT goes out once a second of wall time, ten
seconds of vehicle time at 10x, where PX4 SITL's goes out once a simulated
second, inside the one second PX4's tester leaves for the mode switch. So
after that second these cases also wait, at most one heartbeat period of
wall time, for MAVSDK to see the mode (`wait_for_follow_me_active`). The
target's noise is PX4's own: its tester draws it from
std::default_random_engine seeded with the update count through
std::normal_distribution, which `Libstdcxx` draws as PX4's CI (GCC's
libstdc++) does.

Clocks, as the two files above: the tester's poll_condition_with_timeout
and sleep_for are vehicle seconds (`Watch.until`, `NavWatch.sleep_for`),
each with a wall-clock bound. The control-allocation cases sleep one second
of the host's clock (std::this_thread::sleep_for) between steps; PX4's CI
runs them at 10x, as the vehicle runs here, so they are SPEED times as many
seconds of vehicle time (`wall_as_vehicle_s`). Catch2's CHECK and REQUIRE are
`Checks.check` and `Checks.require`.

Run with the mavsdk<4 venv, in a network namespace of its own (PX4's fixed
ports): `unshare -n bash -c 'ip link set lo up && python -m pytest
tests/clients/test_mavsdk3_px4_allocation_follow.py'`.
"""

import asyncio
import math
import sys
import time
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE / "mavsdk_examples"))
from harness import Vehicle  # noqa: E402
from test_mavsdk3 import free_tcp_port  # noqa: E402
from test_mavsdk3_px4_failsafe import SPEED, arm, boot_params, square_item, wait_until_ready  # noqa: E402
from test_mavsdk3_px4_navigation import (  # noqa: E402
    GROUND_TRUTH_RATE_HZ,
    POSITION_RATE_HZ,
    Checks,
    CoordinateTransformation,
    NavWatch,
    check_home_within,
    coordinate_transformation,
    execute_rtl,
    inject_failure,
    require_within,
    set_param_int,
    set_takeoff_altitude,
    store_home,
    takeoff,
    wait_until_altitude,
    wait_until_disarmed,
    wait_until_hovering,
    wall_as_vehicle_s,
)

import common  # noqa: E402
from mavsdk import System  # noqa: E402
from mavsdk.action import ActionError  # noqa: E402
from mavsdk.failure import FailureType, FailureUnit  # noqa: E402
from mavsdk.follow_me import Config, FollowMeError, TargetLocation  # noqa: E402
from mavsdk.manual_control import ManualControlError  # noqa: E402
from mavsdk.mission import MissionPlan  # noqa: E402

# the airframe the control-allocation cases fly (module doc)
HEXA = "hexa"
# the typhoon_h480's motor count, as PX4's case writes it ("TODO: get from model")
NUM_MOTORS = 6


class AllocationWatch(NavWatch):
    """`NavWatch` plus the last ACTUATOR_OUTPUT_STATUS (MAVSDK's
    actuator_output_status, `None` until one arrives)."""

    def __init__(self, uav, vehicle):
        super().__init__(uav, vehicle)
        self.actuators = None

    def start(self):
        super().start()
        self.keep(self.uav.telemetry.actuator_output_status(), lambda s: setattr(self, "actuators", s))
        return self


def fly(scenario, wall_limit, airframe=None):
    """As test_mavsdk3_px4_navigation.fly, on `airframe` (the daemon's
    default when `None`): boot a vehicle on the filter, run
    `scenario(watch)` within `wall_limit` s; server and vehicle stopped
    whatever happens."""
    extra = ["--airframe", airframe] if airframe else []
    with Vehicle(speed=SPEED, extra=extra, params=boot_params(None)) as v:

        async def main():
            uav = System(port=free_tcp_port())
            await uav.connect(system_address=f"udpin://0.0.0.0:{v.api_port}")
            w = AllocationWatch(uav, v)
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

        return asyncio.run(main())


# ---------------------------------------------------------------------------
# AutopilotTester's helpers these cases call (autopilot_tester.cpp)


async def host_sleep(w, wall_s):
    """std::this_thread::sleep_for(wall_s) in PX4's case: the host's clock,
    SPEED times as many vehicle seconds (module doc)."""
    await w.sleep_for(wall_as_vehicle_s(wall_s))


async def set_rtl_altitude(w, alt_m):
    """set_rtl_altitude: Action's return altitude set, then read back (CHECKs)."""
    try:
        await w.uav.action.set_return_to_launch_altitude(alt_m)
        got = await w.uav.action.get_return_to_launch_altitude()
    except ActionError as e:
        w.checks.check(False, f"return altitude {alt_m}: {e}")
        return
    w.checks.check(abs(got - alt_m) < 1e-4 * max(1.0, alt_m), f"return altitude reads {got}, set {alt_m}")


async def land(w):
    try:
        await w.uav.action.land()
    except ActionError as e:
        Checks.require(False, f"land: {e}")


def current_position_ned(w):
    """get_current_position_ned: the local position estimate, north, east, down."""
    p = w.pos.position
    return [p.north_m, p.east_m, p.down_m]


async def wait_until_speed_lower_than(w, speed_m_s, sim_s):
    """The local velocity estimate's 3D norm under `speed_m_s` within `sim_s` (REQUIRE)."""

    def slow():
        v = w.pos.velocity
        return math.sqrt(v.north_m_s ** 2 + v.east_m_s ** 2 + v.down_m_s ** 2) < speed_m_s

    await require_within(w, lambda: w.pos is not None and slow(), sim_s, f"speed under {speed_m_s} m/s")


async def prepare_square_mission(w):
    """prepare_square_mission with the cases' options (20 m legs, 10 m
    above home, stopping at each, no return at the end): north, north-east,
    east of home (MAVSDK's projection around its home); then 1 s."""
    ct = await coordinate_transformation(w)
    items = [square_item(*ct.global_from_local(n, e)) for n, e in [(20.0, 0.0), (20.0, 20.0), (0.0, 20.0)]]
    await w.uav.mission.set_return_to_launch_after_mission(False)
    try:
        await w.uav.mission.upload_mission(MissionPlan(items))
    except Exception as e:  # noqa: BLE001 - MissionError: REQUIRE
        Checks.require(False, f"mission upload: {e}")
    await w.sleep_for(1)


def point_to_line_distance(p, a, b):
    """The distance of `p` from the line through `a` and `b` (3D, unbounded)."""
    d = [b[i] - a[i] for i in range(3)]
    n = math.sqrt(sum(x * x for x in d))
    u = [x / n for x in d] if n > 1e-6 else [0.0, 0.0, 0.0]
    t = sum(u[i] * (p[i] - a[i]) for i in range(3))
    return math.dist(p, [a[i] + t * u[i] for i in range(3)])


async def check_tracks_mission(w, corridor_m):
    """check_tracks_mission: the mission downloaded, LOCAL_POSITION_NED at
    5 Hz, and while the mission's current item is past the first and not
    past the last, each sample within `corridor_m` of the line from the
    previous item to the current one (CHECK; runs to the end of the case)."""
    try:
        plan = await w.uav.mission.download_mission()
    except Exception as e:  # noqa: BLE001 - MissionError: CHECK
        w.checks.check(False, f"mission download: {e}")
        return
    ct = await coordinate_transformation(w)
    legs = [(*ct.local_from_global(i.latitude_deg, i.longitude_deg), -i.relative_altitude_m)
            for i in plan.mission_items]
    await w.uav.telemetry.set_rate_position_velocity_ned(5.0 * SPEED)
    worst = {}

    def check(s):
        current, total = w.progress
        if 0 < current < total and current < len(legs):
            p = (s.position.north_m, s.position.east_m, s.position.down_m)
            d = point_to_line_distance(p, legs[current - 1], legs[current])
            worst[current] = max(worst.get(current, 0.0), d)
            w.checks.check(d < corridor_m, f"{d:.1f} m off the leg to item {current}, over {corridor_m} m")

    w.monitors.append(check)
    return worst


def start_checking_altitude(w, max_deviation_m):
    """start_checking_altitude: each local position sample within
    `max_deviation_m` of the height now (CHECK); returns the monitor, for
    `stop_checking_altitude`, and the largest deviation seen."""
    target = w.pos.position.down_m
    worst = [0.0]

    def check(s):
        dev = abs(target - s.position.down_m)
        worst[0] = max(worst[0], dev)
        w.checks.check(dev <= max_deviation_m, f"height {dev:.2f} m off where the check started, over "
                                               f"{max_deviation_m} m")

    w.monitors.append(check)
    return check, worst


def stop_checking_altitude(w, monitor):
    check, worst = monitor
    w.monitors.remove(check)
    print(f"height within {worst[0]:.2f} m of where the check started")


async def execute_mission(w):
    """execute_mission: MISSION_START retried until accepted within 3 s
    (REQUIRE), then the mission finished within 500 s (REQUIRE). A vehicle
    that is disarmed flies no mission, so the wait ends there with the same
    verdict PX4's 500 s would give."""
    first, last = w.now_s, None
    while True:
        try:
            await w.uav.mission.start_mission()
            break
        except Exception as e:  # noqa: BLE001 - MissionError, retried as PX4 polls it
            last = e
        Checks.require(w.now_s - first <= 3, f"start_mission refused for 3 s: {last}; modes "
                                             f"{[m.name for m in w.modes]}; texts {w.texts[-8:]}")
        await asyncio.sleep(0.03)
    said = len(w.texts)

    def finished():
        return w.progress[1] > 0 and w.progress[0] == w.progress[1]

    took = await require_within(w, lambda: finished() or w.disarmed(said), 500, "mission finished")
    Checks.require(finished(), f"mission at {w.progress}, the vehicle disarmed {took:.1f} s after its start; "
                               f"modes {[m.name for m in w.modes]}; texts {w.texts[-8:]}")
    Checks.require(await w.uav.mission.is_mission_finished(), "is_mission_finished")
    print(f"mission finished {took:.1f} s of vehicle time after its start")


# ---------------------------------------------------------------------------
# test_multicopter_control_allocation.cpp (AutopilotTesterFailure)

FLIGHT_ALTITUDE = 10.0
ALTITUDE_TOLERANCE = 4.0
HOVER_SPEED_TOLERANCE = 1.0


async def configure_allocation(w, com_act_fail_act=None):
    """SYS_FAILURE_EN, FD_ACT_EN, MC_AIRMODE (1: roll and pitch),
    CA_FAILURE_MODE 1, and COM_ACT_FAIL_ACT when the case sets it (CHECKs)."""
    await set_param_int(w, "SYS_FAILURE_EN", 1)
    await set_param_int(w, "FD_ACT_EN", 1)
    await set_param_int(w, "MC_AIRMODE", 1)
    await set_param_int(w, "CA_FAILURE_MODE", 1)
    if com_act_fail_act is not None:
        await set_param_int(w, "COM_ACT_FAIL_ACT", com_act_fail_act)


async def enable_actuator_output_status(w):
    """ACTUATOR_OUTPUT_STATUS at 20 Hz (CHECK); asked for at SPEED times that."""
    try:
        await w.uav.telemetry.set_rate_actuator_output_status(20.0 * SPEED)
    except Exception as e:  # noqa: BLE001 - TelemetryError: CHECK
        w.checks.check(False, f"ACTUATOR_OUTPUT_STATUS rate: {e}")


def ensure_motor_stopped(w, index, num_motors):
    """ensure_motor_stopped: the last ACTUATOR_OUTPUT_STATUS has at least
    `num_motors` outputs, motor `index` (from 0) at most 901, every other at
    least 999 (CHECKs; an output that is not there fails its CHECK)."""
    s = w.actuators
    active = s.active if s is not None else 0
    outputs = list(s.actuator) if s is not None else []
    w.checks.check(active >= num_motors, f"ACTUATOR_OUTPUT_STATUS active {active}, under {num_motors}"
                                         f"{'' if s is not None else ' (none received)'}")
    print(f"ACTUATOR_OUTPUT_STATUS at {w.now_s:.1f} s: active {active}, motors {outputs[:num_motors]}")
    for i in range(num_motors):
        value = outputs[i] if i < len(outputs) else float("nan")
        if i == index:
            w.checks.check(value <= 901.0, f"motor {i + 1} output {value}, not stopped (<= 901)")
        else:
            w.checks.check(value >= 999.0, f"motor {i + 1} output {value}, not running (>= 999)")


async def allocation_setup(w, com_act_fail_act=None, mission=True, actuator_status=False,
                           altitude=FLIGHT_ALTITUDE, home=True):
    """The cases' common start, up to the hover: ready, the parameters, (the
    square mission, the takeoff and return altitudes, the corridor check),
    the takeoff altitude, home stored, 1 s of the host's clock; returns the
    corridor monitor's worst distances (or None)."""
    await wait_until_ready(w)
    await configure_allocation(w, com_act_fail_act)
    worst = None
    if mission:
        await prepare_square_mission(w)
        await set_takeoff_altitude(w, altitude)
        await set_rtl_altitude(w, altitude)
        worst = await check_tracks_mission(w, 5.0)
    else:
        await set_takeoff_altitude(w, altitude)
    if home:
        await store_home(w)
    if actuator_status:
        await enable_actuator_output_status(w)
    await host_sleep(w, 1)  # PX4: "necessary for the takeoff altitude to be applied properly"
    return worst


async def takeoff_and_settle(w, altitude=FLIGHT_ALTITUDE, sim_s=30, hovering=True):
    await arm(w)
    await takeoff(w)
    if hovering:
        await wait_until_hovering(w)
    await wait_until_altitude(w, altitude, sim_s)
    await wait_until_speed_lower_than(w, HOVER_SPEED_TOLERANCE, sim_s)


async def motor(w, instance, kind):
    """inject_failure(SYSTEM_MOTOR, kind, instance, SUCCESS): a CHECK."""
    got = await inject_failure(w, FailureUnit.SYSTEM_MOTOR, kind, instance, "SUCCESS")
    print(f"motor {instance} {kind.name} at {w.now_s:.1f} s: {got}")


def corridor_report(worst):
    if worst:
        print("largest distance from the legs: " + ", ".join(f"item {k} {v:.2f} m" for k, v in sorted(worst.items())))


def test_control_allocation_remove_one_motor():
    """PX4-Autopilot test/mavsdk_tests/test_multicopter_control_allocation.cpp:40
    at commit 88e483492f87e38d32cbca045ea9c6e81dba1a23, TEST_CASE "Control
    Allocation - Remove one motor": the parameters, the square mission (5 m
    corridor), takeoff to 10 m, hovering, 10 m within 30 s, under 1 m/s
    within 30 s; from then on within 4 m of that height; motor 1 off
    (SUCCESS), 1 s, motor 1 stopped and the other five running
    (ACTUATOR_OUTPUT_STATUS); the mission flown to its end (500 s), the
    motor still stopped; Return, disarmed within 180 s, within 5 m of home."""

    async def scenario(w):
        worst = await allocation_setup(w, actuator_status=True)
        await takeoff_and_settle(w)
        altitude = start_checking_altitude(w, ALTITUDE_TOLERANCE)
        await motor(w, 1, FailureType.OFF)
        await host_sleep(w, 1)
        ensure_motor_stopped(w, 0, NUM_MOTORS)
        await execute_mission(w)
        stop_checking_altitude(w, altitude)
        ensure_motor_stopped(w, 0, NUM_MOTORS)
        said = len(w.texts)
        await execute_rtl(w)
        await wait_until_disarmed(w, 180, said)
        check_home_within(w, 5.0)
        corridor_report(worst)

    fly(scenario, 150, HEXA)


def test_control_allocation_remove_two_motors():
    """PX4-Autopilot test/mavsdk_tests/test_multicopter_control_allocation.cpp:95
    at commit 88e483492f87e38d32cbca045ea9c6e81dba1a23, TEST_CASE "Control
    Allocation - Remove two motors": as one motor, but motors 1 and 2 off,
    1 s apart ("opposite of one another" on PX4's hexa-X); the mission flown
    to its end within 4 m of the height; then Land (a Return would wait for a
    heading it cannot reach), disarmed within 180 s."""

    async def scenario(w):
        worst = await allocation_setup(w)
        await takeoff_and_settle(w)
        altitude = start_checking_altitude(w, ALTITUDE_TOLERANCE)
        await motor(w, 1, FailureType.OFF)
        await host_sleep(w, 1)
        await motor(w, 2, FailureType.OFF)
        await host_sleep(w, 1)
        await execute_mission(w)
        stop_checking_altitude(w, altitude)
        said = len(w.texts)
        await land(w)
        await wait_until_disarmed(w, 180, said)
        corridor_report(worst)

    fly(scenario, 150, HEXA)


def test_control_allocation_remove_and_restore_every_motor_once():
    """PX4-Autopilot test/mavsdk_tests/test_multicopter_control_allocation.cpp:150
    at commit 88e483492f87e38d32cbca045ea9c6e81dba1a23, TEST_CASE "Control
    Allocation - Remove and restore every motor once": in the hover, within
    4 m of its height, each motor 1 to 6 off (SUCCESS), 1 s, back on
    (SUCCESS), 1 s; then the square mission flown to its end, Return,
    disarmed within 180 s, within 5 m of home."""

    async def scenario(w):
        worst = await allocation_setup(w)
        await takeoff_and_settle(w)
        altitude = start_checking_altitude(w, ALTITUDE_TOLERANCE)
        for m in range(1, NUM_MOTORS + 1):
            await motor(w, m, FailureType.OFF)
            await host_sleep(w, 1)
            await motor(w, m, FailureType.OK)
            await host_sleep(w, 1)
        await execute_mission(w)
        stop_checking_altitude(w, altitude)
        said = len(w.texts)
        await execute_rtl(w)
        await wait_until_disarmed(w, 180, said)
        check_home_within(w, 5.0)
        corridor_report(worst)

    fly(scenario, 180, HEXA)


def test_control_allocation_return_home_on_motor_failure():
    """PX4-Autopilot test/mavsdk_tests/test_multicopter_control_allocation.cpp:202
    at commit 88e483492f87e38d32cbca045ea9c6e81dba1a23, TEST_CASE "Control
    Allocation - Return home on motor failure": COM_ACT_FAIL_ACT 3 (Return),
    takeoff to 10 m over home, settled; motor 1 off (SUCCESS), 1 s; the
    vehicle returns by itself: disarmed within 180 s, within 5 m of home."""

    async def scenario(w):
        await allocation_setup(w, com_act_fail_act=3, mission=False)
        await takeoff_and_settle(w)
        said = len(w.texts)
        await motor(w, 1, FailureType.OFF)
        await host_sleep(w, 1)
        await wait_until_disarmed(w, 180, said)
        print(f"modes {[m.name for m in w.modes]}")
        check_home_within(w, 5.0)

    fly(scenario, 120, HEXA)


def test_control_allocation_terminate_on_motor_failure():
    """PX4-Autopilot test/mavsdk_tests/test_multicopter_control_allocation.cpp:243
    at commit 88e483492f87e38d32cbca045ea9c6e81dba1a23, TEST_CASE "Control
    Allocation - Terminate on motor failure": COM_ACT_FAIL_ACT 4
    (Terminate), takeoff to 100 m (no hovering wait), 100 m within 60 s,
    under 1 m/s within 60 s; motor 1 off (SUCCESS), 1 s; disarmed within
    int(2 + sqrt(2 h / 10)) = 6 s, which only a free fall makes."""
    altitude = 100.0

    async def scenario(w):
        await allocation_setup(w, com_act_fail_act=4, mission=False, altitude=altitude, home=False)
        await takeoff_and_settle(w, altitude, 60, hovering=False)
        said = len(w.texts)
        await motor(w, 1, FailureType.OFF)
        await host_sleep(w, 1)
        seconds_to_touchdown = int(2 + math.sqrt(altitude * 2 / 10.0))
        print(f"seconds_to_touchdown: {seconds_to_touchdown}")
        await wait_until_disarmed(w, seconds_to_touchdown, said)
        print(f"modes {[m.name for m in w.modes]}; texts {w.texts[said:]}")

    fly(scenario, 120, HEXA)


# ---------------------------------------------------------------------------
# test_multicopter_follow_me.cpp (AutopilotTesterFollowMe)


class Libstdcxx:
    """std::default_random_engine (minstd_rand0: x <- 16807 x mod 2^31 - 1)
    and std::normal_distribution as GCC's libstdc++ draws it: uniform
    variates from generate_canonical<double, 53> (two engine draws), normal
    ones by Marsaglia's polar method, a pair per accepted point, the second
    kept for the next call. PX4's tester makes a fresh engine and
    distribution for each noisy sample, seeded with the target's update
    count."""

    M = 2**31 - 1
    R = 2**31 - 2  # max - min + 1 of the engine

    def __init__(self, seed):
        self.x = seed % self.M or 1
        self.saved = None

    def engine(self):
        self.x = self.x * 16807 % self.M
        return self.x

    def canonical(self):
        total = float(self.engine() - 1)
        total += float(self.engine() - 1) * float(self.R)
        ret = total / (float(self.R) * float(self.R))
        return ret if ret < 1.0 else math.nextafter(1.0, 0.0)

    def normal(self, mean, stddev):
        if self.saved is not None:
            ret, self.saved = self.saved, None
        else:
            while True:
                x = 2.0 * self.canonical() - 1.0
                y = 2.0 * self.canonical() - 1.0
                r2 = x * x + y * y
                if 0.0 < r2 <= 1.0:
                    break
            mult = math.sqrt(-2.0 * math.log(r2) / r2)
            self.saved = x * mult
            ret = y * mult
        return ret * stddev + mean


class FollowTargetSimulator:
    """FollowTargetSimulator: a target moving north at 2 m/s once updated,
    from a NED start, reported around the stored home's ground truth; its
    noise deterministic, changed by each update."""

    POS_NOISE_STD = 0.3  # (the global position's noise is drawn at 1.0, as PX4's)
    VEL_NOISE_STD = 0.1

    def __init__(self, start_ned, home):
        self.position = list(start_ned)
        self.velocity = [0.0, 0.0, 0.0]
        self.home = home
        self.updates = 0

    def update(self, dt_s):
        self.velocity[0], self.velocity[1] = 2.0, 0.0
        self.position = [p + v * dt_s for p, v in zip(self.position, self.velocity)]
        self.updates += 1

    def noisy(self, values, stddev):
        rng = Libstdcxx(self.updates)
        return [v + rng.normal(0.0, stddev) for v in values]

    def position_ground_truth_ned(self):
        return list(self.position)

    def global_of(self, ned):
        """Latitude, longitude and altitude of `ned` around the stored home,
        the altitude as PX4's tester gives it (home's plus the NED down
        offset, its sign as there); the cases follow at a constant height
        above home, which does not read it."""
        n, e, d = ned
        lat, lon = CoordinateTransformation(self.home.latitude_deg, self.home.longitude_deg).global_from_local(n, e)
        return lat, lon, d + self.home.absolute_altitude_m

    def position_global_ground_truth(self):
        return self.global_of(self.position)

    def position_global_noisy(self):
        return self.global_of(self.noisy(self.position, 1.0))

    def velocity_ned_noisy(self):
        return self.noisy(self.velocity, self.VEL_NOISE_STD)


def check_follow_angle(w, config, drone_ned, target_ned, tolerance_m):
    """FollowTargetSimulator::check_follow_angle: the vehicle's offset from
    the target (moving north) within `tolerance_m` of the follow distance at
    the follow angle, north and east each (CHECKs)."""
    dx, dy = drone_ned[0] - target_ned[0], drone_ned[1] - target_ned[1]
    angle = math.radians(config.follow_angle_deg)
    ex, ey = config.follow_distance_m * math.cos(angle), config.follow_distance_m * math.sin(angle)
    w.checks.check(abs(dx - ex) < tolerance_m, f"angle {config.follow_angle_deg}: north offset {dx:.1f} m, "
                                               f"expected {ex:.1f} +- {tolerance_m}")
    w.checks.check(abs(dy - ey) < tolerance_m, f"angle {config.follow_angle_deg}: east offset {dy:.1f} m, "
                                               f"expected {ey:.1f} +- {tolerance_m}")


def default_config():
    """MAVSDK's FollowMe::Config as constructed: 8 m up, 8 m away, 0.1,
    constant altitude, 8 m/s, 180 deg (behind)."""
    return Config(8.0, 8.0, 0.1, Config.FollowAltitudeMode.CONSTANT, 8.0, 180.0)


async def follow_me_call(w, what, call):
    """CHECK(FollowMe::Result::Success == call): MAVSDK-Python raises for
    every result but SUCCESS."""
    try:
        await call
        got = "SUCCESS"
    except FollowMeError as e:
        got = e._result.result.name
    w.checks.check(got == "SUCCESS", f"follow_me {what}: {got}")
    return got


async def wait_for_follow_me_active(w, wall_s=2.5):
    """MAVSDK's FollowMe active: a HEARTBEAT has shown AUTO.FOLLOW_TARGET
    (module doc: at most one heartbeat period, 1 s of wall time here)."""
    t0, end = time.monotonic(), time.monotonic() + wall_s
    while not await w.uav.follow_me.is_active():
        if time.monotonic() > end:
            w.checks.check(False, f"follow-me not active {wall_s} s of wall time after start; modes "
                                  f"{[m.name for m in w.modes]}")
            return
        await asyncio.sleep(0.02)
    print(f"follow-me active {time.monotonic() - t0:.2f} s of wall time after the mode switch's second")


async def start_follow_me(w):
    """1 s for the mode switch, start (CHECK), 1 s, MAVSDK active."""
    await w.sleep_for(1)
    await follow_me_call(w, "start", w.uav.follow_me.start())
    await w.sleep_for(1)
    await wait_for_follow_me_active(w)


def check_current_altitude(w, rel_alt_m, max_distance_m=1.5):
    """check_current_altitude: GLOBAL_POSITION_INT's relative altitude (CHECK)."""
    w.checks.check(w.rel_alt_m is not None and abs(w.rel_alt_m - rel_alt_m) <= max_distance_m,
                   f"relative altitude {w.rel_alt_m} m, not within {max_distance_m} m of {rel_alt_m}")


async def straight_line_test(w, stream_velocity):
    """AutopilotTesterFollowMe::straight_line_test (module doc): 75 target
    updates at 1 Hz of vehicle time; 5 standing, then the follow angle 180
    (behind; the target moves from the next update on) checked over updates
    15-19, 0 (in front) over 30-34, 45 (front right) over 45-54, -45 (front
    left) over 65-74: relative altitude within 1.5 m of 10 m, the distance to
    the target within 8 +- 11 m, the offset at the angle within 11 m."""
    rate_hz = 1
    tolerance_m = 11.0
    height_m = 10.0
    target = FollowTargetSimulator(current_position_ned(w), w.home_truth)
    base = default_config()
    config = Config(height_m, 8.0, base.responsiveness, base.altitude_mode, 15.0, 0.0)
    await start_follow_me(w)
    moving = checking = False
    distances = {}
    for idx in range(75 * rate_hz):
        truth = target.position_ground_truth_ned()
        here = current_position_ned(w)
        distance = math.dist(truth, here)
        if idx < 5:
            pass
        elif idx in (5, 20, 35, 55):
            checking = False
            angle = {5: 180.0, 20: 0.0, 35: 45.0, 55: -45.0}[idx]
            config = Config(config.follow_height_m, config.follow_distance_m, config.responsiveness,
                            config.altitude_mode, config.max_tangential_vel_m_s, angle)
            await follow_me_call(w, f"set_config (angle {angle})", w.uav.follow_me.set_config(config))
        elif idx < 15:
            moving = True
        elif idx < 20 or 30 <= idx < 35 or 45 <= idx < 55 or 65 <= idx < 75:
            checking = True
        if moving:
            target.update(1.0 / rate_hz)
        if checking:
            check_current_altitude(w, height_m)
            distances.setdefault(config.follow_angle_deg, []).append(distance)
            w.checks.check(distance <= config.follow_distance_m + tolerance_m,
                           f"update {idx}: {distance:.1f} m from the target, over {config.follow_distance_m} + "
                           f"{tolerance_m}")
            w.checks.check(distance >= config.follow_distance_m - tolerance_m,
                           f"update {idx}: {distance:.1f} m from the target, under {config.follow_distance_m} - "
                           f"{tolerance_m}")
            check_follow_angle(w, config, here, truth, tolerance_m)
        lat, lon, alt = target.position_global_noisy()
        vel = target.velocity_ned_noisy() if stream_velocity else [float("nan")] * 3
        await follow_me_call(w, f"set_target_location (update {idx})",
                             w.uav.follow_me.set_target_location(TargetLocation(lat, lon, alt, *vel)))
        await w.sleep_for(1.0 / rate_hz)
    await follow_me_call(w, "stop", w.uav.follow_me.stop())
    for angle, ds in distances.items():
        print(f"follow angle {angle:+.0f}: {min(ds):.1f} to {max(ds):.1f} m from the target")


async def stream_velocity_only(w):
    """AutopilotTesterFollowMe::stream_velocity_only: MAVSDK's default
    config (behind) set, start; 15 target locations at 1 Hz with no position
    (NaN) and a velocity (2, 1, 0.5) m/s; the vehicle moves under 4 m (3D)."""
    await follow_me_call(w, "set_config", w.uav.follow_me.set_config(default_config()))
    await start_follow_me(w)
    start = current_position_ned(w)
    nan = float("nan")
    for i in range(15):
        await follow_me_call(w, f"set_target_location ({i})",
                             w.uav.follow_me.set_target_location(TargetLocation(nan, nan, nan, 2.0, 1.0, 0.5)))
        await w.sleep_for(1)
    moved = math.dist(start, current_position_ned(w))
    print(f"moved {moved:.2f} m while only velocities were streamed")
    w.checks.check(moved < 4.0, f"moved {moved:.2f} m, not under 4 m")


async def rc_adjustment_test(w):
    """AutopilotTesterFollowMe::rc_adjustment_test: follow height 10 m,
    distance 10 m, angle 0 (in front), the rest MAVSDK's defaults (8 m/s
    tangential); a still target where the vehicle is, its ground truth sent
    at every iteration; 60 s of iterations at 50 Hz, each 20 ms of vehicle
    time, the phases by the vehicle's time since the start (PX4 counts
    iterations of a sleep of that length). Sticks (ManualControl, throttle
    centred at 0.5): centred 5 s; throttle up 3 s, centred 2 s, then the
    height 2.25 m over where it was at 5 s (half of 1.5 m/s for 3 s); pitch
    forward 3 s, centred 2 s, then the distance over 13 m (10 + half of
    2 m/s for 3 s); roll right 3 s, centred 2 s, then the follow angle
    turned clockwise.

    The angle. PX4's test asks for 2.25 rad (half of 1.5 rad/s for 3 s), but
    PX4's task turns the angle at min(1.5 rad/s, FLW_TGT_MAX_VEL / distance)
    (FlightTaskAutoFollowTarget::updateRcAdjustedFollowAngle): 8 m/s over
    the 13 m and more the distance check has just asked for, at most
    0.62 rad/s, 1.85 rad in 3 s. So the check here is PX4's own rule, half of
    what that rate gives at the distance the roll starts from.

    The first CHECK: MAVSDK's FollowMe starts sending once a HEARTBEAT shows
    the mode (module doc), so the iterations start once it is active."""
    rate_hz = 50
    height_m, angle_deg, distance_m = 10.0, 0.0, 10.0
    # the test's copies of FlightTaskAutoFollowTarget's constants [m/s, m/s, rad/s]
    distance_speed, height_speed, angle_speed = 2.0, 1.5, 1.5
    target_pos = current_position_ned(w)
    target = FollowTargetSimulator(target_pos, w.home_truth)
    base = default_config()
    config = Config(height_m, distance_m, base.responsiveness, base.altitude_mode, base.max_tangential_vel_m_s,
                    angle_deg)
    await follow_me_call(w, "set_config", w.uav.follow_me.set_config(config))
    lat, lon, alt = target.position_global_ground_truth()
    nan = float("nan")
    location = TargetLocation(lat, lon, alt, nan, nan, nan)
    await follow_me_call(w, "start", w.uav.follow_me.start())
    await wait_for_follow_me_active(w)

    def offset(p):
        return p[0] - target_pos[0], p[1] - target_pos[1]

    async def sticks(x, y, z):
        try:
            await w.uav.manual_control.set_manual_control_input(x, y, z, 0.0)
        except ManualControlError as e:
            w.checks.check(False, f"manual control ({x}, {y}, {z}): {e}")

    t0 = w.now_s
    checked = set()
    initial = roll_from_m = None
    while (t := w.now_s - t0) <= 60.0:
        await w.uav.follow_me.set_target_location(location)
        here = current_position_ned(w)
        if t < 5:
            await sticks(0.0, 0.0, 0.5)
        elif initial is None:
            initial = here
        elif t < 8:
            await sticks(0.0, 0.0, 1.0)
        elif t < 10:
            await sticks(0.0, 0.0, 0.5)
        elif "height" not in checked:
            checked.add("height")
            climbed = -(here[2] - initial[2])
            print(f"[rc] the follow height grew {climbed:.2f} m")
            w.checks.check(climbed > height_speed * 3.0 * 0.5, f"climbed {climbed:.2f} m, not over "
                                                               f"{height_speed * 3.0 * 0.5} m")
        elif t < 13:
            await sticks(1.0, 0.0, 0.5)
        elif t < 15:
            await sticks(0.0, 0.0, 0.5)
        elif "distance" not in checked:
            checked.add("distance")
            roll_from_m = math.hypot(*offset(here))
            print(f"[rc] the follow distance is {roll_from_m:.2f} m")
            w.checks.check(roll_from_m > distance_m + distance_speed * 3.0 * 0.5,
                           f"{roll_from_m:.2f} m from the target, not over {distance_m + distance_speed * 3.0 * 0.5} m")
        elif t < 18:
            await sticks(0.0, 1.0, 0.5)
        elif t < 20:
            await sticks(0.0, 0.0, 0.5)
        elif "angle" not in checked:
            checked.add("angle")
            north, east = offset(here)
            angle = math.atan2(east, north)
            most = min(angle_speed, config.max_tangential_vel_m_s / roll_from_m) * 3.0
            print(f"[rc] the follow angle is {angle:.2f} rad (at most {most:.2f} at PX4's rate)")
            w.checks.check(angle > math.radians(angle_deg) + most * 0.5,
                           f"follow angle {angle:.2f} rad, not over {most * 0.5:.2f}")
        await w.sleep_for(1.0 / rate_hz)
    w.checks.check(checked == {"height", "distance", "angle"}, f"checked only {sorted(checked)}")


async def follow_takeoff(w):
    """The cases' start: ready, home stored, armed, takeoff altitude 10 m,
    takeoff, in the air."""
    await wait_until_ready(w)
    await store_home(w)
    await arm(w)
    await set_takeoff_altitude(w, 10.0)
    await takeoff(w)
    await wait_until_hovering(w)


async def follow_land(w):
    said = len(w.texts)
    await land(w)
    await wait_until_disarmed(w, 300, said)


@pytest.mark.parametrize("stream_velocity", [False, True], ids=["position", "position_and_velocity"])
def test_follow_target_streaming(stream_velocity):
    """PX4-Autopilot test/mavsdk_tests/test_multicopter_follow_me.cpp:40 and :61
    at commit 1bbd11683f715ebce43c377e0c8628d783ba5b04, TEST_CASEs "Follow
    target - Position streaming" and "Follow target - Position and velocity
    streaming": takeoff to 10 m, straight_line_test with the target's
    velocity streamed (noisy, 0.1 m/s) or not (NaN); Land, disarmed within
    300 s."""

    async def scenario(w):
        await follow_takeoff(w)
        await straight_line_test(w, stream_velocity)
        await follow_land(w)

    fly(scenario, 120)


def test_follow_target_velocity_streaming_only():
    """PX4-Autopilot test/mavsdk_tests/test_multicopter_follow_me.cpp:82
    at commit 1bbd11683f715ebce43c377e0c8628d783ba5b04, TEST_CASE "Follow
    target - Velocity streaming only": takeoff to 10 m, velocities alone
    for 15 s (the vehicle must not move: follow-me needs one position to
    integrate velocities from); Land, disarmed within 300 s, within 1 m of
    home."""

    async def scenario(w):
        await follow_takeoff(w)
        await stream_velocity_only(w)
        await follow_land(w)
        check_home_within(w, 1.0)

    fly(scenario, 120)


def test_follow_target_rc_adjustment():
    """PX4-Autopilot test/mavsdk_tests/test_multicopter_follow_me.cpp:106
    at commit 1bbd11683f715ebce43c377e0c8628d783ba5b04, TEST_CASE "Follow
    target - RC Adjustment": takeoff to 10 m, rc_adjustment_test (a still
    target; full throttle, then full pitch, then full roll, each for 3 s,
    the follow height, distance and angle checked after each); Land,
    disarmed within 300 s."""

    async def scenario(w):
        await follow_takeoff(w)
        await rc_adjustment_test(w)
        await follow_land(w)

    fly(scenario, 150)
