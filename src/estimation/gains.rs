//! Filter polynomials and chain gains of the r-th order momentum-based
//! estimator (`docs/model.md` section 7, "Gains from coefficients").
//!
//! Each of the estimator's channels has the transfer function from the true
//! wrench `w` to its estimate `gamma_r`
//!
//! ```text
//! G(s) = c_0 / (s^r + c_{r-1} s^{r-1} + ... + c_1 s + c_0),   G(0) = 1,
//! ```
//!
//! realised by a chain of r integrators with gains `K_1..K_r` such that
//! `prod_{i=j+1..r} K_i = c_j` (j = 0..r-1), i.e. `K_i = c_{i-1} / c_i` with
//! `c_r := 1` (Ruggiero, Cacace, Sadeghian, Lippiello, "Passivity-based control
//! of VToL UAVs with a momentum-based estimator of external wrench and
//! unmodeled dynamics", Robotics and Autonomous Systems 72, 2015; the origin
//! report, exercise 4).
//!
//! Coefficient lists are always `c_0..c_{r-1}` (ascending powers, the leading
//! `c_r = 1` left out); units `c_j` [s^-(r-j)], gains `K_i` [1/s].

use serde::{Deserialize, Serialize};

use super::EstimatorError;

/// Highest supported estimator order r.
pub const MAX_ORDER: usize = 20;

/// The denominator polynomial of `G(s)`.
#[derive(Clone, Debug, PartialEq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Polynomial {
    /// Butterworth of cutoff `omega_c`: poles equally spaced on the left half
    /// of the circle of radius `omega_c` (maximally flat; overshoots for r >= 2).
    #[default]
    Butterworth,
    /// Binomial `(s + omega_c)^r`: all poles at `-omega_c` (no overshoot,
    /// delay `r / omega_c`).
    Binomial,
    /// The user's coefficients `c_0..c_{r-1}` of the monic
    /// `s^r + c_{r-1} s^{r-1} + ... + c_0`, used as given (the cutoff is not
    /// applied). Each must be finite and > 0 and the polynomial Hurwitz.
    Custom(Vec<f64>),
}

/// Reject orders outside `1..=MAX_ORDER`.
///
/// # Errors
/// [`EstimatorError::Order`].
pub fn check_order(order: usize) -> Result<(), EstimatorError> {
    if (1..=MAX_ORDER).contains(&order) {
        Ok(())
    } else {
        Err(EstimatorError::Order(order))
    }
}

/// Reject a cutoff that is not finite and > 0 [rad/s].
///
/// # Errors
/// [`EstimatorError::Cutoff`].
pub fn check_cutoff(cutoff_rad_s: f64) -> Result<(), EstimatorError> {
    if cutoff_rad_s.is_finite() && cutoff_rad_s > 0.0 {
        Ok(())
    } else {
        Err(EstimatorError::Cutoff(cutoff_rad_s))
    }
}

/// Multiply two polynomials given by ascending coefficients.
fn poly_mul(a: &[f64], b: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; a.len() + b.len() - 1];
    for (i, x) in a.iter().enumerate() {
        for (j, y) in b.iter().enumerate() {
            out[i + j] += x * y;
        }
    }
    out
}

/// Normalized Butterworth coefficients `a_0..a_{r-1}` (cutoff 1 rad/s) of
/// `s^r + a_{r-1} s^{r-1} + ... + a_0`, built from the poles
/// `p_k = exp(j pi (2k + r - 1) / (2r))`, k = 1..r: each conjugate pair gives
/// the real factor `s^2 - 2 cos(pi (2k + r - 1) / (2r)) s + 1`, an odd order
/// adds the pole `-1`.
///
/// # Errors
/// [`EstimatorError::Order`] unless `1 <= order <= MAX_ORDER`.
pub fn butterworth_normalized(order: usize) -> Result<Vec<f64>, EstimatorError> {
    check_order(order)?;
    let r = order as f64;
    let mut p = vec![1.0];
    for k in 1..=order / 2 {
        let angle = std::f64::consts::PI * (2.0 * k as f64 + r - 1.0) / (2.0 * r);
        p = poly_mul(&p, &[1.0, -2.0 * angle.cos(), 1.0]);
    }
    if order % 2 == 1 {
        p = poly_mul(&p, &[1.0, 1.0]);
    }
    p.truncate(order); // drop the leading 1
    Ok(p)
}

