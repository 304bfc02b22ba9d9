//! Lockstep tests of the vertical speeds of the automatic modes, as PX4
//! flies them (FlightTaskAuto::_updateTrajConstraints): a takeoff climbs at
//! MPC_TKO_SPEED below MPC_LAND_ALT1 above home and at MPC_Z_V_AUTO_UP above
//! it; the other automatic climbs and descents (a reposition here) at
//! MPC_Z_V_AUTO_UP / MPC_Z_V_AUTO_DN, each at most MPC_Z_VEL_MAX_UP / _DN;
//! a landing descends at MPC_Z_VEL_MAX_DN above MPC_LAND_ALT1, slowing
//! linearly to MPC_LAND_SPEED at MPC_LAND_ALT2 (FlightTaskAuto::_prepareLandSetpoints).
//! One quad in the lockstep core, simulated time only.

mod common;

use common::sitl::{Sitl, real};
use rotorpilot::autopilot::{AutopilotCommand, CommandOutcome, FlightMode, Telemetry};

/// Height of the centre of mass above home [m].
fn height(t: &Telemetry) -> f64 {
    t.global.alt_amsl_m - t.home.alt_amsl_m
}

/// The largest climb speed [m/s] seen in each band of height [m] (`bands`:
/// `(from, to)`), and the time [s] from the command to within 0.25 m of `up_m`.
struct Climb {
    peak_m_s: Vec<f64>,
    took_s: f64,
}

/// Arm, take off to `up_m` above home and watch the climb until the takeoff completes.
fn climb(ap: &mut Sitl, up_m: f64, bands: &[(f64, f64)]) -> Climb {
    ap.step();
    let home_alt_amsl_m = ap.telemetry().home.alt_amsl_m;
    assert_eq!(
        ap.command(AutopilotCommand::Arm { force: false }),
        CommandOutcome::Accepted
    );
    assert_eq!(
        ap.command(AutopilotCommand::Takeoff {
            altitude_amsl_m: Some(home_alt_amsl_m + up_m)
        }),
        CommandOutcome::Accepted
    );
    let t0 = ap.time_s();
    let mut peak_m_s = vec![0.0_f64; bands.len()];
    let mut reached = None;
    let mut taking_off = false;
    ap.run_until(120.0, |t| {
        let h = height(t);
        for (peak, (lo, hi)) in peak_m_s.iter_mut().zip(bands) {
            if h >= *lo && h < *hi {
                *peak = peak.max(-t.velocity_ned.z);
            }
        }
        if reached.is_none() && (h - up_m).abs() < 0.25 {
            reached = Some(t.time_s);
        }
        taking_off |= t.mode == FlightMode::Takeoff;
        taking_off && t.mode == FlightMode::Hold
    })
    .expect("takeoff completes");
    Climb {
        peak_m_s,
        took_s: reached.expect("reached") - t0,
    }
}

#[test]
fn takeoff_to_40_m_climbs_at_mpc_tko_speed_then_at_mpc_z_v_auto_up() {
    let mut ap = Sitl::quad().build();
    let c = climb(&mut ap, 40.0, &[(0.0, 10.0), (15.0, 35.0)]);
    // PX4's defaults: 1.5 m/s up to MPC_LAND_ALT1 (10 m), 3 m/s above
    assert!(c.peak_m_s[0] < 1.5 * 1.03, "below 10 m: {:.3} m/s", c.peak_m_s[0]);
    assert!(
        (c.peak_m_s[1] - 3.0).abs() < 0.1,
        "above 15 m: {:.3} m/s",
        c.peak_m_s[1]
    );
    // 10 m at 1.5 m/s and 30 m at 3 m/s: 16.7 s and the ramps (40 m at
    // 1.5 m/s all the way would be 26.7 s)
    assert!(c.took_s > 16.7 && c.took_s < 21.0, "40 m in {:.2} s", c.took_s);
    let t = ap.telemetry();
    assert!((height(&t) - 40.0).abs() < 0.25, "{}", height(&t));
}

#[test]
fn takeoff_to_mpc_land_alt1_climbs_at_mpc_tko_speed_all_the_way() {
    let mut ap = Sitl::quad().build();
    let c = climb(&mut ap, 10.0, &[(0.0, 11.0)]);
    assert!(c.peak_m_s[0] < 1.5 * 1.03, "{:.3} m/s", c.peak_m_s[0]);
    assert!(c.took_s > 10.0 / 1.5, "{:.2} s", c.took_s);
}

