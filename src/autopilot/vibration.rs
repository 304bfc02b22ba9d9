//! The IMU's vibration metrics as PX4's `VehicleIMU` computes them for
//! `vehicle_imu_status` (what MAVLink VIBRATION reports): on every new
//! accelerometer and gyroscope sample, a first-order low-pass (weight 0.01
//! per sample) of the size of the sample-to-sample change, and of the
//! gyroscope's coning:
//!
//! ```text
//! accel   m_a <- 0.99 m_a + 0.01 |f_k - f_{k-1}|      [m/s^2]
//! gyro    m_g <- 0.99 m_g + 0.01 |w_k - w_{k-1}|      [rad/s]
//! coning  m_c <- 0.99 m_c + 0.01 |w_k x w_{k-1}|      [(rad/s)^2]
//! ```
//!
//! The first difference waits for a second sample (PX4 takes its first
//! previous sample as zero, so its metric starts with a spike of `0.01 g`
//! that decays over a few seconds).

use nalgebra::Vector3;
use serde::Serialize;

use crate::signals::{AxesSample, RawSensorReadings};

/// The IMU's vibration metrics (PX4's `vehicle_imu_status`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct ImuVibration {
    /// Time of the latest sample that moved them [s].
    pub time_s: f64,
    /// `accel_vibration_metric` [m/s^2] (VIBRATION `vibration_z`).
    pub accel_m_s2: f64,
    /// `gyro_vibration_metric` [rad/s] (VIBRATION `vibration_y`).
    pub gyro_rad_s: f64,
    /// `delta_angle_coning_metric` [(rad/s)^2] (VIBRATION `vibration_x`).
    pub coning_rad2_s2: f64,
}

/// Low-pass weight of the newest sample.
const WEIGHT: f64 = 0.01;

/// The metrics' state: the previous samples and the filtered values.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct VibrationMonitor {
    accel_prev: Option<AxesSample>,
    gyro_prev: Option<AxesSample>,
    metrics: Option<ImuVibration>,
}

impl VibrationMonitor {
    /// Takes the newest accelerometer and gyroscope samples, each once
    /// (a sample is new when its time is later than the one taken before).
    pub(super) fn update(&mut self, raw: &RawSensorReadings) {
        if let Some(a) = raw.accel
            && let Some(prev) = newer(self.accel_prev, a)
        {
            self.accel_prev = Some(a);
            if let Some(prev) = prev {
                let m = self.metrics.get_or_insert_default();
                m.accel_m_s2 = lowpass(m.accel_m_s2, (a.frd - prev.frd).norm());
                m.time_s = a.time_s;
            }
        }
        if let Some(w) = raw.gyro
            && let Some(prev) = newer(self.gyro_prev, w)
        {
            self.gyro_prev = Some(w);
            if let Some(prev) = prev {
                let m = self.metrics.get_or_insert_default();
                m.gyro_rad_s = lowpass(m.gyro_rad_s, (w.frd - prev.frd).norm());
                m.coning_rad2_s2 = lowpass(m.coning_rad2_s2, coning(&w.frd, &prev.frd));
                m.time_s = m.time_s.max(w.time_s);
            }
        }
    }

    /// The metrics, once two samples of a sensor have come.
    pub(super) fn metrics(&self) -> Option<ImuVibration> {
        self.metrics
    }
}

/// `Some(previous)` when `sample` is newer than `previous` (or the first).
fn newer(previous: Option<AxesSample>, sample: AxesSample) -> Option<Option<AxesSample>> {
    match previous {
        Some(p) if sample.time_s <= p.time_s => None,
        p => Some(p),
    }
}

/// `m <- 0.99 m + 0.01 x`.
fn lowpass(m: f64, x: f64) -> f64 {
    (1.0 - WEIGHT) * m + WEIGHT * x
}

/// `|w_k x w_{k-1}|`.
fn coning(w: &Vector3<f64>, prev: &Vector3<f64>) -> f64 {
    w.cross(prev).norm()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn raw(t: f64, f: [f64; 3]) -> RawSensorReadings {
        RawSensorReadings {
            accel: Some(AxesSample {
                time_s: t,
                frd: Vector3::from(f),
            }),
            ..RawSensorReadings::default()
        }
    }

    #[test]
    fn a_steady_accelerometer_reads_no_vibration_and_a_shaking_one_its_mean_step() {
        let mut v = VibrationMonitor::default();
        v.update(&raw(0.0, [0.0, 0.0, -9.8]));
        assert_eq!(v.metrics(), None, "one sample gives no difference");
        v.update(&raw(0.004, [0.0, 0.0, -9.8]));
        assert_eq!(v.metrics().map(|m| m.accel_m_s2), Some(0.0));
        // alternating +-0.1 m/s^2: each step changes by 0.2, the metric tends to 0.2
        for k in 2..2000 {
            let s = if k % 2 == 0 { 0.1 } else { -0.1 };
            v.update(&raw(0.004 * f64::from(k), [s, 0.0, -9.8]));
        }
        let m = v.metrics().unwrap();
        assert!((m.accel_m_s2 - 0.2).abs() < 1e-6, "{m:?}");
        // a repeated sample (same time) is taken once
        let before = v.metrics();
        v.update(&raw(0.004 * 1999.0, [5.0, 0.0, -9.8]));
        assert_eq!(v.metrics(), before);
    }
}
