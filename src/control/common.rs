//! Pieces shared by the laws: input checks, the RPY outer-loop inversion
//! (doc section 4), the derivative filter for `phi_d, theta_d`, the SO(3)
//! attitude loop (doc section 5) and output saturation.

use nalgebra::{Matrix3, Vector2, Vector3};

use super::Reference;
use super::gains::ControlLimits;
use crate::airframe::{ControlWrench, GRAVITY};
use crate::math::{euler_zyx, from_euler_zyx, hat, rate_map, rate_map_dot, vee, wrap_pi};
use crate::signals::{Measurement, NominalModel, WrenchEstimate};

/// `e3 = [0, 0, 1]`: NED down.
pub(super) fn e3() -> Vector3<f64> {
    Vector3::new(0.0, 0.0, 1.0)
}

pub(super) fn finite3(v: &Vector3<f64>) -> bool {
    v.x.is_finite() && v.y.is_finite() && v.z.is_finite()
}

pub(super) fn finite_m3(m: &Matrix3<f64>) -> bool {
    m.as_slice().iter().all(|x| x.is_finite())
}

/// Whether a measurement can be used at all.
pub(super) fn measurement_ok(m: &Measurement) -> bool {
    finite3(&m.position_ned)
        && finite3(&m.velocity_ned)
        && finite3(&m.rate_frd)
        && m.attitude.coords.as_slice().iter().all(|x| x.is_finite())
        && (m.attitude.coords.norm() - 1.0).abs() < 1e-6
}

/// Whether the nominal model is usable: positive finite mass, finite inertia with a positive diagonal.
pub(super) fn model_ok(m: &NominalModel) -> bool {
    m.mass_kg.is_finite()
        && m.mass_kg > 0.0
        && finite_m3(&m.inertia_kg_m2)
        && (0..3).all(|k| m.inertia_kg_m2[(k, k)] > 0.0)
}

/// The inertia diagonal `[I_xx, I_yy, I_zz]` [kg m^2].
pub(super) fn inertia_diag(m: &NominalModel) -> Vector3<f64> {
    Vector3::new(
        m.inertia_kg_m2[(0, 0)],
        m.inertia_kg_m2[(1, 1)],
        m.inertia_kg_m2[(2, 2)],
    )
}

/// The reference with every non-finite part replaced by a hold at the measured pose.
pub(super) fn sanitize_reference(r: &Reference, meas: &Measurement) -> (Reference, bool) {
    let mut out = *r;
    let mut bad = false;
    let mut fix = |v: &mut Vector3<f64>, hold: Vector3<f64>| {
        if !finite3(v) {
            *v = hold;
            bad = true;
        }
    };
    fix(&mut out.position_ned, meas.position_ned);
    fix(&mut out.velocity_ned, Vector3::zeros());
    fix(&mut out.acceleration_ned, Vector3::zeros());
    fix(&mut out.jerk_ned, Vector3::zeros());
    fix(&mut out.snap_ned, Vector3::zeros());
    let mut fix_s = |x: &mut f64, hold: f64| {
        if !x.is_finite() {
            *x = hold;
            bad = true;
        }
    };
    if !out.yaw_rad.is_finite() {
        // only now pay for the Euler angles
        fix_s(&mut out.yaw_rad, euler_zyx(&meas.attitude).z);
    }
    fix_s(&mut out.yaw_rate_rad_s, 0.0);
    fix_s(&mut out.yaw_accel_rad_s2, 0.0);
    (out, bad)
}

/// The estimate with non-finite parts dropped and magnitudes limited to what
/// the vehicle could counter (`max_thrust_g m g`, `I_ii max_angular_accel`).
pub(super) fn sanitize_estimate(
    e: Option<&WrenchEstimate>,
    model: &NominalModel,
    limits: &ControlLimits,
) -> WrenchEstimate {
    let Some(e) = e else {
        return WrenchEstimate::default();
    };
    let f_max = limits.max_thrust_g * model.mass_kg * GRAVITY;
    let t_max = inertia_diag(model) * limits.max_angular_accel_rad_s2;
    let cap = |v: &Vector3<f64>, max: f64| {
        if !finite3(v) {
            Vector3::zeros()
        } else if v.norm() > max {
            v * (max / v.norm())
        } else {
            *v
        }
    };
    let clamp_axes = |v: &Vector3<f64>| {
        Vector3::from_fn(|k, _| {
            if v[k].is_finite() {
                v[k].clamp(-t_max[k], t_max[k])
            } else {
                0.0
            }
        })
    };
    WrenchEstimate {
        force_ned: cap(&e.force_ned, f_max),
        torque_rpy: clamp_axes(&e.torque_rpy),
        torque_frd: clamp_axes(&e.torque_frd),
        mass_kg: if e.mass_kg.is_finite() {
            e.mass_kg
        } else {
            model.mass_kg
        },
    }
}

