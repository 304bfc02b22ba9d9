//! The autopilot as clients see it: arming, flight modes, takeoff, landing,
//! return, hold, position, offboard (and later missions), failsafes. Pure and
//! stepped by simulated time: [`Autopilot`] owns a lockstep
//! [`crate::vehicle::Vehicle`] (plant, estimator, controller, allocation),
//! turns the mode and its setpoints into its demand (a reference, an attitude
//! setpoint, idle or stopped rotors) between the vehicle's sense and act
//! phases, and publishes [`Telemetry`]. The MAVLink layer
//! talks to it only through [`AutopilotCommand`], [`CommandOutcome`],
//! [`Telemetry`], [`StatusText`] and the parameter store.
//!
//! # Behaviour (PX4's, doc `mavlink-compat.md` sections 3, 5, 8, 12)
//! * Boot: disarmed, on the ground at home (the NED origin; the ground is at
//!   NED z = 0 and the centre of mass rests `gear_height_m` above it), Hold.
//! * Arm: prearm checks (landed, estimator initialised, home valid, mode
//!   armable); `force` skips them. Disarm refused in the air unless forced.
//!   Auto-disarm `COM_DISARM_LAND` s after a landing, `COM_DISARM_PRFLT` s
//!   after arming without a takeoff. Disarming selects Hold.
//! * Armed on the ground in Hold, Position, Land or RTL the rotors idle.
//! * Takeoff climbs at `MPC_TKO_SPEED` to home + `MIS_TAKEOFF_ALT` (or higher
//!   AMSL target), then Hold there. Land descends at `MPC_Z_VEL_MAX_DN` above
//!   `MPC_LAND_ALT1` and `MPC_LAND_SPEED` below; RTL climbs to
//!   `RTL_RETURN_ALT`, returns at the cruise speed, descends to
//!   `RTL_DESCEND_ALT`, lands. Reposition is Hold with a target.
//! * Offboard: accepted with a setpoint younger than `COM_OF_LOSS_T`; left
//!   for `COM_OBL_RC_ACT`'s action (Hold by default) when they stop. Landed,
//!   the rotors idle until a setpoint asks to climb (a position 0.2 m above,
//!   a climb rate above 0.3 m/s, an upward acceleration, or any attitude
//!   setpoint), PX4's takeoff trigger: ground effect never hops it off.
//! * Landing detector: ground contact for 0.25 s; liftoff at once.
//! * References come from the jerk-limited shaper ([`crate::control::shaper`])
//!   with the mode's speed limits; offboard attitude and rates go to
//!   [`crate::control::Controller::update_attitude`].
//!
//! The estimator restarts on every step the vehicle rests on the ground (the
//! ground's reaction is not a disturbance to learn) and estimates from liftoff on.

mod battery;
mod commands;
mod pilot;
mod settings;

pub use pilot::{Autopilot, AutopilotError};

use nalgebra::{UnitQuaternion, Vector3};
use serde::Serialize;

use crate::geo::GeoPoint;
use crate::signals::WrenchEstimate;

/// Flight modes, as PX4 names them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum FlightMode {
    /// POSCTL: hold position, move with (offboard-free) velocity input; here: hold.
    Position,
    /// AUTO.LOITER (Hold): hold the current position; PX4's idle mode.
    Hold,
    /// AUTO.TAKEOFF: climb to the takeoff altitude, then Hold.
    Takeoff,
    /// AUTO.LAND: descend and land where it is, then disarm.
    Land,
    /// AUTO.RTL: climb to RTL_RETURN_ALT, fly home, land.
    ReturnToLaunch,
    /// OFFBOARD: follow the external setpoint stream.
    Offboard,
    /// AUTO.MISSION (filled by a later issue).
    Mission,
}

/// What the vehicle reports as its landed state (MAV_LANDED_STATE).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum LandedState {
    /// On the ground.
    OnGround,
    /// Flying.
    InAir,
    /// Taking off.
    Takeoff,
    /// Landing.
    Landing,
}

/// An offboard setpoint (SET_POSITION_TARGET_* / SET_ATTITUDE_TARGET, already in NED/FRD SI units).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum OffboardSetpoint {
    /// Position / velocity / acceleration targets in local NED; `None` = ignored by the mask.
    Local {
        /// Position [m], NED.
        position_ned: Option<Vector3<f64>>,
        /// Velocity [m/s], NED.
        velocity_ned: Option<Vector3<f64>>,
        /// Acceleration [m/s^2], NED.
        acceleration_ned: Option<Vector3<f64>>,
        /// Yaw [rad].
        yaw_rad: Option<f64>,
        /// Yaw rate [rad/s].
        yaw_rate_rad_s: Option<f64>,
    },
    /// Attitude (or body rates) and normalised thrust.
    Attitude {
        /// Attitude, FRD to NED; `None` = rates only.
        attitude: Option<UnitQuaternion<f64>>,
        /// Body rates [rad/s], FRD; `None` = ignored.
        rate_frd: Option<Vector3<f64>>,
        /// Collective thrust, 0..1 of the maximum.
        thrust_normalised: f64,
    },
}

