//! The navigation filter: an error-state extended Kalman filter after PX4's
//! EKF2 (`docs/navigation.md` holds the equations, parameters and measured
//! figures). It sees only sensor samples: IMU increments, GNSS fixes,
//! barometric height and the magnetic field.
//!
//! ```text
//! nominal state  p_ned, v_ned, q (FRD -> NED), b_g (FRD, rad/s), b_a (FRD, m/s^2)
//! strapdown      dth = d_ang - b_g dt,  dv = d_vel - b_a dt
//!                q <- q (x) exp(dth),   v <- v + R_mid dv + g e3 dt,   p <- p + (v_old + v) dt / 2
//!                R_mid dv = R (dv - dth x dv / 2)
//! error state    x = [dp, dv, dth, dbg, dba],  R_true = exp([dth]x) R
//! correction     scalar updates: S = H P H^T + r,  K = P H^T / S,  x = K innov,  P <- P - K H P,
//!                then x is injected into the nominal state and reset to zero
//! gate           test ratio = innov^2 / (gate^2 S); above 1 the sample is rejected
//! ```
//!
//! * [`config`]: [`NavConfig`] (PX4's names and defaults) and PX4's fixed timeouts.
//! * [`covariance`]: the covariance prediction by blocks.
//! * [`inputs`]: the samples fed in and the status reported.
//!
//! Pure and deterministic: no clock (time is the sum of the IMU intervals),
//! no randomness, no allocation per step.

pub mod config;
pub mod covariance;
pub mod inputs;

pub use config::{GnssCtrl, HeightRef, NavConfig, STALE_EQUAL_COUNT};
pub use inputs::{BaroHeight, GnssFix, HeightSource, ImuDelta, MagField, NavInputError, NavStatus, TestRatios};

use config::timeouts;
use covariance::{Cov, ProcessNoise, idx};
use nalgebra::{Matrix3, UnitQuaternion, Vector3};

const GRAVITY: f64 = crate::signals::GRAVITY;
/// PX4's fake position fusion interval [s].
const FAKE_POS_PERIOD_S: f64 = 0.2;

/// PX4's sensor voter stale check: a sensor repeating its exact value
/// [`STALE_EQUAL_COUNT`] times in a row is stale, until its value changes.
#[derive(Clone, Copy, Debug, Default)]
struct StaleCheck {
    last: [u64; 3],
    equal_count: u32,
}

impl StaleCheck {
    /// Feeds one sample; true when the sensor is stale.
    fn update(&mut self, value: [f64; 3]) -> bool {
        let bits = value.map(f64::to_bits);
        if bits == self.last {
            self.equal_count = self.equal_count.saturating_add(1);
        } else {
            self.equal_count = 0;
            self.last = bits;
        }
        self.stale()
    }

    fn stale(&self) -> bool {
        self.equal_count >= STALE_EQUAL_COUNT
    }
}

/// One height source (PX4's aid source with its `HeightBiasEstimator`): the
/// measured height is `-p_d + bias`; the reference source's bias is held, the
/// others' is estimated by a scalar Kalman filter.
#[derive(Clone, Copy, Debug)]
struct HeightAid {
    active: bool,
    fault: bool,
    bias_m: f64,
    bias_var: f64,
    bias_time_s: f64,
    last_fuse_s: f64,
    last_sample_s: Option<f64>,
    test_ratio: Option<f64>,
}

impl HeightAid {
    const fn new() -> Self {
        Self {
            active: false,
            fault: false,
            bias_m: 0.0,
            bias_var: 0.0,
            bias_time_s: 0.0,
            last_fuse_s: 0.0,
            last_sample_s: None,
            test_ratio: None,
        }
    }
}

/// GNSS horizontal aiding (PX4's `gnss_pos` and `gnss_vel`).
#[derive(Clone, Copy, Debug)]
struct GnssAid {
    pos_active: bool,
    vel_active: bool,
    fault: bool,
    last_pos_fuse_s: f64,
    last_vel_fuse_s: f64,
    last_sample_s: Option<f64>,
    last_check_fail_s: f64,
    last_check_pass_s: f64,
    origin_set: bool,
    /// Started in the air ([`NavFilter::start_at`]): the checks count as passed before the first fix.
    checks_waived: bool,
    pos_ratio: Option<f64>,
    vel_ratio: Option<f64>,
    position_resets: u32,
}

/// Magnetic heading aiding (PX4's `mag_hdg`).
#[derive(Clone, Copy, Debug)]
struct MagAid {
    active: bool,
    fault: bool,
    stale: StaleCheck,
    last_fuse_s: f64,
    last_sample_s: Option<f64>,
    ratio: Option<f64>,
}

/// Specific force accumulated towards the next covariance prediction.
#[derive(Clone, Copy, Debug, Default)]
struct Accumulated {
    dt_s: f64,
    dv_ned: Vector3<f64>,
}

