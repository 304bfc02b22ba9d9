//! The wind the vehicle feels, end to end in the lockstep core: the world
//! blows (`SIM_WIND_*`), the flight stack sees only its sensors, estimates the
//! external force, explains it by the quad's nominal drag and reports the
//! wind (WIND_COV's content, `Telemetry::wind`); and the estimate's feedback
//! (`EST_COMP`) holds the hover closer in that wind.

mod common;

use common::sitl::{Sitl, SitlBuilder, int, real};
use nalgebra::Vector3;
use rotorpilot::airframe::{AeroCoefficients, Airframe};

/// The shipped quad with drag: PX4's EKF2 drag-fusion defaults scaled to its
/// 2 kg (`EKF2_BCOEF_X/Y` = 100 kg/m^2: `c_d = 0.5 rho m / BCOEF`;
/// `EKF2_MCOEF` = 0.15 1/s at its hover speeds: `k_d = 0.15 m / sum omega`),
/// so that these tests do not hang on the airframe file's own numbers.
fn quad_with_drag() -> SitlBuilder {
    let mut af = Airframe::load("quad").unwrap();
    af.aero = AeroCoefficients {
        c_dx: 0.012,
        c_dy: 0.012,
        c_dz: 0.02,
        k_d: 1.0e-4,
        ..AeroCoefficients::default()
    };
    Sitl::of(af)
}

/// Wind speed [m/s] and the direction it comes from [deg] of a NED wind.
fn speed_from(w: &Vector3<f64>) -> (f64, f64) {
    (w.xy().norm(), (-w.y).atan2(-w.x).to_degrees().rem_euclid(360.0))
}

/// The smallest difference between two directions [deg].
fn angle_between(a: f64, b: f64) -> f64 {
    ((a - b + 180.0).rem_euclid(360.0) - 180.0).abs()
}

/// A quad hovering 5 m up, then the wind set: (seconds until the reported
/// wind is within 0.5 m/s and 10 deg of 5 m/s from the west and stays so
/// over `seconds`, the worst speed error after that).
fn hover_in_wind(ap: &mut Sitl, seconds: f64) -> (Option<f64>, f64) {
    ap.step();
    ap.take_off_to(Some(5.0));
    ap.run(3.0);
    let calm = ap.telemetry().wind.expect("an estimate in still air");
    assert!(calm.wind_ned.norm() < 0.2, "still air: {}", calm.wind_ned);
    ap.set_param("SIM_WIND_DIR", real(270.0));
    ap.set_param("SIM_WIND_SPD", real(5.0));
    let t0 = ap.time_s();
    let mut settled_at = None;
    let mut worst: f64 = 0.0;
    for _ in 0..ap.steps(seconds) {
        ap.step();
        let w = ap.telemetry().wind.expect("an estimate in the air");
        let (speed, from) = speed_from(&w.wind_ned);
        let inside = (speed - 5.0).abs() < 0.5 && angle_between(from, 270.0) < 10.0;
        match (inside, settled_at) {
            (true, None) => settled_at = Some(ap.time_s() - t0),
            (false, Some(_)) => settled_at = None,
            _ => {}
        }
        if settled_at.is_some() {
            worst = worst.max((speed - 5.0).abs());
        }
    }
    (settled_at, worst)
}

#[test]
fn a_hovering_quad_reports_5_m_s_from_the_west_within_bounds() {
    let mut ap = quad_with_drag().params(&[("SIM_WIND_TURB", real(0.0))]).build();
    let (settled, worst) = hover_in_wind(&mut ap, 30.0);
    let settled = settled.expect("the estimate settles within 0.5 m/s and 10 deg");
    let w = ap.telemetry().wind.unwrap();
    let (speed, from) = speed_from(&w.wind_ned);
    println!(
        "no turbulence: within bounds {settled:.2} s after the wind was set; then worst speed error \
         {worst:.3} m/s; final {speed:.3} m/s from {from:.2} deg, variance {:?}",
        w.variance_ne
    );
    assert!(settled < 8.0, "settled after {settled} s");
    assert!(
        (speed - 5.0).abs() < 0.1 && angle_between(from, 270.0) < 2.0,
        "{speed} from {from}"
    );
    assert!(w.variance_ne.x < 0.01 && w.variance_ne.y < 0.01, "{:?}", w.variance_ne);
}

/// RMS of the horizontal distance between two NED winds over a series.
fn rms(pairs: &[(Vector3<f64>, Vector3<f64>)]) -> f64 {
    (pairs.iter().map(|(a, b)| (a - b).xy().norm_squared()).sum::<f64>() / pairs.len() as f64).sqrt()
}

