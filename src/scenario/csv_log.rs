//! The flight CSV (`rotorpilot simulate --csv`, the daemon's `flight.csv`,
//! `rotorpilot replay --csv`): [`csv_header`], then one [`csv_row`] per
//! step. One writer for every producer, so their files agree byte for byte.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

use super::run::{csv_header, csv_row};
use super::{MissionFlight, Scenario};
use crate::autopilot::Autopilot;
use crate::flightlog::LogMeta;
use crate::lockstep::{Lockstep, StepRecord};

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
    pub fn step_row<P: crate::lockstep::Pilot>(&mut self, core: &Lockstep<P>, i: usize) -> std::io::Result<()> {
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

/// The sidecar ([`LogMeta`]) of a scenario's flight CSV written by `producer` (`simulate`).
#[must_use]
pub fn scenario_meta(s: &Scenario, producer: &str) -> LogMeta {
    LogMeta::new(
        producer,
        &s.source,
        &s.airframe.name,
        &s.airframe.nominal(),
        &s.estimator,
        s.step_s,
    )
}

/// The sidecar ([`LogMeta`]) of the flight CSV of `ap`'s vehicle, as it
/// flies now, written by `producer` from `source`.
#[must_use]
pub fn autopilot_meta(ap: &Autopilot, producer: &str, source: &str) -> LogMeta {
    let est = ap.estimator();
    LogMeta::new(
        producer,
        source,
        &ap.airframe().name,
        est.nominal(),
        est.config(),
        ap.dt_s(),
    )
}

/// The sidecar ([`LogMeta`]) of a mission's flight CSV written by `producer`.
///
/// # Errors
/// A mission whose vehicle cannot be built (as flying it would say).
pub fn mission_meta(f: &MissionFlight, producer: &str) -> anyhow::Result<LogMeta> {
    let core = super::mission::mission_lockstep(f)?;
    Ok(autopilot_meta(core.pilot(0), producer, &f.source))
}
