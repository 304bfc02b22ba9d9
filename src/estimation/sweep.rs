//! The offline estimator sweep behind `rotorpilot estimate`: run momentum
//! estimators of several orders, polynomials and cutoffs over the rows of a
//! recorded flight and measure each against the flight's truth (settling,
//! overshoot, RMS error against the effective disturbance
//! `f_e + (m_true - m_nom) g e3`, NED).
//!
//! It takes rows ([`LogRow`]: the estimator's inputs and the truth of each
//! sample), whoever read them; each sample is integrated over its own
//! interval ([`sample_steps`]), so a log whose step varies is estimated as
//! the rule says and a regular one gives the bits of a constant-step
//! estimator.

use nalgebra::Vector3;
use serde::Serialize;

use super::{
    Discretization, EstimatorConfig, EstimatorError, EstimatorInput, MomentumEstimator, Polynomial, step_metrics,
};
use crate::signals::{GRAVITY, NominalModel, WrenchEstimate};

/// The truth a simulated flight log carries.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LogTruth {
    /// External force [N], NED.
    pub force_ned: Vector3<f64>,
    /// External torque [N m], FRD.
    pub torque_frd: Vector3<f64>,
    /// True mass [kg].
    pub mass_kg: f64,
}

/// One row of a flight log: what the sweep runs over.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LogRow {
    /// Estimator inputs at this time; the wrench is the one of *this* row
    /// (held until the next), see [`estimator_inputs`].
    pub input: EstimatorInput,
    /// Truth, when the log has it.
    pub truth: Option<LogTruth>,
}

/// Two steps closer than this are the same step: `|dt - h| <= STEP_TOLERANCE_REL h + STEP_TOLERANCE_ABS_S`
/// (the rounding of the time column, printed in decimal, not jitter).
pub const STEP_TOLERANCE_REL: f64 = 1e-6;
/// See [`STEP_TOLERANCE_REL`] [s].
pub const STEP_TOLERANCE_ABS_S: f64 = 1e-9;

/// Whether `dt` [s] is the step `h` [s] up to the rounding of the time column.
#[must_use]
pub fn same_step(dt: f64, h: f64) -> bool {
    (dt - h).abs() <= STEP_TOLERANCE_REL * h + STEP_TOLERANCE_ABS_S
}

/// The step each sample is integrated over [s]: `h_k = t_k - t_{k-1}`
/// (`h_0`, unused by the estimator's first sample, is `h`), except that an
/// interval within [`same_step`] of `h` is taken as `h` itself, so a
/// regular log (its times printed in decimal) runs at one constant step,
/// bit for bit as an estimator configured with `h`.
#[must_use]
pub fn sample_steps(rows: &[LogRow], h: f64) -> Vec<f64> {
    let mut previous = None;
    rows.iter()
        .map(|r| {
            let t = r.input.time_s;
            let dt = previous.map_or(h, |p| t - p);
            previous = Some(t);
            if same_step(dt, h) { h } else { dt }
        })
        .collect()
}

/// The inputs in the estimator's timing: sample `k` carries `x_k` and the
/// wrench of row `k - 1` (applied over `[t_{k-1}, t_k)`).
pub fn estimator_inputs(rows: &[LogRow]) -> impl Iterator<Item = EstimatorInput> + '_ {
    rows.iter().enumerate().map(|(k, r)| {
        let applied = if k == 0 { &r.input } else { &rows[k - 1].input };
        EstimatorInput {
            thrust_n: applied.thrust_n,
            torque_frd: applied.torque_frd,
            ..r.input
        }
    })
}

/// Run one estimator over a log; one estimate per row. Each sample is
/// integrated over its own step ([`sample_steps`] of the
/// configured sample time), so a log with a varying step is estimated as
/// the rule says; a regular log gives the bits of a constant-step estimator.
///
/// # Errors
/// An invalid estimator configuration (forward Euler unstable at one of the
/// log's steps included).
pub fn estimate_log(
    rows: &[LogRow],
    config: EstimatorConfig,
    nominal: NominalModel,
) -> Result<Vec<WrenchEstimate>, EstimatorError> {
    let steps = sample_steps(rows, config.sample_time_s);
    let mut est = MomentumEstimator::new(config, nominal)?;
    estimator_inputs(rows)
        .zip(steps)
        .map(|(x, h)| est.update_with_step(&x, h))
        .collect()
}

