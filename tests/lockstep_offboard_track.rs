//! Lockstep test of offboard position setpoints that carry their velocity
//! and acceleration (one SET_POSITION_TARGET_LOCAL_NED with all three, as
//! MAVSDK's `set_position_velocity_acceleration_ned` sends them): the
//! velocity and acceleration are feed-forward to the position, as PX4's
//! trajectory setpoint, so a time-stamped path is flown in time. One vehicle
//! in the lockstep core, simulated time only.

mod common;

use common::sitl::Sitl;
use nalgebra::Vector3;
use rotorpilot::autopilot::{AutopilotCommand, CommandOutcome, FlightMode, OffboardSetpoint, Targets};

/// The path: a circle of radius 10 m at 1.5 m/s, 5 m up, starting at the
/// vehicle's hover point and going round anticlockwise seen from above.
fn path(t: f64, centre: Vector3<f64>) -> (Vector3<f64>, Vector3<f64>, Vector3<f64>) {
    let (r, v) = (10.0, 1.5);
    let w = v / r;
    let phi = std::f64::consts::PI + w * t;
    let (s, c) = phi.sin_cos();
    (
        centre + Vector3::new(r * c, r * s, 0.0),
        Vector3::new(-r * w * s, r * w * c, 0.0),
        Vector3::new(-r * w * w * c, -r * w * w * s, 0.0),
    )
}

fn setpoint(p: Vector3<f64>, v: Option<Vector3<f64>>, a: Option<Vector3<f64>>) -> AutopilotCommand {
    AutopilotCommand::Offboard(OffboardSetpoint::Local(Targets {
        position: Some(p),
        velocity: v,
        acceleration: a,
        yaw_rad: Some(0.0),
        yaw_rate_rad_s: None,
    }))
}

/// Fly the path for `seconds` with setpoints at 10 Hz (position, plus the
/// velocity and acceleration when `feed_forward`); the largest and the last
/// distance [m] between the vehicle and where the path is at that instant,
/// after the first 10 s (the start from a hover is a transient).
fn fly(feed_forward: bool, seconds: f64) -> (f64, f64) {
    let mut ap = Sitl::quad().build();
    ap.step();
    ap.take_off_to(Some(5.0));
    let start = ap.telemetry().position_ned;
    let centre = start + Vector3::new(10.0, 0.0, 0.0);
    let every = ap.steps(0.1);
    let t0 = ap.time_s();
    let (mut worst, mut last): (f64, f64) = (0.0, 0.0);
    for k in 0..ap.steps(seconds) {
        let t = ap.time_s() - t0;
        if k % every == 0 {
            let (p, v, a) = path(t, centre);
            let sp = if feed_forward {
                setpoint(p, Some(v), Some(a))
            } else {
                setpoint(p, None, None)
            };
            assert_eq!(ap.command(sp), CommandOutcome::Accepted);
            if k == 0 {
                assert_eq!(
                    ap.command(AutopilotCommand::SetMode(FlightMode::Offboard)),
                    CommandOutcome::Accepted
                );
            }
        }
        ap.step();
        let error = (ap.telemetry().position_ned - path(ap.time_s() - t0, centre).0).norm();
        if ap.time_s() - t0 > 10.0 {
            worst = worst.max(error);
        }
        last = error;
    }
    (worst, last)
}

/// GIVEN a hovering quad in Offboard
/// WHEN a circle of 10 m at 1.5 m/s is streamed at 10 Hz as position,
/// velocity and acceleration together
/// THEN the vehicle is never more than 0.15 m from where the path is at that
/// instant (after the first 10 s), while position alone trails by metres.
#[test]
fn position_with_velocity_and_acceleration_tracks_a_timed_path() {
    let (worst, last) = fly(true, 40.0);
    let (worst_bare, last_bare) = fly(false, 40.0);
    println!(
        "tracking error with feed-forward: max {worst:.3} m, last {last:.3} m; position only: max {worst_bare:.3} m, last {last_bare:.3} m"
    );
    assert!(worst < 0.15, "max error {worst} m");
    assert!(last < 0.15, "last error {last} m");
    assert!(last_bare > 1.0, "position alone trails: {last_bare} m");
}

/// GIVEN a hovering quad in Offboard
/// WHEN it is sent, for 20 s, a fixed position 20 m north with a constant
/// 1 m/s north velocity (MAVSDK's `offboard_position_velocity_ned.py` does so)
/// THEN it settles where PX4's position controller does, `v_sp / MPC_XY_P`
/// = 1.05 m past the point (`v = v_sp + MPC_XY_P (p_sp - p)` is zero there),
/// within 0.1 m.
#[test]
fn a_constant_feed_forward_settles_past_the_point_as_on_px4() {
    let mut ap = Sitl::quad().build();
    ap.step();
    ap.take_off_to(Some(5.0));
    let start = ap.telemetry().position_ned;
    let target = start + Vector3::new(20.0, 0.0, 0.0);
    let sp = setpoint(target, Some(Vector3::new(1.0, 0.0, 0.0)), None);
    let every = ap.steps(0.1);
    for k in 0..ap.steps(20.0) {
        if k % every == 0 {
            assert_eq!(ap.command(sp), CommandOutcome::Accepted);
            if k == 0 {
                assert_eq!(
                    ap.command(AutopilotCommand::SetMode(FlightMode::Offboard)),
                    CommandOutcome::Accepted
                );
            }
        }
        ap.step();
    }
    let past = ap.telemetry().position_ned.x - target.x;
    println!("settled {past:.3} m past the point (PX4: 1 / 0.95 = 1.053 m)");
    assert!((past - 1.0 / 0.95).abs() < 0.1, "{past} m past");
}
