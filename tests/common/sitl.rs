//! One vehicle in the lockstep core (world and flight stack stepped together
//! on simulated time, no sockets), as the `lockstep_*` tests fly it:
//!
//! ```ignore
//! let mut v = Sitl::quad().params(&[("MPC_XY_VEL_MAX", real(5.0))]).run_for(10.0);
//! v.take_off_to(Some(10.0));
//! ```
//!
//! [`SitlBuilder`] picks the airframe, parameters and sensors; [`Sitl`] keeps
//! the core, the parameter store it was built from and everything the
//! vehicle said (its STATUSTEXTs, read back with [`Sitl::texts`] or
//! [`Sitl::said`]). Vehicle 0 is the only vehicle; the core itself stays at
//! hand ([`Sitl::core`]) for what the harness does not wrap. A test that
//! flies its own pilot (a misled navigation solution, a controller swapped
//! in mid-flight) builds it with [`SitlBuilder::build_with`]. Stepping and
//! commanding here add no arithmetic: a flight is the one the core flies.

use nalgebra::Vector3;
use rotorpilot::airframe::Airframe;
use rotorpilot::autopilot::{
    Autopilot, AutopilotCommand, AutopilotError, CommandOutcome, FlightMode, Severity, StatusText, Telemetry,
};
use rotorpilot::geo::GeoPoint;
use rotorpilot::lockstep::{Lockstep, Pilot};
use rotorpilot::params::{ParamStore, ParamValue};
use rotorpilot::signals::{DEFAULT_STEP_S, SensorReadings};
use rotorpilot::sim::{Environment, Fault, SensorConfig, SimFault, Truth, World, WorldSettings};

/// Where every lockstep test starts: PX4 SITL's home (the NED origin).
pub const HOME: GeoPoint = GeoPoint::PX4_SITL_HOME;

/// A REAL32 parameter value.
pub fn real(x: f32) -> ParamValue {
    ParamValue::Real32(x)
}

/// An INT32 parameter value.
pub fn int(i: i32) -> ParamValue {
    ParamValue::Int32(i)
}

/// The point `north`, `east` [m] from home, `up` [m] above it.
pub fn point(north: f64, east: f64, up: f64) -> GeoPoint {
    HOME.offset(&Vector3::new(north, east, -up))
}

/// The vehicle before it exists: airframe, parameters (set in the order
/// given, over the airframe's defaults and the ideal navigation solution)
/// and sensors.
pub struct SitlBuilder {
    airframe: Airframe,
    params: Vec<(String, ParamValue)>,
    sensors: SensorConfig,
}

impl SitlBuilder {
    /// Set these parameters too (after those given before).
    pub fn params(mut self, params: &[(&str, ParamValue)]) -> Self {
        self.params
            .extend(params.iter().map(|(name, value)| ((*name).to_string(), *value)));
        self
    }

    /// Sensors with this noise and seed (default: none).
    pub fn sensors(mut self, sensors: SensorConfig) -> Self {
        self.sensors = sensors;
        self
    }

    /// The store: the airframe's defaults, the ideal navigation solution
    /// (`RP_NAV_SRC` = 0: these tests fly the flight logic, not the filter,
    /// which the daemon boots on and `lockstep_navigation` flies), then the
    /// test's own parameters.
    fn store(&self) -> ParamStore {
        let mut store = ParamStore::new(&self.airframe);
        store.set("RP_NAV_SRC", int(0)).unwrap();
        for (name, value) in &self.params {
            store.set(name, *value).unwrap();
        }
        store
    }

    /// The vehicle on the ground at [`HOME`], flown by the autopilot, as the
    /// daemon flies it (`Lockstep::one_vehicle`); no step taken.
    pub fn build(self) -> Sitl {
        let store = self.store();
        let core = Lockstep::one_vehicle(&self.airframe, HOME, &store, self.sensors).unwrap();
        Sitl::new(core, store)
    }

    /// [`Self::build`], then `seconds` of simulated time on the ground.
    pub fn run_for(self, seconds: f64) -> Sitl {
        let mut v = self.build();
        v.run(seconds);
        v
    }

    /// The vehicle flown by the pilot `pilot(airframe, params)` makes,
    /// in a world built as `Lockstep::one_vehicle` builds it; no step taken.
    pub fn build_with<P: Pilot>(self, pilot: impl FnOnce(&Airframe, &ParamStore) -> P) -> Sitl<P> {
        let store = self.store();
        let mut world = World::new(DEFAULT_STEP_S, Environment::default());
        world.add_vehicle(&self.airframe, self.sensors);
        world.configure(0, &WorldSettings::from_store(&store));
        let pilot = pilot(&self.airframe, &store);
        Sitl::new(Lockstep::new(world, vec![pilot]), store)
    }
}

/// One vehicle in the lockstep core, its parameter store and what it said.
pub struct Sitl<P = Autopilot> {
    core: Lockstep<P>,
    store: ParamStore,
    said: Vec<StatusText>,
    /// How many of `said` [`Sitl::texts`] has handed out.
    read: usize,
}

impl Sitl {
    /// The shipped quad.
    pub fn quad() -> SitlBuilder {
        Self::airframe("quad")
    }

    /// A shipped airframe (or an airframe file) by name.
    pub fn airframe(name: &str) -> SitlBuilder {
        Self::of(Airframe::load(name).unwrap())
    }

    /// This airframe (a shipped one changed by the test).
    pub fn of(airframe: Airframe) -> SitlBuilder {
        SitlBuilder {
            airframe,
            params: Vec::new(),
            sensors: SensorConfig::default(),
        }
    }
}

