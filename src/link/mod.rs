//! MAVLink 2 over UDP as PX4 SITL speaks it, as a sans-I/O state machine:
//! datagrams and the time go in, addressed frames and [`Effect`]s for the
//! daemon come out. No sockets, no tokio, no clock here: the daemon
//! ([`crate::daemon`]) owns the sockets and the lockstep core and calls in.
//!
//! One [`Link`] per UDP socket (PX4 SITL has a GCS link and an API link).
//! Each serves a set of [`peers::Peers`] (its default remote from boot, plus
//! everyone who talks, with a timeout), sends its own telemetry streams at
//! its own rates ([`streams`]), answers the command, parameter, timesync,
//! ping, FTP and mission protocols, and turns commands and offboard
//! setpoints into [`AutopilotCommand`]s and uploads into plan changes. It
//! translates only: whether a command is accepted, what a relative frame
//! means and whether a complete plan is stored are decided by the autopilot
//! at the instant it applies them (the ACK carries that answer). Everything
//! `docs/mavlink.md` promises a client is
//! decided here; the files:
//!
//! | file | job |
//! |---|---|
//! | [`wire`] | framing (v1 and v2 in, v2 out), hand-coded COMMAND_LONG/INT/ACK and MISSION_ITEM(_INT) |
//! | [`convert`] | PX4 custom_mode, MAV_RESULT, units (degE7, cdeg, mm) |
//! | [`command`] | COMMAND_LONG/INT/SET_MODE classified as PX4 does |
//! | [`param`] | PARAM_* protocol, INT32 bytewise |
//! | [`mission`] | MISSION_* protocol: upload, download, clear, set current, progress |
//! | [`offboard`] | SET_POSITION_TARGET_* and SET_ATTITUDE_TARGET to setpoints |
//! | [`manual`] | MANUAL_CONTROL to sticks |
//! | [`streams`] | stream rates, scheduler, message builders from a [`Snapshot`] |
//! | [`peers`] | default remote plus learned peers with a timeout; proven and unproven peers |
//! | [`budget`] | byte budgets: token buckets and an unproven peer's credit (no amplification) |
//! | [`signing`] | MAVLink 2 signing: the key, the gate on input, signatures on output |
//! | [`ftp`] | MAVLink FTP: sessions, bursts, `@PARAM/param.pck`, over a [`ftp::FileStore`] |
//! | [`log_download`] | LOG_REQUEST_* / LOG_ENTRY / LOG_DATA over the store's ULogs |
//! | [`forward`] | forwarding between a vehicle's links, by PX4's rule (`mavlink start -f`) |
//! | [`events`] | the events protocol (health and arming report), component metadata |

// PX4 and its clients still speak messages the XML marks deprecated
// (SET_MODE, PING, ...): we must too.
#![allow(deprecated)]

pub mod budget;
pub mod command;
pub mod convert;
pub mod events;
pub mod forward;
pub mod ftp;
pub mod log_download;
pub mod manual;
pub mod mission;
pub mod offboard;
pub mod param;
pub mod peers;
pub mod signing;
pub mod streams;
#[cfg(test)]
pub(crate) mod testing;
pub mod wire;

use std::net::SocketAddr;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use mavlink::dialects::common::{
    AUTOPILOT_VERSION_DATA, AVAILABLE_MODES_DATA, COMPONENT_METADATA_DATA, EVENT_DATA, HEARTBEAT_DATA, MavMessage,
    MavProtocolCapability, MavSeverity, PING_DATA, STATUSTEXT_DATA, TIMESYNC_DATA,
};
use mission::{ItemMode, Missions, Partner, PlanTicket};

use crate::autopilot::{AutopilotCommand, CommandOutcome, Severity, StatusText, cut_status_text, status_text_lines};
use crate::lockstep::Snapshot;
use crate::mission::{MissionResult, PlanChange};
use crate::params::ParamValue;
use command::{Action, Command};
use param::ParamAccess;
use streams::{Identity, Rates, Scheduler, Stream};
use wire::{CommandAck, Encoder, Frame, Inbound, MissionItemMsg};

/// AUTOPILOT_VERSION capabilities: PX4's set (MISSION_FLOAT, PARAM_FLOAT,
/// MISSION_INT, COMMAND_INT, FTP, SET_ATTITUDE_TARGET,
/// SET_POSITION_TARGET_LOCAL_NED and _GLOBAL_INT, MAVLINK2, MISSION_FENCE,
/// MISSION_RALLY) plus PARAM_ENCODE_BYTEWISE: 57855.
pub const CAPABILITIES: u64 = 57_855;
/// AUTOPILOT_VERSION flight_sw_version: 1.16.0 release, as PX4 encodes it.
pub const FLIGHT_SW_VERSION: u32 = 0x0110_00FF;

/// How a link is set up.
#[derive(Clone, Debug)]
pub struct LinkConfig {
    /// Name for logs ("gcs", "api", "udpout:HOST:PORT", ...).
    pub name: String,
    /// Our system and component id.
    pub identity: Identity,
    /// Where to send from boot, before anyone talks (PX4's default remote).
    pub default_remote: Option<SocketAddr>,
    /// Default stream rates.
    pub rates: Rates,
    /// A learned peer is forgotten after this long without a frame from it.
    pub peer_timeout: Duration,
}

/// Where a frame goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum To {
    /// One peer (the requester).
    Peer(SocketAddr),
    /// Every active peer of the link.
    All,
}

/// One encoded frame to send.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Outgoing {
    /// Destination.
    pub to: To,
    /// A complete MAVLink 2 frame.
    pub bytes: Vec<u8>,
}

/// What to ACK once the autopilot has answered a command.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AckTicket {
    /// The command id to acknowledge (176 for SET_MODE).
    pub command: u16,
    /// Who asked.
    pub to: SocketAddr,
    /// The requester's system and component id (ACK target).
    pub requester: (u8, u8),
}

