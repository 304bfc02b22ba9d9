#!/usr/bin/env python3
"""Follow-me as MAVSDK-Python's follow_me_example.py flies it: take off,
FollowMe.set_config (which sets PX4's FLW_TGT_* parameters), FollowMe.start
(DO_SET_MODE AUTO.FOLLOW_TARGET), then set_target_location in a loop
(FOLLOW_TARGET messages) for a target walking east at 1.5 m/s from a point
about 15 m north of home. The vehicle must fly behind the target (west of
it: the target's course is east) at the configured distance and height, its
nose on the target; after FollowMe.stop it holds, then lands when asked.
"""

import math

from mavsdk.follow_me import Config, TargetLocation
from mavsdk.telemetry import FlightMode

from common import (
    M_PER_DEG_LAT,
    bail,
    bring_up,
    echo_status_text,
    expect_mode,
    ground_gap_m,
    launch,
    next_matching,
    pause,
    sample,
    touchdown,
    vehicle_time_s,
)

HEIGHT = 10.0  # m above home
DISTANCE = 6.0  # m from the target
SPEED = 1.5  # m/s, the target walking east
TOL_DISTANCE = 1.5  # m
TOL_HEIGHT = 0.7  # m
TOL_BEHIND = 20.0  # deg off due west of the target
LATENCY_S = 0.5  # s of vehicle time a position sample may be older than the clock read before it


async def main():
    uav = await bring_up()
    echo_status_text(uav)
    home = await sample(uav.telemetry.home(), "home")
    m_per_deg_lon = M_PER_DEG_LAT * math.cos(math.radians(home.latitude_deg))
    start_lat = home.latitude_deg + 15.0 / M_PER_DEG_LAT
    start_lon = home.longitude_deg

    await uav.action.arm()
    await uav.action.takeoff()
    await next_matching(uav.telemetry.in_air(), bool, 20, "liftoff")
    await pause(uav, 6.0)

    conf = Config(
        follow_height_m=HEIGHT,
        follow_distance_m=DISTANCE,
        responsiveness=0.1,
        altitude_mode=Config.FollowAltitudeMode.CONSTANT,
        max_tangential_vel_m_s=8.0,
        follow_angle_deg=180.0,
    )
    await uav.follow_me.set_config(conf)
    print("[follow] set_config accepted")
    got = await uav.follow_me.get_config()
    print(f"[follow] config {got}")
    t0 = await vehicle_time_s(uav)

    def target_at(t):
        east = SPEED * (t - t0)
        return start_lat, start_lon + east / m_per_deg_lon

    await uav.follow_me.start()
    await expect_mode(uav, FlightMode.FOLLOW_ME)
    if not await uav.follow_me.is_active():
        bail("follow-me not active after start")

    checks = 0
    while True:
        t = await vehicle_time_s(uav)
        lat, lon = target_at(t)
        await uav.follow_me.set_target_location(TargetLocation(lat, lon, home.absolute_altitude_m, 0.0, SPEED, 0.0))
        if t - t0 > 30.0 and checks < 5 and t - t0 > 30.0 + 2.0 * checks:
            # the sample's instant is known only between two readings of the
            # vehicle clock (the streams run on wall time): the target is
            # taken where it was at the instant in [t_a - LATENCY_S, t_b]
            # that fits the sample best
            t_a = await vehicle_time_s(uav)
            p = await sample(uav.telemetry.position(), "position")
            t_b = await vehicle_time_s(uav)
            h = await sample(uav.telemetry.heading(), "heading")
            span = t_b - t_a + LATENCY_S
            instants = [t_a - LATENCY_S + span * k / 50 for k in range(51)]
            t_fit = min(
                instants,
                key=lambda ti: abs(ground_gap_m(p.latitude_deg, p.longitude_deg, *target_at(ti)) - DISTANCE),
            )
            lat, lon = target_at(t_fit)
            d = ground_gap_m(p.latitude_deg, p.longitude_deg, lat, lon)
            north = (p.latitude_deg - lat) * M_PER_DEG_LAT
            east = (p.longitude_deg - lon) * m_per_deg_lon
            bearing = math.degrees(math.atan2(east, north)) % 360
            behind = (bearing - 270.0 + 180.0) % 360.0 - 180.0
            nose = (h.heading_deg - 90.0 + 180.0) % 360.0 - 180.0
            print(
                f"[follow] {d:.2f} m from the target, {behind:+.1f} deg off behind, "
                f"{p.relative_altitude_m:.2f} m up, nose {nose:+.1f} deg off the target"
            )
            if abs(d - DISTANCE) > TOL_DISTANCE:
                bail(f"{d:.2f} m from the target, not {DISTANCE}")
            if abs(behind) > TOL_BEHIND:
                bail(f"not behind the target: {behind:+.1f} deg")
            if abs(p.relative_altitude_m - HEIGHT) > TOL_HEIGHT:
                bail(f"{p.relative_altitude_m:.2f} m up, not {HEIGHT}")
            if abs(nose) > 20.0:
                bail(f"nose {nose:+.1f} deg off the target")
            checks += 1
        if checks == 5:
            break
        if t - t0 > 60.0:
            bail("no steady follow within 60 s")
        # a phone's GPS: a fix about every 0.2 s of vehicle time
        await pause(uav, 0.2)

    await uav.follow_me.stop()
    print("[follow] stopped")
    await expect_mode(uav, FlightMode.HOLD)
    await uav.action.land()
    await touchdown(uav, 90)


if __name__ == "__main__":
    launch(main)
