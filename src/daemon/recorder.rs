//! The run's flight record (`flight.record`, [`crate::logs::record`]'s format)
//! and, with `--log-csv`, its flight CSV (`flight.csv`, the rows of
//! `rotorpilot simulate --csv`, one per step, with its sidecar
//! `flight.csv.meta.json`: what flew it, see [`crate::logs::meta::LogMeta`]),
//! written by the simulation thread. Every input reaches the core through
//! `Sim::apply` (`sim_thread.rs`), which records it here; each record line
//! is flushed as it is written, so a killed daemon leaves a record that replays up to its last input; a write that
//! fails (disk full, I/O error) cuts the file back to its last whole line
//! and ends the record there, so it still replays up to there. The CSV is
//! buffered (written out whenever 256 KiB are due, and at shutdown).

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

use anyhow::Context as _;
use tracing::warn;

use crate::airframe::Airframe;
use crate::autopilot::Autopilot;
use crate::lockstep::Lockstep;
use crate::lockstep::input::{Applied, Input};
use crate::logs::csv::{CsvLog, create_csv_file};
use crate::logs::record::{Header, end_line, header_line, input_line};
use crate::params::ParamStore;
use crate::sim::SensorConfig;

/// The record file's name in the run directory.
pub(super) const RECORD_FILE: &str = "flight.record";
/// The CSV file's name in the run directory.
pub(super) const CSV_FILE: &str = "flight.csv";

/// Writes the run's record and CSV.
pub(super) struct Recorder {
    /// The vehicle recorded (its index in the fleet).
    vehicle: usize,
    record: Option<LineFile<File>>,
    csv: Option<CsvLog<BufWriter<File>>>,
    /// The core's step count as last seen (for the end line).
    steps: u64,
}

impl std::fmt::Debug for Recorder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Recorder")
            .field("steps", &self.steps)
            .finish_non_exhaustive()
    }
}

impl Recorder {
    /// Start vehicle `vehicle`'s record in `dir` with the header of `core` at step 0, built
    /// with `sensors` (the value bind built `core` with: one source) (and
    /// the CSV with its header line when `csv`). The header is checked by
    /// rebuilding a core from it: a header that would not replay stops the start.
    ///
    /// # Errors
    /// A file that cannot be created or written (with its path), the
    /// airframe unreadable, a header that does not rebuild `core`.
    pub(super) fn create(
        dir: &Path,
        config: &super::Config,
        params: &ParamStore,
        sensors: SensorConfig,
        core: &mut Lockstep<Autopilot>,
        vehicle: usize,
    ) -> anyhow::Result<Self> {
        // the rebuilt core's one vehicle
        const VEHICLE: usize = 0;
        let (airframe, home, csv) = (&config.airframe, config.home, config.log_csv);
        let ap = core.pilot(vehicle);
        let header = Header::new(
            Airframe::load_text(airframe)?,
            home,
            params,
            ap.plans(),
            sensors,
            ap.client_clock(),
            core.dt_s(),
        );
        let (mut rebuilt, rebuilt_params) = header
            .build()
            .map_err(|e| anyhow::anyhow!("the flight record's header does not rebuild the vehicle: {e}"))?;
        if core.world().raw_sensors_enabled(vehicle) {
            // as replay rebuilds it for a ULog
            rebuilt.enable_raw_sensors(VEHICLE);
        }
        anyhow::ensure!(
            core.steps() == 0
                // as Debug text: a NaN in the telemetry equals itself there
                && format!("{:?}", rebuilt.snapshot(VEHICLE)) == format!("{:?}", core.snapshot(vehicle))
                && rebuilt_params.iter().eq(params.iter()),
            "the flight record's header does not rebuild the vehicle as it starts"
        );
        let path = dir.join(RECORD_FILE);
        let mut record =
            LineFile::new(File::create(&path).with_context(|| format!("--log-dir: cannot create {}", path.display()))?);
        record
            .append(&header_line(&header)?)
            .with_context(|| format!("writing {}", path.display()))?;
        let rotors = core.pilot(vehicle).airframe().rotor_count();
        let csv = if csv {
            let path = dir.join(CSV_FILE);
            let f = create_csv_file(&path).map_err(|e| anyhow::anyhow!("--log-csv: {e}"))?;
            crate::logs::meta::autopilot_meta(core.pilot(vehicle), "daemon --log-csv", &dir.display().to_string())
                .write_beside(&path)
                .map_err(|e| anyhow::anyhow!("--log-csv: {e}"))?;
            Some(CsvLog::new(f, rotors).with_context(|| format!("writing {}", path.display()))?)
        } else {
            None
        };
        Ok(Self {
            vehicle,
            record: Some(record),
            csv,
            steps: 0,
        })
    }

