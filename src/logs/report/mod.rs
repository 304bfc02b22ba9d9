//! The flight report page (`rotorpilot report`): one self-contained HTML
//! file that shows a flight: the verdict (items reached and when, the
//! largest tracking error, failsafes, failures injected), the north/east
//! path with the mission items, geofence and rally points, altitude, speed
//! and attitude over time, the flight modes and arming as a timeline, every
//! status text at its instant, the rotor speeds, and the estimator's force,
//! torque and mass beside the injected truth.
//!
//! Two halves, both pure: a [`Collector`] watches a lockstep core step by
//! step (an exact replay of a flight record,
//! `replay_report` of the replay module, or a headless
//! `simulate` flight: a mission's flight stack or a plain scenario's bare
//! control law, any pilot that is [`Watched`]) and gives a [`FlightReport`],
//! the page's data; a
//! ULog gives the same data from its topics ([`from_ulog`]); [`html::page`]
//! renders it into a `String` with its JavaScript and CSS inlined (uPlot, at
//! the version `tools/vendor_report_assets.sh` pins), so the page opens
//! offline.
//!
//! The time series are downsampled to at most [`MAX_SAMPLES`] instants
//! (every `k`-th step, `k` at least [`MIN_STRIDE_STEPS`]); the verdict's
//! figures (tracking error, items, modes, texts) are taken at every step.

pub mod html;
mod ulog_source;

pub use ulog_source::from_ulog;

use nalgebra::Vector3;
use serde::Serialize;

use crate::autopilot::{Autopilot, LandedState, Severity, StatusText};
use crate::control::Reference;
use crate::geo::GeoPoint;
use crate::lockstep::{Lockstep, Pilot};
use crate::mission::{MissionItem, MissionType, Plans, cmd};
use crate::signals::ActuatorCommand;

/// The most instants a time series keeps (a 10-minute flight at 10 Hz).
pub const MAX_SAMPLES: u64 = 6000;
/// The shortest interval between two samples, in 1 ms steps (50 Hz).
pub const MIN_STRIDE_STEPS: u64 = 20;

/// The columns of the time series, in order (the rotor speeds `w1`.. follow).
/// Frames: positions, velocities and the force NED [m, m/s, N]; torques FRD
/// [N m]; angles ZYX Euler [deg]; `err` the distance from the tracked
/// reference [m]; `battery` the remaining charge 0..1.
pub const COLUMNS: [&str; 32] = [
    "n",
    "e",
    "d",
    "ref_n",
    "ref_e",
    "ref_d",
    "est_d",
    "vh",
    "vd",
    "ref_vh",
    "roll",
    "pitch",
    "yaw",
    "roll_sp",
    "pitch_sp",
    "yaw_sp",
    "err",
    "f_n",
    "f_e",
    "f_d",
    "tf_n",
    "tf_e",
    "tf_d",
    "tq_x",
    "tq_y",
    "tq_z",
    "ttq_x",
    "ttq_y",
    "ttq_z",
    "mass",
    "true_mass",
    "battery",
];

/// Time series on one time base: `t` [s] and one column per name.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Series {
    /// Simulated time [s].
    pub t: Vec<f64>,
    /// Column names ([`COLUMNS`], then `w1`.. the rotor speeds).
    pub names: Vec<String>,
    /// One vector per name, as long as `t` (NaN: no value then).
    pub columns: Vec<Vec<f64>>,
    /// What the rotor columns hold: `rad/s` (from a record) or `0..1`
    /// (a ULog's `actuator_motors`: thrust over full thrust).
    pub rotor_unit: String,
}

impl Series {
    fn new(rotors: usize, rotor_unit: &str) -> Self {
        let mut names: Vec<String> = COLUMNS.iter().map(|s| (*s).to_string()).collect();
        names.extend((1..=rotors).map(|k| format!("w{k}")));
        Self {
            t: Vec::new(),
            columns: vec![Vec::new(); names.len()],
            names,
            rotor_unit: rotor_unit.into(),
        }
    }

    /// The column `name` (empty when there is none).
    #[must_use]
    pub fn column(&self, name: &str) -> &[f64] {
        self.names
            .iter()
            .position(|n| n == name)
            .map_or(&[], |k| self.columns[k].as_slice())
    }

    /// Append one instant: `values` in the order of `names`.
    fn push(&mut self, t: f64, values: &[f64]) {
        self.t.push(t);
        for (c, v) in self.columns.iter_mut().zip(values) {
            c.push(*v);
        }
    }
}

