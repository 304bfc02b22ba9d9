//! Lockstep tests of follow-me (AUTO.FOLLOW_TARGET with FOLLOW_TARGET fixes)
//! as PX4's follow-target task flies it: the vehicle climbs to `FLW_TGT_HT`,
//! then flies `FLW_TGT_DST` from a moving target at `FLW_TGT_FA` from its
//! course (behind by default), its nose to the target; with the fixes gone
//! for 3 s it holds where it is; the mode cannot be armed in. One vehicle in
//! the lockstep core, simulated time only; fixes come at 5 Hz, as a phone's
//! GPS would give them.

mod common;

use common::sitl::{Sitl, int, point, real};
use nalgebra::{Vector2, Vector3};
use rotorpilot::autopilot::{AutopilotCommand, CommandOutcome, FlightMode, ManualControl, TargetFix, Telemetry};
use rotorpilot::math::{euler_zyx, wrap_pi};
use rotorpilot::params::ParamValue;

/// A fix of a target at `north`, `east` [m] from home on the ground, moving at `v` [m/s] NED.
fn fix(north: f64, east: f64, v: Option<Vector3<f64>>) -> AutopilotCommand {
    let p = point(north, east, 0.0);
    AutopilotCommand::FollowTarget(TargetFix {
        lat_deg: p.lat_deg,
        lon_deg: p.lon_deg,
        alt_amsl_m: p.alt_amsl_m,
        velocity_ned: v,
    })
}

fn airborne(params: &[(&str, ParamValue)]) -> Sitl {
    let mut ap = Sitl::quad().params(params).build();
    ap.step();
    ap.take_off_to(None);
    ap
}

/// Fly `seconds` with the target at `start` + `v t` (t from `t0`), a fix
/// every 0.2 s (`with_velocity`: the fix carries it); the target's position now.
fn chase(
    ap: &mut Sitl,
    seconds: f64,
    t0: f64,
    start: Vector2<f64>,
    v: Vector2<f64>,
    with_velocity: bool,
) -> Vector2<f64> {
    let every = (0.2 / ap.dt_s()).round() as usize;
    let n = ap.steps(seconds);
    for k in 0..n {
        if k % every == 0 {
            let at = start + v * (ap.time_s() - t0);
            let vel = with_velocity.then(|| Vector3::new(v.x, v.y, 0.0));
            assert_eq!(ap.command(fix(at.x, at.y, vel)), CommandOutcome::Accepted);
        }
        ap.step();
    }
    start + v * (ap.time_s() - t0)
}

fn height(t: &Telemetry) -> f64 {
    t.home_ned.z - t.position_ned.z
}

/// Bearing [rad] of the vehicle seen from the target, from north towards east.
fn bearing_from(target: Vector2<f64>, t: &Telemetry) -> f64 {
    let d = t.position_ned.xy() - target;
    d.y.atan2(d.x)
}

