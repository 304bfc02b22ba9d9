//! The raw sensors a navigation filter fuses: accelerometer and gyroscope
//! (the IMU), barometer, magnetometer and GNSS receiver, sampled from the
//! true state at PX4 SITL's rates with its noise figures, on their own
//! seeded ChaCha8 stream (never the navigation solution's: turning the raw
//! sensors on changes no other number of a flight).
//!
//! | sensor | rate | model | source of the figures |
//! |---|---|---|---|
//! | accelerometer | 250 Hz | `f~ = mean over the interval of R^T (a - g e3), + b_a + n_a`, FRD [m/s^2] | Gazebo's IMU plugin defaults (ADIS16448), no turn-on bias (the gz x500's) |
//! | gyroscope | 250 Hz | `w~ = mean over the interval of w, + b_w + n_w`, FRD [rad/s] | the same |
//! | barometer | 20 Hz | ISA troposphere at `h = alt_home - p_z`, plus 1 Pa noise | PX4 `sensor_baro_sim` |
//! | magnetometer | 50 Hz | `m~ = R^T B_ned + n_m`, FRD [gauss] | PX4 `sensor_mag_sim` |
//! | GNSS | 8 Hz | position, NED velocity plus Gauss-Markov noise, one epoch late | PX4 `sensor_gps_sim` |
//!
//! **IMU** (Gazebo's `gazebo_imu_plugin`, the model PX4's Gazebo SITL flew):
//! each sample is what an IMU driver integrates over its interval (PX4's
//! `sensor_combined` carries `delta_velocity / dt`, `delta_angle / dt`): the
//! mean over the simulation steps since the last sample of the specific
//! force `R_j^T ((v_j - v_{j-1}) / dt - g e3)` (each step's true velocity
//! change, so a touchdown's stop is felt as the impulse it is) and of the
//! body rate (at a touchdown, which levels the vehicle in one step, the
//! step's rotation, and the stop's force taken in at the attitude halfway
//! through it: [`step_motion`]). On top of the mean,
//! white noise of density `sigma` [unit/sqrt(Hz)] sampled every `dt` has the
//! standard deviation `sigma / sqrt(dt)`; the bias starts at a turn-on value
//! drawn once and then follows a first-order Gauss-Markov process of
//! correlation time `tau` driven by the random walk `sigma_b`:
//!
//! ```text
//! b_{k+1} = exp(-dt/tau) b_k + sqrt(sigma_b^2 tau / 2 (1 - exp(-2 dt/tau))) N(0, 1)
//! ```
//!
//! **Barometer** (PX4's `sensor_baro_sim`): the ISA troposphere's pressure
//! and temperature at the true altitude ([`crate::geo::isa`]: 288 K at sea
//! level, as PX4's simulator takes it); white noise of 1 Pa; PX4's drift
//! rate is 0 Pa/s and so is ours.
//!
//! **Magnetometer** (PX4's `sensor_mag_sim`): the Earth's field at home
//! ([`crate::geo::earth_field_ned_gauss`]) rotated into the body by the true
//! attitude, plus white noise of 0.02, 0.02, 0.03 gauss per axis.
//!
//! **GNSS** (PX4's `sensor_gps_sim` at 8 Hz): each axis of the position
//! error follows `e_{k+1} = 0.76 e_k + 0.02 * 0.8 m N(0,1)` (down: 1.5 times
//! the noise) and of the velocity error `e_{k+1} = 0.54 e_k + 0.4 * 0.05 m/s
//! N(0,1)` (down: 1.2 times); it reports PX4's accuracies with a fix (eph
//! 0.9 m, epv 1.78 m, speed accuracy 0.4 m/s, HDOP 0.7, VDOP 1.1). The fix
//! taken at one epoch is delivered at the next, 125 ms later: the receiver's
//! latency (PX4's `EKF2_GPS_DELAY` defaults to 110 ms).
//!
//! **Faults** ([`SensorFaults`]): an OFF sensor delivers nothing (its latest
//! sample is `None`), a STUCK one repeats the last value it gave, stamped
//! with the new time, as PX4's simulated sensors do. The GNSS receiver follows
//! the world's one GNSS state: no fix, no sample; a wrong position, the
//! sample is off by the same offset as the navigation solution. The noise
//! streams run on whatever the faults, so a fault on one sensor changes no
//! other sensor's numbers.

use std::f64::consts::PI;

