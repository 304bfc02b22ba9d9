#!/usr/bin/env python3
"""Offboard velocity control, in the NED frame and then in the body frame.

A zero NED velocity goes out before Offboard.start (MAVSDK will not start
offboard without a setpoint). Each step then commands a velocity for a while
and checks what telemetry reports once the vehicle has had time to follow:

- NED: a climb, an eastward run with the nose turning east, a diagonal to
  the south-west with the nose following, a stop;
- body (VelocityBodyYawspeed): straight ahead, a turn on the spot at a fixed
  yaw rate, a sideways slide to the right (checked against the heading the
  vehicle has at that moment), a stop;
- NED again: a slow sink.

Then offboard is left (HOLD), and Action.land brings the vehicle down.
"""

import math

from mavsdk.offboard import OffboardError, VelocityBodyYawspeed, VelocityNedYaw
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

SPEED_TOL = 0.3  # m/s
YAW_TOL_DEG = 5.0
YAW_RATE_DEG_S = 45.0


def ned_speed(pv):
    v = pv.velocity
    return (v.north_m_s, v.east_m_s, v.down_m_s)


async def expect_velocity(uav, want, label, wall_limit=10):
    """Wait until the NED velocity is within SPEED_TOL of `want` on each axis,
    then make sure the vehicle is still in OFFBOARD."""

    def close(pv):
        return all(abs(got - w) < SPEED_TOL for got, w in zip(ned_speed(pv), want))

    pv = await next_matching(uav.telemetry.position_velocity_ned(), close, wall_limit, label)
    n, e, d = ned_speed(pv)
    print(f"[vel]   {label}: {n:+.2f} {e:+.2f} {d:+.2f} m/s at {-pv.position.down_m:.1f} m up")
    await expect_mode(uav, FlightMode.OFFBOARD, 2)


async def expect_heading(uav, yaw, wall_limit=10):
    att = await next_matching(
        uav.telemetry.attitude_euler(),
        lambda a: heading_gap_deg(a.yaw_deg, yaw) < YAW_TOL_DEG,
        wall_limit,
        f"heading {yaw}",
    )
    return att.yaw_deg


async def ned_step(uav, north, east, down, yaw, seconds, note):
    print(f"[vel] {note}")
    await uav.offboard.set_velocity_ned(VelocityNedYaw(north, east, down, yaw))
    await pause(uav, seconds)
    await expect_velocity(uav, (north, east, down), note)


async def main():
    uav = await bring_up()
    echo_status_text(uav)

    await uav.action.arm()
    print("[offboard] armed")
    await uav.offboard.set_velocity_ned(VelocityNedYaw(0.0, 0.0, 0.0, 0.0))
    try:
        await uav.offboard.start()
    except OffboardError as err:
        print(f"[offboard] start refused: {err._result.result}")
        await uav.action.disarm()
        bail("offboard start refused")
    await expect_mode(uav, FlightMode.OFFBOARD)

    # --- NED frame
    await ned_step(uav, 0.0, 0.0, -1.5, 0.0, 4.0, "climb at 1.5 m/s")
    await ned_step(uav, 0.0, 3.0, 0.0, 90.0, 4.0, "east at 3 m/s, nose east")
    await expect_heading(uav, 90.0)
    await ned_step(uav, -2.0, -2.0, 0.0, 225.0, 3.0, "south-west at 2 m/s per axis, nose south-west")
    await expect_heading(uav, 225.0)
    await ned_step(uav, 0.0, 0.0, 0.0, 0.0, 3.0, "stop, nose north")
    await expect_heading(uav, 0.0)

    # --- body frame; the nose points north here, so forward is north
    print("[vel] body: forward at 2.5 m/s")
    await uav.offboard.set_velocity_body(VelocityBodyYawspeed(2.5, 0.0, 0.0, 0.0))
    await pause(uav, 3.0)
    await expect_velocity(uav, (2.5, 0.0, 0.0), "forward = north")

    print(f"[vel] body: stop and turn right at {YAW_RATE_DEG_S:.0f} deg/s")
    await uav.offboard.set_velocity_body(VelocityBodyYawspeed(0.0, 0.0, 0.0, YAW_RATE_DEG_S))
    await pause(uav, 1.0)
    rate = await next_matching(
        uav.telemetry.attitude_angular_velocity_body(),
        lambda w: abs(math.degrees(w.yaw_rad_s) - YAW_RATE_DEG_S) < 8.0,
        10,
        f"yaw rate {YAW_RATE_DEG_S} deg/s",
    )
    print(f"[vel]   yaw rate {math.degrees(rate.yaw_rad_s):.1f} deg/s")

    # sum the heading change sample by sample, so wrapping at +-180 does not matter
    first = (await sample(uav.telemetry.attitude_euler(), "attitude")).yaw_deg
    swept = {"deg": 0.0, "last": first}

    def quarter_turn(att):
        swept["deg"] += (att.yaw_deg - swept["last"] + 180.0) % 360.0 - 180.0
        swept["last"] = att.yaw_deg
        return swept["deg"] > 80.0

    turned = await next_matching(uav.telemetry.attitude_euler(), quarter_turn, 10, "a quarter turn to the right")
    print(f"[vel]   heading {first:.1f} -> {turned.yaw_deg:.1f} deg")

    await uav.offboard.set_velocity_body(VelocityBodyYawspeed(0.0, 0.0, 0.0, 0.0))
    await pause(uav, 2.0)
    heading = math.radians((await sample(uav.telemetry.attitude_euler(), "attitude")).yaw_deg)
    print("[vel] body: slide right at 2 m/s")
    await uav.offboard.set_velocity_body(VelocityBodyYawspeed(0.0, 2.0, 0.0, 0.0))
    await pause(uav, 3.0)
    # body right (0, 2) rotated by the heading into north/east
    await expect_velocity(uav, (-2.0 * math.sin(heading), 2.0 * math.cos(heading), 0.0), "right, seen in NED")

    await uav.offboard.set_velocity_body(VelocityBodyYawspeed(0.0, 0.0, 0.0, 0.0))
    await pause(uav, 2.0)
    await expect_velocity(uav, (0.0, 0.0, 0.0), "stopped")

    # --- NED again
    await ned_step(uav, 0.0, 0.0, 1.0, 180.0, 3.0, "sink at 1 m/s, nose south")

    try:
        await uav.offboard.stop()
    except OffboardError as err:
        bail(f"offboard stop refused: {err._result.result}")
    await expect_mode(uav, FlightMode.HOLD)

    await uav.action.land()
    print("[vel] landing")
    await touchdown(uav, 60)


if __name__ == "__main__":
    launch(main)
