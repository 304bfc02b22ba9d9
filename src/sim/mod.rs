//! The simulated world: every vehicle's plant (rigid body, rotors, ground and
//! ceiling effect), its sensors, its battery, the disturbances acting on it
//! and the faults injected into it, stepped together on one clock. Pure and
//! deterministic: no clock, no I/O, seeded noise.
//!
//! The flight stack ([`crate::autopilot`]) never imports this module: it sees
//! a vehicle only through [`SensorReadings`] and acts on it only through
//! [`ActuatorCommand`] (both in [`crate::signals`]). The `SIM_*` parameters
//! configure the world ([`WorldSettings`]), never the autopilot; a fault
//! ([`Fault`]) changes what the sensors report, nothing else tells.
//!
//! Vehicles are addressed by their index, in the order they were added.
//! One step of the world ([`World::step`]) integrates every vehicle over
//! `[t_k, t_k + dt)` under the actuator command it is given; [`World::sense`] reads a
//! vehicle's sensors at `t_k` (the navigation solution's noise is drawn once
//! per instant: reading telemetry between steps never draws noise the flight
//! would not, so the same inputs give the same flight however often a client
//! looks). The raw sensors of an instant are drawn in its step only (the
//! flight's read, [`VehicleSlot::sense`], or the integration), under the
//! faults in force then: an observer reads their latest samples
//! ([`World::raw_readings`]) and never draws one, so what observers read,
//! and when, changes no raw sample.
//!
//! | file | job |
//! |---|---|
//! | [`plant`] | the 6-DoF rigid body, rotors with lag and limits, contact |
//! | [`aero`] | ground and ceiling effect |
//! | `drag` | the aerodynamic wrench of body and rotors (parasitic and rotor drag, translational lift, flapping) |
//! | `sensors` | the navigation solution's seeded noise |
//! | [`raw_sensors`] | IMU, barometer, magnetometer and GNSS samples, on when something reads them |
//! | `battery` | the pack: discharge with the power drawn |
//! | `fault` | faults and their effect on the plant and sensors |
//! | `settings` | the `SIM_*` parameters |
//! | [`wind`] | mean wind, 1-cosine gusts, Dryden turbulence |
//! | [`proximity`] | vehicle–vehicle proximity and collisions |
//!
//! **One world frame.** Each vehicle's plant lives in its own NED frame,
//! whose origin is the vehicle's home (where it was put on the ground);
//! [`World::set_origin_ned`] places that origin in the world's frame (NED
//! from the world's origin, the fleet's home; every vehicle rests on the
//! one ground, so the origin's down component is 0). A vehicle's position
//! in the world is `p_world = origin + p_vehicle` ([`World::position_ned`]),
//! which is what proximity compares. A lone vehicle's origin is the world's.

pub mod aero;
mod battery;
mod drag;
mod fault;
pub mod plant;
pub mod proximity;
pub mod raw_sensors;
mod sensors;
mod settings;
pub mod wind;

pub use fault::{ActiveFaults, Fault, FaultError, RawSensor, RotorHealth};
pub use plant::{
    Contact, Disturbance, Environment, ExternalWrench, Plant, PlantConfig, RigidBodyState, SimFault, StepEvent,
};
pub use proximity::{Proximity, ProximityEvent, ProximityKind};
pub use raw_sensors::{SensorFaults, SensorMode};
pub use sensors::{DEAD_RECKONING_BIAS_M_S2, SensorNoise, Sensors};
pub use settings::{FaultSettings, WorldSettings};
pub use wind::{Gust, Wind, WindSettings};

use nalgebra::Vector3;

use crate::airframe::{Actuation, Airframe};
use crate::geo::GeoPoint;
use crate::signals::{
    ActuatorCommand, BatteryReading, ControlWrench, GpsFix, GpsReading, Measurement, RawSensorReadings, RotorVector,
    SensorReadings,
};
use battery::Battery;
use raw_sensors::{GnssState, RawSensors};

/// Satellites a healthy receiver reports (PX4 SITL's GPS sends about as many).
const SATELLITES: u8 = 12;
/// The pack fitted until the parameters say otherwise ([`World::configure`]): 4S, 5000 mAh.
const DEFAULT_CELLS: f64 = 4.0;
const DEFAULT_CAPACITY_MAH: f64 = 5000.0;

/// What the GNSS receiver reports, with or without a fix.
fn gps_reading(available: bool) -> GpsReading {
    if available {
        GpsReading {
            fix: GpsFix::Fix3d,
            satellites: SATELLITES,
        }
    } else {
        GpsReading {
            fix: GpsFix::None,
            satellites: 0,
        }
    }
}

/// The disturbance state from a time on: values not given keep their previous value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DisturbanceChange {
    /// From this time [s].
    pub at_s: f64,
    /// New external force [N], NED.
    pub force_ned: Option<Vector3<f64>>,
    /// New external torque [N m], FRD.
    pub torque_frd: Option<Vector3<f64>>,
    /// New true mass [kg].
    pub true_mass_kg: Option<f64>,
}

