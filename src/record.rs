//! Flight records and exact replay (`rotorpilot replay`; the format is
//! documented for users in `docs/record-format.md`).
//!
//! A record is JSON Lines: a header that rebuilds the lockstep core at step
//! 0, then one line per input that reached the core, each with the step
//! index `k` at which it was applied (inputs are applied between steps, so
//! at the instant `t_k = k * step_s`, before step `k` runs), then an end
//! line with the final step count:
//!
//! ```text
//! {"header":{"format":"rotorpilot-flight-record","version":1,"rotorpilot":"0.1.0",...}}
//! {"step":2113,"command":{"Arm":{"force":false}},"outcome":"Accepted"}
//! {"step":2500,"set_param":{"name":"MPC_XY_VEL_MAX","value":{"Real32":8.0}},"outcome":"Ok(Real32(8.0))"}
//! {"end":{"step":61234}}
//! ```
//!
//! Every number reads back bit for bit: f64 in its shortest round-trip form
//! (serde_json's `float_roundtrip` parses it exactly), f32 in its shortest
//! form when that reads back through a double to the same f32, else as the
//! double it is; NaN as the string `"nan"` (the usual quiet NaN) or
//! `"nan:0x…"` (its bits), infinities as `"inf"` and `"-inf"` (JSON has no
//! number for them; MAVLink mission items carry NaN parameters).
//!
//! [`apply`] is the one way an input reaches the core: the daemon's
//! simulation thread calls it for every client input (and records it), and
//! [`replay`] calls it for every recorded line, so the two cannot differ.

use std::collections::BTreeMap;
use std::io::Write;

use serde::de::value::{MapAccessDeserializer, MapDeserializer, SeqDeserializer};
use serde::de::{self, IntoDeserializer, Visitor};
use serde::ser::{self, Serialize};
use serde::{Deserialize, Deserializer};
use serde_json::{Map, Value};

use crate::airframe::Airframe;
use crate::autopilot::{Autopilot, AutopilotCommand, AutopilotError, ClientClock, ClientTimer, CommandOutcome};
use crate::geo::GeoPoint;
use crate::lockstep::Lockstep;
use crate::mission::{MissionItem, MissionResult, MissionType, Plan, PlanChange, Plans};
use crate::params::{ParamStore, ParamValue};
use crate::scenario::CsvLog;
use crate::sim::SensorConfig;
use crate::ulog::flight::FlightUlog;

/// The header's `format` field.
pub const FORMAT: &str = "rotorpilot-flight-record";
/// The format version this rotorpilot writes and reads.
pub const VERSION: u64 = 1;
/// This rotorpilot's version (the header's `rotorpilot` field).
pub const ROTORPILOT_VERSION: &str = env!("CARGO_PKG_VERSION");

/// Everything that rebuilds the core at step 0.
#[derive(Clone, Debug, PartialEq, serde::Serialize, Deserialize)]
pub struct Header {
    /// [`FORMAT`].
    pub format: String,
    /// [`VERSION`].
    pub version: u64,
    /// The rotorpilot that wrote it.
    pub rotorpilot: String,
    /// The airframe's label (built-in name or the path it was read from).
    pub airframe: String,
    /// The airframe's whole TOML text.
    pub airframe_toml: String,
    /// Home and NED origin.
    pub home: GeoPoint,
    /// Every parameter at step 0, by name.
    pub params: BTreeMap<String, ParamValue>,
    /// The stored plans at step 0 (restored from the state directory).
    pub mission: Vec<MissionItem>,
    /// The stored geofence at step 0.
    pub fence: Vec<MissionItem>,
    /// The stored rally points at step 0.
    pub rally: Vec<MissionItem>,
    /// The world's sensor configuration (noise and seed).
    pub sensors: SensorConfig,
    /// Which clock times the client timers (wall above real-time speed;
    /// their expiries are then recorded as `client_timeout` inputs).
    pub client_clock: ClientClock,
    /// The step [s].
    pub step_s: f64,
}

/// One input to the core (plain data), as the `Lockstep` method that takes it.
#[derive(Clone, Debug, PartialEq, serde::Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Input {
    /// [`Lockstep::command`]: a command, an offboard setpoint, manual control, a failure injection.
    Command(AutopilotCommand),
    /// [`Lockstep::set_param`] (refused ones too).
    SetParam {
        /// Parameter name.
        name: String,
        /// The value asked for.
        value: ParamValue,
    },
    /// [`Lockstep::change_plans`]: a mission, geofence or rally upload or clear.
    ChangePlans(PlanChange),
    /// [`Lockstep::gcs_heartbeat`].
    GcsHeartbeat,
    /// [`Lockstep::client_timeout`]: a client timer ran out on the wall clock.
    ClientTimeout {
        /// Which timer.
        timer: ClientTimer,
        /// When it started [s, simulated].
        started_s: f64,
    },
    /// [`Lockstep::reboot`] from the parameters in force.
    Reboot,
    /// Another vehicle of the fleet came near (or touched): the text
    /// [`crate::lockstep::proximity_text`] announced ([`Lockstep::announce`]).
    /// The live fleet's core raised it itself (it sees every vehicle); the
    /// record keeps it so that a replay of this one vehicle tells it alike.
    Proximity {
        /// The other vehicle's label (`system 3`).
        other: String,
        /// Near or touching.
        kind: crate::sim::ProximityKind,
        /// Their distance [m].
        distance_m: f64,
    },
}