use nalgebra::{UnitQuaternion, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use super::sensors::splitmix64;
use crate::geo::{GeoPoint, earth_field_ned_gauss, isa};
use crate::signals::{AxesSample, BaroSample, GRAVITY, GnssSample, GpsFix, Measurement, RawSensorReadings};

/// IMU sample rate [Hz] (the IMU `update_rate` of PX4's Gazebo x500).
pub const IMU_RATE_HZ: f64 = 250.0;
/// Barometer sample rate [Hz] (PX4 `sensor_baro_sim`: every 50 ms).
pub const BARO_RATE_HZ: f64 = 20.0;
/// Magnetometer sample rate [Hz] (PX4 `sensor_mag_sim`: every 20 ms).
pub const MAG_RATE_HZ: f64 = 50.0;
/// GNSS solution rate [Hz] (PX4 `sensor_gps_sim`: every 125 ms).
pub const GNSS_RATE_HZ: f64 = 8.0;

/// Accelerometer noise density [m/s^2/sqrt(Hz)] (Gazebo IMU plugin: 2 x 2.0e-3).
pub const ACCEL_NOISE_DENSITY: f64 = 2.0 * 2.0e-3;
/// Accelerometer bias random walk [m/s^3/sqrt(Hz)] (Gazebo: 2 x 3.0e-3).
pub const ACCEL_RANDOM_WALK: f64 = 2.0 * 3.0e-3;
/// Accelerometer bias correlation time [s] (Gazebo: 300 s).
pub const ACCEL_BIAS_TAU_S: f64 = 300.0;
/// Accelerometer turn-on bias, 1 sigma per axis [m/s^2]: none, as on
/// PX4's default SITL vehicle (the gz x500's IMU has no turn-on bias: a
/// calibrated sensor). Gazebo classic's plugin drew 20 mg; in a hover a
/// horizontal bias `b` is one with a tilt `b / g`, which no filter can
/// tell apart, and the wrench estimator would read `m b` (0.7 N for a 2 kg
/// quad at 1.8 sigma) as an external force. The turn-on draw is still
/// made, so that the other draws keep their values; a biased accelerometer
/// is a fault to inject (`SENSOR_ACCEL` WRONG).
pub const ACCEL_TURN_ON_BIAS: f64 = 0.0;
/// Gyroscope noise density [rad/s/sqrt(Hz)] (Gazebo: 2 x 35 deg/h/sqrt(Hz)).
pub const GYRO_NOISE_DENSITY: f64 = 2.0 * 35.0 / 3600.0 / 180.0 * PI;
/// Gyroscope bias random walk [rad/s^2/sqrt(Hz)] (Gazebo: 2 x 4 deg/h/sqrt(h)).
pub const GYRO_RANDOM_WALK: f64 = 2.0 * 4.0 / 3600.0 / 180.0 * PI;
/// Gyroscope bias correlation time [s] (Gazebo: 1000 s).
pub const GYRO_BIAS_TAU_S: f64 = 1000.0;
/// Gyroscope turn-on bias, 1 sigma per axis [rad/s] (Gazebo: 0.5 deg/s).
pub const GYRO_TURN_ON_BIAS: f64 = 0.5 / 180.0 * PI;
/// Magnetometer white noise per FRD axis [gauss] (PX4 `sensor_mag_sim`).
pub const MAG_NOISE_GAUSS: [f64; 3] = [0.02, 0.02, 0.03];
/// Barometer white noise [Pa] (PX4 `sensor_baro_sim`: 1 Pa RMS).
pub const BARO_NOISE_PA: f64 = 1.0;

/// GNSS position error: Markov coefficient per epoch (PX4 `sensor_gps_sim`).
const GNSS_POS_MARKOV: f64 = 0.76;
/// GNSS position error: driving noise per epoch [m] (0.02 x 0.8 m).
const GNSS_POS_DRIVE_M: f64 = 0.02 * 0.8;
/// GNSS velocity error: Markov coefficient per epoch.
const GNSS_VEL_MARKOV: f64 = 0.54;
/// GNSS velocity error: driving noise per epoch [m/s] (0.4 x 0.05 m/s).
const GNSS_VEL_DRIVE_M_S: f64 = 0.4 * 0.05;
/// What the receiver reports with a fix (PX4 `sensor_gps_sim`).
const GNSS_EPH_M: f64 = 0.9;
const GNSS_EPV_M: f64 = 1.78;
const GNSS_SPEED_ACC_M_S: f64 = 0.4;
const GNSS_HDOP: f64 = 0.7;
const GNSS_VDOP: f64 = 1.1;

/// A raw sensor's health, as MAV_CMD_INJECT_FAILURE sets it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SensorMode {
    /// Works.
    #[default]
    Ok,
    /// Delivers nothing.
    Off,
    /// Repeats the last value it gave.
    Stuck,
}

