//! The loop every pilot shares (the autopilot's modes and a scenario's
//! references alike): the estimator, the control law and the allocation, on
//! the nominal model, never on the plant's truth.
//!
//! One step at `t_k` (doc `model-and-control.md` section 2, timing
//! convention) has two phases, so that a pilot can decide its demand (and the
//! estimate to feed back) from the fresh measurement in between:
//!
//! [`ControlLoop::sense`]: the estimator uses `x_{k-1}, x_k` and the wrench
//! `u_{k-1}` applied over `[t_{k-1}, t_k)` (the nominal hover wrench before
//! the first): no algebraic loop.
//!
//! [`ControlLoop::act`] (with that `x_k`):
//! 1. the controller maps `x_k`, the demand and (when fed back) the estimate
//!    to `u_k = [u_T, tau^b]`; stopped or idling rotors skip it and reset it;
//! 2. a rotor airframe allocates `u_k` to rotor speeds with desaturation (the
//!    estimator then sees the allocated wrench, as a real autopilot knows what
//!    it commanded); an ideal one sends `u_k` as is;
//! 3. the world holds the [`ActuatorCommand`] over `[t_k, t_{k+1})`, and the
//!    applied wrench is the `u_{k-1}` of the next `sense`.

use nalgebra::{UnitQuaternion, Vector3};

use crate::airframe::{Actuation, Airframe, Allocator};
use crate::control::{ControlGains, Controller, ControllerKind, GainError, Reference};
use crate::estimation::{EstimatorConfig, EstimatorError, MomentumEstimator};
use crate::signals::{ActuatorCommand, ControlWrench, GRAVITY, Measurement, NominalModel, RotorVector, WrenchEstimate};

