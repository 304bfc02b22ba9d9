//! Failure injection: MAV_CMD_INJECT_FAILURE's numbers (PX4's FAILURE_UNIT,
//! FAILURE_TYPE; instance from 1, 0 = all) turned into the world's
//! [`Fault`]s and the announcement, and carried out on a vehicle of the core.
//!
//! | unit | OFF (1) | STUCK (2) | WRONG (4) | OK (0) |
//! |---|---|---|---|---|
//! | SENSOR_GYRO (0), SENSOR_ACCEL (1), SENSOR_MAG (2), SENSOR_BARO (3) | the raw sensor delivers nothing | it repeats its last value | — | works |
//! | GPS (4) | no fix; the navigation solution dead-reckons and drifts | the receiver repeats its last solution | position `SIM_GPS_WRONG_M` north | fix, right position, live solutions |
//! | BATTERY (100) | one cell fails: one cell's voltage less | — | — | whole pack |
//! | MOTOR (101) | the rotor stops | — | `SIM_MOT_WRONG_FR` of its thrust | healthy |
//! | MAVLINK_SIGNAL (105) | the vehicle stops sending on its links | — | — | sends again |
//!
//! The sensor rows are PX4's simulated sensors' (`failure_injection`,
//! `sensor_baro_sim`, `sensor_mag_sim`, `sensor_gps_sim`): they honour OFF,
//! STUCK and OK, and only the GNSS receiver WRONG. A raw sensor's fault
//! shows in the raw samples and the messages built from them; the
//! navigation solution the flight stack flies on today does not read them.
//! Any other pair is UNSUPPORTED; an instance that does not exist (a motor
//! beyond the rotor count, any motor of an ideal-actuation airframe, a second
//! sensor, GPS, battery or radio) is DENIED. Nothing changes then.

use nalgebra::Vector3;

use super::{Lockstep, Pilot};
use crate::autopilot::{CommandOutcome, Severity, StatusText};
use crate::sim::{ActiveFaults, Fault, FaultSettings, RawSensor, RotorHealth, SensorMode};

// MAVLink FAILURE_UNIT and FAILURE_TYPE numbers (PX4's `vehicle_command`).
/// FAILURE_UNIT_SENSOR_GYRO.
pub const UNIT_GYRO: u8 = 0;
/// FAILURE_UNIT_SENSOR_ACCEL.
pub const UNIT_ACCEL: u8 = 1;
/// FAILURE_UNIT_SENSOR_MAG.
pub const UNIT_MAG: u8 = 2;
/// FAILURE_UNIT_SENSOR_BARO.
pub const UNIT_BARO: u8 = 3;
/// FAILURE_UNIT_SENSOR_GPS.
pub const UNIT_GPS: u8 = 4;
/// FAILURE_UNIT_SYSTEM_BATTERY.
pub const UNIT_BATTERY: u8 = 100;
/// FAILURE_UNIT_SYSTEM_MOTOR.
pub const UNIT_MOTOR: u8 = 101;
/// FAILURE_UNIT_SYSTEM_MAVLINK_SIGNAL.
pub const UNIT_MAVLINK_SIGNAL: u8 = 105;
/// FAILURE_TYPE_OK: undo.
pub const TYPE_OK: u8 = 0;
/// FAILURE_TYPE_OFF.
pub const TYPE_OFF: u8 = 1;
/// FAILURE_TYPE_STUCK.
pub const TYPE_STUCK: u8 = 2;
/// FAILURE_TYPE_WRONG.
pub const TYPE_WRONG: u8 = 4;

/// A failure to inject, as MAV_CMD_INJECT_FAILURE gives it (plain data).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FailureInjection {
    /// FAILURE_UNIT.
    pub unit: u8,
    /// FAILURE_TYPE.
    pub kind: u8,
    /// Instance, from 1; 0 = all.
    pub instance: u8,
}

