//! The navigation filter's settings, under PX4's EKF2 parameter names and
//! with PX4's defaults (`src/modules/ekf2/module.yaml` and `params_*.yaml`),
//! plus the fixed timeouts PX4 keeps in code (`EKF/common.h`).

/// The height source the filter converges to (`EKF2_HGT_REF`, PX4's values;
/// 2 = range sensor and 3 = vision are PX4's too, and refused here).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HeightRef {
    /// 0: barometric pressure.
    Baro,
    /// 1: GNSS altitude (PX4's default).
    Gnss,
}

impl HeightRef {
    /// From PX4's `EKF2_HGT_REF` value; `None` for a source this filter does not have.
    pub fn from_px4(value: i32) -> Option<Self> {
        match value {
            0 => Some(Self::Baro),
            1 => Some(Self::Gnss),
            _ => None,
        }
    }

    /// PX4's `EKF2_HGT_REF` value.
    pub fn px4_value(self) -> i32 {
        match self {
            Self::Baro => 0,
            Self::Gnss => 1,
        }
    }
}

/// Which GNSS observations are fused (`EKF2_GPS_CTRL` bits 0 to 2; bit 3,
/// dual-antenna heading, is not modelled).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GnssCtrl {
    /// Bit 0: latitude/longitude (horizontal position).
    pub horizontal_position: bool,
    /// Bit 1: altitude (GNSS height).
    pub altitude: bool,
    /// Bit 2: 3D velocity.
    pub velocity: bool,
}

impl GnssCtrl {
    /// From PX4's `EKF2_GPS_CTRL` bitmask (bits above 2 are ignored, as a
    /// filter without dual-antenna heading ignores bit 3).
    pub fn from_px4(mask: i32) -> Self {
        Self {
            horizontal_position: mask & 1 != 0,
            altitude: mask & 2 != 0,
            velocity: mask & 4 != 0,
        }
    }

    /// PX4's `EKF2_GPS_CTRL` bitmask.
    pub fn px4_value(self) -> i32 {
        i32::from(self.horizontal_position) | i32::from(self.altitude) << 1 | i32::from(self.velocity) << 2
    }
}

/// The filter's settings. Field names are PX4's parameter names in lower
/// case without the `EKF2_` prefix; units are PX4's (SI, except where the
/// name says `_us` or `_deg`).
#[derive(Clone, Debug, PartialEq)]
pub struct NavConfig {
    /// `EKF2_PREDICT_US`: covariance prediction period [us] (10000).
    pub predict_us: u32,
    /// `EKF2_GYR_NOISE`: rate gyro noise for covariance prediction [rad/s] (0.015).
    pub gyr_noise: f64,
    /// `EKF2_ACC_NOISE`: accelerometer noise for covariance prediction [m/s^2] (0.35).
    pub acc_noise: f64,
    /// `EKF2_GYR_B_NOISE`: gyro bias process noise [rad/s^2] (0.001).
    pub gyr_b_noise: f64,
    /// `EKF2_ACC_B_NOISE`: accelerometer bias process noise [m/s^3] (0.003).
    pub acc_b_noise: f64,
    /// `EKF2_GBIAS_INIT`: 1-sigma gyro switch-on bias [rad/s] (0.1).
    pub gbias_init: f64,
    /// `EKF2_ABIAS_INIT`: 1-sigma accelerometer switch-on bias [m/s^2] (0.2).
    pub abias_init: f64,
    /// `EKF2_ANGERR_INIT`: 1-sigma tilt error after alignment [rad] (0.1).
    pub angerr_init: f64,
    /// `EKF2_GYR_B_LIM`: gyro bias limit [rad/s] (0.15).
    pub gyr_b_lim: f64,
    /// `EKF2_ABL_LIM`: accelerometer bias limit [m/s^2] (0.4).
    pub abl_lim: f64,
    /// `EKF2_HGT_REF`: the height reference (GNSS).
    pub hgt_ref: HeightRef,
    /// `EKF2_GPS_CTRL`: GNSS observations fused (7: position, altitude, velocity).
    pub gps_ctrl: GnssCtrl,
    /// `EKF2_GPS_P_NOISE`: minimum GNSS position noise [m] (0.5).
    pub gps_p_noise: f64,
    /// `EKF2_GPS_V_NOISE`: minimum GNSS velocity noise [m/s] (0.3).
    pub gps_v_noise: f64,
    /// `EKF2_GPS_P_GATE`: GNSS position innovation gate [SD] (5).
    pub gps_p_gate: f64,
    /// `EKF2_GPS_V_GATE`: GNSS velocity innovation gate [SD] (5).
    pub gps_v_gate: f64,
    /// `EKF2_REQ_EPH`: largest GNSS eph accepted [m] (3).
    pub req_eph: f64,
    /// `EKF2_REQ_EPV`: largest GNSS epv accepted [m] (5).
    pub req_epv: f64,
    /// `EKF2_REQ_SACC`: largest GNSS speed accuracy accepted [m/s] (0.5).
    pub req_sacc: f64,
    /// `EKF2_REQ_GPS_H`: GNSS checks must pass this long before use [s] (10).
    pub req_gps_h: f64,
    /// `EKF2_NOAID_NOISE`: cap on the GNSS position noise when it is the only horizontal aiding [m] (10).
    pub noaid_noise: f64,
    /// `EKF2_BARO_CTRL`: fuse the barometer (1).
    pub baro_ctrl: bool,
    /// `EKF2_BARO_NOISE`: barometric height noise [m] (3.5).
    pub baro_noise: f64,
    /// `EKF2_BARO_GATE`: barometric and GNSS height innovation gate [SD] (5).
    pub baro_gate: f64,
    /// Process noise of a height source's bias (PX4 `baro_bias_nsd`, `gps_hgt_bias_nsd`) [m/s/sqrt(Hz)] (0.13).
    pub hgt_bias_nsd: f64,
    /// `EKF2_HEAD_NOISE`: magnetic heading noise [rad] (0.3).
    pub head_noise: f64,
    /// `EKF2_HDG_GATE`: heading innovation gate [SD] (2.6).
    pub hdg_gate: f64,
    /// `EKF2_MAG_DECL`: magnetic declination, east of true north positive [deg] (0).
    pub mag_decl_deg: f64,
    /// `EKF2_NOAID_TOUT`: dead-reckoning time after which the horizontal
    /// (and, without height aiding, vertical) position is invalid [us] (5000000).
    pub noaid_tout_us: u32,
}

