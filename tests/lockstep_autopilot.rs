//! Lockstep tests of the autopilot as a MAVLink client sees it: arming,
//! takeoff, landing, auto-disarm, RTL, reposition, offboard (position,
//! velocity, attitude, rates, loss), the injected wrench and its estimate,
//! live parameter changes, refusals, determinism, and the preflight lift
//! check (arming refused when the rotors cannot lift the true mass). One vehicle in the
//! lockstep core (world and flight stack), simulated time only; long flights
//! are quick with `cargo test --release --test lockstep_autopilot`.

mod common;

use common::sitl::{HOME, Sitl, int, real};
use nalgebra::{UnitQuaternion, Vector3};
use rotorpilot::airframe::Airframe;
use rotorpilot::autopilot::{
    AttitudeTarget, AutopilotCommand, CommandOutcome, FlightMode, LandedState, OffboardSetpoint, Severity, StatusText,
    Targets, Telemetry,
};
use rotorpilot::control::ControllerKind;
use rotorpilot::geo::GeoPoint;
use rotorpilot::lockstep::preflight::unliftable;
use rotorpilot::math::euler_zyx;
use rotorpilot::sim::{RotorHealth, SensorConfig, SensorNoise};

fn texts(ap: &mut Sitl) -> Vec<String> {
    ap.texts().into_iter().map(|s: StatusText| s.text).collect()
}

fn has(texts: &[String], part: &str) -> bool {
    texts.iter().any(|t| t.contains(part))
}

/// Height of the centre of mass above home [m].
fn height(t: &Telemetry) -> f64 {
    t.global.alt_amsl_m - t.home.alt_amsl_m
}

/// Arm after one step and take off to MIS_TAKEOFF_ALT; returns once in Hold.
fn take_off(ap: &mut Sitl) {
    ap.step();
    ap.take_off_to(None);
}

/// Take off and let the hover settle.
fn hover(ap: &mut Sitl) -> Vector3<f64> {
    take_off(ap);
    ap.run(5.0);
    ap.telemetry().position_ned
}

fn hover_at(ap: &mut Sitl) -> Vector3<f64> {
    ap.telemetry().position_ned
}

#[test]
fn arm_is_refused_until_the_estimator_runs_then_accepted() {
    let mut ap = Sitl::quad().build();
    let t = ap.telemetry();
    assert!(!t.armed && !t.prearm_ok);
    assert_eq!(t.mode, FlightMode::Hold, "PX4 reports AUTO.LOITER when idle");
    assert_eq!(t.landed, LandedState::OnGround);
    assert_eq!(
        ap.command(AutopilotCommand::Arm { force: false }),
        CommandOutcome::TemporarilyRejected("estimator not initialised")
    );
    let s = ap.texts();
    assert_eq!(s.len(), 1);
    assert_eq!(s[0].severity, Severity::Critical);
    assert!(s[0].text.starts_with("Arming denied"), "{}", s[0].text);
    assert!(!ap.armed());
    ap.step();
    assert!(ap.telemetry().prearm_ok);
    assert_eq!(
        ap.command(AutopilotCommand::Arm { force: false }),
        CommandOutcome::Accepted
    );
    assert!(ap.telemetry().armed);
    assert!(has(&texts(&mut ap), "Armed"));
    // arming again is fine; armed on the ground in Hold the rotors idle and nothing moves
    assert_eq!(
        ap.command(AutopilotCommand::Arm { force: false }),
        CommandOutcome::Accepted
    );
    ap.run(2.0);
    let t = ap.telemetry();
    assert!(t.armed && t.landed == LandedState::OnGround);
    assert_eq!(t.position_ned, Vector3::new(0.0, 0.0, -0.24));
    assert!(t.throttle > 0.0 && t.throttle < 0.05, "idle {}", t.throttle);
    assert!(t.battery_current_a > 0.3);
    // a forced arm skips the checks
    let mut fresh = Sitl::quad().build();
    assert_eq!(
        fresh.command(AutopilotCommand::Arm { force: true }),
        CommandOutcome::Accepted
    );
}

#[test]
fn takeoff_reaches_mis_takeoff_alt_then_holds_in_air() {
    let mut ap = Sitl::quad().build();
    ap.step();
    // disarmed: refused as PX4
    assert_eq!(
        ap.command(AutopilotCommand::Takeoff { altitude_amsl_m: None }),
        CommandOutcome::TemporarilyRejected("vehicle not armed")
    );
    assert_eq!(
        ap.command(AutopilotCommand::SetMode(FlightMode::Takeoff)),
        CommandOutcome::TemporarilyRejected("vehicle not armed")
    );
    ap.set_param("MIS_TAKEOFF_ALT", real(3.0));
    ap.command(AutopilotCommand::Arm { force: false });
    texts(&mut ap);
    // a relative altitude sent as AMSL (pymavlink habit) is raised to the minimum
    assert_eq!(
        ap.command(AutopilotCommand::Takeoff {
            altitude_amsl_m: Some(2.0)
        }),
        CommandOutcome::Accepted
    );
    assert!(has(&texts(&mut ap), "Using minimum takeoff altitude: 3.00 m"));
    assert_eq!(ap.telemetry().landed, LandedState::Takeoff);
    let mut seen_takeoff_state = false;
    let done = ap.run_until(30.0, |t| {
        seen_takeoff_state |= t.landed == LandedState::Takeoff && height(t) > 1.0;
        t.mode == FlightMode::Hold
    });
    assert!(done.is_some() && seen_takeoff_state);
    let t = ap.telemetry();
    assert_eq!(t.landed, LandedState::InAir);
    assert!((height(&t) - 3.0).abs() < 0.25, "{}", height(&t));
    ap.run(3.0);
    let t = ap.telemetry();
    assert!((height(&t) - 3.0).abs() < 0.02, "{}", height(&t));
    assert!(t.position_ned.xy().norm() < 0.01);
    assert_eq!((t.mode, t.landed), (FlightMode::Hold, LandedState::InAir));
    let s = texts(&mut ap);
    assert!(has(&s, "Takeoff detected") && has(&s, "Takeoff complete"), "{s:?}");
    // a higher AMSL target is used as given (home: where the vehicle rested)
    let home_alt_amsl_m = ap.telemetry().home.alt_amsl_m;
    assert_eq!(
        ap.command(AutopilotCommand::Takeoff {
            altitude_amsl_m: Some(home_alt_amsl_m + 6.0)
        }),
        CommandOutcome::Accepted
    );
    ap.run_until(30.0, |t| t.mode == FlightMode::Hold).unwrap();
    ap.run(2.0);
    assert!((height(&ap.telemetry()) - 6.0).abs() < 0.05);
}

#[test]
fn land_touches_down_reports_on_ground_and_disarms_after_com_disarm_land() {
    let mut ap = Sitl::quad().build();
    take_off(&mut ap);
    // disarming in the air is refused unless forced
    assert_eq!(
        ap.command(AutopilotCommand::Disarm { force: false }),
        CommandOutcome::TemporarilyRejected("vehicle in the air")
    );
    assert_eq!(ap.command(AutopilotCommand::Land), CommandOutcome::Accepted);
    let mut landing_seen = false;
    let mut max_descent: f64 = 0.0;
    let touchdown = ap
        .run_until(30.0, |t| {
            landing_seen |= t.landed == LandedState::Landing;
            max_descent = max_descent.max(t.velocity_ned.z);
            t.landed == LandedState::OnGround
        })
        .expect("lands");
    assert!(landing_seen);
    assert!((max_descent - 0.7).abs() < 0.1, "MPC_LAND_SPEED, got {max_descent}");
    let t = ap.telemetry();
    assert!(t.armed && t.mode == FlightMode::Land);
    assert!(t.position_ned.xy().norm() < 0.05);
    let disarmed = ap.run_until(10.0, |t| !t.armed).expect("auto-disarm");
    assert!(
        (disarmed - touchdown - 2.0).abs() < 0.01,
        "COM_DISARM_LAND after the landing detection: {}",
        disarmed - touchdown
    );
    let s = texts(&mut ap);
    assert!(has(&s, "Landing detected") && has(&s, "Disarmed by landing"), "{s:?}");
    let t = ap.telemetry();
    assert_eq!((t.mode, t.landed), (FlightMode::Hold, LandedState::OnGround));
}