/// Normalized binomial coefficients `a_j = binom(r, j)`, j = 0..r-1, of `(s + 1)^r`.
///
/// # Errors
/// [`EstimatorError::Order`] unless `1 <= order <= MAX_ORDER`.
pub fn binomial_normalized(order: usize) -> Result<Vec<f64>, EstimatorError> {
    check_order(order)?;
    let mut out = Vec::with_capacity(order);
    let mut c = 1.0; // binom(r, 0)
    for j in 0..order {
        out.push(c);
        c = c * (order - j) as f64 / (j + 1) as f64;
    }
    Ok(out)
}

/// Coefficients `c_0..c_{r-1}` of the polynomial for `order` and `cutoff_rad_s`:
/// `c_j = a_j omega_c^(r-j)` for Butterworth and binomial, the custom list as
/// given (after [`validate_custom`]).
///
/// # Errors
/// Invalid order or cutoff; a custom list of the wrong length, with a
/// coefficient not finite and > 0, or not Hurwitz.
pub fn polynomial_coefficients(
    polynomial: &Polynomial,
    order: usize,
    cutoff_rad_s: f64,
) -> Result<Vec<f64>, EstimatorError> {
    check_order(order)?;
    let scale = |a: Vec<f64>| -> Vec<f64> {
        a.iter()
            .enumerate()
            .map(|(j, aj)| aj * cutoff_rad_s.powi((order - j) as i32))
            .collect()
    };
    match polynomial {
        Polynomial::Butterworth => {
            check_cutoff(cutoff_rad_s)?;
            Ok(scale(butterworth_normalized(order)?))
        }
        Polynomial::Binomial => {
            check_cutoff(cutoff_rad_s)?;
            Ok(scale(binomial_normalized(order)?))
        }
        Polynomial::Custom(c) => {
            validate_custom(c, order)?;
            Ok(c.clone())
        }
    }
}

/// Check a custom list `c_0..c_{r-1}`: length `order`, every `c_j` finite
/// and > 0, and `s^r + c_{r-1} s^{r-1} + ... + c_0` Hurwitz (Routh test).
///
/// # Errors
/// [`EstimatorError::Order`], [`EstimatorError::CustomLength`],
/// [`EstimatorError::Coefficient`] or [`EstimatorError::NotHurwitz`].
pub fn validate_custom(coefficients: &[f64], order: usize) -> Result<(), EstimatorError> {
    check_order(order)?;
    if coefficients.len() != order {
        return Err(EstimatorError::CustomLength {
            order,
            got: coefficients.len(),
        });
    }
    if let Some((index, &value)) = coefficients
        .iter()
        .enumerate()
        .find(|(_, c)| !(c.is_finite() && **c > 0.0))
    {
        return Err(EstimatorError::Coefficient { index, value });
    }
    let mut descending: Vec<f64> = coefficients.iter().rev().copied().collect();
    descending.insert(0, 1.0);
    match routh_first_failure(&descending) {
        None => Ok(()),
        Some(row) => Err(EstimatorError::NotHurwitz { row }),
    }
}

/// Routh test of the real polynomial `p[0] s^n + p[1] s^(n-1) + ... + p[n]`
/// (descending powers, `p[0] > 0` expected): `None` if every entry of the
/// first column of the Routh array is finite and > 0 (all roots in the open
/// left half plane), otherwise the index of the first row that is not (a zero
/// entry counts as a failure: roots on the imaginary axis are not accepted).
#[must_use]
pub fn routh_first_failure(p: &[f64]) -> Option<usize> {
    let n = p.len().checked_sub(1)?;
    let width = n / 2 + 1;
    let mut prev: Vec<f64> = (0..width).map(|j| p.get(2 * j).copied().unwrap_or(0.0)).collect();
    let mut cur: Vec<f64> = (0..width).map(|j| p.get(2 * j + 1).copied().unwrap_or(0.0)).collect();
    let ok = |x: f64| x.is_finite() && x > 0.0;
    if !ok(prev[0]) {
        return Some(0);
    }
    for row in 1..=n {
        if !ok(cur[0]) {
            return Some(row);
        }
        let next: Vec<f64> = (0..width)
            .map(|j| {
                let a = prev.get(j + 1).copied().unwrap_or(0.0);
                let b = cur.get(j + 1).copied().unwrap_or(0.0);
                (cur[0] * a - prev[0] * b) / cur[0]
            })
            .collect();
        prev = cur;
        cur = next;
    }
    None
}

/// `true` if `s^r + c_{r-1} s^{r-1} + ... + c_0` (ascending list `c`) is Hurwitz.
#[must_use]
pub fn is_hurwitz(coefficients: &[f64]) -> bool {
    let mut descending: Vec<f64> = coefficients.iter().rev().copied().collect();
    descending.insert(0, 1.0);
    routh_first_failure(&descending).is_none()
}

