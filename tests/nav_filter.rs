//! The navigation filter (`estimation::nav`) against known trajectories:
//! IMU, GNSS, barometer and magnetometer samples are synthesised from an
//! analytic hover or figure-eight with seeded noise of PX4 SITL's kind, and
//! the estimate is compared with the truth; then each sensor is made to
//! fail as PX4's failsafe tests make it fail (stuck, lost, wrong).

use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use rotorpilot::estimation::nav::{
    BaroHeight, GnssFix, HeightRef, HeightSource, ImuDelta, MagField, NavConfig, NavFilter, NavInputError,
};
use rotorpilot::signals::GRAVITY;

const IMU_DT: f64 = 1e-3;
/// Gazebo's IMU plugin defaults (PX4 SITL): noise densities and a turn-on bias.
const GYRO_NOISE_DENSITY: f64 = 3.394e-4; // rad/s/sqrt(Hz)
const ACCEL_NOISE_DENSITY: f64 = 4.0e-3; // m/s^2/sqrt(Hz)
const GYRO_BIAS: [f64; 3] = [0.003, -0.002, 0.004]; // rad/s
const ACCEL_BIAS: [f64; 3] = [0.05, -0.08, 0.10]; // m/s^2
/// GNSS at 10 Hz: white position and velocity errors, the accuracies it reports.
const GNSS_PERIOD: usize = 100;
const GNSS_POS_SIGMA: [f64; 3] = [0.3, 0.3, 0.5];
const GNSS_VEL_SIGMA: f64 = 0.05;
/// Barometer and magnetometer at 50 Hz.
const BARO_PERIOD: usize = 20;
const BARO_SIGMA: f64 = 0.1;
const MAG_PERIOD: usize = 20;
const MAG_SIGMA: f64 = 0.005;
/// The Earth field at home, NED [gauss] (declination 0).
const EARTH_FIELD: [f64; 3] = [0.21, 0.0, 0.42];

/// The truth at one instant.
#[derive(Clone, Copy)]
struct Truth {
    pos: Vector3<f64>,
    vel: Vector3<f64>,
    att: UnitQuaternion<f64>,
}

#[derive(Clone, Copy)]
enum Path {
    /// Hover at 10 m, yaw 0.3 rad; from 30 s to 40 s a climb whose speed rises to `climb` m/s and back (5 m for 1 m/s).
    Hover { climb: f64 },
    /// tools/scenarios' figure-eight (half width 2 m, 0.5 rad/s, 2 m up)
    /// scaled to `half_width`, yaw swinging 0.5 rad, after 15 s of hover.
    FigureEight { half_width: f64 },
}

impl Path {
    /// Position, velocity, acceleration (NED) and yaw at `t`.
    fn kinematics(self, t: f64) -> (Vector3<f64>, Vector3<f64>, Vector3<f64>, f64) {
        match self {
            Path::Hover { climb } => {
                // a smooth climb from 30 s to 40 s: z = -10 - climb * s(t), s' a raised cosine
                let (mut z, mut vz, mut az) = (-10.0, 0.0, 0.0);
                if climb != 0.0 && t > 30.0 {
                    let u = (t - 30.0).min(10.0);
                    let w = std::f64::consts::PI / 10.0;
                    z -= climb * (u - (w * u).sin() / w) / 2.0;
                    if t < 40.0 {
                        vz = -climb * (1.0 - (w * u).cos()) / 2.0;
                        az = -climb * w * (w * u).sin() / 2.0;
                    }
                }
                (
                    Vector3::new(0.0, 0.0, z),
                    Vector3::new(0.0, 0.0, vz),
                    Vector3::new(0.0, 0.0, az),
                    0.3,
                )
            }
            Path::FigureEight { half_width: a } => {
                // hover at the centre until 15 s, then the eight faded in over
                // 5 s: p = s(t) f(t) with s the quintic smooth step
                let w = 0.5;
                let (s1, c1) = (w * t).sin_cos();
                let (s2, c2) = (2.0 * w * t).sin_cos();
                let f = Vector3::new(a * s1, 0.5 * a * s2, 0.0);
                let df = Vector3::new(a * w * c1, a * w * c2, 0.0);
                let ddf = Vector3::new(-a * w * w * s1, -2.0 * a * w * w * s2, 0.0);
                let u = ((t - 15.0) / 5.0).clamp(0.0, 1.0);
                let ramp = u > 0.0 && u < 1.0;
                let s0 = u * u * u * (10.0 - 15.0 * u + 6.0 * u * u);
                let s1d = if ramp {
                    30.0 * u * u * (1.0 - u) * (1.0 - u) / 5.0
                } else {
                    0.0
                };
                let s2d = if ramp {
                    60.0 * u * (1.0 - u) * (1.0 - 2.0 * u) / 25.0
                } else {
                    0.0
                };
                let pos = f * s0 + Vector3::new(0.0, 0.0, -2.0);
                let vel = df * s0 + f * s1d;
                let acc = ddf * s0 + df * (2.0 * s1d) + f * s2d;
                (pos, vel, acc, 0.5 * (0.2 * t).sin() * s0)
            }
        }
    }