/// A span of the timeline: `label` from `from_s` to `to_s` [s].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Span {
    /// Start [s].
    pub from_s: f64,
    /// End [s].
    pub to_s: f64,
    /// The mode's name, or `armed` / `disarmed`.
    pub label: String,
}

/// What an event is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum EventKind {
    /// A failsafe came in force: the flight stack's failsafe state (PX4's
    /// `vehicle_status.failsafe`) turned on, or its cause changed; the text is the cause.
    Failsafe,
    /// A failure was injected (`CMD_INJECT_FAILURE...`).
    Failure,
    /// A mission item was reached.
    Reached,
    /// Any other status text.
    Text,
}

/// Something that happened at an instant.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Event {
    /// When [s].
    pub t_s: f64,
    /// What.
    pub kind: EventKind,
    /// MAVLink severity name (`Info`, `Warning`, ...).
    pub severity: String,
    /// The text.
    pub text: String,
}

impl Event {
    /// A status text at `t_s`: a failure injected (the injection's
    /// `CMD_INJECT_FAILURE`) or a text. A failsafe is never known from
    /// words: [`Self::failsafe`] takes it from the flight stack's state.
    #[must_use]
    pub fn from_text(t_s: f64, severity: Severity, text: &str) -> Self {
        let kind = if text.starts_with("CMD_INJECT_FAILURE") {
            EventKind::Failure
        } else {
            EventKind::Text
        };
        Self {
            t_s,
            kind,
            severity: format!("{severity:?}"),
            text: text.into(),
        }
    }
}

impl Event {
    /// A failsafe in force from `t_s` for `cause`, the vehicle then in `mode`.
    #[must_use]
    pub fn failsafe(t_s: f64, cause: &str, mode: &str) -> Self {
        Self {
            t_s,
            kind: EventKind::Failsafe,
            severity: "Critical".into(),
            text: format!("{cause} ({mode})"),
        }
    }
}

/// One mission item on the path, north/east from the origin [m].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PlanPoint {
    /// MAVLink seq.
    pub seq: u16,
    /// MAV_CMD.
    pub command: u16,
    /// North [m].
    pub n: f64,
    /// East [m].
    pub e: f64,
    /// Altitude above the origin [m] (up).
    pub alt_m: f64,
}

/// A geofence shape, north/east [m].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FenceShape {
    /// Inside is allowed (inclusion) or forbidden (exclusion).
    pub inclusion: bool,
    /// Polygon vertices, or the circle's centre alone.
    pub points: Vec<[f64; 2]>,
    /// A circle's radius [m] (`None`: a polygon).
    pub radius_m: Option<f64>,
}

/// The plans drawn on the path.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct PlanView {
    /// The mission's items, positional ones only.
    pub mission: Vec<PlanPoint>,
    /// Every item of the mission (for the verdict's list): seq and MAV_CMD.
    pub commands: Vec<u16>,
    /// Geofence shapes.
    pub fence: Vec<FenceShape>,
    /// Rally points, north/east [m].
    pub rally: Vec<[f64; 2]>,
}

impl PlanView {
    /// `plans` around `origin` (north/east from it, altitude above it).
    #[must_use]
    pub fn new(plans: &Plans, origin: GeoPoint) -> Self {
        let at = |it: &MissionItem| {
            it.geo_point(origin.alt_amsl_m).map(|g| {
                let ned = g.ned_from(&origin);
                (ned.x, ned.y, -ned.z)
            })
        };
        let items = plans.get(MissionType::Mission).items();
        let mission = items
            .iter()
            .enumerate()
            .filter_map(|(k, it)| {
                at(it).map(|(n, e, alt_m)| PlanPoint {
                    seq: u16::try_from(k).unwrap_or(u16::MAX),
                    command: it.command,
                    n,
                    e,
                    alt_m,
                })
            })
            .collect();
        let fence_items = plans.get(MissionType::Fence).items();
        let mut fence = Vec::new();
        let mut k = 0;
        while k < fence_items.len() {
            let it = &fence_items[k];
            let inclusion = matches!(
                it.command,
                cmd::FENCE_POLYGON_VERTEX_INCLUSION | cmd::FENCE_CIRCLE_INCLUSION
            );
            match it.command {
                cmd::FENCE_POLYGON_VERTEX_INCLUSION | cmd::FENCE_POLYGON_VERTEX_EXCLUSION => {
                    // param1: the polygon's vertex count; its vertices follow in order
                    let count = (it.params[0] as usize).max(1).min(fence_items.len() - k);
                    let points = fence_items[k..k + count]
                        .iter()
                        .filter_map(|v| at(v).map(|(n, e, _)| [n, e]))
                        .collect();
                    fence.push(FenceShape {
                        inclusion,
                        points,
                        radius_m: None,
                    });
                    k += count;
                }
                cmd::FENCE_CIRCLE_INCLUSION | cmd::FENCE_CIRCLE_EXCLUSION => {
                    if let Some((n, e, _)) = at(it) {
                        fence.push(FenceShape {
                            inclusion,
                            points: vec![[n, e]],
                            radius_m: Some(f64::from(it.params[0])),
                        });
                    }
                    k += 1;
                }
                _ => k += 1,
            }
        }
        let rally = plans
            .get(MissionType::Rally)
            .items()
            .iter()
            .filter_map(|it| at(it).map(|(n, e, _)| [n, e]))
            .collect();
        Self {
            mission,
            commands: items.iter().map(|it| it.command).collect(),
            fence,
            rally,
        }
    }