/// The raw sensors' injected faults (the GNSS receiver's OFF and WRONG are
/// the world's one GNSS state, [`super::ActiveFaults`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SensorFaults {
    /// Accelerometer.
    pub accel: SensorMode,
    /// Gyroscope.
    pub gyro: SensorMode,
    /// Magnetometer.
    pub mag: SensorMode,
    /// Barometer.
    pub baro: SensorMode,
    /// Whether the GNSS receiver repeats its last solution.
    pub gnss_stuck: bool,
}

impl SensorFaults {
    /// Whether any is set.
    #[must_use]
    pub fn any(&self) -> bool {
        *self != SensorFaults::default()
    }
}

/// What the GNSS receiver is told of the world's GNSS state at an instant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct GnssState {
    /// Whether it has a fix.
    pub available: bool,
    /// The wrong-position offset [m] NED, if injected.
    pub offset_ned: Option<Vector3<f64>>,
    /// Satellites it reports with a fix.
    pub satellites: u8,
}

/// A GNSS fix taken, waiting to be delivered.
#[derive(Clone, Copy, Debug, PartialEq)]
struct PendingFix {
    time_s: f64,
    position_ned: Vector3<f64>,
    velocity_ned: Vector3<f64>,
}

/// What the IMU integrates over the step that ended at `truth`: the body
/// rate [rad/s] FRD and the attitude that takes the step's specific force
/// into the body. After any step but a touchdown, the true rate and attitude
/// at its end. A touchdown (`touched_down`) stops the vehicle and levels it
/// in one step, leaving it no rate: then the step's rotation
/// `log(q_{j-1}^-1 q_j) / dt` and the attitude halfway through it (the
/// navigation filter's own assumption, `R_mid`), so that the gyroscope feels
/// the levelling as the accelerometer feels the stop, and the stop's impulse
/// is not tilted by the levelling. The gyroscope is not clipped: a hard
/// landing's levelling reads some 100 rad/s for one sample.
fn step_motion(
    last: Option<&UnitQuaternion<f64>>,
    truth: &Measurement,
    touched_down: bool,
    dt_s: f64,
) -> (Vector3<f64>, UnitQuaternion<f64>) {
    match last {
        Some(q0) if touched_down => {
            let rotation = (q0.inverse() * truth.attitude).scaled_axis();
            (rotation / dt_s, q0 * UnitQuaternion::from_scaled_axis(rotation * 0.5))
        }
        _ => (truth.rate_frd, truth.attitude),
    }
}

/// `(phi, sigma_d)` of a first-order Gauss-Markov bias sampled every `dt`
/// (module doc).
fn gauss_markov(random_walk: f64, tau_s: f64, dt_s: f64) -> (f64, f64) {
    let phi = (-dt_s / tau_s).exp();
    (
        phi,
        (random_walk * random_walk * tau_s / 2.0 * (1.0 - phi * phi)).sqrt(),
    )
}

/// Steps between two samples at `rate_hz` (at least one).
fn every(rate_hz: f64, dt_s: f64) -> u64 {
    ((1.0 / (rate_hz * dt_s)).round() as u64).max(1)
}

/// One vehicle's raw sensors.
/// Sums over the simulation steps since the IMU's last sample, FRD.
#[derive(Clone, Copy, Debug, Default)]
struct ImuSum {
    /// Specific force [m/s^2].
    force_frd: Vector3<f64>,
    /// Body rate [rad/s].
    rate_frd: Vector3<f64>,
    /// How many steps the sums hold.
    steps: u32,
}

#[derive(Clone, Debug)]
pub(super) struct RawSensors {
    home: GeoPoint,
    /// The Earth's field at home [gauss], NED.
    field_ned: Vector3<f64>,
    rng: ChaCha8Rng,
    dt_s: f64,
    /// Steps between samples: IMU, barometer, magnetometer, GNSS.
    every: [u64; 4],
    accel_bias: Vector3<f64>,
    gyro_bias: Vector3<f64>,
    gnss_pos_err: Vector3<f64>,
    gnss_vel_err: Vector3<f64>,
    pending: Option<PendingFix>,
    /// The last value each sensor gave (what a stuck one repeats).
    last: RawSensorReadings,
    /// The true NED velocity at the last step [m/s] (None before the first).
    last_velocity_ned: Option<Vector3<f64>>,
    /// The true attitude at the last step (None before the first).
    last_attitude: Option<UnitQuaternion<f64>>,
    /// What the IMU has summed since its last sample.
    imu_sum: ImuSum,
    /// The step of the first sample (the sensors' power-on): the sample
    /// instants are counted from it.
    first_step: Option<u64>,
}

