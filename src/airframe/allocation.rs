//! Control allocation for a flat multirotor (`docs/model.md` section 3).
//!
//! Effectiveness: `[u_T, tau_x, tau_y, tau_z]^T = B w`, `w_i = omega_i^2`, with
//! column `B_i = [c_T, -l_i c_T sin a_i, l_i c_T cos a_i, s_i c_Q]^T`.
//! Inverse: minimum-norm `w = B^+ v`, `B^+ = B^T (B B^T)^-1`, then
//! desaturation with priority roll/pitch > thrust > yaw:
//! 1. if `w_T + w_rp + w_y` is within `[w_min, w_max]`, use it;
//! 2. otherwise the largest `sigma` in `[0, 1]` for which a collective shift
//!    `delta n_T` with `|delta| <= 0.3 u_T` fits `w_T + sigma w_rp` in bounds
//!    (bisection; smallest `|delta|`); if even `sigma = 0` needs a larger
//!    shift (thrust far beyond the rotors), the shift is unbounded: roll and
//!    pitch still come before thrust;
//! 3. then the largest `lambda` in `[0, 1]` that keeps `+ lambda w_y` in bounds;
//! 4. clamp; what was not delivered is reported.
//!
//! After rotor faults that leave hover with zero yaw torque on the edge of
//! what the rotors can give ([`YawPriority::Last`]), steps 2 and 3 take roll,
//! pitch and thrust from the inverse over `[u_T, tau_x, tau_y]` alone,
//! `P_3`, whatever yaw torque that gives, and step 3 then corrects the yaw
//! along the pure-yaw direction `y = B^+ e_4` of the four-row inverse:
//! `w_y = y (tau_z - b_4^T w_base)`, `b_4^T` the yaw row of `B`.

use nalgebra::{DMatrix, SMatrix, Vector3};

use super::RotorGeometry;
use crate::signals::{ControlWrench, MAX_ROTORS, RotorVector};

/// The 4 x n effectiveness matrix `B` (doc section 3).
///
/// Sines and cosines of multiples of 90 degrees come out as `1e-16`-sized
/// dust (`cos 90 deg`); snap it to the exact zero the geometry means.
pub fn effectiveness(rotors: &[RotorGeometry], c_t: f64, c_q: f64) -> DMatrix<f64> {
    let snap = |x: f64| if x.abs() < 1e-12 { 0.0 } else { x };
    DMatrix::from_fn(4, rotors.len(), |row, i| {
        let r = &rotors[i];
        match row {
            0 => c_t,
            1 => -r.arm_m * c_t * snap(r.angle_rad.sin()),
            2 => r.arm_m * c_t * snap(r.angle_rad.cos()),
            _ => r.spin.sign() * c_q,
        }
    })
}

/// The full 6 x n body wrench map `[f^b; tau^b] = B_bar w`: rows `f_x = f_y = 0`,
/// `f_z = -u_T`, then the torque rows of `B`.
#[must_use]
pub fn wrench_map(b: &DMatrix<f64>) -> DMatrix<f64> {
    DMatrix::from_fn(6, b.ncols(), |row, i| match row {
        0 | 1 => 0.0,
        2 => -b[(0, i)],
        _ => b[(row - 2, i)],
    })
}

/// Numerical rank: singular values above `1e-9` times the largest, after
/// scaling each row to unit norm (rows mix N and N m with very different sizes).
/// An empty matrix (every rotor failed: no column left) has rank 0.
#[must_use]
pub fn rank(m: &DMatrix<f64>) -> usize {
    if m.is_empty() {
        return 0;
    }
    let mut scaled = m.clone();
    for mut row in scaled.row_iter_mut() {
        let n = row.norm();
        if n > 0.0 {
            row /= n;
        }
    }
    let sv = scaled.singular_values();
    let max = sv.max();
    if max <= 0.0 {
        return 0;
    }
    sv.iter().filter(|s| **s > 1e-9 * max).count()
}

