//! The events protocol and component metadata as PX4 serves them to ground
//! stations and MAVSDK's Events plugin: the health and arming report as
//! EVENT messages, the event metadata that decodes them, and the general
//! metadata file that points to it.
//!
//! - **Events.** An EVENT carries an id, a sequence number (one counter per
//!   vehicle, from 0), the time since boot, log levels and up to 40 bytes of
//!   little-endian arguments; what the id means comes from the metadata.
//!   [`Reporter`] (one per vehicle) turns each [`HealthReport`] into PX4's
//!   sequence: an arming-check summary (per mode group: can arm, can run),
//!   one event per failing check (the mode groups it blocks, the component
//!   it concerns), a health summary; as PX4's commander does, a changed
//!   report at most every 2 s, a forced one (MAV_CMD_RUN_PREARM_CHECKS, an
//!   arming request) at once. [`EventLog`] (one per link) keeps the last 20
//!   for REQUEST_EVENT (answered from it, or with RESPONSE_EVENT_ERROR) and
//!   sends CURRENT_EVENT_SEQUENCE every 3 s so a client notices a gap. A
//!   failsafe that starts is an event too ([`failsafe_event`]), in the words
//!   of its STATUSTEXT.
//! - **Mode groups** are PX4's navigation states: bit `n` of a mode mask is
//!   the mode whose `vehicle_status.nav_state` is `n` ([`group`]); the
//!   metadata lists the heartbeat's custom mode of each.
//! - **Metadata.** COMPONENT_METADATA (on MAV_CMD_REQUEST_MESSAGE) names
//!   `mftp://etc/extras/component_general.json` and its CRC; that file
//!   (metadata version 1) names the events file, which this module writes
//!   from the same tables it encodes by ([`events_json`]). Both are served
//!   by MAVLink FTP ([`metadata_file`]), plain JSON (PX4 serves them
//!   xz-compressed; clients decompress only a name ending in `.xz`).
//!
//! Event ids are PX4's: the low 24 bits of the FNV-1a hash of the event's
//! name, the component (1, the autopilot) in the top byte ([`event_id`]).

use std::collections::VecDeque;
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use mavlink::dialects::common::{
    COMPONENT_METADATA_DATA, CURRENT_EVENT_SEQUENCE_DATA, EVENT_DATA, MavEventCurrentSequenceFlags,
    MavEventErrorReason, MavMessage, RESPONSE_EVENT_ERROR_DATA,
};
use serde_json::{Map, Value, json};

use crate::autopilot::{
    CHECK_TEXTS, FAILSAFE_ACTIONS, FAILSAFE_CAUSES, FlightMode, HealthComponent, HealthReport, ModeSet,
};

use super::convert;

/// Where COMPONENT_METADATA points: the general metadata file, by MAVLink FTP.
pub const GENERAL_URI: &str = "mftp://etc/extras/component_general.json";
/// The general metadata file's path on the FTP server.
const GENERAL_PATH: &str = "etc/extras/component_general.json";
/// The event metadata file's path on the FTP server.
const EVENTS_PATH: &str = "etc/extras/all_events.json";
/// COMP_METADATA_TYPE_EVENTS.
const METADATA_TYPE_EVENTS: u32 = 4;

/// Events a link keeps for REQUEST_EVENT (PX4's event buffer).
pub const LOG_CAPACITY: usize = 20;
/// CURRENT_EVENT_SEQUENCE's period on a link (PX4's 3 s).
pub const CURRENT_SEQUENCE_PERIOD: Duration = Duration::from_secs(3);
/// A changed report waits this long after the last one [s] (PX4's 2 s).
pub const MIN_REPORT_INTERVAL_S: f64 = 2.0;
/// How often the checks are run for a changed report [s].
pub const CHECK_PERIOD_S: f64 = 0.1;

/// Log levels byte: internal level in the high nibble, external in the low.
const LOG_PROTOCOL: u8 = 0x88;
/// Log levels byte of a failing check: Error, internal and external.
const LOG_ERROR: u8 = 0x33;

/// Log levels byte of a failsafe: Critical, internal and external.
const LOG_CRITICAL: u8 = 0x22;
/// The name of the failsafe event.
const FAILSAFE: &str = "commander_failsafe_activated";

