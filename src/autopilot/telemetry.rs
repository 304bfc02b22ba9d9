//! What the flight stack tells its clients: one snapshot, in SI units and
//! NED/FRD, built from its state and the latest sensor readings (the link
//! turns it into MAVLink).

use nalgebra::{UnitQuaternion, Vector3};
use serde::Serialize;

use super::FlightMode;
use crate::geo::GeoPoint;
use crate::signals::{GpsFix, MAX_ROTORS, WindEstimate, WrenchEstimate};

/// What the vehicle reports as its landed state (MAV_LANDED_STATE).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum LandedState {
    /// On the ground.
    OnGround,
    /// Flying.
    InAir,
    /// Taking off.
    Takeoff,
    /// Landing.
    Landing,
}

/// The kind of vehicle, from its rotor count (HEARTBEAT `type`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum VehicleType {
    /// 3 rotors.
    Tricopter,
    /// 4 rotors (and any count MAVLink has no name for, as PX4's generic multicopter).
    Quadrotor,
    /// 6 rotors.
    Hexarotor,
    /// 8 rotors.
    Octorotor,
    /// 10 rotors.
    Decarotor,
    /// 12 rotors.
    Dodecarotor,
}

impl VehicleType {
    /// The type of a multirotor with `rotors` rotors.
    #[must_use]
    pub fn from_rotor_count(rotors: usize) -> Self {
        match rotors {
            3 => VehicleType::Tricopter,
            6 => VehicleType::Hexarotor,
            8 => VehicleType::Octorotor,
            10 => VehicleType::Decarotor,
            12 => VehicleType::Dodecarotor,
            _ => VehicleType::Quadrotor,
        }
    }
}

/// A snapshot of everything telemetry needs, in SI units and NED/FRD.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Telemetry {
    /// Simulated time since boot [s] (of the readings).
    pub time_s: f64,
    /// Multirotor kind.
    pub vehicle_type: VehicleType,
    /// Armed.
    pub armed: bool,
    /// Mode.
    pub mode: FlightMode,
    /// A failsafe is in force (PX4's `vehicle_status.failsafe`: an action
    /// the pilot did not command; [`super::Autopilot::failsafe_in_force`]).
    pub failsafe: bool,
    /// Landed state.
    pub landed: LandedState,
    /// Position [m], NED from home's origin.
    pub position_ned: Vector3<f64>,
    /// Velocity [m/s], NED.
    pub velocity_ned: Vector3<f64>,
    /// Acceleration [m/s^2], NED, from the navigation solution.
    pub acceleration_ned: Vector3<f64>,
    /// Attitude, FRD to NED.
    pub attitude: UnitQuaternion<f64>,
    /// Body rates [rad/s], FRD.
    pub rate_frd: Vector3<f64>,
    /// Global position.
    pub global: GeoPoint,
    /// The NED origin (where the vehicle booted).
    pub origin: GeoPoint,
    /// Home.
    pub home: GeoPoint,
    /// Home in local NED [m].
    pub home_ned: Vector3<f64>,
    /// GNSS fix.
    pub gps_fix: GpsFix,
    /// GNSS satellites used.
    pub gps_satellites: u8,
    /// Battery voltage [V].
    pub battery_voltage_v: f64,
    /// Battery current [A].
    pub battery_current_a: f64,
    /// Charge used [mAh].
    pub battery_consumed_mah: f64,
    /// Remaining charge, 0..1.
    pub battery_remaining: f64,
    /// The battery warning level in force (BATTERY_STATUS `charge_state`).
    pub battery_warning: super::BatteryWarning,
    /// Normalised collective thrust commanded, 0..1 (VFR_HUD throttle).
    pub throttle: f64,
    /// The wrench estimate (force NED, torque FRD, real mass).
    pub estimate: WrenchEstimate,
    /// The wind the vehicle feels (NED, horizontal), once estimated (WIND_COV).
    pub wind: Option<WindEstimate>,
    /// Prearm checks pass.
    pub prearm_ok: bool,
    /// The mission's progress (MISSION_CURRENT).
    pub mission: MissionStatus,
    /// Rotors the rotor monitor flags failed: bit `i - 1` for rotor `i` (PX4's motor failure mask).
    pub failed_rotors: u16,
    /// Rotors flagged degraded (below ~90 % thrust): bit `i - 1` for rotor `i`.
    pub degraded_rotors: u16,
    /// The orbit flown, in Orbit (ORBIT_EXECUTION_STATUS).
    pub orbit: Option<OrbitStatus>,
    /// The navigation solution's health and uncertainty (ESTIMATOR_STATUS, ODOMETRY).
    pub navigation: NavigationReport,
    /// The IMU's vibration metrics, once it has given two samples (VIBRATION).
    pub vibration: Option<super::vibration::ImuVibration>,
    /// What the flight stack commands each rotor (ACTUATOR_OUTPUT_STATUS).
    pub rotor_outputs: RotorOutputs,
}

/// What the flight stack commands each rotor in one step, as a client of the
/// autopilot sees its motor outputs: a running rotor's share of its speed
/// range, or stopped. A rotor is stopped while the vehicle is disarmed (or
/// its rotors are stopped) and once the allocation has taken it out after
/// the rotor monitor flagged it failed: the stack then commands it nothing,
/// as PX4's allocator leaves a removed motor's output unset.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct RotorOutputs {
    /// Rotors the vehicle has (0 on an ideal-actuation airframe, whose
    /// thrust and torque act directly: no motor outputs to report).
    pub count: usize,
    /// Per motor from motor 1, by motor number
    /// ([`crate::airframe::RotorGeometry::motor`]; entries past `count` are `None`): `Some(u)`
    /// running, with `u = (w_cmd - w_min) / (w_max - w_min)` in `[0, 1]`
    /// the commanded speed's place between idle and full speed
    /// (dimensionless); `None` stopped.
    pub commands: [Option<f64>; MAX_ROTORS],
}