/// The schedule's wrench and true mass at `t` (the last change at or before
/// `t`; values not given carry over; no force before the first change).
fn schedule_at(changes: &[DisturbanceChange], t: f64) -> (ExternalWrench, Option<f64>) {
    let mut w = ExternalWrench::default();
    let mut mass = None;
    for c in changes.iter().take_while(|c| c.at_s <= t) {
        if let Some(f) = c.force_ned {
            w.force_ned = f;
        }
        if let Some(tq) = c.torque_frd {
            w.torque_frd = tq;
        }
        if c.true_mass_kg.is_some() {
            mass = c.true_mass_kg;
        }
    }
    (w, mass)
}

/// Where a vehicle's external wrench comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum DisturbanceSource {
    /// A constant wrench (the `SIM_*` parameters).
    Constant(ExternalWrench),
    /// A schedule sorted by time (a scenario's `[[disturbance]]`s), which may
    /// also change the true mass.
    Schedule(Vec<DisturbanceChange>),
}

impl Disturbance for DisturbanceSource {
    fn wrench_at(&self, t_s: f64) -> ExternalWrench {
        match self {
            DisturbanceSource::Constant(w) => *w,
            DisturbanceSource::Schedule(changes) => schedule_at(changes, t_s).0,
        }
    }
}

/// How a vehicle's sensors are set up.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SensorConfig {
    /// Noise of the navigation solution.
    pub noise: SensorNoise,
    /// Seed of its random stream.
    pub seed: u64,
}

/// What the world did to one vehicle over one step, with the truth at the
/// step's start (for logs, and for tests that hold estimates against the truth).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepReport {
    /// The true state at `t_k`.
    pub truth: RigidBodyState,
    /// The injected external wrench at `t_k` (the whole one on the body is
    /// this plus [`Self::aero`]).
    pub external: ExternalWrench,
    /// The true mass [kg] over the step.
    pub true_mass_kg: f64,
    /// The air's velocity at the vehicle over the step [m/s], world NED.
    pub wind_ned: Vector3<f64>,
    /// The aerodynamic wrench at `t_k` (force world NED, torque body FRD;
    /// zero for an airframe without aerodynamic coefficients).
    pub aero: ExternalWrench,
    /// Touchdown, liftoff or nothing.
    pub event: StepEvent,
    /// The command the plant refused, or the integration that failed: the
    /// rotors were stopped for this step instead.
    pub fault: Option<SimFault>,
}

impl Default for StepReport {
    /// At rest at the origin, nothing happened.
    fn default() -> Self {
        Self {
            truth: RigidBodyState::at_rest(Vector3::zeros()),
            external: ExternalWrench::default(),
            true_mass_kg: 0.0,
            wind_ned: Vector3::zeros(),
            aero: ExternalWrench::default(),
            event: StepEvent::None,
            fault: None,
        }
    }
}

/// The injected truth a client may compare the estimates with. The true
/// external wrench on the body is the injected one plus the aerodynamic one
/// ([`Truth::external_force_ned`], [`Truth::external_torque_frd`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Truth {
    /// Injected external force [N], world NED.
    pub force_ned: Vector3<f64>,
    /// Injected external torque [N m], body FRD.
    pub torque_frd: Vector3<f64>,
    /// True mass [kg].
    pub true_mass_kg: f64,
    /// The air's velocity at the vehicle [m/s], world NED (held over the last step).
    pub wind_ned: Vector3<f64>,
    /// Aerodynamic force [N], world NED, at the start of the last step.
    pub aero_force_ned: Vector3<f64>,
    /// Aerodynamic torque [N m], body FRD, at the start of the last step.
    pub aero_torque_frd: Vector3<f64>,
}

impl Truth {
    /// The whole external force [N], world NED: injected plus aerodynamic.
    #[must_use]
    pub fn external_force_ned(&self) -> Vector3<f64> {
        self.force_ned + self.aero_force_ned
    }

    /// The whole external torque [N m], body FRD: injected plus aerodynamic.
    #[must_use]
    pub fn external_torque_frd(&self) -> Vector3<f64> {
        self.torque_frd + self.aero_torque_frd
    }
}

