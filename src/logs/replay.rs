//! Exact replay (`rotorpilot replay`): rebuild the core from a record's
//! header, step it, applying each recorded input at its step through
//! [`crate::lockstep::input::apply`] (as the daemon applied it live), and
//! write the flight's CSV and ULog as the daemon writes them.

use std::io::Write;

use super::csv::CsvLog;
use super::items::{ItemResult, ItemTally};
use super::record::Record;
use super::report::{Collector, FlightReport, ReportMeta};
use super::ulog::flight::FlightUlog;
use crate::autopilot::Autopilot;
use crate::lockstep::Lockstep;
use crate::lockstep::input::apply;
use crate::mission::MissionType;
use crate::params::ParamStore;

/// What a replay did.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ReplaySummary {
    /// Steps run.
    pub steps: u64,
    /// Simulated time at the end [s].
    pub sim_time_s: f64,
    /// Inputs applied.
    pub inputs: usize,
    /// Whether the record had its end line (else it ran to its last input).
    pub complete: bool,
    /// Armed at the end.
    pub armed: bool,
    /// Flight mode at the end.
    pub mode: String,
    /// Landed state at the end.
    pub landed_state: String,
    /// True position at the end, NED [m].
    pub position_ned_m: [f64; 3],
    /// The items of the last mission stored (as `simulate` reports them:
    /// reached, ran, never reached, never ran), tallied from when it was
    /// stored (from the start for the mission the vehicle started with).
    pub items: Vec<ItemResult>,
    /// Max distance [m] from the shaped reference, in the air.
    pub max_tracking_error_m: f64,
    /// RMS distance [m] from the shaped reference, in the air.
    pub rms_tracking_error_m: f64,
}

/// Re-fly `record`: rebuild the core from the header, step it, applying
/// each input at its step, up to the end line's step (or the last input's
/// when the record has no end); `csv` receives the flight CSV ([`CsvLog`]:
/// `rotorpilot simulate --csv`'s format, one row per step).
///
/// # Errors
/// A header this rotorpilot cannot rebuild; an input whose outcome differs
/// from the live one (the replay diverged); a failed CSV write.
pub fn replay(record: &Record, file: &str, csv: Option<&mut dyn Write>) -> Result<ReplaySummary, String> {
    replay_logs(record, file, csv, None)
}

/// The logs a replay writes as it steps.
struct ReplayLogs<'a> {
    csv: Option<CsvLog<&'a mut dyn Write>>,
    ulog: Option<FlightUlog<&'a mut dyn Write>>,
    /// The report page's data, when one is wanted.
    report: Option<Collector>,
    /// Steps run (the parameters are looked at every [`PARAM_CHECK_EVERY`]).
    steps: u64,
    generation: u64,
    /// The mission's items as flown, and its plan id (a new mission restarts the tally).
    items: ItemTally,
    mission_id: u32,
    home: crate::geo::GeoPoint,
}

/// Steps between two looks at the parameters for the ULog (0.1 s at 1 kHz),
/// as the daemon's `flight.ulg` looks.
pub const PARAM_CHECK_EVERY: u64 = 100;

impl ReplayLogs<'_> {
    /// After a step, as the daemon's simulation thread: the CSV row, the
    /// parameters if they changed, the ULog's topics, the status texts
    /// (each dated at the instant the core raised it, as the daemon dates them).
    fn after_step(&mut self, core: &mut Lockstep<Autopilot>, params: &ParamStore) -> Result<(), String> {
        self.steps += 1;
        if let Some(l) = &mut self.csv {
            l.step_row(core, 0).map_err(|e| format!("writing the CSV: {e}"))?;
        }
        let mission = core.pilot(0).plans().get(MissionType::Mission);
        if mission.id() != self.mission_id {
            self.mission_id = mission.id();
            self.items = ItemTally::new(mission.items(), self.home);
        }
        // reads (and drains) the item events: the queues do not steer the flight
        let done = self.items.after_step(core, 0);
        if let Some(r) = &mut self.report {
            r.after_step(core);
        }
        if self.ulog.is_none() && self.report.is_none() {
            if core.steps().is_multiple_of(1024) {
                // as the daemon publishes: the queues do not steer the flight
                let _ = core.drain_status_texts(0);
            }
            return Ok(());
        }
        let ue = |e: std::io::Error| format!("writing the ULog: {e}");
        let texts = core.drain_stamped_status_texts(0);
        if let Some(r) = &mut self.report {
            r.texts(&texts);
            let t = core.time_s();
            for seq in ItemTally::reached_seqs(&done) {
                r.reached_at(seq, t, self.items.distance_m(core, 0, seq));
            }
        }
        if let Some(u) = &mut self.ulog {
            if self.steps.is_multiple_of(PARAM_CHECK_EVERY) && params.generation() != self.generation {
                self.generation = params.generation();
                u.parameters(params).map_err(ue)?;
            }
            u.on_step(core, 0).map_err(ue)?;
            for (time_s, t) in &texts {
                u.status_text(*time_s, t).map_err(ue)?;
            }
        }
        Ok(())
    }

    /// At the last step: the status texts its inputs announced (the
    /// daemon publishes them as it stops; no step follows to log them).
    fn last_texts(&mut self, core: &mut Lockstep<Autopilot>) -> Result<(), String> {
        if self.ulog.is_none() && self.report.is_none() {
            return Ok(());
        }
        let texts = core.drain_stamped_status_texts(0);
        if let Some(r) = &mut self.report {
            r.texts(&texts);
        }
        if let Some(u) = &mut self.ulog {
            for (time_s, t) in &texts {
                u.status_text(*time_s, t)
                    .map_err(|e| format!("writing the ULog: {e}"))?;
            }
        }
        Ok(())
    }
}

