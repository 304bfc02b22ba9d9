//! Conversions at the MAVLink edge: PX4 `custom_mode`, MAV_RESULT, landed
//! state, severities, and SI to MAVLink units (degE7, cm/s, cdeg, mm).
//! Everything inside rotorpilot is SI, NED/FRD and `f64`; the wire types appear
//! only here and in the message builders.

use crate::autopilot::{CommandOutcome, FlightMode};
use mavlink::dialects::common::{AVAILABLE_MODES_DATA, MavModeProperty, MavStandardMode};

/// PX4 main modes (`px4_custom_mode.h`).
pub mod main_mode {
    /// MANUAL.
    pub const MANUAL: u8 = 1;
    /// ALTCTL.
    pub const ALTCTL: u8 = 2;
    /// POSCTL.
    pub const POSCTL: u8 = 3;
    /// AUTO (sub-mode says which).
    pub const AUTO: u8 = 4;
    /// ACRO.
    pub const ACRO: u8 = 5;
    /// OFFBOARD.
    pub const OFFBOARD: u8 = 6;
    /// STABILIZED.
    pub const STABILIZED: u8 = 7;
}

/// PX4 POSCTL sub-modes.
pub mod posctl_sub {
    /// POSCTL.ORBIT.
    pub const ORBIT: u8 = 1;
}

/// PX4 AUTO sub-modes.
pub mod auto_sub {
    /// AUTO.READY.
    pub const READY: u8 = 1;
    /// AUTO.TAKEOFF.
    pub const TAKEOFF: u8 = 2;
    /// AUTO.LOITER (Hold).
    pub const LOITER: u8 = 3;
    /// AUTO.MISSION.
    pub const MISSION: u8 = 4;
    /// AUTO.RTL.
    pub const RTL: u8 = 5;
    /// AUTO.LAND.
    pub const LAND: u8 = 6;
    /// AUTO.FOLLOW_TARGET.
    pub const FOLLOW_TARGET: u8 = 8;
}

/// PX4 (main, sub) of a flight mode.
#[must_use]
pub fn px4_mode(mode: FlightMode) -> (u8, u8) {
    match mode {
        FlightMode::Position => (main_mode::POSCTL, 0),
        FlightMode::Orbit => (main_mode::POSCTL, posctl_sub::ORBIT),
        FlightMode::Hold => (main_mode::AUTO, auto_sub::LOITER),
        FlightMode::Takeoff => (main_mode::AUTO, auto_sub::TAKEOFF),
        FlightMode::Land => (main_mode::AUTO, auto_sub::LAND),
        FlightMode::ReturnToLaunch => (main_mode::AUTO, auto_sub::RTL),
        FlightMode::Offboard => (main_mode::OFFBOARD, 0),
        FlightMode::Mission => (main_mode::AUTO, auto_sub::MISSION),
        FlightMode::FollowTarget => (main_mode::AUTO, auto_sub::FOLLOW_TARGET),
        FlightMode::Altitude => (main_mode::ALTCTL, 0),
        FlightMode::Stabilized => (main_mode::STABILIZED, 0),
        FlightMode::Acro => (main_mode::ACRO, 0),
        FlightMode::Manual => (main_mode::MANUAL, 0),
        // PX4 shows its Descend failsafe as AUTO.LAND (`get_px4_custom_mode`)
        FlightMode::Descend => (main_mode::AUTO, auto_sub::LAND),
    }
}

/// HEARTBEAT `custom_mode`: main << 16 | sub << 24 (bits 0..15 zero).
#[must_use]
pub fn custom_mode(mode: FlightMode) -> u32 {
    let (main, sub) = px4_mode(mode);
    (u32::from(main) << 16) | (u32::from(sub) << 24)
}

