#!/usr/bin/env python3
"""MAVSDK-Python examples/all_params.py, plus a set and get of each type."""

import asyncio

from mavsdk import System

from common import GRPC_PORT, URL, wait_until


async def run():
    # Connect to the drone
    drone = System(port=GRPC_PORT)
    await drone.connect(system_address=URL)

    print("Waiting for drone to connect...")
    await wait_until(drone.core.connection_state(), lambda s: s.is_connected, 20, "connection")
    print("-- Connected to drone!")

    # Get the list of parameters
    all_params = await drone.param.get_all_params()

    # Iterate through all int parameters
    for param in all_params.int_params:
        print(f"{param.name}: {param.value}")

    # Iterate through all float parameters
    for param in all_params.float_params:
        print(f"{param.name}: {param.value}")

    names = {p.name for p in all_params.int_params} | {p.name for p in all_params.float_params}
    assert {"MIS_TAKEOFF_ALT", "SYS_FAILURE_EN", "CTRL_TYPE", "SIM_MASS"} <= names, names
    assert len(names) == len(all_params.int_params) + len(all_params.float_params)

    await drone.param.set_param_float("MIS_TAKEOFF_ALT", 4.0)
    assert await drone.param.get_param_float("MIS_TAKEOFF_ALT") == 4.0
    await drone.param.set_param_int("SYS_FAILURE_EN", 1)
    assert await drone.param.get_param_int("SYS_FAILURE_EN") == 1
    assert await drone.action.get_takeoff_altitude() == 4.0
    print("-- set and read back MIS_TAKEOFF_ALT (REAL32) and SYS_FAILURE_EN (INT32)")


if __name__ == "__main__":
    asyncio.run(run())
