//! Headless fleets: several vehicles in one world, each flying its own
//! scenario (or mission) flat out on one clock, with vehicle–vehicle
//! proximity and collisions reported (`rotorpilot simulate FLEET.toml`).
//!
//! ```toml
//! [fleet]
//! proximity_m = 2.0       # report pairs closer than this [m] (and bodies that touch)
//! duration_s = 20.0       # optional: every vehicle flies this long (else each its own)
//!
//! [[vehicle]]
//! scenario = "../scenarios/figure-eight-geometric.toml"  # relative to this file
//! offset_m = [0.0, 0.0]   # its home (NED origin) in the world: north, east [m]
//!
//! [[vehicle]]
//! scenario = "vehicles/hover-2m.toml"
//! offset_m = [50.0, 0.0]
//! count = 98              # optional (default 1): copies k = 0..count,
//! spacing_m = [0.0, 10.0] # copy k at offset_m + k * spacing_m (north, east [m])
//! ```
//!
//! Vehicles are numbered from 0 in the order of the file (a block's copies
//! in turn). `count`, `offset_m` and `spacing_m` are read as the daemon's
//! fleet files read them ([`super::placement`]: one set of rules; without
//! `offset_m` a block starts 3 m north per vehicle number, without
//! `spacing_m` its copies are 3 m apart to the north, PX4's layout). Each keeps everything of its own file: reference or
//! setpoints, controller and switches, estimator, noise seed, disturbances,
//! `[[fault]]`s, mission and parameters, duration (unless `[fleet]` sets
//! one), and flies exactly as it would alone: its vehicle's flight in its own
//! NED frame is the same to the bit, only its place in the world differs
//! (`p_world = offset + p_own`, down ignored: one ground). A fleet is all
//! plain scenarios or all missions (one lockstep flies one kind of pilot);
//! the plain ones must share the step and the `[world]` environment (one clock,
//! one ground).
//!
//! The fleet is stepped until every vehicle's flight is over; a vehicle whose
//! flight is over (its duration, its mission, or a fault of the world) is
//! judged then, and keeps flying (its reference goes on as its formula
//! does, a mission vehicle as its autopilot does) so that it stays in the
//! others' way.

use std::fs::File as FsFile;
use std::io::BufWriter;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use toml::Spanned;

use super::campaign::Outcome;
use super::mission::MissionFlown;
use super::placement::{MAX_VEHICLES, Placement};
use super::run::{self, Flown};
use super::{MissionFlight, Scenario, is_mission, mission};
use crate::autopilot::Autopilot;
use crate::lockstep::{FleetVehicle, Lockstep, MOST_AHEAD, Pilot, StepRecord};
use crate::logs::csv::CsvLog;
use crate::logs::report::{Collector, FlightReport, ReportMeta, Watched};
use crate::sim::World;
use crate::sim::proximity::{ProximityEvent, ProximityKind};
use crate::tomlfile::{self, FileError};

pub mod encounters;

