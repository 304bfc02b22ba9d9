//! The [`Autopilot`]: supervision (landing detection, auto-disarm, offboard
//! loss) and guidance per mode (shaped references, attitude setpoints, idle
//! or stopped rotors) between the two phases of the lockstep
//! [`Vehicle`] step it owns.

use std::collections::VecDeque;

use nalgebra::{UnitQuaternion, Vector2, Vector3};

use super::battery::Battery;
use super::settings::{OffboardLossAction, Settings};
use super::{FlightMode, LandedState, OffboardSetpoint, Severity, StatusText, Telemetry};
use crate::airframe::{Actuation, Airframe, GRAVITY};
use crate::control::{
    ControlGains, ControllerKind, GainError, Reference, Setpoint, Shaper, ShaperError, ShaperLimits,
    TranslationSetpoint, YawSetpoint,
};
use crate::estimation::{Discretization, EstimatorConfig, EstimatorError, MomentumEstimator};
use crate::geo::GeoPoint;
use crate::math::euler_zyx;
use crate::model::{Contact, ExternalWrench, Plant, PlantConfig, SimFault, World};
use crate::params::ParamStore;
use crate::signals::{Measurement, NominalModel, WrenchEstimate};
use crate::vehicle::{Demand, Vehicle, VehicleError};

/// Continuous ground contact this long [s] means "landed" (PX4's land detector takes longer; we see the contact).
pub(super) const LAND_DETECT_S: f64 = 0.25;
/// Status texts kept until drained (oldest dropped first).
const STATUS_QUEUE: usize = 64;
/// Landing aims this far [m] below the ground so the descent never slows before touchdown.
const LAND_SINK_M: f64 = 5.0;
/// The shaped reference has arrived when within this distance [m] of its target...
const REF_ARRIVED_M: f64 = 0.02;
/// ... and slower than this [m/s].
const REF_STOPPED_M_S: f64 = 0.05;
/// A takeoff is complete when the vehicle is also within this height [m] of its target.
const TAKEOFF_ACCEPT_M: f64 = 0.25;
/// Landed in offboard, a position setpoint this far [m] above the vehicle starts the flight (PX4's takeoff trigger)...
const TAKEOFF_TRIGGER_M: f64 = 0.2;
/// ... as does a climb-rate setpoint above this [m/s], or an upward acceleration setpoint above this [m/s^2].
const TAKEOFF_TRIGGER_M_S: f64 = 0.3;
const TAKEOFF_TRIGGER_M_S2: f64 = 0.5;
/// Time comparisons tolerate this much rounding [s].
const TIME_EPS: f64 = 1e-9;

/// Why an autopilot could not be built or parameters applied.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum AutopilotError {
    /// The home position is not a valid point.
    #[error("home {lat_deg}, {lon_deg}, {alt_amsl_m} m is not a valid position")]
    InvalidHome {
        /// Latitude [deg].
        lat_deg: f64,
        /// Longitude [deg].
        lon_deg: f64,
        /// Altitude AMSL [m].
        alt_amsl_m: f64,
    },
    /// A parameter value the autopilot cannot use.
    #[error("parameter: {0}")]
    Param(String),
    /// The control gains derived from the parameters are invalid.
    #[error(transparent)]
    Gains(#[from] GainError),
    /// The estimator settings are invalid.
    #[error("estimator: {0}")]
    Estimator(#[from] EstimatorError),
    /// The reference shaper limits are invalid.
    #[error(transparent)]
    Shaper(#[from] ShaperError),
}

/// Where Hold flies to (DO_REPOSITION), instead of braking where it is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct HoldTarget {
    /// Target [m], NED.
    pub(super) position_ned: Vector3<f64>,
    /// Heading [rad], `None` = keep.
    pub(super) yaw_rad: Option<f64>,
    /// Ground speed [m/s], `None` = cruise.
    pub(super) speed_m_s: Option<f64>,
}

/// Phases of a return to launch.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum RtlPhase {
    /// Climb where the return started (horizontal position [m], NED).
    Climb {
        /// Where the climb happens.
        xy: Vector2<f64>,
    },
    /// Fly home at the return altitude.
    Return,
    /// Descend over home to RTL_DESCEND_ALT.
    Descend,
    /// Land at home.
    Land,
}

/// The active mode with its state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Nav {
    /// Hold (or Position, which behaves the same without RC).
    Hold {
        /// Report POSCTL instead of AUTO.LOITER.
        position_mode: bool,
        /// Reposition target, or brake and hold.
        target: Option<HoldTarget>,
    },
    /// Climb to a point, then Hold there (or at `then`).
    Takeoff {
        /// Target [m], NED.
        target_ned: Vector3<f64>,
        /// Where to go after the climb (a reposition given on the ground).
        then: Option<HoldTarget>,
    },
    /// Descend and land at this horizontal position [m], NED.
    Land {
        /// Where.
        xy: Vector2<f64>,
    },
    /// Return to launch.
    Rtl {
        /// Current phase.
        phase: RtlPhase,
        /// Return altitude [m], NED z.
        z_return: f64,
    },
    /// Follow the offboard setpoints.
    Offboard,
}

