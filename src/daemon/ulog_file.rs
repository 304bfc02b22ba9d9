//! The run's `flight.ulg`: [`crate::logs::ulog::flight::FlightUlog`] on a
//! buffered file, fed by the simulation thread after every step and with
//! every status text. The buffer reaches the file when full, at least every
//! [`FLUSH_EVERY`] of wall time while the simulation steps (as PX4's logger
//! writes continuously, so a log being written is listed by LOG_ENTRY and
//! MAVLink FTP with the size it has on disk, and that much downloads), and
//! when the simulation thread ends (drop). A write error stops the log with
//! one warning; the flight goes on.

use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use tracing::warn;

use super::messages::lock;
use crate::autopilot::{Autopilot, StatusText};
use crate::lockstep::Lockstep;
use crate::logs::ulog::flight::FlightUlog;
use crate::params::ParamStore;

/// The file name in the run directory.
pub(super) const FILE_NAME: &str = "flight.ulg";

/// The longest wall time the buffer keeps what it was given.
const FLUSH_EVERY: Duration = Duration::from_secs(1);
/// Steps between two looks at the wall clock for [`FLUSH_EVERY`].
const FLUSH_CHECK_EVERY: u64 = 50;

/// The ULog of vehicle `vehicle`, written to `flight.ulg`.
#[derive(Debug)]
pub(super) struct UlogFile {
    log: Option<FlightUlog<BufWriter<File>>>,
    path: PathBuf,
    vehicle: usize,
    /// The daemon's parameters, looked at every `PARAM_CHECK_EVERY` steps
    /// for changes (logged as PX4 logs a change in flight).
    params: Arc<Mutex<ParamStore>>,
    generation: u64,
    steps: u64,
    /// When the buffer last went to the file (wall clock).
    flushed: Instant,
}

/// Steps between two looks at the parameters' generation (0.1 s): the
/// replay's, so that `rotorpilot replay --ulog` logs the changes alike.
use crate::logs::replay::PARAM_CHECK_EVERY;

impl UlogFile {
    /// Start `dir/flight.ulg` (header, formats, info, parameters); `None`
    /// with a warning if it cannot be written.
    pub(super) fn create(
        dir: &Path,
        params: &Arc<Mutex<ParamStore>>,
        core: &Lockstep<Autopilot>,
        vehicle: usize,
    ) -> Option<Self> {
        let path = dir.join(FILE_NAME);
        let store = lock(params).clone();
        let started = File::create(&path).and_then(|f| {
            // held while the ULog is written: LOG_ERASE (of any daemon
            // sharing the --log-dir) leaves a locked ULog alone
            if let Err(e) = f.try_lock() {
                warn!(path = %path.display(), error = %e, "cannot lock the ULog against LOG_ERASE");
            }
            FlightUlog::new(BufWriter::with_capacity(256 * 1024, f), &store, core, vehicle)
        });
        match started {
            Ok(log) => Some(Self {
                log: Some(log),
                path,
                vehicle,
                params: params.clone(),
                generation: store.generation(),
                steps: 0,
                flushed: Instant::now(),
            }),
            Err(e) => {
                warn!(path = %path.display(), error = %e, "cannot write the ULog; flying without it");
                None
            }
        }
    }

    fn check(&mut self, r: std::io::Result<()>) {
        if let Err(e) = r {
            warn!(path = %self.path.display(), error = %e, "ULog write failed; the ULog stops here");
            self.log = None;
        }
    }

    /// After a step of the core.
    fn on_step(&mut self, core: &mut Lockstep<Autopilot>) {
        self.steps += 1;
        if self.steps.is_multiple_of(PARAM_CHECK_EVERY) {
            let store = lock(&self.params);
            if store.generation() != self.generation {
                self.generation = store.generation();
                let r = self.log.as_mut().map_or(Ok(()), |l| l.parameters(&store));
                drop(store);
                self.check(r);
            }
        }
        if let Some(log) = &mut self.log {
            let r = log.on_step(core, self.vehicle);
            self.check(r);
        }
        if self.steps.is_multiple_of(FLUSH_CHECK_EVERY) && self.flushed.elapsed() >= FLUSH_EVERY {
            self.flushed = Instant::now();
            let r = self.log.as_mut().map_or(Ok(()), FlightUlog::flush);
            self.check(r);
        }
    }

