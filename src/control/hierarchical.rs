//! Hierarchical controller in ZYX Euler angles: outer position loop giving
//! thrust and roll/pitch setpoints, inner attitude loop by partial feedback
//! linearization (origin report section 2.2; `docs/model.md`
//! section 4; Siciliano, Sciavicco, Villani, Oriolo style two-loop control).
//!
//! NED world, FRD body, `eta = [phi, theta, psi]`, `omega = Q(eta) eta_dot`,
//! `M = Q^T I_b Q`, `C` the Coriolis matrix with `M_dot - 2C` skew (doc section 1).
//! ```text
//! outer: mu = a_d - K_P e_p - K_D e_v (- f_hat / m)                     [m/s^2], NED
//!        u_T = m sqrt(mu_x^2 + mu_y^2 + (mu_z - g)^2)
//!        phi_d = asin(m (mu_y c_psi_d - mu_x s_psi_d) / u_T)
//!        theta_d = atan2(-(mu_x c_psi_d + mu_y s_psi_d), g - mu_z)
//! inner: nu = eta_d'' - K_D,eta e_eta' - K_P,eta e_eta                   e_eta = wrap(eta - eta_d)
//!        tau^b = I_b Q nu + Q^-T (C eta' - tau_hat_eta)
//!              = I_b (Q nu + Q_dot eta') + w x I_b w - Q^-T tau_hat_eta      (w = Q eta')
//! ```
//! giving `e_eta'' + K_D,eta e_eta' + K_P,eta e_eta = M^-1 tau_tilde`. The second
//! form is the one evaluated: with `C` of doc section 1,
//! `Q^-T C eta' = I_b Q_dot eta' - (I_b w) x w`, so neither `C` nor `Q^-1` is
//! formed as a matrix (the `sin`/`cos` of `eta` come from `R`, see `euler`). `phi_d, theta_d`
//! derivatives come from a critically damped second-order filter (`w_n` =
//! `eta_filter_rad_s`), yaw ones from the reference.
//!
//! Guards: `mu_z <= max_down_accel_g g`, tilt of the thrust setpoint within
//! `max_tilt`, `asin` argument clamped. `Q` is singular at `theta = +-90 deg`, so
//! the RPY inner loop is never used near it: above `recovery_tilt` of body
//! tilt (`>= |theta|`) the attitude goes to the SO(3) loop of doc section 5
//! with `K_R = I_b K_P,eta`, `K_w = I_b K_D,eta` (the same linearized poles)
//! and the thrust is projected on the body axis, `u_T max(0, z_b . z_d)`,
//! until the tilt is back below the midpoint of `max_tilt` and `recovery_tilt`.

use super::gains::HierarchicalGains;
use super::law::{LawInput, LawOutput};
use super::rpy::{EulerTracking, RpyStage};

/// Internal state: the attitude-setpoint stage.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Hierarchical {
    stage: RpyStage,
}

impl Hierarchical {
    pub(super) fn reset(&mut self) {
        self.stage.reset();
    }

    /// One step of the law (module doc).
    #[inline(always)]
    pub(super) fn update(&mut self, gains: &HierarchicalGains, input: &LawInput) -> LawOutput {
        let (model, estimate) = (input.model, input.estimate);
        let m = model.mass_kg;
        let inertia = &model.inertia_kg_m2;
        let mu = input.reference.acceleration_ned
            - gains.kp_pos_per_s2.component_mul(&input.position_error())
            - gains.kd_pos_per_s.component_mul(&input.velocity_error())
            - estimate.force_ned / m;
        let inner_torque = |t: &EulerTracking| {
            let nu =
                t.sp.eta_d_ddot - gains.kd_att_per_s.component_mul(&t.e_dot) - gains.kp_att_per_s2.component_mul(&t.e);
            let w = &input.measurement.rate_frd;
            inertia * (t.trig.q_mul(&nu) + t.trig.q_dot_mul(&t.eta_dot, &t.eta_dot)) + w.cross(&(inertia * w))
                - t.q_inv.tr_mul(&estimate.torque_rpy)
        };
        // K_R = I_b K_P,eta, K_w = I_b K_D,eta: the same linearized poles
        let recovery_gains = || {
            let i = inertia.diagonal();
            (
                i.component_mul(&gains.kp_att_per_s2),
                i.component_mul(&gains.kd_att_per_s),
            )
        };
        self.stage
            .step(input, &mu, gains.eta_filter_rad_s, inner_torque, recovery_gains)
    }
}

