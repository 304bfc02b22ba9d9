//! The geometric attitude loop on SO(3) (Lee, Leok, McClamroch 2010; doc
//! section 5), shared by the geometric law, the RPY laws' recovery and the
//! attitude-setpoint mode:
//! ```text
//! e_R = 1/2 (R_d^T R - R^T R_d)^vee,   e_w = w - R^T R_d w_d
//! tau = -K_R e_R - K_w e_w + w x I w - I (w x R^T R_d w_d - R^T R_d w_d_dot)
//! ```
//! `w_d`, `w_d_dot` in the desired body frame, `w` and `tau` in body FRD.

use nalgebra::{Matrix3, Vector3};

use crate::math::vee;

/// The attitude motion the loop tracks: `R_d` (FRD to NED), `w_d` [rad/s] and
/// `w_d_dot` [rad/s^2] in the desired body frame (borrowed: nothing is copied
/// on the hot path).
#[derive(Clone, Copy, Debug)]
pub(super) struct AttitudeTarget<'a> {
    pub(super) r_d: &'a Matrix3<f64>,
    pub(super) omega_d: &'a Vector3<f64>,
    pub(super) omega_dot_d: &'a Vector3<f64>,
}

/// The loop's gains per body axis: `K_R` [N m/rad], `K_w` [N m s/rad].
#[derive(Clone, Copy, Debug)]
pub(super) struct So3Gains<'a> {
    pub(super) kr: &'a Vector3<f64>,
    pub(super) kw: &'a Vector3<f64>,
}

/// Attitude-loop result.
#[derive(Clone, Copy, Debug)]
pub(super) struct So3Output {
    pub(super) torque: Vector3<f64>,
    /// `e_R` [rad].
    pub(super) e_r: Vector3<f64>,
}

/// The torque `tau` [N m] (module doc) for the attitude `r` (FRD to NED) and
/// body rate `omega` [rad/s] of a body of inertia `inertia` [kg m^2]. `R^T R_d`
/// is formed once: `R_d^T R` is its transpose, so `e_R = -(R^T R_d)^vee`.
#[inline(always)]
pub(super) fn so3_attitude(
    inertia: &Matrix3<f64>,
    r: &Matrix3<f64>,
    omega: &Vector3<f64>,
    target: &AttitudeTarget,
    gains: &So3Gains,
) -> So3Output {
    let AttitudeTarget {
        r_d,
        omega_d,
        omega_dot_d,
    } = *target;
    let So3Gains { kr, kw } = *gains;
    let rt_rd = r.tr_mul(r_d);
    let e_r = -vee(&rt_rd);
    let w_d_body = rt_rd * omega_d;
    let e_w = omega - w_d_body;
    let torque = -kr.component_mul(&e_r) - kw.component_mul(&e_w) + omega.cross(&(inertia * omega))
        - inertia * (omega.cross(&w_d_body) - rt_rd * omega_dot_d);
    So3Output { torque, e_r }
}

#[cfg(test)]
mod tests {
    use super::*;

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
        let target = AttitudeTarget {
            r_d: &r,
            omega_d: &w,
            omega_dot_d: &wd,
        };
        let gains = So3Gains {
            kr: &Vector3::repeat(5.0),
            kw: &Vector3::repeat(1.0),
        };
        let out = so3_attitude(&i, &r, &w, &target, &gains);
        assert!(out.e_r.norm() < 1e-15);
        assert!((out.torque - (w.cross(&(i * w)) + i * wd)).norm() < 1e-14);
    }
}
