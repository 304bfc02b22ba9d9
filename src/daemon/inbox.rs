//! The simulation thread's inbox: one bounded queue per vehicle, served
//! round robin, so that a client that floods its vehicle with requests
//! fills only that vehicle's queue (its link then answers "busy") and
//! cannot delay another vehicle's requests by more than one request per
//! vehicle ahead of it in the round.
//!
//! A link task hands a request over with [`InboxSender::try_send`] (never
//! blocking the runtime); the simulation thread takes the next one with
//! [`Inbox::recv_timeout`] (sleeping until one comes or the tick is due)
//! or [`Inbox::try_recv`] (between batches of steps). A vehicle with
//! requests waiting is in the `ready` ring once; each take serves the
//! vehicle at the ring's front and moves it to the back if more wait.

use std::collections::VecDeque;
use std::sync::mpsc::{RecvTimeoutError, TryRecvError, TrySendError};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::Duration;

/// Requests a vehicle may have waiting; more are refused as busy.
pub(super) const QUEUE_CAP: usize = 64;

struct State<T> {
    queues: Vec<VecDeque<T>>,
    /// Vehicles with requests waiting, each once, in the order to serve.
    ready: VecDeque<usize>,
    /// Live senders; none left: the inbox is disconnected.
    senders: usize,
    /// The receiver is gone.
    closed: bool,
    /// Told to stop ([`Stopper::stop`]): the receiver sees the end at once,
    /// whatever waits in the queues.
    stopped: bool,
}

struct Shared<T> {
    state: Mutex<State<T>>,
    bell: Condvar,
}

impl<T> Shared<T> {
    fn lock(&self) -> MutexGuard<'_, State<T>> {
        // a panicking holder left consistent queues (each change is one push or pop)
        self.state.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
    }
}

/// The receiving end (the simulation thread's).
pub(super) struct Inbox<T> {
    shared: Arc<Shared<T>>,
}

/// One vehicle's sending end (cloned for each of its links).
pub(super) struct InboxSender<T> {
    shared: Arc<Shared<T>>,
    vehicle: usize,
}

/// An inbox for `vehicles` vehicles and no senders yet ([`Inbox::sender`]).
pub(super) fn inbox<T>(vehicles: usize) -> Inbox<T> {
    Inbox {
        shared: Arc::new(Shared {
            state: Mutex::new(State {
                queues: (0..vehicles).map(|_| VecDeque::new()).collect(),
                ready: VecDeque::new(),
                senders: 0,
                closed: false,
                stopped: false,
            }),
            bell: Condvar::new(),
        }),
    }
}

impl<T> Inbox<T> {
    /// A sender for vehicle `vehicle`'s queue.
    pub(super) fn sender(&self, vehicle: usize) -> InboxSender<T> {
        self.shared.lock().senders += 1;
        InboxSender {
            shared: self.shared.clone(),
            vehicle,
        }
    }

    fn take(state: &mut State<T>) -> Option<(usize, T)> {
        let v = state.ready.pop_front()?;
        let q = &mut state.queues[v];
        let r = q.pop_front()?;
        if !q.is_empty() {
            state.ready.push_back(v);
        }
        Some((v, r))
    }

    /// Something that stops the receiver from another thread.
    pub(super) fn stopper(&self) -> Stopper<T> {
        Stopper {
            shared: self.shared.clone(),
        }
    }

    /// The next request, round robin over the vehicles, without waiting;
    /// `Disconnected` once stopped or every sender is gone.
    pub(super) fn try_recv(&self) -> Result<(usize, T), TryRecvError> {
        let mut s = self.shared.lock();
        if s.stopped {
            return Err(TryRecvError::Disconnected);
        }
        match Self::take(&mut s) {
            Some(x) => Ok(x),
            None if s.senders == 0 => Err(TryRecvError::Disconnected),
            None => Err(TryRecvError::Empty),
        }
    }

    /// The next request, waiting at most `timeout` for one.
    pub(super) fn recv_timeout(&self, timeout: Duration) -> Result<(usize, T), RecvTimeoutError> {
        let mut s = self.shared.lock();
        let deadline = std::time::Instant::now() + timeout;
        loop {
            if s.stopped {
                return Err(RecvTimeoutError::Disconnected);
            }
            if let Some(x) = Self::take(&mut s) {
                return Ok(x);
            }
            if s.senders == 0 {
                return Err(RecvTimeoutError::Disconnected);
            }
            let now = std::time::Instant::now();
            if now >= deadline {
                return Err(RecvTimeoutError::Timeout);
            }
            s = self
                .shared
                .bell
                .wait_timeout(s, deadline - now)
                .unwrap_or_else(std::sync::PoisonError::into_inner)
                .0;
        }
    }

