//! The mission protocol as PX4 speaks it (`mavlink_mission.cpp`), for the
//! three plan types (mission, geofence, rally points): upload, download,
//! clear, set current, and the progress messages MISSION_CURRENT and
//! MISSION_ITEM_REACHED (`docs/mavlink.md` section 7). The link runs the transfer
//! and translates; the plans are stored whole by the flight stack
//! ([`crate::mission::Plans::apply`]), which alone decides whether a
//! complete plan is taken. Here, each item is only checked on its own
//! ([`crate::mission::validate`]) as it arrives, as PX4 does.
//!
//! **Upload** (one at a time per link, with one partner: address, system
//! and component id). MISSION_COUNT, then the vehicle asks for the items
//! one by one, seq 0 to N−1, aimed at the uploader and carrying the
//! mission type. Like PX4, a link starts in *float mode* (MISSION_REQUEST,
//! which old pymavlink loops wait for) and toggles to *int mode*
//! (MISSION_REQUEST_INT, all MAVSDK accepts) on a MISSION_ACK UNSUPPORTED
//! from the partner, asking again for the same item at once; a MISSION_ITEM
//! or MISSION_REQUEST arriving sets float mode, a MISSION_ITEM_INT or
//! MISSION_REQUEST_INT int mode, and the mode sticks to the link. Both item
//! messages are read into the same [`MissionItem`] (degrees or degE7 by the
//! frame). An item that is not the expected one is ignored (PX4): the
//! request for the expected one goes again after [`RETRY`] of silence, and
//! the transfer is dropped after [`TIMEOUT`] with a STATUSTEXT and no ACK
//! (PX4 says "Operation timeout"). An item refused by validation gets
//! MISSION_ACK with PX4's result and a STATUSTEXT naming it, and ends the
//! transfer; the stored plan is unchanged. After the last item the whole
//! plan goes to the flight stack ([`Step::plans`]) with the id the stored
//! plan had when MISSION_COUNT arrived, so that of two uploads over two
//! links the later finisher is refused (DENIED) rather than silently
//! overwriting; only its answer ([`Missions::on_plans_changed`]) sends
//! MISSION_ACK, ACCEPTED with the new plan's id in `opaque_id`. MAVSDK takes
//! any earlier ACCEPTED as a protocol error, so there is none. The answer
//! to the last item is remembered: if that item comes again (the ACK was
//! lost) the same ACK goes again. A MISSION_COUNT of 0 is a clear of that
//! type, as in PX4; more than [`MAX_ITEMS`] gets NO_SPACE at once.
//! A second uploader gets MISSION_ACK ERROR (PX4's busy answer) and does
//! not disturb the transfer; the partner's own new MISSION_COUNT starts
//! the upload again. Where this differs from PX4, deliberately: a
//! MISSION_COUNT of type ALL (255) gets UNSUPPORTED (PX4 answers NO_SPACE,
//! by accident of an array bound); any error ACK from the partner abandons
//! the upload (PX4 abandons on CANCELLED only and keeps asking otherwise);
//! an item of another type ends the transfer with ERROR (PX4 sends ERROR
//! and goes on waiting, but every client gives up on that ERROR). Types the
//! dialect does not name (3 to 254) do not decode, and are not answered.
//!
//! **Download** is served without state, from the snapshot's plans:
//! MISSION_REQUEST_LIST gets MISSION_COUNT (with the plan id), each
//! MISSION_REQUEST_INT a MISSION_ITEM_INT and each MISSION_REQUEST a
//! MISSION_ITEM, exactly as stored, `current` set on the mission's current
//! item. So MAVProxy's pipelined requests (five at a time, again after 2 s)
//! need nothing special. A seq past the end gets INVALID_SEQUENCE. The
//! client's closing MISSION_ACK needs no answer. MAV_MISSION_TYPE_ALL (255)
//! is no plan: PX4 counts 0 items for it, and so does this.
//!
//! **Clear**: MISSION_CLEAR_ALL (255: all three) goes to the flight stack;
//! MISSION_ACK with the same type once applied. Like PX4, ignored (with a
//! STATUSTEXT) while this link receives an upload.
//!
//! **Set current**: MISSION_SET_CURRENT is ignored while an upload runs or
//! for a seq past the stored mission (PX4), else handed to the autopilot;
//! once it accepted, MISSION_CURRENT with that seq goes out at once (MAVSDK
//! repeats the request until it sees it).
//!
//! **Progress**: MISSION_CURRENT goes out at 1 Hz as a stream
//! ([`super::streams::Stream::MissionCurrent`]) and at once whenever its
//! content changes; MISSION_ITEM_REACHED goes out at once, then the latest
//! again every second, [`REACHED_REPEATS`] times, while a mission is stored
//! (PX4).