use encounters::Encounters;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileFleetTable {
    proximity_m: Spanned<f64>,
    duration_s: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileVehicle {
    scenario: Spanned<String>,
    offset_m: Option<Spanned<Vec<f64>>>,
    count: Option<Spanned<i64>>,
    spacing_m: Option<Spanned<Vec<f64>>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FleetFile {
    fleet: FileFleetTable,
    #[serde(default, rename = "vehicle")]
    vehicles: Vec<Spanned<FileVehicle>>,
}

/// The flights of a fleet: one kind of pilot per lockstep.
#[derive(Clone, Debug)]
pub enum FleetFlights {
    /// Plain scenarios (an analytic reference or setpoints, a bare control law).
    Plain(Vec<Scenario>),
    /// Missions flown by the flight stack.
    Mission(Vec<MissionFlight>),
}

/// A fleet ready to fly.
#[derive(Clone, Debug)]
pub struct Fleet {
    /// The fleet file.
    pub source: String,
    /// Pairs closer than this are reported [m].
    pub proximity_m: f64,
    /// Each vehicle's home in the world: north, east [m].
    pub offsets_m: Vec<[f64; 2]>,
    /// Each vehicle's flight (with `[fleet] duration_s` put in, if given).
    pub flights: FleetFlights,
}

/// Whether `path` is a fleet file (a TOML with a `[fleet]` table).
#[must_use]
pub fn is_fleet(path: &Path) -> bool {
    path.extension().and_then(|e| e.to_str()) == Some("toml")
        && std::fs::read_to_string(path)
            .ok()
            .and_then(|t| t.parse::<toml::Table>().ok())
            .is_some_and(|t| t.contains_key("fleet"))
}

impl Fleet {
    /// Number of vehicles.
    #[must_use]
    pub fn len(&self) -> usize {
        self.offsets_m.len()
    }

    /// Whether the fleet has no vehicle (never, once loaded).
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.offsets_m.is_empty()
    }

    /// Vehicle `i`'s file (labels its summary and log).
    #[must_use]
    pub fn source_of(&self, i: usize) -> &str {
        match &self.flights {
            FleetFlights::Plain(v) => &v[i].source,
            FleetFlights::Mission(v) => &v[i].source,
        }
    }

    /// Load a fleet file: errors name the file, the field with its line,
    /// and the problem; a vehicle's own file's errors are that file's.
    ///
    /// # Errors
    /// As said.
    pub fn load(path: &Path) -> anyhow::Result<Self> {
        let text = tomlfile::read(path)?;
        let file = path.display().to_string();
        let raw: FleetFile = tomlfile::parse(&text, &file)?;
        let at = |offset: usize, msg: String| -> anyhow::Error { tomlfile::error_at(&text, &file, offset, msg).into() };
        let p = *raw.fleet.proximity_m.get_ref();
        if !(p.is_finite() && p > 0.0) {
            return Err(at(
                raw.fleet.proximity_m.span().start,
                format!("fleet.proximity_m: must be a positive distance [m], got {p}"),
            ));
        }
        let duration = match &raw.fleet.duration_s {
            Some(d) => {
                let v = *d.get_ref();
                if !(v.is_finite() && v > 0.0 && v <= 86_400.0) {
                    return Err(at(
                        d.span().start,
                        format!("fleet.duration_s: must be in (0, 86400] s, got {v}"),
                    ));
                }
                Some(v)
            }
            None => None,
        };
        if raw.vehicles.is_empty() {
            return Err(FileError::invalid(&file, "vehicle", "no [[vehicle]]: a fleet needs at least one").into());
        }
        let dir = path.parent().unwrap_or(Path::new(""));
        let mut offsets_m = Vec::new();
        let mut plain: Vec<Scenario> = Vec::new();
        let mut missions: Vec<MissionFlight> = Vec::new();
        // (block, offset) of the first vehicle: its kind, step and world are the fleet's
        let mut first: Option<(usize, bool)> = None;
        for (k, v) in raw.vehicles.iter().enumerate() {
            let start = v.span().start;
            let v = v.get_ref();
            let field = |name: &str| format!("vehicle[{}].{name}", k + 1);
            let place = Placement::read(
                k + 1,
                offsets_m.len() as u64,
                v.count.as_ref(),
                v.offset_m.as_ref(),
                v.spacing_m.as_ref(),
            )
            .map_err(|(o, m)| at(o, m))?;
            let count = place.count();
            if offsets_m.len() + count > MAX_VEHICLES {
                return Err(at(
                    start,
                    format!("{}: more than {MAX_VEHICLES} vehicles", field("count")),
                ));
            }
            let rel = Path::new(v.scenario.get_ref());
            let sub: PathBuf = if rel.is_absolute() {
                rel.to_path_buf()
            } else {
                dir.join(rel)
            };
            let line = |msg: &str| at(v.scenario.span().start, format!("{}: {msg}", field("scenario")));
            if !sub.is_file() {
                return Err(line(&format!("{} is not a file", sub.display())));
            }
            if is_fleet(&sub) {
                return Err(line(&format!(
                    "{} is a fleet itself: list its vehicles here",
                    sub.display()
                )));
            }
            let mission = is_mission(&sub);
            let context = || format!("{file}: {} ({})", field("scenario"), v.scenario.get_ref());
            match first {
                None => first = Some((k, mission)),
                Some((k0, m0)) if m0 != mission => {
                    let kind = |m: bool| if m { "a mission" } else { "a plain scenario" };
                    return Err(line(&format!(
                        "{} is {} but vehicle[{}] is {}: a fleet is all plain scenarios or all missions",
                        sub.display(),
                        kind(mission),
                        k0 + 1,
                        kind(m0)
                    )));
                }
                Some(_) => {}
            }
            if mission {
                let mut f = MissionFlight::from_file(&sub).map_err(|e| e.context(context()))?;
                if let Some(d) = duration {
                    f.duration_s = d;
                }
                missions.extend(std::iter::repeat_n(f, count));
            } else {
                let mut s = Scenario::from_file(&sub).map_err(|e| anyhow::Error::new(e).context(context()))?;
                if let Some(d) = duration {
                    s.duration_s = d;
                }
                if let Some(s0) = plain.first() {
                    if s.step_s != s0.step_s {
                        return Err(line(&format!(
                            "its step_s {} differs from the fleet's {} (vehicle[1]): a fleet flies on one clock",
                            s.step_s, s0.step_s
                        )));
                    }
                    if s.world != s0.world {
                        return Err(line(&format!(
                            "its [world] differs from the fleet's (vehicle[1]'s {}): one world, one ground",
                            s0.source
                        )));
                    }
                }
                plain.extend(std::iter::repeat_n(s, count));
            }
            offsets_m.extend((0..count).map(|c| place.spawn(c)));
        }
        let flights = if missions.is_empty() {
            FleetFlights::Plain(plain)
        } else {
            FleetFlights::Mission(missions)
        };
        Ok(Self {
            source: file,
            proximity_m: p,
            offsets_m,
            flights,
        })
    }
}

/// A proximity event of a fleet's flight.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct FleetEvent {
    /// Simulated time after the step that raised it [s].
    pub time_s: f64,
    /// The lower vehicle index.
    pub a: usize,
    /// The higher vehicle index.
    pub b: usize,
    /// Their distance [m] then: the threshold just crossed.
    pub distance_m: f64,
    /// `near` or `collision`.
    pub kind: ProximityKind,
    /// The encounter's closest approach [m]: the least distance between
    /// the two (centre to centre) from this event until they are apart
    /// again (beyond the reporting distance x 1.1) or the flight ends.
    pub closest_m: f64,
    /// When it came [s] (simulated time after its step).
    pub closest_s: f64,
}

