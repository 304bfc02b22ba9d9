#!/usr/bin/env python3
"""Ground truth as PX4's own integration tests read it: ask for it with
Telemetry.set_rate_ground_truth (SET_MESSAGE_INTERVAL for HIL_STATE_QUATERNION,
which PX4 SITL does not stream unasked), store home from it, then climb and
check that the true position follows the estimated one: on the ground and
after the climb within POS_TOL horizontally and ALT_TOL vertically of
telemetry.position(), and the true altitude MIS_TAKEOFF_ALT above the true
home.
"""

from common import bail, bring_up, ground_gap_m, launch, next_matching, sample, touchdown

POS_TOL = 0.5  # m, the navigation filter's horizontal error is decimetres
# m: its height moves off the truth with GNSS height over a flight (measured
# up to 0.57 m on the ground after landing)
ALT_TOL = 1.0
RATE_HZ = 20.0


def gap(truth, pos):
    """Horizontal and vertical gaps [m] between a GroundTruth and a Position."""
    across = ground_gap_m(truth.latitude_deg, truth.longitude_deg, pos.latitude_deg, pos.longitude_deg)
    return across, abs(truth.absolute_altitude_m - pos.absolute_altitude_m)


async def compare(uav, label):
    truth = await sample(uav.telemetry.ground_truth(), "ground truth")
    pos = await sample(uav.telemetry.position(), "position")
    across, up = gap(truth, pos)
    print(f"[truth] {label}: truth {truth.latitude_deg:.7f} {truth.longitude_deg:.7f} "
          f"{truth.absolute_altitude_m:.2f} m, estimate {across:.3f} m across, {up:.3f} m up")
    if across > POS_TOL or up > ALT_TOL:
        bail(f"{label}: ground truth {across:.2f} m across and {up:.2f} m up from the estimate")
    return truth


async def main():
    uav = await bring_up()
    await uav.telemetry.set_rate_ground_truth(RATE_HZ)
    home = await compare(uav, "home")

    target = await uav.action.get_takeoff_altitude()
    await uav.action.arm()
    await uav.action.takeoff()

    def level(p):
        return abs(p.absolute_altitude_m - home.absolute_altitude_m - target) < ALT_TOL

    await next_matching(uav.telemetry.ground_truth(), level, 40, f"true altitude {target:.1f} m above home")
    await compare(uav, "hovering")

    await uav.action.land()
    await touchdown(uav, 40)
    rest = await compare(uav, "landed")
    if abs(rest.absolute_altitude_m - home.absolute_altitude_m) > ALT_TOL:
        bail(f"landed {rest.absolute_altitude_m - home.absolute_altitude_m:.2f} m above the true home")


if __name__ == "__main__":
    launch(main)
