"""PX4's multicopter offboard and manual-control integration tests,
re-expressed with MAVSDK-Python 3.x (a real MAVSDK 3 core in mavsdk_server)
against the rotorpilot binary flying on its navigation filter (RP_NAV_SRC 1,
preset in the state directory), in the style of test_mavsdk3_px4_failsafe.py
and test_mavsdk3_px4_navigation.py (whose `wait_until_ready`, `arm`,
`fly` with its `NavWatch`, `Checks` and AutopilotTester helpers this file
uses).

The cases, each a TEST_CASE of PX4-Autopilot's test/mavsdk_tests (the
docstrings name the file, the line of the TEST_CASE and the commit):

* test_multicopter_offboard.cpp (commit 15c4f0887da9): from the ground to
  2 m by an offboard position setpoint, a square of position setpoints with
  yaw (0.3 m, 10 s each), a landing by a velocity setpoint (1 m/s down),
  disarmed within 120 s near home; and a flight on attitude setpoints
  alone: 80 % thrust to 10 m above the start by the raw GNSS altitude, 20 deg
  nose down for 3 s, 40 % thrust for 6 s, then no thrust;
* test_multicopter_manual.cpp (commit 0cc4b41a5172): MAVSDK's ManualControl
  as the sticks, in Position (POSCTL) and in Altitude (ALTCTL): 5 s of full
  throttle, 10 s of half forward pitch, throttle down until landed, then
  disarmed within 180 s, more than 5 m from home.

The helpers are AutopilotTester's of autopilot_tester.cpp (commit
014866564299): set_rc_loss_exception (COM_RCL_EXCEPT, bit 2 for Offboard),
offboard_goto with start_offboard_with_retry, offboard_land,
fly_forward_in_posctl, fly_forward_in_altctl and
fly_forward_in_offboard_attitude. Each case that fails for a difference
from PX4 is marked xfail (strict) with what rotorpilot does, what PX4 does
and where PX4 does it.

Clocks. PX4's tester measures poll_condition_with_timeout and sleep_for
on the autopilot's clock (the attitude's time stamp), so those are
simulated seconds here too, each with a wall-clock bound so a stalled
vehicle fails the test rather than hangs it. Its stick and attitude loops
send one input and sleep 20 ms of that clock, 50 times a vehicle second:
`stream` sends for the same vehicle seconds, paced at 20 ms of vehicle
time at SPEED (the vehicle keeps the latest input, and its stick-loss
timer runs on the wall clock above 1x). The climb on attitude setpoints has
no timeout in PX4 (it loops until 10 m are gained); here it is bounded at
CLIMB_BOUND_S of vehicle time.

Catch2's CHECK records a failure and goes on; REQUIRE stops the case:
`Checks.check` and `Checks.require`, as in test_mavsdk3_px4_navigation.py.

Rates. PX4 SITL counts stream rates in simulated time, rotorpilot in wall
time (as test_mavsdk3_px4_navigation.py says), so two streams these cases
stop a loop on are asked for at SPEED times PX4's rate, the same samples per
simulated second as in PX4's CI: GPS_RAW_INT, PX4's 5 Hz on this link, whose
ellipsoid altitude ends the climb on attitude setpoints (at 5 Hz of wall time
the loop would see a fix every 2 s of vehicle time and climb on at 80 %
thrust for up to 2 s more); and EXTENDED_SYS_STATE, which MAVSDK's Action
plugin sets to 1 Hz when it is made (mavsdk_server makes it on the first
arm; PX4's tester at connection), and whose landed state ends the sticks'
descent.

Run with the mavsdk<4 venv, in a network namespace of its own (PX4's fixed
ports): `unshare -n bash -c 'ip link set lo up && python -m pytest
tests/clients/test_mavsdk3_px4_offboard_manual.py'`.
"""

import asyncio
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from test_mavsdk3_px4_failsafe import SPEED, WALL_EXTRA_S, WALL_SLACK, arm, wait_until_ready  # noqa: E402
from test_mavsdk3_px4_navigation import (  # noqa: E402
    Checks,
    check_home_not_within,
    check_home_within,
    fly,
    offboard_goto,
    set_param_int,
    store_home,
    wait_until_disarmed,
)

from mavsdk.manual_control import ManualControlError  # noqa: E402
from mavsdk.offboard import Attitude, OffboardError, PositionNedYaw, VelocityNedYaw  # noqa: E402