impl From<(f64, ProximityEvent)> for FleetEvent {
    fn from((time_s, e): (f64, ProximityEvent)) -> Self {
        Self {
            time_s,
            a: e.a,
            b: e.b,
            distance_m: e.distance_m,
            kind: e.kind,
            closest_m: e.distance_m,
            closest_s: time_s,
        }
    }
}

/// One vehicle's result in a fleet's summary.
#[derive(Clone, Debug, Serialize)]
pub struct VehicleResult {
    /// Its index.
    pub vehicle: usize,
    /// Its home in the world: north, east [m].
    pub offset_m: [f64; 2],
    /// Its summary, as if flown alone.
    #[serde(flatten)]
    pub outcome: Outcome,
}

/// What `rotorpilot simulate FLEET.toml` prints.
#[derive(Clone, Debug, Serialize)]
pub struct FleetSummary {
    /// The fleet file.
    pub fleet: String,
    /// Number of vehicles.
    pub vehicles: usize,
    /// Threads stepping them.
    pub threads: usize,
    /// Lockstep steps (every vehicle stepped in each).
    pub steps: u64,
    /// Simulated time [s].
    pub sim_time_s: f64,
    /// Vehicle steps: `steps * vehicles`.
    pub vehicle_steps: u64,
    /// Wall time [s] (filled in by the caller, which owns the clock).
    pub wall_time_s: f64,
    /// `vehicle_steps / wall_time_s` (filled in with the wall time).
    pub vehicle_steps_per_s: f64,
    /// `sim_time_s / wall_time_s` (filled in with the wall time).
    pub real_time_factor: f64,
    /// The reporting distance [m].
    pub proximity_m: f64,
    /// The proximity events, in order.
    pub events: Vec<FleetEvent>,
    /// Per vehicle, in index order.
    pub results: Vec<VehicleResult>,
}