/// One vehicle of the world.
#[derive(Clone, Debug)]
struct Body {
    plant: Plant,
    sensors: Sensors,
    battery: Battery,
    /// Total rotor disk area [m^2] (battery power).
    disk_area_m2: f64,
    disturbance: DisturbanceSource,
    /// The air at this vehicle (its turbulence on its own stream).
    wind: Wind,
    faults: ActiveFaults,
    /// Each rotor's motor number ([`crate::airframe::RotorGeometry::motor`]),
    /// from rotor 1: the numbers failures are injected by.
    motors: Vec<usize>,
    /// What an injected WRONG fault does (`SIM_*_WRONG_*`).
    fault_settings: FaultSettings,
    /// The navigation solution at the current instant before the injected
    /// GNSS faults' errors (its noise drawn once per instant).
    nav: Measurement,
    /// The sensors' latest reading...
    reading: SensorReadings,
    /// ... whose navigation solution was taken at the current instant (its
    /// noise is drawn once per instant; the other sensors are read each time).
    measured: bool,
    /// Where this vehicle's NED origin (its home) lies in the world's NED frame [m].
    origin_ned: Vector3<f64>,
    /// The body's radius [m]: the farthest rotor hub plus a rotor radius.
    radius_m: f64,
    /// Its seed (the raw sensors derive their own stream from it).
    seed: u64,
    /// The raw sensors, once something reads them ([`World::enable_raw_sensors`]).
    raw: Option<Box<RawSensors>>,
    /// Whether the raw sensors of the current instant were drawn.
    raw_sampled: bool,
    /// Whether the step that ended at the current instant was a touchdown
    /// (the raw IMU then feels its levelling).
    touched_down: bool,
}

impl Body {
    /// Set the air; calm air is no air at all for the plant.
    fn set_wind(&mut self, wind: WindSettings) {
        self.wind.set(wind);
        if wind.is_calm() {
            self.plant.set_wind_ned(Vector3::zeros());
        }
    }

    /// Draw the raw sensors due at the current instant into
    /// `self.reading.raw`, once per instant, under the faults in force now.
    /// Only the step calls this (the flight's own read, or the integration
    /// when the flight did not read): what an observer reads between steps,
    /// and when, never changes a raw sample.
    fn sample_raw(&mut self) {
        if self.raw_sampled {
            return;
        }
        self.raw_sampled = true;
        if let Some(raw) = &mut self.raw {
            let gnss = GnssState {
                available: self.faults.gps_available,
                offset_ned: self.faults.gps_offset_ned,
                satellites: SATELLITES,
            };
            let accel = self.plant.acceleration_ned();
            raw.sample(
                &self.plant.truth(),
                &accel,
                self.touched_down,
                &self.faults.sensors,
                gnss,
                &mut self.reading.raw,
            );
        }
    }

    /// Read the sensors at the current instant into `self.reading`: the
    /// navigation solution once per instant, the others every time (they
    /// follow a fault or a new pack at once). The raw sensors are not read
    /// here: they are drawn in the step ([`Self::sample_raw`]), and this
    /// leaves their latest samples as they are.
    fn read(&mut self) {
        if !self.measured {
            self.nav = self.sensors.measure(&self.plant.truth());
            self.measured = true;
        }
        let r = &mut self.reading;
        r.measurement = if self.sensors.degraded() {
            self.sensors.degrade(&self.nav)
        } else {
            self.nav
        };
        r.acceleration_ned = self.plant.acceleration_ned();
        r.rotor_speeds_rad_s = *self.plant.rotor_speeds();
        r.battery = BatteryReading {
            voltage_v: self.battery.voltage_v(),
            current_a: self.battery.current_a(),
        };
        r.gps = gps_reading(self.faults.gps_available);
    }

    /// Integrate over `[t, t + dt)` under `command`; a refused command or a
    /// failed integration stops the rotors for the step instead (what ESCs do
    /// with garbage). What happened goes to `report`.
    fn step(&mut self, command: &ActuatorCommand, report: &mut StepReport) {
        // the raw sensors of the instant left, if the flight did not read them
        self.sample_raw();
        let t = self.plant.time_s();
        // the wrench in force now, and until when
        let (current, until_s) = match &self.disturbance {
            DisturbanceSource::Constant(w) => (*w, f64::INFINITY),
            DisturbanceSource::Schedule(changes) => {
                let (wrench, mass) = schedule_at(changes, t);
                if let Some(m) = mass {
                    self.plant.set_true_mass(m);
                }
                let next = changes.iter().map(|c| c.at_s).find(|&at| at > t);
                (wrench, next.unwrap_or(f64::INFINITY))
            }
        };
        report.truth = *self.plant.state();
        // the air at t, held over the step; the turbulence then moves on
        if !self.wind.is_calm() {
            let s = report.truth;
            let height_m = self.plant.environment().ground_z_ned - s.position_ned.z;
            self.plant.set_wind_ned(self.wind.at(t, height_m));
            self.wind.advance(self.plant.dt_s(), height_m, &s.velocity_ned);
        }
        // RK4 evaluates the wrench at t, t + dt/2 and t + dt: held constant
        // unless a scheduled change falls inside the step
        let held = until_s > t + self.plant.dt_s();
        let mut step = |cmd: &ActuatorCommand| {
            if held {
                self.plant.step(cmd, &current)
            } else {
                self.plant.step(cmd, &self.disturbance)
            }
        };
        let (event, fault) = match step(command) {
            Ok(event) => (event, None),
            // Stop is finite and the state was kept finite, so this step succeeds.
            Err(fault) => (step(&ActuatorCommand::Stop).unwrap_or(StepEvent::None), Some(fault)),
        };
        self.battery
            .update(self.plant.last_wrench().thrust_n, self.plant.dt_s());
        self.measured = false;
        self.raw_sampled = false;
        self.touched_down = matches!(event, StepEvent::Touchdown { .. });
        report.external = self.plant.last_external_wrench();
        report.true_mass_kg = self.plant.true_mass_kg();
        report.wind_ned = self.plant.wind_ned();
        report.aero = self.plant.last_aero_wrench();
        report.event = event;
        report.fault = fault;
    }
}