use std::net::SocketAddr;
use std::time::{Duration, Instant};

use mavlink::dialects::common::{
    MISSION_ACK_DATA, MISSION_COUNT_DATA, MISSION_CURRENT_DATA, MISSION_ITEM_REACHED_DATA, MISSION_REQUEST_DATA,
    MISSION_REQUEST_INT_DATA, MavMessage, MavMissionResult, MavMissionType,
};

use super::To;
use super::streams;
use super::wire::{ItemXy, MissionItemMsg};
use crate::autopilot::Severity;
use crate::lockstep::Snapshot;
use crate::mission::{self, MAX_ITEMS, MissionItem, MissionResult, MissionType, PlanChange};

/// An upload's request goes again after this long without an answer (PX4).
pub const RETRY: Duration = Duration::from_millis(250);
/// An upload is dropped after this long without a frame from its partner (PX4).
pub const TIMEOUT: Duration = Duration::from_secs(5);
/// MISSION_ITEM_REACHED is repeated this many times after the first (PX4).
pub const REACHED_REPEATS: u8 = 10;
/// ... once per this period.
pub const REACHED_PERIOD: Duration = Duration::from_secs(1);
/// MAV_COMP_ID_MISSIONPLANNER: PX4 takes mission messages aimed at it too.
pub const MISSION_PLANNER: u8 = 190;

/// Which item messages a link uses (PX4's `_int_mode`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ItemMode {
    /// MISSION_REQUEST and MISSION_ITEM (degrees as floats).
    Float,
    /// MISSION_REQUEST_INT and MISSION_ITEM_INT (degE7).
    Int,
}

impl ItemMode {
    /// The other mode.
    #[must_use]
    pub fn toggled(self) -> Self {
        match self {
            ItemMode::Float => ItemMode::Int,
            ItemMode::Int => ItemMode::Float,
        }
    }
}

/// Who a transfer is with: a client is its address and its ids.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Partner {
    /// Where it sends from.
    pub addr: SocketAddr,
    /// Its system id.
    pub system: u8,
    /// Its component id.
    pub component: u8,
}

/// What to answer once the flight stack has changed the plans.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlanTicket {
    /// Who asked.
    pub partner: Partner,
    /// The type to echo in MISSION_ACK (ALL for a clear of all three).
    pub mission_type: MavMissionType,
    /// What was asked.
    pub origin: PlanOrigin,
}

/// The request a plan change answers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlanOrigin {
    /// The last item of an upload.
    Upload {
        /// Which upload of this link.
        serial: u32,
        /// The plan type.
        kind: MissionType,
        /// The last item's seq (its repeat gets the same ACK).
        last_seq: u16,
    },
    /// MISSION_CLEAR_ALL, or a MISSION_COUNT of 0.
    Clear,
}

/// A frame the protocol sends.
#[derive(Clone, Debug, PartialEq)]
pub enum Out {
    /// A message (boxed: MavMessage is large).
    Message(To, Box<MavMessage>),
    /// A mission item (hand-coded, [`MissionItemMsg`]) for one peer.
    Item(SocketAddr, MissionItemMsg),
    /// A STATUSTEXT.
    Text(To, Severity, String),
}

/// The answer to a message that may change the plans.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Step {
    /// Frames to send now.
    pub out: Vec<Out>,
    /// A plan change for the flight stack, answered with
    /// [`Missions::on_plans_changed`] and the ticket.
    pub plans: Option<(PlanTicket, PlanChange)>,
}

impl Step {
    /// Frames only.
    fn frames(out: Vec<Out>) -> Self {
        Self { out, plans: None }
    }

    /// A plan change only.
    fn plans(ticket: PlanTicket, change: PlanChange) -> Self {
        Self {
            out: Vec::new(),
            plans: Some((ticket, change)),
        }
    }
}