impl RawSensors {
    /// The raw sensors of a vehicle whose home is `home`, stepped every
    /// `dt_s`, on a stream derived from the vehicle's `seed` (never the
    /// navigation solution's stream).
    pub(super) fn new(home: GeoPoint, dt_s: f64, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(splitmix64(seed ^ 0x5241_575F_5345_4E53));
        let mut draw = || -> Vector3<f64> {
            Vector3::new(
                StandardNormal.sample(&mut rng),
                StandardNormal.sample(&mut rng),
                StandardNormal.sample(&mut rng),
            )
        };
        let accel_bias = draw() * ACCEL_TURN_ON_BIAS;
        let gyro_bias = draw() * GYRO_TURN_ON_BIAS;
        Self {
            home,
            field_ned: earth_field_ned_gauss(&home),
            rng,
            dt_s,
            every: [
                every(IMU_RATE_HZ, dt_s),
                every(BARO_RATE_HZ, dt_s),
                every(MAG_RATE_HZ, dt_s),
                every(GNSS_RATE_HZ, dt_s),
            ],
            accel_bias,
            gyro_bias,
            gnss_pos_err: Vector3::zeros(),
            gnss_vel_err: Vector3::zeros(),
            pending: None,
            last: RawSensorReadings::default(),
            last_velocity_ned: None,
            last_attitude: None,
            imu_sum: ImuSum::default(),
            first_step: None,
        }
    }

    fn gauss3(&mut self) -> Vector3<f64> {
        let mut draw = || -> f64 { StandardNormal.sample(&mut self.rng) };
        Vector3::new(draw(), draw(), draw())
    }

    /// Sample the sensors due at the instant of `truth` into `out`, given
    /// the true NED acceleration `accel_ned` [m/s^2] at that instant (used
    /// only at the first step seen: after it, the step's velocity change),
    /// whether the step that ended there was a touchdown, the injected
    /// faults and the GNSS state. Called once every step; the sensors not
    /// due keep their latest sample.
    pub(super) fn sample(
        &mut self,
        truth: &Measurement,
        accel_ned: &Vector3<f64>,
        touched_down: bool,
        faults: &SensorFaults,
        gnss: GnssState,
        out: &mut RawSensorReadings,
    ) {
        let t = truth.time_s;
        let step = (t / self.dt_s).round() as u64;
        let k = step.saturating_sub(*self.first_step.get_or_insert(step));
        let r: &UnitQuaternion<f64> = &truth.attitude;
        let a = match self.last_velocity_ned {
            Some(v0) => (truth.velocity_ned - v0) / self.dt_s,
            None => *accel_ned,
        };
        self.last_velocity_ned = Some(truth.velocity_ned);
        let (rate_frd, felt_in) = step_motion(self.last_attitude.as_ref(), truth, touched_down, self.dt_s);
        self.last_attitude = Some(truth.attitude);
        self.imu_sum.force_frd += felt_in.inverse_transform_vector(&(a - Vector3::new(0.0, 0.0, GRAVITY)));
        self.imu_sum.rate_frd += rate_frd;
        self.imu_sum.steps += 1;
        if k.is_multiple_of(self.every[0]) {
            let dt = self.every[0] as f64 * self.dt_s;
            let (phi_a, sd_a) = gauss_markov(ACCEL_RANDOM_WALK, ACCEL_BIAS_TAU_S, dt);
            let (phi_w, sd_w) = gauss_markov(GYRO_RANDOM_WALK, GYRO_BIAS_TAU_S, dt);
            let n_a = self.gauss3() * (ACCEL_NOISE_DENSITY / dt.sqrt());
            let n_w = self.gauss3() * (GYRO_NOISE_DENSITY / dt.sqrt());
            let db_a = self.gauss3() * sd_a;
            let db_w = self.gauss3() * sd_w;
            let sum = std::mem::take(&mut self.imu_sum);
            let n = f64::from(sum.steps);
            let accel = sum.force_frd / n + self.accel_bias + n_a;
            let gyro = sum.rate_frd / n + self.gyro_bias + n_w;
            self.accel_bias = self.accel_bias * phi_a + db_a;
            self.gyro_bias = self.gyro_bias * phi_w + db_w;
            out.accel = apply(faults.accel, &mut self.last.accel, AxesSample { time_s: t, frd: accel });
            out.gyro = apply(faults.gyro, &mut self.last.gyro, AxesSample { time_s: t, frd: gyro });
        }
        if k.is_multiple_of(self.every[1]) {
            let (p, temp) = isa(self.home.alt_amsl_m - truth.position_ned.z);
            let noise: f64 = StandardNormal.sample(&mut self.rng);
            let s = BaroSample {
                time_s: t,
                pressure_pa: p + BARO_NOISE_PA * noise,
                temperature_c: temp,
            };
            out.baro = apply(faults.baro, &mut self.last.baro, s);
        }
        if k.is_multiple_of(self.every[2]) {
            let n = self.gauss3().component_mul(&Vector3::from(MAG_NOISE_GAUSS));
            let s = AxesSample {
                time_s: t,
                frd: r.inverse_transform_vector(&self.field_ned) + n,
            };
            out.mag = apply(faults.mag, &mut self.last.mag, s);
        }
        if k.is_multiple_of(self.every[3]) {
            self.gnss_epoch(truth, faults.gnss_stuck, gnss, out);
        }
    }

