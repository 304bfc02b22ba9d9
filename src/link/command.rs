//! The command protocol: COMMAND_LONG and COMMAND_INT read alike (PX4 does),
//! then classified into what to do: hand the autopilot a typed command (it
//! accepts or refuses at the instant it applies it), answer a request for a
//! message or a stream rate here, or answer what no vehicle state can change
//! (an unknown command, malformed parameters). NaN parameters mean "default"
//! or "keep", as MAVSDK sends them; pymavlink sends 0 in the same places,
//! which is read the same way where PX4 does (lat/lon 0/0 = current position).

use std::time::Duration;

use super::convert::{self, ModeRequest, result};
use super::streams::Interval;
use super::wire::{CommandInt, CommandLong};
use crate::autopilot::{AutopilotCommand, OrbitYaw, PowerAction};
use crate::geo::GeoPoint;

/// MAV_CMD ids handled here.
pub mod id {
    /// MAV_CMD_NAV_RETURN_TO_LAUNCH.
    pub const NAV_RETURN_TO_LAUNCH: u16 = 20;
    /// MAV_CMD_NAV_LAND.
    pub const NAV_LAND: u16 = 21;
    /// MAV_CMD_NAV_TAKEOFF.
    pub const NAV_TAKEOFF: u16 = 22;
    /// MAV_CMD_DO_ORBIT.
    pub const DO_ORBIT: u16 = 34;
    /// MAV_CMD_DO_SET_MODE.
    pub const DO_SET_MODE: u16 = 176;
    /// MAV_CMD_DO_CHANGE_SPEED.
    pub const DO_CHANGE_SPEED: u16 = 178;
    /// MAV_CMD_DO_SET_HOME.
    pub const DO_SET_HOME: u16 = 179;
    /// MAV_CMD_DO_REPOSITION.
    pub const DO_REPOSITION: u16 = 192;
    /// MAV_CMD_DO_SET_MISSION_CURRENT.
    pub const DO_SET_MISSION_CURRENT: u16 = 224;
    /// MAV_CMD_DO_SET_STANDARD_MODE.
    pub const DO_SET_STANDARD_MODE: u16 = 262;
    /// MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN.
    pub const PREFLIGHT_REBOOT_SHUTDOWN: u16 = 246;
    /// MAV_CMD_MISSION_START.
    pub const MISSION_START: u16 = 300;
    /// MAV_CMD_COMPONENT_ARM_DISARM.
    pub const COMPONENT_ARM_DISARM: u16 = 400;
    /// MAV_CMD_RUN_PREARM_CHECKS.
    pub const RUN_PREARM_CHECKS: u16 = 401;
    /// MAV_CMD_GET_HOME_POSITION.
    pub const GET_HOME_POSITION: u16 = 410;
    /// MAV_CMD_INJECT_FAILURE.
    pub const INJECT_FAILURE: u16 = 420;
    /// MAV_CMD_SET_MESSAGE_INTERVAL.
    pub const SET_MESSAGE_INTERVAL: u16 = 511;
    /// MAV_CMD_REQUEST_MESSAGE.
    pub const REQUEST_MESSAGE: u16 = 512;
    /// MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES.
    pub const REQUEST_AUTOPILOT_CAPABILITIES: u16 = 520;
}

/// The "force" magic number of MAV_CMD_COMPONENT_ARM_DISARM param2.
pub const FORCE_MAGIC: f32 = 21196.0;

/// AUTOPILOT_VERSION message id.
pub const AUTOPILOT_VERSION_ID: u32 = 148;
/// HOME_POSITION message id.
pub const HOME_POSITION_ID: u32 = 242;

/// Where a command's position parameters came from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Position {
    /// COMMAND_LONG params 5..7 (lat/lon in degrees).
    Float {
        /// param5.
        x: f32,
        /// param6.
        y: f32,
        /// param7.
        z: f32,
    },
    /// COMMAND_INT x, y (degE7), z and frame.
    Int {
        /// Latitude [degE7].
        x: i32,
        /// Longitude [degE7].
        y: i32,
        /// Altitude [m].
        z: f32,
        /// MAV_FRAME (ignored for altitudes: AMSL whatever the frame, as PX4).
        frame: u8,
    },
}