/// One vehicle of the world for one step ([`World::slots`]).
#[derive(Debug)]
pub struct VehicleSlot<'w> {
    body: &'w mut Body,
    report: &'w mut StepReport,
}

impl VehicleSlot<'_> {
    /// The vehicle's sensors at the current instant, read by its flight in
    /// the step: as [`World::sense`], and the raw sensors due now drawn.
    pub fn sense(&mut self) -> &SensorReadings {
        self.body.read();
        self.body.sample_raw();
        &self.body.reading
    }

    /// Integrate the vehicle over `[t, t + dt)` under `command` (as
    /// [`World::step`] does for each vehicle); what happened.
    pub fn integrate(&mut self, command: &ActuatorCommand) -> &StepReport {
        self.body.step(command, self.report);
        self.report
    }

    /// What the latest step did (as [`World::last_report`]).
    #[must_use]
    pub fn report(&self) -> &StepReport {
        self.report
    }

    /// The vehicle's true state (as [`World::plant`]'s).
    #[must_use]
    pub fn state(&self) -> &RigidBodyState {
        self.body.plant.state()
    }

    /// The vehicle's position in the world's NED frame [m] (as
    /// [`World::position_ned`]: its origin plus its own NED position).
    #[must_use]
    pub fn position_ned(&self) -> Vector3<f64> {
        self.body.origin_ned + self.body.plant.state().position_ned
    }

    /// The vehicle's body radius [m] (as [`World::body_radius_m`]).
    #[must_use]
    pub fn body_radius_m(&self) -> f64 {
        self.body.radius_m
    }
}

/// A body's radius [m]: `max_i |r_i| + rotor radius`, the rotor hubs `r_i`
/// in FRD (an airframe without rotor geometry: the rotor radius alone).
fn body_radius_m(airframe: &Airframe) -> f64 {
    let arm = airframe
        .rotors
        .iter()
        .map(|r| r.position_frd().norm())
        .fold(0.0, f64::max);
    arm + airframe.rotor.radius_m
}

/// Every simulated vehicle on one clock.
#[derive(Clone, Debug)]
pub struct World {
    dt_s: f64,
    environment: Environment,
    steps: u64,
    bodies: Vec<Body>,
    reports: Vec<StepReport>,
}

impl World {
    /// An empty world stepping by `dt_s` [s] in `environment`.
    #[must_use]
    pub fn new(dt_s: f64, environment: Environment) -> Self {
        Self {
            dt_s,
            environment,
            steps: 0,
            bodies: Vec::new(),
            reports: Vec::new(),
        }
    }

    /// Add a vehicle resting on the ground below the NED origin, with a full
    /// battery and no disturbance; its index.
    ///
    /// # Panics
    /// When the world has already stepped (every vehicle shares the clock from 0).
    pub fn add_vehicle(&mut self, airframe: &Airframe, sensors: SensorConfig) -> usize {
        assert_eq!(self.steps, 0, "vehicles join the world before it starts");
        let plant = Plant::new(
            airframe,
            PlantConfig {
                dt_s: self.dt_s,
                environment: self.environment,
            },
        );
        let n = airframe.rotor_count();
        let disk_area_m2 = n as f64 * std::f64::consts::PI * airframe.rotor.radius_m.powi(2);
        let radius_m = body_radius_m(airframe);
        self.bodies.push(Body {
            plant,
            sensors: Sensors::new(sensors.noise, sensors.seed),
            battery: Battery::new(disk_area_m2, DEFAULT_CELLS, DEFAULT_CAPACITY_MAH, 0.0),
            disk_area_m2,
            disturbance: DisturbanceSource::Constant(ExternalWrench::default()),
            wind: Wind::new(sensors.seed),
            faults: ActiveFaults::none(if airframe.actuation == Actuation::Rotors { n } else { 0 }),
            motors: airframe.rotors.iter().map(|r| r.motor).collect(),
            fault_settings: FaultSettings::default(),
            nav: Measurement::default(),
            reading: SensorReadings {
                measurement: Measurement::default(),
                acceleration_ned: Vector3::zeros(),
                rotor_speeds_rad_s: RotorVector::zeros(),
                battery: BatteryReading {
                    voltage_v: 0.0,
                    current_a: 0.0,
                },
                gps: GpsReading {
                    fix: GpsFix::None,
                    satellites: 0,
                },
                raw: RawSensorReadings::default(),
            },
            measured: false,
            origin_ned: Vector3::zeros(),
            radius_m,
            seed: sensors.seed,
            raw: None,
            raw_sampled: false,
            touched_down: false,
        });
        self.reports.push(StepReport::default());
        self.bodies.len() - 1
    }

