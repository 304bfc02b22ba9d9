//! Values that cross the boundary between the simulated world and the flight
//! stack, and the blocks of the loop (sensors -> estimator -> controller ->
//! allocation -> actuators): what flight software may know about the vehicle
//! and what it sends back. The flight stack imports these, never [`crate::sim`].
//! Also the constants everyone shares: gravity and the simulation step.

use nalgebra::{Matrix3, SVector, UnitQuaternion, Vector2, Vector3, Vector4};
use serde::Serialize;

/// Standard gravity [m/s^2] used everywhere (doc section 1: use 9.81 in tests).
pub const GRAVITY: f64 = 9.81;

/// The simulation step [s] unless a scenario says otherwise: 1 kHz, as PX4's
/// lockstep SITL.
pub const DEFAULT_STEP_S: f64 = 1e-3;

/// Largest rotor count supported (fixed-size vectors keep the hot path free of allocation).
pub const MAX_ROTORS: usize = 12;

/// Per-rotor values, rotor 1 first, zero beyond the vehicle's rotor count.
pub type RotorVector = SVector<f64, MAX_ROTORS>;

/// The four virtual inputs of a flat multirotor.
#[derive(Clone, Copy, Debug, PartialEq, Default, Serialize)]
pub struct ControlWrench {
    /// Total thrust `u_T` [N] along `-z_b`.
    pub thrust_n: f64,
    /// Body torque `tau^b` [N m], FRD.
    pub torque_frd: Vector3<f64>,
}

impl ControlWrench {
    /// A wrench from thrust [N] and body FRD torque [N m].
    #[must_use]
    pub fn new(thrust_n: f64, torque_frd: Vector3<f64>) -> Self {
        Self { thrust_n, torque_frd }
    }

    /// `[u_T, tau_x, tau_y, tau_z]`.
    #[must_use]
    pub fn to_vector(&self) -> Vector4<f64> {
        Vector4::new(self.thrust_n, self.torque_frd.x, self.torque_frd.y, self.torque_frd.z)
    }

    /// From `[u_T, tau_x, tau_y, tau_z]`.
    #[must_use]
    pub fn from_vector(v: &Vector4<f64>) -> Self {
        Self::new(v[0], Vector3::new(v[1], v[2], v[3]))
    }
}

/// What the flight stack sends to the actuators for one step (held over it).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ActuatorCommand {
    /// Rotors stopped (disarmed): every speed decays towards 0.
    Stop,
    /// Rotor speed commands [rad/s], clamped to the rotor limits. On an
    /// ideal-actuation airframe the wrench `B omega^2` acts directly.
    RotorSpeeds(RotorVector),
    /// Total thrust and body torque. On an ideal-actuation airframe it acts
    /// directly; on a rotor airframe it is allocated (with desaturation) to
    /// rotor speed commands first.
    Wrench(ControlWrench),
}

/// A measurement of the vehicle state at one instant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Measurement {
    /// Simulated time [s].
    pub time_s: f64,
    /// Position [m], NED.
    pub position_ned: Vector3<f64>,
    /// Velocity [m/s], NED.
    pub velocity_ned: Vector3<f64>,
    /// Attitude, body FRD to NED.
    pub attitude: UnitQuaternion<f64>,
    /// Angular velocity [rad/s], body FRD.
    pub rate_frd: Vector3<f64>,
}

impl Default for Measurement {
    /// At rest at the origin, level, at time 0.
    fn default() -> Self {
        Self {
            time_s: 0.0,
            position_ned: Vector3::zeros(),
            velocity_ned: Vector3::zeros(),
            attitude: UnitQuaternion::identity(),
            rate_frd: Vector3::zeros(),
        }
    }
}

/// The model that controllers and estimators assume (never the plant's truth).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct NominalModel {
    /// Nominal mass `m` [kg].
    pub mass_kg: f64,
    /// Nominal inertia `I_b` [kg m^2], body FRD.
    pub inertia_kg_m2: Matrix3<f64>,
}

/// An estimate of the external wrench and of the real mass.
#[derive(Clone, Copy, Debug, PartialEq, Default, Serialize)]
pub struct WrenchEstimate {
    /// Estimated external force `f_e` [N], world NED.
    pub force_ned: Vector3<f64>,
    /// Estimated external torque as a generalized force on the ZYX Euler
    /// angles, `tau_e = Q^T tau_e^b` [N m] (the report's coordinates).
    pub torque_rpy: Vector3<f64>,
    /// Estimated external torque `tau_e^b` [N m], body FRD.
    pub torque_frd: Vector3<f64>,
    /// Real mass `m + f_e,z / g` [kg].
    pub mass_kg: f64,
}

/// The wind the flight stack estimates (`estimation::wind`), at one instant.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct WindEstimate {
    /// When it was last updated [s] (simulated time).
    pub time_s: f64,
    /// The wind [m/s], NED (`z` = 0: horizontal).
    pub wind_ned: Vector3<f64>,
    /// The variance of the solutions about it [(m/s)^2], north and east.
    pub variance_ne: Vector2<f64>,
}

/// What a GNSS receiver reports about its fix.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum GpsFix {
    /// No fix (receiver off or no signal).
    None,
    /// A 3D fix.
    Fix3d,
}

/// One reading of the GNSS receiver's status.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct GpsReading {
    /// Fix type.
    pub fix: GpsFix,
    /// Satellites used.
    pub satellites: u8,
}