/// GIVEN a hovering quad with PX4's defaults (8 m behind, 8 m high)
/// WHEN it is switched to AUTO.FOLLOW_TARGET and a target 10 m north walks
/// east at 2 m/s, its fixes carrying its velocity
/// THEN after the climb and the catch-up it flies 8 m behind it (west),
/// 8 m above home, its nose on the target, and keeps pace.
#[test]
fn follows_a_moving_target_from_behind_at_distance_and_height() {
    let mut ap = airborne(&[]);
    let t0 = ap.time_s();
    let start = Vector2::new(10.0, 0.0);
    let v = Vector2::new(0.0, 2.0);
    assert_eq!(
        ap.command(fix(start.x, start.y, Some(Vector3::zeros()))),
        CommandOutcome::Accepted
    );
    assert_eq!(
        ap.command(AutopilotCommand::SetMode(FlightMode::FollowTarget)),
        CommandOutcome::Accepted
    );
    assert_eq!(ap.mode(), FlightMode::FollowTarget);
    chase(&mut ap, 30.0, t0, start, v, true);
    let mut worst: f64 = 0.0;
    for _ in 0..10 {
        let target = chase(&mut ap, 1.0, t0, start, v, true);
        let t = ap.telemetry();
        let d = (t.position_ned.xy() - target).norm();
        worst = worst.max((d - 8.0).abs());
        assert!((height(&t) - 8.0).abs() < 0.3, "height {}", height(&t));
        // behind: the course is east, so the vehicle is west of the target
        let behind = wrap_pi(bearing_from(target, &t) - (-std::f64::consts::FRAC_PI_2));
        assert!(
            behind.abs() < 10f64.to_radians(),
            "bearing off by {} deg",
            behind.to_degrees()
        );
        let yaw = euler_zyx(&t.attitude).z;
        assert!(
            wrap_pi(yaw - std::f64::consts::FRAC_PI_2).abs() < 10f64.to_radians(),
            "yaw {yaw}"
        );
        assert!((t.velocity_ned.xy() - v).norm() < 0.3, "speed {}", t.velocity_ned);
    }
    assert!(worst < 1.0, "distance off by {worst} m");
    assert_eq!(ap.mode(), FlightMode::FollowTarget);
}

/// GIVEN FLW_TGT_FA 90 (the target's right), FLW_TGT_DST 5, FLW_TGT_HT 12
/// WHEN the target walks north at 1.5 m/s with position-only fixes
/// THEN the vehicle flies 5 m east of it (its right), 12 m up.
#[test]
fn angle_distance_and_height_are_the_parameters() {
    let mut ap = airborne(&[
        ("FLW_TGT_FA", real(90.0)),
        ("FLW_TGT_DST", real(5.0)),
        ("FLW_TGT_HT", real(12.0)),
    ]);
    let t0 = ap.time_s();
    let start = Vector2::new(0.0, -6.0);
    let v = Vector2::new(1.5, 0.0);
    chase(&mut ap, 0.5, t0, start, v, false);
    assert_eq!(
        ap.command(AutopilotCommand::SetMode(FlightMode::FollowTarget)),
        CommandOutcome::Accepted
    );
    let target = chase(&mut ap, 40.0, t0, start, v, false);
    let t = ap.telemetry();
    let d = t.position_ned.xy() - target;
    assert!((d.norm() - 5.0).abs() < 1.0, "distance {}", d.norm());
    assert!(d.y > 4.0 && d.x.abs() < 1.5, "not on the right: {d}");
    assert!((height(&t) - 12.0).abs() < 0.3, "height {}", height(&t));
}

/// GIVEN a vehicle following a walking target
/// WHEN the fixes stop
/// THEN it flies on the prediction for up to 3 s, then holds where it is
/// (still in AUTO.FOLLOW_TARGET), and picks the target up again when fixes
/// return.
#[test]
fn holds_when_the_target_is_lost_and_resumes_when_it_returns() {
    let mut ap = airborne(&[]);
    let t0 = ap.time_s();
    let start = Vector2::new(10.0, 0.0);
    let v = Vector2::new(0.0, 2.0);
    chase(&mut ap, 0.2, t0, start, v, true);
    assert_eq!(
        ap.command(AutopilotCommand::SetMode(FlightMode::FollowTarget)),
        CommandOutcome::Accepted
    );
    chase(&mut ap, 30.0, t0, start, v, true);
    // fixes stop: after the prediction runs out (3 s) and a brake, it holds
    ap.run(8.0);
    let here = ap.telemetry().position_ned;
    ap.run(5.0);
    let t = ap.telemetry();
    assert!(
        (t.position_ned - here).norm() < 0.2,
        "drifted {}",
        (t.position_ned - here).norm()
    );
    assert!(t.velocity_ned.norm() < 0.1);
    assert_eq!(t.mode, FlightMode::FollowTarget);
    // fixes again: it catches up behind the target
    let target = chase(&mut ap, 40.0, t0, start, v, true);
    let t = ap.telemetry();
    assert!(((t.position_ned.xy() - target).norm() - 8.0).abs() < 1.0);
}

