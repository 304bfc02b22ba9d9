//! One task per UDP link: it owns a [`Link`] (the protocol, sans I/O) and
//! its socket, receives datagrams, sends the streams when due (wall-time
//! rates; heartbeats keep going at 1 Hz even if the simulation is slow),
//! forwards commands, parameter sets and plan changes to the simulation
//! thread and sends the answers. While the vehicle's radio is silent (an
//! injected MAVLINK_SIGNAL failure) it sends nothing, bar the ACK of the
//! command that silenced it, and keeps receiving.

use std::net::SocketAddr;
use std::sync::mpsc::TrySendError;
use std::sync::{Arc, Mutex};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use tokio::net::UdpSocket;
use tokio::sync::{Notify, broadcast, mpsc, oneshot, watch};
use tokio::time::Instant;
use tracing::{debug, warn};

use super::saver::lock;
use super::sim_thread::{Event, SimRequest};
use crate::autopilot::{AutopilotCommand, CommandOutcome, PowerAction};
use crate::link::{Effect, Link, Outgoing, To};
use crate::lockstep::Snapshot;
use crate::mission::MissionResult;
use crate::params::ParamStore;

/// One link's task state.
pub(super) struct LinkTask {
    pub(super) link: Link,
    pub(super) socket: UdpSocket,
    pub(super) params: Arc<Mutex<ParamStore>>,
    pub(super) tel: watch::Receiver<Snapshot>,
    /// The world's radio is silent: send nothing.
    pub(super) link_lost: watch::Receiver<bool>,
    pub(super) sim: super::inbox::InboxSender<SimRequest>,
    pub(super) events: broadcast::Sender<Event>,
    pub(super) events_rx: broadcast::Receiver<Event>,
    pub(super) save: Arc<Notify>,
    pub(super) exit: mpsc::Sender<()>,
    pub(super) dests: Vec<SocketAddr>,
    pub(super) send_errors: u64,
    /// This link's `.tlog` (`--log-dir`; inert without).
    pub(super) tlog: super::tlog::Tlog,
}

/// How long a link waits for the autopilot's answer before ACKing FAILED
/// (or MISSION_ACK ERROR for a plan change).
const COMMAND_TIMEOUT: Duration = Duration::from_secs(1);

fn unix_time_us() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_micros()).unwrap_or(u64::MAX))
}

/// The largest datagram a link sends: several MAVLink frames share one
/// datagram up to this size, as PX4's UDP links send them (one system call
/// per datagram, not per frame; every MAVLink client parses all the frames
/// of a datagram). 1472 bytes: an Ethernet MTU less the IP and UDP headers.
pub(super) const MAX_DATAGRAM: usize = 1472;

/// `frames` as datagrams: for each destination (a frame's peer, or every
/// address of `all` for [`To::All`]) its frames in order, packed into
/// datagrams of at most [`MAX_DATAGRAM`] bytes (a frame is never split).
fn pack_datagrams(frames: &[Outgoing], all: &[SocketAddr]) -> Vec<(SocketAddr, Vec<u8>)> {
    let mut out: Vec<(SocketAddr, Vec<u8>)> = Vec::new();
    // each destination's open datagram, by index in `out`
    let mut open: Vec<(SocketAddr, usize)> = Vec::new();
    for Outgoing { to, bytes } in frames {
        let dests = match to {
            To::Peer(a) => std::slice::from_ref(a),
            To::All => all,
        };
        for &a in dests {
            match open.iter_mut().find(|(d, _)| *d == a) {
                Some((_, k)) if out[*k].1.len() + bytes.len() <= MAX_DATAGRAM => out[*k].1.extend_from_slice(bytes),
                Some((_, k)) => {
                    *k = out.len();
                    out.push((a, bytes.clone()));
                }
                None => {
                    open.push((a, out.len()));
                    out.push((a, bytes.clone()));
                }
            }
        }
    }
    out
}