    /// The attitude a multirotor flies this acceleration with: thrust
    /// (`-z_b`) along `g e3 - a`, the yaw given.
    fn truth(self, t: f64) -> Truth {
        let (pos, vel, acc, yaw) = self.kinematics(t);
        let z_b = (acc - Vector3::new(0.0, 0.0, GRAVITY)).normalize() * -1.0;
        let heading = Vector3::new(yaw.cos(), yaw.sin(), 0.0);
        let y_b = z_b.cross(&heading).normalize();
        let x_b = y_b.cross(&z_b);
        let r = Matrix3::from_columns(&[x_b, y_b, z_b]);
        Truth {
            pos,
            vel,
            att: UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r)),
        }
    }
}

#[derive(Clone, Copy, PartialEq)]
enum Fault {
    None,
    /// From this time the sensor repeats its last value.
    Stuck(f64),
    /// From this time the sensor sends nothing.
    Off(f64),
    /// From this time the sensor's reading is offset by this much (NED for GNSS, up for the barometer).
    Offset(f64, [f64; 3]),
}

#[derive(Clone, Copy)]
struct Faults {
    baro: Fault,
    gnss: Fault,
    mag: Fault,
}

const NO_FAULTS: Faults = Faults {
    baro: Fault::None,
    gnss: Fault::None,
    mag: Fault::None,
};

/// Flies `path` for `duration_s`, feeding the filter, calling `observe`
/// after every IMU step with the time, the filter and the truth.
fn fly(
    cfg: NavConfig,
    path: Path,
    duration_s: f64,
    seed: u64,
    faults: Faults,
    mut observe: impl FnMut(f64, &NavFilter, &Truth),
) -> NavFilter {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let unit = Normal::new(0.0, 1.0).unwrap();
    let n = |rng: &mut ChaCha8Rng| unit.sample(rng);
    let mut filter = NavFilter::new(cfg);
    let gyro_bias = Vector3::from(GYRO_BIAS);
    let accel_bias = Vector3::from(ACCEL_BIAS);
    let earth = Vector3::from(EARTH_FIELD);
    let (mut last_baro, mut last_mag, mut last_gnss) = (None::<BaroHeight>, None::<MagField>, None::<GnssFix>);
    let steps = (duration_s / IMU_DT).round() as usize;
    let mut prev = path.truth(0.0);
    for k in 0..steps {
        let t0 = k as f64 * IMU_DT;
        let t1 = t0 + IMU_DT;
        let now = path.truth(t1);
        let mid = path.truth(t0 + 0.5 * IMU_DT);
        let dang = (prev.att.inverse() * now.att).scaled_axis();
        let dvel = mid.att.inverse() * (now.vel - prev.vel - Vector3::new(0.0, 0.0, GRAVITY * IMU_DT));
        let sd_g = GYRO_NOISE_DENSITY * IMU_DT.sqrt();
        let sd_a = ACCEL_NOISE_DENSITY * IMU_DT.sqrt();
        let imu = ImuDelta {
            dt_s: IMU_DT,
            delta_angle_frd_rad: dang + gyro_bias * IMU_DT + Vector3::from_fn(|_, _| sd_g * n(&mut rng)),
            delta_velocity_frd_m_s: dvel + accel_bias * IMU_DT + Vector3::from_fn(|_, _| sd_a * n(&mut rng)),
        };
        filter.predict(&imu).unwrap();
        let step = k + 1;
        if step % BARO_PERIOD == 0 {
            let fresh = BaroHeight {
                time_s: t1,
                height_m: -now.pos.z + BARO_SIGMA * n(&mut rng),
            };
            let sample = match faults.baro {
                Fault::Stuck(t) if t1 >= t => last_baro,
                Fault::Off(t) if t1 >= t => None,
                Fault::Offset(t, d) if t1 >= t => Some(BaroHeight {
                    height_m: fresh.height_m + d[2],
                    ..fresh
                }),
                _ => Some(fresh),
            };
            if let Some(b) = sample {
                filter.fuse_baro(&b).unwrap();
                last_baro = Some(b);
            }
        }
        if step % MAG_PERIOD == 0 {
            let field = now.att.inverse() * earth + Vector3::from_fn(|_, _| MAG_SIGMA * n(&mut rng));
            let fresh = MagField {
                time_s: t1,
                field_frd_gauss: field,
            };
            let sample = match faults.mag {
                Fault::Stuck(t) if t1 >= t => last_mag,
                Fault::Off(t) if t1 >= t => None,
                _ => Some(fresh),
            };
            if let Some(m) = sample {
                filter.fuse_mag(&m).unwrap();
                last_mag = Some(m);
            }
        }
        if step % GNSS_PERIOD == 0 {
            let pos = now.pos + Vector3::from_fn(|i, _| GNSS_POS_SIGMA[i] * n(&mut rng));
            let vel = now.vel + Vector3::from_fn(|_, _| GNSS_VEL_SIGMA * n(&mut rng));
            let fresh = GnssFix {
                time_s: t1,
                position_ned_m: pos,
                velocity_ned_m_s: vel,
                eph_m: 0.9,
                epv_m: 1.3,
                speed_accuracy_m_s: 0.2,
            };
            let sample = match faults.gnss {
                Fault::Stuck(t) if t1 >= t => last_gnss,
                Fault::Off(t) if t1 >= t => None,
                Fault::Offset(t, d) if t1 >= t => Some(GnssFix {
                    position_ned_m: pos + Vector3::from(d),
                    ..fresh
                }),
                _ => Some(fresh),
            };
            if let Some(g) = sample {
                filter.fuse_gnss(&g).unwrap();
                last_gnss = Some(g);
            }
        }
        observe(t1, &filter, &now);
        prev = now;
    }
    filter
}

