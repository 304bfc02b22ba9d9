#!/usr/bin/env python3
"""Offboard along a time-stamped path, as MAVSDK-Python's
offboard_from_csv.py flies one: rows of (t, position, velocity,
acceleration) sent with Offboard.set_position_velocity_acceleration_ned
at 10 Hz of vehicle time, each row at its own time. Here the rows are made in
memory (that example reads them from a CSV file): a climb to 5 m, then a
circle of 8 m radius at 1.5 m/s. The velocity and acceleration are
feed-forward to the position (PX4's trajectory setpoint), so the vehicle
must be where the path says at the time it says: within TOL_M all along the
circle and when the path ends and land() is called (a vehicle flying to the
positions alone trails by 3 m, 2 s of the path).
"""

import math

from mavsdk.offboard import AccelerationNed, PositionNedYaw, VelocityNedYaw
from mavsdk.telemetry import FlightMode

from common import (
    bail,
    bring_up,
    echo_status_text,
    expect_mode,
    launch,
    next_matching,
    pause,
    sample,
    touchdown,
    vehicle_time_s,
)

TOL_M = 0.6
RADIUS = 8.0  # m
SPEED = 1.5  # m/s
CLIMB_S = 8.0  # s, holding 5 m up before the circle
LAP_S = 2.0 * math.pi * RADIUS / SPEED
LATENCY_S = 0.3  # s of vehicle time a position sample may be older than the clock read before it


def row(t):
    """The path at `t` [s]: position, velocity, acceleration (NED)."""
    if t < CLIMB_S:
        return (0.0, 0.0, -5.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
    w = SPEED / RADIUS
    phi = w * (t - CLIMB_S)
    # a circle through the start point, centre 8 m north
    s, c = math.sin(phi), math.cos(phi)
    p = (RADIUS - RADIUS * c, RADIUS * s, -5.0)
    v = (RADIUS * w * s, RADIUS * w * c, 0.0)
    a = (RADIUS * w * w * c, -RADIUS * w * w * s, 0.0)
    return p, v, a


async def send(uav, t):
    p, v, a = row(t)
    await uav.offboard.set_position_velocity_acceleration_ned(
        PositionNedYaw(*p, 0.0), VelocityNedYaw(*v, 0.0), AccelerationNed(*a)
    )


async def main():
    uav = await bring_up()
    echo_status_text(uav)
    await uav.action.arm()
    await uav.action.takeoff()
    await next_matching(uav.telemetry.in_air(), bool, 20, "liftoff")
    await pause(uav, 6.0)

    await send(uav, 0.0)
    await uav.offboard.start()
    await expect_mode(uav, FlightMode.OFFBOARD)
    t0 = await vehicle_time_s(uav)
    end = CLIMB_S + LAP_S
    worst = 0.0
    last = 0.0
    while True:
        t = await vehicle_time_s(uav) - t0
        if t > end:
            break
        await send(uav, t)
        if t > CLIMB_S + 4.0:
            # the sample's instant is known only between two readings of the
            # vehicle clock (the streams run on wall time): the gap is to the
            # nearest point of the path in [t_a - LATENCY_S, t_b]
            t_a = await vehicle_time_s(uav) - t0
            pv = await sample(uav.telemetry.position_velocity_ned(), "local position")
            t_b = await vehicle_time_s(uav) - t0
            q = pv.position
            here = (q.north_m, q.east_m, q.down_m)
            span = t_b - t_a + LATENCY_S
            last = min(math.dist(here, row(t_a - LATENCY_S + span * k / 50)[0]) for k in range(51))
            worst = max(worst, last)
        await pause(uav, 0.1)
    print(f"[path] largest gap to the timed path {worst:.2f} m, at the end {last:.2f} m")
    if worst > TOL_M:
        bail(f"trailed the timed path by {worst:.2f} m")
    await uav.action.land()
    await touchdown(uav, 60)


if __name__ == "__main__":
    launch(main)
