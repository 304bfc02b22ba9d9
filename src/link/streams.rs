//! Telemetry streams: which messages a link sends unasked, at what rate, and
//! how each is built from a [`Snapshot`] (the autopilot's [`Telemetry`] and
//! the world's injected truth).
//!
//! Rates are in wall time (a stream at 50 Hz sends 50 messages per wall
//! second whatever `--speed` is), so traffic and CPU stay bounded when the
//! simulation runs fast; the timestamps inside are simulated time. The
//! default rates are PX4's (`docs/mavlink.md` section 4) for the GCS link (normal
//! mode) and the API link (onboard mode). SET_MESSAGE_INTERVAL changes a
//! stream on the link it arrives on only, as in PX4.
//!
//! Global position is computed by the autopilot from local NED around the
//! NED origin with the flat-earth model of [`crate::geo`] (fine within a few
//! kilometres of home).

use std::time::{Duration, Instant};

use mavlink::MessageData;
use mavlink::dialects::common::{
    ACTUATOR_OUTPUT_STATUS_DATA, ALTITUDE_DATA, ATTITUDE_DATA, ATTITUDE_QUATERNION_DATA, BATTERY_STATUS_DATA,
    CURRENT_MODE_DATA, DEBUG_VECT_DATA, ESTIMATOR_STATUS_DATA, EXTENDED_SYS_STATE_DATA, EstimatorStatusFlags,
    GLOBAL_POSITION_INT_DATA, GPS_RAW_INT_DATA, GpsFixType, HEARTBEAT_DATA, HIGHRES_IMU_DATA,
    HIL_STATE_QUATERNION_DATA, HOME_POSITION_DATA, HighresImuUpdatedFlags, LOCAL_POSITION_NED_DATA,
    MISSION_CURRENT_DATA, MavAutopilot, MavBatteryFunction, MavBatteryType, MavEstimatorType, MavFrame, MavLandedState,
    MavMessage, MavModeFlag, MavState, MavSysStatusSensor, MavType, MavVtolState, MissionState as MavMissionState,
    NAMED_VALUE_FLOAT_DATA, ODOMETRY_DATA, ORBIT_EXECUTION_STATUS_DATA, SCALED_IMU_DATA, SCALED_PRESSURE_DATA,
    SYS_STATUS_DATA, SYSTEM_TIME_DATA, VFR_HUD_DATA, VIBRATION_DATA, WIND_COV_DATA,
};

use super::convert;
use crate::autopilot::{
    BatteryWarning, FlightMode, ImuVibration, LandedState, MissionState, NavigationReport, RotorOutputs, Telemetry,
    VehicleType,
};
use crate::lockstep::Snapshot;
use crate::signals::{GnssSample, GpsFix, RawSensorReadings};

/// A message the vehicle streams.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Stream {
    /// HEARTBEAT (0).
    Heartbeat,
    /// SYS_STATUS (1).
    SysStatus,
    /// SYSTEM_TIME (2).
    SystemTime,
    /// GPS_RAW_INT (24): the receiver's own solution and accuracies.
    GpsRawInt,
    /// SCALED_IMU (26): the raw IMU and magnetometer in PX4's integer units.
    ScaledImu,
    /// SCALED_PRESSURE (29): the barometer.
    ScaledPressure,
    /// HIGHRES_IMU (105): the raw IMU, magnetometer and barometer (SI units).
    HighresImu,
    /// ATTITUDE (30).
    Attitude,
    /// ATTITUDE_QUATERNION (31).
    AttitudeQuaternion,
    /// LOCAL_POSITION_NED (32).
    LocalPositionNed,
    /// GLOBAL_POSITION_INT (33).
    GlobalPositionInt,
    /// HIL_STATE_QUATERNION (115): the world's true state, PX4 SITL's ground
    /// truth; off unless a client asks for it (MAVSDK's `set_rate_ground_truth`).
    HilStateQuaternion,
    /// MISSION_CURRENT (42); also sent at once on change ([`super::mission`]).
    MissionCurrent,
    /// VFR_HUD (74).
    VfrHud,
    /// ALTITUDE (141).
    Altitude,
    /// BATTERY_STATUS (147).
    BatteryStatus,
    /// ORBIT_EXECUTION_STATUS (360): sent only while orbiting.
    OrbitExecutionStatus,
    /// HOME_POSITION (242).
    HomePosition,
    /// EXTENDED_SYS_STATE (245).
    ExtendedSysState,
    /// DEBUG_VECT (250): `EST_FORCE` and `EST_TORQUE`, and the injected truth
    /// `SIM_FORCE` and `SIM_TORQUE`.
    DebugVect,
    /// NAMED_VALUE_FLOAT (251): `EST_MASS`, and the true `SIM_MASS`.
    NamedValueFloat,
    /// WIND_COV (231): the wind the vehicle feels, once estimated ([`wind_cov`]).
    WindCov,
    /// ESTIMATOR_STATUS (230): the navigation solution's flags, test ratios
    /// and accuracies ([`estimator_status`]).
    EstimatorStatus,
    /// VIBRATION (241): the IMU's vibration metrics ([`vibration`]), from
    /// the raw sensors.
    Vibration,
    /// ODOMETRY (331): the navigation solution with its covariance ([`odometry`]).
    Odometry,
    /// CURRENT_MODE (436): the mode as a custom and a standard mode ([`current_mode`]).
    CurrentMode,
    /// ACTUATOR_OUTPUT_STATUS (375): each motor output as PX4 SITL's PWM
    /// outputs read ([`actuator_output_status`]); off unless a client asks
    /// (MAVSDK's `set_rate_actuator_output_status`).
    ActuatorOutputStatus,
}

impl Stream {
    /// Every stream.
    pub const ALL: [Stream; 27] = [
        Stream::Heartbeat,
        Stream::SysStatus,
        Stream::SystemTime,
        Stream::GpsRawInt,
        Stream::ScaledImu,
        Stream::ScaledPressure,
        Stream::HighresImu,
        Stream::Attitude,
        Stream::AttitudeQuaternion,
        Stream::LocalPositionNed,
        Stream::GlobalPositionInt,
        Stream::HilStateQuaternion,
        Stream::MissionCurrent,
        Stream::VfrHud,
        Stream::Altitude,
        Stream::BatteryStatus,
        Stream::OrbitExecutionStatus,
        Stream::HomePosition,
        Stream::ExtendedSysState,
        Stream::DebugVect,
        Stream::NamedValueFloat,
        Stream::WindCov,
        Stream::EstimatorStatus,
        Stream::Vibration,
        Stream::Odometry,
        Stream::CurrentMode,
        Stream::ActuatorOutputStatus,
    ];

