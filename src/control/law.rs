//! What every control law reads in one step ([`LawInput`]) and what it hands
//! back before output saturation ([`LawOutput`]). The [`super::Controller`]
//! builds the input once per step from checked (or replaced) parts, so a law
//! never sees a non-finite reference or estimate, an unusable model or
//! measurement, or a negative `dt`.

use nalgebra::{Matrix3, Vector3};

use super::Reference;
use super::gains::ControlLimits;
use crate::signals::{Measurement, NominalModel, WrenchEstimate};

/// One step's input of a law: the vehicle model, the measured state, the
/// desired trajectory, the external-wrench estimate to feed back (zero for
/// none), the limits the guards keep, and the time since the previous step.
#[derive(Clone, Copy, Debug)]
pub(super) struct LawInput<'a> {
    /// The nominal model `m`, `I_b`.
    pub(super) model: &'a NominalModel,
    /// `p, v, R, w`.
    pub(super) measurement: &'a Measurement,
    /// `p_d` and its derivatives, `psi_d` and its derivatives.
    pub(super) reference: &'a Reference,
    /// `f_hat` [N] NED, `tau_hat_eta`, `tau_hat^b` [N m].
    pub(super) estimate: &'a WrenchEstimate,
    /// Tilt, vertical-acceleration and rate limits of the guards.
    pub(super) limits: &'a ControlLimits,
    /// Time since the previous step [s], `>= 0` (0: same instant, no derivative update).
    pub(super) dt: f64,
}

impl LawInput<'_> {
    /// `e_p = p - p_d` [m], NED.
    #[inline]
    pub(super) fn position_error(&self) -> Vector3<f64> {
        self.measurement.position_ned - self.reference.position_ned
    }

    /// `e_v = v - v_d` [m/s], NED.
    #[inline]
    pub(super) fn velocity_error(&self) -> Vector3<f64> {
        self.measurement.velocity_ned - self.reference.velocity_ned
    }
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

#[cfg(test)]
impl<'a> LawInput<'a> {
    /// The laws' unit tests' input: no estimate, `dt` = 1 ms.
    pub(super) fn without_estimate(
        model: &'a NominalModel,
        measurement: &'a Measurement,
        reference: &'a Reference,
        limits: &'a ControlLimits,
    ) -> Self {
        Self {
            model,
            measurement,
            reference,
            estimate: &super::sanitise::NO_ESTIMATE,
            limits,
            dt: 1e-3,
        }
    }
}
