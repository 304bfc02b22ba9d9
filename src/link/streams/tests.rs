//! Unit tests of `link/streams.rs`: the telemetry streams: which messages, at
//! what rates.

use super::*;
use crate::link::testing::snapshot;
use mavlink::dialects::common::MavStandardMode;
use nalgebra::{UnitQuaternion, Vector3};

#[test]
fn heartbeat_type_follows_the_airframe() {
    let mut s = snapshot();
    for (rotors, mav_type) in [(4, 2), (6, 13), (8, 14), (3, 15), (12, 29), (5, 2)] {
        s.telemetry.vehicle_type = VehicleType::from_rotor_count(rotors);
        assert_eq!(heartbeat(&s.telemetry).mavtype as u8, mav_type, "{rotors} rotors");
    }
}

#[test]
fn gps_fix_and_health_follow_the_receiver() {
    let mut s = snapshot();
    let gps_raw = |s: &Snapshot| match build(Stream::GpsRawInt, s, 0).pop() {
        Some(MavMessage::GPS_RAW_INT(g)) => (g.fix_type as u8, g.satellites_visible),
        _ => panic!(),
    };
    let gps_healthy = |s: &Snapshot| match build(Stream::SysStatus, s, 0).pop() {
        Some(MavMessage::SYS_STATUS(m)) => m.onboard_control_sensors_health.bits() & GPS != 0,
        _ => panic!(),
    };
    assert_eq!(gps_raw(&s), (3, 12));
    assert!(gps_healthy(&s));
    // the receiver's own accuracies (PX4 `sensor_gps_sim`): HDOP/VDOP x 100, mm
    match build(Stream::GpsRawInt, &s, 0).pop() {
        Some(MavMessage::GPS_RAW_INT(g)) => {
            assert_eq!((g.eph, g.epv, g.h_acc, g.v_acc, g.vel_acc), (70, 110, 900, 1780, 400));
            assert_eq!(g.time_usec, 12_375_000, "the fix's own time, one epoch before delivery");
        }
        _ => panic!(),
    }
    // a receiver with a fix whose first solution is not out yet: nothing (PX4)
    s.raw.gnss = None;
    assert!(build(Stream::GpsRawInt, &s, 0).is_empty());
    // the GPS off: no solution from the receiver; PX4's silent-receiver
    // message (GPS_RAW_INT.hpp), never the navigation solution's position
    s.telemetry.gps_fix = GpsFix::None;
    s.telemetry.gps_satellites = 0;
    assert_eq!(gps_raw(&s), (0, 255), "GPS_FIX_TYPE_NO_GPS, satellites unknown");
    match build(Stream::GpsRawInt, &s, 0).pop() {
        Some(MavMessage::GPS_RAW_INT(g)) => {
            assert_eq!((g.lat, g.lon, g.alt, g.time_usec), (0, 0, 0, 0));
            assert_eq!((g.eph, g.epv, g.vel, g.cog), (u16::MAX, u16::MAX, u16::MAX, u16::MAX));
            assert_eq!((g.h_acc, g.v_acc, g.vel_acc), (0, 0, 0));
        }
        _ => panic!(),
    }
    assert!(!gps_healthy(&s));
}

#[test]
fn mission_current_as_px4_fills_it() {
    let mut s = snapshot();
    let m = mission_current(&s.telemetry);
    assert_eq!((m.seq, m.total, m.mission_mode), (0, u16::MAX, 2));
    assert_eq!(m.mission_state, MavMissionState::MISSION_STATE_NO_MISSION);
    s.telemetry.mission.total = 4;
    s.telemetry.mission.seq = 2;
    s.telemetry.mission.state = MissionState::Paused;
    s.telemetry.mission.mission_id = 0xDEAD_BEEF;
    for (mode, active) in [(FlightMode::Mission, 1), (FlightMode::Land, 1), (FlightMode::Hold, 2)] {
        s.telemetry.mode = mode;
        let m = mission_current(&s.telemetry);
        assert_eq!(
            (m.seq, m.total, m.mission_mode, m.mission_id),
            (2, 4, active, 0xDEAD_BEEF)
        );
        assert_eq!(m.mission_state, MavMissionState::MISSION_STATE_PAUSED);
    }
    assert_eq!(Stream::from_message_id(42), Some(Stream::MissionCurrent));
}

