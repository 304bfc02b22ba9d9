//! The lockstep core: the simulated world and each vehicle's flight
//! software, stepped together by simulated time. One step at `t_k`, for
//! every vehicle: **sense** (the world reads its sensors), **decide** (its
//! pilot turns the readings into an actuator command), then **act and
//! integrate** (the world steps every vehicle over `[t_k, t_{k+1})` under
//! its command, on its one clock). The scenario runner
//! ([`crate::scenario`]) and the daemon ([`crate::daemon`]) both step this;
//! no other loop exists.
//!
//! The core is the only place that sees both halves: it routes each
//! vehicle's `SIM_*` parameters to the world and the rest to its autopilot,
//! restarts a vehicle (world and autopilot) on a reboot, turns an accepted
//! failure injection (MAV_CMD_INJECT_FAILURE's numbers, [`failure::FailureInjection`])
//! into the world's [`Fault`]s and announces it, and pairs the autopilot's
//! telemetry with the world's injected truth for the clients that compare
//! them. Vehicles are addressed by index; an index beyond the world panics,
//! as a slice index does.
//!
//! The pieces beside the loop: [`input`] (the one path by which every
//! client and recorded input reaches the core), [`failure`] (failure
//! injection: the supported units and types) and [`preflight`] (the lift
//! check before arming).

pub mod failure;
pub mod input;
pub mod preflight;

use std::collections::VecDeque;
use std::ops::ControlFlow;

use crate::airframe::Airframe;
use nalgebra::Vector3;

use crate::autopilot::{
    Autopilot, AutopilotCommand, AutopilotError, ClientTimer, CommandOutcome, ControlOutput, Severity, StatusText,
    Telemetry,
};
use crate::geo::GeoPoint;
use crate::mission::{MissionResult, PlanChange, Plans};
use crate::params::{ParamStore, ParamValue};
use crate::signals::{DEFAULT_STEP_S, Measurement, RawSensorReadings, SensorReadings};
use crate::sim::{
    Environment, Proximity, ProximityEvent, ProximityKind, RigidBodyState, SensorConfig, SimFault, StepReport, Truth,
    VehicleSlot, World, WorldSettings,
};

/// Flight software in the loop: from the sensor readings at `t_k` to what
/// the actuators get over `[t_k, t_{k+1})`. `Send`: a fleet's vehicles may
/// be stepped on several threads ([`Lockstep::set_threads`]).
pub trait Pilot: Send {
    /// Decide this step ([`Self::output`] holds the decision).
    fn decide(&mut self, readings: &SensorReadings);
    /// What the latest [`Self::decide`] decided.
    fn output(&self) -> &ControlOutput;
    /// The world refused the command (it was not finite) or could not
    /// integrate it, and stopped the rotors for the step instead.
    fn rotors_stopped(&mut self, why: &SimFault);
    /// The status texts raised since the last call, oldest first (none by
    /// default); the lockstep takes them before every step to stamp them
    /// with the simulated time.
    fn take_status_texts(&mut self) -> Vec<StatusText> {
        Vec::new()
    }
    /// The navigation solution the latest [`Self::decide`] flew on, given
    /// the readings it was given (their own, unless the pilot runs a filter).
    fn solution(&self, readings: &SensorReadings) -> Measurement {
        readings.measurement
    }
}

impl Pilot for Autopilot {
    fn decide(&mut self, readings: &SensorReadings) {
        self.step(readings);
    }

    fn output(&self) -> &ControlOutput {
        Autopilot::output(self)
    }

    fn rotors_stopped(&mut self, why: &SimFault) {
        Autopilot::rotors_stopped(self, &why.to_string());
    }

    fn take_status_texts(&mut self) -> Vec<StatusText> {
        Autopilot::drain_status_texts(self)
    }

    fn solution(&self, readings: &SensorReadings) -> Measurement {
        Autopilot::solution(self, readings)
    }
}

/// Everything about one vehicle's latest step, for logs and summaries
/// (borrowed where it lives: nothing is copied per step).
#[derive(Clone, Copy, Debug)]
pub struct StepRecord<'a> {
    /// The measurement the pilot decided on (`x_k`).
    pub measurement: &'a Measurement,
    /// What the pilot decided.
    pub control: &'a ControlOutput,
    /// What the world did.
    pub world: &'a StepReport,
    /// The true state at the step's end, `t_{k+1}` (through
    /// [`Lockstep::last_step`]: the vehicle's state now).
    pub end: &'a RigidBodyState,
}