#[test]
fn arming_without_takeoff_disarms_after_com_disarm_prflt() {
    let mut ap = Sitl::quad().build();
    ap.set_param("COM_DISARM_PRFLT", real(3.0));
    ap.step();
    ap.command(AutopilotCommand::Arm { force: false });
    let armed_at = ap.time_s();
    let off = ap.run_until(10.0, |t| !t.armed).expect("preflight disarm");
    assert!((off - armed_at - 3.0).abs() < 0.01, "{}", off - armed_at);
    assert!(has(&texts(&mut ap), "preflight"));
    // <= 0 disables it
    ap.set_param("COM_DISARM_PRFLT", real(-1.0));
    ap.command(AutopilotCommand::Arm { force: false });
    ap.run(12.0);
    assert!(ap.armed());
}

#[test]
fn rtl_from_20_m_away_returns_lands_near_home_and_disarms() {
    let mut ap = Sitl::quad()
        .params(&[("RTL_RETURN_ALT", real(12.0)), ("RTL_DESCEND_ALT", real(6.0))])
        .build();
    take_off(&mut ap);
    let away = HOME.offset(&Vector3::new(16.0, 12.0, -5.0));
    ap.command(AutopilotCommand::Reposition {
        lat_deg: Some(away.lat_deg),
        lon_deg: Some(away.lon_deg),
        alt_amsl_m: Some(away.alt_amsl_m),
        yaw_rad: None,
        speed_m_s: None,
    });
    ap.run_until(30.0, |t| {
        (t.position_ned - Vector3::new(16.0, 12.0, -5.0)).norm() < 0.05
    })
    .unwrap();
    ap.set_param("MPC_XY_CRUISE", real(4.0));
    assert_eq!(
        ap.command(AutopilotCommand::SetMode(FlightMode::ReturnToLaunch)),
        CommandOutcome::Accepted
    );
    let mut max_height: f64 = 0.0;
    let mut max_speed: f64 = 0.0;
    let landed = ap
        .run_until(120.0, |t| {
            max_height = max_height.max(height(t));
            max_speed = max_speed.max(t.velocity_ned.xy().norm());
            !t.armed
        })
        .expect("returns, lands and disarms");
    assert!(
        (max_height - 12.0).abs() < 0.2,
        "climbed to RTL_RETURN_ALT: {max_height}"
    );
    assert!(max_speed < 4.1 && max_speed > 3.8, "cruise: {max_speed}");
    assert!(landed < 120.0);
    let t = ap.telemetry();
    assert!(t.position_ned.xy().norm() < 0.3, "near home: {}", t.position_ned);
    assert_eq!(t.landed, LandedState::OnGround);
    let s = texts(&mut ap);
    assert!(
        has(&s, "Return to launch at 12.0 m") && has(&s, "RTL: landing"),
        "{s:?}"
    );
}

/// RTL_DESCEND_ALT 0, the least PX4 declares: the return descends over home
/// all the way, touches down gently and disarms.
#[test]
fn rtl_with_descend_alt_0_descends_over_home_lands_and_disarms() {
    let mut ap = Sitl::quad()
        .params(&[("RTL_RETURN_ALT", real(12.0)), ("RTL_DESCEND_ALT", real(0.0))])
        .build();
    take_off(&mut ap);
    assert_eq!(
        ap.command(AutopilotCommand::SetMode(FlightMode::ReturnToLaunch)),
        CommandOutcome::Accepted
    );
    let mut touchdown_speed: f64 = 0.0;
    ap.run_until(120.0, |t| {
        if height(t) < 0.5 {
            touchdown_speed = touchdown_speed.max(t.velocity_ned.z);
        }
        !t.armed
    })
    .expect("returns, lands and disarms");
    let t = ap.telemetry();
    assert!(t.position_ned.xy().norm() < 0.3, "near home: {}", t.position_ned);
    assert_eq!(t.landed, LandedState::OnGround);
    assert!(touchdown_speed < 0.7, "touched down at {touchdown_speed} m/s");
    let s = texts(&mut ap);
    assert!(has(&s, "Landing detected") && has(&s, "Disarmed by landing"), "{s:?}");
}

#[test]
fn reposition_flies_to_lat_lon_alt_with_yaw_and_holds() {
    let mut ap = Sitl::quad().build();
    take_off(&mut ap);
    let goal = Vector3::new(-15.0, 10.0, -8.0);
    let p = HOME.offset(&goal);
    assert_eq!(
        ap.command(AutopilotCommand::Reposition {
            lat_deg: Some(p.lat_deg),
            lon_deg: Some(p.lon_deg),
            alt_amsl_m: Some(p.alt_amsl_m),
            yaw_rad: Some(1.0),
            speed_m_s: Some(3.0),
        }),
        CommandOutcome::Accepted
    );
    assert_eq!(ap.mode(), FlightMode::Hold);
    let mut max_speed: f64 = 0.0;
    ap.run_until(40.0, |t| {
        max_speed = max_speed.max(t.velocity_ned.xy().norm());
        (t.position_ned - goal).norm() < 0.02
    })
    .expect("arrives");
    assert!(max_speed < 3.1, "{max_speed}");
    ap.run(2.0);
    let t = ap.telemetry();
    assert!((t.global.lat_deg - p.lat_deg).abs() < 1e-7 && (t.global.lon_deg - p.lon_deg).abs() < 1e-7);
    assert!((t.global.alt_amsl_m - p.alt_amsl_m).abs() < 0.02);
    assert!((euler_zyx(&t.attitude).z - 1.0).abs() < 0.01);
    // None parts keep the current value: only the altitude changes
    ap.command(AutopilotCommand::Reposition {
        lat_deg: None,
        lon_deg: None,
        alt_amsl_m: Some(HOME.alt_amsl_m + 4.0),
        yaw_rad: None,
        speed_m_s: None,
    });
    ap.run(10.0);
    let t = ap.telemetry();
    assert!(
        (t.position_ned - Vector3::new(-15.0, 10.0, -4.0)).norm() < 0.02,
        "{}",
        t.position_ned
    );
    // DO_CHANGE_SPEED sets the cruise speed of the next leg
    assert_eq!(
        ap.command(AutopilotCommand::ChangeSpeed { speed_m_s: 2.0 }),
        CommandOutcome::Accepted
    );
    ap.command(AutopilotCommand::Reposition {
        lat_deg: Some(HOME.lat_deg),
        lon_deg: Some(HOME.lon_deg),
        alt_amsl_m: None,
        yaw_rad: None,
        speed_m_s: None,
    });
    let mut max_speed: f64 = 0.0;
    ap.run_until(30.0, |t| {
        max_speed = max_speed.max(t.velocity_ned.xy().norm());
        false
    });
    assert!(max_speed < 2.1 && max_speed > 1.9, "{max_speed}");
}

fn position_sp(p: Vector3<f64>, yaw: f64) -> AutopilotCommand {
    AutopilotCommand::Offboard(OffboardSetpoint::Local(Targets {
        position: Some(p),
        velocity: None,
        acceleration: None,
        yaw_rad: Some(yaw),
        yaw_rate_rad_s: None,
    }))
}

fn velocity_sp(v: Vector3<f64>) -> AutopilotCommand {
    AutopilotCommand::Offboard(OffboardSetpoint::Local(Targets {
        position: None,
        velocity: Some(v),
        acceleration: None,
        yaw_rad: Some(0.0),
        yaw_rate_rad_s: None,
    }))
}

/// Run `seconds`, sending `cmd` every 50 ms (MAVSDK's 20 Hz stream); the time of the last one.
fn stream(ap: &mut Sitl, seconds: f64, cmd: AutopilotCommand) -> f64 {
    let every = ap.steps(0.05);
    let mut last = ap.time_s();
    for k in 0..ap.steps(seconds) {
        if k % every == 0 {
            assert_eq!(ap.command(cmd), CommandOutcome::Accepted);
            last = ap.time_s();
        }
        ap.step();
    }
    last
}

