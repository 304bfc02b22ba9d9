//! Lockstep tests of the vertical speeds of the automatic modes, as PX4
//! flies them (FlightTaskAuto::_updateTrajConstraints): a takeoff climbs at
//! MPC_TKO_SPEED below MPC_LAND_ALT1 above home and at MPC_Z_V_AUTO_UP above
//! it; the other automatic climbs and descents (a reposition here) at
//! MPC_Z_V_AUTO_UP / MPC_Z_V_AUTO_DN, each at most MPC_Z_VEL_MAX_UP / _DN.
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