/// A cross-fade of the fed-back estimate after the estimator was rebuilt in flight.
#[derive(Clone, Copy, Debug)]
struct EstimateFade {
    from: WrenchEstimate,
    start_s: f64,
    duration_s: f64,
}

/// The autopilot: arming, modes and guidance around the lockstep [`Vehicle`].
///
/// Each step senses (`x_k`, the estimate from `u_{k-1}`), decides the
/// [`Demand`] for the mode and the estimate to feed back, and acts with them
/// (module doc of [`crate::vehicle`]).
#[derive(Debug)]
pub struct Autopilot {
    pub(super) airframe: Airframe,
    /// Plant, controller, estimator and allocation.
    pub(super) vehicle: Vehicle,
    base_limits: ShaperLimits,
    shaper: Shaper,
    /// The shaper's state is the reference of the previous step (else reset it to the measurement first).
    pub(super) shaper_live: bool,
    pub(super) settings: Settings,
    external: ExternalWrench,
    fade: Option<EstimateFade>,
    disk_area_m2: f64,
    acceleration_ned: Vector3<f64>,
    pub(super) origin: GeoPoint,
    pub(super) home: GeoPoint,
    pub(super) armed: bool,
    armed_at_s: f64,
    /// Left the ground since arming.
    took_off: bool,
    /// Landing-detector output (ground contact for `LAND_DETECT_S`).
    pub(super) landed: bool,
    ground_since_s: Option<f64>,
    landed_at_s: f64,
    pub(super) nav: Nav,
    /// DO_CHANGE_SPEED override of MPC_XY_CRUISE [m/s].
    pub(super) cruise_override: Option<f64>,
    /// Latest offboard setpoint and its arrival time [s].
    pub(super) offboard: Option<(OffboardSetpoint, f64)>,
    /// Attitude target integrated from body-rate setpoints.
    pub(super) rate_target: Option<UnitQuaternion<f64>>,
    battery: Battery,
    status: VecDeque<StatusText>,
    last_fault: Option<SimFault>,
}

/// Gains for the airframe with nominal mass `MDL_MASS`, the airframe file's
/// overrides, and the loop frequency scales `CTRL_POS_SCALE`, `CTRL_ATT_SCALE`
/// (stiffness x s^2, damping and the passivity coupling x s: every pole of
/// the loop moves by the factor s, damping ratios unchanged).
fn control_gains(airframe: &Airframe, s: &Settings) -> ControlGains {
    let mut model_frame = airframe.clone();
    model_frame.mass_kg = s.model_mass_kg;
    let mut g = ControlGains::for_airframe(&model_frame);
    g.apply(&airframe.control);
    let (p, a) = (s.position_scale, s.attitude_scale);
    let (p2, a2) = (p * p, a * a);
    let h = &mut g.hierarchical;
    h.kp_pos_per_s2 *= p2;
    h.kd_pos_per_s *= p;
    h.kp_att_per_s2 *= a2;
    h.kd_att_per_s *= a;
    let geo = &mut g.geometric;
    geo.kp_n_per_m *= p2;
    geo.kv_n_s_per_m *= p;
    geo.kr_n_m_per_rad *= a2;
    geo.komega_n_m_s_per_rad *= a;
    let pa = &mut g.passivity;
    pa.sigma_p_per_s *= p;
    pa.dp_n_s_per_m *= p;
    pa.kp_n_per_m *= p2;
    pa.sigma_per_s *= a;
    pa.do_n_m_s_per_rad *= a;
    pa.ko_n_m_per_rad *= a2;
    g
}

fn estimator_config(s: &Settings, dt: f64) -> EstimatorConfig {
    EstimatorConfig {
        order: s.estimator_order,
        polynomial: s.estimator_polynomial.clone(),
        cutoff_rad_s: s.estimator_cutoff_rad_s,
        discretization: Discretization::Trapezoidal,
        sample_time_s: dt,
    }
}

fn blend(a: &WrenchEstimate, b: &WrenchEstimate, w: f64) -> WrenchEstimate {
    WrenchEstimate {
        force_ned: a.force_ned * (1.0 - w) + b.force_ned * w,
        torque_rpy: a.torque_rpy * (1.0 - w) + b.torque_rpy * w,
        torque_frd: a.torque_frd * (1.0 - w) + b.torque_frd * w,
        mass_kg: a.mass_kg * (1.0 - w) + b.mass_kg * w,
    }
}

/// Whether a shaped reference has reached `target` and stopped.
fn arrived(r: &Reference, target: &Vector3<f64>) -> bool {
    (r.position_ned - target).norm() < REF_ARRIVED_M && r.velocity_ned.norm() < REF_STOPPED_M_S
}

