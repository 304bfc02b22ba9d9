"""Flights written as a user of the fixture writes them: MAVSDK 3 (takeoff,
a short mission, land; with its own `System`, and with the
`rotorpilot_mavsdk` fixture's) and pymavlink (arm, takeoff, land), each
against its own vehicle from `rotorpilot_vehicle`. Passes alone and under
`pytest -n 2`.

Needs `pip install .` (or the plugin on the path), mavsdk==3.17.4 and
pymavlink==2.4.50. Every wait is bounded.
"""

import asyncio
import math
import time

import pytest
from mavsdk import System
from mavsdk.mission import MissionItem, MissionPlan
from pymavlink import mavutil

from rotorpilot import wait_message

M_PER_DEG = 111_195.0  # metres per degree of latitude


async def first(stream, cond, timeout, what):
    """The first item of a MAVSDK stream that satisfies `cond`, within `timeout` wall seconds."""
    async def scan():
        async for x in stream:
            if cond(x):
                return x
    try:
        return await asyncio.wait_for(scan(), timeout)
    except asyncio.TimeoutError:
        raise AssertionError(f"no {what} within {timeout} s") from None


def waypoint(home, north_m, east_m, alt_m):
    lat = home.latitude_deg + north_m / M_PER_DEG
    lon = home.longitude_deg + east_m / (M_PER_DEG * math.cos(math.radians(home.latitude_deg)))
    nan = float("nan")
    return MissionItem(lat, lon, alt_m, 5.0, True, nan, nan, MissionItem.CameraAction.NONE, nan, 1.0, 2.0,
                       nan, nan, MissionItem.VehicleAction.NONE)


async def takeoff_mission_land(drone):
    await first(drone.core.connection_state(), lambda c: c.is_connected, 20, "connection")
    await first(drone.telemetry.health(), lambda h: h.is_armable and h.is_home_position_ok, 10, "health")
    home = await first(drone.telemetry.home(), lambda h: True, 10, "home")

    await drone.action.arm()
    await drone.action.takeoff()
    await first(drone.telemetry.position(), lambda p: p.relative_altitude_m > 4.5, 30, "takeoff to 5 m")

    plan = MissionPlan([waypoint(home, 15, 0, 8), waypoint(home, 15, 15, 8), waypoint(home, 0, 0, 8)])
    await drone.mission.set_return_to_launch_after_mission(False)
    await drone.mission.upload_mission(plan)
    await drone.mission.start_mission()
    await first(drone.mission.mission_progress(), lambda p: p.current == p.total == 3, 60, "mission done")
    assert await drone.mission.is_mission_finished()

    await drone.action.land()
    await first(drone.telemetry.armed(), lambda armed: not armed, 60, "landed and disarmed")
    p = await first(drone.telemetry.position(), lambda p: True, 5, "position")
    assert abs(p.relative_altitude_m) < 0.5
    assert abs(p.latitude_deg - home.latitude_deg) * M_PER_DEG < 3.0, "landed near home"


@pytest.mark.rotorpilot(speed=10, params={"MIS_TAKEOFF_ALT": 5.0})
def test_mavsdk3_takeoff_mission_land(rotorpilot_vehicle):
    async def fly():
        # its own mavsdk_server port: the default 50051 clashes between parallel tests
        drone = System(port=rotorpilot_vehicle.mavsdk_server_port)
        await drone.connect(system_address=rotorpilot_vehicle.mavsdk_url)
        try:
            await takeoff_mission_land(drone)
        finally:
            drone._stop_mavsdk_server()  # MAVSDK 3 has no public close

    asyncio.run(asyncio.wait_for(fly(), 180))


@pytest.mark.rotorpilot(speed=10, params={"MIS_TAKEOFF_ALT": 5.0})
def test_mavsdk_fixture_takeoff_mission_land(rotorpilot_mavsdk):
    async def fly():
        await rotorpilot_mavsdk.connect()  # to the fixture's mavsdk_server, which it stops
        await takeoff_mission_land(rotorpilot_mavsdk)

    asyncio.run(asyncio.wait_for(fly(), 180))


def recv(m, kind, cond=None, timeout=10.0):
    msg = wait_message(m, kind, cond, timeout)
    assert msg is not None, f"no {kind} meeting the condition within {timeout} s"
    return msg


@pytest.mark.rotorpilot(speed=10)
def test_pymavlink_arm_takeoff_land(rotorpilot_vehicle):
    m = mavutil.mavlink_connection(rotorpilot_vehicle.pymavlink_url, source_system=255)
    hb = m.wait_heartbeat(timeout=5)
    assert hb is not None and m.target_system == rotorpilot_vehicle.system_id

    m.arducopter_arm()
    recv(m, "HEARTBEAT", lambda h: h.base_mode & 128, 5)
    m.mav.command_long_send(m.target_system, 1, mavutil.mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 0, 0)
    recv(m, "COMMAND_ACK", lambda a: a.command == mavutil.mavlink.MAV_CMD_NAV_TAKEOFF and a.result == 0)
    recv(m, "GLOBAL_POSITION_INT", lambda g: g.relative_alt > 2000, 30)

    m.mav.command_long_send(m.target_system, 1, mavutil.mavlink.MAV_CMD_NAV_LAND, 0, 0, 0, 0, 0, 0, 0, 0)
    recv(m, "EXTENDED_SYS_STATE", lambda e: e.landed_state == 4, 10)  # landing
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:  # PX4 disarms itself after touchdown
        hb = recv(m, "HEARTBEAT")
        if not hb.base_mode & 128:
            break
    else:
        raise AssertionError("not disarmed after landing within 60 s")
    assert recv(m, "GLOBAL_POSITION_INT").relative_alt < 500