    /// A GNSS epoch: deliver the fix taken at the last epoch, take this one's.
    fn gnss_epoch(&mut self, truth: &Measurement, stuck: bool, gnss: GnssState, out: &mut RawSensorReadings) {
        let down = Vector3::new(1.0, 1.0, 1.5);
        let down_v = Vector3::new(1.0, 1.0, 1.2);
        let wp = self.gauss3().component_mul(&down) * GNSS_POS_DRIVE_M;
        let wv = self.gauss3().component_mul(&down_v) * GNSS_VEL_DRIVE_M_S;
        self.gnss_pos_err = self.gnss_pos_err * GNSS_POS_MARKOV + wp;
        self.gnss_vel_err = self.gnss_vel_err * GNSS_VEL_MARKOV + wv;
        let taken = PendingFix {
            time_s: truth.time_s,
            position_ned: truth.position_ned + self.gnss_pos_err,
            velocity_ned: truth.velocity_ned + self.gnss_vel_err,
        };
        let delivered = self.pending.replace(taken);
        out.gnss = match delivered {
            _ if !gnss.available => None,
            // stuck: the last solution again, stamped as a fresh one would be
            _ if stuck && self.last.gnss.is_some() => self.last.gnss.map(|g| GnssSample {
                time_s: delivered.map_or(truth.time_s, |f| f.time_s),
                delivered_s: truth.time_s,
                ..g
            }),
            None => None,
            Some(fix) => {
                let p = fix.position_ned + gnss.offset_ned.unwrap_or_else(Vector3::zeros);
                let at = self.home.offset(&p);
                let s = GnssSample {
                    time_s: fix.time_s,
                    delivered_s: truth.time_s,
                    lat_deg: at.lat_deg,
                    lon_deg: at.lon_deg,
                    alt_amsl_m: at.alt_amsl_m,
                    velocity_ned: fix.velocity_ned,
                    eph_m: GNSS_EPH_M,
                    epv_m: GNSS_EPV_M,
                    speed_accuracy_m_s: GNSS_SPEED_ACC_M_S,
                    hdop: GNSS_HDOP,
                    vdop: GNSS_VDOP,
                    fix: GpsFix::Fix3d,
                    satellites: gnss.satellites,
                };
                self.last.gnss = Some(s);
                Some(s)
            }
        };
    }
}

/// A sample that a stuck sensor re-stamps.
trait Stamped: Copy {
    /// The instant it describes [s].
    fn time(&self) -> f64;
    /// The same values stamped `time_s`.
    fn at(self, time_s: f64) -> Self;
}

impl Stamped for AxesSample {
    fn time(&self) -> f64 {
        self.time_s
    }
    fn at(self, time_s: f64) -> Self {
        AxesSample { time_s, ..self }
    }
}

impl Stamped for BaroSample {
    fn time(&self) -> f64 {
        self.time_s
    }
    fn at(self, time_s: f64) -> Self {
        BaroSample { time_s, ..self }
    }
}

