//! The navigation solution the flight stack flies on (`RP_NAV_SRC`): either
//! the one the sensor readings carry (the world's ideal solution, the true
//! state plus seeded noise), or the navigation filter's
//! ([`crate::estimation::nav::NavFilter`], after PX4's EKF2) fed by the raw
//! IMU, barometer, magnetometer and GNSS samples of the same readings.
//!
//! Feeding the filter from the readings at `t_k` (every sample newer than
//! the one fed before):
//!
//! ```text
//! IMU        d_ang = w~ dt,  d_vel = f~ dt,   dt = t_imu - t_imu_prev   (FRD)
//! barometer  h = pressure_altitude(p) - alt_origin                      (up, m)
//! GNSS       p_ned = ned(lat, lon, alt) + v_ned (t_k - t_fix)           (latency bridged)
//! magnetometer  m~ (FRD, gauss) as sampled
//! ```
//!
//! and the solution it gives: position and velocity NED and attitude from
//! PX4's output predictor on the filter ([`Output`]); body rates `w~ - b_g`
//! (FRD) and acceleration `a = R (f~ - b_a) + g e3` (NED) from the latest
//! IMU sample.

use nalgebra::{UnitQuaternion, Vector3};

use super::position_checks::HorizontalAccuracy;
use super::telemetry::{InnovationRatios, NavVariances, NavigationReport, SolutionStatus};
use crate::estimation::nav::{BaroHeight, GnssCtrl, GnssFix, HeightRef, ImuDelta, MagField, NavConfig, NavFilter};
use crate::geo::{GeoPoint, earth_field_ned_gauss, pressure_altitude_m};
use crate::params::{Param, ParamStore};
use crate::signals::{GRAVITY, GpsFix, Measurement, RawSensorReadings, SensorReadings};

/// Where the flight stack's navigation solution comes from (`RP_NAV_SRC`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum NavSource {
    /// 0: the solution the readings carry (the world's: truth plus noise).
    #[default]
    Ideal,
    /// 1: the navigation filter on the raw sensors.
    Filter,
}

impl NavSource {
    /// From `RP_NAV_SRC`.
    #[must_use]
    pub fn from_params(params: &ParamStore) -> Self {
        match params.int(Param::RP_NAV_SRC) {
            1 => Self::Filter,
            _ => Self::Ideal,
        }
    }

    /// The name a scenario file gives it (`[navigation] source`).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Ideal => "ideal",
            Self::Filter => "filter",
        }
    }
}

/// The filter's settings from the `EKF2_*` parameters rotorpilot reads
/// (PX4's defaults for the others, [`NavConfig::default`]).
#[must_use]
pub fn nav_config(params: &ParamStore) -> NavConfig {
    NavConfig {
        hgt_ref: HeightRef::from_px4(params.int(Param::EKF2_HGT_REF)).unwrap_or(HeightRef::Gnss),
        baro_ctrl: params.int(Param::EKF2_BARO_CTRL) != 0,
        gps_ctrl: GnssCtrl::from_px4(params.int(Param::EKF2_GPS_CTRL)),
        req_gps_h: params.real(Param::EKF2_REQ_GPS_H),
        baro_noise: params.real(Param::EKF2_BARO_NOISE),
        baro_gate: params.real(Param::EKF2_BARO_GATE),
        gps_p_noise: params.real(Param::EKF2_GPS_P_NOISE),
        gps_v_noise: params.real(Param::EKF2_GPS_V_NOISE),
        noaid_tout_us: u32::try_from(params.int(Param::EKF2_NOAID_TOUT)).unwrap_or(5_000_000),
        ..NavConfig::default()
    }
}

/// The times of the latest samples fed (a sample is new when its time is later).
#[derive(Clone, Copy, Debug, Default)]
struct Fed {
    imu_s: Option<f64>,
    baro_s: Option<f64>,
    mag_s: Option<f64>,
    gnss_s: Option<f64>,
}

/// PX4's `EKF2_TAU_VEL`: time constant of the output predictor's velocity correction [s].
const TAU_VEL_S: f64 = 0.25;
/// PX4's `EKF2_TAU_POS`: time constant of the output predictor's position correction [s].
const TAU_POS_S: f64 = 0.25;
/// Time constant of the output predictor's attitude correction [s].
const TAU_ATT_S: f64 = 0.25;

