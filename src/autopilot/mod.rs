//! The flight stack: what runs on the vehicle. It sees only what a real
//! autopilot sees — [`SensorReadings`] (the navigation solution with its
//! noise and acceleration, rotor speeds from the ESCs, the battery monitor,
//! the GNSS fix) and what it commanded itself — and answers with an
//! [`ActuatorCommand`] each step. It never imports the simulated world
//! ([`crate::sim`]), its faults or the `SIM_*` parameters (CI greps for it).
//! Pure and stepped by simulated time.
//!
//! | file | job |
//! |---|---|
//! | `stack` | [`Autopilot`]: the state, parameters, and one step in order (sense, detect, supervise, guide, act) |
//! | `command` | the commands a client gives ([`AutopilotCommand`]) and the answers ([`CommandOutcome`]) |
//! | `commander` | commands: the `Commander` (arming state, arming, disarm, auto-disarm timers, reboot and failure-injection gates) and the wiring of each command (the mode state machine, home) |
//! | `navigator/` | guidance per mode family: `auto` (hold, takeoff, land, return), `offboard` (setpoints and their frames), `mission` (the stored mission flown as paths), `manual` (sticks and the manual modes), `blind` (the descent without a position), `orbit` (circling a centre) |
//! | `mission` | the mission as the commander sees it: start, set current, what a new upload does, MISSION_CURRENT's state |
//! | `failsafe` | supervision: the `Failsafe` (data link, battery level, geofence breach, clamp notice, client clock) and the one runner's choice; offboard, data-link, manual-control loss, battery, geofence, auto-disarm wired through it; which clock the timers that wait for a client run on |
//! | `prearm` | the prearm checks for any mode, in PX4's order: the first failure arming is refused with, and the health and arming report (all of them, every mode at once) |
//! | `health` | the health and arming report's types: the failing checks, the modes each blocks, what each concerns |
//! | `geofence` | the stored fence's zones and PX4's distance limits, as pure geometry |
//! | `fence_avoidance` | Return's way round the fence's zones: grown by a margin, a visibility graph, its shortest path (PX4's geofence avoidance planner) |
//! | `rotor_monitor` | dead and degraded rotors from commanded versus ESC-reported speeds |
//! | `land_detector` | landed or flying, from the measurements and the commanded thrust |
//! | `estimate` | the wrench estimate fed back: held on the ground, cross-faded after a rebuild |
//! | `control_loop` | estimator update, control law, allocation (around a lost rotor; relaxed hover for a quad): the loop every pilot shares |
//! | `navigation` | the navigation solution flown on (`RP_NAV_SRC`): the readings' own, or the navigation filter fed by the raw sensors |
//! | `position_checks` | whether the horizontal solution may be flown on (PX4's `COM_POS_FS_EPH`, `COM_VEL_FS_EVH` with their hysteresis), and what each mode needs of it |
//! | `wind` | the wind estimate reported (WIND_COV): the estimated force through the nominal drag model, filtered |
//! | `battery` | the battery monitor: charge used and remaining from voltage and current |
//! | `telemetry` | the snapshot clients are told |
//! | `settings` | the parameters as typed values, the failsafe actions among them |
//! | `status` | status texts: severity, the announcement queue, the one 50-byte STATUSTEXT cut and split |
//! | `error` | why an autopilot could not be built or parameters applied |
//!
//! # Behaviour (PX4's, `docs/mavlink.md` sections 3, 5, 8, 12)
//! * Boot: disarmed, on the ground at home (the NED origin), Hold.
//! * Arm: prearm checks (landed, estimator initialised, home valid, mode
//!   armable); `force` skips them. Disarm refused in the air unless forced.
//!   Auto-disarm `COM_DISARM_LAND` s after a landing, `COM_DISARM_PRFLT` s
//!   after arming without a takeoff. Disarming selects Hold.
//! * Armed on the ground in Hold, Position, Land or RTL the rotors idle.
//! * Takeoff climbs to home + `MIS_TAKEOFF_ALT` (or higher AMSL target) at
//!   `MPC_TKO_SPEED` below `MPC_LAND_ALT1` above home and `MPC_Z_V_AUTO_UP`
//!   above (`Settings::takeoff_climb_m_s`), then Hold there. The other
//!   automatic climbs and descents (Hold's reposition, RTL, mission legs) are
//!   at `MPC_Z_V_AUTO_UP`/`_DN`, each at most `MPC_Z_VEL_MAX_UP`/`_DN`.
//!   Land descends at `MPC_Z_VEL_MAX_DN` above `MPC_LAND_ALT1` and
//!   `MPC_LAND_SPEED` below; RTL climbs to
//!   `RTL_RETURN_ALT`, returns at the cruise speed (round the geofence's
//!   zones, `fence_avoidance`), descends to `RTL_DESCEND_ALT`, lands.
//!   Reposition is Hold with a target.
//! * Orbit (DO_ORBIT, `navigator/orbit.rs`): flies to the circle, then
//!   round it at the commanded radius, speed and heading behaviour; not armable.
//! * Follow target (`navigator/follow.rs`): FOLLOW_TARGET fixes kept in any
//!   mode; AUTO.FOLLOW_TARGET flies behind (`FLW_TGT_FA`) the target at
//!   `FLW_TGT_DST` and `FLW_TGT_HT`, holding while no fix is younger than
//!   3 s; not armable.
//! * Offboard: accepted with a setpoint younger than `COM_OF_LOSS_T`; left
//!   for `COM_OBL_RC_ACT`'s action (Hold by default) when they stop. Landed,
//!   the rotors idle until a setpoint asks to climb (a position 0.2 m above,
//!   a climb rate above 0.3 m/s, an upward acceleration, or any attitude
//!   setpoint), PX4's takeoff trigger: ground effect never hops it off.
//!   Relative and body frames are resolved against the state at the instant
//!   a setpoint arrives.
//! * Land detector (PX4's, reduced): still (vertical speed, horizontal speed
//!   and tilt rate low) at the height it rests at is ground contact; ground
//!   contact with low commanded thrust for 0.25 s is landed; 0.05 s without
//!   either (off the ground, or trying to fly) is a takeoff. On ground
//!   contact a mode that is not climbing idles the rotors (PX4 cuts the
//!   thrust the same way).
//! * Manual control (`navigator/manual`): MANUAL_CONTROL sticks, kept with
//!   their arrival time. Position, Altitude, Stabilized, Acro and Manual are
//!   refused without fresh sticks; arming there needs the throttle low (at
//!   most centred where it is a climb rate). Sticks older than
//!   `COM_RC_LOSS_T` in a manual mode: "Manual control lost", then
//!   `NAV_RCL_ACT` (Return by default); not in the automatic modes.
//! * Position loss (`navigator/blind`, `position_checks`): a mode that
//!   steers by position descends without it (PX4's Descend, AUTO.LAND in
//!   the heartbeat), Position falls back to Altitude; the position back
//!   before touchdown gives Hold (Position). On the ideal solution the
//!   position is lost with the GNSS fix; on the filter when the filter's
//!   own accuracy says so (it dead-reckons through a short GNSS loss).
//! * References come from the jerk-limited shaper ([`crate::control::shaper`])
//!   with the mode's speed limits; offboard attitude and rates go to
//!   [`crate::control::Controller::update_attitude`].
//!
//! The estimator restarts on every step the land detector says landed or in
//! ground contact (the ground's reaction is not a disturbance to learn) and
//! estimates from liftoff on.