#[test]
fn under_turbulence_the_estimate_follows_the_felt_wind() {
    // MIL-F-8785C "light" at W20 = 5 m/s is sigma_w = 0.5 m/s; 1.5 m/s is "moderate"
    for sigma_w in [0.5, 1.5] {
        let mut ap = quad_with_drag().params(&[("SIM_WIND_TURB", real(sigma_w))]).build();
        ap.step();
        ap.take_off_to(Some(5.0));
        ap.set_param("SIM_WIND_DIR", real(270.0));
        ap.set_param("SIM_WIND_SPD", real(5.0));
        ap.run(10.0);
        let mean = Vector3::new(0.0, 5.0, 0.0);
        // the true wind low-passed as the estimate is (tau = 1 s): what a perfect force estimate would give
        let mut felt = ap.truth().wind_ned;
        let a = 1.0 - (-ap.dt_s()).exp();
        let (mut vs_mean, mut vs_truth, mut vs_felt) = (Vec::new(), Vec::new(), Vec::new());
        for _ in 0..ap.steps(60.0) {
            ap.step();
            let truth = ap.truth().wind_ned;
            felt += a * (truth - felt);
            let w = ap.telemetry().wind.expect("an estimate in the air").wind_ned;
            vs_mean.push((w, mean));
            vs_truth.push((w, truth));
            vs_felt.push((w, felt));
        }
        let (m, t, f) = (rms(&vs_mean), rms(&vs_truth), rms(&vs_felt));
        let truth_spread = rms(&vs_truth.iter().map(|(_, t)| (*t, mean)).collect::<Vec<_>>());
        let w = ap.telemetry().wind.unwrap();
        println!(
            "sigma_w {sigma_w} m/s over 60 s: the true wind's rms off the mean {truth_spread:.3} m/s; the estimate's rms \
             error vs the mean {m:.3}, vs the true wind {t:.3}, vs the true wind low-passed at 1 s {f:.3} m/s; \
             variance reported {:?}",
            w.variance_ne.as_slice()
        );
        assert!(f < 0.35 * truth_spread, "{f} vs spread {truth_spread}");
        assert!(
            w.variance_ne.x + w.variance_ne.y > 1e-3,
            "turbulence shows in the variance"
        );
    }
}

#[test]
fn an_airframe_without_drag_reports_no_wind() {
    let mut af = Airframe::load("quad").unwrap();
    af.aero = AeroCoefficients::default();
    let mut ap = Sitl::of(af).params(&[("SIM_WIND_SPD", real(5.0))]).build();
    ap.step();
    ap.take_off_to(Some(5.0));
    ap.run(10.0);
    assert!(ap.telemetry().estimate.force_ned.norm().is_finite());
    assert_eq!(ap.telemetry().wind, None);
}

#[test]
fn feedback_of_the_estimate_holds_the_hover_closer_in_wind() {
    let mut off_on = [0.0; 2];
    for (i, comp) in [0, 1].into_iter().enumerate() {
        let mut ap = quad_with_drag()
            .params(&[("SIM_WIND_TURB", real(0.0)), ("EST_COMP", int(comp))])
            .build();
        ap.step();
        ap.take_off_to(Some(5.0));
        ap.run(3.0);
        let p0 = ap.telemetry().position_ned;
        ap.set_param("SIM_WIND_DIR", real(270.0));
        ap.set_param("SIM_WIND_SPD", real(5.0));
        ap.run(15.0);
        off_on[i] = (ap.telemetry().position_ned - p0).xy().norm();
    }
    println!(
        "5 m/s wind, after 15 s: pushed {:.4} m without EST_COMP, {:.4} m with",
        off_on[0], off_on[1]
    );
    assert!(off_on[0] > 0.05, "the wind pushes: {}", off_on[0]);
    assert!(off_on[1] < off_on[0] / 5.0, "{off_on:?}");
}

/// Drag coefficients for the injected-force test (not a shipped airframe's).
fn some_drag() -> AeroCoefficients {
    AeroCoefficients {
        c_dx: 0.01,
        c_dy: 0.01,
        k_d: 1e-5,
        ..AeroCoefficients::default()
    }
}

#[test]
fn an_injected_force_reads_as_the_wind_whose_drag_it_equals() {
    // the estimate assumes every force in the body plane is drag: 0.4 N east
    // on a level quad is the drag of the airspeed v that solves
    // (c |v| + k_d S) |v| = 0.4 N, blowing east (from the west)
    let mut af = Airframe::load("quad").unwrap();
    af.aero = some_drag();
    let mut ap = Sitl::of(af).build();
    ap.step();
    ap.take_off_to(Some(5.0));
    assert_eq!(
        ap.telemetry().wind.map(|w| w.wind_ned.norm() < 0.05),
        Some(true),
        "calm in still air"
    );
    ap.set_param("SIM_FEXT_Y", real(0.4));
    ap.run(15.0);
    let t = ap.telemetry();
    let w = t.wind.expect("an estimate");
    let s: f64 = ap.readings().rotor_speeds_rad_s.sum();
    // the positive root of 0.01 v^2 + 1e-5 S v - 0.4 = 0
    let b = 1e-5 * s;
    let v = (-b + (b * b + 4.0 * 0.01 * 0.4).sqrt()) / (2.0 * 0.01);
    let (speed, from) = speed_from(&w.wind_ned);
    println!(
        "0.4 N east: wind {speed:.4} m/s from {from:.2} deg (drag model: {v:.4} m/s), f_e {:?}",
        t.estimate.force_ned.as_slice()
    );
    assert!((speed - v).abs() < 0.05 * v, "{speed} vs {v}");
    assert!(angle_between(from, 270.0) < 3.0, "{from}");
}