/// GIVEN a quad on the ground
/// WHEN AUTO.FOLLOW_TARGET is selected
/// THEN it is accepted but arming in it is refused (PX4: not armable), and
/// a fix that is not finite or off the globe is DENIED.
#[test]
fn the_mode_is_not_armable_and_bad_fixes_are_denied() {
    let mut ap = Sitl::quad().params(&[("FLW_TGT_ALT_M", int(0))]).build();
    ap.run(3.0);
    assert_eq!(
        ap.command(AutopilotCommand::SetMode(FlightMode::FollowTarget)),
        CommandOutcome::Accepted
    );
    assert_eq!(
        ap.command(AutopilotCommand::Arm { force: false }),
        CommandOutcome::TemporarilyRejected("flight mode not armable")
    );
    for bad in [
        TargetFix {
            lat_deg: f64::NAN,
            lon_deg: 8.0,
            alt_amsl_m: 500.0,
            velocity_ned: None,
        },
        TargetFix {
            lat_deg: 47.0,
            lon_deg: 181.0,
            alt_amsl_m: 500.0,
            velocity_ned: None,
        },
    ] {
        assert!(matches!(
            ap.command(AutopilotCommand::FollowTarget(bad)),
            CommandOutcome::Denied(_)
        ));
    }
}

/// GIVEN a hovering quad in FLW_TGT_ALT_M 2 (track the target's altitude),
/// FLW_TGT_HT 8, and a still target 8 m below home (MAVSDK's
/// `follow_me_example.py` sends 480 m AMSL over a 488 m home)
/// WHEN it follows: the height it is asked for is the ground
/// THEN it comes down only to PX4's safety altitude (1 m above the ground,
/// `MINIMUM_SAFETY_ALTITUDE`), climbs back at 0.5 m/s whenever below it,
/// and so never lands: still armed, still in AUTO.FOLLOW_TARGET.
#[test]
fn a_target_below_the_ground_brings_it_down_to_the_safety_altitude_not_to_land() {
    let mut ap = airborne(&[("FLW_TGT_ALT_M", int(2)), ("FLW_TGT_HT", real(8.0))]);
    let below = point(10.0, 0.0, -8.0);
    let send = |ap: &mut Sitl| {
        let f = AutopilotCommand::FollowTarget(TargetFix {
            lat_deg: below.lat_deg,
            lon_deg: below.lon_deg,
            alt_amsl_m: below.alt_amsl_m,
            velocity_ned: Some(Vector3::zeros()),
        });
        assert_eq!(ap.command(f), CommandOutcome::Accepted);
    };
    send(&mut ap);
    assert_eq!(
        ap.command(AutopilotCommand::SetMode(FlightMode::FollowTarget)),
        CommandOutcome::Accepted
    );
    let mut lowest = f64::INFINITY;
    for _ in 0..150 {
        send(&mut ap);
        let every = ap.steps(0.2);
        for _ in 0..every {
            ap.step();
            let t = ap.telemetry();
            lowest = lowest.min(height(&t));
        }
    }
    let t = ap.telemetry();
    assert!(ap.armed(), "landed and disarmed");
    assert_eq!(ap.mode(), FlightMode::FollowTarget);
    assert!(lowest > 0.5, "came down to {lowest} m");
    assert!((height(&t) - 1.0).abs() < 0.5, "height {}", height(&t));
}

/// Fly `seconds` holding `sticks` (sent at 50 Hz, as PX4's test sends
/// them) with a still target at `target`, a fix every 0.2 s.
fn hold_sticks(ap: &mut Sitl, seconds: f64, target: Vector2<f64>, sticks: ManualControl) {
    let (fix_every, stick_every) = ((0.2 / ap.dt_s()).round() as usize, (0.02 / ap.dt_s()).round() as usize);
    for k in 0..ap.steps(seconds) {
        if k % fix_every == 0 {
            assert_eq!(
                ap.command(fix(target.x, target.y, Some(Vector3::zeros()))),
                CommandOutcome::Accepted
            );
        }
        if k % stick_every == 0 {
            assert_eq!(
                ap.command(AutopilotCommand::ManualControl(sticks)),
                CommandOutcome::Accepted
            );
        }
        ap.step();
    }
}

