//! Lockstep tests of Orbit (MAV_CMD_DO_ORBIT, mode POSCTL.ORBIT) as PX4's
//! Orbit task flies it: the vehicle flies to the circle, then goes round it
//! at the commanded radius, speed, direction, altitude and heading; what the
//! command leaves out keeps its value; a radius beyond PX4's limits is
//! refused; the mode cannot be armed in. One vehicle in the lockstep core,
//! simulated time only.

mod common;

use common::sitl::{Sitl, point};
use nalgebra::Vector3;
use rotorpilot::autopilot::{AutopilotCommand, CommandOutcome, FlightMode, OrbitYaw, Telemetry};
use rotorpilot::math::{euler_zyx, wrap_pi};

/// An orbit around `centre` (NED from home, horizontal) at `up` m above home.
fn orbit(radius_m: f64, speed: f64, yaw: Option<OrbitYaw>, centre: (f64, f64), up: f64) -> AutopilotCommand {
    let c = point(centre.0, centre.1, up);
    AutopilotCommand::Orbit {
        radius_m: Some(radius_m),
        velocity_m_s: Some(speed),
        yaw,
        lat_deg: Some(c.lat_deg),
        lon_deg: Some(c.lon_deg),
        alt_amsl_m: Some(c.alt_amsl_m),
    }
}

fn airborne() -> Sitl {
    let mut ap = Sitl::quad().build();
    ap.step();
    ap.take_off_to(None);
    ap
}

/// Angle [rad] of the vehicle around `centre`, from north towards east.
fn angle(t: &Telemetry, centre: (f64, f64)) -> f64 {
    (t.position_ned.y - centre.1).atan2(t.position_ned.x - centre.0)
}

fn distance(t: &Telemetry, centre: (f64, f64)) -> f64 {
    (t.position_ned.xy() - nalgebra::Vector2::new(centre.0, centre.1)).norm()
}

#[test]
fn flies_to_the_circle_then_round_it_clockwise_facing_the_centre() {
    let mut ap = airborne();
    let centre = (20.0, 10.0);
    assert_eq!(
        ap.command(orbit(10.0, 2.0, Some(OrbitYaw::FrontToCentre), centre, 8.0)),
        CommandOutcome::Accepted
    );
    assert_eq!(ap.telemetry().mode, FlightMode::Orbit);
    let status = ap.telemetry().orbit.expect("orbit status while orbiting");
    assert_eq!(status.radius_m, 10.0);
    assert!((status.centre.alt_amsl_m - point(0.0, 0.0, 8.0).alt_amsl_m).abs() < 1e-9);
    // reach the circle
    ap.run_until(60.0, |t| {
        (distance(t, centre) - 10.0).abs() < 0.5 && (t.position_ned.z + 8.0).abs() < 0.3
    })
    .expect("reaches the circle");
    ap.run(10.0);
    // one lap at 2 m/s is 2 pi 10 / 2 = 31.4 s; watch 30 s of it
    let mut swept = 0.0;
    let mut last = angle(&ap.telemetry(), centre);
    let (mut worst_r, mut worst_z, mut worst_yaw, mut worst_v) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for _ in 0..300 {
        ap.run(0.1);
        let t = ap.telemetry();
        let a = angle(&t, centre);
        swept += wrap_pi(a - last);
        last = a;
        worst_r = worst_r.max((distance(&t, centre) - 10.0).abs());
        worst_z = worst_z.max((t.position_ned.z + 8.0).abs());
        worst_v = worst_v.max((t.velocity_ned.xy().norm() - 2.0).abs());
        // front to the centre: heading = angle + pi
        worst_yaw = worst_yaw.max(wrap_pi(euler_zyx(&t.attitude).z - (a + std::f64::consts::PI)).abs());
    }
    // clockwise seen from above is north -> east: the angle grows
    assert!(
        swept > 5.6 && swept < 6.4,
        "swept {swept} rad in 30 s (2 pi 30/31.4 = 6.0)"
    );
    assert!(worst_r < 0.3, "radius error {worst_r} m");
    assert!(worst_z < 0.2, "altitude error {worst_z} m");
    assert!(worst_v < 0.15, "speed error {worst_v} m/s");
    assert!(
        worst_yaw < 3f64.to_radians(),
        "heading error {} deg",
        worst_yaw.to_degrees()
    );
}