    /// Restart vehicle `i` (a reboot): resting below the NED origin, rotors
    /// still, a full battery, no disturbance and no fault; the clock and the
    /// navigation solution's random stream go on (the raw sensors restart
    /// when enabled again, [`Self::enable_raw_sensors`]).
    pub fn restart_vehicle(&mut self, i: usize, airframe: &Airframe) {
        let steps = self.steps;
        let b = &mut self.bodies[i];
        b.plant = Plant::new(
            airframe,
            PlantConfig {
                dt_s: self.dt_s,
                environment: self.environment,
            },
        );
        b.plant.set_steps(steps);
        b.sensors.force_noise(None);
        b.sensors.set_gps_lost(None);
        b.sensors.set_gps_offset(None);
        b.battery = Battery::new(b.disk_area_m2, DEFAULT_CELLS, DEFAULT_CAPACITY_MAH, 0.0);
        b.disturbance = DisturbanceSource::Constant(ExternalWrench::default());
        b.faults = ActiveFaults::none(b.faults.rotors.len());
        b.motors = airframe.rotors.iter().map(|r| r.motor).collect();
        b.measured = false;
        b.touched_down = false;
    }

    /// Simulate vehicle `i`'s raw sensors ([`raw_sensors`]) from now on, its
    /// home (where its NED origin lies on the globe) at `home`; they then
    /// appear in its [`SensorReadings::raw`]. Off by default: a flight that
    /// nothing reads them from (a headless run) does not pay for them, and
    /// they change no other number of a flight. Enabling them again restarts
    /// them (a new home, their stream from its start, their sample instants
    /// counted from their first sample).
    pub fn enable_raw_sensors(&mut self, i: usize, home: GeoPoint) {
        let b = &mut self.bodies[i];
        b.raw = Some(Box::new(RawSensors::new(home, self.dt_s, b.seed)));
        b.reading.raw = RawSensorReadings::default();
    }

    /// Whether vehicle `i`'s raw sensors are simulated.
    #[must_use]
    pub fn raw_sensors_enabled(&self, i: usize) -> bool {
        self.bodies[i].raw.is_some()
    }

    /// Number of vehicles.
    #[must_use]
    pub fn len(&self) -> usize {
        self.bodies.len()
    }