#[test]
fn offboard_needs_setpoints_follows_position_and_velocity_and_falls_back_to_hold() {
    let mut ap = Sitl::quad().build();
    take_off(&mut ap);
    texts(&mut ap);
    assert_eq!(
        ap.command(AutopilotCommand::SetMode(FlightMode::Offboard)),
        CommandOutcome::TemporarilyRejected("no offboard signal")
    );
    assert!(has(&texts(&mut ap), "Offboard"));
    assert_eq!(ap.mode(), FlightMode::Hold);

    let goal = Vector3::new(3.0, -4.0, -5.0);
    ap.command(position_sp(goal, 0.5));
    assert_eq!(
        ap.command(AutopilotCommand::SetMode(FlightMode::Offboard)),
        CommandOutcome::Accepted
    );
    assert_eq!(ap.telemetry().mode, FlightMode::Offboard);
    stream(&mut ap, 15.0, position_sp(goal, 0.5));
    let t = ap.telemetry();
    assert_eq!(t.mode, FlightMode::Offboard);
    assert!((t.position_ned - goal).norm() < 0.03, "{}", t.position_ned);
    assert!((euler_zyx(&t.attitude).z - 0.5).abs() < 0.01);

    let last = stream(&mut ap, 6.0, velocity_sp(Vector3::new(1.0, 0.5, 0.0)));
    let t = ap.telemetry();
    assert!(
        (t.velocity_ned - Vector3::new(1.0, 0.5, 0.0)).norm() < 0.03,
        "{}",
        t.velocity_ned
    );
    assert!((t.position_ned.z - goal.z).abs() < 0.05);

    // the stream stops: Hold after COM_OF_LOSS_T, with a STATUSTEXT
    texts(&mut ap);
    let lost = ap
        .run_until(5.0, |t| t.mode != FlightMode::Offboard)
        .expect("falls back");
    assert!((lost - last - 1.0).abs() < 0.01, "{}", lost - last);
    assert_eq!(ap.mode(), FlightMode::Hold);
    let s = ap.texts();
    assert!(
        s.iter()
            .any(|s| s.severity == Severity::Warning && s.text.contains("Offboard signal lost")),
        "{s:?}"
    );
    // Hold brakes and stays
    ap.run(5.0);
    let p = hover_at(&mut ap);
    ap.run(2.0);
    assert!((hover_at(&mut ap) - p).norm() < 0.005);
    assert_eq!(ap.telemetry().landed, LandedState::InAir);
}

#[test]
fn offboard_loss_action_can_be_land() {
    let mut ap = Sitl::quad().build();
    take_off(&mut ap);
    ap.set_param("COM_OBL_RC_ACT", int(4));
    ap.command(position_sp(Vector3::new(0.0, 0.0, -3.0), 0.0));
    ap.command(AutopilotCommand::SetMode(FlightMode::Offboard));
    ap.run_until(3.0, |t| t.mode == FlightMode::Land)
        .expect("lands on loss");
    ap.run_until(20.0, |t| t.landed == LandedState::OnGround)
        .expect("touches down");
}

fn attitude_sp(q: UnitQuaternion<f64>, thrust: f64) -> AutopilotCommand {
    AutopilotCommand::Offboard(OffboardSetpoint::Attitude(AttitudeTarget {
        attitude: Some(q),
        rate_frd: None,
        thrust_normalised: thrust,
    }))
}

#[test]
fn offboard_attitude_keeps_the_commanded_tilt_and_rates_turn() {
    let mut ap = Sitl::quad().build();
    take_off(&mut ap);
    let hover = ap.telemetry().throttle;
    let q = UnitQuaternion::from_euler_angles(8f64.to_radians(), -5f64.to_radians(), 0.3);
    ap.command(attitude_sp(q, hover));
    assert_eq!(
        ap.command(AutopilotCommand::SetMode(FlightMode::Offboard)),
        CommandOutcome::Accepted
    );
    stream(&mut ap, 0.8, attitude_sp(q, hover));
    for _ in 0..10 {
        stream(&mut ap, 0.1, attitude_sp(q, hover));
        let t = ap.telemetry();
        let err = t.attitude.angle_to(&q);
        assert!(err < 1f64.to_radians(), "attitude error {} deg", err.to_degrees());
        assert!(t.velocity_ned.xy().norm() > 0.1, "tilted thrust accelerates sideways");
    }
    // body rates: yaw at 0.5 rad/s, level, for 2 s
    let level = UnitQuaternion::from_euler_angles(0.0, 0.0, euler_zyx(&ap.telemetry().attitude).z);
    stream(&mut ap, 1.5, attitude_sp(level, hover));
    let yaw0 = euler_zyx(&ap.telemetry().attitude).z;
    let rates = AutopilotCommand::Offboard(OffboardSetpoint::Attitude(AttitudeTarget {
        attitude: None,
        rate_frd: Some(Vector3::new(0.0, 0.0, 0.5)),
        thrust_normalised: hover,
    }));
    stream(&mut ap, 2.0, rates);
    let t = ap.telemetry();
    let turned = rotorpilot::math::wrap_pi(euler_zyx(&t.attitude).z - yaw0);
    assert!((turned - 1.0).abs() < 0.1, "turned {turned} rad");
    assert!((t.rate_frd.z - 0.5).abs() < 0.05, "{}", t.rate_frd.z);
    assert!(!ap.telemetry().landed.eq(&LandedState::OnGround));
}

#[test]
fn injected_wrench_and_mass_are_estimated_fsr_quad_report_values() {
    // The report's case: f_e = (0.5, 0.5, 0) N, tau_e,z = 0.2 N m, true mass 1.25 kg, nominal 1.5 kg.
    let mut ap = Sitl::airframe("fsr-quad").build();
    take_off(&mut ap);
    for (name, v) in [
        ("SIM_FEXT_X", 0.5),
        ("SIM_FEXT_Y", 0.5),
        ("SIM_TEXT_Z", 0.2),
        ("SIM_MASS", 1.25),
        ("MDL_MASS", 1.5),
    ] {
        ap.set_param(name, real(v));
    }
    ap.run(10.0);
    let t = ap.telemetry();
    let truth = ap.truth();
    assert_eq!(truth.force_ned, Vector3::new(0.5, 0.5, 0.0));
    assert!((truth.torque_frd.z - 0.2).abs() < 1e-6);
    assert_eq!(truth.true_mass_kg, 1.25);
    let e = t.estimate;
    assert!(
        (e.force_ned.x - 0.5).abs() < 0.015 && (e.force_ned.y - 0.5).abs() < 0.015,
        "{}",
        e.force_ned
    );
    assert!((e.torque_frd.z - 0.2).abs() < 0.006, "{}", e.torque_frd);
    assert!((e.mass_kg - 1.25).abs() < 0.0125, "{}", e.mass_kg);
    // the force's z part is the mass error seen at hover
    assert!((e.force_ned.z + 0.25 * 9.81).abs() < 0.05);
}

#[test]
fn injected_wrench_and_lighter_vehicle_are_estimated_quad() {
    let mut ap = Sitl::quad().build();
    take_off(&mut ap);
    for (name, v) in [
        ("SIM_FEXT_X", 0.5),
        ("SIM_FEXT_Y", 0.5),
        ("SIM_TEXT_Z", 0.05),
        ("SIM_MASS", 1.6),
    ] {
        ap.set_param(name, real(v));
    }
    ap.run(10.0);
    let e = ap.telemetry().estimate;
    assert!(
        (e.force_ned.x - 0.5).abs() < 0.015 && (e.force_ned.y - 0.5).abs() < 0.015,
        "{}",
        e.force_ned
    );
    assert!((e.torque_frd.z - 0.05).abs() < 0.0015, "{}", e.torque_frd);
    assert!((e.mass_kg - 1.6).abs() < 0.016, "{}", e.mass_kg);
}

