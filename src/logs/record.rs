//! Flight records: the format (the user's description is
//! `docs/record-format.md`), written line by line and read back.
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
//! Every number reads back bit for bit ([`crate::exact_json`]: NaN as the
//! string `"nan"` or `"nan:0x…"`, infinities as `"inf"` and `"-inf"`; JSON
//! has no number for them and MAVLink mission items carry NaN parameters).
//! `null` is "not given" (an absent optional value).
//!
//! An input line holds a [`crate::lockstep::input::Input`], the one way an
//! input reaches the core; [`super::replay`] re-flies a record through it.

use std::collections::BTreeMap;

use serde::Deserialize;
use serde::ser;
use serde_json::{Map, Value};

use crate::airframe::Airframe;
use crate::autopilot::{Autopilot, ClientClock};
use crate::exact_json;
use crate::geo::GeoPoint;
use crate::lockstep::Lockstep;
use crate::lockstep::input::Input;
use crate::mission::{MissionItem, MissionType, Plan, Plans};
use crate::params::{ParamStore, ParamValue};
use crate::sim::SensorConfig;

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
    m.insert("header".into(), exact_json::to_value(h)?);
    serde_json::to_string(&Value::Object(m))
}

/// An input line (no newline): the input applied at `step` and what the core answered.
///
/// # Errors
/// As [`header_line`].
pub fn input_line(step: u64, input: &Input, outcome: &str) -> Result<String, serde_json::Error> {
    let mut m = match exact_json::to_value(input)? {
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
        let input =
            exact_json::from_value::<Input>(Value::Object(m)).map_err(|e| format!("{at}: not a record line: {e}"))?;
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
    exact_json::from_value::<Header>(h.clone()).map_err(|e| format!("{at}: header: {e}"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::autopilot::{AutopilotCommand, ClientTimer};
    use crate::autopilot::{FlightMode, OffboardSetpoint, PowerAction};
    use crate::mission::PlanChange;
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
                exact_json::to_value(&back).unwrap().to_string(),
                exact_json::to_value(i).unwrap().to_string()
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
