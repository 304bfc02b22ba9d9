//! The navigation solution the flight stack sees: the true state with seeded
//! white Gaussian noise.
//!
//! `p~ = p + n_p`, `v~ = v + n_v` (NED), `q~ = q exp(n_att)` (a small body-frame
//! rotation), `w~ = w + n_w` (FRD), each `n ~ N(0, sigma^2)` per axis, drawn
//! from a ChaCha8 stream seeded by the caller: no global RNG, so the same seed
//! gives the same noise.

use nalgebra::{UnitQuaternion, Vector3};

use crate::signals::Measurement;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};

/// Standard deviations of the measurement noise (0 = exact).
#[derive(Clone, Copy, Debug, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SensorNoise {
    /// Position noise [m] per NED axis.
    pub position_m: f64,
    /// Velocity noise [m/s] per NED axis.
    pub velocity_m_s: f64,
    /// Attitude noise [rad] per body axis.
    pub attitude_rad: f64,
    /// Angular-rate noise [rad/s] per FRD axis.
    pub rate_rad_s: f64,
}

impl SensorNoise {
    /// Whether every standard deviation is finite and not negative.
    #[must_use]
    pub fn is_valid(&self) -> bool {
        [self.position_m, self.velocity_m_s, self.attitude_rad, self.rate_rad_s]
            .iter()
            .all(|s| s.is_finite() && *s >= 0.0)
    }

    /// Whether every standard deviation is zero.
    #[must_use]
    pub fn is_zero(&self) -> bool {
        self.position_m == 0.0 && self.velocity_m_s == 0.0 && self.attitude_rad == 0.0 && self.rate_rad_s == 0.0
    }
}

/// Noise source with its own seeded random stream.
#[derive(Clone, Debug)]
pub struct Sensors {
    /// The configured noise.
    noise: SensorNoise,
    /// The noise in force: the configured one, or a fault's.
    active: SensorNoise,
    rng: ChaCha8Rng,
}

impl Sensors {
    /// Sensors with the given noise, seeded.
    #[must_use]
    pub fn new(noise: SensorNoise, seed: u64) -> Self {
        Self {
            noise,
            active: noise,
            rng: ChaCha8Rng::seed_from_u64(seed),
        }
    }

    /// Measure with `noise` instead of the configured noise (a sensor
    /// fault), or with the configured one again (`None`).
    pub fn force_noise(&mut self, noise: Option<SensorNoise>) {
        self.active = noise.unwrap_or(self.noise);
    }

    fn gauss3(&mut self, sigma: f64) -> Vector3<f64> {
        if sigma == 0.0 {
            return Vector3::zeros();
        }
        let mut draw = || -> f64 { StandardNormal.sample(&mut self.rng) };
        Vector3::new(draw(), draw(), draw()) * sigma
    }

    /// Measure a true state.
    pub fn measure(&mut self, truth: &Measurement) -> Measurement {
        if self.active.is_zero() {
            return *truth;
        }
        let n = self.active;
        Measurement {
            time_s: truth.time_s,
            position_ned: truth.position_ned + self.gauss3(n.position_m),
            velocity_ned: truth.velocity_ned + self.gauss3(n.velocity_m_s),
            attitude: truth.attitude * UnitQuaternion::from_scaled_axis(self.gauss3(n.attitude_rad)),
            rate_frd: truth.rate_frd + self.gauss3(n.rate_rad_s),
        }
    }
}