#[test]
fn ctrl_type_switched_in_flight_keeps_the_hover() {
    let mut ap = Sitl::quad().build();
    let p0 = hover(&mut ap);
    for (value, kind) in [
        (0, ControllerKind::Hierarchical),
        (2, ControllerKind::Passivity),
        (1, ControllerKind::Geometric),
    ] {
        ap.set_param("CTRL_TYPE", int(value));
        assert_eq!(ap.pilot().controller_kind(), kind);
        let mut worst: f64 = 0.0;
        for _ in 0..ap.steps(4.0) {
            ap.step();
            worst = worst.max((ap.telemetry().position_ned - p0).norm());
        }
        assert!(worst < 0.02, "{kind}: moved {worst} m");
        assert_eq!(ap.mode(), FlightMode::Hold);
    }
}

#[test]
fn est_comp_removes_the_steady_error_under_a_disturbance() {
    let mut ap = Sitl::quad().build();
    let p0 = hover(&mut ap);
    ap.set_param("SIM_FEXT_X", real(2.0));
    ap.set_param("SIM_FEXT_Y", real(-1.0));
    ap.run(8.0);
    let off = (hover_at(&mut ap) - p0).norm();
    assert!(off > 0.1, "no feedback: pushed {off} m");
    ap.set_param("EST_COMP", int(1));
    ap.run(8.0);
    let on = (hover_at(&mut ap) - p0).norm();
    assert!(on < 0.01, "feedback: {on} m");
    // rebuilding the estimator in flight keeps the compensation (cross-fade)
    ap.set_param("EST_ORDER", int(5));
    ap.set_param("EST_POLY", int(1));
    let mut worst: f64 = 0.0;
    for _ in 0..ap.steps(8.0) {
        ap.step();
        worst = worst.max((ap.telemetry().position_ned - p0).norm());
    }
    assert!(worst < 0.05, "estimator rebuilt: moved {worst} m");
    assert!((hover_at(&mut ap) - p0).norm() < 0.01);
    // the gain scales apply live too
    ap.set_param("CTRL_POS_SCALE", real(1.5));
    ap.set_param("CTRL_ATT_SCALE", real(0.8));
    ap.run(3.0);
    assert!((hover_at(&mut ap) - p0).norm() < 0.01);
}

#[test]
fn forced_disarm_in_the_air_falls_and_lands() {
    let mut ap = Sitl::quad().build();
    take_off(&mut ap);
    assert_eq!(
        ap.command(AutopilotCommand::Disarm { force: true }),
        CommandOutcome::Accepted
    );
    let t = ap.telemetry();
    assert!(!t.armed && t.landed == LandedState::InAir);
    ap.run_until(5.0, |t| t.landed == LandedState::OnGround)
        .expect("falls to the ground");
    assert_eq!(ap.telemetry().position_ned.z, -0.24);
}

#[test]
fn invalid_or_untimely_commands_are_refused_without_panicking() {
    let mut ap = Sitl::quad().build();
    ap.step();
    let nan = f64::NAN;
    let inf = f64::INFINITY;
    let before = ap.telemetry();
    for (cmd, want) in [
        (
            AutopilotCommand::Takeoff {
                altitude_amsl_m: Some(nan),
            },
            CommandOutcome::Denied("invalid takeoff altitude"),
        ),
        (
            AutopilotCommand::Reposition {
                lat_deg: Some(inf),
                lon_deg: None,
                alt_amsl_m: None,
                yaw_rad: None,
                speed_m_s: None,
            },
            CommandOutcome::Denied("invalid reposition value"),
        ),
        (
            AutopilotCommand::Reposition {
                lat_deg: Some(91.0),
                lon_deg: None,
                alt_amsl_m: None,
                yaw_rad: None,
                speed_m_s: None,
            },
            CommandOutcome::Denied("invalid reposition position"),
        ),
        (
            AutopilotCommand::ChangeSpeed { speed_m_s: nan },
            CommandOutcome::Denied("invalid speed"),
        ),
        (
            AutopilotCommand::SetHome(Some(GeoPoint { lat_deg: nan, ..HOME })),
            CommandOutcome::Denied("invalid home position"),
        ),
        (
            AutopilotCommand::Offboard(OffboardSetpoint::Local(Targets {
                position: Some(Vector3::new(0.0, nan, 0.0)),
                velocity: None,
                acceleration: None,
                yaw_rad: None,
                yaw_rate_rad_s: None,
            })),
            CommandOutcome::Denied("invalid offboard setpoint"),
        ),
        (
            AutopilotCommand::Offboard(OffboardSetpoint::Local(Targets {
                position: None,
                velocity: None,
                acceleration: None,
                yaw_rad: Some(0.0),
                yaw_rate_rad_s: None,
            })),
            CommandOutcome::Denied("invalid offboard setpoint"),
        ),
        (
            AutopilotCommand::Offboard(OffboardSetpoint::Attitude(AttitudeTarget {
                attitude: None,
                rate_frd: None,
                thrust_normalised: nan,
            })),
            CommandOutcome::Denied("invalid offboard setpoint"),
        ),
        (
            AutopilotCommand::SetMode(FlightMode::Mission),
            CommandOutcome::TemporarilyRejected("no mission"),
        ),
        (
            AutopilotCommand::Land,
            CommandOutcome::TemporarilyRejected("vehicle not armed"),
        ),
        (
            AutopilotCommand::ReturnToLaunch,
            CommandOutcome::TemporarilyRejected("vehicle not armed"),
        ),
    ] {
        assert_eq!(ap.command(cmd), want, "{cmd:?}");
    }
    assert_eq!(ap.telemetry(), before, "refusals change nothing");
    ap.step();
    assert!(ap.telemetry().position_ned.iter().all(|x| x.is_finite()));
    // Position needs manual control (PX4: "No manual control input"); home is always fine
    assert_eq!(
        ap.command(AutopilotCommand::SetMode(FlightMode::Position)),
        CommandOutcome::TemporarilyRejected("no manual control input")
    );
    assert_eq!(ap.mode(), FlightMode::Hold);
    let elsewhere = HOME.offset(&Vector3::new(10.0, 0.0, -1.0));
    assert_eq!(
        ap.command(AutopilotCommand::SetHome(Some(elsewhere))),
        CommandOutcome::Accepted
    );
    let t = ap.telemetry();
    assert_eq!(t.home, elsewhere);
    assert!((t.home_ned - Vector3::new(10.0, 0.0, -1.0)).norm() < 1e-6);
    assert_eq!(t.origin, HOME);
    assert_eq!(ap.command(AutopilotCommand::SetHome(None)), CommandOutcome::Accepted);
    let t = ap.telemetry();
    assert!(
        (t.home_ned - Vector3::new(0.0, 0.0, t.position_ned.z)).norm() < 1e-6,
        "home where the landed vehicle rests: {:?}",
        t.home_ned
    );
}

/// Commands that are invalid in any state, each with its answer.
fn invalid_commands() -> Vec<(AutopilotCommand, CommandOutcome)> {
    let nan = f64::NAN;
    let targets = |position, yaw_rad| Targets {
        position,
        velocity: None,
        acceleration: None,
        yaw_rad,
        yaw_rate_rad_s: None,
    };
    vec![
        (
            AutopilotCommand::Takeoff {
                altitude_amsl_m: Some(nan),
            },
            CommandOutcome::Denied("invalid takeoff altitude"),
        ),
        (
            AutopilotCommand::Reposition {
                lat_deg: Some(HOME.lat_deg + 1e-4),
                lon_deg: None,
                alt_amsl_m: None,
                yaw_rad: None,
                speed_m_s: Some(f64::INFINITY),
            },
            CommandOutcome::Denied("invalid reposition value"),
        ),
        (
            AutopilotCommand::Reposition {
                lat_deg: Some(91.0),
                lon_deg: None,
                alt_amsl_m: Some(HOME.alt_amsl_m + 20.0),
                yaw_rad: Some(1.0),
                speed_m_s: Some(3.0),
            },
            CommandOutcome::Denied("invalid reposition position"),
        ),
        (
            AutopilotCommand::ChangeSpeed { speed_m_s: nan },
            CommandOutcome::Denied("invalid speed"),
        ),
        (
            AutopilotCommand::SetHome(Some(GeoPoint { lat_deg: nan, ..HOME })),
            CommandOutcome::Denied("invalid home position"),
        ),
        (
            AutopilotCommand::Offboard(OffboardSetpoint::Local(targets(
                Some(Vector3::new(1.0, nan, -3.0)),
                Some(0.3),
            ))),
            CommandOutcome::Denied("invalid offboard setpoint"),
        ),
        (
            AutopilotCommand::Offboard(OffboardSetpoint::Local(targets(None, Some(0.0)))),
            CommandOutcome::Denied("invalid offboard setpoint"),
        ),
        (
            AutopilotCommand::Offboard(OffboardSetpoint::Attitude(AttitudeTarget {
                attitude: Some(UnitQuaternion::identity()),
                rate_frd: None,
                thrust_normalised: nan,
            })),
            CommandOutcome::Denied("invalid offboard setpoint"),
        ),
    ]
}