/// A command in either form.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Command {
    /// MAV_CMD id.
    pub command: u16,
    /// param1..param4.
    pub p: [f32; 4],
    /// params 5..7 or x/y/z.
    pub position: Position,
    /// Target system.
    pub target_system: u8,
    /// Target component.
    pub target_component: u8,
}

impl From<&CommandLong> for Command {
    fn from(c: &CommandLong) -> Self {
        Self {
            command: c.command,
            p: [c.params[0], c.params[1], c.params[2], c.params[3]],
            position: Position::Float {
                x: c.params[4],
                y: c.params[5],
                z: c.params[6],
            },
            target_system: c.target_system,
            target_component: c.target_component,
        }
    }
}

impl From<&CommandInt> for Command {
    fn from(c: &CommandInt) -> Self {
        Self {
            command: c.command,
            p: c.params,
            position: Position::Int {
                x: c.x,
                y: c.y,
                z: c.z,
                frame: c.frame,
            },
            target_system: c.target_system,
            target_component: c.target_component,
        }
    }
}

impl Command {
    /// Latitude and longitude [deg], `None` when unset (NaN, INT32_MAX, or 0/0).
    #[must_use]
    pub fn lat_lon(&self) -> Option<(f64, f64)> {
        match self.position {
            Position::Float { x, y, .. } => {
                let (lat, lon) = (convert::finite(x)?, convert::finite(y)?);
                (lat != 0.0 || lon != 0.0).then_some((lat, lon))
            }
            Position::Int { x, y, .. } => {
                if x == i32::MAX || y == i32::MAX || (x == 0 && y == 0) {
                    None
                } else {
                    Some((convert::from_deg_e7(x), convert::from_deg_e7(y)))
                }
            }
        }
    }

    /// Whether the latitude and longitude given (if any) are within ±90° and
    /// ±180° (an unset position is in range).
    #[must_use]
    pub fn lat_lon_in_range(&self) -> bool {
        self.lat_lon()
            .is_none_or(|(lat, lon)| lat.abs() <= 90.0 && lon.abs() <= 180.0)
    }

    /// param7 / z, `None` when NaN.
    #[must_use]
    pub fn z(&self) -> Option<f64> {
        match self.position {
            Position::Float { z, .. } | Position::Int { z, .. } => convert::finite(z),
        }
    }
}

/// What the vehicle does about a command.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Action {
    /// Ask the autopilot; the ACK carries its outcome.
    Autopilot(AutopilotCommand),
    /// ACK at once with this MAV_RESULT; a refusal may carry a reason for
    /// STATUSTEXT.
    Answer(u8, Option<&'static str>),
    /// ACK ACCEPTED (if the link can build the message, else DENIED), then
    /// send the message: its id, and param2 of MAV_CMD_REQUEST_MESSAGE
    /// rounded, `None` when NaN or outside 0..=255 (AVAILABLE_MODES reads it
    /// as the mode index, 0 for all; the other messages ignore it).
    SendMessage(u32, Option<u8>),
    /// Change a stream interval on this link (ACCEPTED, or FAILED for a
    /// message the vehicle does not stream).
    SetInterval(u32, Interval),
}

