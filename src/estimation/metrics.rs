//! Step-response metrics of an estimate time series against the true value
//! (2 % settling time, overshoot, RMS error), for the offline comparison of
//! orders and polynomials (`docs/model.md` sections 7 and 10).
//! Pure functions on slices.

/// Why a metric could not be computed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum MetricsError {
    /// No samples.
    #[error("the time series is empty")]
    Empty,
    /// Two series that should pair up do not.
    #[error("series lengths differ: {left} vs {right}")]
    LengthMismatch {
        /// Length of the first series.
        left: usize,
        /// Length of the second series.
        right: usize,
    },
    /// The step has no size, so a relative band or overshoot is undefined.
    #[error("step size is zero or not finite (initial {initial}, final {target})")]
    ZeroStep {
        /// Value before the step.
        initial: f64,
        /// True value after the step.
        target: f64,
    },
    /// A band fraction that is not finite and > 0.
    #[error("settling band must be finite and > 0, got {0}")]
    Band(f64),
}

/// Metrics of one channel's response to a step of the true value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepMetrics {
    /// Time from the step until the estimate enters the band of +-2 % of the
    /// step size around the true value for good [s]; `None` if the last
    /// sample is still outside.
    pub settling_time_s: Option<f64>,
    /// Largest excursion beyond the true value in the step direction, in %
    /// of the step size (0 if none).
    pub overshoot_percent: f64,
    /// RMS of `estimate - target` over the samples at or after the step
    /// [units of the channel].
    pub rms_error: f64,
}

fn check_pair(a: usize, b: usize) -> Result<(), MetricsError> {
    if a == 0 {
        return Err(MetricsError::Empty);
    }
    if a != b {
        return Err(MetricsError::LengthMismatch { left: a, right: b });
    }
    Ok(())
}

fn step_size(initial: f64, target: f64) -> Result<f64, MetricsError> {
    let s = target - initial;
    if s.is_finite() && s != 0.0 {
        Ok(s)
    } else {
        Err(MetricsError::ZeroStep { initial, target })
    }
}

/// Settling time: the estimate `values[k]` at `times[k]` stays within
/// `band * |target - initial|` of `target` from the returned time on. The
/// time is measured from `step_time_s` and interpolated linearly to the
/// band edge between the last sample outside the band and the next one
/// (0 if every sample at or after the step is inside). Samples before
/// `step_time_s` are ignored. `None` if the last sample is outside the band.
///
/// # Errors
/// Empty or mismatched series, a zero step, or a band not finite and > 0.
pub fn settling_time(
    times: &[f64],
    values: &[f64],
    step_time_s: f64,
    initial: f64,
    target: f64,
    band: f64,
) -> Result<Option<f64>, MetricsError> {
    check_pair(times.len(), values.len())?;
    let size = step_size(initial, target)?.abs();
    if !(band.is_finite() && band > 0.0) {
        return Err(MetricsError::Band(band));
    }
    let tol = band * size;
    let outside = |v: f64| v.is_nan() || (v - target).abs() > tol;
    let start = times.partition_point(|&t| t < step_time_s);
    if start == times.len() {
        return Err(MetricsError::Empty);
    }
    let Some(last_out) = (start..times.len()).rev().find(|&k| outside(values[k])) else {
        return Ok(Some(0.0));
    };
    if last_out + 1 == times.len() {
        return Ok(None);
    }
    let (t0, t1) = (times[last_out], times[last_out + 1]);
    let (v0, v1) = (values[last_out], values[last_out + 1]);
    // band edge on the side where v0 lies
    let edge = if v0 > target { target + tol } else { target - tol };
    let frac = if v1 != v0 && v0.is_finite() {
        ((edge - v0) / (v1 - v0)).clamp(0.0, 1.0)
    } else {
        1.0
    };
    Ok(Some(t0 + frac * (t1 - t0) - step_time_s))
}

/// Overshoot in % of the step size: `100 max_k (values[k] - target) / (target - initial)`
/// (the excursion past the true value in the direction of the step), 0 if
/// the estimate never passes it.
///
/// # Errors
/// Empty series or a zero step.
pub fn overshoot_percent(values: &[f64], initial: f64, target: f64) -> Result<f64, MetricsError> {
    if values.is_empty() {
        return Err(MetricsError::Empty);
    }
    let size = step_size(initial, target)?;
    let worst = values.iter().map(|v| (v - target) / size).fold(0.0_f64, f64::max);
    Ok(100.0 * worst)
}