/// What to answer once a PARAM_SET has been applied or refused.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ParamTicket {
    /// Parameter name.
    pub name: String,
    /// Its index.
    pub index: usize,
    /// Who asked.
    pub to: SocketAddr,
    /// The requester's system and component id.
    pub requester: (u8, u8),
}

/// What the daemon must do beyond sending frames.
#[derive(Clone, Debug, PartialEq)]
pub enum Effect {
    /// Give the autopilot a command, then pass its outcome to
    /// [`Link::on_outcome`] with the ticket (offboard setpoints have none).
    Autopilot {
        /// The command.
        command: AutopilotCommand,
        /// ACK to send with the outcome.
        ack: Option<AckTicket>,
    },
    /// Set a parameter (type already checked): store it and apply it to the
    /// autopilot, then pass the outcome to [`Link::on_param_set`].
    SetParam {
        /// Who asked, for the answer.
        ticket: ParamTicket,
        /// The value to set.
        value: ParamValue,
    },
    /// Store or clear plans in the flight stack (whole or not at all), then
    /// pass its answer to [`Link::on_plans_changed`] with the ticket.
    Plans {
        /// Who asked, for the MISSION_ACK.
        ticket: PlanTicket,
        /// The change.
        change: PlanChange,
    },
    /// MISSION_SET_CURRENT: give the autopilot
    /// [`AutopilotCommand::SetMissionCurrent`], then pass its outcome to
    /// [`Link::on_mission_current_set`] (the answer is a MISSION_CURRENT).
    SetMissionCurrent {
        /// The item to make current.
        seq: u16,
    },
    /// A ground station's HEARTBEAT (MAV_TYPE_GCS) arrived: tell the
    /// autopilot the data link is alive (no answer).
    GcsHeartbeat,
    /// SETUP_SIGNING changed (or cleared) the vehicle's signing key, already
    /// in force on every link of the vehicle: store it (no answer, as PX4).
    SigningKeyChanged,
}

/// One MAVLink link (one UDP socket's worth of protocol state).
#[derive(Debug)]
pub struct Link {
    config: LinkConfig,
    encoder: Encoder,
    peers: peers::Peers,
    streams: Scheduler,
    missions: Missions,
    outbox: Vec<Outgoing>,
    delayed: Vec<(Instant, Outgoing)>,
    due: Vec<Stream>,
    stats: LinkStats,
    /// The vehicle's signing state (shared by its links) and this link's id in it.
    signing: (signing::Shared, u8),
    /// The latest time given to the link: what direct answers are charged at.
    clock: Instant,
    /// Parameter lists being sent, paced ([`Link::poll`]).
    param_lists: Vec<ParamList>,
    /// The link's streams to all peers together.
    stream_budget: budget::TokenBucket,
    /// MAVLink FTP: the session, a burst, the files served.
    ftp: ftp::Server,
    /// Log download: the list and the transfer.
    logs: log_download::Server,
    /// Forwarding to and from the vehicle's other links (`None`: it has none).
    forwarding: Option<forward::Forwarding>,
    /// The raw sensors' simulation: not asked for, to ask for (a raw
    /// sensor stream came due), asked for.
    raw_sensors: RawDemand,
    /// The events sent lately, for REQUEST_EVENT, and CURRENT_EVENT_SEQUENCE's turn.
    events: events::EventLog,
}

/// Whether a link needs the vehicle's raw sensors simulated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum RawDemand {
    /// No raw sensor stream came due yet.
    None,
    /// One came due: the runtime is to start the raw sensors.
    Wanted,
    /// The runtime was told.
    Asked,
}

/// A PARAM_REQUEST_LIST being answered: PX4 sends one parameter per
/// iteration of its link loop, not the whole list at once; here
/// [`PARAMS_PER_TURN`] every [`PARAM_LIST_TURN`], each charged to the
/// requester's budget (the list waits while the budget is spent).
#[derive(Clone, Debug)]
struct ParamList {
    to: SocketAddr,
    values: Vec<MavMessage>,
    next: usize,
    due: Instant,
    /// Since when the budget has held the next value back (`None`: not held).
    held_since: Option<Instant>,
}

/// Parameters a list sends per turn.
const PARAMS_PER_TURN: usize = 20;
/// A list's turn comes this often: at most 2,000 PARAM_VALUEs/s per list
/// (PX4 SITL's ~1,300 parameters in about 0.7 s).
const PARAM_LIST_TURN: Duration = Duration::from_millis(10);
/// A list held back by the budget this long is dropped (an unproven
/// requester that never proves it listens).
const PARAM_LIST_STALL: Duration = Duration::from_secs(3);
/// At most this many lists at once; a new one from a proven peer replaces
/// one for an unproven peer.
const MAX_PARAM_LISTS: usize = 8;
/// A PARAM_VALUE frame's largest size (MAVLink 2, 25-byte payload, unsigned).
const PARAM_VALUE_FRAME: usize = 12 + 25;

/// Counters for logs and tests.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkStats {
    /// Frames received with a valid CRC.
    pub frames_in: u64,
    /// Frames that did not decode, came back with our own ids, or were
    /// commands for another system or component.
    pub ignored: u64,
    /// Direct answers dropped because the requester's budget was spent
    /// ([`budget`]).
    pub held_back: u64,
    /// Stream messages skipped because the link's stream budget was spent.
    pub streams_shed: u64,
    /// Frames from the vehicle's other links sent on this one ([`forward`]).
    pub forwarded: u64,
    /// Frames from the other links dropped because this link's forwarding
    /// budget was spent.
    pub forward_shed: u64,
}