    /// After each step: the CSV row.
    pub(super) fn after_step(&mut self, core: &Lockstep<Autopilot>) {
        self.steps = core.steps();
        if let Some(l) = &mut self.csv
            && let Err(e) = l.step_row(core, self.vehicle)
        {
            warn!(error = %e, "cannot write {CSV_FILE}; the CSV stops here");
            self.csv = None;
        }
    }

    /// One input line, written out at once.
    pub(super) fn input(&mut self, step: u64, input: &Input, applied: &Applied) {
        self.steps = self.steps.max(step);
        let Some(f) = &mut self.record else { return };
        let line = input_line(step, input, &applied.text());
        if let Err(e) = line.map_err(std::io::Error::other).and_then(|l| f.append(&l)) {
            warn!(error = %e, "cannot write {RECORD_FILE}; the record stops here (it replays up to here)");
            self.record = None;
        }
    }
}

/// A file cut back to a length (a [`File`]'s `set_len`; a test's buffer).
trait Truncate {
    /// Cut to `len` bytes.
    fn truncate_to(&mut self, len: u64) -> std::io::Result<()>;
}

impl Truncate for File {
    fn truncate_to(&mut self, len: u64) -> std::io::Result<()> {
        self.set_len(len)
    }
}

/// A file written whole line by whole line: `whole` is the byte offset
/// after its last complete line. A write that fails mid-line cuts the file
/// back to `whole`, so it never ends in a partial line (which
/// [`crate::logs::record::read_record`] would refuse as cut short).
struct LineFile<F> {
    file: F,
    whole: u64,
}

impl<F: Write + Truncate> LineFile<F> {
    fn new(file: F) -> Self {
        Self { file, whole: 0 }
    }

    /// Append `line` and its `\n`; on failure cut back to the last whole
    /// line (the file is then not written to any more).
    fn append(&mut self, line: &str) -> std::io::Result<()> {
        let bytes = format!("{line}\n");
        match self.file.write_all(bytes.as_bytes()) {
            Ok(()) => {
                self.whole += bytes.len() as u64;
                Ok(())
            }
            Err(e) => {
                if let Err(t) = self.file.truncate_to(self.whole) {
                    warn!(error = %t, "cannot cut {RECORD_FILE} back to its last whole line");
                }
                Err(e)
            }
        }
    }
}

impl Drop for Recorder {
    /// At a clean stop: the end line and the rest of the CSV (not after a
    /// panic: a record without its end replays up to its last input).
    fn drop(&mut self) {
        if std::thread::panicking() {
            return;
        }
        if let Some(f) = &mut self.record
            && let Err(e) = f.append(&end_line(self.steps))
        {
            warn!(error = %e, "cannot end {RECORD_FILE}");
        }
        if let Some(l) = self.csv.take()
            && let Err(e) = l.finish()
        {
            warn!(error = %e, "cannot write {CSV_FILE}");
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geo::GeoPoint;

    /// A disk that fills up: takes `room` bytes, then fails.
    struct Filling {
        data: Vec<u8>,
        room: usize,
    }

    impl Write for Filling {
        fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
            let n = buf.len().min(self.room - self.data.len());
            if n == 0 {
                return Err(std::io::Error::other("no space left on device"));
            }
            self.data.extend_from_slice(&buf[..n]);
            Ok(n)
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    impl Truncate for Filling {
        fn truncate_to(&mut self, len: u64) -> std::io::Result<()> {
            self.data.truncate(len as usize);
            Ok(())
        }
    }

    #[test]
    fn a_write_failing_mid_line_leaves_whole_lines_that_replay() {
        let a = Airframe::load("quad").unwrap();
        let header = Header::new(
            Airframe::load_text("quad").unwrap(),
            GeoPoint::PX4_SITL_HOME,
            &ParamStore::new(&a),
            &crate::mission::Plans::default(),
            SensorConfig::default(),
            crate::autopilot::ClientClock::Simulated,
            crate::signals::DEFAULT_STEP_S,
        );
        let h = header_line(&header).unwrap();
        let beat = input_line(3, &Input::GcsHeartbeat, &Applied::GcsHeartbeat.text()).unwrap();
        // room for the header, one input and half of the next
        let room = h.len() + 1 + beat.len() + 1 + beat.len() / 2;
        let mut f = LineFile::new(Filling { data: Vec::new(), room });
        f.append(&h).unwrap();
        f.append(&beat).unwrap();
        assert!(f.append(&beat).is_err());
        let text = String::from_utf8(f.file.data).unwrap();
        assert_eq!(text, format!("{h}\n{beat}\n"));
        let r = crate::logs::record::read_record(&text, "full.record").unwrap();
        assert_eq!((r.inputs.len(), r.end), (1, None));
    }
}