/// RMS error `sqrt(mean((values - truth)^2))` of paired series.
///
/// # Errors
/// Empty or mismatched series.
pub fn rms_error(values: &[f64], truth: &[f64]) -> Result<f64, MetricsError> {
    check_pair(values.len(), truth.len())?;
    let sum: f64 = values.iter().zip(truth).map(|(v, t)| (v - t) * (v - t)).sum();
    Ok((sum / values.len() as f64).sqrt())
}

/// RMS error of a series against a constant true value.
///
/// # Errors
/// Empty series.
pub fn rms_error_to(values: &[f64], truth: f64) -> Result<f64, MetricsError> {
    if values.is_empty() {
        return Err(MetricsError::Empty);
    }
    let sum: f64 = values.iter().map(|v| (v - truth) * (v - truth)).sum();
    Ok((sum / values.len() as f64).sqrt())
}

/// 2 % settling time, overshoot and RMS error of a step from `initial` to
/// `target` at `step_time_s`; only samples at or after the step count.
///
/// # Errors
/// As [`settling_time`]; also no sample at or after the step.
pub fn step_metrics(
    times: &[f64],
    values: &[f64],
    step_time_s: f64,
    initial: f64,
    target: f64,
) -> Result<StepMetrics, MetricsError> {
    let settling_time_s = settling_time(times, values, step_time_s, initial, target, 0.02)?;
    let start = times.partition_point(|&t| t < step_time_s);
    let after = &values[start..];
    Ok(StepMetrics {
        settling_time_s,
        overshoot_percent: overshoot_percent(after, initial, target)?,
        rms_error: rms_error_to(after, target)?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_order_response() {
        // y = 1 - exp(-t): t2% = ln 50 = 3.912, no overshoot
        let h = 1e-3;
        let times: Vec<f64> = (0..10_000).map(|k| k as f64 * h).collect();
        let y: Vec<f64> = times.iter().map(|t| 1.0 - (-t).exp()).collect();
        let m = step_metrics(&times, &y, 0.0, 0.0, 1.0).unwrap();
        assert!((m.settling_time_s.unwrap() - 50f64.ln()).abs() < 1e-6, "{m:?}");
        assert_eq!(m.overshoot_percent, 0.0);
        // rms of exp(-t) over [0, 10): sqrt((1 - e^-20)/2 / 10)
        assert!((m.rms_error - (0.5f64 / 10.0).sqrt()).abs() < 1e-3);
    }

    #[test]
    fn negative_step_and_overshoot() {
        let times = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0];
        let y = [0.0, -1.5, -2.2, -1.9, -2.01, -2.0];
        let m = step_metrics(&times, &y, 0.0, 0.0, -2.0).unwrap();
        assert!((m.overshoot_percent - 10.0).abs() < 1e-12);
        // band 0.04: last outside is t=3 (-1.9), enters at -1.96 between t=3 and t=4
        let expected = 3.0 + (-1.96 - -1.9) / (-2.01 - -1.9);
        assert!((m.settling_time_s.unwrap() - expected).abs() < 1e-12);
        // not settled at the end
        let y2 = [0.0, -1.0, -1.5, -1.8, -1.9, -1.95];
        assert_eq!(settling_time(&times, &y2, 0.0, 0.0, -2.0, 0.02).unwrap(), None);
        // step later than the first sample: earlier samples ignored
        let s = settling_time(&times, &[5.0, 5.0, -2.0, -2.0, -2.0, -2.0], 2.0, 0.0, -2.0, 0.02).unwrap();
        assert_eq!(s, Some(0.0));
    }

    #[test]
    fn errors() {
        assert_eq!(rms_error(&[], &[]), Err(MetricsError::Empty));
        assert!(matches!(
            rms_error(&[1.0], &[1.0, 2.0]),
            Err(MetricsError::LengthMismatch { .. })
        ));
        assert!(matches!(
            overshoot_percent(&[1.0], 1.0, 1.0),
            Err(MetricsError::ZeroStep { .. })
        ));
        assert!(matches!(
            settling_time(&[0.0], &[0.0], 0.0, 0.0, 1.0, 0.0),
            Err(MetricsError::Band(_))
        ));
        assert_eq!(rms_error(&[1.0, 3.0], &[1.0, 1.0]), Ok(2f64.sqrt()));
    }
}