impl Link {
    /// A link whose streams all start due at `now`.
    #[must_use]
    pub fn new(config: LinkConfig, now: Instant) -> Self {
        let encoder = Encoder::new(config.identity.system_id, config.identity.component_id);
        let peers = peers::Peers::new(config.default_remote, config.peer_timeout, now);
        let streams = Scheduler::new(now, &config.rates);
        Self {
            config,
            encoder,
            peers,
            streams,
            missions: Missions::new(),
            outbox: Vec::new(),
            delayed: Vec::new(),
            due: Vec::new(),
            stats: LinkStats::default(),
            signing: (Arc::new(Mutex::new(signing::Signing::unkeyed(now, 0))), 0),
            clock: now,
            param_lists: Vec::new(),
            stream_budget: budget::TokenBucket::new(now, budget::LINK_STREAM_RATE, 2.0 * budget::LINK_STREAM_RATE),
            ftp: ftp::Server::new(Box::new(ftp::NoFiles), now),
            logs: log_download::Server::default(),
            forwarding: None,
            raw_sensors: RawDemand::None,
            events: events::EventLog::new(now),
        }
    }

    /// True once, after a stream of raw sensor messages first came due
    /// ([`Stream::needs_raw_sensors`]): the runtime then starts the
    /// vehicle's raw sensors (they are off until something reads them).
    pub fn take_raw_sensors_request(&mut self) -> bool {
        let wanted = self.raw_sensors == RawDemand::Wanted;
        if wanted {
            self.raw_sensors = RawDemand::Asked;
        }
        wanted
    }

    /// Forward to and from the vehicle's other links ([`forward`]); `fellows`
    /// is this link's handle of the vehicle's shared state. A new link
    /// forwards nothing (its vehicle has no other link).
    pub fn set_forwarding(&mut self, fellows: forward::Fellows) {
        self.forwarding = Some(forward::Forwarding::new(fellows, self.clock));
    }

    /// The frames received since the last call that go to the vehicle's
    /// other links (each link then decides with [`Link::pass`]).
    pub fn take_forwarded(&mut self) -> Vec<forward::Forwarded> {
        self.forwarding
            .as_mut()
            .map(forward::Forwarding::take)
            .unwrap_or_default()
    }

    /// A frame received on another link of the vehicle: queued, as it is,
    /// for this link's peers if PX4 would pass it here ([`forward`]).
    pub fn pass(&mut self, now: Instant, f: &forward::Forwarded) -> forward::Passed {
        self.tick(now);
        let Some(fwd) = self.forwarding.as_mut() else {
            return forward::Passed::NotSeen;
        };
        let fanout = self.peers.active_count(now);
        let passed = fwd.pass(now, f, fanout);
        match passed {
            forward::Passed::Sent => self.stats.forwarded += 1,
            forward::Passed::OverBudget => self.stats.forward_shed += 1,
            _ => {}
        }
        passed
    }

    /// Serve `files` by MAVLink FTP and log download (a new link serves
    /// [`ftp::NoFiles`]).
    pub fn set_files(&mut self, files: Box<dyn ftp::FileStore>) {
        self.ftp = ftp::Server::new(files, self.clock);
        self.logs = log_download::Server::default();
    }

    /// The link's configuration.
    #[must_use]
    pub fn config(&self) -> &LinkConfig {
        &self.config
    }

    /// Counters.
    #[must_use]
    pub fn stats(&self) -> LinkStats {
        self.stats
    }

    /// The stream scheduler (to read intervals).
    #[must_use]
    pub fn streams(&self) -> &Scheduler {
        &self.streams
    }

    /// The mission protocol state (item mode, upload running).
    #[must_use]
    pub fn missions(&self) -> &Missions {
        &self.missions
    }

    /// The addresses [`To::All`] means now.
    pub fn destinations(&mut self, now: Instant, out: &mut Vec<SocketAddr>) {
        self.peers.active(now, out);
    }

    /// Take the frames queued so far (signed, in order, when the vehicle
    /// has a key), then the frames forwarded from the vehicle's other links
    /// (as they came: never signed again).
    pub fn drain(&mut self) -> Vec<Outgoing> {
        let mut out = std::mem::take(&mut self.outbox);
        self.sign_all(&mut out);
        if let Some(fwd) = self.forwarding.as_mut() {
            out.extend(
                fwd.drain_passed()
                    .into_iter()
                    .map(|bytes| Outgoing { to: To::All, bytes }),
            );
        }
        out
    }

    /// Use the vehicle's signing state `shared` (one per vehicle, shared by
    /// its links), signing with `link_id` (the link's index). A new link has
    /// its own, without a key.
    pub fn set_signing(&mut self, shared: signing::Shared, link_id: u8) {
        self.signing = (shared, link_id);
    }

    /// The vehicle's signing state.
    #[must_use]
    pub fn signing(&self) -> &signing::Shared {
        &self.signing.0
    }

    fn sign_all(&self, out: &mut [Outgoing]) {
        let mut s = signing::lock(&self.signing.0);
        if s.is_keyed() {
            let now = Instant::now();
            for o in out {
                s.sign(&mut o.bytes, self.signing.1, now);
            }
        }
    }

    /// The signing gate ([`signing`]): false when `frame` goes no
    /// further: refused (unsigned, bad signature, replay, stale), or a
    /// SETUP_SIGNING for us, which it applies (with no key, or signed with
    /// the key: the refusals came first) and turns into
    /// [`Effect::SigningKeyChanged`].
    fn signing_gate(&mut self, now: Instant, frame: &Frame<'_>, effects: &mut Vec<Effect>) -> bool {
        let mut s = signing::lock(&self.signing.0);
        if let Err(why) = s.check(frame, now) {
            tracing::debug!(link = %self.config.name, ?why, id = frame.message_id, "refused by signing");
            return false;
        }
        if frame.message_id != signing::SETUP_SIGNING_ID {
            return true;
        }
        if let Some(Inbound::Other(m)) = wire::decode(frame)
            && let MavMessage::SETUP_SIGNING(m) = *m
            && self.for_me(m.target_system, m.target_component)
        {
            s.setup(m.secret_key, m.initial_timestamp);
            tracing::info!(link = %self.config.name, keyed = s.is_keyed(), "signing key set by SETUP_SIGNING");
            effects.push(Effect::SigningKeyChanged);
        }
        false
    }