/// The name of the arming-check summary event (PX4's).
const ARMING_SUMMARY: &str = "commander_arming_check_summary";
/// The name of the health summary event (PX4's).
const HEALTH_SUMMARY: &str = "commander_health_summary";

/// PX4's event id of `name`: FNV-1a 32 of the name's bytes, its low 24
/// bits, with the autopilot component (1) in the top byte:
/// `id = (fnv1a32(name) & 0xFF_FFFF) | 1 << 24`.
#[must_use]
pub const fn event_id(name: &str) -> u32 {
    let bytes = name.as_bytes();
    let mut hash: u32 = 0x811C_9DC5;
    let mut i = 0;
    while i < bytes.len() {
        hash = (hash ^ bytes[i] as u32).wrapping_mul(0x0100_0193);
        i += 1;
    }
    (hash & 0xFF_FFFF) | 1 << 24
}

/// PX4's mode group of `mode`: its bit in a mode mask (the mode's
/// `nav_state`), name and description; `None` for Descend, which has no
/// group (clients see it as Land).
fn group(mode: FlightMode) -> Option<(u32, &'static str, &'static str)> {
    let (name, description) = match mode {
        FlightMode::Manual => ("manual", "Manual"),
        FlightMode::Altitude => ("altctl", "Altitude"),
        FlightMode::Position => ("posctl", "Position"),
        FlightMode::Mission => ("mission", "Mission"),
        FlightMode::Hold => ("loiter", "Hold"),
        FlightMode::ReturnToLaunch => ("rtl", "Return"),
        FlightMode::Acro => ("acro", "Acro"),
        FlightMode::Offboard => ("offboard", "Offboard"),
        FlightMode::Stabilized => ("stab", "Stabilized"),
        FlightMode::Takeoff => ("takeoff", "Takeoff"),
        FlightMode::Land => ("land", "Land"),
        FlightMode::FollowTarget => ("follow_target", "Follow Target"),
        FlightMode::Orbit => ("orbit", "Orbit"),
        FlightMode::Descend => return None,
    };
    Some((u32::from(mode.nav_state()), name, description))
}

/// `modes` as a mode-group mask (bit = the mode's `nav_state`, [`group`]).
fn group_mask(modes: ModeSet) -> u32 {
    modes.iter().filter_map(group).fold(0, |m, (bit, ..)| m | 1 << bit)
}

/// PX4's health component bit, name and label of `c`.
fn component(c: HealthComponent) -> (u32, &'static str, &'static str) {
    match c {
        HealthComponent::None => (1, "none", "None"),
        HealthComponent::Gps => (8, "gps", "GPS"),
        HealthComponent::RemoteControl => (128, "remote_control", "Remote Control (RC or Joystick)"),
        HealthComponent::MotorsEscs => (256, "motors_escs", "Motors/ESCs"),
        HealthComponent::Battery => (2048, "battery", "Battery"),
        HealthComponent::CommunicationLinks => (4096, "communication_links", "Communication links"),
        HealthComponent::Mission => (262_144, "mission", "Mission"),
        HealthComponent::AttitudeEstimate => (65_536, "attitude_estimate", "Attitude estimate"),
        HealthComponent::LocalPositionEstimate => (131_072, "local_position_estimate", "Local position estimate"),
        HealthComponent::GlobalPositionEstimate => (16_777_216, "global_position_estimate", "Global position estimate"),
    }
}

/// Every component a report can name.
const COMPONENTS: [HealthComponent; 10] = [
    HealthComponent::None,
    HealthComponent::Gps,
    HealthComponent::RemoteControl,
    HealthComponent::MotorsEscs,
    HealthComponent::Battery,
    HealthComponent::CommunicationLinks,
    HealthComponent::Mission,
    HealthComponent::AttitudeEstimate,
    HealthComponent::LocalPositionEstimate,
    HealthComponent::GlobalPositionEstimate,
];

/// The components the simulated vehicle has (health summary `is_present`):
/// all but "none", the sticks and the mission.
fn present_mask() -> u32 {
    COMPONENTS
        .iter()
        .filter(|c| {
            !matches!(
                c,
                HealthComponent::None | HealthComponent::RemoteControl | HealthComponent::Mission
            )
        })
        .fold(0, |m, c| m | component(*c).0)
}

