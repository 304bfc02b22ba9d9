//! The discrete r-th order integrator chain shared by every estimator channel
//! (`docs/model.md` section 7, "Discrete implementation").
//!
//! Continuous form, per channel, with momentum `q`, known part `d` of `q'`
//! and the true wrench `w` (`q' = d + w`):
//!
//! ```text
//! gamma_1 = K_1 (q(t) - q(0) - int_0^t (d + gamma_r) ds)
//! gamma_i = K_i int_0^t (gamma_{i-1} - gamma_r) ds,      i = 2..r
//! ```
//!
//! The chain here is fed, at each sample k >= 1, the *unexplained momentum
//! increment* `u_k = (q_k - q_{k-1}) - (D_k - D_{k-1})`, where `D_k - D_{k-1}`
//! is the integral of `d` over `[t_{k-1}, t_k)` by the chosen rule. The
//! growing integrals `q - q_0 - D` and `S` (integral of `gamma_r`) are never
//! formed: their bounded difference, the residual `e_k = q_k - q_0 - D_k - S_k`,
//! is `gamma_{1,k} / K_1` at every sample, so `gamma_1..gamma_r` are the whole
//! state.
//!
//! * Forward Euler (`D_k = D_{k-1} + h d_{k-1}`, `S_k = S_{k-1} + h gamma_{r,k-1}`):
//!   `gamma_{1,k} = K_1 e_k = gamma_{1,k-1} + K_1 u_k - h K_1 gamma_{r,k-1}`,
//!   `gamma_{i,k} = gamma_{i,k-1} + h K_i (gamma_{i-1,k-1} - gamma_{r,k-1})`.
//! * Trapezoidal (Tustin): solve the constant r x r system `A Gamma_k = b_k`
//!   with rows `gamma_1 + (h/2) K_1 gamma_r = K_1 (y_k - S_{k-1} - (h/2) gamma_{r,k-1})`
//!   (`y_k - S_{k-1} = e_{k-1} + u_k`)
//!   and `gamma_i - (h/2) K_i (gamma_{i-1} - gamma_r) = gamma_{i,k-1} + (h/2) K_i (gamma_{i-1,k-1} - gamma_{r,k-1})`;
//!   `S_k = S_{k-1} + (h/2)(gamma_{r,k-1} + gamma_{r,k})` is implied.
//!   `A^-1` is computed once per configuration (one matrix serves every
//!   channel). While every `(h/2) K_i <= 1` (any sensible setting: `K_i h <= 2`)
//!   the update uses only its last row `w`, `gamma_r = w . b_k`, and then the
//!   rows of `A` themselves (lower bidiagonal once `gamma_r` is known) for
//!   `gamma_1..gamma_{r-1}`: the same solution as `A^-1 b` in O(r) instead of
//!   O(r^2) operations per channel. Beyond that the full product is used,
//!   because the substitution would amplify rounding.
//!
//!   The O(r) update never forms `b_k`: with `a_i = (h/2) K_i`, `b_k` is
//!   linear in the old state and `u_k`, so
//!   `gamma_{r,k} = w_1 K_1 u_k + sum_j c_j gamma_{j,k-1}` with
//!   `c_j = w_j + w_{j+1} a_{j+1}` (`j < r`) and `c_r = w_r - sum_i w_i a_i`
//!   (`gamma_{r,k-1}` is both a state and the `- a_i gamma_{r,k-1}` of every row),
//!   and substituting `b_k` into the rows of `A` gives, with
//!   `s = gamma_{r,k-1} + gamma_{r,k}`,
//!   `gamma_{1,k} = gamma_{1,k-1} + K_1 u_k - a_1 s` and
//!   `gamma_{i,k} = gamma_{i,k-1} + a_i (gamma_{i-1,k-1} + gamma_{i-1,k} - s)`.
//!   The state part `sum_j c_j gamma_{j,k}` is formed at the end of each
//!   update, while the stages are at hand, ready for the next one, which then
//!   needs only `u_k` to get `gamma_{r,k}`.

// Index loops over the fixed-size per-channel arrays read like the equations
// and let the compiler unroll and vectorize across channels.
#![allow(clippy::needless_range_loop)]

use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