/// The whole state of the core (world and flight stack, every target, timer
/// and setpoint: their `Debug`) at the current instant, status texts drained
/// first. Any input reads the sensors once at its instant (as the next step
/// would) and sets the autopilot's clock `now_s` to it: both are brought to
/// the instant here, so only what the input itself did can differ.
fn whole_state(ap: &mut Sitl) -> String {
    ap.texts();
    ap.readings();
    let full = format!("{:?}", ap.core());
    let key = "now_s: ";
    assert_eq!(full.matches(key).count(), 1, "one autopilot clock");
    let at = full.find(key).unwrap() + key.len();
    let end = at + full[at..].find([',', ' ']).unwrap();
    format!("{}{}", &full[..at], &full[end..])
}

/// Where two states first differ, with some context.
fn difference(a: &str, b: &str) -> String {
    let i = a.bytes().zip(b.bytes()).take_while(|(x, y)| x == y).count();
    let from = a[..i].char_indices().rev().nth(120).map_or(0, |(k, _)| k);
    let end = |s: &str| s[i..].char_indices().nth(120).map_or(s.len(), |(k, _)| i + k);
    format!("before: …{}…\nafter:  …{}…", &a[from..end(a)], &b[from..end(b)])
}

/// Each command is refused as `want` says and leaves the whole state as it was.
fn assert_refusals_change_nothing(ap: &mut Sitl, phase: &str, refused: Vec<(AutopilotCommand, CommandOutcome)>) {
    for (cmd, want) in refused {
        let before = whole_state(ap);
        assert_eq!(ap.command(cmd), want, "{phase}: {cmd:?}");
        let after = whole_state(ap);
        assert!(
            before == after,
            "{phase}: refused {cmd:?} changed the state\n{}",
            difference(&before, &after)
        );
    }
}

/// A refusal changes nothing, on the ground, in Hold and in Offboard: the
/// whole core (targets, cruise speed, offboard setpoint and timer, home, the
/// world) is the same before and after each refused command, and the flight
/// goes on as before.
#[test]
fn refusals_leave_the_whole_state_unchanged_on_the_ground_and_in_flight() {
    use rotorpilot::autopilot::PowerAction;
    let mut ap = Sitl::quad().build();
    ap.step();
    let mut on_ground = invalid_commands();
    on_ground.extend([
        (
            AutopilotCommand::SetMode(FlightMode::Mission),
            CommandOutcome::TemporarilyRejected("no mission"),
        ),
        (
            AutopilotCommand::Land,
            CommandOutcome::TemporarilyRejected("vehicle not armed"),
        ),
        (
            AutopilotCommand::ReturnToLaunch,
            CommandOutcome::TemporarilyRejected("vehicle not armed"),
        ),
    ]);
    assert_refusals_change_nothing(&mut ap, "on the ground", on_ground);

    let in_flight = |offboard: bool| {
        let mut v = invalid_commands();
        v.extend([
            (
                AutopilotCommand::Disarm { force: false },
                CommandOutcome::TemporarilyRejected("vehicle in the air"),
            ),
            (
                AutopilotCommand::SetMode(FlightMode::Mission),
                CommandOutcome::TemporarilyRejected("no mission"),
            ),
            (
                AutopilotCommand::SetMode(FlightMode::Position),
                CommandOutcome::TemporarilyRejected("no manual control input"),
            ),
            (
                AutopilotCommand::Power(PowerAction::Reboot),
                CommandOutcome::Denied("disarm before reboot"),
            ),
        ]);
        if !offboard {
            v.push((
                AutopilotCommand::SetMode(FlightMode::Offboard),
                CommandOutcome::TemporarilyRejected("no offboard signal"),
            ));
        }
        v
    };
    // in Hold, on the way to a reposition target at its cruise speed
    take_off(&mut ap);
    assert_eq!(
        ap.command(AutopilotCommand::ChangeSpeed { speed_m_s: 2.0 }),
        CommandOutcome::Accepted
    );
    let target = HOME.offset(&Vector3::new(8.0, 0.0, -4.0));
    assert_eq!(
        ap.command(AutopilotCommand::Reposition {
            lat_deg: Some(target.lat_deg),
            lon_deg: Some(target.lon_deg),
            alt_amsl_m: Some(target.alt_amsl_m),
            yaw_rad: None,
            speed_m_s: None,
        }),
        CommandOutcome::Accepted
    );
    ap.run(1.0);
    assert_refusals_change_nothing(&mut ap, "in Hold", in_flight(false));
    ap.run_until(20.0, |t| (t.position_ned - Vector3::new(8.0, 0.0, -4.0)).norm() < 0.05)
        .expect("the reposition target kept");
    // in Offboard, the stream 0.5 s old (its timer running)
    let goal = Vector3::new(8.0, 3.0, -5.0);
    ap.command(position_sp(goal, 0.5));
    assert_eq!(
        ap.command(AutopilotCommand::SetMode(FlightMode::Offboard)),
        CommandOutcome::Accepted
    );
    stream(&mut ap, 3.0, position_sp(goal, 0.5));
    ap.run(0.5);
    assert_refusals_change_nothing(&mut ap, "in Offboard", in_flight(true));
    assert_eq!(ap.mode(), FlightMode::Offboard);
    // the refused setpoints did not feed the stream: it goes stale on time
    // (COM_OF_LOSS_T 1 s after the last accepted one) and the vehicle holds
    ap.run(0.6);
    assert_eq!(ap.mode(), FlightMode::Hold);
}

#[test]
fn telemetry_is_complete_and_consistent() {
    let mut ap = Sitl::quad().build();
    let t0 = ap.telemetry();
    assert!((t0.battery_voltage_v - 16.8).abs() < 0.05);
    assert_eq!(t0.battery_remaining, 1.0);
    take_off(&mut ap);
    ap.run(1.0);
    let t = ap.telemetry();
    assert_eq!(t.global, HOME.offset(&t.position_ned));
    assert!(t.acceleration_ned.norm() < 0.05);
    assert!(t.throttle > 0.5 && t.throttle < 0.65, "{}", t.throttle);
    assert!(t.battery_current_a > 8.0 && t.battery_current_a < 25.0);
    assert!(t.battery_consumed_mah > 0.0 && t.battery_remaining < 1.0);
    assert!(t.battery_voltage_v < 16.8);
    assert!(!t.prearm_ok, "not armable in the air");
    // true mass 2.0 kg; measured 1.9985 kg one second after the take-off
    assert!((t.estimate.mass_kg - 2.0).abs() < 2e-3, "{}", t.estimate.mass_kg);
}

