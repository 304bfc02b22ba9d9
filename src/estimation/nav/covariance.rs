//! Covariance prediction of the 15-state error filter, using the sparsity of
//! the state transition (PX4 EKF2 predicts its covariance at
//! `EKF2_PREDICT_US` from the IMU increments accumulated over that period).
//!
//! ```text
//! error state x = [dp, dv, dth, dbg, dba]   (NED, NED, NED angle, FRD, FRD)
//! dp' = dv
//! dv' = -[a_ned]x dth - R dba                a_ned = mean specific force, NED
//! dth' = -R dbg                              R = FRD -> NED
//! F = I + A dt,   P <- F P F^T + Q
//! Q = diag(0, (acc_noise dt)^2, (gyr_noise dt)^2, (gyr_b_noise dt)^2, (acc_b_noise dt)^2)
//! ```
//! `F P F^T` is formed as `F (F P)^T` with `F X` applied by blocks (only the
//! position, velocity and angle rows of `A` are non-zero): about 900
//! multiply-adds instead of the 6750 of two dense 15x15 products.

use nalgebra::{Matrix3, SMatrix, Vector3};

/// Error-state dimension.
pub const N: usize = 15;
/// The error covariance.
pub type Cov = SMatrix<f64, N, N>;

/// First index of each error-state block.
pub mod idx {
    /// Position error, NED [m].
    pub const POS: usize = 0;
    /// Velocity error, NED [m/s].
    pub const VEL: usize = 3;
    /// Attitude error, a rotation vector in NED [rad].
    pub const ANG: usize = 6;
    /// Gyro bias error, FRD [rad/s].
    pub const GB: usize = 9;
    /// Accelerometer bias error, FRD [m/s^2].
    pub const AB: usize = 12;
}

/// The white-noise figures of one prediction, as standard deviations over its interval.
#[derive(Clone, Copy, Debug)]
pub struct ProcessNoise {
    /// Velocity increment noise [m/s].
    pub dvel: f64,
    /// Angle increment noise [rad].
    pub dang: f64,
    /// Gyro bias increment [rad/s].
    pub gyro_bias: f64,
    /// Accelerometer bias increment [m/s^2].
    pub accel_bias: f64,
}

/// `F X` with `F = I + A dt` (see the module equations).
fn apply_f(x: &Cov, dt: f64, r: &Matrix3<f64>, a_hat: &Matrix3<f64>) -> Cov {
    let mut out = *x;
    let vel = x.fixed_rows::<3>(idx::VEL);
    let ang = x.fixed_rows::<3>(idx::ANG);
    let gb = x.fixed_rows::<3>(idx::GB);
    let ab = x.fixed_rows::<3>(idx::AB);
    let dpos = vel * dt;
    let dvel = (a_hat * ang + r * ab) * (-dt);
    let dang = (r * gb) * (-dt);
    let mut rows = out.fixed_rows_mut::<3>(idx::POS);
    rows += dpos;
    let mut rows = out.fixed_rows_mut::<3>(idx::VEL);
    rows += dvel;
    let mut rows = out.fixed_rows_mut::<3>(idx::ANG);
    rows += dang;
    out
}

/// `P <- F P F^T + Q` over `dt` seconds with attitude `r` (FRD -> NED) and
/// mean specific force `a_ned`; the result is made exactly symmetric.
pub fn predict(p: &mut Cov, dt: f64, r: &Matrix3<f64>, a_ned: &Vector3<f64>, noise: &ProcessNoise) {
    let a_hat = crate::math::hat(a_ned);
    let fp = apply_f(p, dt, r, &a_hat);
    let fpf = apply_f(&fp.transpose(), dt, r, &a_hat);
    for i in 0..N {
        for j in i..N {
            let m = 0.5 * (fpf[(i, j)] + fpf[(j, i)]);
            p[(i, j)] = m;
            p[(j, i)] = m;
        }
    }
    let add = [
        noise.dvel * noise.dvel,
        noise.dang * noise.dang,
        noise.gyro_bias * noise.gyro_bias,
        noise.accel_bias * noise.accel_bias,
    ];
    for (block, var) in [idx::VEL, idx::ANG, idx::GB, idx::AB].into_iter().zip(add) {
        for k in 0..3 {
            p[(block + k, block + k)] += var;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn block_product_equals_the_dense_one() {
        let mut p = Cov::identity();
        for i in 0..N {
            for j in 0..N {
                p[(i, j)] += 0.01 * ((i * 7 + j * 3) % 11) as f64 + 0.01 * ((j * 7 + i * 3) % 11) as f64;
            }
        }
        let r = nalgebra::Rotation3::from_euler_angles(0.1, -0.2, 0.7).into_inner();
        let a = Vector3::new(0.3, -0.4, -9.7);
        let dt = 0.01;
        let mut f = Cov::identity();
        for k in 0..3 {
            f[(idx::POS + k, idx::VEL + k)] = dt;
        }
        f.fixed_view_mut::<3, 3>(idx::VEL, idx::ANG)
            .copy_from(&(-crate::math::hat(&a) * dt));
        f.fixed_view_mut::<3, 3>(idx::VEL, idx::AB).copy_from(&(-r * dt));
        f.fixed_view_mut::<3, 3>(idx::ANG, idx::GB).copy_from(&(-r * dt));
        let dense = f * p * f.transpose();
        let noise = ProcessNoise {
            dvel: 0.0,
            dang: 0.0,
            gyro_bias: 0.0,
            accel_bias: 0.0,
        };
        predict(&mut p, dt, &r, &a, &noise);
        assert!((p - dense).abs().max() < 1e-12, "{}", (p - dense).abs().max());
    }
}