    fn send(&mut self, to: To, msg: &MavMessage) {
        let bytes = self.encoder.message(msg);
        self.queue(to, bytes);
    }

    /// Queue a frame; a direct answer only if the peer's budget allows it
    /// ([`peers::Peers::charge`]), else it is dropped and counted (false).
    fn queue(&mut self, to: To, bytes: Vec<u8>) -> bool {
        // signed in `drain`: the signature's bytes count against the budget too
        let signature = if signing::lock(&self.signing.0).is_keyed() {
            wire::SIGNATURE_LEN
        } else {
            0
        };
        if let To::Peer(a) = to
            && !self.peers.charge(self.clock, a, bytes.len() + signature)
        {
            self.stats.held_back += 1;
            return false;
        }
        self.outbox.push(Outgoing { to, bytes });
        true
    }

    /// Move the link's clock forward to `now` (never back).
    fn tick(&mut self, now: Instant) {
        if now > self.clock {
            self.clock = now;
        }
    }

    /// What `addr` has shown this link (`None`: not a peer).
    #[must_use]
    pub fn standing(&self, addr: SocketAddr) -> Option<peers::Standing> {
        self.peers.standing(addr)
    }

    fn ack(&mut self, t: AckTicket, result: u8) {
        let bytes = self.encoder.command_ack(&CommandAck {
            command: t.command,
            result,
            progress: 0,
            result_param2: 0,
            target_system: t.requester.0,
            target_component: t.requester.1,
        });
        self.queue(To::Peer(t.to), bytes);
    }

    /// Queue `text` as STATUSTEXT lines ([`status_text_lines`]: a longer text is split).
    fn text(&mut self, to: To, severity: Severity, text: &str) {
        for line in status_text_lines(text) {
            let msg = status_text_msg(severity, line);
            self.send(to, &msg);
        }
    }

    /// Queue a STATUSTEXT for every peer.
    pub fn status_text(&mut self, t: &StatusText) {
        self.text(To::All, t.severity, &t.text);
    }

    /// Queue the vehicle's new events ([`events::Reporter`]) for every
    /// peer, and keep them for REQUEST_EVENT.
    pub fn send_events(&mut self, now: Instant, list: &[EVENT_DATA]) {
        self.tick(now);
        for e in list {
            self.events.keep(e);
            self.send(To::All, &MavMessage::EVENT(e.clone()));
        }
    }

    /// Queue a PARAM_VALUE for every peer, [`command::PARAM_REBROADCAST_DELAY`]
    /// from `now` (PX4 rebroadcasts a changed parameter on every link).
    pub fn broadcast_param(&mut self, now: Instant, value: &MavMessage) {
        self.tick(now);
        // a list still being sent sends the new value (PX4 reads each value
        // as it sends it): a client's cache must not end older than the echo
        if let MavMessage::PARAM_VALUE(v) = value {
            for list in &mut self.param_lists {
                if let Some(m) = list.values.get_mut(usize::from(v.param_index)) {
                    *m = value.clone();
                }
            }
        }
        let bytes = self.encoder.message(value);
        self.delayed
            .push((now + command::PARAM_REBROADCAST_DELAY, Outgoing { to: To::All, bytes }));
    }

    /// When [`Link::poll`] next has something to send.
    #[must_use]
    pub fn next_deadline(&self) -> Option<Instant> {
        let delayed = self.delayed.iter().map(|(t, _)| *t).min();
        let lists = self.param_lists.iter().map(|l| l.due).min();
        [
            self.streams.next_deadline(),
            delayed,
            self.missions.next_deadline(),
            lists,
            self.ftp.next_deadline(),
            self.logs.next_deadline(),
            Some(self.events.next_deadline()),
        ]
        .into_iter()
        .flatten()
        .min()
    }

    /// Queue the streams due at `now` (and delayed frames whose time has come).
    pub fn poll(&mut self, now: Instant, t: &Snapshot, unix_time_us: u64) {
        self.tick(now);
        let mut i = 0;
        while i < self.delayed.len() {
            if self.delayed[i].0 <= now {
                let (_, out) = self.delayed.swap_remove(i);
                self.outbox.push(out);
            } else {
                i += 1;
            }
        }
        let mut due = std::mem::take(&mut self.due);
        due.clear();
        self.streams.due(now, &mut due);
        let fanout = self.peers.active_count(now);
        if self.raw_sensors == RawDemand::None && fanout > 0 && due.iter().any(|s| s.needs_raw_sensors()) {
            self.raw_sensors = RawDemand::Wanted;
        }
        for s in &due {
            for m in streams::build(*s, t, unix_time_us) {
                if let MavMessage::MISSION_CURRENT(c) = &m {
                    self.missions.note_current(c);
                }
                let bytes = self.encoder.message(&m);
                // heartbeats always go: they are what tells a GCS the link lives
                if *s != Stream::Heartbeat && !self.stream_budget.take(now, bytes.len() * fanout) {
                    self.stats.streams_shed += 1;
                    continue;
                }
                self.outbox.push(Outgoing { to: To::All, bytes });
            }
        }
        self.due = due;
        if let Some(m) = self.events.current_sequence(now) {
            self.send(To::All, &m);
        }
        self.send_param_lists(now);
        self.ftp_poll(now);
        self.log_send(now);
        let out = self.missions.poll(now, t);
        self.mission_frames(out);
    }