    fn is_empty(&self) -> bool {
        self.mission.is_empty() && self.commands.is_empty() && self.fence.is_empty() && self.rally.is_empty()
    }
}

/// One mission item in the verdict.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ItemRow {
    /// MAVLink seq.
    pub seq: u16,
    /// MAV_CMD.
    pub command: u16,
    /// When first reached [s] (`None`: never reported reached).
    pub reached_s: Option<f64>,
    /// How often it was reached (DO_JUMP loops).
    pub times: u32,
    /// Distance [m] from the true position to the item's point when first
    /// reached (relative altitudes above home: the summaries' "m off").
    pub distance_m: Option<f64>,
}

/// The header's verdict.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Verdict {
    /// `pass` / `fail` when a judge gave one (`simulate`'s mission verdict).
    pub outcome: Option<String>,
    /// Why it failed.
    pub reasons: Vec<String>,
    /// The mission's items, reached or not.
    pub items: Vec<ItemRow>,
    /// The largest distance [m] from the tracked reference in the air, and when [s].
    pub max_tracking_error: Option<(f64, f64)>,
    /// Which part of the flight that maximum counts, as the header words it
    /// (a flight record: flying, takeoff and landing excluded, as the
    /// mission summary counts it; a ULog: not landed).
    pub tracking_counted: &'static str,
    /// How long a rotor command sat at a limit in the air: `None` without
    /// rotors (ideal actuation) or never in the air.
    pub rotor_limit: Option<RotorLimit>,
    /// Armed, mode and landed state at the end.
    pub final_state: String,
}

/// A rotor command at a limit while in the air: the rotors cannot give the
/// wrench the controller asked for (a thrust or torque lost to saturation).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct RotorLimit {
    /// Share of the time in the air with a rotor command at a limit, 0..1.
    pub share: f64,
    /// The first such instant [s].
    pub first_s: Option<f64>,
    /// What counts as a limit, as the header words it.
    pub counted: &'static str,
}

/// Where a report's data came from and what to call it.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ReportMeta {
    /// The page's title: the test's name when a test made the flight, else the file.
    pub title: String,
    /// The test that flew it (the pytest plugin's node id), if any.
    pub test: Option<String>,
    /// The file the report was made from.
    pub source: String,
    /// How it was read: `record (exact replay)`, `ULog`, `simulate`.
    pub method: String,
    /// The airframe's name.
    pub airframe: String,
    /// The rotorpilot that made the flight.
    pub rotorpilot: String,
    /// The command that reproduces the flight, if there is one.
    pub reproduce: Option<String>,
    /// What the source could not give (e.g. a ULog has no mission items).
    pub notes: Vec<String>,
}

/// Everything the page shows.
#[derive(Clone, Debug, Default, Serialize)]
pub struct FlightReport {
    /// Where from.
    pub meta: ReportMeta,
    /// Simulated time at the end [s].
    pub duration_s: f64,
    /// The header's verdict.
    pub verdict: Verdict,
    /// The plans drawn on the path (the last non-empty ones in force).
    pub plans: PlanView,
    /// The time series.
    pub series: Series,
    /// Flight modes over time.
    pub modes: Vec<Span>,
    /// Armed / disarmed over time.
    pub arming: Vec<Span>,
    /// Every event, in time order.
    pub events: Vec<Event>,
}

/// A running timeline: the label in force since `from_s`.
#[derive(Debug, Default)]
struct Timeline {
    spans: Vec<Span>,
}