/// What the core answered to an [`Input`].
#[derive(Debug)]
pub enum Applied {
    /// To a command.
    Command(CommandOutcome),
    /// To a parameter set: the stored value or why it was refused.
    SetParam(Result<ParamValue, String>),
    /// To a plan change: the new plan's id or why nothing changed.
    Plans(Result<u32, MissionResult>),
    /// To a heartbeat (nothing to answer).
    GcsHeartbeat,
    /// To a client timeout: whether the timer still ran.
    ClientTimeout(bool),
    /// To a reboot.
    Reboot(Result<(), AutopilotError>),
    /// To a proximity event (announced).
    Announced,
}

impl Applied {
    /// The outcome as the record keeps it (replay compares it).
    #[must_use]
    pub fn text(&self) -> String {
        match self {
            Applied::Command(o) => format!("{o:?}"),
            Applied::SetParam(r) => format!("{r:?}"),
            Applied::Plans(r) => format!("{r:?}"),
            Applied::GcsHeartbeat => "done".into(),
            Applied::ClientTimeout(b) => b.to_string(),
            Applied::Reboot(r) => match r {
                Ok(()) => "Ok".into(),
                Err(e) => format!("Err({e})"),
            },
            Applied::Announced => "announced".into(),
        }
    }
}

/// Apply `input` to vehicle `i` of `core` at the current instant;
/// `params` is the vehicle's parameter store (set_param changes it, reboot
/// reads it).
pub fn apply(core: &mut Lockstep<Autopilot>, i: usize, params: &mut ParamStore, input: &Input) -> Applied {
    match input {
        Input::Command(c) => Applied::Command(core.command(i, *c)),
        Input::SetParam { name, value } => Applied::SetParam(core.set_param(i, params, name, *value)),
        Input::ChangePlans(change) => Applied::Plans(core.change_plans(i, change.clone())),
        Input::GcsHeartbeat => {
            core.gcs_heartbeat(i);
            Applied::GcsHeartbeat
        }
        Input::ClientTimeout { timer, started_s } => Applied::ClientTimeout(core.client_timeout(i, *timer, *started_s)),
        Input::Reboot => Applied::Reboot(core.reboot(i, params)),
        Input::Proximity {
            other,
            kind,
            distance_m,
        } => {
            core.announce(i, crate::lockstep::proximity_text(*kind, other, *distance_m));
            Applied::Announced
        }
    }
}

impl Header {
    /// The header of a core about to start: the airframe's TOML text and
    /// label (as [`Airframe::load_text`] gives them), `params` and the plans
    /// as the autopilot holds them.
    #[must_use]
    pub fn new(
        airframe: (String, String),
        home: GeoPoint,
        params: &ParamStore,
        plans: &Plans,
        sensors: SensorConfig,
        client_clock: ClientClock,
        step_s: f64,
    ) -> Self {
        let (text, label) = airframe;
        Self {
            format: FORMAT.into(),
            version: VERSION,
            rotorpilot: ROTORPILOT_VERSION.into(),
            airframe: label,
            airframe_toml: text,
            home,
            params: params.iter().map(|(s, v)| (s.name.to_string(), v)).collect(),
            mission: plans.get(MissionType::Mission).items().to_vec(),
            fence: plans.get(MissionType::Fence).items().to_vec(),
            rally: plans.get(MissionType::Rally).items().to_vec(),
            sensors,
            client_clock,
            step_s,
        }
    }

    /// Rebuild the core at step 0 and its parameter store, as the daemon
    /// builds them (`one_vehicle`, the client clock, the restored plans).
    ///
    /// # Errors
    /// The airframe text, a parameter or a plan that this rotorpilot refuses,
    /// another step.
    pub fn build(&self) -> Result<(Lockstep<Autopilot>, ParamStore), String> {
        let airframe =
            Airframe::from_toml(&self.airframe_toml, &self.airframe).map_err(|e| format!("airframe: {e}"))?;
        let mut params = ParamStore::new(&airframe);
        for (name, v) in &self.params {
            params.set(name, *v).map_err(|e| format!("parameter {name}: {e}"))?;
        }
        let mut core = Lockstep::one_vehicle(&airframe, self.home, &params, self.sensors).map_err(|e| e.to_string())?;
        if core.dt_s().to_bits() != self.step_s.to_bits() {
            return Err(format!(
                "step {} s, this rotorpilot steps by {} s",
                self.step_s,
                core.dt_s()
            ));
        }
        core.pilot_mut(0).set_client_clock(self.client_clock);
        let mut plans = Plans::default();
        for (kind, items) in [
            (MissionType::Mission, &self.mission),
            (MissionType::Fence, &self.fence),
            (MissionType::Rally, &self.rally),
        ] {
            let plan =
                Plan::new(kind, items.clone()).map_err(|(k, r)| format!("{} item {k}: {}", kind.name(), r.reason()))?;
            plans.set(kind, plan);
        }
        core.pilot_mut(0).restore_plans(plans);
        Ok((core, params))
    }
}

