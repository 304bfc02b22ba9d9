//! `rotorpilot simulate`: the shipped scenarios fly, the summary and CSV have
//! the documented shape, and broken scenario files are refused by name.

use std::process::Command;

fn rotorpilot(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_rotorpilot"))
        .args(args)
        .output()
        .unwrap()
}

fn scenario(name: &str) -> String {
    format!("{}/tools/scenarios/{name}", env!("CARGO_MANIFEST_DIR"))
}

fn json_of(out: &std::process::Output) -> serde_json::Value {
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).unwrap()
}

/// The report's exercise 4 flown end to end from the CLI: the geometric steady
/// error is K_p^-1 [0.5, 0.5, -2.4525] N and the estimate converges (doc section 9).
#[test]
fn fsr_exercise4_summary_matches_the_report() {
    let v = json_of(&rotorpilot(&["simulate", &scenario("fsr-exercise4.toml"), "--json"]));
    for key in [
        "sim_time_s",
        "wall_time_s",
        "rms_pos_err_m",
        "max_pos_err_m",
        "max_att_err_rad",
        "final_position_ned",
        "upright",
        "finite",
        "est_force_ned",
        "est_torque_frd",
        "est_mass_kg",
    ] {
        assert!(v.get(key).is_some(), "missing {key}: {v}");
    }
    assert_eq!(v["upright"], true);
    assert_eq!(v["finite"], true);
    assert!((v["sim_time_s"].as_f64().unwrap() - 10.0).abs() < 1e-9);
    let e: Vec<f64> = v["final_pos_err_ned"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    let theory = [0.5 / 355.0, 0.5 / 355.0, -2.4525 / 565.0];
    for (got, want) in e.iter().zip(theory) {
        assert!(
            (got - want).abs() < 0.02 * want.abs(),
            "steady error {e:?} vs {theory:?}"
        );
    }
    let f: Vec<f64> = v["est_force_ned"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    assert!(
        (f[0] - 0.5).abs() < 5e-3 && (f[1] - 0.5).abs() < 5e-3 && (f[2] + 2.4525).abs() < 0.025,
        "{f:?}"
    );
    assert!((v["est_mass_kg"].as_f64().unwrap() - 1.25).abs() < 0.00625);
}

/// Every shipped scenario flies upright and finite; the figure-eights stay within centimetres.
#[test]
fn every_shipped_scenario_flies() {
    let dir = format!("{}/tools/scenarios", env!("CARGO_MANIFEST_DIR"));
    let mut count = 0;
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        let v = json_of(&rotorpilot(&["simulate", path.to_str().unwrap(), "--json"]));
        assert_eq!(v["upright"], true, "{}", path.display());
        assert_eq!(v["finite"], true, "{}", path.display());
        let err = v["max_pos_err_m"].as_f64().or(v["max_tracking_error_m"].as_f64());
        assert!(err.unwrap() < 0.05, "{}: {v}", path.display());
        count += 1;
    }
    assert!(count >= 6);
}

/// The CSV has a header naming the report's inputs and one exact row per step.
#[test]
fn csv_log_has_the_documented_columns() {
    let dir = std::env::temp_dir().join(format!("rotorpilot-csv-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let csv = dir.join("flight.csv");
    let out = rotorpilot(&[
        "simulate",
        &scenario("quad-step-10m.toml"),
        "--csv",
        csv.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    for col in [
        "time_s",
        "vel_n",
        "vel_e",
        "vel_d",
        "roll",
        "pitch",
        "yaw",
        "roll_rate",
        "pitch_rate",
        "yaw_rate",
        "thrust_n",
        "tau_x",
        "tau_y",
        "tau_z",
        "w1",
        "w4",
        "fext_n",
        "text_z",
        "true_mass_kg",
        "est_fn",
        "est_mass_kg",
    ] {
        assert!(header.contains(&col), "missing column {col}");
    }
    let rows: Vec<&str> = lines.collect();
    assert_eq!(rows.len(), 15_000);
    assert!(rows.iter().all(|r| r.split(',').count() == header.len()));
    let last_t: f64 = rows.last().unwrap().split(',').next().unwrap().parse().unwrap();
    assert!((last_t - 14.999).abs() < 1e-9);
    std::fs::remove_dir_all(&dir).ok();
}

/// Each broken scenario names the file, the field and the problem, and exits non-zero without a panic.
#[test]
fn broken_scenarios_are_refused_by_name() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures/scenarios");
    for (file, field, problem) in [
        ("both-references.toml", "reference", "not both"),
        ("unknown-controller.toml", "pid", "unknown variant"),
        ("negative-duration.toml", "duration_s", "must be in"),
        ("late-disturbance.toml", "disturbance[1].at_s", "within"),
        ("bad-gain.toml", "gains.geometric.kp_n_per_m", "-2"),
        ("missing-airframe.toml", "no-such-frame", "unknown airframe"),
        ("bad-estimator.toml", "estimator", "25"),
        ("typo-key.toml", "postion_ned", "unknown field"),
    ] {
        let out = rotorpilot(&["simulate", &format!("{dir}/{file}")]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{file} was accepted");
        assert!(!err.contains("panicked"), "{file}: {err}");
        for needle in [file, field, problem] {
            assert!(err.contains(needle), "{file}: `{needle}` not in: {err}");
        }
    }
}