use super::EstimatorError;
use super::gains::{MAX_ORDER, check_order};

/// How the continuous chain is discretized at sample time `h`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Discretization {
    /// Trapezoidal (Tustin) rule: unconditionally stable, recommended.
    #[default]
    Trapezoidal,
    /// Forward (explicit) Euler: stable only while every pole `p` of `G`
    /// keeps `|1 + h p| < 1` (Butterworth `omega_c h < 2 sin(pi/2r)`,
    /// binomial `omega_c h < 2`).
    ForwardEuler,
}

/// An r-th order integrator chain for `C` independent channels sharing one
/// set of gains (`1 <= r <= MAX_ORDER`). Fixed-size storage: updating
/// allocates nothing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChainFilter<const C: usize> {
    order: usize,
    discretization: Discretization,
    h: f64,
    /// `K_1..K_r` [1/s].
    gains: [f64; MAX_ORDER],
    /// Trapezoidal: `(h/2) K_i`; forward Euler: `h K_i`.
    step_gains: [f64; MAX_ORDER],
    /// Trapezoidal: `c_1..c_r` of `gamma_{r,k} = w_1 K_1 u_k + sum_j c_j gamma_{j,k-1}`
    /// (module doc; `w` is the last row of `A^-1`).
    output_weights: [f64; MAX_ORDER],
    /// Trapezoidal: `w_1 K_1`, the weight of `u_k` in `gamma_{r,k}`.
    input_weight: f64,
    /// `A^-1` (trapezoidal only), used when `structured` is false.
    inverse: [[f64; MAX_ORDER]; MAX_ORDER],
    /// Trapezoidal: every `(h/2) K_i <= 1`, so the O(r) solve is as accurate as
    /// `A^-1 b`; otherwise it could amplify rounding by up to `prod (h/2) K_i`
    /// and the full product is used.
    structured: bool,
    /// `gamma_1..gamma_r` per channel (row i-1 holds `gamma_i`) [wrench units].
    stages: [[f64; C]; MAX_ORDER],
    /// Structured trapezoidal: `sum_j c_j gamma_j` of the current `stages` per channel.
    state_part: [f64; C],
}

impl<const C: usize> ChainFilter<C> {
    /// A chain with gains `K_1..K_r` (`r = gains.len()`) [1/s], sample time `h` [s], state zero.
    ///
    /// # Errors
    /// Order outside `1..=MAX_ORDER`, a gain not finite and > 0, `h` not finite
    /// and > 0, or a trapezoidal matrix that cannot be inverted (not reachable
    /// for positive gains).
    pub fn new(gains: &[f64], discretization: Discretization, h: f64) -> Result<Self, EstimatorError> {
        let r = gains.len();
        check_order(r)?;
        if !(h.is_finite() && h > 0.0) {
            return Err(EstimatorError::SampleTime(h));
        }
        if let Some((i, &value)) = gains.iter().enumerate().find(|(_, k)| !(k.is_finite() && **k > 0.0)) {
            return Err(EstimatorError::Gain { index: i + 1, value });
        }
        let mut k = [0.0; MAX_ORDER];
        k[..r].copy_from_slice(gains);
        let mut step_gains = [0.0; MAX_ORDER];
        let mut output_weights = [0.0; MAX_ORDER];
        let mut input_weight = 0.0;
        let mut inverse = [[0.0; MAX_ORDER]; MAX_ORDER];
        let mut structured = false;
        match discretization {
            Discretization::ForwardEuler => {
                for i in 0..r {
                    step_gains[i] = h * k[i];
                }
            }
            Discretization::Trapezoidal => {
                for i in 0..r {
                    step_gains[i] = 0.5 * h * k[i];
                }
                let inv = trapezoidal_matrix(&k[..r], h)
                    .try_inverse()
                    .ok_or(EstimatorError::SingularSystem)?;
                for i in 0..r {
                    for j in 0..r {
                        inverse[i][j] = inv[(i, j)];
                    }
                }
                let w = inverse[r - 1];
                // c_j = w_j + w_{j+1} a_{j+1}; c_r = w_r - sum_i w_i a_i
                for j in 0..r - 1 {
                    output_weights[j] = w[j] + w[j + 1] * step_gains[j + 1];
                }
                output_weights[r - 1] = w[r - 1] - (0..r).map(|i| w[i] * step_gains[i]).sum::<f64>();
                input_weight = w[0] * k[0];
                structured = step_gains[..r].iter().all(|a| *a <= 1.0);
            }
        }
        Ok(Self {
            order: r,
            discretization,
            h,
            gains: k,
            step_gains,
            output_weights,
            input_weight,
            inverse,
            structured,
            stages: [[0.0; C]; MAX_ORDER],
            state_part: [0.0; C],
        })
    }