    /// MAVLink message id.
    #[must_use]
    pub fn message_id(self) -> u32 {
        match self {
            Stream::Heartbeat => HEARTBEAT_DATA::ID,
            Stream::SysStatus => SYS_STATUS_DATA::ID,
            Stream::SystemTime => SYSTEM_TIME_DATA::ID,
            Stream::GpsRawInt => GPS_RAW_INT_DATA::ID,
            Stream::ScaledImu => SCALED_IMU_DATA::ID,
            Stream::ScaledPressure => SCALED_PRESSURE_DATA::ID,
            Stream::HighresImu => HIGHRES_IMU_DATA::ID,
            Stream::Attitude => ATTITUDE_DATA::ID,
            Stream::AttitudeQuaternion => ATTITUDE_QUATERNION_DATA::ID,
            Stream::LocalPositionNed => LOCAL_POSITION_NED_DATA::ID,
            Stream::GlobalPositionInt => GLOBAL_POSITION_INT_DATA::ID,
            Stream::HilStateQuaternion => HIL_STATE_QUATERNION_DATA::ID,
            Stream::MissionCurrent => MISSION_CURRENT_DATA::ID,
            Stream::VfrHud => VFR_HUD_DATA::ID,
            Stream::Altitude => ALTITUDE_DATA::ID,
            Stream::BatteryStatus => BATTERY_STATUS_DATA::ID,
            Stream::OrbitExecutionStatus => ORBIT_EXECUTION_STATUS_DATA::ID,
            Stream::HomePosition => HOME_POSITION_DATA::ID,
            Stream::ExtendedSysState => EXTENDED_SYS_STATE_DATA::ID,
            Stream::DebugVect => DEBUG_VECT_DATA::ID,
            Stream::NamedValueFloat => NAMED_VALUE_FLOAT_DATA::ID,
            Stream::WindCov => WIND_COV_DATA::ID,
            Stream::EstimatorStatus => ESTIMATOR_STATUS_DATA::ID,
            Stream::Vibration => VIBRATION_DATA::ID,
            Stream::Odometry => ODOMETRY_DATA::ID,
            Stream::CurrentMode => CURRENT_MODE_DATA::ID,
            Stream::ActuatorOutputStatus => ACTUATOR_OUTPUT_STATUS_DATA::ID,
        }
    }

    /// Whether its message is built from the raw sensors (which run only
    /// once something reads them).
    #[must_use]
    pub fn needs_raw_sensors(self) -> bool {
        matches!(
            self,
            Stream::GpsRawInt | Stream::HighresImu | Stream::ScaledImu | Stream::ScaledPressure | Stream::Vibration
        )
    }

    /// The stream sending this message id, if any.
    #[must_use]
    pub fn from_message_id(id: u32) -> Option<Stream> {
        Stream::ALL.into_iter().find(|s| s.message_id() == id)
    }
}

/// Default stream rates [Hz] of a link.
pub type Rates = Vec<(Stream, f64)>;

/// PX4's GCS link (normal mode, after the SITL overrides; WIND_COV at
/// PX4's 0.5 Hz, ESTIMATOR_STATUS 0.5 Hz, VIBRATION 0.1 Hz, CURRENT_MODE
/// 0.5 Hz, no ODOMETRY), plus the estimator streams at 10 Hz.
#[must_use]
pub fn gcs_rates() -> Rates {
    vec![
        (Stream::Heartbeat, 1.0),
        (Stream::SysStatus, 1.0),
        (Stream::SystemTime, 1.0),
        (Stream::GpsRawInt, 1.0),
        (Stream::Attitude, 50.0),
        (Stream::AttitudeQuaternion, 50.0),
        (Stream::LocalPositionNed, 50.0),
        (Stream::GlobalPositionInt, 50.0),
        (Stream::MissionCurrent, 1.0),
        (Stream::VfrHud, 4.0),
        (Stream::Altitude, 1.0),
        (Stream::BatteryStatus, 0.5),
        (Stream::OrbitExecutionStatus, 2.0),
        (Stream::HomePosition, 0.5),
        (Stream::ExtendedSysState, 1.0),
        (Stream::DebugVect, 10.0),
        (Stream::NamedValueFloat, 10.0),
        (Stream::WindCov, 0.5),
        (Stream::EstimatorStatus, 0.5),
        (Stream::Vibration, 0.1),
        (Stream::CurrentMode, 0.5),
    ]
}

/// PX4's API link (onboard mode; WIND_COV at PX4's 10 Hz, HIGHRES_IMU at
/// PX4's 50 Hz, ODOMETRY 30 Hz, ESTIMATOR_STATUS 1 Hz, VIBRATION 0.5 Hz,
/// CURRENT_MODE 0.5 Hz), plus the estimator streams at 10 Hz. SCALED_IMU and
/// SCALED_PRESSURE are off on both links, as in PX4's normal and onboard
/// modes, until a client asks.
#[must_use]
pub fn api_rates() -> Rates {
    vec![
        (Stream::Heartbeat, 1.0),
        (Stream::SysStatus, 5.0),
        (Stream::SystemTime, 1.0),
        (Stream::GpsRawInt, 5.0),
        (Stream::HighresImu, 50.0),
        (Stream::Attitude, 100.0),
        (Stream::AttitudeQuaternion, 50.0),
        (Stream::LocalPositionNed, 30.0),
        (Stream::GlobalPositionInt, 50.0),
        (Stream::MissionCurrent, 1.0),
        (Stream::VfrHud, 10.0),
        (Stream::Altitude, 10.0),
        (Stream::BatteryStatus, 0.5),
        (Stream::OrbitExecutionStatus, 5.0),
        (Stream::HomePosition, 0.5),
        (Stream::ExtendedSysState, 5.0),
        (Stream::DebugVect, 10.0),
        (Stream::NamedValueFloat, 10.0),
        (Stream::WindCov, 10.0),
        (Stream::Odometry, 30.0),
        (Stream::EstimatorStatus, 1.0),
        (Stream::Vibration, 0.5),
        (Stream::CurrentMode, 0.5),
    ]
}

/// A SET_MESSAGE_INTERVAL request.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interval {
    /// Back to the link's default rate (interval 0).
    Default,
    /// Stop the stream (interval -1).
    Disabled,
    /// Send every so often.
    Every(Duration),
}

