//! Pieces shared by the laws: input checks, the RPY outer-loop inversion
//! (doc section 4), the derivative filter for `phi_d, theta_d`, the ZYX rate
//! map in closed form, the SO(3) attitude loop (doc section 5) and output
//! saturation.
//!
//! Hot path: one control step runs every simulation step, so inputs are first
//! tested in one go ([`all_finite`]) and only sanitised part by part when that
//! fails, trigonometric values are derived once (from the rotation matrix or
//! the setpoint's own ratios) instead of recomputed, and values of rarely
//! changing inputs (limits, a held heading, the step size) are kept in a [`Memo`].

use nalgebra::{Matrix3, Vector2, Vector3};

use super::Reference;
use super::gains::ControlLimits;
use crate::math::{euler_zyx, vee, wrap_pi};
use crate::signals::{ControlWrench, GRAVITY};
use crate::signals::{Measurement, NominalModel, WrenchEstimate};

/// `e3 = [0, 0, 1]`: NED down.
pub(super) fn e3() -> Vector3<f64> {
    Vector3::new(0.0, 0.0, 1.0)
}

/// Whether every value is finite, without a branch per value: `x * 0` is
/// `+-0` for a finite `x` and NaN for an infinite or NaN one, so the sum is
/// zero exactly when all are finite.
pub(super) fn all_finite(xs: &[f64]) -> bool {
    xs.iter().fold(0.0, |s, x| s + x * 0.0) == 0.0
}

pub(super) fn finite3(v: &Vector3<f64>) -> bool {
    all_finite(v.as_slice())
}

pub(super) fn finite_m3(m: &Matrix3<f64>) -> bool {
    all_finite(m.as_slice())
}

/// The last value of a function of rarely changing inputs (limits, a held
/// heading, the step size), keyed on their exact bits: the same value as
/// calling the function, computed once per change.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Memo<K, T> {
    last: Option<(K, T)>,
}

impl<K: Copy + PartialEq, T: Copy> Memo<K, T> {
    /// `f()` for `key`, from the memo when `key` is the last one.
    pub(super) fn get(&mut self, key: K, f: impl FnOnce() -> T) -> T {
        match self.last {
            Some((k, v)) if k == key => v,
            _ => {
                let v = f();
                self.last = Some((key, v));
                v
            }
        }
    }
}