impl Default for RotorOutputs {
    /// No rotors.
    fn default() -> Self {
        Self {
            count: 0,
            commands: [None; MAX_ROTORS],
        }
    }
}

/// What PX4's EKF2 says of its solution (`estimator_status` and
/// `vehicle_odometry`): which parts of it are good, how its latest
/// innovations compare with their gates, and how uncertain it is.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct NavigationReport {
    /// Which parts of the solution are good (`solution_status_flags`).
    pub solution: SolutionStatus,
    /// The innovation test ratios `|innov| / (gate sqrt(S))` of the sources
    /// fused (above 1 a sample is rejected); `None` for a source not fused.
    pub ratios: InnovationRatios,
    /// Horizontal position accuracy `sqrt(P_nn + P_ee)` [m].
    pub pos_horiz_accuracy_m: f64,
    /// Vertical position accuracy `sqrt(P_dd)` [m].
    pub pos_vert_accuracy_m: f64,
    /// The covariance's diagonal, when the solution has one (the filter's;
    /// the ideal solution has none).
    pub variances: Option<NavVariances>,
    /// How often the solution was reset (position resets on a new GNSS fix).
    pub reset_count: u32,
}

/// PX4's `estimator_status.solution_status_flags`, one field per bit
/// (`Ekf::get_ekf_soln_status`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct SolutionStatus {
    /// The attitude is good (tilt aligned).
    pub attitude: bool,
    /// The horizontal velocity is good (horizontal aiding active).
    pub velocity_horiz: bool,
    /// The vertical velocity is good (a height source fused).
    pub velocity_vert: bool,
    /// The relative horizontal position is good.
    pub pos_horiz_rel: bool,
    /// The absolute horizontal position is good (GNSS fused).
    pub pos_horiz_abs: bool,
    /// The absolute vertical position is good.
    pub pos_vert_abs: bool,
    /// No horizontal aiding: the position is held constant.
    pub const_pos_mode: bool,
    /// The relative horizontal position would be good once moving.
    pub pred_pos_horiz_rel: bool,
    /// The absolute horizontal position would be good once moving.
    pub pred_pos_horiz_abs: bool,
    /// GNSS innovations fail their gates while the magnetometer's do not.
    pub gps_glitch: bool,
}

impl SolutionStatus {
    /// A good GNSS-aided solution (PX4 SITL in flight: 831), or with
    /// `horizontal_aiding` false one without horizontal aiding
    /// (attitude and height only, position held).
    #[must_use]
    pub fn good(horizontal_aiding: bool) -> Self {
        Self {
            attitude: true,
            velocity_horiz: horizontal_aiding,
            velocity_vert: true,
            pos_horiz_rel: horizontal_aiding,
            pos_horiz_abs: horizontal_aiding,
            pos_vert_abs: true,
            const_pos_mode: !horizontal_aiding,
            pred_pos_horiz_rel: horizontal_aiding,
            pred_pos_horiz_abs: horizontal_aiding,
            gps_glitch: false,
        }
    }
}

/// ESTIMATOR_STATUS's test ratios (`None`: the source is not fused).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct InnovationRatios {
    /// `vel_ratio`: the largest GNSS velocity ratio.
    pub vel: Option<f64>,
    /// `pos_horiz_ratio`: the largest GNSS horizontal position ratio.
    pub pos_horiz: Option<f64>,
    /// `pos_vert_ratio`: the height reference's ratio.
    pub pos_vert: Option<f64>,
    /// `mag_ratio`: the magnetic heading ratio.
    pub mag: Option<f64>,
}

/// The navigation covariance's diagonal as ODOMETRY carries it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct NavVariances {
    /// Position, NED [m^2].
    pub position_ned_m2: Vector3<f64>,
    /// Velocity, NED [(m/s)^2].
    pub velocity_ned_m2_s2: Vector3<f64>,
    /// Attitude about the body axes (roll, pitch, yaw), FRD [rad^2].
    pub attitude_frd_rad2: Vector3<f64>,
}

/// An orbit as ORBIT_EXECUTION_STATUS reports it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct OrbitStatus {
    /// Radius [m], signed: positive clockwise seen from above.
    pub radius_m: f64,
    /// Centre (latitude, longitude) and the altitude flown (AMSL).
    pub centre: GeoPoint,
    /// Where the nose points.
    pub yaw: super::OrbitYaw,
}

/// MISSION_CURRENT's `mission_state`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum MissionState {
    /// 1: no mission stored.
    NoMission,
    /// 2: a mission is stored and not started (or not flown since it was stored).
    NotStarted,
    /// 3: flying it.
    Active,
    /// 4: paused (another mode took over before the end).
    Paused,
    /// 5: the last item is done.
    Complete,
}

impl MissionState {
    /// MISSION_STATE value.
    #[must_use]
    pub fn to_mav(self) -> u8 {
        match self {
            MissionState::NoMission => 1,
            MissionState::NotStarted => 2,
            MissionState::Active => 3,
            MissionState::Paused => 4,
            MissionState::Complete => 5,
        }
    }
}

/// The mission's progress as MISSION_CURRENT carries it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct MissionStatus {
    /// The current item's sequence number (0 without a mission).
    pub seq: u16,
    /// Number of mission items.
    pub total: u16,
    /// Where the mission stands.
    pub state: MissionState,
    /// The mission's id (CRC32, 0 when empty).
    pub mission_id: u32,
    /// The geofence's id.
    pub fence_id: u32,
    /// The rally points' id.
    pub rally_id: u32,
}