/// One recorded input.
#[derive(Clone, Debug, PartialEq)]
pub struct Entry {
    /// The step index at which it was applied.
    pub step: u64,
    /// The input.
    pub input: Input,
    /// What the core answered live ([`Applied::text`]).
    pub outcome: String,
    /// Its line number in the file (from 1).
    pub line: usize,
}

/// A record read back.
#[derive(Clone, Debug, PartialEq)]
pub struct Record {
    /// The header.
    pub header: Header,
    /// The inputs, in the order they were applied.
    pub inputs: Vec<Entry>,
    /// The end line's step count; `None` when the daemon did not stop cleanly.
    pub end: Option<u64>,
}

/// The header line (no newline).
///
/// # Errors
/// Never for these types (a serializer error is passed on).
pub fn header_line(h: &Header) -> Result<String, serde_json::Error> {
    let mut m = Map::new();
    m.insert("header".into(), to_exact_value(h)?);
    serde_json::to_string(&Value::Object(m))
}

/// An input line (no newline): the input applied at `step` and what the core answered.
///
/// # Errors
/// As [`header_line`].
pub fn input_line(step: u64, input: &Input, outcome: &str) -> Result<String, serde_json::Error> {
    let mut m = match to_exact_value(input)? {
        Value::Object(m) => m,
        // unit variants serialize as their name
        Value::String(name) => Map::from_iter([(name, Value::Null)]),
        other => return Err(ser::Error::custom(format!("an input serialized as {other}"))),
    };
    m.insert("step".into(), Value::from(step));
    m.insert("outcome".into(), Value::from(outcome));
    serde_json::to_string(&Value::Object(m))
}

/// The end line (no newline): the final step count.
#[must_use]
pub fn end_line(step: u64) -> String {
    format!("{{\"end\":{{\"step\":{step}}}}}")
}

/// Read a record; `file` labels the messages (`flight.record:17: ...`).
///
/// # Errors
/// Empty, not a record, another format version, a line cut short or not a
/// record line, inputs out of step order or after the end.
pub fn read_record(text: &str, file: &str) -> Result<Record, String> {
    let mut lines = text.split_inclusive('\n').enumerate().map(|(k, l)| (k + 1, l));
    let Some((_, first)) = lines.next() else {
        return Err(format!("{file}: empty file, not a flight record"));
    };
    let header = read_header(first, file)?;
    let mut inputs: Vec<Entry> = Vec::new();
    let mut end = None;
    for (n, raw) in lines {
        let at = format!("{file}:{n}");
        if !raw.ends_with('\n') {
            return Err(format!("{at}: cut short (no end of line: the writer stopped mid-line)"));
        }
        let line = raw.trim_end();
        if line.is_empty() {
            continue;
        }
        if end.is_some() {
            return Err(format!("{at}: a line after the end line"));
        }
        let v: Value = serde_json::from_str(line).map_err(|e| bad_json(&at, &e))?;
        let Value::Object(mut m) = v else {
            return Err(format!("{at}: not a record line: not a JSON object"));
        };
        if let Some(e) = m.remove("end") {
            let step = e.get("step").and_then(Value::as_u64);
            match step {
                Some(s) if m.is_empty() => {
                    if let Some(last) = inputs.last().filter(|l| l.step > s) {
                        return Err(format!(
                            "{at}: ends at step {s}, before the input at step {}",
                            last.step
                        ));
                    }
                    end = Some(s);
                }
                _ => {
                    return Err(format!(
                        "{at}: not a record line: an end line holds only {{\"step\": N}}"
                    ));
                }
            }
            continue;
        }
        let step = m
            .remove("step")
            .and_then(|s| s.as_u64())
            .ok_or_else(|| format!("{at}: not a record line: no \"step\" (a whole number)"))?;
        let outcome = match m.remove("outcome") {
            Some(Value::String(s)) => s,
            _ => return Err(format!("{at}: not a record line: no \"outcome\" text")),
        };
        if m.len() != 1 {
            return Err(format!(
                "{at}: not a record line: expected one input beside step and outcome, found {:?}",
                m.keys().collect::<Vec<_>>()
            ));
        }
        let input = Input::deserialize(Exact(Value::Object(m))).map_err(|e| format!("{at}: not a record line: {e}"))?;
        if let Some(last) = inputs.last().filter(|l| l.step > step) {
            return Err(format!(
                "{at}: step {step} comes after step {} (inputs are in step order)",
                last.step
            ));
        }
        inputs.push(Entry {
            step,
            input,
            outcome,
            line: n,
        });
    }
    Ok(Record { header, inputs, end })
}

fn bad_json(at: &str, e: &serde_json::Error) -> String {
    if e.is_eof() {
        format!("{at}: cut short ({e})")
    } else {
        format!("{at}: not a record line: {e}")
    }
}