impl Default for NavConfig {
    fn default() -> Self {
        Self {
            predict_us: 10_000,
            gyr_noise: 0.015,
            acc_noise: 0.35,
            gyr_b_noise: 0.001,
            acc_b_noise: 0.003,
            gbias_init: 0.1,
            abias_init: 0.2,
            angerr_init: 0.1,
            gyr_b_lim: 0.15,
            abl_lim: 0.4,
            hgt_ref: HeightRef::Gnss,
            gps_ctrl: GnssCtrl::from_px4(7),
            gps_p_noise: 0.5,
            gps_v_noise: 0.3,
            gps_p_gate: 5.0,
            gps_v_gate: 5.0,
            req_eph: 3.0,
            req_epv: 5.0,
            req_sacc: 0.5,
            req_gps_h: 10.0,
            noaid_noise: 10.0,
            baro_ctrl: true,
            baro_noise: 3.5,
            baro_gate: 5.0,
            hgt_bias_nsd: 0.13,
            head_noise: 0.3,
            hdg_gate: 2.6,
            mag_decl_deg: 0.0,
            noaid_tout_us: 5_000_000,
        }
    }
}

/// PX4's fixed timeouts (`EKF/common.h`, `EKF/estimator_interface.h`) [s].
pub mod timeouts {
    /// `reset_timeout_max`: GNSS fusion failing (or its data or checks gone)
    /// this long resets the states to GNSS, or stops GNSS fusion.
    pub const RESET_S: f64 = 7.0;
    /// `no_aid_timeout_max`: without horizontal aiding this long the filter is dead reckoning.
    pub const NO_AID_S: f64 = 1.0;
    /// `hgt_fusion_timeout_max`: a height source failing fusion this long is stopped.
    pub const HGT_FUSION_S: f64 = 5.0;
    /// `2 * BARO_MAX_INTERVAL`: no barometer sample this long stops barometric height.
    pub const BARO_DATA_S: f64 = 0.4;
    /// `2 * GNSS_MAX_INTERVAL`: no GNSS sample this long stops GNSS height.
    pub const GNSS_HGT_DATA_S: f64 = 1.0;
    /// `2 * MAG_MAX_INTERVAL`: no magnetometer sample this long stops heading fusion.
    pub const MAG_DATA_S: f64 = 1.0;
    /// Tilt alignment: the specific force is averaged this long before the filter starts.
    pub const ALIGN_S: f64 = 0.2;
}

/// PX4's sensor voter (`DataValidator`, `VALUE_EQUAL_COUNT_DEFAULT`): a
/// sensor repeating its exact value this many times in a row is stale (stuck).
pub const STALE_EQUAL_COUNT: u32 = 100;