/// Largest errors of the estimate after `settle_s`.
#[derive(Debug, Default)]
struct Errors {
    pos_h: f64,
    pos_v: f64,
    vel: f64,
    att_deg: f64,
}

fn errors(path: Path, duration_s: f64, settle_s: f64, faults: Faults) -> (Errors, NavFilter) {
    let mut e = Errors::default();
    let filter = fly(NavConfig::default(), path, duration_s, 7, faults, |t, f, truth| {
        if t >= settle_s {
            let dp = f.position_ned_m() - truth.pos;
            e.pos_h = e.pos_h.max(dp.xy().norm());
            e.pos_v = e.pos_v.max(dp.z.abs());
            e.vel = e.vel.max((f.velocity_ned_m_s() - truth.vel).norm());
            e.att_deg = e.att_deg.max(f.attitude().angle_to(&truth.att).to_degrees());
        }
    });
    (e, filter)
}

#[test]
fn hovering_the_estimate_holds_the_truth_and_the_biases_converge() {
    let (e, f) = errors(Path::Hover { climb: 0.0 }, 90.0, 20.0, NO_FAULTS);
    eprintln!(
        "hover errors after 20 s: {e:?}; gyro bias {:?}, accel bias {:?}",
        f.gyro_bias_frd_rad_s(),
        f.accel_bias_frd_m_s2()
    );
    assert!(
        e.pos_h < 0.5 && e.pos_v < 1.0 && e.vel < 0.15 && e.att_deg < 1.0,
        "{e:?}"
    );
    let gb = f.gyro_bias_frd_rad_s() - Vector3::from(GYRO_BIAS);
    assert!(gb.norm() < 1e-3, "gyro bias error {gb:?}");
    let ab_z = f.accel_bias_frd_m_s2().z - ACCEL_BIAS[2];
    assert!(ab_z.abs() < 0.03, "vertical accel bias error {ab_z}");
    let s = f.status();
    assert!(
        s.gnss_pos && s.gnss_vel && s.gnss_hgt && s.baro_hgt && s.mag_hdg,
        "{s:?}"
    );
    assert_eq!(s.height_ref, Some(HeightSource::Gnss));
    assert!(s.horizontal_position_valid && s.vertical_position_valid && !s.dead_reckoning);
    assert!(
        f.eph_m() < 0.5 && f.epv_m() < 0.6,
        "eph {} epv {}",
        f.eph_m(),
        f.epv_m()
    );
    let r = f.test_ratios();
    for ratio in [r.vel, r.pos_horiz, r.pos_vert, r.mag] {
        assert!(ratio.is_some_and(|x| x < 1.0), "{r:?}");
    }
}