/// The error-state EKF. Feed [`NavFilter::predict`] every IMU sample and the
/// other samples as they come; read the estimate and [`NavFilter::status`].
#[derive(Clone, Debug)]
pub struct NavFilter {
    cfg: NavConfig,
    time_s: f64,
    tilt_aligned: bool,
    yaw_aligned: bool,
    align: Accumulated,
    last_mag_frd: Option<Vector3<f64>>,
    pos_ned: Vector3<f64>,
    vel_ned: Vector3<f64>,
    att: UnitQuaternion<f64>,
    rot: Matrix3<f64>,
    gyro_bias: Vector3<f64>,
    accel_bias: Vector3<f64>,
    cov: Cov,
    acc: Accumulated,
    baro: HeightAid,
    baro_stale: StaleCheck,
    gnss_hgt: HeightAid,
    height_ref: Option<HeightSource>,
    last_height_fuse_s: Option<f64>,
    gnss: GnssAid,
    mag: MagAid,
    last_horizontal_aiding_s: Option<f64>,
    fake_position: Option<(Vector3<f64>, f64)>,
}

/// Checks that every value is finite.
fn finite(values: &[f64], what: &'static str) -> Result<(), NavInputError> {
    if values.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(NavInputError::NotFinite(what))
    }
}

impl NavFilter {
    /// A filter waiting for tilt alignment (`timeouts::ALIGN_S` of IMU samples).
    pub fn new(cfg: NavConfig) -> Self {
        Self {
            cfg,
            time_s: 0.0,
            tilt_aligned: false,
            yaw_aligned: false,
            align: Accumulated::default(),
            last_mag_frd: None,
            pos_ned: Vector3::zeros(),
            vel_ned: Vector3::zeros(),
            att: UnitQuaternion::identity(),
            rot: Matrix3::identity(),
            gyro_bias: Vector3::zeros(),
            accel_bias: Vector3::zeros(),
            cov: Cov::zeros(),
            acc: Accumulated::default(),
            baro: HeightAid::new(),
            baro_stale: StaleCheck::default(),
            gnss_hgt: HeightAid::new(),
            height_ref: None,
            last_height_fuse_s: None,
            gnss: GnssAid {
                pos_active: false,
                vel_active: false,
                fault: false,
                last_pos_fuse_s: 0.0,
                last_vel_fuse_s: 0.0,
                last_sample_s: None,
                last_check_fail_s: 0.0,
                last_check_pass_s: 0.0,
                origin_set: false,
                checks_waived: false,
                pos_ratio: None,
                vel_ratio: None,
                position_resets: 0,
            },
            mag: MagAid {
                active: false,
                fault: false,
                stale: StaleCheck::default(),
                last_fuse_s: 0.0,
                last_sample_s: None,
                ratio: None,
            },
            last_horizontal_aiding_s: None,
            fake_position: None,
        }
    }

    /// The settings.
    pub fn config(&self) -> &NavConfig {
        &self.cfg
    }

    /// The filter's clock: the sum of the IMU intervals fed [s].
    pub fn time_s(&self) -> f64 {
        self.time_s
    }

    /// Position relative to the origin, NED [m].
    pub fn position_ned_m(&self) -> Vector3<f64> {
        self.pos_ned
    }

    /// Velocity, NED [m/s].
    pub fn velocity_ned_m_s(&self) -> Vector3<f64> {
        self.vel_ned
    }

    /// Attitude, FRD -> NED.
    pub fn attitude(&self) -> UnitQuaternion<f64> {
        self.att
    }

    /// Gyro bias estimate, FRD [rad/s].
    pub fn gyro_bias_frd_rad_s(&self) -> Vector3<f64> {
        self.gyro_bias
    }

    /// Accelerometer bias estimate, FRD [m/s^2].
    pub fn accel_bias_frd_m_s2(&self) -> Vector3<f64> {
        self.accel_bias
    }

    /// Horizontal position accuracy `eph = sqrt(P_nn + P_ee)` [m] (PX4's `get_ekf_lpos_accuracy`).
    pub fn eph_m(&self) -> f64 {
        (self.cov[(idx::POS, idx::POS)] + self.cov[(idx::POS + 1, idx::POS + 1)])
            .max(0.0)
            .sqrt()
    }

    /// Vertical position accuracy `epv = sqrt(P_dd)` [m].
    pub fn epv_m(&self) -> f64 {
        self.cov[(idx::POS + 2, idx::POS + 2)].max(0.0).sqrt()
    }

    /// Horizontal velocity accuracy `evh = sqrt(P_vn + P_ve)` [m/s].
    pub fn evh_m_s(&self) -> f64 {
        (self.cov[(idx::VEL, idx::VEL)] + self.cov[(idx::VEL + 1, idx::VEL + 1)])
            .max(0.0)
            .sqrt()
    }

