//! Analytic references with exact derivatives up to snap, for scenarios that
//! fly a known curve instead of shaped setpoints.
//!
//! * Circle (`docs/model.md` section 10, generalised):
//!   `p_d = [r cos(w t) - r, r sin(w t), -h - a sin(w_z t)]`, `psi_d = b sin(w_y t)`;
//!   the doc's circle is `r = 1, w = 1, h = 1, a = 0.3, w_z = 0.5, b = 0.5, w_y = 0.5`.
//! * Figure-eight (Gerono lemniscate): `p_d = [a sin(w t), (a/2) sin(2 w t), -h]`, yaw fixed.
//! * Hover: `p_d` constant.

use nalgebra::Vector3;
use serde::Deserialize;

use crate::control::Reference;

/// A curve in time.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Trajectory {
    /// Hold a position and heading.
    Hover {
        /// Position [m], NED.
        position_ned: [f64; 3],
        /// Heading [deg].
        #[serde(default)]
        yaw_deg: f64,
    },
    /// The report's circle, with its parameters.
    Circle {
        /// Radius `r` [m].
        #[serde(default = "one")]
        radius_m: f64,
        /// Angular rate `w` [rad/s].
        #[serde(default = "one")]
        rate_rad_s: f64,
        /// Mean altitude `h` [m] above the NED origin.
        #[serde(default = "one")]
        altitude_m: f64,
        /// Vertical amplitude `a` [m].
        #[serde(default)]
        vertical_amplitude_m: f64,
        /// Vertical rate `w_z` [rad/s].
        #[serde(default)]
        vertical_rate_rad_s: f64,
        /// Yaw amplitude `b` [rad].
        #[serde(default)]
        yaw_amplitude_rad: f64,
        /// Yaw rate `w_y` [rad/s].
        #[serde(default)]
        yaw_rate_rad_s: f64,
    },
    /// A figure-eight (lemniscate of Gerono) at constant altitude.
    FigureEight {
        /// Half-width `a` [m] along North.
        half_width_m: f64,
        /// Angular rate `w` [rad/s] (one eight takes `2 pi / w` s).
        rate_rad_s: f64,
        /// Altitude `h` [m].
        altitude_m: f64,
    },
}

fn one() -> f64 {
    1.0
}

/// Derivatives 0..=4 in `t` of `A sin(theta)`, `theta = w t`, given
/// `(sin theta, cos theta)`.
fn sine(a: f64, w: f64, (s, c): (f64, f64)) -> [f64; 5] {
    [a * s, a * w * c, -a * w * w * s, -a * w.powi(3) * c, a * w.powi(4) * s]
}

/// `(sin 2 theta, cos 2 theta)` from `(sin theta, cos theta)`.
fn double_angle((s, c): (f64, f64)) -> (f64, f64) {
    (2.0 * s * c, (c - s) * (c + s))
}

impl Trajectory {
    /// The doc's section-10 circle.
    #[must_use]
    pub fn doc_circle() -> Self {
        Trajectory::Circle {
            radius_m: 1.0,
            rate_rad_s: 1.0,
            altitude_m: 1.0,
            vertical_amplitude_m: 0.3,
            vertical_rate_rad_s: 0.5,
            yaw_amplitude_rad: 0.5,
            yaw_rate_rad_s: 0.5,
        }
    }