/// Chain gains `K_i = c_{i-1} / c_i`, i = 1..r, with `c_r := 1`, so that
/// `prod_{i=j+1..r} K_i = c_j` [1/s].
///
/// # Errors
/// [`EstimatorError::Order`] for an empty or too long list,
/// [`EstimatorError::Coefficient`] for a coefficient not finite and > 0.
pub fn chain_gains(coefficients: &[f64]) -> Result<Vec<f64>, EstimatorError> {
    check_order(coefficients.len())?;
    if let Some((index, &value)) = coefficients
        .iter()
        .enumerate()
        .find(|(_, c)| !(c.is_finite() && **c > 0.0))
    {
        return Err(EstimatorError::Coefficient { index, value });
    }
    let r = coefficients.len();
    Ok((1..=r)
        .map(|i| {
            let upper = if i == r { 1.0 } else { coefficients[i] };
            coefficients[i - 1] / upper
        })
        .collect())
}

/// The polynomial coefficients `c_j = prod_{i=j+1..r} K_i`, j = 0..r-1, of a chain.
#[must_use]
pub fn coefficients_from_gains(gains: &[f64]) -> Vec<f64> {
    let r = gains.len();
    let mut c = vec![0.0; r];
    let mut prod = 1.0;
    for j in (0..r).rev() {
        prod *= gains[j]; // K_{j+1}
        c[j] = prod;
    }
    c
}

/// Butterworth chain gains in closed form:
/// `K_i = omega_c sin(i g) / cos((i - 1) g)`, `g = pi / (2r)`, i = 1..r
/// (r = 3: `omega_c [0.5, 1, 2]`).
///
/// # Errors
/// Invalid order or cutoff.
pub fn butterworth_gains(order: usize, cutoff_rad_s: f64) -> Result<Vec<f64>, EstimatorError> {
    check_order(order)?;
    check_cutoff(cutoff_rad_s)?;
    let g = std::f64::consts::PI / (2.0 * order as f64);
    Ok((1..=order)
        .map(|i| cutoff_rad_s * (i as f64 * g).sin() / ((i - 1) as f64 * g).cos())
        .collect())
}

/// Binomial chain gains in closed form: `K_i = omega_c i / (r - i + 1)`, i = 1..r.
///
/// # Errors
/// Invalid order or cutoff.
pub fn binomial_gains(order: usize, cutoff_rad_s: f64) -> Result<Vec<f64>, EstimatorError> {
    check_order(order)?;
    check_cutoff(cutoff_rad_s)?;
    Ok((1..=order)
        .map(|i| cutoff_rad_s * i as f64 / (order - i + 1) as f64)
        .collect())
}

/// Chain gains for a polynomial: the closed forms for Butterworth and
/// binomial (no `omega_c^r` overflow), `K_i = c_{i-1}/c_i` for a custom list.
///
/// # Errors
/// As [`polynomial_coefficients`].
pub fn gains_for(polynomial: &Polynomial, order: usize, cutoff_rad_s: f64) -> Result<Vec<f64>, EstimatorError> {
    match polynomial {
        Polynomial::Butterworth => butterworth_gains(order, cutoff_rad_s),
        Polynomial::Binomial => binomial_gains(order, cutoff_rad_s),
        Polynomial::Custom(c) => {
            validate_custom(c, order)?;
            chain_gains(c)
        }
    }
}

/// `true` if forward Euler at sample time `h` keeps the chain stable, i.e.
/// every root `p` of `s^r + c_{r-1} s^{r-1} + ... + c_0` has `|1 + h p| < 1`.
///
/// Test: `z = 1 + h s` lies in the open unit disc iff `w = (z - 1)/(z + 1)`
/// lies in the open left half plane; substituting `h s = 2w/(1 - w)` and
/// multiplying by `(1 - w)^r` gives the degree-r polynomial
/// `sum_j c_j h^(r-j) (2w)^j (1 - w)^(r-j)`, checked with the Routh test.
/// Rounding can make it refuse a stable polynomial whose roots form a tight
/// cluster close to the bound (binomial r = 20 from about 0.8 of its bound
/// `omega_c h < 2`); the built-in polynomials use [`forward_euler_bound`].
#[must_use]
pub fn forward_euler_stable(coefficients: &[f64], h: f64) -> bool {
    let r = coefficients.len();
    // ascending coefficients of the polynomial in w
    let mut pw = vec![0.0; r + 1];
    for j in 0..=r {
        let cj = if j == r { 1.0 } else { coefficients[j] };
        let scaled = cj * h.powi((r - j) as i32) * 2f64.powi(j as i32);
        // (1 - w)^(r-j) = sum_m binom(r-j, m) (-w)^m
        let n = r - j;
        let mut b = 1.0;
        for m in 0..=n {
            let sign = if m % 2 == 0 { 1.0 } else { -1.0 };
            pw[j + m] += scaled * b * sign;
            b = b * (n - m) as f64 / (m + 1) as f64;
        }
    }
    let mut descending: Vec<f64> = pw.into_iter().rev().collect();
    if descending[0] < 0.0 {
        descending.iter_mut().for_each(|x| *x = -*x);
    }
    routh_first_failure(&descending).is_none()
}

