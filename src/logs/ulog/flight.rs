//! A flight's ULog: PX4-named topics filled from the lockstep core, decimated
//! from the simulation step to PX4's default logger rates. The daemon calls
//! [`FlightUlog::on_step`] after every step; so does `rotorpilot replay
//! --ulog` ([`crate::logs::replay::replay_logs`]).
//!
//! `timestamp` is the simulated time [us] since boot (PX4 SITL's lockstep
//! clock); `timestamp_sample` the instant the data describes (equal here).
//! Units and frames are PX4's: SI, world NED, body FRD, attitude the
//! quaternion (w, x, y, z) rotating FRD into NED.
//!
//! | topic | rate | source |
//! |---|---|---|
//! | `vehicle_attitude` | 20 Hz | navigation solution |
//! | `vehicle_angular_velocity` | 50 Hz | navigation solution |
//! | `vehicle_local_position` | 10 Hz | navigation solution |
//! | `vehicle_global_position` | 5 Hz | navigation solution |
//! | `vehicle_attitude_setpoint` | 20 Hz | the controller |
//! | `trajectory_setpoint` | 5 Hz | the reference tracked (only while one is) |
//! | `actuator_motors` | 10 Hz | rotor commands, by motor number (PX4's) |
//! | `battery_status` | 5 Hz | battery |
//! | `vehicle_status` | 1 Hz and on change (arming, mode, `failsafe`) | commander |
//! | `vehicle_land_detected` | 1 Hz and on change | land detector |
//! | `wind` | 1 Hz, once estimated | the wind estimate (PX4's fields; no airspeed or sideslip fusion: innovations 0) |
//! | `rotorpilot_wrench_estimate` | 50 Hz | the momentum-based estimator (and its order) |
//! | `rotorpilot_control_wrench` | 50 Hz | the controller's wrench |
//! | `rotorpilot_sim_truth` | 50 Hz | the simulated world (truth) |
//! | `rotorpilot_sim_wind` | 10 Hz | the air at the vehicle and its aerodynamic wrench (truth) |
//! | `sensor_combined` | 50 Hz | the raw accelerometer and gyroscope (FRD) |
//! | `vehicle_air_data` | 5 Hz | the raw barometer |
//! | `vehicle_magnetometer` | 5 Hz | the raw magnetometer (FRD, gauss) |
//! | `sensor_gps` | every fix (8 Hz) | the raw GNSS receiver |
//!
//! The raw sensor topics are logged when the world simulates the raw
//! sensors (the daemon and `replay --ulog` turn them on), from each sensor's
//! latest sample, stamped with its sample time, at most at the rate above;
//! an OFF sensor logs nothing, a STUCK one its repeated value.
//!
//! The rates are the intervals of PX4's default logger profile
//! (`logged_topics.cpp`); status and land detection are logged on change, as
//! PX4 logs every publication of those, plus once a second.

use std::io::{self, Write};

use nalgebra::{UnitQuaternion, Vector3};

use super::{Format, LogLevel, Sample, UlogWriter, Value};
use crate::autopilot::{Autopilot, FlightMode, LandedState, Severity, StatusText};
use crate::control::Reference;
use crate::lockstep::Lockstep;
use crate::params::{Param, ParamStore, ParamValue};
use crate::signals::{ActuatorCommand, GpsFix, RawSensorReadings};

/// The device id the raw sensor topics carry: 0, no device (a simulated
/// sensor here has no bus address).
const DEVICE_ID: u32 = 0;
/// `sensor_gps.c_variance_rad` [rad], the course accuracy PX4's simulated
/// receiver reports with a fix (`sensor_gps_sim`).
const GPS_COURSE_VARIANCE_RAD: f64 = 0.1;

/// PX4's `actuator_motors.control` length.
const MOTORS: usize = 12;

/// A topic and its logging interval [ms] (0: on change and once a second).
struct Topic {
    format: Format,
    interval_ms: u32,
}

/// Topic `name` logged every `interval_ms` [ms] with `fields` ([`Format::fields`]).
const fn topic(name: &'static str, interval_ms: u32, fields: &'static str) -> Topic {
    Topic {
        format: Format { name, fields },
        interval_ms,
    }
}