#[test]
fn current_mode_as_px4_fills_it() {
    let mut s = snapshot();
    for (mode, standard) in [
        (FlightMode::Mission, MavStandardMode::MAV_STANDARD_MODE_MISSION),
        (
            FlightMode::ReturnToLaunch,
            MavStandardMode::MAV_STANDARD_MODE_SAFE_RECOVERY,
        ),
        (FlightMode::Hold, MavStandardMode::MAV_STANDARD_MODE_NON_STANDARD),
        (FlightMode::Descend, MavStandardMode::MAV_STANDARD_MODE_NON_STANDARD),
    ] {
        s.telemetry.mode = mode;
        s.telemetry.failsafe = false;
        let c = current_mode(&s.telemetry);
        assert_eq!(c.custom_mode, heartbeat(&s.telemetry).custom_mode);
        assert_eq!((c.intended_custom_mode, c.standard_mode), (c.custom_mode, standard));
        // a failsafe replaced what the user meant: unknown here
        s.telemetry.failsafe = true;
        assert_eq!(current_mode(&s.telemetry).intended_custom_mode, 0);
    }
    assert_eq!(Stream::from_message_id(436), Some(Stream::CurrentMode));
    for rates in [gcs_rates(), api_rates()] {
        assert!(rates.contains(&(Stream::CurrentMode, 0.5)), "PX4's 0.5 Hz");
    }
}

#[test]
fn default_rates_and_deadlines() {
    let t0 = Instant::now();
    let mut s = Scheduler::new(t0, &gcs_rates());
    let mut due = Vec::new();
    s.due(t0, &mut due);
    // every stream but the ground truth, which waits to be asked for (as in
    // PX4 SITL), the motor outputs, and the raw sensor streams and ODOMETRY
    // PX4's normal mode does not send
    assert_eq!(due.len(), Stream::ALL.len() - 6);
    for off in [
        Stream::HilStateQuaternion,
        Stream::ActuatorOutputStatus,
        Stream::HighresImu,
        Stream::ScaledImu,
        Stream::ScaledPressure,
        Stream::Odometry,
    ] {
        assert!(!due.contains(&off), "{off:?}");
    }
    assert!(api_rates().contains(&(Stream::HighresImu, 50.0)), "PX4's onboard mode");
    // PX4's `configure_streams_to_default`: normal and onboard mode
    for (stream, gcs, api) in [
        (Stream::EstimatorStatus, Some(0.5), Some(1.0)),
        (Stream::Vibration, Some(0.1), Some(0.5)),
        (Stream::Odometry, None, Some(30.0)),
    ] {
        let rate = |rates: Rates| rates.iter().find(|(s, _)| *s == stream).map(|(_, hz)| *hz);
        assert_eq!(rate(gcs_rates()), gcs, "{stream:?}");
        assert_eq!(rate(api_rates()), api, "{stream:?}");
    }
    assert_eq!(due.len(), gcs_rates().len());
    due.clear();
    // 20 ms later only the 50 Hz streams are due
    s.due(t0 + Duration::from_millis(20), &mut due);
    assert_eq!(
        due,
        vec![
            Stream::Attitude,
            Stream::AttitudeQuaternion,
            Stream::LocalPositionNed,
            Stream::GlobalPositionInt
        ]
    );
    assert_eq!(s.next_deadline(), Some(t0 + Duration::from_millis(40)));
}

#[test]
fn intervals_from_set_message_interval() {
    let t0 = Instant::now();
    let mut s = Scheduler::new(t0, &api_rates());
    s.set(t0, Stream::DebugVect, Interval::from_param_us(20_000.0));
    assert_eq!(s.interval(Stream::DebugVect), Some(Duration::from_millis(20)));
    s.set(t0, Stream::DebugVect, Interval::from_param_us(-1.0));
    assert_eq!(s.interval(Stream::DebugVect), None);
    s.set(t0, Stream::DebugVect, Interval::from_param_us(0.0));
    assert_eq!(s.interval(Stream::DebugVect), Some(Duration::from_millis(100)));
    // any positive f32 is taken, capped at what MESSAGE_INTERVAL can report
    s.set(t0, Stream::DebugVect, Interval::from_param_us(f32::MAX));
    assert_eq!(s.interval(Stream::DebugVect), Some(MAX_INTERVAL));
    let mut due = Vec::new();
    s.due(t0, &mut due);
    s.due(t0 + Duration::from_secs(2000), &mut due);
    assert_eq!(due.iter().filter(|d| **d == Stream::DebugVect).count(), 1);
    s.set(t0, Stream::DebugVect, Interval::from_param_us(1.0));
    assert_eq!(s.interval(Stream::DebugVect), Some(MIN_INTERVAL));
    assert_eq!(period(1e-300), Some(MAX_INTERVAL));
    assert_eq!(Stream::from_message_id(251), Some(Stream::NamedValueFloat));
    assert_eq!(Stream::from_message_id(9999), None);
}