/// Whether a measurement can be used at all.
pub(super) fn measurement_ok(m: &Measurement) -> bool {
    let (p, v, w, q) = (&m.position_ned, &m.velocity_ned, &m.rate_frd, &m.attitude.coords);
    // | |q| - 1 | < 1e-6, compared squared (no root per step)
    let n2 = q.norm_squared();
    all_finite(&[p.x, p.y, p.z, v.x, v.y, v.z, w.x, w.y, w.z, q.x, q.y, q.z, q.w])
        && n2 > (1.0 - 1e-6) * (1.0 - 1e-6)
        && n2 < (1.0 + 1e-6) * (1.0 + 1e-6)
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

/// The reference with every non-finite part replaced by a hold at the measured
/// pose (called only when [`Reference::is_finite`] fails).
#[cold]
pub(super) fn sanitize_reference(r: &Reference, meas: &Measurement) -> Reference {
    let mut out = *r;
    let fix = |v: &mut Vector3<f64>, hold: Vector3<f64>| {
        if !finite3(v) {
            *v = hold;
        }
    };
    fix(&mut out.position_ned, meas.position_ned);
    fix(&mut out.velocity_ned, Vector3::zeros());
    fix(&mut out.acceleration_ned, Vector3::zeros());
    fix(&mut out.jerk_ned, Vector3::zeros());
    fix(&mut out.snap_ned, Vector3::zeros());
    if !out.yaw_rad.is_finite() {
        // only now pay for the Euler angles
        out.yaw_rad = euler_zyx(&meas.attitude).z;
    }
    let fix_s = |x: &mut f64| {
        if !x.is_finite() {
            *x = 0.0;
        }
    };
    fix_s(&mut out.yaw_rate_rad_s);
    fix_s(&mut out.yaw_accel_rad_s2);
    out
}

/// No external-wrench estimate: nothing fed back.
pub(super) const NO_ESTIMATE: WrenchEstimate = WrenchEstimate {
    force_ned: Vector3::new(0.0, 0.0, 0.0),
    torque_rpy: Vector3::new(0.0, 0.0, 0.0),
    torque_frd: Vector3::new(0.0, 0.0, 0.0),
    mass_kg: 0.0,
};

/// Magnitudes of an estimate the vehicle could counter: `max_thrust_g m g` [N]
/// for the force, `I_ii max_angular_accel` [N m] per torque axis.
fn estimate_caps(model: &NominalModel, limits: &ControlLimits) -> (f64, Vector3<f64>) {
    (
        limits.max_thrust_g * model.mass_kg * GRAVITY,
        inertia_diag(model) * limits.max_angular_accel_rad_s2,
    )
}

/// Whether the estimate can be fed back as it is: finite and within
/// [`estimate_caps`] (then [`sanitize_estimate`] would return it unchanged).
pub(super) fn estimate_usable(e: &WrenchEstimate, model: &NominalModel, limits: &ControlLimits) -> bool {
    let (f_max, t_max) = estimate_caps(model, limits);
    let (f, tr, tf) = (&e.force_ned, &e.torque_rpy, &e.torque_frd);
    let within = |v: &Vector3<f64>| v.x.abs() <= t_max.x && v.y.abs() <= t_max.y && v.z.abs() <= t_max.z;
    all_finite(&[f.x, f.y, f.z, tr.x, tr.y, tr.z, tf.x, tf.y, tf.z, e.mass_kg])
        && f.norm_squared() <= f_max * f_max
        && within(tr)
        && within(tf)
}

/// The estimate with non-finite parts dropped and magnitudes limited to
/// [`estimate_caps`], and whether a force or torque was not finite.
#[cold]
pub(super) fn sanitize_estimate(
    e: &WrenchEstimate,
    model: &NominalModel,
    limits: &ControlLimits,
) -> (WrenchEstimate, bool) {
    let (f_max, t_max) = estimate_caps(model, limits);
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
    let out = WrenchEstimate {
        force_ned: cap(&e.force_ned, f_max),
        torque_rpy: clamp_axes(&e.torque_rpy),
        torque_frd: clamp_axes(&e.torque_frd),
        mass_kg: if e.mass_kg.is_finite() {
            e.mass_kg
        } else {
            model.mass_kg
        },
    };
    let replaced = !(finite3(&e.force_ned) && finite3(&e.torque_rpy) && finite3(&e.torque_frd));
    (out, replaced)
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
    /// `(sin phi_d, cos phi_d)`.
    pub(super) roll_sin_cos: (f64, f64),
    /// `(sin theta_d, cos theta_d)`.
    pub(super) pitch_sin_cos: (f64, f64),
    /// A guard changed the request.
    pub(super) limited: bool,
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
pub(super) fn thrust_and_angles(
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

/// `atan2(s, c)` of a point `(s, c)` on the unit circle: `asin(s)` within
/// 45 deg of `(0, 1)`, where it is as accurate as `atan2` and several times
/// cheaper, `atan2` elsewhere.
pub(super) fn unit_angle(s: f64, c: f64) -> f64 {
    if c > 0.0 && s.abs() < std::f64::consts::FRAC_1_SQRT_2 {
        s.asin()
    } else {
        s.atan2(c)
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
    /// `exp(-w dt)` for the last `(w, dt)`.
    decay: Memo<(u64, u64), f64>,
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
        let u_ok = all_finite(u.as_slice());
        if !self.initialized || !u_ok {
            // steady state on a ramp of slope v_init through u: x lags u by 2 v_init / w
            let u0 = if u_ok { *u } else { Vector2::zeros() };
            self.v = if all_finite(v_init.as_slice()) {
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
            let decay = self.decay.get((w.to_bits(), dt.to_bits()), || (-w * dt).exp());
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

/// Sines and cosines of ZYX Euler angles `eta = [phi, theta, psi]`, from
/// which `R(eta)`, the rate map `Q(eta)`, its inverse and its derivative
/// follow without further trigonometry.
#[derive(Clone, Copy, Debug)]
pub(super) struct EulerTrig {
    sp: f64,
    cp: f64,
    st: f64,
    ct: f64,
    ss: f64,
    cs: f64,
}

impl EulerTrig {
    /// From `(sin, cos)` of `phi`, `theta` and `psi`.
    pub(super) fn new(phi: (f64, f64), theta: (f64, f64), psi: (f64, f64)) -> Self {
        Self {
            sp: phi.0,
            cp: phi.1,
            st: theta.0,
            ct: theta.1,
            ss: psi.0,
            cs: psi.1,
        }
    }

    /// The Euler angles of the attitude `r` (FRD to NED) as [`euler_zyx`]:
    /// `phi = atan2(r32, r33)`, `theta = -asin(r31)`, `psi = atan2(r21, r11)`,
    /// with their sines and cosines read off `r`: `s_theta = -r31`,
    /// `c_theta = |(r32, r33)|`, `(s_phi, c_phi) = (r32, r33) / c_theta`,
    /// `(s_psi, c_psi) = (r21, r11) / c_theta` (`sin_cos` when `c_theta` is tiny);
    /// `phi`, `psi` by [`unit_angle`].
    pub(super) fn of_rotation(r: &Matrix3<f64>) -> (Vector3<f64>, Self) {
        let (r11, r21, r31, r32, r33) = (r[(0, 0)], r[(1, 0)], r[(2, 0)], r[(2, 1)], r[(2, 2)]);
        let theta = -r31.clamp(-1.0, 1.0).asin();
        let ct = (r32 * r32 + r33 * r33).sqrt();
        if ct > 1e-9 {
            let inv = 1.0 / ct;
            let (phi, psi) = ((r32 * inv, r33 * inv), (r21 * inv, r11 * inv));
            let eta = Vector3::new(unit_angle(phi.0, phi.1), theta, unit_angle(psi.0, psi.1));
            (eta, Self::new(phi, (-r31, ct), psi))
        } else {
            let eta = Vector3::new(r32.atan2(r33), theta, r21.atan2(r11));
            (eta, Self::new(eta.x.sin_cos(), eta.y.sin_cos(), eta.z.sin_cos()))
        }
    }

    /// `cos theta` (`det Q`).
    pub(super) fn cos_theta(&self) -> f64 {
        self.ct
    }

    /// `R(eta) = Rz(psi) Ry(theta) Rx(phi)`.
    pub(super) fn rotation(&self) -> Matrix3<f64> {
        let Self { sp, cp, st, ct, ss, cs } = *self;
        Matrix3::new(
            cs * ct,
            cs * st * sp - ss * cp,
            cs * st * cp + ss * sp,
            ss * ct,
            ss * st * sp + cs * cp,
            ss * st * cp - cs * sp,
            -st,
            ct * sp,
            ct * cp,
        )
    }

    /// `Q(eta) v` with `Q = [[1, 0, -s_th], [0, c_ph, c_th s_ph], [0, -s_ph, c_th c_ph]]` ([`crate::math::rate_map`]).
    pub(super) fn q_mul(&self, v: &Vector3<f64>) -> Vector3<f64> {
        Vector3::new(
            v.x - self.st * v.z,
            self.cp * v.y + self.ct * self.sp * v.z,
            -self.sp * v.y + self.ct * self.cp * v.z,
        )
    }

    /// `Q_dot(eta, eta_dot) v` ([`crate::math::rate_map_dot`]).
    pub(super) fn q_dot_mul(&self, eta_dot: &Vector3<f64>, v: &Vector3<f64>) -> Vector3<f64> {
        let Self { sp, cp, st, ct, .. } = *self;
        let (pd, td) = (eta_dot.x, eta_dot.y);
        Vector3::new(
            -ct * td * v.z,
            -sp * pd * v.y + (-st * sp * td + ct * cp * pd) * v.z,
            -cp * pd * v.y + (-st * cp * td - ct * sp * pd) * v.z,
        )
    }

    /// `Q^-1`, `None` when `|det Q| = |cos theta| < 1e-6`:
    /// `Q^-1 = [[1, s_ph t_th, c_ph t_th], [0, c_ph, -s_ph], [0, s_ph / c_th, c_ph / c_th]]`.
    pub(super) fn rate_map_inverse(&self) -> Option<RateMapInverse> {
        if self.ct.abs() < 1e-6 {
            return None;
        }
        let sec = 1.0 / self.ct;
        Some(RateMapInverse {
            sp: self.sp,
            cp: self.cp,
            tt: self.st * sec,
            sec,
        })
    }
}

/// `Q^-1` of the ZYX rate map ([`EulerTrig::rate_map_inverse`]).
#[derive(Clone, Copy, Debug)]
pub(super) struct RateMapInverse {
    sp: f64,
    cp: f64,
    /// `tan theta`.
    tt: f64,
    /// `1 / cos theta`.
    sec: f64,
}

impl RateMapInverse {
    /// `Q^-1 v`: Euler rates of the body rate `v`.
    pub(super) fn mul(&self, v: &Vector3<f64>) -> Vector3<f64> {
        Vector3::new(
            v.x + (self.sp * v.y + self.cp * v.z) * self.tt,
            self.cp * v.y - self.sp * v.z,
            (self.sp * v.y + self.cp * v.z) * self.sec,
        )
    }

    /// `Q^-T v`: body torque of the generalized force `v` on the Euler angles.
    pub(super) fn tr_mul(&self, v: &Vector3<f64>) -> Vector3<f64> {
        Vector3::new(
            v.x,
            self.sp * self.tt * v.x + self.cp * v.y + self.sp * self.sec * v.z,
            self.cp * self.tt * v.x - self.sp * v.y + self.cp * self.sec * v.z,
        )
    }
}

/// The measured attitude as the RPY laws see it: `eta` of `R`, its sines and
/// cosines, and, away from `theta = +-90 deg` (`|cos theta| >= 1e-6`), `Q^-1`
/// with the Euler rates `eta_dot = Q^-1 omega`.
#[derive(Clone, Copy, Debug)]
pub(super) struct MeasuredEuler {
    pub(super) eta: Vector3<f64>,
    pub(super) trig: EulerTrig,
    pub(super) rates: Option<(RateMapInverse, Vector3<f64>)>,
}

impl MeasuredEuler {
    /// From the attitude `r` (FRD to NED) and the body rate `omega` [rad/s], FRD.
    pub(super) fn new(r: &Matrix3<f64>, omega: &Vector3<f64>) -> Self {
        let (eta, trig) = EulerTrig::of_rotation(r);
        let rates = trig.rate_map_inverse().map(|q_inv| (q_inv, q_inv.mul(omega)));
        Self { eta, trig, rates }
    }

    /// The Euler rates that start the setpoint filter bumplessly: the measured
    /// ones, zero near `theta = 90 deg` (`cos theta <= 0.3`).
    pub(super) fn filter_start(&self) -> Vector3<f64> {
        match self.rates {
            Some((_, eta_dot)) if self.trig.cos_theta() > 0.3 => eta_dot,
            _ => Vector3::zeros(),
        }
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
/// `omega_d`, `omega_dot_d` are in the desired body frame. `R^T R_d` is formed
/// once: `R_d^T R` is its transpose, so `e_R = -(R^T R_d)^vee`.
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
    let rt_rd = r.tr_mul(r_d);
    let e_r = -vee(&rt_rd);
    let w_d_body = rt_rd * omega_d;
    let e_w = omega - w_d_body;
    let torque = -kr.component_mul(&e_r) - kw.component_mul(&e_w) + omega.cross(&(inertia * omega))
        - inertia * (omega.cross(&w_d_body) - rt_rd * omega_dot_d);
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
    sp: &RpySetpoint,
    kr: &Vector3<f64>,
    kw: &Vector3<f64>,
    tau_hat_frd: &Vector3<f64>,
) -> (So3Output, Matrix3<f64>, Vector3<f64>) {
    let r_d = sp.trig.rotation();
    let w_d = sp.trig.q_mul(&sp.eta_d_dot);
    let w_d_dot = sp.trig.q_mul(&sp.eta_d_ddot) + sp.trig.q_dot_mul(&sp.eta_d_dot, &sp.eta_d_dot);
    let mut out = so3_attitude(inertia, r, omega, &r_d, &w_d, &w_d_dot, kr, kw);
    out.torque -= tau_hat_frd;
    (out, r_d, w_d)
}

/// Thrust along the current body axis in recovery: `u_T max(0, (R e3) . (R_d e3))`.
pub(super) fn projected_thrust(thrust: f64, r: &Matrix3<f64>, r_d: &Matrix3<f64>) -> f64 {
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
    pub(super) fn rotation(&self) -> Matrix3<f64> {
        self.trig.rotation()
    }

    /// `omega_d = Q(eta_d) eta_d_dot` [rad/s], desired body frame.
    pub(super) fn body_rate(&self) -> Vector3<f64> {
        self.trig.q_mul(&self.eta_d_dot)
    }
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

    /// From the desired acceleration `mu` [m/s^2]: `u_T, phi_d, theta_d` (doc
    /// section 4, with guards), roll/pitch derivatives by the filter (started
    /// at the measured Euler rates `eta_dot_now` after a reset), yaw and its
    /// derivatives from the reference. `cos_tilt = r33` of the measured attitude
    /// drives the recovery latch.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn setpoint(
        &mut self,
        mu: &Vector3<f64>,
        reference: &Reference,
        mass: f64,
        limits: &ControlLimits,
        filter_rad_s: f64,
        cos_tilt: f64,
        eta_dot_now: &Vector3<f64>,
        dt: f64,
    ) -> RpySetpoint {
        let max_tilt = limits.max_tilt_rad;
        let tan_max_tilt = self.tan_max_tilt.get(max_tilt.to_bits(), || max_tilt.tan());
        let yaw = reference.yaw_rad;
        let yaw_sin_cos = self.yaw_sin_cos.get(yaw.to_bits(), || yaw.sin_cos());
        let ta = thrust_and_angles(mu, yaw_sin_cos, mass, limits, tan_max_tilt);
        let (rate, acc) = self
            .filter
            .update(&Vector2::new(ta.roll, ta.pitch), &eta_dot_now.xy(), filter_rad_s, dt);
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
pub(super) struct RecoveryLatch {
    active: bool,
    /// `(cos recovery_tilt, cos exit)` for the last `(max_tilt, recovery_tilt)`.
    cos_thresholds: Memo<(u64, u64), (f64, f64)>,
}

impl RecoveryLatch {
    pub(super) fn reset(&mut self) {
        self.active = false;
    }

    /// `cos_tilt` = cosine of the angle between body `z` and NED down (`r33`;
    /// the tilt is `>= |theta|`).
    pub(super) fn update(&mut self, cos_tilt: f64, limits: &ControlLimits) -> bool {
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
    let t_max = inertia_diag(model) * limits.max_angular_accel_rad_s2;
    let clamp = |t: f64, max: f64| if t.is_finite() { t.clamp(-max, max) } else { 0.0 };
    let u = if thrust.is_finite() {
        thrust.clamp(lo, hi)
    } else {
        w.clamp(lo, hi)
    };
    let tau = Vector3::new(
        clamp(torque.x, t_max.x),
        clamp(torque.y, t_max.y),
        clamp(torque.z, t_max.z),
    );
    // a replaced non-finite value always differs from its input (NaN != anything)
    let changed = u != thrust || tau != *torque;
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

    /// GIVEN a tilted, rotating attitude WHEN its Euler trigonometry is read off
    /// `R` THEN angles, `R(eta)`, `Q v`, `Q_dot v`, `Q^-1 v` and `Q^-T v` match the
    /// matrices of `math`.
    #[test]
    fn euler_trig_matches_the_rate_map_matrices() {
        use crate::math::{from_euler_zyx, rate_map, rate_map_dot};
        let eta = Vector3::new(0.4, -1.1, 2.5);
        let eta_dot = Vector3::new(0.3, -0.7, 1.2);
        let v = Vector3::new(-0.2, 0.9, 0.5);
        let r = *from_euler_zyx(&eta).to_rotation_matrix().matrix();
        let (angles, trig) = EulerTrig::of_rotation(&r);
        assert!((angles - eta).norm() < 1e-12);
        assert!((trig.rotation() - r).norm() < 1e-12);
        let q = rate_map(&eta);
        assert!((trig.q_mul(&v) - q * v).norm() < 1e-12);
        assert!((trig.q_dot_mul(&eta_dot, &v) - rate_map_dot(&eta, &eta_dot) * v).norm() < 1e-12);
        let q_inv = q.try_inverse().unwrap();
        let inv = trig.rate_map_inverse().unwrap();
        assert!((inv.mul(&v) - q_inv * v).norm() < 1e-12);
        assert!((inv.tr_mul(&v) - q_inv.transpose() * v).norm() < 1e-12);
        let vertical = EulerTrig::new((0.0, 1.0), (1.0, 0.0), (0.0, 1.0));
        assert!(vertical.rate_map_inverse().is_none());
    }

    /// GIVEN measured attitudes and rates WHEN read as Euler quantities THEN
    /// `eta_dot = Q^-1 omega` starts the setpoint filter at moderate pitch, zero
    /// starts it beyond `cos theta = 0.3`, and at `theta = 90 deg` there are no rates.
    #[test]
    fn measured_euler_rates_and_filter_start() {
        use crate::math::{from_euler_zyx, rate_map};
        let eta_dot = Vector3::new(0.3, -0.7, 1.2);
        for (pitch, starts) in [(0.5, true), (1.3, false)] {
            let eta = Vector3::new(0.2, pitch, -0.4);
            let r = *from_euler_zyx(&eta).to_rotation_matrix().matrix();
            let now = MeasuredEuler::new(&r, &(rate_map(&eta) * eta_dot));
            assert!((now.eta - eta).norm() < 1e-12);
            let (_, rates) = now.rates.unwrap();
            assert!((rates - eta_dot).norm() < 1e-11);
            let expected = if starts { eta_dot } else { Vector3::zeros() };
            assert!((now.filter_start() - expected).norm() < 1e-11, "pitch {pitch}");
        }
        let vertical = *from_euler_zyx(&Vector3::new(0.0, std::f64::consts::FRAC_PI_2, 0.0))
            .to_rotation_matrix()
            .matrix();
        let now = MeasuredEuler::new(&vertical, &Vector3::new(0.1, 0.2, 0.3));
        assert!(now.rates.is_none() && now.filter_start() == Vector3::zeros());
    }

    #[test]
    fn unit_angle_is_atan2_on_the_unit_circle() {
        for k in -64..=64 {
            let a = f64::from(k) * std::f64::consts::PI / 64.0;
            let (s, c) = a.sin_cos();
            assert!((unit_angle(s, c) - s.atan2(c)).abs() < 1e-15, "{a}");
        }
    }

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