    /// A status text announced at the core's current time.
    fn status_text(&mut self, time_s: f64, text: &StatusText) {
        if let Some(log) = &mut self.log {
            let r = log.status_text(time_s, text);
            self.check(r);
        }
    }
}

/// The simulation thread's hook after each step (nothing without a ULog).
pub(super) fn after_step(log: &mut Option<UlogFile>, core: &mut Lockstep<Autopilot>) {
    if let Some(l) = log {
        l.on_step(core);
    }
}

/// The simulation thread's hook for the status texts it publishes: drain
/// vehicle `vehicle`'s texts from the core, log each at the simulated time
/// it was raised ([`Lockstep::drain_stamped_status_texts`]), not at the
/// drain's (up to a batch of steps later), and hand them back for the links.
pub(super) fn drain_status_texts(
    log: &mut Option<UlogFile>,
    core: &mut Lockstep<Autopilot>,
    vehicle: usize,
) -> Vec<StatusText> {
    let texts = core.drain_stamped_status_texts(vehicle);
    texts
        .into_iter()
        .map(|(t, s)| {
            status_text(log, t, &s);
            s
        })
        .collect()
}

/// The simulation thread's hook for each status text it publishes.
pub(super) fn status_text(log: &mut Option<UlogFile>, time_s: f64, text: &StatusText) {
    if let Some(l) = log {
        l.status_text(time_s, text);
    }
}

impl Drop for UlogFile {
    fn drop(&mut self) {
        if let Some(Err(e)) = self.log.take().map(FlightUlog::finish) {
            warn!(path = %self.path.display(), error = %e, "ULog: the last writes failed");
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::autopilot::{AutopilotCommand, CommandOutcome};

    /// The ULog's logged strings (`L` messages) as (timestamp [us], text).
    fn logged_strings(b: &[u8]) -> Vec<(u64, String)> {
        crate::logs::ulog::messages(b)
            .into_iter()
            .filter(|(kind, _)| *kind == b'L')
            .map(|(_, body)| {
                let t = u64::from_le_bytes(body[1..9].try_into().unwrap());
                (t, String::from_utf8_lossy(&body[9..]).into_owned())
            })
            .collect()
    }

    #[test]
    fn a_status_text_is_logged_at_the_step_it_was_raised_not_when_drained() {
        let (mut core, store) = crate::lockstep::test_quad();
        let dir = crate::statefile::scratch_dir("ulog-stamp");
        let params = Arc::new(Mutex::new(store));
        let mut log = UlogFile::create(&dir, &params, &core, 0);
        assert!(log.is_some());
        let step = |core: &mut Lockstep<Autopilot>, log: &mut Option<UlogFile>, n: u32| {
            for _ in 0..n {
                core.step();
                after_step(log, core);
            }
        };
        step(&mut core, &mut log, 1234);
        let _ = drain_status_texts(&mut log, &mut core, 0);
        // raised between steps 1234 and 1235, at t = 1.234 s
        let arm_us = 1_234_000;
        assert_eq!(
            core.command(0, AutopilotCommand::Arm { force: true }),
            CommandOutcome::Accepted
        );
        // drained 2 s of simulated time later, as a slow batch would
        step(&mut core, &mut log, 2000);
        let texts = drain_status_texts(&mut log, &mut core, 0);
        assert!(texts.iter().any(|s| s.text == "Armed by external command"), "{texts:?}");
        drop(log);
        let logged = logged_strings(&std::fs::read(dir.join(FILE_NAME)).unwrap());
        std::fs::remove_dir_all(&dir).unwrap();
        let armed: Vec<_> = logged
            .iter()
            .filter(|(_, s)| s == "Armed by external command")
            .collect();
        assert_eq!(armed.len(), 1, "{logged:?}");
        assert!(
            armed[0].0.abs_diff(arm_us) <= 1,
            "logged at {} us, raised at {arm_us} us",
            armed[0].0
        );
    }
}
