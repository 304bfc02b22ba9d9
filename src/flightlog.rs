//! Flight logs (the CSV that `rotorpilot simulate --csv` writes) and the
//! offline estimator sweep behind `rotorpilot estimate`.
//!
//! Required columns, the report's inputs: `time_s`, `vel_n vel_e vel_d`
//! [m/s] NED, `roll pitch yaw` [rad], `roll_rate pitch_rate yaw_rate`
//! (Euler-angle rates) [rad/s], `thrust_n` [N] and `tau_x tau_y tau_z` [N m]
//! FRD (the command held from that row to the next). Optional: `p_frd q_frd
//! r_frd` (body rates; otherwise `Q(eta) eta_dot`), and the truth
//! `fext_n fext_e fext_d`, `text_x text_y text_z`, `true_mass_kg` for error
//! metrics. Other columns are ignored. Time must increase; the step may
//! vary (each sample is integrated over its own interval, see
//! [`FlightLog::sample_steps`]).
//!
//! What produced a log (airframe, nominal model, step, estimator settings)
//! is in its sidecar `<log>.meta.json` ([`LogMeta`]), next to it: the CSV
//! itself carries no header comment, so the shipped logs stay byte for byte.
//!
//! The estimates CSV ([`write_estimates`]) holds millions of numbers: they
//! are formatted with [`push_f64`] (shortest round-trip digits, several times
//! faster than `Display`).

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use crate::estimation::{Discretization, EstimatorConfig, EstimatorInput, MomentumEstimator, Polynomial, step_metrics};
use crate::math::rate_map;
use crate::signals::GRAVITY;
use crate::signals::{NominalModel, WrenchEstimate};

/// Why a log could not be read.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum LogError {
    /// The file could not be read.
    #[error("{file}: cannot read: {message}")]
    Io {
        /// Path.
        file: String,
        /// OS message.
        message: String,
    },
    /// A required column is absent from the header.
    #[error("{file}:1: missing column `{column}`")]
    MissingColumn {
        /// Path.
        file: String,
        /// Column name.
        column: String,
    },
    /// A row has a different number of fields than the header.
    #[error("{file}:{line}: {found} fields, the header has {expected}")]
    Ragged {
        /// Path.
        file: String,
        /// 1-based line.
        line: usize,
        /// Fields in the header.
        expected: usize,
        /// Fields in this row.
        found: usize,
    },
    /// A field is not a finite number.
    #[error("{file}:{line}: column `{column}`: `{text}` is not a finite number")]
    NotANumber {
        /// Path.
        file: String,
        /// 1-based line.
        line: usize,
        /// Column name.
        column: String,
        /// The text found.
        text: String,
    },
    /// Time does not increase from one row to the next.
    #[error("{file}:{line}: column `time_s`: {problem}")]
    Time {
        /// Path.
        file: String,
        /// 1-based line.
        line: usize,
        /// What is wrong.
        problem: String,
    },
    /// Fewer than two rows.
    #[error("{file}: needs at least two rows of data")]
    TooShort {
        /// Path.
        file: String,
    },
}

/// The truth a simulated log carries.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LogTruth {
    /// External force [N], NED.
    pub force_ned: Vector3<f64>,
    /// External torque [N m], FRD.
    pub torque_frd: Vector3<f64>,
    /// True mass [kg].
    pub mass_kg: f64,
}

/// One row of a log.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LogRow {
    /// Estimator inputs at this time; the wrench is the one of *this* row
    /// (held until the next), see [`FlightLog::estimator_inputs`].
    pub input: EstimatorInput,
    /// Truth, when the log has it.
    pub truth: Option<LogTruth>,
}