/// The mission protocol state of one link.
#[derive(Debug)]
pub struct Missions {
    /// Which item messages the link uses.
    mode: ItemMode,
    /// The upload running, if any.
    upload: Upload,
    /// The answer to the last upload's last item, for its repeat.
    answered: Option<Answered>,
    /// The number of the last upload stored (tickets carry it).
    serial: u32,
    /// MISSION_ITEM_REACHED to repeat.
    reached: Option<Reached>,
    /// The last MISSION_CURRENT sent to every peer.
    reported: Option<MISSION_CURRENT_DATA>,
}

/// Where this link's upload stands.
#[derive(Debug)]
enum Upload {
    /// None running.
    Idle,
    /// Asking for items.
    Receiving(Transfer),
    /// All items in; the flight stack is storing the plan.
    Storing {
        /// Which upload.
        serial: u32,
        /// Since when (an answer that never comes frees the link after [`TIMEOUT`]).
        since: Instant,
    },
}

/// An upload receiving its items.
#[derive(Debug)]
struct Transfer {
    /// The uploader.
    partner: Partner,
    /// The plan type.
    kind: MissionType,
    /// MISSION_COUNT's count.
    count: u16,
    /// The items so far; the next expected seq is their number.
    items: Vec<MissionItem>,
    /// The stored plan's id when MISSION_COUNT arrived.
    base_id: u32,
    /// When the last request went out (the next goes [`RETRY`] later).
    last_sent: Instant,
    /// When the partner last spoke (the transfer ends [`TIMEOUT`] later).
    last_heard: Instant,
}

/// The MISSION_ACK that ended the last upload, and the item it answered.
#[derive(Clone, Copy, Debug)]
struct Answered {
    /// The uploader.
    partner: Partner,
    /// The plan type.
    kind: MissionType,
    /// The item answered.
    seq: u16,
    /// The answer.
    result: MavMissionResult,
    /// The stored plan's id (0 unless accepted).
    opaque_id: u32,
}

/// MISSION_ITEM_REACHED repeats.
#[derive(Clone, Copy, Debug)]
struct Reached {
    /// The item reached.
    seq: u16,
    /// Repeats still to send.
    left: u8,
    /// When the next is due.
    next: Instant,
}

impl Default for Missions {
    fn default() -> Self {
        Self::new()
    }
}

impl Missions {
    /// A link's state at boot: float mode, nothing running.
    #[must_use]
    pub fn new() -> Self {
        Self {
            mode: ItemMode::Float,
            upload: Upload::Idle,
            answered: None,
            serial: 0,
            reached: None,
            reported: None,
        }
    }

    /// The link's item mode.
    #[must_use]
    pub fn mode(&self) -> ItemMode {
        self.mode
    }

    /// Whether an upload runs on this link (receiving or storing).
    #[must_use]
    pub fn busy(&self) -> bool {
        !matches!(self.upload, Upload::Idle)
    }

    /// MISSION_COUNT from `from`: start (or restart) an upload.
    pub fn on_count(&mut self, now: Instant, from: Partner, m: &MISSION_COUNT_DATA, t: &Snapshot) -> Step {
        match &self.upload {
            Upload::Idle => {}
            // the uploader starting again: the new count replaces the transfer
            Upload::Receiving(tr) if tr.partner == from => {}
            Upload::Receiving(_) | Upload::Storing { .. } => {
                return Step::frames(vec![
                    ack(from, MavMissionResult::MAV_MISSION_ERROR, m.mission_type, 0),
                    text(from, "Mission upload busy".into()),
                ]);
            }
        }
        self.upload = Upload::Idle;
        // a new upload: the last one's answer is not repeated any more, and
        // PX4 forgets the last item reached
        self.answered = None;
        self.reached = None;
        let Some(kind) = kind_of(m.mission_type) else {
            return Step::frames(vec![
                ack(from, MavMissionResult::MAV_MISSION_UNSUPPORTED, m.mission_type, 0),
                text(from, "Upload refused: not a plan type".into()),
            ]);
        };
        if usize::from(m.count) > MAX_ITEMS {
            return Step::frames(vec![
                ack(from, MavMissionResult::MAV_MISSION_NO_SPACE, m.mission_type, 0),
                text(
                    from,
                    format!("{} upload refused: {} items, max {MAX_ITEMS}", title(kind), m.count),
                ),
            ]);
        }
        if m.count == 0 {
            let ticket = PlanTicket {
                partner: from,
                mission_type: m.mission_type,
                origin: PlanOrigin::Clear,
            };
            return Step::plans(ticket, PlanChange::Clear(Some(kind)));
        }
        let transfer = Transfer {
            partner: from,
            kind,
            count: m.count,
            items: Vec::new(),
            base_id: t.plans.get(kind).id(),
            last_sent: now,
            last_heard: now,
        };
        let out = vec![request(&transfer, self.mode)];
        self.upload = Upload::Receiving(transfer);
        Step::frames(out)
    }