/// The name of the event of the check `text` ("no GPS fix" → `check_no_gps_fix`).
fn check_name(text: &str) -> String {
    let snake: String = text
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() {
                c.to_ascii_lowercase()
            } else {
                '_'
            }
        })
        .collect();
    format!("check_{snake}")
}

/// The message of the check `text`: its first letter capitalised.
fn check_message(text: &str) -> String {
    let mut c = text.chars();
    c.next()
        .map(|f| f.to_uppercase().chain(c).collect())
        .unwrap_or_default()
}

/// The event of a check whose text the metadata does not list.
const OTHER_CHECK: &str = "check_failed";

/// An event before its sequence number and time.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Pending {
    /// The event id ([`event_id`]).
    pub id: u32,
    /// Log levels byte.
    pub log_levels: u8,
    /// Arguments, little-endian, zero-padded.
    pub arguments: [u8; 40],
}

/// Packs arguments little-endian into an event's 40 bytes.
struct Args {
    bytes: [u8; 40],
    len: usize,
}

impl Default for Args {
    fn default() -> Self {
        Self { bytes: [0; 40], len: 0 }
    }
}

impl Args {
    fn put(mut self, v: &[u8]) -> Self {
        self.bytes[self.len..self.len + v.len()].copy_from_slice(v);
        self.len += v.len();
        self
    }
    fn u8(self, v: u8) -> Self {
        self.put(&[v])
    }
    fn u32(self, v: u32) -> Self {
        self.put(&v.to_le_bytes())
    }
}

/// The events of `report`, as PX4's commander sends a report: the
/// arming-check summary (chunk 0, the components the failing checks concern
/// as errors, no warnings, can-arm and can-run mode groups), each failing
/// check (mode groups, component bit index), the health summary (chunk 0,
/// the components present, those whose health fails, no warnings).
#[must_use]
pub fn health_events(report: &HealthReport) -> Vec<Pending> {
    // the arming checks' errors: every component a failing check concerns
    let arming_errors = report
        .checks
        .iter()
        .filter(|c| c.component != HealthComponent::None)
        .fold(0, |m, c| m | component(c.component).0);
    let health_errors = report.health_errors().fold(0, |m, c| m | component(c).0);
    let mut out = Vec::with_capacity(report.checks.len() + 2);
    let summary = Args::default()
        .u8(0)
        .u32(arming_errors)
        .u32(0)
        .u32(group_mask(report.can_arm))
        .u32(group_mask(report.can_run));
    out.push(Pending {
        id: event_id(ARMING_SUMMARY),
        log_levels: LOG_PROTOCOL,
        arguments: summary.bytes,
    });
    for c in &report.checks {
        let name = if CHECK_TEXTS.contains(&c.text) {
            check_name(c.text)
        } else {
            OTHER_CHECK.to_owned()
        };
        let index = component(c.component).0.trailing_zeros() as u8;
        out.push(Pending {
            id: event_id(&name),
            log_levels: LOG_ERROR,
            arguments: Args::default().u32(group_mask(c.modes)).u8(index).bytes,
        });
    }
    let health = Args::default().u8(0).u32(present_mask()).u32(health_errors).u32(0);
    out.push(Pending {
        id: event_id(HEALTH_SUMMARY),
        log_levels: LOG_PROTOCOL,
        arguments: health.bytes,
    });
    out
}

/// The event of a failsafe acting for `cause` with `action` (the words of
/// its STATUSTEXT, "Failsafe: {cause}, triggering {action}"): their places
/// in [`FAILSAFE_CAUSES`] and [`FAILSAFE_ACTIONS`] from 1, 0 for one the
/// metadata does not list.
#[must_use]
pub fn failsafe_event(cause: &str, action: &str) -> Pending {
    let place = |list: &[&str], x: &str| list.iter().position(|c| *c == x).map_or(0, |i| i as u8 + 1);
    Pending {
        id: event_id(FAILSAFE),
        log_levels: LOG_CRITICAL,
        arguments: Args::default()
            .u8(place(&FAILSAFE_CAUSES, cause))
            .u8(place(&FAILSAFE_ACTIONS, action))
            .bytes,
    }
}