/// Why a control loop could not be built.
#[derive(Debug, thiserror::Error)]
pub enum ControlLoopError {
    /// A gain is invalid.
    #[error(transparent)]
    Gains(#[from] GainError),
    /// The estimator configuration is invalid.
    #[error("estimator: {0}")]
    Estimator(#[from] EstimatorError),
}

/// What drives the vehicle in one step ([`ControlLoop::act`]).
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

/// What the loop decided in one step, for the world and for logs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ControlOutput {
    /// What the actuators get over `[t_k, t_{k+1})`.
    pub actuator: ActuatorCommand,
    /// The reference at `t_k` ([`Demand::Track`]; the default reference for the other demands).
    pub reference: Reference,
    /// The controller's output `u_k` (zero for stopped or idling rotors).
    pub command: ControlWrench,
    /// What was sent to the rotors: the allocated wrench (equal to `command` unless saturated).
    pub applied: ControlWrench,
    /// Whether the allocation had to desaturate.
    pub saturated: bool,
    /// The estimate at `t_k` (from `x_{k-1}, x_k` and `u_{k-1}`).
    pub estimate: WrenchEstimate,
    /// The controller's attitude setpoint at `t_k`.
    pub attitude_sp: UnitQuaternion<f64>,
}

impl Default for ControlOutput {
    /// Rotors stopped, nothing commanded.
    fn default() -> Self {
        Self {
            actuator: ActuatorCommand::Stop,
            reference: Reference::default(),
            command: ControlWrench::default(),
            applied: ControlWrench::default(),
            saturated: false,
            estimate: WrenchEstimate::default(),
            attitude_sp: UnitQuaternion::identity(),
        }
    }
}

impl ControlOutput {
    /// Rotor speed commands [rad/s] (zero for stopped rotors and ideal actuation).
    #[must_use]
    pub fn rotor_speed_cmd(&self) -> RotorVector {
        match self.actuator {
            ActuatorCommand::RotorSpeeds(w) => w,
            ActuatorCommand::Stop | ActuatorCommand::Wrench(_) => RotorVector::zeros(),
        }
    }
}

/// Estimator, controller and allocation of one vehicle.
#[derive(Debug)]
pub struct ControlLoop {
    nominal: NominalModel,
    controller: Controller,
    estimator: MomentumEstimator,
    allocator: Allocator,
    actuation: Actuation,
    /// Rotor speeds at idle [rad/s] (zero beyond the rotor count).
    idle_speeds: RotorVector,
    /// `u_{k-1}` as the estimator must see it.
    last_applied: Option<ControlWrench>,
    /// The latest step's output (its estimate from the latest [`Self::sense`]).
    output: ControlOutput,
}

impl ControlLoop {
    /// A loop for `airframe` with the given law, gains and estimator (the
    /// airframe's nominal model).
    ///
    /// # Errors
    /// Invalid gains or estimator configuration.
    pub fn new(
        airframe: &Airframe,
        kind: ControllerKind,
        gains: ControlGains,
        estimator: EstimatorConfig,
    ) -> Result<Self, ControlLoopError> {
        let nominal = airframe.nominal();
        let mut idle_speeds = RotorVector::zeros();
        idle_speeds
            .rows_mut(0, airframe.rotor_count())
            .fill(airframe.rotor.speed_min_rad_s);
        let estimator = MomentumEstimator::new(estimator, nominal)?;
        let output = ControlOutput {
            estimate: estimator.estimate(),
            ..ControlOutput::default()
        };
        Ok(Self {
            nominal,
            controller: Controller::new(kind, gains)?,
            estimator,
            allocator: airframe.allocator(),
            actuation: airframe.actuation,
            idle_speeds,
            last_applied: None,
            output,
        })
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

    /// Hover wrench of the nominal model.
    #[must_use]
    pub fn hover_wrench(&self) -> ControlWrench {
        ControlWrench::new(self.nominal.mass_kg * GRAVITY, Vector3::zeros())
    }

    /// The wrench sent to the actuators last step (`u_{k-1}`), zero before the first.
    #[must_use]
    pub fn last_applied(&self) -> ControlWrench {
        self.last_applied.unwrap_or_default()
    }

    /// Start over as if in flight from now on: controller and estimator
    /// reset, no previous wrench.
    pub fn restart(&mut self) {
        self.controller.reset();
        self.estimator.reset();
        self.last_applied = None;
    }

    /// The first phase of a step at `t_k`: update the estimator with `x_k`
    /// and the wrench `u_{k-1}` applied over `[t_{k-1}, t_k)` (the nominal
    /// hover wrench before the first applied one).
    pub fn sense(&mut self, measurement: &Measurement) -> WrenchEstimate {
        let applied_before = self.last_applied.unwrap_or_else(|| self.hover_wrench());
        self.output.estimate = self.estimator.update_measured(measurement, &applied_before);
        self.output.estimate
    }

    /// What the latest [`Self::act`] decided.
    #[must_use]
    pub fn output(&self) -> &ControlOutput {
        &self.output
    }

    /// The second phase of a step at `t_k`: the controller for `demand` on
    /// the measurement of that [`Self::sense`], with `feedback` as the
    /// estimate to compensate ([`Demand::Track`] only), then allocation; `u_k`
    /// is remembered for the next `sense`.
    pub fn act(
        &mut self,
        measurement: &Measurement,
        demand: &Demand,
        feedback: Option<&WrenchEstimate>,
        dt: f64,
    ) -> &ControlOutput {
        // (the reference goes straight to the output: it is large)
        let command = match demand {
            Demand::Stop | Demand::Idle => {
                self.controller.reset();
                self.output.reference = Reference::default();
                ControlWrench::default()
            }
            Demand::Track(reference) => {
                self.output.reference = *reference;
                self.controller
                    .update(&self.nominal, measurement, reference, feedback, dt)
            }
            Demand::Attitude {
                attitude,
                rate_frd,
                thrust_n,
            } => {
                self.output.reference = Reference::default();
                self.controller
                    .update_attitude(&self.nominal, measurement, attitude, rate_frd, *thrust_n, dt)
            }
        };
        // (written straight into the output: the rotor speeds are large)
        let out = &mut self.output;
        out.saturated = false;
        match (demand, self.actuation) {
            (Demand::Stop, _) => {
                out.actuator = ActuatorCommand::Stop;
                out.applied = ControlWrench::default();
            }
            (Demand::Idle, Actuation::Rotors) => {
                let speed_sq = self.idle_speeds.component_mul(&self.idle_speeds);
                out.actuator = ActuatorCommand::RotorSpeeds(self.idle_speeds);
                out.applied = self.allocator.forward(&speed_sq);
            }
            (Demand::Idle, Actuation::Ideal) => {
                out.actuator = ActuatorCommand::Wrench(ControlWrench::default());
                out.applied = ControlWrench::default();
            }
            (_, Actuation::Rotors) => {
                let a = self.allocator.allocate(&command);
                out.actuator = ActuatorCommand::RotorSpeeds(a.speed_cmd_rad_s);
                out.applied = a.achieved;
                out.saturated = a.saturated;
            }
            (_, Actuation::Ideal) => {
                out.actuator = ActuatorCommand::Wrench(command);
                out.applied = command;
            }
        }
        out.command = command;
        out.attitude_sp = self.controller.status().attitude_sp;
        self.last_applied = Some(out.applied);
        &self.output
    }

    /// The actuators refused the last command (it was not finite) and the
    /// rotors were stopped instead: the estimator sees no wrench, the
    /// controller starts over.
    pub fn rotors_stopped(&mut self) {
        self.controller.reset();
        self.last_applied = Some(ControlWrench::default());
    }
}
