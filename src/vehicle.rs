//! The lockstep vehicle: plant, sensors, estimator, controller and allocation
//! stepped together by simulated time. No clock, no I/O: the caller supplies
//! the [`Demand`] and the disturbance and decides the pacing. The scenario
//! runner flies references with [`Vehicle::step`]; the autopilot owns a
//! vehicle and adds stopped and idling rotors and attitude setpoints.
//!
//! One step at `t_k` (doc `model-and-control.md` section 2, timing convention)
//! has two phases, so that the caller can decide the demand (and the
//! estimate to feed back) from the fresh measurement in between.
//!
//! [`Vehicle::sense`]:
//! 1. measure `x_k` (with the plant's seeded noise);
//! 2. the estimator uses `x_{k-1}, x_k` and the wrench `u_{k-1}` applied over
//!    `[t_{k-1}, t_k)`: no algebraic loop.
//!
//! [`Vehicle::act`] (with the `x_k` of that `sense`):
//! 3. the controller maps `x_k`, the demand and (when fed back) the estimate
//!    to `u_k = [u_T, tau^b]`; stopped or idling rotors skip it and reset it;
//! 4. a rotor airframe allocates `u_k` to rotor speeds with desaturation (the
//!    estimator then sees the allocated wrench, as a real autopilot knows what
//!    it commanded); an ideal one applies `u_k` directly;
//! 5. the plant integrates `[t_k, t_{k+1})`; the applied wrench is the
//!    `u_{k-1}` of the next `sense`.
//!
//! [`Vehicle::step`] is `sense` then `act` with [`Demand::Track`].

use nalgebra::{UnitQuaternion, Vector3};

use crate::airframe::{Actuation, Airframe, Allocator, ControlWrench, GRAVITY, RotorVector};
use crate::control::{ControlGains, Controller, ControllerKind, GainError, Reference};
use crate::estimation::{EstimatorConfig, EstimatorError, MomentumEstimator};
use crate::model::{
    ActuatorCommand, Disturbance, ExternalWrench, Plant, PlantConfig, RigidBodyState, SimFault, StepEvent,
};
use crate::signals::{Measurement, NominalModel, WrenchEstimate};

/// Why a vehicle could not be built.
#[derive(Debug, thiserror::Error)]
pub enum VehicleError {
    /// A gain is invalid.
    #[error(transparent)]
    Gains(#[from] GainError),
    /// The estimator configuration is invalid.
    #[error("estimator: {0}")]
    Estimator(#[from] EstimatorError),
}

/// What drives the vehicle in one step ([`Vehicle::act`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Demand {
    /// Rotors stopped (disarmed): no wrench; the controller is reset.
    Stop,
    /// Rotors at the airframe's idle speed (armed on the ground; ideal
    /// actuation: no wrench); the controller is reset.
    Idle,
    /// Fly this reference with the active law ([`Controller::update`]).
    Track(Reference),
    /// Attitude and thrust setpoint ([`Controller::update_attitude`]).
    Attitude {
        /// Attitude, FRD to NED.
        attitude: UnitQuaternion<f64>,
        /// Body-rate feedforward [rad/s], FRD.
        rate_frd: Vector3<f64>,
        /// Collective thrust [N].
        thrust_n: f64,
    },
}

/// What [`Vehicle::sense`] saw at `t_k`.
#[derive(Clone, Copy, Debug)]
pub struct Sensed {
    /// The measurement `x_k`.
    pub measurement: Measurement,
    /// The estimate at `t_k` (from `x_{k-1}, x_k` and `u_{k-1}`).
    pub estimate: WrenchEstimate,
}

/// Everything about one step, for logs and summaries.
#[derive(Clone, Copy, Debug)]
pub struct StepRecord {
    /// The measurement the step started from (`x_k`).
    pub measurement: Measurement,
    /// The true state at `t_k`.
    pub truth: RigidBodyState,
    /// The reference at `t_k` ([`Demand::Track`]; the default reference for the other demands).
    pub reference: Reference,
    /// The controller's output `u_k` (zero for stopped or idling rotors).
    pub command: ControlWrench,
    /// What was sent to the rotors: the allocated wrench (equal to `command` unless saturated).
    pub applied: ControlWrench,
    /// Whether the allocation had to desaturate.
    pub saturated: bool,
    /// Rotor speed commands [rad/s] (zero for ideal actuation).
    pub rotor_speed_cmd: RotorVector,
    /// The estimate at `t_k`.
    pub estimate: WrenchEstimate,
    /// The true external wrench at `t_k`.
    pub external: ExternalWrench,
    /// The plant's true mass [kg].
    pub true_mass_kg: f64,
    /// The controller's attitude setpoint at `t_k`.
    pub attitude_sp: UnitQuaternion<f64>,
    /// What the plant reported for `[t_k, t_{k+1})`.
    pub event: StepEvent,
}

/// A flying vehicle in lockstep.
#[derive(Debug)]
pub struct Vehicle {
    plant: Plant,
    nominal: NominalModel,
    controller: Controller,
    estimator: MomentumEstimator,
    feedback: bool,
    allocator: Allocator,
    actuation: Actuation,
    /// Rotor speeds at idle [rad/s] (zero beyond the rotor count).
    idle_speeds: RotorVector,
    /// `u_{k-1}` as the estimator must see it.
    last_applied: Option<ControlWrench>,
    /// The latest [`Self::sense`], until a plant step consumes it.
    sensed: Option<Sensed>,
}

impl Vehicle {
    /// A vehicle on `airframe` with the given law, gains and estimator, resting on the ground.
    ///
    /// # Errors
    /// Invalid gains or estimator configuration.
    pub fn new(
        airframe: &Airframe,
        plant: PlantConfig,
        kind: ControllerKind,
        gains: ControlGains,
        estimator: EstimatorConfig,
    ) -> Result<Self, VehicleError> {
        let nominal = airframe.nominal();
        let mut idle_speeds = RotorVector::zeros();
        idle_speeds
            .rows_mut(0, airframe.rotor_count())
            .fill(airframe.rotor.speed_min_rad_s);
        Ok(Self {
            plant: Plant::new(airframe, plant),
            nominal,
            controller: Controller::new(kind, gains)?,
            estimator: MomentumEstimator::new(estimator, nominal)?,
            feedback: false,
            allocator: airframe.allocator(),
            actuation: airframe.actuation,
            idle_speeds,
            last_applied: None,
            sensed: None,
        })
    }