impl FleetSummary {
    /// Fill in the wall time [s] and the rates derived from it.
    pub fn set_wall_time_s(&mut self, wall_s: f64) {
        self.wall_time_s = wall_s;
        let w = wall_s.max(1e-9);
        self.vehicle_steps_per_s = self.vehicle_steps as f64 / w;
        self.real_time_factor = self.sim_time_s / w;
        for r in &mut self.results {
            r.outcome.set_wall_time_s(wall_s);
        }
    }

    /// `false` when a mission vehicle failed its verdict.
    #[must_use]
    pub fn passed(&self) -> bool {
        self.results.iter().all(|r| r.outcome.passed())
    }

    /// Human-readable: a header, one line per vehicle, one per event.
    #[must_use]
    pub fn to_text(&self) -> String {
        let mut s = format!(
            "fleet {}: {} vehicles, flew {:.3} s simulated in {:.3} s wall on {} threads \
             ({:.0} vehicle-steps/s, {:.2}x real time)\n",
            self.fleet,
            self.vehicles,
            self.sim_time_s,
            self.wall_time_s,
            self.threads,
            self.vehicle_steps_per_s,
            self.real_time_factor
        );
        let width = self.vehicles.max(2).saturating_sub(1).to_string().len();
        for r in &self.results {
            let name = match &r.outcome {
                Outcome::Scenario(x) => &x.scenario,
                Outcome::Mission(x) => &x.scenario,
            };
            s.push_str(&format!(
                "{:>width$} {name} at [{}, {}] m: {}\n",
                r.vehicle,
                r.offset_m[0],
                r.offset_m[1],
                r.outcome.to_line()
            ));
        }
        let collisions = self
            .events
            .iter()
            .filter(|e| e.kind == ProximityKind::Collision)
            .count();
        s.push_str(&format!(
            "proximity (closer than {} m): {}, {}\n",
            self.proximity_m,
            count(self.events.len(), "event", "events"),
            count(collisions, "collision", "collisions")
        ));
        for e in &self.events {
            s.push_str(&format!(
                "  t = {:.3} s: vehicles {} and {} {} (at {:.3} m); closest approach {:.3} m at t = {:.3} s\n",
                e.time_s,
                e.a,
                e.b,
                e.kind.name(),
                e.distance_m,
                e.closest_m,
                e.closest_s
            ));
        }
        s
    }
}

/// A fleet vehicle's CSV file's write buffer [bytes] (small: a fleet keeps
/// one open per vehicle).
const FLEET_CSV_BUFFER_BYTES: usize = 32 * 1024;

/// Vehicle `i`'s CSV file name in a fleet's `--csv` directory:
/// `NNNN-STEM.csv`, NNNN its index zero-padded to the width of the last.
#[must_use]
pub fn csv_name(i: usize, n: usize, source: &str) -> String {
    let width = n.max(2).saturating_sub(1).to_string().len();
    let stem = Path::new(source)
        .file_stem()
        .map_or_else(|| "vehicle".into(), |s| s.to_string_lossy().into_owned());
    format!("{i:0width$}-{stem}.csv")
}

/// A vehicle's CSV log in a fleet.
type Log = CsvLog<BufWriter<FsFile>>;