// `actuator_motors.control` has [`MOTORS`] entries.
const ATTITUDE: Topic = topic(
    "vehicle_attitude",
    50,
    "uint64_t timestamp;uint64_t timestamp_sample;float[4] q;",
);
const ANGULAR_VELOCITY: Topic = topic(
    "vehicle_angular_velocity",
    20,
    "uint64_t timestamp;uint64_t timestamp_sample;float[3] xyz;",
);
const LOCAL_POSITION: Topic = topic(
    "vehicle_local_position",
    100,
    "uint64_t timestamp;uint64_t timestamp_sample;double ref_lat;double ref_lon;float x;\
     float y;float z;float vx;float vy;float vz;float z_deriv;float ax;float ay;float az;\
     float heading;float ref_alt;bool xy_valid;bool z_valid;bool v_xy_valid;\
     bool v_z_valid;bool xy_global;bool z_global;",
);
const GLOBAL_POSITION: Topic = topic(
    "vehicle_global_position",
    200,
    "uint64_t timestamp;uint64_t timestamp_sample;double lat;double lon;float alt;\
     bool lat_lon_valid;bool alt_valid;",
);
const ATTITUDE_SETPOINT: Topic = topic(
    "vehicle_attitude_setpoint",
    50,
    "uint64_t timestamp;float yaw_sp_move_rate;float[4] q_d;float[3] thrust_body;",
);
const TRAJECTORY_SETPOINT: Topic = topic(
    "trajectory_setpoint",
    200,
    "uint64_t timestamp;float[3] position;float[3] velocity;float[3] acceleration;\
     float[3] jerk;float yaw;float yawspeed;",
);
const ACTUATOR_MOTORS: Topic = topic(
    "actuator_motors",
    100,
    "uint64_t timestamp;uint64_t timestamp_sample;uint16_t reversible_flags;\
     float[12] control;",
);
const BATTERY_STATUS: Topic = topic(
    "battery_status",
    200,
    "uint64_t timestamp;float voltage_v;float current_a;float discharged_mah;\
     float remaining;bool connected;uint8_t warning;",
);
const VEHICLE_STATUS: Topic = topic(
    "vehicle_status",
    0,
    "uint64_t timestamp;uint8_t arming_state;uint8_t nav_state;uint8_t vehicle_type;\
     bool pre_flight_checks_pass;bool failsafe;",
);
const LAND_DETECTED: Topic = topic("vehicle_land_detected", 0, "uint64_t timestamp;bool landed;");
const WIND: Topic = topic(
    "wind",
    1000,
    "uint64_t timestamp;uint64_t timestamp_sample;float windspeed_north;\
     float windspeed_east;float variance_north;float variance_east;float tas_innov;\
     float tas_innov_var;float beta_innov;float beta_innov_var;",
);
const WRENCH_ESTIMATE: Topic = topic(
    "rotorpilot_wrench_estimate",
    20,
    "uint64_t timestamp;float[3] force_ned;float[3] torque_frd;float mass_kg;\
     uint8_t order;",
);
const CONTROL_WRENCH: Topic = topic(
    "rotorpilot_control_wrench",
    20,
    "uint64_t timestamp;float thrust_n;float[3] torque_frd;float applied_thrust_n;\
     float[3] applied_torque_frd;bool saturated;",
);
const SIM_TRUTH: Topic = topic(
    "rotorpilot_sim_truth",
    20,
    "uint64_t timestamp;float[3] position_ned;float[3] velocity_ned;float[4] q;\
     float[3] rate_frd;float[3] external_force_ned;float[3] external_torque_frd;\
     float mass_kg;",
);

const SIM_WIND: Topic = topic(
    "rotorpilot_sim_wind",
    100,
    "uint64_t timestamp;float[3] wind_ned;float[3] aero_force_ned;float[3] aero_torque_frd;",
);

const SENSOR_COMBINED: Topic = topic(
    "sensor_combined",
    20,
    "uint64_t timestamp;float[3] gyro_rad;uint32_t gyro_integral_dt;\
     int32_t accelerometer_timestamp_relative;float[3] accelerometer_m_s2;\
     uint32_t accelerometer_integral_dt;uint8_t accelerometer_clipping;uint8_t gyro_clipping;",
);
const AIR_DATA: Topic = topic(
    "vehicle_air_data",
    200,
    "uint64_t timestamp;uint64_t timestamp_sample;uint32_t baro_device_id;\
     float baro_alt_meter;float baro_temp_celcius;float baro_pressure_pa;float rho;",
);
const MAGNETOMETER: Topic = topic(
    "vehicle_magnetometer",
    200,
    "uint64_t timestamp;uint64_t timestamp_sample;uint32_t device_id;float[3] magnetometer_ga;",
);
const SENSOR_GPS: Topic = topic(
    "sensor_gps",
    125,
    "uint64_t timestamp;uint64_t timestamp_sample;uint32_t device_id;double latitude_deg;\
     double longitude_deg;double altitude_msl_m;double altitude_ellipsoid_m;\
     float s_variance_m_s;float c_variance_rad;float eph;float epv;float hdop;float vdop;\
     float vel_m_s;float vel_n_m_s;float vel_e_m_s;float vel_d_m_s;float cog_rad;\
     bool vel_ned_valid;uint8_t fix_type;uint8_t satellites_used;",
);