/// MAV_STANDARD_MODE of a flight mode, as PX4 reports a multicopter's
/// (`mode_util::getStandardModeFromNavState`): position hold, orbit,
/// altitude hold, safe recovery (Return), mission, land, takeoff;
/// non-standard for the rest, Descend among them (PX4's nav state DESCEND,
/// though its custom mode reads AUTO.LAND).
#[must_use]
pub fn standard_mode(mode: FlightMode) -> MavStandardMode {
    match mode {
        FlightMode::Position => MavStandardMode::MAV_STANDARD_MODE_POSITION_HOLD,
        FlightMode::Orbit => MavStandardMode::MAV_STANDARD_MODE_ORBIT,
        FlightMode::Altitude => MavStandardMode::MAV_STANDARD_MODE_ALTITUDE_HOLD,
        FlightMode::ReturnToLaunch => MavStandardMode::MAV_STANDARD_MODE_SAFE_RECOVERY,
        FlightMode::Mission => MavStandardMode::MAV_STANDARD_MODE_MISSION,
        FlightMode::Land => MavStandardMode::MAV_STANDARD_MODE_LAND,
        FlightMode::Takeoff => MavStandardMode::MAV_STANDARD_MODE_TAKEOFF,
        FlightMode::Hold
        | FlightMode::Offboard
        | FlightMode::FollowTarget
        | FlightMode::Stabilized
        | FlightMode::Acro
        | FlightMode::Manual
        | FlightMode::Descend => MavStandardMode::MAV_STANDARD_MODE_NON_STANDARD,
    }
}

/// AVAILABLE_MODES, as PX4's mavlink stream answers MAV_CMD_REQUEST_MESSAGE
/// for it: `index` 0 gives every mode, `k` the k-th (from 1); `None` (the
/// request DENIED) past the last. The modes are those rotorpilot flies, in
/// PX4's order (by nav state); each carries its MAV_STANDARD_MODE and PX4
/// custom mode, PX4's name where it is not a standard mode
/// (`mode_util::nav_state_names`), and MAV_MODE_PROPERTY_ADVANCED for all
/// but Altitude and Position (`mode_util::isAdvanced`). PX4 also lists
/// modes a multicopter here cannot fly (Termination, Precision Landing,
/// VTOL Takeoff, ...); they are left out, so a ground station offers only
/// what the vehicle accepts. The list never changes, so no
/// AVAILABLE_MODES_MONITOR is sent (PX4 sends it only after a change).
#[must_use]
pub fn available_modes(index: u8) -> Option<Vec<AVAILABLE_MODES_DATA>> {
    let mut modes = FlightMode::ALL;
    modes.sort_by_key(|m| m.nav_state());
    let count = modes.len() as u8;
    let entry = |i: usize, mode: FlightMode| {
        let standard = standard_mode(mode);
        let name = match standard {
            MavStandardMode::MAV_STANDARD_MODE_NON_STANDARD => px4_mode_name(mode),
            _ => "",
        };
        let mut properties = MavModeProperty::empty();
        if !matches!(mode, FlightMode::Altitude | FlightMode::Position) {
            properties |= MavModeProperty::MAV_MODE_PROPERTY_ADVANCED;
        }
        AVAILABLE_MODES_DATA {
            custom_mode: custom_mode(mode),
            properties,
            number_modes: count,
            mode_index: i as u8 + 1,
            standard_mode: standard,
            mode_name: name.into(),
        }
    };
    match index {
        0 => Some(modes.iter().enumerate().map(|(i, m)| entry(i, *m)).collect()),
        k if k <= count => Some(vec![entry(usize::from(k) - 1, modes[usize::from(k) - 1])]),
        _ => None,
    }
}

/// PX4's name of a mode's nav state (`mode_util::nav_state_names`).
fn px4_mode_name(mode: FlightMode) -> &'static str {
    match mode {
        FlightMode::Manual => "Manual",
        FlightMode::Altitude => "Altitude",
        FlightMode::Position => "Position",
        FlightMode::Mission => "Mission",
        FlightMode::Hold => "Hold",
        FlightMode::ReturnToLaunch => "Return",
        FlightMode::Acro => "Acro",
        FlightMode::Descend => "Descend",
        FlightMode::Offboard => "Offboard",
        FlightMode::Stabilized => "Stabilized",
        FlightMode::Takeoff => "Takeoff",
        FlightMode::Land => "Land",
        FlightMode::FollowTarget => "Follow Target",
        FlightMode::Orbit => "Orbit",
    }
}

/// The flight mode MAV_CMD_DO_SET_STANDARD_MODE asks for (PX4's
/// `getNavStateFromStandardMode` for a multicopter), `None` for a standard
/// mode a multicopter does not fly (non-standard, cruise, unknown).
#[must_use]
pub fn mode_from_standard(standard: u8) -> Option<FlightMode> {
    const FLOWN: [FlightMode; 7] = [
        FlightMode::Position,
        FlightMode::Orbit,
        FlightMode::Altitude,
        FlightMode::ReturnToLaunch,
        FlightMode::Mission,
        FlightMode::Land,
        FlightMode::Takeoff,
    ];
    FLOWN.into_iter().find(|m| standard_mode(*m) as u8 == standard)
}