#[test]
fn same_commands_give_identical_telemetry() {
    let fly = || {
        let mut ap = Sitl::quad().build();
        let mut log = Vec::new();
        take_off(&mut ap);
        ap.set_param("SIM_FEXT_X", real(1.0));
        ap.set_param("EST_COMP", int(1));
        ap.command(position_sp(Vector3::new(1.0, 1.0, -3.0), 0.2));
        ap.command(AutopilotCommand::SetMode(FlightMode::Offboard));
        for _ in 0..40 {
            stream(&mut ap, 0.1, position_sp(Vector3::new(1.0, 1.0, -3.0), 0.2));
            log.push(ap.telemetry());
        }
        ap.command(AutopilotCommand::Land);
        for _ in 0..30 {
            ap.run(0.1);
            log.push(ap.telemetry());
        }
        (log, ap.texts())
    };
    let (a, sa) = fly();
    let (b, sb) = fly();
    assert_eq!(a, b);
    assert_eq!(sa, sb);
}

#[test]
fn reposition_on_the_ground_takes_off_first() {
    let mut ap = Sitl::quad().build();
    ap.step();
    ap.command(AutopilotCommand::Arm { force: false });
    let goal = Vector3::new(5.0, 0.0, -4.0);
    let p = HOME.offset(&goal);
    assert_eq!(
        ap.command(AutopilotCommand::Reposition {
            lat_deg: Some(p.lat_deg),
            lon_deg: Some(p.lon_deg),
            alt_amsl_m: Some(p.alt_amsl_m),
            yaw_rad: None,
            speed_m_s: None,
        }),
        CommandOutcome::Accepted
    );
    assert_eq!(ap.mode(), FlightMode::Takeoff);
    ap.run_until(40.0, |t| (t.position_ned - goal).norm() < 0.02)
        .expect("takes off and goes");
    assert_eq!(ap.mode(), FlightMode::Hold);
}

#[test]
fn mavsdk_offboard_example_flow_takes_off_in_offboard_lands_at_z0_and_disarms() {
    // offboard_position_ned.py: arm, setpoint (0, 0, 0), start, climb to 5 m, move, back down to z = 0, stop
    let mut ap = Sitl::quad().build();
    ap.step();
    assert_eq!(
        ap.command(AutopilotCommand::Arm { force: false }),
        CommandOutcome::Accepted
    );
    ap.command(position_sp(Vector3::zeros(), 0.0));
    assert_eq!(
        ap.command(AutopilotCommand::SetMode(FlightMode::Offboard)),
        CommandOutcome::Accepted
    );
    stream(&mut ap, 0.5, position_sp(Vector3::zeros(), 0.0));
    assert_eq!(
        ap.telemetry().landed,
        LandedState::OnGround,
        "a setpoint on the ground keeps it there"
    );
    stream(&mut ap, 10.0, position_sp(Vector3::new(0.0, 0.0, -5.0), 0.0));
    let t = ap.telemetry();
    assert!((t.position_ned.z + 5.0).abs() < 0.05 && t.landed == LandedState::InAir);
    stream(
        &mut ap,
        10.0,
        position_sp(Vector3::new(5.0, 0.0, -5.0), 90f64.to_radians()),
    );
    let t = ap.telemetry();
    assert!((t.position_ned - Vector3::new(5.0, 0.0, -5.0)).norm() < 0.05);
    assert!((euler_zyx(&t.attitude).z - 90f64.to_radians()).abs() < 0.02);
    texts(&mut ap);
    stream(
        &mut ap,
        10.0,
        position_sp(Vector3::new(5.0, 0.0, 0.0), 90f64.to_radians()),
    );
    let t = ap.telemetry();
    assert!(
        !t.armed,
        "landed in offboard at z = 0 and disarmed after COM_DISARM_LAND"
    );
    assert_eq!(t.landed, LandedState::OnGround);
    assert!((t.position_ned.xy() - Vector3::new(5.0, 0.0, 0.0).xy()).norm() < 0.05);
    let s = texts(&mut ap);
    assert!(has(&s, "Landing detected") && has(&s, "Disarmed by landing"), "{s:?}");
    assert_eq!(
        ap.command(AutopilotCommand::SetMode(FlightMode::Hold)),
        CommandOutcome::Accepted,
        "offboard.stop()"
    );
}

#[test]
fn every_builtin_airframe_takes_off_holds_and_lands() {
    for name in ["quad", "hexa", "octo", "fsr-quad"] {
        let mut ap = Sitl::airframe(name).build();
        let p0 = hover(&mut ap);
        assert!((height(&ap.telemetry()) - 2.5).abs() < 0.03, "{name}");
        ap.run(2.0);
        assert!((hover_at(&mut ap) - p0).norm() < 0.01, "{name}");
        ap.command(AutopilotCommand::Land);
        ap.run_until(30.0, |t| !t.armed)
            .unwrap_or_else(|| panic!("{name} lands and disarms"));
        assert_eq!(ap.telemetry().landed, LandedState::OnGround, "{name}");
    }
}

#[test]
fn every_parameter_at_its_bounds_is_applied_in_flight_without_faults() {
    let mut ap = Sitl::quad().build();
    hover(&mut ap);
    let mut store = ap.params().clone();
    let defaults = store.clone();
    for i in 0..store.len() {
        let (spec, _) = store.by_index(i).unwrap();
        if spec.effect == rotorpilot::params::Effect::StoredOnly {
            continue; // PX4's parameters rotorpilot stores without using
        }
        for bound in [spec.min, spec.max] {
            let v = match spec.kind {
                rotorpilot::params::ParamType::Int32 => int(bound as i32),
                rotorpilot::params::ParamType::Real32 => real(bound as f32),
            };
            store.set(spec.name, v).unwrap();
            ap.apply_params(&store)
                .unwrap_or_else(|e| panic!("{} = {bound}: {e}", spec.name));
            ap.run(0.2);
            let t = ap.telemetry();
            assert!(
                t.position_ned
                    .iter()
                    .chain(t.estimate.force_ned.iter())
                    .all(|x| x.is_finite()),
                "{} = {bound}",
                spec.name
            );
            assert!(ap.last_fault().is_none(), "{} = {bound}", spec.name);
        }
        store = defaults.clone();
        ap.apply_params(&store).unwrap();
        if !ap.armed() || ap.telemetry().landed == LandedState::OnGround {
            // an extreme (a huge force, a tiny mass) may have ended the flight: start again
            let fresh = Sitl::quad().build();
            ap = fresh;
            hover(&mut ap);
        }
    }
}

/// GIVEN white sensor noise on every measurement at 1 kHz (position 1 cm,
/// velocity 2 cm/s, attitude 0.1 deg, rates 0.3 deg/s) WHEN the quad rests,
/// takes off, hovers and lands through the lockstep core THEN the land
/// detector, which sees only those measurements and the thrust it commanded,
/// reports one takeoff and one landing, at the right moments, and the vehicle
/// disarms on the ground. (The hierarchical law flies: the geometric law
/// differentiates its desired attitude step by step, which such noise upsets.)
#[test]
fn landing_detection_works_on_noisy_measurements() {
    let noise = SensorNoise {
        position_m: 0.01,
        velocity_m_s: 0.02,
        attitude_rad: 0.002,
        rate_rad_s: 0.005,
    };
    let mut ap = Sitl::quad()
        .params(&[("CTRL_TYPE", int(0))])
        .sensors(SensorConfig { noise, seed: 11 })
        .build();
    // resting, noisy: still on the ground, and armable
    let on_ground = ap.run_until(5.0, |t| t.landed != LandedState::OnGround);
    assert_eq!(on_ground, None, "noise alone never lifts it off");
    assert!(ap.telemetry().prearm_ok);
    take_off(&mut ap);
    let mut lowest: f64 = f64::INFINITY;
    let spurious = ap.run_until(5.0, |t| {
        lowest = lowest.min(height(t));
        t.landed != LandedState::InAir
    });
    assert_eq!(spurious, None, "hovering is never taken for a landing");
    assert!(lowest > 2.0, "{lowest}");
    assert_eq!(ap.command(AutopilotCommand::Land), CommandOutcome::Accepted);
    let touchdown = ap
        .run_until(30.0, |t| t.landed == LandedState::OnGround)
        .expect("lands");
    let t = ap.telemetry();
    assert!(
        ap.core().world().plant(0).contact() == rotorpilot::sim::Contact::OnGround,
        "landed means on the ground"
    );
    assert!(t.position_ned.xy().norm() < 0.1);
    let disarmed = ap.run_until(10.0, |t| !t.armed).expect("auto-disarm");
    assert!((disarmed - touchdown - 2.0).abs() < 0.01, "{}", disarmed - touchdown);
    let s = texts(&mut ap);
    let count = |part: &str| s.iter().filter(|x| x.contains(part)).count();
    assert_eq!((count("Takeoff detected"), count("Landing detected")), (1, 1), "{s:?}");
    // it stays landed on noisy measurements, disarmed
    assert_eq!(ap.run_until(5.0, |t| t.landed != LandedState::OnGround), None);
}