/// Minimum-norm allocator with priority desaturation.
#[derive(Clone, Debug)]
pub struct Allocator {
    n: usize,
    /// `B`, zero-padded to `MAX_ROTORS` columns.
    b: SMatrix<f64, 4, MAX_ROTORS>,
    /// `B^+`, zero-padded rows.
    b_pinv: SMatrix<f64, MAX_ROTORS, 4>,
    w_min: f64,
    w_max: f64,
    /// Largest collective shift as a fraction of the requested thrust.
    delta_max_fraction: f64,
    /// Rotors the allocation uses; the others (failed) are held at idle, `w_min`.
    active: [bool; MAX_ROTORS],
    /// With [`YawPriority::Last`], `P_3`: the inverse over `[u_T, tau_x,
    /// tau_y]` that steps 2 and 3 desaturate from (module doc). Boxed: held
    /// inline, its 288 bytes in every vehicle's control loop changed the
    /// control law's generated code (+43 instructions a step, measured).
    yaw_free: Option<Box<SMatrix<f64, MAX_ROTORS, 3>>>,
}

/// Where the yaw torque stands in an allocator built after rotor faults
/// ([`Allocator::with_rotor_gains`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum YawPriority {
    /// A row of the inverse like the others, desaturated last (the module
    /// doc's steps): the intact vehicle's way.
    Row,
    /// Roll, pitch and thrust first, from the inverse over `[u_T, tau_x,
    /// tau_y]`, whatever yaw torque that gives; then the yaw torque
    /// corrected towards the request as far as the bounds allow (module
    /// doc). For a hover whose zero yaw torque lies on the edge of what the
    /// remaining rotors can give: roll and pitch keep their whole margin,
    /// and the yaw gets what is left.
    Last,
    /// No yaw at all: the inverse over `[u_T, tau_x, tau_y]` only, its yaw
    /// column zero (the remaining rotors have rank 3).
    Dropped,
}

/// The result of one allocation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Allocation {
    /// Squared rotor speeds `w = omega^2` [rad^2/s^2], within bounds.
    pub speed_sq: RotorVector,
    /// Rotor speed commands `omega = sqrt(w)` [rad/s].
    pub speed_cmd_rad_s: RotorVector,
    /// What the rotors deliver: `B w`.
    pub achieved: ControlWrench,
    /// Requested minus achieved.
    pub unallocated: ControlWrench,
    /// Roll/pitch scale `sigma` in `[0, 1]`.
    pub roll_pitch_scale: f64,
    /// Collective shift `delta` [N of thrust].
    pub thrust_shift_n: f64,
    /// Yaw scale `lambda` in `[0, 1]`.
    pub yaw_scale: f64,
    /// Whether the unconstrained inverse was out of bounds.
    pub saturated: bool,
}

impl Allocator {
    /// Build from `B` (4 x n) and squared-speed bounds `[w_min, w_max]`.
    ///
    /// # Errors
    /// The rank of `B` when it is below 4 (no inverse), or when `n` is out of range.
    pub fn new(b: &DMatrix<f64>, w_min: f64, w_max: f64) -> Result<Self, usize> {
        // every rotor healthy: the fault allocator with all thrust fractions 1
        Self::with_rotor_gains(b, w_min, w_max, &vec![1.0; b.ncols()], YawPriority::Row)
    }