    /// MISSION_ITEM or MISSION_ITEM_INT from `from`.
    pub fn on_item(&mut self, now: Instant, from: Partner, m: &MissionItemMsg) -> Step {
        self.mode = match m.xy {
            ItemXy::Float { .. } => ItemMode::Float,
            ItemXy::Int { .. } => ItemMode::Int,
        };
        match std::mem::replace(&mut self.upload, Upload::Idle) {
            Upload::Receiving(tr) if tr.partner == from => return self.receive(now, tr, m),
            other => self.upload = other,
        }
        match self.answered {
            Some(a) if a.partner == from && a.seq == m.seq && a.kind.to_mav() == m.mission_type => {
                // the answer was lost: the same again
                Step::frames(vec![ack(from, a.result, mav_type(a.kind), a.opaque_id)])
            }
            // no transfer with this client: nothing to say (an ACK could
            // abort a MAVSDK upload running elsewhere)
            _ => Step::default(),
        }
    }

    /// An item of the running transfer `tr` (taken out of `self.upload`).
    fn receive(&mut self, now: Instant, mut tr: Transfer, m: &MissionItemMsg) -> Step {
        tr.last_heard = now;
        let (partner, kind) = (tr.partner, tr.kind);
        if m.mission_type != kind.to_mav() {
            return Step::frames(vec![
                ack(partner, MavMissionResult::MAV_MISSION_ERROR, mav_type(kind), 0),
                text(partner, format!("{} upload dropped: item of another type", title(kind))),
            ]);
        }
        if usize::from(m.seq) != tr.items.len() {
            // PX4 ignores it; the request goes again on silence
            self.upload = Upload::Receiving(tr);
            return Step::default();
        }
        let item = item_from_msg(m);
        if let Err(r) = mission::validate(kind, &item) {
            let result = mav_result(r);
            self.answered = Some(Answered {
                partner,
                kind,
                seq: m.seq,
                result,
                opaque_id: 0,
            });
            return Step::frames(vec![
                ack(partner, result, mav_type(kind), 0),
                text(
                    partner,
                    format!("{} item {} refused: {}", title(kind), m.seq, r.reason()),
                ),
            ]);
        }
        tr.items.push(item);
        if tr.items.len() < usize::from(tr.count) {
            tr.last_sent = now;
            let out = vec![request(&tr, self.mode)];
            self.upload = Upload::Receiving(tr);
            return Step::frames(out);
        }
        self.serial = self.serial.wrapping_add(1);
        self.upload = Upload::Storing {
            serial: self.serial,
            since: now,
        };
        let ticket = PlanTicket {
            partner,
            mission_type: mav_type(kind),
            origin: PlanOrigin::Upload {
                serial: self.serial,
                kind,
                last_seq: m.seq,
            },
        };
        let change = PlanChange::Store {
            kind,
            items: tr.items,
            base_id: Some(tr.base_id),
        };
        Step::plans(ticket, change)
    }

    /// MISSION_ACK from `from`: during its upload, UNSUPPORTED toggles the
    /// item mode and asks again, another error abandons the upload;
    /// otherwise (the end of a download) nothing to do.
    pub fn on_ack(&mut self, now: Instant, from: Partner, m: &MISSION_ACK_DATA) -> Vec<Out> {
        let Upload::Receiving(tr) = &mut self.upload else {
            return Vec::new();
        };
        if tr.partner != from {
            return Vec::new();
        }
        tr.last_heard = now;
        match m.mavtype {
            MavMissionResult::MAV_MISSION_ACCEPTED => Vec::new(),
            MavMissionResult::MAV_MISSION_UNSUPPORTED => {
                self.mode = self.mode.toggled();
                tr.last_sent = now;
                vec![request(tr, self.mode)]
            }
            _ => {
                let kind = tr.kind;
                self.upload = Upload::Idle;
                vec![text(from, format!("{} upload cancelled by the client", title(kind)))]
            }
        }
    }