/// The land detector needs no contact flag: it lands as soon after touchdown
/// as the low thrust has lasted 0.25 s, whatever the airframe.
#[test]
fn touchdown_to_landed_takes_about_the_detection_time() {
    for name in ["quad", "hexa", "octo", "fsr-quad"] {
        let mut ap = Sitl::airframe(name).build();
        take_off(&mut ap);
        ap.command(AutopilotCommand::Land);
        let mut touched = None;
        let mut landed = None;
        for _ in 0..30_000 {
            ap.step();
            let now = ap.time_s();
            if touched.is_none() && ap.core().world().plant(0).contact() == rotorpilot::sim::Contact::OnGround {
                touched = Some(now);
            }
            if ap.telemetry().landed == LandedState::OnGround {
                landed = Some(now);
                break;
            }
        }
        let delay = landed.expect("lands") - touched.expect("touches down");
        assert!((0.25..0.3).contains(&delay), "{name}: {delay} s");
    }
}

/// What the link used to decide is the autopilot's now, at the instant the
/// command is applied: reboot and shutdown only disarmed, failure injection
/// only with SYS_FAILURE_EN (then the world's: it has no optical-flow sensor), no mission
/// to start, an invalid home refused, a body-frame setpoint turned by the
/// heading the vehicle has when it arrives.
#[test]
fn the_autopilot_decides_what_the_link_only_translates() {
    use rotorpilot::autopilot::{PowerAction, RelativeFrame};
    let mut ap = Sitl::quad().build();
    ap.step();
    let reboot = AutopilotCommand::Power(PowerAction::Reboot);
    // FAILURE_UNIT_SENSOR_OPTICAL_FLOW, FAILURE_TYPE_OFF
    let inject = AutopilotCommand::InjectFailure {
        unit: 5,
        kind: 1,
        instance: 1,
    };
    assert_eq!(ap.command(reboot), CommandOutcome::Accepted);
    assert_eq!(
        ap.command(inject),
        CommandOutcome::Denied("failure injection disabled (SYS_FAILURE_EN)")
    );
    ap.set_param("SYS_FAILURE_EN", int(1));
    assert_eq!(ap.command(inject), CommandOutcome::Unsupported);
    assert_eq!(
        ap.command(AutopilotCommand::StartMission { first: Some(0) }),
        CommandOutcome::Denied("no mission")
    );
    assert_eq!(
        ap.command(AutopilotCommand::SetHome(Some(GeoPoint { lat_deg: 91.0, ..HOME }))),
        CommandOutcome::Denied("invalid home position")
    );
    take_off(&mut ap);
    for (power, why) in [
        (PowerAction::Reboot, "disarm before reboot"),
        (PowerAction::Shutdown, "disarm before shutdown"),
    ] {
        assert_eq!(ap.command(AutopilotCommand::Power(power)), CommandOutcome::Denied(why));
    }
    // face east, then "forward at 1 m/s" in BODY_NED is east
    let here = ap.telemetry().global;
    ap.command(AutopilotCommand::Reposition {
        lat_deg: Some(here.lat_deg),
        lon_deg: Some(here.lon_deg),
        alt_amsl_m: None,
        yaw_rad: Some(std::f64::consts::FRAC_PI_2),
        speed_m_s: None,
    });
    ap.run(6.0);
    let forward = AutopilotCommand::Offboard(OffboardSetpoint::Relative(
        RelativeFrame::Body,
        Targets {
            position: None,
            velocity: Some(Vector3::new(1.0, 0.0, 0.0)),
            acceleration: None,
            yaw_rad: None,
            yaw_rate_rad_s: Some(0.0),
        },
    ));
    ap.command(forward);
    assert_eq!(
        ap.command(AutopilotCommand::SetMode(FlightMode::Offboard)),
        CommandOutcome::Accepted
    );
    stream(&mut ap, 4.0, forward);
    let v = ap.telemetry().velocity_ned;
    assert!((v - Vector3::new(0.0, 1.0, 0.0)).norm() < 0.05, "{v}");
}

/// HEARTBEAT's type comes from the airframe: the autopilot reports what it flies.
#[test]
fn telemetry_names_the_multirotor() {
    use rotorpilot::autopilot::VehicleType;
    for (name, kind) in [
        ("quad", VehicleType::Quadrotor),
        ("hexa", VehicleType::Hexarotor),
        ("octo", VehicleType::Octorotor),
        ("fsr-quad", VehicleType::Quadrotor),
    ] {
        assert_eq!(Sitl::airframe(name).build().telemetry().vehicle_type, kind, "{name}");
    }
}

/// GIVEN the slowest climbs a client can ask for (a takeoff at MPC_TKO_SPEED
/// 0.5 m/s, an offboard climb at 0.5 m/s, both under the land detector's
/// stillness limit while landed) WHEN they end in a hover THEN the vehicle is
/// flying, not "landed" in the air: it holds its height and refuses a disarm.
#[test]
fn slow_climbs_are_takeoffs() {
    let mut ap = Sitl::quad().params(&[("MPC_TKO_SPEED", real(0.5))]).build();
    take_off(&mut ap);
    ap.run(3.0);
    let t = ap.telemetry();
    assert_eq!(t.landed, LandedState::InAir);
    assert!((height(&t) - 2.5).abs() < 0.05, "{}", height(&t));
    assert_eq!(
        ap.command(AutopilotCommand::Disarm { force: false }),
        CommandOutcome::TemporarilyRejected("vehicle in the air")
    );

    let mut ap = Sitl::quad().build();
    ap.step();
    ap.command(AutopilotCommand::Arm { force: false });
    let climb = AutopilotCommand::Offboard(OffboardSetpoint::Local(Targets {
        position: None,
        velocity: Some(Vector3::new(0.0, 0.0, -0.5)),
        acceleration: None,
        yaw_rad: Some(0.0),
        yaw_rate_rad_s: None,
    }));
    ap.command(climb);
    assert_eq!(
        ap.command(AutopilotCommand::SetMode(FlightMode::Offboard)),
        CommandOutcome::Accepted
    );
    stream(&mut ap, 4.0, climb);
    let z = ap.telemetry().position_ned.z;
    assert!(z < -1.2, "climbing: {z}");
    stream(&mut ap, 8.0, position_sp(Vector3::new(0.0, 0.0, z), 0.0));
    let t = ap.telemetry();
    assert_eq!(t.landed, LandedState::InAir);
    assert!((t.position_ned.z - z).abs() < 0.05, "{} vs {z}", t.position_ned.z);
}

