//! The simulation thread: the only owner of the lockstep core (every vehicle
//! of the fleet, on one clock), paced against the wall clock. Every tick of
//! wall time it runs the steps that are due so that simulated time = speed x
//! wall time (batched: no per-step syscall; requests are served between
//! chunks of steps, each vehicle stepped through a chunk before the next
//! unless it logs), then publishes each vehicle's [`Snapshot`] on its
//! `watch` and its status texts on its `broadcast`. Between ticks it sleeps
//! in the [`Inbox`] (one bounded queue per vehicle, served round robin), so
//! a command is served at once and a flooding client delays the others by
//! at most one request per turn. If the machine cannot keep up, simulated
//! time falls behind instead of bursting (a warning says so). A fleet
//! stepped on several threads runs this loop on one of them
//! ([`crate::lockstep::StepThreads::run`]).

use std::ops::ControlFlow;
use std::sync::mpsc::{RecvTimeoutError, TryRecvError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use tokio::sync::{Notify, broadcast, mpsc, watch};
use tracing::{debug, info, warn};

use super::inbox::Inbox;
use super::messages::{Event, SimRequest, lock};
use super::recorder::Recorder;
use super::ulog_file::{self, UlogFile};
use crate::autopilot::{
    Autopilot, AutopilotCommand, AutopilotError, ClientClock, ClientTimer, CommandOutcome, ItemDone, PendingTimer,
    PowerAction,
};
use crate::link::events;
use crate::lockstep::input::{Applied, Input};
use crate::lockstep::{Lockstep, MOST_AHEAD, Snapshot};
use crate::mission::{MissionResult, PlanChange};
use crate::params::{ParamStore, ParamValue};
use crate::scenario::fleet::FleetEvent;
use crate::scenario::fleet::encounters::Encounters;

/// Vehicle-steps run between two looks at the requests, at most
/// [`MOST_AHEAD`] steps: 64 steps of a lone vehicle or of a fleet of up to
/// 64, 16 of a fleet of 250 (the most the daemon holds); a millisecond or
/// two of wall time.
const CHUNK_VEHICLE_STEPS: u64 = 4096;
/// At most this much wall time is spent stepping per tick; the rest waits.
const MAX_BATCH_WALL: Duration = Duration::from_millis(20);

/// What follows a command's answer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum AfterAnswer {
    /// Nothing: the simulation goes on.
    GoOn,
    /// The daemon stops (an accepted shutdown).
    StopDaemon,
}

/// The simulation thread's state.
pub(super) struct Sim {
    pub(super) core: Lockstep<Autopilot>,
    pub(super) speed: f64,
    pub(super) tick: Duration,
    /// Vehicle `i`'s channels and logs.
    pub(super) vehicles: Vec<VehicleIo>,
    /// Stops the daemon: a client's accepted shutdown ([`Self::power`]).
    pub(super) exit: mpsc::Sender<()>,
    /// The fleet's open encounters, followed to their closest approach
    /// ([`follow_proximity`]).
    pub(super) encounters: Encounters,
}

/// What the simulation thread holds for one vehicle.
pub(super) struct VehicleIo {
    /// Its PX4 SITL instance, as the user set it (named in log lines).
    pub(super) instance: u8,
    /// Its MAVLink system id (named in log lines).
    pub(super) system_id: u8,
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
    pub(super) ulog: Option<UlogFile>,
    /// The flight record and CSV (`--log-dir`): every input goes through `Sim::apply`.
    pub(super) recorder: Option<Recorder>,
    /// The vehicle's events (the health and arming report, failsafes):
    /// their sequence, and when the next report goes out.
    pub(super) health: events::Reporter,
    /// A report is to go out at the next publication, changed or not
    /// (MAV_CMD_RUN_PREARM_CHECKS or an arming request came).
    pub(super) health_forced: bool,
}