    /// Variances of the position error, NED [m^2] (the covariance's
    /// diagonal: PX4's `getPositionVariance`, ODOMETRY's pose covariance).
    pub fn position_variance_ned_m2(&self) -> Vector3<f64> {
        self.diagonal(idx::POS)
    }

    /// Variances of the velocity error, NED [(m/s)^2] (PX4's `getVelocityVariance`).
    pub fn velocity_variance_ned_m2_s2(&self) -> Vector3<f64> {
        self.diagonal(idx::VEL)
    }

    /// Variances of the attitude error about the body axes [rad^2], PX4's
    /// `getRotVarBody`: the NED rotation-vector covariance `P_a` taken into
    /// FRD, `diag(R^T P_a R)`.
    pub fn attitude_variance_frd_rad2(&self) -> Vector3<f64> {
        let r = self.attitude().to_rotation_matrix().into_inner();
        let p = self.cov.fixed_view::<3, 3>(idx::ANG, idx::ANG);
        (r.transpose() * p * r).diagonal()
    }

    fn diagonal(&self, first: usize) -> Vector3<f64> {
        Vector3::new(
            self.cov[(first, first)],
            self.cov[(first + 1, first + 1)],
            self.cov[(first + 2, first + 2)],
        )
    }

    /// The innovation test ratios, as ESTIMATOR_STATUS reports them.
    pub fn test_ratios(&self) -> TestRatios {
        let pos_vert = match self.height_ref {
            Some(HeightSource::Baro) => self.baro.test_ratio,
            Some(HeightSource::Gnss) => self.gnss_hgt.test_ratio,
            None => None,
        };
        TestRatios {
            vel: self.gnss.vel_ratio,
            pos_horiz: self.gnss.pos_ratio,
            pos_vert,
            mag: self.mag.ratio,
        }
    }

    /// What the filter fuses and decides now.
    pub fn status(&self) -> NavStatus {
        let since = |t: Option<f64>| t.map_or(f64::INFINITY, |t| self.time_s - t);
        let noaid = f64::from(self.cfg.noaid_tout_us) * 1e-6;
        NavStatus {
            tilt_aligned: self.tilt_aligned,
            yaw_aligned: self.yaw_aligned,
            gnss_pos: self.gnss.pos_active,
            gnss_vel: self.gnss.vel_active,
            gnss_hgt: self.gnss_hgt.active,
            baro_hgt: self.baro.active,
            mag_hdg: self.mag.active,
            height_ref: self.height_ref,
            baro_fault: self.baro.fault,
            mag_fault: self.mag.fault,
            baro_stale: self.baro_stale.stale(),
            mag_stale: self.mag.stale.stale(),
            dead_reckoning: since(self.last_horizontal_aiding_s) > timeouts::NO_AID_S,
            horizontal_position_valid: since(self.last_horizontal_aiding_s) <= noaid,
            vertical_position_valid: since(self.last_height_fuse_s) <= noaid,
            gnss_position_resets: self.gnss.position_resets,
        }
    }

    /// Propagates the nominal state by one IMU sample; every `EKF2_PREDICT_US`
    /// of samples, also the covariance and the sensor timeouts.
    pub fn predict(&mut self, imu: &ImuDelta) -> Result<(), NavInputError> {
        if !(imu.dt_s.is_finite() && imu.dt_s > 0.0) {
            return Err(NavInputError::ImuInterval(imu.dt_s));
        }
        finite(imu.delta_angle_frd_rad.as_slice(), "IMU")?;
        finite(imu.delta_velocity_frd_m_s.as_slice(), "IMU")?;
        self.time_s += imu.dt_s;
        if !self.tilt_aligned {
            self.align.dt_s += imu.dt_s;
            self.align.dv_ned += imu.delta_velocity_frd_m_s;
            // half a sample of slack: the intervals are differences of
            // time stamps, whose rounding must not move the alignment a sample
            if self.align.dt_s >= timeouts::ALIGN_S - 0.5 * imu.dt_s {
                self.align_tilt();
            }
            return Ok(());
        }
        let dang = imu.delta_angle_frd_rad - self.gyro_bias * imu.dt_s;
        let dvel = imu.delta_velocity_frd_m_s - self.accel_bias * imu.dt_s;
        self.att =
            UnitQuaternion::new_normalize(self.att.into_inner() * UnitQuaternion::from_scaled_axis(dang).into_inner());
        self.rot = self.att.to_rotation_matrix().into_inner();
        let dv_ned = self.rot * (dvel - 0.5 * dang.cross(&dvel));
        let vel_old = self.vel_ned;
        self.vel_ned += dv_ned;
        self.vel_ned.z += GRAVITY * imu.dt_s;
        self.pos_ned += 0.5 * (vel_old + self.vel_ned) * imu.dt_s;
        self.acc.dt_s += imu.dt_s;
        self.acc.dv_ned += dv_ned;
        if self.acc.dt_s >= f64::from(self.cfg.predict_us) * 1e-6 - 0.5 * imu.dt_s {
            self.predict_covariance();
            self.check_timeouts();
            self.control_fake_position();
        }
        Ok(())
    }