/// Whether an offboard setpoint asks a landed vehicle to take off: a
/// position more than `TAKEOFF_TRIGGER_M` above it, a climb or upward
/// acceleration, or any attitude setpoint (its thrust decides).
fn wants_to_climb(sp: &OffboardSetpoint, meas: &Measurement) -> bool {
    match sp {
        OffboardSetpoint::Local {
            position_ned,
            velocity_ned,
            acceleration_ned,
            ..
        } => {
            if let Some(p) = position_ned {
                p.z < meas.position_ned.z - TAKEOFF_TRIGGER_M
            } else if let Some(v) = velocity_ned {
                v.z < -TAKEOFF_TRIGGER_M_S
            } else {
                acceleration_ned.is_some_and(|a| a.z < -TAKEOFF_TRIGGER_M_S2)
            }
        }
        OffboardSetpoint::Attitude { .. } => true,
    }
}

fn yaw_setpoint(yaw_rad: Option<f64>, yaw_rate_rad_s: Option<f64>) -> YawSetpoint {
    match (yaw_rad, yaw_rate_rad_s) {
        (Some(y), _) => YawSetpoint::Angle(y),
        (None, Some(r)) => YawSetpoint::Rate(r),
        (None, None) => YawSetpoint::Hold,
    }
}

impl Autopilot {
    /// An autopilot on `airframe`, disarmed on the ground at `home` (the NED
    /// origin; the ground is at NED z = 0 and the vehicle's centre of mass
    /// rests `gear_height_m` above it), in Hold, with `params` applied.
    ///
    /// # Errors
    /// Invalid home, or parameters that give invalid gains or estimator settings.
    pub fn new(airframe: &Airframe, home: GeoPoint, params: &ParamStore) -> Result<Self, AutopilotError> {
        Self::with_plant(airframe, home, params, PlantConfig::default())
    }

    /// [`Self::new`] with plant options (step, sensor noise and its seed). The
    /// world's ground height is kept; effects and ceiling come from the parameters.
    ///
    /// # Errors
    /// As [`Self::new`]; also a step the estimator cannot run at.
    pub fn with_plant(
        airframe: &Airframe,
        home: GeoPoint,
        params: &ParamStore,
        plant: PlantConfig,
    ) -> Result<Self, AutopilotError> {
        if !home.is_valid() {
            return Err(AutopilotError::InvalidHome {
                lat_deg: home.lat_deg,
                lon_deg: home.lon_deg,
                alt_amsl_m: home.alt_amsl_m,
            });
        }
        let settings = Settings::from_store(params)?;
        // the nominal model (MDL_MASS) is set by `apply_params` below
        let vehicle = Vehicle::new(
            airframe,
            plant,
            settings.controller,
            control_gains(airframe, &settings),
            estimator_config(&settings, plant.dt_s),
        )
        .map_err(|e| match e {
            VehicleError::Gains(e) => AutopilotError::Gains(e),
            VehicleError::Estimator(e) => AutopilotError::Estimator(e),
        })?;
        let base_limits = ShaperLimits::for_airframe(airframe);
        let shaper = Shaper::new(base_limits)?;
        let n = airframe.rotor_count() as f64;
        let battery = Battery::new(
            settings.battery_cells,
            settings.battery_capacity_mah,
            settings.battery_min_fraction,
        );
        let mut ap = Self {
            airframe: airframe.clone(),
            vehicle,
            base_limits,
            shaper,
            shaper_live: false,
            settings,
            external: ExternalWrench::default(),
            fade: None,
            disk_area_m2: n * std::f64::consts::PI * airframe.rotor.radius_m.powi(2),
            acceleration_ned: Vector3::zeros(),
            origin: home,
            home,
            armed: false,
            armed_at_s: 0.0,
            took_off: false,
            landed: true,
            ground_since_s: None,
            landed_at_s: 0.0,
            nav: Nav::Hold {
                position_mode: false,
                target: None,
            },
            cruise_override: None,
            offboard: None,
            rate_target: None,
            battery,
            status: VecDeque::new(),
            last_fault: None,
        };
        ap.apply_params(params)?;
        Ok(ap)
    }

