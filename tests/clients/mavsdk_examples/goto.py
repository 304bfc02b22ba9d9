#!/usr/bin/env python3
"""MAVSDK-Python examples/goto.py, with a bounded wait instead of the endless
loop, and a landing."""

import asyncio
import math

from mavsdk import System

from common import GRPC_PORT, URL, sleep, wait_until


async def run():
    drone = System(port=GRPC_PORT)
    await drone.connect(system_address=URL)

    print("Waiting for drone to connect...")
    await wait_until(drone.core.connection_state(), lambda s: s.is_connected, 20, "connection")
    print("-- Connected to drone!")

    print("Waiting for drone to have a global position estimate...")
    await wait_until(
        drone.telemetry.health(),
        lambda h: h.is_global_position_ok and h.is_home_position_ok,
        20,
        "health",
    )
    print("-- Global position estimate OK")

    print("Fetching amsl altitude at home location....")
    home = await wait_until(drone.telemetry.home(), lambda h: True, 10, "home")
    absolute_altitude = home.absolute_altitude_m

    print("-- Arming")
    await drone.action.arm()

    print("-- Taking off")
    await drone.action.takeoff()

    await sleep(1)
    # To fly drone 20m above the ground plane
    flying_alt = absolute_altitude + 20.0
    # goto_location() takes Absolute MSL altitude
    await drone.action.goto_location(47.397606, 8.543060, flying_alt, 0)

    def near(p):
        north = (p.latitude_deg - 47.397606) * 111_195.0
        east = (p.longitude_deg - 8.543060) * 111_195.0 * math.cos(math.radians(47.397606))
        return math.hypot(north, east) < 2.0 and abs(p.absolute_altitude_m - flying_alt) < 1.0

    pos = await wait_until(drone.telemetry.position(), near, 60, "the goto target")
    print(f"-- Reached {pos.latitude_deg:.6f}, {pos.longitude_deg:.6f}, {pos.absolute_altitude_m:.1f} m")

    print("-- Landing")
    await drone.action.land()
    await wait_until(drone.telemetry.in_air(), lambda a: not a, 60, "landed")


if __name__ == "__main__":
    asyncio.run(run())