    /// A PARAM_REQUEST_LIST from `to`: start sending `values` to it, unless
    /// a list for it is already running (a repeat does not restart it, so
    /// a datagram of many requests draws one list).
    fn start_param_list(&mut self, now: Instant, to: SocketAddr, values: Vec<MavMessage>) {
        if self.param_lists.iter().any(|l| l.to == to) {
            return;
        }
        let proven = |s: Option<peers::Standing>| matches!(s, Some(peers::Standing::Proven | peers::Standing::Default));
        if self.param_lists.len() >= MAX_PARAM_LISTS {
            if !proven(self.peers.standing(to)) {
                return;
            }
            match self.param_lists.iter().position(|l| !proven(self.peers.standing(l.to))) {
                Some(i) => {
                    self.param_lists.swap_remove(i);
                }
                None => return,
            }
        }
        self.param_lists.push(ParamList {
            to,
            values,
            next: 0,
            due: now,
            held_since: None,
        });
    }

    /// Send each due list's next [`PARAMS_PER_TURN`] values its requester's
    /// budget allows.
    fn send_param_lists(&mut self, now: Instant) {
        let mut lists = std::mem::take(&mut self.param_lists);
        lists.retain_mut(|l| {
            if l.due > now {
                return true;
            }
            if self.peers.standing(l.to).is_none() {
                return false; // forgotten
            }
            for _ in 0..PARAMS_PER_TURN {
                let Some(v) = l.values.get(l.next) else { break };
                if !self.peers.charge(now, l.to, PARAM_VALUE_FRAME) {
                    let since = *l.held_since.get_or_insert(now);
                    if now.saturating_duration_since(since) > PARAM_LIST_STALL {
                        return false;
                    }
                    break;
                }
                l.held_since = None;
                let bytes = self.encoder.message(v);
                self.outbox.push(Outgoing {
                    to: To::Peer(l.to),
                    bytes,
                });
                l.next += 1;
            }
            l.due = now + PARAM_LIST_TURN;
            l.next < l.values.len()
        });
        self.param_lists = lists;
    }

    /// Queue the mission protocol's frames.
    fn mission_frames(&mut self, out: Vec<mission::Out>) {
        for o in out {
            match o {
                mission::Out::Message(to, m) => self.send(to, &m),
                mission::Out::Item(to, item) => {
                    let bytes = self.encoder.mission_item(&item);
                    self.queue(To::Peer(to), bytes);
                }
                mission::Out::Text(to, severity, text) => self.text(to, severity, &text),
            }
        }
    }

    /// Queue a step's frames; its plan change becomes an effect.
    fn mission_step(&mut self, step: mission::Step, effects: &mut Vec<Effect>) {
        self.mission_frames(step.out);
        if let Some((ticket, change)) = step.plans {
            effects.push(Effect::Plans { ticket, change });
        }
    }

    /// Handle one received datagram from `from`.
    pub fn on_datagram<P: ParamAccess + ?Sized>(
        &mut self,
        now: Instant,
        from: SocketAddr,
        data: &[u8],
        t: &Snapshot,
        params: &P,
    ) -> Vec<Effect> {
        let mut effects = Vec::new();
        self.tick(now);
        for frame in wire::frames(data) {
            self.stats.frames_in += 1;
            if !self.signing_gate(now, &frame, &mut effects) {
                continue;
            }
            let me = self.config.identity;
            if frame.system_id == me.system_id && frame.component_id == me.component_id {
                // our own frames looped back (or another vehicle with our ids)
                self.stats.ignored += 1;
                continue;
            }
            // the whole frame, signature included, earns the sender its credit
            if self.peers.heard(now, from, frame.bytes.len()) {
                tracing::debug!(link = %self.config.name, peer = %from, "new peer (unproven)");
            }
            if frame.message_id == 0 {
                // a HEARTBEAT: every GCS, MAVSDK and MAVProxy sends one at 1 Hz
                self.prove(now, from);
            }
            if let Some(fwd) = self.forwarding.as_mut() {
                fwd.heard(frame.system_id, frame.component_id);
            }
            match wire::decode(&frame) {
                Some(msg) => {
                    self.offer_forward(&frame, &msg, params);
                    self.on_message(now, from, &frame, msg, t, params, &mut effects);
                }
                None => self.stats.ignored += 1,
            }
        }
        effects
    }

    /// Keep `frame` for the vehicle's other links if PX4 would forward it
    /// ([`forward`]); the link handles it as well.
    fn offer_forward<P: ParamAccess + ?Sized>(&mut self, frame: &Frame<'_>, msg: &Inbound, params: &P) {
        let me = self.config.identity;
        let Some(fwd) = self.forwarding.as_mut() else {
            return;
        };
        let heartbeats = || {
            // PX4's default (1) when the table has no such parameter
            params
                .by_name(forward::HEARTBEAT_PARAM)
                .is_none_or(|(_, v)| v != ParamValue::Int32(0))
        };
        let source = (frame.system_id, frame.component_id);
        fwd.offer(frame.bytes, source, frame.message_id, msg, me, heartbeats);
    }

    /// `from` has shown it listens: it gets the streams from now on.
    fn prove(&mut self, now: Instant, from: SocketAddr) {
        if self.peers.prove(now, from) {
            tracing::info!(link = %self.config.name, peer = %from, "new peer");
        }
    }

    fn for_me(&self, system: u8, component: u8) -> bool {
        let me = self.config.identity;
        (system == 0 || system == me.system_id) && (component == 0 || component == me.component_id)
    }

    /// Mission messages may also be aimed at the mission planner component (PX4).
    fn for_mission(&self, system: u8, component: u8) -> bool {
        self.for_me(system, component) || (self.for_me(system, 0) && component == mission::MISSION_PLANNER)
    }