/// A closed list as an enum of the metadata: 0 `other`, then each entry.
fn enum_entries(list: &[&str]) -> Map<String, Value> {
    let mut entries = Map::new();
    entries.insert("0".into(), json!({ "name": "other", "description": "other" }));
    for (i, text) in list.iter().enumerate() {
        let name = text.to_lowercase().replace(' ', "_");
        entries.insert((i + 1).to_string(), json!({ "name": name, "description": text }));
    }
    entries
}

/// One vehicle's event source: the sequence counter and PX4's rule for
/// when a health report goes out.
#[derive(Clone, Debug)]
pub struct Reporter {
    /// The next event's sequence number.
    next_sequence: u16,
    /// The last report sent, and when [s].
    last: Option<(HealthReport, f64)>,
    /// When the checks run next [s].
    next_check_s: f64,
    /// The failsafe last said (cause, action), while one is in force.
    failsafe_said: Option<(String, &'static str)>,
}

impl Default for Reporter {
    fn default() -> Self {
        Self {
            next_sequence: 0,
            last: None,
            next_check_s: f64::NEG_INFINITY,
            failsafe_said: None,
        }
    }
}

impl Reporter {
    /// Whether the checks are to run at `now_s` [s] (every [`CHECK_PERIOD_S`]).
    #[must_use]
    pub fn due(&self, now_s: f64) -> bool {
        now_s >= self.next_check_s
    }

    /// The checks ran at `now_s` [s] and gave `report`: the events to send
    /// (none if nothing is to be said). A report is sent when `forced`, or
    /// when it differs from the last one sent and that one is at least
    /// [`MIN_REPORT_INTERVAL_S`] old (a change meanwhile waits for it).
    pub fn update(&mut self, now_s: f64, report: HealthReport, forced: bool) -> Vec<EVENT_DATA> {
        self.next_check_s = now_s + CHECK_PERIOD_S;
        let send = forced
            || match &self.last {
                None => true,
                Some((last, at)) => *last != report && now_s - at >= MIN_REPORT_INTERVAL_S,
            };
        if !send {
            return Vec::new();
        }
        let events = health_events(&report)
            .into_iter()
            .map(|p| self.stamp(now_s, p))
            .collect();
        self.last = Some((report, now_s));
        events
    }

    /// The failsafe in force at `now_s` [s] (its cause and the action it
    /// triggered, as announced; `None`: none): its event if it was not said
    /// yet, a new cause or a new action for it ([`failsafe_event`]).
    pub fn failsafe(&mut self, now_s: f64, in_force: Option<(&str, &'static str)>) -> Option<EVENT_DATA> {
        let said = self.failsafe_said.as_ref().map(|(c, a)| (c.as_str(), *a));
        if in_force == said {
            return None;
        }
        self.failsafe_said = in_force.map(|(c, a)| (c.to_owned(), a));
        let (cause, action) = in_force?;
        Some(self.stamp(now_s, failsafe_event(cause, action)))
    }

    /// `p` with the next sequence number and the time `now_s` [s].
    fn stamp(&mut self, now_s: f64, p: Pending) -> EVENT_DATA {
        let sequence = self.next_sequence;
        self.next_sequence = sequence.wrapping_add(1);
        EVENT_DATA {
            id: p.id,
            event_time_boot_ms: (now_s * 1e3) as u32,
            sequence,
            // broadcast, as PX4 sends every event
            destination_component: 0,
            destination_system: 0,
            log_levels: p.log_levels,
            arguments: p.arguments,
        }
    }
}

/// One link's events: the last [`LOG_CAPACITY`] sent, and when the next
/// CURRENT_EVENT_SEQUENCE is due.
#[derive(Clone, Debug)]
pub struct EventLog {
    events: VecDeque<EVENT_DATA>,
    next_current: Instant,
}

impl EventLog {
    /// No events yet; CURRENT_EVENT_SEQUENCE due at `now`.
    #[must_use]
    pub fn new(now: Instant) -> Self {
        Self {
            events: VecDeque::with_capacity(LOG_CAPACITY),
            next_current: now,
        }
    }

    /// Keep `e` (the oldest goes when full).
    pub fn keep(&mut self, e: &EVENT_DATA) {
        if self.events.len() == LOG_CAPACITY {
            self.events.pop_front();
        }
        self.events.push_back(e.clone());
    }

