//! Output saturation: the wrench every law hands out is clamped to what the
//! vehicle may be asked for,
//! ```text
//! u_T in [min_thrust_g, max_thrust_g] m g            [N]
//! |tau_i| <= I_ii max_angular_accel                   [N m], body FRD
//! ```
//! non-finite parts becoming hover thrust / zero torque.

use nalgebra::Vector3;

use super::gains::ControlLimits;
use crate::signals::{ControlWrench, GRAVITY, NominalModel};

/// Clamp thrust to `[min_thrust_g, max_thrust_g] m g` and each torque axis to
/// `I_ii max_angular_accel`; non-finite parts become hover thrust / zero torque.
/// Returns the wrench and whether anything was changed.
#[inline(always)]
pub(super) fn saturate(
    thrust: f64,
    torque: &Vector3<f64>,
    model: &NominalModel,
    limits: &ControlLimits,
) -> (ControlWrench, bool) {
    let w = model.mass_kg * GRAVITY;
    let (lo, hi) = (limits.min_thrust_g * w, limits.max_thrust_g * w);
    let t_max = model.inertia_kg_m2.diagonal() * limits.max_angular_accel_rad_s2;
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