#[test]
fn repeated_requests_cannot_send_a_stream_faster_than_the_floor() {
    let t0 = Instant::now();
    let mut s = Scheduler::new(t0, &vec![(Stream::Attitude, 50.0)]);
    let mut due = Vec::new();
    // 10,000 requests for 1 us over 1 s, each followed by a poll
    for k in 0..10_000u64 {
        let now = t0 + Duration::from_micros(100 * k);
        s.set(now, Stream::Attitude, Interval::from_param_us(1.0));
        s.due(now, &mut due);
    }
    let n = due.len() as u64;
    let most = 1_000_000 / MIN_INTERVAL.as_micros() as u64 + 1;
    assert!(n <= most && n >= most - 2, "{n} sends in 1 s, floor allows {most}");
}

#[test]
fn a_late_poll_does_not_burst() {
    let t0 = Instant::now();
    let mut s = Scheduler::new(t0, &vec![(Stream::Heartbeat, 1.0)]);
    let mut due = Vec::new();
    s.due(t0, &mut due);
    s.due(t0 + Duration::from_secs(5), &mut due);
    s.due(t0 + Duration::from_millis(5100), &mut due);
    assert_eq!(due.len(), 2);
}

#[test]
fn ground_truth_is_the_worlds_state_around_the_origin() {
    let mut snap = snapshot();
    let origin = snap.telemetry.origin;
    // the estimate says one thing, the world another: the message carries the world's
    snap.telemetry.position_ned = Vector3::new(0.0, 0.0, 0.0);
    snap.ground_truth.state.time_s = 12.5;
    snap.ground_truth.state.position_ned = Vector3::new(100.0, -50.0, -20.0);
    snap.ground_truth.state.velocity_ned = Vector3::new(1.5, -0.25, -3.0);
    snap.ground_truth.state.attitude = UnitQuaternion::from_euler_angles(0.1, -0.2, 1.0);
    snap.ground_truth.state.rate_frd = Vector3::new(0.01, 0.02, -0.3);
    snap.ground_truth.acceleration_ned = Vector3::new(0.4, -2.7, 9.9);
    let [m] = build(Stream::HilStateQuaternion, &snap, 0).try_into().unwrap();
    let MavMessage::HIL_STATE_QUATERNION(h) = m else {
        panic!("{m:?}")
    };
    let at = origin.offset(&Vector3::new(100.0, -50.0, -20.0));
    assert_eq!(h.time_usec, 12_500_000);
    assert_eq!(h.lat, convert::deg_e7(at.lat_deg));
    assert_eq!(h.lon, convert::deg_e7(at.lon_deg));
    assert_eq!(h.alt, ((origin.alt_amsl_m + 20.0) * 1e3) as i32);
    assert_eq!((h.vx, h.vy, h.vz), (150, -25, -300));
    let q = snap.ground_truth.state.attitude.quaternion();
    assert_eq!(h.attitude_quaternion, [q.w as f32, q.i as f32, q.j as f32, q.k as f32]);
    assert_eq!((h.rollspeed, h.pitchspeed, h.yawspeed), (0.01, 0.02, -0.3));
    // PX4 writes the acceleration in m/s^2, cut to an integer
    assert_eq!((h.xacc, h.yacc, h.zacc), (0, -2, 9));
    assert_eq!((h.ind_airspeed, h.true_airspeed), (0, 0));
}

#[test]
fn orbit_status_only_while_orbiting() {
    let mut snap = snapshot();
    assert!(build(Stream::OrbitExecutionStatus, &snap, 0).is_empty());
    let centre = snap.telemetry.origin.offset(&Vector3::new(20.0, 10.0, -8.0));
    snap.telemetry.orbit = Some(crate::autopilot::OrbitStatus {
        radius_m: -10.0,
        centre,
        yaw: crate::autopilot::OrbitYaw::FrontToCentre,
    });
    let [m] = build(Stream::OrbitExecutionStatus, &snap, 0).try_into().unwrap();
    let MavMessage::ORBIT_EXECUTION_STATUS(o) = m else {
        panic!("{m:?}")
    };
    assert_eq!(o.radius, -10.0);
    assert_eq!(o.frame, MavFrame::MAV_FRAME_GLOBAL);
    assert_eq!(
        (o.x, o.y),
        (convert::deg_e7(centre.lat_deg), convert::deg_e7(centre.lon_deg))
    );
    assert_eq!(o.z, centre.alt_amsl_m as f32);
}