    /// The plant (true state, time, contact).
    #[must_use]
    pub fn plant(&self) -> &Plant {
        &self.plant
    }

    /// The plant, to set initial conditions or the true mass.
    pub fn plant_mut(&mut self) -> &mut Plant {
        &mut self.plant
    }

    /// The controller.
    #[must_use]
    pub fn controller(&self) -> &Controller {
        &self.controller
    }

    /// The controller, to change its gains or reset it.
    pub fn controller_mut(&mut self) -> &mut Controller {
        &mut self.controller
    }

    /// Switch the control law in flight (bumpless: the new law starts from the current state).
    pub fn switch_controller(&mut self, kind: ControllerKind) {
        self.controller.switch_to(kind);
    }

    /// Feed the estimate back to the controller or not.
    pub fn set_feedback(&mut self, on: bool) {
        self.feedback = on;
    }

    /// Whether the estimate is fed back.
    #[must_use]
    pub fn feedback(&self) -> bool {
        self.feedback
    }

    /// The latest estimate.
    #[must_use]
    pub fn estimate(&self) -> WrenchEstimate {
        self.estimator.estimate()
    }

    /// The estimator (configuration, initialisation).
    #[must_use]
    pub fn estimator(&self) -> &MomentumEstimator {
        &self.estimator
    }

    /// Swap in another estimator (e.g. rebuilt with a new order or cutoff in
    /// flight). It brings its own nominal model: build it with
    /// [`Self::nominal`] or call [`Self::set_nominal`] after.
    pub fn replace_estimator(&mut self, estimator: MomentumEstimator) {
        self.estimator = estimator;
    }

    /// Restart the estimator: its next sample sets `x_0` again.
    pub fn reset_estimator(&mut self) {
        self.estimator.reset();
    }

    /// The nominal model the controller and estimator use.
    #[must_use]
    pub fn nominal(&self) -> &NominalModel {
        &self.nominal
    }

    /// Change the nominal model of controller and estimator
    /// ([`MomentumEstimator::set_nominal`]: the estimate does not jump).
    ///
    /// # Errors
    /// A model the estimator refuses; nothing is changed then.
    pub fn set_nominal(&mut self, nominal: NominalModel) -> Result<(), EstimatorError> {
        self.estimator.set_nominal(nominal)?;
        self.nominal = nominal;
        Ok(())
    }

