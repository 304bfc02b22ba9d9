//! The ZYX Euler-angle kinematics in closed form: from the sines and cosines
//! of `eta = [phi, theta, psi]` (read off `R` or taken from a setpoint), the
//! rotation, the rate map, its inverse and its derivative, with no further
//! trigonometry (`s_x = sin x`, `c_x = cos x`, `t_x = tan x`):
//! ```text
//! R(eta)  = Rz(psi) Ry(theta) Rx(phi)                          (FRD to NED)
//! w       = Q(eta) eta_dot,  Q = [[1, 0, -s_th], [0, c_ph, c_th s_ph], [0, -s_ph, c_th c_ph]]
//! Q^-1    = [[1, s_ph t_th, c_ph t_th], [0, c_ph, -s_ph], [0, s_ph / c_th, c_ph / c_th]]
//! phi = atan2(r32, r33),  theta = -asin(r31),  psi = atan2(r21, r11)
//! ```
//! `Q` is singular at `theta = +-90 deg` (`det Q = cos theta`).

use nalgebra::{Matrix3, Vector3};

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

    /// The Euler angles of the attitude `r` (FRD to NED) as [`crate::math::euler_zyx`]:
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

#[cfg(test)]
mod tests {
    use super::*;

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
}
