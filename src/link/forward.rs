//! Forwarding between a vehicle's links, as PX4 SITL's MAVLink instances do
//! it: PX4 starts its GCS and API links with `mavlink start ... -f`, so a
//! message a client sends on one link reaches the clients of the others
//! (a companion's STATUSTEXT reaches the ground station). PX4's rule
//! (`Mavlink::forward_message`, called for every message a link receives,
//! after the link has handled it):
//!
//! - a message aimed at this vehicle's autopilot alone (target system and
//!   component both ours) is kept;
//! - a HEARTBEAT is forwarded only while `MAV_HB_FORW_EN` is 1 (PX4's
//!   default);
//! - any other message goes to every other link of the vehicle that has
//!   seen its target (`MavlinkReceiver::component_was_seen`): a target
//!   system 0 (or a message without a target) needs any component heard on
//!   that link, a target component 0 any component of the target system, and
//!   otherwise that very component;
//! - the frame goes out as it came in: header (sequence, system and
//!   component id of its sender), payload, CRC and signature untouched.
//!
//! SETUP_SIGNING never is (the signing gate consumes it), nor a frame the
//! signing gate refused. The links of a vehicle forward among themselves
//! only: each vehicle of a fleet forwards as one PX4 instance does.
//!
//! Loops: a frame goes only to the vehicle's *other* links, is never fed
//! back into a link's input, and is not sent onto a link where its own
//! sender was heard (that sender is already there; the frame could only
//! come back round).
//!
//! Cost: nothing of this runs for a vehicle with one link; a link decides
//! nothing per frame while none of the vehicle's other links has heard a
//! component ([`Fellows`]). A link passes on at most [`FORWARD_RATE`] bytes
//! per second (counted once per destination address), so a flood on one
//! link cannot be multiplied onto another (PX4 holds two forwarded messages
//! per link and drops the rest).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use mavlink::Message as _;

use super::budget::TokenBucket;
use super::streams::Identity;
use super::wire::Inbound;

/// At most this many components are remembered per link, as PX4's receiver
/// (`MAX_REMOTE_COMPONENTS`); never forgotten.
pub const MAX_REMOTE_COMPONENTS: usize = 16;

/// Forwarded bytes a link may send per second, all destinations together.
pub const FORWARD_RATE: f64 = 65_536.0;

/// The parameter that lets heartbeats be forwarded (PX4's, default 1).
pub const HEARTBEAT_PARAM: &str = "MAV_HB_FORW_EN";

/// HEARTBEAT's message id.
const HEARTBEAT_ID: u32 = 0;

/// A frame received on one link, for the vehicle's other links.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Forwarded {
    /// The frame exactly as received (MAVLink 1 or 2, with its signature).
    pub bytes: Vec<u8>,
    /// Its sender's system and component id.
    pub source: (u8, u8),
    /// Its target system and component (0: all; no target field: (0, 0)).
    pub target: (u8, u8),
}

/// The components heard on a link (PX4's receiver component states).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Components {
    ids: Vec<(u8, u8)>,
}

impl Components {
    /// Remember `(system, component)`; true if it is new here (and there
    /// was room for it).
    pub fn note(&mut self, system: u8, component: u8) -> bool {
        if self.ids.contains(&(system, component)) || self.ids.len() >= MAX_REMOTE_COMPONENTS {
            return false;
        }
        self.ids.push((system, component));
        true
    }

    /// PX4's `component_was_seen`: system 0 means anyone heard here; a
    /// component 0 any component of `system`.
    #[must_use]
    pub fn was_seen(&self, system: u8, component: u8) -> bool {
        if system == 0 {
            return !self.ids.is_empty();
        }
        self.ids
            .iter()
            .any(|&(s, c)| s == system && (component == 0 || c == component))
    }

    /// Exactly `(system, component)` was heard here.
    #[must_use]
    pub fn has(&self, system: u8, component: u8) -> bool {
        self.ids.contains(&(system, component))
    }
}

/// Which of a vehicle's links have heard a component, shared by them: a
/// link prepares nothing for forwarding while no other link has.
#[derive(Clone, Debug)]
pub struct Fellows {
    heard: Arc<[AtomicBool]>,
    me: usize,
}

impl Fellows {
    /// One handle per link of a vehicle with `n` links (link `i` gets the `i`th).
    #[must_use]
    pub fn for_links(n: usize) -> Vec<Self> {
        let heard: Arc<[AtomicBool]> = (0..n).map(|_| AtomicBool::new(false)).collect();
        (0..n)
            .map(|me| Self {
                heard: heard.clone(),
                me,
            })
            .collect()
    }

    /// This link has heard a component.
    pub fn set_heard(&self) {
        self.heard[self.me].store(true, Ordering::Relaxed);
    }

