//! The lockstep vehicle: plant, sensors, estimator, controller and allocation
//! stepped together by simulated time. No clock, no I/O: the caller supplies
//! the reference and the disturbance and decides the pacing.
//!
//! One step at `t_k` (doc `model-and-control.md` section 2, timing convention):
//! 1. measure `x_k` (with the plant's seeded noise);
//! 2. the estimator uses `x_{k-1}, x_k` and the wrench `u_{k-1}` applied over
//!    `[t_{k-1}, t_k)`: no algebraic loop;
//! 3. the controller maps `x_k`, the reference and (when feedback is on) the
//!    estimate to `u_k = [u_T, tau^b]`;
//! 4. a rotor airframe allocates `u_k` to rotor speeds with desaturation (the
//!    estimator then sees the allocated wrench, as a real autopilot knows what
//!    it commanded); an ideal one applies `u_k` directly;
//! 5. the plant integrates `[t_k, t_{k+1})`.

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

/// Everything about one step, for logs and summaries.
#[derive(Clone, Copy, Debug)]
pub struct StepRecord {
    /// The measurement the step started from (`x_k`).
    pub measurement: Measurement,
    /// The true state at `t_k`.
    pub truth: RigidBodyState,
    /// The reference at `t_k`.
    pub reference: Reference,
    /// The controller's output `u_k`.
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
    pub attitude_sp: nalgebra::UnitQuaternion<f64>,
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
    /// `u_{k-1}` as the estimator must see it.
    last_applied: Option<ControlWrench>,
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
        Ok(Self {
            plant: Plant::new(airframe, plant),
            nominal,
            controller: Controller::new(kind, gains)?,
            estimator: MomentumEstimator::new(estimator, nominal)?,
            feedback: false,
            allocator: airframe.allocator(),
            actuation: airframe.actuation,
            last_applied: None,
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

    /// The nominal model the controller and estimator use.
    #[must_use]
    pub fn nominal(&self) -> &NominalModel {
        &self.nominal
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
    }

    /// Hover wrench of the nominal model.
    #[must_use]
    pub fn hover_wrench(&self) -> ControlWrench {
        ControlWrench::new(self.nominal.mass_kg * GRAVITY, nalgebra::Vector3::zeros())
    }

    /// One lockstep step (module doc).
    ///
    /// # Errors
    /// [`SimFault`] when the plant refuses the step (the state is then unchanged).
    pub fn step<D: Disturbance + ?Sized>(
        &mut self,
        reference: &Reference,
        disturbance: &D,
    ) -> Result<StepRecord, SimFault> {
        let dt = self.plant.dt_s();
        let measurement = self.plant.measure();
        let truth = *self.plant.state();
        let applied_before = self.last_applied.unwrap_or_else(|| self.hover_wrench());
        let estimate = self.estimator.update_measured(&measurement, &applied_before);
        let est = self.feedback.then_some(&estimate);
        let command = self.controller.update(&self.nominal, &measurement, reference, est, dt);
        let (cmd, applied, saturated, rotor_speed_cmd) = match self.actuation {
            Actuation::Rotors => {
                let a = self.allocator.allocate(&command);
                (
                    ActuatorCommand::RotorSpeeds(a.speed_cmd_rad_s),
                    a.achieved,
                    a.saturated,
                    a.speed_cmd_rad_s,
                )
            }
            Actuation::Ideal => (ActuatorCommand::Wrench(command), command, false, RotorVector::zeros()),
        };
        let external = disturbance.wrench_at(self.plant.time_s());
        let event = self.plant.step(&cmd, disturbance)?;
        self.last_applied = Some(applied);
        Ok(StepRecord {
            measurement,
            truth,
            reference: *reference,
            command,
            applied,
            saturated,
            rotor_speed_cmd,
            estimate,
            external,
            true_mass_kg: self.plant.true_mass_kg(),
            attitude_sp: self.controller.status().attitude_sp,
            event,
        })
    }
}