impl Sim {
    /// The simulation loop (on its own thread) until the inbox is stopped
    /// ([`super::inbox::Stopper`]) or every sender is gone.
    pub(super) fn run(mut self, rx: &Inbox<SimRequest>) {
        let wall = Instant::now();
        let steps = self.core.steps();
        self.run_loop(rx);
        // the encounters still open end with the flight
        let open = std::mem::take(&mut self.encounters).finish();
        end_encounters(&mut self.core, &mut self.vehicles, open);
        for v in 0..self.vehicles.len() {
            self.publish(v);
        }
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
        let chunk = (CHUNK_VEHICLE_STEPS / vehicles).clamp(1, MOST_AHEAD);
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
                self.step_chunk(n);
                steps += n;
                due -= n;
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
                let (instance, sysid) = self.vehicles[v].who();
                debug!(instance, sysid, timer = ?p.timer, "client timer ran out on the wall clock");
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
        for s in ulog_file::drain_status_texts(&mut io.ulog, &mut self.core, v) {
            info!(instance = io.instance, sysid = io.system_id, text = %s.text, "status");
            let _ = io.events.send(Event::StatusText(s));
        }
        let now_s = self.core.time_s();
        let failsafe = self.core.pilot(v).failsafe_in_force();
        if let Some(e) = io
            .health
            .failsafe(now_s, failsafe.map(|f| (f.cause.as_str(), f.triggered)))
        {
            let _ = io.events.send(Event::Events(Arc::new(vec![e])));
        }
        if io.health_forced || io.health.due(now_s) {
            let report = self.core.pilot(v).health_report(now_s);
            let sent = io.health.update(now_s, report, std::mem::take(&mut io.health_forced));
            if !sent.is_empty() {
                let _ = io.events.send(Event::Events(Arc::new(sent)));
            }
        }
        // MISSION_ITEM_REACHED tells the items reached, not those run at once (PX4)
        for done in self.core.drain_mission_done(v) {
            if let ItemDone::Reached(seq) = done {
                let _ = io.events.send(Event::MissionItemReached(seq));
            }
        }
    }

