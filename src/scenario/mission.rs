//! Missions flown headless: `rotorpilot simulate` on a QGroundControl
//! `.plan`, a QGC WPL 110 file, or a scenario TOML with a `[mission]`
//! table. The flight stack flies it exactly as it does over MAVLink (the
//! same [`Autopilot`] in the same lockstep core, the items stored as a
//! client would upload them: global coordinates in degE7, as MAVSDK and
//! MAVProxy send them), flat out, and the run ends in a verdict.
//!
//! ```toml
//! airframe = "quad"            # built-in name or TOML path (default quad)
//! duration_s = 600             # the time limit [s] (default 1800)
//! home = [47.397742, 8.545594, 488.0]   # lat, lon [deg], alt AMSL [m] (default PX4's SITL home)
//! seed = 0                     # sensor noise seed ([noise] as in other scenarios)
//!
//! [params]                     # PX4 parameters by name
//! MPC_XY_CRUISE = 8.0
//!
//! [[fault]]                    # failures injected (see `scenario::fault`);
//! at_s = 30.0                  # SYS_FAILURE_EN is set to 1 unless [params] says
//! unit = "gps"
//! type = "off"
//!
//! [mission]
//! file = "survey.plan"         # relative to this file; or the items below
//! max_tracking_error_m = 3.0   # pass only below this (optional)
//!
//! [[mission.item]]             # MISSION_ITEM_INT's fields, x/y in degrees
//! command = 22                 # NAV_TAKEOFF
//! frame = 3                    # default: 3 with a position, else 2
//! params = [nan, nan, nan, nan]  # default all NaN (unset, as MAVSDK)
//! x = 47.397742
//! y = 8.545594
//! z = 10.0
//! ```
//!
//! The flight: the plans stored, the vehicle armed once its prearm checks
//! pass, MISSION_START from item 0 (pymavlink's `set_mode_auto`), stepped
//! until the mission is complete and the vehicle holds (or, when it ends
//! on the ground, is disarmed), or the time limit. **Pass** when the mission
//! completed, every positional item was reached, the vehicle stayed upright
//! and finite, a mission that lands ended disarmed on the ground, and the
//! tracking error (true position against the shaped reference, in the
//! air) stayed under `max_tracking_error_m` if given.

use std::io::Write;
use std::path::Path;

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use super::fault::{self, AppliedFault, FileFault, ScheduledFault};
use crate::airframe::Airframe;
use crate::autopilot::{Autopilot, AutopilotCommand, CommandOutcome, LandedState, MissionState};
use crate::geo::GeoPoint;
use crate::lockstep::Lockstep;
use crate::logs::csv::CsvLog;
pub use crate::logs::items::ItemResult;
use crate::logs::items::{ItemTally, item_lines};
use crate::logs::meta::LogMeta;
use crate::logs::report::{Collector, FlightReport, ReportMeta};
use crate::mission::file::{PlanFile, load_mission_file};
use crate::mission::{MissionItem, MissionType, PlanChange, cmd, frame, quantise_deg};
use crate::params::{ParamStore, ParamValue};
use crate::sim::{SensorConfig, SensorNoise};
use crate::tomlfile::{self, FileError};

/// Default time limit [s].
const DEFAULT_DURATION_S: f64 = 1800.0;
/// A mission that ends in the air is over this long [s] after it completes (to see it hold).
const SETTLE_S: f64 = 1.0;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    /// Default quad; its span places an error at its line.
    airframe: Option<toml::Spanned<String>>,
    #[serde(default = "default_duration")]
    duration_s: f64,
    home: Option<[f64; 3]>,
    #[serde(default)]
    seed: u64,
    #[serde(default)]
    noise: SensorNoise,
    /// With each name's span, for errors at its line.
    #[serde(default)]
    params: std::collections::BTreeMap<toml::Spanned<String>, toml::Value>,
    /// The air, as the `SIM_WIND_*` and `SIM_GUST_*` parameters it sets.
    wind: Option<crate::sim::WindSettings>,
    #[serde(default, rename = "fault")]
    faults: Vec<FileFault>,
    #[serde(default)]
    navigation: super::FileNavigation,
    mission: FileMission,
}

