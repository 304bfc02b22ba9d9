//! The loop every pilot shares (the autopilot's modes and a scenario's
//! references alike): the estimator, the control law and the allocation, on
//! the nominal model, never on the plant's truth.
//!
//! One step at `t_k` (`docs/model.md` section 2, timing
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

use crate::airframe::{Actuation, Airframe, Allocator, HoverVerdict, YawPriority, degraded_verdict};
use crate::control::{
    ControlGains, Controller, ControllerKind, GainError, Reference, RelaxedHover, RelaxedHoverError, RelaxedHoverPhase,
};
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

/// What the loop flies with after rotor faults (`docs/model.md`
/// section 3b), chosen by [`ControlLoop::set_rotor_gains`] from the hover
/// verdict of the remaining rotors ([`degraded_verdict`]).
#[derive(Clone, Debug, PartialEq)]
pub enum RotorAllocation {
    /// Every rotor as built.
    Full,
    /// Failed rotors' columns deleted, degraded ones scaled by their thrust
    /// fraction; hover is interior to the attainable set: full control.
    Reduced {
        /// Thrust fraction per rotor (0 failed, 1 healthy), from rotor 1.
        gains: Vec<f64>,
    },
    /// Failed columns deleted, degraded ones scaled, but hover with zero yaw
    /// torque is only on the boundary of the attainable set (or beyond it),
    /// or the remaining rotors of a vehicle with more than four have rank 3:
    /// the heading is given up (the reference heading follows the measured
    /// one, no yaw rate asked) and roll, pitch and thrust come first — the
    /// inverse over `[u_T, tau_x, tau_y]` gives them the remaining rotors'
    /// full range (from a zero-yaw base the boundary would leave no roll or
    /// pitch margin and the vehicle would flip) — and the yaw gets what is
    /// left ([`YawPriority::Last`]; none at rank 3, [`YawPriority::Dropped`]).
    /// The yaw rate settles where the rotors' drag holds it, and the vehicle
    /// flies on as PX4's allocator flies on with what it can give.
    LostYaw {
        /// Thrust fraction per rotor (0 failed, 1 healthy), from rotor 1.
        gains: Vec<f64>,
        /// The verdict ([`HoverVerdict::Boundary`], [`HoverVerdict::Infeasible`]
        /// or [`HoverVerdict::RankDeficient`]).
        verdict: HoverVerdict,
    },
    /// The remaining rotors have rank 3 (a quad with a dead rotor): no
    /// static hover. Once [`ControlLoop::engage_relaxed_hover`] succeeds the
    /// relaxed-hover controller (`control::relaxed_hover`, Mueller and
    /// D'Andrea 2014: spin about the thrust axis, control the reduced
    /// attitude) flies every airborne demand ([`RelaxedHoverFlight`]);
    /// until then (or when it cannot be built, e.g. no rotational drag) the
    /// loop allocates over `[u_T, tau_x, tau_y]` only (yaw given up, heading
    /// free) as a best effort, and the autopilot lands.
    RelaxedHover {
        /// Thrust fraction per rotor (0 failed, 1 healthy), from rotor 1.
        gains: Vec<f64>,
    },
}

impl RotorAllocation {
    /// Whether the heading is given up (the reference yaw follows the measured one).
    #[must_use]
    pub fn heading_free(&self) -> bool {
        matches!(
            self,
            RotorAllocation::LostYaw { .. } | RotorAllocation::RelaxedHover { .. }
        )
    }
}

/// A quadrotor with a dead rotor coming down under [`RelaxedHover`]: it
/// holds `target_ned` horizontally (NED, where the failure was detected) and
/// descends at `descent_m_s` until the centre of mass is at its resting
/// height above the ground at `target_ned.z`; then every rotor is stopped
/// ([`ActuatorCommand::Stop`]) and stays stopped until the engagement ends
/// (disarm, [`Demand::Stop`]; or the rotor recovers).
#[derive(Clone, Debug)]
pub struct RelaxedHoverFlight {
    /// The controller, built for the dead rotor.
    pub hover: RelaxedHover,
    /// Where to land [m], NED: `x, y` held, `z` the ground.
    pub target_ned: Vector3<f64>,
    /// Descent speed [m/s], positive down.
    pub descent_m_s: f64,
    /// Rotors cut from outside (ground contact seen before the controller's touchdown).
    pub cut: bool,
}

