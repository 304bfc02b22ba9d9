//! What the link tasks and the simulation thread say to each other, and
//! what they share: [`SimRequest`] (links to the simulation thread), [`Event`]
//! (the simulation thread and the savers to every link), the one-shot
//! answer of a request with its claim ([`Reply`], [`Waiter`]), and the
//! parameter store's [`lock`]. A leaf of the daemon: every task file
//! imports it, it imports none of them.
//!
//! # The claim
//!
//! A link's request to the simulation thread is answered once, with a
//! claim that makes a timed-out request either applied (and answered late)
//! or never applied — never refused and then applied.
//!
//! Each request carries one [`Reply`] (the simulation thread's end) and the
//! link keeps its [`Waiter`]. Both ends share one state, changed once by
//! compare-and-swap:
//!
//! ```text
//! Pending --claim() by the simulation thread, before it applies--> Claimed
//! Pending --the link's wait times out----------------------------> Abandoned
//! ```
//!
//! The simulation thread applies a request only when its claim wins, so a
//! request the link gave up on ("did not answer": FAILED, PARAM_ERROR,
//! MISSION_ACK ERROR) is dropped unapplied; a request claimed before the
//! link's timeout is waited for to the end and answered with what the
//! autopilot decided, however late.

use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use mavlink::dialects::common::{EVENT_DATA, MavMessage};
use tokio::sync::oneshot;

use crate::autopilot::{AutopilotCommand, CommandOutcome, StatusText};
use crate::mission::{MissionResult, PlanChange};
use crate::params::{ParamStore, ParamValue};

/// Messages from the link tasks to the simulation thread.
#[derive(Debug)]
pub(super) enum SimRequest {
    /// A command, answered on `reply` (offboard setpoints have none).
    Command {
        command: AutopilotCommand,
        reply: Option<Reply<CommandOutcome>>,
    },
    /// A parameter set, answered with the stored value or why it was refused.
    SetParam {
        name: String,
        value: ParamValue,
        reply: Reply<Result<ParamValue, String>>,
    },
    /// Store or clear plans, answered with the new plan's id or why nothing changed.
    Plans {
        change: PlanChange,
        reply: Reply<Result<u32, MissionResult>>,
    },
    /// A ground station's HEARTBEAT arrived (data-link loss supervision; no answer).
    GcsHeartbeat,
    /// A link streams a raw sensor message: simulate the vehicle's raw
    /// sensors from now on (no answer; nothing when they already are).
    /// Not recorded: they change no other number of the flight, and a run
    /// that keeps a flight record simulates them from its first step.
    RawSensors,
}

impl SimRequest {
    /// Take the request up before applying it: true when it may be applied
    /// (claimed, or one without an answer), false when its link has given
    /// up on it: the simulation thread then drops it unapplied.
    pub(super) fn claim(&self) -> bool {
        let claimed = match self {
            SimRequest::Command { reply: Some(x), .. } => x.claim(),
            SimRequest::SetParam { reply, .. } => reply.claim(),
            SimRequest::Plans { reply, .. } => reply.claim(),
            _ => true,
        };
        if !claimed {
            tracing::debug!("a request its link gave up on is dropped unapplied");
        }
        claimed
    }
}

/// Messages to every link task.
#[derive(Clone, Debug)]
pub(super) enum Event {
    StatusText(StatusText),
    /// MISSION_ITEM_REACHED for this seq.
    MissionItemReached(u16),
    ParamValue(Arc<MavMessage>),
    /// EVENTs of the health and arming report, numbered for the vehicle.
    Events(Arc<Vec<EVENT_DATA>>),
}

/// The parameter store, locked (never across an `.await`).
pub(super) fn lock(p: &Mutex<ParamStore>) -> MutexGuard<'_, ParamStore> {
    // A panic while holding the lock leaves the store consistent (every
    // mutation is a single checked set), so a poisoned lock is still usable.
    p.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

const PENDING: u8 = 0;
const CLAIMED: u8 = 1;
const ABANDONED: u8 = 2;