/// Thrust and roll/pitch setpoints from a desired acceleration, doc section 4.
#[derive(Clone, Copy, Debug)]
pub(super) struct ThrustAttitude {
    /// `u_T` [N].
    pub(super) thrust_n: f64,
    /// `phi_d` [rad].
    pub(super) roll: f64,
    /// `theta_d` [rad].
    pub(super) pitch: f64,
    /// A guard changed the request.
    pub(super) limited: bool,
}

/// Invert `m mu = m g e3 - u_T R(eta_d) e3` for `u_T, phi_d, theta_d` given `psi_d`:
/// `u_T = m sqrt(mu_x^2 + mu_y^2 + (mu_z - g)^2)`,
/// `phi_d = asin(m (mu_y c_psi - mu_x s_psi) / u_T)`,
/// `theta_d = atan2(-(mu_x c_psi + mu_y s_psi), g - mu_z)`.
/// Guards (doc section 4): `mu_z <= max_down_accel_g g`, horizontal part
/// scaled so that the tilt stays within `max_tilt`, `asin` argument clamped,
/// `|phi_d|, |theta_d| <= max_tilt`.
pub(super) fn thrust_and_angles(mu: &Vector3<f64>, psi_d: f64, mass: f64, limits: &ControlLimits) -> ThrustAttitude {
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
    let h_max = vertical * limits.max_tilt_rad.tan();
    if h > h_max {
        let s = h_max / h;
        mu.x *= s;
        mu.y *= s;
        limited = true;
    }
    let u = mass * (mu.x * mu.x + mu.y * mu.y + vertical * vertical).sqrt();
    let (s_psi, c_psi) = psi_d.sin_cos();
    let s_phi = (mass * (mu.y * c_psi - mu.x * s_psi) / u).clamp(-1.0, 1.0);
    let tilt = limits.max_tilt_rad;
    let roll = s_phi.asin().clamp(-tilt, tilt);
    let pitch = (-(mu.x * c_psi + mu.y * s_psi)).atan2(vertical).clamp(-tilt, tilt);
    ThrustAttitude {
        thrust_n: u,
        roll,
        pitch,
        limited,
    }
}

/// Critically damped second-order filter per channel,
/// `x'' = w^2 (u - x) - 2 w x'`, giving the derivatives `x', x''` of a kinked
/// signal (prototype: `phi_d, theta_d` with `w = 60 rad/s`, doc section 4).
/// Discretized exactly for an input interpolated linearly between samples
/// (first-order hold), so a ramp gives its slope and zero acceleration with
/// no sampling bias; the mean delay is `2 / w`.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct DerivativeFilter {
    x: Vector2<f64>,
    v: Vector2<f64>,
    u_prev: Vector2<f64>,
    initialized: bool,
}

impl DerivativeFilter {
    pub(super) fn reset(&mut self) {
        *self = Self::default();
    }

