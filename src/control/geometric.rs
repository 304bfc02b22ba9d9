//! Geometric tracking controller on SE(3): Lee, Leok, McClamroch, "Geometric
//! tracking control of a quadrotor UAV on SE(3)", IEEE CDC 2010, in the origin
//! report's notation (report section 5.1; `docs/model.md` section 5).
//!
//! NED world, FRD body, thrust along `-z_b`; `e_p = p - p_d`, `e_v = v - v_d`.
//! ```text
//! A     = -K_p e_p - K_v e_v - m g e3 + m a_d  (- f_hat)        [N], NED
//! u_T   = -A^T R e3                                             [N]
//! z_d   = -A / |A|,  x_c = [cos psi_d, sin psi_d, 0]
//! y_d   = (z_d x x_c) / |z_d x x_c|,  R_d = [y_d x z_d, y_d, z_d]
//! e_R   = 1/2 (R_d^T R - R^T R_d)^vee,  e_w = w - R^T R_d w_d
//! tau   = -K_R e_R - K_w e_w + w x I w - I (w x R^T R_d w_d - R^T R_d w_d_dot)  (- tau_hat^b)
//! ```
//! `w_d`, `w_d_dot` come from `R_d` itself (doc section 5, "numerical"):
//! `w_d,k = log(R_d,k-1^T R_d,k) / h`, `w_d_dot,k = (w_d,k - w_d,k-1) / h`, zero
//! for the first two samples and after a reset or a jump of `R_d` (a step rate
//! above [`JUMP_RATE_RAD_S`]); on the first sample `w_d` is the current rate
//! expressed in the desired frame, so a law switched in does not kick.
//! With a cutoff `f_c > 0` (`omega_dot_d_cutoff_hz`) `w_d_dot` is low-passed,
//! first order, exact for a value held over the step,
//! `y_k = y_k-1 + (w_d_dot,k - y_k-1) (1 - exp(-2 pi f_c h))`: a navigation
//! solution that moves in kinks (a filter propagated by 250 Hz IMU samples,
//! flown at 1 kHz) makes the raw second difference a train of spikes that
//! the rotors chase; `f_c = 0`, the report's law, differences raw.
//! The rates matter: with the report's gains there is
//! no time-scale separation between attitude and position, and the loop
//! diverges unless `w_d, w_d_dot` carry the feedback part of `A` (doc section 5,
//! seed erratum 4); derivatives of the reference alone are not enough.
//!
//! Guards: `A` non-finite becomes hover (`-m g e3`); `A_z <= -(1 - max_down_accel_g) m g`
//! (never command thrust pointing down); the horizontal part of `A` is scaled
//! so that `z_d` stays within `max_tilt` of vertical; the heading is taken
//! from the previous `R_d` when `|z_d x x_c|` is tiny.

use nalgebra::{Matrix3, Vector3};

use super::attitude::{AttitudeTarget, So3Gains, so3_attitude};
use super::e3;
use super::gains::{ControlLimits, GeometricGains};
use super::law::{LawInput, LawOutput};
use super::memo::Memo;
use super::sanitise::{finite_m3, finite3};
use crate::math::vee;
use crate::signals::GRAVITY;

/// Desired-attitude step rate [rad/s] above which `R_d` is treated as having
/// jumped (reference jump, guard switching): its derivatives restart at zero.
pub const JUMP_RATE_RAD_S: f64 = 30.0;

/// Internal state: the previous desired attitude and rate.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Geometric {
    prev_rd: Option<Matrix3<f64>>,
    prev_omega_d: Vector3<f64>,
    /// Desired-attitude samples since the last reset or jump.
    samples: u32,
    /// The low-passed `w_d_dot` (module doc; zero while `f_c = 0`).
    omega_dot_d: Vector3<f64>,
    /// `1 - exp(-2 pi f_c h)` for the last `(f_c, h)`.
    omega_dot_d_gain: Memo<(u64, u64), f64>,
    /// `tan(max_tilt)`: the limit rarely changes.
    tan_max_tilt: Memo<u64, f64>,
    /// `(sin psi_d, cos psi_d)`: the heading is often held.
    yaw_sin_cos: Memo<u64, (f64, f64)>,
    /// `1 / dt`: the step rarely changes.
    inv_dt: Memo<u64, f64>,
}