impl Timeline {
    fn at(&mut self, t_s: f64, label: &str) {
        match self.spans.last_mut() {
            Some(s) if s.label == label => s.to_s = t_s,
            Some(s) => {
                s.to_s = t_s;
                self.spans.push(Span {
                    from_s: t_s,
                    to_s: t_s,
                    label: label.into(),
                });
            }
            None => self.spans.push(Span {
                from_s: t_s,
                to_s: t_s,
                label: label.into(),
            }),
        }
    }
}

/// ZYX Euler angles [deg] of a quaternion (FRD to NED).
fn euler_deg(q: &nalgebra::UnitQuaternion<f64>) -> [f64; 3] {
    let (r, p, y) = q.euler_angles();
    [r.to_degrees(), p.to_degrees(), y.to_degrees()]
}

/// A pilot's state as the page shows it (timeline, verdict).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PilotState {
    /// The rotors may run.
    pub armed: bool,
    /// The flight mode's name (a bare control law: its controller's).
    pub mode: String,
    /// Flying, neither taking off nor landing (the header's tracking error
    /// counts only then, as the mission summary's does; the plot shows it
    /// whenever a reference is tracked).
    pub in_air: bool,
    /// Off the ground: taking off, flying or landing.
    pub airborne: bool,
    /// The cause of the failsafe in force, if any (PX4's `vehicle_status.failsafe`).
    pub failsafe: Option<String>,
    /// On the ground or in the air, as the page words it at the end.
    pub landed: String,
}

/// What a [`Collector`] reads of a pilot beyond its step record. A pilot
/// without a flight stack (a plain scenario's control law) has no plans and
/// no battery estimate: its page shows no items and no charge.
pub trait Watched: Pilot + Sized {
    /// Its airframe's rotor count.
    fn rotor_count(&self) -> usize;
    /// Its state now.
    fn pilot_state(&self) -> PilotState;
    /// Its stored plans and the origin of its local NED frame, if it has plans.
    fn plans_at(&self) -> Option<(&Plans, GeoPoint)>;
    /// Vehicle `i`'s remaining charge 0..1 now (NaN: none estimated).
    fn battery_remaining(core: &mut Lockstep<Self>, i: usize) -> f64;
}

impl Watched for Autopilot {
    fn rotor_count(&self) -> usize {
        self.airframe().rotor_count()
    }

    fn pilot_state(&self) -> PilotState {
        let landed = self.landed_state();
        PilotState {
            armed: self.armed(),
            mode: format!("{:?}", self.mode()),
            in_air: landed == LandedState::InAir,
            airborne: landed != LandedState::OnGround,
            failsafe: self.failsafe_in_force().map(|f| f.cause.clone()),
            landed: format!("{landed:?}"),
        }
    }

    fn plans_at(&self) -> Option<(&Plans, GeoPoint)> {
        Some((self.plans(), self.origin()))
    }

    fn battery_remaining(core: &mut Lockstep<Self>, i: usize) -> f64 {
        core.telemetry(i).battery_remaining
    }
}

/// Watches one vehicle of a lockstep core, step by step, and gives its
/// [`FlightReport`]. Call [`Self::after_step`] after every step, hand it
/// the status texts and reached items as the runtime drains them
/// ([`Self::texts`], [`Self::reached`]); it never drains a queue itself and
/// never changes the flight.
#[derive(Debug)]
pub struct Collector {
    vehicle: usize,
    stride: u64,
    series: Series,
    modes: Timeline,
    arming: Timeline,
    events: Vec<Event>,
    items: Vec<ItemRow>,
    plans: PlanView,
    plans_seen: Option<Plans>,
    max_err: Option<(f64, f64)>,
    /// Steps in the air, and those with a rotor command at a limit (and the first's instant).
    air_steps: u64,
    limit_steps: u64,
    first_limit_s: Option<f64>,
    /// The cause of the failsafe in force after the last step.
    failsafe: Option<String>,
    row: Vec<f64>,
}

impl Collector {
    /// Watch vehicle `vehicle` of `core` (at its start) over a flight of
    /// about `steps` steps (the stride of the series follows from it).
    #[must_use]
    pub fn new<P: Watched>(core: &Lockstep<P>, vehicle: usize, steps: u64) -> Self {
        let rotors = core.pilot(vehicle).rotor_count();
        let mut c = Self {
            vehicle,
            stride: steps.div_ceil(MAX_SAMPLES).max(MIN_STRIDE_STEPS),
            series: Series::new(rotors, "rad/s"),
            modes: Timeline::default(),
            arming: Timeline::default(),
            events: Vec::new(),
            items: Vec::new(),
            plans: PlanView::default(),
            plans_seen: None,
            max_err: None,
            air_steps: 0,
            limit_steps: 0,
            first_limit_s: None,
            failsafe: None,
            row: vec![f64::NAN; COLUMNS.len() + rotors],
        };
        c.watch_plans(core);
        c
    }