/// A vehicle's flight as it goes ([`Flown`], [`MissionFlown`]).
trait Track<P: Pilot>: Send {
    fn is_over(&self) -> bool;
    fn before_step(&mut self, core: &mut Lockstep<P>, i: usize);
    /// How many of the next steps (at least 1, at most `most`) vehicle `i`'s
    /// flight needs nothing of the core for but [`Self::before_step`]
    /// before the first, nor [`Self::after_step`] after any: a flight
    /// that ends within them is judged after them, from what it kept at
    /// its end.
    fn steps_alone(&self, core: &Lockstep<P>, i: usize, most: u64) -> u64;
    /// The steps left until the flight ends at the latest.
    fn steps_left(&self) -> u64;
    /// The flight was over once the core had taken `steps` steps.
    fn over_by(&self, steps: u64) -> bool;
    /// After the vehicle's step, with its own record alone: run on the
    /// thread that stepped it, beside the other vehicles' steps.
    fn after_own_step(&mut self, pilot: &P, rec: &StepRecord<'_>, log: Option<&mut Log>) -> anyhow::Result<()>;
    /// After the step of every vehicle, with the whole core (in vehicle order).
    fn after_step(&mut self, core: &mut Lockstep<P>, i: usize, log: Option<&mut Log>) -> anyhow::Result<()>;
    fn outcome(self, core: &mut Lockstep<P>, i: usize) -> Outcome;
}

/// A plain scenario's flight is judged from its own record alone: all of
/// it on the stepping threads.
impl<'a> Track<run::ScenarioPilot<'a>> for Flown {
    fn is_over(&self) -> bool {
        Flown::is_over(self)
    }
    fn before_step(&mut self, core: &mut Lockstep<run::ScenarioPilot<'a>>, i: usize) {
        Flown::before_step(self, core, i);
    }
    fn steps_alone(&self, core: &Lockstep<run::ScenarioPilot<'a>>, i: usize, most: u64) -> u64 {
        Flown::steps_alone(self, core, i, most)
    }
    fn steps_left(&self) -> u64 {
        Flown::steps_left(self)
    }
    fn over_by(&self, steps: u64) -> bool {
        Flown::over_by(self, steps)
    }
    fn after_own_step(
        &mut self,
        pilot: &run::ScenarioPilot<'a>,
        rec: &StepRecord<'_>,
        log: Option<&mut Log>,
    ) -> anyhow::Result<()> {
        Ok(Flown::after_step(self, pilot, rec, log)?)
    }
    fn after_step(
        &mut self,
        _core: &mut Lockstep<run::ScenarioPilot<'a>>,
        _i: usize,
        _log: Option<&mut Log>,
    ) -> anyhow::Result<()> {
        Ok(())
    }
    fn outcome(self, core: &mut Lockstep<run::ScenarioPilot<'a>>, i: usize) -> Outcome {
        Outcome::Scenario(Box::new(self.summary(core, i)))
    }
}

/// A mission's flight asks its autopilot and starts its mission: all of it
/// with the whole core.
impl Track<Autopilot> for MissionFlown<'_> {
    fn is_over(&self) -> bool {
        MissionFlown::is_over(self)
    }
    fn before_step(&mut self, core: &mut Lockstep<Autopilot>, i: usize) {
        MissionFlown::before_step(self, core, i);
    }
    fn steps_alone(&self, _core: &Lockstep<Autopilot>, _i: usize, _most: u64) -> u64 {
        1
    }
    // stepped one step at a time (`steps_alone`): the next step may be its last
    fn steps_left(&self) -> u64 {
        1
    }
    fn over_by(&self, _steps: u64) -> bool {
        MissionFlown::is_over(self)
    }
    fn after_own_step(
        &mut self,
        _pilot: &Autopilot,
        _rec: &StepRecord<'_>,
        _log: Option<&mut Log>,
    ) -> anyhow::Result<()> {
        Ok(())
    }
    fn after_step(&mut self, core: &mut Lockstep<Autopilot>, i: usize, log: Option<&mut Log>) -> anyhow::Result<()> {
        MissionFlown::after_step(self, core, i, log)
    }
    fn outcome(self, core: &mut Lockstep<Autopilot>, i: usize) -> Outcome {
        Outcome::Mission(Box::new(self.summary(core, i)))
    }
}