#[test]
fn wind_cov_as_px4_fills_it_and_only_once_estimated() {
    let mut s = snapshot();
    assert!(build(Stream::WindCov, &s, 0).is_empty(), "no estimate: nothing sent");
    s.telemetry.wind = Some(crate::signals::WindEstimate {
        time_s: 12.25,
        wind_ned: nalgebra::Vector3::new(0.25, 5.0, 0.0),
        variance_ne: nalgebra::Vector2::new(0.01, 0.02),
    });
    let Some(MavMessage::WIND_COV(w)) = build(Stream::WindCov, &s, 0).pop() else {
        panic!("WIND_COV expected")
    };
    assert_eq!(
        (w.time_usec, w.wind_x, w.wind_y, w.wind_z),
        (12_250_000, 0.25, 5.0, 0.0)
    );
    assert_eq!((w.var_horiz, w.var_vert), (0.03, 0.0));
    assert_eq!(w.wind_alt, s.telemetry.global.alt_amsl_m as f32);
    assert_eq!((w.horiz_accuracy, w.vert_accuracy), (0.0, 0.0));
    assert_eq!(Stream::from_message_id(231), Some(Stream::WindCov));
    // PX4's rates: 0.5 Hz in normal mode (GCS), 10 Hz onboard (API)
    let t0 = Instant::now();
    let gcs = Scheduler::new(t0, &gcs_rates());
    let api = Scheduler::new(t0, &api_rates());
    assert_eq!(gcs.interval(Stream::WindCov), Some(Duration::from_secs(2)));
    assert_eq!(api.interval(Stream::WindCov), Some(Duration::from_millis(100)));
}

#[test]
fn raw_sensor_messages_in_px4_units_and_an_off_sensor_unflagged() {
    let mut s = snapshot();
    let Some(MavMessage::HIGHRES_IMU(h)) = build(Stream::HighresImu, &s, 0).pop() else {
        panic!()
    };
    assert_eq!((h.xacc, h.yacc, h.zacc), (0.0, 0.0, -9.81));
    assert_eq!(
        h.fields_updated.bits(),
        0x1bff,
        "acc, gyro, mag, pressure, altitude, temperature"
    );
    assert!((h.abs_pressure - 954.6).abs() < 1e-3, "hPa");
    assert!((f64::from(h.pressure_alt) - crate::geo::pressure_altitude_m(95_460.0)).abs() < 1e-3);
    assert_eq!(h.time_usec, 12_500_000);
    let Some(MavMessage::SCALED_IMU(i)) = build(Stream::ScaledImu, &s, 0).pop() else {
        panic!()
    };
    // -9.81 m/s^2 is -1000.3 mG; 0.44 G is 440 mG
    assert_eq!((i.zacc, i.zmag, i.temperature), (-1000, 440, 1170));
    let Some(MavMessage::SCALED_PRESSURE(p)) = build(Stream::ScaledPressure, &s, 0).pop() else {
        panic!()
    };
    assert_eq!((p.press_abs, p.temperature), (954.6, 1170));
    // the barometer and magnetometer off: no SCALED_PRESSURE, their HIGHRES_IMU fields unflagged
    s.raw.baro = None;
    s.raw.mag = None;
    assert!(build(Stream::ScaledPressure, &s, 0).is_empty());
    let Some(MavMessage::HIGHRES_IMU(h)) = build(Stream::HighresImu, &s, 0).pop() else {
        panic!()
    };
    assert_eq!((h.fields_updated.bits(), h.abs_pressure, h.xmag), (0x3f, 0.0, 0.0));
    // no raw sensors simulated: nothing at all
    s.raw = Default::default();
    for stream in [Stream::HighresImu, Stream::ScaledImu, Stream::ScaledPressure] {
        assert!(build(stream, &s, 0).is_empty(), "{stream:?}");
    }
}

