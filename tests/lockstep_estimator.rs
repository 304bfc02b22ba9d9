//! The origin report's exercise 4 end to end: fly `tools/scenarios/fsr-exercise4.toml`,
//! log it, run the estimator of every order and polynomial over the log, and
//! compare with `docs/model.md` sections 9 and 10.

mod common;

use nalgebra::Vector3;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use rotorpilot::control::ControllerKind;
use rotorpilot::estimation::sweep::{estimate_log, sweep_config, sweep_result};
use rotorpilot::estimation::{Discretization, Polynomial};
use rotorpilot::logs::csv::{FlightLog, LogError};
use rotorpilot::math::rate_map;
use rotorpilot::scenario::{Scenario, run};

fn exercise4() -> Scenario {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/tools/scenarios/fsr-exercise4.toml");
    Scenario::from_file(std::path::Path::new(path)).unwrap()
}

/// Fly a scenario and return its log as text.
fn fly(s: &Scenario) -> (rotorpilot::scenario::Summary, String) {
    let mut csv = Vec::new();
    let summary = run(s, Some(&mut csv)).unwrap();
    (summary, String::from_utf8(csv).unwrap())
}

/// Doc section 10: 2 % settling times [s] of the estimate, omega_c = 10 rad/s.
const BUTTERWORTH_T2: [(usize, f64); 6] = [(1, 0.38), (2, 0.59), (3, 0.66), (5, 1.08), (10, 2.05), (20, 3.75)];
const BINOMIAL_T2: [(usize, f64); 6] = [(1, 0.38), (2, 0.59), (3, 0.75), (5, 1.06), (10, 1.75), (20, 3.02)];

/// Every r in {1, 2, 3, 5, 10, 20}, both polynomials, estimate not fed back:
/// f = [0.5, 0.5, -2.4525] N within 1 %, yaw torque 0.2 N m within 1 %, mass
/// 1.25 kg within 0.5 %, 2 % settling within 10 % of the doc's table.
#[test]
fn every_order_converges_to_the_reports_disturbance() {
    let s = exercise4();
    let (_, text) = fly(&s);
    let log = FlightLog::parse(&text, "exercise4.csv").unwrap();
    let nominal = s.airframe.nominal();
    for (poly, table) in [
        (Polynomial::Butterworth, BUTTERWORTH_T2),
        (Polynomial::Binomial, BINOMIAL_T2),
    ] {
        for (order, t2) in table {
            let config = sweep_config(order, poly.clone(), 10.0, log.step_s, Discretization::Trapezoidal);
            let est = estimate_log(&log.rows, config.clone(), nominal).unwrap();
            let r = sweep_result(&log.rows, &config, &nominal, &est);
            let f = r.final_force_ned;
            let label = format!("{poly:?} r={order}");
            assert!(
                (f[0] - 0.5).abs() < 0.005 && (f[1] - 0.5).abs() < 0.005,
                "{label}: {f:?}"
            );
            assert!((f[2] + 2.4525).abs() < 0.024525, "{label}: {f:?}");
            assert!(
                (r.final_torque_frd[2] - 0.2).abs() < 0.002,
                "{label}: {:?}",
                r.final_torque_frd
            );
            assert!((r.mass_kg - 1.25).abs() < 0.00625, "{label}: {}", r.mass_kg);
            let settle = r.settle_s.expect("settled");
            assert!(
                (settle - t2).abs() <= 0.1 * t2,
                "{label}: settles in {settle} s, doc {t2} s"
            );
        }
    }
}

/// With the estimate fed back, all three laws hold the hover to under 0.1 mm
/// despite the report's disturbances and mass error.
#[test]
fn feedback_removes_the_steady_error_for_every_controller() {
    for kind in ControllerKind::ALL {
        let mut s = exercise4();
        s.controller = kind;
        s.feedback = true;
        s.duration_s = 15.0;
        let summary = run(&s, None).unwrap();
        let e = Vector3::from(summary.final_pos_err_ned);
        assert!(e.norm() < 1e-4, "{kind:?}: steady error {e:?} m");
        // and without feedback the error is the large, known one
        s.feedback = false;
        let without = Vector3::from(run(&s, None).unwrap().final_pos_err_ned);
        assert!(without.norm() > 4e-3, "{kind:?}: {without:?}");
    }
}