impl<P: Pilot> Sitl<P> {
    fn new(core: Lockstep<P>, store: ParamStore) -> Self {
        Self {
            core,
            store,
            said: Vec::new(),
            read: 0,
        }
    }

    /// The lockstep core (vehicle 0 is this vehicle).
    pub fn core(&self) -> &Lockstep<P> {
        &self.core
    }

    /// The lockstep core, to change.
    pub fn core_mut(&mut self) -> &mut Lockstep<P> {
        &mut self.core
    }

    /// The pilot (the flight stack).
    pub fn pilot(&self) -> &P {
        self.core.pilot(0)
    }

    /// The pilot, to change.
    pub fn pilot_mut(&mut self) -> &mut P {
        self.core.pilot_mut(0)
    }

    /// The parameters it was built with or last given.
    pub fn params(&self) -> &ParamStore {
        &self.store
    }

    /// One step of the world and the flight stack.
    pub fn step(&mut self) {
        self.core.step();
    }

    /// How many steps `seconds` of simulated time is (rounded).
    pub fn steps(&self, seconds: f64) -> usize {
        (seconds / self.core.dt_s()).round() as usize
    }

    /// Run `seconds` of simulated time.
    pub fn run(&mut self, seconds: f64) {
        for _ in 0..self.steps(seconds) {
            self.step();
        }
    }

    /// Simulated time [s].
    pub fn time_s(&self) -> f64 {
        self.core.time_s()
    }

    /// The step [s].
    pub fn dt_s(&self) -> f64 {
        self.core.dt_s()
    }

    /// What the sensors read now.
    pub fn readings(&mut self) -> SensorReadings {
        *self.core.world_mut().sense(0)
    }

    /// A fault in the world (a rotor, the GNSS fix, the sensors' noise, ...).
    pub fn inject(&mut self, fault: Fault) {
        self.core.world_mut().inject(0, fault).unwrap();
    }

    /// The GNSS receiver loses (`false`) or regains its fix.
    pub fn gps(&mut self, available: bool) {
        self.inject(Fault::Gps { available });
    }

    /// Why the world stopped the rotors, if it did.
    pub fn last_fault(&self) -> Option<SimFault> {
        self.core.last_fault(0)
    }
}

impl Sitl {
    /// Carry out a command, judged at this instant.
    pub fn command(&mut self, cmd: AutopilotCommand) -> CommandOutcome {
        self.core.command(0, cmd)
    }

    /// What a client reads now.
    pub fn telemetry(&mut self) -> Telemetry {
        self.core.telemetry(0)
    }

    /// The world's true state of the vehicle.
    pub fn truth(&self) -> Truth {
        self.core.world().truth(0)
    }

    /// Armed.
    pub fn armed(&self) -> bool {
        self.core.pilot(0).armed()
    }

    /// The flight mode.
    pub fn mode(&self) -> FlightMode {
        self.core.pilot(0).mode()
    }

    /// A GCS heartbeat arrives now.
    pub fn heartbeat(&mut self) {
        self.core.gcs_heartbeat(0);
    }

    /// Set a parameter and apply it, as PARAM_SET does (it must be accepted).
    pub fn set_param(&mut self, name: &str, value: ParamValue) {
        if let Err(e) = self.core.set_param(0, &mut self.store, name, value) {
            panic!("{name} = {value:?} refused: {e}");
        }
    }

    /// Apply a whole parameter store; kept as the vehicle's when accepted.
    pub fn apply_params(&mut self, store: &ParamStore) -> Result<(), AutopilotError> {
        self.core.apply_params(0, store)?;
        self.store = store.clone();
        Ok(())
    }

    /// Run until `done` holds (checked after every step) or `max_s` passes;
    /// the simulated time it held.
    pub fn run_until(&mut self, max_s: f64, mut done: impl FnMut(&Telemetry) -> bool) -> Option<f64> {
        for _ in 0..self.steps(max_s) {
            self.step();
            let t = self.telemetry();
            if done(&t) {
                return Some(t.time_s);
            }
        }
        None
    }

    /// Arm, and take off to `up_m` above home (None: MIS_TAKEOFF_ALT); both accepted.
    pub fn arm_and_take_off(&mut self, up_m: Option<f64>) {
        assert_eq!(
            self.command(AutopilotCommand::Arm { force: false }),
            CommandOutcome::Accepted
        );
        assert_eq!(
            self.command(AutopilotCommand::Takeoff {
                altitude_amsl_m: up_m.map(|up| HOME.alt_amsl_m + up)
            }),
            CommandOutcome::Accepted
        );
    }

    /// [`Self::arm_and_take_off`], then fly until the takeoff completes (Hold, within 40 s).
    pub fn take_off_to(&mut self, up_m: Option<f64>) {
        self.arm_and_take_off(up_m);
        self.run_until(40.0, |t| t.mode == FlightMode::Hold)
            .expect("takeoff completes");
    }

    fn hear(&mut self) {
        let texts = self.core.drain_status_texts(0);
        self.said.extend(texts);
    }

    /// Everything said so far, oldest first.
    pub fn said(&mut self) -> &[StatusText] {
        self.hear();
        &self.said
    }

    /// What was said since the last call (the first: since the start).
    pub fn texts(&mut self) -> Vec<StatusText> {
        self.hear();
        let new = self.said[self.read..].to_vec();
        self.read = self.said.len();
        new
    }

    /// How many announcements so far contain `part`.
    pub fn count(&mut self, part: &str) -> usize {
        self.said().iter().filter(|s| s.text.contains(part)).count()
    }

    /// The severity of the first announcement that contains `part`.
    pub fn severity_of(&mut self, part: &str) -> Option<Severity> {
        self.said().iter().find(|s| s.text.contains(part)).map(|s| s.severity)
    }
}