    #[allow(clippy::too_many_arguments)]
    fn on_message<P: ParamAccess + ?Sized>(
        &mut self,
        now: Instant,
        from: SocketAddr,
        frame: &Frame<'_>,
        msg: Inbound,
        t: &Snapshot,
        params: &P,
        effects: &mut Vec<Effect>,
    ) {
        let requester = (frame.system_id, frame.component_id);
        let command = match msg {
            Inbound::CommandLong(c) => Command::from(&c),
            Inbound::CommandInt(c) => Command::from(&c),
            Inbound::MissionItem(m) => return self.on_mission_item(now, from, requester, &m, effects),
            Inbound::Other(m) => return self.on_other_message(now, from, requester, *m, t, params, effects),
        };
        if self.for_me(command.target_system, command.target_component) {
            let ticket = AckTicket {
                command: command.command,
                to: from,
                requester,
            };
            self.act(now, ticket, command::classify(&command), t, effects);
        } else {
            self.stats.ignored += 1;
        }
    }

    /// MISSION_ITEM or MISSION_ITEM_INT.
    fn on_mission_item(
        &mut self,
        now: Instant,
        from: SocketAddr,
        requester: (u8, u8),
        m: &MissionItemMsg,
        effects: &mut Vec<Effect>,
    ) {
        if self.for_mission(m.target_system, m.target_component) {
            let step = self.missions.on_item(now, partner(from, requester), m);
            if !step.out.is_empty() || step.plans.is_some() {
                // an item of a transfer we asked it for: it listens
                self.prove(now, from);
            }
            self.mission_step(step, effects);
        } else {
            self.stats.ignored += 1;
        }
    }

    /// Any message but a command or a mission item.
    #[allow(clippy::too_many_arguments)]
    fn on_other_message<P: ParamAccess + ?Sized>(
        &mut self,
        now: Instant,
        from: SocketAddr,
        requester: (u8, u8),
        msg: MavMessage,
        t: &Snapshot,
        params: &P,
        effects: &mut Vec<Effect>,
    ) {
        let reply = To::Peer(from);
        match msg {
            MavMessage::SET_MODE(m) if self.for_me(m.target_system, 0) => {
                let main = ((m.custom_mode >> 16) & 0xFF) as u8;
                let sub = ((m.custom_mode >> 24) & 0xFF) as u8;
                let action = command::set_mode(m.base_mode.bits(), main, sub);
                let ticket = AckTicket {
                    command: command::id::DO_SET_MODE,
                    to: from,
                    requester,
                };
                self.act(now, ticket, action, t, effects);
            }
            // a repeat while its list runs is ignored (falls through)
            MavMessage::PARAM_REQUEST_LIST(m)
                if self.for_me(m.target_system, m.target_component)
                    && !self.param_lists.iter().any(|l| l.to == from) =>
            {
                self.start_param_list(now, from, param::list(params));
                self.send_param_lists(now);
            }
            MavMessage::PARAM_REQUEST_READ(m) if self.for_me(m.target_system, m.target_component) => {
                let name = param::name_of(&m.param_id);
                let v = param::read(params, &name, m.param_index, requester);
                self.send(reply, &v);
            }
            MavMessage::PARAM_SET(m) if self.for_me(m.target_system, m.target_component) => {
                let name = param::name_of(&m.param_id);
                match param::check_set(params, &name, m.param_type, m.param_value, requester) {
                    Ok((index, value)) => effects.push(Effect::SetParam {
                        ticket: ParamTicket {
                            name,
                            index,
                            to: from,
                            requester,
                        },
                        value,
                    }),
                    Err(r) => self.param_reply(reply, &r),
                }
            }
            MavMessage::SET_POSITION_TARGET_LOCAL_NED(m) if self.for_me(m.target_system, m.target_component) => {
                if let Some(sp) = offboard::local_ned(&m) {
                    effects.push(Effect::Autopilot {
                        command: AutopilotCommand::Offboard(sp),
                        ack: None,
                    });
                }
            }
            MavMessage::SET_POSITION_TARGET_GLOBAL_INT(m) if self.for_me(m.target_system, m.target_component) => {
                if let Some(sp) = offboard::global_int(&m) {
                    effects.push(Effect::Autopilot {
                        command: AutopilotCommand::Offboard(sp),
                        ack: None,
                    });
                }
            }
            MavMessage::SET_ATTITUDE_TARGET(m) if self.for_me(m.target_system, m.target_component) => {
                if let Some(sp) = offboard::attitude(&m) {
                    effects.push(Effect::Autopilot {
                        command: AutopilotCommand::Offboard(sp),
                        ack: None,
                    });
                }
            }
            // FOLLOW_TARGET has no target: PX4 takes it from any client
            MavMessage::FOLLOW_TARGET(m) => {
                effects.push(Effect::Autopilot {
                    command: AutopilotCommand::FollowTarget(offboard::follow_target(&m)),
                    ack: None,
                });
            }
            // PX4 takes MANUAL_CONTROL aimed at it or at everyone (target 0)
            MavMessage::MANUAL_CONTROL(m) if m.target == 0 || m.target == self.config.identity.system_id => {
                effects.push(Effect::Autopilot {
                    command: AutopilotCommand::ManualControl(manual::sticks(&m)),
                    ack: None,
                });
            }
            MavMessage::TIMESYNC(m) if m.tc1 == 0 => {
                let now_ns = (t.telemetry.time_s * 1e9) as i64;
                self.send(
                    reply,
                    &MavMessage::TIMESYNC(TIMESYNC_DATA {
                        tc1: now_ns.max(1),
                        ts1: m.ts1,
                        // PX4 aims the answer at the requester
                        target_system: requester.0,
                        target_component: requester.1,
                    }),
                );
            }
            MavMessage::PING(m) if m.target_system == 0 && m.target_component == 0 => {
                self.send(
                    reply,
                    &MavMessage::PING(PING_DATA {
                        time_usec: m.time_usec,
                        seq: m.seq,
                        target_system: requester.0,
                        target_component: requester.1,
                    }),
                );
            }
            MavMessage::MISSION_COUNT(m) if self.for_mission(m.target_system, m.target_component) => {
                let step = self.missions.on_count(now, partner(from, requester), &m, t);
                self.mission_step(step, effects);
            }
            MavMessage::MISSION_ACK(m) if self.for_mission(m.target_system, m.target_component) => {
                let out = self.missions.on_ack(now, partner(from, requester), &m);
                self.mission_frames(out);
            }
            MavMessage::MISSION_REQUEST_LIST(m) if self.for_mission(m.target_system, m.target_component) => {
                let out = Missions::on_request_list(partner(from, requester), m.mission_type, t);
                self.mission_frames(vec![out]);
            }
            MavMessage::MISSION_REQUEST(m) if self.for_mission(m.target_system, m.target_component) => {
                let p = partner(from, requester);
                let out = self.missions.on_request(p, m.seq, m.mission_type, ItemMode::Float, t);
                self.mission_frames(out);
            }
            MavMessage::MISSION_REQUEST_INT(m) if self.for_mission(m.target_system, m.target_component) => {
                let p = partner(from, requester);
                let out = self.missions.on_request(p, m.seq, m.mission_type, ItemMode::Int, t);
                self.mission_frames(out);
            }
            MavMessage::MISSION_CLEAR_ALL(m) if self.for_mission(m.target_system, m.target_component) => {
                let step = self.missions.on_clear_all(partner(from, requester), m.mission_type);
                self.mission_step(step, effects);
            }
            MavMessage::MISSION_SET_CURRENT(m) if self.for_mission(m.target_system, m.target_component) => {
                match self.missions.check_set_current(m.seq, t) {
                    Ok(()) => effects.push(Effect::SetMissionCurrent { seq: m.seq }),
                    Err(why) => self.text(reply, Severity::Warning, &why),
                }
            }
            MavMessage::HEARTBEAT(m) if m.mavtype == mavlink::dialects::common::MavType::MAV_TYPE_GCS => {
                effects.push(Effect::GcsHeartbeat);
            }
            MavMessage::FILE_TRANSFER_PROTOCOL(m) if self.for_me(m.target_system, m.target_component) => {
                self.on_ftp(now, from, requester, &m, params, effects);
            }
            MavMessage::LOG_REQUEST_LIST(m) if self.for_me(m.target_system, m.target_component) => {
                self.on_log_request_list(now, from, m.start, m.end);
            }
            MavMessage::LOG_REQUEST_DATA(m) if self.for_me(m.target_system, m.target_component) => {
                self.on_log_request_data(now, from, m.id, m.ofs, m.count);
            }
            MavMessage::LOG_REQUEST_END(m) if self.for_me(m.target_system, m.target_component) => {
                self.on_log_request_end();
            }
            MavMessage::LOG_ERASE(m) if self.for_me(m.target_system, m.target_component) => self.on_log_erase(),
            MavMessage::REQUEST_EVENT(m) if self.for_me(m.target_system, m.target_component) => {
                for answer in self.events.request(m.first_sequence, m.last_sequence, requester) {
                    self.send(reply, &answer);
                }
            }
            _ => {}
        }
    }