# test_multicopter_offboard.cpp's acceptance_radius [m]
ACCEPTANCE_RADIUS_M = 0.3
# AutopilotTester::RcLossException::Offboard, as set_rc_loss_exception sets it
RCL_EXCEPT_OFFBOARD = 1 << 2
# manual_control_rate_hz and offboard_rate_hz: one input per 20 ms of vehicle time
INPUT_PERIOD_S = 1.0 / 50
# GPS_RAW_INT's rate on PX4's onboard link, and EXTENDED_SYS_STATE's as
# MAVSDK's Action plugin sets it [Hz of vehicle time]
RAW_GPS_RATE_HZ = 5.0
EXTENDED_SYS_STATE_RATE_HZ = 1.0
# a bound on the attitude climb, which PX4 loops on without one [s of vehicle time]
CLIMB_BOUND_S = 60.0


def watch_more(w):
    """What these cases read beyond NavWatch: in-air (MAVSDK's, from
    EXTENDED_SYS_STATE), the raw GNSS fix (GPS_RAW_INT) and the attitude."""
    w.in_air = None
    w.raw_gps = None
    w.attitude = None
    t = w.uav.telemetry
    w.keep(t.in_air(), lambda a: setattr(w, "in_air", a))
    w.keep(t.raw_gps(), lambda g: setattr(w, "raw_gps", g))
    w.keep(t.attitude_euler(), lambda a: setattr(w, "attitude", a))


async def check_within(w, cond, sim_s, what):
    """CHECK(poll_condition_with_timeout(cond, sim_s))."""
    try:
        return await w.until(cond, sim_s, what)
    except AssertionError as e:
        w.checks.check(False, f"{e}; modes {[m.name for m in w.modes]}; texts {w.texts[-6:]}")
        return None


async def stream(w, send, sim_s, what, stop=None):
    """PX4's `for i < sim_s * 50: CHECK(send() == Success); sleep_for(20 ms)`
    (with `stop`: the loop's break): `send` every 20 ms of vehicle time at
    SPEED, for `sim_s` of the vehicle's time or until `stop()`; a failed
    send is a CHECK (counted, one entry a loop). Returns the vehicle seconds
    it ran."""
    await w.until(lambda: True, 1, "the vehicle's clock")
    start = w.now_s
    wall_end = time.monotonic() + WALL_EXTRA_S + WALL_SLACK * sim_s / SPEED
    failed, last = 0, None
    while w.now_s - start < sim_s and not (stop is not None and stop()):
        if time.monotonic() > wall_end:
            raise AssertionError(f"{what}: {sim_s} s of vehicle time did not pass within the wall bound "
                                 f"(only {w.now_s - start:.1f} s did)")
        try:
            await send()
        except (ManualControlError, OffboardError) as e:
            failed, last = failed + 1, e
        await asyncio.sleep(INPUT_PERIOD_S / SPEED)
    w.checks.check(failed == 0, f"{what}: {failed} inputs refused, the last: {last}")
    return w.now_s - start


def sticks(w, x, y, z, r):
    """ManualControl::set_manual_control_input(x, y, z, r)."""
    return lambda: w.uav.manual_control.set_manual_control_input(x, y, z, r)


async def check_ok(w, call, what):
    """CHECK(call() == Success): MAVSDK-Python raises for every other result."""
    try:
        await call
        ok = True
    except (ManualControlError, OffboardError) as e:
        ok = w.checks.check(False, f"{what}: {e}")
    return ok


async def set_rc_loss_exception_offboard(w):
    """set_rc_loss_exception(RcLossException::Offboard): COM_RCL_EXCEPT 1 << 2."""
    await set_param_int(w, "COM_RCL_EXCEPT", RCL_EXCEPT_OFFBOARD)


async def offboard_land(w):
    """offboard_land: the setpoint becomes 1 m/s down (offboard already running)."""
    await w.uav.offboard.set_velocity_ned(VelocityNedYaw(0.0, 0.0, 1.0, 0.0))


async def start_offboard_with_retry(w, resend):
    """start_offboard_with_retry: start, and on a refusal send the setpoint
    again and retry (20 ms of the host's clock apart), ten times at most;
    REQUIRE the last start."""
    last = None
    for _ in range(10):
        try:
            await w.uav.offboard.start()
            return
        except OffboardError as e:
            last = e
        await resend()
        await asyncio.sleep(0.02)
    Checks.require(False, f"offboard start: {last}")


# ---------------------------------------------------------------------------
# test_multicopter_offboard.cpp

TAKEOFF_POSITION = PositionNedYaw(0.0, 0.0, -2.0, 0.0)


