//! `[[fault]]` in a scenario: a failure injected at a simulated instant, as a
//! client would inject it with MAV_CMD_INJECT_FAILURE (PX4's units and types,
//! by name), through the same lockstep method.
//!
//! ```toml
//! [[fault]]
//! at_s = 12.0             # when [s], within the duration
//! unit = "motor"          # motor | gps | battery | mavlink_signal | gyro | accel | mag | baro
//! type = "off"            # off | stuck | wrong | ok (ok undoes)
//! instance = 3            # from 1; 0 (the default) = all
//! thrust_fraction = 0.3   # motor wrong only: the thrust it gives (default SIM_MOT_WRONG_FR)
//! offset_m = 25.0         # gps wrong only: position reported this far north (default SIM_GPS_WRONG_M)
//! ```
//!
//! Supported: motor off/wrong/ok, gps off/stuck/wrong/ok, battery off/ok,
//! mavlink_signal off/ok (headless, no link: it changes nothing else),
//! gyro, accel, mag and baro off/stuck/ok (the raw sensors: they show in the
//! raw samples, which a headless run without a ULog does not simulate). Any
//! other name, pair, or a motor the airframe lacks is an error naming the
//! file, the field (and for a name, the line).

use serde::{Deserialize, Serialize};

use crate::airframe::Airframe;
use crate::autopilot::CommandOutcome;
use crate::lockstep::failure::{self, FailureInjection};
use crate::lockstep::{Lockstep, Pilot};
use crate::sim::FaultSettings;

/// A failing part (FAILURE_UNIT), by name.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FaultUnit {
    /// FAILURE_UNIT_SENSOR_GPS (4).
    Gps,
    /// FAILURE_UNIT_SYSTEM_BATTERY (100).
    Battery,
    /// FAILURE_UNIT_SYSTEM_MOTOR (101).
    Motor,
    /// FAILURE_UNIT_SYSTEM_MAVLINK_SIGNAL (105).
    MavlinkSignal,
    /// FAILURE_UNIT_SENSOR_GYRO (0).
    Gyro,
    /// FAILURE_UNIT_SENSOR_ACCEL (1).
    Accel,
    /// FAILURE_UNIT_SENSOR_MAG (2).
    Mag,
    /// FAILURE_UNIT_SENSOR_BARO (3).
    Baro,
}

impl FaultUnit {
    /// The MAVLink number.
    #[must_use]
    pub fn number(self) -> u8 {
        match self {
            FaultUnit::Gps => failure::UNIT_GPS,
            FaultUnit::Battery => failure::UNIT_BATTERY,
            FaultUnit::Motor => failure::UNIT_MOTOR,
            FaultUnit::MavlinkSignal => failure::UNIT_MAVLINK_SIGNAL,
            FaultUnit::Gyro => failure::UNIT_GYRO,
            FaultUnit::Accel => failure::UNIT_ACCEL,
            FaultUnit::Mag => failure::UNIT_MAG,
            FaultUnit::Baro => failure::UNIT_BARO,
        }
    }

    /// The name a scenario gives it.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            FaultUnit::Gps => "gps",
            FaultUnit::Battery => "battery",
            FaultUnit::Motor => "motor",
            FaultUnit::MavlinkSignal => "mavlink_signal",
            FaultUnit::Gyro => "gyro",
            FaultUnit::Accel => "accel",
            FaultUnit::Mag => "mag",
            FaultUnit::Baro => "baro",
        }
    }
}

/// How it fails (FAILURE_TYPE), by name.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FaultType {
    /// FAILURE_TYPE_OK (0): undo.
    Ok,
    /// FAILURE_TYPE_OFF (1).
    Off,
    /// FAILURE_TYPE_STUCK (2).
    Stuck,
    /// FAILURE_TYPE_WRONG (4).
    Wrong,
}

impl FaultType {
    /// The MAVLink number.
    #[must_use]
    pub fn number(self) -> u8 {
        match self {
            FaultType::Ok => failure::TYPE_OK,
            FaultType::Off => failure::TYPE_OFF,
            FaultType::Stuck => failure::TYPE_STUCK,
            FaultType::Wrong => failure::TYPE_WRONG,
        }
    }

