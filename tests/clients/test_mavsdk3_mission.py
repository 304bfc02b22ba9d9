"""Missions with MAVSDK-Python 3.x (the gRPC API, a real MAVSDK 3 core in
mavsdk_server) against the rotorpilot binary: the mission example script,
the Mission plugin (upload with speed changes and return to launch, flying,
progress, finished, pause and resume, set current, download), the Geofence
plugin, and MissionRaw (rally points, a QGroundControl .plan imported and
flown). Every wait is bounded by MAVSDK's own timeouts and ours.

Run with the mavsdk<4 venv (it also holds pymavlink, used here only to clear
rally points, which MAVSDK 3 has no call for):
`python -m pytest tests/clients/test_mavsdk3_mission.py`.
"""

import asyncio
import math
import sys
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE / "mavsdk_examples"))
from harness import Vehicle  # noqa: E402
from test_mavsdk3 import free_tcp_port, run_script  # noqa: E402

import common  # noqa: E402  (mavsdk_examples/common.py: next_matching, sample, pause)
from mavsdk import System  # noqa: E402
from mavsdk.geofence import Circle, FenceType, GeofenceData, Point, Polygon  # noqa: E402
from mavsdk.mission import MissionItem, MissionPlan  # noqa: E402
from mavsdk.mission_raw import MissionItem as RawItem  # noqa: E402
from mavsdk.telemetry import FlightMode  # noqa: E402

FAST = 20.0
PLAN = HERE.parents[1] / "tools" / "missions" / "home-square.plan"
M_PER_DEG = common.M_PER_DEG_LAT
# a short RTL for the flights: climb to 10 m, not PX4 SITL's 30 m
SHORT_RTL = {"RTL_RETURN_ALT": 10.0, "RTL_DESCEND_ALT": 10.0}


def fly(vehicle, scenario, wall_limit):
    """Run `scenario(uav, vehicle)` against a fresh mavsdk_server on the
    vehicle's API link, within `wall_limit` seconds; the server is stopped
    after, whatever happened."""

    async def main():
        uav = System(port=free_tcp_port())
        await uav.connect(system_address=f"udpin://0.0.0.0:{vehicle.api_port}")
        try:
            await common.next_matching(uav.core.connection_state(), lambda c: c.is_connected, 20, "heartbeat")
            await asyncio.wait_for(scenario(uav, vehicle), wall_limit)
        finally:
            uav._stop_mavsdk_server()

    asyncio.run(main())


async def ready(uav):
    await common.next_matching(
        uav.telemetry.health(), lambda h: h.is_global_position_ok and h.is_home_position_ok and h.is_armable, 20,
        "health")
    return await common.sample(uav.telemetry.home(), "home", 10)


def at(home, north, east):
    """Latitude and longitude `north`, `east` metres from `home`."""
    lat = home.latitude_deg + north / M_PER_DEG
    return lat, home.longitude_deg + east / (M_PER_DEG * math.cos(math.radians(home.latitude_deg)))


def gap_m(p, lat, lon):
    return common.ground_gap_m(p.latitude_deg, p.longitude_deg, lat, lon)


def item(lat, lon, alt, speed, fly_through=True, accept=2.0):
    """A waypoint; the optional fields as MAVSDK reads them back (the photo
    interval has no MAVLink item without a camera action, and reads back as 1)."""
    nan = float("nan")
    return MissionItem(lat, lon, alt, speed, fly_through, nan, nan, MissionItem.CameraAction.NONE, nan, 1.0, accept,
                       nan, nan, MissionItem.VehicleAction.NONE)


def same(a, b):
    return (isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b)) or a == b


def mission_difference(sent, got):
    """None if the downloaded mission items are the uploaded ones, else what
    differs (positions to 1e-7 degrees, the resolution of MISSION_ITEM_INT)."""
    if len(sent) != len(got):
        return f"{len(got)} items, not {len(sent)}"
    for k, (a, b) in enumerate(zip(sent, got)):
        for f in vars(a):
            x, y = getattr(a, f), getattr(b, f)
            if f in ("latitude_deg", "longitude_deg"):
                ok = abs(x - y) < 1.01e-7
            elif isinstance(x, float):
                ok = same(x, y) or (not math.isnan(x) and abs(x - y) < 1e-4)
            else:
                ok = x == y
            if not ok:
                return f"item {k}: {f} {x!r} != {y!r}"
    return None