/// One vehicle's flight in a fleet: its track until it is judged, its log
/// until closed, and the error its own step's work met (if any).
struct Lane<T> {
    track: Option<T>,
    log: Option<Log>,
    failed: Option<anyhow::Error>,
}

/// A vehicle's report page as it is collected, and the meta it will carry.
type Watch = Option<(Collector, ReportMeta)>;

/// What [`fly_tracks`] gives: the outcomes, the events, the steps, the pages.
type FleetFlown = (Vec<Outcome>, Vec<FleetEvent>, u64, Vec<FlightReport>);

/// Step `core` until every track is over; each vehicle judged when its
/// flight ends, its log closed and its page (when watched) finished then.
/// The outcomes, the events, the steps, the pages (in vehicle order).
fn fly_tracks<P: Watched, T: Track<P>>(
    core: &mut Lockstep<P>,
    tracks: Vec<T>,
    logs: Vec<Option<Log>>,
    mut watches: Vec<Watch>,
) -> anyhow::Result<FleetFlown> {
    let n = tracks.len();
    let mut lanes: Vec<Lane<T>> = tracks
        .into_iter()
        .zip(logs)
        .map(|(t, log)| Lane {
            track: Some(t),
            log,
            failed: None,
        })
        .collect();
    let mut outcomes: Vec<Option<Outcome>> = vec![None; n];
    let mut pages: Vec<Option<FlightReport>> = vec![None; n];
    let mut events = Vec::new();
    let mut encounters = Encounters::default();
    let mut running = n;
    // a flight over before its first step (a zero duration) is judged at once
    for i in 0..n {
        if lanes[i].track.as_ref().is_some_and(Track::is_over) {
            finish(core, i, &mut lanes[i], &mut outcomes)?;
            pages[i] = page(core, &mut watches[i], outcomes[i].as_ref());
            running -= 1;
        }
    }
    while running > 0 {
        for (i, lane) in lanes.iter_mut().enumerate() {
            if let Some(t) = &mut lane.track {
                t.before_step(core, i);
            }
        }
        // as many steps as every flight flies alone, none past the last
        // one's end (one while a page watches every step)
        let running_tracks = || {
            lanes
                .iter()
                .enumerate()
                .filter_map(|(i, l)| Some((i, l.track.as_ref()?)))
        };
        let ahead = if watches.iter().any(Option::is_some) {
            1
        } else {
            let alone = running_tracks().map(|(i, t)| t.steps_alone(core, i, MOST_AHEAD)).min();
            let left = running_tracks().map(|(_, t)| t.steps_left()).max();
            alone.unwrap_or(1).min(left.unwrap_or(1)).max(1)
        };
        core.step_ahead(
            ahead as usize,
            &mut lanes,
            |lane, pilot, rec| {
                // a flight over within the steps ahead is judged after them
                if let Some(t) = &mut lane.track
                    && !t.is_over()
                    && lane.failed.is_none()
                    && let Err(e) = t.after_own_step(pilot, &rec, lane.log.as_mut())
                {
                    lane.failed = Some(e);
                }
            },
            |core, lanes| {
                for (t, e) in core.drain_proximity_events() {
                    encounters.open(t, e);
                }
                events.extend(encounters.follow(core));
                // the clock stops where the last flight ended (on a fault, that
                // may be inside the steps ahead)
                let steps = core.steps();
                if lanes.iter().all(|l| l.track.as_ref().is_none_or(|t| t.over_by(steps))) {
                    ControlFlow::Break(())
                } else {
                    ControlFlow::Continue(())
                }
            },
        );
        for i in 0..n {
            let lane = &mut lanes[i];
            if let Some(e) = lane.failed.take() {
                return Err(e);
            }
            let Some(t) = &mut lane.track else { continue };
            t.after_step(core, i, lane.log.as_mut())?;
            if let Some((c, _)) = &mut watches[i] {
                run::watch_step(c, core, i);
            }
            if lanes[i].track.as_ref().is_some_and(Track::is_over) {
                finish(core, i, &mut lanes[i], &mut outcomes)?;
                pages[i] = page(core, &mut watches[i], outcomes[i].as_ref());
                running -= 1;
            }
        }
    }
    events.extend(encounters.finish());
    // in the order they were raised: by time, then by pair (a pair rises
    // at most once a step)
    events.sort_by(|x, y| x.time_s.total_cmp(&y.time_s).then((x.a, x.b).cmp(&(y.a, y.b))));
    Ok((
        outcomes.into_iter().flatten().collect(),
        events,
        core.steps(),
        pages.into_iter().flatten().collect(),
    ))
}