    /// Apply every parameter at once, in flight too: `CTRL_TYPE` (bumpless
    /// switch), the gain scales and `MDL_MASS` (gains recomputed, nominal
    /// model of controller and estimator changed), `EST_ORDER/POLY/CUTOFF`
    /// (estimator rebuilt; with `EST_COMP` on in flight the fed-back estimate
    /// cross-fades from the old estimate to the new one over `8 r / omega_c`
    /// seconds, 0.5 to 30 s), `EST_COMP`, the `SIM_*` wrench, mass and
    /// ground/ceiling effect, and the navigation values (altitudes, speeds,
    /// timeouts). Call it after every accepted parameter change.
    ///
    /// # Errors
    /// A combination the controller or estimator refuses; nothing is changed then.
    pub fn apply_params(&mut self, params: &ParamStore) -> Result<(), AutopilotError> {
        let s = Settings::from_store(params)?;
        let now = self.vehicle.plant().time_s();
        let nominal = NominalModel {
            mass_kg: s.model_mass_kg,
            inertia_kg_m2: self.airframe.inertia_kg_m2,
        };
        let nominal_changed = nominal != *self.vehicle.nominal();
        let gains = control_gains(&self.airframe, &s);
        gains.validate()?;
        let config = estimator_config(&s, self.vehicle.plant().dt_s());
        let rebuilt = if &config == self.vehicle.estimator().config() {
            if nominal_changed {
                // whether the estimator accepts the model, asked of a copy
                self.vehicle.estimator().clone().set_nominal(nominal)?;
            }
            None
        } else {
            Some(MomentumEstimator::new(config, nominal)?)
        };
        // Everything is valid: commit.
        self.vehicle.controller_mut().set_gains(gains)?;
        self.vehicle.switch_controller(s.controller);
        if let Some(e) = rebuilt {
            if s.feedback && !self.landed {
                let from = self.current_feedback(now);
                let duration_s = (8.0 * s.estimator_order as f64 / s.estimator_cutoff_rad_s).clamp(0.5, 30.0);
                self.fade = Some(EstimateFade {
                    from,
                    start_s: now,
                    duration_s,
                });
            }
            self.vehicle.replace_estimator(e);
        }
        if nominal_changed {
            self.vehicle.set_nominal(nominal)?;
        }
        let plant = self.vehicle.plant_mut();
        plant.set_true_mass(s.sim_mass_kg);
        let ground = plant.world().ground_z_ned;
        plant.set_world(World {
            ground_z_ned: ground,
            ceiling_z_ned: (s.ceiling_height_m > 0.0).then_some(ground - s.ceiling_height_m),
            ground_effect: s.ground_effect,
            ceiling_effect: s.ceiling_effect,
        });
        self.external = ExternalWrench {
            force_ned: s.force_ned,
            torque_frd: s.torque_frd,
        };
        self.battery
            .configure(s.battery_cells, s.battery_capacity_mah, s.battery_min_fraction);
        if s.cruise_m_s != self.settings.cruise_m_s {
            self.cruise_override = None;
        }
        self.settings = s;
        Ok(())
    }

    // ----- accessors ------------------------------------------------------------------------------

    /// Simulated time since boot [s].
    #[must_use]
    pub fn time_s(&self) -> f64 {
        self.vehicle.plant().time_s()
    }

    /// Step length [s] (the plant's, 1 ms by default).
    #[must_use]
    pub fn dt_s(&self) -> f64 {
        self.vehicle.plant().dt_s()
    }

    /// Armed.
    #[must_use]
    pub fn armed(&self) -> bool {
        self.armed
    }

    /// The mode as clients see it.
    #[must_use]
    pub fn mode(&self) -> FlightMode {
        match self.nav {
            Nav::Hold {
                position_mode: true, ..
            } => FlightMode::Position,
            Nav::Hold { .. } => FlightMode::Hold,
            Nav::Takeoff { .. } => FlightMode::Takeoff,
            Nav::Land { .. } => FlightMode::Land,
            Nav::Rtl { .. } => FlightMode::ReturnToLaunch,
            Nav::Offboard => FlightMode::Offboard,
        }
    }

    /// The landed state (never undefined): Takeoff while a takeoff runs,
    /// OnGround when landed, Landing while descending to land, else InAir.
    #[must_use]
    pub fn landed_state(&self) -> LandedState {
        let landing = matches!(
            self.nav,
            Nav::Land { .. }
                | Nav::Rtl {
                    phase: RtlPhase::Land,
                    ..
                }
        );
        if self.armed && matches!(self.nav, Nav::Takeoff { .. }) {
            LandedState::Takeoff
        } else if self.landed {
            LandedState::OnGround
        } else if self.armed && landing {
            LandedState::Landing
        } else {
            LandedState::InAir
        }
    }

    /// Home.
    #[must_use]
    pub fn home(&self) -> GeoPoint {
        self.home
    }

    /// The NED origin (where the vehicle booted).
    #[must_use]
    pub fn origin(&self) -> GeoPoint {
        self.origin
    }

    /// The control law flying.
    #[must_use]
    pub fn controller_kind(&self) -> ControllerKind {
        self.vehicle.controller().kind()
    }

    /// The plant (true state, contact, rotor speeds), read-only.
    #[must_use]
    pub fn plant(&self) -> &Plant {
        self.vehicle.plant()
    }

    /// The latest wrench estimate.
    #[must_use]
    pub fn estimate(&self) -> WrenchEstimate {
        self.vehicle.estimate()
    }

    /// The last simulation fault, if any (the vehicle was disarmed then).
    #[must_use]
    pub fn last_fault(&self) -> Option<SimFault> {
        self.last_fault
    }

    /// Status texts since the last call, oldest first (at most the latest 64).
    pub fn drain_status_texts(&mut self) -> Vec<StatusText> {
        self.status.drain(..).collect()
    }

    pub(super) fn announce(&mut self, severity: Severity, text: impl Into<String>) {
        if self.status.len() >= STATUS_QUEUE {
            self.status.pop_front();
        }
        let mut text = text.into();
        text.truncate(50);
        tracing::debug!(?severity, %text, "status");
        self.status.push_back(StatusText { severity, text });
    }