/// [`replay`], also writing the flight's PX4 ULog to `ulog`
/// ([`FlightUlog`], the topics and rates of the daemon's `flight.ulg`).
///
/// # Errors
/// As [`replay`]; a failed ULog write.
pub fn replay_logs<'a>(
    record: &Record,
    file: &str,
    csv: Option<&'a mut dyn Write>,
    ulog: Option<&'a mut dyn Write>,
) -> Result<ReplaySummary, String> {
    replay_into(record, file, csv, ulog, None).map(|(s, _)| s)
}

/// The flight report page's data ([`super::report`]) of `record`, by
/// exact replay: the core's full state at every step, downsampled for the
/// page. `meta` names the page (its airframe is filled in here).
///
/// # Errors
/// As [`replay`].
pub fn replay_report(record: &Record, file: &str, mut meta: ReportMeta) -> Result<FlightReport, String> {
    let (core, _) = record.header.build().map_err(|e| format!("{file}:1: header: {e}"))?;
    let end = record.end.unwrap_or_else(|| record.inputs.last().map_or(0, |e| e.step));
    meta.airframe.clone_from(&core.pilot(0).airframe().name);
    let collector = Collector::new(&core, 0, end);
    let (_, report) = replay_into(record, file, None, None, Some(collector))?;
    report
        .map(|(r, mut core)| r.finish(&mut core, meta))
        .ok_or_else(|| "no report".to_string())
}

/// The summary, and the collector with the core at the end when one was given.
type Replayed = (ReplaySummary, Option<(Collector, Lockstep<Autopilot>)>);

/// Replay writing the logs asked for and collecting the report's data.
fn replay_into<'a>(
    record: &Record,
    file: &str,
    csv: Option<&'a mut dyn Write>,
    ulog: Option<&'a mut dyn Write>,
    report: Option<Collector>,
) -> Result<Replayed, String> {
    let (mut core, mut params) = record.header.build().map_err(|e| format!("{file}:1: header: {e}"))?;
    if ulog.is_some() {
        // the ULog logs the raw sensors, as the daemon's did
        core.enable_raw_sensors(0);
    }
    let n = core.pilot(0).airframe().rotor_count();
    let mut logs = ReplayLogs {
        csv: csv
            .map(|w| CsvLog::new(w, n))
            .transpose()
            .map_err(|e| format!("writing the CSV: {e}"))?,
        ulog: ulog
            .map(|w| FlightUlog::new(w, &params, &core, 0))
            .transpose()
            .map_err(|e| format!("writing the ULog: {e}"))?,
        report,
        steps: 0,
        generation: params.generation(),
        items: ItemTally::new(&record.header.mission, record.header.home),
        mission_id: core.pilot(0).plans().get(MissionType::Mission).id(),
        home: record.header.home,
    };
    let end = record.end.unwrap_or_else(|| record.inputs.last().map_or(0, |e| e.step));
    let step_to = |core: &mut Lockstep<Autopilot>, params: &ParamStore, target: u64, logs: &mut ReplayLogs<'_>| {
        while core.steps() < target {
            core.step();
            logs.after_step(core, params)?;
        }
        Ok::<(), String>(())
    };
    for e in &record.inputs {
        step_to(&mut core, &params, e.step, &mut logs)?;
        let got = apply(&mut core, 0, &mut params, &e.input).text();
        if got != e.outcome {
            return Err(format!(
                "{file}:{}: the replay diverged at step {}: live outcome {}, replayed {got}",
                e.line, e.step, e.outcome
            ));
        }
        if let Some(r) = &mut logs.report {
            r.watch_plans(&core);
        }
    }
    step_to(&mut core, &params, end, &mut logs)?;
    logs.last_texts(&mut core)?;
    if let Some(l) = logs.csv {
        l.finish().map_err(|e| format!("writing the CSV: {e}"))?;
    }
    if let Some(u) = logs.ulog {
        u.finish().map_err(|e| format!("writing the ULog: {e}"))?;
    }
    let ap = core.pilot(0);
    let p = core.last_step(0).world.truth.position_ned;
    let (max_tracking_error_m, rms_tracking_error_m) =
        (logs.items.max_tracking_error_m(), logs.items.rms_tracking_error_m());
    let summary = ReplaySummary {
        steps: core.steps(),
        sim_time_s: core.time_s(),
        inputs: record.inputs.len(),
        complete: record.end.is_some(),
        armed: ap.armed(),
        mode: format!("{:?}", ap.mode()),
        landed_state: format!("{:?}", ap.landed_state()),
        position_ned_m: [p.x, p.y, p.z],
        items: logs.items.into_results(),
        max_tracking_error_m,
        rms_tracking_error_m,
    };
    Ok((summary, logs.report.map(|r| (r, core))))
}
