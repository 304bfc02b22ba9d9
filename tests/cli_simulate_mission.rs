//! `rotorpilot simulate` on missions: the shipped mission scenario passes
//! with every item reached in order, a mission that cannot complete fails
//! with a reason and exit status 1, and bad files are refused with the file,
//! the field and the problem.

mod common;

use common::bin::run;

use rotorpilot::scenario::{MissionFlight, run_mission};

#[test]
fn the_shipped_square_passes_with_every_item_reached_in_order() {
    let f = MissionFlight::from_file(std::path::Path::new("tools/scenarios/mission-square.toml")).unwrap();
    let s = run_mission(&f, None).unwrap();
    println!("{}", s.to_text());
    assert_eq!(s.verdict, "pass", "{:?}", s.reasons);
    assert!(s.complete && s.landed_and_disarmed && s.upright && s.finite);
    let reached: Vec<_> = s.items.iter().filter_map(|i| i.reached_s.map(|t| (i.seq, t))).collect();
    assert_eq!(reached.iter().map(|r| r.0).collect::<Vec<_>>(), vec![0, 1, 2, 4, 5, 6]);
    assert!(reached.windows(2).all(|w| w[0].1 < w[1].1), "out of order: {reached:?}");
    // the stop waypoint is reached
    // within its 1 m acceptance radius and NAV_MC_ALT_RAD (0.8 m) of height
    assert!(s.items[5].distance_m.unwrap() <= 1.0_f64.hypot(0.8));
    assert!(s.max_tracking_error_m < 0.05, "{}", s.max_tracking_error_m);
}

#[test]
fn a_mission_that_cannot_complete_fails_with_a_reason_and_exit_status_1() {
    let dir = common::scratch_dir("sim-mission");
    let f = dir.join("short.toml");
    std::fs::write(
        &f,
        "duration_s = 5\n[mission]\n[[mission.item]]\ncommand = 16\nparams = [0.0, 1.0, 0.0, nan]\nx = 47.3986\ny = 8.5456\nz = 20.0\n",
    )
    .unwrap();
    let out = run(&["simulate", f.to_str().unwrap(), "--json"]);
    assert_eq!(out.code, Some(1));
    let v: serde_json::Value = serde_json::from_str(&out.stdout).unwrap();
    assert_eq!(v["verdict"], "fail");
    let reasons = v["reasons"].to_string();
    assert!(
        reasons.contains("did not complete") && reasons.contains("never reached"),
        "{reasons}"
    );
}

#[test]
fn bad_mission_files_are_refused_naming_the_file_and_the_field() {
    let dir = common::scratch_dir("sim-mission-bad");
    for (name, text, expect) in [
        (
            "lat.toml",
            "[mission]\n[[mission.item]]\ncommand = 16\nx = 91.0\ny = 8.5\nz = 10.0\n",
            "mission.item[0]: invalid latitude",
        ),
        (
            "empty.toml",
            "[mission]\n",
            "mission: no `file` and no `[[mission.item]]`",
        ),
        (
            "param.toml",
            "[params]\nMPC_XY_CRUISE = 99.0\n[mission]\n[[mission.item]]\ncommand = 16\nx = 47.4\ny = 8.5\nz = 10.0\n",
            "params.MPC_XY_CRUISE",
        ),
        (
            "cmd.toml",
            "[mission]\n[[mission.item]]\ncommand = 5001\nx = 47.4\ny = 8.5\nz = 10.0\n",
            "mission.item[0]: unsupported command",
        ),
    ] {
        let f = dir.join(name);
        std::fs::write(&f, text).unwrap();
        let out = run(&["simulate", f.to_str().unwrap()]);
        let err = &out.stderr;
        assert!(!out.ok(), "{name} accepted");
        assert!(err.contains(name) && err.contains(expect), "{name}: {err}");
        assert!(!err.contains("panicked"), "{err}");
    }
}