    /// Change the sample time to `h` [s] for the following samples, keeping
    /// the state `gamma_1..gamma_r`: the coefficients are those
    /// [`Self::new`] computes for `h`, so a chain advanced with the step of
    /// each sample is the chosen rule applied interval by interval (a log
    /// with a varying step). The same `h` changes nothing.
    ///
    /// # Errors
    /// `h` not finite and > 0 (the chain is then unchanged).
    pub fn set_sample_time(&mut self, h: f64) -> Result<(), EstimatorError> {
        if h.to_bits() == self.h.to_bits() {
            return Ok(());
        }
        let stages = self.stages;
        *self = Self::new(self.gains(), self.discretization, h)?;
        self.stages = stages;
        self.state_part = Self::weighted_stages(&self.stages[..self.order], &self.output_weights);
        Ok(())
    }

    /// Order r.
    #[must_use]
    pub fn order(&self) -> usize {
        self.order
    }

    /// Sample time `h` [s].
    #[must_use]
    pub fn sample_time_s(&self) -> f64 {
        self.h
    }

    /// The discretization rule.
    #[must_use]
    pub fn discretization(&self) -> Discretization {
        self.discretization
    }

    /// Gains `K_1..K_r` [1/s].
    #[must_use]
    pub fn gains(&self) -> &[f64] {
        &self.gains[..self.order]
    }

    /// Zero the state (estimate 0).
    pub fn reset(&mut self) {
        self.stages = [[0.0; C]; MAX_ORDER];
        self.state_part = [0.0; C];
    }

    /// The estimate `gamma_r` per channel.
    #[must_use]
    pub fn output(&self) -> [f64; C] {
        self.stages[self.order - 1]
    }

    /// `gamma_1..gamma_r` (element i-1 is `gamma_i`, per channel).
    #[must_use]
    pub fn stages(&self) -> &[[f64; C]] {
        &self.stages[..self.order]
    }

    /// Advance one sample with the unexplained momentum increment
    /// `u_k = (q_k - q_{k-1}) - integral of d over [t_{k-1}, t_k)` per channel
    /// and return the new estimate `gamma_{r,k}`. For a constant true wrench
    /// `w` acting from `t_0`, `u_k = w h`.
    ///
    /// The residual is carried by `gamma_1 = K_1 e`: the doc's first row
    /// `K_1 (y_k - S_{k-1} - ...)` is `gamma_{1,k-1} + K_1 u_k - ...`.
    // Inlined into the estimator's update: increments and estimate stay in registers.
    #[inline(always)]
    pub fn advance(&mut self, increment: &[f64; C]) -> [f64; C] {
        let r = self.order;
        let gr_old = self.stages[r - 1];
        let k1 = self.gains[0];
        let a = &self.step_gains[..r];
        let stages = &mut self.stages[..r];
        match self.discretization {
            Discretization::ForwardEuler => {
                // gamma_{i,k} = gamma_{i,k-1} + h K_i (gamma_{i-1,k-1} - gamma_{r,k-1}), descending
                // so that gamma_{i-1} is still the old value
                for i in (1..r).rev() {
                    let (lo, hi) = stages.split_at_mut(i);
                    let (prev, cur, ai) = (&lo[i - 1], &mut hi[0], a[i]);
                    for c in 0..C {
                        cur[c] += ai * (prev[c] - gr_old[c]);
                    }
                }
                // gamma_{1,k} = K_1 e_k, e_k = e_{k-1} + u_k - h gamma_{r,k-1}
                for c in 0..C {
                    stages[0][c] += k1 * increment[c] - a[0] * gr_old[c];
                }
            }
            Discretization::Trapezoidal if self.structured => {
                let mut gr = self.state_part;
                for c in 0..C {
                    gr[c] += self.input_weight * increment[c];
                }
                if r > 1 {
                    // s = gamma_{r,k-1} + gamma_{r,k}; carry gamma_{i-1,k-1} + gamma_{i-1,k}
                    let mut s = [0.0; C];
                    let mut prev_sum = [0.0; C];
                    for c in 0..C {
                        s[c] = gr_old[c] + gr[c];
                        let old = stages[0][c];
                        stages[0][c] = old + k1 * increment[c] - a[0] * s[c];
                        prev_sum[c] = old + stages[0][c];
                    }
                    for i in 1..r - 1 {
                        let (cur, ai) = (&mut stages[i], a[i]);
                        for c in 0..C {
                            let old = cur[c];
                            cur[c] = old + ai * (prev_sum[c] - s[c]);
                            prev_sum[c] = old + cur[c];
                        }
                    }
                }
                stages[r - 1] = gr;
                self.state_part = Self::weighted_stages(stages, &self.output_weights);
            }
            Discretization::Trapezoidal => {
                // right-hand side b_k in place (descending, gamma_{i-1} still old), then A^-1 b_k
                for i in (1..r).rev() {
                    let prev = stages[i - 1];
                    let (cur, ai) = (&mut stages[i], a[i]);
                    for c in 0..C {
                        cur[c] += ai * (prev[c] - gr_old[c]);
                    }
                }
                // b_1 = K_1 (e_{k-1} + u_k - (h/2) gamma_{r,k-1})
                for c in 0..C {
                    stages[0][c] += k1 * increment[c] - a[0] * gr_old[c];
                }
                Self::solve_full(stages, &self.inverse);
            }
        }
        self.stages[r - 1]
    }

