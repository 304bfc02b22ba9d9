//! Passivity-based controller: Ruggiero, Cacace, Sadeghian, Lippiello,
//! "Passivity-based control of VToL UAVs with a momentum-based estimator of
//! external wrench and unmodeled dynamics", Robotics and Autonomous Systems 72
//! (2015); origin report section 2.4; `docs/model.md` section 6.
//!
//! Slotine-Li style: the model is evaluated along reference signals
//! `(.)_r`, not cancelled. NED world, FRD body, ZYX Euler angles, `M`, `C` as
//! in doc section 1 (`M_dot - 2C` skew, which the passivity argument needs).
//! ```text
//! linear:  e_p = p - p_d,  v_r = v_d - sigma_p e_p,  a_r = a_d - sigma_p e_v,  nu_p = e_v + sigma_p e_p
//!          mu_d = a_r - (D_p nu_p + K_p e_p (+ f_hat)) / m                      [m/s^2], NED
//!          u_T, phi_d, theta_d from mu_d as in the hierarchical law (doc section 4, same guards)
//! angular: e = wrap(eta - eta_d),  eta_r' = eta_d' - sigma e,  eta_r'' = eta_d'' - sigma e',  nu = e' + sigma e
//!          tau^b = Q^-T (M eta_r'' + C(eta, eta') eta_r' - tau_hat_eta - D_o nu - K_o e)
//!                = I_b (Q eta_r'' + Q_dot eta_r') + (Q eta_r') x I_b w - Q^-T (tau_hat_eta + D_o nu + K_o e)
//! ```
//! (`w = Q eta'`; the second form is the one evaluated: `Q^-T M = I_b Q` and
//! `Q^-T C v = I_b Q_dot v - (I_b w) x (Q v)` with `C` of doc section 1, so
//! neither `M`, `C` nor `Q^-1` is formed as a matrix.)
//! Closed loop `M nu' + (C + D_o) nu + K_o e = tau_tilde` is passive from
//! `tau_tilde` to `nu`; linearized per axis
//! `m e'' + (m sigma_p + D_p) e' + (D_p sigma_p + K_p) e = f_tilde` and the same with
//! `I_b, sigma, D_o, K_o`. Near `theta = +-90 deg` the attitude goes to the SO(3)
//! loop with the matching `K_R = D_o sigma + K_o`, `K_w = I_b sigma + D_o`
//! (see the hierarchical module for the recovery rule).

use super::gains::PassivityGains;
use super::law::{LawInput, LawOutput};
use super::rpy::{EulerTracking, RpyStage};

/// Internal state: the attitude-setpoint stage.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Passivity {
    stage: RpyStage,
}

impl Passivity {
    pub(super) fn reset(&mut self) {
        self.stage.reset();
    }

    /// One step of the law (module doc).
    #[inline(always)]
    pub(super) fn update(&mut self, gains: &PassivityGains, input: &LawInput) -> LawOutput {
        let (model, estimate) = (input.model, input.estimate);
        let m = model.mass_kg;
        let inertia = &model.inertia_kg_m2;
        let e_p = input.position_error();
        let e_v = input.velocity_error();
        let sigma_p = gains.sigma_p_per_s;
        let nu_p = e_v + e_p * sigma_p;
        let a_r = input.reference.acceleration_ned - e_v * sigma_p;
        let mu_d = a_r
            - (gains.dp_n_s_per_m.component_mul(&nu_p) + gains.kp_n_per_m.component_mul(&e_p) + estimate.force_ned) / m;
        let sigma = gains.sigma_per_s;
        let inner_torque = |t: &EulerTracking| {
            let (e, e_dot) = (t.e, t.e_dot);
            let eta_r_dot = t.sp.eta_d_dot - e * sigma;
            let eta_r_ddot = t.sp.eta_d_ddot - e_dot * sigma;
            let nu = e_dot + e * sigma;
            let w = &input.measurement.rate_frd;
            // Q^-T (M eta_r'' + C eta_r') = I_b (Q eta_r'' + Q_dot eta_r') + (Q eta_r') x I_b w
            let model_terms = inertia * (t.trig.q_mul(&eta_r_ddot) + t.trig.q_dot_mul(&t.eta_dot, &eta_r_dot))
                + t.trig.q_mul(&eta_r_dot).cross(&(inertia * w));
            let generalized = -estimate.torque_rpy
                - gains.do_n_m_s_per_rad.component_mul(&nu)
                - gains.ko_n_m_per_rad.component_mul(&e);
            model_terms + t.q_inv.tr_mul(&generalized)
        };
        // K_R = D_o sigma + K_o, K_w = I_b sigma + D_o: the same linearized poles
        let recovery_gains = || {
            let i = inertia.diagonal();
            (
                gains.do_n_m_s_per_rad * sigma + gains.ko_n_m_per_rad,
                i * sigma + gains.do_n_m_s_per_rad,
            )
        };
        self.stage
            .step(input, &mu_d, gains.eta_filter_rad_s, inner_torque, recovery_gains)
    }
}

#[cfg(test)]
mod tests {
    use super::super::ControlGains;
    use super::super::Reference;
    use super::super::hierarchical::Hierarchical;
    use super::*;
    use crate::signals::GRAVITY;
    use crate::signals::{Measurement, NominalModel};
    use nalgebra::{Matrix3, UnitQuaternion};

    /// GIVEN gains matched to the same linearized poles (doc section 10) and a
    /// state near hover at rest WHEN both RPY laws run THEN thrust and torque agree
    /// (the position parts are identical linear maps; the angular ones differ only
    /// through `M(eta)` versus `I_b Q` at small angles).
    #[test]
    fn matched_passivity_equals_hierarchical_near_hover() {
        let model = NominalModel {
            mass_kg: 1.5,
            inertia_kg_m2: Matrix3::from_diagonal(&nalgebra::Vector3::new(0.03, 0.03, 0.05)),
        };
        let g = ControlGains::for_vehicle(&model);
        let meas = Measurement {
            time_s: 0.0,
            position_ned: nalgebra::Vector3::new(0.01, -0.02, -1.0),
            velocity_ned: nalgebra::Vector3::new(0.02, 0.01, -0.01),
            attitude: crate::math::from_euler_zyx(&nalgebra::Vector3::new(0.002, -0.001, 0.003)),
            rate_frd: nalgebra::Vector3::zeros(),
        };
        let reference = Reference::hold(nalgebra::Vector3::new(0.0, 0.0, -1.0), 0.0);
        let input = LawInput::without_estimate(&model, &meas, &reference, &g.limits);
        let h = Hierarchical::default().update(&g.hierarchical, &input);
        let p = Passivity::default().update(&g.passivity, &input);
        assert!((h.thrust_n - p.thrust_n).abs() < 1e-12 * model.mass_kg * GRAVITY);
        assert!(
            (h.torque_frd - p.torque_frd).norm() < 1e-3 * h.torque_frd.norm(),
            "{} {}",
            h.torque_frd,
            p.torque_frd
        );
        // at hover on the reference both are at equilibrium
        let hover = Measurement {
            position_ned: reference.position_ned,
            velocity_ned: nalgebra::Vector3::zeros(),
            attitude: UnitQuaternion::identity(),
            ..meas
        };
        let input = LawInput::without_estimate(&model, &hover, &reference, &g.limits);
        let p = Passivity::default().update(&g.passivity, &input);
        assert!((p.thrust_n - model.mass_kg * GRAVITY).abs() < 1e-12 && p.torque_frd.norm() < 1e-15);
    }
}
