//! Ground and ceiling effect as per-rotor thrust ratios (doc
//! `docs/model.md` section 8).
//!
//! * Single rotor (Cheeseman and Bennett 1955, image method):
//!   `T_ige / T_oge = 1 / (1 - (rho / 4z)^2)`.
//! * Multirotor, all rotors at height `z` (Sanchez-Cuevas, Heredia, Ollero 2017):
//!   `1 / (1 - (rho/4z)^2 - rho^2 z/(d^2+4z^2)^1.5 - rho^2/2 z/(2d^2+4z^2)^1.5 - 2 rho^2 z/(b^2+4z^2)^1.5 K_b)`.
//! * Per rotor, heights `z_i` differing (tilt, partial cover):
//!   `T_i / T_i,oge = [1 - sum_j rho^2/4 (z_i+z_j)/(d_ij^2+(z_i+z_j)^2)^1.5 - 2 K_b rho^2 z_i/(b_i^2+4 z_i^2)^1.5]^-1`,
//!   equal to the closed form at equal heights; `z_i` clamped to `>= rho/2`,
//!   ratio capped at 1.6.
//! * Ceiling, rotor plane a gap `z >= 0` below it (Sanchez-Cuevas et al., ICUAS
//!   2017): `T / T_oce = 1 / (1 - (rho / (z + k2))^2 / k1)`.
//!
//! Far from a surface the ratios are 1 to within [`NEGLIGIBLE`]; beyond that
//! height they are not evaluated at all, which keeps free flight cheap.

use crate::airframe::Airframe;
use crate::signals::{MAX_ROTORS, RotorVector};

/// Ratio deviation from 1 below which an effect is not evaluated.
pub const NEGLIGIBLE: f64 = 1e-4;
/// Largest ground-effect thrust ratio applied.
pub const GROUND_RATIO_CAP: f64 = 1.6;

/// Cheeseman-Bennett single-rotor ground-effect ratio at rotor height `z` [m].
#[must_use]
pub fn cheeseman_bennett(radius_m: f64, z_m: f64) -> f64 {
    1.0 / (1.0 - (radius_m / (4.0 * z_m)).powi(2))
}

/// Closed-form multirotor ground-effect ratio (quadrotor, all rotors at height `z`):
/// `d` adjacent-rotor distance, `b` rotor-to-centre distance [m], `k_b` body coefficient.
#[must_use]
pub fn multirotor_ground_effect(radius_m: f64, z_m: f64, d_m: f64, b_m: f64, k_b: f64) -> f64 {
    let r2 = radius_m * radius_m;
    let z = z_m;
    let den = 1.0
        - (radius_m / (4.0 * z)).powi(2)
        - r2 * z / (d_m * d_m + 4.0 * z * z).powf(1.5)
        - 0.5 * r2 * z / (2.0 * d_m * d_m + 4.0 * z * z).powf(1.5)
        - 2.0 * r2 * z / (b_m * b_m + 4.0 * z * z).powf(1.5) * k_b;
    1.0 / den
}

/// Ceiling-effect ratio for a rotor plane `gap_m >= 0` below the ceiling.
#[must_use]
pub fn ceiling_ratio(radius_m: f64, k1: f64, k2_m: f64, gap_m: f64) -> f64 {
    1.0 / (1.0 - (radius_m / (gap_m.max(0.0) + k2_m)).powi(2) / k1)
}

/// Per-rotor ground and ceiling effect of one airframe, with its geometry precomputed.
#[derive(Clone, Debug)]
pub struct AeroEffects {
    n: usize,
    radius_m: f64,
    k_b: f64,
    k1: f64,
    k2_m: f64,
    /// Squared hub distances `d_ij^2` [m^2].
    d2: [[f64; MAX_ROTORS]; MAX_ROTORS],
    /// Squared arm lengths `b_i^2` [m^2].
    b2: [f64; MAX_ROTORS],
    /// Above this rotor height the ground ratio is within [`NEGLIGIBLE`] of 1.
    ground_cutoff_m: f64,
    /// Beyond this gap the ceiling ratio is within [`NEGLIGIBLE`] of 1.
    ceiling_cutoff_m: f64,
}

impl AeroEffects {
    /// Precompute for an airframe.
    #[must_use]
    pub fn new(a: &Airframe) -> Self {
        let n = a.rotor_count();
        let mut d2 = [[0.0; MAX_ROTORS]; MAX_ROTORS];
        let mut b2 = [0.0; MAX_ROTORS];
        for (i, ri) in a.rotors.iter().enumerate() {
            b2[i] = ri.arm_m.powi(2);
            for (j, rj) in a.rotors.iter().enumerate() {
                d2[i][j] = (ri.position_frd() - rj.position_frd()).norm_squared();
            }
        }
        let mut s = Self {
            n,
            radius_m: a.rotor.radius_m,
            k_b: a.ground_effect.body_coefficient,
            k1: a.ceiling_effect.k1,
            k2_m: a.ceiling_effect.k2_m,
            d2,
            b2,
            ground_cutoff_m: f64::INFINITY,
            ceiling_cutoff_m: f64::INFINITY,
        };
        // Both ratios fall monotonically with distance: bisect for the cutoff.
        let level = |s: &Self, z: f64| {
            s.ground_ratios(&[z; MAX_ROTORS])
                .iter()
                .take(n)
                .fold(1.0f64, |m, r| m.max(*r))
        };
        s.ground_cutoff_m = bisect_cutoff(|z| level(&s, z) - 1.0, s.radius_m);
        s.ceiling_cutoff_m = bisect_cutoff(|z| ceiling_ratio(s.radius_m, s.k1, s.k2_m, z) - 1.0, s.radius_m);
        s
    }