    fn act(&mut self, now: Instant, ticket: AckTicket, action: Action, t: &Snapshot, effects: &mut Vec<Effect>) {
        let reply = To::Peer(ticket.to);
        match action {
            Action::Autopilot(command) => effects.push(Effect::Autopilot {
                command,
                ack: Some(ticket),
            }),
            Action::Answer(result, reason) => {
                self.ack(ticket, result);
                if let Some(r) = reason
                    && result != convert::result::ACCEPTED
                {
                    self.text(reply, Severity::Warning, r);
                }
            }
            Action::SendMessage(id, index) => match requested(id, index, t, self.config.identity) {
                Some(msgs) => {
                    self.ack(ticket, convert::result::ACCEPTED);
                    for m in &msgs {
                        self.send(reply, m);
                    }
                }
                None => self.ack(ticket, convert::result::DENIED),
            },
            // A stream's rate is the whole link's: only a peer that listens
            // may change it (one spoofed frame could otherwise silence or
            // speed up every client's streams), and the heartbeat is not
            // for changing (the link's liveness for every client).
            Action::SetInterval(..) if self.peers.standing(ticket.to) == Some(peers::Standing::Unproven) => {
                self.ack(ticket, convert::result::DENIED);
            }
            Action::SetInterval(id, _) if id == <HEARTBEAT_DATA as mavlink::MessageData>::ID => {
                self.ack(ticket, convert::result::DENIED)
            }
            Action::SetInterval(id, interval) => match Stream::from_message_id(id) {
                Some(s) => {
                    self.streams.set(now, s, interval);
                    self.ack(ticket, convert::result::ACCEPTED);
                }
                None => self.ack(ticket, convert::result::FAILED),
            },
        }
    }

    /// Answer a PARAM_SET once applied (`Ok`: the value stored) or refused
    /// (`Err`: why; nothing changed). On success returns the PARAM_VALUE the
    /// daemon must have every link broadcast once more
    /// ([`Link::broadcast_param`]), as PX4 does.
    pub fn on_param_set<P: ParamAccess + ?Sized>(
        &mut self,
        ticket: &ParamTicket,
        outcome: Result<ParamValue, String>,
        params: &P,
    ) -> Option<MavMessage> {
        let r = param::finish_set(params, &ticket.name, ticket.index, outcome, ticket.requester);
        self.param_reply(To::Peer(ticket.to), &r);
        r.changed.map(|(_, m)| *m)
    }