/// `log(R)^vee` (rotation vector) of a rotation matrix; `None` near 180 deg,
/// where the axis is ill-defined.
#[inline]
fn log_so3(m: &Matrix3<f64>) -> Option<Vector3<f64>> {
    let v = vee(m); // sin(angle) * axis
    let s2 = v.norm_squared(); // sin^2(angle): no square root on the common paths
    let c = (0.5 * (m.trace() - 1.0)).clamp(-1.0, 1.0);
    if s2 < 1e-18 {
        return (c > 0.0).then_some(v);
    }
    if s2 < 1e-4 && c > 0.0 {
        // angle / sin(angle) = asin(s)/s = 1 + s^2/6 + 3 s^4/40 + O(s^6): exact to
        // 1e-13 here, and successive desired attitudes 1 ms apart are always here
        return Some(v * (1.0 + s2 * (1.0 / 6.0 + s2 * (3.0 / 40.0))));
    }
    let s = s2.sqrt();
    let angle = s.atan2(c);
    Some(v * (angle / s))
}

impl Geometric {
    pub(super) fn reset(&mut self) {
        *self = Self::default();
    }

    /// Desired rate and acceleration from the `R_d` sequence (module doc). On
    /// the first sample after a reset or a jump there is no previous `R_d`: the
    /// desired rate is then the current one, `w_now() = R_d^T R w` (no damping
    /// kick when a law is switched in; only evaluated then).
    #[inline(always)]
    fn desired_rates(
        &mut self,
        r_d: &Matrix3<f64>,
        w_now: impl FnOnce() -> Vector3<f64>,
        dt: f64,
        max_accel: f64,
        cutoff_hz: f64,
    ) -> (Vector3<f64>, Vector3<f64>, bool) {
        let w_now = || {
            let w = w_now();
            if finite3(&w) && w.norm_squared() <= JUMP_RATE_RAD_S * JUMP_RATE_RAD_S {
                w
            } else {
                Vector3::zeros()
            }
        };
        let mut jump = false;
        let inv_dt = self.inv_dt.get(dt.to_bits(), || 1.0 / dt);
        let (w, w_dot) = match self.prev_rd {
            Some(prev) if dt > 0.0 => match log_so3(&prev.tr_mul(r_d)).map(|v| v * inv_dt) {
                Some(w) if finite3(&w) && w.norm_squared() <= JUMP_RATE_RAD_S * JUMP_RATE_RAD_S => {
                    let w_dot = if self.samples >= 2 {
                        let a = (w - self.prev_omega_d) * inv_dt;
                        let a2 = a.norm_squared();
                        if a2 > max_accel * max_accel {
                            a * (max_accel / a2.sqrt())
                        } else {
                            a
                        }
                    } else {
                        Vector3::zeros()
                    };
                    let w_dot = if cutoff_hz > 0.0 {
                        let k = self.omega_dot_d_gain.get((cutoff_hz.to_bits(), dt.to_bits()), || {
                            -(-std::f64::consts::TAU * cutoff_hz * dt).exp_m1()
                        });
                        self.omega_dot_d += (w_dot - self.omega_dot_d) * k;
                        self.omega_dot_d
                    } else {
                        w_dot
                    };
                    self.samples = self.samples.saturating_add(1);
                    (w, w_dot)
                }
                _ => {
                    jump = true;
                    self.samples = 1;
                    self.omega_dot_d = Vector3::zeros();
                    (w_now(), Vector3::zeros())
                }
            },
            // same instant again: keep the rate, no new derivative
            Some(_) => (self.prev_omega_d, Vector3::zeros()),
            None => {
                self.samples = 1;
                self.omega_dot_d = Vector3::zeros();
                (w_now(), Vector3::zeros())
            }
        };
        self.prev_rd = Some(*r_d);
        self.prev_omega_d = w;
        (w, w_dot, jump)
    }