/// A read log.
#[derive(Clone, Debug, PartialEq)]
pub struct FlightLog {
    /// Rows in time order.
    pub rows: Vec<LogRow>,
    /// The log's nominal step [s]: its first interval `t_1 - t_0` (every
    /// interval of a regular log, see [`FlightLog::sample_steps`]).
    pub step_s: f64,
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

const REQUIRED: [&str; 14] = [
    "time_s",
    "vel_n",
    "vel_e",
    "vel_d",
    "roll",
    "pitch",
    "yaw",
    "roll_rate",
    "pitch_rate",
    "yaw_rate",
    "thrust_n",
    "tau_x",
    "tau_y",
    "tau_z",
];
const RATES: [&str; 3] = ["p_frd", "q_frd", "r_frd"];
const TRUTH: [&str; 7] = [
    "fext_n",
    "fext_e",
    "fext_d",
    "text_x",
    "text_y",
    "text_z",
    "true_mass_kg",
];

impl FlightLog {
    /// Read a log file.
    ///
    /// # Errors
    /// [`LogError`] naming the file, the line and the column.
    pub fn from_file(path: &std::path::Path) -> Result<Self, LogError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| LogError::Io {
            file: file.clone(),
            message: e.to_string(),
        })?;
        Self::parse(&text, &file)
    }

    /// Parse log text; `file` labels errors.
    ///
    /// # Errors
    /// [`LogError`] naming the file, the line and the column.
    pub fn parse(text: &str, file: &str) -> Result<Self, LogError> {
        let mut lines = text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty());
        let header: Vec<&str> = lines
            .next()
            .map(|(_, l)| l.split(',').map(str::trim).collect())
            .unwrap_or_default();
        let find = |name: &str| header.iter().position(|h| *h == name);
        let mut required = [0usize; 14];
        for (slot, name) in required.iter_mut().zip(REQUIRED) {
            *slot = find(name).ok_or_else(|| LogError::MissingColumn {
                file: file.to_string(),
                column: name.to_string(),
            })?;
        }
        let rates: Option<Vec<usize>> = RATES.iter().map(|n| find(n)).collect();
        let truth: Option<Vec<usize>> = TRUTH.iter().map(|n| find(n)).collect();
        let mut rows = Vec::new();
        let mut step = None;
        let mut previous_t: Option<f64> = None;
        let mut fields: Vec<&str> = Vec::with_capacity(header.len());
        for (index, line) in lines {
            let number = index + 1;
            fields.clear();
            fields.extend(line.split(','));
            if fields.len() != header.len() {
                return Err(LogError::Ragged {
                    file: file.to_string(),
                    line: number,
                    expected: header.len(),
                    found: fields.len(),
                });
            }
            let value = |col: usize| -> Result<f64, LogError> {
                let t = fields[col].trim();
                t.parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| LogError::NotANumber {
                        file: file.to_string(),
                        line: number,
                        column: header[col].to_string(),
                        text: t.to_string(),
                    })
            };
            let v = |i: usize| value(required[i]);
            let t = v(0)?;
            if let Some(p) = previous_t {
                let dt: f64 = t - p;
                if dt <= 0.0 {
                    return Err(LogError::Time {
                        file: file.to_string(),
                        line: number,
                        problem: format!("{t} does not increase (previous row {p}): time must increase row by row"),
                    });
                }
                step.get_or_insert(dt);
            }
            previous_t = Some(t);
            let eta = Vector3::new(v(4)?, v(5)?, v(6)?);
            let eta_dot = Vector3::new(v(7)?, v(8)?, v(9)?);
            let rate_frd = match &rates {
                Some(c) => Vector3::new(value(c[0])?, value(c[1])?, value(c[2])?),
                None => rate_map(&eta) * eta_dot,
            };
            let input = EstimatorInput {
                time_s: t,
                velocity_ned: Vector3::new(v(1)?, v(2)?, v(3)?),
                eta,
                eta_dot,
                rate_frd,
                thrust_n: v(10)?,
                torque_frd: Vector3::new(v(11)?, v(12)?, v(13)?),
            };
            let truth = match &truth {
                Some(c) => Some(LogTruth {
                    force_ned: Vector3::new(value(c[0])?, value(c[1])?, value(c[2])?),
                    torque_frd: Vector3::new(value(c[3])?, value(c[4])?, value(c[5])?),
                    mass_kg: value(c[6])?,
                }),
                None => None,
            };
            rows.push(LogRow { input, truth });
        }
        match step {
            Some(step_s) if rows.len() >= 2 => Ok(Self { rows, step_s }),
            _ => Err(LogError::TooShort { file: file.to_string() }),
        }
    }

    /// The step each sample is integrated over [s]: `h_k = t_k - t_{k-1}`
    /// (`h_0`, unused by the estimator's first sample, is `h`), except that an
    /// interval within [`same_step`] of `h` is taken as `h` itself, so a
    /// regular log (its times printed in decimal) runs at one constant step,
    /// bit for bit as an estimator configured with `h`.
    #[must_use]
    pub fn sample_steps(&self, h: f64) -> Vec<f64> {
        let mut previous = None;
        self.rows
            .iter()
            .map(|r| {
                let t = r.input.time_s;
                let dt = previous.map_or(h, |p| t - p);
                previous = Some(t);
                if same_step(dt, h) { h } else { dt }
            })
            .collect()
    }

    /// The smallest and largest interval between rows [s].
    #[must_use]
    pub fn step_range(&self) -> (f64, f64) {
        self.rows
            .windows(2)
            .map(|w| w[1].input.time_s - w[0].input.time_s)
            .fold((f64::INFINITY, 0.0f64), |(lo, hi), dt| (lo.min(dt), hi.max(dt)))
    }

    /// Whether every interval is the nominal step ([`same_step`]).
    #[must_use]
    pub fn is_regular(&self) -> bool {
        self.rows
            .windows(2)
            .all(|w| same_step(w[1].input.time_s - w[0].input.time_s, self.step_s))
    }

    /// The inputs in the estimator's timing: sample `k` carries `x_k` and the
    /// wrench of row `k - 1` (applied over `[t_{k-1}, t_k)`).
    pub fn estimator_inputs(&self) -> impl Iterator<Item = EstimatorInput> + '_ {
        self.rows.iter().enumerate().map(|(k, r)| {
            let applied = if k == 0 { &r.input } else { &self.rows[k - 1].input };
            EstimatorInput {
                thrust_n: applied.thrust_n,
                torque_frd: applied.torque_frd,
                ..r.input
            }
        })
    }
}