/// Every topic, in subscription order (message id = index).
const TOPICS: [&Topic; 19] = [
    &ATTITUDE,
    &ANGULAR_VELOCITY,
    &LOCAL_POSITION,
    &GLOBAL_POSITION,
    &ATTITUDE_SETPOINT,
    &TRAJECTORY_SETPOINT,
    &ACTUATOR_MOTORS,
    &BATTERY_STATUS,
    &VEHICLE_STATUS,
    &LAND_DETECTED,
    &WRENCH_ESTIMATE,
    &CONTROL_WRENCH,
    &SIM_TRUTH,
    &WIND,
    &SIM_WIND,
    &SENSOR_COMBINED,
    &AIR_DATA,
    &MAGNETOMETER,
    &SENSOR_GPS,
];

/// Message ids (indices into [`TOPICS`]).
mod id {
    pub(super) const ATTITUDE: u16 = 0;
    pub(super) const ANGULAR_VELOCITY: u16 = 1;
    pub(super) const LOCAL_POSITION: u16 = 2;
    pub(super) const GLOBAL_POSITION: u16 = 3;
    pub(super) const ATTITUDE_SETPOINT: u16 = 4;
    pub(super) const TRAJECTORY_SETPOINT: u16 = 5;
    pub(super) const ACTUATOR_MOTORS: u16 = 6;
    pub(super) const BATTERY_STATUS: u16 = 7;
    pub(super) const VEHICLE_STATUS: u16 = 8;
    pub(super) const LAND_DETECTED: u16 = 9;
    pub(super) const WRENCH_ESTIMATE: u16 = 10;
    pub(super) const CONTROL_WRENCH: u16 = 11;
    pub(super) const SIM_TRUTH: u16 = 12;
    pub(super) const WIND: u16 = 13;
    pub(super) const SIM_WIND: u16 = 14;
    pub(super) const SENSOR_COMBINED: u16 = 15;
    pub(super) const AIR_DATA: u16 = 16;
    pub(super) const MAGNETOMETER: u16 = 17;
    pub(super) const SENSOR_GPS: u16 = 18;
}

/// Air density [kg/m^3] from pressure [Pa] and temperature [degC]:
/// `rho = p / (R T)`, `R` = 287.1 J/(kg K) (PX4's `vehicle_air_data`).
fn air_density(pressure_pa: f64, temperature_c: f64) -> f64 {
    pressure_pa / (287.1 * (temperature_c + 273.15))
}

/// The ULog level of a STATUSTEXT severity (both are syslog's numbers).
#[must_use]
pub fn log_level(severity: Severity) -> LogLevel {
    match severity {
        Severity::Emergency => LogLevel::Emergency,
        Severity::Critical => LogLevel::Critical,
        Severity::Error => LogLevel::Error,
        Severity::Warning => LogLevel::Warning,
        Severity::Notice => LogLevel::Notice,
        Severity::Info => LogLevel::Info,
    }
}

fn ulog_value(v: ParamValue) -> Value {
    match v {
        ParamValue::Int32(i) => Value::I32(i),
        ParamValue::Real32(f) => Value::F32(f),
    }
}

/// `EST_ORDER` (validated 1..20 by the parameter table).
fn est_order(store: &ParamStore) -> u8 {
    u8::try_from(store.int(Param::EST_ORDER)).unwrap_or(0)
}

/// Simulated seconds to ULog microseconds (rounded).
fn us(t_s: f64) -> u64 {
    (t_s * 1e6).round().max(0.0) as u64
}

/// The (w, x, y, z) components of a quaternion, PX4's order.
fn wxyz(q: &UnitQuaternion<f64>) -> [f64; 4] {
    [q.w, q.i, q.j, q.k]
}

fn v3(v: &Vector3<f64>) -> [f64; 3] {
    [v.x, v.y, v.z]
}

/// What `vehicle_status` and `vehicle_land_detected` last logged.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Status {
    armed: bool,
    mode: FlightMode,
    failsafe: bool,
    landed: bool,
}

/// One vehicle's flight as a ULog, written to `W`.
#[derive(Debug)]
pub struct FlightUlog<W: Write> {
    ulog: UlogWriter<W>,
    /// `interval_ms` of each topic in steps (0: on change).
    every: [u64; TOPICS.len()],
    /// The full-thrust rotor speed [rad/s] (`actuator_motors` = (w / w_max)^2).
    speed_max_rad_s: f64,
    rotor_count: usize,
    /// Each rotor's motor number, from rotor 1: `actuator_motors.control[N - 1]`
    /// is motor N, as on PX4 ([`crate::airframe::RotorGeometry::motor`]).
    motors: Vec<usize>,
    /// What the status topics last logged.
    last: Option<Status>,
    /// Every parameter's value as last logged (by index).
    params: Vec<ParamValue>,
    /// The estimator's order `r` (`EST_ORDER` in force).
    order: u8,
    /// The sample time [s] each raw sensor topic last logged (IMU,
    /// barometer, magnetometer, GNSS).
    raw_logged: [f64; 4],
}