    fn predict_covariance(&mut self) {
        let dt = self.acc.dt_s;
        let a_ned = self.acc.dv_ned / dt;
        let c = &self.cfg;
        let noise = ProcessNoise {
            dvel: c.acc_noise * dt,
            dang: c.gyr_noise * dt,
            gyro_bias: c.gyr_b_noise * dt,
            accel_bias: c.acc_b_noise * dt,
        };
        covariance::predict(&mut self.cov, dt, &self.rot, &a_ned, &noise);
        self.acc = Accumulated::default();
    }

    /// Starts aligned at a known state, as the filter stands after a ground
    /// alignment (for a flight that starts in the air): position, velocity
    /// and attitude set, the biases zero, the covariance as after tilt
    /// alignment, and the GNSS checks counted as passed `EKF2_REQ_GPS_H`
    /// before (the first fix then resets the horizontal position to it).
    pub fn start_at(
        &mut self,
        position_ned_m: Vector3<f64>,
        velocity_ned_m_s: Vector3<f64>,
        attitude: UnitQuaternion<f64>,
    ) {
        self.pos_ned = position_ned_m;
        self.vel_ned = velocity_ned_m_s;
        self.att = attitude;
        self.rot = attitude.to_rotation_matrix().into_inner();
        self.tilt_aligned = true;
        self.yaw_aligned = true;
        self.init_covariance();
        self.gnss.last_check_fail_s = self.time_s - self.cfg.req_gps_h;
        self.gnss.checks_waived = true;
    }

    /// Tilt from the mean specific force (at rest `f_frd = -R^T g e3`), yaw
    /// from the magnetometer when a sample has come; the covariance from
    /// `EKF2_ANGERR_INIT`, `EKF2_GBIAS_INIT`, `EKF2_ABIAS_INIT` and the sensor noises.
    fn align_tilt(&mut self) {
        let f = self.align.dv_ned / self.align.dt_s;
        let roll = (-f.y).atan2(-f.z);
        let pitch = f.x.atan2((f.y * f.y + f.z * f.z).sqrt());
        self.att = UnitQuaternion::from_euler_angles(roll, pitch, 0.0);
        self.rot = self.att.to_rotation_matrix().into_inner();
        self.tilt_aligned = true;
        self.init_covariance();
        if let Some(m) = self.last_mag_frd {
            self.reset_yaw(self.mag_heading(&m));
        }
    }

    /// The covariance after alignment.
    fn init_covariance(&mut self) {
        let c = &self.cfg;
        let diag = [
            (idx::POS, c.noaid_noise * c.noaid_noise),
            (idx::POS + 2, c.baro_noise * c.baro_noise),
            (idx::VEL, c.gps_v_noise * c.gps_v_noise),
            (idx::ANG, c.angerr_init * c.angerr_init),
            (idx::GB, c.gbias_init * c.gbias_init),
            (idx::AB, c.abias_init * c.abias_init),
        ];
        for (block, var) in diag {
            let n = if block == idx::POS {
                2
            } else if block == idx::POS + 2 {
                1
            } else {
                3
            };
            for k in 0..n {
                self.cov[(block + k, block + k)] = var;
            }
        }
        self.cov[(idx::ANG + 2, idx::ANG + 2)] = c.head_noise * c.head_noise;
    }

    /// Heading of the field: the sample levelled with the estimated tilt,
    /// `psi = atan2(-m_y, m_x) + declination`.
    fn mag_heading(&self, field_frd: &Vector3<f64>) -> f64 {
        let (_, _, yaw) = self.att.euler_angles();
        let level = UnitQuaternion::from_euler_angles(0.0, 0.0, -yaw) * self.att;
        let m = level * field_frd;
        (-m.y).atan2(m.x) + self.cfg.mag_decl_deg.to_radians()
    }

    /// Sets the yaw, keeping the tilt; the yaw variance becomes `EKF2_HEAD_NOISE^2`.
    fn reset_yaw(&mut self, yaw: f64) {
        let (_, _, old) = self.att.euler_angles();
        self.att = UnitQuaternion::from_euler_angles(0.0, 0.0, yaw - old) * self.att;
        self.rot = self.att.to_rotation_matrix().into_inner();
        let k = idx::ANG + 2;
        for i in 0..covariance::N {
            self.cov[(k, i)] = 0.0;
            self.cov[(i, k)] = 0.0;
        }
        self.cov[(k, k)] = self.cfg.head_noise * self.cfg.head_noise;
        self.yaw_aligned = true;
    }