#[test]
fn a_negative_radius_turns_the_other_way_and_a_command_keeps_what_it_leaves_out() {
    let mut ap = airborne();
    let centre = (0.0, 15.0);
    ap.command(orbit(-8.0, 3.0, Some(OrbitYaw::FrontTangent), centre, 5.0));
    ap.run_until(60.0, |t| (distance(t, centre) - 8.0).abs() < 0.5).unwrap();
    ap.run(8.0);
    let a0 = angle(&ap.telemetry(), centre);
    ap.run(2.0);
    let t = ap.telemetry();
    let turned = wrap_pi(angle(&t, centre) - a0);
    assert!(turned < -0.5, "counter-clockwise: {turned} rad in 2 s (3/8 rad/s)");
    // the nose points along the flight path
    let course = t.velocity_ned.y.atan2(t.velocity_ned.x);
    assert!(wrap_pi(euler_zyx(&t.attitude).z - course).abs() < 5f64.to_radians());
    assert_eq!(t.orbit.unwrap().radius_m, -8.0);
    // only a new speed: radius, direction, centre and altitude stay
    let speed_only = AutopilotCommand::Orbit {
        radius_m: None,
        velocity_m_s: Some(1.0),
        yaw: None,
        lat_deg: None,
        lon_deg: None,
        alt_amsl_m: None,
    };
    assert_eq!(ap.command(speed_only), CommandOutcome::Accepted);
    ap.run(10.0);
    let t = ap.telemetry();
    assert!(
        (t.velocity_ned.xy().norm() - 1.0).abs() < 0.1,
        "{}",
        t.velocity_ned.xy().norm()
    );
    assert!((distance(&t, centre) - 8.0).abs() < 0.3);
    assert_eq!(t.orbit.unwrap().radius_m, -8.0);
    assert_eq!(t.orbit.unwrap().yaw, OrbitYaw::FrontTangent);
}

#[test]
fn the_speed_is_kept_under_the_centripetal_limit() {
    let mut ap = airborne();
    // 10 m/s on 5 m is 20 m/s^2: PX4 lowers it to sqrt(2 * 5) = 3.16 m/s
    ap.command(orbit(5.0, 10.0, None, (10.0, 0.0), 5.0));
    ap.run(40.0);
    let v = ap.telemetry().velocity_ned.xy().norm();
    assert!((v - 10f64.sqrt()).abs() < 0.15, "{v}");
}

#[test]
fn refusals() {
    let mut ap = airborne();
    for r in [0.5, 1500.0] {
        assert_eq!(
            ap.command(orbit(r, 2.0, None, (10.0, 0.0), 5.0)),
            CommandOutcome::Denied("orbit radius out of range")
        );
        assert!(ap.texts().iter().any(|s| s.text == "Orbit radius limit exceeded"));
        assert_eq!(ap.telemetry().mode, FlightMode::Hold, "a refused orbit changes nothing");
    }
    let nan = AutopilotCommand::Orbit {
        radius_m: Some(f64::NAN),
        velocity_m_s: None,
        yaw: None,
        lat_deg: None,
        lon_deg: None,
        alt_amsl_m: None,
    };
    assert!(matches!(ap.command(nan), CommandOutcome::Denied(_)));
    // the mode may be selected on the ground, but not armed in (PX4)
    let mut ground = Sitl::quad().build();
    ground.step();
    assert_eq!(
        ground.command(AutopilotCommand::SetMode(FlightMode::Orbit)),
        CommandOutcome::Accepted
    );
    assert_eq!(
        ground.command(AutopilotCommand::Arm { force: false }),
        CommandOutcome::TemporarilyRejected("flight mode not armable")
    );
}

#[test]
fn the_mode_alone_circles_where_it_is_and_another_mode_takes_over_smoothly() {
    let mut ap = airborne();
    let here = ap.telemetry().position_ned;
    assert_eq!(
        ap.command(AutopilotCommand::SetMode(FlightMode::Orbit)),
        CommandOutcome::Accepted
    );
    ap.run(10.0);
    let t = ap.telemetry();
    // PX4's placeholder: 1 m radius, centre 1 m south of where it was
    let centre = Vector3::new(here.x - 1.0, here.y, here.z);
    assert!(((t.position_ned - centre).xy().norm() - 1.0).abs() < 0.2);
    assert_eq!(t.orbit.unwrap().radius_m, 1.0);
    assert_eq!(
        ap.command(AutopilotCommand::SetMode(FlightMode::Hold)),
        CommandOutcome::Accepted
    );
    assert!(ap.telemetry().orbit.is_none());
    ap.run(5.0);
    let t = ap.telemetry();
    assert!(t.velocity_ned.norm() < 0.05 && (t.position_ned - centre).norm() < 2.0);
}
