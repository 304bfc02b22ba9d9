//! The RPY laws' attitude setpoint (doc section 4): the inversion of the
//! translational model for thrust and roll/pitch,
//! ```text
//! m mu = m g e3 - u_T R(eta_d) e3
//! u_T     = m sqrt(mu_x^2 + mu_y^2 + (mu_z - g)^2)
//! phi_d   = asin(m (mu_y c_psi - mu_x s_psi) / u_T)
//! theta_d = atan2(-(mu_x c_psi + mu_y s_psi), g - mu_z)
//! ```
//! with its guards, the derivatives of `phi_d, theta_d` by the
//! [`DerivativeFilter`], and the recovery: above `recovery_tilt` the attitude
//! goes to the SO(3) loop on `R(eta_d)` with
//! ```text
//! w_d = Q(eta_d) eta_d',   w_d' = Q(eta_d) eta_d'' + Q_dot(eta_d, eta_d') eta_d'
//! u_T max(0, (R e3) . (R_d e3))                     thrust along the current body axis
//! ```
//! until the tilt is back below the midpoint of `max_tilt` and `recovery_tilt`.
//! Both RPY laws run the same step ([`RpyStage::step`]) and differ only in
//! `mu`, the inner-loop torque and the recovery gains.

use nalgebra::{Matrix3, Vector2, Vector3};

use super::attitude::{AttitudeTarget, So3Gains, so3_attitude};
use super::derivative_filter::DerivativeFilter;
use super::euler::{EulerTrig, MeasuredEuler, RateMapInverse, unit_angle};
use super::gains::ControlLimits;
use super::law::{LawInput, LawOutput};
use super::memo::Memo;
use super::sanitise::finite3;
use crate::math::wrap_pi;
use crate::signals::GRAVITY;

/// Thrust and roll/pitch setpoints from a desired acceleration, doc section 4.
#[derive(Clone, Copy, Debug)]
struct ThrustAttitude {
    /// `u_T` [N].
    thrust_n: f64,
    /// `phi_d` [rad].
    roll: f64,
    /// `theta_d` [rad].
    pitch: f64,
    /// `(sin phi_d, cos phi_d)`.
    roll_sin_cos: (f64, f64),
    /// `(sin theta_d, cos theta_d)`.
    pitch_sin_cos: (f64, f64),
    /// A guard changed the request.
    limited: bool,
}

/// Invert `m mu = m g e3 - u_T R(eta_d) e3` for `u_T, phi_d, theta_d` given
/// `psi_sin_cos = (sin psi_d, cos psi_d)`:
/// `u_T = m sqrt(mu_x^2 + mu_y^2 + (mu_z - g)^2)`,
/// `phi_d = asin(m (mu_y c_psi - mu_x s_psi) / u_T)`,
/// `theta_d = atan2(-(mu_x c_psi + mu_y s_psi), g - mu_z)`.
/// Guards (doc section 4): `mu_z <= max_down_accel_g g`, horizontal part
/// scaled so that the tilt stays within `max_tilt` (`tan_max_tilt = tan(max_tilt)`),
/// `asin` argument clamped, `|phi_d|, |theta_d| <= max_tilt`.
/// The sines and cosines of `phi_d, theta_d` come from the same ratios
/// (`cos phi_d = sqrt(1 - sin^2 phi_d)`, `(sin, cos) theta_d = (y, x) / |(x, y)|`
/// of the `atan2` arguments, the angle then by [`unit_angle`]) unless a tilt
/// clamp changed the angle.
fn thrust_and_angles(
    mu: &Vector3<f64>,
    psi_sin_cos: (f64, f64),
    mass: f64,
    limits: &ControlLimits,
    tan_max_tilt: f64,
) -> ThrustAttitude {
    let g = GRAVITY;
    let mut limited = false;
    let mut mu = if finite3(mu) {
        *mu
    } else {
        limited = true;
        Vector3::zeros()
    };
    let mz_max = limits.max_down_accel_g * g;
    if mu.z > mz_max {
        mu.z = mz_max;
        limited = true;
    }
    let vertical = g - mu.z; // > 0
    let h = mu.xy().norm();
    let h_max = vertical * tan_max_tilt;
    if h > h_max {
        let s = h_max / h;
        mu.x *= s;
        mu.y *= s;
        limited = true;
    }
    let u = mass * (mu.x * mu.x + mu.y * mu.y + vertical * vertical).sqrt();
    let (s_psi, c_psi) = psi_sin_cos;
    let s_phi = (mass * (mu.y * c_psi - mu.x * s_psi) / u).clamp(-1.0, 1.0);
    let tilt = limits.max_tilt_rad;
    let asin = s_phi.asin();
    let roll = asin.clamp(-tilt, tilt);
    let roll_sin_cos = if roll == asin {
        (s_phi, (1.0 - s_phi * s_phi).sqrt())
    } else {
        roll.sin_cos()
    };
    let forward = -(mu.x * c_psi + mu.y * s_psi);
    let n = (forward * forward + vertical * vertical).sqrt();
    let unit = (forward / n, vertical / n);
    let atan = unit_angle(unit.0, unit.1); // atan2(forward, vertical)
    let pitch = atan.clamp(-tilt, tilt);
    let pitch_sin_cos = if pitch == atan { unit } else { pitch.sin_cos() };
    ThrustAttitude {
        thrust_n: u,
        roll,
        pitch,
        roll_sin_cos,
        pitch_sin_cos,
        limited,
    }
}