    /// A PARAM_SET answered by [`Link::on_param_set`] (value in force) whose
    /// value could not be written to the state directory (`why` names the
    /// file and the error): PARAM_ERROR (PERMISSION_DENIED: the write was
    /// refused) and a critical STATUSTEXT to the requester, after the echo.
    pub fn on_param_not_saved(&mut self, ticket: &ParamTicket, why: &str) {
        let index = i16::try_from(ticket.index).unwrap_or(-1);
        let err = param::param_error(
            &ticket.name,
            index,
            mavlink::dialects::common::MavParamError::MAV_PARAM_ERROR_PERMISSION_DENIED,
            ticket.requester,
        );
        let to = To::Peer(ticket.to);
        self.send(to, &err);
        // a path and an OS error do not fit one STATUSTEXT: `text` splits it
        self.text(to, Severity::Critical, &format!("{} not saved: {why}", ticket.name));
    }

    fn param_reply(&mut self, to: To, r: &param::SetReply) {
        for v in &r.replies {
            self.send(to, v);
        }
        if let Some(why) = &r.refused {
            self.text(to, Severity::Warning, &format!("param: {why}"));
        }
    }

    /// Answer a plan change the flight stack has applied (`Ok`: the new
    /// plan's id) or refused (`Err`: why; nothing changed): MISSION_ACK to
    /// the client, with a STATUSTEXT on refusal.
    pub fn on_plans_changed(&mut self, ticket: PlanTicket, outcome: Result<u32, MissionResult>) {
        let out = self.missions.on_plans_changed(ticket, outcome);
        self.mission_frames(out);
    }

    /// The autopilot's answer to [`Effect::SetMissionCurrent`]: once
    /// accepted, MISSION_CURRENT with `seq` to every peer (`t`: the
    /// snapshot published before the answer). A refusal the autopilot
    /// announces itself.
    pub fn on_mission_current_set(&mut self, seq: u16, outcome: &CommandOutcome, t: &Snapshot) {
        if *outcome == CommandOutcome::Accepted {
            let out = self.missions.current_set(seq, t);
            self.mission_frames(vec![out]);
        }
    }

    /// The vehicle reached mission item `seq`: MISSION_ITEM_REACHED to every
    /// peer now, repeated by [`Link::poll`].
    pub fn on_mission_item_reached(&mut self, now: Instant, seq: u16) {
        self.tick(now);
        let out = self.missions.on_item_reached(now, seq);
        self.mission_frames(vec![out]);
    }

    /// Send the ACK for a command the autopilot has answered. (The autopilot
    /// announces its own refusals as status texts, so none is added here.)
    pub fn on_outcome(&mut self, ticket: AckTicket, outcome: &CommandOutcome) {
        let (result, _reason) = convert::mav_result(outcome);
        self.ack(ticket, result);
    }
}

/// A transfer partner: the address and ids a frame came from.
fn partner(addr: SocketAddr, (system, component): (u8, u8)) -> Partner {
    Partner {
        addr,
        system,
        component,
    }
}

/// STATUSTEXT (text cut to the 50 bytes one message holds, [`cut_status_text`]).
#[must_use]
pub fn status_text_msg(severity: Severity, text: &str) -> MavMessage {
    let cut = cut_status_text(text);
    let sev = match severity {
        Severity::Emergency => MavSeverity::MAV_SEVERITY_EMERGENCY,
        Severity::Critical => MavSeverity::MAV_SEVERITY_CRITICAL,
        Severity::Error => MavSeverity::MAV_SEVERITY_ERROR,
        Severity::Warning => MavSeverity::MAV_SEVERITY_WARNING,
        Severity::Notice => MavSeverity::MAV_SEVERITY_NOTICE,
        Severity::Info => MavSeverity::MAV_SEVERITY_INFO,
    };
    MavMessage::STATUSTEXT(STATUSTEXT_DATA {
        severity: sev,
        text: cut.into(),
        // a complete line: id 0 (a longer text goes as several lines, not as PX4's numbered chunks)
        id: 0,
        chunk_seq: 0,
    })
}

/// AUTOPILOT_VERSION as PX4 would send it.
#[must_use]
pub fn autopilot_version(identity: Identity) -> MavMessage {
    MavMessage::AUTOPILOT_VERSION(AUTOPILOT_VERSION_DATA {
        capabilities: MavProtocolCapability::from_bits_retain(CAPABILITIES),
        uid: 0x5250_0000_0000_0000 | u64::from(identity.system_id),
        flight_sw_version: FLIGHT_SW_VERSION,
        middleware_sw_version: 0,
        os_sw_version: 0,
        board_version: 0,
        vendor_id: 0,
        product_id: 0,
        flight_custom_version: [0; 8],
        middleware_custom_version: [0; 8],
        os_custom_version: [0; 8],
        uid2: [0; 18],
    })
}

/// The messages a REQUEST_MESSAGE for `id` (with param2 as `index`) gets:
/// AUTOPILOT_VERSION, COMPONENT_METADATA, AVAILABLE_MODES, or any
/// stream's message; `None` (DENIED, as PX4) for the rest and for a stream
/// with nothing to send (WIND_COV without a wind estimate: PX4 denies a
/// request its stream does not answer).
#[must_use]
pub fn requested(id: u32, index: Option<u8>, t: &Snapshot, identity: Identity) -> Option<Vec<MavMessage>> {
    if id == command::AUTOPILOT_VERSION_ID {
        return Some(vec![autopilot_version(identity)]);
    }
    if id == <AVAILABLE_MODES_DATA as mavlink::MessageData>::ID {
        return convert::available_modes(index?).map(|m| m.into_iter().map(MavMessage::AVAILABLE_MODES).collect());
    }
    if id == <COMPONENT_METADATA_DATA as mavlink::MessageData>::ID {
        return Some(vec![events::component_metadata(t.telemetry.time_s)]);
    }
    // SYSTEM_TIME's unix time is not known here; 0 means "unknown".
    Stream::from_message_id(id)
        .map(|s| streams::build(s, t, 0))
        .filter(|m| !m.is_empty())
}

#[cfg(test)]
mod tests;