impl Interval {
    /// Read SET_MESSAGE_INTERVAL param2 [us]: 0 default, negative stop (PX4
    /// treats any value < 0 as stop), otherwise the interval; NaN is default.
    #[must_use]
    pub fn from_param_us(us: f32) -> Interval {
        if !us.is_finite() || us == 0.0 {
            Interval::Default
        } else if us < 0.0 {
            Interval::Disabled
        } else {
            Interval::Every(Duration::try_from_secs_f64(f64::from(us) * 1e-6).unwrap_or(Duration::MAX))
        }
    }
}

fn period(hz: f64) -> Option<Duration> {
    (hz.is_finite() && hz > 0.0).then(|| Duration::try_from_secs_f64(1.0 / hz).map_or(MAX_INTERVAL, clamp_interval))
}

/// An interval within `MIN_INTERVAL..=MAX_INTERVAL`.
fn clamp_interval(d: Duration) -> Duration {
    d.clamp(MIN_INTERVAL, MAX_INTERVAL)
}

/// When each stream of one link is due.
#[derive(Clone, Debug)]
pub struct Scheduler {
    entries: Vec<Entry>,
}

#[derive(Clone, Debug)]
struct Entry {
    stream: Stream,
    default: Option<Duration>,
    interval: Option<Duration>,
    next: Instant,
    /// When it was last sent.
    last: Option<Instant>,
}

/// The shortest interval a stream may have: 5 ms (200 Hz), per stream and
/// so per peer (a link's streams go to each of its peers). The simulation
/// publishes a new snapshot every 4 ms of wall time (250 Hz), so a faster
/// stream would only repeat samples; 200 Hz is above every default rate
/// (100 Hz at most, ATTITUDE on the API link) and what MAVSDK asks for.
/// PX4 likewise caps a stream at its link's rate budget.
pub const MIN_INTERVAL: Duration = Duration::from_millis(5);
/// The longest: what MESSAGE_INTERVAL's `interval_us` (int32) can report,
/// and far from overflowing an `Instant`.
const MAX_INTERVAL: Duration = Duration::from_micros(i32::MAX as u64);

impl Scheduler {
    /// Streams at their default rates, all due at `now`.
    #[must_use]
    pub fn new(now: Instant, rates: &Rates) -> Self {
        let entries = Stream::ALL
            .iter()
            .map(|s| {
                let default = rates.iter().find(|(r, _)| r == s).and_then(|(_, hz)| period(*hz));
                Entry {
                    stream: *s,
                    default,
                    interval: default,
                    next: now,
                    last: None,
                }
            })
            .collect();
        Self { entries }
    }

    /// Change one stream's interval; the stream is next due at `now`, or
    /// [`MIN_INTERVAL`] after its last send if that is later (so that a
    /// flood of requests cannot send it faster than the floor).
    pub fn set(&mut self, now: Instant, stream: Stream, interval: Interval) {
        if let Some(e) = self.entries.iter_mut().find(|e| e.stream == stream) {
            e.interval = match interval {
                Interval::Default => e.default,
                Interval::Disabled => None,
                Interval::Every(d) => Some(clamp_interval(d)),
            };
            e.next = e.last.map_or(now, |l| now.max(l + MIN_INTERVAL));
        }
    }

    /// The current interval of a stream (`None`: not sent).
    #[must_use]
    pub fn interval(&self, stream: Stream) -> Option<Duration> {
        self.entries
            .iter()
            .find(|e| e.stream == stream)
            .and_then(|e| e.interval)
    }

    /// The streams due at `now`, each advanced to its next time. A stream
    /// that fell behind skips the missed sends rather than bursting.
    pub fn due(&mut self, now: Instant, out: &mut Vec<Stream>) {
        for e in &mut self.entries {
            let Some(iv) = e.interval else { continue };
            if now >= e.next {
                out.push(e.stream);
                e.last = Some(now);
                e.next += iv;
                if e.next <= now {
                    e.next = now + iv;
                }
            }
        }
    }

    /// The earliest time any stream is due.
    #[must_use]
    pub fn next_deadline(&self) -> Option<Instant> {
        self.entries
            .iter()
            .filter(|e| e.interval.is_some())
            .map(|e| e.next)
            .min()
    }
}

/// What identifies the vehicle in messages that carry it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Identity {
    /// System id (PX4 SITL: instance + 1).
    pub system_id: u8,
    /// Component id (1, the autopilot).
    pub component_id: u8,
}

/// Simulated time since boot [ms] (MAVLink `time_boot_ms`).
#[must_use]
pub fn time_boot_ms(t: &Telemetry) -> u32 {
    (t.time_s * 1e3) as u32
}

/// Simulated time since boot [us].
#[must_use]
pub fn time_usec(t: &Telemetry) -> u64 {
    (t.time_s * 1e6) as u64
}

/// The sensors SYS_STATUS reports present, enabled and healthy: gyro, accel,
/// mag, baro, GPS, AHRS (0x20002F), plus PREARM_CHECK (0x10000000) in
/// health when arming would pass.
pub const SENSORS: u32 = 0x0020_002F;
/// MAV_SYS_STATUS_PREARM_CHECK.
pub const PREARM_CHECK: u32 = 0x1000_0000;
/// MAV_SYS_STATUS_SENSOR_GPS: unhealthy without a fix.
pub const GPS: u32 = 0x20;

