#!/usr/bin/env python3
"""Hop: arm, climb to the configured takeoff height, hover, come back down.

The flight uses only Action commands with their defaults (arm, takeoff, land),
the way a first MAVSDK script would. Around them it checks that the vehicle
reports itself airborne, levels off within ALT_TOL of MIS_TAKEOFF_ALT (read
through Action.get_takeoff_altitude) and switches to HOLD there, is still at
that height after hovering, touches down and disarms on its own, within
REST_TOL of home's height.
"""

import asyncio

from mavsdk.telemetry import FlightMode

from common import bail, bring_up, echo_status_text, expect_mode, launch, next_matching, pause, sample, touchdown

ALT_TOL = 0.3  # m
# m: heights after a flight, on the navigation filter, whose height moves
# over a flight (measured up to 0.71 m after landing)
REST_TOL = 1.0
HOVER_S = 10.0  # simulated seconds


async def main():
    uav = await bring_up()
    echo = echo_status_text(uav)

    target = await uav.action.get_takeoff_altitude()
    print(f"[hop] takeoff height is {target:.2f} m")

    await uav.action.arm()
    print("[hop] armed")
    await uav.action.takeoff()
    print("[hop] takeoff sent")
    await next_matching(uav.telemetry.in_air(), bool, 20, "liftoff")

    def level(p):
        return abs(p.relative_altitude_m - target) < ALT_TOL

    await next_matching(uav.telemetry.position(), level, 30, f"level-off at {target:.1f} m")
    await expect_mode(uav, FlightMode.HOLD, 20)

    await pause(uav, HOVER_S)
    here = await sample(uav.telemetry.position(), "position")
    print(f"[hop] after hovering: {here.relative_altitude_m:.2f} m above home")
    if not level(here):
        bail(f"drifted to {here.relative_altitude_m:.2f} m while hovering")

    await uav.action.land()
    print("[hop] land sent")
    await touchdown(uav, 40)
    rest = await sample(uav.telemetry.position(), "position")
    if abs(rest.relative_altitude_m) > REST_TOL:
        bail(f"on the ground but {rest.relative_altitude_m:.2f} m above home")

    echo.cancel()
    await asyncio.gather(echo, return_exceptions=True)


if __name__ == "__main__":
    launch(main)