/// Run one estimator over a log; one estimate per row. Each sample is
/// integrated over its own step ([`FlightLog::sample_steps`] of the
/// configured sample time), so a log with a varying step is estimated as
/// the rule says; a regular log gives the bits of a constant-step estimator.
///
/// # Errors
/// An invalid estimator configuration (forward Euler unstable at one of the
/// log's steps included).
pub fn estimate_log(
    log: &FlightLog,
    config: EstimatorConfig,
    nominal: NominalModel,
) -> Result<Vec<WrenchEstimate>, crate::estimation::EstimatorError> {
    let steps = log.sample_steps(config.sample_time_s);
    let mut est = MomentumEstimator::new(config, nominal)?;
    log.estimator_inputs()
        .zip(steps)
        .map(|(x, h)| est.update_with_step(&x, h))
        .collect()
}

/// What produced a flight CSV: its sidecar `<csv>.meta.json`
/// ([`meta_path`]), one JSON object written next to the CSV by every
/// producer (`simulate --csv`, the daemon's `--log-csv`, `replay --csv`):
///
/// ```text
/// { "format": "rotorpilot-flight-csv-meta", "version": 1,
///   "producer": "rotorpilot 0.1.0 simulate", "source": "tools/scenarios/quad-step-10m.toml",
///   "airframe": "quad", "nominal_mass_kg": 2.0,
///   "nominal_inertia_kg_m2": [[Ixx, Ixy, Ixz], [Iyx, Iyy, Iyz], [Izx, Izy, Izz]],   (body FRD)
///   "step_s": 0.001,
///   "estimator": { "order": 3, "polynomial": "butterworth", "cutoff_rad_s": 10.0,
///                  "discretization": "trapezoidal", "sample_time_s": 0.001 } }
/// ```
///
/// The nominal model is the one the flight's estimator used (`MDL_MASS` for
/// the daemon), at the start of the flight.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LogMeta {
    /// Always [`META_FORMAT`].
    pub format: String,
    /// [`META_VERSION`].
    pub version: u32,
    /// The program and command that wrote the CSV (`rotorpilot 0.1.0 simulate`).
    pub producer: String,
    /// What was flown: the scenario or mission file, or the daemon's run.
    pub source: String,
    /// The airframe's name (`quad`, ...; a file's own name for a TOML airframe).
    pub airframe: String,
    /// The estimator's nominal mass [kg].
    pub nominal_mass_kg: f64,
    /// The estimator's nominal inertia [kg m^2], body FRD, rows.
    pub nominal_inertia_kg_m2: [[f64; 3]; 3],
    /// The simulation step [s] (the interval between rows).
    pub step_s: f64,
    /// The flight's own estimator settings.
    pub estimator: EstimatorConfig,
}

/// [`LogMeta::format`].
pub const META_FORMAT: &str = "rotorpilot-flight-csv-meta";
/// [`LogMeta::version`].
pub const META_VERSION: u32 = 1;