#[test]
fn estimator_status_packs_the_solution_flags_ratios_and_accuracies() {
    let s = snapshot();
    let Some(MavMessage::ESTIMATOR_STATUS(e)) = build(Stream::EstimatorStatus, &s, 0).pop() else {
        panic!("ESTIMATOR_STATUS")
    };
    // attitude, velocities, horizontal positions, vertical position, predicted positions
    assert_eq!(
        e.flags.bits(),
        831,
        "a good GNSS-aided solution, as PX4 SITL reports it"
    );
    assert_eq!(e.time_usec, 12_500_000);
    assert_eq!(
        [e.vel_ratio, e.pos_horiz_ratio, e.pos_vert_ratio, e.mag_ratio],
        [0.1, 0.2, 0.3, 0.4]
    );
    assert!(
        e.hagl_ratio.is_nan() && e.tas_ratio.is_nan(),
        "no range finder, no airspeed"
    );
    assert_eq!((e.pos_horiz_accuracy, e.pos_vert_accuracy), (0.5, 0.7));
    // a source not fused reads NaN; without horizontal aiding the position is held
    let mut n = s.telemetry.navigation;
    n.ratios.vel = None;
    n.solution = crate::autopilot::SolutionStatus::good(false);
    let e = estimator_status(0, &n);
    assert!(e.vel_ratio.is_nan());
    assert_eq!(e.flags.bits(), 1 | 4 | 32 | 128);
    // the whole message survives the wire
    let m = MavMessage::ESTIMATOR_STATUS(e);
    let back = roundtrip(&m);
    let MavMessage::ESTIMATOR_STATUS(b) = back else {
        panic!()
    };
    assert_eq!(b.flags.bits(), 165);
}

#[test]
fn vibration_packs_the_imu_metrics_and_waits_for_them() {
    let mut s = snapshot();
    let Some(MavMessage::VIBRATION(v)) = build(Stream::Vibration, &s, 0).pop() else {
        panic!("VIBRATION")
    };
    assert_eq!(
        (v.vibration_x, v.vibration_y, v.vibration_z),
        (1e-6, 0.004, 0.05),
        "x coning, y gyro, z accel, as PX4's VIBRATION.hpp"
    );
    assert_eq!(v.time_usec, 12_496_000);
    assert_eq!((v.clipping_0, v.clipping_1, v.clipping_2), (0, 0, 0));
    assert!(Stream::Vibration.needs_raw_sensors());
    s.telemetry.vibration = None;
    assert!(
        build(Stream::Vibration, &s, 0).is_empty(),
        "nothing before the IMU's samples"
    );
}

#[test]
fn odometry_packs_the_solution_in_ned_with_the_covariance_diagonal() {
    let mut s = snapshot();
    s.telemetry.position_ned = Vector3::new(1.0, -2.0, -5.0);
    s.telemetry.velocity_ned = Vector3::new(0.5, 0.25, -0.125);
    s.telemetry.rate_frd = Vector3::new(0.01, 0.02, 0.03);
    s.telemetry.attitude = UnitQuaternion::from_euler_angles(0.0, 0.0, std::f64::consts::FRAC_PI_2);
    let Some(MavMessage::ODOMETRY(o)) = build(Stream::Odometry, &s, 0).pop() else {
        panic!("ODOMETRY")
    };
    assert_eq!(o.frame_id, MavFrame::MAV_FRAME_LOCAL_NED);
    assert_eq!(
        o.child_frame_id,
        MavFrame::MAV_FRAME_LOCAL_NED,
        "PX4's EKF2 odometry: velocity NED"
    );
    assert_eq!((o.x, o.y, o.z), (1.0, -2.0, -5.0));
    assert_eq!((o.vx, o.vy, o.vz), (0.5, 0.25, -0.125));
    assert_eq!((o.rollspeed, o.pitchspeed, o.yawspeed), (0.01, 0.02, 0.03));
    let h = std::f32::consts::FRAC_1_SQRT_2;
    assert!((o.q[0] - h).abs() < 1e-6 && (o.q[3] - h).abs() < 1e-6 && o.q[1] == 0.0 && o.q[2] == 0.0);
    let diag = [0, 6, 11, 15, 18, 20];
    let pose: Vec<f32> = diag.iter().map(|&i| o.pose_covariance[i]).collect();
    assert_eq!(pose, [0.125, 0.125, 0.49, 1e-4, 1e-4, 4e-4]);
    assert_eq!(
        [
            o.velocity_covariance[0],
            o.velocity_covariance[6],
            o.velocity_covariance[11]
        ],
        [0.01, 0.01, 0.02]
    );
    for (i, c) in o.pose_covariance.iter().enumerate() {
        assert_eq!(c.is_nan(), !diag.contains(&i), "pose covariance {i}");
    }
    assert!(o.velocity_covariance[15].is_nan() && o.velocity_covariance[1].is_nan());
    assert_eq!(o.estimator_type, MavEstimatorType::MAV_ESTIMATOR_TYPE_AUTOPILOT);
    assert_eq!((o.quality, o.reset_counter), (0, 1));
    // the ideal solution has no covariance: "unknown", NaN first
    s.telemetry.navigation.variances = None;
    let Some(MavMessage::ODOMETRY(o)) = build(Stream::Odometry, &s, 0).pop() else {
        panic!("ODOMETRY")
    };
    assert!(o.pose_covariance[0].is_nan() && o.velocity_covariance[0].is_nan());
    let MavMessage::ODOMETRY(b) = roundtrip(&MavMessage::ODOMETRY(o)) else {
        panic!()
    };
    assert_eq!(
        (b.x, b.y, b.z, b.child_frame_id),
        (1.0, -2.0, -5.0, MavFrame::MAV_FRAME_LOCAL_NED)
    );
}