def raw_difference(sent, got):
    if len(sent) != len(got):
        return f"{len(got)} items, not {len(sent)}"
    for k, (a, b) in enumerate(zip(sent, got)):
        for f in ("seq", "frame", "command", "autocontinue", "param1", "param2", "param3", "param4", "x", "y", "z",
                  "mission_type"):
            if not same(getattr(a, f), getattr(b, f)):
                return f"item {k}: {f} {getattr(a, f)!r} != {getattr(b, f)!r}"
    return None


async def until(cond, wall_limit, what):
    for _ in range(int(wall_limit / 0.02)):
        if cond():
            return
        await asyncio.sleep(0.02)
    raise AssertionError(f"no {what} within {wall_limit} s")


async def collect_progress(uav, seen):
    async for p in uav.mission.mission_progress():
        seen.append((p.current, p.total))


async def track(uav, samples, progress):
    """(mission progress current, ground speed, position) at every velocity report."""
    async for pv in uav.telemetry.position_velocity_ned():
        v = pv.velocity
        samples.append((progress[-1][0] if progress else -1, math.hypot(v.north_m_s, v.east_m_s)))


@pytest.mark.parametrize("speed", [FAST])
def test_mission_example_script(speed):
    """mission.py: three waypoints at 25 m and 10 m/s, RTL, back on the ground."""
    with Vehicle(speed=speed) as v:
        out = run_script("mission.py", v, timeout=120)
        assert "[mission] progress 3/3" in out


