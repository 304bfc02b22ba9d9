#!/usr/bin/env python3
"""Offboard position control: a triangle in the local NED frame, then a
landing flown with the setpoint alone.

MAVSDK refuses to start offboard without a setpoint, so one (the ground at
home, nose north) is sent before Offboard.start. The legs below are flown one
after the other; each must be reached within REACH_M and held there for HOLD_S,
with the nose within YAW_TOL_DEG of the requested yaw and the vehicle still in
OFFBOARD. The last setpoint is the ground below home: the vehicle must touch
down and disarm before the script leaves offboard, after which it must report
HOLD.
"""

import math

from mavsdk.offboard import OffboardError, PositionNedYaw
from mavsdk.telemetry import FlightMode

from common import (
    bail,
    bring_up,
    echo_status_text,
    expect_mode,
    heading_gap_deg,
    launch,
    next_matching,
    pause,
    sample,
    touchdown,
)

REACH_M = 0.3
HOLD_S = 2.0  # simulated seconds
YAW_TOL_DEG = 5.0

# (north, east, down) in metres, yaw in degrees, and a note for the log
LEGS = [
    ((0.0, 0.0, -4.0), 0.0, "straight up to 4 m"),
    ((6.0, 0.0, -4.0), 0.0, "6 m north"),
    ((6.0, -6.0, -6.0), 270.0, "6 m west and 2 m up, nose west"),
    ((0.0, 0.0, -6.0), 135.0, "back over home, nose south-east"),
]
GROUND = ((0.0, 0.0, 0.0), 135.0, "down to the ground below home")


def gap(pv, ned):
    p = pv.position
    return math.dist((p.north_m, p.east_m, p.down_m), ned)


async def fly_leg(uav, ned, yaw, note):
    print(f"[leg] {note}: N {ned[0]:+.1f} E {ned[1]:+.1f} D {ned[2]:+.1f}, yaw {yaw:.0f}")
    await uav.offboard.set_position_ned(PositionNedYaw(*ned, yaw))
    await next_matching(uav.telemetry.position_velocity_ned(), lambda pv: gap(pv, ned) < REACH_M, 40, note)
    await pause(uav, HOLD_S)
    pv = await sample(uav.telemetry.position_velocity_ned(), "local position")
    p = pv.position
    print(f"[leg]   holding at {p.north_m:+.2f} {p.east_m:+.2f} {p.down_m:+.2f} ({gap(pv, ned):.2f} m off)")
    if gap(pv, ned) >= REACH_M:
        bail(f"did not hold {note}: {gap(pv, ned):.2f} m off")
    att = await next_matching(
        uav.telemetry.attitude_euler(),
        lambda a: heading_gap_deg(a.yaw_deg, yaw) < YAW_TOL_DEG,
        10,
        f"yaw {yaw}",
    )
    print(f"[leg]   yaw {att.yaw_deg:.1f}")
    await expect_mode(uav, FlightMode.OFFBOARD, 2)


async def main():
    uav = await bring_up()
    echo_status_text(uav)

    await uav.action.arm()
    print("[offboard] armed")
    await uav.offboard.set_position_ned(PositionNedYaw(0.0, 0.0, 0.0, 0.0))
    try:
        await uav.offboard.start()
    except OffboardError as err:
        print(f"[offboard] start refused: {err._result.result}")
        await uav.action.disarm()
        bail("offboard start refused")
    await expect_mode(uav, FlightMode.OFFBOARD)

    for ned, yaw, note in LEGS:
        await fly_leg(uav, ned, yaw, note)

    ned, yaw, note = GROUND
    print(f"[leg] {note}")
    await uav.offboard.set_position_ned(PositionNedYaw(*ned, yaw))
    await touchdown(uav, 40)

    try:
        await uav.offboard.stop()
    except OffboardError as err:
        bail(f"offboard stop refused: {err._result.result}")
    await expect_mode(uav, FlightMode.HOLD)


if __name__ == "__main__":
    launch(main)