    /// One step of the law (module doc).
    #[inline(always)]
    pub(super) fn update(&mut self, gains: &GeometricGains, input: &LawInput) -> LawOutput {
        let (model, meas, reference, limits) = (input.model, input.measurement, input.reference, input.limits);
        let m = model.mass_kg;
        let rot = meas.attitude.to_rotation_matrix();
        let r = rot.matrix();
        let weight = Vector3::new(0.0, 0.0, m * GRAVITY); // m g e3
        let a = -gains.kp_n_per_m.component_mul(&input.position_error())
            - gains.kv_n_s_per_m.component_mul(&input.velocity_error())
            - weight
            + reference.acceleration_ned * m
            - input.estimate.force_ned;
        let max_tilt = limits.max_tilt_rad;
        let tan_max_tilt = self.tan_max_tilt.get(max_tilt.to_bits(), || max_tilt.tan());
        let (a, limited) = guard_a(a, m, limits, tan_max_tilt);
        let thrust = -a.dot(&r.column(2)); // -A^T R e3
        let yaw = reference.yaw_rad;
        let yaw = self.yaw_sin_cos.get(yaw.to_bits(), || yaw.sin_cos());
        let r_d = self.desired_attitude(&a, yaw, r);
        let (w_d, w_dot_d, jump) = self.desired_rates(
            &r_d,
            || r_d.tr_mul(&(r * meas.rate_frd)),
            input.dt,
            limits.max_angular_accel_rad_s2,
            gains.omega_dot_d_cutoff_hz,
        );
        let target = AttitudeTarget {
            r_d: &r_d,
            omega_d: &w_d,
            omega_dot_d: &w_dot_d,
        };
        let out = so3_attitude(&model.inertia_kg_m2, r, &meas.rate_frd, &target, &gains.so3());
        LawOutput {
            thrust_n: thrust,
            torque_frd: out.torque - input.estimate.torque_frd,
            attitude_sp: r_d,
            rate_sp_frd: w_d,
            attitude_error: out.e_r,
            limited,
            recovery: false,
            reference_jump: jump,
        }
    }

    /// `R_d = [y_d x z_d, y_d, z_d]` with `z_d = -A/|A|` and the heading `psi_d`.
    /// `yaw` is `(sin psi_d, cos psi_d)`.
    #[inline(always)]
    fn desired_attitude(&self, a: &Vector3<f64>, yaw: (f64, f64), r: &Matrix3<f64>) -> Matrix3<f64> {
        let a2 = a.norm_squared();
        let z_d = a * (-1.0 / a2.sqrt());
        let (s, c) = yaw;
        // z_d x x_c (x_c = [c, s, 0]) is (x_c x A) / |A|: built from A itself,
        // so that its normalisation does not wait for z_d's
        let mut y = Vector3::new(s * a.z, -c * a.z, c * a.y - s * a.x);
        let mut y2 = y.norm_squared();
        if y2 < 1e-12 * a2 {
            // z_d along the heading: keep the previous desired (or current) x axis
            let x_prev = self
                .prev_rd
                .map_or_else(|| r.column(0).into_owned(), |p| p.column(0).into_owned());
            y = z_d.cross(&x_prev);
            y2 = y.norm_squared();
            if y2 < 1e-12 {
                // any axis normal to z_d
                let other = if z_d.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() };
                y = z_d.cross(&other);
                y2 = y.norm_squared();
            }
        }
        let y_d = y * (1.0 / y2.sqrt());
        let x_d = y_d.cross(&z_d);
        let r_d = Matrix3::from_columns(&[x_d, y_d, z_d]);
        if finite_m3(&r_d) { r_d } else { Matrix3::identity() }
    }
}

impl GeometricGains {
    /// The attitude loop's gains `K_R`, `K_w`.
    pub(super) fn so3(&self) -> So3Gains<'_> {
        So3Gains {
            kr: &self.kr_n_m_per_rad,
            kw: &self.komega_n_m_s_per_rad,
        }
    }
}

/// Guards on `A` (module doc) with `tan_max_tilt = tan(limits.max_tilt_rad)`;
/// returns the guarded `A` and whether it changed.
#[inline]
fn guard_a(mut a: Vector3<f64>, m: f64, limits: &ControlLimits, tan_max_tilt: f64) -> (Vector3<f64>, bool) {
    let mut limited = false;
    if !finite3(&a) {
        a = -e3() * (m * GRAVITY);
        limited = true;
    }
    let az_max = -(1.0 - limits.max_down_accel_g) * m * GRAVITY;
    if a.z > az_max {
        a.z = az_max;
        limited = true;
    }
    // |A_xy| > h_max, compared squared (h_max >= 0): a root only when limiting
    let h2 = a.x * a.x + a.y * a.y;
    let h_max = -a.z * tan_max_tilt;
    if h2 > h_max * h_max {
        let s = h_max / h2.sqrt();
        a.x *= s;
        a.y *= s;
        limited = true;
    }
    (a, limited)
}

#[cfg(test)]
mod tests {
    use super::super::Reference;
    use super::*;
    use crate::signals::{Measurement, NominalModel};
    use nalgebra::{Rotation3, UnitQuaternion};

