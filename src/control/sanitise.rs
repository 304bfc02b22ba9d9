//! Input checks: whether a measurement, the nominal model, a reference and an
//! external-wrench estimate can be used as they are, and the hold that
//! replaces what cannot.
//!
//! Hot path: one control step runs every simulation step, so inputs are first
//! tested in one go ([`all_finite`]) and only sanitised part by part (the
//! `#[cold]` functions) when that fails. What is checked:
//! ```text
//! measurement   all of p, v, w, q finite and | |q| - 1 | < 1e-6
//! model         m > 0 finite, I_b finite with I_ii > 0
//! reference     every part finite, else: p_d = p (held), derivatives 0, psi_d = psi
//! estimate      finite, |f_hat| <= max_thrust_g m g, |tau_hat_i| <= I_ii max_angular_accel
//!               (else non-finite parts dropped, magnitudes limited to those caps)
//! ```

use nalgebra::{Matrix3, Vector3};

use super::Reference;
use super::gains::ControlLimits;
use crate::math::euler_zyx;
use crate::signals::GRAVITY;
use crate::signals::{Measurement, NominalModel, WrenchEstimate};

/// Whether every value is finite, without a branch per value: `x * 0` is
/// `+-0` for a finite `x` and NaN for an infinite or NaN one, so the sum is
/// zero exactly when all are finite.
pub(super) fn all_finite(xs: &[f64]) -> bool {
    xs.iter().fold(0.0, |s, x| s + x * 0.0) == 0.0
}

pub(super) fn finite3(v: &Vector3<f64>) -> bool {
    all_finite(v.as_slice())
}

/// `v` when finite, else zero.
#[inline]
pub(super) fn finite_or_zero(v: &Vector3<f64>) -> Vector3<f64> {
    if finite3(v) { *v } else { Vector3::zeros() }
}

pub(super) fn finite_m3(m: &Matrix3<f64>) -> bool {
    all_finite(m.as_slice())
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
        model.inertia_kg_m2.diagonal() * limits.max_angular_accel_rad_s2,
    )
}

/// Whether the estimate can be fed back as it is: finite and within
/// [`estimate_caps`] (then [`sanitize_estimate`] would return it unchanged).
#[inline(always)]
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