    /// MISSION_REQUEST_LIST: the count and id of the stored plan.
    #[must_use]
    pub fn on_request_list(from: Partner, mission_type: MavMissionType, t: &Snapshot) -> Out {
        let (count, opaque_id) = kind_of(mission_type).map_or((0, 0), |k| {
            let plan = t.plans.get(k);
            (u16::try_from(plan.len()).unwrap_or(u16::MAX), plan.id())
        });
        Out::Message(
            To::Peer(from.addr),
            Box::new(MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
                count,
                target_system: from.system,
                target_component: from.component,
                mission_type,
                opaque_id,
            })),
        )
    }

    /// MISSION_REQUEST (`mode` Float) or MISSION_REQUEST_INT (Int): the
    /// stored item in the matching message, or INVALID_SEQUENCE.
    pub fn on_request(
        &mut self,
        from: Partner,
        seq: u16,
        mission_type: MavMissionType,
        mode: ItemMode,
        t: &Snapshot,
    ) -> Vec<Out> {
        self.mode = mode;
        let kind = kind_of(mission_type);
        let item = kind.and_then(|k| t.plans.get(k).items().get(usize::from(seq)));
        match (kind, item) {
            (Some(k), Some(item)) => {
                let current = k == MissionType::Mission && seq == t.telemetry.mission.seq;
                vec![Out::Item(from.addr, item_msg(item, seq, current, k, mode, from))]
            }
            _ => vec![
                ack(from, MavMissionResult::MAV_MISSION_INVALID_SEQUENCE, mission_type, 0),
                text(from, format!("Download: no item {seq}")),
            ],
        }
    }

    /// MISSION_CLEAR_ALL: clear one plan or all (ALL), unless an upload runs.
    pub fn on_clear_all(&mut self, from: Partner, mission_type: MavMissionType) -> Step {
        if self.busy() {
            return Step::frames(vec![text(from, "Clear ignored: upload in progress".into())]);
        }
        let ticket = PlanTicket {
            partner: from,
            mission_type,
            origin: PlanOrigin::Clear,
        };
        Step::plans(ticket, PlanChange::Clear(kind_of(mission_type)))
    }

    /// The flight stack's answer to a plan change: MISSION_ACK (ACCEPTED
    /// with the new plan's id, or why not, with a STATUSTEXT).
    pub fn on_plans_changed(&mut self, ticket: PlanTicket, outcome: Result<u32, MissionResult>) -> Vec<Out> {
        let partner = ticket.partner;
        let (result, opaque_id) = match outcome {
            Ok(id) => (MavMissionResult::MAV_MISSION_ACCEPTED, id),
            Err(r) => (mav_result(r), 0),
        };
        let mut out = vec![ack(partner, result, ticket.mission_type, opaque_id)];
        if let PlanOrigin::Upload { serial, kind, last_seq } = ticket.origin {
            if matches!(self.upload, Upload::Storing { serial: s, .. } if s == serial) {
                self.upload = Upload::Idle;
            }
            self.answered = Some(Answered {
                partner,
                kind,
                seq: last_seq,
                result,
                opaque_id,
            });
        }
        if let Err(r) = outcome {
            let why = match r {
                MissionResult::Denied => "changed by another client",
                other => other.reason(),
            };
            let what = match ticket.origin {
                PlanOrigin::Upload { kind, .. } => format!("{} upload refused", title(kind)),
                PlanOrigin::Clear => "Clear failed".to_string(),
            };
            out.push(text(partner, format!("{what}: {why}")));
        }
        out
    }

    /// Whether MISSION_SET_CURRENT `seq` goes to the autopilot: not while
    /// an upload runs, nor past the stored mission (PX4). The refusal is a
    /// STATUSTEXT.
    ///
    /// # Errors
    /// Why it is ignored.
    pub fn check_set_current(&self, seq: u16, t: &Snapshot) -> Result<(), String> {
        if self.busy() {
            return Err("Set current ignored: upload in progress".into());
        }
        let n = t.plans.get(MissionType::Mission).len();
        if usize::from(seq) >= n {
            return Err(format!("Set current ignored: no item {seq} of {n}"));
        }
        Ok(())
    }

    /// The autopilot took `seq` as the current item: MISSION_CURRENT with
    /// it, for every peer (the rest from the snapshot published before the
    /// answer).
    pub fn current_set(&mut self, seq: u16, t: &Snapshot) -> Out {
        let mut m = streams::mission_current(&t.telemetry);
        m.seq = seq;
        self.reported = Some(m.clone());
        Out::Message(To::All, Box::new(MavMessage::MISSION_CURRENT(m)))
    }

    /// MISSION_CURRENT was sent to every peer (the stream).
    pub fn note_current(&mut self, m: &MISSION_CURRENT_DATA) {
        self.reported = Some(m.clone());
    }

    /// The vehicle reached item `seq`: MISSION_ITEM_REACHED now, repeated later.
    pub fn on_item_reached(&mut self, now: Instant, seq: u16) -> Out {
        self.reached = Some(Reached {
            seq,
            left: REACHED_REPEATS,
            next: now + REACHED_PERIOD,
        });
        item_reached(seq)
    }

    /// Timers and changes at `now`: the upload's request again or its
    /// timeout, MISSION_ITEM_REACHED repeats, MISSION_CURRENT on change.
    pub fn poll(&mut self, now: Instant, t: &Snapshot) -> Vec<Out> {
        let mut out = Vec::new();
        match &mut self.upload {
            Upload::Receiving(tr) if now >= tr.last_heard + TIMEOUT => {
                out.push(text(tr.partner, format!("{} upload timed out", title(tr.kind))));
                self.upload = Upload::Idle;
            }
            Upload::Receiving(tr) if now >= tr.last_sent + RETRY => {
                tr.last_sent = now;
                out.push(request(tr, self.mode));
            }
            Upload::Storing { since, .. } if now >= *since + TIMEOUT => {
                tracing::warn!("plan change never answered; upload dropped");
                self.upload = Upload::Idle;
            }
            _ => {}
        }
        if let Some(r) = &mut self.reached
            && r.left > 0
            && now >= r.next
        {
            r.left -= 1;
            r.next = now + REACHED_PERIOD;
            if t.telemetry.mission.total > 0 {
                out.push(item_reached(r.seq));
            }
        }
        let current = streams::mission_current(&t.telemetry);
        if self.reported.as_ref() != Some(&current) {
            self.reported = Some(current.clone());
            out.push(Out::Message(To::All, Box::new(MavMessage::MISSION_CURRENT(current))));
        }
        out
    }

    /// When [`Missions::poll`] next has a timer to run.
    #[must_use]
    pub fn next_deadline(&self) -> Option<Instant> {
        let upload = match &self.upload {
            Upload::Idle => None,
            Upload::Receiving(tr) => Some((tr.last_sent + RETRY).min(tr.last_heard + TIMEOUT)),
            Upload::Storing { since, .. } => Some(*since + TIMEOUT),
        };
        let reached = self.reached.filter(|r| r.left > 0).map(|r| r.next);
        match (upload, reached) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }
}