/// What a requested PX4 (main, sub) asks of us.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ModeRequest {
    /// A mode rotorpilot flies.
    Mode(FlightMode),
    /// A PX4 mode that exists but that we cannot fly (precision land,
    /// ...): PX4 answers TEMPORARILY_REJECTED when a mode is not available.
    NotAvailable,
    /// Not a PX4 mode at all.
    Unknown,
}

/// Map a PX4 (main, sub) pair to a flight mode. AUTO with sub 0 is MISSION
/// (PX4); POSCTL with sub-mode ORBIT is Orbit; the other main modes ignore
/// the sub-mode (POSCTL's SLOW is flown as POSCTL).
#[must_use]
pub fn mode_from_px4(main: u8, sub: u8) -> ModeRequest {
    match (main, sub) {
        (main_mode::POSCTL, posctl_sub::ORBIT) => ModeRequest::Mode(FlightMode::Orbit),
        (main_mode::POSCTL, _) => ModeRequest::Mode(FlightMode::Position),
        (main_mode::MANUAL, _) => ModeRequest::Mode(FlightMode::Manual),
        (main_mode::ALTCTL, _) => ModeRequest::Mode(FlightMode::Altitude),
        (main_mode::ACRO, _) => ModeRequest::Mode(FlightMode::Acro),
        (main_mode::STABILIZED, _) => ModeRequest::Mode(FlightMode::Stabilized),
        (main_mode::OFFBOARD, _) => ModeRequest::Mode(FlightMode::Offboard),
        (main_mode::AUTO, auto_sub::LOITER) => ModeRequest::Mode(FlightMode::Hold),
        (main_mode::AUTO, auto_sub::TAKEOFF) => ModeRequest::Mode(FlightMode::Takeoff),
        (main_mode::AUTO, auto_sub::LAND) => ModeRequest::Mode(FlightMode::Land),
        (main_mode::AUTO, auto_sub::RTL) => ModeRequest::Mode(FlightMode::ReturnToLaunch),
        (main_mode::AUTO, 0 | auto_sub::MISSION) => ModeRequest::Mode(FlightMode::Mission),
        (main_mode::AUTO, auto_sub::FOLLOW_TARGET) => ModeRequest::Mode(FlightMode::FollowTarget),
        (main_mode::AUTO, auto_sub::READY | 7 | 9..=18) => ModeRequest::NotAvailable,
        (8..=11, _) => ModeRequest::NotAvailable,
        _ => ModeRequest::Unknown,
    }
}

/// Base-mode flags (MAV_MODE_FLAG).
pub mod mode_flag {
    /// CUSTOM_MODE_ENABLED.
    pub const CUSTOM: u8 = 1;
    /// AUTO_ENABLED.
    pub const AUTO: u8 = 4;
    /// GUIDED_ENABLED.
    pub const GUIDED: u8 = 8;
    /// STABILIZE_ENABLED.
    pub const STABILIZE: u8 = 16;
    /// MANUAL_INPUT_ENABLED.
    pub const MANUAL: u8 = 64;
    /// SAFETY_ARMED.
    pub const ARMED: u8 = 128;
}

/// The mode a DO_SET_MODE / SET_MODE asks for, read as PX4 does: with
/// CUSTOM_MODE_ENABLED in `base_mode`, from main and sub; without it, from the
/// base flags (AUTO gives Mission; MANUAL_INPUT with GUIDED POSCTL, with
/// STABILIZE STABILIZED, alone MANUAL).
#[must_use]
pub fn mode_from_set_mode(base_mode: u8, main: u8, sub: u8) -> ModeRequest {
    if base_mode & mode_flag::CUSTOM != 0 {
        mode_from_px4(main, sub)
    } else if base_mode & mode_flag::AUTO != 0 {
        ModeRequest::Mode(FlightMode::Mission)
    } else if base_mode & mode_flag::MANUAL != 0 {
        ModeRequest::Mode(if base_mode & mode_flag::GUIDED != 0 {
            FlightMode::Position
        } else if base_mode & mode_flag::STABILIZE != 0 {
            FlightMode::Stabilized
        } else {
            FlightMode::Manual
        })
    } else {
        ModeRequest::Unknown
    }
}

