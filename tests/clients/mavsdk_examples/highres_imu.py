#!/usr/bin/env python3
"""MAVSDK's `highres_imu.py` example as a check: ask for the IMU with
Telemetry.set_rate_imu (SET_MESSAGE_INTERVAL for HIGHRES_IMU) and read
Telemetry.imu() as the example prints it: acceleration, angular velocity and
magnetic field (FRD) and temperature. At rest on the ground the
accelerometer reads about -9.81 m/s^2 on z (specific force, FRD), the
gyroscope about nothing, the magnetometer the Earth's field at home (~0.49
gauss, mostly down); the samples are noisy and their timestamps advance.
"""

from common import bail, bring_up, launch, next_matching

RATE_HZ = 50.0
SAMPLES = 40


async def main():
    uav = await bring_up(need_position=False)
    await uav.telemetry.set_rate_imu(RATE_HZ)
    seen = []

    def keep(imu):
        seen.append(imu)
        return len(seen) >= SAMPLES

    await next_matching(uav.telemetry.imu(), keep, 20, f"{SAMPLES} IMU samples")
    for imu in seen[:3]:
        a, w, m = imu.acceleration_frd, imu.angular_velocity_frd, imu.magnetic_field_frd
        print(f"[imu] t {imu.timestamp_us} us: acc {a.forward_m_s2:.3f} {a.right_m_s2:.3f} {a.down_m_s2:.3f} m/s^2, "
              f"gyro {w.forward_rad_s:.4f} {w.right_rad_s:.4f} {w.down_rad_s:.4f} rad/s, "
              f"mag {m.forward_gauss:.3f} {m.right_gauss:.3f} {m.down_gauss:.3f} G, {imu.temperature_degc:.1f} degC")
    down = sum(i.acceleration_frd.down_m_s2 for i in seen) / len(seen)
    if abs(down + 9.81) > 0.6:
        bail(f"at rest the accelerometer reads {down:.3f} m/s^2 on z, not about -9.81")
    if any(abs(i.angular_velocity_frd.down_rad_s) > 0.05 for i in seen):
        bail("a vehicle at rest turns, says the gyroscope")
    # the field averaged over the samples: one sample's noise (0.02 to 0.03 G
    # an axis, PX4's sensor_mag_sim) is 2 sigma off 0.05 G now and then
    f, r, d = (sum(getattr(i.magnetic_field_frd, k) for i in seen) / len(seen)
               for k in ("forward_gauss", "right_gauss", "down_gauss"))
    field = (f ** 2 + r ** 2 + d ** 2) ** 0.5
    if abs(field - 0.486) > 0.05 or d < 0.3:
        bail(f"the magnetic field is {field:.3f} G ({d:.3f} G down), averaged over {len(seen)} samples")
    if len({i.acceleration_frd.down_m_s2 for i in seen}) < SAMPLES // 2:
        bail("the accelerometer repeats itself: no noise")
    if not all(b.timestamp_us > a.timestamp_us for a, b in zip(seen, seen[1:]) if b.timestamp_us != a.timestamp_us):
        bail("IMU timestamps go back")
    if not -20 < seen[-1].temperature_degc < 40:
        bail(f"temperature {seen[-1].temperature_degc} degC")


if __name__ == "__main__":
    launch(main)