/// PX4's output predictor: the solution flown on, propagated every step
/// by the latest IMU sample and pulled towards the filter's state, so that
/// the filter's corrections (8 Hz GNSS, 50 Hz heading, 20 Hz height) reach
/// the controllers as smooth changes, not steps.
///
/// ```text
/// q_o <- q_o (x) exp(w dt),   a = R_o f + g e3,   v_o' = v_o + a dt,   p_o <- p_o + (v_o + v_o') dt / 2
/// v_o <- v_o + (v - v_o) dt / EKF2_TAU_VEL,   p_o <- p_o + (p - p_o) dt / EKF2_TAU_POS
/// q_o <- q_o (x) exp(log(q_o^-1 (x) q) dt / tau_att)
/// ```
#[derive(Clone, Copy, Debug)]
struct Output {
    time_s: f64,
    position_ned: Vector3<f64>,
    velocity_ned: Vector3<f64>,
    attitude: UnitQuaternion<f64>,
}

/// The navigation filter fed from the sensor readings, and the solution it gives.
#[derive(Clone, Debug)]
pub struct FilterNavigation {
    filter: NavFilter,
    origin: GeoPoint,
    fed: Fed,
    /// Body rates from the latest gyro sample less the bias, FRD [rad/s].
    rate_frd: Vector3<f64>,
    /// Specific force from the latest accelerometer sample less the bias, FRD [m/s^2].
    force_frd: Vector3<f64>,
    /// The output predictor (`None` until the filter has a tilt).
    output: Option<Output>,
}

impl FilterNavigation {
    /// A filter that aligns from the raw sensors (a vehicle booting at rest),
    /// its NED origin at `origin`. The magnetic declination is the Earth
    /// field's at the origin ([`earth_field_ned_gauss`], `atan2(B_E, B_N)`),
    /// as PX4 takes it from its field tables (`EKF2_DECL_TYPE`'s default).
    #[must_use]
    pub fn new(cfg: NavConfig, origin: GeoPoint) -> Self {
        let field = earth_field_ned_gauss(&origin);
        let cfg = NavConfig {
            mag_decl_deg: field.y.atan2(field.x).to_degrees(),
            ..cfg
        };
        Self {
            filter: NavFilter::new(cfg),
            origin,
            fed: Fed::default(),
            rate_frd: Vector3::zeros(),
            force_frd: Vector3::new(0.0, 0.0, -GRAVITY),
            output: None,
        }
    }

    /// A filter already aligned at `state` (a flight that starts in the air,
    /// as after a ground alignment: [`NavFilter::start_at`]).
    #[must_use]
    pub fn started_at(cfg: NavConfig, origin: GeoPoint, state: &Measurement) -> Self {
        let mut nav = Self::new(cfg, origin);
        nav.filter
            .start_at(state.position_ned, state.velocity_ned, state.attitude);
        nav.rate_frd = state.rate_frd;
        nav.output = Some(Output {
            time_s: state.time_s,
            position_ned: state.position_ned,
            velocity_ned: state.velocity_ned,
            attitude: state.attitude,
        });
        nav
    }

    /// The filter.
    #[must_use]
    pub fn filter(&self) -> &NavFilter {
        &self.filter
    }

    /// Feeds every raw sample of `readings` newer than the ones fed before:
    /// the IMU first (it moves the filter's clock), then the barometer,
    /// magnetometer and GNSS. Samples the filter refuses (not finite) are dropped.
    pub fn update(&mut self, readings: &SensorReadings) {
        let raw = &readings.raw;
        let now = readings.measurement.time_s;
        self.feed_imu(raw);
        if let Some(b) = raw.baro.filter(|b| self.fed.baro_s.is_none_or(|t| b.time_s > t)) {
            self.fed.baro_s = Some(b.time_s);
            let height_m = pressure_altitude_m(b.pressure_pa) - self.origin.alt_amsl_m;
            let _ = self.filter.fuse_baro(&BaroHeight {
                time_s: b.time_s,
                height_m,
            });
        }
        if let Some(m) = raw.mag.filter(|m| self.fed.mag_s.is_none_or(|t| m.time_s > t)) {
            self.fed.mag_s = Some(m.time_s);
            let _ = self.filter.fuse_mag(&MagField {
                time_s: m.time_s,
                field_frd_gauss: m.frd,
            });
        }
        if let Some(g) = raw.gnss.filter(|g| self.fed.gnss_s.is_none_or(|t| g.delivered_s > t)) {
            self.fed.gnss_s = Some(g.delivered_s);
            let at = GeoPoint {
                lat_deg: g.lat_deg,
                lon_deg: g.lon_deg,
                alt_amsl_m: g.alt_amsl_m,
            };
            // the fix describes `time_s`; carried to now along its own velocity
            let latency_s = (now - g.time_s).max(0.0);
            let _ = self.filter.fuse_gnss(&GnssFix {
                time_s: g.time_s,
                position_ned_m: at.ned_from(&self.origin) + g.velocity_ned * latency_s,
                velocity_ned_m_s: g.velocity_ned,
                eph_m: g.eph_m,
                epv_m: g.epv_m,
                speed_accuracy_m_s: g.speed_accuracy_m_s,
            });
        }
        self.predict_output(now);
    }