    /// Feed the sample `u` taken `dt` after the previous one; returns `(x', x'')`.
    /// The first sample after a reset initialises the filter in its steady
    /// state on a ramp through `u` of slope `v_init` (e.g. the measured rate, so
    /// that a law switched in starts without a rate-error or acceleration kick).
    pub(super) fn update(
        &mut self,
        u: &Vector2<f64>,
        v_init: &Vector2<f64>,
        w: f64,
        dt: f64,
    ) -> (Vector2<f64>, Vector2<f64>) {
        let u_ok = u.iter().all(|x| x.is_finite());
        if !self.initialized || !u_ok {
            // steady state on a ramp of slope v_init through u: x lags u by 2 v_init / w
            let u0 = if u_ok { *u } else { Vector2::zeros() };
            self.v = if v_init.iter().all(|x| x.is_finite()) {
                *v_init
            } else {
                Vector2::zeros()
            };
            self.x = u0 - self.v * (2.0 / w);
            self.u_prev = u0;
            self.initialized = true;
            return (self.v, Vector2::zeros());
        }
        if dt > 0.0 {
            // particular solution for the ramp u_prev + r t: x_p = u - 2 r / w, x_p' = r;
            // the error e = x - x_p obeys the homogeneous equation.
            let r = (u - self.u_prev) / dt;
            let e0 = self.x - (self.u_prev - r * (2.0 / w));
            let ed0 = self.v - r;
            let decay = (-w * dt).exp();
            let c2 = ed0 + e0 * w;
            let e1 = (e0 + c2 * dt) * decay;
            let ed1 = (ed0 - c2 * (w * dt)) * decay;
            self.x = u - r * (2.0 / w) + e1;
            self.v = r + ed1;
            self.u_prev = *u;
        }
        let acc = (u - self.x) * (w * w) - self.v * (2.0 * w);
        (self.v, acc)
    }
}

/// Attitude-loop result.
#[derive(Clone, Copy, Debug)]
pub(super) struct So3Output {
    pub(super) torque: Vector3<f64>,
    /// `e_R` [rad].
    pub(super) e_r: Vector3<f64>,
}

/// The geometric attitude loop (Lee, Leok, McClamroch 2010; doc section 5):
/// `e_R = 1/2 (R_d^T R - R^T R_d)^vee`, `e_w = w - R^T R_d w_d`,
/// `tau = -K_R e_R - K_w e_w + w x I w - I (w x R^T R_d w_d - R^T R_d w_d_dot)`.
/// `omega_d`, `omega_dot_d` are in the desired body frame.
#[allow(clippy::too_many_arguments)]
pub(super) fn so3_attitude(
    inertia: &Matrix3<f64>,
    r: &Matrix3<f64>,
    omega: &Vector3<f64>,
    r_d: &Matrix3<f64>,
    omega_d: &Vector3<f64>,
    omega_dot_d: &Vector3<f64>,
    kr: &Vector3<f64>,
    kw: &Vector3<f64>,
) -> So3Output {
    let rt_rd = r.transpose() * r_d;
    let e_r = vee(&(r_d.transpose() * r));
    let w_d_body = rt_rd * omega_d;
    let e_w = omega - w_d_body;
    let torque = -kr.component_mul(&e_r) - kw.component_mul(&e_w) + omega.cross(&(inertia * omega))
        - inertia * (hat(omega) * w_d_body - rt_rd * omega_dot_d);
    So3Output { torque, e_r }
}

/// What a law computed in one step (before output saturation).
#[derive(Clone, Copy, Debug)]
pub(super) struct LawOutput {
    /// `u_T` [N].
    pub(super) thrust_n: f64,
    /// `tau^b` [N m], FRD.
    pub(super) torque_frd: Vector3<f64>,
    /// Desired attitude `R_d` (FRD to NED).
    pub(super) attitude_sp: Matrix3<f64>,
    /// Desired body rate `omega_d` [rad/s] in the desired body frame.
    pub(super) rate_sp_frd: Vector3<f64>,
    /// Attitude error [rad]: `e_R` (SO(3) loop) or `e_eta` (RPY loop).
    pub(super) attitude_error: Vector3<f64>,
    /// A guard (tilt, vertical acceleration, non-finite value) changed the request.
    pub(super) limited: bool,
    /// The RPY law handed its attitude to the SO(3) loop.
    pub(super) recovery: bool,
    /// The desired attitude jumped; its derivatives were restarted.
    pub(super) reference_jump: bool,
}