    /// When CURRENT_EVENT_SEQUENCE is due next.
    #[must_use]
    pub fn next_deadline(&self) -> Instant {
        self.next_current
    }

    /// CURRENT_EVENT_SEQUENCE if due at `now`: the latest sequence sent
    /// (65535 before the first, flagged RESET while none is kept, as PX4).
    pub fn current_sequence(&mut self, now: Instant) -> Option<MavMessage> {
        if now < self.next_current {
            return None;
        }
        self.next_current = now + CURRENT_SEQUENCE_PERIOD;
        let flags = if self.events.is_empty() {
            MavEventCurrentSequenceFlags::MAV_EVENT_CURRENT_SEQUENCE_FLAGS_RESET
        } else {
            MavEventCurrentSequenceFlags::empty()
        };
        Some(MavMessage::CURRENT_EVENT_SEQUENCE(CURRENT_EVENT_SEQUENCE_DATA {
            sequence: self.events.back().map_or(u16::MAX, |e| e.sequence),
            flags,
        }))
    }

    /// The answer to REQUEST_EVENT for `first..=last` (wrapping) from
    /// `requester`: each kept event again, else RESPONSE_EVENT_ERROR naming
    /// the oldest one kept after it. More than the log holds is answered
    /// with one error for the part that cannot be kept, as PX4.
    #[must_use]
    pub fn request(&self, first: u16, last: u16, requester: (u8, u8)) -> Vec<MavMessage> {
        let end = last.wrapping_add(1);
        let mut seq = first;
        let mut out = Vec::new();
        let requested = end.wrapping_sub(seq);
        if usize::from(requested) > LOG_CAPACITY {
            out.push(self.unavailable(seq, requester));
            seq = end.wrapping_sub(LOG_CAPACITY as u16);
        }
        while seq != end {
            match self.events.iter().find(|e| e.sequence == seq) {
                Some(e) => out.push(MavMessage::EVENT(e.clone())),
                None => out.push(self.unavailable(seq, requester)),
            }
            seq = seq.wrapping_add(1);
        }
        out
    }