#[cfg(test)]
mod tests {
    use super::super::ControlGains;
    use super::super::Reference;
    use super::super::rpy::wrap3;
    use super::*;
    use crate::math::{euler_zyx, from_euler_zyx, rate_map, rate_map_dot};
    use crate::signals::GRAVITY;
    use crate::signals::{Measurement, NominalModel};
    use nalgebra::Matrix3;
    use nalgebra::UnitQuaternion;
    use nalgebra::Vector3;

    fn model() -> NominalModel {
        NominalModel {
            mass_kg: 2.0,
            inertia_kg_m2: Matrix3::from_diagonal(&Vector3::new(0.0217, 0.0217, 0.04)),
        }
    }

    /// GIVEN the vehicle tilted and rotating WHEN the inner loop computes tau THEN
    /// Euler's equation with that tau gives exactly eta'' = nu (partial feedback
    /// linearization, doc section 4).
    #[test]
    fn inner_loop_linearizes_the_angular_dynamics() {
        let model = model();
        let g = ControlGains::for_vehicle(&model);
        let eta = Vector3::new(0.2, -0.3, 1.0);
        let q = rate_map(&eta);
        let eta_dot = Vector3::new(0.5, -0.4, 0.3);
        let meas = Measurement {
            time_s: 0.0,
            position_ned: Vector3::new(0.0, 0.0, -2.0),
            velocity_ned: Vector3::zeros(),
            attitude: from_euler_zyx(&eta),
            rate_frd: q * eta_dot,
        };
        let reference = Reference::hold(meas.position_ned, 0.0);
        let mut law = Hierarchical::default();
        let out = law.update(
            &g.hierarchical,
            &LawInput::without_estimate(&model, &meas, &reference, &g.limits),
        );
        assert!(!out.recovery);
        // nu from the reported setpoint: first sample, the filter starts at the measured rates
        let eta_d = euler_zyx(&UnitQuaternion::from_rotation_matrix(
            &nalgebra::Rotation3::from_matrix_unchecked(out.attitude_sp),
        ));
        let e = wrap3(&(eta - eta_d));
        let e_dot = Vector3::new(0.0, 0.0, eta_dot.z);
        let nu = -g.hierarchical.kd_att_per_s.component_mul(&e_dot) - g.hierarchical.kp_att_per_s2.component_mul(&e);
        // M eta'' + C eta' = Q^T tau  =>  eta'' = M^-1 (Q^T tau - C eta')
        let i = model.inertia_kg_m2;
        let w = q * eta_dot;
        let w_dot = i.try_inverse().unwrap() * (out.torque_frd - w.cross(&(i * w)));
        let eta_ddot = q.try_inverse().unwrap() * (w_dot - rate_map_dot(&eta, &eta_dot) * eta_dot);
        assert!((eta_ddot - nu).norm() < 1e-9 * nu.norm(), "{eta_ddot} vs {nu}");
    }

    /// GIVEN hover on the reference WHEN the law runs THEN u_T = m g and no torque.
    #[test]
    fn hover_on_reference_is_an_equilibrium() {
        let model = model();
        let g = ControlGains::for_vehicle(&model);
        let meas = Measurement {
            time_s: 0.0,
            position_ned: Vector3::new(1.0, 2.0, -3.0),
            velocity_ned: Vector3::zeros(),
            attitude: UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.7),
            rate_frd: Vector3::zeros(),
        };
        let reference = Reference::hold(meas.position_ned, 0.7);
        let mut law = Hierarchical::default();
        for _ in 0..3 {
            let out = law.update(
                &g.hierarchical,
                &LawInput::without_estimate(&model, &meas, &reference, &g.limits),
            );
            assert!((out.thrust_n - 2.0 * GRAVITY).abs() < 1e-12);
            assert!(out.torque_frd.norm() < 1e-12, "{}", out.torque_frd);
        }
    }
}