async def offboard_takeoff(w, goto_timeout_s):
    """The cases' common start: ready, home stored, COM_RCL_EXCEPT, armed,
    then offboard to 2 m above the start."""
    await wait_until_ready(w)
    await store_home(w)
    await set_rc_loss_exception_offboard(w)
    await arm(w)
    await offboard_goto(w, TAKEOFF_POSITION, ACCEPTANCE_RADIUS_M, goto_timeout_s)


async def offboard_land_and_disarm(w):
    said = len(w.texts)
    await offboard_land(w)
    await wait_until_disarmed(w, 120, said)
    print(f"disarmed; modes {[m.name for m in w.modes]}")
    check_home_within(w, 2.0)


def test_offboard_takeoff_and_land():
    """PX4-Autopilot test/mavsdk_tests/test_multicopter_offboard.cpp:39 at commit
    15c4f0887da9, TEST_CASE "Offboard takeoff and land": ready, home stored,
    COM_RCL_EXCEPT 4, armed; offboard position setpoint 2 m up (within 0.3 m in
    90 s), then 1 m/s down; disarmed within 120 s, within 2 m of home."""

    async def scenario(w):
        await offboard_takeoff(w, 90)
        await offboard_land_and_disarm(w)

    fly(scenario, 120)


def test_offboard_position_control():
    """PX4-Autopilot test/mavsdk_tests/test_multicopter_offboard.cpp:55 at commit
    15c4f0887da9, TEST_CASE "Offboard position control": as the takeoff and land
    case, with 10 s for each setpoint: 2 m up, then 5 m east yawed to 180 deg,
    5 m north and east at 4 m (180 deg), 5 m north at 4 m (90 deg), back to
    2 m above the start (0 deg), each within 0.3 m (3D); then 1 m/s down,
    disarmed within 120 s, within 2 m of home."""
    setpoints = [
        PositionNedYaw(0.0, 5.0, -2.0, 180.0),
        PositionNedYaw(5.0, 5.0, -4.0, 180.0),
        PositionNedYaw(5.0, 0.0, -4.0, 90.0),
        TAKEOFF_POSITION,
    ]

    async def scenario(w):
        await offboard_takeoff(w, 10)
        for target in setpoints:
            await offboard_goto(w, target, ACCEPTANCE_RADIUS_M, 10)
        await offboard_land_and_disarm(w)

    fly(scenario, 150)


async def fly_forward_in_offboard_attitude(w):
    """fly_forward_in_offboard_attitude: no position needed. A raw fix and a
    level attitude (CHECK, 20 s); attitude setpoint with no thrust, offboard
    started; armable (CHECK, 20 s), armed; 80 % thrust until the fix's
    ellipsoid altitude is 10 m above the start; 20 deg nose down at 80 % for
    3 s, then CHECK roll and pitch within 5 deg of the setpoint; level at
    40 % for 6 s; then no thrust."""
    watch_more(w)
    await w.uav.telemetry.set_rate_raw_gps(RAW_GPS_RATE_HZ * SPEED)

    def level_with_fix():
        a, g = w.attitude, w.raw_gps
        return (g is not None and a is not None and g.altitude_ellipsoid_m > 0 and abs(a.roll_deg) < 5
                and abs(a.pitch_deg) < 5)

    await check_within(w, level_with_fix, 20, "a raw fix and a level attitude")
    start_alt_m = w.raw_gps.altitude_ellipsoid_m
    attitude = Attitude(0.0, 0.0, 0.0, 0.0)
    await w.uav.offboard.set_attitude(attitude)
    await start_offboard_with_retry(w, lambda: w.uav.offboard.set_attitude(attitude))
    await check_within(w, lambda: w.armable, 20, "armable")
    await arm(w)

    climb = Attitude(0.0, 0.0, 0.0, 0.8)
    took = await stream(w, lambda: w.uav.offboard.set_attitude(climb), CLIMB_BOUND_S, "climb",
                        stop=lambda: w.raw_gps.altitude_ellipsoid_m - start_alt_m >= 10.0)
    Checks.require(w.raw_gps.altitude_ellipsoid_m - start_alt_m >= 10.0,
                   f"10 m climbed on 80 % thrust within {CLIMB_BOUND_S:.0f} s (PX4 waits without a bound)")
    print(f"climbed 10 m in {took:.1f} s of vehicle time")

    forward = Attitude(0.0, -20.0, 0.0, 0.8)
    await stream(w, lambda: w.uav.offboard.set_attitude(forward), 3, "forward")
    a = w.attitude
    print(f"after 3 s forward: roll {a.roll_deg:.2f} deg, pitch {a.pitch_deg:.2f} deg")
    w.checks.check(abs(forward.roll_deg - a.roll_deg) < 5, f"roll {a.roll_deg:.1f} deg, setpoint 0")
    w.checks.check(abs(forward.pitch_deg - a.pitch_deg) < 5, f"pitch {a.pitch_deg:.1f} deg, setpoint -20")

    descend = Attitude(0.0, 0.0, 0.0, 0.4)
    await stream(w, lambda: w.uav.offboard.set_attitude(descend), 6, "descend")
    await check_ok(w, w.uav.offboard.set_attitude(Attitude(0.0, 0.0, 0.0, 0.0)), "set_attitude (no thrust)")