impl<W: Write> FlightUlog<W> {
    /// Start the log of vehicle `vehicle` at the core's current instant:
    /// header, formats, info (`sys_name` "rotorpilot", `ver_sw`, the
    /// airframe, `time_ref_utc` 0), every parameter of `params`, one
    /// subscription per topic.
    ///
    /// # Errors
    /// Writing fails.
    pub fn new(w: W, params: &ParamStore, core: &Lockstep<Autopilot>, vehicle: usize) -> io::Result<Self> {
        let dt = core.dt_s();
        let mut ulog = UlogWriter::new(w, us(core.time_s()))?;
        for t in TOPICS {
            ulog.format(&t.format)?;
        }
        let pilot = core.pilot(vehicle);
        let airframe = pilot.airframe();
        ulog.info_str("sys_name", "rotorpilot")?;
        ulog.info_str("ver_sw", env!("CARGO_PKG_VERSION"))?;
        ulog.info_str("ver_hw", "ROTORPILOT_SITL")?;
        ulog.info_str("sys_os_name", std::env::consts::OS)?;
        ulog.info_str("rotorpilot_airframe", &airframe.name)?;
        ulog.info("time_ref_utc", Value::I32(0))?;
        for (spec, value) in params.iter() {
            ulog.parameter(spec.name, ulog_value(value))?;
        }
        for t in TOPICS {
            ulog.add_logged(&t.format, 0)?;
        }
        let mut every = [0; TOPICS.len()];
        for (e, t) in every.iter_mut().zip(TOPICS) {
            if t.interval_ms > 0 {
                *e = ((f64::from(t.interval_ms) * 1e-3 / dt).round() as u64).max(1);
            }
        }
        Ok(Self {
            ulog,
            every,
            speed_max_rad_s: airframe.rotor.speed_max_rad_s,
            rotor_count: airframe.rotor_count().min(MOTORS),
            motors: airframe.rotors.iter().map(|r| r.motor).collect(),
            last: None,
            params: params.iter().map(|(_, v)| v).collect(),
            order: est_order(params),
            raw_logged: [f64::NEG_INFINITY; 4],
        })
    }

    /// Log every parameter whose value differs from the one last logged
    /// ('P' in the data section, as PX4 logs a change in flight; readers
    /// date it by the data before it). Call after a parameter change is
    /// applied (the daemon looks every 0.1 s of simulated time).
    ///
    /// # Errors
    /// Writing fails.
    pub fn parameters(&mut self, store: &ParamStore) -> io::Result<()> {
        for (i, (spec, value)) in store.iter().enumerate() {
            if self.params.get(i) != Some(&value) {
                self.ulog.parameter(spec.name, ulog_value(value))?;
                if let Some(old) = self.params.get_mut(i) {
                    *old = value;
                }
            }
        }
        self.order = est_order(store);
        Ok(())
    }

    fn due(&self, topic: u16, k: u64) -> bool {
        let e = self.every[usize::from(topic)];
        e > 0 && k.is_multiple_of(e)
    }

    /// Log the raw sensors' samples that are new and due (module doc).
    fn raw_sensors(&mut self, raw: &RawSensorReadings) -> io::Result<()> {
        // a sample is due when at least its topic's interval after the last logged
        let mut due = |slot: usize, topic: &Topic, time_s: f64| {
            let due = time_s - self.raw_logged[slot] >= f64::from(topic.interval_ms) * 1e-3 - 1e-9;
            if due {
                self.raw_logged[slot] = time_s;
            }
            due
        };
        if let (Some(a), Some(g)) = (raw.accel, raw.gyro)
            && due(0, &SENSOR_COMBINED, g.time_s)
        {
            let dt_us = (1e6 / crate::sim::raw_sensors::IMU_RATE_HZ) as u32;
            let s = Sample::new(us(g.time_s))
                .f32s(&v3(&g.frd))
                .u32(dt_us)
                .i32((us(a.time_s) as i64 - us(g.time_s) as i64) as i32)
                .f32s(&v3(&a.frd))
                .u32(dt_us)
                .u8(0)
                .u8(0);
            self.ulog.data(id::SENSOR_COMBINED, &s)?;
        }
        if let Some(b) = raw.baro
            && due(1, &AIR_DATA, b.time_s)
        {
            let t = us(b.time_s);
            let s = Sample::new(t)
                .u64(t)
                .u32(DEVICE_ID)
                .f32(crate::geo::pressure_altitude_m(b.pressure_pa))
                .f32(b.temperature_c)
                .f32(b.pressure_pa)
                .f32(air_density(b.pressure_pa, b.temperature_c));
            self.ulog.data(id::AIR_DATA, &s)?;
        }
        if let Some(m) = raw.mag
            && due(2, &MAGNETOMETER, m.time_s)
        {
            let t = us(m.time_s);
            let s = Sample::new(t).u64(t).u32(DEVICE_ID).f32s(&v3(&m.frd));
            self.ulog.data(id::MAGNETOMETER, &s)?;
        }
        if let Some(g) = raw.gnss
            && due(3, &SENSOR_GPS, g.delivered_s)
        {
            let v = &g.velocity_ned;
            let s = Sample::new(us(g.delivered_s))
                .u64(us(g.time_s))
                .u32(DEVICE_ID)
                .f64(g.lat_deg)
                .f64(g.lon_deg)
                .f64(g.alt_amsl_m)
                .f64(g.alt_amsl_m)
                .f32(g.speed_accuracy_m_s)
                .f32(GPS_COURSE_VARIANCE_RAD)
                .f32(g.eph_m)
                .f32(g.epv_m)
                .f32(g.hdop)
                .f32(g.vdop)
                .f32(v.xy().norm())
                .f32(v.x)
                .f32(v.y)
                .f32(v.z)
                .f32(v.y.atan2(v.x))
                .bool(true)
                .u8(match g.fix {
                    GpsFix::None => 0,
                    GpsFix::Fix3d => 3,
                })
                .u8(g.satellites);
            self.ulog.data(id::SENSOR_GPS, &s)?;
        }
        Ok(())
    }