/// Sticks held at `pitch`, `roll`, `throttle` (yaw centred).
fn sticks(pitch: f64, roll: f64, throttle: f64) -> ManualControl {
    ManualControl {
        pitch,
        roll,
        throttle,
        yaw: 0.0,
    }
}

/// Switch to AUTO.FOLLOW_TARGET with a still target at `target` and follow
/// it for 25 s, the sticks centred, until the vehicle has settled.
fn follow_still_target(ap: &mut Sitl, target: Vector2<f64>) {
    hold_sticks(ap, 0.2, target, ManualControl::CENTRED);
    assert_eq!(
        ap.command(AutopilotCommand::SetMode(FlightMode::FollowTarget)),
        CommandOutcome::Accepted
    );
    hold_sticks(ap, 25.0, target, ManualControl::CENTRED);
}

/// GIVEN a quad following a still target from 10 m in front, 10 m high
/// (PX4's "Follow target - RC Adjustment" case: `FLW_TGT_FA` 0), the
/// sticks centred
/// WHEN full throttle is held for 3 s, then full pitch forward, then full
/// roll right, each followed by centred sticks until the vehicle settles
/// THEN the follow height grows, at most by its 1.5 m/s for those 3 s and
/// at least by the half of it that PX4's test asks for; the distance the
/// same with 2 m/s; the angle clockwise, at most by `FLW_TGT_MAX_VEL / d`
/// (5 m/s over some 15 m: 0.33 rad/s); and centred sticks then hold the
/// geometry the sticks made.
#[test]
fn the_sticks_move_the_follow_height_distance_and_angle() {
    let mut ap = airborne(&[
        ("FLW_TGT_DST", real(10.0)),
        ("FLW_TGT_HT", real(10.0)),
        ("FLW_TGT_FA", real(0.0)),
    ]);
    let target = ap.telemetry().position_ned.xy();
    follow_still_target(&mut ap, target);
    // (height above home, distance from the target, bearing from it clockwise from north)
    let at = |ap: &mut Sitl| {
        let t = ap.telemetry();
        let d = t.position_ned.xy() - target;
        (height(&t), d.norm(), d.y.atan2(d.x))
    };
    // `held` for 3 s, then centred sticks for 8 s, until the vehicle settles
    let after = |ap: &mut Sitl, held: ManualControl| {
        hold_sticks(ap, 3.0, target, held);
        hold_sticks(ap, 8.0, target, ManualControl::CENTRED);
        at(ap)
    };
    let (h0, d0, a0) = at(&mut ap);
    assert!(
        (h0 - 10.0).abs() < 0.3 && (d0 - 10.0).abs() < 0.5 && a0.abs() < 0.1,
        "{h0} m high, {d0} m away, at {a0} rad"
    );

    let (h1, d1, a1) = after(&mut ap, sticks(0.0, 0.0, 1.0));
    assert!(h1 - h0 > 2.25 && h1 - h0 < 4.5 + 0.1, "climbed {} m", h1 - h0);
    assert!(
        (d1 - d0).abs() < 0.3 && wrap_pi(a1 - a0).abs() < 0.05,
        "throttle moved more than the height"
    );

    let (h2, d2, a2) = after(&mut ap, sticks(1.0, 0.0, 0.0));
    assert!(d2 - d1 > 3.0 && d2 - d1 < 6.0 + 0.1, "moved out {} m", d2 - d1);
    assert!(
        (h2 - h1).abs() < 0.3 && wrap_pi(a2 - a1).abs() < 0.05,
        "pitch moved more than the distance"
    );

    let (h3, d3, a3) = after(&mut ap, sticks(0.0, 1.0, 0.0));
    let most = 5.0 / d2 * 3.0;
    let turned = wrap_pi(a3 - a2);
    assert!(
        turned > most / 2.0 && turned < most + 0.05,
        "turned {turned} rad clockwise, at most {most}"
    );
    assert!(
        (h3 - h2).abs() < 0.3 && (d3 - d2).abs() < 0.3,
        "roll moved more than the angle"
    );

    // centred sticks hold what the sticks made
    hold_sticks(&mut ap, 10.0, target, ManualControl::CENTRED);
    let (h4, d4, a4) = at(&mut ap);
    assert!((h4 - h3).abs() < 0.1 && (d4 - d3).abs() < 0.1 && wrap_pi(a4 - a3).abs() < 0.01);
    assert_eq!(ap.mode(), FlightMode::FollowTarget);
}