    #[test]
    fn log_map_is_the_rotation_vector() {
        for v in [
            Vector3::new(0.1, -0.2, 0.3),
            Vector3::new(1e-7, 0.0, 2e-7),
            Vector3::new(2.5, 0.3, -0.1),
        ] {
            let m = *Rotation3::new(v).matrix();
            assert!((log_so3(&m).unwrap() - v).norm() < 1e-12, "{v}");
        }
        assert!(log_so3(&Matrix3::from_diagonal(&Vector3::new(1.0, -1.0, -1.0))).is_none());
    }

    /// GIVEN hover on the reference WHEN the law runs THEN u_T = m g, R_d = I and no torque.
    #[test]
    fn hover_on_reference_is_an_equilibrium() {
        let model = NominalModel {
            mass_kg: 1.5,
            inertia_kg_m2: Matrix3::from_diagonal(&Vector3::new(1.2416, 1.2416, 2.4832)),
        };
        let gains = super::super::ControlGains::report();
        let meas = Measurement {
            time_s: 0.0,
            position_ned: Vector3::new(0.0, 0.0, -1.0),
            velocity_ned: Vector3::zeros(),
            attitude: UnitQuaternion::identity(),
            rate_frd: Vector3::zeros(),
        };
        let reference = Reference::hold(meas.position_ned, 0.0);
        let mut g = Geometric::default();
        for _ in 0..3 {
            let out = g.update(
                &gains.geometric,
                &LawInput::without_estimate(&model, &meas, &reference, &gains.limits),
            );
            assert!((out.thrust_n - 1.5 * GRAVITY).abs() < 1e-12);
            assert!(out.torque_frd.norm() < 1e-12);
            assert!((out.attitude_sp - Matrix3::identity()).norm() < 1e-12);
        }
    }

    /// GIVEN R_d rotating at a constant rate WHEN sampled THEN w_d is that rate,
    /// w_d_dot is zero for the first two samples, and a 90-degree jump restarts both.
    #[test]
    fn numerical_rates_restart_after_a_jump() {
        let mut g = Geometric::default();
        let w = Vector3::new(0.2, -0.1, 0.5);
        let h = 1e-3;
        let mut outs = vec![];
        for k in 0..4 {
            let r = *Rotation3::new(w * (f64::from(k) * h)).matrix();
            outs.push(g.desired_rates(&r, Vector3::zeros, h, 1e3, 0.0));
        }
        assert_eq!(outs[0].0, Vector3::zeros());
        assert!((outs[1].0 - w).norm() < 1e-9 && outs[1].1 == Vector3::zeros());
        assert!((outs[3].0 - w).norm() < 1e-9 && outs[3].1.norm() < 1e-5);
        let now = Vector3::new(0.1, 0.0, 0.0);
        let jumped = g.desired_rates(
            Rotation3::new(Vector3::new(1.5, 0.0, 0.0)).matrix(),
            || now,
            h,
            1e3,
            0.0,
        );
        assert!(jumped.2 && jumped.0 == now && jumped.1 == Vector3::zeros());
    }

    /// With a cutoff `f_c`, a desired attitude that starts turning at a
    /// constant acceleration `alpha` gives `w_d_dot` rising as
    /// `alpha (1 - exp(-2 pi f_c t))`; the cutoff 0 gives `alpha` at once.
    #[test]
    fn the_low_pass_on_w_d_dot_follows_a_first_order_rise() {
        let alpha = Vector3::new(2.0, -1.0, 0.5);
        let h = 1e-3;
        let run = |cutoff_hz: f64| {
            let mut g = Geometric::default();
            (0..=40)
                .map(|k| {
                    let t = f64::from(k) * h;
                    let r = *Rotation3::new(alpha * (0.5 * t * t)).matrix();
                    g.desired_rates(&r, Vector3::zeros, h, 1e3, cutoff_hz).1
                })
                .collect::<Vec<_>>()
        };
        let raw = run(0.0);
        assert!((raw[40] - alpha).norm() < 1e-3 * alpha.norm(), "{:?}", raw[40]);
        let smooth = run(10.0);
        // the third sample gives the first w_d_dot: 39 updates by sample 40
        let t = 39.0 * h;
        let expected = alpha * (1.0 - (-std::f64::consts::TAU * 10.0 * t).exp());
        assert!(
            (smooth[40] - expected).norm() < 1e-3 * alpha.norm(),
            "{:?} vs {expected:?}",
            smooth[40]
        );
        assert!(smooth[40].norm() < 0.95 * alpha.norm());
    }
}