    /// Requests waiting, over every vehicle.
    pub(super) fn len(&self) -> usize {
        self.shared.lock().queues.iter().map(VecDeque::len).sum()
    }
}

impl<T> Drop for Inbox<T> {
    fn drop(&mut self) {
        let mut s = self.shared.lock();
        s.closed = true;
        for q in &mut s.queues {
            q.clear();
        }
        s.ready.clear();
    }
}

/// Stops the receiver ([`Inbox::stopper`]): out of band, so a vehicle's
/// full queue cannot hold up the daemon's shutdown.
pub(super) struct Stopper<T> {
    shared: Arc<Shared<T>>,
}

impl<T> Stopper<T> {
    /// From now on the receiver gets `Disconnected`.
    pub(super) fn stop(&self) {
        self.shared.lock().stopped = true;
        self.shared.bell.notify_all();
    }
}

impl<T> InboxSender<T> {
    /// Queue `r` for this sender's vehicle: `Full` when [`QUEUE_CAP`]
    /// requests already wait, `Disconnected` when the simulation is gone.
    pub(super) fn try_send(&self, r: T) -> Result<(), TrySendError<T>> {
        let mut s = self.shared.lock();
        if s.closed {
            return Err(TrySendError::Disconnected(r));
        }
        let v = self.vehicle;
        let q = &mut s.queues[v];
        if q.len() >= QUEUE_CAP {
            return Err(TrySendError::Full(r));
        }
        let was_empty = q.is_empty();
        q.push_back(r);
        if was_empty {
            s.ready.push_back(v);
        }
        drop(s);
        self.shared.bell.notify_one();
        Ok(())
    }
}

impl<T> Clone for InboxSender<T> {
    fn clone(&self) -> Self {
        self.shared.lock().senders += 1;
        Self {
            shared: self.shared.clone(),
            vehicle: self.vehicle,
        }
    }
}

impl<T> Drop for InboxSender<T> {
    fn drop(&mut self) {
        let mut s = self.shared.lock();
        s.senders -= 1;
        drop(s);
        self.shared.bell.notify_one();
    }
}

impl<T> std::fmt::Debug for InboxSender<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("InboxSender").field("vehicle", &self.vehicle).finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_flooded_vehicle_fills_only_its_queue_and_the_others_are_served_in_turn() {
        let inbox = inbox::<u32>(3);
        let a = inbox.sender(0);
        let b = inbox.sender(1);
        let c = inbox.sender(2);
        for k in 0..QUEUE_CAP as u32 {
            a.try_send(k).unwrap();
        }
        assert!(matches!(a.try_send(999), Err(TrySendError::Full(999))));
        b.try_send(100).unwrap();
        c.try_send(200).unwrap();
        b.try_send(101).unwrap();
        // round robin: a, b, c, a, b, a, a, ...
        let got: Vec<(usize, u32)> = (0..6).map(|_| inbox.try_recv().unwrap()).collect();
        assert_eq!(got, vec![(0, 0), (1, 100), (2, 200), (0, 1), (1, 101), (0, 2)]);
        assert_eq!(inbox.len(), QUEUE_CAP - 3);
        // a's queue has room again
        a.try_send(1000).unwrap();
    }

    #[test]
    fn the_inbox_disconnects_when_every_sender_is_gone_and_refuses_after_it_is_dropped() {
        let inbox = inbox::<u32>(1);
        let a = inbox.sender(0);
        let a2 = a.clone();
        a.try_send(1).unwrap();
        drop(a);
        drop(a2);
        // what was sent is still served, then the end
        assert_eq!(inbox.try_recv().unwrap(), (0, 1));
        assert!(matches!(inbox.try_recv(), Err(TryRecvError::Disconnected)));
        assert!(matches!(
            inbox.recv_timeout(Duration::from_millis(1)),
            Err(RecvTimeoutError::Disconnected)
        ));
        let inbox = super::inbox::<u32>(1);
        let a = inbox.sender(0);
        assert!(matches!(
            inbox.recv_timeout(Duration::from_millis(1)),
            Err(RecvTimeoutError::Timeout)
        ));
        drop(inbox);
        assert!(matches!(a.try_send(1), Err(TrySendError::Disconnected(1))));
    }

    #[test]
    fn a_stop_gets_through_a_full_queue_at_once() {
        let inbox = super::inbox::<u32>(1);
        let a = inbox.sender(0);
        for k in 0..QUEUE_CAP as u32 {
            a.try_send(k).unwrap();
        }
        let stopper = inbox.stopper();
        std::thread::spawn(move || stopper.stop()).join().unwrap();
        assert!(matches!(inbox.try_recv(), Err(TryRecvError::Disconnected)));
        assert!(matches!(
            inbox.recv_timeout(Duration::from_secs(5)),
            Err(RecvTimeoutError::Disconnected)
        ));
    }
}