    /// Every parameter finite and rates/sizes sensible; `Err((field, problem))` otherwise.
    ///
    /// # Errors
    /// The field and the problem.
    pub fn validate(&self) -> Result<(), (&'static str, String)> {
        let finite = |name: &'static str, v: f64| {
            if v.is_finite() {
                Ok(())
            } else {
                Err((name, format!("must be finite, got {v}")))
            }
        };
        match *self {
            Trajectory::Hover { position_ned, yaw_deg } => {
                position_ned.iter().try_for_each(|v| finite("position_ned", *v))?;
                finite("yaw_deg", yaw_deg)
            }
            Trajectory::Circle {
                radius_m,
                rate_rad_s,
                altitude_m,
                vertical_amplitude_m,
                vertical_rate_rad_s,
                yaw_amplitude_rad,
                yaw_rate_rad_s,
            } => {
                finite("radius_m", radius_m)?;
                finite("rate_rad_s", rate_rad_s)?;
                finite("altitude_m", altitude_m)?;
                finite("vertical_amplitude_m", vertical_amplitude_m)?;
                finite("vertical_rate_rad_s", vertical_rate_rad_s)?;
                finite("yaw_amplitude_rad", yaw_amplitude_rad)?;
                finite("yaw_rate_rad_s", yaw_rate_rad_s)
            }
            Trajectory::FigureEight {
                half_width_m,
                rate_rad_s,
                altitude_m,
            } => {
                finite("half_width_m", half_width_m)?;
                finite("altitude_m", altitude_m)?;
                if rate_rad_s.is_finite() && rate_rad_s > 0.0 {
                    Ok(())
                } else {
                    Err(("rate_rad_s", format!("must be finite and > 0, got {rate_rad_s}")))
                }
            }
        }
    }

    /// The reference at time `t` [s].
    #[must_use]
    pub fn at(&self, t: f64) -> Reference {
        let mut d = [Vector3::zeros(); 5];
        let mut yaw = [0.0; 3];
        match *self {
            Trajectory::Hover { position_ned, yaw_deg } => {
                d[0] = Vector3::from(position_ned);
                yaw[0] = yaw_deg.to_radians();
            }
            Trajectory::Circle {
                radius_m: r,
                rate_rad_s: w,
                altitude_m: h,
                vertical_amplitude_m: a,
                vertical_rate_rad_s: wz,
                yaw_amplitude_rad: b,
                yaw_rate_rad_s: wy,
            } => {
                let (s, c) = (w * t).sin_cos();
                let x = sine(r, w, (c, -s)); // r cos(w t) = r sin(w t + pi/2)
                let y = sine(r, w, (s, c));
                let z = sine(-a, wz, (wz * t).sin_cos());
                for k in 0..5 {
                    d[k] = Vector3::new(x[k], y[k], z[k]);
                }
                d[0] += Vector3::new(-r, 0.0, -h);
                let psi = sine(b, wy, (wy * t).sin_cos());
                yaw.copy_from_slice(&psi[..3]);
            }
            Trajectory::FigureEight {
                half_width_m: a,
                rate_rad_s: w,
                altitude_m: h,
            } => {
                let angle = (w * t).sin_cos();
                let x = sine(a, w, angle);
                let y = sine(0.5 * a, 2.0 * w, double_angle(angle));
                for k in 0..5 {
                    d[k] = Vector3::new(x[k], y[k], 0.0);
                }
                d[0].z = -h;
            }
        }
        Reference {
            position_ned: d[0],
            velocity_ned: d[1],
            acceleration_ned: d[2],
            jerk_ned: d[3],
            snap_ned: d[4],
            yaw_rad: yaw[0],
            yaw_rate_rad_s: yaw[1],
            yaw_accel_rad_s2: yaw[2],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each derivative equals the finite difference of the one before.
    #[test]
    fn derivatives_are_consistent() {
        let h = 1e-5;
        for traj in [
            Trajectory::doc_circle(),
            Trajectory::FigureEight {
                half_width_m: 2.0,
                rate_rad_s: 0.8,
                altitude_m: 2.0,
            },
        ] {
            for t in [0.0, 0.7, 3.1] {
                let (a, b) = (traj.at(t - h), traj.at(t + h));
                let mid = traj.at(t);
                let fd = |x: Vector3<f64>, y: Vector3<f64>| (y - x) / (2.0 * h);
                assert!((fd(a.position_ned, b.position_ned) - mid.velocity_ned).norm() < 1e-6);
                assert!((fd(a.velocity_ned, b.velocity_ned) - mid.acceleration_ned).norm() < 1e-6);
                assert!((fd(a.acceleration_ned, b.acceleration_ned) - mid.jerk_ned).norm() < 1e-6);
                assert!((fd(a.jerk_ned, b.jerk_ned) - mid.snap_ned).norm() < 1e-6);
                assert!(((b.yaw_rad - a.yaw_rad) / (2.0 * h) - mid.yaw_rate_rad_s).abs() < 1e-6);
            }
        }
        // the doc's circle starts at [0, 0, -1]
        let r0 = Trajectory::doc_circle().at(0.0);
        assert!((r0.position_ned - Vector3::new(0.0, 0.0, -1.0)).norm() < 1e-15);
    }
}
