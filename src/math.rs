//! Small SO(3) helpers shared by the plant, the controllers and the estimator.
//!
//! Conventions (`docs/model.md` section 1): `S(a) b = a x b`;
//! for any 3x3 `X`, `vee(X) = vee((X - X^T)/2)`; ZYX Euler angles
//! `eta = [phi, theta, psi]` with `R = Rz(psi) Ry(theta) Rx(phi)` mapping
//! FRD body vectors into NED.

use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};

/// `S(a)`: the skew-symmetric matrix with `S(a) b = a x b`.
#[must_use]
pub fn hat(a: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -a.z, a.y, a.z, 0.0, -a.x, -a.y, a.x, 0.0)
}

/// `X^vee` of the skew part of `X`: `1/2 [X32 - X23, X13 - X31, X21 - X12]`.
#[must_use]
pub fn vee(x: &Matrix3<f64>) -> Vector3<f64> {
    0.5 * Vector3::new(x[(2, 1)] - x[(1, 2)], x[(0, 2)] - x[(2, 0)], x[(1, 0)] - x[(0, 1)])
}

/// ZYX Euler angles `[phi, theta, psi]` [rad] of the body-to-NED rotation:
/// `phi = atan2(r32, r33)`, `theta = -asin(r31)`, `psi = atan2(r21, r11)`.
#[must_use]
pub fn euler_zyx(q: &UnitQuaternion<f64>) -> Vector3<f64> {
    let r = q.to_rotation_matrix();
    let r = r.matrix();
    Vector3::new(
        r[(2, 1)].atan2(r[(2, 2)]),
        -r[(2, 0)].clamp(-1.0, 1.0).asin(),
        r[(1, 0)].atan2(r[(0, 0)]),
    )
}

/// Body-to-NED attitude from ZYX Euler angles: `R = Rz(psi) Ry(theta) Rx(phi)`.
#[must_use]
pub fn from_euler_zyx(eta: &Vector3<f64>) -> UnitQuaternion<f64> {
    UnitQuaternion::from_rotation_matrix(&Rotation3::from_euler_angles(eta.x, eta.y, eta.z))
}

/// Rate map `Q(eta)` with `omega_frd = Q eta_dot` (ZYX Euler angles):
/// `[[1, 0, -s_th], [0, c_ph, c_th s_ph], [0, -s_ph, c_th c_ph]]`, `det Q = cos theta`.
#[must_use]
pub fn rate_map(eta: &Vector3<f64>) -> Matrix3<f64> {
    let (sp, cp) = eta.x.sin_cos();
    let (st, ct) = eta.y.sin_cos();
    Matrix3::new(1.0, 0.0, -st, 0.0, cp, ct * sp, 0.0, -sp, ct * cp)
}

/// Time derivative `Q_dot(eta, eta_dot)` of [`rate_map`]:
/// `[[0, 0, -c_th th'], [0, -s_ph ph', -s_th s_ph th' + c_th c_ph ph'], [0, -c_ph ph', -s_th c_ph th' - c_th s_ph ph']]`.
#[must_use]
pub fn rate_map_dot(eta: &Vector3<f64>, eta_dot: &Vector3<f64>) -> Matrix3<f64> {
    let (sp, cp) = eta.x.sin_cos();
    let (st, ct) = eta.y.sin_cos();
    let (pd, td) = (eta_dot.x, eta_dot.y);
    Matrix3::new(
        0.0,
        0.0,
        -ct * td,
        0.0,
        -sp * pd,
        -st * sp * td + ct * cp * pd,
        0.0,
        -cp * pd,
        -st * cp * td - ct * sp * pd,
    )
}

/// RPY inertia matrix `M(eta) = Q^T I_b Q`.
#[must_use]
pub fn rpy_inertia(inertia_frd: &Matrix3<f64>, eta: &Vector3<f64>) -> Matrix3<f64> {
    let q = rate_map(eta);
    q.transpose() * inertia_frd * q
}

/// RPY Coriolis matrix `C(eta, eta_dot) = Q^T I_b Q_dot - Q^T S(I_b Q eta_dot) Q`,
/// the one for which `M_dot - 2C` is skew-symmetric (doc section 1; the often
/// quoted `Q^T S(Q eta_dot) I_b Q + Q^T I_b Q_dot` is not, and biases the estimator).
#[must_use]
pub fn rpy_coriolis(inertia_frd: &Matrix3<f64>, eta: &Vector3<f64>, eta_dot: &Vector3<f64>) -> Matrix3<f64> {
    let q = rate_map(eta);
    let qd = rate_map_dot(eta, eta_dot);
    let qt = q.transpose();
    qt * inertia_frd * qd - qt * hat(&(inertia_frd * q * eta_dot)) * q
}