    /// `sum_j c_j gamma_j` per channel: the state part of the next `gamma_r`
    /// (structured trapezoidal update, module doc).
    fn weighted_stages(stages: &[[f64; C]], weights: &[f64; MAX_ORDER]) -> [f64; C] {
        let mut sum = [0.0; C];
        for (stage, cj) in stages.iter().zip(weights) {
            for c in 0..C {
                sum[c] += cj * stage[c];
            }
        }
        sum
    }

    /// `Gamma_k = A^-1 b_k` with `stages` holding `b_k`.
    fn solve_full(stages: &mut [[f64; C]], inverse: &[[f64; MAX_ORDER]; MAX_ORDER]) {
        let r = stages.len();
        let mut b = [[0.0; C]; MAX_ORDER];
        b[..r].copy_from_slice(stages);
        for (i, out) in stages.iter_mut().enumerate() {
            let mut x = [0.0; C];
            for j in 0..r {
                let w = inverse[i][j];
                for c in 0..C {
                    x[c] += w * b[j][c];
                }
            }
            *out = x;
        }
    }

    /// Set the chain state so that every stage equals `estimate` per channel
    /// (the steady state of a constant wrench `estimate`).
    pub fn set_steady(&mut self, estimate: &[f64; C]) {
        for stage in &mut self.stages[..self.order] {
            *stage = *estimate;
        }
        self.state_part = Self::weighted_stages(self.stages(), &self.output_weights);
    }
}

/// The constant trapezoidal matrix `A` (r x r) of `A Gamma_k = b_k`:
/// row 1 `[1, 0, .., 0, (h/2) K_1]`, row i >= 2: `-(h/2) K_i` at column i-1,
/// `1` at column i, `+(h/2) K_i` at column r (for r = 1: `1 + (h/2) K_1`).
#[must_use]
pub fn trapezoidal_matrix(gains: &[f64], h: f64) -> DMatrix<f64> {
    let r = gains.len();
    let mut a = DMatrix::identity(r, r);
    for (i, k) in gains.iter().enumerate() {
        let hk = 0.5 * h * k;
        a[(i, r - 1)] += hk;
        if i > 0 {
            a[(i, i - 1)] -= hk;
        }
    }
    a
}