#[test]
fn along_the_figure_eight_the_estimate_holds_the_truth() {
    let (e, f) = errors(Path::FigureEight { half_width: 2.0 }, 90.0, 25.0, NO_FAULTS);
    eprintln!(
        "figure-eight errors after 25 s: {e:?}; gyro bias {:?}, accel bias {:?}",
        f.gyro_bias_frd_rad_s(),
        f.accel_bias_frd_m_s2()
    );
    assert!(
        e.pos_h < 0.5 && e.pos_v < 1.0 && e.vel < 0.15 && e.att_deg < 1.0,
        "{e:?}"
    );
    let ab = f.accel_bias_frd_m_s2() - Vector3::from(ACCEL_BIAS);
    assert!(ab.norm() < 0.05, "accel bias error {ab:?}");
}

#[test]
fn the_same_seed_gives_the_same_bits() {
    let run = || {
        let f = fly(
            NavConfig::default(),
            Path::FigureEight { half_width: 2.0 },
            15.0,
            3,
            NO_FAULTS,
            |_, _, _| {},
        );
        let mut bits: Vec<u64> = f
            .position_ned_m()
            .iter()
            .chain(f.velocity_ned_m_s().iter())
            .map(|v| v.to_bits())
            .collect();
        bits.extend(f.attitude().coords.iter().map(|v| v.to_bits()));
        bits.push(f.eph_m().to_bits());
        bits
    };
    assert_eq!(run(), run());
}

/// Time from `start` to the first instant `pred` holds.
fn first_time(start: f64, times: &[(f64, bool)]) -> Option<f64> {
    times.iter().find(|(t, b)| *t >= start && *b).map(|(t, _)| t - start)
}

#[test]
fn a_stuck_barometer_is_dropped_and_the_height_falls_back_to_gnss() {
    // barometric height reference, stuck at 30 s as the vehicle starts a 10 m climb
    let cfg = NavConfig {
        hgt_ref: HeightRef::Baro,
        ..NavConfig::default()
    };
    let mut dropped = Vec::new();
    let mut worst_height = 0.0_f64;
    let faults = Faults {
        baro: Fault::Stuck(30.0),
        ..NO_FAULTS
    };
    let f = fly(cfg, Path::Hover { climb: 1.0 }, 50.0, 11, faults, |t, f, truth| {
        let s = f.status();
        if t > 20.0 && t < 30.0 {
            assert_eq!(
                s.height_ref,
                Some(HeightSource::Baro),
                "before the fault the barometer is the reference"
            );
        }
        dropped.push((t, !s.baro_hgt && s.height_ref == Some(HeightSource::Gnss)));
        if t > 20.0 {
            worst_height = worst_height.max((f.position_ned_m().z - truth.pos.z).abs());
        }
    });
    let reject = first_time(30.0, &dropped).expect("the stuck barometer was never dropped");
    eprintln!("stuck barometer dropped after {reject:.3} s; worst height error {worst_height:.3} m");
    // the 29.98 s sample repeated 100 times at 50 Hz (PX4's sensor voter): 31.98 s
    assert!((reject - 1.98).abs() < 0.015, "{reject}");
    assert!(worst_height < 1.0, "{worst_height}");
    assert!(f.status().baro_stale);
}

