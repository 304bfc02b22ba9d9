#!/usr/bin/env python3
"""Survey hop: three waypoints at 25 m, flown at 10 m/s, then home.

The Mission plugin calls of MAVSDK-Python's mission example, in its order:
connect, watch mission progress and the in-air flag in the background, set
return-to-launch after the mission, upload three fly-through waypoints (no
camera or gimbal action, everything optional left NaN), wait for a position
estimate and home, arm, start the mission, and wait until the vehicle has
flown and is back on the ground.

Checks beyond the example's: every waypoint shows in the progress reports and
the last report is `total / total`, the mission reads as finished, the
vehicle came back within HOME_TOL_M of home and disarmed on its own.
"""

import asyncio

from mavsdk.mission import MissionItem, MissionPlan

from common import bail, bring_up, echo_status_text, ground_gap_m, launch, next_matching, sample

CRUISE_M_S = 10.0
ALT_M = 25.0
HOME_TOL_M = 1.5
# three corners of a 25 m by 40 m box north-west of PX4's SITL home
CORNERS = [
    (47.3980399, 8.5455725),
    (47.3980362, 8.5450146),
    (47.3978256, 8.5450093),
]


def waypoint(lat, lon):
    nan = float("nan")
    return MissionItem(
        lat, lon, ALT_M, CRUISE_M_S,
        True,  # fly through
        nan, nan,  # gimbal pitch, yaw
        MissionItem.CameraAction.NONE,
        nan, nan,  # loiter time, photo interval
        nan, nan, nan,  # acceptance radius, yaw, photo distance
        MissionItem.VehicleAction.NONE,
    )


async def follow_progress(uav, seen):
    async for p in uav.mission.mission_progress():
        print(f"[mission] progress {p.current}/{p.total}")
        seen.append((p.current, p.total))


async def until_back_down(uav):
    """Return once the vehicle has been in the air and is on the ground again."""
    flown = False
    async for in_air in uav.telemetry.in_air():
        flown = flown or in_air
        if flown and not in_air:
            return


async def main():
    uav = await bring_up(need_position=False)
    echo_status_text(uav)

    progress = []
    watcher = asyncio.ensure_future(follow_progress(uav, progress))
    landed = asyncio.ensure_future(until_back_down(uav))

    plan = MissionPlan([waypoint(lat, lon) for lat, lon in CORNERS])
    await uav.mission.set_return_to_launch_after_mission(True)
    print("[mission] uploading")
    await uav.mission.upload_mission(plan)

    await next_matching(
        uav.telemetry.health(), lambda h: h.is_global_position_ok and h.is_home_position_ok, 20, "position and home"
    )
    home = await sample(uav.telemetry.home(), "home position", 10)

    await uav.action.arm()
    print("[mission] armed, starting")
    await uav.mission.start_mission()

    try:
        await asyncio.wait_for(landed, 240)
    except asyncio.TimeoutError:
        bail("the vehicle did not fly the mission and come back down within 240 s")
    print("[mission] back on the ground")
    watcher.cancel()
    await asyncio.gather(watcher, return_exceptions=True)

    if not await uav.mission.is_mission_finished():
        bail("back on the ground but the mission is not finished")
    if not progress or progress[-1][0] != progress[-1][1] or progress[-1][1] != len(CORNERS):
        bail(f"progress ended at {progress[-1:]}, not {len(CORNERS)}/{len(CORNERS)}")
    if sorted({c for c, _ in progress if c < len(CORNERS)}) != list(range(len(CORNERS))):
        bail(f"not every waypoint showed in the progress: {progress}")
    rest = await sample(uav.telemetry.position(), "position")
    gap = ground_gap_m(rest.latitude_deg, rest.longitude_deg, home.latitude_deg, home.longitude_deg)
    if gap > HOME_TOL_M:
        bail(f"landed {gap:.2f} m from home")
    await next_matching(uav.telemetry.armed(), lambda armed: not armed, 20, "automatic disarm")
    print(f"[mission] landed {gap:.2f} m from home and disarmed")


if __name__ == "__main__":
    launch(main)
