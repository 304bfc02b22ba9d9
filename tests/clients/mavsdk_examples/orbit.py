#!/usr/bin/env python3
"""Orbit as MAVSDK-Python's do_orbit.py example flies it: take off, then
Action.do_orbit with a 10 m radius at 2 m/s, nose to the centre, around a
point about 20 m north-east of home, 10 m above the ground; sent by MAVSDK
as COMMAND_INT (MAV_CMD_DO_ORBIT). The vehicle must fly to the circle and go
round it clockwise at that altitude and speed, facing the centre, then
return home and land when asked.
"""

import math

from mavsdk.action import OrbitYawBehavior

from common import (
    M_PER_DEG_LAT,
    bail,
    bring_up,
    ground_gap_m,
    launch,
    next_matching,
    pause,
    sample,
    touchdown,
)

RADIUS = 10.0  # m
SPEED = 2.0  # m/s
TOL = 0.6  # m on the radius and the altitude


async def main():
    uav = await bring_up()
    home = await sample(uav.telemetry.home(), "home")
    lat = home.latitude_deg + 14.0 / M_PER_DEG_LAT
    lon = home.longitude_deg + 14.0 / (M_PER_DEG_LAT * math.cos(math.radians(home.latitude_deg)))
    alt = home.absolute_altitude_m + 10.0

    await uav.action.arm()
    await uav.action.takeoff()
    await next_matching(uav.telemetry.in_air(), bool, 20, "liftoff")
    await pause(uav, 8.0)

    await uav.action.do_orbit(
        radius_m=RADIUS,
        velocity_ms=SPEED,
        yaw_behavior=OrbitYawBehavior.HOLD_FRONT_TO_CIRCLE_CENTER,
        latitude_deg=lat,
        longitude_deg=lon,
        absolute_altitude_m=alt,
    )
    print("[orbit] do_orbit accepted")

    def on_circle(p):
        r = ground_gap_m(p.latitude_deg, p.longitude_deg, lat, lon)
        return abs(r - RADIUS) < TOL and abs(p.absolute_altitude_m - alt) < TOL

    await next_matching(uav.telemetry.position(), on_circle, 60, "the circle")
    await pause(uav, 10.0)
    # a quarter lap (7.9 s at 2 m/s) at a time: stays on the circle, faces the centre, flies at speed
    for _ in range(3):
        await pause(uav, 4.0)
        p = await sample(uav.telemetry.position(), "position")
        v = await sample(uav.telemetry.velocity_ned(), "velocity")
        h = await sample(uav.telemetry.heading(), "heading")
        r = ground_gap_m(p.latitude_deg, p.longitude_deg, lat, lon)
        speed = math.hypot(v.north_m_s, v.east_m_s)
        north = (lat - p.latitude_deg) * M_PER_DEG_LAT
        east = (lon - p.longitude_deg) * M_PER_DEG_LAT * math.cos(math.radians(lat))
        to_centre = math.degrees(math.atan2(east, north)) % 360
        off = (h.heading_deg - to_centre + 180) % 360 - 180
        print(f"[orbit] r {r:.2f} m, alt {p.absolute_altitude_m - alt:+.2f} m, {speed:.2f} m/s, nose {off:+.1f} deg off the centre")
        if not on_circle(p):
            bail(f"off the circle: r {r:.2f} m, {p.absolute_altitude_m - alt:+.2f} m")
        if abs(speed - SPEED) > 0.3:
            bail(f"orbiting at {speed:.2f} m/s")
        if abs(off) > 10:
            bail(f"nose {off:.1f} deg off the centre")

    await uav.action.return_to_launch()
    await touchdown(uav, 90)
    rest = await sample(uav.telemetry.position(), "position")
    gap = ground_gap_m(rest.latitude_deg, rest.longitude_deg, home.latitude_deg, home.longitude_deg)
    if gap > 2.0:
        bail(f"landed {gap:.1f} m from home")


if __name__ == "__main__":
    launch(main)