    /// The name a scenario gives it.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            FaultType::Ok => "ok",
            FaultType::Off => "off",
            FaultType::Stuck => "stuck",
            FaultType::Wrong => "wrong",
        }
    }
}

/// One `[[fault]]` table as written.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct FileFault {
    at_s: f64,
    unit: FaultUnit,
    #[serde(rename = "type")]
    kind: FaultType,
    #[serde(default)]
    instance: u8,
    thrust_fraction: Option<f64>,
    offset_m: Option<f64>,
}

/// A failure to inject at a simulated instant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScheduledFault {
    /// When [s].
    pub at_s: f64,
    /// What fails.
    pub unit: FaultUnit,
    /// How.
    pub kind: FaultType,
    /// Instance from 1; 0 = all.
    pub instance: u8,
    /// Motor wrong: the thrust fraction, instead of `SIM_MOT_WRONG_FR`.
    pub thrust_fraction: Option<f64>,
    /// GPS wrong: the offset north [m], instead of `SIM_GPS_WRONG_M`.
    pub offset_m: Option<f64>,
}

impl ScheduledFault {
    /// The injection as MAV_CMD_INJECT_FAILURE carries it.
    #[must_use]
    pub fn injection(&self) -> FailureInjection {
        FailureInjection {
            unit: self.unit.number(),
            kind: self.kind.number(),
            instance: self.instance,
        }
    }

    /// The world's WRONG settings with this entry's values in place of `base`'s.
    #[must_use]
    pub fn settings(&self, base: FaultSettings) -> FaultSettings {
        FaultSettings {
            motor_thrust_fraction: self.thrust_fraction.unwrap_or(base.motor_thrust_fraction),
            gps_offset_north_m: self.offset_m.unwrap_or(base.gps_offset_north_m),
        }
    }
}

/// Apply `f` to vehicle `i` now through `inject` (the lockstep's injection for
/// a bare control law, the MAV_CMD_INJECT_FAILURE command for a flight
/// stack), with this entry's WRONG values in force for that instant only;
/// what happened, for the summary.
pub(super) fn apply<P: Pilot>(
    core: &mut Lockstep<P>,
    i: usize,
    f: &ScheduledFault,
    inject: impl FnOnce(&mut Lockstep<P>, FailureInjection) -> CommandOutcome,
) -> AppliedFault {
    let base = core.world().fault_settings(i);
    core.world_mut().set_fault_settings(i, f.settings(base));
    let outcome = inject(core, f.injection());
    core.world_mut().set_fault_settings(i, base);
    AppliedFault::new(f, core.time_s(), &outcome)
}

/// A fault as it was applied, for the run's summary.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AppliedFault {
    /// Simulated time it was applied at [s].
    pub time_s: f64,
    /// What failed.
    pub unit: FaultUnit,
    /// How.
    #[serde(rename = "type")]
    pub kind: FaultType,
    /// Instance from 1; 0 = all.
    pub instance: u8,
    /// The answer: "accepted", or why not.
    pub outcome: String,
}

impl AppliedFault {
    /// `fault` applied at `time_s` with `outcome`.
    #[must_use]
    pub fn new(fault: &ScheduledFault, time_s: f64, outcome: &CommandOutcome) -> Self {
        Self {
            time_s,
            unit: fault.unit,
            kind: fault.kind,
            instance: fault.instance,
            outcome: match outcome {
                CommandOutcome::Accepted => "accepted".into(),
                CommandOutcome::Unsupported => "unsupported".into(),
                CommandOutcome::Denied(why) => format!("denied: {why}"),
                CommandOutcome::TemporarilyRejected(why) => format!("temporarily rejected: {why}"),
                CommandOutcome::Failed(why) => format!("failed: {why}"),
            },
        }
    }

    /// One line: `t = 12.000 s: motor 3 off: accepted`.
    #[must_use]
    pub fn to_line(&self) -> String {
        format!(
            "t = {:.3} s: {} {} {}: {}",
            self.time_s,
            self.unit.name(),
            if self.instance == 0 {
                "(all)".to_string()
            } else {
                self.instance.to_string()
            },
            self.kind.name(),
            self.outcome
        )
    }
}