/// The SO(3) loop driven by an RPY setpoint (recovery mode of the RPY laws):
/// `R_d = R(eta_d)`, `omega_d = Q(eta_d) eta_d_dot`,
/// `omega_d_dot = Q(eta_d) eta_d_ddot + Q_dot(eta_d, eta_d_dot) eta_d_dot`.
/// Returns the torque (estimate `tau_hat^b` subtracted), `e_R`, `R_d` and `omega_d`.
#[allow(clippy::too_many_arguments)]
pub(super) fn rpy_setpoint_on_so3(
    inertia: &Matrix3<f64>,
    r: &Matrix3<f64>,
    omega: &Vector3<f64>,
    eta_d: &Vector3<f64>,
    eta_d_dot: &Vector3<f64>,
    eta_d_ddot: &Vector3<f64>,
    kr: &Vector3<f64>,
    kw: &Vector3<f64>,
    tau_hat_frd: &Vector3<f64>,
) -> (So3Output, Matrix3<f64>, Vector3<f64>) {
    let r_d = *from_euler_zyx(eta_d).to_rotation_matrix().matrix();
    let q_d = rate_map(eta_d);
    let w_d = q_d * eta_d_dot;
    let w_d_dot = q_d * eta_d_ddot + rate_map_dot(eta_d, eta_d_dot) * eta_d_dot;
    let mut out = so3_attitude(inertia, r, omega, &r_d, &w_d, &w_d_dot, kr, kw);
    out.torque -= tau_hat_frd;
    (out, r_d, w_d)
}

/// Thrust along the current body axis in recovery: `u_T max(0, (R e3) . (R_d e3))`.
pub(super) fn projected_thrust(thrust: f64, r: &Matrix3<f64>, r_d: &Matrix3<f64>) -> f64 {
    thrust * (r.column(2).dot(&r_d.column(2))).max(0.0)
}

/// `Q^{-1}` and `Q^{-T}` of the ZYX rate map, `None` when `|det Q| = |cos theta|` is tiny.
pub(super) fn rate_map_solve(q: &Matrix3<f64>) -> Option<(Matrix3<f64>, Matrix3<f64>)> {
    if q.determinant().abs() < 1e-6 {
        return None;
    }
    let inv = q.try_inverse()?;
    finite_m3(&inv).then(|| (inv, inv.transpose()))
}

/// Wrap each Euler-angle error to `(-pi, pi]`.
pub(super) fn wrap3(v: &Vector3<f64>) -> Vector3<f64> {
    v.map(wrap_pi)
}

/// The attitude setpoint of the RPY laws: `eta_d` and its derivatives, the thrust,
/// and whether the attitude goes to the SO(3) loop (recovery).
#[derive(Clone, Copy, Debug)]
pub(super) struct RpySetpoint {
    pub(super) thrust_n: f64,
    pub(super) eta_d: Vector3<f64>,
    pub(super) eta_d_dot: Vector3<f64>,
    pub(super) eta_d_ddot: Vector3<f64>,
    pub(super) limited: bool,
    pub(super) recovery: bool,
}

/// State shared by the RPY laws between the translational law and the attitude
/// loop: the `phi_d, theta_d` derivative filter and the recovery latch.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct RpyStage {
    filter: DerivativeFilter,
    latch: RecoveryLatch,
}

impl RpyStage {
    pub(super) fn reset(&mut self) {
        self.filter.reset();
        self.latch.reset();
    }

    /// From the desired acceleration `mu` [m/s^2]: `u_T, phi_d, theta_d` (doc
    /// section 4, with guards), roll/pitch derivatives by the filter (started
    /// at the measured Euler rates `eta_dot_now` after a reset), yaw and its
    /// derivatives from the reference.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn setpoint(
        &mut self,
        mu: &Vector3<f64>,
        reference: &Reference,
        mass: f64,
        limits: &ControlLimits,
        filter_rad_s: f64,
        r: &Matrix3<f64>,
        eta_dot_now: &Vector3<f64>,
        dt: f64,
    ) -> RpySetpoint {
        let ta = thrust_and_angles(mu, reference.yaw_rad, mass, limits);
        let (rate, acc) = self
            .filter
            .update(&Vector2::new(ta.roll, ta.pitch), &eta_dot_now.xy(), filter_rad_s, dt);
        let recovery = self.latch.update(tilt_of(r), limits);
        RpySetpoint {
            thrust_n: ta.thrust_n,
            eta_d: Vector3::new(ta.roll, ta.pitch, reference.yaw_rad),
            eta_d_dot: Vector3::new(rate.x, rate.y, reference.yaw_rate_rad_s),
            eta_d_ddot: Vector3::new(acc.x, acc.y, reference.yaw_accel_rad_s2),
            limited: ta.limited,
            recovery,
        }
    }
}

/// Hysteresis on the tilt for handing RPY laws to the SO(3) attitude loop.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct RecoveryLatch {
    active: bool,
}

impl RecoveryLatch {
    pub(super) fn reset(&mut self) {
        self.active = false;
    }