/// Largest `omega_c h` for which forward Euler is stable, for the built-in
/// polynomials (poles on the circle of radius `omega_c`): Butterworth
/// `2 sin(pi / 2r)` (the pole pair nearest the imaginary axis decides),
/// binomial `2`. `None` for a custom polynomial (see [`forward_euler_stable`]).
#[must_use]
pub fn forward_euler_bound(polynomial: &Polynomial, order: usize) -> Option<f64> {
    match polynomial {
        Polynomial::Butterworth => Some(2.0 * (std::f64::consts::PI / (2.0 * order as f64)).sin()),
        Polynomial::Binomial => Some(2.0),
        Polynomial::Custom(_) => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: &[f64], b: &[f64], tol: f64) -> bool {
        a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() <= tol)
    }

    #[test]
    fn butterworth_gains_match_doc_oracle() {
        let k = |r| gains_for(&Polynomial::Butterworth, r, 10.0).unwrap();
        assert!(close(&k(1), &[10.0], 1e-12));
        assert!(close(&k(2), &[7.0711, 14.1421], 1e-4));
        assert!(close(&k(3), &[5.0, 10.0, 20.0], 1e-12));
        let k5 = k(5);
        assert!(
            close(&k5, &[3.09017, 6.18034, 10.0, 16.18034, 32.36068], 1e-5),
            "{k5:?}"
        );
        let b3 = gains_for(&Polynomial::Binomial, 3, 10.0).unwrap();
        assert!(close(&b3, &[10.0 / 3.0, 10.0, 30.0], 1e-12));
    }

    /// Doc section 7 table, a_r..a_0 for r = 1..8.
    #[test]
    #[allow(clippy::approx_constant, reason = "the doc table's rounded values")]
    fn butterworth_polynomials_match_doc_table() {
        let table: [&[f64]; 8] = [
            &[1.0, 1.0],
            &[1.0, 1.414214, 1.0],
            &[1.0, 2.0, 2.0, 1.0],
            &[1.0, 2.613126, 3.414214, 2.613126, 1.0],
            &[1.0, 3.236068, 5.236068, 5.236068, 3.236068, 1.0],
            &[1.0, 3.863703, 7.464102, 9.141620, 7.464102, 3.863703, 1.0],
            &[1.0, 4.493959, 10.097835, 14.591794, 14.591794, 10.097835, 4.493959, 1.0],
            &[
                1.0, 5.125831, 13.137071, 21.846151, 25.688356, 21.846151, 13.137071, 5.125831, 1.0,
            ],
        ];
        for (i, row) in table.iter().enumerate() {
            let r = i + 1;
            let a = butterworth_normalized(r).unwrap();
            // table is a_r (=1) .. a_0; ours is a_0 .. a_{r-1}
            let doc: Vec<f64> = row.iter().rev().take(r).copied().collect();
            assert!(close(&a, &doc, 1e-6), "r={r}: {a:?} vs {doc:?}");
            // a_1 = a_{r-1} = 1 / sin(pi / 2r)
            if r >= 2 {
                let s = 1.0 / (std::f64::consts::PI / (2.0 * r as f64)).sin();
                assert!((a[1] - s).abs() < 1e-12 && (a[r - 1] - s).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn closed_forms_equal_coefficient_route_for_all_orders() {
        for r in 1..=MAX_ORDER {
            for wc in [0.5, 10.0, 37.0] {
                for (poly, closed) in [
                    (Polynomial::Butterworth, butterworth_gains(r, wc).unwrap()),
                    (Polynomial::Binomial, binomial_gains(r, wc).unwrap()),
                ] {
                    let c = polynomial_coefficients(&poly, r, wc).unwrap();
                    let k = chain_gains(&c).unwrap();
                    for (i, (a, b)) in k.iter().zip(&closed).enumerate() {
                        assert!(
                            (a - b).abs() <= 1e-9 * b.abs(),
                            "{poly:?} r={r} wc={wc} K{}: {a} vs {b}",
                            i + 1
                        );
                    }
                    // and back: prod K = c
                    let c2 = coefficients_from_gains(&closed);
                    for (a, b) in c.iter().zip(&c2) {
                        assert!((a - b).abs() <= 1e-9 * b.abs());
                    }
                }
            }
        }
    }

    #[test]
    fn binomial_coefficients() {
        assert_eq!(binomial_normalized(4).unwrap(), vec![1.0, 4.0, 6.0, 4.0]);
        let c = binomial_normalized(20).unwrap();
        assert_eq!(c[10], 184_756.0);
        assert_eq!(c[1], 20.0);
    }

    #[test]
    fn routh_accepts_builtin_and_rejects_unstable() {
        for r in 1..=MAX_ORDER {
            assert!(is_hurwitz(&butterworth_normalized(r).unwrap()), "butterworth r={r}");
            assert!(is_hurwitz(&binomial_normalized(r).unwrap()), "binomial r={r}");
            assert!(is_hurwitz(
                &polynomial_coefficients(&Polynomial::Butterworth, r, 10.0).unwrap()
            ));
        }
        // s^3 + s^2 + s + 2: positive coefficients, two roots in the right half plane
        assert!(!is_hurwitz(&[2.0, 1.0, 1.0]));
        // s^3 + s^2 + s + 1 = (s + 1)(s^2 + 1): marginal, refused
        assert!(!is_hurwitz(&[1.0, 1.0, 1.0]));
        // s^2 + 3s + 2 = (s + 1)(s + 2)
        assert!(is_hurwitz(&[2.0, 3.0]));
        // s^4 + s^3 + 3 s^2 + 2 s + 5: first column 1, 1, 1, -3, 5 (fails at row 3)
        assert!(!is_hurwitz(&[5.0, 2.0, 3.0, 1.0]));
    }

    #[test]
    fn custom_validation_messages() {
        let e = validate_custom(&[1.0, 2.0], 3).unwrap_err();
        assert!(e.to_string().contains("3 coefficients"), "{e}");
        let e = validate_custom(&[1.0, -2.0, 3.0], 3).unwrap_err();
        assert!(e.to_string().contains("c_1"), "{e}");
        let e = validate_custom(&[2.0, 1.0, 1.0], 3).unwrap_err();
        assert!(e.to_string().contains("Hurwitz"), "{e}");
        let e = validate_custom(&[f64::NAN], 1).unwrap_err();
        assert!(e.to_string().contains("finite"), "{e}");
        assert!(validate_custom(&[6.0, 11.0, 6.0], 3).is_ok()); // (s+1)(s+2)(s+3)
        assert!(check_order(0).is_err() && check_order(21).is_err() && check_order(20).is_ok());
        assert!(check_cutoff(0.0).is_err() && check_cutoff(f64::INFINITY).is_err());
    }

    /// Forward Euler bound of doc section 7: Butterworth `omega_c h < 2 sin(pi/2r)`,
    /// binomial `omega_c h < 2`.
    #[test]
    fn forward_euler_stability_bound() {
        let h = 1e-3;
        for r in [1, 2, 3, 5, 10, 20] {
            let bound = 2.0 * (std::f64::consts::PI / (2.0 * r as f64)).sin() / h;
            let c = |wc| polynomial_coefficients(&Polynomial::Butterworth, r, wc).unwrap();
            assert!(forward_euler_stable(&c(0.97 * bound), h), "r={r}");
            assert!(!forward_euler_stable(&c(1.03 * bound), h), "r={r}");
            // the binomial's r-fold root is ill-conditioned: test with a margin for high r
            let margin = match r {
                1..=5 => 0.03,
                6..=10 => 0.1,
                _ => 0.3,
            };
            let b = |wc| polynomial_coefficients(&Polynomial::Binomial, r, wc).unwrap();
            assert!(forward_euler_stable(&b((1.0 - margin) * 2.0 / h), h), "binomial r={r}");
            assert!(!forward_euler_stable(&b((1.0 + margin) * 2.0 / h), h), "binomial r={r}");
            assert_eq!(forward_euler_bound(&Polynomial::Binomial, r), Some(2.0));
            assert_eq!(forward_euler_bound(&Polynomial::Butterworth, r), Some(bound * h));
        }
        assert_eq!(forward_euler_bound(&Polynomial::Custom(vec![1.0]), 1), None);
    }
}