#[test]
fn a_jumping_barometer_fails_its_gate_and_is_declared_faulty() {
    // barometric height reference; the barometer jumps 30 m up at 30 s: its
    // innovations leave the gate, and 5 s of failing fusion while GNSS
    // height works stop it as faulty and GNSS becomes the reference
    let faults = Faults {
        baro: Fault::Offset(30.0, [0.0, 0.0, 30.0]),
        ..NO_FAULTS
    };
    let mut stopped = Vec::new();
    let mut worst_height = 0.0_f64;
    let cfg = NavConfig {
        hgt_ref: HeightRef::Baro,
        ..NavConfig::default()
    };
    let f = fly(cfg, Path::Hover { climb: 0.0 }, 50.0, 5, faults, |t, f, truth| {
        stopped.push((t, f.status().baro_fault));
        if t > 20.0 {
            worst_height = worst_height.max((f.position_ned_m().z - truth.pos.z).abs());
        }
    });
    let reject = first_time(30.0, &stopped).expect("the jumping barometer was never declared faulty");
    eprintln!("jumping barometer faulty after {reject:.2} s; worst height error {worst_height:.3} m");
    // the last fused sample came at 29.98 s; 5 s (hgt_fusion_timeout_max) later it is stopped
    assert!((reject - 5.0).abs() < 0.05, "{reject}");
    assert!(worst_height < 1.0, "{worst_height}");
    let s = f.status();
    assert!(!s.baro_hgt && s.height_ref == Some(HeightSource::Gnss), "{s:?}");
}

#[test]
fn a_lost_barometer_keeps_gnss_height_or_falls_back_to_it() {
    for hgt_ref in [HeightRef::Gnss, HeightRef::Baro] {
        let cfg = NavConfig {
            hgt_ref,
            ..NavConfig::default()
        };
        let faults = Faults {
            baro: Fault::Off(30.0),
            ..NO_FAULTS
        };
        let mut stop = Vec::new();
        let mut worst_height = 0.0_f64;
        let f = fly(cfg, Path::Hover { climb: 1.0 }, 50.0, 13, faults, |t, f, truth| {
            stop.push((t, !f.status().baro_hgt));
            if t > 20.0 {
                worst_height = worst_height.max((f.position_ned_m().z - truth.pos.z).abs());
            }
        });
        let after = first_time(30.0, &stop).unwrap();
        eprintln!(
            "{hgt_ref:?} reference: barometer lost, stopped after {after:.3} s, worst height error {worst_height:.3} m"
        );
        // the last sample came at 29.98 s: stopped 2 x BARO_MAX_INTERVAL later
        assert!((after - 0.38).abs() < 0.015, "{after}");
        assert_eq!(f.status().height_ref, Some(HeightSource::Gnss));
        assert!(f.status().vertical_position_valid && worst_height < 1.0);
    }
}

#[test]
fn without_gnss_the_filter_dead_reckons_then_declares_the_position_invalid() {
    let faults = Faults {
        gnss: Fault::Off(30.0),
        ..NO_FAULTS
    };
    let mut eph = Vec::new();
    let mut invalid = Vec::new();
    let mut dead = Vec::new();
    fly(
        NavConfig::default(),
        Path::FigureEight { half_width: 2.0 },
        40.0,
        17,
        faults,
        |t, f, _| {
            eph.push((t, f.eph_m()));
            invalid.push((t, !f.status().horizontal_position_valid));
            dead.push((t, f.status().dead_reckoning));
        },
    );
    let at = |t: f64| eph.iter().find(|(s, _)| *s >= t).unwrap().1;
    let dr = first_time(29.9, &dead).unwrap();
    let inv = first_time(29.9, &invalid).unwrap();
    eprintln!(
        "GNSS lost at 30 s (last fix 29.9 s): dead reckoning after {dr:.2} s, invalid after {inv:.2} s; eph {:.2} -> {:.2} -> {:.2} m",
        at(29.9),
        at(32.0),
        at(35.0)
    );
    // PX4: no_aid_timeout_max 1 s, EKF2_NOAID_TOUT 5 s after the last fused fix
    assert!((dr - 1.0).abs() < 0.02 && (inv - 5.0).abs() < 0.02, "{dr} {inv}");
    assert!(
        at(32.0) > 1.5 * at(29.9) && at(35.0) > 2.0 * at(32.0),
        "eph must grow while dead reckoning"
    );
}