    /// The output predictor to `now` (see [`Output`]); while the filter has
    /// no tilt yet, the output is the filter's state.
    fn predict_output(&mut self, now: f64) {
        let f = &self.filter;
        if !f.status().tilt_aligned {
            self.output = None;
            return;
        }
        let mut o = *self.output.get_or_insert(Output {
            time_s: now,
            position_ned: f.position_ned_m(),
            velocity_ned: f.velocity_ned_m_s(),
            attitude: f.attitude(),
        });
        let dt = now - o.time_s;
        if dt > 0.0 {
            o.attitude *= UnitQuaternion::from_scaled_axis(self.rate_frd * dt);
            let a = o.attitude * self.force_frd + Vector3::new(0.0, 0.0, GRAVITY);
            let v = o.velocity_ned + a * dt;
            o.position_ned += 0.5 * (o.velocity_ned + v) * dt;
            o.velocity_ned = v;
            o.velocity_ned += (f.velocity_ned_m_s() - o.velocity_ned) * (dt / TAU_VEL_S).min(1.0);
            o.position_ned += (f.position_ned_m() - o.position_ned) * (dt / TAU_POS_S).min(1.0);
            let err = (o.attitude.inverse() * f.attitude()).scaled_axis();
            o.attitude *= UnitQuaternion::from_scaled_axis(err * (dt / TAU_ATT_S).min(1.0));
            o.time_s = now;
        }
        self.output = Some(o);
    }

    /// Propagates the filter by the IMU sample, once the gyro and
    /// accelerometer both hold one of the same instant.
    fn feed_imu(&mut self, raw: &RawSensorReadings) {
        let (Some(gyro), Some(accel)) = (raw.gyro, raw.accel) else {
            return;
        };
        if gyro.time_s != accel.time_s || self.fed.imu_s.is_some_and(|t| gyro.time_s <= t) {
            return;
        }
        let previous = self.fed.imu_s.replace(gyro.time_s);
        let Some(dt_s) = previous.map(|t| gyro.time_s - t) else {
            return;
        };
        let fed = self.filter.predict(&ImuDelta {
            dt_s,
            delta_angle_frd_rad: gyro.frd * dt_s,
            delta_velocity_frd_m_s: accel.frd * dt_s,
        });
        if fed.is_ok() {
            self.rate_frd = gyro.frd - self.filter.gyro_bias_frd_rad_s();
            self.force_frd = accel.frd - self.filter.accel_bias_frd_m_s2();
        }
    }

    /// The navigation solution (the output predictor's, else the filter's
    /// state) stamped `time_s`.
    #[must_use]
    pub fn measurement(&self, time_s: f64) -> Measurement {
        let (position_ned, velocity_ned, attitude) = match &self.output {
            Some(o) => (o.position_ned, o.velocity_ned, o.attitude),
            None => (
                self.filter.position_ned_m(),
                self.filter.velocity_ned_m_s(),
                self.filter.attitude(),
            ),
        };
        Measurement {
            time_s,
            position_ned,
            velocity_ned,
            attitude,
            rate_frd: self.rate_frd,
        }
    }

    /// `readings` with the navigation solution and the acceleration
    /// (`R f + g e3`, NED) replaced by the filter's (the rest as read: rotor
    /// speeds, battery, GNSS status, raw samples).
    #[must_use]
    pub fn readings(&self, readings: &SensorReadings) -> SensorReadings {
        let measurement = self.measurement(readings.measurement.time_s);
        SensorReadings {
            acceleration_ned: measurement.attitude * self.force_frd + Vector3::new(0.0, 0.0, GRAVITY),
            measurement,
            ..*readings
        }
    }

    /// Whether the solution may be flown on: tilt and yaw aligned, and the
    /// horizontal and vertical position valid (PX4's `xy_valid`, `z_valid`
    /// and the attitude's validity, which its arming checks require).
    #[must_use]
    pub fn ready(&self) -> bool {
        let s = self.filter.status();
        s.tilt_aligned && s.yaw_aligned && s.horizontal_position_valid && s.vertical_position_valid
    }