    /// `tilt` = angle between body `z` and NED down [rad] (`>= |theta|`).
    pub(super) fn update(&mut self, tilt: f64, limits: &ControlLimits) -> bool {
        let exit = 0.5 * (limits.max_tilt_rad + limits.recovery_tilt_rad);
        if !tilt.is_finite() || tilt > limits.recovery_tilt_rad {
            self.active = true;
        } else if tilt < exit {
            self.active = false;
        }
        self.active
    }
}

/// Tilt of the body `z` axis from NED down [rad].
pub(super) fn tilt_of(r: &Matrix3<f64>) -> f64 {
    r[(2, 2)].clamp(-1.0, 1.0).acos()
}

/// Clamp thrust to `[min_thrust_g, max_thrust_g] m g` and each torque axis to
/// `I_ii max_angular_accel`; non-finite parts become hover thrust / zero torque.
/// Returns the wrench and whether anything was changed.
pub(super) fn saturate(
    thrust: f64,
    torque: &Vector3<f64>,
    model: &NominalModel,
    limits: &ControlLimits,
) -> (ControlWrench, bool) {
    let w = model.mass_kg * GRAVITY;
    let (lo, hi) = (limits.min_thrust_g * w, limits.max_thrust_g * w);
    let mut changed = false;
    let u = if thrust.is_finite() {
        let c = thrust.clamp(lo, hi);
        changed |= c != thrust;
        c
    } else {
        changed = true;
        w.clamp(lo, hi)
    };
    let t_max = inertia_diag(model) * limits.max_angular_accel_rad_s2;
    let tau = Vector3::from_fn(|k, _| {
        let t = torque[k];
        if t.is_finite() {
            let c = t.clamp(-t_max[k], t_max[k]);
            changed |= c != t;
            c
        } else {
            changed = true;
            0.0
        }
    });
    (ControlWrench::new(u, tau), changed)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thrust_and_angles_inverts_the_translational_model() {
        let limits = ControlLimits::default();
        let mu = Vector3::new(1.0, -2.0, -0.5);
        let psi = 0.7;
        let ta = thrust_and_angles(&mu, psi, 1.5, &limits);
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
            let ta = thrust_and_angles(&mu, 0.3, 2.0, &limits);
            assert!(ta.limited && ta.thrust_n >= 0.1 * 2.0 * GRAVITY * (1.0 - 1e-12));
            assert!(ta.roll.abs() <= limits.max_tilt_rad && ta.pitch.abs() <= limits.max_tilt_rad);
        }
    }

    /// GIVEN ramps and a parabola WHEN filtered at w = 60 rad/s THEN the rate is
    /// the true one delayed by the filter's mean delay `2 / w` and the acceleration settles.
    #[test]
    fn derivative_filter_tracks_a_ramp() {
        let mut f = DerivativeFilter::default();
        let (mut v, mut a) = (Vector2::zeros(), Vector2::zeros());
        let mut t = 0.0;
        for k in 0..2000 {
            t = f64::from(k) * 1e-3;
            (v, a) = f.update(&Vector2::new(0.5 * t, -t * t), &Vector2::zeros(), 60.0, 1e-3);
        }
        assert!((v.x - 0.5).abs() < 1e-3, "{v}");
        assert!((v.y + 2.0 * (t - 2.0 / 60.0)).abs() < 2e-3, "{v}");
        assert!((a.y + 2.0).abs() < 1e-2, "{a}");
    }

    /// GIVEN R = R_d and matching rates WHEN the SO(3) loop runs THEN only the
    /// feedforward `w x I w + I w_d_dot` remains.
    #[test]
    fn so3_loop_feedforward_only_on_the_reference() {
        let i = Matrix3::from_diagonal(&Vector3::new(0.03, 0.04, 0.05));
        let r = *crate::math::from_euler_zyx(&Vector3::new(0.2, -0.1, 1.0))
            .to_rotation_matrix()
            .matrix();
        let w = Vector3::new(0.3, -0.2, 0.5);
        let wd = Vector3::new(1.0, 2.0, 3.0);
        let out = so3_attitude(&i, &r, &w, &r, &w, &wd, &Vector3::repeat(5.0), &Vector3::repeat(1.0));
        assert!(out.e_r.norm() < 1e-15);
        assert!((out.torque - (w.cross(&(i * w)) + i * wd)).norm() < 1e-14);
    }
}