fn read_header(raw: &str, file: &str) -> Result<Header, String> {
    let at = format!("{file}:1");
    let not_record = || format!("{file}: not a flight record (the first line is no {FORMAT} header)");
    let v: Value = serde_json::from_str(raw.trim_end()).map_err(|e| {
        if e.is_eof() {
            format!("{at}: cut short ({e})")
        } else {
            not_record()
        }
    })?;
    let h = v.get("header").ok_or_else(not_record)?;
    if h.get("format").and_then(Value::as_str) != Some(FORMAT) {
        return Err(not_record());
    }
    match (h.get("version"), h.get("version").and_then(Value::as_u64)) {
        (_, Some(VERSION)) => {}
        (_, Some(v)) => {
            return Err(format!(
                "{file}: format version {v}, this rotorpilot reads version {VERSION} (rotorpilot {ROTORPILOT_VERSION})"
            ));
        }
        (Some(v), None) => {
            return Err(format!(
                "{at}: the header's format version is {v}, not a whole number (this rotorpilot reads version {VERSION})"
            ));
        }
        (None, None) => return Err(format!("{at}: the header has no format version")),
    }
    Header::deserialize(Exact(h.clone())).map_err(|e| format!("{at}: header: {e}"))
}

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
    /// Steps run (the parameters are looked at every [`PARAM_CHECK_EVERY`]).
    steps: u64,
    generation: u64,
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
        let Some(u) = &mut self.ulog else {
            if core.steps().is_multiple_of(1024) {
                // as the daemon publishes: the queues do not steer the flight
                let _ = core.drain_status_texts(0);
                let _ = core.drain_mission_reached(0);
            }
            return Ok(());
        };
        let ue = |e: std::io::Error| format!("writing the ULog: {e}");
        if self.steps.is_multiple_of(PARAM_CHECK_EVERY) && params.generation() != self.generation {
            self.generation = params.generation();
            u.parameters(params).map_err(ue)?;
        }
        u.on_step(core, 0).map_err(ue)?;
        for (time_s, t) in core.drain_stamped_status_texts(0) {
            u.status_text(time_s, &t).map_err(ue)?;
        }
        let _ = core.drain_mission_reached(0);
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
    let (mut core, mut params) = record.header.build().map_err(|e| format!("{file}:1: header: {e}"))?;
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
        steps: 0,
        generation: params.generation(),
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
    }
    step_to(&mut core, &params, end, &mut logs)?;
    if let Some(l) = logs.csv {
        l.finish().map_err(|e| format!("writing the CSV: {e}"))?;
    }
    if let Some(u) = logs.ulog {
        u.finish().map_err(|e| format!("writing the ULog: {e}"))?;
    }
    let ap = core.pilot(0);
    let p = core.last_step(0).world.truth.position_ned;
    Ok(ReplaySummary {
        steps: core.steps(),
        sim_time_s: core.time_s(),
        inputs: record.inputs.len(),
        complete: record.end.is_some(),
        armed: ap.armed(),
        mode: format!("{:?}", ap.mode()),
        landed_state: format!("{:?}", ap.landed_state()),
        position_ned_m: [p.x, p.y, p.z],
    })
}

// ----- exact JSON values ---------------------------------------------------------------------

/// `v` as a JSON value whose numbers read back bit for bit (module doc).
///
/// # Errors
/// A map key that is not a string or number.
pub fn to_exact_value<T: Serialize + ?Sized>(v: &T) -> Result<Value, serde_json::Error> {
    v.serialize(ExactSer)
}

/// Read back what [`to_exact_value`] wrote.
///
/// # Errors
/// `v` does not hold a `T`.
pub fn from_exact_value<T: de::DeserializeOwned>(v: Value) -> Result<T, de::value::Error> {
    T::deserialize(Exact(v))
}

fn nan_or_inf(is_nan: bool, positive: bool, canonical: bool, bits: String) -> Value {
    Value::String(match (is_nan, canonical) {
        (true, true) => "nan".into(),
        (true, false) => format!("nan:0x{bits}"),
        (false, _) => if positive { "inf" } else { "-inf" }.into(),
    })
}

fn f64_value(v: f64) -> Value {
    if v.is_finite() {
        Value::from(v)
    } else {
        nan_or_inf(
            v.is_nan(),
            v > 0.0,
            v.to_bits() == f64::NAN.to_bits(),
            format!("{:016x}", v.to_bits()),
        )
    }
}

fn f32_value(v: f32) -> Value {
    if v.is_finite() {
        let short = format!("{v:?}");
        match short.parse::<f64>() {
            // through a double, as serde_json reads it
            Ok(d) if (d as f32).to_bits() == v.to_bits() => Value::from(d),
            _ => Value::from(f64::from(v)),
        }
    } else {
        nan_or_inf(
            v.is_nan(),
            v > 0.0,
            v.to_bits() == f32::NAN.to_bits(),
            format!("{:08x}", v.to_bits()),
        )
    }
}

/// Serializes into a [`Value`] with [`f64_value`] / [`f32_value`] numbers.
struct ExactSer;