/// Build the messages of one stream.
#[must_use]
pub fn build(stream: Stream, snapshot: &Snapshot, unix_time_us: u64) -> Vec<MavMessage> {
    let t = &snapshot.telemetry;
    let ms = time_boot_ms(t);
    let us = time_usec(t);
    let (roll, pitch, yaw) = t.attitude.euler_angles();
    let rel_alt = t.global.alt_amsl_m - t.home.alt_amsl_m;
    let ground_speed = t.velocity_ned.xy().norm();
    let m = match stream {
        Stream::Heartbeat => MavMessage::HEARTBEAT(heartbeat(t)),
        Stream::CurrentMode => MavMessage::CURRENT_MODE(current_mode(t)),
        Stream::SysStatus => {
            let gps = if t.gps_fix == GpsFix::None { GPS } else { 0 };
            let health =
                (SENSORS & !gps & !battery_unhealthy(t)) | if t.prearm_ok || t.armed { PREARM_CHECK } else { 0 };
            MavMessage::SYS_STATUS(SYS_STATUS_DATA {
                onboard_control_sensors_present: MavSysStatusSensor::from_bits_retain(SENSORS | PREARM_CHECK),
                onboard_control_sensors_enabled: MavSysStatusSensor::from_bits_retain(SENSORS | PREARM_CHECK),
                onboard_control_sensors_health: MavSysStatusSensor::from_bits_retain(health),
                load: 100,
                voltage_battery: convert::sat_u16(t.battery_voltage_v * 1e3),
                current_battery: convert::sat_i16(t.battery_current_a * 100.0),
                drop_rate_comm: 0,
                errors_comm: 0,
                errors_count1: 0,
                errors_count2: 0,
                errors_count3: 0,
                errors_count4: 0,
                battery_remaining: battery_percent(t),
                // MAVLink 2 extensions: not reported (zero, cut off the wire)
                ..Default::default()
            })
        }
        Stream::SystemTime => MavMessage::SYSTEM_TIME(SYSTEM_TIME_DATA {
            time_unix_usec: unix_time_us,
            time_boot_ms: ms,
        }),
        Stream::GpsRawInt => match (&snapshot.raw.gnss, t.gps_fix) {
            (Some(g), _) => MavMessage::GPS_RAW_INT(gps_raw_int(g)),
            (None, GpsFix::None) => MavMessage::GPS_RAW_INT(gps_raw_int_no_gps()),
            // a receiver with a fix whose first solution is not out yet: PX4
            // sends nothing before its first sample
            (None, GpsFix::Fix3d) => return Vec::new(),
        },
        Stream::HighresImu => match highres_imu(&snapshot.raw) {
            Some(m) => MavMessage::HIGHRES_IMU(m),
            None => return Vec::new(),
        },
        Stream::ScaledImu => match scaled_imu(&snapshot.raw) {
            Some(m) => MavMessage::SCALED_IMU(m),
            None => return Vec::new(),
        },
        Stream::ScaledPressure => match &snapshot.raw.baro {
            Some(b) => MavMessage::SCALED_PRESSURE(SCALED_PRESSURE_DATA {
                time_boot_ms: (b.time_s * 1e3) as u32,
                press_abs: (b.pressure_pa / 100.0) as f32,
                press_diff: 0.0,
                temperature: convert::sat_i16(b.temperature_c * 100.0),
                // MAVLink 2 extension: not reported (zero, cut off the wire)
                ..Default::default()
            }),
            None => return Vec::new(),
        },
        Stream::Attitude => MavMessage::ATTITUDE(ATTITUDE_DATA {
            time_boot_ms: ms,
            roll: roll as f32,
            pitch: pitch as f32,
            yaw: yaw as f32,
            rollspeed: t.rate_frd.x as f32,
            pitchspeed: t.rate_frd.y as f32,
            yawspeed: t.rate_frd.z as f32,
        }),
        Stream::AttitudeQuaternion => MavMessage::ATTITUDE_QUATERNION(ATTITUDE_QUATERNION_DATA {
            time_boot_ms: ms,
            q1: t.attitude.w as f32,
            q2: t.attitude.i as f32,
            q3: t.attitude.j as f32,
            q4: t.attitude.k as f32,
            rollspeed: t.rate_frd.x as f32,
            pitchspeed: t.rate_frd.y as f32,
            yawspeed: t.rate_frd.z as f32,
            // MAVLink 2 extensions: not reported (zero, cut off the wire)
            ..Default::default()
        }),
        Stream::LocalPositionNed => MavMessage::LOCAL_POSITION_NED(LOCAL_POSITION_NED_DATA {
            time_boot_ms: ms,
            x: t.position_ned.x as f32,
            y: t.position_ned.y as f32,
            z: t.position_ned.z as f32,
            vx: t.velocity_ned.x as f32,
            vy: t.velocity_ned.y as f32,
            vz: t.velocity_ned.z as f32,
        }),
        Stream::GlobalPositionInt => MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
            time_boot_ms: ms,
            lat: convert::deg_e7(t.global.lat_deg),
            lon: convert::deg_e7(t.global.lon_deg),
            alt: convert::sat_i32(t.global.alt_amsl_m * 1e3),
            relative_alt: convert::sat_i32(rel_alt * 1e3),
            vx: convert::sat_i16(t.velocity_ned.x * 100.0),
            vy: convert::sat_i16(t.velocity_ned.y * 100.0),
            vz: convert::sat_i16(t.velocity_ned.z * 100.0),
            hdg: convert::heading_cdeg(yaw),
        }),
        Stream::HilStateQuaternion => MavMessage::HIL_STATE_QUATERNION(ground_truth(snapshot)),
        Stream::MissionCurrent => MavMessage::MISSION_CURRENT(mission_current(t)),
        Stream::VfrHud => MavMessage::VFR_HUD(VFR_HUD_DATA {
            airspeed: ground_speed as f32,
            groundspeed: ground_speed as f32,
            alt: t.global.alt_amsl_m as f32,
            climb: (-t.velocity_ned.z) as f32,
            heading: convert::sat_i16(f64::from(convert::heading_cdeg(yaw)) / 100.0),
            throttle: convert::sat_u16((t.throttle * 100.0).clamp(0.0, 100.0)),
        }),
        Stream::Altitude => MavMessage::ALTITUDE(ALTITUDE_DATA {
            time_usec: us,
            altitude_monotonic: t.global.alt_amsl_m as f32,
            altitude_amsl: t.global.alt_amsl_m as f32,
            altitude_local: (-t.position_ned.z) as f32,
            altitude_relative: rel_alt as f32,
            // flat ground at the NED origin's altitude
            altitude_terrain: t.origin.alt_amsl_m as f32,
            bottom_clearance: (t.global.alt_amsl_m - t.origin.alt_amsl_m) as f32,
        }),
        Stream::BatteryStatus => {
            let mut voltages = [u16::MAX; 10];
            voltages[0] = convert::sat_u16(t.battery_voltage_v * 1e3);
            MavMessage::BATTERY_STATUS(BATTERY_STATUS_DATA {
                current_consumed: convert::sat_i32(t.battery_consumed_mah),
                energy_consumed: -1,
                temperature: i16::MAX,
                voltages,
                current_battery: convert::sat_i16(t.battery_current_a * 100.0),
                id: 0,
                battery_function: MavBatteryFunction::MAV_BATTERY_FUNCTION_ALL,
                mavtype: MavBatteryType::MAV_BATTERY_TYPE_LIPO,
                battery_remaining: battery_percent(t),
                charge_state: convert::charge_state(t.battery_warning),
                // other MAVLink 2 extensions: not reported (zero, cut off the wire)
                ..Default::default()
            })
        }
        Stream::OrbitExecutionStatus => {
            // PX4 sends it only while its orbit task publishes
            let Some(o) = &t.orbit else { return Vec::new() };
            MavMessage::ORBIT_EXECUTION_STATUS(ORBIT_EXECUTION_STATUS_DATA {
                time_usec: us,
                radius: o.radius_m as f32,
                frame: MavFrame::MAV_FRAME_GLOBAL,
                x: convert::deg_e7(o.centre.lat_deg),
                y: convert::deg_e7(o.centre.lon_deg),
                z: o.centre.alt_amsl_m as f32,
            })
        }
        Stream::HomePosition => MavMessage::HOME_POSITION(home_position(t)),
        Stream::ExtendedSysState => MavMessage::EXTENDED_SYS_STATE(EXTENDED_SYS_STATE_DATA {
            vtol_state: MavVtolState::MAV_VTOL_STATE_UNDEFINED,
            landed_state: match t.landed {
                LandedState::OnGround => MavLandedState::MAV_LANDED_STATE_ON_GROUND,
                LandedState::InAir => MavLandedState::MAV_LANDED_STATE_IN_AIR,
                LandedState::Takeoff => MavLandedState::MAV_LANDED_STATE_TAKEOFF,
                LandedState::Landing => MavLandedState::MAV_LANDED_STATE_LANDING,
            },
        }),
        Stream::DebugVect => {
            let f = t.estimate.force_ned;
            let tq = t.estimate.torque_frd;
            let sf = snapshot.truth.force_ned;
            let st = snapshot.truth.torque_frd;
            return vec![
                debug_vect("EST_FORCE", us, [f.x, f.y, f.z]),
                debug_vect("EST_TORQUE", us, [tq.x, tq.y, tq.z]),
                debug_vect("SIM_FORCE", us, [sf.x, sf.y, sf.z]),
                debug_vect("SIM_TORQUE", us, [st.x, st.y, st.z]),
            ];
        }
        Stream::NamedValueFloat => {
            return vec![
                named_float("EST_MASS", ms, t.estimate.mass_kg),
                named_float("SIM_MASS", ms, snapshot.truth.true_mass_kg),
            ];
        }
        Stream::WindCov => return wind_cov(t).map(MavMessage::WIND_COV).into_iter().collect(),
        Stream::EstimatorStatus => MavMessage::ESTIMATOR_STATUS(estimator_status(us, &t.navigation)),
        Stream::Vibration => {
            return t
                .vibration
                .map(|v| MavMessage::VIBRATION(vibration(&v)))
                .into_iter()
                .collect();
        }
        Stream::Odometry => MavMessage::ODOMETRY(odometry(t)),
        Stream::ActuatorOutputStatus => match actuator_output_status(us, &t.rotor_outputs) {
            Some(m) => MavMessage::ACTUATOR_OUTPUT_STATUS(m),
            None => return Vec::new(),
        },
    };
    vec![m]
}