/// HEARTBEAT `base_mode`: CUSTOM_MODE_ENABLED always, SAFETY_ARMED when armed,
/// and the flags PX4 sets for the mode (no client reads them, QGC shows them).
#[must_use]
pub fn base_mode(mode: FlightMode, armed: bool) -> u8 {
    let mut b = mode_flag::CUSTOM;
    b |= match mode {
        FlightMode::Position => mode_flag::MANUAL | mode_flag::STABILIZE | mode_flag::GUIDED,
        FlightMode::Altitude | FlightMode::Stabilized | FlightMode::Manual => mode_flag::MANUAL | mode_flag::STABILIZE,
        FlightMode::Acro => mode_flag::MANUAL,
        FlightMode::Descend
        | FlightMode::Hold
        | FlightMode::Takeoff
        | FlightMode::Land
        | FlightMode::ReturnToLaunch
        | FlightMode::Mission
        | FlightMode::Orbit
        | FlightMode::FollowTarget
        | FlightMode::Offboard => mode_flag::AUTO | mode_flag::GUIDED | mode_flag::STABILIZE,
    };
    if armed {
        b |= mode_flag::ARMED;
    }
    b
}

/// MAV_RESULT values.
pub mod result {
    /// ACCEPTED.
    pub const ACCEPTED: u8 = 0;
    /// TEMPORARILY_REJECTED.
    pub const TEMPORARILY_REJECTED: u8 = 1;
    /// DENIED.
    pub const DENIED: u8 = 2;
    /// UNSUPPORTED.
    pub const UNSUPPORTED: u8 = 3;
    /// FAILED.
    pub const FAILED: u8 = 4;
}

/// MAV_RESULT of an autopilot outcome, and its reason if it is a refusal.
#[must_use]
pub fn mav_result(outcome: &CommandOutcome) -> (u8, Option<&'static str>) {
    match outcome {
        CommandOutcome::Accepted => (result::ACCEPTED, None),
        CommandOutcome::TemporarilyRejected(r) => (result::TEMPORARILY_REJECTED, Some(r)),
        CommandOutcome::Denied(r) => (result::DENIED, Some(r)),
        CommandOutcome::Unsupported => (result::UNSUPPORTED, None),
        CommandOutcome::Failed(r) => (result::FAILED, Some(r)),
    }
}

/// Degrees to degE7 (rounded, saturating).
#[must_use]
pub fn deg_e7(deg: f64) -> i32 {
    sat_i32((deg * 1e7).round())
}

/// degE7 to degrees.
#[must_use]
pub fn from_deg_e7(v: i32) -> f64 {
    f64::from(v) * 1e-7
}

/// Saturating, NaN-safe float to i32.
#[must_use]
pub fn sat_i32(v: f64) -> i32 {
    // `as` saturates and maps NaN to 0.
    v as i32
}

/// Saturating, NaN-safe float to i16.
#[must_use]
pub fn sat_i16(v: f64) -> i16 {
    v as i16
}

/// Saturating, NaN-safe float to u16.
#[must_use]
pub fn sat_u16(v: f64) -> u16 {
    v as u16
}

/// Heading [rad] to centidegrees in 0..36000.
#[must_use]
pub fn heading_cdeg(yaw_rad: f64) -> u16 {
    let d = yaw_rad.to_degrees().rem_euclid(360.0);
    let c = (d * 100.0).round();
    if c >= 36000.0 { 0 } else { sat_u16(c) }
}

/// MAVLink's "unset" for a float command parameter is NaN; `None` then.
#[must_use]
pub fn finite(v: f32) -> Option<f64> {
    v.is_finite().then_some(f64::from(v))
}

/// BATTERY_STATUS `charge_state` of a warning level (PX4: warning + 1):
/// OK, LOW, CRITICAL, EMERGENCY.
#[must_use]
pub fn charge_state(w: crate::autopilot::BatteryWarning) -> mavlink::dialects::common::MavBatteryChargeState {
    use crate::autopilot::BatteryWarning as W;
    use mavlink::dialects::common::MavBatteryChargeState as S;
    match w {
        W::None => S::MAV_BATTERY_CHARGE_STATE_OK,
        W::Low => S::MAV_BATTERY_CHARGE_STATE_LOW,
        W::Critical => S::MAV_BATTERY_CHARGE_STATE_CRITICAL,
        W::Emergency => S::MAV_BATTERY_CHARGE_STATE_EMERGENCY,
    }
}

#[cfg(test)]
mod tests;