#[test]
fn takeoff_speeds_and_height_follow_the_parameters() {
    let mut ap = Sitl::quad()
        .params(&[
            ("MPC_TKO_SPEED", real(1.0)),
            ("MPC_LAND_ALT1", real(5.0)),
            ("MPC_Z_V_AUTO_UP", real(2.0)),
        ])
        .build();
    let c = climb(&mut ap, 25.0, &[(0.0, 5.0), (8.0, 22.0)]);
    assert!(c.peak_m_s[0] < 1.0 * 1.03, "below 5 m: {:.3} m/s", c.peak_m_s[0]);
    assert!(
        (c.peak_m_s[1] - 2.0).abs() < 0.07,
        "above 8 m: {:.3} m/s",
        c.peak_m_s[1]
    );
    // MPC_Z_V_AUTO_UP above MPC_Z_VEL_MAX_UP is held to it (PX4's MulticopterPositionControl)
    let mut ap = Sitl::quad()
        .params(&[("MPC_Z_VEL_MAX_UP", real(2.5)), ("MPC_Z_V_AUTO_UP", real(6.0))])
        .build();
    let c = climb(&mut ap, 30.0, &[(15.0, 25.0)]);
    assert!((c.peak_m_s[0] - 2.5).abs() < 0.08, "{:.3} m/s", c.peak_m_s[0]);
}

#[test]
fn a_reposition_climbs_at_mpc_z_v_auto_up_and_descends_at_mpc_z_v_auto_dn() {
    let mut ap = Sitl::quad()
        .params(&[("MPC_Z_V_AUTO_UP", real(2.0)), ("MPC_Z_V_AUTO_DN", real(1.0))])
        .build();
    ap.step();
    let home_alt_amsl_m = ap.telemetry().home.alt_amsl_m;
    ap.take_off_to(Some(5.0));
    let to = |ap: &mut Sitl, up_m: f64| {
        assert_eq!(
            ap.command(AutopilotCommand::Reposition {
                lat_deg: None,
                lon_deg: None,
                alt_amsl_m: Some(home_alt_amsl_m + up_m),
                yaw_rad: None,
                speed_m_s: None,
            }),
            CommandOutcome::Accepted
        );
        let (mut up, mut down) = (0.0_f64, 0.0_f64);
        ap.run_until(60.0, |t| {
            up = up.max(-t.velocity_ned.z);
            down = down.max(t.velocity_ned.z);
            (height(t) - up_m).abs() < 0.02 && t.velocity_ned.norm() < 0.02
        })
        .expect("arrives");
        (up, down)
    };
    let (up, _) = to(&mut ap, 35.0);
    assert!((up - 2.0).abs() < 0.06, "climb {up:.3} m/s");
    let (_, down) = to(&mut ap, 10.0);
    assert!((down - 1.0).abs() < 0.05, "descent {down:.3} m/s");
}

/// Land from `up_m` [m]: the descent speed [m/s] against the height [m],
/// one sample a step, until the vehicle is on the ground.
fn landing(ap: &mut Sitl, up_m: f64) -> Vec<(f64, f64)> {
    ap.step();
    ap.take_off_to(Some(up_m));
    assert_eq!(ap.command(AutopilotCommand::Land), CommandOutcome::Accepted);
    let mut samples = Vec::new();
    ap.run_until(90.0, |t| {
        samples.push((height(t), t.velocity_ned.z));
        !t.armed
    })
    .expect("lands and disarms");
    samples
}

/// The largest descent speed [m/s] of `samples` between `from` and `to` m.
fn peak_descent(samples: &[(f64, f64)], from: f64, to: f64) -> f64 {
    samples
        .iter()
        .filter(|(h, _)| *h > from && *h < to)
        .fold(0.0, |m, (_, v)| m.max(*v))
}

#[test]
fn a_landing_slows_from_mpc_z_vel_max_dn_at_mpc_land_alt1_to_mpc_land_speed_at_mpc_land_alt2() {
    let mut ap = Sitl::quad().build();
    let s = landing(&mut ap, 20.0);
    // PX4's defaults: 1.5 m/s above 10 m, 0.7 m/s below 5 m, linear between
    let above = peak_descent(&s, 11.0, 19.0);
    assert!((above - 1.5).abs() < 0.05, "above MPC_LAND_ALT1: {above:.3} m/s");
    // halfway the limit is 1.1 m/s; the shaper follows it down within its
    // acceleration and jerk limits, a little behind
    let (_, midway) = *s.iter().find(|(h, _)| *h < 7.5).unwrap();
    assert!(midway > 1.1 && midway < 1.3, "at 7.5 m, halfway: {midway:.3} m/s");
    let below = peak_descent(&s, 0.5, 3.0);
    assert!(below < 0.7 * 1.03, "below MPC_LAND_ALT2: {below:.3} m/s");
    // MPC_LAND_ALT2 at MPC_LAND_ALT1: the step of the builds before
    let mut ap = Sitl::quad().params(&[("MPC_LAND_ALT2", real(10.0))]).build();
    let s = landing(&mut ap, 20.0);
    let (_, at_7) = *s.iter().find(|(h, _)| *h < 7.0).unwrap();
    assert!((at_7 - 0.7).abs() < 0.02, "at 7 m: {at_7:.3} m/s");
}
