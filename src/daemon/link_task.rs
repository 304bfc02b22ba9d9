//! One task per UDP link: it owns a [`Link`] (the protocol, sans I/O) and
//! its socket, receives datagrams, sends the streams when due (wall-time
//! rates; heartbeats keep going at 1 Hz even if the simulation is slow),
//! forwards commands, parameter sets and plan changes to the simulation
//! thread and sends the answers. While the vehicle's radio is silent (an
//! injected MAVLINK_SIGNAL failure) it sends nothing, bar the ACK of the
//! command that silenced it, and keeps receiving. The tasks of one vehicle's
//! links hand each other the frames PX4 forwards between links
//! ([`crate::link::forward`]), over bounded queues ([`Forwards`]).

use std::net::SocketAddr;
use std::sync::mpsc::TrySendError;
use std::sync::{Arc, Mutex};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use tokio::net::UdpSocket;
use tokio::sync::{Notify, broadcast, mpsc, watch};
use tokio::time::Instant;
use tracing::{debug, warn};

use super::messages::{Answer, Event, SimRequest, lock, reply};
use crate::autopilot::{AutopilotCommand, CommandOutcome};
use crate::link::forward::{Fellows, Forwarded};
use crate::link::{Effect, Link, Outgoing, To};
use crate::lockstep::Snapshot;
use crate::mission::MissionResult;
use crate::params::{ParamStore, ParamValue};

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
    /// The parameter file, written through on each accepted set before the echo.
    pub(super) params_file: super::saver::ParamsFile,
    pub(super) dests: Vec<SocketAddr>,
    pub(super) send_errors: u64,
    /// This link's `.tlog` (`--log-dir`; inert without).
    pub(super) tlog: super::tlog::Tlog,
    /// Notified when SETUP_SIGNING changed the vehicle's key (`signing.rs` stores it).
    pub(super) signing_changed: Arc<Notify>,
    /// Frames to and from the vehicle's other links.
    pub(super) forwards: Forwards,
}

/// Frames forwarded between the links of one vehicle: what a link task
/// receives from the others, and the queues of the others. A frame that
/// finds a queue full is dropped (PX4 holds two per link and drops the rest).
#[derive(Debug, Default)]
pub(super) struct Forwards {
    inbox: Option<mpsc::Receiver<Forwarded>>,
    others: Vec<mpsc::Sender<Forwarded>>,
}

/// Frames a link task holds for it from the other links before dropping more.
const FORWARD_QUEUE: usize = 64;

impl Forwards {
    /// The queues of a vehicle's `n` links, and each link's share of the
    /// vehicle's forwarding state; nothing for a lone link (it forwards nothing).
    pub(super) fn for_links(n: usize) -> Vec<(Self, Option<Fellows>)> {
        if n < 2 {
            return (0..n).map(|_| (Self::default(), None)).collect();
        }
        let (txs, rxs): (Vec<_>, Vec<_>) = (0..n).map(|_| mpsc::channel(FORWARD_QUEUE)).unzip();
        rxs.into_iter()
            .zip(Fellows::for_links(n))
            .enumerate()
            .map(|(i, (rx, fellows))| {
                let others = txs
                    .iter()
                    .enumerate()
                    .filter(|(j, _)| *j != i)
                    .map(|(_, t)| t.clone())
                    .collect();
                (
                    Self {
                        inbox: Some(rx),
                        others,
                    },
                    Some(fellows),
                )
            })
            .collect()
    }

    /// The next frame from another link (pending for ever without any).
    async fn recv(&mut self) -> Option<Forwarded> {
        match self.inbox.as_mut() {
            Some(rx) => rx.recv().await,
            None => std::future::pending().await,
        }
    }

    /// Hand `frames` to every other link, dropping what finds a queue full.
    fn send(&self, frames: Vec<Forwarded>) {
        for f in frames {
            for tx in &self.others {
                let _ = tx.try_send(f.clone());
            }
        }
    }
}

/// How long a link waits for the simulation thread to take a request up
/// before giving it up: ACK FAILED ("autopilot did not answer"), PARAM_ERROR,
/// or MISSION_ACK ERROR, and the request is never applied. One taken up in
/// time is answered when done, however late ([`super::messages`]).
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

