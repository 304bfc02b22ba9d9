//! What the navigation filter is fed (IMU increments, GNSS fixes, barometric
//! height, magnetic field) and what it reports (test ratios, status), in SI
//! units with frames named.

use nalgebra::Vector3;

/// One IMU sample as increments over `dt_s` (PX4's `imuSample`: delta angle
/// and delta velocity, the accelerometer's specific force integrated, so
/// gravity is not in it: at rest level it reads `-g e3 dt` in FRD).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImuDelta {
    /// Integration interval [s], > 0.
    pub dt_s: f64,
    /// Integrated body rate, FRD [rad].
    pub delta_angle_frd_rad: Vector3<f64>,
    /// Integrated specific force, FRD [m/s].
    pub delta_velocity_frd_m_s: Vector3<f64>,
}

/// A GNSS fix, in the filter's local frame (NED around the filter's origin).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GnssFix {
    /// Time of validity on the filter's clock (the sum of the IMU `dt_s`) [s].
    pub time_s: f64,
    /// Position relative to the filter's origin, NED [m].
    pub position_ned_m: Vector3<f64>,
    /// Velocity, NED [m/s].
    pub velocity_ned_m_s: Vector3<f64>,
    /// Reported horizontal accuracy (1 sigma) [m].
    pub eph_m: f64,
    /// Reported vertical accuracy (1 sigma) [m].
    pub epv_m: f64,
    /// Reported speed accuracy (1 sigma) [m/s].
    pub speed_accuracy_m_s: f64,
}

/// A barometric height sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BaroHeight {
    /// Time of validity on the filter's clock [s].
    pub time_s: f64,
    /// Height above the origin (up positive) [m].
    pub height_m: f64,
}

/// A magnetometer sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MagField {
    /// Time of validity on the filter's clock [s].
    pub time_s: f64,
    /// Measured field, FRD [gauss].
    pub field_frd_gauss: Vector3<f64>,
}

/// Why an input was refused (the filter state is unchanged).
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum NavInputError {
    /// The IMU interval is not finite and > 0.
    #[error("IMU interval must be finite and > 0 s, got {0}")]
    ImuInterval(f64),
    /// A value of the named input is not finite.
    #[error("{0} sample holds a value that is not finite")]
    NotFinite(&'static str),
}

/// Innovation test ratios as PX4's ESTIMATOR_STATUS reports them: the
/// innovation over (gate x its standard deviation), the square root of
/// EKF2's internal ratio; above 1 the measurement is rejected. `None` when
/// the source has not been checked yet.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TestRatios {
    /// `vel_ratio`: the largest GNSS velocity ratio.
    pub vel: Option<f64>,
    /// `pos_horiz_ratio`: the largest GNSS horizontal position ratio.
    pub pos_horiz: Option<f64>,
    /// `pos_vert_ratio`: the height reference's ratio.
    pub pos_vert: Option<f64>,
    /// `mag_ratio`: the magnetic heading ratio.
    pub mag: Option<f64>,
}

/// A height source.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HeightSource {
    /// The barometer.
    Baro,
    /// GNSS altitude.
    Gnss,
}

/// What the filter uses and what it has decided (PX4's `filter_control_status`
/// and `local_position` validity, the parts this filter has).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NavStatus {
    /// Tilt aligned from the accelerometer; before, nothing else runs.
    pub tilt_aligned: bool,
    /// Yaw aligned from the magnetometer (PX4 `yaw_align`); GNSS fusion waits for it.
    pub yaw_aligned: bool,
    /// GNSS horizontal position fused (`gnss_pos`).
    pub gnss_pos: bool,
    /// GNSS velocity fused (`gnss_vel`).
    pub gnss_vel: bool,
    /// GNSS height fused (`gps_hgt`).
    pub gnss_hgt: bool,
    /// Barometric height fused (`baro_hgt`).
    pub baro_hgt: bool,
    /// Magnetic heading fused (`mag_hdg`).
    pub mag_hdg: bool,
    /// The height reference now in use (`EKF2_HGT_REF`, or PX4's fallback).
    pub height_ref: Option<HeightSource>,
    /// Barometer declared faulty (`baro_fault`: its fusion failed while another height source worked).
    pub baro_fault: bool,
    /// Magnetometer declared faulty (`mag_fault`).
    pub mag_fault: bool,
    /// Barometer stale: repeating its exact value (PX4's sensor voter).
    pub baro_stale: bool,
    /// Magnetometer stale: repeating its exact value.
    pub mag_stale: bool,
    /// No horizontal aiding for `no_aid_timeout_max` (`inertial_dead_reckoning`).
    pub dead_reckoning: bool,
    /// Local horizontal position valid: aided within `EKF2_NOAID_TOUT`.
    pub horizontal_position_valid: bool,
    /// Local vertical position valid: a height fused within `EKF2_NOAID_TOUT`.
    pub vertical_position_valid: bool,
    /// Times the horizontal position was reset to GNSS.
    pub gnss_position_resets: u32,
}
