//! The flight CSV: written one row per step by [`CsvLog`] (`rotorpilot
//! simulate --csv`, the daemon's `flight.csv`, `rotorpilot replay --csv`:
//! one writer for every producer, so their files agree byte for byte), read
//! back by [`FlightLog`] (`rotorpilot estimate`); and the estimates CSV
//! [`write_estimates`] writes.
//!
//! Written, one row per step `k` (state `x_k` at `t_k`, command `u_k` held
//! over `[t_k, t_{k+1})`), SI units, NED/FRD. First the measurements the
//! estimator and controller saw (the report's inputs): `time_s`,
//! `pos_n pos_e pos_d`, `vel_n vel_e vel_d`, `roll pitch yaw` [rad],
//! `roll_rate pitch_rate yaw_rate` (Euler-angle rates `eta_dot = Q^-1 omega`),
//! `p_frd q_frd r_frd` (body rates); then the truth `true_pos_n/e/d`,
//! `true_vel_n/e/d`; the reference `ref_n ref_e ref_d ref_yaw`; `thrust_n
//! tau_x tau_y tau_z` (the wrench applied over the step: what the estimator is
//! told), `cmd_thrust_n cmd_tau_x cmd_tau_y cmd_tau_z` (controller output
//! before allocation), `saturated`, `w1..wn` (rotor speed commands, rad/s),
//! `fext_n fext_e fext_d`, `text_x text_y text_z` (the injected external
//! wrench; the aerodynamic one is not in it),
//! `true_mass_kg`, `est_fn est_fe est_fd`, `est_tx est_ty est_tz` (body FRD),
//! `est_mass_kg`. Numbers are printed in the shortest form that reads back to
//! the same `f64`, so an offline run on the log reproduces the online one.
//!
//! Read (`rotorpilot estimate`), the required columns, the report's inputs:
//! `time_s`, `vel_n vel_e vel_d` [m/s] NED, `roll pitch yaw` [rad],
//! `roll_rate pitch_rate yaw_rate` (Euler-angle rates) [rad/s], `thrust_n`
//! [N] and `tau_x tau_y tau_z` [N m] FRD (the command held from that row to
//! the next). Optional: `p_frd q_frd r_frd` (body rates; otherwise `Q(eta)
//! eta_dot`), and the truth `fext_n fext_e fext_d`, `text_x text_y text_z`,
//! `true_mass_kg` for error metrics. Other columns are ignored. Time must
//! increase; the step may vary (each sample is integrated over its own
//! interval, see [`crate::estimation::sweep::sample_steps`]).
//!
//! What produced a log (airframe, nominal model, step, estimator settings)
//! is in its sidecar `<log>.meta.json` ([`super::meta::LogMeta`]), next to
//! it: the CSV itself carries no header comment, so the shipped logs stay
//! byte for byte.
//!
//! The estimates CSV ([`write_estimates`]) holds millions of numbers: they
//! are formatted with [`push_f64`] (shortest round-trip digits, several times
//! faster than `Display`).

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

use nalgebra::Vector3;

use crate::estimation::sweep::{LogRow, LogTruth, same_step};
use crate::estimation::{EstimatorInput, input_from};
use crate::lockstep::{Lockstep, Pilot, StepRecord};
use crate::math::rate_map;
use crate::signals::WrenchEstimate;

/// A flight CSV file's write buffer: rows go out in blocks of this many bytes.
pub const CSV_BUFFER_BYTES: usize = 256 * 1024;

/// Create the CSV file at `path`, buffered ([`CSV_BUFFER_BYTES`]).
///
/// # Errors
/// A file that cannot be created (the message names it).
pub fn create_csv_file(path: &Path) -> Result<BufWriter<File>, String> {
    File::create(path)
        .map(|f| BufWriter::with_capacity(CSV_BUFFER_BYTES, f))
        .map_err(|e| format!("cannot create {}: {e}", path.display()))
}

/// A flight CSV being written: the header line at [`CsvLog::new`], one row
/// per [`CsvLog::row`], flushed by [`CsvLog::finish`].
#[derive(Debug)]
pub struct CsvLog<W: Write> {
    out: W,
    rotors: usize,
}