/// What MAV_SYS_ID answers when asked to change: the system id is the
/// instance's (instance + 1, as PX4 SITL's startup sets it on every start),
/// so a set would be lost at the next start; it is refused instead.
pub(super) const SYS_ID_REFUSAL: &str = "MAV_SYS_ID is instance+1: use --instance";

/// What MAV_COMP_ID answers when asked to change: the autopilot is
/// component 1, as PX4's is.
pub(super) const COMP_ID_REFUSAL: &str = "MAV_COMP_ID is 1, the autopilot's";

/// A parameter set refused before the autopilot sees it, with why: the
/// vehicle's MAVLink ids to another value ([`SYS_ID_REFUSAL`],
/// [`COMP_ID_REFUSAL`]; the same value is accepted and changes nothing).
fn refuse_param_set(name: &str, value: ParamValue, params: &Mutex<ParamStore>) -> Option<String> {
    let why = match name {
        "MAV_SYS_ID" => SYS_ID_REFUSAL,
        "MAV_COMP_ID" => COMP_ID_REFUSAL,
        _ => return None,
    };
    (lock(params).get(name).map(|(_, v)| v) != Some(value)).then(|| why.to_string())
}

impl LinkTask {
    /// Serve the link until `stop`. Fair under a flood: the
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
                    Ok(Event::Events(list)) => {
                        self.link.send_events(Instant::now().into_std(), &list);
                        self.flush().await;
                    }
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
                        self.forwards.send(self.link.take_forwarded());
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
                // after the socket: this link's own clients come first
                f = self.forwards.recv() => match f {
                    Some(f) => {
                        self.link.pass(Instant::now().into_std(), &f);
                        self.flush().await;
                    }
                    None => self.forwards.inbox = None,
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
            forwarded = s.forwarded,
            forward_shed = s.forward_shed,
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
        if self.link.take_raw_sensors_request() {
            // lost only if the simulation is stuck (its queue full)
            let _ = self.to_sim(SimRequest::RawSensors);
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
            }
            Effect::SetParam { ticket, value } => {
                let outcome = match refuse_param_set(&ticket.name, value, &self.params) {
                    Some(why) => Err(why),
                    None => {
                        let (tx, rx) = reply();
                        match self.to_sim(SimRequest::SetParam {
                            name: ticket.name.clone(),
                            value,
                            reply: tx,
                        }) {
                            Err(false) => return false,
                            Err(true) => Err("simulation busy".to_string()),
                            Ok(()) => match rx.wait(COMMAND_TIMEOUT).await {
                                Answer::Done(o) => o,
                                Answer::Gone => return false,
                                Answer::Expired => Err("autopilot did not answer".to_string()),
                            },
                        }
                    }
                };
                // on disk before the echo (the saver retries a failed write)
                let not_saved = if outcome.is_ok() {
                    self.write_params().await.err()
                } else {
                    None
                };
                let changed = {
                    let p = lock(&self.params);
                    let changed = self.link.on_param_set(&ticket, outcome, &*p);
                    if let Some(why) = &not_saved {
                        self.link.on_param_not_saved(&ticket, why);
                    }
                    changed
                };
                self.flush().await;
                if let Some(m) = changed {
                    let _ = self.events.send(Event::ParamValue(Arc::new(m)));
                }
                if not_saved.is_some() {
                    self.save.notify_one();
                }
            }
            Effect::Plans { ticket, change } => {
                let (tx, rx) = reply();
                // a busy, slow or stuck flight stack changed nothing: ERROR
                let outcome = match self.to_sim(SimRequest::Plans { change, reply: tx }) {
                    Err(false) => return false,
                    Err(true) => Err(MissionResult::Error),
                    Ok(()) => match rx.wait(COMMAND_TIMEOUT).await {
                        Answer::Done(o) => o,
                        Answer::Gone => return false,
                        Answer::Expired => Err(MissionResult::Error),
                    },
                };
                self.link.on_plans_changed(ticket, outcome);
                self.flush().await;
            }
            Effect::SigningKeyChanged => self.signing_changed.notify_one(),
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
    /// busy, or as unanswered when the simulation did not take it up within
    /// [`COMMAND_TIMEOUT`]: then it is never applied); `None` when the
    /// daemon is going down.
    async fn command(&self, command: AutopilotCommand) -> Option<CommandOutcome> {
        let (tx, rx) = reply();
        let outcome = match self.to_sim(SimRequest::Command {
            command,
            reply: Some(tx),
        }) {
            Err(false) => return None,
            Err(true) => CommandOutcome::TemporarilyRejected("simulation busy"),
            Ok(()) => match rx.wait(COMMAND_TIMEOUT).await {
                Answer::Done(o) => o,
                Answer::Gone => return None,
                Answer::Expired => CommandOutcome::Failed("autopilot did not answer"),
            },
        };
        Some(outcome)
    }

    /// Write the parameters in force to the state directory now (off this
    /// task's thread); why not, naming the file, when the write failed.
    async fn write_params(&self) -> Result<(), String> {
        let file = self.params_file.clone();
        let params = self.params.clone();
        match tokio::task::spawn_blocking(move || file.save(&params)).await {
            Ok(Ok(())) => Ok(()),
            Ok(Err(e)) => {
                warn!(link = %self.link.config().name, error = %e, "parameter set not saved");
                Err(e.to_string())
            }
            Err(e) => Err(format!("parameter writer failed: {e}")),
        }
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

    /// A link task whose simulation thread is stalled: the test holds the
    /// inbox and serves it (or not) by hand.
    async fn stalled() -> (LinkTask, super::super::inbox::Inbox<SimRequest>) {
        use crate::link::LinkConfig;
        use crate::link::streams::{Identity, gcs_rates};
        let (mut core, store) = crate::lockstep::test_quad();
        let (_tel_tx, tel) = watch::channel(core.snapshot(0));
        let (_lost_tx, link_lost) = watch::channel(false);
        let (events, events_rx) = broadcast::channel(16);
        let inbox = super::super::inbox::inbox::<SimRequest>(1);
        let dir = std::env::temp_dir().join(format!("rotorpilot-stalled-{}", std::process::id()));
        let task = LinkTask {
            link: Link::new(
                LinkConfig {
                    name: "gcs".into(),
                    identity: Identity {
                        system_id: 1,
                        component_id: 1,
                    },
                    default_remote: None,
                    rates: gcs_rates(),
                    peer_timeout: Duration::from_secs(30),
                },
                Instant::now().into_std(),
            ),
            socket: UdpSocket::bind("127.0.0.1:0").await.unwrap(),
            params: Arc::new(Mutex::new(store)),
            tel,
            link_lost,
            sim: inbox.sender(0),
            events,
            events_rx,
            save: Arc::new(Notify::new()),
            params_file: super::super::saver::ParamsFile::new(dir.join("params.toml")),
            signing_changed: Arc::new(Notify::new()),
            dests: Vec::new(),
            send_errors: 0,
            tlog: super::super::tlog::Tlog::default(),
            forwards: Forwards::default(),
        };
        (task, inbox)
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_command_the_stalled_simulation_never_took_up_is_failed_and_never_applied() {
        let (task, inbox) = stalled().await;
        let t0 = std::time::Instant::now();
        let outcome = task.command(AutopilotCommand::Land).await;
        assert_eq!(outcome, Some(CommandOutcome::Failed("autopilot did not answer")));
        assert!(t0.elapsed() >= COMMAND_TIMEOUT);
        // the simulation wakes up: the request is there, and it must drop it
        let (_, r) = inbox.try_recv().unwrap();
        assert!(!r.claim(), "a FAILED command must never be applied");
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_command_taken_up_in_time_is_acknowledged_late_with_the_autopilots_answer() {
        let (task, inbox) = stalled().await;
        // the simulation takes it up in time, then takes longer than the timeout to apply it
        let sim = std::thread::spawn(move || {
            let (_, r) = inbox.recv_timeout(Duration::from_secs(5)).unwrap();
            assert!(r.claim(), "taken up in time");
            std::thread::sleep(COMMAND_TIMEOUT + Duration::from_millis(500));
            match r {
                SimRequest::Command { reply: Some(x), .. } => {
                    let _ = x.send(CommandOutcome::Accepted);
                }
                other => panic!("{other:?}"),
            }
        });
        let t0 = std::time::Instant::now();
        let outcome = task.command(AutopilotCommand::Land).await;
        assert_eq!(outcome, Some(CommandOutcome::Accepted), "late, not refused");
        assert!(t0.elapsed() > COMMAND_TIMEOUT);
        sim.join().unwrap();
    }
}