/// The plan type of a MAV_MISSION_TYPE (ALL is none).
#[must_use]
pub fn kind_of(t: MavMissionType) -> Option<MissionType> {
    match t {
        MavMissionType::MAV_MISSION_TYPE_MISSION => Some(MissionType::Mission),
        MavMissionType::MAV_MISSION_TYPE_FENCE => Some(MissionType::Fence),
        MavMissionType::MAV_MISSION_TYPE_RALLY => Some(MissionType::Rally),
        MavMissionType::MAV_MISSION_TYPE_ALL => None,
    }
}

/// The MAV_MISSION_TYPE of a plan type.
#[must_use]
pub fn mav_type(kind: MissionType) -> MavMissionType {
    match kind {
        MissionType::Mission => MavMissionType::MAV_MISSION_TYPE_MISSION,
        MissionType::Fence => MavMissionType::MAV_MISSION_TYPE_FENCE,
        MissionType::Rally => MavMissionType::MAV_MISSION_TYPE_RALLY,
    }
}

/// MAV_MISSION_RESULT of a result.
#[must_use]
pub fn mav_result(r: MissionResult) -> MavMissionResult {
    use MavMissionResult as M;
    match r {
        MissionResult::Accepted => M::MAV_MISSION_ACCEPTED,
        MissionResult::Error => M::MAV_MISSION_ERROR,
        MissionResult::UnsupportedFrame => M::MAV_MISSION_UNSUPPORTED_FRAME,
        MissionResult::Unsupported => M::MAV_MISSION_UNSUPPORTED,
        MissionResult::NoSpace => M::MAV_MISSION_NO_SPACE,
        MissionResult::Invalid => M::MAV_MISSION_INVALID,
        MissionResult::InvalidParam1 => M::MAV_MISSION_INVALID_PARAM1,
        MissionResult::InvalidParam2 => M::MAV_MISSION_INVALID_PARAM2,
        MissionResult::InvalidParam3 => M::MAV_MISSION_INVALID_PARAM3,
        MissionResult::InvalidParam4 => M::MAV_MISSION_INVALID_PARAM4,
        MissionResult::InvalidParam5X => M::MAV_MISSION_INVALID_PARAM5_X,
        MissionResult::InvalidParam6Y => M::MAV_MISSION_INVALID_PARAM6_Y,
        MissionResult::InvalidParam7 => M::MAV_MISSION_INVALID_PARAM7,
        MissionResult::InvalidSequence => M::MAV_MISSION_INVALID_SEQUENCE,
        MissionResult::Denied => M::MAV_MISSION_DENIED,
        MissionResult::OperationCancelled => M::MAV_MISSION_OPERATION_CANCELLED,
    }
}

