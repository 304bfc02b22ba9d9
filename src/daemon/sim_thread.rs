//! The simulation thread: the only owner of the lockstep core, paced against
//! the wall clock. Every tick of wall time it runs the steps that are due so
//! that simulated time = speed x wall time (batched: no per-step syscall;
//! requests are served between chunks of steps), then publishes a
//! [`Snapshot`] on a `watch` and status texts on a `broadcast`. Between
//! ticks it sleeps in `recv_timeout` on its bounded request channel, so a
//! command is served at once. If the machine cannot keep up, simulated time
//! falls behind instead of bursting (a warning says so).

use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use mavlink::dialects::common::MavMessage;
use tokio::sync::{Notify, broadcast, oneshot, watch};
use tracing::{debug, info, warn};

use crate::autopilot::{
    Autopilot, AutopilotCommand, ClientClock, CommandOutcome, PendingTimer, PowerAction, StatusText,
};
use crate::lockstep::{Lockstep, Snapshot};
use crate::mission::{MissionResult, PlanChange};
use crate::params::{ParamStore, ParamValue};

/// The vehicle this daemon flies (one today; the fleet addresses more).
pub(super) const VEHICLE: usize = 0;
/// Steps run between two looks at the request queue.
const CHUNK: u64 = 50;
/// At most this much wall time is spent stepping per tick; the rest waits.
const MAX_BATCH_WALL: Duration = Duration::from_millis(20);

/// Messages from the link tasks to the simulation thread.
#[derive(Debug)]
pub(super) enum SimRequest {
    /// A command, answered on `reply` (offboard setpoints have none).
    Command {
        command: AutopilotCommand,
        reply: Option<oneshot::Sender<CommandOutcome>>,
    },
    /// A parameter set, answered with the stored value or why it was refused.
    SetParam {
        name: String,
        value: ParamValue,
        reply: oneshot::Sender<Result<ParamValue, String>>,
    },
    /// Store or clear plans, answered with the new plan's id or why nothing changed.
    Plans {
        change: PlanChange,
        reply: oneshot::Sender<Result<u32, MissionResult>>,
    },
    /// A ground station's HEARTBEAT arrived (data-link loss supervision; no answer).
    GcsHeartbeat,
    /// Stop the thread.
    Stop,
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
    pub(super) params: Arc<Mutex<ParamStore>>,
    pub(super) tel: watch::Sender<Snapshot>,
    pub(super) events: broadcast::Sender<Event>,
    pub(super) speed: f64,
    pub(super) tick: Duration,
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
    /// The simulation loop (on its own thread) until [`SimRequest::Stop`] or
    /// every sender is gone.
    pub(super) fn run(mut self, rx: &Receiver<SimRequest>) {
        let dt = self.core.dt_s();
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
                    Ok(SimRequest::Stop) | Err(RecvTimeoutError::Disconnected) => return,
                    Ok(r) => self.handle(r),
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
                let n = due.min(CHUNK);
                for _ in 0..n {
                    self.core.step();
                    self.after_step();
                    super::ulog_file::after_step(&mut self.ulog, &mut self.core);
                }
                steps += n;
                due -= n;
                loop {
                    match rx.try_recv() {
                        Ok(SimRequest::Stop) => return,
                        Ok(r) => self.handle(r),
                        Err(_) => break,
                    }
                }
                if now.elapsed() > MAX_BATCH_WALL {
                    break;
                }
            }
            self.publish();
        }
    }

    /// Above real-time speed, time the autopilot's client timers on the wall
    /// clock and report each expiry to it (module doc of `autopilot::failsafe`).
    fn time_client_timers(&mut self) {
        if self.core.pilot(VEHICLE).client_clock() != ClientClock::Wall {
            return;
        }
        let now = Instant::now();
        let pending = self.core.pilot(VEHICLE).client_timers();
        self.wall_timers.retain(|(t, _)| {
            pending
                .iter()
                .any(|p| p.timer == t.timer && p.started_s.to_bits() == t.started_s.to_bits())
        });
        for p in pending {
            let seen = self
                .wall_timers
                .iter()
                .find(|(t, _)| t.timer == p.timer)
                .map(|(_, at)| *at);
            match seen {
                None => self.wall_timers.push((p, now)),
                Some(at) if now.duration_since(at).as_secs_f64() >= p.duration_s => {
                    if self.client_timeout(p.timer, p.started_s) {
                        debug!(timer = ?p.timer, "client timer ran out on the wall clock");
                    }
                    self.wall_timers.retain(|(t, _)| t.timer != p.timer);
                }
                Some(_) => {}
            }
        }
    }

    /// Publish the snapshot and the status texts.
    pub(super) fn publish(&mut self) {
        self.time_client_timers();
        self.tel.send_replace(self.core.snapshot(VEHICLE));
        let lost = self.core.world().faults(VEHICLE).link_lost;
        self.link_lost.send_if_modified(|l| std::mem::replace(l, lost) != lost);
        for s in super::ulog_file::drain_status_texts(&mut self.ulog, &mut self.core, VEHICLE) {
            info!(text = %s.text, "status");
            let _ = self.events.send(Event::StatusText(s));
        }
        for seq in self.core.drain_mission_reached(VEHICLE) {
            let _ = self.events.send(Event::MissionItemReached(seq));
        }
    }

    fn handle(&mut self, r: SimRequest) {
        match r {
            SimRequest::Command { command, reply } => {
                let mut outcome = self.command(command);
                if command == AutopilotCommand::Power(PowerAction::Reboot) && outcome == CommandOutcome::Accepted {
                    // carried out before the ACK, so that ACCEPTED means done
                    outcome = self.reboot();
                }
                // Publish before answering: a client that acts on the ACK (disarm,
                // then shutdown) must find the links already seeing the new state.
                self.publish();
                // setpoints stream without a reply: log only their refusals
                if reply.is_some() || outcome != CommandOutcome::Accepted {
                    debug!(?command, ?outcome, "command");
                }
                if let Some(tx) = reply {
                    let _ = tx.send(outcome);
                }
            }
            SimRequest::SetParam { name, value, reply } => {
                let outcome = self.set_param(&name, value);
                match &outcome {
                    Ok(v) => info!(%name, value = %v, "parameter set"),
                    Err(e) => info!(%name, error = %e, "parameter refused"),
                }
                self.publish();
                let _ = reply.send(outcome);
            }
            SimRequest::Plans { change, reply } => {
                let outcome = self.change_plans(change);
                info!(?outcome, "plans changed");
                self.publish();
                if outcome.is_ok() {
                    self.plans_changed.notify_one();
                }
                let _ = reply.send(outcome);
            }
            SimRequest::GcsHeartbeat => self.gcs_heartbeat(),
            // the loop returns on Stop before handing requests here
            SimRequest::Stop => {}
        }
    }

    /// PREFLIGHT_REBOOT_SHUTDOWN p1 = 1: the vehicle restarts on the ground at
    /// home, disarmed, from the current parameters; simulated time goes on.
    /// The answer for the ACK.
    fn reboot(&mut self) -> CommandOutcome {
        match self.reboot_core() {
            Ok(()) => {
                // the core announces it ("Rebooted: simulation reset"); the
                // caller publishes before the ACK
                info!("rebooted: simulation reset");
                CommandOutcome::Accepted
            }
            Err(e) => {
                warn!(error = %e, "reboot failed");
                CommandOutcome::Failed("reboot failed")
            }
        }
    }
}
