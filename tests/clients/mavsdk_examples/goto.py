#!/usr/bin/env python3
"""Reposition flight: take off, fly to a global waypoint, land on it.

The waypoint lies LEG_NORTH_M / LEG_EAST_M from home (50 m to the
north-north-west) and LEG_UP_M above it. Action.goto_location wants the
altitude above mean sea level, so the script adds LEG_UP_M to the AMSL altitude
of home as telemetry reports it. Before arming it sets the takeoff height with
Action.set_takeoff_altitude and reads it back; the reposition is sent shortly
after the takeoff command, while the vehicle is still climbing.

Checks: arrival within ARRIVE_H_M horizontally and ARRIVE_V_M vertically, the
vehicle in HOLD facing LEG_YAW_DEG, a touchdown within ARRIVE_H_M of the
waypoint, and an automatic disarm.
"""

import math

from mavsdk.telemetry import FlightMode

from common import (
    M_PER_DEG_LAT,
    bail,
    bring_up,
    echo_status_text,
    expect_mode,
    ground_gap_m,
    heading_gap_deg,
    launch,
    next_matching,
    pause,
    sample,
    touchdown,
)

TAKEOFF_M = 4.0
LEG_NORTH_M = 40.0
LEG_EAST_M = -30.0
LEG_UP_M = 15.0
LEG_YAW_DEG = 300.0
ARRIVE_H_M = 1.5
ARRIVE_V_M = 0.5


async def main():
    uav = await bring_up()
    echo_status_text(uav)

    home = await sample(uav.telemetry.home(), "home position", 10)
    print(f"[goto] home {home.latitude_deg:.7f} {home.longitude_deg:.7f}, {home.absolute_altitude_m:.2f} m AMSL")
    wp_lat = home.latitude_deg + LEG_NORTH_M / M_PER_DEG_LAT
    wp_lon = home.longitude_deg + LEG_EAST_M / (M_PER_DEG_LAT * math.cos(math.radians(home.latitude_deg)))
    wp_amsl = home.absolute_altitude_m + LEG_UP_M

    await uav.action.set_takeoff_altitude(TAKEOFF_M)
    readback = await uav.action.get_takeoff_altitude()
    if abs(readback - TAKEOFF_M) > 1e-4:
        bail(f"takeoff height reads back as {readback}, not {TAKEOFF_M}")

    await uav.action.arm()
    print("[goto] armed")
    await uav.action.takeoff()
    print(f"[goto] climbing to {TAKEOFF_M} m")
    await pause(uav, 1.0)

    print(f"[goto] waypoint {wp_lat:.7f} {wp_lon:.7f}, {wp_amsl:.2f} m AMSL, heading {LEG_YAW_DEG}")
    await uav.action.goto_location(wp_lat, wp_lon, wp_amsl, LEG_YAW_DEG)

    def arrived(p):
        return (
            ground_gap_m(p.latitude_deg, p.longitude_deg, wp_lat, wp_lon) < ARRIVE_H_M
            and abs(p.absolute_altitude_m - wp_amsl) < ARRIVE_V_M
        )

    there = await next_matching(uav.telemetry.position(), arrived, 60, "arrival at the waypoint")
    print(f"[goto] arrived: {there.latitude_deg:.7f} {there.longitude_deg:.7f}, {there.absolute_altitude_m:.2f} m AMSL")
    await expect_mode(uav, FlightMode.HOLD)
    facing = await next_matching(
        uav.telemetry.attitude_euler(),
        lambda a: heading_gap_deg(a.yaw_deg, LEG_YAW_DEG) < 5.0,
        20,
        f"heading {LEG_YAW_DEG}",
    )
    print(f"[goto] heading {facing.yaw_deg:.1f} deg")

    await uav.action.land()
    print("[goto] landing at the waypoint")
    await touchdown(uav, 60)
    down = await sample(uav.telemetry.position(), "position")
    miss = ground_gap_m(down.latitude_deg, down.longitude_deg, wp_lat, wp_lon)
    print(f"[goto] touched down {miss:.2f} m from the waypoint")
    if miss > ARRIVE_H_M:
        bail(f"touched down {miss:.2f} m from the waypoint")


if __name__ == "__main__":
    launch(main)
