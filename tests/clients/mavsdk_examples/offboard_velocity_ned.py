#!/usr/bin/env python3
"""MAVSDK-Python examples/offboard_velocity_ned.py, then a landing."""

import asyncio

from mavsdk import System
from mavsdk.offboard import OffboardError, VelocityNedYaw

from common import GRPC_PORT, URL, sleep, wait_until


async def run():
    """Does Offboard control using velocity NED coordinates."""

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

    print("-- Arming")
    await drone.action.arm()

    print("-- Setting initial setpoint")
    await drone.offboard.set_velocity_ned(VelocityNedYaw(0.0, 0.0, 0.0, 0.0))

    print("-- Starting offboard")
    try:
        await drone.offboard.start()
    except OffboardError as error:
        print(f"Starting offboard mode failed with error code: {error._result.result}")
        print("-- Disarming")
        await drone.action.disarm()
        raise SystemExit(1)

    print("-- Go up 2 m/s")
    await drone.offboard.set_velocity_ned(VelocityNedYaw(0.0, 0.0, -2.0, 0.0))
    await sleep(4)
    pv = await wait_until(drone.telemetry.position_velocity_ned(), lambda p: True, 5, "velocity")
    print(f"   vertical speed {pv.velocity.down_m_s:.2f} m/s")
    assert abs(pv.velocity.down_m_s + 2.0) < 0.5, pv

    print("-- Go North 2 m/s, turn to face East")
    await drone.offboard.set_velocity_ned(VelocityNedYaw(2.0, 0.0, 0.0, 90.0))
    await sleep(4)
    pv = await wait_until(drone.telemetry.position_velocity_ned(), lambda p: True, 5, "velocity")
    print(f"   north speed {pv.velocity.north_m_s:.2f} m/s")
    assert abs(pv.velocity.north_m_s - 2.0) < 0.5, pv

    print("-- Go South 2 m/s, turn to face West")
    await drone.offboard.set_velocity_ned(VelocityNedYaw(-2.0, 0.0, 0.0, 270.0))
    await sleep(4)

    print("-- Go West 2 m/s, turn to face East")
    await drone.offboard.set_velocity_ned(VelocityNedYaw(0.0, -2.0, 0.0, 90.0))
    await sleep(4)

    print("-- Go East 2 m/s")
    await drone.offboard.set_velocity_ned(VelocityNedYaw(0.0, 2.0, 0.0, 90.0))
    await sleep(4)

    print("-- Turn to face South")
    await drone.offboard.set_velocity_ned(VelocityNedYaw(0.0, 0.0, 0.0, 180.0))
    await sleep(2)

    print("-- Go down 1 m/s, turn to face North")
    await drone.offboard.set_velocity_ned(VelocityNedYaw(0.0, 0.0, 1.0, 0.0))
    await sleep(4)

    print("-- Stopping offboard")
    try:
        await drone.offboard.stop()
    except OffboardError as error:
        print(f"Stopping offboard mode failed with error code: {error._result.result}")
        raise SystemExit(1)

    print("-- Landing")
    await drone.action.land()
    await wait_until(drone.telemetry.in_air(), lambda a: not a, 60, "landed")


if __name__ == "__main__":
    asyncio.run(run())