/// Thrust along the current body axis in recovery: `u_T max(0, (R e3) . (R_d e3))`.
fn projected_thrust(thrust: f64, r: &Matrix3<f64>, r_d: &Matrix3<f64>) -> f64 {
    thrust * (r.column(2).dot(&r_d.column(2))).max(0.0)
}

/// Wrap each Euler-angle error to `(-pi, pi]` (errors already inside are kept as they are).
pub(super) fn wrap3(v: &Vector3<f64>) -> Vector3<f64> {
    v.map(|a| if a.abs() < std::f64::consts::PI { a } else { wrap_pi(a) })
}

/// The attitude setpoint of the RPY laws: `eta_d` (with its sines and
/// cosines) and its derivatives, the thrust, and whether the attitude goes
/// to the SO(3) loop (recovery).
#[derive(Clone, Copy, Debug)]
pub(super) struct RpySetpoint {
    pub(super) thrust_n: f64,
    pub(super) eta_d: Vector3<f64>,
    pub(super) trig: EulerTrig,
    pub(super) eta_d_dot: Vector3<f64>,
    pub(super) eta_d_ddot: Vector3<f64>,
    pub(super) limited: bool,
    pub(super) recovery: bool,
}

impl RpySetpoint {
    /// `R(eta_d)`.
    fn rotation(&self) -> Matrix3<f64> {
        self.trig.rotation()
    }

    /// `omega_d = Q(eta_d) eta_d_dot` [rad/s], desired body frame.
    fn body_rate(&self) -> Vector3<f64> {
        self.trig.q_mul(&self.eta_d_dot)
    }

    /// `w_d' = Q(eta_d) eta_d'' + Q_dot(eta_d, eta_d') eta_d'` [rad/s^2], desired body frame.
    fn body_acceleration(&self) -> Vector3<f64> {
        self.trig.q_mul(&self.eta_d_ddot) + self.trig.q_dot_mul(&self.eta_d_dot, &self.eta_d_dot)
    }
}

/// What an RPY law's inner loop reads, away from recovery and from
/// `theta = +-90 deg`: the measured attitude's Euler trigonometry, `Q^-1`, the
/// measured `eta'`, the setpoint, and the errors `e = wrap(eta - eta_d)`,
/// `e' = eta' - eta_d'`.
#[derive(Clone, Copy, Debug)]
pub(super) struct EulerTracking<'a> {
    /// `sin`/`cos` of the measured `eta` (for `Q v`, `Q_dot v`).
    pub(super) trig: &'a EulerTrig,
    pub(super) q_inv: RateMapInverse,
    pub(super) eta_dot: Vector3<f64>,
    pub(super) sp: &'a RpySetpoint,
    pub(super) e: Vector3<f64>,
    pub(super) e_dot: Vector3<f64>,
}

/// State shared by the RPY laws between the translational law and the attitude
/// loop: the `phi_d, theta_d` derivative filter, the recovery latch, and the
/// memos of `tan(max_tilt)` and of the heading's sine and cosine.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct RpyStage {
    filter: DerivativeFilter,
    latch: RecoveryLatch,
    tan_max_tilt: Memo<u64, f64>,
    yaw_sin_cos: Memo<u64, (f64, f64)>,
}

impl RpyStage {
    pub(super) fn reset(&mut self) {
        self.filter.reset();
        self.latch.reset();
    }