    /// The allocator after rotor faults (`docs/model.md` sections 3
    /// and 3b): column `i` of the intact `B` scaled by the thrust fraction
    /// `gains[i]` the rotor still gives (1 healthy, `0 < f < 1` degraded);
    /// a rotor with `gains[i] <= 0` (failed) is dropped: its column is deleted
    /// from the inverse, `B_f^+ = B_f^T (B_f B_f^T)^-1`, and it is commanded idle.
    /// `yaw` says where the yaw torque stands: with [`YawPriority::Dropped`]
    /// the inverse is over the rows `[u_T, tau_x, tau_y]` only (the
    /// rank-deficient case of a quad with a dead rotor) and the yaw column
    /// of `B^+` is zero; with [`YawPriority::Last`] `B^+` is the right
    /// inverse `[P_3 - y b_4^T P_3, y]` (exact where nothing saturates) and
    /// desaturation starts from `P_3` (module doc).
    ///
    /// # Errors
    /// The rank of the rows the inverse needs when it is below their number
    /// (no inverse), or when the shapes are wrong.
    pub fn with_rotor_gains(
        b: &DMatrix<f64>,
        w_min: f64,
        w_max: f64,
        gains: &[f64],
        yaw: YawPriority,
    ) -> Result<Self, usize> {
        let n = b.ncols();
        if b.nrows() != 4 || n > MAX_ROTORS || gains.len() != n {
            return Err(rank(b));
        }
        let kept: Vec<usize> = (0..n).filter(|i| gains[*i] > 0.0).collect();
        // the minimum-norm inverse of the first `rows` rows over the kept columns
        let inverse = |rows: usize| -> Result<DMatrix<f64>, usize> {
            let bf = DMatrix::from_fn(rows, kept.len(), |r, j| b[(r, kept[j])] * gains[kept[j]]);
            let r = rank(&bf);
            if r < rows {
                return Err(r);
            }
            let inv = (&bf * bf.transpose()).try_inverse().ok_or(r)?;
            Ok(bf.transpose() * inv)
        };
        let mut bp = SMatrix::<f64, 4, MAX_ROTORS>::zeros();
        let mut active = [false; MAX_ROTORS];
        for &i in &kept {
            active[i] = true;
            for k in 0..4 {
                bp[(k, i)] = b[(k, i)] * gains[i];
            }
        }
        // a kept rotor's rows of a pseudo-inverse, zero-padded
        let padded = |pinv: &DMatrix<f64>| {
            let mut pp = SMatrix::<f64, MAX_ROTORS, 4>::zeros();
            for (j, &i) in kept.iter().enumerate() {
                for k in 0..pinv.ncols() {
                    pp[(i, k)] = pinv[(j, k)];
                }
            }
            pp
        };
        let (b_pinv, yaw_free) = match yaw {
            YawPriority::Row => (padded(&inverse(4)?), None),
            YawPriority::Dropped => (padded(&inverse(3)?), None),
            YawPriority::Last => {
                let y = padded(&inverse(4)?).column(3).into_owned();
                let p3 = padded(&inverse(3)?).fixed_columns::<3>(0).into_owned();
                // `P_3 - y b_4^T P_3`: roll, pitch and thrust with zero yaw torque
                let k = bp.row(3) * p3;
                let mut pp = SMatrix::<f64, MAX_ROTORS, 4>::zeros();
                pp.fixed_columns_mut::<3>(0).copy_from(&(p3 - y * k));
                pp.set_column(3, &y);
                (pp, Some(Box::new(p3)))
            }
        };
        Ok(Self {
            n,
            b: bp,
            b_pinv,
            w_min,
            w_max,
            delta_max_fraction: 0.3,
            active,
            yaw_free,
        })
    }

    /// Where the yaw torque stands in this allocator.
    #[must_use]
    pub fn yaw_priority(&self) -> YawPriority {
        match (&self.yaw_free, self.b_pinv.column(3).iter().all(|x| *x == 0.0)) {
            (Some(_), _) => YawPriority::Last,
            (None, true) => YawPriority::Dropped,
            (None, false) => YawPriority::Row,
        }
    }

    /// Whether rotor `i` (from 0) is allocated (false for a dropped, failed rotor).
    #[must_use]
    pub fn is_active(&self, i: usize) -> bool {
        self.active.get(i).copied().unwrap_or(false)
    }

    /// Number of rotors.
    #[must_use]
    pub fn rotor_count(&self) -> usize {
        self.n
    }

    /// `B`, zero-padded.
    #[must_use]
    pub fn b(&self) -> &SMatrix<f64, 4, MAX_ROTORS> {
        &self.b
    }