    /// Log what is due after a step of the core (decimated by the step
    /// index of the step's instant `t_k`).
    ///
    /// # Errors
    /// Writing fails.
    pub fn on_step(&mut self, core: &mut Lockstep<Autopilot>, vehicle: usize) -> io::Result<()> {
        let dt = core.dt_s();
        let step = core.last_step(vehicle);
        let m = *step.measurement;
        let k = (m.time_s / dt).round() as u64;
        let t = us(m.time_s);
        let c = step.control;
        if self.due(id::ATTITUDE, k) {
            let s = Sample::new(t).u64(t).f32s(&wxyz(&m.attitude));
            self.ulog.data(id::ATTITUDE, &s)?;
        }
        if self.due(id::ANGULAR_VELOCITY, k) {
            let s = Sample::new(t).u64(t).f32s(&v3(&m.rate_frd));
            self.ulog.data(id::ANGULAR_VELOCITY, &s)?;
        }
        if self.due(id::ATTITUDE_SETPOINT, k) {
            let max = core.pilot(vehicle).max_thrust_n();
            let thrust = if max > 0.0 { c.command.thrust_n / max } else { 0.0 };
            let s = Sample::new(t)
                .f32(c.reference.yaw_rate_rad_s)
                .f32s(&wxyz(&c.attitude_sp))
                // normalised, along body z (FRD): upward thrust is negative
                .f32s(&[0.0, 0.0, -thrust]);
            self.ulog.data(id::ATTITUDE_SETPOINT, &s)?;
        }
        if self.due(id::TRAJECTORY_SETPOINT, k) && c.reference != Reference::default() {
            let r = &c.reference;
            let s = Sample::new(t)
                .f32s(&v3(&r.position_ned))
                .f32s(&v3(&r.velocity_ned))
                .f32s(&v3(&r.acceleration_ned))
                .f32s(&v3(&r.jerk_ned))
                .f32(r.yaw_rad)
                .f32(r.yaw_rate_rad_s);
            self.ulog.data(id::TRAJECTORY_SETPOINT, &s)?;
        }
        if self.due(id::ACTUATOR_MOTORS, k) {
            let mut control = [f64::NAN; MOTORS];
            match c.actuator {
                ActuatorCommand::Stop => control[..self.rotor_count].fill(0.0),
                ActuatorCommand::RotorSpeeds(w) => {
                    for (&motor, w) in self.motors.iter().zip(w.iter()).take(self.rotor_count) {
                        // thrust over full thrust: T = c_T w^2
                        if let Some(u) = control.get_mut(motor - 1) {
                            *u = (w / self.speed_max_rad_s).powi(2).clamp(0.0, 1.0);
                        }
                    }
                }
                // a wrench acts directly (ideal actuation): no rotor commands
                ActuatorCommand::Wrench(_) => {}
            }
            let s = Sample::new(t).u64(t).u16(0).f32s(&control);
            self.ulog.data(id::ACTUATOR_MOTORS, &s)?;
        }
        if self.due(id::WRENCH_ESTIMATE, k) {
            let e = &c.estimate;
            let s = Sample::new(t)
                .f32s(&v3(&e.force_ned))
                .f32s(&v3(&e.torque_frd))
                .f32(e.mass_kg)
                .u8(self.order);
            self.ulog.data(id::WRENCH_ESTIMATE, &s)?;
        }
        if self.due(id::CONTROL_WRENCH, k) {
            let s = Sample::new(t)
                .f32(c.command.thrust_n)
                .f32s(&v3(&c.command.torque_frd))
                .f32(c.applied.thrust_n)
                .f32s(&v3(&c.applied.torque_frd))
                .bool(c.saturated);
            self.ulog.data(id::CONTROL_WRENCH, &s)?;
        }
        if self.due(id::SIM_TRUTH, k) {
            let w = step.world;
            let s = Sample::new(t)
                .f32s(&v3(&w.truth.position_ned))
                .f32s(&v3(&w.truth.velocity_ned))
                .f32s(&wxyz(&w.truth.attitude))
                .f32s(&v3(&w.truth.rate_frd))
                .f32s(&v3(&w.external.force_ned))
                .f32s(&v3(&w.external.torque_frd))
                .f32(w.true_mass_kg);
            self.ulog.data(id::SIM_TRUTH, &s)?;
        }
        if self.due(id::SIM_WIND, k) {
            let w = step.world;
            let s = Sample::new(t)
                .f32s(&v3(&w.wind_ned))
                .f32s(&v3(&w.aero.force_ned))
                .f32s(&v3(&w.aero.torque_frd));
            self.ulog.data(id::SIM_WIND, &s)?;
        }
        if core.world().raw_sensors_enabled(vehicle) {
            let raw = *core.world().raw_readings(vehicle);
            self.raw_sensors(&raw)?;
        }
        let pilot = core.pilot(vehicle);
        if self.due(id::WIND, k)
            && let Some(w) = pilot.wind()
        {
            let tw = us(w.time_s);
            let s = Sample::new(tw)
                .u64(tw)
                .f32(w.wind_ned.x)
                .f32(w.wind_ned.y)
                .f32(w.variance_ne.x)
                .f32(w.variance_ne.y)
                .f32s(&[0.0; 4]);
            self.ulog.data(id::WIND, &s)?;
        }
        let now = Status {
            armed: pilot.armed(),
            mode: pilot.mode(),
            failsafe: pilot.failsafe_in_force().is_some(),
            landed: pilot.landed_state() == LandedState::OnGround,
        };
        let second = k.is_multiple_of(((1.0 / dt).round() as u64).max(1));
        let status_due = second
            || self
                .last
                .is_none_or(|l| l.armed != now.armed || l.mode != now.mode || l.failsafe != now.failsafe);
        let land_due = second || self.last.is_none_or(|l| l.landed != now.landed);
        let tel_due = status_due
            || self.due(id::LOCAL_POSITION, k)
            || self.due(id::GLOBAL_POSITION, k)
            || self.due(id::BATTERY_STATUS, k);
        if !(tel_due || land_due) {
            return Ok(());
        }
        // the autopilot's telemetry at the instant after the step
        let tel = core.telemetry(vehicle);
        let tt = us(tel.time_s);
        if self.due(id::LOCAL_POSITION, k) {
            let xy = tel.gps_fix == GpsFix::Fix3d;
            let (_, _, heading) = tel.attitude.euler_angles();
            let (p, v, acc) = (&tel.position_ned, &tel.velocity_ned, &tel.acceleration_ned);
            let s = Sample::new(tt)
                .u64(tt)
                .f64(tel.origin.lat_deg)
                .f64(tel.origin.lon_deg)
                .f32s(&v3(p))
                .f32s(&v3(v))
                .f32(v.z)
                .f32s(&v3(acc))
                .f32(heading)
                .f32(tel.origin.alt_amsl_m)
                .bool(xy)
                .bool(true)
                .bool(xy)
                .bool(true)
                .bool(xy)
                .bool(true);
            self.ulog.data(id::LOCAL_POSITION, &s)?;
        }
        if self.due(id::GLOBAL_POSITION, k) {
            let xy = tel.gps_fix == GpsFix::Fix3d;
            let s = Sample::new(tt)
                .u64(tt)
                .f64(tel.global.lat_deg)
                .f64(tel.global.lon_deg)
                .f32(tel.global.alt_amsl_m)
                .bool(xy)
                .bool(true);
            self.ulog.data(id::GLOBAL_POSITION, &s)?;
        }
        if self.due(id::BATTERY_STATUS, k) {
            let s = Sample::new(tt)
                .f32(tel.battery_voltage_v)
                .f32(tel.battery_current_a)
                .f32(tel.battery_consumed_mah)
                .f32(tel.battery_remaining)
                .bool(true)
                // PX4's BATTERY_WARNING_NONE/LOW/CRITICAL/EMERGENCY
                .u8(tel.battery_warning as u8);
            self.ulog.data(id::BATTERY_STATUS, &s)?;
        }
        if status_due {
            let s = Sample::new(tt)
                // ARMING_STATE_DISARMED = 1, ARMED = 2
                .u8(if tel.armed { 2 } else { 1 })
                .u8(tel.mode.nav_state())
                // VEHICLE_TYPE_ROTARY_WING
                .u8(1)
                .bool(tel.prearm_ok)
                .bool(tel.failsafe);
            self.ulog.data(id::VEHICLE_STATUS, &s)?;
        }
        if land_due {
            let s = Sample::new(tt).bool(tel.landed == LandedState::OnGround);
            self.ulog.data(id::LAND_DETECTED, &s)?;
        }
        self.last = Some(Status {
            armed: tel.armed,
            mode: tel.mode,
            failsafe: tel.failsafe,
            landed: tel.landed == LandedState::OnGround,
        });
        Ok(())
    }