impl LogMeta {
    /// The sidecar of a log written by `producer` (e.g. `simulate`) from `source`.
    #[must_use]
    pub fn new(
        producer: &str,
        source: &str,
        airframe: &str,
        nominal: &NominalModel,
        estimator: &EstimatorConfig,
        step_s: f64,
    ) -> Self {
        let i = &nominal.inertia_kg_m2;
        Self {
            format: META_FORMAT.into(),
            version: META_VERSION,
            producer: format!("rotorpilot {} {producer}", env!("CARGO_PKG_VERSION")),
            source: source.into(),
            airframe: airframe.into(),
            nominal_mass_kg: nominal.mass_kg,
            nominal_inertia_kg_m2: std::array::from_fn(|r| std::array::from_fn(|c| i[(r, c)])),
            step_s,
            estimator: estimator.clone(),
        }
    }

    /// The nominal model it records.
    #[must_use]
    pub fn nominal(&self) -> NominalModel {
        let i = &self.nominal_inertia_kg_m2;
        NominalModel {
            mass_kg: self.nominal_mass_kg,
            inertia_kg_m2: nalgebra::Matrix3::from_fn(|r, c| i[r][c]),
        }
    }

    /// Write it as the sidecar of the CSV at `csv` ([`meta_path`]).
    ///
    /// # Errors
    /// A file that cannot be written (the message names it).
    pub fn write_beside(&self, csv: &std::path::Path) -> Result<(), String> {
        let path = meta_path(csv);
        let text = serde_json::to_string_pretty(self).map_err(|e| e.to_string())? + "\n";
        std::fs::write(&path, text).map_err(|e| format!("cannot write {}: {e}", path.display()))
    }

    /// Read the sidecar of the CSV at `csv`: `Ok(None)` when there is none.
    ///
    /// # Errors
    /// A sidecar that cannot be read or is not a valid [`LogMeta`] (the
    /// message names the file, the line and the field).
    pub fn read_beside(csv: &std::path::Path) -> Result<Option<Self>, String> {
        let path = meta_path(csv);
        let text = match std::fs::read_to_string(&path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(format!("{}: cannot read: {e}", path.display())),
        };
        let meta: Self = serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))?;
        if meta.format != META_FORMAT || meta.version != META_VERSION {
            return Err(format!(
                "{}: format `{}` version {}, this rotorpilot reads `{META_FORMAT}` version {META_VERSION}",
                path.display(),
                meta.format,
                meta.version
            ));
        }
        crate::estimation::MomentumEstimator::new(meta.estimator.clone(), meta.nominal())
            .map_err(|e| format!("{}: {e}", path.display()))?;
        Ok(Some(meta))
    }
}

/// The sidecar's path: the CSV's path with `.meta.json` appended
/// (`flight.csv` -> `flight.csv.meta.json`).
#[must_use]
pub fn meta_path(csv: &std::path::Path) -> std::path::PathBuf {
    let mut name = csv.as_os_str().to_owned();
    name.push(".meta.json");
    std::path::PathBuf::from(name)
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
    log: &FlightLog,
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
    let truths: Option<Vec<LogTruth>> = log.rows.iter().map(|r| r.truth).collect();
    let Some(truths) = truths else { return result };
    let times: Vec<f64> = log.rows.iter().map(|r| r.input.time_s).collect();
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

/// Column suffixes of one estimator run in the estimates CSV, in the order of
/// [`write_estimates`]: force NED, torque FRD, torque RPY, mass.
pub const ESTIMATE_COLUMNS: [&str; 10] = [
    "fn", "fe", "fd", "tx", "ty", "tz", "t_roll", "t_pitch", "t_yaw", "mass_kg",
];

/// Write the estimates CSV: a header `time_s,{label}_fn,...` (the
/// [`ESTIMATE_COLUMNS`] of each run), then one line per log row with the
/// row's time and each run's estimate (numbers by [`push_f64`]).
/// `runs` pairs a label (e.g. `butterworth5`) with one estimate per log row.
///
/// # Errors
/// A write error, or a run that has not one estimate per row
/// ([`std::io::ErrorKind::InvalidInput`]).
pub fn write_estimates<W: std::io::Write>(
    w: &mut W,
    log: &FlightLog,
    runs: &[(String, Vec<WrenchEstimate>)],
) -> std::io::Result<()> {
    if runs.iter().any(|(_, e)| e.len() != log.rows.len()) {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "an estimator run does not have one estimate per log row",
        ));
    }
    let mut header = String::from("time_s");
    for (label, _) in runs {
        for ch in ESTIMATE_COLUMNS {
            header.push_str(&format!(",{label}_{ch}"));
        }
    }
    writeln!(w, "{header}")?;
    let mut line = Vec::new();
    for (k, row) in log.rows.iter().enumerate() {
        line.clear();
        push_f64(&mut line, row.input.time_s);
        for (_, estimates) in runs {
            let e = &estimates[k];
            for v in e.force_ned.iter().chain(e.torque_frd.iter()).chain(e.torque_rpy.iter()) {
                line.push(b',');
                push_f64(&mut line, *v);
            }
            line.push(b',');
            push_f64(&mut line, e.mass_kg);
        }
        line.push(b'\n');
        w.write_all(&line)?;
    }
    Ok(())
}

