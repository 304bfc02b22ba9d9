#!/usr/bin/env python3
"""MAVSDK-Python examples/takeoff_and_land.py, plus checks that it flew."""

import asyncio

from mavsdk import System

from common import GRPC_PORT, URL, sleep, wait_until


async def run():
    drone = System(port=GRPC_PORT)
    await drone.connect(system_address=URL)

    status_text_task = asyncio.ensure_future(print_status_text(drone))

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

    print("-- Arming")
    await drone.action.arm()

    print("-- Taking off")
    await drone.action.takeoff()
    await wait_until(drone.telemetry.in_air(), lambda a: a, 20, "in air")

    await sleep(10)
    pos = await wait_until(drone.telemetry.position(), lambda p: True, 5, "position")
    print(f"-- Relative altitude {pos.relative_altitude_m:.2f} m")
    assert 2.0 < pos.relative_altitude_m < 3.0, pos

    print("-- Landing")
    await drone.action.land()
    await wait_until(drone.telemetry.in_air(), lambda a: not a, 40, "landed")
    await wait_until(drone.telemetry.armed(), lambda a: not a, 20, "disarmed")
    print("-- Landed and disarmed")

    status_text_task.cancel()


async def print_status_text(drone):
    try:
        async for status_text in drone.telemetry.status_text():
            print(f"Status: {status_text.type}: {status_text.text}")
    except asyncio.CancelledError:
        return


if __name__ == "__main__":
    asyncio.run(run())
