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
//! restarts a vehicle (world and autopilot) on a reboot, is where an accepted
//! failure injection will reach the world, and pairs the autopilot's
//! telemetry with the world's injected truth for the clients that compare
//! them. Vehicles are addressed by index; an index beyond the world panics,
//! as a slice index does.

use crate::airframe::Airframe;
use crate::autopilot::{
    Autopilot, AutopilotCommand, AutopilotError, ClientTimer, CommandOutcome, ControlOutput, StatusText, Telemetry,
};
use crate::geo::GeoPoint;
use crate::mission::{MissionResult, PlanChange, Plans};
use crate::params::{ParamStore, ParamValue};
use crate::signals::{DEFAULT_STEP_S, Measurement, SensorReadings};
use crate::sim::{Environment, SensorConfig, SimFault, StepReport, Truth, World, WorldSettings};

/// Flight software in the loop: from the sensor readings at `t_k` to what
/// the actuators get over `[t_k, t_{k+1})`.
pub trait Pilot {
    /// Decide this step ([`Self::output`] holds the decision).
    fn decide(&mut self, readings: &SensorReadings);
    /// What the latest [`Self::decide`] decided.
    fn output(&self) -> &ControlOutput;
    /// The world refused the command (it was not finite) or could not
    /// integrate it, and stopped the rotors for the step instead.
    fn rotors_stopped(&mut self, why: &SimFault);
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
}

/// What a client may be told about a vehicle: its autopilot's telemetry and
/// the truth injected into the world (to compare with the estimates).
#[derive(Clone, Debug, PartialEq)]
pub struct Snapshot {
    /// What the autopilot reports.
    pub telemetry: Telemetry,
    /// The injected wrench and true mass.
    pub truth: Truth,
    /// The stored mission, geofence and rally points (shared, not copied).
    pub plans: Plans,
}

/// The world and one pilot per vehicle.
#[derive(Debug)]
pub struct Lockstep<P> {
    world: World,
    pilots: Vec<P>,
    /// The measurement each vehicle's pilot decided on last.
    measurements: Vec<Measurement>,
    last_fault: Vec<Option<SimFault>>,
}

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
        }
    }

    /// One step of every vehicle: sense, decide, act, integrate.
    pub fn step(&mut self) {
        for (i, (pilot, measurement)) in self.pilots.iter_mut().zip(&mut self.measurements).enumerate() {
            let readings = self.world.sense(i);
            *measurement = readings.measurement;
            pilot.decide(readings);
        }
        let pilots = &self.pilots;
        let reports = self.world.step(|i| &pilots[i].output().actuator);
        for ((report, pilot), fault) in reports.iter().zip(&mut self.pilots).zip(&mut self.last_fault) {
            if let Some(f) = report.fault {
                pilot.rotors_stopped(&f);
                *fault = Some(f);
            }
        }
    }

    /// Vehicle `i`'s latest step.
    #[must_use]
    pub fn last_step(&self, i: usize) -> StepRecord<'_> {
        StepRecord {
            measurement: &self.measurements[i],
            control: self.pilots[i].output(),
            world: self.world.last_report(i),
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

    /// The last time the world stopped vehicle `i`'s rotors on a fault, and why.
    #[must_use]
    pub fn last_fault(&self, i: usize) -> Option<SimFault> {
        self.last_fault[i]
    }
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
        let mut world = World::new(DEFAULT_STEP_S, Environment::default());
        world.add_vehicle(airframe, sensors);
        world.configure(0, &WorldSettings::from_store(params));
        let autopilot = Autopilot::new(airframe, home, params, DEFAULT_STEP_S)?;
        Ok(Self::new(world, vec![autopilot]))
    }

    /// Carry out a command for vehicle `i`, judged by its autopilot at the
    /// instant it is applied. A failure injection the autopilot allows is the
    /// world's to do: none is wired yet (UNSUPPORTED). A reboot the autopilot
    /// allows is the runtime's to carry out ([`Self::reboot`]).
    pub fn command(&mut self, i: usize, command: AutopilotCommand) -> CommandOutcome {
        let readings = self.world.sense(i);
        let outcome = self.pilots[i].command(command, readings);
        match (command, outcome) {
            // no failure is wired to the world yet (issue 12): PX4's answer for an unknown one
            (AutopilotCommand::InjectFailure { .. }, CommandOutcome::Accepted) => CommandOutcome::Unsupported,
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
        self.pilots[i] = autopilot;
        self.last_fault[i] = None;
        Ok(())
    }

    /// Vehicle `i`'s telemetry at the current instant.
    pub fn telemetry(&mut self, i: usize) -> Telemetry {
        let readings = self.world.sense(i);
        self.pilots[i].telemetry(readings)
    }

    /// Vehicle `i`'s telemetry and the world's injected truth.
    pub fn snapshot(&mut self, i: usize) -> Snapshot {
        Snapshot {
            telemetry: self.telemetry(i),
            truth: self.world.truth(i),
            plans: self.pilots[i].plans().clone(),
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

    /// Vehicle `i`'s mission items reached since the last call, oldest first.
    pub fn drain_mission_reached(&mut self, i: usize) -> Vec<u16> {
        self.pilots[i].drain_mission_reached()
    }

    /// Vehicle `i`'s status texts since the last call.
    pub fn drain_status_texts(&mut self, i: usize) -> Vec<StatusText> {
        self.pilots[i].drain_status_texts()
    }
}