    /// Adds the error `dx` to the nominal state (`R <- exp([dth]x) R`) and
    /// holds the biases within `EKF2_GYR_B_LIM` and `EKF2_ABL_LIM`.
    fn inject(&mut self, dx: &nalgebra::SVector<f64, { covariance::N }>) {
        self.pos_ned += dx.fixed_rows::<3>(idx::POS);
        self.vel_ned += dx.fixed_rows::<3>(idx::VEL);
        let dth: Vector3<f64> = dx.fixed_rows::<3>(idx::ANG).into_owned();
        self.att =
            UnitQuaternion::new_normalize(UnitQuaternion::from_scaled_axis(dth).into_inner() * self.att.into_inner());
        self.rot = self.att.to_rotation_matrix().into_inner();
        let glim = self.cfg.gyr_b_lim;
        let alim = self.cfg.abl_lim;
        self.gyro_bias = (self.gyro_bias + dx.fixed_rows::<3>(idx::GB)).map(|b| b.clamp(-glim, glim));
        self.accel_bias = (self.accel_bias + dx.fixed_rows::<3>(idx::AB)).map(|b| b.clamp(-alim, alim));
    }

    /// Innovation variance of a measurement of state `i` (`H = e_i`).
    fn var_of(&self, i: usize, r: f64) -> f64 {
        self.cov[(i, i)] + r
    }

    /// The scalar update for `H = e_i` with innovation `innov = z - x_i` and
    /// innovation variance `s`: `P <- P - P e_i e_i^T P / s`.
    fn fuse_direct(&mut self, i: usize, innov: f64, s: f64) {
        let col = self.cov.column(i).into_owned();
        let k = col / s;
        self.cov -= k * col.transpose();
        self.inject(&(k * innov));
    }

    /// `innov^2 / (gate^2 s)`, EKF2's internal test ratio.
    fn ratio(innov: f64, s: f64, gate: f64) -> f64 {
        innov * innov / (gate.max(1.0).powi(2) * s)
    }

    /// Resets states `first..first + values.len()` of the position (block
    /// `idx::POS`) or velocity (`idx::VEL`) to `values` with variance `var`,
    /// their cross-covariances zeroed (PX4's `resetHorizontalPositionTo` and kin).
    fn reset_states(&mut self, first: usize, values: &[f64], var: f64) {
        for (k, v) in values.iter().enumerate() {
            let i = first + k;
            for j in 0..covariance::N {
                self.cov[(i, j)] = 0.0;
                self.cov[(j, i)] = 0.0;
            }
            self.cov[(i, i)] = var;
            if i < idx::VEL {
                self.pos_ned[i - idx::POS] = *v;
            } else {
                self.vel_ned[i - idx::VEL] = *v;
            }
        }
    }

    /// Fuses a GNSS fix: horizontal position and 3D velocity per
    /// `EKF2_GPS_CTRL`, each gated; GNSS height as a height source.
    pub fn fuse_gnss(&mut self, fix: &GnssFix) -> Result<(), NavInputError> {
        finite(fix.position_ned_m.as_slice(), "GNSS")?;
        finite(fix.velocity_ned_m_s.as_slice(), "GNSS")?;
        finite(&[fix.time_s, fix.eph_m, fix.epv_m, fix.speed_accuracy_m_s], "GNSS")?;
        let now = self.time_s;
        if self.gnss.last_sample_s.is_none() && !self.gnss.checks_waived {
            self.gnss.last_check_fail_s = now;
        }
        self.gnss.last_sample_s = Some(now);
        let c = &self.cfg;
        let checks_ok = fix.eph_m <= c.req_eph && fix.epv_m <= c.req_epv && fix.speed_accuracy_m_s <= c.req_sacc;
        if checks_ok {
            self.gnss.last_check_pass_s = now;
        } else {
            self.gnss.last_check_fail_s = now;
        }
        let checks_passed = checks_ok && now - self.gnss.last_check_fail_s >= c.req_gps_h;
        if !self.tilt_aligned {
            return Ok(());
        }
        let may_run = self.yaw_aligned && !self.gnss.fault;
        if (self.gnss.pos_active || self.gnss.vel_active) && now - self.gnss.last_check_pass_s > timeouts::RESET_S {
            self.gnss.pos_active = false;
            self.gnss.vel_active = false;
        }
        if checks_ok {
            if self.cfg.gps_ctrl.velocity && may_run {
                self.control_gnss_velocity(fix, checks_passed);
            }
            if self.cfg.gps_ctrl.horizontal_position && may_run {
                self.control_gnss_position(fix, checks_passed);
            }
        }
        if self.cfg.gps_ctrl.altitude {
            let noise = fix.epv_m.max(1.5 * self.cfg.gps_p_noise);
            self.control_height(HeightSource::Gnss, -fix.position_ned_m.z, noise * noise, checks_passed);
        }
        Ok(())
    }