    /// Take the vehicle's plans when they changed (kept: the last non-empty
    /// mission, geofence and rally points; a test often clears them at its end).
    pub fn watch_plans<P: Watched>(&mut self, core: &Lockstep<P>) {
        let Some((plans, origin)) = core.pilot(self.vehicle).plans_at() else {
            return;
        };
        if self.plans_seen.as_ref() == Some(plans) {
            return;
        }
        self.plans_seen = Some(plans.clone());
        let view = PlanView::new(plans, origin);
        if view.is_empty() {
            return;
        }
        if !view.commands.is_empty() {
            if view.commands != self.plans.commands {
                self.items = view
                    .commands
                    .iter()
                    .enumerate()
                    .map(|(k, c)| ItemRow {
                        seq: u16::try_from(k).unwrap_or(u16::MAX),
                        command: *c,
                        reached_s: None,
                        times: 0,
                        distance_m: None,
                    })
                    .collect();
            }
            self.plans.mission = view.mission;
            self.plans.commands = view.commands;
        }
        if !view.fence.is_empty() {
            self.plans.fence = view.fence;
        }
        if !view.rally.is_empty() {
            self.plans.rally = view.rally;
        }
    }

    /// After a step: the timeline and tracking error every step, a sample
    /// of the series every stride.
    pub fn after_step<P: Watched>(&mut self, core: &mut Lockstep<P>) {
        let t = core.time_s();
        let i = self.vehicle;
        let PilotState {
            armed,
            mode,
            in_air,
            airborne,
            failsafe,
            ..
        } = core.pilot(i).pilot_state();
        if failsafe != self.failsafe {
            if let Some(cause) = &failsafe {
                self.events.push(Event::failsafe(t, cause, &mode));
            }
            self.failsafe = failsafe;
        }
        self.arming.at(t, if armed { "armed" } else { "disarmed" });
        self.modes.at(t, &mode);
        let rec = core.last_step(i);
        let truth = rec.world.truth;
        let reference = &rec.control.reference;
        let tracking = *reference != Reference::default();
        if tracking && in_air {
            let e = (truth.position_ned - reference.position_ned).norm();
            if self.max_err.is_none_or(|(m, _)| e > m) {
                self.max_err = Some((e, t));
            }
        }
        if airborne && matches!(rec.control.actuator, ActuatorCommand::RotorSpeeds(_)) {
            self.air_steps += 1;
            if rec.control.saturated {
                self.limit_steps += 1;
                self.first_limit_s.get_or_insert(t);
            }
        }
        if !core.steps().is_multiple_of(self.stride) {
            return;
        }
        let battery = P::battery_remaining(core, i);
        let rec = core.last_step(i);
        let (truth, reference) = (rec.world.truth, &rec.control.reference);
        let c = rec.control;
        let m = rec.measurement;
        let nan3 = [f64::NAN; 3];
        let (rp, rv) = if tracking {
            (reference.position_ned, reference.velocity_ned)
        } else {
            (Vector3::repeat(f64::NAN), Vector3::repeat(f64::NAN))
        };
        let (p, v) = (truth.position_ned, truth.velocity_ned);
        let att = euler_deg(&truth.attitude);
        let sp = if armed { euler_deg(&c.attitude_sp) } else { nan3 };
        let est = &c.estimate;
        let ext = &rec.world.external;
        let mut k = 0;
        let mut put = |x: f64| {
            self.row[k] = x;
            k += 1;
        };
        for x in [p.x, p.y, p.z, rp.x, rp.y, rp.z, m.position_ned.z] {
            put(x);
        }
        put(v.xy().norm());
        put(v.z);
        put(rv.xy().norm());
        for x in att.into_iter().chain(sp) {
            put(x);
        }
        put(if tracking { (p - rp).norm() } else { f64::NAN });
        for x in est.force_ned.iter().chain(ext.force_ned.iter()) {
            put(*x);
        }
        for x in est.torque_frd.iter().chain(ext.torque_frd.iter()) {
            put(*x);
        }
        put(est.mass_kg);
        put(rec.world.true_mass_kg);
        self.row[k] = battery;
        k += 1;
        let rotors = self.row.len() - k;
        for r in 0..rotors {
            self.row[k + r] = match &c.actuator {
                ActuatorCommand::RotorSpeeds(w) => w[r],
                ActuatorCommand::Stop => 0.0,
                ActuatorCommand::Wrench(_) => f64::NAN,
            };
        }
        let row = std::mem::take(&mut self.row);
        self.series.push(t, &row);
        self.row = row;
    }