/// Vehicle `i`'s page, now that its flight is judged (`outcome`): a
/// mission's with its verdict.
fn page<P: Watched>(core: &mut Lockstep<P>, watch: &mut Watch, outcome: Option<&Outcome>) -> Option<FlightReport> {
    let (c, meta) = watch.take()?;
    Some(match outcome {
        Some(Outcome::Mission(m)) => mission::judged_page(c, core, meta, m),
        _ => c.finish(core, meta),
    })
}

/// `n` and the noun, singular for one: `1 event`, `2 events`.
#[must_use]
pub fn count(n: usize, one: &str, many: &str) -> String {
    format!("{n} {}", if n == 1 { one } else { many })
}

/// Judge vehicle `i` (its `lane`) now and close its log.
fn finish<P: Pilot, T: Track<P>>(
    core: &mut Lockstep<P>,
    i: usize,
    lane: &mut Lane<T>,
    outcomes: &mut [Option<Outcome>],
) -> anyhow::Result<()> {
    if let Some(t) = lane.track.take() {
        outcomes[i] = Some(t.outcome(core, i));
    }
    if let Some(l) = lane.log.take() {
        l.finish()?;
    }
    Ok(())
}

/// Fly `fleet` on `threads` threads ([`Lockstep::set_threads`]: the same
/// bits on any number); with `csv_dir`, vehicle `i`'s log (the bytes
/// `rotorpilot simulate --csv` writes for its file alone) goes to
/// `csv_dir/`[`csv_name`]. The summary's wall time is left for the caller.
///
/// # Errors
/// A vehicle that cannot start (its file named), a log that cannot be
/// written, the threads that cannot start.
pub fn fly(fleet: &Fleet, threads: usize, csv_dir: Option<&Path>) -> anyhow::Result<FleetSummary> {
    fly_with(fleet, threads, csv_dir, None).map(|(summary, _)| summary)
}