    /// Home in local NED [m].
    pub(super) fn home_ned(&self) -> Vector3<f64> {
        self.home.ned_from(&self.origin)
    }

    /// Where the vehicle is meant to be: the live reference, else the true position [m], NED.
    pub(super) fn current_position(&self) -> Vector3<f64> {
        if self.shaper_live {
            self.shaper.reference().position_ned
        } else {
            self.vehicle.plant().state().position_ned
        }
    }

    /// The cruise speed in force [m/s].
    pub(super) fn cruise_m_s(&self) -> f64 {
        self.cruise_override
            .unwrap_or(self.settings.cruise_m_s)
            .min(self.settings.xy_vel_max_m_s)
    }

    /// The largest collective thrust [N] (what offboard thrust 1.0 means).
    #[must_use]
    pub fn max_thrust_n(&self) -> f64 {
        match self.airframe.actuation {
            Actuation::Rotors => {
                let (_, w_max) = self.airframe.speed_sq_bounds();
                self.airframe.rotor_count() as f64 * self.airframe.rotor.c_t * w_max
            }
            Actuation::Ideal => {
                self.vehicle.controller().gains().limits.max_thrust_g * self.vehicle.nominal().mass_kg * GRAVITY
            }
        }
    }

    /// Whether an offboard setpoint arrived within `COM_OF_LOSS_T`.
    pub(super) fn offboard_fresh(&self) -> bool {
        let now = self.vehicle.plant().time_s();
        self.offboard
            .is_some_and(|(_, t)| now - t <= self.settings.offboard_loss_s + TIME_EPS)
    }