    /// Height above which the ground effect is skipped [m].
    #[must_use]
    pub fn ground_cutoff_m(&self) -> f64 {
        self.ground_cutoff_m
    }

    /// Distance beyond which the ceiling effect is skipped [m].
    #[must_use]
    pub fn ceiling_cutoff_m(&self) -> f64 {
        self.ceiling_cutoff_m
    }

    /// Per-rotor ground-effect ratios for rotor heights `z_i` [m] above the surface below each.
    ///
    /// Evaluated with few square roots and divisions (they dominate the
    /// cost): a rotor's own image term `rho^2/4 (2z)/(4z^2)^1.5 = rho^2 / (16 z^2)`
    /// needs no root; it and the body term share one denominator,
    /// `rho^2/(16 z^2) + 2 K_b rho^2 z / y = N / D` with `y = (b^2 + 4 z^2)^1.5`,
    /// `N = rho^2 (y + 32 K_b z^3)`, `D = 16 z^2 y`; and the ratio
    /// `1 / (1 - P - N/D) = D / (D (1 - P) - N)` (`P` the other rotors' terms)
    /// takes a single division.
    #[must_use]
    #[inline(always)]
    pub fn ground_ratios(&self, heights_m: &[f64; MAX_ROTORS]) -> RotorVector {
        let mut out = RotorVector::from_element(1.0);
        let rho2 = self.radius_m * self.radius_m;
        let zmin = 0.5 * self.radius_m;
        // n <= MAX_ROTORS, said to the compiler: no bounds checks in the loops
        let n = self.n.min(MAX_ROTORS);
        let mut z = [0.0; MAX_ROTORS];
        for i in 0..n {
            z[i] = heights_m[i].max(zmin);
        }
        // P_i: the images of the other rotors
        let mut others = [0.0; MAX_ROTORS];
        for i in 0..n {
            for j in i + 1..n {
                let s = z[i] + z[j];
                let term = 0.25 * rho2 * s / pow_1_5(self.d2[i][j] + s * s);
                others[i] += term;
                others[j] += term;
            }
        }
        for i in 0..n {
            let z2 = z[i] * z[i];
            let y = pow_1_5(self.b2[i] + 4.0 * z2);
            let num = rho2 * (y + 32.0 * self.k_b * z2 * z[i]);
            let den = 16.0 * z2 * y;
            // ratio = den / rest, capped: rest > den / cap <=> ratio < cap (den > 0)
            let rest = den * (1.0 - others[i]) - num;
            out[i] = if rest > den * (1.0 / GROUND_RATIO_CAP) {
                den / rest
            } else {
                GROUND_RATIO_CAP
            };
        }
        out
    }

    /// Per-rotor ground ratios, or `None` when every rotor is above the cutoff.
    #[must_use]
    #[inline(always)]
    pub fn ground_ratios_if_near(&self, heights_m: &[f64; MAX_ROTORS]) -> Option<RotorVector> {
        let lowest = heights_m.iter().take(self.n).fold(f64::INFINITY, |m, z| m.min(*z));
        (lowest < self.ground_cutoff_m).then(|| self.ground_ratios(heights_m))
    }

    /// Per-rotor ceiling ratios for gaps [m] below the ceiling, or `None` when all are beyond the cutoff.
    #[must_use]
    pub fn ceiling_ratios_if_near(&self, gaps_m: &[f64; MAX_ROTORS]) -> Option<RotorVector> {
        let nearest = gaps_m.iter().take(self.n).fold(f64::INFINITY, |m, z| m.min(*z));
        (nearest < self.ceiling_cutoff_m).then(|| {
            let mut out = RotorVector::from_element(1.0);
            for i in 0..self.n {
                out[i] = ceiling_ratio(self.radius_m, self.k1, self.k2_m, gaps_m[i]);
            }
            out
        })
    }
}

/// `x^(3/2)` as `x sqrt(x)` (several times faster than `powf`).
fn pow_1_5(x: f64) -> f64 {
    x * x.sqrt()
}

/// Smallest distance beyond which `excess(z) < NEGLIGIBLE`, for a decreasing `excess`.
fn bisect_cutoff(excess: impl Fn(f64) -> f64, scale: f64) -> f64 {
    let mut hi = scale;
    while excess(hi) >= NEGLIGIBLE {
        hi *= 2.0;
        if hi > 1e6 {
            return f64::INFINITY;
        }
    }
    let mut lo = 0.0;
    for _ in 0..60 {
        let m = 0.5 * (lo + hi);
        if excess(m) >= NEGLIGIBLE { lo = m } else { hi = m }
    }
    hi
}
