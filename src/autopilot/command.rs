//! The commands a client gives the flight stack ([`AutopilotCommand`],
//! mapped from MAVLink by the link, NaN as `None`) and the answer to each
//! ([`CommandOutcome`], mapped to MAV_RESULT by the link).

use super::FlightMode;
use super::navigator::{ManualControl, OffboardSetpoint, OrbitYaw, TargetFix};
use crate::geo::GeoPoint;

/// What MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN asks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum PowerAction {
    /// Restart the vehicle (the simulation restarts on the ground at home).
    Reboot,
    /// Stop (PX4 SITL exits).
    Shutdown,
}

/// A command to the autopilot. NaN from MAVLink is mapped to `None` by the link.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
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
    /// Start the mission (MAV_CMD_MISSION_START, DO_SET_MODE AUTO.MISSION
    /// goes through `SetMode`): arm-free start of AUTO.MISSION, from `first`
    /// when given (p1), else where it stands.
    StartMission {
        /// The item to start from (MAVLink seq).
        first: Option<u16>,
    },
    /// Make item `seq` the current one (MISSION_SET_CURRENT, DO_SET_MISSION_CURRENT).
    SetMissionCurrent {
        /// MAVLink seq.
        seq: u16,
    },
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
    /// DO_REPOSITION without its change-mode flag (param2 = 0): PX4's
    /// commander answers UNSUPPORTED, but its navigator still moves the
    /// target of a Hold in force (`navigator_main.cpp`); in any other mode
    /// nothing happens. `None` parts keep the current value.
    RepositionInHold {
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
    /// Circle a centre, switching to Orbit (DO_ORBIT): `None` parts keep the
    /// current value (the centre needs both latitude and longitude).
    Orbit {
        /// Signed radius [m]: its sign is the direction, positive clockwise seen from above.
        radius_m: Option<f64>,
        /// Tangential speed [m/s].
        velocity_m_s: Option<f64>,
        /// Where the nose points.
        yaw: Option<OrbitYaw>,
        /// Centre latitude [deg].
        lat_deg: Option<f64>,
        /// Centre longitude [deg].
        lon_deg: Option<f64>,
        /// Altitude AMSL [m].
        alt_amsl_m: Option<f64>,
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
    /// Where the target of follow-me is (FOLLOW_TARGET), kept with its arrival time.
    FollowTarget(TargetFix),
    /// The pilot's sticks (MANUAL_CONTROL), kept with their arrival time.
    ManualControl(ManualControl),
    /// Reboot or shut down: accepted only disarmed; the runtime carries it out.
    Power(PowerAction),
    /// MAV_CMD_RUN_PREARM_CHECKS: run the arming checks now and say the
    /// first that fails ("Preflight Fail: ..."); always accepted (PX4).
    RunPrearmChecks,
    /// MAV_CMD_INJECT_FAILURE, PX4's numbers: accepted only with
    /// `SYS_FAILURE_EN`; the world carries it out.
    InjectFailure {
        /// FAILURE_UNIT.
        unit: u8,
        /// FAILURE_TYPE.
        kind: u8,
        /// Instance, from 1; 0 = all.
        instance: u8,
    },
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
    /// Not supported (UNSUPPORTED).
    Unsupported,
    /// Failed, with a reason.
    Failed(&'static str),
}