    /// What the commander reads of the horizontal solution (PX4's
    /// `vehicle_local_position`): valid while aligned and aided within
    /// `EKF2_NOAID_TOUT` (`xy_valid`, `v_xy_valid`), with `eph` and `evh`;
    /// `fix`: the receiver's, to say why a position is lost.
    #[must_use]
    pub(super) fn horizontal_accuracy(&self, fix: bool) -> HorizontalAccuracy {
        let f = &self.filter;
        let s = f.status();
        HorizontalAccuracy {
            valid: s.tilt_aligned && s.yaw_aligned && s.horizontal_position_valid,
            eph_m: f.eph_m(),
            evh_m_s: f.evh_m_s(),
            fix,
        }
    }

    /// Whether the land detector may read the solution: attitude aligned and
    /// the height valid (PX4's land detector needs `v_z_valid`; without a
    /// horizontal position, as after a GNSS loss, it still finds the ground).
    #[must_use]
    pub fn height_ready(&self) -> bool {
        let s = self.filter.status();
        s.tilt_aligned && s.yaw_aligned && s.vertical_position_valid
    }

    /// What ESTIMATOR_STATUS and ODOMETRY report of the filter, as PX4's
    /// EKF2 fills `estimator_status` (`Ekf::get_ekf_soln_status`) and
    /// `vehicle_odometry`:
    ///
    /// ```text
    /// attitude        tilt aligned
    /// velocity_horiz  GNSS position or velocity fused    (horizontal aiding)
    /// velocity_vert   a height fused (baro or GNSS);      pos_vert_abs the same
    /// pos_horiz_rel   GNSS fused;                         pos_horiz_abs, pred_pos_horiz_* the same
    /// const_pos_mode  not velocity_horiz
    /// gps_glitch      (GNSS vel or pos ratio > 1) and mag_innov_good
    /// ```
    ///
    /// with PX4's `mag_innov_good` as written: false when the heading is
    /// fused and its ratio is *below* 1 (so a GNSS glitch shows only while
    /// the heading also fails its gate, or is not fused).
    #[must_use]
    pub fn report(&self) -> NavigationReport {
        let f = &self.filter;
        let s = f.status();
        let r = f.test_ratios();
        let horizontal_aiding = s.gnss_pos || s.gnss_vel;
        let height = s.baro_hgt || s.gnss_hgt;
        let over = |x: Option<f64>| x.is_some_and(|x| x > 1.0);
        let mag_innov_good = !(s.mag_hdg && r.mag.is_some_and(|m| m < 1.0));
        NavigationReport {
            solution: SolutionStatus {
                attitude: s.tilt_aligned,
                velocity_horiz: horizontal_aiding,
                velocity_vert: height,
                pos_horiz_rel: s.gnss_pos,
                pos_horiz_abs: s.gnss_pos,
                pos_vert_abs: height,
                const_pos_mode: !horizontal_aiding,
                pred_pos_horiz_rel: s.gnss_pos,
                pred_pos_horiz_abs: s.gnss_pos,
                gps_glitch: (over(r.vel) || over(r.pos_horiz)) && mag_innov_good,
            },
            ratios: InnovationRatios {
                vel: r.vel,
                pos_horiz: r.pos_horiz,
                pos_vert: r.pos_vert,
                mag: r.mag,
            },
            pos_horiz_accuracy_m: f.eph_m(),
            pos_vert_accuracy_m: f.epv_m(),
            variances: Some(NavVariances {
                position_ned_m2: f.position_variance_ned_m2(),
                velocity_ned_m2_s2: f.velocity_variance_ned_m2_s2(),
                attitude_frd_rad2: f.attitude_variance_frd_rad2(),
            }),
            reset_count: s.gnss_position_resets,
        }
    }
}

/// What ESTIMATOR_STATUS and ODOMETRY report of the ideal navigation
/// solution (the true state plus the world's noise, no filter): what a
/// healthy EKF reports. The flags of a good solution (831 with a GNSS fix;
/// without one, attitude and height only and the position held), every
/// test ratio 0 (no innovation: nothing is rejected) for the sources a
/// healthy EKF fuses (GNSS velocity and position only with a fix), the
/// accuracies 0 m and no covariance (ODOMETRY says "unknown"), no resets.
#[must_use]
pub(super) fn ideal_navigation_report(fix: GpsFix) -> NavigationReport {
    let gnss = fix != GpsFix::None;
    let with_fix = gnss.then_some(0.0);
    NavigationReport {
        solution: SolutionStatus::good(gnss),
        ratios: InnovationRatios {
            vel: with_fix,
            pos_horiz: with_fix,
            pos_vert: Some(0.0),
            mag: Some(0.0),
        },
        pos_horiz_accuracy_m: 0.0,
        pos_vert_accuracy_m: 0.0,
        variances: None,
        reset_count: 0,
    }
}