/// What guidance knows at the instant of the measurement `$m`
/// ([`navigator::Situation`]), borrowing only the autopilot's settings, so
/// the navigator and the announcements stay free to change.
macro_rules! situation {
    ($ap:expr, $m:expr) => {
        crate::autopilot::navigator::Situation {
            meas: $m,
            settings: &$ap.settings,
            home_ned: $ap.home_ned(),
            rest_z: $ap.land.rest_z($m),
            resting: $ap.land.landed() || $ap.land.ground_contact(),
            landed: $ap.land.landed(),
            dt: $ap.dt_s(),
            clock: $ap.failsafe.clock(),
            max_thrust_n: $ap.max_thrust_n(),
            origin: &$ap.origin,
            home: &$ap.home,
            mission: $ap.plans.get(crate::mission::MissionType::Mission).items(),
            rally: $ap.plans.get(crate::mission::MissionType::Rally).items(),
            fence: $ap.plans.get(crate::mission::MissionType::Fence).items(),
        }
    };
}

mod battery;
mod command;
mod commander;
mod control_loop;
mod error;
mod estimate;
mod failsafe;
mod fence_avoidance;
mod geofence;
mod health;
mod land_detector;
mod mission;
mod navigation;
mod navigator;
mod position_checks;
mod prearm;
mod rotor_monitor;
mod settings;
mod stack;
mod status;
mod telemetry;
mod vibration;
mod wind;