/// One reading of the battery monitor (power module).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct BatteryReading {
    /// Terminal voltage [V].
    pub voltage_v: f64,
    /// Current drawn [A].
    pub current_a: f64,
}

/// The LiPo cell of the simulated packs, which the flight stack's battery
/// monitor assumes too: the open-circuit voltage is linear in the state of
/// charge between empty and full, behind a series resistance,
/// ```text
/// V_oc = V_empty + (V_full - V_empty) soc        [V], soc 0..1
/// V    = V_oc - R_cell I                         [V] at the terminals, drawing I [A]
/// ```
pub mod lipo_cell {
    /// Cell voltage when empty [V] (PX4's `BAT1_V_EMPTY`).
    pub const EMPTY_V: f64 = 3.5;
    /// Cell voltage when full [V] (PX4's `BAT1_V_CHARGED`).
    pub const FULL_V: f64 = 4.2;
    /// Internal resistance [Ohm] (PX4's `BAT1_R_INTERNAL` per cell).
    pub const R_OHM: f64 = 0.010;

    /// `V_oc` [V] at the state of charge `soc`.
    #[inline]
    #[must_use]
    pub fn open_circuit_v(soc: f64) -> f64 {
        EMPTY_V + (FULL_V - EMPTY_V) * soc
    }

    /// The state of charge at the open-circuit voltage `open_circuit_v` [V]
    /// (the inverse of [`open_circuit_v`], not clamped to 0..1).
    #[inline]
    #[must_use]
    pub fn charge(open_circuit_v: f64) -> f64 {
        (open_circuit_v - EMPTY_V) / (FULL_V - EMPTY_V)
    }
}

/// One sample of a three-axis body sensor (accelerometer, gyroscope,
/// magnetometer), body FRD, in the unit its field names.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct AxesSample {
    /// The instant the sample describes [s] (simulated time).
    pub time_s: f64,
    /// The reading, body FRD: specific force [m/s^2] (accelerometer,
    /// `f = R^T (a - g e3)`, -g on z at rest), angular rate [rad/s]
    /// (gyroscope) or magnetic field [gauss] (magnetometer).
    pub frd: Vector3<f64>,
}

/// One barometer sample.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct BaroSample {
    /// The instant the sample describes [s] (simulated time).
    pub time_s: f64,
    /// Static pressure [Pa].
    pub pressure_pa: f64,
    /// Air temperature at the sensor [degC].
    pub temperature_c: f64,
}

/// One GNSS receiver solution, as PX4's `sensor_gps` carries it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct GnssSample {
    /// The instant the fix describes [s] (simulated time); the receiver's
    /// latency is `delivered_s - time_s`.
    pub time_s: f64,
    /// When the receiver delivered it [s] (simulated time).
    pub delivered_s: f64,
    /// Latitude [deg] (WGS-84).
    pub lat_deg: f64,
    /// Longitude [deg] (WGS-84).
    pub lon_deg: f64,
    /// Altitude above mean sea level [m].
    pub alt_amsl_m: f64,
    /// Velocity [m/s], NED.
    pub velocity_ned: Vector3<f64>,
    /// Horizontal position accuracy (1 sigma) [m].
    pub eph_m: f64,
    /// Vertical position accuracy (1 sigma) [m].
    pub epv_m: f64,
    /// Speed accuracy (1 sigma) [m/s].
    pub speed_accuracy_m_s: f64,
    /// Horizontal dilution of precision.
    pub hdop: f64,
    /// Vertical dilution of precision.
    pub vdop: f64,
    /// Fix type.
    pub fix: GpsFix,
    /// Satellites used.
    pub satellites: u8,
}

/// The raw sensors' latest samples (each `None` until its first sample, and
/// while the sensor is off): what a navigation filter fuses. A sample is new
/// when its time is later than the one seen before.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct RawSensorReadings {
    /// Accelerometer: specific force [m/s^2], body FRD.
    pub accel: Option<AxesSample>,
    /// Gyroscope: angular rate [rad/s], body FRD.
    pub gyro: Option<AxesSample>,
    /// Magnetometer: magnetic field [gauss], body FRD.
    pub mag: Option<AxesSample>,
    /// Barometer.
    pub baro: Option<BaroSample>,
    /// GNSS receiver.
    pub gnss: Option<GnssSample>,
}

/// Everything the flight stack's sensors report at one instant `t_k`: all a
/// real autopilot knows of its vehicle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SensorReadings {
    /// The navigation solution: position, velocity, attitude and body rates
    /// (with the sensors' noise), stamped with the simulated time.
    pub measurement: Measurement,
    /// Acceleration [m/s^2], NED, as the navigation filter puts the
    /// accelerometer's reading (`a = R f + g e3`; zero at rest).
    pub acceleration_ned: Vector3<f64>,
    /// Rotor speeds as the ESCs report them [rad/s] (zero beyond the rotor count).
    pub rotor_speeds_rad_s: RotorVector,
    /// Battery monitor.
    pub battery: BatteryReading,
    /// GNSS receiver status.
    pub gps: GpsReading,
    /// The raw sensors (IMU, barometer, magnetometer, GNSS), when the world
    /// simulates them (`sim::World::enable_raw_sensors`); all `None` otherwise.
    pub raw: RawSensorReadings,
}