    fn control_gnss_velocity(&mut self, fix: &GnssFix, checks_passed: bool) {
        let now = self.time_s;
        let sd = fix.speed_accuracy_m_s.max(self.cfg.gps_v_noise).max(0.01);
        let r = [sd * sd, sd * sd, sd * sd * 2.25];
        let gate = self.cfg.gps_v_gate;
        let mut worst: f64 = 0.0;
        for (k, &rk) in r.iter().enumerate() {
            let innov = fix.velocity_ned_m_s[k] - self.vel_ned[k];
            worst = worst.max(Self::ratio(innov, self.var_of(idx::VEL + k, rk), gate));
        }
        self.gnss.vel_ratio = Some(worst.sqrt());
        if self.gnss.vel_active {
            if worst <= 1.0 {
                self.fuse_velocity(fix, &r);
            } else if now - self.gnss.last_vel_fuse_s > timeouts::RESET_S {
                self.reset_velocity(fix, r[0]);
            }
        } else if checks_passed {
            if self.gnss.origin_set && worst <= 1.0 {
                self.fuse_velocity(fix, &r);
            } else {
                self.reset_velocity(fix, r[0]);
            }
            self.gnss.vel_active = true;
        }
    }

    fn fuse_velocity(&mut self, fix: &GnssFix, r: &[f64; 3]) {
        for (k, &rk) in r.iter().enumerate() {
            let i = idx::VEL + k;
            let innov = fix.velocity_ned_m_s[k] - self.vel_ned[k];
            let s = self.var_of(i, rk);
            self.fuse_direct(i, innov, s);
        }
        self.gnss.last_vel_fuse_s = self.time_s;
        self.last_horizontal_aiding_s = Some(self.time_s);
    }

    fn reset_velocity(&mut self, fix: &GnssFix, var: f64) {
        self.reset_states(idx::VEL, fix.velocity_ned_m_s.as_slice(), var);
        self.gnss.last_vel_fuse_s = self.time_s;
        self.gnss.vel_ratio = Some(0.0);
    }

    fn control_gnss_position(&mut self, fix: &GnssFix, checks_passed: bool) {
        let now = self.time_s;
        let sd = fix.eph_m.max(self.cfg.gps_p_noise).min(self.cfg.noaid_noise).max(0.01);
        let r = sd * sd;
        let gate = self.cfg.gps_p_gate;
        let mut worst: f64 = 0.0;
        for k in 0..2 {
            let innov = fix.position_ned_m[k] - self.pos_ned[k];
            worst = worst.max(Self::ratio(innov, self.var_of(idx::POS + k, r), gate));
        }
        self.gnss.pos_ratio = Some(worst.sqrt());
        if self.gnss.pos_active {
            if worst <= 1.0 {
                self.fuse_horizontal_position(fix, r);
            } else if now - self.gnss.last_pos_fuse_s > timeouts::RESET_S {
                self.reset_horizontal_position(fix, r);
            }
        } else if checks_passed {
            if self.gnss.origin_set && worst <= 1.0 {
                self.fuse_horizontal_position(fix, r);
            } else {
                self.reset_horizontal_position(fix, r);
            }
            self.gnss.origin_set = true;
            self.gnss.pos_active = true;
        }
    }

    fn fuse_horizontal_position(&mut self, fix: &GnssFix, r: f64) {
        for k in 0..2 {
            let i = idx::POS + k;
            let innov = fix.position_ned_m[k] - self.pos_ned[k];
            let s = self.var_of(i, r);
            self.fuse_direct(i, innov, s);
        }
        self.gnss.last_pos_fuse_s = self.time_s;
        self.last_horizontal_aiding_s = Some(self.time_s);
    }

    fn reset_horizontal_position(&mut self, fix: &GnssFix, r: f64) {
        self.reset_states(idx::POS, &[fix.position_ned_m.x, fix.position_ned_m.y], r);
        self.gnss.last_pos_fuse_s = self.time_s;
        self.gnss.pos_ratio = Some(0.0);
        self.gnss.position_resets += 1;
    }

    /// Fuses a barometric height (stale samples stop barometric height, as
    /// PX4's sensor voter drops a stuck barometer).
    pub fn fuse_baro(&mut self, baro: &BaroHeight) -> Result<(), NavInputError> {
        finite(&[baro.time_s, baro.height_m], "barometer")?;
        let stale = self.baro_stale.update([baro.height_m, 0.0, 0.0]);
        if !self.tilt_aligned || stale {
            if stale {
                self.stop_height(HeightSource::Baro);
            }
            return Ok(());
        }
        if self.cfg.baro_ctrl {
            let r = self.cfg.baro_noise * self.cfg.baro_noise;
            self.control_height(HeightSource::Baro, baro.height_m, r, true);
        }
        Ok(())
    }