    /// `B^+`, zero-padded.
    #[must_use]
    pub fn b_pinv(&self) -> &SMatrix<f64, MAX_ROTORS, 4> {
        &self.b_pinv
    }

    /// The wrench `B w` of squared speeds `w`.
    #[must_use]
    pub fn forward(&self, speed_sq: &RotorVector) -> ControlWrench {
        // `B w` over the n used columns only (column-major storage), summed in
        // the order of nalgebra's product: the padding only adds exact zeros
        let mut acc = [0.0; 4];
        for (col, &x) in self.b.as_slice().chunks_exact(4).zip(speed_sq.as_slice()).take(self.n) {
            for (a, b) in acc.iter_mut().zip(col) {
                *a += b * x;
            }
        }
        ControlWrench::new(acc[0], Vector3::new(acc[1], acc[2], acc[3]))
    }

    /// Unconstrained minimum-norm squared speeds `B^+ v` (may leave the bounds).
    #[must_use]
    pub fn inverse(&self, v: &ControlWrench) -> RotorVector {
        self.b_pinv * v.to_vector()
    }

    #[inline(always)]
    fn in_bounds(&self, w: &RotorVector) -> bool {
        w.iter()
            .take(self.n)
            .zip(&self.active)
            .all(|(x, on)| !on || (*x >= self.w_min && *x <= self.w_max))
    }

    /// Feasible collective-shift interval `[lo, hi]` for `base + delta n_T`.
    fn shift_interval(&self, base: &RotorVector, n_t: &RotorVector) -> (f64, f64) {
        let mut lo = f64::NEG_INFINITY;
        let mut hi = f64::INFINITY;
        for i in (0..self.n).filter(|i| self.active[*i]) {
            // n_T entries are > 0 for any flat frame (every column has c_T > 0 in row 1).
            lo = lo.max((self.w_min - base[i]) / n_t[i]);
            hi = hi.min((self.w_max - base[i]) / n_t[i]);
        }
        (lo, hi)
    }

    /// Allocate a requested wrench to rotor speeds within limits (module doc).
    #[must_use]
    pub fn allocate(&self, req: &ControlWrench) -> Allocation {
        allocate_wrench(self, req)
    }

