//! What can go wrong with a simulated vehicle. Faults are the world's doing:
//! the flight stack never sees them, only what its sensors then report (a
//! rotor speed that does not follow its command, a receiver without a fix,
//! noisier or wrong measurements, a pack short of a cell). A silent radio is
//! the world's too: the runtime reads it and stops sending.

/// The state of one motor and its propeller.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RotorHealth {
    /// Follows its command.
    Healthy,
    /// Gives only this fraction of the thrust it is commanded (0..1): the
    /// motor reaches `sqrt(fraction)` of the commanded speed, which its ESC reports.
    Degraded {
        /// Thrust fraction `T / T_cmd` in `[0, 1]`.
        thrust_fraction: f64,
    },
    /// Dead: no power, it spins down with its motor lag.
    Off,
}

impl RotorHealth {
    /// The fraction of its commanded speed the rotor reaches: `T = c_T omega^2`,
    /// so a thrust fraction `f` is a speed fraction `sqrt(f)`.
    #[must_use]
    pub fn speed_factor(self) -> f64 {
        match self {
            RotorHealth::Healthy => 1.0,
            RotorHealth::Degraded { thrust_fraction } => thrust_fraction.sqrt(),
            RotorHealth::Off => 0.0,
        }
    }
}

use nalgebra::Vector3;

use super::SensorNoise;
use super::raw_sensors::{SensorFaults, SensorMode};

/// A raw sensor that can fail on its own (the GNSS receiver's faults are
/// [`Fault::Gps`], [`Fault::GpsOffset`] and [`Fault::GpsStuck`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RawSensor {
    /// The accelerometer.
    Accel,
    /// The gyroscope.
    Gyro,
    /// The magnetometer.
    Mag,
    /// The barometer.
    Baro,
}

/// One fault (or its repair) injected into one vehicle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Fault {
    /// Rotor `rotor` (counted from 0) changes its health.
    Rotor {
        /// Which rotor, from 0.
        rotor: usize,
        /// Its new state.
        health: RotorHealth,
    },
    /// The GNSS receiver loses its fix (`false`) or has it again (`true`).
    Gps {
        /// Whether the receiver has a fix.
        available: bool,
    },
    /// The navigation solution's noise at this level (`None`: back to the
    /// configured one).
    SensorNoise(Option<SensorNoise>),
    /// The GNSS receiver reports a wrong but plausible position: the
    /// navigation solution is off by this offset [m], world NED,
    /// `p~ = p + offset` (`None`: right again).
    GpsOffset(Option<Vector3<f64>>),
    /// One cell of the pack fails (`true`: the pack gives one cell's voltage
    /// less) or the pack is whole again (`false`).
    BatteryCell {
        /// Whether one cell has failed.
        failed: bool,
    },
    /// The vehicle's telemetry radio goes silent (`true`) or works again
    /// (`false`): the runtime stops sending on every link meanwhile.
    LinkLost(bool),
    /// A raw sensor works, delivers nothing or repeats its last value.
    Sensor {
        /// Which sensor.
        sensor: RawSensor,
        /// Its new state.
        mode: SensorMode,
    },
    /// The GNSS receiver repeats its last solution (`true`) or works again
    /// (`false`); the navigation solution does not notice.
    GpsStuck(bool),
}

/// Why a fault cannot be injected.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum FaultError {
    /// No such vehicle in the world.
    #[error("no vehicle {0} in the world")]
    NoSuchVehicle(usize),
    /// The rotor does not exist.
    #[error("rotor {} does not exist: the vehicle has {count}", rotor + 1)]
    NoSuchRotor {
        /// The rotor asked for, from 0.
        rotor: usize,
        /// How many rotors there are.
        count: usize,
    },
    /// The airframe's thrust and torque act directly: it has no rotors to fail.
    #[error("the airframe has ideal actuation: no rotor can fail")]
    NoRotors,
    /// A thrust fraction, noise level or offset outside its range, or not a number.
    #[error("fault value {0} is out of range")]
    OutOfRange(f64),
}

/// The faults active on one vehicle.
#[derive(Clone, Debug, PartialEq)]
pub struct ActiveFaults {
    /// Per rotor, from 0.
    pub rotors: Vec<RotorHealth>,
    /// Whether the GNSS receiver has a fix.
    pub gps_available: bool,
    /// The noise forced on the navigation solution, if any.
    pub noise: Option<SensorNoise>,
    /// The wrong-position offset of the GNSS receiver [m], world NED, if any.
    pub gps_offset_ned: Option<Vector3<f64>>,
    /// Whether one cell of the pack has failed.
    pub battery_cell_failed: bool,
    /// Whether the telemetry radio is silent.
    pub link_lost: bool,
    /// The raw sensors' own faults.
    pub sensors: SensorFaults,
}

impl ActiveFaults {
    /// Nothing wrong with a vehicle of `rotors` rotors.
    #[must_use]
    pub fn none(rotors: usize) -> Self {
        Self {
            rotors: vec![RotorHealth::Healthy; rotors],
            gps_available: true,
            noise: None,
            gps_offset_ned: None,
            battery_cell_failed: false,
            link_lost: false,
            sensors: SensorFaults::default(),
        }
    }

    /// Whether anything is wrong.
    #[must_use]
    pub fn any(&self) -> bool {
        !self.gps_available
            || self.noise.is_some()
            || self.gps_offset_ned.is_some()
            || self.battery_cell_failed
            || self.link_lost
            || self.sensors.any()
            || self.rotors.iter().any(|r| *r != RotorHealth::Healthy)
    }
}