    fn aid(&mut self, source: HeightSource) -> &mut HeightAid {
        match source {
            HeightSource::Baro => &mut self.baro,
            HeightSource::Gnss => &mut self.gnss_hgt,
        }
    }

    fn configured_ref(&self) -> HeightSource {
        match self.cfg.hgt_ref {
            HeightRef::Baro => HeightSource::Baro,
            HeightRef::Gnss => HeightSource::Gnss,
        }
    }

    /// One height sample of `source` (`z` = height above origin, variance
    /// `r`): PX4's `controlBaroHeightFusion` / `controlGnssHeightFusion`.
    fn control_height(&mut self, source: HeightSource, z: f64, r: f64, may_start: bool) {
        let now = self.time_s;
        let is_ref = self.height_ref == Some(source);
        let nsd = self.cfg.hgt_bias_nsd;
        let gate = self.cfg.baro_gate;
        let p_dd = self.cov[(idx::POS + 2, idx::POS + 2)];
        let pos_d = self.pos_ned.z;
        let aid = self.aid(source);
        aid.last_sample_s = Some(now);
        // bias: predicted always, learnt only while not the reference
        aid.bias_var += nsd * nsd * (now - aid.bias_time_s).max(0.0);
        aid.bias_time_s = now;
        let innov_meas = -(z - aid.bias_m) - pos_d;
        let s = p_dd + r + aid.bias_var;
        let test = Self::ratio(innov_meas, s, gate);
        aid.test_ratio = Some(test.sqrt());
        if aid.active && !is_ref {
            let b_innov = (z + pos_d) - aid.bias_m;
            let sb = aid.bias_var + r + p_dd;
            let k = aid.bias_var / sb;
            aid.bias_m += k * b_innov;
            aid.bias_var *= 1.0 - k;
        }
        let (active, fault, last_fuse) = (aid.active, aid.fault, aid.last_fuse_s);
        if active {
            if test <= 1.0 {
                self.fuse_direct(idx::POS + 2, innov_meas, s);
                self.aid(source).last_fuse_s = now;
                self.last_height_fuse_s = Some(now);
            } else if is_ref && self.last_height_fuse_s.is_none_or(|t| now - t > timeouts::HGT_FUSION_S) {
                // all height sources failing: reset the height to the reference
                let bias = self.aid(source).bias_m;
                self.reset_states(idx::POS + 2, &[-(z - bias)], r);
                self.aid(source).last_fuse_s = now;
                self.last_height_fuse_s = Some(now);
            } else if now - last_fuse > timeouts::HGT_FUSION_S {
                let other_working = self
                    .last_height_fuse_s
                    .is_some_and(|t| now - t <= timeouts::HGT_FUSION_S);
                self.stop_height(source);
                if other_working {
                    self.aid(source).fault = true;
                }
            }
        } else if may_start && !fault {
            let configured = self.configured_ref() == source;
            let first_height = self.last_height_fuse_s.is_none();
            let aid = self.aid(source);
            aid.active = true;
            aid.last_fuse_s = now;
            if first_height {
                // the first height source defines the height above the origin
                aid.bias_m = 0.0;
                aid.bias_var = 0.0;
                self.reset_states(idx::POS + 2, &[-z], r);
                self.last_height_fuse_s = Some(now);
                if configured {
                    self.height_ref = Some(source);
                }
            } else if configured {
                // PX4 ("starting height fusion, resetting height"): the
                // configured reference sets the height, and the other
                // sources' biases follow the jump (`b = z + p_d`)
                aid.bias_m = 0.0;
                aid.bias_var = 0.0;
                self.reset_states(idx::POS + 2, &[-z], r);
                let jump = self.pos_ned.z - pos_d;
                let other = match source {
                    HeightSource::Baro => &mut self.gnss_hgt,
                    HeightSource::Gnss => &mut self.baro,
                };
                other.bias_m += jump;
                self.last_height_fuse_s = Some(now);
                self.height_ref = Some(source);
            } else {
                aid.bias_m = z + pos_d;
                aid.bias_var = r;
            }
        }
        self.height_ref_fallback();
    }

    fn stop_height(&mut self, source: HeightSource) {
        let aid = self.aid(source);
        aid.active = false;
        if self.height_ref == Some(source) {
            self.height_ref = None;
        }
        self.height_ref_fallback();
    }

    /// PX4's `checkHeightSensorRefFallback`: without a working reference,
    /// the first active source in the order of `EKF2_HGT_REF` becomes it.
    fn height_ref_fallback(&mut self) {
        if self.height_ref.is_some() {
            return;
        }
        let order = match self.cfg.hgt_ref {
            HeightRef::Baro => [HeightSource::Baro, HeightSource::Gnss],
            HeightRef::Gnss => [HeightSource::Gnss, HeightSource::Baro],
        };
        self.height_ref = order.into_iter().find(|s| match s {
            HeightSource::Baro => self.baro.active,
            HeightSource::Gnss => self.gnss_hgt.active,
        });
    }