/// GIVEN a quad following a still target 10 m away, 10 m high
/// WHEN one MANUAL_CONTROL at full throttle comes, and no other
/// THEN the height grows only while those sticks are fresh (`COM_RC_LOSS_T`,
/// 0.5 s: PX4 zeroes sticks whose signal is lost), some 0.75 m at most.
#[test]
fn sticks_that_stop_coming_stop_moving_the_geometry() {
    let mut ap = airborne(&[("FLW_TGT_DST", real(10.0)), ("FLW_TGT_HT", real(10.0))]);
    let target = ap.telemetry().position_ned.xy() + Vector2::new(10.0, 0.0);
    follow_still_target(&mut ap, target);
    let h0 = height(&ap.telemetry());
    assert_eq!(
        ap.command(AutopilotCommand::ManualControl(sticks(0.0, 0.0, 1.0))),
        CommandOutcome::Accepted
    );
    let now = ap.time_s();
    chase(&mut ap, 15.0, now, target, Vector2::zeros(), true);
    let climbed = height(&ap.telemetry()) - h0;
    assert!(climbed > 0.2 && climbed < 0.75 + 0.05, "climbed {climbed} m");
}

/// GIVEN a quad following a still target, with the client timers on the
/// wall clock (the daemon above `--speed 1`)
/// WHEN one MANUAL_CONTROL at full throttle comes, and no other
/// THEN the sticks' loss timer runs in Follow target too, and once the
/// runtime says it ran out the height stops growing, without a failsafe
/// (the mode stays, nothing is announced: `NAV_RCL_ACT` is for the manual
/// modes).
#[test]
fn on_the_wall_clock_the_runtimes_stick_loss_stops_the_sticks_in_follow() {
    use rotorpilot::autopilot::{ClientClock, ClientTimer};
    let mut ap = airborne(&[("FLW_TGT_DST", real(10.0)), ("FLW_TGT_HT", real(10.0))]);
    ap.pilot_mut().set_client_clock(ClientClock::Wall);
    let target = ap.telemetry().position_ned.xy() + Vector2::new(10.0, 0.0);
    follow_still_target(&mut ap, target);
    assert_eq!(
        ap.command(AutopilotCommand::ManualControl(sticks(0.0, 0.0, 1.0))),
        CommandOutcome::Accepted
    );
    let sent = ap.time_s();
    chase(&mut ap, 3.0, sent, target, Vector2::zeros(), true);
    let timer = ap
        .pilot()
        .client_timers()
        .into_iter()
        .find(|p| p.timer == ClientTimer::ManualControlLoss)
        .expect("the sticks' loss timer runs in Follow target");
    assert_eq!(timer.started_s, sent);
    assert!(
        height(&ap.telemetry()) > 11.0,
        "the stick, still in force, raised the height"
    );
    ap.core_mut().client_timeout(0, ClientTimer::ManualControlLoss, sent);
    let h = height(&ap.telemetry());
    let now = ap.time_s();
    chase(&mut ap, 10.0, now, target, Vector2::zeros(), true);
    assert!(height(&ap.telemetry()) - h < 1.0, "climbed on after the loss");
    assert_eq!(ap.mode(), FlightMode::FollowTarget);
}