pub use battery::BatteryWarning;
pub use command::{AutopilotCommand, CommandOutcome, PowerAction};
pub use control_loop::RotorAllocation;
pub use control_loop::{ControlLoop, ControlLoopError, ControlOutput, Demand};
pub use error::AutopilotError;
pub use failsafe::{ClientClock, ClientTimer, FAILSAFE_ACTIONS, FAILSAFE_CAUSES, PendingTimer};
pub use health::{CHECK_TEXTS, FailedCheck, HealthComponent, HealthReport, ModeSet};
pub use navigation::{FilterNavigation, NavSource, nav_config};
pub use navigator::ItemDone;
pub use navigator::{AltitudeReference, AttitudeTarget, GlobalTarget, OffboardSetpoint, RelativeFrame, Targets};
pub use navigator::{ManualControl, OrbitYaw, TARGET_STALE_S, TargetFix};
pub use rotor_monitor::{FAILED_SPEED_RATIO, RotorEvent, RotorMonitor, RotorStatus};
pub use stack::{Autopilot, FailsafeInForce};
pub use status::{STATUS_TEXT_LEN, Severity, StatusText, cut_status_text, status_text_lines};
pub use telemetry::{
    InnovationRatios, LandedState, MissionState, MissionStatus, NavVariances, NavigationReport, OrbitStatus,
    RotorOutputs, SolutionStatus, Telemetry, VehicleType,
};
pub use vibration::ImuVibration;

use serde::Serialize;

/// Flight modes, as PX4 names them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, serde::Deserialize)]
pub enum FlightMode {
    /// POSCTL: sticks give horizontal velocity (MPC_VEL_MANUAL), climb rate
    /// and yaw rate; centred sticks hold the position. Needs manual control.
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
    /// AUTO.MISSION: fly the stored mission.
    Mission,
    /// ALTCTL: sticks give tilt (MPC_MAN_TILT_MAX), climb rate and yaw rate;
    /// centred throttle holds the altitude. Needs manual control.
    Altitude,
    /// STABILIZED: sticks give tilt and yaw rate, throttle the collective thrust.
    Stabilized,
    /// ACRO: sticks give body rates (MC_ACRO_*_MAX), throttle the thrust.
    Acro,
    /// MANUAL: on a multicopter flown as Stabilized (PX4).
    Manual,
    /// POSCTL.ORBIT: circle a centre (MAV_CMD_DO_ORBIT), as PX4's Orbit task.
    Orbit,
    /// AUTO.FOLLOW_TARGET: fly at `FLW_TGT_DST`, `FLW_TGT_HT` and
    /// `FLW_TGT_FA` from a target a client reports (FOLLOW_TARGET), as PX4's
    /// follow-target task.
    FollowTarget,
    /// PX4's Descend (shown as AUTO.LAND): land without a position estimate —
    /// level, no horizontal control, sinking at MPC_LAND_SPEED (GPS loss).
    Descend,
}

impl FlightMode {
    /// Every mode, in declaration order.
    pub const ALL: [Self; 14] = [
        Self::Position,
        Self::Hold,
        Self::Takeoff,
        Self::Land,
        Self::ReturnToLaunch,
        Self::Offboard,
        Self::Mission,
        Self::Altitude,
        Self::Stabilized,
        Self::Acro,
        Self::Manual,
        Self::Orbit,
        Self::FollowTarget,
        Self::Descend,
    ];

    /// The mode's place in [`FlightMode::ALL`].
    #[must_use]
    pub fn index(self) -> usize {
        self as usize
    }

    /// PX4's `vehicle_status.nav_state` of the mode (`NAVIGATION_STATE_*`).
    #[must_use]
    pub fn nav_state(self) -> u8 {
        match self {
            Self::Manual => 0,
            Self::Altitude => 1,
            Self::Position => 2,
            Self::Mission => 3,
            Self::Hold => 4,
            Self::ReturnToLaunch => 5,
            Self::Acro => 10,
            Self::Descend => 12,
            Self::Offboard => 14,
            Self::Stabilized => 15,
            Self::Takeoff => 17,
            Self::Land => 18,
            Self::FollowTarget => 19,
            Self::Orbit => 21,
        }
    }
}

/// Time comparisons of the flight stack tolerate this much rounding [s]
/// (simulated time is a step count times the step).
const TIME_EPS: f64 = 1e-9;

#[cfg(test)]
mod tests {
    use super::FlightMode;

    #[test]
    fn nav_states_are_px4_numbers() {
        let px4 = [
            (FlightMode::Hold, 4),
            (FlightMode::Takeoff, 17),
            (FlightMode::Land, 18),
            (FlightMode::Offboard, 14),
            (FlightMode::Mission, 3),
        ];
        for (mode, n) in px4 {
            assert_eq!(mode.nav_state(), n, "{mode:?}");
        }
    }
}