    /// RESPONSE_EVENT_ERROR for `seq`: the nearest kept sequence after it.
    fn unavailable(&self, seq: u16, requester: (u8, u8)) -> MavMessage {
        let oldest = self
            .events
            .iter()
            .map(|e| e.sequence)
            .filter(|s| *s != seq)
            .min_by_key(|s| s.wrapping_sub(seq))
            .or_else(|| self.events.back().map(|e| e.sequence))
            .unwrap_or(u16::MAX);
        MavMessage::RESPONSE_EVENT_ERROR(RESPONSE_EVENT_ERROR_DATA {
            sequence: seq,
            sequence_oldest_available: oldest,
            target_system: requester.0,
            target_component: requester.1,
            reason: MavEventErrorReason::MAV_EVENT_ERROR_REASON_UNAVAILABLE,
        })
    }
}

/// An event's argument in the metadata.
fn arg(name: &str, ty: &str) -> Value {
    json!({ "name": name, "type": ty })
}

/// The event metadata (libevents' format, version 2): component 1 in
/// PX4's namespace, the health-and-arming-check protocol, the mode groups
/// with the custom modes of each, the two enums, and the events
/// [`health_events`] sends.
#[must_use]
pub fn events_json() -> &'static [u8] {
    static FILE: OnceLock<Vec<u8>> = OnceLock::new();
    FILE.get_or_init(|| {
        let mut groups = Map::new();
        let mut group_entries = Map::new();
        for mode in FlightMode::ALL {
            let Some((bit, name, description)) = group(mode) else {
                continue;
            };
            groups.insert(bit.to_string(), json!([convert::custom_mode(mode)]));
            group_entries.insert(
                (1u32 << bit).to_string(),
                json!({ "name": name, "description": description }),
            );
        }
        let mut component_entries = Map::new();
        for c in COMPONENTS {
            let (bit, name, label) = component(c);
            component_entries.insert(bit.to_string(), json!({ "name": name, "description": label }));
        }
        let check_args = json!([
            arg("modes", "navigation_mode_group_t"),
            arg("health_component_index", "uint8_t")
        ]);
        let mut arming = Map::new();
        arming.insert(
            (event_id(ARMING_SUMMARY) & 0xFF_FFFF).to_string(),
            json!({
                "name": ARMING_SUMMARY, "type": "summary", "message": "Arming check summary event",
                "arguments": [arg("chunk_idx", "uint8_t"), arg("error", "health_component_t"),
                    arg("warning", "health_component_t"), arg("can_arm", "navigation_mode_group_t"),
                    arg("can_run", "navigation_mode_group_t")],
            }),
        );
        let checks = CHECK_TEXTS
            .iter()
            .map(|t| (check_name(t), check_message(t)))
            .chain([(OTHER_CHECK.to_owned(), "Arming check failed".to_owned())]);
        for (name, message) in checks {
            arming.insert(
                (event_id(&name) & 0xFF_FFFF).to_string(),
                json!({ "name": name, "message": message, "arguments": check_args }),
            );
        }
        let health = json!({ (event_id(HEALTH_SUMMARY) & 0xFF_FFFF).to_string(): {
            "name": HEALTH_SUMMARY, "type": "summary", "message": "Health report summary event",
            "arguments": [arg("chunk_idx", "uint8_t"), arg("is_present", "health_component_t"),
                arg("error", "health_component_t"), arg("warning", "health_component_t")],
        }});
        let file = json!({
            "version": 2,
            "components": { "1": {
                "namespace": "px4",
                "supported_protocols": ["health_and_arming_check"],
                "navigation_mode_groups": { "groups": groups },
                "enums": {
                    "navigation_mode_group_t": {
                        "type": "uint32_t", "is_bitfield": true,
                        "description": "Flight mode groups: one per PX4 navigation state",
                        "entries": group_entries,
                    },
                    "health_component_t": {
                        "type": "uint32_t", "is_bitfield": true,
                        "description": "Subsystems and components",
                        "entries": component_entries,
                    },
                    "failsafe_cause_t": {
                        "type": "uint8_t", "description": "Why a failsafe acts",
                        "entries": enum_entries(&FAILSAFE_CAUSES),
                    },
                    "failsafe_action_t": {
                        "type": "uint8_t", "description": "What a failsafe does",
                        "entries": enum_entries(&FAILSAFE_ACTIONS),
                    },
                },
                "event_groups": {
                    "arming_check": { "events": arming },
                    "health": { "events": health },
                    "default": { "events": {
                        (event_id(FAILSAFE) & 0xFF_FFFF).to_string(): {
                            "name": FAILSAFE, "message": "Failsafe: {1}, triggering {2}",
                            "arguments": [arg("cause", "failsafe_cause_t"), arg("action", "failsafe_action_t")],
                        },
                    }},
                },
            }},
        });
        serde_json::to_vec_pretty(&file).unwrap_or_default()
    })
}

/// The general metadata (version 1): where the event metadata is, and its CRC.
#[must_use]
pub fn general_json() -> &'static [u8] {
    static FILE: OnceLock<Vec<u8>> = OnceLock::new();
    FILE.get_or_init(|| {
        let file = json!({
            "version": 1,
            "metadataTypes": [{
                "type": METADATA_TYPE_EVENTS,
                "uri": format!("mftp://{EVENTS_PATH}"),
                "fileCrc": crc(events_json()),
            }],
        });
        serde_json::to_vec_pretty(&file).unwrap_or_default()
    })
}

/// The CRC32 a metadata file is named with (as FTP's CalcFileCRC32 sums it).
fn crc(bytes: &[u8]) -> u32 {
    crate::mission::crc::crc32part(bytes, 0)
}

/// The metadata file at FTP `path` (with or without a leading `/`), if it is one.
#[must_use]
pub fn metadata_file(path: &str) -> Option<&'static [u8]> {
    match path.trim_start_matches('/') {
        GENERAL_PATH => Some(general_json()),
        EVENTS_PATH => Some(events_json()),
        _ => None,
    }
}

/// COMPONENT_METADATA, as PX4 answers MAV_CMD_REQUEST_MESSAGE for it
/// (`time_s` [s] since boot).
#[must_use]
pub fn component_metadata(time_s: f64) -> MavMessage {
    MavMessage::COMPONENT_METADATA(COMPONENT_METADATA_DATA {
        time_boot_ms: (time_s * 1e3) as u32,
        file_crc: crc(general_json()),
        uri: GENERAL_URI.into(),
    })
}

#[cfg(test)]
mod tests;