/// Doc section 10: with white noise on the velocity (0.02 m/s) and the body
/// rates (0.01 rad/s) the steady RMS of the x force estimate falls with r;
/// Butterworth flattens after r = 3..5, binomial keeps falling.
#[test]
fn noise_rms_falls_with_the_order_as_the_doc_says() {
    let s = exercise4();
    let (_, text) = fly(&s);
    let mut log = FlightLog::parse(&text, "exercise4.csv").unwrap();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(42);
    let nv = Normal::new(0.0, 0.02).unwrap();
    let nw = Normal::new(0.0, 0.01).unwrap();
    for row in &mut log.rows {
        let x = &mut row.input;
        x.velocity_ned += Vector3::new(nv.sample(&mut rng), nv.sample(&mut rng), nv.sample(&mut rng));
        x.rate_frd += Vector3::new(nw.sample(&mut rng), nw.sample(&mut rng), nw.sample(&mut rng));
        x.eta_dot = rate_map(&x.eta).try_inverse().unwrap() * x.rate_frd;
    }
    let nominal = s.airframe.nominal();
    let steady_rms = |poly: Polynomial, order: usize| {
        let config = sweep_config(order, poly, 10.0, log.step_s, Discretization::Trapezoidal);
        let est = estimate_log(&log.rows, config, nominal).unwrap();
        let tail: Vec<f64> = est[5000..].iter().map(|e| e.force_ned.x - 0.5).collect();
        (tail.iter().map(|v| v * v).sum::<f64>() / tail.len() as f64).sqrt()
    };
    let bw: Vec<f64> = [1, 2, 3, 5, 10, 20]
        .iter()
        .map(|r| steady_rms(Polynomial::Butterworth, *r))
        .collect();
    let bi: Vec<f64> = [1, 2, 3, 5, 10, 20]
        .iter()
        .map(|r| steady_rms(Polynomial::Binomial, *r))
        .collect();
    // r = 1 passes white noise with gain K1: about K1 m sigma_v = 0.3 N
    assert!((bw[0] - 0.298).abs() < 0.06, "r=1 {bw:?}");
    // doc: Butterworth r = 2 gives 0.020 N; from r = 3..5 on it flattens (the
    // doc's prototype printed 0.016 for r >= 3, we measure about 0.012 falling to
    // 0.008: the same flattening at half the level)
    assert!((bw[1] - 0.020).abs() < 0.35 * 0.020, "Butterworth r=2 {bw:?}");
    assert!(bw[1] > bw[2] && bw[2] > bw[3], "Butterworth falls up to r = 5: {bw:?}");
    let flat = &bw[3..];
    let (lo, hi) = flat
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(a, b), v| (a.min(*v), b.max(*v)));
    assert!(hi / lo < 1.25, "Butterworth flat from r = 5 on: {bw:?}");
    // doc: binomial 0.016, 0.010, 0.006, 0.003, 0.001
    for w in bi[1..].windows(2) {
        assert!(w[1] < w[0], "binomial must keep falling: {bi:?}");
    }
    assert!(bi[5] < bi[2] / 4.0, "{bi:?}");
}