/// Wrap an angle [rad] to `(-pi, pi]`.
#[must_use]
pub fn wrap_pi(a: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    let s = a + PI;
    // `rem_euclid` (a software `fmod`) returns an `s` already in `[0, 2 pi)`
    // unchanged: skip it then, as for every angle that is already wrapped
    let w = if (0.0..TAU).contains(&s) { s } else { s.rem_euclid(TAU) } - PI;
    if w <= -PI { w + TAU } else { w }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hat_is_cross_product_and_vee_inverts_it() {
        let a = Vector3::new(0.3, -1.2, 2.0);
        let b = Vector3::new(-0.7, 0.4, 1.1);
        assert!((hat(&a) * b - a.cross(&b)).norm() < 1e-15);
        assert!((vee(&hat(&a)) - a).norm() < 1e-15);
    }

    #[test]
    fn euler_round_trip_matches_doc_convention() {
        let eta = Vector3::new(0.1, -0.2, 0.3);
        let q = from_euler_zyx(&eta);
        assert!((euler_zyx(&q) - eta).norm() < 1e-12);
        // r31 = -sin(theta)
        let r = q.to_rotation_matrix();
        assert!((r[(2, 0)] + (-0.2f64).sin()).abs() < 1e-12);
    }

    /// Doc section 9 oracle: Q, M, C eta_dot, C^T eta_dot and the skew property.
    #[test]
    fn rpy_matrices_match_doc_oracle() {
        let i_b = Matrix3::from_diagonal(&Vector3::new(1.2416, 1.2416, 2.4832));
        let eta = Vector3::new(0.1, -0.2, 0.3);
        let eta_dot = Vector3::new(0.4, -0.5, 0.6);
        let q = rate_map(&eta);
        let q_doc = Matrix3::new(1.0, 0.0, 0.198669, 0.0, 0.995004, 0.097843, 0.0, -0.099833, 0.975170);
        assert!((q - q_doc).abs().max() < 1e-6);
        let m = rpy_inertia(&i_b, &eta);
        let m_doc = Matrix3::new(
            1.2416, 0.0, 0.246668, 0.0, 1.253975, -0.120875, 0.246668, -0.120875, 2.422308,
        );
        assert!((m - m_doc).abs().max() < 1e-6);
        let c = rpy_coriolis(&i_b, &eta, &eta_dot);
        assert!((c * eta_dot - Vector3::new(0.019091, -0.129675, 0.275295)).abs().max() < 1e-6);
        assert!(
            (c.transpose() * eta_dot - Vector3::new(0.345964, -0.198530, 0.0))
                .abs()
                .max()
                < 1e-6
        );
        // M_dot by central difference along eta_dot; M_dot - 2C must be skew
        let h = 1e-6;
        let m_dot = (rpy_inertia(&i_b, &(eta + eta_dot * h)) - rpy_inertia(&i_b, &(eta - eta_dot * h))) / (2.0 * h);
        let n = m_dot - 2.0 * c;
        assert!((n + n.transpose()).abs().max() < 1e-8);
    }

    /// `M eta_ddot + C eta_dot = Q^T tau` is Euler's equation times `Q^T`.
    #[test]
    fn rpy_model_is_euler_equation() {
        let i_b = Matrix3::from_diagonal(&Vector3::new(0.03, 0.04, 0.05));
        let eta = Vector3::new(0.3, 0.2, -1.0);
        let eta_dot = Vector3::new(-0.4, 0.7, 0.2);
        let eta_ddot = Vector3::new(1.0, -2.0, 0.5);
        let q = rate_map(&eta);
        let w = q * eta_dot;
        let w_dot = q * eta_ddot + rate_map_dot(&eta, &eta_dot) * eta_dot;
        let tau = i_b * w_dot + w.cross(&(i_b * w));
        let lhs = rpy_inertia(&i_b, &eta) * eta_ddot + rpy_coriolis(&i_b, &eta, &eta_dot) * eta_dot;
        assert!((lhs - q.transpose() * tau).norm() < 1e-12);
    }

    #[test]
    fn wrap_pi_range() {
        assert!((wrap_pi(3.0 * std::f64::consts::PI) - std::f64::consts::PI).abs() < 1e-12);
        assert!((wrap_pi(-0.5) + 0.5).abs() < 1e-15);
        assert!(wrap_pi(-std::f64::consts::PI) > 0.0);
    }

    /// GIVEN angles inside and outside `(-pi, pi]`, the edges and zeros WHEN
    /// wrapped THEN the result is `rem_euclid`'s for every one, to the bit.
    #[test]
    fn wrap_pi_equals_the_rem_euclid_formula_bit_for_bit() {
        use std::f64::consts::{PI, TAU};
        let formula = |a: f64| {
            let w = (a + PI).rem_euclid(TAU) - PI;
            if w <= -PI { w + TAU } else { w }
        };
        let mut angles = vec![0.0, -0.0, PI, -PI, TAU, -TAU, f64::NAN, f64::INFINITY, 1e-300, -1e-300];
        angles.extend((-20_000..20_000).map(|k| f64::from(k) * 1.37e-3));
        angles.extend((0..64).flat_map(|k| {
            let edge = f64::from(k - 32) * PI;
            [
                edge,
                f64::from_bits(edge.to_bits() + 1),
                f64::from_bits(edge.to_bits().wrapping_sub(1)),
            ]
        }));
        for a in angles {
            assert_eq!(wrap_pi(a).to_bits(), formula(a).to_bits(), "{a:e}");
        }
    }
}