#[test]
fn a_gnss_jump_is_rejected_by_the_gate_then_the_position_is_reset_to_it() {
    let jump = [20.0, 0.0, 0.0];
    let faults = Faults {
        gnss: Fault::Offset(30.0, jump),
        ..NO_FAULTS
    };
    let mut worst_before_reset = 0.0_f64;
    let mut reset_at = None;
    let mut resets_before = 0;
    let f = fly(
        NavConfig::default(),
        Path::Hover { climb: 0.0 },
        45.0,
        19,
        faults,
        |t, f, truth| {
            let s = f.status();
            if t < 30.0 {
                resets_before = s.gnss_position_resets;
            } else if s.gnss_position_resets == resets_before {
                worst_before_reset = worst_before_reset.max((f.position_ned_m() - truth.pos).xy().norm());
                if t > 30.5 {
                    assert!(f.test_ratios().pos_horiz.unwrap() > 1.0, "the jump is outside the gate");
                    assert!(s.horizontal_position_valid, "GNSS velocity still aids");
                }
            } else if reset_at.is_none() {
                reset_at = Some(t - 30.0);
            }
        },
    );
    let reset_at = reset_at.expect("never reset to the jumped GNSS");
    let offset = (f.position_ned_m() - Path::Hover { climb: 0.0 }.truth(45.0).pos).x;
    eprintln!(
        "GNSS jump of 20 m: held within {worst_before_reset:.2} m of the truth, reset after {reset_at:.2} s; then {offset:.2} m north of the truth"
    );
    // PX4's reset_timeout_max: 7 s after the last fused fix (29.9 s)
    assert!(
        worst_before_reset < 0.5 && (reset_at - 7.0).abs() < 0.2,
        "{worst_before_reset} {reset_at}"
    );
    assert!(
        (offset - 20.0).abs() < 1.0,
        "after the reset the estimate follows the GNSS: {offset}"
    );
}

#[test]
fn a_stuck_magnetometer_is_dropped_and_the_heading_holds() {
    let faults = Faults {
        mag: Fault::Stuck(30.0),
        ..NO_FAULTS
    };
    let mut dropped = Vec::new();
    let mut worst_att = 0.0_f64;
    let f = fly(
        NavConfig::default(),
        Path::FigureEight { half_width: 2.0 },
        60.0,
        23,
        faults,
        |t, f, truth| {
            dropped.push((t, !f.status().mag_hdg));
            if t > 30.0 {
                worst_att = worst_att.max(f.attitude().angle_to(&truth.att).to_degrees());
            }
        },
    );
    let after = first_time(30.0, &dropped).expect("the stuck magnetometer was never dropped");
    eprintln!("stuck magnetometer dropped after {after:.3} s; worst attitude error over 30 s {worst_att:.2} deg");
    assert!((after - 1.98).abs() < 0.015, "{after}");
    assert!(worst_att < 6.0, "{worst_att}");
    assert!(f.status().mag_stale && f.status().horizontal_position_valid);
}

#[test]
fn a_lost_magnetometer_stops_heading_fusion_and_the_flight_goes_on() {
    let faults = Faults {
        mag: Fault::Off(30.0),
        ..NO_FAULTS
    };
    let mut stop = Vec::new();
    let mut worst_att = 0.0_f64;
    let f = fly(
        NavConfig::default(),
        Path::FigureEight { half_width: 2.0 },
        60.0,
        29,
        faults,
        |t, f, truth| {
            stop.push((t, !f.status().mag_hdg));
            if t > 30.0 {
                worst_att = worst_att.max(f.attitude().angle_to(&truth.att).to_degrees());
            }
        },
    );
    let after = first_time(30.0, &stop).unwrap();
    eprintln!("magnetometer lost: heading fusion stopped after {after:.3} s; worst attitude error {worst_att:.2} deg");
    // the last sample came at 29.98 s: stopped 2 x MAG_MAX_INTERVAL later
    assert!((after - 0.98).abs() < 0.015, "{after}");
    assert!(worst_att < 2.0 && f.status().horizontal_position_valid);
}

#[test]
fn bad_samples_are_refused_with_a_reason() {
    let mut f = NavFilter::new(NavConfig::default());
    let zero = Vector3::zeros();
    assert_eq!(
        f.predict(&ImuDelta {
            dt_s: 0.0,
            delta_angle_frd_rad: zero,
            delta_velocity_frd_m_s: zero
        }),
        Err(NavInputError::ImuInterval(0.0))
    );
    let nan = Vector3::new(f64::NAN, 0.0, 0.0);
    assert_eq!(
        f.predict(&ImuDelta {
            dt_s: 1e-3,
            delta_angle_frd_rad: nan,
            delta_velocity_frd_m_s: zero
        }),
        Err(NavInputError::NotFinite("IMU"))
    );
    assert_eq!(
        f.fuse_baro(&BaroHeight {
            time_s: 0.0,
            height_m: f64::INFINITY
        }),
        Err(NavInputError::NotFinite("barometer"))
    );
    assert_eq!(f.time_s(), 0.0, "a refused sample changes nothing");
}