impl LinkTask {
    /// Serve the link until `stop`. Fair under a flood (issue 15 §2): the
    /// branches are tried in order stop, due streams, events, socket, so
    /// the scheduler runs whenever a deadline has passed and at most one
    /// datagram is handled between two looks at it; a datagram whose
    /// effects wait on the simulation looks again after each effect.
    pub(super) async fn run(mut self, mut stop: watch::Receiver<bool>) {
        let name = self.link.config().name.clone();
        let mut buf = vec![0u8; 65_536];
        loop {
            let deadline = self
                .link
                .next_deadline()
                .map_or_else(|| Instant::now() + Duration::from_secs(1), Instant::from_std);
            tokio::select! {
                biased;
                _ = stop.changed() => break,
                () = tokio::time::sleep_until(deadline) => self.poll_streams().await,
                ev = self.events_rx.recv() => match ev {
                    Ok(Event::StatusText(s)) => {
                        self.link.status_text(&s);
                        self.flush().await;
                    }
                    Ok(Event::ParamValue(m)) => self.link.broadcast_param(Instant::now().into_std(), &m),
                    Ok(Event::MissionItemReached(seq)) => {
                        self.link.on_mission_item_reached(Instant::now().into_std(), seq);
                        self.flush().await;
                    }
                    Err(broadcast::error::RecvError::Lagged(n)) => warn!(link = %name, missed = n, "events dropped"),
                    Err(broadcast::error::RecvError::Closed) => break,
                },
                r = self.socket.recv_from(&mut buf) => match r {
                    Ok((n, from)) => {
                        self.tlog.received(&buf[..n]);
                        let effects = {
                            let t = self.tel.borrow();
                            let p = lock(&self.params);
                            self.link.on_datagram(Instant::now().into_std(), from, &buf[..n], &t, &*p)
                        };
                        self.flush().await;
                        for e in effects {
                            if !self.effect(e).await {
                                return;
                            }
                            if self.link.next_deadline().is_some_and(|d| d <= Instant::now().into_std()) {
                                self.poll_streams().await;
                            }
                        }
                    }
                    Err(e) => {
                        debug!(link = %name, error = %e, "recv failed");
                        // do not spin if the error persists
                        tokio::time::sleep(Duration::from_millis(10)).await;
                    }
                },
            }
        }
        let s = self.link.stats();
        debug!(
            link = %name,
            frames_in = s.frames_in,
            ignored = s.ignored,
            held_back = s.held_back,
            streams_shed = s.streams_shed,
            "link stopped"
        );
    }

    /// Send what is due: streams, delayed frames, parameter lists, mission
    /// retries.
    async fn poll_streams(&mut self) {
        {
            let t = self.tel.borrow();
            self.link.poll(Instant::now().into_std(), &t, unix_time_us());
        }
        self.tlog.flush_if_due();
        self.flush().await;
    }

    /// Hand a request to the simulation thread without blocking this task
    /// (the queue only fills if the simulation is stuck). False when it is gone.
    fn to_sim(&self, r: SimRequest) -> Result<(), bool> {
        match self.sim.try_send(r) {
            Ok(()) => Ok(()),
            Err(TrySendError::Full(_)) => Err(true),
            Err(TrySendError::Disconnected(_)) => Err(false),
        }
    }

    /// Carry out one effect; false when the daemon is going down.
    async fn effect(&mut self, e: Effect) -> bool {
        match e {
            Effect::Autopilot { command, ack: None } => {
                // Offboard setpoints: a dropped one is replaced by the next
                // (MAVSDK streams at 20 Hz).
                let _ = self.to_sim(SimRequest::Command { command, reply: None });
            }
            Effect::Autopilot {
                command,
                ack: Some(ticket),
            } => {
                let Some(outcome) = self.command(command).await else {
                    return false;
                };
                self.link.on_outcome(ticket, &outcome);
                if matches!(command, AutopilotCommand::InjectFailure { .. }) {
                    // the answer to the injection goes out even if it silenced the radio
                    self.flush_muted(false).await;
                } else {
                    self.flush().await;
                }
                if command == AutopilotCommand::Power(PowerAction::Shutdown) && outcome == CommandOutcome::Accepted {
                    // PX4 SITL exits after acknowledging
                    let _ = self.exit.try_send(());
                }
            }
            Effect::SetParam { ticket, value } => {
                let (tx, rx) = oneshot::channel();
                let outcome = match self.to_sim(SimRequest::SetParam {
                    name: ticket.name.clone(),
                    value,
                    reply: tx,
                }) {
                    Err(false) => return false,
                    Err(true) => Err("simulation busy".to_string()),
                    Ok(()) => match tokio::time::timeout(COMMAND_TIMEOUT, rx).await {
                        Ok(Ok(o)) => o,
                        Ok(Err(_)) => return false,
                        Err(_) => Err("autopilot did not answer".to_string()),
                    },
                };
                let changed = {
                    let p = lock(&self.params);
                    self.link.on_param_set(&ticket, outcome, &*p)
                };
                self.flush().await;
                if let Some(m) = changed {
                    let _ = self.events.send(Event::ParamValue(Arc::new(m)));
                    self.save.notify_one();
                }
            }
            Effect::Plans { ticket, change } => {
                let (tx, rx) = oneshot::channel();
                // a busy, slow or stuck flight stack changed nothing: ERROR
                let outcome = match self.to_sim(SimRequest::Plans { change, reply: tx }) {
                    Err(false) => return false,
                    Err(true) => Err(MissionResult::Error),
                    Ok(()) => match tokio::time::timeout(COMMAND_TIMEOUT, rx).await {
                        Ok(Ok(o)) => o,
                        Ok(Err(_)) => return false,
                        Err(_) => Err(MissionResult::Error),
                    },
                };
                self.link.on_plans_changed(ticket, outcome);
                self.flush().await;
            }
            Effect::GcsHeartbeat => {
                // a dropped one is replaced by the next (GCSs send at 1 Hz)
                let _ = self.to_sim(SimRequest::GcsHeartbeat);
            }
            Effect::SetMissionCurrent { seq } => {
                let Some(outcome) = self.command(AutopilotCommand::SetMissionCurrent { seq }).await else {
                    return false;
                };
                {
                    // published before the answer: it has the new current item
                    let t = self.tel.borrow();
                    self.link.on_mission_current_set(seq, &outcome, &t);
                }
                self.flush().await;
            }
        }
        true
    }