/// The simulation thread's end of one request's answer.
#[derive(Debug)]
pub(super) struct Reply<T> {
    tx: oneshot::Sender<T>,
    state: Arc<AtomicU8>,
}

/// The link's end of one request's answer.
#[derive(Debug)]
pub(super) struct Waiter<T> {
    rx: oneshot::Receiver<T>,
    state: Arc<AtomicU8>,
}

/// How a request the link waited for ended.
#[derive(Debug, PartialEq, Eq)]
pub(super) enum Answer<T> {
    /// Applied (or refused) by the autopilot: its answer.
    Done(T),
    /// Not taken up within the timeout: given up, and never applied.
    Expired,
    /// The simulation thread is gone (the daemon is going down).
    Gone,
}

/// A fresh answer channel for one request.
pub(super) fn reply<T>() -> (Reply<T>, Waiter<T>) {
    let (tx, rx) = oneshot::channel();
    let state = Arc::new(AtomicU8::new(PENDING));
    (
        Reply {
            tx,
            state: state.clone(),
        },
        Waiter { rx, state },
    )
}

impl<T> Reply<T> {
    /// Take the request up: true when it may be applied, false when the
    /// link has given up on it (then it must not be applied).
    pub(super) fn claim(&self) -> bool {
        self.state
            .compare_exchange(PENDING, CLAIMED, Ordering::AcqRel, Ordering::Acquire)
            .is_ok()
    }

    /// Answer; the value back when the link is gone (as `oneshot::Sender::send`).
    ///
    /// # Errors
    /// The link stopped waiting.
    pub(super) fn send(self, value: T) -> Result<(), T> {
        self.tx.send(value)
    }
}

impl<T> Waiter<T> {
    /// Wait for the answer; when none came within `timeout`, give the
    /// request up unless the simulation thread has already claimed it, in
    /// which case wait for its answer to the end.
    pub(super) async fn wait(mut self, timeout: Duration) -> Answer<T> {
        match tokio::time::timeout(timeout, &mut self.rx).await {
            Ok(Ok(v)) => return Answer::Done(v),
            Ok(Err(_)) => return Answer::Gone,
            Err(_) => {}
        }
        if self
            .state
            .compare_exchange(PENDING, ABANDONED, Ordering::AcqRel, Ordering::Acquire)
            .is_ok()
        {
            return Answer::Expired;
        }
        // claimed: being applied now; its answer follows
        match self.rx.await {
            Ok(v) => Answer::Done(v),
            Err(_) => Answer::Gone,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn a_request_given_up_on_is_never_claimed() {
        let (r, w) = reply::<u32>();
        assert_eq!(w.wait(Duration::from_millis(20)).await, Answer::Expired);
        assert!(!r.claim(), "the simulation thread must not apply it");
    }

    #[tokio::test]
    async fn a_claimed_request_is_answered_late_not_expired() {
        let (r, w) = reply::<u32>();
        assert!(r.claim());
        let slow = tokio::spawn(async move {
            tokio::time::sleep(Duration::from_millis(100)).await;
            let _ = r.send(7);
        });
        assert_eq!(w.wait(Duration::from_millis(10)).await, Answer::Done(7));
        slow.await.unwrap();
    }

    #[tokio::test]
    async fn an_answer_in_time_and_a_vanished_simulation() {
        let (r, w) = reply::<u32>();
        assert!(r.claim());
        let _ = r.send(3);
        assert_eq!(w.wait(Duration::from_millis(10)).await, Answer::Done(3));
        let (r, w) = reply::<u32>();
        drop(r);
        assert_eq!(w.wait(Duration::from_millis(10)).await, Answer::Gone);
        // claimed, then dropped unanswered (the thread died mid-request)
        let (r, w) = reply::<u32>();
        assert!(r.claim());
        let t = tokio::spawn(async move {
            tokio::time::sleep(Duration::from_millis(50)).await;
            drop(r);
        });
        assert_eq!(w.wait(Duration::from_millis(10)).await, Answer::Gone);
        t.await.unwrap();
    }
}