@pytest.mark.parametrize("speed", [1.0, FAST], ids=["x1", "x20"])
def test_three_waypoints_with_speed_changes_and_rtl(speed):
    """Upload three waypoints (8 m/s, then 3 m/s, then 5 m/s) with return to
    launch after the mission; read it back equal; fly it: each leg at its
    speed, progress through every item, finished, back on the ground at home,
    disarmed."""

    async def scenario(uav, v):
        home = await ready(uav)
        wps = [at(home, 15, 0), at(home, 15, 30), at(home, 0, 30)]
        speeds = [8.0, 3.0, 5.0]
        plan = MissionPlan([item(*wp, 8.0, s) for wp, s in zip(wps, speeds)])
        await uav.mission.set_return_to_launch_after_mission(True)
        await uav.mission.upload_mission(plan)
        got = await uav.mission.download_mission()
        assert mission_difference(plan.mission_items, got.mission_items) is None
        assert await uav.mission.get_return_to_launch_after_mission()
        assert not await uav.mission.is_mission_finished()

        # velocity reports at 50 Hz of wall time: enough samples per leg at 20x too
        await uav.telemetry.set_rate_position_velocity_ned(50.0)
        progress, samples = [], []
        tasks = [asyncio.ensure_future(collect_progress(uav, progress)),
                 asyncio.ensure_future(track(uav, samples, progress))]
        await uav.action.arm()
        await uav.mission.start_mission()
        if speed == 1.0:
            # at 20x the whole mission lasts about a second of wall time: the
            # 1 Hz heartbeat may show RTL first (start_mission's ACK was checked)
            await common.expect_mode(uav, FlightMode.MISSION, 5)
        # finished, then (RTL) down
        await common.next_matching(uav.telemetry.in_air(), bool, 30, "liftoff")

        async def finished():
            while not await uav.mission.is_mission_finished():
                await asyncio.sleep(0.1)

        await asyncio.wait_for(finished(), 30 + 120 / speed)
        await common.next_matching(uav.telemetry.in_air(), lambda f: not f, 30 + 60 / speed, "touchdown")
        await common.next_matching(uav.telemetry.armed(), lambda a: not a, 20, "disarm")
        for t in tasks:
            t.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)

        rest = await common.sample(uav.telemetry.position(), "position")
        print(f"progress {sorted(set(progress))}; landed {gap_m(rest, home.latitude_deg, home.longitude_deg):.2f} m "
              "from home")
        assert gap_m(rest, home.latitude_deg, home.longitude_deg) < 1.5
        assert progress[-1] == (3, 3)
        assert {c for c, _ in progress} >= {0, 1, 2, 3}
        # leg k (to item k + 1) is flown at item k's speed: it gets there, and
        # once the corner is behind (the second half of the leg) it keeps to it
        for leg, s in ((1, speeds[0]), (2, speeds[1])):
            ground = [g for c, g in samples if c == leg]
            top, late = max(ground), max(ground[len(ground) // 2:])
            print(f"leg {leg}: {len(ground)} samples, top {top:.2f} m/s, second half {late:.2f} m/s (set {s})")
            assert top > 0.9 * s and late < 1.1 * s, f"leg {leg}"

    with Vehicle(speed=speed, params=SHORT_RTL) as v:
        fly(v, scenario, 60 + 240 / speed)


def test_pause_resume_and_set_current():
    """At 20x: pause (Hold) just after the first waypoint stops the vehicle
    where it is; set the current item to the third (skipping the second) while
    paused; start resumes there: the second waypoint is never approached, and
    the mission finishes."""

    async def scenario(uav, v):
        home = await ready(uav)
        wps = [at(home, 20, 0), at(home, 20, 60), at(home, 60, 0)]
        plan = MissionPlan([item(*wp, 10.0, 5.0) for wp in wps])
        await uav.mission.set_return_to_launch_after_mission(True)
        await uav.mission.upload_mission(plan)
        progress = []
        watcher = asyncio.ensure_future(collect_progress(uav, progress))
        await uav.action.arm()
        await uav.mission.start_mission()
        await common.next_matching(uav.mission.mission_progress(), lambda p: p.current == 1, 60, "first waypoint")
        await uav.mission.pause_mission()
        await common.expect_mode(uav, FlightMode.HOLD, 5)
        await common.pause(uav, 4.0)
        here = await common.sample(uav.telemetry.position(), "position")
        await common.pause(uav, 3.0)
        later = await common.sample(uav.telemetry.position(), "position")
        drift = gap_m(later, here.latitude_deg, here.longitude_deg)
        print(f"paused {gap_m(here, *wps[0]):.1f} m past the first waypoint; drift over 3 s {drift:.3f} m")
        assert drift < 0.2, "holds while paused"
        assert gap_m(here, *wps[0]) < 10, "paused near the first waypoint"
        assert not await uav.mission.is_mission_finished()
        assert progress[-1][0] == 1, "progress stands still while paused"

        await uav.mission.set_current_mission_item(2)
        await until(lambda: progress[-1][0] == 2, 5, "progress at item 2")
        await uav.mission.start_mission()
        closest = math.inf

        async def finished():
            nonlocal closest
            while not await uav.mission.is_mission_finished():
                p = await common.sample(uav.telemetry.position(), "position")
                closest = min(closest, gap_m(p, *wps[1]))
                await asyncio.sleep(0.02)

        await asyncio.wait_for(finished(), 60)
        await common.next_matching(uav.telemetry.in_air(), lambda f: not f, 60, "touchdown")
        watcher.cancel()
        await asyncio.gather(watcher, return_exceptions=True)
        print(f"closest to the skipped waypoint: {closest:.1f} m; progress {progress}")
        assert closest > 25, "the skipped waypoint was not flown to"
        assert (1, 3) in progress and progress[-1] == (3, 3)

    with Vehicle(speed=FAST, params=SHORT_RTL) as v:
        fly(v, scenario, 120)


def test_geofence_upload_and_clear():
    async def scenario(uav, v):
        await ready(uav)
        home = await common.sample(uav.telemetry.home(), "home")
        corners = [at(home, n, e) for n, e in ((-80, -80), (-80, 80), (80, 80), (80, -80))]
        await uav.geofence.upload_geofence(
            GeofenceData([Polygon([Point(lat, lon) for lat, lon in corners], FenceType.INCLUSION)], []))
        raw = await uav.mission_raw.download_geofence()
        assert [(r.command, r.frame, r.param1) for r in raw] == [(5001, 5, 4.0)] * 4
        for r, (lat, lon) in zip(raw, corners):
            assert (r.x, r.y) == (round(lat * 1e7), round(lon * 1e7))
        # the mission is another plan: clearing it leaves the fence
        await uav.mission_raw.clear_mission()
        assert len(await uav.mission_raw.download_geofence()) == 4
        await uav.geofence.clear_geofence()
        assert await uav.mission_raw.download_geofence() == []

    with Vehicle(speed=5.0) as v:
        fly(v, scenario, 60)


def test_geofence_as_mavsdks_example_uploads_it():
    """MAVSDK's geofence.py example uploads its polygon together with a
    zero-radius inclusion circle at latitude 0, longitude 0 ("the circle object
    is necessary"): PX4 stores a fence circle whatever its radius
    (mavlink_mission.cpp), and a vehicle inside the polygon flies on."""
    async def scenario(uav, v):
        home = await ready(uav)
        corners = [at(home, n, e) for n, e in ((-80, -80), (-80, 80), (80, 80), (80, -80))]
        await uav.geofence.upload_geofence(GeofenceData(
            [Polygon([Point(lat, lon) for lat, lon in corners], FenceType.INCLUSION)],
            [Circle(Point(0.0, 0.0), 0.0, FenceType.INCLUSION)]))
        raw = await uav.mission_raw.download_geofence()
        assert [(r.command, r.param1) for r in raw] == [(5001, 4.0)] * 4 + [(5003, 0.0)]
        await uav.action.set_takeoff_altitude(5.0)
        await uav.action.arm()
        await uav.action.takeoff()
        await common.next_matching(uav.telemetry.in_air(), lambda f: f, 30, "in the air")
        await common.pause(uav, 8.0)
        mode = await common.sample(uav.telemetry.flight_mode(), "flight mode")
        assert mode in (FlightMode.TAKEOFF, FlightMode.HOLD), f"{mode}: the fence was breached"
        await uav.action.land()
        await common.next_matching(uav.telemetry.in_air(), lambda f: not f, 60, "touchdown")

    with Vehicle(speed=5.0) as v:
        fly(v, scenario, 90)


def test_rally_points_upload_download_and_clear():
    from pymavlink import mavutil

    async def scenario(uav, v):
        home = await ready(uav)
        points = [at(home, 30, -20), at(home, -25, 40)]
        rally = [RawItem(k, 6, 5100, 1 if k == 0 else 0, 1, 0.0, 0.0, 0.0, 0.0, round(lat * 1e7), round(lon * 1e7),
                         15.0 + k, 2) for k, (lat, lon) in enumerate(points)]
        await uav.mission_raw.upload_rally_points(rally)
        got = await uav.mission_raw.download_rallypoints()
        assert raw_difference(rally, got) is None
        # an upload of the mission leaves them
        await uav.mission.upload_mission(MissionPlan([item(*at(home, 10, 0), 10.0, 5.0)]))
        assert raw_difference(rally, await uav.mission_raw.download_rallypoints()) is None
        # MAVSDK 3 has no call to clear rally points: MISSION_CLEAR_ALL type 2 from a GCS
        gcs = mavutil.mavlink_connection(f"udpin:127.0.0.1:{v.gcs_port}", source_system=255)
        assert gcs.wait_heartbeat(timeout=5) is not None
        gcs.mav.mission_clear_all_send(gcs.target_system, 0, 2)
        ack = gcs.recv_match(type="MISSION_ACK", blocking=True, timeout=3)
        gcs.close()
        assert ack is not None and (ack.type, ack.mission_type) == (0, 2)
        assert await uav.mission_raw.download_rallypoints() == []
        assert len((await uav.mission.download_mission()).mission_items) == 1

    with Vehicle(speed=5.0) as v:
        fly(v, scenario, 60)


def test_qgroundcontrol_plan_imported_uploaded_and_flown():
    """tools/missions/home-square.plan through MissionRaw.import_qgroundcontrol_mission:
    the mission, the fence and the rally points go up and read back the same;
    the mission flies at 20x to the end, and RTL lands at the closest rally point."""

    async def scenario(uav, v):
        home = await ready(uav)
        data = await uav.mission_raw.import_qgroundcontrol_mission(str(PLAN))
        mission, fence, rally = data.mission_items, data.geofence_items, data.rally_items
        assert [i.command for i in mission] == [22, 16, 16, 16, 16, 20]
        assert len(fence) == 5 and len(rally) == 2
        await uav.mission_raw.upload_mission(mission)
        await uav.mission_raw.upload_geofence(fence)
        await uav.mission_raw.upload_rally_points(rally)
        assert raw_difference(mission, await uav.mission_raw.download_mission()) is None
        assert raw_difference(fence, await uav.mission_raw.download_geofence()) is None
        assert raw_difference(rally, await uav.mission_raw.download_rallypoints()) is None

        await uav.action.arm()
        await uav.mission_raw.start_mission()

        async def finished():
            while not await uav.mission_raw.is_mission_finished():
                await asyncio.sleep(0.1)

        await common.next_matching(uav.telemetry.in_air(), bool, 30, "liftoff")
        await asyncio.wait_for(finished(), 60)
        await common.next_matching(uav.telemetry.in_air(), lambda f: not f, 60, "touchdown")
        await common.next_matching(uav.telemetry.armed(), lambda a: not a, 20, "disarm")
        rest = await common.sample(uav.telemetry.position(), "position")
        last = mission[-2]
        last_lat, last_lon = last.x / 1e7, last.y / 1e7
        spots = [(home.latitude_deg, home.longitude_deg)] + [(r.x / 1e7, r.y / 1e7) for r in rally]
        target = min(spots, key=lambda s: common.ground_gap_m(last_lat, last_lon, *s))
        print(f"landed {gap_m(rest, *target):.2f} m from {target} (home {spots[0]})")
        assert target != spots[0], "the plan puts a rally point nearer than home"
        assert gap_m(rest, *target) < 1.5

    with Vehicle(speed=FAST, params={"RTL_RETURN_ALT": 25.0}) as v:
        fly(v, scenario, 120)