struct SeqSer(Vec<Value>);
struct VariantSeqSer(&'static str, Vec<Value>);
struct MapSer(Map<String, Value>, Option<String>);
struct VariantMapSer(&'static str, Map<String, Value>);

fn variant(name: &str, v: Value) -> Value {
    Value::Object(Map::from_iter([(name.to_string(), v)]))
}

type SerResult = Result<Value, serde_json::Error>;

impl ser::Serializer for ExactSer {
    type Ok = Value;
    type Error = serde_json::Error;
    type SerializeSeq = SeqSer;
    type SerializeTuple = SeqSer;
    type SerializeTupleStruct = SeqSer;
    type SerializeTupleVariant = VariantSeqSer;
    type SerializeMap = MapSer;
    type SerializeStruct = MapSer;
    type SerializeStructVariant = VariantMapSer;

    fn serialize_bool(self, v: bool) -> SerResult {
        Ok(Value::Bool(v))
    }
    fn serialize_i8(self, v: i8) -> SerResult {
        Ok(Value::from(v))
    }
    fn serialize_i16(self, v: i16) -> SerResult {
        Ok(Value::from(v))
    }
    fn serialize_i32(self, v: i32) -> SerResult {
        Ok(Value::from(v))
    }
    fn serialize_i64(self, v: i64) -> SerResult {
        Ok(Value::from(v))
    }
    fn serialize_u8(self, v: u8) -> SerResult {
        Ok(Value::from(v))
    }
    fn serialize_u16(self, v: u16) -> SerResult {
        Ok(Value::from(v))
    }
    fn serialize_u32(self, v: u32) -> SerResult {
        Ok(Value::from(v))
    }
    fn serialize_u64(self, v: u64) -> SerResult {
        Ok(Value::from(v))
    }
    fn serialize_f32(self, v: f32) -> SerResult {
        Ok(f32_value(v))
    }
    fn serialize_f64(self, v: f64) -> SerResult {
        Ok(f64_value(v))
    }
    fn serialize_char(self, v: char) -> SerResult {
        Ok(Value::String(v.to_string()))
    }
    fn serialize_str(self, v: &str) -> SerResult {
        Ok(Value::String(v.to_string()))
    }
    fn serialize_bytes(self, v: &[u8]) -> SerResult {
        Ok(Value::Array(v.iter().map(|&b| Value::from(b)).collect()))
    }
    fn serialize_none(self) -> SerResult {
        Ok(Value::Null)
    }
    fn serialize_some<T: Serialize + ?Sized>(self, v: &T) -> SerResult {
        v.serialize(self)
    }
    fn serialize_unit(self) -> SerResult {
        Ok(Value::Null)
    }
    fn serialize_unit_struct(self, _: &'static str) -> SerResult {
        Ok(Value::Null)
    }
    fn serialize_unit_variant(self, _: &'static str, _: u32, name: &'static str) -> SerResult {
        Ok(Value::String(name.into()))
    }
    fn serialize_newtype_struct<T: Serialize + ?Sized>(self, _: &'static str, v: &T) -> SerResult {
        v.serialize(self)
    }
    fn serialize_newtype_variant<T: Serialize + ?Sized>(
        self,
        _: &'static str,
        _: u32,
        name: &'static str,
        v: &T,
    ) -> SerResult {
        Ok(variant(name, v.serialize(self)?))
    }
    fn serialize_seq(self, len: Option<usize>) -> Result<SeqSer, serde_json::Error> {
        Ok(SeqSer(Vec::with_capacity(len.unwrap_or(0))))
    }
    fn serialize_tuple(self, len: usize) -> Result<SeqSer, serde_json::Error> {
        self.serialize_seq(Some(len))
    }
    fn serialize_tuple_struct(self, _: &'static str, len: usize) -> Result<SeqSer, serde_json::Error> {
        self.serialize_seq(Some(len))
    }
    fn serialize_tuple_variant(
        self,
        _: &'static str,
        _: u32,
        name: &'static str,
        _: usize,
    ) -> Result<VariantSeqSer, serde_json::Error> {
        Ok(VariantSeqSer(name, Vec::new()))
    }
    fn serialize_map(self, _: Option<usize>) -> Result<MapSer, serde_json::Error> {
        Ok(MapSer(Map::new(), None))
    }
    fn serialize_struct(self, _: &'static str, _: usize) -> Result<MapSer, serde_json::Error> {
        self.serialize_map(None)
    }
    fn serialize_struct_variant(
        self,
        _: &'static str,
        _: u32,
        name: &'static str,
        _: usize,
    ) -> Result<VariantMapSer, serde_json::Error> {
        Ok(VariantMapSer(name, Map::new()))
    }
}

impl ser::SerializeSeq for SeqSer {
    type Ok = Value;
    type Error = serde_json::Error;
    fn serialize_element<T: Serialize + ?Sized>(&mut self, v: &T) -> Result<(), serde_json::Error> {
        self.0.push(v.serialize(ExactSer)?);
        Ok(())
    }
    fn end(self) -> SerResult {
        Ok(Value::Array(self.0))
    }
}

impl ser::SerializeTuple for SeqSer {
    type Ok = Value;
    type Error = serde_json::Error;
    fn serialize_element<T: Serialize + ?Sized>(&mut self, v: &T) -> Result<(), serde_json::Error> {
        ser::SerializeSeq::serialize_element(self, v)
    }
    fn end(self) -> SerResult {
        ser::SerializeSeq::end(self)
    }
}

impl ser::SerializeTupleStruct for SeqSer {
    type Ok = Value;
    type Error = serde_json::Error;
    fn serialize_field<T: Serialize + ?Sized>(&mut self, v: &T) -> Result<(), serde_json::Error> {
        ser::SerializeSeq::serialize_element(self, v)
    }
    fn end(self) -> SerResult {
        ser::SerializeSeq::end(self)
    }
}

impl ser::SerializeTupleVariant for VariantSeqSer {
    type Ok = Value;
    type Error = serde_json::Error;
    fn serialize_field<T: Serialize + ?Sized>(&mut self, v: &T) -> Result<(), serde_json::Error> {
        self.1.push(v.serialize(ExactSer)?);
        Ok(())
    }
    fn end(self) -> SerResult {
        Ok(variant(self.0, Value::Array(self.1)))
    }
}

impl ser::SerializeMap for MapSer {
    type Ok = Value;
    type Error = serde_json::Error;
    fn serialize_key<T: Serialize + ?Sized>(&mut self, k: &T) -> Result<(), serde_json::Error> {
        self.1 = Some(match k.serialize(ExactSer)? {
            Value::String(s) => s,
            Value::Number(n) => n.to_string(),
            other => return Err(ser::Error::custom(format!("a map key must be a string, got {other}"))),
        });
        Ok(())
    }
    fn serialize_value<T: Serialize + ?Sized>(&mut self, v: &T) -> Result<(), serde_json::Error> {
        let k = self
            .1
            .take()
            .ok_or_else(|| ser::Error::custom("a map value without a key"))?;
        self.0.insert(k, v.serialize(ExactSer)?);
        Ok(())
    }
    fn end(self) -> SerResult {
        Ok(Value::Object(self.0))
    }
}

impl ser::SerializeStruct for MapSer {
    type Ok = Value;
    type Error = serde_json::Error;
    fn serialize_field<T: Serialize + ?Sized>(&mut self, k: &'static str, v: &T) -> Result<(), serde_json::Error> {
        self.0.insert(k.into(), v.serialize(ExactSer)?);
        Ok(())
    }
    fn end(self) -> SerResult {
        Ok(Value::Object(self.0))
    }
}

impl ser::SerializeStructVariant for VariantMapSer {
    type Ok = Value;
    type Error = serde_json::Error;
    fn serialize_field<T: Serialize + ?Sized>(&mut self, k: &'static str, v: &T) -> Result<(), serde_json::Error> {
        self.1.insert(k.into(), v.serialize(ExactSer)?);
        Ok(())
    }
    fn end(self) -> SerResult {
        Ok(variant(self.0, Value::Object(self.1)))
    }
}

/// Deserializes what [`ExactSer`] wrote: the strings `"nan"`, `"nan:0x…"`,
/// `"inf"`, `"-inf"` where a float is expected.
struct Exact(Value);

type DeError = de::value::Error;

impl<'de> IntoDeserializer<'de, DeError> for Exact {
    type Deserializer = Self;
    fn into_deserializer(self) -> Self {
        self
    }
}

/// The non-finite float a string names, as f64 bits or f32 bits:
/// `nan`, `inf`, `-inf`, or `nan:0x<hex bits>` for a NaN of other bits
/// (bits that are not a NaN of that width are refused: `None`).
fn special_float(s: &str, f32_bits: bool) -> Option<u64> {
    match s {
        "nan" if f32_bits => Some(u64::from(f32::NAN.to_bits())),
        "nan" => Some(f64::NAN.to_bits()),
        "inf" if f32_bits => Some(u64::from(f32::INFINITY.to_bits())),
        "inf" => Some(f64::INFINITY.to_bits()),
        "-inf" if f32_bits => Some(u64::from(f32::NEG_INFINITY.to_bits())),
        "-inf" => Some(f64::NEG_INFINITY.to_bits()),
        _ => {
            let bits = u64::from_str_radix(s.strip_prefix("nan:0x")?, 16).ok()?;
            let is_nan = if f32_bits {
                f32::from_bits(u32::try_from(bits).ok()?).is_nan()
            } else {
                f64::from_bits(bits).is_nan()
            };
            is_nan.then_some(bits)
        }
    }
}

impl<'de> Deserializer<'de> for Exact {
    type Error = DeError;

    fn deserialize_any<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, DeError> {
        match self.0 {
            Value::Null => visitor.visit_unit(),
            Value::Bool(b) => visitor.visit_bool(b),
            Value::Number(n) => {
                if let Some(u) = n.as_u64() {
                    visitor.visit_u64(u)
                } else if let Some(i) = n.as_i64() {
                    visitor.visit_i64(i)
                } else {
                    visitor.visit_f64(n.as_f64().unwrap_or(f64::NAN))
                }
            }
            Value::String(s) => visitor.visit_string(s),
            Value::Array(a) => {
                let mut seq = SeqDeserializer::new(a.into_iter().map(Exact));
                let v = visitor.visit_seq(&mut seq)?;
                seq.end()?;
                Ok(v)
            }
            Value::Object(m) => {
                let mut map = MapDeserializer::new(m.into_iter().map(|(k, v)| (k, Exact(v))));
                let v = visitor.visit_map(&mut map)?;
                map.end()?;
                Ok(v)
            }
        }
    }

    fn deserialize_f64<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, DeError> {
        match &self.0 {
            Value::String(s) => match special_float(s, false) {
                Some(bits) => visitor.visit_f64(f64::from_bits(bits)),
                None => Err(de::Error::custom(format!("expected a number, found \"{s}\""))),
            },
            _ => self.deserialize_any(visitor),
        }
    }

    fn deserialize_f32<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, DeError> {
        match &self.0 {
            Value::String(s) => match special_float(s, true).and_then(|b| u32::try_from(b).ok()) {
                Some(bits) => visitor.visit_f32(f32::from_bits(bits)),
                None => Err(de::Error::custom(format!("expected a number, found \"{s}\""))),
            },
            _ => self.deserialize_any(visitor),
        }
    }

    fn deserialize_option<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, DeError> {
        match self.0 {
            Value::Null => visitor.visit_none(),
            v => visitor.visit_some(Exact(v)),
        }
    }

    fn deserialize_newtype_struct<V: Visitor<'de>>(self, _: &'static str, visitor: V) -> Result<V::Value, DeError> {
        visitor.visit_newtype_struct(self)
    }

    fn deserialize_enum<V: Visitor<'de>>(
        self,
        _: &'static str,
        _: &'static [&'static str],
        visitor: V,
    ) -> Result<V::Value, DeError> {
        match self.0 {
            Value::String(s) => visitor.visit_enum(s.into_deserializer()),
            Value::Object(m) if m.len() == 1 => visitor.visit_enum(MapAccessDeserializer::new(MapDeserializer::new(
                m.into_iter().map(|(k, v)| (k, Exact(v))),
            ))),
            other => Err(de::Error::custom(format!(
                "expected a variant name or {{\"Variant\": ...}}, found {other}"
            ))),
        }
    }

    serde::forward_to_deserialize_any! {
        bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 char str string bytes byte_buf unit unit_struct seq tuple
        tuple_struct map struct identifier ignored_any
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::autopilot::{FlightMode, OffboardSetpoint, PowerAction};
    use nalgebra::Vector3;

    fn round_trip(input: &Input) -> Input {
        let line = input_line(7, input, "Accepted").unwrap();
        let text = format!("{}\n{line}\n", header_line(&test_header()).unwrap());
        let r = read_record(&text, "t").unwrap();
        assert_eq!(r.inputs[0].step, 7);
        r.inputs[0].input.clone()
    }

    fn test_header() -> Header {
        let a = Airframe::load("quad").unwrap();
        Header::new(
            Airframe::load_text("quad").unwrap(),
            GeoPoint::PX4_SITL_HOME,
            &ParamStore::new(&a),
            &Plans::default(),
            SensorConfig::default(),
            ClientClock::Wall,
            crate::signals::DEFAULT_STEP_S,
        )
    }

    #[test]
    fn floats_read_back_bit_for_bit() {
        let specials = [
            f64::NAN,
            -f64::NAN,
            f64::from_bits(0x7ff8_0000_0000_0001),
            f64::INFINITY,
            f64::NEG_INFINITY,
            0.1,
            -0.0,
            f64::MIN_POSITIVE,
            5e-324,
            f64::MAX,
        ];
        let mut x: u64 = 0x9e37_79b9_7f4a_7c15;
        let mut values: Vec<f64> = specials.to_vec();
        for _ in 0..20_000 {
            // xorshift: arbitrary bit patterns
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            values.push(f64::from_bits(x));
        }
        for v in values {
            let back: f64 = from_exact_value(serde_json::from_str(&f64_value(v).to_string()).unwrap()).unwrap();
            assert_eq!(back.to_bits(), v.to_bits(), "{v:?}");
            let f = f32::from_bits(x as u32 ^ v.to_bits() as u32);
            let back: f32 = from_exact_value(serde_json::from_str(&f32_value(f).to_string()).unwrap()).unwrap();
            assert_eq!(back.to_bits(), f.to_bits(), "{f:?}");
        }
        for f in [
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::from_bits(0x7fc0_0001),
            0.1,
            16_777_217.0,
        ] {
            let back: f32 = from_exact_value(serde_json::from_str(&f32_value(f).to_string()).unwrap()).unwrap();
            assert_eq!(back.to_bits(), f.to_bits(), "{f:?}");
        }
    }

    #[test]
    fn nan_bits_that_are_no_nan_are_refused() {
        let read64 = |s: &str| from_exact_value::<f64>(Value::String(s.into())).map(f64::to_bits);
        let read32 = |s: &str| from_exact_value::<f32>(Value::String(s.into())).map(f32::to_bits);
        assert_eq!(read64("nan:0x7ff8000000000001").unwrap(), 0x7ff8_0000_0000_0001);
        assert_eq!(read32("nan:0x7fc00001").unwrap(), 0x7fc0_0001);
        // 1.0, an infinity, zero: bit patterns that are no NaN
        for s in ["nan:0x3ff0000000000000", "nan:0x7ff0000000000000", "nan:0x0"] {
            let e = read64(s).unwrap_err().to_string();
            assert!(e.contains("expected a number"), "{s}: {e}");
        }
        for s in ["nan:0x3f800000", "nan:0x7f800000", "nan:0x7ff8000000000001"] {
            let e = read32(s).unwrap_err().to_string();
            assert!(e.contains("expected a number"), "{s}: {e}");
        }
    }

    #[test]
    fn inputs_round_trip() {
        let items = vec![MissionItem {
            frame: 3,
            command: 16,
            autocontinue: true,
            params: [0.0, 1.5, f32::NAN, f32::from_bits(0x7fc0_1234)],
            x: 47.1,
            y: f64::NAN,
            z: 10.0,
        }];
        let inputs = [
            Input::Command(AutopilotCommand::Arm { force: false }),
            Input::Command(AutopilotCommand::SetMode(FlightMode::Offboard)),
            Input::Command(AutopilotCommand::Power(PowerAction::Reboot)),
            Input::Command(AutopilotCommand::Offboard(OffboardSetpoint::Local(
                crate::autopilot::Targets {
                    position: None,
                    velocity: Some(Vector3::new(1.0, f64::NAN, -0.1)),
                    acceleration: None,
                    yaw_rad: Some(f64::INFINITY),
                    yaw_rate_rad_s: None,
                },
            ))),
            Input::SetParam {
                name: "X".into(),
                value: ParamValue::Real32(f32::NAN),
            },
            Input::ChangePlans(PlanChange::Store {
                kind: MissionType::Mission,
                items,
                base_id: Some(3),
            }),
            Input::ChangePlans(PlanChange::Clear(None)),
            Input::GcsHeartbeat,
            Input::ClientTimeout {
                timer: ClientTimer::OffboardLoss,
                started_s: 1.25,
            },
            Input::Reboot,
        ];
        for i in &inputs {
            let back = round_trip(i);
            // Debug shows NaN as NaN; bits are checked through the JSON text
            assert_eq!(format!("{back:?}"), format!("{i:?}"));
            assert_eq!(
                to_exact_value(&back).unwrap().to_string(),
                to_exact_value(i).unwrap().to_string()
            );
        }
    }

    #[test]
    fn header_rebuilds_and_round_trips() {
        let h = test_header();
        let text = format!("{}\n{}\n", header_line(&h).unwrap(), end_line(0));
        let r = read_record(&text, "t").unwrap();
        assert_eq!(r.header, h);
        assert_eq!(r.end, Some(0));
        let (core, params) = h.build().unwrap();
        assert_eq!(core.steps(), 0);
        assert_eq!(params.len(), h.params.len());
        assert_eq!(core.pilot(0).client_clock(), ClientClock::Wall);
    }

    #[test]
    fn bad_records_are_refused_with_the_line() {
        let h = header_line(&test_header()).unwrap();
        let e = read_record("", "f.record").unwrap_err();
        assert!(e.contains("f.record: empty"), "{e}");
        let v2 = h.replacen("\"version\":1", "\"version\":2", 1);
        let e = read_record(&format!("{v2}\n"), "f.record").unwrap_err();
        assert_eq!(
            e,
            format!("f.record: format version 2, this rotorpilot reads version 1 (rotorpilot {ROTORPILOT_VERSION})")
        );
        let line = input_line(5, &Input::GcsHeartbeat, "done").unwrap();
        let e = read_record(&format!("{h}\n{}", &line[..line.len() - 3]), "f.record").unwrap_err();
        assert!(e.starts_with("f.record:2: cut short"), "{e}");
        let e = read_record(&format!("{h}\n{}\n", &line[..line.len() - 3]), "f.record").unwrap_err();
        assert!(e.starts_with("f.record:2: cut short"), "{e}");
        let e = read_record(&format!("{h}\n{line}\n[1, 2]\n"), "f.record").unwrap_err();
        assert!(e.starts_with("f.record:3: not a record line"), "{e}");
        let e = read_record(
            &format!("{h}\n{{\"step\":1,\"fly\":null,\"outcome\":\"\"}}\n"),
            "f.record",
        )
        .unwrap_err();
        assert!(e.starts_with("f.record:2: not a record line"), "{e}");
        let e = read_record("hello\n", "f.record").unwrap_err();
        assert!(e.contains("not a flight record"), "{e}");
        // one line, not JSON, no end of line: not a record (not "cut short")
        let e = read_record("hello", "f.record").unwrap_err();
        assert_eq!(
            e,
            "f.record: not a flight record (the first line is no rotorpilot-flight-record header)"
        );
        // a header cut mid-line is still cut short
        let e = read_record(&h[..h.len() / 2], "f.record").unwrap_err();
        assert!(e.starts_with("f.record:1: cut short"), "{e}");
        // a version that is not a whole number says so
        for bad in ["1.5", "\"1\"", "-1"] {
            let hv = h.replacen("\"version\":1", &format!("\"version\":{bad}"), 1);
            let e = read_record(&format!("{hv}\n"), "f.record").unwrap_err();
            assert_eq!(
                e,
                format!(
                    "f.record:1: the header's format version is {bad}, not a whole number (this rotorpilot reads version 1)"
                )
            );
        }
        let hv = h.replacen(",\"version\":1", "", 1);
        assert_ne!(hv, h);
        let e = read_record(&format!("{hv}\n"), "f.record").unwrap_err();
        assert_eq!(e, "f.record:1: the header has no format version");
        let later = input_line(9, &Input::GcsHeartbeat, "done").unwrap();
        let e = read_record(&format!("{h}\n{later}\n{line}\n"), "f.record").unwrap_err();
        assert!(e.starts_with("f.record:3: step 5 comes after step 9"), "{e}");
    }
}