    /// Another link of the vehicle has heard a component.
    #[must_use]
    pub fn others_heard(&self) -> bool {
        self.heard
            .iter()
            .enumerate()
            .any(|(i, h)| i != self.me && h.load(Ordering::Relaxed))
    }
}

/// A decoded message's target (system, component), as PX4 reads it from
/// the message's `target_system` and `target_component` fields; (0, 0)
/// for a message without them.
#[must_use]
pub fn target(msg: &Inbound) -> (u8, u8) {
    match msg {
        Inbound::CommandLong(c) => (c.target_system, c.target_component),
        Inbound::CommandInt(c) => (c.target_system, c.target_component),
        Inbound::MissionItem(m) => (m.target_system, m.target_component),
        Inbound::Other(m) => (m.target_system_id().unwrap_or(0), m.target_component_id().unwrap_or(0)),
    }
}

/// PX4's first two rules: whether a message with `message_id` aimed at
/// `target` leaves the vehicle `me` at all (before asking each other link
/// whether it has seen the target). `heartbeats`: `MAV_HB_FORW_EN`.
#[must_use]
pub fn leaves(message_id: u32, target: (u8, u8), me: Identity, heartbeats: bool) -> bool {
    if target == (me.system_id, me.component_id) {
        return false;
    }
    message_id != HEARTBEAT_ID || heartbeats
}

/// What became of a frame offered to a link by [`Forwarding::pass`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Passed {
    /// Queued for every peer of the link.
    Sent,
    /// Its target was never heard on this link (PX4 drops it too).
    NotSeen,
    /// Its sender was heard on this link: it would come back round.
    Loop,
    /// The link has no one to send it to.
    NoPeers,
    /// The link's forwarding budget is spent ([`FORWARD_RATE`]).
    OverBudget,
}

/// A link's forwarding state; a link has one only when its vehicle has
/// other links.
#[derive(Debug)]
pub struct Forwarding {
    fellows: Fellows,
    components: Components,
    /// Frames received here, for the other links ([`Forwarding::take`]).
    out: Vec<Forwarded>,
    /// Frames from the other links, to send as they are.
    passed: Vec<Vec<u8>>,
    budget: TokenBucket,
}

impl Forwarding {
    /// Forwarding for the link that holds `fellows`, from `now`.
    #[must_use]
    pub fn new(fellows: Fellows, now: Instant) -> Self {
        Self {
            fellows,
            components: Components::default(),
            out: Vec::new(),
            passed: Vec::new(),
            budget: TokenBucket::new(now, FORWARD_RATE, 2.0 * FORWARD_RATE),
        }
    }

    /// A frame from `(system, component)` was received (signing passed, not our own).
    pub fn heard(&mut self, system: u8, component: u8) {
        if self.components.note(system, component) {
            self.fellows.set_heard();
        }
    }

    /// A received frame, decoded as `msg`: kept for the other links if PX4
    /// would forward it ([`leaves`]; `heartbeats` is `MAV_HB_FORW_EN`).
    /// Whether another link has seen its target is theirs to say
    /// ([`Forwarding::pass`]); nothing is kept while no other link has
    /// heard anyone.
    pub fn offer(
        &mut self,
        bytes: &[u8],
        source: (u8, u8),
        message_id: u32,
        msg: &Inbound,
        me: Identity,
        heartbeats: impl FnOnce() -> bool,
    ) {
        if !self.fellows.others_heard() {
            return;
        }
        let target = target(msg);
        if leaves(message_id, target, me, message_id == HEARTBEAT_ID && heartbeats()) {
            self.out.push(Forwarded {
                bytes: bytes.to_vec(),
                source,
                target,
            });
        }
    }

    /// The frames kept for the other links since the last call.
    pub fn take(&mut self) -> Vec<Forwarded> {
        std::mem::take(&mut self.out)
    }

    /// A frame from another link of the vehicle, to be sent to this link's
    /// `fanout` peers: queued if its target was seen here, its sender was
    /// not, and the budget allows.
    pub fn pass(&mut self, now: Instant, f: &Forwarded, fanout: usize) -> Passed {
        if !self.components.was_seen(f.target.0, f.target.1) {
            return Passed::NotSeen;
        }
        if self.components.has(f.source.0, f.source.1) {
            return Passed::Loop;
        }
        if fanout == 0 {
            return Passed::NoPeers;
        }
        if !self.budget.take(now, f.bytes.len() * fanout) {
            return Passed::OverBudget;
        }
        self.passed.push(f.bytes.clone());
        Passed::Sent
    }

    /// The frames queued by [`Forwarding::pass`] since the last call.
    pub fn drain_passed(&mut self) -> Vec<Vec<u8>> {
        std::mem::take(&mut self.passed)
    }
}

#[cfg(test)]
mod tests;
