//! The simulation thread: the only owner of the lockstep core (every vehicle
//! of the fleet, on one clock), paced against the wall clock. Every tick of
//! wall time it runs the steps that are due so that simulated time = speed x
//! wall time (batched: no per-step syscall; requests are served between
//! chunks of steps), then publishes each vehicle's [`Snapshot`] on its
//! `watch` and its status texts on its `broadcast`. Between ticks it sleeps
//! in the [`Inbox`] (one bounded queue per vehicle, served round robin), so
//! a command is served at once and a flooding client delays the others by
//! at most one request per turn. If the machine cannot keep up, simulated
//! time falls behind instead of bursting (a warning says so).

use std::sync::mpsc::{RecvTimeoutError, TryRecvError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use mavlink::dialects::common::MavMessage;
use tokio::sync::{Notify, broadcast, watch};
use tracing::{debug, info, warn};

use super::inbox::Inbox;
use crate::autopilot::{
    Autopilot, AutopilotCommand, ClientClock, CommandOutcome, PendingTimer, PowerAction, StatusText,
};
use crate::lockstep::{Lockstep, Snapshot};
use crate::mission::{MissionResult, PlanChange};
use crate::params::{ParamStore, ParamValue};

/// Vehicle-steps run between two looks at the requests (50 steps of a lone
/// vehicle; one step of a fleet of 50 or more).
const CHUNK_VEHICLE_STEPS: u64 = 50;
/// At most this much wall time is spent stepping per tick; the rest waits.
const MAX_BATCH_WALL: Duration = Duration::from_millis(20);

/// Messages from the link tasks to the simulation thread.
#[derive(Debug)]
pub(super) enum SimRequest {
    /// A command, answered on `reply` (offboard setpoints have none).
    Command {
        command: AutopilotCommand,
        reply: Option<super::reply::Reply<CommandOutcome>>,
    },
    /// A parameter set, answered with the stored value or why it was refused.
    SetParam {
        name: String,
        value: ParamValue,
        reply: super::reply::Reply<Result<ParamValue, String>>,
    },
    /// Store or clear plans, answered with the new plan's id or why nothing changed.
    Plans {
        change: PlanChange,
        reply: super::reply::Reply<Result<u32, MissionResult>>,
    },
    /// A ground station's HEARTBEAT arrived (data-link loss supervision; no answer).
    GcsHeartbeat,
}

/// Messages to every link task.
#[derive(Clone, Debug)]
pub(super) enum Event {
    StatusText(StatusText),
    /// MISSION_ITEM_REACHED for this seq.
    MissionItemReached(u16),
    ParamValue(Arc<MavMessage>),
}

/// The simulation thread's state.
pub(super) struct Sim {
    pub(super) core: Lockstep<Autopilot>,
    pub(super) speed: f64,
    pub(super) tick: Duration,
    /// Vehicle `i`'s channels and logs.
    pub(super) vehicles: Vec<VehicleIo>,
}

/// What the simulation thread holds for one vehicle.
pub(super) struct VehicleIo {
    pub(super) params: Arc<Mutex<ParamStore>>,
    pub(super) tel: watch::Sender<Snapshot>,
    pub(super) events: broadcast::Sender<Event>,
    /// Notified after every accepted plan change (the plan saver writes the file).
    pub(super) plans_changed: Arc<Notify>,
    /// The client timers being timed on the wall clock (above real-time speed):
    /// each with the simulated instant it started and the wall instant it was first seen.
    pub(super) wall_timers: Vec<(PendingTimer, Instant)>,
    /// Whether the vehicle's radio is silent (an injected MAVLINK_SIGNAL
    /// failure): the link tasks send nothing meanwhile.
    pub(super) link_lost: watch::Sender<bool>,
    /// The run's `flight.ulg` (`--log-dir`), fed after every step.
    pub(super) ulog: Option<super::ulog_file::UlogFile>,
    /// The flight record and CSV (`--log-dir`): every input goes through `Sim::apply`.
    pub(super) recorder: Option<super::recorder::Recorder>,
}

impl Sim {
    /// The simulation loop (on its own thread) until the inbox is stopped
    /// ([`super::inbox::Stopper`]) or every sender is gone.
    pub(super) fn run(mut self, rx: &Inbox<SimRequest>) {
        let wall = Instant::now();
        let steps = self.core.steps();
        self.run_loop(rx);
        // how fast it went, for the log (a fleet's user wants its real-time factor)
        let simulated_s = (self.core.steps() - steps) as f64 * self.core.dt_s();
        let wall_s = wall.elapsed().as_secs_f64();
        info!(
            vehicles = self.vehicles.len(),
            simulated_s,
            wall_s,
            real_time_factor = simulated_s / wall_s.max(1e-9),
            "simulation stopped"
        );
    }

    fn run_loop(&mut self, rx: &Inbox<SimRequest>) {
        let dt = self.core.dt_s();
        let vehicles = self.vehicles.len().max(1) as u64;
        let chunk = (CHUNK_VEHICLE_STEPS / vehicles).max(1);
        let start = Instant::now();
        let mut base = start;
        let mut base_steps: u64 = 0;
        let mut steps: u64 = 0;
        let mut next_tick = start;
        let mut last_lag_warning: Option<Instant> = None;
        loop {
            let now = Instant::now();
            if now < next_tick {
                match rx.recv_timeout(next_tick - now) {
                    Err(RecvTimeoutError::Disconnected) => return,
                    Ok((v, r)) => self.handle(v, r),
                    Err(RecvTimeoutError::Timeout) => {}
                }
                continue;
            }
            next_tick += self.tick;
            if next_tick <= now {
                next_tick = now + self.tick;
            }
            let target = base_steps + (now.duration_since(base).as_secs_f64() * self.speed / dt) as u64;
            let mut due = target.saturating_sub(steps);
            // More than a second of wall time behind: stop trying to catch
            // up, let simulated time lag instead.
            let limit = ((self.speed / dt) as u64).max(1000);
            if due > limit {
                if last_lag_warning.is_none_or(|t| now.duration_since(t) > Duration::from_secs(10)) {
                    warn!(
                        behind_s = due as f64 * dt,
                        "simulation cannot keep up with --speed; slowing down"
                    );
                    last_lag_warning = Some(now);
                }
                base = now;
                base_steps = steps;
                due = 0;
            }
            while due > 0 {
                let n = due.min(chunk);
                for _ in 0..n {
                    self.core.step();
                    self.after_step();
                }
                steps += n;
                due -= n;
                self.record_proximity();
                // the requests waiting now, round robin (what comes in
                // meanwhile waits for the next look)
                for _ in 0..rx.len() {
                    match rx.try_recv() {
                        Ok((v, r)) => self.handle(v, r),
                        Err(TryRecvError::Disconnected) => return,
                        Err(TryRecvError::Empty) => break,
                    }
                }
                if now.elapsed() > MAX_BATCH_WALL {
                    break;
                }
            }
            for v in 0..self.vehicles.len() {
                self.publish(v);
            }
        }
    }

    /// Above real-time speed, time vehicle `v`'s autopilot's client timers on
    /// the wall clock and report each expiry to it (module doc of
    /// `autopilot::failsafe`).
    fn time_client_timers(&mut self, v: usize) {
        if self.core.pilot(v).client_clock() != ClientClock::Wall {
            return;
        }
        let now = Instant::now();
        let pending = self.core.pilot(v).client_timers();
        let timers = &mut self.vehicles[v].wall_timers;
        timers.retain(|(t, _)| {
            pending
                .iter()
                .any(|p| p.timer == t.timer && p.started_s.to_bits() == t.started_s.to_bits())
        });
        let mut expired = Vec::new();
        for p in pending {
            let seen = timers.iter().find(|(t, _)| t.timer == p.timer).map(|(_, at)| *at);
            match seen {
                None => timers.push((p, now)),
                Some(at) if now.duration_since(at).as_secs_f64() >= p.duration_s => {
                    expired.push(p);
                    timers.retain(|(t, _)| t.timer != p.timer);
                }
                Some(_) => {}
            }
        }
        for p in expired {
            if self.client_timeout(v, p.timer, p.started_s) {
                debug!(vehicle = v, timer = ?p.timer, "client timer ran out on the wall clock");
            }
        }
    }

    /// Publish vehicle `v`'s snapshot and status texts.
    pub(super) fn publish(&mut self, v: usize) {
        self.time_client_timers(v);
        let io = &mut self.vehicles[v];
        io.tel.send_replace(self.core.snapshot(v));
        let lost = self.core.world().faults(v).link_lost;
        io.link_lost.send_if_modified(|l| std::mem::replace(l, lost) != lost);
        for s in super::ulog_file::drain_status_texts(&mut io.ulog, &mut self.core, v) {
            info!(vehicle = v, text = %s.text, "status");
            let _ = io.events.send(Event::StatusText(s));
        }
        for seq in self.core.drain_mission_reached(v) {
            let _ = io.events.send(Event::MissionItemReached(seq));
        }
    }

    /// Serve vehicle `v`'s request.
    fn handle(&mut self, v: usize, r: SimRequest) {
        // a request its link gave up on (timed out) is never applied (reply.rs)
        if super::reply::given_up(&r) {
            return;
        }
        match r {
            SimRequest::Command { command, reply } => {
                let mut outcome = self.command(v, command);
                if command == AutopilotCommand::Power(PowerAction::Reboot) && outcome == CommandOutcome::Accepted {
                    // carried out before the ACK, so that ACCEPTED means done
                    outcome = self.reboot(v);
                }
                // Publish before answering: a client that acts on the ACK (disarm,
                // then shutdown) must find the links already seeing the new state.
                self.publish(v);
                // setpoints stream without a reply: log only their refusals
                if reply.is_some() || outcome != CommandOutcome::Accepted {
                    debug!(?command, ?outcome, "command");
                }
                if let Some(tx) = reply {
                    let _ = tx.send(outcome);
                }
            }
            SimRequest::SetParam { name, value, reply } => {
                let outcome = self.set_param(v, &name, value);
                match &outcome {
                    Ok(x) => info!(vehicle = v, %name, value = %x, "parameter set"),
                    Err(e) => info!(vehicle = v, %name, error = %e, "parameter refused"),
                }
                self.publish(v);
                let _ = reply.send(outcome);
            }
            SimRequest::Plans { change, reply } => {
                let outcome = self.change_plans(v, change);
                info!(vehicle = v, ?outcome, "plans changed");
                self.publish(v);
                if outcome.is_ok() {
                    self.vehicles[v].plans_changed.notify_one();
                }
                let _ = reply.send(outcome);
            }
            SimRequest::GcsHeartbeat => self.gcs_heartbeat(v),
        }
    }

    /// PREFLIGHT_REBOOT_SHUTDOWN p1 = 1: the vehicle restarts on the ground at
    /// home, disarmed, from the current parameters; simulated time goes on.
    /// The answer for the ACK.
    fn reboot(&mut self, v: usize) -> CommandOutcome {
        match self.reboot_core(v) {
            Ok(()) => {
                // the core announces it ("Rebooted: simulation reset"); the
                // caller publishes before the ACK
                info!(vehicle = v, "rebooted: simulation reset");
                CommandOutcome::Accepted
            }
            Err(e) => {
                warn!(vehicle = v, error = %e, "reboot failed");
                CommandOutcome::Failed("reboot failed")
            }
        }
    }
}
