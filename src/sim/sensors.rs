//! The navigation solution the flight stack sees: the true state with seeded
//! white Gaussian noise.
//!
//! `p~ = p + n_p`, `v~ = v + n_v` (NED), `q~ = q exp(n_att)` (a small body-frame
//! rotation), `w~ = w + n_w` (FRD), each `n ~ N(0, sigma^2)` per axis, drawn
//! from a ChaCha8 stream seeded by the caller: no global RNG, so the same seed
//! gives the same noise.
//!
//! Injected GNSS faults add a deterministic error on top ([`Sensors::degrade`]):
//! a wrong receiver shifts the position, `p~ += offset` (NED); a lost fix
//! leaves the solution dead-reckoning like an unaided EKF, whose horizontal
//! velocity error grows from an uncorrected accelerometer bias `a`:
//!
//! ```text
//! tau = t - t_loss,   v~ += a tau d,   p~ += a tau^2 / 2 d
//! ```
//! with `a` = [`DEAD_RECKONING_BIAS_M_S2`] and `d` a horizontal unit vector
//! (NED) drawn from the seed (not from the noise stream, which runs on
//! unchanged). The fix back, the error is gone at once (the EKF resets to GNSS).

use nalgebra::{UnitQuaternion, Vector3};
use std::f64::consts::TAU;

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

/// Uncorrected horizontal accelerometer bias of the dead-reckoning solution
/// after a GNSS loss [m/s^2] (about 2 mg: 9 m off after 30 s, 36 m after 60 s).
pub const DEAD_RECKONING_BIAS_M_S2: f64 = 0.02;

/// Noise source with its own seeded random stream.
#[derive(Clone, Debug)]
pub struct Sensors {
    /// The configured noise.
    noise: SensorNoise,
    /// The noise in force: the configured one, or a fault's.
    active: SensorNoise,
    rng: ChaCha8Rng,
    /// Direction of the dead-reckoning drift, horizontal unit vector, NED.
    drift_dir_ned: Vector3<f64>,
    /// Since when [s] the GNSS fix is lost, if it is.
    gps_lost_since_s: Option<f64>,
    /// Offset of a wrong GNSS position [m], NED, if one is injected.
    gps_offset_ned: Option<Vector3<f64>>,
}

/// SplitMix64: a seed's well-mixed 64-bit image (for the drift direction).
pub(super) fn splitmix64(seed: u64) -> u64 {
    let mut z = seed.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

impl Sensors {
    /// Sensors with the given noise, seeded.
    #[must_use]
    pub fn new(noise: SensorNoise, seed: u64) -> Self {
        // heading of the drift, psi = 2 pi u with u uniform in [0, 1) from the seed
        let psi = TAU * (splitmix64(seed) >> 11) as f64 / (1u64 << 53) as f64;
        Self {
            noise,
            active: noise,
            rng: ChaCha8Rng::seed_from_u64(seed),
            drift_dir_ned: Vector3::new(psi.cos(), psi.sin(), 0.0),
            gps_lost_since_s: None,
            gps_offset_ned: None,
        }
    }

    /// The GNSS fix is lost at `t_s` [s] (`Some`; a loss already running
    /// keeps its start) or back (`None`).
    pub fn set_gps_lost(&mut self, since_s: Option<f64>) {
        self.gps_lost_since_s = since_s.map(|t| self.gps_lost_since_s.unwrap_or(t));
    }

    /// A wrong GNSS position, off by `offset` [m] NED, or right again (`None`).
    pub fn set_gps_offset(&mut self, offset_ned: Option<Vector3<f64>>) {
        self.gps_offset_ned = offset_ned;
    }

    /// Whether an injected GNSS fault changes the navigation solution.
    #[must_use]
    pub fn degraded(&self) -> bool {
        self.gps_lost_since_s.is_some() || self.gps_offset_ned.is_some()
    }

    /// The navigation solution `m` with the injected GNSS faults' errors at
    /// its time (module doc); `m` itself when there is none.
    #[must_use]
    pub fn degrade(&self, m: &Measurement) -> Measurement {
        let mut out = *m;
        if let Some(offset) = self.gps_offset_ned {
            out.position_ned += offset;
        }
        if let Some(t0) = self.gps_lost_since_s {
            let tau = (m.time_s - t0).max(0.0);
            let a = DEAD_RECKONING_BIAS_M_S2 * self.drift_dir_ned;
            out.velocity_ned += a * tau;
            out.position_ned += a * (0.5 * tau * tau);
        }
        out
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