/// Above real-time speed the runtime times the timers that wait for a client
/// on the wall clock: the core then never fires them on simulated time, and
/// acts only on the runtime's expiry events — for the timer still running.
#[test]
fn client_timers_on_the_wall_clock_fire_only_on_the_runtimes_event() {
    use rotorpilot::autopilot::{ClientClock, ClientTimer};
    let mut ap = Sitl::quad().build();
    ap.pilot_mut().set_client_clock(ClientClock::Wall);
    ap.step();
    ap.command(AutopilotCommand::Arm { force: false });
    let armed_at = ap.time_s();
    // 30 s of simulated time: COM_DISARM_PRFLT (10 s) is a wall-clock timer now
    ap.run(30.0);
    assert!(ap.armed(), "disarmed on simulated time");
    let pending = ap.pilot().client_timers();
    assert_eq!(pending.len(), 1);
    assert_eq!(
        (pending[0].timer, pending[0].started_s, pending[0].duration_s),
        (ClientTimer::PreflightDisarm, armed_at, 10.0)
    );
    // a stale event (another arming's timer) changes nothing
    assert!(
        !ap.core_mut()
            .client_timeout(0, ClientTimer::PreflightDisarm, armed_at + 1.0)
    );
    assert!(ap.armed());
    assert!(ap.core_mut().client_timeout(0, ClientTimer::PreflightDisarm, armed_at));
    assert!(!ap.armed());
    assert!(has(&texts(&mut ap), "preflight"));

    // offboard: the stream's freshness is the runtime's to judge
    take_off(&mut ap);
    let here = ap.telemetry().position_ned;
    let last = stream(&mut ap, 0.5, position_sp(here, 0.0));
    assert_eq!(
        ap.command(AutopilotCommand::SetMode(FlightMode::Offboard)),
        CommandOutcome::Accepted
    );
    ap.run(20.0);
    assert_eq!(ap.mode(), FlightMode::Offboard, "left offboard on simulated time");
    let t = ap.pilot().client_timers();
    assert!(
        t.iter()
            .any(|p| p.timer == ClientTimer::OffboardLoss && p.started_s == last),
        "{t:?}"
    );
    assert!(ap.core_mut().client_timeout(0, ClientTimer::OffboardLoss, last));
    assert_eq!(ap.mode(), FlightMode::Hold);
    // lost: OFFBOARD is refused until a new setpoint arrives
    assert!(matches!(
        ap.command(AutopilotCommand::SetMode(FlightMode::Offboard)),
        CommandOutcome::TemporarilyRejected(_)
    ));
    assert_eq!(ap.command(position_sp(here, 0.0)), CommandOutcome::Accepted);
    assert_eq!(
        ap.command(AutopilotCommand::SetMode(FlightMode::Offboard)),
        CommandOutcome::Accepted
    );
}

// ----- preflight: arming refused when the rotors cannot lift the true mass -------------------

#[test]
fn lockstep_refuses_to_arm_what_cannot_hover_and_says_why() {
    let quad = Airframe::load("quad").unwrap();
    let lift_kg = quad.max_thrust_n() / rotorpilot::signals::GRAVITY;
    let mut v = Sitl::quad().params(&[("SIM_MASS", real(10.0))]).build();
    for _ in 0..50 {
        v.step();
    }
    let _ = v.core_mut().drain_world_texts(0);
    let outcome = v.command(AutopilotCommand::Arm { force: false });
    assert!(matches!(outcome, CommandOutcome::Denied(_)), "{outcome:?}");
    assert!(!v.armed());
    let texts: Vec<String> = v.core_mut().drain_world_texts(0).into_iter().map(|t| t.text).collect();
    assert_eq!(
        texts,
        [format!("Preflight Fail: SIM_MASS 10.0 kg > lift {lift_kg:.1} kg")]
    );
    // forced arming skips the preflight checks, as PX4's
    assert_eq!(
        v.command(AutopilotCommand::Arm { force: true }),
        CommandOutcome::Accepted
    );

    // nominal mass: arms
    let mut v = Sitl::quad().build();
    for _ in 0..50 {
        v.step();
    }
    assert_eq!(
        v.command(AutopilotCommand::Arm { force: false }),
        CommandOutcome::Accepted
    );
}

#[test]
fn a_dead_rotor_takes_its_share_of_the_lift() {
    let quad = Airframe::load("quad").unwrap();
    let lift_kg = quad.max_thrust_n() / rotorpilot::signals::GRAVITY;
    let healthy = [RotorHealth::Healthy; 4];
    let one_dead = [
        RotorHealth::Off,
        RotorHealth::Healthy,
        RotorHealth::Healthy,
        RotorHealth::Healthy,
    ];
    let half = [
        RotorHealth::Degraded { thrust_fraction: 0.5 },
        RotorHealth::Healthy,
        RotorHealth::Healthy,
        RotorHealth::Healthy,
    ];
    let m = 0.8 * lift_kg;
    assert_eq!(unliftable(&quad, m, &healthy), None);
    assert_eq!(unliftable(&quad, m, &[]), None, "no fault list: all healthy");
    assert_eq!(unliftable(&quad, m, &half), None, "7/8 of the lift is enough");
    assert_eq!(
        unliftable(&quad, m, &one_dead),
        Some(format!(
            "Preflight Fail: SIM_MASS {m:.1} kg > lift {:.1} kg",
            0.75 * lift_kg
        ))
    );
    assert!(
        unliftable(&quad, lift_kg, &healthy).is_some(),
        "hover at full speed is no hover"
    );
    assert!(unliftable(&quad, quad.mass_kg, &healthy).is_none());
}

/// DO_REPOSITION without its change-mode flag (param2 = 0), as PX4 takes
/// it: the commander answers UNSUPPORTED whatever the state, and the
/// navigator moves the target of a Hold in force; on the ground or in
/// another mode nothing happens (no takeoff, no turn).
#[test]
fn reposition_without_change_mode_moves_a_hold_only_and_answers_unsupported() {
    let mut ap = Sitl::quad().build();
    let goal = Vector3::new(10.0, -5.0, -4.0);
    let to = |p: GeoPoint| AutopilotCommand::RepositionInHold {
        lat_deg: Some(p.lat_deg),
        lon_deg: Some(p.lon_deg),
        alt_amsl_m: Some(p.alt_amsl_m),
        yaw_rad: None,
        speed_m_s: None,
    };
    let away = to(HOME.offset(&goal));
    ap.step();
    // on the ground: no takeoff
    let rest = ap.telemetry().position_ned;
    assert_eq!(ap.command(away), CommandOutcome::Unsupported);
    ap.run(2.0);
    assert!(!ap.armed());
    assert!((ap.telemetry().position_ned - rest).norm() < 0.01);
    // holding in the air: the Hold moves there
    take_off(&mut ap);
    assert_eq!(ap.mode(), FlightMode::Hold);
    assert_eq!(ap.command(away), CommandOutcome::Unsupported);
    ap.run_until(30.0, |t| (t.position_ned - goal).norm() < 0.05)
        .expect("flies to the new Hold target");
    assert_eq!(ap.mode(), FlightMode::Hold);
    // landing: nothing changes
    assert_eq!(ap.command(AutopilotCommand::Land), CommandOutcome::Accepted);
    ap.run(0.5);
    let before = ap.telemetry().position_ned;
    assert_eq!(
        ap.command(to(HOME.offset(&Vector3::zeros()))),
        CommandOutcome::Unsupported
    );
    ap.run(3.0);
    let t = ap.telemetry();
    assert_eq!(t.mode, FlightMode::Land);
    assert!(
        (t.position_ned.xy() - before.xy()).norm() < 0.3,
        "{} -> {}",
        before,
        t.position_ned
    );
}

/// A far offboard position setpoint alone is flown at up to MPC_XY_VEL_MAX
/// (PX4's position controller's limit in Offboard), not at the cruise speed
/// of missions and repositions.
#[test]
fn offboard_position_alone_is_flown_up_to_mpc_xy_vel_max() {
    let mut ap = Sitl::quad().build();
    take_off(&mut ap);
    let goal = Vector3::new(150.0, 0.0, -5.0);
    ap.command(position_sp(goal, 0.0));
    assert_eq!(
        ap.command(AutopilotCommand::SetMode(FlightMode::Offboard)),
        CommandOutcome::Accepted
    );
    let every = ap.steps(0.05);
    let mut fastest: f64 = 0.0;
    for k in 0..ap.steps(25.0) {
        if k % every == 0 {
            ap.command(position_sp(goal, 0.0));
        }
        ap.step();
        fastest = fastest.max(ap.telemetry().velocity_ned.xy().norm());
    }
    // MPC_XY_CRUISE is 5 m/s, MPC_XY_VEL_MAX 12 m/s
    assert!(fastest > 11.0 && fastest < 12.5, "{fastest}");
    assert!(
        (ap.telemetry().position_ned - goal).norm() < 0.5,
        "{}",
        ap.telemetry().position_ned
    );
}
