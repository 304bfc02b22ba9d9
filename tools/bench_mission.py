#!/usr/bin/env python3
"""Measure rotorpilot's mission protocol and a mission flown at 20x, on
loopback, against a vehicle it starts itself (the release binary):

1. upload and download of 100, 1,000 and 10,000 mission items with pymavlink
   (MISSION_COUNT / MISSION_REQUEST_INT / MISSION_ITEM_INT one at a time, as a
   ground-station script does; tests/clients/mission_link.py);
2. the same with MAVSDK 3's MissionRaw (mavsdk_server), when `mavsdk<4` is
   importable;
3. a five-waypoint mission (tools/missions/five-waypoints.txt's waypoints,
   return to launch after) flown through MAVSDK's Mission plugin at --speed 20:
   wall time from start_mission to is_mission_finished, and the simulated
   time it covered.

    cargo build --release
    python3 tools/bench_mission.py                     # pymavlink only
    .venv/mavsdk3/bin/python tools/bench_mission.py    # + MAVSDK (tools/test-all.sh makes that venv)

Needs pymavlink 2.4.50. Not run in CI. Options: --sizes 100,1000,10000,
--repeat N (best of N per size), --no-flight.
"""

import argparse
import asyncio
import statistics
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests" / "clients"))
import mission_link as ml  # noqa: E402
from harness import Vehicle, free_tcp_port  # noqa: E402

HOME = (47.397742, 8.545594)
FIVE = REPO / "tools" / "missions" / "five-waypoints.txt"


def bench_pymavlink(v, sizes, repeat):
    c = ml.Client(f"udpout:127.0.0.1:{v.gcs_bind}")
    rows = []
    for n in sizes:
        items = ml.survey(n, HOME)
        ups, downs = [], []
        for _ in range(repeat):
            t = time.perf_counter()
            result = c.upload(items, budget=600)
            ups.append(time.perf_counter() - t)
            if result != ml.ACCEPTED:
                raise SystemExit(f"pymavlink upload of {n} items: MISSION_ACK {result}")
            t = time.perf_counter()
            got = c.download(timeout=600)
            downs.append(time.perf_counter() - t)
            diff = ml.plan_difference(items, got)
            if diff:
                raise SystemExit(f"pymavlink download of {n} items differs: {diff}")
        rows.append(("pymavlink", n, min(ups), min(downs)))
    c.close()
    return rows


async def mavsdk_session(v, body):
    from mavsdk import System

    uav = System(port=free_tcp_port())
    await uav.connect(system_address=f"udpin://0.0.0.0:{v.api_port}")
    try:
        async for state in uav.core.connection_state():
            if state.is_connected:
                break
        return await body(uav)
    finally:
        uav._stop_mavsdk_server()


def bench_mavsdk(v, sizes, repeat):
    from mavsdk.mission_raw import MissionItem as RawItem

    async def body(uav):
        rows = []
        for n in sizes:
            items = [RawItem(k, it.frame, it.command, 1 if k == 0 else 0, 1, it.p1, it.p2, it.p3, it.p4,
                             round(it.x * 1e7), round(it.y * 1e7), it.z, 0)
                     for k, it in enumerate(ml.survey(n, HOME))]
            ups, downs = [], []
            for _ in range(repeat):
                t = time.perf_counter()
                await uav.mission_raw.upload_mission(items)
                ups.append(time.perf_counter() - t)
                t = time.perf_counter()
                got = await uav.mission_raw.download_mission()
                downs.append(time.perf_counter() - t)
                if len(got) != n or (got[-1].x, got[-1].y) != (items[-1].x, items[-1].y):
                    raise SystemExit(f"MAVSDK download of {n} items differs")
            rows.append(("MAVSDK 3 mission_raw", n, min(ups), min(downs)))
        return rows

    return asyncio.run(mavsdk_session(v, body))


def five_waypoints():
    """The waypoints of tools/missions/five-waypoints.txt (its takeoff and RTL
    items are what MAVSDK's Mission plugin adds or does itself)."""
    pts = []
    for line in FIVE.read_text().splitlines():
        f = line.split()
        if len(f) == 12 and f[3] == "16":
            pts.append((float(f[8]), float(f[9]), float(f[10])))
    return pts


def bench_flight(v):
    from mavsdk.mission import MissionItem, MissionPlan

    nan = float("nan")
    plan = MissionPlan([
        MissionItem(lat, lon, alt, nan, True, nan, nan, MissionItem.CameraAction.NONE, nan, 1.0, nan, nan, nan,
                    MissionItem.VehicleAction.NONE)
        for lat, lon, alt in five_waypoints()])

    async def body(uav):
        async for h in uav.telemetry.health():
            if h.is_global_position_ok and h.is_home_position_ok and h.is_armable:
                break
        await uav.mission.set_return_to_launch_after_mission(True)
        await uav.mission.upload_mission(plan)
        await uav.action.arm()
        sim0 = await sim_time(uav)
        t = time.perf_counter()
        await uav.mission.start_mission()
        while not await uav.mission.is_mission_finished():
            if time.perf_counter() - t > 120:
                raise SystemExit("the mission did not finish in 120 s")
            await asyncio.sleep(0.01)
        wall = time.perf_counter() - t
        sim = await sim_time(uav) - sim0
        async for flying in uav.telemetry.in_air():
            if not flying:
                break
        down = time.perf_counter() - t
        return wall, sim, down

    return asyncio.run(mavsdk_session(v, body))


async def sim_time(uav):
    async for a in uav.telemetry.attitude_euler():
        return a.timestamp_us / 1e6


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="100,1000,10000")
    ap.add_argument("--repeat", type=int, default=3, help="best of N per size (default 3)")
    ap.add_argument("--no-flight", action="store_true")
    args = ap.parse_args()
    sizes = [int(s) for s in args.sizes.split(",")]
    try:
        import mavsdk  # noqa: F401
        from mavsdk import System  # noqa: F401

        have_mavsdk = callable(System)
    except Exception:  # mavsdk 4.x has no System; no mavsdk at all is fine too
        have_mavsdk = False

    rows = []
    with Vehicle(speed=1.0, extra=["--reset-params"]) as v:
        rows += bench_pymavlink(v, sizes, args.repeat)
        if have_mavsdk:
            rows += bench_mavsdk(v, sizes, args.repeat)
    print(f"\nmission transfer on loopback (best of {args.repeat}; vehicle at 1x)")
    print(f"{'client':<22} {'items':>7} {'upload s':>9} {'download s':>11} {'up items/s':>11} {'down items/s':>13}")
    for who, n, up, down in rows:
        print(f"{who:<22} {n:>7} {up:>9.3f} {down:>11.3f} {n / up:>11.0f} {n / down:>13.0f}")
    if not have_mavsdk:
        print("(MAVSDK rows and the flight need mavsdk<4: run with .venv/mavsdk3/bin/python)")
        return
    if not args.no_flight:
        walls = []
        for _ in range(3):
            with Vehicle(speed=20.0) as v:
                walls.append(bench_flight(v))
        print("\nfive-waypoint mission (five-waypoints.txt, RTL after) over MAVSDK 3 at --speed 20")
        for wall, sim, down in walls:
            print(f"  start_mission -> is_mission_finished: {wall:.2f} s wall, {sim:.1f} s simulated "
                  f"({sim / wall:.1f}x); on the ground {down:.2f} s after start")
        print(f"  median wall time to finished: {statistics.median(w for w, _, _ in walls):.2f} s")


if __name__ == "__main__":
    main()