/// Step metrics of one estimator run against the log's truth.
#[derive(Clone, Debug, Serialize)]
pub struct SweepResult {
    /// Order r.
    pub order: usize,
    /// Polynomial name.
    pub poly: String,
    /// Cutoff [rad/s].
    pub cutoff_rad_s: f64,
    /// Final force estimate [N], NED.
    pub final_force_ned: [f64; 3],
    /// Final torque estimate [N m], FRD.
    pub final_torque_frd: [f64; 3],
    /// Final torque estimate in Euler-angle coordinates [N m].
    pub final_torque_rpy: [f64; 3],
    /// Final real-mass estimate [kg].
    pub mass_kg: f64,
    /// Largest 2 % settling time over the channels with a step [s]; `None` without truth or if unsettled.
    pub settle_s: Option<f64>,
    /// Largest overshoot over those channels [%].
    pub overshoot_pct: Option<f64>,
    /// RMS force error against the effective disturbance [N] (`None` without truth).
    pub rms_force_error_n: Option<f64>,
    /// RMS body-torque error [N m].
    pub rms_torque_error_n_m: Option<f64>,
}

/// The force the estimator should see at hover: `f_e + (m_true - m_nom) g e3` (doc section 7).
fn effective_force(t: &LogTruth, nominal_mass: f64) -> Vector3<f64> {
    t.force_ned + Vector3::new(0.0, 0.0, (t.mass_kg - nominal_mass) * GRAVITY)
}

/// Metrics of `estimates` against the log's truth.
#[must_use]
pub fn sweep_result(
    rows: &[LogRow],
    config: &EstimatorConfig,
    nominal: &NominalModel,
    estimates: &[WrenchEstimate],
) -> SweepResult {
    let last = estimates.last().copied().unwrap_or_default();
    let arr = |v: Vector3<f64>| [v.x, v.y, v.z];
    let mut result = SweepResult {
        order: config.order,
        poly: match &config.polynomial {
            Polynomial::Butterworth => "butterworth".into(),
            Polynomial::Binomial => "binomial".into(),
            Polynomial::Custom(_) => "custom".into(),
        },
        cutoff_rad_s: config.cutoff_rad_s,
        final_force_ned: arr(last.force_ned),
        final_torque_frd: arr(last.torque_frd),
        final_torque_rpy: arr(last.torque_rpy),
        mass_kg: last.mass_kg,
        settle_s: None,
        overshoot_pct: None,
        rms_force_error_n: None,
        rms_torque_error_n_m: None,
    };
    let truths: Option<Vec<LogTruth>> = rows.iter().map(|r| r.truth).collect();
    let Some(truths) = truths else { return result };
    let times: Vec<f64> = rows.iter().map(|r| r.input.time_s).collect();
    let forces: Vec<Vector3<f64>> = truths.iter().map(|t| effective_force(t, nominal.mass_kg)).collect();
    let n = estimates.len() as f64;
    let rms = |f: &dyn Fn(usize) -> f64| ((0..estimates.len()).map(f).map(|e| e * e).sum::<f64>() / n).sqrt();
    result.rms_force_error_n = Some(rms(&|k| (estimates[k].force_ned - forces[k]).norm()));
    result.rms_torque_error_n_m = Some(rms(&|k| (estimates[k].torque_frd - truths[k].torque_frd).norm()));
    // Settling and overshoot per channel whose final truth differs from the estimator's start (0).
    let final_force = *forces.last().unwrap_or(&Vector3::zeros());
    let final_torque = truths.last().map_or(Vector3::zeros(), |t| t.torque_frd);
    let mut settle: Option<f64> = Some(0.0);
    let mut overshoot: f64 = 0.0;
    let mut any = false;
    for (target, series) in (0..3)
        .map(|i| {
            (
                final_force[i],
                estimates.iter().map(|e| e.force_ned[i]).collect::<Vec<_>>(),
            )
        })
        .chain((0..3).map(|i| {
            (
                final_torque[i],
                estimates.iter().map(|e| e.torque_frd[i]).collect::<Vec<_>>(),
            )
        }))
    {
        if target.abs() < 1e-9 {
            continue;
        }
        if let Ok(m) = step_metrics(&times, &series, times[0], 0.0, target) {
            any = true;
            settle = match (settle, m.settling_time_s) {
                (Some(a), Some(b)) => Some(a.max(b)),
                _ => None,
            };
            overshoot = overshoot.max(m.overshoot_percent);
        }
    }
    if any {
        result.settle_s = settle;
        result.overshoot_pct = Some(overshoot);
    }
    result
}

/// Parse `butterworth`, `binomial` (comma lists are split by the caller).
///
/// # Errors
/// The unknown name.
pub fn parse_poly(name: &str) -> Result<Polynomial, String> {
    match name.trim() {
        "butterworth" => Ok(Polynomial::Butterworth),
        "binomial" => Ok(Polynomial::Binomial),
        other => Err(format!("unknown polynomial `{other}` (butterworth, binomial)")),
    }
}

/// The estimator configuration for one sweep cell.
#[must_use]
pub fn sweep_config(
    order: usize,
    poly: Polynomial,
    cutoff_rad_s: f64,
    step_s: f64,
    disc: Discretization,
) -> EstimatorConfig {
    EstimatorConfig {
        order,
        polynomial: poly,
        cutoff_rad_s,
        discretization: disc,
        sample_time_s: step_s,
    }
}