def test_offboard_attitude_control():
    """PX4-Autopilot test/mavsdk_tests/test_multicopter_offboard.cpp:78 at commit
    15c4f0887da9, TEST_CASE "Offboard attitude control": COM_RCL_EXCEPT 4, then
    fly_forward_in_offboard_attitude; disarmed within 120 s."""

    async def scenario(w):
        await set_rc_loss_exception_offboard(w)
        said = len(w.texts)
        await fly_forward_in_offboard_attitude(w)
        await wait_until_disarmed(w, 120, said)
        print(f"disarmed; modes {[m.name for m in w.modes]}")

    fly(scenario, 150)


# ---------------------------------------------------------------------------
# test_multicopter_manual.cpp


async def fly_forward_in(w, start_mode, what, centred_after_arming):
    """fly_forward_in_posctl / fly_forward_in_altctl: 1 s of centred sticks
    (throttle 0.5) between each step — the mode started (CHECK), home
    stored, ready, armed (Altitude: 1 s more after arming); then 5 s of full
    throttle, 10 s of half forward pitch at mid throttle, and throttle 0
    until no longer in the air (60 s at most)."""
    watch_more(w)
    centred = sticks(w, 0.0, 0.0, 0.5, 0.0)
    await stream(w, centred, 1, "sticks centred")
    await check_ok(w, start_mode(), what)
    await stream(w, centred, 1, "sticks centred")
    await store_home(w)
    await stream(w, centred, 1, "sticks centred")
    await wait_until_ready(w)
    await stream(w, centred, 1, "sticks centred")
    await arm(w)
    # after the Action plugin's own request (see the module doc)
    await w.uav.telemetry.set_rate_in_air(EXTENDED_SYS_STATE_RATE_HZ * SPEED)
    if centred_after_arming:
        await stream(w, centred, 1, "sticks centred")
    await stream(w, sticks(w, 0.0, 0.0, 1.0, 0.0), 5, "climb")
    up_m = -w.pos.position.down_m
    await stream(w, sticks(w, 0.5, 0.0, 0.5, 0.0), 10, "forward")
    p = w.pos.position
    print(f"{what}: climbed to {up_m:.1f} m, then flew to {p.north_m:.1f} m N {p.east_m:.1f} m E "
          f"{-p.down_m:.1f} m up; modes {[m.name for m in w.modes]}")
    took = await stream(w, sticks(w, 0.0, 0.0, 0.0, 0.0), 60, "descend", stop=lambda: w.in_air is False)
    print(f"{what}: landed after {took:.1f} s of throttle down")


def fly_forward_case(start, what, centred_after_arming):
    async def scenario(w):
        said = len(w.texts)
        await fly_forward_in(w, start(w), what, centred_after_arming)
        await wait_until_disarmed(w, 180, said)
        check_home_not_within(w, 5.0)

    fly(scenario, 150)


def test_fly_forward_in_position_control():
    """PX4-Autopilot test/mavsdk_tests/test_multicopter_manual.cpp:37 at commit
    0cc4b41a5172, TEST_CASE "Fly forward in position control":
    fly_forward_in_posctl, disarmed within 180 s, more than 5 m from home."""
    fly_forward_case(lambda w: w.uav.manual_control.start_position_control, "start_position_control", False)


def test_fly_forward_in_altitude_control():
    """PX4-Autopilot test/mavsdk_tests/test_multicopter_manual.cpp:47 at commit
    0cc4b41a5172, TEST_CASE "Fly forward in altitude control":
    fly_forward_in_altctl, disarmed within 180 s, more than 5 m from home."""
    fly_forward_case(lambda w: w.uav.manual_control.start_altitude_control, "start_altitude_control", True)