/// The output channels PX4 SITL's simulated PWM output driver has (and
/// reports as `active`), whatever the airframe uses of them.
pub const OUTPUT_CHANNELS: usize = 16;
/// A stopped motor's output [us]: the disarmed PWM (PX4's default
/// `PWM_MAIN_DISn`), also what an unused channel holds.
pub const PWM_DISARMED_US: f32 = 900.0;
/// A motor's output at idle [us] (PX4's default `PWM_MAIN_MINn`).
pub const PWM_MIN_US: f32 = 1000.0;
/// A motor's output at full speed [us] (PX4's default `PWM_MAIN_MAXn`).
pub const PWM_MAX_US: f32 = 2000.0;

/// ACTUATOR_OUTPUT_STATUS as PX4 SITL sends it from its motor outputs
/// (`ACTUATOR_OUTPUT_STATUS.hpp`), on the PWM scale its simulated output
/// driver uses with SIH and Gazebo Classic (whose typhoon_h480 PX4's
/// control-allocation test flies): `active` the driver's 16 channels,
/// channel `i` motor `i + 1`; a running motor at `1000 + 1000 u` [us] (`u`
/// its place between idle and full speed, [`RotorOutputs`]; whole
/// microseconds, cut as PX4 cuts them to an integer); a stopped one (disarmed, or taken out of
/// the allocation after a motor failure, which PX4 leaves unset) and an
/// unused channel at the disarmed 900 us; the 16 channels past those 0.
/// Stamped `time_usec`. Nothing on an airframe without motors (ideal
/// actuation), as PX4 sends nothing without an output driver.
#[must_use]
pub fn actuator_output_status(time_usec: u64, r: &RotorOutputs) -> Option<ACTUATOR_OUTPUT_STATUS_DATA> {
    if r.count == 0 {
        return None;
    }
    let mut actuator = [0.0f32; 32];
    actuator[..OUTPUT_CHANNELS].fill(PWM_DISARMED_US);
    for (out, cmd) in actuator.iter_mut().zip(&r.commands).take(r.count.min(OUTPUT_CHANNELS)) {
        if let Some(u) = cmd {
            *out = (PWM_MIN_US + (PWM_MAX_US - PWM_MIN_US) * (*u as f32).clamp(0.0, 1.0)).trunc();
        }
    }
    Some(ACTUATOR_OUTPUT_STATUS_DATA {
        time_usec,
        active: OUTPUT_CHANNELS as u32,
        actuator,
    })
}

/// GPS_RAW_INT from the receiver's solution as PX4 fills it
/// (`GPS_RAW_INT.hpp`): `eph`/`epv` are the HDOP/VDOP times 100, the
/// accuracies `h_acc`/`v_acc` [mm] and `vel_acc` [mm/s] the receiver's own,
/// the course over ground from the NED velocity.
#[must_use]
pub fn gps_raw_int(g: &GnssSample) -> GPS_RAW_INT_DATA {
    let v = &g.velocity_ned;
    let speed = v.xy().norm();
    GPS_RAW_INT_DATA {
        time_usec: (g.time_s * 1e6) as u64,
        lat: convert::deg_e7(g.lat_deg),
        lon: convert::deg_e7(g.lon_deg),
        alt: convert::sat_i32(g.alt_amsl_m * 1e3),
        eph: convert::sat_u16(g.hdop * 100.0),
        epv: convert::sat_u16(g.vdop * 100.0),
        vel: convert::sat_u16(speed * 100.0),
        cog: convert::heading_cdeg(v.y.atan2(v.x)),
        fix_type: match g.fix {
            GpsFix::None => GpsFixType::GPS_FIX_TYPE_NO_FIX,
            GpsFix::Fix3d => GpsFixType::GPS_FIX_TYPE_3D_FIX,
        },
        satellites_visible: g.satellites,
        // PX4's `sensor_gps_sim` reports its AMSL altitude as the ellipsoid's too
        alt_ellipsoid: convert::sat_i32(g.alt_amsl_m * 1e3),
        h_acc: (g.eph_m * 1e3).round() as u32,
        v_acc: (g.epv_m * 1e3).round() as u32,
        vel_acc: (g.speed_accuracy_m_s * 1e3).round() as u32,
        hdg_acc: 0,
        yaw: 0,
    }
}