fn default_duration() -> f64 {
    DEFAULT_DURATION_S
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileMission {
    file: Option<String>,
    #[serde(default, rename = "item")]
    items: Vec<FileItem>,
    max_tracking_error_m: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileItem {
    command: u16,
    frame: Option<u8>,
    params: Option<[f32; 4]>,
    x: Option<f64>,
    y: Option<f64>,
    z: Option<f32>,
    #[serde(default = "yes")]
    autocontinue: bool,
}

fn yes() -> bool {
    true
}

/// A mission flight, ready to fly.
#[derive(Clone, Debug)]
pub struct MissionFlight {
    /// Where it came from (labels the summary).
    pub source: String,
    /// The vehicle.
    pub airframe: Airframe,
    /// Home and NED origin.
    pub home: GeoPoint,
    /// Parameters.
    pub params: ParamStore,
    /// Sensor noise and seed.
    pub sensors: SensorConfig,
    /// Mission, geofence and rally points, as a client would upload them.
    pub plans: PlanFile,
    /// Time limit [s].
    pub duration_s: f64,
    /// Pass only below this tracking error [m].
    pub max_tracking_error_m: Option<f64>,
    /// Failures injected, sorted by time (empty for a `.plan` or WPL file).
    pub faults: Vec<ScheduledFault>,
}

/// Whether `path` names a mission rather than a scenario: a `.plan`, a WPL
/// file, or a TOML with a `[mission]` table.
#[must_use]
pub fn is_mission(path: &Path) -> bool {
    match path.extension().and_then(|e| e.to_str()) {
        Some("toml") => std::fs::read_to_string(path)
            .ok()
            .and_then(|t| t.parse::<toml::Table>().ok())
            .is_some_and(|t| t.contains_key("mission")),
        _ => true,
    }
}

/// A global item's x/y as a client sends them (degE7, MISSION_ITEM_INT).
fn quantised(frame: u8, x: f64, y: f64) -> (f64, f64) {
    if frame::is_global(frame) {
        (quantise_deg(x), quantise_deg(y))
    } else {
        (x, y)
    }
}

impl MissionFlight {
    /// A `.plan` or WPL file flown on `quad` with default parameters, or a
    /// TOML mission flight.
    ///
    /// # Errors
    /// The file, the field and the problem.
    pub fn from_file(path: &Path) -> anyhow::Result<Self> {
        if path.extension().and_then(|e| e.to_str()) == Some("toml") {
            let text = tomlfile::read(path)?;
            return Self::from_toml(&text, &path.display().to_string(), path.parent());
        }
        let plans = load_mission_file(path)?;
        let airframe = Airframe::load("quad")?;
        Ok(Self {
            source: path.display().to_string(),
            params: ParamStore::new(&airframe),
            airframe,
            home: GeoPoint::PX4_SITL_HOME,
            sensors: SensorConfig::default(),
            plans,
            duration_s: DEFAULT_DURATION_S,
            max_tracking_error_m: None,
            faults: Vec::new(),
        })
    }

    /// A TOML mission flight (`file` labels errors, `dir` resolves relative paths).
    ///
    /// # Errors
    /// The file, the field and the problem.
    pub fn from_toml(text: &str, file: &str, dir: Option<&Path>) -> anyhow::Result<Self> {
        let raw: File = tomlfile::parse(text, file)?;
        let fail = |field: &str, problem: String| FileError::invalid(file, field, problem);
        let rel = |p: &str| match dir {
            Some(d) if !Path::new(p).is_absolute() => d.join(p),
            _ => Path::new(p).to_path_buf(),
        };
        // a problem at a key whose place is known: file:line:column: field: problem
        let fail_at =
            |at: usize, field: &str, problem: String| tomlfile::error_at(text, file, at, format!("{field}: {problem}"));
        let (name, airframe_at) = raw
            .airframe
            .as_ref()
            .map_or(("quad", 0), |a| (a.get_ref().as_str(), a.span().start));
        let airframe_spec = if name.ends_with(".toml") {
            rel(name).display().to_string()
        } else {
            name.to_string()
        };
        let airframe = Airframe::load(&airframe_spec).map_err(|e| fail_at(airframe_at, "airframe", e.to_string()))?;
        if !(raw.duration_s.is_finite() && raw.duration_s > 0.0 && raw.duration_s <= 86_400.0) {
            return Err(fail("duration_s", format!("must be in (0, 86400] s, got {}", raw.duration_s)).into());
        }
        let home = match raw.home {
            Some([lat_deg, lon_deg, alt_amsl_m]) => GeoPoint {
                lat_deg,
                lon_deg,
                alt_amsl_m,
            },
            None => GeoPoint::PX4_SITL_HOME,
        };
        if !home.is_valid() {
            return Err(fail("home", format!("{:?} is not a valid position", raw.home)).into());
        }
        let mut params = ParamStore::new(&airframe);
        raw.navigation.apply(&mut params);
        for (spanned, v) in &raw.params {
            let (name, at) = (spanned.get_ref(), spanned.span().start);
            let fail = |field: &str, problem: String| fail_at(at, field, problem);
            let value = match v {
                toml::Value::Integer(i) => ParamValue::Int32(
                    i32::try_from(*i).map_err(|_| fail(&format!("params.{name}"), "out of range".into()))?,
                ),
                toml::Value::Float(f) => ParamValue::Real32(*f as f32),
                _ => return Err(fail(&format!("params.{name}"), "must be a number".into()).into()),
            };
            // a float given for an integer parameter (or the reverse) is converted if exact
            let value = match (params.get(name).map(|(_, v)| v), value) {
                (Some(ParamValue::Int32(_)), ParamValue::Real32(f)) if f.fract() == 0.0 => ParamValue::Int32(f as i32),
                (Some(ParamValue::Real32(_)), ParamValue::Int32(i)) => ParamValue::Real32(i as f32),
                (_, v) => v,
            };
            params
                .set(name, value)
                .map_err(|e| fail(&format!("params.{name}"), e.to_string()))?;
        }
        if let Some(w) = &raw.wind {
            w.validate().map_err(|(f, p)| fail(&format!("wind.{f}"), p))?;
            for (name, v, field) in [
                ("SIM_WIND_SPD", w.speed_m_s, "speed_m_s"),
                ("SIM_WIND_DIR", w.from_deg, "from_deg"),
                ("SIM_WIND_DIR_Z", w.dir_z_deg, "dir_z_deg"),
                ("SIM_WIND_TURB", w.turbulence_m_s, "turbulence_m_s"),
                ("SIM_GUST_SPD", w.gust.speed_m_s, "gust.speed_m_s"),
                ("SIM_GUST_DIR", w.gust.from_deg, "gust.from_deg"),
                ("SIM_GUST_T0", w.gust.start_s, "gust.start_s"),
                ("SIM_GUST_DUR", w.gust.duration_s, "gust.duration_s"),
                ("SIM_GUST_PER", w.gust.period_s, "gust.period_s"),
            ] {
                params
                    .set(name, ParamValue::Real32(v as f32))
                    .map_err(|e| fail(&format!("wind.{field}"), e.to_string()))?;
            }
        }
        let faults = fault::validate(&raw.faults, raw.duration_s, &airframe).map_err(|(f, p)| fail(&f, p))?;
        if !faults.is_empty() && !raw.params.keys().any(|k| k.get_ref() == "SYS_FAILURE_EN") {
            // a scenario that injects failures allows them (PX4 needs it for MAV_CMD_INJECT_FAILURE)
            params
                .set("SYS_FAILURE_EN", ParamValue::Int32(1))
                .map_err(|e| fail("params.SYS_FAILURE_EN", e.to_string()))?;
        }
        let m = &raw.mission;
        let plans = match (&m.file, m.items.is_empty()) {
            (Some(_), false) => {
                return Err(fail("mission", "give either `file` or `[[mission.item]]`, not both".into()).into());
            }
            (Some(f), true) => load_mission_file(&rel(f))?,
            (None, true) => return Err(fail("mission", "no `file` and no `[[mission.item]]`".into()).into()),
            (None, false) => {
                let mut items = Vec::new();
                for (k, it) in m.items.iter().enumerate() {
                    let has_xy = it.x.is_some() || it.y.is_some();
                    let fr = it.frame.unwrap_or(if has_xy {
                        frame::GLOBAL_RELATIVE_ALT
                    } else {
                        frame::MISSION
                    });
                    let (x, y) = quantised(fr, it.x.unwrap_or(f64::NAN), it.y.unwrap_or(f64::NAN));
                    let item = MissionItem {
                        frame: fr,
                        command: it.command,
                        autocontinue: it.autocontinue,
                        params: it.params.unwrap_or([f32::NAN; 4]),
                        x,
                        y,
                        z: it.z.unwrap_or(0.0),
                    };
                    crate::mission::validate(MissionType::Mission, &item)
                        .map_err(|r| fail(&format!("mission.item[{k}]"), r.reason().to_string()))?;
                    items.push(item);
                }
                PlanFile {
                    mission: items,
                    ..PlanFile::default()
                }
            }
        };
        if plans.mission.is_empty() {
            return Err(fail("mission", "the mission has no items".into()).into());
        }
        if let Some(e) = m.max_tracking_error_m
            && !(e.is_finite() && e > 0.0)
        {
            return Err(fail("mission.max_tracking_error_m", format!("must be positive, got {e}")).into());
        }
        Ok(Self {
            source: file.to_string(),
            airframe,
            home,
            params,
            sensors: SensorConfig {
                noise: raw.noise,
                seed: raw.seed,
            },
            plans,
            duration_s: raw.duration_s,
            max_tracking_error_m: m.max_tracking_error_m,
            faults,
        })
    }
}

/// What `rotorpilot simulate` prints for a mission.
#[derive(Clone, Debug, Serialize)]
pub struct MissionSummary {
    /// The file flown.
    pub scenario: String,
    /// Airframe name.
    pub airframe: String,
    /// "pass" or "fail".
    pub verdict: &'static str,
    /// Why it failed (empty when it passed).
    pub reasons: Vec<String>,
    /// The mission completed.
    pub complete: bool,
    /// Per item.
    pub items: Vec<ItemResult>,
    /// From MISSION_START to the end of the flight [s].
    pub mission_time_s: f64,
    /// Simulated time [s].
    pub sim_time_s: f64,
    /// Wall time [s] (filled in by the caller).
    pub wall_time_s: f64,
    /// Max distance [m] from the shaped reference, in the air.
    pub max_tracking_error_m: f64,
    /// RMS distance [m] from the shaped reference, in the air.
    pub rms_tracking_error_m: f64,
    /// Final true position [m], NED.
    pub final_position_ned: [f64; 3],
    /// Ended disarmed on the ground.
    pub landed_and_disarmed: bool,
    /// Tilt below 90 degrees throughout.
    pub upright: bool,
    /// No NaN or infinity.
    pub finite: bool,
    /// The `[[fault]]`s applied, when and with what answer (absent when none).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub faults: Vec<AppliedFault>,
}

/// Whether a mission ends on the ground (its last item lands or returns).
fn ends_on_ground(items: &[MissionItem]) -> bool {
    items
        .iter()
        .rev()
        .find(|i| i.command != cmd::DO_JUMP && !cmd::NO_OPS.contains(&i.command) && i.command != cmd::DO_CHANGE_SPEED)
        .is_some_and(|i| matches!(i.command, cmd::NAV_LAND | cmd::NAV_RETURN_TO_LAUNCH))
}

/// The lockstep core with the flight's plans stored, at `t = 0`.
///
/// # Errors
/// Parameters the autopilot refuses, or a plan it refuses (with the item).
pub fn mission_lockstep(f: &MissionFlight) -> anyhow::Result<Lockstep<Autopilot>> {
    let mut core = Lockstep::one_vehicle(&f.airframe, f.home, &f.params, f.sensors)?;
    store_plans(&mut core, 0, f)?;
    Ok(core)
}

/// Store `f`'s mission, geofence and rally points in vehicle `i`'s autopilot,
/// as a client uploads them.
///
/// # Errors
/// A plan the autopilot refuses (with the item).
pub(super) fn store_plans(core: &mut Lockstep<Autopilot>, i: usize, f: &MissionFlight) -> anyhow::Result<()> {
    for (kind, items) in [
        (MissionType::Mission, &f.plans.mission),
        (MissionType::Fence, &f.plans.fence),
        (MissionType::Rally, &f.plans.rally),
    ] {
        if items.is_empty() {
            continue;
        }
        let stored = core.change_plans(
            i,
            PlanChange::Store {
                kind,
                items: items.clone(),
                base_id: None,
            },
        );
        if let Err(r) = stored {
            let said: Vec<String> = core.drain_status_texts(i).into_iter().map(|t| t.text).collect();
            anyhow::bail!(
                "{}: {} refused: {}",
                f.source,
                kind.name(),
                refusal(r.reason(), &said, &f.params)
            );
        }
    }
    Ok(())
}

/// Why a plan was refused, as a user wants it: the vehicle's own words
/// (which name the item and the parameter whose limit it broke), the
/// parameters they name with their values, then the MAV_MISSION_RESULT's
/// reason: `Plan rejected: item 3 at 12488 m > RP_ALT_MAX_AMSL
/// (RP_ALT_MAX_AMSL = 9000; invalid altitude / z)`.
fn refusal(reason: &str, said: &[String], params: &ParamStore) -> String {
    if said.is_empty() {
        return reason.to_string();
    }
    let mut named: Vec<String> = Vec::new();
    for word in said
        .iter()
        .flat_map(|t| t.split(|c: char| !(c.is_ascii_alphanumeric() || c == '_')))
    {
        if let Some((_, v)) = params.get(word) {
            let line = format!("{word} = {v}");
            if !named.contains(&line) {
                named.push(line);
            }
        }
    }
    named.push(reason.to_string());
    format!("{} ({})", said.join("; "), named.join("; "))
}

/// Fly the mission; `csv` receives the flight log (the format of
/// `rotorpilot simulate --csv`) when given.
///
/// # Errors
/// As [`mission_lockstep`], or a failed write to `csv`.
pub fn run_mission(f: &MissionFlight, csv: Option<&mut dyn Write>) -> anyhow::Result<MissionSummary> {
    run_mission_with(f, csv, None).map(|(s, _)| s)
}

/// [`run_mission`], also collecting the flight's report page
/// ([`crate::logs::report`]) when `report` gives its meta: the page's
/// verdict is the summary's (PASS/FAIL, reasons, items reached). The
/// collector only watches: the flight is the same to the bit.
///
/// # Errors
/// As [`run_mission`].
pub fn run_mission_with(
    f: &MissionFlight,
    csv: Option<&mut dyn Write>,
    report: Option<ReportMeta>,
) -> anyhow::Result<(MissionSummary, Option<FlightReport>)> {
    let mut core = mission_lockstep(f)?;
    let mut log = csv.map(|w| CsvLog::new(w, f.airframe.rotor_count())).transpose()?;
    let mut flight = MissionFlown::new(f, core.dt_s());
    let mut collector = report
        .as_ref()
        .map(|_| Collector::new(&core, 0, (f.duration_s / core.dt_s()).round() as u64));
    while !flight.is_over() {
        flight.before_step(&mut core, 0);
        core.step();
        flight.after_step(&mut core, 0, log.as_mut())?;
        if let Some(c) = &mut collector {
            super::run::watch_step(c, &mut core, 0);
        }
    }
    if let Some(l) = log {
        l.finish()?;
    }
    let summary = flight.summary(&mut core, 0);
    let page = collector
        .zip(report)
        .map(|(c, meta)| judged_page(c, &mut core, meta, &summary));
    Ok((summary, page))
}

/// The page `c` collected of a mission vehicle, with `summary`'s verdict:
/// PASS/FAIL, its reasons, and the items reached (the runner drained them:
/// its findings, first reach of each).
pub(super) fn judged_page<P: crate::logs::report::Watched>(
    mut c: Collector,
    core: &mut Lockstep<P>,
    meta: ReportMeta,
    summary: &MissionSummary,
) -> FlightReport {
    for r in &summary.items {
        if let Some(t) = r.reached_s {
            c.reached_at(r.seq, t, r.distance_m);
        }
    }
    let mut page = c.finish(core, meta);
    page.verdict.outcome = Some(summary.verdict.to_string());
    page.verdict.reasons.clone_from(&summary.reasons);
    page
}

/// A mission vehicle's flight as it goes, step by step: its `[[fault]]`s
/// injected through the flight stack when due, the mission started once
/// the prearm checks pass, the items reached and the tracking error
/// tallied, its log written, until the mission is over or the time limit;
/// then its [`MissionSummary`]. The same code judges a vehicle flown alone
/// ([`run_mission`]) and one of a fleet.
#[derive(Debug)]
pub(super) struct MissionFlown<'f> {
    f: &'f MissionFlight,
    /// Steps to fly at most: `round(duration / dt)`.
    steps: u64,
    /// Steps flown.
    k: u64,
    over: bool,
    items: ItemTally,
    lands: bool,
    started_s: Option<f64>,
    complete_s: Option<f64>,
    upright: bool,
    finite: bool,
    applied: Vec<AppliedFault>,
    next_fault: usize,
}

impl<'f> MissionFlown<'f> {
    /// Before the first step of `f`, stepped by `dt_s` [s].
    pub(super) fn new(f: &'f MissionFlight, dt_s: f64) -> Self {
        let items = &f.plans.mission;
        Self {
            f,
            steps: (f.duration_s / dt_s).round() as u64,
            k: 0,
            over: false,
            items: ItemTally::new(items, f.home),
            lands: ends_on_ground(items),
            started_s: None,
            complete_s: None,
            upright: true,
            finite: true,
            applied: Vec::new(),
            next_fault: 0,
        }
    }

    /// The flight is over (the mission done, the time limit, or a fault of the world).
    pub(super) fn is_over(&self) -> bool {
        self.over || self.k >= self.steps
    }

    /// Before the next step of vehicle `i`: the faults due now.
    pub(super) fn before_step(&mut self, core: &mut Lockstep<Autopilot>, i: usize) {
        let f = self.f;
        for sf in &f.faults[fault::due(&f.faults, &mut self.next_fault, core.time_s())] {
            // as a client injects it: through the flight stack's command
            self.applied.push(fault::apply(core, i, sf, |c, inj| {
                c.command(
                    i,
                    AutopilotCommand::InjectFailure {
                        unit: inj.unit,
                        kind: inj.kind,
                        instance: inj.instance,
                    },
                )
            }));
        }
    }

    /// After a step of vehicle `i`: log it, tally it, start the mission
    /// once it may, and see whether it is over.
    ///
    /// # Errors
    /// A failed write to `log`, or a mission that would not start.
    pub(super) fn after_step<W: Write>(
        &mut self,
        core: &mut Lockstep<Autopilot>,
        i: usize,
        log: Option<&mut CsvLog<W>>,
    ) -> anyhow::Result<()> {
        let f = self.f;
        self.k += 1;
        let rec = core.last_step(i);
        if let Some(l) = log {
            l.row(&rec)?;
        }
        let truth = rec.world.truth;
        self.upright &= (truth.attitude * Vector3::z()).z > 0.0;
        self.finite &= truth.position_ned.iter().all(|x| x.is_finite());
        if rec.world.fault.is_some() {
            self.finite = false;
            self.over = true;
            return Ok(());
        }
        self.items.after_step(core, i);
        let time_s = core.time_s();
        let armed = core.pilot(i).armed();
        let progress = core.pilot(i).mission_progress();
        if self.started_s.is_none() && !armed && core.telemetry(i).prearm_ok {
            match core.command(i, AutopilotCommand::StartMission { first: Some(0) }) {
                CommandOutcome::Accepted => self.started_s = Some(time_s),
                other => anyhow::bail!("{}: the mission would not start: {other:?}", f.source),
            }
        }
        if progress.state == MissionState::Complete && self.complete_s.is_none() {
            self.complete_s = Some(time_s);
        }
        if let Some(c) = self.complete_s {
            self.over = if self.lands { !armed } else { time_s - c >= SETTLE_S };
        }
        Ok(())
    }

    /// The summary and verdict of vehicle `i`'s flight (at its end).
    pub(super) fn summary(self, core: &mut Lockstep<Autopilot>, i: usize) -> MissionSummary {
        let f = self.f;
        let items = &f.plans.mission;
        let t = core.telemetry(i);
        let p = core.world().plant(i).state().position_ned;
        let complete = self.complete_s.is_some();
        let landed_and_disarmed = !t.armed && t.landed == LandedState::OnGround;
        let mut reasons = Vec::new();
        if !complete {
            reasons.push(format!(
                "the mission did not complete in {:.0} s (at item {} of {})",
                f.duration_s, t.mission.seq, t.mission.total
            ));
        }
        for r in self.items.results() {
            if r.reached_s.is_none() && items[usize::from(r.seq)].geo_point(t.home.alt_amsl_m).is_some() {
                reasons.push(format!("item {} (command {}) was never reached", r.seq, r.command));
            }
        }
        if self.lands && complete && !landed_and_disarmed {
            reasons.push("the mission ends on the ground but the vehicle did not land and disarm".into());
        }
        if !self.upright {
            reasons.push("the vehicle tipped over".into());
        }
        if !self.finite {
            reasons.push("the simulation stopped on a non-finite state".into());
        }
        let max_err = self.items.max_tracking_error_m();
        let rms_err = self.items.rms_tracking_error_m();
        if let Some(limit) = f.max_tracking_error_m
            && max_err > limit
        {
            reasons.push(format!("tracking error {max_err:.3} m above the limit {limit} m"));
        }
        MissionSummary {
            scenario: f.source.clone(),
            airframe: f.airframe.name.clone(),
            verdict: if reasons.is_empty() { "pass" } else { "fail" },
            reasons,
            complete,
            items: self.items.into_results(),
            mission_time_s: self.started_s.map_or(0.0, |s| t.time_s - s),
            sim_time_s: t.time_s,
            wall_time_s: 0.0,
            max_tracking_error_m: max_err,
            rms_tracking_error_m: rms_err,
            final_position_ned: [p.x, p.y, p.z],
            landed_and_disarmed,
            upright: self.upright,
            finite: self.finite,
            faults: self.applied,
        }
    }
}

impl MissionSummary {
    /// Human-readable rendering: one line per item, then the verdict.
    #[must_use]
    pub fn to_text(&self) -> String {
        let mut s = format!(
            "mission {} on {}: {} items, flew {:.1} s simulated ({:.1} s of mission) in {:.3} s wall\n",
            self.scenario,
            self.airframe,
            self.items.len(),
            self.sim_time_s,
            self.mission_time_s,
            self.wall_time_s
        );
        s.push_str(&item_lines(&self.items));
        s.push_str(&format!(
            "tracking error: max {:.3} m, RMS {:.3} m; final position {:.2?} m NED; landed and disarmed: {}\n",
            self.max_tracking_error_m, self.rms_tracking_error_m, self.final_position_ned, self.landed_and_disarmed
        ));
        for f in &self.faults {
            s.push_str(&format!("fault injected: {}\n", f.to_line()));
        }
        s.push_str(&format!("verdict: {}\n", self.verdict.to_uppercase()));
        for r in &self.reasons {
            s.push_str(&format!("  - {r}\n"));
        }
        s
    }
}

/// The sidecar ([`LogMeta`]) of a mission's flight CSV written by `producer`.
///
/// # Errors
/// A mission whose vehicle cannot be built (as flying it would say).
pub fn mission_meta(f: &MissionFlight, producer: &str) -> anyhow::Result<LogMeta> {
    let core = mission_lockstep(f)?;
    Ok(crate::logs::meta::autopilot_meta(core.pilot(0), producer, &f.source))
}