/// A received item as stored: x, y in degrees from either message (the
/// frame says whether MISSION_ITEM_INT's integers are degE7).
#[must_use]
pub fn item_from_msg(m: &MissionItemMsg) -> MissionItem {
    let (x, y) = match m.xy {
        ItemXy::Float { x, y } => (f64::from(x), f64::from(y)),
        ItemXy::Int { x, y } => MissionItem::xy_from_int(m.frame, x, y),
    };
    MissionItem {
        frame: m.frame,
        command: m.command,
        autocontinue: m.autocontinue != 0,
        params: m.params,
        x,
        y,
        z: m.z,
    }
}

/// A stored item as MISSION_ITEM (`Float`) or MISSION_ITEM_INT (`Int`),
/// aimed at `to`.
#[must_use]
pub fn item_msg(
    item: &MissionItem,
    seq: u16,
    current: bool,
    kind: MissionType,
    mode: ItemMode,
    to: Partner,
) -> MissionItemMsg {
    let xy = match mode {
        ItemMode::Float => ItemXy::Float {
            x: item.x_f32(),
            y: item.y_f32(),
        },
        ItemMode::Int => ItemXy::Int {
            x: item.x_int(),
            y: item.y_int(),
        },
    };
    MissionItemMsg {
        params: item.params,
        xy,
        z: item.z,
        seq,
        command: item.command,
        target_system: to.system,
        target_component: to.component,
        frame: item.frame,
        current: u8::from(current),
        autocontinue: u8::from(item.autocontinue),
        mission_type: kind.to_mav(),
    }
}

/// "Mission", "Fence" or "Rally", to start a STATUSTEXT.
fn title(kind: MissionType) -> &'static str {
    match kind {
        MissionType::Mission => "Mission",
        MissionType::Fence => "Fence",
        MissionType::Rally => "Rally",
    }
}

/// MISSION_ACK to a client.
fn ack(to: Partner, result: MavMissionResult, mission_type: MavMissionType, opaque_id: u32) -> Out {
    Out::Message(
        To::Peer(to.addr),
        Box::new(MavMessage::MISSION_ACK(MISSION_ACK_DATA {
            target_system: to.system,
            target_component: to.component,
            mavtype: result,
            mission_type,
            opaque_id,
        })),
    )
}

/// A warning STATUSTEXT to a client.
fn text(to: Partner, text: String) -> Out {
    Out::Text(To::Peer(to.addr), Severity::Warning, text)
}

/// The request for the transfer's next item, in the link's mode.
fn request(tr: &Transfer, mode: ItemMode) -> Out {
    let seq = u16::try_from(tr.items.len()).unwrap_or(u16::MAX);
    let (p, mission_type) = (tr.partner, mav_type(tr.kind));
    let msg = match mode {
        ItemMode::Float => MavMessage::MISSION_REQUEST(MISSION_REQUEST_DATA {
            seq,
            target_system: p.system,
            target_component: p.component,
            mission_type,
        }),
        ItemMode::Int => MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
            seq,
            target_system: p.system,
            target_component: p.component,
            mission_type,
        }),
    };
    Out::Message(To::Peer(p.addr), Box::new(msg))
}

/// MISSION_ITEM_REACHED for every peer.
fn item_reached(seq: u16) -> Out {
    Out::Message(
        To::All,
        Box::new(MavMessage::MISSION_ITEM_REACHED(MISSION_ITEM_REACHED_DATA { seq })),
    )
}

#[cfg(test)]
mod tests;