/// The sample a sensor in `mode` delivers given a fresh one: none when off,
/// the last value re-stamped when stuck (the fresh one if it never gave
/// one), the fresh one otherwise (then kept as the last).
fn apply<S: Stamped>(mode: SensorMode, last: &mut Option<S>, fresh: S) -> Option<S> {
    match (mode, *last) {
        (SensorMode::Off, _) => None,
        (SensorMode::Stuck, Some(l)) => Some(l.at(fresh.time())),
        _ => {
            *last = Some(fresh);
            Some(fresh)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at_rest(t: f64) -> Measurement {
        Measurement {
            time_s: t,
            ..Measurement::default()
        }
    }

    /// Sample a level vehicle at rest for `seconds`, every `dt`; the samples
    /// each sensor gave (a new one when its time moved on).
    fn run(
        raw: &mut RawSensors,
        faults: SensorFaults,
        seconds: f64,
        truth: impl Fn(f64) -> Measurement,
    ) -> Vec<RawSensorReadings> {
        let mut out = RawSensorReadings::default();
        let mut all = Vec::new();
        let gnss = GnssState {
            available: true,
            offset_ned: None,
            satellites: 12,
        };
        for k in 0..(seconds / raw.dt_s).round() as u64 {
            let m = truth(k as f64 * raw.dt_s);
            // the plant's touchdown: the first step that ends stopped and levelled
            let touched_down = k > 0
                && m.velocity_ned == Vector3::zeros()
                && truth((k - 1) as f64 * raw.dt_s).velocity_ned != Vector3::zeros();
            raw.sample(&m, &Vector3::zeros(), touched_down, &faults, gnss, &mut out);
            all.push(out);
        }
        all
    }

    #[test]
    fn isa_pressure_and_temperature_at_known_altitudes() {
        // the ISA table: 101 325 Pa and 15 degC at sea level, 89 875 Pa at
        // 1000 m, 22 632 Pa at 11 km (PX4's 288 K and 5.256 differ by a few Pa)
        let (p0, t0) = isa(0.0);
        assert_eq!(p0, 101_325.0);
        assert!((t0 - 14.85).abs() < 1e-9, "{t0}");
        assert!((isa(1000.0).0 - 89_875.0).abs() < 10.0, "{}", isa(1000.0).0);
        assert!((isa(11_000.0).0 - 22_632.0).abs() < 30.0, "{}", isa(11_000.0).0);
        // PX4's pressure altitude reads it back within 0.06 % (288 K vs 288.15 K)
        let h = crate::geo::pressure_altitude_m(isa(488.0).0);
        assert!((h - 488.0).abs() < 0.3, "{h}");
    }

    #[test]
    fn imu_noise_has_the_gazebo_density_at_250_hz() {
        let mut raw = RawSensors::new(GeoPoint::PX4_SITL_HOME, 1e-3, 7);
        let b0 = raw.accel_bias;
        let all = run(&mut raw, SensorFaults::default(), 20.0, at_rest);
        let mut acc: Vec<AxesSample> = all.iter().filter_map(|r| r.accel).collect();
        acc.dedup_by(|a, b| a.time_s == b.time_s);
        let mut gyr: Vec<AxesSample> = all.iter().filter_map(|r| r.gyro).collect();
        gyr.dedup_by(|a, b| a.time_s == b.time_s);
        assert_eq!(acc.len(), 5000, "250 Hz for 20 s");
        // consecutive differences: var = 2 sigma^2 (the bias moves far less)
        let sigma = |s: &[AxesSample], axis: usize| {
            let d: Vec<f64> = s.windows(2).map(|w| w[1].frd[axis] - w[0].frd[axis]).collect();
            (d.iter().map(|x| x * x).sum::<f64>() / d.len() as f64 / 2.0).sqrt()
        };
        let sa = ACCEL_NOISE_DENSITY * 250f64.sqrt();
        let sg = GYRO_NOISE_DENSITY * 250f64.sqrt();
        for axis in 0..3 {
            assert!(
                (sigma(&acc, axis) / sa - 1.0).abs() < 0.05,
                "{} vs {sa}",
                sigma(&acc, axis)
            );
            assert!(
                (sigma(&gyr, axis) / sg - 1.0).abs() < 0.05,
                "{} vs {sg}",
                sigma(&gyr, axis)
            );
        }
        // at rest the specific force is -g on z plus the turn-on bias
        let mean_z = acc.iter().map(|s| s.frd.z).sum::<f64>() / acc.len() as f64;
        assert!((mean_z - (-GRAVITY + b0.z)).abs() < 0.01, "{mean_z} {b0}");
    }

    /// GIVEN a level vehicle descending at 1 m/s that stops dead on the ground
    /// at 10.0005 s (a touchdown: one step's velocity change)
    /// WHEN the accelerometer's samples are summed over its intervals
    /// THEN they hold the stop: the specific force's sum times the interval
    /// changes by the 1 m/s the vehicle lost (an instantaneous sample
    /// between the steps would never see it), and at rest it reads -g.
    #[test]
    fn the_accelerometer_feels_the_touchdown_it_integrates_over() {
        let mut raw = RawSensors::new(GeoPoint::PX4_SITL_HOME, 1e-3, 5);
        let falling = |t: f64| Measurement {
            time_s: t,
            velocity_ned: Vector3::new(0.0, 0.0, if t < 10.0005 { 1.0 } else { 0.0 }),
            ..Measurement::default()
        };
        let all = run(&mut raw, SensorFaults::default(), 12.0, falling);
        let mut acc: Vec<AxesSample> = all.iter().filter_map(|r| r.accel).collect();
        acc.dedup_by(|a, b| a.time_s == b.time_s);
        let interval = 1.0 / IMU_RATE_HZ;
        // the specific force's excess over -g along z, integrated [m/s]
        let dv = |from: f64, to: f64| -> f64 {
            acc.iter()
                .filter(|s| s.time_s > from && s.time_s <= to)
                .map(|s| (s.frd.z + GRAVITY) * interval)
                .sum()
        };
        let stop = dv(9.9, 10.1);
        assert!((stop + 1.0).abs() < 0.01, "{stop} m/s: the stop, upward");
        let rest = dv(10.1, 12.0);
        assert!(rest.abs() < 0.01, "{rest}");
    }

    /// GIVEN a vehicle rolled 20 deg, descending at 2 m/s with no rate, that
    /// the touchdown at 10.0005 s stops and levels in one step (as the plant
    /// does)
    /// WHEN the gyroscope's and accelerometer's samples are summed over
    /// their intervals
    /// THEN the gyroscope holds the levelling (its rate times the interval
    /// sums to the -20 deg roll) and the accelerometer the stop along the
    /// attitude halfway through it, so that a strapdown that turns the
    /// stop's impulse by that attitude (the navigation filter's `R_mid`)
    /// finds it vertical.
    #[test]
    fn the_gyroscope_feels_the_levelling_at_a_touchdown() {
        let mut raw = RawSensors::new(GeoPoint::PX4_SITL_HOME, 1e-3, 5);
        let roll = 20f64.to_radians();
        let landing = |t: f64| {
            let before = t < 10.0005;
            Measurement {
                time_s: t,
                velocity_ned: Vector3::new(0.0, 0.0, if before { 2.0 } else { 0.0 }),
                attitude: UnitQuaternion::from_euler_angles(if before { roll } else { 0.0 }, 0.0, 0.0),
                ..Measurement::default()
            }
        };
        let all = run(&mut raw, SensorFaults::default(), 10.5, landing);
        let samples = |f: &dyn Fn(&RawSensorReadings) -> Option<AxesSample>| {
            let mut v: Vec<AxesSample> = all.iter().filter_map(f).collect();
            v.dedup_by(|a, b| a.time_s == b.time_s);
            v
        };
        let (gyr, acc) = (samples(&|r| r.gyro), samples(&|r| r.accel));
        let interval = 1.0 / IMU_RATE_HZ;
        let sum = |v: &[AxesSample], from: f64, to: f64, g: Vector3<f64>| -> Vector3<f64> {
            v.iter()
                .filter(|s| s.time_s > from && s.time_s <= to)
                .map(|s| (s.frd - g) * interval)
                .sum()
        };
        let turned = sum(&gyr, 9.9, 10.1, Vector3::zeros());
        assert!((turned.x + roll).abs() < 0.01, "{turned}: the levelling");
        assert!(turned.yz().norm() < 0.01, "{turned}");
        // the stop, in the body at half the roll: vertical once turned back
        let half = UnitQuaternion::from_euler_angles(0.5 * roll, 0.0, 0.0);
        let stop = half * sum(&acc, 9.9, 10.1, Vector3::zeros());
        let gravity_in = |from: f64, to: f64| -> Vector3<f64> {
            // the sampled intervals' gravity, level or rolled
            acc.iter()
                .filter(|s| s.time_s > from && s.time_s <= to)
                .map(|s| {
                    let q = UnitQuaternion::from_euler_angles(if s.time_s < 10.0005 { roll } else { 0.0 }, 0.0, 0.0);
                    half * q.inverse_transform_vector(&Vector3::new(0.0, 0.0, -GRAVITY)) * interval
                })
                .sum()
        };
        let dv = stop - gravity_in(9.9, 10.1);
        assert!(
            (dv.z + 2.0).abs() < 0.05 && dv.xy().norm() < 0.05,
            "{dv}: the 2 m/s stop, upward"
        );
    }

    #[test]
    fn rates_latency_and_the_field_rotated_by_the_attitude() {
        let mut raw = RawSensors::new(GeoPoint::PX4_SITL_HOME, 1e-3, 3);
        // yawed 90 degrees east: north in the world is -y in the body
        let yawed = |t: f64| Measurement {
            time_s: t,
            attitude: UnitQuaternion::from_euler_angles(0.0, 0.0, std::f64::consts::FRAC_PI_2),
            ..Measurement::default()
        };
        let all = run(&mut raw, SensorFaults::default(), 2.0, yawed);
        let count = |f: &dyn Fn(&RawSensorReadings) -> Option<f64>| {
            let mut t: Vec<f64> = all.iter().filter_map(f).collect();
            t.dedup();
            t.len()
        };
        assert_eq!(count(&|r| r.baro.map(|b| b.time_s)), 40);
        assert_eq!(count(&|r| r.mag.map(|b| b.time_s)), 100);
        // the first GNSS epoch only takes a fix: 15 delivered in 2 s
        assert_eq!(count(&|r| r.gnss.map(|b| b.delivered_s)), 15);
        let last = all.last().unwrap();
        let g = last.gnss.unwrap();
        assert!((g.delivered_s - g.time_s - 0.125).abs() < 1e-9, "{g:?}");
        assert!((g.lat_deg - GeoPoint::PX4_SITL_HOME.lat_deg).abs() < 1e-6);
        assert_eq!((g.fix, g.eph_m, g.epv_m), (GpsFix::Fix3d, 0.9, 1.78));
        let b = earth_field_ned_gauss(&GeoPoint::PX4_SITL_HOME);
        let mean = all.iter().filter_map(|r| r.mag).map(|m| m.frd).sum::<Vector3<f64>>() / all.len() as f64;
        let expect = Vector3::new(b.y, -b.x, b.z);
        assert!((mean - expect).norm() < 0.01, "{mean} vs {expect}");
        // pressure at home's altitude
        let p = last.baro.unwrap().pressure_pa;
        assert!((p - isa(488.0).0).abs() < 5.0, "{p}");
    }

    #[test]
    fn faults_off_stuck_and_gnss_state() {
        let mut raw = RawSensors::new(GeoPoint::PX4_SITL_HOME, 1e-3, 5);
        let mut out = RawSensorReadings::default();
        let mut gnss = GnssState {
            available: true,
            offset_ned: None,
            satellites: 12,
        };
        let mut faults = SensorFaults::default();
        let step = |raw: &mut RawSensors, k: u64, f: &SensorFaults, g: GnssState, out: &mut RawSensorReadings| {
            raw.sample(&at_rest(k as f64 * 1e-3), &Vector3::zeros(), false, f, g, out);
        };
        for k in 0..500 {
            step(&mut raw, k, &faults, gnss, &mut out);
        }
        let before = out;
        faults.baro = SensorMode::Stuck;
        faults.mag = SensorMode::Off;
        faults.gnss_stuck = true;
        for k in 500..1000 {
            step(&mut raw, k, &faults, gnss, &mut out);
        }
        assert_eq!(out.mag, None);
        let (b0, b1) = (before.baro.unwrap(), out.baro.unwrap());
        assert_eq!(b1.pressure_pa, b0.pressure_pa);
        assert!(b1.time_s > b0.time_s);
        let (g0, g1) = (before.gnss.unwrap(), out.gnss.unwrap());
        assert_eq!(g1.lat_deg, g0.lat_deg);
        // a stuck receiver's solution is stamped anew, as every stuck sensor's:
        // the fix time one epoch before its delivery, as a fresh fix's
        assert!(
            g1.delivered_s > g0.delivered_s && g1.time_s > g0.time_s,
            "{g0:?} {g1:?}"
        );
        assert!((g1.delivered_s - g1.time_s - 1.0 / GNSS_RATE_HZ).abs() < 1e-9);
        // the world's GNSS state: a wrong position shifts the fix, no fix gives none
        faults = SensorFaults::default();
        gnss.offset_ned = Some(Vector3::new(30.0, 0.0, 0.0));
        for k in 1000..1300 {
            step(&mut raw, k, &faults, gnss, &mut out);
        }
        let north =
            (out.gnss.unwrap().lat_deg - GeoPoint::PX4_SITL_HOME.lat_deg).to_radians() * crate::geo::EARTH_RADIUS_M;
        assert!((north - 30.0).abs() < 0.5, "{north}");
        assert!(out.mag.is_some() && out.baro.unwrap().pressure_pa != b0.pressure_pa);
        gnss.available = false;
        for k in 1300..1500 {
            step(&mut raw, k, &faults, gnss, &mut out);
        }
        assert_eq!(out.gnss, None);
    }
}