    /// The body of [`Self::allocate`], inlined into both versions of
    /// [`allocate_wrench`].
    #[inline(always)]
    fn allocate_inner(&self, req: &ControlWrench) -> Allocation {
        // fast path: the unsaturated `B^+ v`, `w_T + w_rp + w_y` per rotor
        let (t, tau) = (req.thrust_n, &req.torque_frd);
        let p = &self.b_pinv;
        let mut full = RotorVector::zeros();
        // n <= MAX_ROTORS, said to the compiler: no bounds checks in the loops
        let n = self.n.min(MAX_ROTORS);
        for i in 0..n {
            full[i] = p[(i, 0)] * t + (p[(i, 1)] * tau.x + p[(i, 2)] * tau.y) + p[(i, 3)] * tau.z;
        }
        let (sigma, delta, lambda, saturated, w) = if self.in_bounds(&full) {
            (1.0, 0.0, 1.0, false, full)
        } else {
            // roll, pitch and thrust from `P_3` when yaw comes last
            let (w_t, w_rp, n_t): (RotorVector, RotorVector, RotorVector) = match &self.yaw_free {
                None => (
                    self.b_pinv.column(0) * req.thrust_n,
                    self.b_pinv.column(1) * req.torque_frd.x + self.b_pinv.column(2) * req.torque_frd.y,
                    self.b_pinv.column(0).into_owned(),
                ),
                Some(p3) => (
                    p3.column(0) * req.thrust_n,
                    p3.column(1) * req.torque_frd.x + p3.column(2) * req.torque_frd.y,
                    p3.column(0).into_owned(),
                ),
            };
            let delta_max = self.delta_max_fraction * req.thrust_n.abs();
            // For a fixed sigma the feasible shifts form an interval; the feasible
            // (sigma, delta) set is convex, so feasibility in sigma is an interval
            // [0, sigma*] found by bisection.
            let feasible = |sigma: f64, delta_max: f64| -> Option<f64> {
                let (lo, hi) = self.shift_interval(&(w_t + w_rp * sigma), &n_t);
                let (lo, hi) = (lo.max(-delta_max), hi.min(delta_max));
                (lo <= hi).then(|| 0.0f64.clamp(lo, hi))
            };
            let largest_sigma = |delta_max: f64| -> Option<(f64, f64)> {
                if let Some(d) = feasible(1.0, delta_max) {
                    return Some((1.0, d));
                }
                let mut d = feasible(0.0, delta_max)?;
                let (mut a, mut b) = (0.0, 1.0);
                for _ in 0..40 {
                    let m = 0.5 * (a + b);
                    if let Some(dm) = feasible(m, delta_max) {
                        a = m;
                        d = dm;
                    } else {
                        b = m;
                    }
                }
                Some((a, d))
            };
            // Thrust gives way to roll/pitch within delta_max; when even hover
            // thrust does not fit within it (a request far beyond the rotors),
            // thrust gives way without limit so roll and pitch keep priority.
            let (sigma, delta) = largest_sigma(delta_max)
                .or_else(|| largest_sigma(f64::INFINITY))
                .unwrap_or((0.0, 0.0));
            let base = w_t + w_rp * sigma + n_t * delta;
            // the yaw torque still wanted: all of it, or what `P_3`'s base lacks
            let w_y = match &self.yaw_free {
                None => self.b_pinv.column(3) * req.torque_frd.z,
                Some(_) => self.b_pinv.column(3) * (req.torque_frd.z - self.b.row(3).transpose().dot(&base)),
            };
            let mut lambda: f64 = 1.0;
            for i in (0..self.n).filter(|i| self.active[*i]) {
                if w_y[i] > 0.0 {
                    lambda = lambda.min((self.w_max - base[i]) / w_y[i]);
                } else if w_y[i] < 0.0 {
                    lambda = lambda.min((self.w_min - base[i]) / w_y[i]);
                }
            }
            let lambda = lambda.max(0.0);
            (sigma, delta, lambda, true, base + w_y * lambda)
        };
        let mut speed_sq = RotorVector::zeros();
        let mut speed_cmd = RotorVector::zeros();
        for i in 0..n {
            // a dropped rotor idles: its column of `B` is zero, so it adds nothing
            speed_sq[i] = if self.active[i] {
                w[i].clamp(self.w_min, self.w_max)
            } else {
                self.w_min
            };
            speed_cmd[i] = speed_sq[i].sqrt();
        }
        let achieved = self.forward(&speed_sq);
        Allocation {
            speed_sq,
            speed_cmd_rad_s: speed_cmd,
            achieved,
            unallocated: ControlWrench::from_vector(&(req.to_vector() - achieved.to_vector())),
            roll_pitch_scale: sigma,
            thrust_shift_n: delta,
            yaw_scale: lambda,
            saturated,
        }
    }
}

// Compiled for the x86-64 baseline and for AVX2, the CPU picking one at the
// first call: the same bits, fewer instructions (why: the comment above
// `step_plant` in sim/plant.rs).