impl RelaxedHoverFlight {
    /// Down, rotors stopped.
    #[must_use]
    pub fn landed(&self) -> bool {
        self.cut || self.hover.phase() == RelaxedHoverPhase::Landed
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
    /// The airframe as built (for reallocation after rotor faults).
    airframe: Airframe,
    /// What the allocation flies with ([`Self::set_rotor_gains`]).
    rotor_allocation: RotorAllocation,
    /// Relaxed hover flying in place of the controller ([`Self::engage_relaxed_hover`]).
    relaxed_hover: Option<RelaxedHoverFlight>,
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
            airframe: airframe.clone(),
            rotor_allocation: RotorAllocation::Full,
            relaxed_hover: None,
            idle_speeds,
            last_applied: None,
            output,
        })
    }

    /// What the allocation flies with.
    #[must_use]
    pub fn rotor_allocation(&self) -> &RotorAllocation {
        &self.rotor_allocation
    }

    /// Rebuild the allocation for the thrust fraction `gains[i]` each rotor
    /// still gives (1 healthy, in `(0, 1)` degraded, 0 failed; missing
    /// entries count as 1), at the nominal mass: all ones is the airframe's own
    /// allocator; otherwise failed columns are deleted and degraded ones
    /// scaled ([`Allocator::with_rotor_gains`]), and the hover verdict of
    /// what remains chooses [`RotorAllocation`]: Feasible `Reduced`,
    /// Boundary or Infeasible `LostYaw` (yaw last), RankDeficient
    /// `RelaxedHover` for a quad and `LostYaw` for more rotors
    /// (yaw row dropped). When no inverse exists at all the previous allocator stays.
    /// Ideal actuation has no rotors: nothing changes.
    pub fn set_rotor_gains(&mut self, gains: &[f64]) -> &RotorAllocation {
        let n = self.airframe.rotor_count();
        if self.actuation != Actuation::Rotors {
            return &self.rotor_allocation;
        }
        let gains: Vec<f64> = (0..n)
            .map(|i| gains.get(i).copied().unwrap_or(1.0).clamp(0.0, 1.0))
            .collect();
        if gains.iter().all(|g| *g >= 1.0) {
            self.allocator = self.airframe.allocator();
            self.rotor_allocation = RotorAllocation::Full;
            self.relaxed_hover = None;
            return &self.rotor_allocation;
        }
        let verdict = degraded_verdict(&self.airframe, &gains, self.nominal.mass_kg).verdict;
        let dead = single_dead_rotor(&gains);
        let b = self.airframe.effectiveness();
        let (lo, hi) = self.airframe.speed_sq_bounds();
        let full_rank = Allocator::with_rotor_gains(&b, lo, hi, &gains, YawPriority::Row);
        let (allocator, mode) = match (verdict, full_rank) {
            (HoverVerdict::Feasible, Ok(a)) => (Some(a), RotorAllocation::Reduced { gains }),
            (HoverVerdict::Boundary | HoverVerdict::Infeasible, Ok(_)) => (
                Allocator::with_rotor_gains(&b, lo, hi, &gains, YawPriority::Last).ok(),
                RotorAllocation::LostYaw { gains, verdict },
            ),
            (_, _) if n == 4 => (
                Allocator::with_rotor_gains(&b, lo, hi, &gains, YawPriority::Dropped).ok(),
                RotorAllocation::RelaxedHover { gains },
            ),
            (_, _) => (
                Allocator::with_rotor_gains(&b, lo, hi, &gains, YawPriority::Dropped).ok(),
                RotorAllocation::LostYaw { gains, verdict },
            ),
        };
        if let Some(a) = allocator {
            self.allocator = a;
        }
        // relaxed hover was built for one dead rotor and the others healthy
        if let Some(flight) = &self.relaxed_hover
            && !(matches!(mode, RotorAllocation::RelaxedHover { .. }) && dead == Some(flight.hover.dead_rotor()))
        {
            self.relaxed_hover = None;
        }
        self.rotor_allocation = mode;
        &self.rotor_allocation
    }

    /// Fly [`RelaxedHover`] from now on (every demand but [`Demand::Stop`]
    /// and, once landed, [`Demand::Idle`]): the allocation must be
    /// [`RotorAllocation::RelaxedHover`] with exactly one dead rotor and the
    /// others healthy; hold `target_ned` [m, NED] horizontally and land on
    /// the ground at its `z`, descending at `descent_m_s` [m/s]. Engaged
    /// already for that rotor: nothing changes.
    ///
    /// # Errors
    /// Why relaxed hover cannot fly this vehicle (not a quad with one dead
    /// rotor, no rotational drag in the airframe, no equilibrium within the
    /// rotor limits); the best-effort allocation stays then.
    pub fn engage_relaxed_hover(
        &mut self,
        target_ned: Vector3<f64>,
        descent_m_s: f64,
    ) -> Result<&RelaxedHoverFlight, RelaxedHoverError> {
        let RotorAllocation::RelaxedHover { gains } = &self.rotor_allocation else {
            return Err(RelaxedHoverError::NoEquilibrium(
                "the remaining rotors can still hover: no relaxed hover needed".into(),
            ));
        };
        let Some(dead) = single_dead_rotor(gains) else {
            return Err(RelaxedHoverError::NoEquilibrium(
                "relaxed hover is for one dead rotor, the others healthy".into(),
            ));
        };
        let keep = self
            .relaxed_hover
            .as_ref()
            .is_some_and(|f| f.hover.dead_rotor() == dead);
        if !keep {
            let hover = RelaxedHover::new(&self.airframe, &self.nominal, dead)?;
            self.relaxed_hover = Some(RelaxedHoverFlight {
                hover,
                target_ned,
                descent_m_s,
                cut: false,
            });
        }
        Ok(self.relaxed_hover.as_ref().expect("engaged above"))
    }

    /// The relaxed-hover flight, when engaged.
    #[must_use]
    pub fn relaxed_hover(&self) -> Option<&RelaxedHoverFlight> {
        self.relaxed_hover.as_ref()
    }

    /// Stop the rotors of an engaged relaxed hover now (the vehicle is on the
    /// ground before the controller saw its touchdown height).
    pub fn cut_relaxed_hover(&mut self) {
        if let Some(f) = &mut self.relaxed_hover {
            f.cut = true;
        }
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

    /// The vertical speed [m/s] NED (down positive) the latest [`Self::act`]
    /// commanded: the reference's, or during the emergency descent after a
    /// rotor loss (whose reference is none) its descent rate. The land
    /// detector's "the ground stopped a commanded descent" needs it.
    #[must_use]
    pub fn commanded_vz_m_s(&self) -> f64 {
        match &self.relaxed_hover {
            Some(flight) if self.actuation == Actuation::Rotors => flight.descent_m_s,
            _ => self.output.reference.velocity_ned.z,
        }
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
        if matches!(demand, Demand::Stop) {
            // disarmed: the emergency is over
            self.relaxed_hover = None;
        } else if self.actuation == Actuation::Rotors
            && let Some(flight) = &mut self.relaxed_hover
        {
            let speeds = flight
                .hover
                .update(measurement, flight.target_ned, flight.descent_m_s, dt);
            let landed = flight.landed();
            self.controller.reset();
            let out = &mut self.output;
            out.reference = Reference::default();
            out.saturated = false;
            if landed {
                out.actuator = ActuatorCommand::Stop;
                out.applied = ControlWrench::default();
            } else {
                out.actuator = ActuatorCommand::RotorSpeeds(speeds);
                out.applied = self.allocator.forward(&speeds.component_mul(&speeds));
            }
            out.command = out.applied;
            out.attitude_sp = measurement.attitude;
            self.last_applied = Some(out.applied);
            return &self.output;
        }
        // (the reference goes straight to the output: it is large)
        let command = match demand {
            Demand::Stop | Demand::Idle => {
                self.controller.reset();
                self.output.reference = Reference::default();
                ControlWrench::default()
            }
            Demand::Track(reference) if self.rotor_allocation.heading_free() => {
                // heading given up: hold the measured one, no yaw rate asked
                let mut free = *reference;
                free.yaw_rad = crate::math::euler_zyx(&measurement.attitude).z;
                free.yaw_rate_rad_s = 0.0;
                free.yaw_accel_rad_s2 = 0.0;
                self.output.reference = free;
                self.controller.update(&self.nominal, measurement, &free, feedback, dt)
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

/// The one rotor with no thrust left when every other one is healthy.
fn single_dead_rotor(gains: &[f64]) -> Option<usize> {
    let mut dead = gains.iter().enumerate().filter(|(_, g)| **g <= 0.0).map(|(i, _)| i);
    let first = dead.next()?;
    (dead.next().is_none() && gains.iter().filter(|g| **g > 0.0).all(|g| *g >= 1.0)).then_some(first)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::{ControlGains, ControllerKind};
    use nalgebra::UnitQuaternion;

    fn quad_loop(gamma: f64) -> ControlLoop {
        let mut af = Airframe::load("quad").unwrap();
        af.rotational_drag_n_m_s = gamma;
        let gains = ControlGains::for_airframe(&af, af.mass_kg).unwrap();
        ControlLoop::new(&af, ControllerKind::Geometric, gains, EstimatorConfig::default()).unwrap()
    }

    fn hovering_at_10_m() -> Measurement {
        Measurement {
            time_s: 1.0,
            position_ned: Vector3::new(0.0, 0.0, -10.0),
            velocity_ned: Vector3::zeros(),
            attitude: UnitQuaternion::identity(),
            rate_frd: Vector3::zeros(),
        }
    }

    #[test]
    fn one_dead_rotor_among_healthy_ones_is_the_relaxed_hover_case() {
        assert_eq!(single_dead_rotor(&[1.0, 0.0, 1.0, 1.0]), Some(1));
        assert_eq!(single_dead_rotor(&[1.0, 0.0, 0.0, 1.0]), None);
        assert_eq!(single_dead_rotor(&[1.0, 0.0, 0.5, 1.0]), None);
        assert_eq!(single_dead_rotor(&[1.0, 1.0, 1.0, 1.0]), None);
    }

    #[test]
    fn relaxed_hover_flies_the_dead_quad_until_touchdown_and_ends_with_the_emergency() {
        let target = Vector3::new(0.0, 0.0, 0.0);
        let mut c = quad_loop(0.013);
        // a full allocation needs no relaxed hover
        assert!(c.engage_relaxed_hover(target, 0.7).is_err());
        assert!(matches!(
            c.set_rotor_gains(&[1.0, 0.0, 1.0, 1.0]),
            RotorAllocation::RelaxedHover { .. }
        ));
        assert_eq!(c.engage_relaxed_hover(target, 0.7).unwrap().hover.dead_rotor(), 1);
        let m = hovering_at_10_m();
        let track = Demand::Track(Reference::default());
        let out = *c.act(&m, &track, None, 0.004);
        let ActuatorCommand::RotorSpeeds(w) = out.actuator else {
            panic!("{:?}", out.actuator)
        };
        assert_eq!(w[1], 0.0, "the dead rotor is not commanded");
        // the two rotors next to the dead one carry the weight
        assert!(w[0] > 300.0 && w[2] > 300.0 && w[3].is_finite(), "{w}");
        assert!(out.applied.thrust_n > 0.0);
        // on the ground (centre of mass at the gear height): rotors stopped,
        // also for the Idle the navigator asks for on the ground
        let mut down = m;
        down.position_ned.z = -0.24;
        assert_eq!(c.act(&down, &track, None, 0.004).actuator, ActuatorCommand::Stop);
        assert_eq!(c.act(&down, &Demand::Idle, None, 0.004).actuator, ActuatorCommand::Stop);
        assert!(c.relaxed_hover().unwrap().landed());
        // disarmed: over
        c.act(&down, &Demand::Stop, None, 0.004);
        assert!(c.relaxed_hover().is_none());
        // a second rotor lost or the rotor back: relaxed hover no longer applies
        c.set_rotor_gains(&[1.0, 0.0, 1.0, 1.0]);
        c.engage_relaxed_hover(target, 0.7).unwrap();
        c.set_rotor_gains(&[1.0, 1.0, 1.0, 1.0]);
        assert!(c.relaxed_hover().is_none());
        c.set_rotor_gains(&[1.0, 0.0, 1.0, 1.0]);
        c.engage_relaxed_hover(target, 0.7).unwrap();
        c.set_rotor_gains(&[0.0, 0.0, 1.0, 1.0]);
        assert!(c.relaxed_hover().is_none());
        assert!(c.engage_relaxed_hover(target, 0.7).is_err());
    }

    #[test]
    fn without_rotational_drag_relaxed_hover_is_refused_and_the_best_effort_stays() {
        let mut c = quad_loop(0.0);
        c.set_rotor_gains(&[1.0, 0.0, 1.0, 1.0]);
        assert_eq!(
            c.engage_relaxed_hover(Vector3::zeros(), 0.7).unwrap_err(),
            RelaxedHoverError::NoRotationalDrag
        );
        assert!(c.relaxed_hover().is_none());
        let out = c.act(&hovering_at_10_m(), &Demand::Track(Reference::default()), None, 0.004);
        assert!(matches!(out.actuator, ActuatorCommand::RotorSpeeds(_)));
        assert!(out.command.thrust_n > 0.0, "the controller flies");
    }
}
