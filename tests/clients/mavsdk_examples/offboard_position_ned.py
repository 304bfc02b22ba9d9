#!/usr/bin/env python3
"""MAVSDK-Python examples/offboard_position_ned.py, with position checks."""

import asyncio
import math

from mavsdk import System
from mavsdk.offboard import OffboardError, PositionNedYaw

from common import GRPC_PORT, URL, sleep, wait_until


async def check(drone, n, e, d, tol=0.5):
    pv = await wait_until(drone.telemetry.position_velocity_ned(), lambda p: True, 5, "position")
    p = pv.position
    err = math.dist((p.north_m, p.east_m, p.down_m), (n, e, d))
    print(f"   at {p.north_m:.2f} {p.east_m:.2f} {p.down_m:.2f} (error {err:.2f} m)")
    assert err < tol, (n, e, d, p)


async def run():
    """Does Offboard control using position NED coordinates."""

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
    await drone.offboard.set_position_ned(PositionNedYaw(0.0, 0.0, 0.0, 0.0))

    print("-- Starting offboard")
    try:
        await drone.offboard.start()
    except OffboardError as error:
        print(f"Starting offboard mode failed with error code: {error._result.result}")
        print("-- Disarming")
        await drone.action.disarm()
        raise SystemExit(1)

    print("-- Go 0m North, 0m East, -5m Down within local coordinate system")
    await drone.offboard.set_position_ned(PositionNedYaw(0.0, 0.0, -5.0, 0.0))
    await sleep(10)
    await check(drone, 0.0, 0.0, -5.0)

    print("-- Go 5m North, 0m East, -5m Down within local coordinate system, turn to face East")
    await drone.offboard.set_position_ned(PositionNedYaw(5.0, 0.0, -5.0, 90.0))
    await sleep(10)
    await check(drone, 5.0, 0.0, -5.0)
    att = await wait_until(drone.telemetry.attitude_euler(), lambda a: True, 5, "attitude")
    assert abs(att.yaw_deg - 90.0) < 5.0, att

    print("-- Go 5m North, 10m East, -5m Down within local coordinate system")
    await drone.offboard.set_position_ned(PositionNedYaw(5.0, 10.0, -5.0, 90.0))
    await sleep(15)
    await check(drone, 5.0, 10.0, -5.0)

    print("-- Go 0m North, 10m East, 0m Down within local coordinate system, turn to face South")
    await drone.offboard.set_position_ned(PositionNedYaw(0.0, 10.0, 0.0, 180.0))
    await sleep(10)
    await wait_until(drone.telemetry.in_air(), lambda a: not a, 20, "on the ground")

    print("-- Stopping offboard")
    try:
        await drone.offboard.stop()
    except OffboardError as error:
        print(f"Stopping offboard mode failed with error code: {error._result.result}")
        raise SystemExit(1)
    mode = await wait_until(drone.telemetry.flight_mode(), lambda m: True, 5, "flight mode")
    print(f"-- Flight mode after stop: {mode}")
    assert str(mode) == "HOLD", mode


if __name__ == "__main__":
    asyncio.run(run())