    /// Log a status text ('L') at simulated time `time_s` [s], with its severity.
    ///
    /// # Errors
    /// Writing fails.
    pub fn status_text(&mut self, time_s: f64, text: &StatusText) -> io::Result<()> {
        self.ulog
            .logged_string(log_level(text.severity), us(time_s), &text.text)
    }

    /// Flush what is buffered.
    ///
    /// # Errors
    /// Flushing fails.
    pub fn flush(&mut self) -> io::Result<()> {
        self.ulog.flush()
    }

    /// Flush and hand back the writer (ULog needs no trailer).
    ///
    /// # Errors
    /// Flushing fails.
    pub fn finish(mut self) -> io::Result<W> {
        self.ulog.flush()?;
        Ok(self.ulog.into_inner())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Data messages per message id in a ULog file.
    fn data_counts(b: &[u8]) -> Vec<usize> {
        let mut counts = vec![0; TOPICS.len()];
        for (_, body) in super::super::messages(b).into_iter().filter(|(kind, _)| *kind == b'D') {
            counts[usize::from(u16::from_le_bytes([body[0], body[1]]))] += 1;
        }
        counts
    }

    #[test]
    fn a_second_on_the_ground_is_decimated_to_the_topic_rates() {
        let (mut core, params) = crate::lockstep::test_quad();
        let mut log = FlightUlog::new(Vec::new(), &params, &core, 0).unwrap();
        for _ in 0..1000 {
            core.step();
            log.on_step(&mut core, 0).unwrap();
        }
        let counts = data_counts(&log.finish().unwrap());
        // steps at t_k = 0 .. 0.999 s: one sample every interval from t = 0
        assert_eq!(counts[usize::from(id::ATTITUDE)], 20);
        assert_eq!(counts[usize::from(id::ANGULAR_VELOCITY)], 50);
        assert_eq!(counts[usize::from(id::LOCAL_POSITION)], 10);
        assert_eq!(counts[usize::from(id::GLOBAL_POSITION)], 5);
        assert_eq!(counts[usize::from(id::ACTUATOR_MOTORS)], 10);
        assert_eq!(counts[usize::from(id::SIM_TRUTH)], 50);
        // nothing changes disarmed on the ground: once, at t = 0
        assert_eq!(counts[usize::from(id::VEHICLE_STATUS)], 1);
        assert_eq!(counts[usize::from(id::LAND_DETECTED)], 1);
        // disarmed: no reference is tracked
        assert_eq!(counts[usize::from(id::TRAJECTORY_SETPOINT)], 0);
        // on the ground: no wind estimate
        assert_eq!(counts[usize::from(id::WIND)], 0);
        assert_eq!(counts[usize::from(id::SIM_WIND)], 10);
        // the raw sensors are not simulated: none of their topics
        for raw in [id::SENSOR_COMBINED, id::AIR_DATA, id::MAGNETOMETER, id::SENSOR_GPS] {
            assert_eq!(counts[usize::from(raw)], 0);
        }
    }

    #[test]
    fn the_raw_sensor_topics_at_their_rates_and_an_off_barometer_silent() {
        let (mut core, params) = crate::lockstep::test_quad();
        core.enable_raw_sensors(0);
        let mut log = FlightUlog::new(Vec::new(), &params, &core, 0).unwrap();
        for _ in 0..1000 {
            core.step();
            log.on_step(&mut core, 0).unwrap();
        }
        let counts = data_counts(&log.finish().unwrap());
        // samples of the instants the 1000 steps drew, 0 .. 0.999 s (an
        // instant's are drawn in its step, never by the log): the IMU's
        // every 20 ms, the barometer's and the magnetometer's every 200 ms,
        // every GNSS fix delivered from 125 ms (the one taken at 0 s)
        assert_eq!(counts[usize::from(id::SENSOR_COMBINED)], 50);
        assert_eq!(counts[usize::from(id::AIR_DATA)], 5);
        assert_eq!(counts[usize::from(id::MAGNETOMETER)], 5);
        assert_eq!(counts[usize::from(id::SENSOR_GPS)], 7);
        let (mut core, params) = crate::lockstep::test_quad();
        core.enable_raw_sensors(0);
        let off = crate::lockstep::failure::FailureInjection {
            unit: crate::lockstep::failure::UNIT_BARO,
            kind: crate::lockstep::failure::TYPE_OFF,
            instance: 0,
        };
        assert_eq!(core.inject_failure(0, off), crate::autopilot::CommandOutcome::Accepted);
        let mut log = FlightUlog::new(Vec::new(), &params, &core, 0).unwrap();
        for _ in 0..1000 {
            core.step();
            log.on_step(&mut core, 0).unwrap();
        }
        let counts = data_counts(&log.finish().unwrap());
        assert_eq!(counts[usize::from(id::AIR_DATA)], 0);
        assert_eq!(counts[usize::from(id::SENSOR_COMBINED)], 50);
    }

    /// `actuator_motors.control[N - 1]` is motor N, PX4's numbering: on the
    /// hexa, whose motor 1 is its file's rotor 2, the motor switched off
    /// (taken out of the allocation, commanded idle) is `control[0]`, and
    /// its opposite, motor 2 (rotor 5), which the hover without it idles, `control[1]`.
    #[test]
    fn actuator_motors_count_by_motor_number() {
        use crate::autopilot::{AutopilotCommand, CommandOutcome};
        use crate::lockstep::failure::{FailureInjection, TYPE_OFF, UNIT_MOTOR};
        let airframe = crate::airframe::Airframe::load("hexa").unwrap();
        assert_eq!(airframe.rotor_of_motor(1), Some(1));
        let mut params = ParamStore::new(&airframe);
        params.set("RP_NAV_SRC", ParamValue::Int32(0)).unwrap();
        let mut core = Lockstep::one_vehicle(
            &airframe,
            crate::geo::GeoPoint::PX4_SITL_HOME,
            &params,
            crate::sim::SensorConfig::default(),
        )
        .unwrap();
        for _ in 0..1000 {
            core.step();
        }
        assert_eq!(
            core.command(0, AutopilotCommand::Arm { force: false }),
            CommandOutcome::Accepted
        );
        let takeoff = AutopilotCommand::Takeoff { altitude_amsl_m: None };
        assert_eq!(core.command(0, takeoff), CommandOutcome::Accepted);
        for _ in 0..10_000 {
            core.step();
        }
        let off = FailureInjection {
            unit: UNIT_MOTOR,
            kind: TYPE_OFF,
            instance: 1,
        };
        assert_eq!(core.inject_failure(0, off), CommandOutcome::Accepted);
        for _ in 0..1000 {
            core.step();
        }
        let mut log = FlightUlog::new(Vec::new(), &params, &core, 0).unwrap();
        for _ in 0..1000 {
            core.step();
            log.on_step(&mut core, 0).unwrap();
        }
        let ulog = super::super::read::read_ulog(&log.finish().unwrap(), "test.ulg").unwrap();
        let motors = ulog.topic("actuator_motors").unwrap();
        let last = |k: usize| *motors.field(&format!("control[{k}]")).unwrap().last().unwrap();
        assert!(last(0) < 0.02, "motor 1 runs: {}", last(0));
        assert!(last(1) < 0.02, "motor 2 runs: {}", last(1));
        for k in 2..6 {
            assert!(last(k) > 0.2, "motor {} idles: {}", k + 1, last(k));
        }
        assert!(last(6).is_nan(), "no motor 7");
    }

    #[test]
    fn topic_ids_follow_the_table() {
        let names = [
            (id::ATTITUDE, "vehicle_attitude"),
            (id::ANGULAR_VELOCITY, "vehicle_angular_velocity"),
            (id::LOCAL_POSITION, "vehicle_local_position"),
            (id::GLOBAL_POSITION, "vehicle_global_position"),
            (id::ATTITUDE_SETPOINT, "vehicle_attitude_setpoint"),
            (id::TRAJECTORY_SETPOINT, "trajectory_setpoint"),
            (id::ACTUATOR_MOTORS, "actuator_motors"),
            (id::BATTERY_STATUS, "battery_status"),
            (id::VEHICLE_STATUS, "vehicle_status"),
            (id::LAND_DETECTED, "vehicle_land_detected"),
            (id::WRENCH_ESTIMATE, "rotorpilot_wrench_estimate"),
            (id::CONTROL_WRENCH, "rotorpilot_control_wrench"),
            (id::SIM_TRUTH, "rotorpilot_sim_truth"),
            (id::WIND, "wind"),
            (id::SIM_WIND, "rotorpilot_sim_wind"),
            (id::SENSOR_COMBINED, "sensor_combined"),
            (id::AIR_DATA, "vehicle_air_data"),
            (id::MAGNETOMETER, "vehicle_magnetometer"),
            (id::SENSOR_GPS, "sensor_gps"),
        ];
        for (i, name) in names {
            assert_eq!(TOPICS[usize::from(i)].format.name, name);
        }
        for t in TOPICS {
            assert!(t.format.fields.starts_with("uint64_t timestamp;"), "{}", t.format.name);
            assert!(t.format.size().is_some(), "{}", t.format.name);
        }
        assert!(
            ACTUATOR_MOTORS
                .format
                .fields
                .contains(&format!("float[{MOTORS}] control;"))
        );
    }
}