    /// Why arming would be refused now, if it would.
    pub(super) fn prearm_failure(&self) -> Option<&'static str> {
        if !self.landed {
            return Some("vehicle not landed");
        }
        if !self.vehicle.estimator().is_initialized() {
            return Some("estimator not initialised");
        }
        if !self.home.is_valid() {
            return Some("home position invalid");
        }
        match self.nav {
            Nav::Offboard if !self.offboard_fresh() => Some("no offboard signal"),
            Nav::Hold { .. } | Nav::Offboard => None,
            Nav::Takeoff { .. } | Nav::Land { .. } | Nav::Rtl { .. } => Some("flight mode not armable"),
        }
    }

    // ----- arming ---------------------------------------------------------------------------------

    pub(super) fn arm_now(&mut self) {
        self.armed = true;
        self.armed_at_s = self.vehicle.plant().time_s();
        self.took_off = !self.landed;
        self.announce(Severity::Info, "Armed by external command");
    }

    pub(super) fn disarm_now(&mut self, text: &str) {
        self.armed = false;
        self.nav = match self.nav {
            Nav::Hold { position_mode, .. } => Nav::Hold {
                position_mode,
                target: None,
            },
            _ => Nav::Hold {
                position_mode: false,
                target: None,
            },
        };
        self.vehicle.controller_mut().reset();
        self.shaper_live = false;
        self.rate_target = None;
        self.announce(Severity::Info, text);
    }

    // ----- mode entry -----------------------------------------------------------------------------

    pub(super) fn enter_hold(&mut self) {
        self.nav = Nav::Hold {
            position_mode: false,
            target: None,
        };
    }

    pub(super) fn enter_land(&mut self) {
        let p = self.current_position();
        self.nav = Nav::Land { xy: p.xy() };
        if !self.landed {
            self.announce(Severity::Info, "Landing at current position");
        }
    }

    pub(super) fn enter_rtl(&mut self) {
        let p = self.current_position();
        let home = self.home_ned();
        let z_return = p.z.min(home.z - self.settings.rtl_return_alt_m);
        self.nav = Nav::Rtl {
            phase: RtlPhase::Climb { xy: p.xy() },
            z_return,
        };
        if !self.landed {
            self.announce(
                Severity::Info,
                format!("Return to launch at {:.1} m above home", home.z - z_return),
            );
        }
    }

    // ----- the loop -------------------------------------------------------------------------------

    /// Advance one step of simulated time (1 ms by default): sense (estimator
    /// restarted while resting on the ground), landing detection, auto-disarm
    /// and offboard-loss supervision, guidance for the mode, act (controller,
    /// allocation, plant), battery. A plant fault (non-finite command or
    /// state) disarms with a STATUSTEXT and steps the plant with the rotors
    /// stopped, so time always advances.
    pub fn step(&mut self) {
        let dt = self.vehicle.plant().dt_s();
        let now = self.vehicle.plant().time_s();
        let on_ground = self.vehicle.plant().contact() == Contact::OnGround;
        if on_ground {
            // The ground's reaction is no external wrench worth estimating:
            // restart from every resting sample, estimate from liftoff on.
            self.vehicle.reset_estimator();
            self.fade = None;
        }
        let sensed = self.vehicle.sense();
        self.detect_landing(now, on_ground);
        self.supervise(now);
        let demand = self.guidance(&sensed.measurement, dt);
        if matches!(demand, Demand::Stop | Demand::Idle) {
            self.shaper_live = false;
        }
        let feedback = if self.settings.feedback {
            Some(self.feedback_estimate(&sensed.estimate, now))
        } else {
            None
        };
        if let Err(fault) = self.vehicle.act(&demand, feedback.as_ref(), &self.external) {
            self.on_fault(fault);
        }
        self.acceleration_ned = self.true_acceleration();
        self.battery
            .update(self.vehicle.plant().last_wrench().thrust_n, self.disk_area_m2, dt);
    }

    fn on_fault(&mut self, fault: SimFault) {
        self.last_fault = Some(fault);
        self.announce(Severity::Critical, format!("Simulation fault: {fault}"));
        if self.armed {
            self.disarm_now("Disarmed: simulation fault");
        }
        self.shaper_live = false;
        // the same step with the rotors stopped (resets the controller), to
        // keep time moving; if even this fails the state stays as it was
        let _ = self.vehicle.act(&Demand::Stop, None, &self.external);
    }

    /// `g e3 + (R (-T e3) + f_e) / m` with the true mass; zero on the ground.
    fn true_acceleration(&self) -> Vector3<f64> {
        if self.vehicle.plant().contact() == Contact::OnGround {
            return Vector3::zeros();
        }
        let plant = self.vehicle.plant();
        let s = plant.state();
        let thrust = s.attitude * Vector3::new(0.0, 0.0, -plant.last_wrench().thrust_n);
        Vector3::new(0.0, 0.0, GRAVITY) + (thrust + self.external.force_ned) / plant.true_mass_kg()
    }

    /// The estimate to feed back (cross-faded after an estimator rebuild).
    fn feedback_estimate(&mut self, estimate: &WrenchEstimate, now: f64) -> WrenchEstimate {
        match self.fade {
            Some(f) => {
                let w = ((now - f.start_s) / f.duration_s).clamp(0.0, 1.0);
                if w >= 1.0 {
                    self.fade = None;
                    *estimate
                } else {
                    blend(&f.from, estimate, w)
                }
            }
            None => *estimate,
        }
    }

    /// What is being fed back right now (for the start of a cross-fade).
    fn current_feedback(&self, now: f64) -> WrenchEstimate {
        let e = self.vehicle.estimate();
        match self.fade {
            Some(f) => blend(&f.from, &e, ((now - f.start_s) / f.duration_s).clamp(0.0, 1.0)),
            None if self.settings.feedback => e,
            None => WrenchEstimate {
                mass_kg: self.vehicle.nominal().mass_kg,
                ..WrenchEstimate::default()
            },
        }
    }

    /// Landing detector: ground contact for `LAND_DETECT_S`; liftoff at once.
    fn detect_landing(&mut self, now: f64, on_ground: bool) {
        if on_ground {
            self.ground_since_s.get_or_insert(now);
        } else {
            self.ground_since_s = None;
        }
        if self.landed && !on_ground {
            self.landed = false;
            if self.armed {
                self.took_off = true;
                self.announce(Severity::Info, "Takeoff detected");
            }
        } else if !self.landed && self.ground_since_s.is_some_and(|t| now - t >= LAND_DETECT_S - TIME_EPS) {
            self.landed = true;
            self.landed_at_s = now;
            if self.armed {
                self.announce(Severity::Info, "Landing detected");
            }
        }
    }

    /// Offboard loss and auto-disarm.
    fn supervise(&mut self, now: f64) {
        if self.nav == Nav::Offboard && !self.offboard_fresh() {
            match self.settings.offboard_loss_action {
                OffboardLossAction::Hold => {
                    self.enter_hold();
                    self.announce(Severity::Warning, "Offboard signal lost: switching to Hold");
                }
                OffboardLossAction::Return => {
                    self.announce(Severity::Warning, "Offboard signal lost: returning");
                    self.enter_rtl();
                }
                OffboardLossAction::Land => {
                    self.announce(Severity::Warning, "Offboard signal lost: landing");
                    self.enter_land();
                }
            }
        }
        if self.armed && self.landed {
            let s = &self.settings;
            if self.took_off {
                if s.disarm_land_s > 0.0
                    && !matches!(self.nav, Nav::Takeoff { .. })
                    && now - self.landed_at_s >= s.disarm_land_s - TIME_EPS
                {
                    self.disarm_now("Disarmed by landing");
                }
            } else if s.disarm_preflight_s > 0.0 && now - self.armed_at_s >= s.disarm_preflight_s - TIME_EPS {
                self.disarm_now("Disarmed by auto preflight disarming");
            }
        }
    }

    fn limits(&self, xy: f64, up: f64, down: f64) -> ShaperLimits {
        ShaperLimits {
            max_speed_xy_m_s: xy,
            max_climb_m_s: up,
            max_descent_m_s: down,
            ..self.base_limits
        }
    }

    /// The shaped reference towards `sp` with `limits` (restarted at the measurement when not live).
    fn shape(&mut self, meas: &Measurement, sp: Setpoint, limits: ShaperLimits, dt: f64) -> Reference {
        if *self.shaper.limits() != limits {
            // the limits come from validated parameters; on refusal the old ones stay
            let _ = self.shaper.set_limits(limits);
        }
        if !self.shaper_live {
            self.shaper.reset_to(meas);
            self.shaper_live = true;
        }
        self.shaper.update(&sp, dt)
    }

    /// Height of the centre of mass above its resting height [m].
    fn height_above_ground(&self, meas: &Measurement) -> f64 {
        self.vehicle.plant().world().ground_z_ned - self.airframe.gear_height_m - meas.position_ned.z
    }

    /// Descend to land at `xy`: MPC_Z_VEL_MAX_DN above MPC_LAND_ALT1, MPC_LAND_SPEED below.
    fn descend(&mut self, meas: &Measurement, xy: Vector2<f64>, dt: f64) -> Reference {
        let s = &self.settings;
        let speed = if self.height_above_ground(meas) > s.land_alt1_m {
            s.descent_m_s
        } else {
            s.land_speed_m_s
        };
        let target = Vector3::new(xy.x, xy.y, self.vehicle.plant().world().ground_z_ned + LAND_SINK_M);
        let limits = self.limits(self.cruise_m_s(), s.climb_m_s, speed);
        self.shape(
            meas,
            Setpoint {
                translation: TranslationSetpoint::Position(target),
                yaw: YawSetpoint::Hold,
            },
            limits,
            dt,
        )
    }

    fn go_to(
        &mut self,
        meas: &Measurement,
        target: Vector3<f64>,
        yaw: YawSetpoint,
        limits: ShaperLimits,
        dt: f64,
    ) -> Reference {
        self.shape(
            meas,
            Setpoint {
                translation: TranslationSetpoint::Position(target),
                yaw,
            },
            limits,
            dt,
        )
    }

    /// The demand of the active mode (may advance the mode: takeoff done, RTL phases).
    fn guidance(&mut self, meas: &Measurement, dt: f64) -> Demand {
        if !self.armed {
            return Demand::Stop;
        }
        let cruise = self.cruise_m_s();
        let (climb, descent) = (self.settings.climb_m_s, self.settings.descent_m_s);
        let normal = self.limits(cruise, climb, descent);
        match self.nav {
            Nav::Hold { target, .. } => {
                if self.landed {
                    return Demand::Idle;
                }
                let r = match target {
                    None => self.shape(
                        meas,
                        Setpoint {
                            translation: TranslationSetpoint::Hold,
                            yaw: YawSetpoint::Hold,
                        },
                        normal,
                        dt,
                    ),
                    Some(t) => {
                        let limits = self.limits(t.speed_m_s.unwrap_or(cruise), climb, descent);
                        let yaw = t.yaw_rad.map_or(YawSetpoint::Hold, YawSetpoint::Angle);
                        self.go_to(meas, t.position_ned, yaw, limits, dt)
                    }
                };
                Demand::Track(r)
            }
            Nav::Takeoff { target_ned, then } => {
                let limits = self.limits(cruise, self.settings.takeoff_speed_m_s, descent);
                let r = self.go_to(meas, target_ned, YawSetpoint::Hold, limits, dt);
                if arrived(&r, &target_ned) && (meas.position_ned.z - target_ned.z).abs() < TAKEOFF_ACCEPT_M {
                    self.nav = Nav::Hold {
                        position_mode: false,
                        target: Some(then.unwrap_or(HoldTarget {
                            position_ned: target_ned,
                            yaw_rad: None,
                            speed_m_s: None,
                        })),
                    };
                    self.announce(Severity::Info, "Takeoff complete, holding position");
                }
                Demand::Track(r)
            }
            Nav::Land { xy } => {
                if self.landed {
                    Demand::Idle
                } else {
                    Demand::Track(self.descend(meas, xy, dt))
                }
            }
            Nav::Rtl { phase, z_return } => {
                if self.landed {
                    return Demand::Idle;
                }
                Demand::Track(self.rtl(meas, phase, z_return, normal, dt))
            }
            Nav::Offboard => self.offboard_demand(meas, normal, dt),
        }
    }

    fn rtl(&mut self, meas: &Measurement, phase: RtlPhase, z_return: f64, normal: ShaperLimits, dt: f64) -> Reference {
        let home = self.home_ned();
        let z_descend = home.z - self.settings.rtl_descend_alt_m;
        let set_phase = |ap: &mut Self, phase: RtlPhase| ap.nav = Nav::Rtl { phase, z_return };
        match phase {
            RtlPhase::Climb { xy } => {
                let target = Vector3::new(xy.x, xy.y, z_return);
                let r = self.go_to(meas, target, YawSetpoint::Hold, normal, dt);
                if arrived(&r, &target) {
                    set_phase(self, RtlPhase::Return);
                }
                r
            }
            RtlPhase::Return => {
                let target = Vector3::new(home.x, home.y, z_return);
                let r = self.go_to(meas, target, YawSetpoint::Hold, normal, dt);
                let near = (meas.position_ned.xy() - home.xy()).norm() <= self.settings.acceptance_radius_m;
                if arrived(&r, &target) && near {
                    if z_return < z_descend - REF_ARRIVED_M {
                        set_phase(self, RtlPhase::Descend);
                    } else {
                        set_phase(self, RtlPhase::Land);
                        self.announce(Severity::Info, "RTL: landing at home");
                    }
                }
                r
            }
            RtlPhase::Descend => {
                let target = Vector3::new(home.x, home.y, z_descend);
                let r = self.go_to(meas, target, YawSetpoint::Hold, normal, dt);
                if arrived(&r, &target) {
                    set_phase(self, RtlPhase::Land);
                    self.announce(Severity::Info, "RTL: landing at home");
                }
                r
            }
            RtlPhase::Land => self.descend(meas, home.xy(), dt),
        }
    }

    fn offboard_demand(&mut self, meas: &Measurement, normal: ShaperLimits, dt: f64) -> Demand {
        let hold = Setpoint {
            translation: TranslationSetpoint::Hold,
            yaw: YawSetpoint::Hold,
        };
        let Some((sp, _)) = self.offboard else {
            return Demand::Track(self.shape(meas, hold, normal, dt));
        };
        if self.landed && !wants_to_climb(&sp, meas) {
            // PX4's takeoff handling: a landed vehicle idles until the setpoint asks it up
            return Demand::Idle;
        }
        match sp {
            OffboardSetpoint::Local {
                position_ned,
                velocity_ned,
                acceleration_ned,
                yaw_rad,
                yaw_rate_rad_s,
            } => {
                let yaw = yaw_setpoint(yaw_rad, yaw_rate_rad_s);
                if let Some(p) = position_ned {
                    Demand::Track(self.go_to(meas, p, yaw, normal, dt))
                } else if let Some(v) = velocity_ned {
                    let limits = ShaperLimits {
                        max_speed_xy_m_s: self.settings.xy_vel_max_m_s,
                        ..normal
                    };
                    let sp = Setpoint {
                        translation: TranslationSetpoint::Velocity(v),
                        yaw,
                    };
                    Demand::Track(self.shape(meas, sp, limits, dt))
                } else if let Some(a) = acceleration_ned {
                    // Pure acceleration: feedforward from the measured state (drifts, as in PX4).
                    self.shaper_live = false;
                    let heading = euler_zyx(&meas.attitude).z;
                    Demand::Track(Reference {
                        position_ned: meas.position_ned,
                        velocity_ned: meas.velocity_ned,
                        acceleration_ned: a,
                        yaw_rad: yaw_rad.unwrap_or(heading),
                        yaw_rate_rad_s: if yaw_rad.is_some() {
                            0.0
                        } else {
                            yaw_rate_rad_s.unwrap_or(0.0)
                        },
                        ..Reference::default()
                    })
                } else {
                    Demand::Track(self.shape(meas, hold, normal, dt))
                }
            }
            OffboardSetpoint::Attitude {
                attitude,
                rate_frd,
                thrust_normalised,
            } => {
                self.shaper_live = false;
                let rate = rate_frd.unwrap_or_else(Vector3::zeros);
                let q = match attitude {
                    Some(q) => {
                        self.rate_target = None;
                        q
                    }
                    None => {
                        let q0 = self.rate_target.unwrap_or(meas.attitude);
                        let q1 = q0 * UnitQuaternion::from_scaled_axis(rate * dt);
                        self.rate_target = Some(q1);
                        q1
                    }
                };
                Demand::Attitude {
                    attitude: q,
                    rate_frd: rate,
                    thrust_n: thrust_normalised.clamp(0.0, 1.0) * self.max_thrust_n(),
                }
            }
        }
    }

    /// A snapshot for telemetry (SI units, NED/FRD).
    #[must_use]
    pub fn telemetry(&self) -> Telemetry {
        let plant = self.vehicle.plant();
        let s = plant.state();
        let max_thrust = self.max_thrust_n();
        Telemetry {
            time_s: plant.time_s(),
            armed: self.armed,
            mode: self.mode(),
            landed: self.landed_state(),
            position_ned: s.position_ned,
            velocity_ned: s.velocity_ned,
            acceleration_ned: self.acceleration_ned,
            attitude: s.attitude,
            rate_frd: s.rate_frd,
            global: self.origin.offset(&s.position_ned),
            origin: self.origin,
            home: self.home,
            home_ned: self.home_ned(),
            battery_voltage_v: self.battery.voltage_v(),
            battery_current_a: self.battery.current_a(),
            battery_consumed_mah: self.battery.consumed_mah(),
            battery_remaining: self.battery.remaining(),
            throttle: if max_thrust > 0.0 {
                (plant.last_wrench().thrust_n / max_thrust).clamp(0.0, 1.0)
            } else {
                0.0
            },
            estimate: self.vehicle.estimate(),
            injected_force_ned: self.external.force_ned,
            injected_torque_frd: self.external.torque_frd,
            true_mass_kg: plant.true_mass_kg(),
            prearm_ok: self.prearm_failure().is_none(),
        }
    }
}