    /// Status texts as drained, each with the instant it was raised [s].
    pub fn texts(&mut self, texts: &[(f64, StatusText)]) {
        for (t, s) in texts {
            self.events.push(Event::from_text(*t, s.severity, &s.text));
        }
    }

    /// Mission item `seq` reached at `t_s`, `distance_m` from its point (the
    /// one distance of [`crate::logs::items::ItemTally::distance_m`]; the
    /// runner drains the queue and tells its findings here).
    pub fn reached_at(&mut self, seq: u16, t_s: f64, distance_m: Option<f64>) {
        if let Some(r) = self.items.get_mut(usize::from(seq)) {
            r.times += 1;
            if r.reached_s.is_none() {
                r.reached_s = Some(t_s);
                r.distance_m = distance_m;
            }
        }
        let off = distance_m.map_or(String::new(), |d| format!(", {d:.2} m off"));
        let what = self
            .items
            .get(usize::from(seq))
            .map_or(String::new(), |r| format!(" ({})", command_name(r.command)));
        self.events.push(Event {
            t_s,
            kind: EventKind::Reached,
            severity: "Info".into(),
            text: format!("Reached item {seq}{what}{off}"),
        });
    }

    /// The report, at the end of the flight.
    #[must_use]
    pub fn finish<P: Watched>(mut self, core: &mut Lockstep<P>, meta: ReportMeta) -> FlightReport {
        let t = core.time_s();
        if self.series.t.last().is_none_or(|last| *last < t) {
            // the last instant, whatever the stride
            let stride = self.stride;
            self.stride = 1;
            self.after_step(core);
            self.stride = stride;
        }
        let end = core.pilot(self.vehicle).pilot_state();
        let final_state = format!(
            "{}, mode {}, {}",
            if end.armed { "armed" } else { "disarmed" },
            end.mode,
            end.landed
        );
        let mut events = self.events;
        events.sort_by(|a, b| a.t_s.total_cmp(&b.t_s));
        FlightReport {
            meta,
            duration_s: t,
            verdict: Verdict {
                outcome: None,
                reasons: Vec::new(),
                items: self.items,
                max_tracking_error: self.max_err,
                tracking_counted: "while flying: takeoff and landing excluded, as the mission summary counts it",
                rotor_limit: (self.air_steps > 0).then(|| RotorLimit {
                    share: self.limit_steps as f64 / self.air_steps as f64,
                    first_s: self.first_limit_s,
                    counted: "every step in the air; a rotor speed commanded at its minimum or maximum",
                }),
                final_state,
            },
            plans: self.plans,
            series: self.series,
            modes: self.modes.spans,
            arming: self.arming.spans,
            events,
        }
    }
}

/// A MAV_CMD's short name (its number when not a common one).
#[must_use]
pub fn command_name(command: u16) -> String {
    match command {
        cmd::NAV_WAYPOINT => "WAYPOINT".into(),
        cmd::NAV_LOITER_UNLIM => "LOITER_UNLIM".into(),
        cmd::NAV_LOITER_TURNS => "LOITER_TURNS".into(),
        cmd::NAV_LOITER_TIME => "LOITER_TIME".into(),
        cmd::NAV_RETURN_TO_LAUNCH => "RETURN_TO_LAUNCH".into(),
        cmd::NAV_LAND => "LAND".into(),
        cmd::NAV_TAKEOFF => "TAKEOFF".into(),
        cmd::NAV_LOITER_TO_ALT => "LOITER_TO_ALT".into(),
        cmd::NAV_DELAY => "DELAY".into(),
        cmd::DO_JUMP => "DO_JUMP".into(),
        cmd::DO_CHANGE_SPEED => "DO_CHANGE_SPEED".into(),
        cmd::DO_SET_HOME => "DO_SET_HOME".into(),
        cmd::DO_LAND_START => "DO_LAND_START".into(),
        cmd::DO_SET_ROI => "DO_SET_ROI".into(),
        other => format!("MAV_CMD {other}"),
    }
}