    /// Whether the world holds no vehicle.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.bodies.is_empty()
    }

    /// The step [s].
    #[must_use]
    pub fn dt_s(&self) -> f64 {
        self.dt_s
    }

    /// Simulated time [s]: the steps taken times the step.
    #[must_use]
    pub fn time_s(&self) -> f64 {
        self.steps as f64 * self.dt_s
    }

    /// The steps taken since the world started (a reboot keeps counting).
    #[must_use]
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// Vehicle `i`'s sensors at the current instant (the navigation
    /// solution drawn once per instant), with the raw sensors' latest
    /// samples as the steps drew them (an instant's raw samples are drawn
    /// in its step, [`VehicleSlot::sense`]: reading here never draws one).
    pub fn sense(&mut self, i: usize) -> &SensorReadings {
        let b = &mut self.bodies[i];
        b.read();
        &b.reading
    }

    /// Vehicle `i`'s raw sensors' latest samples, as the steps drew them
    /// (all `None` unless [`Self::enable_raw_sensors`]): for observers
    /// (telemetry, logs), which read them without changing the world.
    #[must_use]
    pub fn raw_readings(&self, i: usize) -> &RawSensorReadings {
        &self.bodies[i].reading.raw
    }

    /// One tick of the clock: integrate every vehicle `i` over `[t, t + dt)`
    /// under `command(i)`; what happened to each, by index.
    pub fn step<'c>(&mut self, command: impl Fn(usize) -> &'c ActuatorCommand) -> &[StepReport] {
        for (i, (body, report)) in self.bodies.iter_mut().zip(&mut self.reports).enumerate() {
            body.step(command(i), report);
        }
        self.steps += 1;
        &self.reports
    }

    /// Each vehicle on its own, to step them one by one or in parallel (they
    /// do not interact): [`VehicleSlot::sense`] then [`VehicleSlot::integrate`]
    /// for every slot, then [`Self::tick`] once. The same as [`Self::step`].
    pub fn slots(&mut self) -> impl Iterator<Item = VehicleSlot<'_>> {
        self.bodies
            .iter_mut()
            .zip(&mut self.reports)
            .map(|(body, report)| VehicleSlot { body, report })
    }

    /// Advance the clock by one step once every vehicle was integrated
    /// through its [`VehicleSlot`].
    pub fn tick(&mut self) {
        self.steps += 1;
    }

    /// Place vehicle `i`'s NED origin (its home) at `origin_ned` [m] in the
    /// world's frame (module doc); the down component is ignored (one ground).
    pub fn set_origin_ned(&mut self, i: usize, origin_ned: Vector3<f64>) {
        self.bodies[i].origin_ned = Vector3::new(origin_ned.x, origin_ned.y, 0.0);
    }

    /// Vehicle `i`'s NED origin in the world's frame [m].
    #[must_use]
    pub fn origin_ned(&self, i: usize) -> Vector3<f64> {
        self.bodies[i].origin_ned
    }

    /// Vehicle `i`'s position in the world's frame [m, NED]:
    /// `p_world = origin + p_vehicle`.
    #[must_use]
    pub fn position_ned(&self, i: usize) -> Vector3<f64> {
        let b = &self.bodies[i];
        b.origin_ned + b.plant.state().position_ned
    }

    /// Vehicle `i`'s body radius [m] (the farthest rotor hub plus a rotor
    /// radius): two bodies touch when their centres are closer than the sum.
    #[must_use]
    pub fn body_radius_m(&self, i: usize) -> f64 {
        self.bodies[i].radius_m
    }

    /// What the latest step did to vehicle `i`.
    #[must_use]
    pub fn last_report(&self, i: usize) -> &StepReport {
        &self.reports[i]
    }

    /// Configure vehicle `i` from its parameters: the injected wrench (a
    /// schedule, if one is set, is replaced), true mass, effects, battery.
    pub fn configure(&mut self, i: usize, s: &WorldSettings) {
        let ground = self.environment.ground_z_ned;
        let b = &mut self.bodies[i];
        b.disturbance = DisturbanceSource::Constant(s.external);
        b.plant.set_true_mass(s.true_mass_kg);
        b.set_wind(s.wind);
        b.plant.set_environment(Environment {
            ground_z_ned: ground,
            ceiling_z_ned: s.ceiling_height_m.map(|h| ground - h),
            ground_effect: s.ground_effect,
            ceiling_effect: s.ceiling_effect,
        });
        b.battery
            .configure(s.battery_cells, s.battery_capacity_mah, s.battery_min_fraction);
        b.fault_settings = s.faults;
    }

    /// Set what an injected WRONG fault does to vehicle `i` (a scenario
    /// without parameters; [`Self::configure`] sets it from them).
    pub fn set_fault_settings(&mut self, i: usize, settings: FaultSettings) {
        self.bodies[i].fault_settings = settings;
    }

    /// What an injected WRONG fault does to vehicle `i` (its `SIM_*_WRONG_*` parameters).
    #[must_use]
    pub fn fault_settings(&self, i: usize) -> FaultSettings {
        self.bodies[i].fault_settings
    }

    /// Set the air at vehicle `i` (mean wind, turbulence, gusts; its
    /// turbulence state carries on).
    pub fn set_wind(&mut self, i: usize, wind: WindSettings) {
        self.bodies[i].set_wind(wind);
    }

    /// The air at vehicle `i` as set.
    #[must_use]
    pub fn wind(&self, i: usize) -> &WindSettings {
        self.bodies[i].wind.settings()
    }

    /// Let a schedule drive vehicle `i`'s external wrench and true mass.
    pub fn set_disturbance(&mut self, i: usize, source: DisturbanceSource) {
        let b = &mut self.bodies[i];
        b.disturbance = source;
    }

    /// Place vehicle `i` in flight at `state` with its rotors spinning to give
    /// `wrench` (allocated; ideal actuation: nothing spins).
    pub fn start_in_flight(&mut self, i: usize, state: RigidBodyState, wrench: &ControlWrench) {
        let b = &mut self.bodies[i];
        b.plant.set_state(state);
        let speeds = match b.plant.actuation() {
            Actuation::Rotors => b.plant.allocate(wrench),
            Actuation::Ideal => RotorVector::zeros(),
        };
        b.plant.set_rotor_speeds(&speeds);
        b.measured = false;
    }

    /// Inject (or repair) a fault in vehicle `i`.
    ///
    /// # Errors
    /// A vehicle or rotor that does not exist, a rotor fault on an airframe
    /// without rotors, a value out of range; nothing changes then.
    pub fn inject(&mut self, i: usize, fault: Fault) -> Result<(), FaultError> {
        let b = self.bodies.get_mut(i).ok_or(FaultError::NoSuchVehicle(i))?;
        match fault {
            Fault::Rotor { rotor, health } => {
                if b.faults.rotors.is_empty() {
                    return Err(FaultError::NoRotors);
                }
                if rotor >= b.faults.rotors.len() {
                    return Err(FaultError::NoSuchRotor {
                        rotor,
                        count: b.faults.rotors.len(),
                    });
                }
                if let RotorHealth::Degraded { thrust_fraction: f } = health
                    && !(0.0..=1.0).contains(&f)
                {
                    return Err(FaultError::OutOfRange(f));
                }
                b.plant.set_rotor_health(rotor, health.speed_factor());
                b.faults.rotors[rotor] = health;
            }
            Fault::Gps { available } => {
                let t = b.plant.time_s();
                b.sensors.set_gps_lost((!available).then_some(t));
                b.faults.gps_available = available;
            }
            Fault::GpsOffset(offset) => {
                if let Some(o) = offset
                    && let Some(bad) = o.iter().copied().find(|x| !x.is_finite())
                {
                    return Err(FaultError::OutOfRange(bad));
                }
                b.sensors.set_gps_offset(offset);
                b.faults.gps_offset_ned = offset;
            }
            Fault::BatteryCell { failed } => {
                b.battery.set_cell_failed(failed);
                b.faults.battery_cell_failed = failed;
            }
            Fault::LinkLost(lost) => b.faults.link_lost = lost,
            Fault::Sensor { sensor, mode } => {
                let f = &mut b.faults.sensors;
                match sensor {
                    RawSensor::Accel => f.accel = mode,
                    RawSensor::Gyro => f.gyro = mode,
                    RawSensor::Mag => f.mag = mode,
                    RawSensor::Baro => f.baro = mode,
                }
            }
            Fault::GpsStuck(stuck) => b.faults.sensors.gnss_stuck = stuck,
            Fault::SensorNoise(noise) => {
                if let Some(n) = noise
                    && !n.is_valid()
                {
                    let worst = [n.position_m, n.velocity_m_s, n.attitude_rad, n.rate_rad_s]
                        .into_iter()
                        .find(|s| !(s.is_finite() && *s >= 0.0))
                        .unwrap_or(f64::NAN);
                    return Err(FaultError::OutOfRange(worst));
                }
                b.sensors.force_noise(noise);
                b.faults.noise = noise;
            }
        }
        Ok(())
    }

    /// The faults active on vehicle `i`.
    #[must_use]
    pub fn faults(&self, i: usize) -> &ActiveFaults {
        &self.bodies[i].faults
    }

    /// Vehicle `i`'s motor number of each rotor, from rotor 1
    /// ([`crate::airframe::RotorGeometry::motor`]).
    #[must_use]
    pub fn motors(&self, i: usize) -> &[usize] {
        &self.bodies[i].motors
    }

    /// The injected truth on vehicle `i` now (a schedule's values at this
    /// instant, even before the step that applies them).
    #[must_use]
    pub fn truth(&self, i: usize) -> Truth {
        let b = &self.bodies[i];
        let (w, mass) = match &b.disturbance {
            DisturbanceSource::Constant(w) => (*w, None),
            DisturbanceSource::Schedule(changes) => schedule_at(changes, self.time_s()),
        };
        let aero = b.plant.last_aero_wrench();
        Truth {
            force_ned: w.force_ned,
            torque_frd: w.torque_frd,
            true_mass_kg: mass.unwrap_or_else(|| b.plant.true_mass_kg()),
            wind_ned: b.plant.wind_ned(),
            aero_force_ned: aero.force_ned,
            aero_torque_frd: aero.torque_frd,
        }
    }

    /// Vehicle `i`'s plant (true state, contact, rotor speeds), read-only: for
    /// logs and tests, never for the flight stack.
    #[must_use]
    pub fn plant(&self, i: usize) -> &Plant {
        &self.bodies[i].plant
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad_world() -> World {
        let mut w = World::new(crate::signals::DEFAULT_STEP_S, Environment::default());
        w.add_vehicle(&Airframe::load("quad").unwrap(), SensorConfig::default());
        w
    }

    #[test]
    fn a_dead_rotor_spins_down_and_its_esc_says_so() {
        let mut w = quad_world();
        let hover = RotorVector::from_fn(|i, _| if i < 4 { 700.0 } else { 0.0 });
        w.start_in_flight(
            0,
            RigidBodyState::at_rest(Vector3::new(0.0, 0.0, -10.0)),
            &ControlWrench::default(),
        );
        w.inject(
            0,
            Fault::Rotor {
                rotor: 2,
                health: RotorHealth::Off,
            },
        )
        .unwrap();
        w.inject(
            0,
            Fault::Rotor {
                rotor: 1,
                health: RotorHealth::Degraded { thrust_fraction: 0.25 },
            },
        )
        .unwrap();
        // 0.5 s: forty motor time constants
        let spin = ActuatorCommand::RotorSpeeds(hover);
        for _ in 0..500 {
            w.step(|_| &spin);
        }
        let esc = w.sense(0).rotor_speeds_rad_s;
        assert!((esc[0] - 700.0).abs() < 1e-6, "{}", esc[0]);
        assert!(
            (esc[1] - 350.0).abs() < 1e-6,
            "half the speed: a quarter of the thrust, {}",
            esc[1]
        );
        assert!(esc[2] < 1e-3, "dead: {}", esc[2]);
        assert!(w.faults(0).any());
        // repaired
        w.inject(
            0,
            Fault::Rotor {
                rotor: 2,
                health: RotorHealth::Healthy,
            },
        )
        .unwrap();
        assert!(matches!(
            w.inject(
                0,
                Fault::Rotor {
                    rotor: 4,
                    health: RotorHealth::Off
                }
            ),
            Err(FaultError::NoSuchRotor { rotor: 4, count: 4 })
        ));
        let mut ideal = World::new(crate::signals::DEFAULT_STEP_S, Environment::default());
        ideal.add_vehicle(&Airframe::load("fsr-quad").unwrap(), SensorConfig::default());
        assert_eq!(
            ideal.inject(
                0,
                Fault::Rotor {
                    rotor: 0,
                    health: RotorHealth::Off
                }
            ),
            Err(FaultError::NoRotors)
        );
    }

    #[test]
    fn raw_sensors_are_seeded_apart_and_leave_the_navigation_solution_alone() {
        let noisy = SensorConfig {
            noise: SensorNoise {
                position_m: 0.1,
                velocity_m_s: 0.05,
                attitude_rad: 0.01,
                rate_rad_s: 0.01,
            },
            seed: 42,
        };
        let world = |raw: bool, seed: u64| {
            let mut w = World::new(crate::signals::DEFAULT_STEP_S, Environment::default());
            w.add_vehicle(&Airframe::load("quad").unwrap(), SensorConfig { seed, ..noisy });
            if raw {
                w.enable_raw_sensors(0, GeoPoint::PX4_SITL_HOME);
            }
            w
        };
        let (mut plain, mut with, mut again, mut other) =
            (world(false, 42), world(true, 42), world(true, 42), world(true, 43));
        for _ in 0..300 {
            let p = *plain.sense(0);
            let r = *with.sense(0);
            assert_eq!(
                p.measurement, r.measurement,
                "the navigation solution's stream is untouched"
            );
            assert_eq!(p.raw, RawSensorReadings::default());
            assert_eq!(*again.sense(0), r, "same seed, same samples");
            other.sense(0);
            for w in [&mut plain, &mut with, &mut again, &mut other] {
                w.step(|_| &ActuatorCommand::Stop);
            }
        }
        let (a, b) = (with.sense(0).raw, other.sense(0).raw);
        assert!(a.accel.is_some() && a.baro.is_some() && a.mag.is_some() && a.gnss.is_some());
        assert_ne!(a.accel.unwrap().frd, b.accel.unwrap().frd, "another seed, other noise");
    }

    #[test]
    fn gps_loss_and_noise_show_only_in_the_readings() {
        let mut w = quad_world();
        assert_eq!(w.sense(0).gps.fix, GpsFix::Fix3d);
        w.inject(0, Fault::Gps { available: false }).unwrap();
        w.step(|_| &ActuatorCommand::Stop);
        let r = *w.sense(0);
        assert_eq!((r.gps.fix, r.gps.satellites), (GpsFix::None, 0));
        // reading twice at one instant gives the same reading
        assert_eq!(*w.sense(0), r);
        // at rest the ground carries the weight: no acceleration
        assert_eq!(r.acceleration_ned, Vector3::zeros());
        // without a fix the solution dead-reckons away from the still truth; the fix back, it is right
        let drift = (r.measurement.position_ned - w.plant(0).state().position_ned).norm();
        let tau = w.dt_s();
        assert!(
            (drift - DEAD_RECKONING_BIAS_M_S2 * tau * tau / 2.0).abs() < 1e-12,
            "{drift}"
        );
        w.inject(0, Fault::Gps { available: true }).unwrap();
        let fixed = w.sense(0).measurement.position_ned;
        assert_eq!(fixed, w.plant(0).state().position_ned);
        // the noise up: a noiseless vehicle gets noisy measurements, then clean ones again
        let noisy = SensorNoise {
            position_m: 0.5,
            ..SensorNoise::default()
        };
        w.inject(0, Fault::SensorNoise(Some(noisy))).unwrap();
        w.step(|_| &ActuatorCommand::Stop);
        let p = w.sense(0).measurement.position_ned;
        assert!((p - w.plant(0).state().position_ned).norm() > 1e-3, "{p}");
        w.inject(0, Fault::SensorNoise(None)).unwrap();
        w.step(|_| &ActuatorCommand::Stop);
        let clean = w.sense(0).measurement.position_ned;
        assert_eq!(clean, w.plant(0).state().position_ned);
        assert!(matches!(
            w.inject(
                0,
                Fault::SensorNoise(Some(SensorNoise {
                    rate_rad_s: f64::NAN,
                    ..SensorNoise::default()
                }))
            ),
            Err(FaultError::OutOfRange(_))
        ));
    }
}