    /// Serve vehicle `v`'s request.
    fn handle(&mut self, v: usize, r: SimRequest) {
        // a request its link gave up on (timed out) is never applied (messages.rs)
        if !r.claim() {
            return;
        }
        match r {
            SimRequest::Command { command, reply } => {
                // PX4 reports the arming checks at once when asked to or asked to arm
                if matches!(
                    command,
                    AutopilotCommand::RunPrearmChecks | AutopilotCommand::Arm { .. }
                ) {
                    self.vehicles[v].health_forced = true;
                }
                let mut outcome = self.command(v, command);
                let mut then = AfterAnswer::GoOn;
                if let AutopilotCommand::Power(action) = command
                    && outcome == CommandOutcome::Accepted
                {
                    (outcome, then) = self.power(v, action);
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
                if then == AfterAnswer::StopDaemon {
                    // after the answer: PX4 SITL exits after acknowledging
                    let _ = self.exit.try_send(());
                }
            }
            SimRequest::SetParam { name, value, reply } => {
                let outcome = self.set_param(v, &name, value);
                let (instance, sysid) = self.vehicles[v].who();
                match &outcome {
                    Ok(x) => info!(instance, sysid, %name, value = %x, "parameter set"),
                    Err(e) => info!(instance, sysid, %name, error = %e, "parameter refused"),
                }
                self.publish(v);
                let _ = reply.send(outcome);
            }
            SimRequest::Plans { change, reply } => {
                let outcome = self.change_plans(v, change);
                let (instance, sysid) = self.vehicles[v].who();
                info!(instance, sysid, ?outcome, "plans changed");
                self.publish(v);
                if outcome.is_ok() {
                    self.vehicles[v].plans_changed.notify_one();
                }
                let _ = reply.send(outcome);
            }
            SimRequest::GcsHeartbeat => self.gcs_heartbeat(v),
            SimRequest::RawSensors => self.core.enable_raw_sensors(v),
        }
    }

    /// PREFLIGHT_REBOOT_SHUTDOWN that the autopilot accepted (it refuses
    /// both while armed: the decision is its), carried out here, the one
    /// place: the answer for the ACK, and what follows once it is sent.
    ///
    /// - Reboot (p1 = 1): the vehicle restarts on the ground at home,
    ///   disarmed, from the current parameters; simulated time goes on.
    ///   Done before the ACK, so that ACCEPTED means done.
    /// - Shutdown (p1 = 2): the daemon stops (every task, the final saves),
    ///   as PX4 SITL exits, after the ACK.
    fn power(&mut self, v: usize, action: PowerAction) -> (CommandOutcome, AfterAnswer) {
        match action {
            PowerAction::Reboot => (self.reboot(v), AfterAnswer::GoOn),
            PowerAction::Shutdown => (CommandOutcome::Accepted, AfterAnswer::StopDaemon),
        }
    }

    /// Reboot vehicle `v` ([`Self::power`]); the answer for the ACK.
    fn reboot(&mut self, v: usize) -> CommandOutcome {
        match self.reboot_core(v) {
            Ok(()) => {
                // the core announces it ("Rebooted: simulation reset"); the
                // caller publishes before the ACK
                let (instance, sysid) = self.vehicles[v].who();
                info!(instance, sysid, "rebooted: simulation reset");
                CommandOutcome::Accepted
            }
            Err(e) => {
                let (instance, sysid) = self.vehicles[v].who();
                warn!(instance, sysid, error = %e, "reboot failed");
                CommandOutcome::Failed("reboot failed")
            }
        }
    }

    /// Apply one input to vehicle `v` at the current instant (between
    /// steps), recording it in its record when recording: the only way
    /// inputs reach the core.
    pub(super) fn apply(&mut self, v: usize, input: Input) -> Applied {
        apply(&mut self.core, &mut self.vehicles, v, input)
    }

    /// [`Self::apply`] a command.
    pub(super) fn command(&mut self, v: usize, command: AutopilotCommand) -> CommandOutcome {
        match self.apply(v, Input::Command(command)) {
            Applied::Command(o) => o,
            other => unreachable!("a command answered {other:?}"),
        }
    }

    /// [`Self::apply`] a parameter set.
    pub(super) fn set_param(&mut self, v: usize, name: &str, value: ParamValue) -> Result<ParamValue, String> {
        match self.apply(
            v,
            Input::SetParam {
                name: name.to_string(),
                value,
            },
        ) {
            Applied::SetParam(r) => r,
            other => unreachable!("a parameter set answered {other:?}"),
        }
    }

    /// [`Self::apply`] a plan change.
    pub(super) fn change_plans(&mut self, v: usize, change: PlanChange) -> Result<u32, MissionResult> {
        match self.apply(v, Input::ChangePlans(change)) {
            Applied::Plans(r) => r,
            other => unreachable!("a plan change answered {other:?}"),
        }
    }

    /// [`Self::apply`] a ground station's heartbeat.
    pub(super) fn gcs_heartbeat(&mut self, v: usize) {
        self.apply(v, Input::GcsHeartbeat);
    }

    /// [`Self::apply`] a client timer's expiry on the wall clock.
    pub(super) fn client_timeout(&mut self, v: usize, timer: ClientTimer, started_s: f64) -> bool {
        match self.apply(v, Input::ClientTimeout { timer, started_s }) {
            Applied::ClientTimeout(b) => b,
            other => unreachable!("a client timeout answered {other:?}"),
        }
    }

    /// [`Self::apply`] a reboot from the parameters in force.
    pub(super) fn reboot_core(&mut self, v: usize) -> Result<(), AutopilotError> {
        match self.apply(v, Input::Reboot) {
            Applied::Reboot(r) => r,
            other => unreachable!("a reboot answered {other:?}"),
        }
    }

    /// `n` steps of every vehicle, the proximity followed at each instant
    /// ([`follow_proximity`]). While no vehicle logs its steps
    /// (`--log-dir`), each vehicle runs through all `n` before the next
    /// ([`Lockstep::step_ahead`]: its data stays in the caches); nothing
    /// reaches a vehicle between them anyway, the requests being served
    /// between chunks. A vehicle that logs its steps is written after every
    /// step, from the whole core: then the vehicles take one step at a time.
    fn step_chunk(&mut self, n: u64) {
        if self.vehicles.iter().any(VehicleIo::logs_its_steps) {
            for _ in 0..n {
                self.core.step();
                self.after_step();
                follow_proximity(&mut self.core, &mut self.vehicles, &mut self.encounters);
            }
            return;
        }
        let Self {
            core,
            vehicles,
            encounters,
            ..
        } = self;
        let mut none = vec![(); vehicles.len()];
        // a chunk is at most MOST_AHEAD (64) steps: the cast is exact
        core.step_ahead(
            n.min(MOST_AHEAD) as usize,
            &mut none,
            |(), _, _| {},
            |core, _| {
                follow_proximity(core, vehicles, encounters);
                ControlFlow::Continue(())
            },
        );
    }

    /// After each step: every vehicle's CSV row and ULog topics.
    pub(super) fn after_step(&mut self) {
        for io in &mut self.vehicles {
            if let Some(r) = &mut io.recorder {
                r.after_step(&self.core);
            }
            ulog_file::after_step(&mut io.ulog, &mut self.core);
        }
    }
}

impl VehicleIo {
    /// Its instance and system id, as the user set them (log lines name a
    /// vehicle by these, never by its place in the fleet).
    fn who(&self) -> (u8, u8) {
        (self.instance, self.system_id)
    }