/// GPS_RAW_INT with no receiver solution (the GPS OFF), as PX4's
/// `GPS_RAW_INT.hpp` sends it once its receiver fell silent: NO_GPS,
/// position 0, `eph`, `epv`, `vel` and `cog` unknown (`u16::MAX`),
/// satellites unknown (255), no accuracies. (PX4 sends it at most once a
/// second; here at the stream's rate.)
#[must_use]
pub fn gps_raw_int_no_gps() -> GPS_RAW_INT_DATA {
    GPS_RAW_INT_DATA {
        fix_type: GpsFixType::GPS_FIX_TYPE_NO_GPS,
        eph: u16::MAX,
        epv: u16::MAX,
        vel: u16::MAX,
        cog: u16::MAX,
        satellites_visible: u8::MAX,
        ..Default::default()
    }
}

/// HIGHRES_IMU as PX4 fills it (`HIGHRES_IMU.hpp`): accelerometer [m/s^2],
/// gyroscope [rad/s] and magnetometer [gauss] in FRD, absolute pressure
/// [hPa], pressure altitude [m] and temperature [degC]; `fields_updated`
/// names the fields a sensor filled (an OFF sensor's are 0 and unflagged).
/// Stamped with the IMU's sample time; nothing before any sample.
#[must_use]
pub fn highres_imu(raw: &RawSensorReadings) -> Option<HIGHRES_IMU_DATA> {
    if raw.accel.is_none() && raw.gyro.is_none() && raw.mag.is_none() && raw.baro.is_none() {
        return None;
    }
    let time_s = [raw.accel.map(|s| s.time_s), raw.gyro.map(|s| s.time_s)]
        .into_iter()
        .flatten()
        .chain(raw.baro.map(|b| b.time_s))
        .chain(raw.mag.map(|m| m.time_s))
        .fold(0.0, f64::max);
    type F = HighresImuUpdatedFlags;
    let mut flags = F::empty();
    let mut xyz = |s: Option<crate::signals::AxesSample>, bits: F| {
        s.map_or([0.0f32; 3], |s| {
            flags |= bits;
            [s.frd.x as f32, s.frd.y as f32, s.frd.z as f32]
        })
    };
    let a = xyz(
        raw.accel,
        F::HIGHRES_IMU_UPDATED_XACC | F::HIGHRES_IMU_UPDATED_YACC | F::HIGHRES_IMU_UPDATED_ZACC,
    );
    let w = xyz(
        raw.gyro,
        F::HIGHRES_IMU_UPDATED_XGYRO | F::HIGHRES_IMU_UPDATED_YGYRO | F::HIGHRES_IMU_UPDATED_ZGYRO,
    );
    let m = xyz(
        raw.mag,
        F::HIGHRES_IMU_UPDATED_XMAG | F::HIGHRES_IMU_UPDATED_YMAG | F::HIGHRES_IMU_UPDATED_ZMAG,
    );
    let (p, alt, temp) = match raw.baro {
        Some(b) => {
            flags |= F::HIGHRES_IMU_UPDATED_ABS_PRESSURE
                | F::HIGHRES_IMU_UPDATED_PRESSURE_ALT
                | F::HIGHRES_IMU_UPDATED_TEMPERATURE;
            (
                (b.pressure_pa / 100.0) as f32,
                crate::geo::pressure_altitude_m(b.pressure_pa) as f32,
                b.temperature_c as f32,
            )
        }
        None => (0.0, 0.0, 0.0),
    };
    Some(HIGHRES_IMU_DATA {
        time_usec: (time_s * 1e6) as u64,
        xacc: a[0],
        yacc: a[1],
        zacc: a[2],
        xgyro: w[0],
        ygyro: w[1],
        zgyro: w[2],
        xmag: m[0],
        ymag: m[1],
        zmag: m[2],
        abs_pressure: p,
        diff_pressure: 0.0,
        pressure_alt: alt,
        temperature: temp,
        fields_updated: flags,
        id: 0,
    })
}

/// SCALED_IMU as PX4 fills it (`SCALED_IMU.hpp`): acceleration [mG]
/// (`f / 9.80665 * 1000`), rates [mrad/s], field [mgauss], FRD,
/// temperature [cdegC] (the barometer's); nothing while the accelerometer
/// and gyroscope give nothing.
#[must_use]
pub fn scaled_imu(raw: &RawSensorReadings) -> Option<SCALED_IMU_DATA> {
    let t = raw.accel.or(raw.gyro)?.time_s;
    let scale = |s: Option<crate::signals::AxesSample>, k: f64| {
        s.map_or([0i16; 3], |s| {
            [
                convert::sat_i16(s.frd.x * k),
                convert::sat_i16(s.frd.y * k),
                convert::sat_i16(s.frd.z * k),
            ]
        })
    };
    let a = scale(raw.accel, 1000.0 / 9.806_65);
    let w = scale(raw.gyro, 1000.0);
    let m = scale(raw.mag, 1000.0);
    Some(SCALED_IMU_DATA {
        time_boot_ms: (t * 1e3) as u32,
        xacc: a[0],
        yacc: a[1],
        zacc: a[2],
        xgyro: w[0],
        ygyro: w[1],
        zgyro: w[2],
        xmag: m[0],
        ymag: m[1],
        zmag: m[2],
        temperature: raw.baro.map_or(0, |b| convert::sat_i16(b.temperature_c * 100.0)),
    })
}

/// HEARTBEAT as PX4 sends it: the multirotor's type, autopilot PX4, custom mode.
#[must_use]
pub fn heartbeat(t: &Telemetry) -> HEARTBEAT_DATA {
    HEARTBEAT_DATA {
        custom_mode: convert::custom_mode(t.mode),
        mavtype: match t.vehicle_type {
            VehicleType::Tricopter => MavType::MAV_TYPE_TRICOPTER,
            VehicleType::Quadrotor => MavType::MAV_TYPE_QUADROTOR,
            VehicleType::Hexarotor => MavType::MAV_TYPE_HEXAROTOR,
            VehicleType::Octorotor => MavType::MAV_TYPE_OCTOROTOR,
            VehicleType::Decarotor => MavType::MAV_TYPE_DECAROTOR,
            VehicleType::Dodecarotor => MavType::MAV_TYPE_DODECAROTOR,
        },
        autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
        base_mode: MavModeFlag::from_bits_retain(convert::base_mode(t.mode, t.armed)),
        system_status: if t.armed {
            MavState::MAV_STATE_ACTIVE
        } else {
            MavState::MAV_STATE_STANDBY
        },
        mavlink_version: 3,
    }
}