/// Append `v` to `out` as the shortest decimal that reads back to the same
/// `f64` (`zmij`, several times faster than `Display`; it may use an
/// exponent, `1e-7`, and writes integers as `3.0`); `NaN`, `inf` and `-inf`
/// as `Display` writes them.
pub fn push_f64(out: &mut Vec<u8>, v: f64) {
    if v.is_finite() {
        out.extend_from_slice(zmij::Buffer::new().format_finite(v).as_bytes());
    } else {
        out.extend_from_slice(format!("{v}").as_bytes());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `push_f64` reads back to the same bits, for edge cases and a spread
    /// of random bit patterns over every exponent.
    #[test]
    fn push_f64_round_trips() {
        let mut values = vec![
            0.0,
            -0.0,
            1.0,
            -1.5,
            0.1,
            1e-7,
            1e22,
            9007199254740993.0,
            f64::MAX,
            f64::MIN_POSITIVE,
            5e-324,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ];
        let mut x: u64 = 0x2545_f491_4f6c_dd1d;
        for _ in 0..100_000 {
            // xorshift64
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            values.push(f64::from_bits(x));
        }
        let mut out = Vec::new();
        for v in values.into_iter().filter(|v| !v.is_nan()) {
            out.clear();
            push_f64(&mut out, v);
            let back: f64 = std::str::from_utf8(&out).unwrap().parse().unwrap();
            assert_eq!(back.to_bits(), v.to_bits(), "{v}");
        }
        out.clear();
        push_f64(&mut out, f64::NAN);
        assert_eq!(out, b"NaN");
    }

    /// One header and one line per row, the runs side by side.
    #[test]
    fn estimates_csv_layout() {
        let rows = (0..3)
            .map(|k| LogRow {
                input: EstimatorInput {
                    time_s: f64::from(k) * 1e-3,
                    ..EstimatorInput::default()
                },
                truth: None,
            })
            .collect();
        let log = FlightLog { rows, step_s: 1e-3 };
        let estimates: Vec<_> = (0..3)
            .map(|k| WrenchEstimate {
                force_ned: Vector3::new(f64::from(k), 0.25, -2.5),
                torque_frd: Vector3::new(0.5, 0.0, -0.125),
                torque_rpy: Vector3::repeat(1e-7),
                mass_kg: 1.5,
            })
            .collect();
        let runs = vec![
            ("binomial3".to_string(), estimates.clone()),
            ("butterworth5".to_string(), estimates),
        ];
        let mut out = Vec::new();
        write_estimates(&mut out, &log, &runs).unwrap();
        let text = String::from_utf8(out).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 4);
        assert!(lines[0].starts_with("time_s,binomial3_fn,binomial3_fe,"));
        assert!(lines[0].ends_with(",butterworth5_t_yaw,butterworth5_mass_kg"));
        let fields: Vec<f64> = lines[2].split(',').map(|f| f.parse().unwrap()).collect();
        let one = [1.0, 0.25, -2.5, 0.5, 0.0, -0.125, 1e-7, 1e-7, 1e-7, 1.5];
        assert_eq!(fields[0], 1e-3);
        assert_eq!(&fields[1..11], &one);
        assert_eq!(&fields[11..], &one);
        let mut short = runs.clone();
        short[1].1.pop();
        assert!(write_estimates(&mut Vec::new(), &log, &short).is_err());
    }
}
