"""PX4's multicopter sensor-failsafe integration tests, re-expressed with
MAVSDK-Python 3.x (a real MAVSDK 3 core in mavsdk_server) against the
rotorpilot binary flying on its navigation filter (RP_NAV_SRC 1, preset in
the state directory with the filter's height reference EKF2_HGT_REF, both
read at boot).

PX4's steps, parameters and timeouts, from its MAVSDK tests
(test/mavsdk_tests/test_multicopter_failsafe.cpp, the eight TEST_CASEs, and
the AutopilotTester helpers they call in autopilot_tester.cpp):

* set the height source (EKF2_HGT_REF 0 barometer, 1 GNSS) where the case
  names one; wait until ready (health all ok within 30 s, then armable
  within 45 s);
* a square mission: 20 m north, 20 m north and east, 20 m east, each at
  10 m above home, stopping at each (not fly-through), return to launch
  after the mission; upload, then 1 s for the vehicle to take it in;
* arm (retried for up to 30 s);
* SYS_FAILURE_EN 1, start the mission, wait (60 s) until the mission's
  current item is at least 1, then inject the failure (instance 0);
* GPS off: nothing more, the vehicle must land and disarm within 30 s;
  mag or baro off or stuck: the mission must finish (90 s; 120 s for a stuck
  magnetometer), and the vehicle disarm after its return (90 s; 120 s for a
  lost magnetometer).

PX4 measures these timeouts on the autopilot's clock (the time stamp of
its attitude), so they are simulated seconds here too, taken from the
attitude's time stamp; each wait also has a wall-clock bound, so a stalled
vehicle fails the test rather than hangs it. The vehicle runs at 10x, as
PX4's CI runs these tests. Beyond PX4's checks each test names the
injection the vehicle announced, and prints (the ground truth, asked for
as PX4's tests ask for it) where and when the vehicle landed.

Run with the mavsdk<4 venv: `python -m pytest tests/clients/test_mavsdk3_px4_failsafe.py`.
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

import common  # noqa: E402
from mavsdk import System  # noqa: E402
from mavsdk.action import ActionError  # noqa: E402
from mavsdk.failure import FailureType, FailureUnit  # noqa: E402
from mavsdk.mission import MissionItem, MissionPlan  # noqa: E402
from mavsdk.telemetry import FlightMode  # noqa: E402

SPEED = 10.0
M_PER_DEG = common.M_PER_DEG_LAT
# EKF2_HGT_REF, as AutopilotTester::set_height_source sets it
BARO, GNSS = 0, 1
HEIGHT = {BARO: "baro height mode", GNSS: "GPS height mode"}
# a wall-clock allowance over a wait's simulated seconds at SPEED: a loaded
# machine may run the simulation at a fraction of the speed asked
WALL_SLACK = 4.0
WALL_EXTRA_S = 15.0


def at(home, north, east):
    """Latitude and longitude `north`, `east` metres from `home` (a local
    tangent plane, as MAVSDK's CoordinateTransformation for 20 m legs)."""
    lat = home.latitude_deg + north / M_PER_DEG
    return lat, home.longitude_deg + east / (M_PER_DEG * math.cos(math.radians(home.latitude_deg)))


def north_east_m(home, lat, lon):
    n = (lat - home.latitude_deg) * M_PER_DEG
    e = (lon - home.longitude_deg) * M_PER_DEG * math.cos(math.radians(home.latitude_deg))
    return n, e


def square_item(lat, lon):
    """A mission item as AutopilotTester::create_mission_item makes one with
    PX4's MissionOptions (10 m above home, not fly-through); every other
    field at MAVSDK's default (speed and acceptance radius unset)."""
    nan = float("nan")
    return MissionItem(lat, lon, 10.0, nan, False, nan, nan, MissionItem.CameraAction.NONE, nan, 1.0, nan, nan, nan,
                       MissionItem.VehicleAction.NONE)


class Watch:
    """What the vehicle reports, kept current by background subscriptions:
    its clock (the attitude's time stamp, simulated seconds), mission
    progress, armed, flight modes seen, health, status texts and the
    ground truth. `until` is PX4's poll_condition_with_timeout: a condition
    polled until it holds or `sim_s` of the vehicle's time have gone by."""

    def __init__(self, uav):
        self.uav = uav
        self.now_s = None
        self.progress = (0, 0)
        self.armed = None
        self.modes = []
        self.all_ok = False
        self.armable = False
        self.texts = []
        self.truth = None
        self.rel_alt_m = None
        self.tasks = []

    def start(self):
        t = self.uav.telemetry

        def keep(stream, f):
            async def run():
                async for x in stream:
                    f(x)

            self.tasks.append(asyncio.ensure_future(run()))

        keep(t.attitude_euler(), lambda a: setattr(self, "now_s", a.timestamp_us / 1e6))
        keep(self.uav.mission.mission_progress(), lambda p: setattr(self, "progress", (p.current, p.total)))
        keep(t.armed(), lambda a: setattr(self, "armed", a))
        keep(t.flight_mode(), lambda m: self.modes.append(m) if not self.modes or self.modes[-1] != m else None)
        keep(t.health_all_ok(), lambda ok: setattr(self, "all_ok", ok))
        keep(t.health(), lambda h: setattr(self, "armable", h.is_armable))
        keep(t.status_text(), lambda s: self.texts.append(s.text))
        keep(t.ground_truth(), lambda g: setattr(self, "truth", g))
        keep(t.position(), lambda p: setattr(self, "rel_alt_m", p.relative_altitude_m))
        return self

    async def stop(self):
        """Cancel the subscriptions, waiting at most 5 s for them: a gRPC
        stream can sit out a cancellation, and a test that passed must not
        hang in its teardown. Stop mavsdk_server first (`fly`), so that every
        stream ends with its connection."""
        for task in self.tasks:
            task.cancel()
        if self.tasks:
            await asyncio.wait(self.tasks, timeout=5.0)

    async def until(self, cond, sim_s, what, late=AssertionError):
        """Wait until `cond()` holds, at most `sim_s` seconds of vehicle time
        (and a wall-clock bound beyond it; `late` is raised when the vehicle
        time runs out); returns the vehicle seconds it took."""
        wall_end = time.monotonic() + WALL_EXTRA_S + WALL_SLACK * sim_s / SPEED
        while self.now_s is None:
            if time.monotonic() > wall_end:
                raise AssertionError(f"no attitude (the vehicle's clock) while waiting for {what}")
            await asyncio.sleep(0.02)
        start = self.now_s
        while not cond():
            if self.now_s - start > sim_s:
                raise late(f"no {what} within {sim_s:.0f} s of vehicle time")
            if time.monotonic() > wall_end:
                raise AssertionError(f"no {what} within {wall_end - time.monotonic() + WALL_EXTRA_S:.0f} s of wall "
                                     f"time (only {self.now_s - start:.1f} s of vehicle time went by)")
            await asyncio.sleep(0.02)
        return self.now_s - start

    def said(self, fragment):
        return any(fragment in t for t in self.texts)


async def wait_until_ready(w):
    await w.until(lambda: w.all_ok, 30, "health all ok")
    await w.until(lambda: w.armable, 45, "armable")


async def prepare_square_mission(uav):
    home = await common.sample(uav.telemetry.home(), "home", 10)
    corners = [(20.0, 0.0), (20.0, 20.0), (0.0, 20.0)]
    await uav.mission.set_return_to_launch_after_mission(True)
    await uav.mission.upload_mission(MissionPlan([square_item(*at(home, n, e)) for n, e in corners]))
    # PX4's tests give the vehicle a second to take the mission in
    await asyncio.sleep(1.0)
    return home


async def arm(w):
    """Arm, retried until accepted for up to 30 s of vehicle time (the
    arming check may flicker just after the vehicle is ready)."""
    first_s, last = w.now_s, None
    wall_end = time.monotonic() + WALL_EXTRA_S + WALL_SLACK * 30 / SPEED
    while True:
        try:
            await w.uav.action.arm()
            return
        except ActionError as e:
            last = e
        if w.now_s - first_s > 30 or time.monotonic() > wall_end:
            raise AssertionError(f"arming refused for 30 s of vehicle time: {last}")
        await asyncio.sleep(0.1)


async def start_and_wait_for_mission_sequence(w, sequence):
    await w.uav.mission.start_mission()
    await w.until(lambda: w.progress[0] >= sequence, 60, f"mission item {sequence}")


async def inject_after_first_item(w, unit, kind):
    """SYS_FAILURE_EN 1, the mission started and at item 1, then the failure (instance 0)."""
    await w.uav.param.set_param_int("SYS_FAILURE_EN", 1)
    await start_and_wait_for_mission_sequence(w, 1)
    await w.uav.failure.inject(unit, kind, 0)
    return w.now_s, w.truth


async def wait_for_mission_finished(w, sim_s):
    await w.until(lambda: w.progress[1] > 0 and w.progress[0] == w.progress[1], sim_s, "mission finished")
    assert await w.uav.mission.is_mission_finished()


def fly(params, scenario, wall_limit):
    """Boot a vehicle on the filter with `params`, run `scenario(watch)`
    against a fresh mavsdk_server within `wall_limit` s; the server and the
    vehicle are stopped whatever happens."""
    with Vehicle(speed=SPEED, params=params) as v:

        async def main():
            uav = System(port=free_tcp_port())
            await uav.connect(system_address=f"udpin://0.0.0.0:{v.api_port}")
            w = Watch(uav)
            try:
                await common.next_matching(uav.core.connection_state(), lambda c: c.is_connected, 20, "heartbeat")
                await uav.telemetry.set_rate_ground_truth(10.0)
                w.start()
                return await asyncio.wait_for(scenario(w), wall_limit)
            finally:
                uav._stop_mavsdk_server()
                await w.stop()

        return asyncio.run(main())


def boot_params(height):
    """The navigation filter, with the height reference a case names (read at boot)."""
    params = {"RP_NAV_SRC": 1}
    if height is not None:
        params["EKF2_HGT_REF"] = height
    return params


async def set_height_source(w, height):
    """As PX4's test sets it; the vehicle reads it at boot, where it was preset."""
    if height is not None:
        await w.uav.param.set_param_int("EKF2_HGT_REF", height)
        assert await w.uav.param.get_param_int("EKF2_HGT_REF") == height


def report(what, w, lost_at, truth_at_loss, home):
    """Print when (after the injection) and where the vehicle disarmed;
    returns where, metres north and east of home (the ground truth)."""
    n, e = north_east_m(home, w.truth.latitude_deg, w.truth.longitude_deg)
    n0, e0 = north_east_m(home, truth_at_loss.latitude_deg, truth_at_loss.longitude_deg)
    up0 = truth_at_loss.absolute_altitude_m - home.absolute_altitude_m
    print(f"{what}: injected at {n0:.1f} m N {e0:.1f} m E {up0:.1f} m up; disarmed {w.now_s - lost_at:.1f} s of "
          f"vehicle time later at {n:.1f} m N {e:.1f} m E; modes {[m.name for m in w.modes]}")
    return n, e


class StillArmed(AssertionError):
    """On the ground, the vehicle has not disarmed in time."""


@pytest.mark.parametrize("height", [BARO, GNSS], ids=["baro", "gps"])
def test_land_on_gps_lost_during_mission(height):
    """PX4-Autopilot test/mavsdk_tests/test_multicopter_failsafe.cpp, TEST_CASEs
    "Land on GPS lost during mission (baro height mode)" and "Land on GPS
    lost during mission (GPS height mode)": the GPS off once the mission is at
    item 1; with no position aiding left the vehicle descends (PX4's
    Descend, AUTO.LAND on the wire), the mission unfinished, and disarms
    within 30 s of vehicle time of the loss. The touchdown (the ground
    truth back at its resting altitude) is checked on the way, within the
    same 30 s."""

    async def scenario(w):
        await set_height_source(w, height)
        await wait_until_ready(w)
        await w.until(lambda: w.truth is not None, 5, "ground truth")
        ground_m = w.truth.absolute_altitude_m
        home = await prepare_square_mission(w.uav)
        await arm(w)
        lost_at, truth = await inject_after_first_item(w, FailureUnit.SENSOR_GPS, FailureType.OFF)
        said_before = len(w.texts)
        await w.until(lambda: w.truth.absolute_altitude_m - ground_m < 0.05, 30, "touchdown (ground truth)")
        down_s = w.now_s - lost_at
        print(f"GPS lost ({HEIGHT[height]}): on the ground {down_s:.1f} s of vehicle time after the loss")
        assert w.said("CMD_INJECT_FAILURE, GPS off"), w.texts
        assert FlightMode.LAND in w.modes, w.modes
        assert w.progress[0] < w.progress[1], f"the mission went on: {w.progress}"
        # MAVSDK reads `armed` from HEARTBEAT, which rotorpilot sends once a
        # second of wall time: at 10x that is up to 10 s of vehicle time late
        # (PX4 SITL's heartbeat runs on the simulated clock); the disarm's own
        # STATUSTEXT ("Disarmed by landing") comes at once
        try:
            await w.until(lambda: w.armed is False or any("Disarmed" in t for t in w.texts[said_before:]),
                          30 - down_s, "disarm", late=StillArmed)
        except StillArmed as e:
            raise StillArmed(f"{e}: on the ground {down_s:.1f} s after the GPS loss, still armed 30 s after it in "
                             f"{w.modes[-1].name}, estimated height {w.rel_alt_m:.2f} m above home") from None
        report(f"GPS lost ({HEIGHT[height]})", w, lost_at, truth, home)

    fly(boot_params(height), scenario, 150)


def continue_after(height, unit, kind, announced, finish_s, disarm_s, what):
    async def scenario(w):
        await set_height_source(w, height)
        await wait_until_ready(w)
        home = await prepare_square_mission(w.uav)
        await arm(w)
        lost_at, truth = await inject_after_first_item(w, unit, kind)
        await wait_for_mission_finished(w, finish_s)
        await w.until(lambda: w.armed is False, disarm_s, "disarm after the return")
        n, e = report(what, w, lost_at, truth, home)
        assert w.said(f"CMD_INJECT_FAILURE, {announced}"), w.texts
        assert FlightMode.RETURN_TO_LAUNCH in w.modes, w.modes
        assert math.hypot(n, e) < 3.0, f"landed {n:.1f} m N {e:.1f} m E of home"

    fly(boot_params(height), scenario, 240)


def test_continue_on_mag_lost_during_mission():
    """PX4-Autopilot test/mavsdk_tests/test_multicopter_failsafe.cpp, TEST_CASE
    "Continue on mag lost during mission": the magnetometer off at item 1
    (height source left at its default); the mission finishes within 90 s
    and the vehicle returns and disarms within 120 s of vehicle time."""
    continue_after(None, FailureUnit.SENSOR_MAG, FailureType.OFF, "mag off", 90, 120, "mag lost")


def test_continue_on_mag_stuck_during_mission():
    """PX4-Autopilot test/mavsdk_tests/test_multicopter_failsafe.cpp, TEST_CASE
    "Continue on mag stuck during mission": the magnetometer stuck at item 1;
    the mission finishes within 120 s and the vehicle returns and disarms
    within 90 s of vehicle time."""
    continue_after(None, FailureUnit.SENSOR_MAG, FailureType.STUCK, "mag stuck", 120, 90, "mag stuck")


@pytest.mark.parametrize("height", [BARO, GNSS], ids=["baro", "gps"])
def test_continue_on_baro_lost_during_mission(height):
    """PX4-Autopilot test/mavsdk_tests/test_multicopter_failsafe.cpp, TEST_CASEs
    "Continue on baro lost during mission (baro height mode)" and "Continue
    on baro lost during mission (GPS height mode)": the barometer off at
    item 1; the mission finishes within 90 s and the vehicle returns and
    disarms within 90 s of vehicle time."""
    continue_after(height, FailureUnit.SENSOR_BARO, FailureType.OFF, "baro off", 90, 90,
                   f"baro lost ({HEIGHT[height]})")


@pytest.mark.parametrize("height", [BARO, GNSS], ids=["baro", "gps"])
def test_continue_on_baro_stuck_during_mission(height):
    """PX4-Autopilot test/mavsdk_tests/test_multicopter_failsafe.cpp, TEST_CASEs
    "Continue on baro stuck during mission (baro height mode)" and "Continue
    on baro stuck during mission (GPS height mode)": the barometer stuck at
    item 1; the mission finishes within 90 s and the vehicle returns and
    disarms within 90 s of vehicle time."""
    continue_after(height, FailureUnit.SENSOR_BARO, FailureType.STUCK, "baro stuck", 90, 90,
                   f"baro stuck ({HEIGHT[height]})")