/// [`Allocator::allocate`].
#[multiversion::multiversion(targets("x86_64+avx2"))]
fn allocate_wrench(allocator: &Allocator, req: &ControlWrench) -> Allocation {
    allocator.allocate_inner(req)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::airframe::Airframe;

    #[test]
    fn all_gains_one_is_the_intact_allocator_and_a_dropped_rotor_idles_while_the_rest_deliver() {
        let af = Airframe::load("octo").unwrap();
        let (lo, hi) = af.speed_sq_bounds();
        let b = af.effectiveness();
        let intact = af.allocator();
        let same = Allocator::with_rotor_gains(&b, lo, hi, &[1.0; 8], YawPriority::Row).unwrap();
        let req = ControlWrench::new(16.0, Vector3::new(0.2, -0.3, 0.05));
        assert_eq!(intact.allocate(&req).speed_sq, same.allocate(&req).speed_sq);
        let mut g = [1.0; 8];
        g[2] = 0.0;
        g[5] = 0.5;
        let reduced = Allocator::with_rotor_gains(&b, lo, hi, &g, YawPriority::Row).unwrap();
        assert!(!reduced.is_active(2) && reduced.is_active(5));
        let a = reduced.allocate(&req);
        assert!(!a.saturated);
        assert_eq!(a.speed_sq[2], lo);
        // what the remaining rotors (rotor 6 at half thrust) deliver is the request
        let mut col = b.clone();
        col.column_mut(2).fill(0.0);
        col.column_mut(5).scale_mut(0.5);
        let w = nalgebra::DVector::from_fn(8, |i, _| a.speed_sq[i]);
        let delivered = &col * w;
        for (d, r) in delivered.iter().zip(req.to_vector().iter()) {
            assert!((d - r).abs() < 1e-9, "{delivered} vs {req:?}");
        }
        // a quad without a rotor has no 4-row inverse; without the yaw row it has one
        let q = Airframe::load("quad").unwrap();
        let (lo, hi) = q.speed_sq_bounds();
        let g = [0.0, 1.0, 1.0, 1.0];
        assert_eq!(
            Allocator::with_rotor_gains(&q.effectiveness(), lo, hi, &g, YawPriority::Row).unwrap_err(),
            3
        );
        let yawless = Allocator::with_rotor_gains(&q.effectiveness(), lo, hi, &g, YawPriority::Dropped).unwrap();
        assert_eq!(yawless.b_pinv().column(3).norm(), 0.0);
    }

    #[test]
    fn with_yaw_last_roll_pitch_and_thrust_keep_their_range_and_yaw_gets_the_rest() {
        // the stock hexa without rotor 1: hover with zero yaw torque needs
        // the opposite rotor at idle, so a zero-yaw base leaves no margin
        let af = Airframe::load("hexa").unwrap();
        let (lo, hi) = af.speed_sq_bounds();
        let b = af.effectiveness();
        let g = [0.0, 1.0, 1.0, 1.0, 1.0, 1.0];
        let row = Allocator::with_rotor_gains(&b, lo, hi, &g, YawPriority::Row).unwrap();
        let last = Allocator::with_rotor_gains(&b, lo, hi, &g, YawPriority::Last).unwrap();
        assert_eq!(last.yaw_priority(), YawPriority::Last);
        assert_eq!(row.yaw_priority(), YawPriority::Row);
        let hover = af.mass_kg * 9.81;
        let mut row_lost_roll_pitch = false;
        for (tx, ty) in [(0.3, 0.0), (-0.3, 0.0), (0.0, 0.3), (0.0, -0.3), (0.2, -0.2)] {
            let req = ControlWrench::new(hover, Vector3::new(tx, ty, 0.0));
            let a = last.allocate(&req);
            let (got, want) = (a.achieved.to_vector(), req.to_vector());
            for k in 0..3 {
                assert!((got[k] - want[k]).abs() < 1e-6, "{tx} {ty}: {got} vs {want}");
            }
            assert_eq!(a.roll_pitch_scale, 1.0);
            row_lost_roll_pitch |= row.allocate(&req).roll_pitch_scale < 1.0;
            // the yaw torque left is the closest the bounds allow: one step
            // further along the pure-yaw direction leaves them
            let dz = a.unallocated.torque_frd.z;
            if dz.abs() > 1e-9 {
                assert!(a.yaw_scale < 1.0);
                assert!(!last.in_bounds(&(a.speed_sq + last.b_pinv().column(3) * (1e-3 * dz))));
            }
        }
        assert!(row_lost_roll_pitch, "the zero-yaw base gives way on roll or pitch");
        // a wrench the rotors can give (one they gave) is given exactly
        let given = last.allocate(&ControlWrench::new(hover, Vector3::zeros())).achieved;
        assert!(last.allocate(&given).unallocated.to_vector().norm() < 1e-6);
    }
}