/// Validate the `[[fault]]` tables against the duration and the airframe,
/// sorted by time (stable: entries at one instant keep their order).
///
/// # Errors
/// `(field, problem)`, the field as `fault[k].name` counted from 1.
pub(super) fn validate(
    raw: &[FileFault],
    duration_s: f64,
    airframe: &Airframe,
) -> Result<Vec<ScheduledFault>, (String, String)> {
    let mut out = Vec::new();
    for (k, f) in raw.iter().enumerate() {
        let at = |name: &str| format!("fault[{}].{name}", k + 1);
        if !(f.at_s.is_finite() && f.at_s >= 0.0 && f.at_s <= duration_s) {
            return Err((
                at("at_s"),
                format!("must be within [0, duration_s = {duration_s}] s, got {}", f.at_s),
            ));
        }
        let sensor = matches!(
            f.unit,
            FaultUnit::Gyro | FaultUnit::Accel | FaultUnit::Mag | FaultUnit::Baro
        );
        match (f.unit, f.kind) {
            (FaultUnit::Battery | FaultUnit::MavlinkSignal, FaultType::Wrong) => {
                return Err((
                    at("type"),
                    "\"wrong\" is for a motor or the gps; this unit takes \"off\" or \"ok\"".into(),
                ));
            }
            (FaultUnit::Battery | FaultUnit::MavlinkSignal | FaultUnit::Motor, FaultType::Stuck) => {
                return Err((
                    at("type"),
                    "\"stuck\" is for a sensor (gyro, accel, mag, baro, gps)".into(),
                ));
            }
            (_, FaultType::Wrong) if sensor => {
                return Err((
                    at("type"),
                    "\"wrong\" is for a motor or the gps; this sensor takes \"off\", \"stuck\" or \"ok\"".into(),
                ));
            }
            (FaultUnit::Motor, _) => {
                let n = airframe.rotor_count();
                if airframe.actuation != crate::airframe::Actuation::Rotors {
                    return Err((at("unit"), "the airframe has ideal actuation: no motor can fail".into()));
                }
                if usize::from(f.instance) > n {
                    return Err((
                        at("instance"),
                        format!(
                            "the airframe has {n} motors (1 to {n}, or 0 for all), got {}",
                            f.instance
                        ),
                    ));
                }
            }
            (_, _) if f.instance > 1 => {
                return Err((
                    at("instance"),
                    format!("there is one (1, or 0 for all), got {}", f.instance),
                ));
            }
            _ => {}
        }
        if let Some(x) = f.thrust_fraction {
            if (f.unit, f.kind) != (FaultUnit::Motor, FaultType::Wrong) {
                return Err((
                    at("thrust_fraction"),
                    "only for unit = \"motor\", type = \"wrong\"".into(),
                ));
            }
            if !(0.0..=1.0).contains(&x) {
                return Err((at("thrust_fraction"), format!("must be in [0, 1], got {x}")));
            }
        }
        if let Some(x) = f.offset_m {
            if (f.unit, f.kind) != (FaultUnit::Gps, FaultType::Wrong) {
                return Err((at("offset_m"), "only for unit = \"gps\", type = \"wrong\"".into()));
            }
            if !(x.is_finite() && (0.0..=1000.0).contains(&x)) {
                return Err((at("offset_m"), format!("must be in [0, 1000] m, got {x}")));
            }
        }
        out.push(ScheduledFault {
            at_s: f.at_s,
            unit: f.unit,
            kind: f.kind,
            instance: f.instance,
            thrust_fraction: f.thrust_fraction,
            offset_m: f.offset_m,
        });
    }
    out.sort_by(|a, b| a.at_s.total_cmp(&b.at_s));
    Ok(out)
}

/// The faults due at simulated time `t_s` [s] from `next` on (`at_s <= t`,
/// within a nanosecond of rounding): their indices, and `next` moved past them.
pub(super) fn due(faults: &[ScheduledFault], next: &mut usize, t_s: f64) -> std::ops::Range<usize> {
    let start = *next;
    while *next < faults.len() && faults[*next].at_s <= t_s + 1e-9 {
        *next += 1;
    }
    start..*next
}