/// What a client may be told about a vehicle: its autopilot's telemetry and
/// the truth injected into the world (to compare with the estimates).
#[derive(Clone, Debug, PartialEq)]
pub struct Snapshot {
    /// What the autopilot reports.
    pub telemetry: Telemetry,
    /// The injected wrench and true mass.
    pub truth: Truth,
    /// The vehicle's true motion (PX4 SITL's ground truth).
    pub ground_truth: GroundTruth,
    /// The stored mission, geofence and rally points (shared, not copied).
    pub plans: Plans,
    /// The raw sensors' latest samples, as the steps drew them (all `None`
    /// unless the world simulates them, [`Lockstep::enable_raw_sensors`]);
    /// taking a snapshot never draws one.
    pub raw: RawSensorReadings,
}

/// The vehicle's true motion, what PX4 SITL calls its ground truth (the
/// simulator's state, never the flight stack's estimate); NED from the
/// vehicle's own origin (its home), body FRD.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GroundTruth {
    /// True position [m] and velocity [m/s] (NED), attitude (FRD to NED) and
    /// body rates [rad/s] (FRD), at the snapshot's instant.
    pub state: Measurement,
    /// True acceleration of the centre of mass [m/s^2], NED: the second
    /// derivative of the position, `a = g e3 + (-u_T R e3 + f_e) / m` (zero
    /// in a hover and at rest on the ground).
    pub acceleration_ned: Vector3<f64>,
}

/// The world and one pilot per vehicle.
#[derive(Debug)]
pub struct Lockstep<P> {
    world: World,
    pilots: Vec<P>,
    /// The measurement each vehicle's pilot decided on last.
    measurements: Vec<Measurement>,
    last_fault: Vec<Option<SimFault>>,
    /// Per vehicle, the world's announcements (failure injections) not yet
    /// drained, each with the simulated time [s] it was made.
    world_texts: Vec<Vec<(f64, StatusText)>>,
    /// Per vehicle, its pilot's status texts taken at the start of each step
    /// and stamped with the simulated time [s] then (the instant they were
    /// raised: by the last step or by an input after it), oldest first, at
    /// most the latest [`PILOT_TEXTS_KEPT`].
    pilot_texts: Vec<VecDeque<(f64, StatusText)>>,
    /// Vehicle–vehicle proximity, when watched ([`Self::watch_proximity`]).
    proximity: Option<Proximity>,
    /// Each vehicle's name in proximity texts (`vehicle i` unless set).
    labels: Vec<String>,
    /// The proximity events not yet drained, each with the simulated time [s]
    /// after the step that raised it (every one: the runtimes drain them
    /// after each batch of steps; a pair is told once per rise).
    proximity_events: VecDeque<(f64, ProximityEvent)>,
    /// The vehicles' world positions [m, NED] and body radii [m] at the
    /// latest instant, noted by each vehicle's step for the proximity check.
    positions: Vec<Vector3<f64>>,
    radii: Vec<f64>,
    /// Every vehicle's places over the steps of [`Self::step_ahead`],
    /// vehicle by vehicle: `noted[i * steps + s]` after its step `s`.
    noted: Vec<Place>,
    /// Threads stepping the vehicles (none: on the caller's thread).
    threads: StepThreads,
}

/// The threads that step a fleet's vehicles ([`Lockstep::set_threads`];
/// none: the caller's thread steps them).
///
/// A loop of steps run on one of them ([`Self::run`]) hands each step's
/// split to the others while they still wait for work from the step
/// before; called from any other thread, every step wakes the threads and
/// then the caller again.
#[derive(Clone, Debug, Default)]
pub struct StepThreads(Option<std::sync::Arc<rayon::ThreadPool>>);

impl StepThreads {
    /// `f`, run on one of the stepping threads (on the caller's without them).
    pub fn run<R: Send>(&self, f: impl FnOnce() -> R + Send) -> R {
        match &self.0 {
            Some(pool) => pool.install(f),
            None => f(),
        }
    }
}

/// Pilot status texts kept per vehicle until drained (the autopilot's own queue's size).
const PILOT_TEXTS_KEPT: usize = 64;