/// What an injection does to the world: the faults, in order, and the
/// announcement; or the refusal (UNSUPPORTED, DENIED) when it cannot be done.
/// A motor's instance is its motor number, `motors[i]` that of rotor `i`
/// (PX4's numbering, [`crate::airframe::RotorGeometry::motor`]).
///
/// # Errors
/// The outcome to answer instead; nothing is to change then.
pub fn failure_faults(
    inj: FailureInjection,
    active: &ActiveFaults,
    motors: &[usize],
    settings: FaultSettings,
) -> Result<(Vec<Fault>, StatusText), CommandOutcome> {
    use self::{
        TYPE_OFF, TYPE_OK, TYPE_STUCK, TYPE_WRONG, UNIT_ACCEL, UNIT_BARO, UNIT_BATTERY, UNIT_GPS, UNIT_GYRO, UNIT_MAG,
        UNIT_MAVLINK_SIGNAL, UNIT_MOTOR,
    };
    let say = |severity, text: String| StatusText { severity, text };
    let warn = |what: &str| say(Severity::Warning, format!("CMD_INJECT_FAILURE, {what}"));
    let ok = |what: &str| say(Severity::Info, format!("CMD_INJECT_FAILURE, {what} ok"));
    // the single GPS, battery and radio: instance 0 (all) or 1
    let single = |what: &'static str| {
        if inj.instance <= 1 {
            Ok(())
        } else {
            Err(CommandOutcome::Denied(what))
        }
    };
    match (inj.unit, inj.kind) {
        (UNIT_MOTOR, TYPE_OK | TYPE_OFF | TYPE_WRONG) => {
            let n = active.rotors.len();
            let rotors: Vec<usize> = match usize::from(inj.instance) {
                _ if n == 0 => return Err(CommandOutcome::Denied("no motor can fail: ideal actuation")),
                0 => (0..n).collect(),
                k => match rotor_of_motor(motors, k) {
                    Some(r) if r < n => vec![r],
                    _ => return Err(CommandOutcome::Denied("no such motor")),
                },
            };
            let f = settings.motor_thrust_fraction;
            let (health, what) = match inj.kind {
                TYPE_OK => (RotorHealth::Healthy, "ok".to_string()),
                TYPE_OFF => (RotorHealth::Off, "off".to_string()),
                _ => (
                    RotorHealth::Degraded { thrust_fraction: f },
                    format!("wrong ({:.0}% thrust)", f * 100.0),
                ),
            };
            let which = match rotors.as_slice() {
                [_] => format!("motor {}", inj.instance),
                _ => "motors".to_string(),
            };
            let severity = if inj.kind == TYPE_OK {
                Severity::Info
            } else {
                Severity::Warning
            };
            let faults = rotors.iter().map(|&rotor| Fault::Rotor { rotor, health }).collect();
            Ok((faults, say(severity, format!("CMD_INJECT_FAILURE, {which} {what}"))))
        }
        (UNIT_GYRO | UNIT_ACCEL | UNIT_MAG | UNIT_BARO, TYPE_OK | TYPE_OFF | TYPE_STUCK) => {
            let (sensor, name) = match inj.unit {
                UNIT_GYRO => (RawSensor::Gyro, "gyro"),
                UNIT_ACCEL => (RawSensor::Accel, "accel"),
                UNIT_MAG => (RawSensor::Mag, "mag"),
                _ => (RawSensor::Baro, "baro"),
            };
            single(match sensor {
                RawSensor::Gyro => "no such gyro",
                RawSensor::Accel => "no such accel",
                RawSensor::Mag => "no such mag",
                RawSensor::Baro => "no such baro",
            })?;
            let (mode, text) = match inj.kind {
                TYPE_OK => (SensorMode::Ok, ok(name)),
                TYPE_OFF => (SensorMode::Off, warn(&format!("{name} off"))),
                _ => (SensorMode::Stuck, warn(&format!("{name} stuck"))),
            };
            Ok((vec![Fault::Sensor { sensor, mode }], text))
        }
        (UNIT_GPS, TYPE_OK | TYPE_OFF | TYPE_STUCK | TYPE_WRONG) => {
            single("no such GPS")?;
            Ok(match inj.kind {
                TYPE_OK => (
                    vec![
                        Fault::Gps { available: true },
                        Fault::GpsOffset(None),
                        Fault::GpsStuck(false),
                    ],
                    ok("GPS"),
                ),
                TYPE_OFF => (vec![Fault::Gps { available: false }], warn("GPS off")),
                TYPE_STUCK => (vec![Fault::GpsStuck(true)], warn("GPS stuck")),
                _ => (
                    vec![Fault::GpsOffset(Some(Vector3::new(
                        settings.gps_offset_north_m,
                        0.0,
                        0.0,
                    )))],
                    warn("GPS wrong"),
                ),
            })
        }
        (UNIT_BATTERY, TYPE_OK | TYPE_OFF) => {
            single("no such battery")?;
            let failed = inj.kind == TYPE_OFF;
            let text = if failed {
                warn("battery cell off")
            } else {
                ok("battery")
            };
            Ok((vec![Fault::BatteryCell { failed }], text))
        }
        (UNIT_MAVLINK_SIGNAL, TYPE_OK | TYPE_OFF) => {
            single("no such link")?;
            let lost = inj.kind == TYPE_OFF;
            let text = if lost { warn("MAVLink off") } else { ok("MAVLink") };
            Ok((vec![Fault::LinkLost(lost)], text))
        }
        _ => Err(CommandOutcome::Unsupported),
    }
}