#[test]
fn actuator_output_status_reads_px4_sitl_pwm_and_waits_to_be_asked() {
    use crate::autopilot::RotorOutputs;
    let mut s = snapshot();
    let outputs = |s: &Snapshot| match build(Stream::ActuatorOutputStatus, s, 0).pop() {
        Some(m @ MavMessage::ACTUATOR_OUTPUT_STATUS(_)) => match roundtrip(&m) {
            MavMessage::ACTUATOR_OUTPUT_STATUS(a) => a,
            other => panic!("{other:?}"),
        },
        other => panic!("{other:?}"),
    };
    // disarmed: every channel of PX4 SITL's 16 at the disarmed 900 us, the rest 0
    let a = outputs(&s);
    assert_eq!((a.time_usec, a.active), (12_500_000, 16));
    assert!(a.actuator[..16].iter().all(|v| *v == 900.0), "{:?}", a.actuator);
    assert!(a.actuator[16..].iter().all(|v| *v == 0.0));
    // a hexa in flight, rotor 1 taken out after a failure: 900 for it (at
    // most 901, PX4's test), idle 1000, full 2000, whole microseconds;
    // channels 7 to 16 unused, at their disarmed value
    let mut commands = [None; crate::signals::MAX_ROTORS];
    commands[1..6].copy_from_slice(&[Some(0.0), Some(0.5), Some(1.0), Some(0.2345), Some(1.5)]);
    s.telemetry.rotor_outputs = RotorOutputs { count: 6, commands };
    let a = outputs(&s);
    assert_eq!(a.actuator[..7], [900.0, 1000.0, 1500.0, 2000.0, 1234.0, 2000.0, 900.0]);
    assert!(a.actuator[6..16].iter().all(|v| *v == 900.0));
    // an ideal-actuation airframe has no motor outputs: nothing, and a
    // REQUEST_MESSAGE for it is denied
    s.telemetry.rotor_outputs = RotorOutputs::default();
    assert!(build(Stream::ActuatorOutputStatus, &s, 0).is_empty());
    // id 375; off on both links until SET_MESSAGE_INTERVAL (PX4 streams it
    // only when asked)
    assert_eq!(Stream::from_message_id(375), Some(Stream::ActuatorOutputStatus));
    let t0 = Instant::now();
    for rates in [gcs_rates(), api_rates()] {
        let mut sched = Scheduler::new(t0, &rates);
        assert_eq!(sched.interval(Stream::ActuatorOutputStatus), None);
        sched.set(
            t0,
            Stream::ActuatorOutputStatus,
            Interval::Every(Duration::from_millis(5)),
        );
        let mut due = Vec::new();
        sched.due(t0, &mut due);
        assert!(due.contains(&Stream::ActuatorOutputStatus));
    }
}

/// `m` framed by the link's encoder and read back from the bytes.
fn roundtrip(m: &MavMessage) -> MavMessage {
    use crate::link::wire::{Encoder, Inbound, decode, frames};
    let bytes = Encoder::new(1, 1).message(m);
    let frame = frames(&bytes).next().expect("one frame with a valid CRC");
    match decode(&frame) {
        Some(Inbound::Other(m)) => *m,
        other => panic!("{other:?}"),
    }
}