/// [`fly`], also collecting every vehicle's report page when `report`
/// gives the meta they share: each page titled with its vehicle's number
/// and file, in vehicle order. The collectors only watch: every vehicle
/// flies the same to the bit.
///
/// # Errors
/// As [`fly`].
pub fn fly_with(
    fleet: &Fleet,
    threads: usize,
    csv_dir: Option<&Path>,
    report: Option<&ReportMeta>,
) -> anyhow::Result<(FleetSummary, Vec<FlightReport>)> {
    let n = fleet.len();
    let meta_of = |i: usize| {
        report.map(|m| ReportMeta {
            title: format!("vehicle {i} of {}: {}", fleet.source, fleet.source_of(i)),
            source: fleet.source_of(i).to_string(),
            ..m.clone()
        })
    };
    let mut logs = Vec::with_capacity(n);
    for i in 0..n {
        logs.push(match csv_dir {
            Some(d) => {
                let path = d.join(csv_name(i, n, fleet.source_of(i)));
                let f = FsFile::create(&path).map_err(|e| anyhow::anyhow!("cannot create {}: {e}", path.display()))?;
                let rotors = match &fleet.flights {
                    FleetFlights::Plain(v) => v[i].airframe.rotor_count(),
                    FleetFlights::Mission(v) => v[i].airframe.rotor_count(),
                };
                let meta = match &fleet.flights {
                    FleetFlights::Plain(v) => super::scenario_meta(&v[i], "simulate"),
                    FleetFlights::Mission(v) => super::mission_meta(&v[i], "simulate")?,
                };
                meta.write_beside(&path).map_err(anyhow::Error::msg)?;
                Some(CsvLog::new(
                    BufWriter::with_capacity(FLEET_CSV_BUFFER_BYTES, f),
                    rotors,
                )?)
            }
            None => None,
        });
    }
    let place = |world: &mut World| {
        for (i, o) in fleet.offsets_m.iter().enumerate() {
            world.set_origin_ned(i, nalgebra::Vector3::new(o[0], o[1], 0.0));
        }
    };
    let (outcomes, events, steps, dt, pages) = match &fleet.flights {
        FleetFlights::Plain(list) => {
            let s0 = &list[0];
            let mut world = World::new(s0.step_s, s0.world);
            let mut pilots = Vec::with_capacity(n);
            for s in list {
                run::add_vehicle(&mut world, s);
                pilots.push(run::pilot(s)?);
            }
            place(&mut world);
            let mut core = Lockstep::new(world, pilots);
            for i in 0..n {
                run::place(&mut core, i);
            }
            prepare(&mut core, fleet.proximity_m, threads)?;
            let tracks = list.iter().map(Flown::new).collect();
            let dt = core.dt_s();
            let watches = list
                .iter()
                .enumerate()
                .map(|(i, s)| {
                    let steps = (s.duration_s / s.step_s).round() as u64;
                    meta_of(i).map(|m| (Collector::new(&core, i, steps), m))
                })
                .collect();
            core.threads()
                .run(|| fly_tracks(&mut core, tracks, logs, watches))
                .map(|(o, e, s, p)| (o, e, s, dt, p))?
        }
        FleetFlights::Mission(list) => {
            let vehicles: Vec<FleetVehicle<'_>> = list
                .iter()
                .map(|f| FleetVehicle {
                    airframe: &f.airframe,
                    home: f.home,
                    params: &f.params,
                    sensors: f.sensors,
                })
                .collect();
            let mut core = Lockstep::fleet(list[0].home, &vehicles)
                .map_err(|(i, e)| anyhow::anyhow!("{}: vehicle {i}: {e}", list[i].source))?;
            // each home where the fleet file puts it (not where its latitude and longitude would)
            place(core.world_mut());
            for (i, f) in list.iter().enumerate() {
                mission::store_plans(&mut core, i, f)?;
            }
            prepare(&mut core, fleet.proximity_m, threads)?;
            let dt = core.dt_s();
            let tracks = list.iter().map(|f| MissionFlown::new(f, dt)).collect();
            let watches = list
                .iter()
                .enumerate()
                .map(|(i, f)| {
                    let steps = (f.duration_s / dt).round() as u64;
                    meta_of(i).map(|m| (Collector::new(&core, i, steps), m))
                })
                .collect();
            core.threads()
                .run(|| fly_tracks(&mut core, tracks, logs, watches))
                .map(|(o, e, s, p)| (o, e, s, dt, p))?
        }
    };
    let summary = FleetSummary {
        fleet: fleet.source.clone(),
        vehicles: n,
        threads: threads.max(1),
        steps,
        sim_time_s: steps as f64 * dt,
        vehicle_steps: steps * n as u64,
        wall_time_s: 0.0,
        vehicle_steps_per_s: 0.0,
        real_time_factor: 0.0,
        proximity_m: fleet.proximity_m,
        events,
        results: outcomes
            .into_iter()
            .enumerate()
            .map(|(i, outcome)| VehicleResult {
                vehicle: i,
                offset_m: fleet.offsets_m[i],
                outcome,
            })
            .collect(),
    };
    Ok((summary, pages))
}

/// Watch proximity and set the threads.
fn prepare<P: Pilot>(core: &mut Lockstep<P>, proximity_m: f64, threads: usize) -> anyhow::Result<()> {
    core.watch_proximity(proximity_m);
    core.set_threads(threads)
        .map_err(|e| anyhow::anyhow!("cannot start {threads} threads: {e}"))
}