impl<W: Write> CsvLog<W> {
    /// Start the CSV of a vehicle with `rotors` rotors: its header line.
    ///
    /// # Errors
    /// A failed write.
    pub fn new(mut out: W, rotors: usize) -> std::io::Result<Self> {
        writeln!(out, "{}", csv_header(rotors))?;
        Ok(Self { out, rotors })
    }

    /// One step's row.
    ///
    /// # Errors
    /// A failed write.
    pub fn row(&mut self, rec: &StepRecord<'_>) -> std::io::Result<()> {
        writeln!(self.out, "{}", csv_row(rec, self.rotors))
    }

    /// The row of vehicle `i`'s last step in `core`.
    ///
    /// # Errors
    /// A failed write.
    pub fn step_row<P: Pilot>(&mut self, core: &Lockstep<P>, i: usize) -> std::io::Result<()> {
        self.row(&core.last_step(i))
    }

    /// Write out what is buffered; the writer back.
    ///
    /// # Errors
    /// A failed write.
    pub fn finish(mut self) -> std::io::Result<W> {
        self.out.flush()?;
        Ok(self.out)
    }
}

/// The flight CSV's header line (`rotorpilot simulate --csv`) for `n` rotors.
#[must_use]
pub fn csv_header(n: usize) -> String {
    let mut h = String::from(
        "time_s,pos_n,pos_e,pos_d,vel_n,vel_e,vel_d,roll,pitch,yaw,roll_rate,pitch_rate,yaw_rate,p_frd,q_frd,r_frd,\
         true_pos_n,true_pos_e,true_pos_d,true_vel_n,true_vel_e,true_vel_d,ref_n,ref_e,ref_d,ref_yaw,\
         thrust_n,tau_x,tau_y,tau_z,cmd_thrust_n,cmd_tau_x,cmd_tau_y,cmd_tau_z,saturated",
    );
    for i in 1..=n {
        h.push_str(&format!(",w{i}"));
    }
    h.push_str(
        ",fext_n,fext_e,fext_d,text_x,text_y,text_z,true_mass_kg,est_fn,est_fe,est_fd,est_tx,est_ty,est_tz,est_mass_kg",
    );
    h
}

/// One step's line of the flight CSV (`rotorpilot simulate --csv`), for `n` rotors.
#[must_use]
pub fn csv_row(rec: &StepRecord<'_>, n: usize) -> String {
    let (m, r, w) = (rec.measurement, rec.control, rec.world);
    // the report's inputs exactly as the estimator derives them (eta, eta_dot = Q^-1 omega)
    let input = input_from(m, &r.applied);
    let (eta, eta_dot) = (input.eta, input.eta_dot);
    let mut v: Vec<f64> = Vec::with_capacity(64);
    v.push(m.time_s);
    v.extend(m.position_ned.iter());
    v.extend(m.velocity_ned.iter());
    v.extend(eta.iter());
    v.extend(eta_dot.iter());
    v.extend(m.rate_frd.iter());
    v.extend(w.truth.position_ned.iter());
    v.extend(w.truth.velocity_ned.iter());
    v.extend(r.reference.position_ned.iter());
    v.push(r.reference.yaw_rad);
    v.push(r.applied.thrust_n);
    v.extend(r.applied.torque_frd.iter());
    v.push(r.command.thrust_n);
    v.extend(r.command.torque_frd.iter());
    v.push(f64::from(u8::from(r.saturated)));
    v.extend(r.rotor_speed_cmd().iter().take(n));
    v.extend(w.external.force_ned.iter());
    v.extend(w.external.torque_frd.iter());
    v.push(w.true_mass_kg);
    v.extend(r.estimate.force_ned.iter());
    v.extend(r.estimate.torque_frd.iter());
    v.push(r.estimate.mass_kg);
    // `{}` prints the shortest text that parses back to the same f64: the log is exact.
    v.iter().map(|x| format!("{x}")).collect::<Vec<_>>().join(",")
}

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

/// A read log.
#[derive(Clone, Debug, PartialEq)]
pub struct FlightLog {
    /// Rows in time order.
    pub rows: Vec<LogRow>,
    /// The log's nominal step [s]: its first interval `t_1 - t_0` (every
    /// interval of a regular log, see [`crate::estimation::sweep::sample_steps`]).
    pub step_s: f64,
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