    /// The attitude half of an RPY law from its desired acceleration `mu`
    /// [m/s^2] (NED): the setpoint ([`Self::setpoint`], `phi_d, theta_d`
    /// filtered at `filter_rad_s`), then either the law's own `inner_torque`
    /// tau^b [N m] (FRD) on the Euler errors, or, in recovery or at
    /// `theta = +-90 deg`, the SO(3) loop on `R(eta_d)` with the law's
    /// `recovery_gains` `(K_R, K_w)` and the projected thrust (module doc).
    #[inline]
    pub(super) fn step(
        &mut self,
        input: &LawInput,
        mu: &Vector3<f64>,
        filter_rad_s: f64,
        inner_torque: impl FnOnce(&EulerTracking) -> Vector3<f64>,
        recovery_gains: impl FnOnce() -> (Vector3<f64>, Vector3<f64>),
    ) -> LawOutput {
        let meas = input.measurement;
        let rot = meas.attitude.to_rotation_matrix();
        let r = rot.matrix();
        let now = MeasuredEuler::new(r, &meas.rate_frd);
        let sp = self.setpoint(input, mu, filter_rad_s, r[(2, 2)], &now.filter_start());
        match (sp.recovery, now.rates) {
            (false, Some((q_inv, eta_dot))) => {
                let e = wrap3(&(now.eta - sp.eta_d));
                let e_dot = eta_dot - sp.eta_d_dot;
                let torque = inner_torque(&EulerTracking {
                    trig: &now.trig,
                    q_inv,
                    eta_dot,
                    sp: &sp,
                    e,
                    e_dot,
                });
                LawOutput {
                    thrust_n: sp.thrust_n,
                    torque_frd: torque,
                    attitude_sp: sp.rotation(),
                    rate_sp_frd: sp.body_rate(),
                    attitude_error: e,
                    limited: sp.limited,
                    recovery: false,
                    reference_jump: false,
                }
            }
            _ => {
                let (r_d, w_d, w_d_dot) = (sp.rotation(), sp.body_rate(), sp.body_acceleration());
                let target = AttitudeTarget {
                    r_d: &r_d,
                    omega_d: &w_d,
                    omega_dot_d: &w_d_dot,
                };
                let (kr, kw) = recovery_gains();
                let out = so3_attitude(
                    &input.model.inertia_kg_m2,
                    r,
                    &meas.rate_frd,
                    &target,
                    &So3Gains { kr: &kr, kw: &kw },
                );
                LawOutput {
                    thrust_n: projected_thrust(sp.thrust_n, r, &r_d),
                    torque_frd: out.torque - input.estimate.torque_frd,
                    attitude_sp: r_d,
                    rate_sp_frd: w_d,
                    attitude_error: out.e_r,
                    limited: sp.limited,
                    recovery: true,
                    reference_jump: false,
                }
            }
        }
    }

    /// From the desired acceleration `mu` [m/s^2]: `u_T, phi_d, theta_d` (doc
    /// section 4, with guards), roll/pitch derivatives by the filter (started
    /// at the measured Euler rates `eta_dot_now` after a reset), yaw and its
    /// derivatives from the reference. `cos_tilt = r33` of the measured attitude
    /// drives the recovery latch.
    fn setpoint(
        &mut self,
        input: &LawInput,
        mu: &Vector3<f64>,
        filter_rad_s: f64,
        cos_tilt: f64,
        eta_dot_now: &Vector3<f64>,
    ) -> RpySetpoint {
        let (reference, limits) = (input.reference, input.limits);
        let max_tilt = limits.max_tilt_rad;
        let tan_max_tilt = self.tan_max_tilt.get(max_tilt.to_bits(), || max_tilt.tan());
        let yaw = reference.yaw_rad;
        let yaw_sin_cos = self.yaw_sin_cos.get(yaw.to_bits(), || yaw.sin_cos());
        let ta = thrust_and_angles(mu, yaw_sin_cos, input.model.mass_kg, limits, tan_max_tilt);
        let (rate, acc) = self.filter.update(
            &Vector2::new(ta.roll, ta.pitch),
            &eta_dot_now.xy(),
            filter_rad_s,
            input.dt,
        );
        let recovery = self.latch.update(cos_tilt, limits);
        RpySetpoint {
            thrust_n: ta.thrust_n,
            eta_d: Vector3::new(ta.roll, ta.pitch, yaw),
            trig: EulerTrig::new(ta.roll_sin_cos, ta.pitch_sin_cos, yaw_sin_cos),
            eta_d_dot: Vector3::new(rate.x, rate.y, reference.yaw_rate_rad_s),
            eta_d_ddot: Vector3::new(acc.x, acc.y, reference.yaw_accel_rad_s2),
            limited: ta.limited,
            recovery,
        }
    }
}