    /// Give the autopilot a command and wait for its outcome (refused as
    /// busy or unanswered when the simulation is); `None` when the
    /// daemon is going down.
    async fn command(&self, command: AutopilotCommand) -> Option<CommandOutcome> {
        let (tx, rx) = oneshot::channel();
        let outcome = match self.to_sim(SimRequest::Command {
            command,
            reply: Some(tx),
        }) {
            Err(false) => return None,
            Err(true) => CommandOutcome::TemporarilyRejected("simulation busy"),
            Ok(()) => match tokio::time::timeout(COMMAND_TIMEOUT, rx).await {
                Ok(Ok(o)) => o,
                Ok(Err(_)) => return None,
                Err(_) => CommandOutcome::Failed("autopilot did not answer"),
            },
        };
        Some(outcome)
    }

    async fn flush(&mut self) {
        let muted = *self.link_lost.borrow();
        self.flush_muted(muted).await;
    }

    /// Send what the link has queued, or drop it when `muted`: the frames
    /// for each destination packed into as few datagrams as fit
    /// ([`pack_datagrams`]).
    async fn flush_muted(&mut self, muted: bool) {
        let out = self.link.drain();
        if out.is_empty() || muted {
            return;
        }
        let now = Instant::now().into_std();
        if out.iter().any(|o| o.to == To::All) {
            self.link.destinations(now, &mut self.dests);
        }
        for o in &out {
            if matches!(o.to, To::Peer(_)) || !self.dests.is_empty() {
                self.tlog.sent(&o.bytes);
            }
        }
        for (to, datagram) in pack_datagrams(&out, &self.dests) {
            self.send(&datagram, to).await;
        }
    }

    async fn send(&mut self, bytes: &[u8], to: SocketAddr) {
        if let Err(e) = self.socket.send_to(bytes, to).await {
            self.send_errors += 1;
            // rate-limited: the first, then every 1000th
            if self.send_errors % 1000 == 1 {
                debug!(link = %self.link.config().name, %to, error = %e, count = self.send_errors, "send failed");
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_are_packed_per_destination_in_order_never_split() {
        let a: SocketAddr = "127.0.0.1:1".parse().unwrap();
        let b: SocketAddr = "127.0.0.1:2".parse().unwrap();
        let f = |to, n: usize, tag: u8| Outgoing {
            to,
            bytes: vec![tag; n],
        };
        let frames = vec![
            f(To::All, 100, 1),
            f(To::Peer(b), 50, 2),
            f(To::All, 1300, 3),
            f(To::All, 60, 4),
        ];
        let d = pack_datagrams(&frames, &[a, b]);
        let summary: Vec<(SocketAddr, Vec<u8>)> = d
            .iter()
            .map(|(to, bytes)| {
                let mut tags: Vec<u8> = bytes.clone();
                tags.dedup();
                (*to, tags)
            })
            .collect();
        // a: 100 + 1300 + 60 = 1460 bytes fit one datagram; b: 100 + 50 +
        // 1300 = 1450, and 60 more would not: frame 4 opens b's second
        assert_eq!(summary, vec![(a, vec![1, 3, 4]), (b, vec![1, 2, 3]), (b, vec![4])]);
        assert!(d.iter().all(|(_, x)| x.len() <= MAX_DATAGRAM));
        let total: usize = d.iter().map(|(_, x)| x.len()).sum();
        assert_eq!(total, 2 * (100 + 1300 + 60) + 50);
    }
}