/// Classify a command as PX4 would.
#[must_use]
pub fn classify(c: &Command) -> Action {
    let [p1, p2, p3, p4] = c.p;
    match c.command {
        id::COMPONENT_ARM_DISARM => {
            let force = (p2 - FORCE_MAGIC).abs() < 0.5;
            match p1.round() {
                1.0 => Action::Autopilot(AutopilotCommand::Arm { force }),
                0.0 => Action::Autopilot(AutopilotCommand::Disarm { force }),
                _ => Action::Answer(result::UNSUPPORTED, None),
            }
        }
        // lat/lon (params 5, 6) are not flown (PX4 multirotors take off
        // where they stand) but must be a place: beyond ±90°/±180° is malformed
        id::NAV_TAKEOFF if !c.lat_lon_in_range() => {
            Action::Answer(result::DENIED, Some("Takeoff denied: latitude/longitude out of range"))
        }
        id::NAV_TAKEOFF => Action::Autopilot(AutopilotCommand::Takeoff { altitude_amsl_m: c.z() }),
        id::NAV_LAND => Action::Autopilot(AutopilotCommand::Land),
        id::NAV_RETURN_TO_LAUNCH => Action::Autopilot(AutopilotCommand::ReturnToLaunch),
        id::DO_SET_MODE => set_mode(p1 as u8, p2 as u8, p3 as u8),
        // PX4: a standard mode the vehicle has no nav state for FAILS
        id::DO_SET_STANDARD_MODE => convert::finite(p1)
            .filter(|x| (0.0..=255.0).contains(x))
            .and_then(|x| convert::mode_from_standard(x.round() as u8))
            .map_or(Action::Answer(result::FAILED, None), |m| {
                Action::Autopilot(AutopilotCommand::SetMode(m))
            }),
        id::RUN_PREARM_CHECKS => Action::Autopilot(AutopilotCommand::RunPrearmChecks),
        id::DO_REPOSITION => {
            // PX4: bit 0 (CHANGE_MODE) switches to Hold; any other bit is
            // UNSUPPORTED; without bit 0 the commander answers UNSUPPORTED
            // but the navigator still moves a Hold in force
            let flags = if p2.is_finite() && p2 >= 0.0 { p2 as u32 } else { 0 };
            if flags & !1 != 0 {
                return Action::Answer(result::UNSUPPORTED, Some("DO_REPOSITION: param2 has bits other than 1"));
            }
            let (lat_deg, lon_deg) = c.lat_lon().unzip();
            let (alt_amsl_m, yaw_rad) = (c.z(), convert::finite(p4));
            let speed_m_s = convert::finite(p1).filter(|s| *s > 0.0);
            Action::Autopilot(if flags == 1 {
                AutopilotCommand::Reposition {
                    lat_deg,
                    lon_deg,
                    alt_amsl_m,
                    yaw_rad,
                    speed_m_s,
                }
            } else {
                AutopilotCommand::RepositionInHold {
                    lat_deg,
                    lon_deg,
                    alt_amsl_m,
                    yaw_rad,
                    speed_m_s,
                }
            })
        }
        // p1 signed radius, p2 speed, p3 yaw behaviour (5: unchanged; a
        // number MAVLink does not define flies PX4's default, front to the
        // centre), p5/p6 centre, p7 altitude AMSL; NaN keeps
        id::DO_ORBIT => {
            let (lat, lon) = c.lat_lon().unzip();
            Action::Autopilot(AutopilotCommand::Orbit {
                radius_m: convert::finite(p1),
                velocity_m_s: convert::finite(p2),
                yaw: convert::finite(p3)
                    .map(|y| y.round())
                    .filter(|y| *y != 5.0)
                    .map(|y| OrbitYaw::from_mavlink(y.clamp(0.0, 255.0) as u8).unwrap_or(OrbitYaw::FrontToCentre)),
                lat_deg: lat,
                lon_deg: lon,
                alt_amsl_m: c.z(),
            })
        }
        // p2 = speed; NaN (MAVSDK's "unchanged") is PX4's -1, no change
        id::DO_CHANGE_SPEED => Action::Autopilot(AutopilotCommand::ChangeSpeed {
            speed_m_s: convert::finite(p2).unwrap_or(-1.0),
        }),
        id::DO_SET_HOME => {
            if p1.round() == 1.0 {
                return Action::Autopilot(AutopilotCommand::SetHome(None));
            }
            // no position (NaN or 0/0) is no valid home: the autopilot refuses it
            let (lat_deg, lon_deg) = c.lat_lon().unwrap_or((f64::NAN, f64::NAN));
            Action::Autopilot(AutopilotCommand::SetHome(Some(GeoPoint {
                lat_deg,
                lon_deg,
                alt_amsl_m: c.z().unwrap_or(f64::NAN),
            })))
        }
        id::PREFLIGHT_REBOOT_SHUTDOWN => match p1.round() {
            0.0 => Action::Answer(result::ACCEPTED, None),
            1.0 => Action::Autopilot(AutopilotCommand::Power(PowerAction::Reboot)),
            2.0 => Action::Autopilot(AutopilotCommand::Power(PowerAction::Shutdown)),
            _ => Action::Answer(result::UNSUPPORTED, None),
        },
        // p1 = the first item; NaN or negative: where the mission stands
        id::MISSION_START => Action::Autopilot(AutopilotCommand::StartMission { first: seq(p1) }),
        // p1 = the item; the autopilot refuses one past the mission
        id::DO_SET_MISSION_CURRENT => match seq(p1) {
            Some(seq) => Action::Autopilot(AutopilotCommand::SetMissionCurrent { seq }),
            None => Action::Answer(result::DENIED, Some("DO_SET_MISSION_CURRENT needs an item")),
        },
        id::SET_MESSAGE_INTERVAL => {
            if !p1.is_finite() || p1 < 0.0 {
                return Action::Answer(result::FAILED, None);
            }
            Action::SetInterval(p1 as u32, Interval::from_param_us(p2))
        }
        id::REQUEST_MESSAGE => {
            if !p1.is_finite() || p1 < 0.0 {
                return Action::Answer(result::DENIED, None);
            }
            let index = convert::finite(p2)
                .map(f64::round)
                .filter(|x| (0.0..=255.0).contains(x))
                .map(|x| x as u8);
            Action::SendMessage(p1 as u32, index)
        }
        id::REQUEST_AUTOPILOT_CAPABILITIES => Action::SendMessage(AUTOPILOT_VERSION_ID, None),
        id::GET_HOME_POSITION => Action::SendMessage(HOME_POSITION_ID, None),
        // param1 failure unit, param2 failure type, param3 instance (0: all);
        // a number that is none (NaN, out of 0..255) is 255, which names nothing
        id::INJECT_FAILURE => {
            let number = |p: f32| {
                convert::finite(p)
                    .filter(|x| (0.0..=254.0).contains(x))
                    .map_or(u8::MAX, |x| x as u8)
            };
            Action::Autopilot(AutopilotCommand::InjectFailure {
                unit: number(p1),
                kind: number(p2),
                instance: convert::finite(p3).map_or(0, |_| number(p3)),
            })
        }
        _ => Action::Answer(result::UNSUPPORTED, None),
    }
}

/// A mission item's seq from a float parameter: `None` when NaN or
/// negative; beyond u16 it saturates (no such item: the autopilot refuses).
fn seq(p: f32) -> Option<u16> {
    convert::finite(p).filter(|x| *x >= 0.0).map(|x| x as u16)
}

/// DO_SET_MODE / SET_MODE: the requested mode, or a refusal.
#[must_use]
pub fn set_mode(base: u8, main: u8, sub: u8) -> Action {
    match convert::mode_from_set_mode(base, main, sub) {
        ModeRequest::Mode(m) => Action::Autopilot(AutopilotCommand::SetMode(m)),
        ModeRequest::NotAvailable => Action::Answer(result::TEMPORARILY_REJECTED, Some("mode not available")),
        ModeRequest::Unknown => Action::Answer(result::UNSUPPORTED, None),
    }
}

/// How long after a param set the change is broadcast again (PX4's
/// `send_untransmitted()` runs a few milliseconds later).
pub const PARAM_REBROADCAST_DELAY: Duration = Duration::from_millis(5);

#[cfg(test)]
mod tests;