/// CURRENT_MODE as PX4 fills it (`CURRENT_MODE.hpp`): the heartbeat's
/// custom mode, its standard mode ([`convert::standard_mode`]) and the
/// custom mode the user meant: the same, unless a failsafe is in force,
/// when rotorpilot does not keep the mode it replaced and says 0
/// ("unknown", as MAVLink allows).
#[must_use]
pub fn current_mode(t: &Telemetry) -> CURRENT_MODE_DATA {
    let custom_mode = convert::custom_mode(t.mode);
    CURRENT_MODE_DATA {
        custom_mode,
        intended_custom_mode: if t.failsafe { 0 } else { custom_mode },
        standard_mode: convert::standard_mode(t.mode),
    }
}

/// MISSION_CURRENT as PX4 fills it (`send_mission_current`): `total` is
/// UINT16_MAX without a mission; `mission_mode` is 1 (active) in the modes
/// PX4 counts as flying the mission (mission, takeoff, land), else 2
/// (suspended).
#[must_use]
pub fn mission_current(t: &Telemetry) -> MISSION_CURRENT_DATA {
    let m = &t.mission;
    MISSION_CURRENT_DATA {
        seq: m.seq,
        total: if m.total == 0 { u16::MAX } else { m.total },
        mission_state: match m.state {
            MissionState::NoMission => MavMissionState::MISSION_STATE_NO_MISSION,
            MissionState::NotStarted => MavMissionState::MISSION_STATE_NOT_STARTED,
            MissionState::Active => MavMissionState::MISSION_STATE_ACTIVE,
            MissionState::Paused => MavMissionState::MISSION_STATE_PAUSED,
            MissionState::Complete => MavMissionState::MISSION_STATE_COMPLETE,
        },
        mission_mode: if matches!(t.mode, FlightMode::Mission | FlightMode::Takeoff | FlightMode::Land) {
            1
        } else {
            2
        },
        mission_id: m.mission_id,
        fence_id: m.fence_id,
        rally_points_id: m.rally_id,
    }
}

/// HIL_STATE_QUATERNION as PX4 SITL fills it from its ground-truth topics
/// (`HIL_STATE_QUATERNION.hpp`): the true attitude and body rates, the true
/// position as latitude/longitude/AMSL around the vehicle's NED origin
/// (flat earth, [`crate::geo`]), the true NED velocity [cm/s], airspeeds 0,
/// and the true NED acceleration written as PX4 writes it: the value in
/// m/s^2 cut to an integer (not the milli-g the message's definition names),
/// so that a client sees what it sees from PX4.
#[must_use]
pub fn ground_truth(snapshot: &Snapshot) -> HIL_STATE_QUATERNION_DATA {
    let g = &snapshot.ground_truth;
    let s = &g.state;
    let q = s.attitude.quaternion();
    let at = snapshot.telemetry.origin.offset(&s.position_ned);
    HIL_STATE_QUATERNION_DATA {
        time_usec: (s.time_s * 1e6) as u64,
        attitude_quaternion: [q.w as f32, q.i as f32, q.j as f32, q.k as f32],
        rollspeed: s.rate_frd.x as f32,
        pitchspeed: s.rate_frd.y as f32,
        yawspeed: s.rate_frd.z as f32,
        lat: convert::deg_e7(at.lat_deg),
        lon: convert::deg_e7(at.lon_deg),
        alt: convert::sat_i32(at.alt_amsl_m * 1e3),
        vx: convert::sat_i16(s.velocity_ned.x * 100.0),
        vy: convert::sat_i16(s.velocity_ned.y * 100.0),
        vz: convert::sat_i16(s.velocity_ned.z * 100.0),
        ind_airspeed: 0,
        true_airspeed: 0,
        xacc: convert::sat_i16(g.acceleration_ned.x.trunc()),
        yacc: convert::sat_i16(g.acceleration_ned.y.trunc()),
        zacc: convert::sat_i16(g.acceleration_ned.z.trunc()),
    }
}

/// WIND_COV as PX4 fills it (`streams/WIND_COV.hpp`) from its wind
/// estimate: `wind_x` north, `wind_y` east [m/s], `wind_z` 0 (the estimate is
/// horizontal), `var_horiz` the sum of the north and east variances
/// [(m/s)^2], `var_vert` 0, `wind_alt` the altitude AMSL [m], the accuracies
/// 0; `time_usec` the estimate's time. Nothing without an estimate (on the
/// ground, or an airframe without drag coefficients), as PX4 sends nothing
/// until its wind topic is published.
#[must_use]
pub fn wind_cov(t: &Telemetry) -> Option<WIND_COV_DATA> {
    let w = t.wind.as_ref()?;
    Some(WIND_COV_DATA {
        time_usec: (w.time_s * 1e6) as u64,
        wind_x: w.wind_ned.x as f32,
        wind_y: w.wind_ned.y as f32,
        wind_z: 0.0,
        var_horiz: (w.variance_ne.x + w.variance_ne.y) as f32,
        var_vert: 0.0,
        wind_alt: t.global.alt_amsl_m as f32,
        horiz_accuracy: 0.0,
        vert_accuracy: 0.0,
    })
}