    /// Place the vehicle in flight at `state` with the rotors spinning to hold
    /// `thrust` along body `-z` (no torque); resets controller and estimator.
    pub fn start_in_flight(&mut self, state: RigidBodyState, wrench: ControlWrench) {
        self.plant.set_state(state);
        let speeds = match self.actuation {
            Actuation::Rotors => self.allocator.allocate(&wrench).speed_cmd_rad_s,
            Actuation::Ideal => RotorVector::zeros(),
        };
        self.plant.set_rotor_speeds(&speeds);
        self.controller.reset();
        self.estimator.reset();
        self.last_applied = None;
        self.sensed = None;
    }

    /// Hover wrench of the nominal model.
    #[must_use]
    pub fn hover_wrench(&self) -> ControlWrench {
        ControlWrench::new(self.nominal.mass_kg * GRAVITY, Vector3::zeros())
    }

    /// One lockstep step (module doc): [`Self::sense`], then [`Self::act`]
    /// towards `reference`, with the estimate fed back when [`Self::feedback`] is on.
    ///
    /// # Errors
    /// [`SimFault`] when the plant refuses the step (the state is then unchanged).
    pub fn step<D: Disturbance + ?Sized>(
        &mut self,
        reference: &Reference,
        disturbance: &D,
    ) -> Result<StepRecord, SimFault> {
        let sensed = self.measure();
        let feedback = self.feedback.then_some(&sensed.estimate);
        self.act_on(&sensed, &Demand::Track(*reference), feedback, disturbance)
    }

    /// The first phase of a step at `t_k`: measure `x_k` and update the
    /// estimator with it and the wrench `u_{k-1}` applied over `[t_{k-1}, t_k)`
    /// (the nominal hover wrench before the first applied one). The
    /// measurement is kept for [`Self::act`].
    pub fn sense(&mut self) -> Sensed {
        let sensed = self.measure();
        self.sensed = Some(sensed);
        sensed
    }

    /// [`Self::sense`] without keeping the measurement.
    fn measure(&mut self) -> Sensed {
        let measurement = self.plant.measure();
        let applied_before = self.last_applied.unwrap_or_else(|| self.hover_wrench());
        let estimate = self.estimator.update_measured(&measurement, &applied_before);
        Sensed { measurement, estimate }
    }

    /// The second phase of a step at `t_k`: the controller for `demand` on
    /// the measurement of the latest [`Self::sense`] (sensing first if the
    /// plant has stepped since), with `feedback` as the estimate to
    /// compensate ([`Demand::Track`] only), then allocation, the plant step
    /// over `[t_k, t_{k+1})` and `u_k` remembered for the estimator.
    ///
    /// # Errors
    /// [`SimFault`] when the plant refuses the step: the state and time are
    /// then unchanged and the measurement stays current, so another `act`
    /// (e.g. with [`Demand::Stop`]) retries the same step.
    pub fn act<D: Disturbance + ?Sized>(
        &mut self,
        demand: &Demand,
        feedback: Option<&WrenchEstimate>,
        disturbance: &D,
    ) -> Result<StepRecord, SimFault> {
        let sensed = match self.sensed {
            Some(s) => s,
            None => self.sense(),
        };
        self.act_on(&sensed, demand, feedback, disturbance)
    }