/// Step response of one channel of the chain for a unit wrench acting from
/// `t = 0`: `n_samples` values of `gamma_r` at `t_k = k h`, k = 0..n-1 (the
/// first, at `t_0`, is the initial 0).
///
/// # Errors
/// As [`ChainFilter::new`].
pub fn step_response(
    gains: &[f64],
    discretization: Discretization,
    h: f64,
    n_samples: usize,
) -> Result<Vec<f64>, EstimatorError> {
    let mut chain = ChainFilter::<1>::new(gains, discretization, h)?;
    let mut out = Vec::with_capacity(n_samples);
    if n_samples > 0 {
        out.push(0.0);
    }
    for _ in 1..n_samples {
        out.push(chain.advance(&[h])[0]);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimation::gains::{Polynomial, gains_for};

    /// The O(r) solve equals the full `A^-1 b`, including badly scaled cases.
    #[test]
    fn structured_solve_equals_full_inverse() {
        for (poly, r, wc, h) in [
            (Polynomial::Butterworth, 1, 10.0, 1e-3),
            (Polynomial::Butterworth, 5, 10.0, 1e-3),
            (Polynomial::Binomial, 7, 30.0, 1e-3),
            (Polynomial::Butterworth, 20, 10.0, 1e-3),
            (Polynomial::Butterworth, 20, 300.0, 1e-2), // (h/2) K_i up to ~19
            (Polynomial::Binomial, 20, 1000.0, 1e-2),
        ] {
            let k = gains_for(&poly, r, wc).unwrap();
            let ainv = trapezoidal_matrix(&k, h).try_inverse().unwrap();
            let mut chain = ChainFilter::<2>::new(&k, Discretization::Trapezoidal, h).unwrap();
            // the O(r) solve is used exactly when every (h/2) K_i <= 1
            assert_eq!(chain.structured, k.iter().all(|ki| 0.5 * h * ki <= 1.0));
            // some state
            for n in 0..50 {
                let x = n as f64;
                chain.advance(&[(0.3 * x).sin() * h, (0.11 * x).cos() * h]);
            }
            let before = chain;
            let u = [0.7 * h, -0.2 * h];
            chain.advance(&u);
            for c in 0..2 {
                // build b from the old state as the doc writes it
                let g = |i: usize| before.stages[i][c];
                let grp = g(r - 1);
                let mut b = nalgebra::DVector::zeros(r);
                // K_1 (e_{k-1} + u_k - (h/2) gamma_{r,k-1}) with e_{k-1} = gamma_{1,k-1} / K_1
                b[0] = k[0] * (g(0) / k[0] + u[c] - 0.5 * h * grp);
                for i in 1..r {
                    b[i] = g(i) + 0.5 * h * k[i] * (g(i - 1) - grp);
                }
                let full = &ainv * b;
                let scale = full.amax().max(1e-12);
                for i in 0..r {
                    let err = (chain.stages[i][c] - full[i]).abs() / scale;
                    assert!(err < 1e-13, "{poly:?} r={r} wc={wc} h={h} stage {i}: {err}");
                }
            }
        }
    }

    /// The chain equals the doc's formulas written out literally, with the
    /// growing integrals `D`, `S` and `q_0`.
    #[test]
    fn matches_doc_formulas_literally() {
        let h = 1e-3;
        let q = |k: usize| {
            let t = k as f64 * h;
            3.0 + 2.0 * (1.7 * t).sin() + 0.4 * t
        };
        let d = |k: usize| {
            let t = k as f64 * h;
            1.5 * (0.9 * t).cos() - 0.2
        };
        for (poly, r) in [
            (Polynomial::Butterworth, 1),
            (Polynomial::Butterworth, 4),
            (Polynomial::Binomial, 7),
        ] {
            let k = gains_for(&poly, r, 10.0).unwrap();
            for disc in [Discretization::ForwardEuler, Discretization::Trapezoidal] {
                let mut chain = ChainFilter::<1>::new(&k, disc, h).unwrap();
                let ainv = trapezoidal_matrix(&k, h).try_inverse().unwrap();
                let (mut big_d, mut big_s) = (0.0, 0.0);
                let mut g = vec![0.0; r];
                for n in 1..3000 {
                    let d_int = match disc {
                        Discretization::ForwardEuler => h * d(n - 1),
                        Discretization::Trapezoidal => 0.5 * h * (d(n - 1) + d(n)),
                    };
                    big_d += d_int;
                    let gr_old = g[r - 1];
                    match disc {
                        Discretization::ForwardEuler => {
                            big_s += h * gr_old;
                            let old = g.clone();
                            g[0] = k[0] * (q(n) - q(0) - big_d - big_s);
                            for i in 1..r {
                                g[i] = old[i] + h * k[i] * (old[i - 1] - gr_old);
                            }
                        }
                        Discretization::Trapezoidal => {
                            let y = q(n) - q(0) - big_d;
                            let mut b = nalgebra::DVector::zeros(r);
                            b[0] = k[0] * (y - big_s - 0.5 * h * gr_old);
                            for i in 1..r {
                                b[i] = g[i] + 0.5 * h * k[i] * (g[i - 1] - gr_old);
                            }
                            let x = &ainv * b;
                            g = x.iter().copied().collect();
                            big_s += 0.5 * h * (gr_old + g[r - 1]);
                        }
                    }
                    let out = chain.advance(&[q(n) - q(n - 1) - d_int])[0];
                    assert!(
                        (out - g[r - 1]).abs() < 1e-9,
                        "{poly:?} r={r} {disc:?} n={n}: {out} vs {}",
                        g[r - 1]
                    );
                }
            }
        }
    }

    #[test]
    fn refuses_bad_gains_and_sample_time() {
        assert!(matches!(
            ChainFilter::<1>::new(&[1.0, -1.0], Discretization::Trapezoidal, 1e-3),
            Err(EstimatorError::Gain { index: 2, .. })
        ));
        assert!(ChainFilter::<1>::new(&[], Discretization::Trapezoidal, 1e-3).is_err());
        assert!(ChainFilter::<1>::new(&[1.0; 21], Discretization::Trapezoidal, 1e-3).is_err());
        assert!(ChainFilter::<1>::new(&[1.0], Discretization::Trapezoidal, 0.0).is_err());
        assert!(ChainFilter::<1>::new(&[1.0], Discretization::ForwardEuler, f64::NAN).is_err());
    }

    /// A constant wrench is reached exactly in steady state, and
    /// `set_steady` is a fixed point of the update.
    #[test]
    fn steady_state_is_exact() {
        let k = gains_for(&Polynomial::Butterworth, 4, 10.0).unwrap();
        for d in [Discretization::Trapezoidal, Discretization::ForwardEuler] {
            let h = 1e-3;
            let mut chain = ChainFilter::<3>::new(&k, d, h).unwrap();
            chain.set_steady(&[0.5, -2.4525, 0.2]);
            let y = chain.advance(&[0.5 * h, -2.4525 * h, 0.2 * h]);
            for (a, b) in y.iter().zip([0.5, -2.4525, 0.2]) {
                assert!((a - b).abs() < 1e-12, "{d:?}");
            }
        }
    }

    /// A chain advanced with a varying step (each sample's increment `w h_k`)
    /// converges to the constant wrench `w` as with a constant step; the same
    /// step set again changes nothing, bit for bit.
    #[test]
    fn a_varying_step_converges_to_the_wrench() {
        let k = gains_for(&Polynomial::Butterworth, 5, 10.0).unwrap();
        for d in [Discretization::Trapezoidal, Discretization::ForwardEuler] {
            let mut chain = ChainFilter::<1>::new(&k, d, 1e-3).unwrap();
            let mut same = chain;
            for i in 0..6000 {
                // steps of 0.5, 1.0 and 1.5 ms in turn
                let h = 1e-3 * (0.5 + 0.5 * f64::from(i % 3));
                chain.set_sample_time(h).unwrap();
                chain.advance(&[0.7 * h]);
                same.set_sample_time(1e-3).unwrap();
                same.advance(&[0.7e-3]);
            }
            assert!((chain.output()[0] - 0.7).abs() < 1e-6, "{d:?}: {:?}", chain.output());
            let mut constant = ChainFilter::<1>::new(&k, d, 1e-3).unwrap();
            for _ in 0..6000 {
                constant.advance(&[0.7e-3]);
            }
            assert_eq!(constant.output()[0].to_bits(), same.output()[0].to_bits(), "{d:?}");
            assert!(chain.set_sample_time(0.0).is_err());
        }
    }
}