/// ESTIMATOR_STATUS as PX4 fills it (`ESTIMATOR_STATUS.hpp` from EKF2's
/// `estimator_status`): `flags` the solution status bits, the test ratios
/// `|innov| / (gate sqrt(S))` of the sources fused and NaN for a source not
/// fused (`hagl_ratio` and `tas_ratio` always: no range finder, no
/// airspeed), the position accuracies [m]; stamped `time_usec`.
#[must_use]
pub fn estimator_status(time_usec: u64, n: &NavigationReport) -> ESTIMATOR_STATUS_DATA {
    type F = EstimatorStatusFlags;
    let s = &n.solution;
    let flags = [
        (s.attitude, F::ESTIMATOR_ATTITUDE),
        (s.velocity_horiz, F::ESTIMATOR_VELOCITY_HORIZ),
        (s.velocity_vert, F::ESTIMATOR_VELOCITY_VERT),
        (s.pos_horiz_rel, F::ESTIMATOR_POS_HORIZ_REL),
        (s.pos_horiz_abs, F::ESTIMATOR_POS_HORIZ_ABS),
        (s.pos_vert_abs, F::ESTIMATOR_POS_VERT_ABS),
        (s.const_pos_mode, F::ESTIMATOR_CONST_POS_MODE),
        (s.pred_pos_horiz_rel, F::ESTIMATOR_PRED_POS_HORIZ_REL),
        (s.pred_pos_horiz_abs, F::ESTIMATOR_PRED_POS_HORIZ_ABS),
        (s.gps_glitch, F::ESTIMATOR_GPS_GLITCH),
    ]
    .into_iter()
    .filter(|(on, _)| *on)
    .fold(F::empty(), |acc, (_, bit)| acc | bit);
    let ratio = |r: Option<f64>| r.map_or(f32::NAN, |r| r as f32);
    ESTIMATOR_STATUS_DATA {
        time_usec,
        vel_ratio: ratio(n.ratios.vel),
        pos_horiz_ratio: ratio(n.ratios.pos_horiz),
        pos_vert_ratio: ratio(n.ratios.pos_vert),
        mag_ratio: ratio(n.ratios.mag),
        hagl_ratio: f32::NAN,
        tas_ratio: f32::NAN,
        pos_horiz_accuracy: n.pos_horiz_accuracy_m as f32,
        pos_vert_accuracy: n.pos_vert_accuracy_m as f32,
        flags,
    }
}

/// VIBRATION as PX4 fills it (`VIBRATION.hpp` from `vehicle_imu_status`):
/// `vibration_x` the gyro's coning metric, `vibration_y` the gyro's and
/// `vibration_z` the accelerometer's high-frequency metric
/// ([`ImuVibration`]); no clipping (the simulated IMU has no range limit);
/// stamped with the latest IMU sample's time.
#[must_use]
pub fn vibration(v: &ImuVibration) -> VIBRATION_DATA {
    VIBRATION_DATA {
        time_usec: (v.time_s * 1e6) as u64,
        vibration_x: v.coning_rad2_s2 as f32,
        vibration_y: v.gyro_rad_s as f32,
        vibration_z: v.accel_m_s2 as f32,
        clipping_0: 0,
        clipping_1: 0,
        clipping_2: 0,
    }
}

/// ODOMETRY as PX4 v1.14 on fills it (`ODOMETRY.hpp` from EKF2's
/// `vehicle_odometry`, whose pose and velocity are both NED): `frame_id`
/// and `child_frame_id` MAV_FRAME_LOCAL_NED, position [m] and velocity
/// [m/s] NED, attitude quaternion (w, x, y, z; FRD to NED), body rates
/// [rad/s] FRD; the covariances' upper-right triangles row-major, NaN but
/// for the diagonal (pose: x, y, z, roll, pitch, yaw at indices 0, 6, 11,
/// 15, 18, 20; velocity: vx, vy, vz at 0, 6, 11, the rates' NaN), all NaN
/// without a covariance (the ideal solution: "unknown"); `estimator_type`
/// AUTOPILOT, `quality` 0 as PX4's EKF2 sets it.
#[must_use]
pub fn odometry(t: &Telemetry) -> ODOMETRY_DATA {
    let mut pose_covariance = [f32::NAN; 21];
    let mut velocity_covariance = [f32::NAN; 21];
    if let Some(v) = &t.navigation.variances {
        for (k, i) in [0, 6, 11].into_iter().enumerate() {
            pose_covariance[i] = v.position_ned_m2[k] as f32;
            velocity_covariance[i] = v.velocity_ned_m2_s2[k] as f32;
        }
        for (k, i) in [15, 18, 20].into_iter().enumerate() {
            pose_covariance[i] = v.attitude_frd_rad2[k] as f32;
        }
    }
    let q = &t.attitude;
    ODOMETRY_DATA {
        time_usec: time_usec(t),
        x: t.position_ned.x as f32,
        y: t.position_ned.y as f32,
        z: t.position_ned.z as f32,
        q: [q.w as f32, q.i as f32, q.j as f32, q.k as f32],
        vx: t.velocity_ned.x as f32,
        vy: t.velocity_ned.y as f32,
        vz: t.velocity_ned.z as f32,
        rollspeed: t.rate_frd.x as f32,
        pitchspeed: t.rate_frd.y as f32,
        yawspeed: t.rate_frd.z as f32,
        pose_covariance,
        velocity_covariance,
        frame_id: MavFrame::MAV_FRAME_LOCAL_NED,
        child_frame_id: MavFrame::MAV_FRAME_LOCAL_NED,
        reset_counter: (t.navigation.reset_count % 256) as u8,
        estimator_type: MavEstimatorType::MAV_ESTIMATOR_TYPE_AUTOPILOT,
        quality: 0,
    }
}

/// HOME_POSITION from telemetry.
#[must_use]
pub fn home_position(t: &Telemetry) -> HOME_POSITION_DATA {
    HOME_POSITION_DATA {
        latitude: convert::deg_e7(t.home.lat_deg),
        longitude: convert::deg_e7(t.home.lon_deg),
        altitude: convert::sat_i32(t.home.alt_amsl_m * 1e3),
        x: t.home_ned.x as f32,
        y: t.home_ned.y as f32,
        z: t.home_ned.z as f32,
        q: [1.0, 0.0, 0.0, 0.0],
        approach_x: 0.0,
        approach_y: 0.0,
        approach_z: 0.0,
        // MAVLink 2 extension: not reported (zero, cut off the wire)
        ..Default::default()
    }
}

/// MAV_SYS_STATUS_SENSOR_BATTERY: unhealthy from the critical level on (PX4's battery health check).
pub const BATTERY: u32 = 0x0020_0000;

/// The battery bit when it is unhealthy, else 0.
fn battery_unhealthy(t: &Telemetry) -> u32 {
    if t.battery_warning >= BatteryWarning::Critical {
        BATTERY
    } else {
        0
    }
}

fn battery_percent(t: &Telemetry) -> i8 {
    (t.battery_remaining * 100.0).round().clamp(0.0, 100.0) as i8
}

fn debug_vect(name: &str, time_usec: u64, v: [f64; 3]) -> MavMessage {
    MavMessage::DEBUG_VECT(DEBUG_VECT_DATA {
        time_usec,
        x: v[0] as f32,
        y: v[1] as f32,
        z: v[2] as f32,
        name: name.into(),
    })
}

fn named_float(name: &str, time_boot_ms: u32, v: f64) -> MavMessage {
    MavMessage::NAMED_VALUE_FLOAT(NAMED_VALUE_FLOAT_DATA {
        time_boot_ms,
        value: v as f32,
        name: name.into(),
    })
}

#[cfg(test)]
mod tests;