/// Hysteresis on the tilt for handing RPY laws to the SO(3) attitude loop:
/// on above `recovery_tilt`, off below the midpoint of `max_tilt` and
/// `recovery_tilt`. Compared as cosines (`cos tilt = r33`), the thresholds'
/// cosines kept in a memo.
#[derive(Clone, Copy, Debug, Default)]
struct RecoveryLatch {
    active: bool,
    /// `(cos recovery_tilt, cos exit)` for the last `(max_tilt, recovery_tilt)`.
    cos_thresholds: Memo<(u64, u64), (f64, f64)>,
}

impl RecoveryLatch {
    fn reset(&mut self) {
        self.active = false;
    }

    /// `cos_tilt` = cosine of the angle between body `z` and NED down (`r33`;
    /// the tilt is `>= |theta|`).
    fn update(&mut self, cos_tilt: f64, limits: &ControlLimits) -> bool {
        let (max_tilt, recovery_tilt) = (limits.max_tilt_rad, limits.recovery_tilt_rad);
        let (cos_enter, cos_exit) = self
            .cos_thresholds
            .get((max_tilt.to_bits(), recovery_tilt.to_bits()), || {
                (recovery_tilt.cos(), (0.5 * (max_tilt + recovery_tilt)).cos())
            });
        // tilt > recovery_tilt, or not finite
        if cos_tilt.is_nan() || cos_tilt < cos_enter {
            self.active = true;
        } else if cos_tilt > cos_exit {
            self.active = false;
        }
        self.active
    }
}

#[cfg(test)]
mod tests {
    use super::super::e3;
    use super::*;

    #[test]
    fn thrust_and_angles_inverts_the_translational_model() {
        let limits = ControlLimits::default();
        let mu = Vector3::new(1.0, -2.0, -0.5);
        let psi = 0.7;
        let ta = thrust_and_angles(&mu, f64::sin_cos(psi), 1.5, &limits, limits.max_tilt_rad.tan());
        assert!(!ta.limited);
        let r = crate::math::from_euler_zyx(&Vector3::new(ta.roll, ta.pitch, psi));
        // m mu = m g e3 - u_T R e3
        let acc = e3() * GRAVITY - (r * e3()) * (ta.thrust_n / 1.5);
        assert!((acc - mu).norm() < 1e-12);
    }

    #[test]
    fn thrust_and_angles_guards_free_fall_and_tilt() {
        let limits = ControlLimits::default();
        for mu in [Vector3::new(0.0, 0.0, GRAVITY), Vector3::new(1e9, 0.0, 5.0 * GRAVITY)] {
            let ta = thrust_and_angles(&mu, 0.3f64.sin_cos(), 2.0, &limits, limits.max_tilt_rad.tan());
            assert!(ta.limited && ta.thrust_n >= 0.1 * 2.0 * GRAVITY * (1.0 - 1e-12));
            assert!(ta.roll.abs() <= limits.max_tilt_rad && ta.pitch.abs() <= limits.max_tilt_rad);
        }
    }

    /// GIVEN ramps and a parabola WHEN filtered at w = 60 rad/s THEN the rate is

    #[test]
    fn thrust_and_angles_sines_match_the_angles() {
        let limits = ControlLimits::default();
        let tan = limits.max_tilt_rad.tan();
        for mu in [Vector3::new(1.0, -2.0, -0.5), Vector3::new(40.0, 30.0, 0.0)] {
            let ta = thrust_and_angles(&mu, 0.7f64.sin_cos(), 1.5, &limits, tan);
            let (s, c) = ta.roll.sin_cos();
            assert!((ta.roll_sin_cos.0 - s).abs() < 1e-15 && (ta.roll_sin_cos.1 - c).abs() < 1e-15);
            let (s, c) = ta.pitch.sin_cos();
            assert!((ta.pitch_sin_cos.0 - s).abs() < 1e-15 && (ta.pitch_sin_cos.1 - c).abs() < 1e-15);
        }
    }
}