/// A command to the autopilot. NaN from MAVLink is mapped to `None` by the link.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AutopilotCommand {
    /// Arm (prearm checks unless forced).
    Arm {
        /// MAV_CMD_COMPONENT_ARM_DISARM p2 = 21196.
        force: bool,
    },
    /// Disarm (refused in flight unless forced).
    Disarm {
        /// MAV_CMD_COMPONENT_ARM_DISARM p2 = 21196.
        force: bool,
    },
    /// Take off to this altitude AMSL [m], `None` = home + MIS_TAKEOFF_ALT (PX4 raises lower values to that).
    Takeoff {
        /// Target altitude AMSL [m].
        altitude_amsl_m: Option<f64>,
    },
    /// Land where it is.
    Land,
    /// Return to launch.
    ReturnToLaunch,
    /// Switch mode.
    SetMode(FlightMode),
    /// Fly to a point and hold there (DO_REPOSITION): `None` parts keep the current value.
    Reposition {
        /// Latitude [deg].
        lat_deg: Option<f64>,
        /// Longitude [deg].
        lon_deg: Option<f64>,
        /// Altitude AMSL [m].
        alt_amsl_m: Option<f64>,
        /// Yaw [rad].
        yaw_rad: Option<f64>,
        /// Ground speed [m/s].
        speed_m_s: Option<f64>,
    },
    /// Change the cruise speed [m/s] (DO_CHANGE_SPEED).
    ChangeSpeed {
        /// Ground speed [m/s].
        speed_m_s: f64,
    },
    /// Set home here (`None`) or at a point.
    SetHome(Option<GeoPoint>),
    /// A new offboard setpoint.
    Offboard(OffboardSetpoint),
}

/// The answer to a command (mapped to MAV_RESULT by the link).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CommandOutcome {
    /// Done or started.
    Accepted,
    /// Not now (PX4's TEMPORARILY_REJECTED), with a reason for STATUSTEXT.
    TemporarilyRejected(&'static str),
    /// Never in this state (DENIED), with a reason.
    Denied(&'static str),
    /// Failed, with a reason.
    Failed(&'static str),
}

/// STATUSTEXT severity (MAV_SEVERITY).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum Severity {
    /// 0
    Emergency,
    /// 2
    Critical,
    /// 3
    Error,
    /// 4
    Warning,
    /// 5
    Notice,
    /// 6
    Info,
}

/// An event to announce as STATUSTEXT.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct StatusText {
    /// Severity.
    pub severity: Severity,
    /// Text (at most 50 characters fit one STATUSTEXT).
    pub text: String,
}

/// A snapshot of everything telemetry needs, in SI units and NED/FRD.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Telemetry {
    /// Simulated time since boot [s].
    pub time_s: f64,
    /// Armed.
    pub armed: bool,
    /// Mode.
    pub mode: FlightMode,
    /// Landed state.
    pub landed: LandedState,
    /// Position [m], NED from home's origin.
    pub position_ned: Vector3<f64>,
    /// Velocity [m/s], NED.
    pub velocity_ned: Vector3<f64>,
    /// Acceleration [m/s^2], NED (for VFR_HUD climb etc.).
    pub acceleration_ned: Vector3<f64>,
    /// Attitude, FRD to NED.
    pub attitude: UnitQuaternion<f64>,
    /// Body rates [rad/s], FRD.
    pub rate_frd: Vector3<f64>,
    /// Global position.
    pub global: GeoPoint,
    /// The NED origin (where the vehicle booted).
    pub origin: GeoPoint,
    /// Home.
    pub home: GeoPoint,
    /// Home in local NED [m].
    pub home_ned: Vector3<f64>,
    /// Battery voltage [V].
    pub battery_voltage_v: f64,
    /// Battery current [A].
    pub battery_current_a: f64,
    /// Charge used [mAh].
    pub battery_consumed_mah: f64,
    /// Remaining charge, 0..1.
    pub battery_remaining: f64,
    /// Normalised collective thrust 0..1 (VFR_HUD throttle).
    pub throttle: f64,
    /// The wrench estimate (force NED, torque FRD, real mass).
    pub estimate: WrenchEstimate,
    /// The injected truth, for tools that compare.
    pub injected_force_ned: Vector3<f64>,
    /// Injected torque [N m], FRD.
    pub injected_torque_frd: Vector3<f64>,
    /// True mass [kg].
    pub true_mass_kg: f64,
    /// Prearm checks pass.
    pub prearm_ok: bool,
}