/// One vehicle's share of a step: its slot in the world, its pilot and
/// what the core keeps for it.
struct Lane<'a, P> {
    slot: VehicleSlot<'a>,
    pilot: &'a mut P,
    measurement: &'a mut Measurement,
    fault: &'a mut Option<SimFault>,
    texts: &'a mut VecDeque<(f64, StatusText)>,
}

/// Where a vehicle was after one of its steps: its world position [m, NED]
/// and body radius [m] (for the proximity check).
type Place = (Vector3<f64>, f64);

/// One vehicle's step at `t_s`: its pilot's texts stamped, sense, decide,
/// integrate; a fault that stopped the rotors told to the pilot and kept;
/// its `place` noted; then `after` given its record.
fn step_vehicle<P: Pilot, T>(
    lane: &mut Lane<'_, P>,
    t_s: f64,
    place: &mut Place,
    extra: &mut T,
    after: &impl Fn(&mut T, &P, StepRecord<'_>),
) {
    let (slot, pilot) = (&mut lane.slot, &mut *lane.pilot);
    stamp_texts(lane.texts, pilot, t_s);
    let readings = slot.sense();
    pilot.decide(readings);
    *lane.measurement = pilot.solution(readings);
    let report = slot.integrate(&pilot.output().actuator);
    if let Some(f) = report.fault {
        pilot.rotors_stopped(&f);
        *lane.fault = Some(f);
    }
    *place = (slot.position_ned(), slot.body_radius_m());
    let record = StepRecord {
        measurement: lane.measurement,
        control: pilot.output(),
        world: slot.report(),
        end: slot.state(),
    };
    after(extra, pilot, record);
}

/// What a vehicle is told when `other` (its label) came `kind` at `distance_m`:
/// a warning when near, critical when touching.
#[must_use]
pub fn proximity_text(kind: ProximityKind, other: &str, distance_m: f64) -> StatusText {
    match kind {
        ProximityKind::Near => StatusText {
            severity: Severity::Warning,
            text: format!("Proximity: {other} at {distance_m:.1} m"),
        },
        ProximityKind::Collision => StatusText {
            severity: Severity::Critical,
            text: format!("Collision with {other} ({distance_m:.2} m)"),
        },
    }
}

/// What a vehicle is told when its encounter with `other` (its label) is
/// over (the pair apart again, or the flight ended): the encounter's
/// closest approach `closest_m` [m] (centre to centre), for information.
#[must_use]
pub fn encounter_text(other: &str, closest_m: f64) -> StatusText {
    StatusText {
        severity: Severity::Info,
        text: format!("Passed {other}: closest approach {closest_m:.2} m"),
    }
}

/// Move `pilot`'s queued status texts to `q`, stamped with `t_s`, keeping
/// the latest [`PILOT_TEXTS_KEPT`].
fn stamp_texts<P: Pilot>(q: &mut VecDeque<(f64, StatusText)>, pilot: &mut P, t_s: f64) {
    for s in pilot.take_status_texts() {
        if q.len() >= PILOT_TEXTS_KEPT {
            q.pop_front();
        }
        q.push_back((t_s, s));
    }
}
/// Vehicles per parallel task: below this a fleet is stepped on one thread.
const VEHICLES_PER_TASK: usize = 8;

/// The most steps the vehicles are stepped ahead at once
/// ([`Lockstep::step_ahead`]): 64 ms of flight at the default 1 kHz, 2 MB
/// of noted places for 1,024 vehicles.
pub const MOST_AHEAD: u64 = 64;

impl<P: Pilot> Lockstep<P> {
    /// `world` with `pilots[i]` flying its vehicle `i`.
    ///
    /// # Panics
    /// When the counts differ.
    #[must_use]
    pub fn new(world: World, pilots: Vec<P>) -> Self {
        assert_eq!(world.len(), pilots.len(), "one pilot per vehicle");
        let n = pilots.len();
        Self {
            world,
            pilots,
            measurements: vec![Measurement::default(); n],
            last_fault: vec![None; n],
            world_texts: vec![Vec::new(); n],
            pilot_texts: vec![VecDeque::new(); n],
            proximity: None,
            labels: (0..n).map(|i| format!("vehicle {i}")).collect(),
            proximity_events: VecDeque::new(),
            positions: Vec::new(),
            radii: Vec::new(),
            noted: Vec::new(),
            threads: StepThreads::default(),
        }
    }

    /// Step the vehicles on `threads` threads (1: on the caller's, the
    /// default). Every vehicle's step is the same arithmetic either way (the
    /// vehicles do not interact within a step), so the flight is the same
    /// to the bit; only wall time changes.
    ///
    /// # Errors
    /// The threads could not be started.
    pub fn set_threads(&mut self, threads: usize) -> Result<(), String> {
        self.threads = StepThreads(if threads > 1 {
            Some(std::sync::Arc::new(
                rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .thread_name(|k| format!("rotorpilot-step-{k}"))
                    // a whole loop of steps may run on one of them (`StepThreads::run`),
                    // with the main thread's stack
                    .stack_size(8 << 20)
                    .build()
                    .map_err(|e| e.to_string())?,
            ))
        } else {
            None
        });
        Ok(())
    }

    /// The threads of [`Self::set_threads`], to run a loop of steps on.
    #[must_use]
    pub fn threads(&self) -> StepThreads {
        self.threads.clone()
    }

    /// Report every pair of vehicles that comes closer than `distance_m` [m]
    /// and every pair whose bodies touch ([`crate::sim::proximity`]): after
    /// each step, a status text to both vehicles (a warning when near,
    /// critical when touching, naming the other by its label) and an event
    /// ([`Self::drain_proximity_events`]). Vehicles pass through each other:
    /// a collision is reported, not simulated as contact.
    pub fn watch_proximity(&mut self, distance_m: f64) {
        self.proximity = Some(Proximity::new(distance_m));
    }

    /// The pairs now near or touching, `(a, b, level)` with `a < b`, sorted
    /// (none when proximity is not watched): a pair stays here from its
    /// event until it is apart again (beyond the threshold x 1.1).
    #[must_use]
    pub fn proximity_pairs(&self) -> &[(usize, usize, ProximityKind)] {
        self.proximity.as_ref().map_or(&[], Proximity::levels)
    }

    /// Name the vehicles in proximity texts (`labels[i]` for vehicle `i`,
    /// e.g. `system 3`); missing ones keep `vehicle i`.
    pub fn set_labels(&mut self, labels: Vec<String>) {
        for (l, new) in self.labels.iter_mut().zip(labels) {
            *l = new;
        }
    }

    /// Vehicle `i`'s label in proximity texts ([`Self::set_labels`]).
    #[must_use]
    pub fn label(&self, i: usize) -> &str {
        &self.labels[i]
    }

    /// Announce `text` to vehicle `i` at the current instant, as the world
    /// announces its own events (a replay re-telling a proximity event that
    /// another vehicle of the live fleet caused).
    pub fn announce(&mut self, i: usize, text: StatusText) {
        let t = self.time_s();
        self.world_texts[i].push((t, text));
    }

    /// The proximity events since the last call, oldest first, each with the
    /// simulated time [s] after the step that raised it.
    pub fn drain_proximity_events(&mut self) -> Vec<(f64, ProximityEvent)> {
        self.proximity_events.drain(..).collect()
    }

    /// Check proximity after a step (module doc of [`crate::sim::proximity`]).
    fn check_proximity(&mut self) {
        let Some(prox) = &mut self.proximity else {
            return;
        };
        if self.world.len() < 2 {
            return;
        }
        // the positions and radii were noted by each vehicle's step
        let mut events = Vec::new();
        prox.check(&self.positions, &self.radii, &mut events);
        let t = self.world.time_s();
        for e in events {
            for (me, other) in [(e.a, e.b), (e.b, e.a)] {
                let text = proximity_text(e.kind, &self.labels[other], e.distance_m);
                self.world_texts[me].push((t, text));
            }
            self.proximity_events.push_back((t, e));
        }
    }

    /// Vehicle `i`'s world announcements (accepted failure injections) since
    /// the last call, oldest first.
    pub fn drain_world_texts(&mut self, i: usize) -> Vec<StatusText> {
        self.world_texts[i].drain(..).map(|(_, s)| s).collect()
    }

    /// Vehicle `i`'s status texts since the last call: its pilot's, then
    /// the world's (accepted failure injections).
    pub fn drain_status_texts(&mut self, i: usize) -> Vec<StatusText> {
        self.drain_stamped_status_texts(i).into_iter().map(|(_, s)| s).collect()
    }

    /// [`Self::drain_status_texts`], each with the simulated time [s] it was
    /// raised at: a text the autopilot raises in a step carries the time
    /// after that step, one raised by an input between steps (or the world's
    /// failure injection) the time of the input.
    pub fn drain_stamped_status_texts(&mut self, i: usize) -> Vec<(f64, StatusText)> {
        self.stamp_pilot_texts(i);
        let mut texts: Vec<_> = self.pilot_texts[i].drain(..).collect();
        texts.append(&mut self.world_texts[i]);
        texts
    }

    /// Move vehicle `i`'s pilot's queued status texts to `pilot_texts`,
    /// stamped with the current simulated time.
    fn stamp_pilot_texts(&mut self, i: usize) {
        let t = self.time_s();
        stamp_texts(&mut self.pilot_texts[i], &mut self.pilots[i], t);
    }

    /// One step of every vehicle: sense, decide, act, integrate (each
    /// vehicle on its own: they do not interact within a step; on the
    /// threads of [`Self::set_threads`] when set), then the clock ticks and
    /// proximity is checked.
    pub fn step(&mut self) {
        let mut none = vec![(); self.pilots.len()];
        self.step_each(&mut none, |(), _, _| {});
    }

    /// [`Self::step`], with `after(&mut extras[i], pilot, record)` run for
    /// each vehicle `i` as soon as its own step is done, on the thread that
    /// stepped it (work that needs only the vehicle's own record, such as
    /// tallying it or writing its log row, shares the stepping threads).
    /// `after` sees the vehicle alone, so the flight is the same to the bit
    /// whatever it does and however many threads run.
    ///
    /// # Panics
    /// When `extras` is not one per vehicle.
    pub fn step_each<T: Send>(&mut self, extras: &mut [T], after: impl Fn(&mut T, &P, StepRecord<'_>) + Sync) {
        self.step_ahead(1, extras, after, |_, _| ControlFlow::Continue(()));
    }

    /// `steps` of [`Self::step_each`], each vehicle through all of them
    /// before the next vehicle (on the threads of [`Self::set_threads`]
    /// when set), so that a vehicle's data stays in its core's caches over
    /// its steps. The vehicles do not interact within a step, so each one
    /// flies the same to the bit as in `steps` calls of
    /// [`Self::step_each`]. Then the clock ticks once per step, and after
    /// each tick the proximity check looks at the places the vehicles'
    /// steps noted for that instant and `instant(self, extras)` runs (to
    /// drain and follow that instant's proximity events, as after
    /// [`Self::step`]): the time, the proximity pairs and
    /// [`Self::noted_position_ned`] are that instant's, while the vehicles
    /// already stand after all `steps`.
    ///
    /// Nothing reaches a vehicle between these steps: only for flights
    /// that need no input but before the first of them. When `instant`
    /// breaks, the clock stops at that instant, the vehicles standing the
    /// rest of the steps ahead of it: for the end of a run, after which
    /// the core is stepped no more.
    ///
    /// # Panics
    /// When `extras` is not one per vehicle.
    pub fn step_ahead<T: Send>(
        &mut self,
        steps: usize,
        extras: &mut [T],
        after: impl Fn(&mut T, &P, StepRecord<'_>) + Sync,
        mut instant: impl FnMut(&mut Self, &mut [T]) -> ControlFlow<()>,
    ) {
        let n = self.pilots.len();
        assert_eq!(extras.len(), n, "one extra per vehicle");
        if steps == 0 {
            return;
        }
        let (first, dt) = (self.world.steps(), self.world.dt_s());
        self.noted.resize(n * steps, (Vector3::zeros(), 0.0));
        // each step's instant as `World::time_s` gives it then
        let per_vehicle = |((mut lane, extra), places): ((Lane<'_, P>, &mut T), &mut [Place])| {
            for (s, place) in (first..).zip(places) {
                step_vehicle(&mut lane, s as f64 * dt, place, extra, &after);
            }
        };
        let lanes = self
            .world
            .slots()
            .zip(self.pilots.iter_mut())
            .zip(self.measurements.iter_mut())
            .zip(self.last_fault.iter_mut().zip(self.pilot_texts.iter_mut()))
            .map(|(((slot, pilot), measurement), (fault, texts))| Lane {
                slot,
                pilot,
                measurement,
                fault,
                texts,
            })
            .zip(extras.iter_mut())
            .zip(self.noted.chunks_mut(steps));
        match &self.threads.0 {
            Some(pool) if n >= 2 * VEHICLES_PER_TASK => {
                use rayon::iter::{IndexedParallelIterator as _, IntoParallelIterator as _, ParallelIterator as _};
                let all: Vec<_> = lanes.collect();
                pool.install(|| {
                    all.into_par_iter()
                        .with_min_len(VEHICLES_PER_TASK)
                        .for_each(per_vehicle);
                });
            }
            _ => lanes.for_each(per_vehicle),
        }
        // the places noted are for the proximity check alone
        let watched = self.proximity.is_some();
        self.positions.resize(n, Vector3::zeros());
        self.radii.resize(n, 0.0);
        for s in 0..steps {
            if watched {
                for (i, &(p, r)) in self.noted.iter().skip(s).step_by(steps).enumerate() {
                    self.positions[i] = p;
                    self.radii[i] = r;
                }
            }
            self.world.tick();
            self.check_proximity();
            if instant(self, extras).is_break() {
                break;
            }
        }
    }

    /// Vehicle `i`'s world position [m, NED] at the latest instant the
    /// clock ticked to, as its step noted it for the proximity check (while
    /// proximity is watched: [`Self::watch_proximity`]).
    ///
    /// # Panics
    /// Before the first step.
    #[must_use]
    pub fn noted_position_ned(&self, i: usize) -> Vector3<f64> {
        self.positions[i]
    }

    /// Vehicle `i`'s latest step.
    #[must_use]
    pub fn last_step(&self, i: usize) -> StepRecord<'_> {
        StepRecord {
            measurement: &self.measurements[i],
            control: self.pilots[i].output(),
            world: self.world.last_report(i),
            end: self.world.plant(i).state(),
        }
    }

    /// The world (truth, for logs and tests; never for a pilot).
    #[must_use]
    pub fn world(&self) -> &World {
        &self.world
    }

    /// The world, to configure it (disturbances, faults, initial states).
    pub fn world_mut(&mut self) -> &mut World {
        &mut self.world
    }

    /// Vehicle `i`'s pilot.
    #[must_use]
    pub fn pilot(&self, i: usize) -> &P {
        &self.pilots[i]
    }

    /// Vehicle `i`'s pilot, to configure it.
    pub fn pilot_mut(&mut self, i: usize) -> &mut P {
        &mut self.pilots[i]
    }

    /// Simulated time [s].
    #[must_use]
    pub fn time_s(&self) -> f64 {
        self.world.time_s()
    }

    /// The step [s].
    #[must_use]
    pub fn dt_s(&self) -> f64 {
        self.world.dt_s()
    }

    /// The steps taken since `t = 0` (the instant is `steps * dt_s`).
    #[must_use]
    pub fn steps(&self) -> u64 {
        self.world.steps()
    }

    /// The last time the world stopped vehicle `i`'s rotors on a fault, and why.
    #[must_use]
    pub fn last_fault(&self, i: usize) -> Option<SimFault> {
        self.last_fault[i]
    }
}

/// One vehicle of a fleet ([`Lockstep::fleet`]).
#[derive(Clone, Copy, Debug)]
pub struct FleetVehicle<'a> {
    /// Its airframe.
    pub airframe: &'a Airframe,
    /// Its home: where it rests at start, its NED origin.
    pub home: GeoPoint,
    /// Its parameters (the autopilot's and the world's `SIM_*`).
    pub params: &'a ParamStore,
    /// Its sensors' noise and seed.
    pub sensors: SensorConfig,
}

impl Lockstep<Autopilot> {
    /// A world of one vehicle on `airframe`, resting on the ground at `home`
    /// (the NED origin), flown by an autopilot with `params`; the world takes
    /// its `SIM_*` parameters.
    ///
    /// # Errors
    /// As [`Autopilot::new`].
    pub fn one_vehicle(
        airframe: &Airframe,
        home: GeoPoint,
        params: &ParamStore,
        sensors: SensorConfig,
    ) -> Result<Self, AutopilotError> {
        let vehicle = FleetVehicle {
            airframe,
            home,
            params,
            sensors,
        };
        Self::fleet(home, &[vehicle]).map_err(|(_, e)| e)
    }

    /// A world whose NED origin is `origin` (the fleet's home, on the ground)
    /// holding `vehicles[i]` as vehicle `i`: each resting on the ground at its
    /// own home, which is also its autopilot's home and NED origin, placed in
    /// the world at the home's north and east offset from `origin`
    /// ([`World::set_origin_ned`]); each world body takes its vehicle's
    /// `SIM_*` parameters. Vehicle `i` flies exactly as it would alone.
    ///
    /// # Errors
    /// The first vehicle whose autopilot cannot start, with its index.
    pub fn fleet(origin: GeoPoint, vehicles: &[FleetVehicle<'_>]) -> Result<Self, (usize, AutopilotError)> {
        let mut world = World::new(DEFAULT_STEP_S, Environment::default());
        let mut pilots = Vec::with_capacity(vehicles.len());
        for (i, v) in vehicles.iter().enumerate() {
            world.add_vehicle(v.airframe, v.sensors);
            world.configure(i, &WorldSettings::from_store(v.params));
            if i > 0 || v.home != origin {
                world.set_origin_ned(i, v.home.ned_from(&origin));
            }
            let pilot = Autopilot::new(v.airframe, v.home, v.params, DEFAULT_STEP_S).map_err(|e| (i, e))?;
            if pilot.navigation().is_some() {
                // the filter is fed by the raw sensors
                world.enable_raw_sensors(i, v.home);
            }
            pilots.push(pilot);
        }
        Ok(Self::new(world, pilots))
    }

    /// Carry out a command for vehicle `i`, judged by its autopilot at the
    /// instant it is applied. A failure injection the autopilot allows
    /// (`SYS_FAILURE_EN`) is the world's to do ([`Self::inject_failure`]).
    /// A reboot the autopilot allows is the runtime's to carry out ([`Self::reboot`]).
    pub fn command(&mut self, i: usize, command: AutopilotCommand) -> CommandOutcome {
        if let Some(refused) = self.preflight(i, command) {
            return refused;
        }
        let readings = self.world.sense(i);
        let outcome = self.pilots[i].command(command, readings);
        let m = readings.measurement;
        match (command, outcome) {
            (AutopilotCommand::InjectFailure { unit, kind, instance }, CommandOutcome::Accepted) => {
                let outcome = self.inject_failure(i, failure::FailureInjection { unit, kind, instance });
                if (unit, kind, outcome) == (failure::UNIT_MOTOR, failure::TYPE_OK, CommandOutcome::Accepted) {
                    // the ESCs report healthy again (PX4's injector cleared)
                    let rotors: Vec<usize> = match usize::from(instance) {
                        0 => (0..crate::signals::MAX_ROTORS).collect(),
                        k => failure::rotor_of_motor(self.world.motors(i), k).into_iter().collect(),
                    };
                    self.pilots[i].esc_reports_healthy(&rotors, &m);
                }
                outcome
            }
            _ => outcome,
        }
    }

    /// Apply vehicle `i`'s parameters: its autopilot's first (it may refuse
    /// the combination; nothing changes then), then the world's `SIM_*`.
    ///
    /// # Errors
    /// As [`Autopilot::apply_params`].
    pub fn apply_params(&mut self, i: usize, params: &ParamStore) -> Result<(), AutopilotError> {
        self.pilots[i].apply_params(params)?;
        self.world.configure(i, &WorldSettings::from_store(params));
        Ok(())
    }

    /// Set one parameter of vehicle `i` in `store` and apply it, or neither:
    /// a value out of range, of the wrong type, or a combination the
    /// autopilot refuses leaves the store and the vehicle as they were.
    /// The stored value on success.
    ///
    /// # Errors
    /// Why the value was refused.
    pub fn set_param(
        &mut self,
        i: usize,
        store: &mut ParamStore,
        name: &str,
        value: ParamValue,
    ) -> Result<ParamValue, String> {
        let old = store.get(name).map(|(_, v)| v);
        let stored = store.set(name, value).map_err(|e| e.to_string())?;
        match self.apply_params(i, store) {
            Ok(()) => Ok(stored),
            Err(e) => {
                if let Some(old) = old {
                    let _ = store.set(name, old);
                }
                Err(e.to_string())
            }
        }
    }

    /// Restart vehicle `i` as after a power cycle: a new autopilot from
    /// `params`, the vehicle resting at its origin with a full battery and
    /// no fault; the clock keeps counting.
    ///
    /// # Errors
    /// As [`Autopilot::new`]; nothing changes then.
    pub fn reboot(&mut self, i: usize, params: &ParamStore) -> Result<(), AutopilotError> {
        let old = &self.pilots[i];
        let mut autopilot = Autopilot::new(old.airframe(), old.origin(), params, self.world.dt_s())?;
        // plans are stored, as PX4's dataman keeps them across a reboot
        autopilot.restore_plans(old.plans().clone());
        autopilot.set_client_clock(old.client_clock());
        self.world.restart_vehicle(i, old.airframe());
        self.world.configure(i, &WorldSettings::from_store(params));
        if autopilot.navigation().is_some() || self.world.raw_sensors_enabled(i) {
            // the raw sensors power-cycle with the vehicle (the filter is fed
            // by them): a fresh start of their stream and sample instants, so
            // a flight after a reboot is a fresh vehicle's
            self.world.enable_raw_sensors(i, autopilot.origin());
        }
        self.pilots[i] = autopilot;
        self.last_fault[i] = None;
        self.world_texts[i].clear();
        self.pilot_texts[i].clear();
        let said = StatusText {
            severity: Severity::Info,
            text: "Rebooted: simulation reset".into(),
        };
        self.world_texts[i].push((self.world.time_s(), said));
        Ok(())
    }

    /// Vehicle `i`'s telemetry at the current instant.
    pub fn telemetry(&mut self, i: usize) -> Telemetry {
        let readings = self.world.sense(i);
        self.pilots[i].telemetry(readings)
    }

    /// Vehicle `i`'s telemetry, the world's injected truth and its ground truth.
    pub fn snapshot(&mut self, i: usize) -> Snapshot {
        let plant = self.world.plant(i);
        let ground_truth = GroundTruth {
            state: plant.truth(),
            acceleration_ned: plant.acceleration_ned(),
        };
        let telemetry = self.telemetry(i);
        Snapshot {
            telemetry,
            truth: self.world.truth(i),
            ground_truth,
            plans: self.pilots[i].plans().clone(),
            raw: *self.world.raw_readings(i),
        }
    }

    /// Simulate vehicle `i`'s raw sensors from now on (IMU, barometer,
    /// magnetometer, GNSS: [`crate::sim::raw_sensors`]), around its
    /// autopilot's home: for the runtimes that stream or log them. They
    /// change no other number of the flight. Nothing changes when they are
    /// already simulated.
    pub fn enable_raw_sensors(&mut self, i: usize) {
        if !self.world.raw_sensors_enabled(i) {
            self.world.enable_raw_sensors(i, self.pilots[i].origin());
        }
    }

    /// Store or clear vehicle `i`'s plans, whole or not at all, at the
    /// current instant ([`Autopilot::change_plans`]): the new plan's id.
    ///
    /// # Errors
    /// Why nothing changed.
    pub fn change_plans(&mut self, i: usize, change: PlanChange) -> Result<u32, MissionResult> {
        self.pilots[i].change_plans(change)
    }

    /// The runtime's wall clock says vehicle `i`'s client timer `timer`
    /// (started at `started_s`) ran out: the autopilot acts on it at the
    /// current instant if it still runs ([`Autopilot::client_timeout`]).
    pub fn client_timeout(&mut self, i: usize, timer: ClientTimer, started_s: f64) -> bool {
        let readings = self.world.sense(i);
        self.pilots[i].client_timeout(timer, started_s, readings)
    }

    /// A ground station's HEARTBEAT for vehicle `i` arrived (from any link):
    /// its autopilot records it at the current instant (data-link loss,
    /// [`Autopilot::gcs_heartbeat`]).
    pub fn gcs_heartbeat(&mut self, i: usize) {
        let readings = self.world.sense(i);
        self.pilots[i].gcs_heartbeat(readings);
    }

    /// Vehicle `i`'s mission items reached or run since the last call, oldest first.
    pub fn drain_mission_done(&mut self, i: usize) -> Vec<crate::autopilot::ItemDone> {
        self.pilots[i].drain_mission_done()
    }
}

/// A quad resting at PX4 SITL's home with the default parameters on the
/// ideal navigation solution (`RP_NAV_SRC` = 0) and the default sensors,
/// and its parameter store (for tests that need a core to step).
#[cfg(test)]
pub(crate) fn test_quad() -> (Lockstep<Autopilot>, ParamStore) {
    let airframe = Airframe::load("quad").expect("the built-in quad");
    let mut params = ParamStore::new(&airframe);
    params.set("RP_NAV_SRC", ParamValue::Int32(0)).expect("RP_NAV_SRC");
    let core = Lockstep::one_vehicle(&airframe, GeoPoint::PX4_SITL_HOME, &params, SensorConfig::default())
        .expect("the default parameters");
    (core, params)
}