    /// [`Self::act`] on the measurement `sensed` (kept as the current one
    /// when the plant refuses the step).
    fn act_on<D: Disturbance + ?Sized>(
        &mut self,
        sensed: &Sensed,
        demand: &Demand,
        feedback: Option<&WrenchEstimate>,
        disturbance: &D,
    ) -> Result<StepRecord, SimFault> {
        let dt = self.plant.dt_s();
        let truth = *self.plant.state();
        let measurement = &sensed.measurement;
        let (command, reference) = match demand {
            Demand::Stop | Demand::Idle => {
                self.controller.reset();
                (ControlWrench::default(), Reference::default())
            }
            Demand::Track(reference) => (
                self.controller
                    .update(&self.nominal, measurement, reference, feedback, dt),
                *reference,
            ),
            Demand::Attitude {
                attitude,
                rate_frd,
                thrust_n,
            } => (
                self.controller
                    .update_attitude(&self.nominal, measurement, attitude, rate_frd, *thrust_n, dt),
                Reference::default(),
            ),
        };
        let (cmd, applied, saturated, rotor_speed_cmd) = match (demand, self.actuation) {
            (Demand::Stop, _) => (
                ActuatorCommand::Stop,
                ControlWrench::default(),
                false,
                RotorVector::zeros(),
            ),
            (Demand::Idle, Actuation::Rotors) => {
                let speed_sq = self.idle_speeds.component_mul(&self.idle_speeds);
                (
                    ActuatorCommand::RotorSpeeds(self.idle_speeds),
                    self.allocator.forward(&speed_sq),
                    false,
                    self.idle_speeds,
                )
            }
            (Demand::Idle, Actuation::Ideal) => (
                ActuatorCommand::Wrench(ControlWrench::default()),
                ControlWrench::default(),
                false,
                RotorVector::zeros(),
            ),
            (_, Actuation::Rotors) => {
                let a = self.allocator.allocate(&command);
                (
                    ActuatorCommand::RotorSpeeds(a.speed_cmd_rad_s),
                    a.achieved,
                    a.saturated,
                    a.speed_cmd_rad_s,
                )
            }
            (_, Actuation::Ideal) => (ActuatorCommand::Wrench(command), command, false, RotorVector::zeros()),
        };
        let external = disturbance.wrench_at(self.plant.time_s());
        let event = match self.plant.step(&cmd, disturbance) {
            Ok(event) => event,
            Err(fault) => {
                self.sensed = Some(*sensed);
                return Err(fault);
            }
        };
        self.last_applied = Some(applied);
        self.sensed = None;
        Ok(StepRecord {
            measurement: sensed.measurement,
            truth,
            reference,
            command,
            applied,
            saturated,
            rotor_speed_cmd,
            estimate: sensed.estimate,
            external,
            true_mass_kg: self.plant.true_mass_kg(),
            attitude_sp: self.controller.status().attitude_sp,
            event,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad() -> (Airframe, Vehicle) {
        let a = Airframe::load("quad").unwrap();
        let mut gains = ControlGains::for_airframe(&a);
        gains.apply(&a.control);
        let v = Vehicle::new(
            &a,
            PlantConfig::default(),
            ControllerKind::Geometric,
            gains,
            EstimatorConfig::default(),
        )
        .unwrap();
        (a, v)
    }

    #[test]
    fn step_is_sense_then_act_and_act_senses_when_needed() {
        let wind = ExternalWrench {
            force_ned: Vector3::new(0.5, 0.0, 0.0),
            torque_frd: Vector3::zeros(),
        };
        let r = Reference::hold(Vector3::new(1.0, 0.0, -2.0), 0.0);
        let mut v: Vec<Vehicle> = (0..4).map(|_| quad().1).collect();
        for (i, x) in v.iter_mut().enumerate() {
            x.set_feedback(i == 0);
            let mut state = *x.plant().state();
            state.position_ned.z = -2.0;
            let hover = x.hover_wrench();
            x.start_in_flight(state, hover);
        }
        for _ in 0..300 {
            let stepped = v[0].step(&r, &wind).unwrap();
            let sensed = v[1].sense();
            let split = v[1].act(&Demand::Track(r), Some(&sensed.estimate), &wind).unwrap();
            assert_eq!(stepped.applied, split.applied);
            let stepped = v[2].step(&r, &wind).unwrap();
            let unsensed = v[3].act(&Demand::Track(r), None, &wind).unwrap();
            assert_eq!(stepped.applied, unsensed.applied);
            assert_eq!(stepped.measurement, unsensed.measurement);
        }
        assert_eq!(v[0].plant().state(), v[1].plant().state());
        assert_eq!(v[2].plant().state(), v[3].plant().state());
        assert_ne!(v[0].plant().state(), v[2].plant().state());
    }

    #[test]
    fn stop_and_idle_skip_the_controller() {
        let (af, mut v) = quad();
        let still = ExternalWrench::default();
        let n = af.rotor_count();
        let sensed = v.sense();
        assert_eq!(sensed.measurement.time_s, 0.0);
        let idle = v.act(&Demand::Idle, None, &still).unwrap();
        assert!(
            idle.rotor_speed_cmd
                .rows(0, n)
                .iter()
                .all(|w| *w == af.rotor.speed_min_rad_s)
        );
        assert!(idle.applied.thrust_n > 0.0 && idle.command.thrust_n == 0.0);
        let stop = v.act(&Demand::Stop, None, &still).unwrap();
        assert_eq!(stop.applied, ControlWrench::default());
        assert_eq!(v.plant().time_s(), 2.0 * v.plant().dt_s());
    }
}