/// The estimates written online during the flight and those recomputed from the log agree to 1e-9.
#[test]
fn offline_and_online_estimates_agree() {
    let s = exercise4();
    let (_, text) = fly(&s);
    let log = FlightLog::parse(&text, "exercise4.csv").unwrap();
    let config = s.estimator.clone();
    let offline = estimate_log(&log.rows, config, s.airframe.nominal()).unwrap();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let cols = [
        col("est_fn"),
        col("est_fe"),
        col("est_fd"),
        col("est_tx"),
        col("est_ty"),
        col("est_tz"),
        col("est_mass_kg"),
    ];
    let mut worst: f64 = 0.0;
    for (line, off) in text.lines().skip(1).zip(&offline) {
        let f: Vec<f64> = line.split(',').map(|v| v.parse().unwrap()).collect();
        let online = [
            f[cols[0]], f[cols[1]], f[cols[2]], f[cols[3]], f[cols[4]], f[cols[5]], f[cols[6]],
        ];
        let mine = [
            off.force_ned.x,
            off.force_ned.y,
            off.force_ned.z,
            off.torque_frd.x,
            off.torque_frd.y,
            off.torque_frd.z,
            off.mass_kg,
        ];
        for (a, b) in online.iter().zip(mine) {
            worst = worst.max((a - b).abs());
        }
    }
    assert!(worst < 1e-9, "online and offline differ by {worst}");
}

/// `rotorpilot estimate` over the flight prints one JSON object per order and polynomial.
#[test]
fn estimate_command_prints_the_documented_json() {
    let dir = common::scratch_dir("est");
    let log = dir.join("ex4.csv");
    let (_, text) = fly(&exercise4());
    std::fs::write(&log, text).unwrap();
    let out = common::bin::rotorpilot()
        .args([
            "estimate",
            log.to_str().unwrap(),
            "--order",
            "1,3,20",
            "--poly",
            "butterworth,binomial",
            "--json",
        ])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let list = v.as_array().unwrap();
    assert_eq!(list.len(), 6);
    for item in list {
        for key in [
            "order",
            "poly",
            "final_force_ned",
            "final_torque_frd",
            "mass_kg",
            "settle_s",
            "overshoot_pct",
        ] {
            assert!(item.get(key).is_some(), "missing {key}");
        }
    }
    assert!(dir.join("ex4-estimates.csv").exists());
    std::fs::remove_dir_all(&dir).ok();
}

/// A log with a missing column, a non-monotonic time or a NaN row is refused by line and column.
#[test]
fn broken_logs_are_refused_by_line_and_column() {
    let (_, text) = fly(&Scenario {
        duration_s: 0.01,
        ..exercise4()
    });
    let lines: Vec<&str> = text.lines().collect();
    let header = lines[0];

    let no_pitch = text.replacen(",pitch,", ",pitch_deg,", 1);
    let err = FlightLog::parse(&no_pitch, "a.csv").unwrap_err();
    assert!(matches!(&err, LogError::MissingColumn { column, .. } if column == "pitch"));
    assert!(
        err.to_string().contains("a.csv:1") && err.to_string().contains("`pitch`"),
        "{err}"
    );

    let mut back_in_time = lines.clone();
    let row = lines[3].replacen(lines[3].split(',').next().unwrap(), "0", 1);
    back_in_time[3] = &row;
    let err = FlightLog::parse(&back_in_time.join("\n"), "b.csv")
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("b.csv:4") && err.contains("time_s") && err.contains("does not increase"),
        "{err}"
    );

    let fields: Vec<&str> = lines[5].split(',').collect();
    let roll = header.split(',').position(|h| h == "roll").unwrap();
    let mut nan_row = fields.clone();
    nan_row[roll] = "NaN";
    let mut with_nan = lines.clone();
    let row = nan_row.join(",");
    with_nan[5] = &row;
    let err = FlightLog::parse(&with_nan.join("\n"), "c.csv").unwrap_err().to_string();
    assert!(
        err.contains("c.csv:6") && err.contains("`roll`") && err.contains("NaN"),
        "{err}"
    );

    // and the CLI says so without a panic
    let dir = common::scratch_dir("badlog");
    let path = dir.join("c.csv");
    std::fs::write(&path, with_nan.join("\n")).unwrap();
    let out = common::bin::rotorpilot()
        .args(["estimate", path.to_str().unwrap()])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && stderr.contains("c.csv:6") && !stderr.contains("panicked"),
        "{stderr}"
    );
    std::fs::remove_dir_all(&dir).ok();
}