/// The rotor (from 0) whose motor number in `motors` is `motor`.
#[must_use]
pub fn rotor_of_motor(motors: &[usize], motor: usize) -> Option<usize> {
    motors.iter().position(|m| *m == motor)
}

impl<P: Pilot> Lockstep<P> {
    /// Inject a failure into vehicle `i`'s world at the current instant
    /// (module doc: the supported units and types), without asking its
    /// pilot: ACCEPTED (announced, see [`Self::drain_world_texts`]),
    /// UNSUPPORTED or DENIED (nothing changed). [`Lockstep::command`] calls
    /// this once the autopilot allows the injection (`SYS_FAILURE_EN`).
    pub fn inject_failure(&mut self, i: usize, inj: FailureInjection) -> CommandOutcome {
        let (faults, text) = match failure_faults(
            inj,
            self.world.faults(i),
            self.world.motors(i),
            self.world.fault_settings(i),
        ) {
            Ok(x) => x,
            Err(outcome) => return outcome,
        };
        // validated above: the world refuses none of these; if it did, undo
        let before = self.world.faults(i).clone();
        for f in faults {
            if self.world.inject(i, f).is_err() {
                self.restore_faults(i, &before);
                return CommandOutcome::Failed("the world refused the fault");
            }
        }
        let t = self.time_s();
        self.world_texts[i].push((t, text));
        CommandOutcome::Accepted
    }

    /// Put vehicle `i`'s faults back as `faults` says.
    fn restore_faults(&mut self, i: usize, faults: &ActiveFaults) {
        let mut back: Vec<Fault> = faults
            .rotors
            .iter()
            .enumerate()
            .map(|(rotor, &health)| Fault::Rotor { rotor, health })
            .collect();
        back.extend([
            Fault::Gps {
                available: faults.gps_available,
            },
            Fault::SensorNoise(faults.noise),
            Fault::GpsOffset(faults.gps_offset_ned),
            Fault::BatteryCell {
                failed: faults.battery_cell_failed,
            },
            Fault::LinkLost(faults.link_lost),
            Fault::GpsStuck(faults.sensors.gnss_stuck),
            Fault::Sensor {
                sensor: RawSensor::Accel,
                mode: faults.sensors.accel,
            },
            Fault::Sensor {
                sensor: RawSensor::Gyro,
                mode: faults.sensors.gyro,
            },
            Fault::Sensor {
                sensor: RawSensor::Mag,
                mode: faults.sensors.mag,
            },
            Fault::Sensor {
                sensor: RawSensor::Baro,
                mode: faults.sensors.baro,
            },
        ]);
        for f in back {
            let _ = self.world.inject(i, f);
        }
    }
}