    /// Fuses the magnetic heading of a magnetometer sample (PX4's
    /// `EKF2_MAG_TYPE` = 1, magnetic heading), gated by `EKF2_HDG_GATE`.
    ///
    /// ```text
    /// psi = atan2(R_10, R_00);  for R = exp([dth]x) R:
    /// H_ang = [-R_00 R_20, -R_10 R_20, R_00^2 + R_10^2] / (R_00^2 + R_10^2)
    /// ```
    pub fn fuse_mag(&mut self, mag: &MagField) -> Result<(), NavInputError> {
        finite(mag.field_frd_gauss.as_slice(), "magnetometer")?;
        finite(&[mag.time_s], "magnetometer")?;
        let now = self.time_s;
        let m = mag.field_frd_gauss;
        if self.mag.stale.update([m.x, m.y, m.z]) {
            self.mag.active = false;
            return Ok(());
        }
        self.mag.last_sample_s = Some(now);
        if !self.tilt_aligned {
            self.last_mag_frd = Some(m);
            return Ok(());
        }
        if !self.yaw_aligned {
            self.reset_yaw(self.mag_heading(&m));
        }
        if self.mag.fault {
            return Ok(());
        }
        let meas = self.mag_heading(&m);
        let r = &self.rot;
        let n = r[(0, 0)] * r[(0, 0)] + r[(1, 0)] * r[(1, 0)];
        if n < 1e-6 {
            return Ok(());
        }
        let pred = r[(1, 0)].atan2(r[(0, 0)]);
        let h = Vector3::new(-r[(0, 0)] * r[(2, 0)] / n, -r[(1, 0)] * r[(2, 0)] / n, 1.0);
        let innov = crate::math::wrap_pi(meas - pred);
        let ph = self.cov.fixed_columns::<3>(idx::ANG) * h;
        let s = h.dot(&ph.fixed_rows::<3>(idx::ANG)) + self.cfg.head_noise * self.cfg.head_noise;
        let test = Self::ratio(innov, s, self.cfg.hdg_gate);
        self.mag.ratio = Some(test.sqrt());
        if !self.mag.active {
            self.mag.active = true;
            self.mag.last_fuse_s = now;
        }
        if test <= 1.0 {
            let k = ph / s;
            self.cov -= k * ph.transpose();
            self.inject(&(k * innov));
            self.mag.last_fuse_s = now;
        } else if now - self.mag.last_fuse_s > timeouts::RESET_S {
            // PX4: with other aiding in flight, a heading that keeps failing is a mag fault
            self.mag.active = false;
            self.mag.fault = true;
        }
        Ok(())
    }

    /// PX4's `controlFakePosFusion`: without horizontal aiding for
    /// `EKF2_NOAID_TOUT` (or before any), the position held when aiding
    /// ended is fused every 0.2 s with noise `EKF2_NOAID_NOISE`, which keeps
    /// the velocity and tilt errors bounded.
    fn control_fake_position(&mut self) {
        let now = self.time_s;
        let noaid = f64::from(self.cfg.noaid_tout_us) * 1e-6;
        let unaided = self.last_horizontal_aiding_s.is_none_or(|t| now - t > noaid);
        if !unaided {
            self.fake_position = None;
            return;
        }
        let (held, last) = *self.fake_position.get_or_insert((self.pos_ned, now));
        if now - last < FAKE_POS_PERIOD_S {
            return;
        }
        let r = self.cfg.noaid_noise * self.cfg.noaid_noise;
        for k in 0..2 {
            let innov = held[k] - self.pos_ned[k];
            let s = self.var_of(idx::POS + k, r);
            self.fuse_direct(idx::POS + k, innov, s);
        }
        self.fake_position = Some((held, now));
    }

    /// Data timeouts, checked at the covariance rate: a source silent past
    /// PX4's interval stops (GNSS: `reset_timeout_max`).
    fn check_timeouts(&mut self) {
        let now = self.time_s;
        let silent = |t: Option<f64>, limit: f64| t.is_some_and(|t| now - t > limit);
        if self.baro.active && silent(self.baro.last_sample_s, timeouts::BARO_DATA_S) {
            self.stop_height(HeightSource::Baro);
        }
        if self.gnss_hgt.active && silent(self.gnss_hgt.last_sample_s, timeouts::GNSS_HGT_DATA_S) {
            self.stop_height(HeightSource::Gnss);
        }
        if (self.gnss.pos_active || self.gnss.vel_active) && silent(self.gnss.last_sample_s, timeouts::RESET_S) {
            self.gnss.pos_active = false;
            self.gnss.vel_active = false;
        }
        if self.mag.active && silent(self.mag.last_sample_s, timeouts::MAG_DATA_S) {
            self.mag.active = false;
        }
    }
}