    /// Whether it logs its steps (`--log-dir`: the flight record, the CSV,
    /// the ULog), each written after the step from the whole core.
    fn logs_its_steps(&self) -> bool {
        self.recorder.is_some() || self.ulog.is_some()
    }
}

/// Apply one input to vehicle `v` at the current instant (between its
/// steps), recording it in its record when recording ([`Sim::apply`]).
fn apply(core: &mut Lockstep<Autopilot>, vehicles: &mut [VehicleIo], v: usize, input: Input) -> Applied {
    let step = core.steps();
    let io = &mut vehicles[v];
    let applied = {
        let mut p = lock(&io.params);
        crate::lockstep::input::apply(core, v, &mut p, &input)
    };
    if let Some(r) = &mut io.recorder {
        r.input(step, &input, &applied);
    }
    applied
}

/// After each instant: record the proximity events its step raised in
/// both vehicles' records (the core announced them itself: recorded, not
/// applied; a replay applies them), open an encounter with each, follow
/// the open ones, and tell both vehicles of each that ended
/// ([`end_encounters`]). Nothing to do when no pair is near.
fn follow_proximity(core: &mut Lockstep<Autopilot>, vehicles: &mut [VehicleIo], encounters: &mut Encounters) {
    let step = core.steps();
    for (t, e) in core.drain_proximity_events() {
        for (me, other) in [(e.a, e.b), (e.b, e.a)] {
            let (instance, sysid) = vehicles[me].who();
            info!(instance, sysid, other = %core.label(other), kind = e.kind.name(), distance_m = e.distance_m, "proximity");
            if let Some(r) = &mut vehicles[me].recorder {
                let input = Input::Proximity {
                    other: core.label(other).to_string(),
                    kind: e.kind,
                    distance_m: e.distance_m,
                };
                r.input(step, &input, &Applied::Announced);
            }
        }
        encounters.open(t, e);
    }
    let ended = encounters.follow(core);
    if !ended.is_empty() {
        end_encounters(core, vehicles, ended);
    }
}

/// Tell both vehicles of each encounter in `ended` its closest approach
/// (applied and recorded as [`Input::EncounterEnded`], logged). A pair that
/// rose twice (near, then touching) ends both encounters at once: it is
/// told once, of the first (which followed it longest: its closest approach
/// is the least).
fn end_encounters(core: &mut Lockstep<Autopilot>, vehicles: &mut [VehicleIo], mut ended: Vec<FleetEvent>) {
    // stable: each pair's first-opened encounter stays first
    ended.sort_by_key(|e| (e.a, e.b));
    ended.dedup_by_key(|e| (e.a, e.b));
    for e in ended {
        for (me, other) in [(e.a, e.b), (e.b, e.a)] {
            let (instance, sysid) = vehicles[me].who();
            let label = core.label(other).to_string();
            info!(instance, sysid, other = %label, closest_m = e.closest_m, closest_s = e.closest_s, "encounter ended");
            apply(
                core,
                vehicles,
                me,
                Input::EncounterEnded {
                    other: label,
                    closest_m: e.closest_m,
                    closest_s: e.closest_s,
                },
            );
        }
    }
}
