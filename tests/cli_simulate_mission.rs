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
    // the quad's drag on the 8 m/s legs, no estimate fed back: measured 0.231 m
    assert!(s.max_tracking_error_m < 0.3, "{}", s.max_tracking_error_m);
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

/// Each item says what became of it: a DO_ item that ran is not a
/// waypoint never reached. The square's DO_CHANGE_SPEED (item 3) ran when
/// item 2 was reached; a waypoint out of time is "never reached", and the
/// DO_ item behind it "never ran".
#[test]
fn items_tell_reached_ran_never_reached_and_never_ran_apart() {
    let square = run(&["simulate", "tools/scenarios/mission-square.toml", "--json"]);
    assert!(square.ok(), "{}", square.stderr);
    let v: serde_json::Value = serde_json::from_str(&square.stdout).unwrap();
    let items = v["items"].as_array().unwrap();
    let outcomes: Vec<&str> = items.iter().map(|i| i["outcome"].as_str().unwrap()).collect();
    assert_eq!(
        outcomes,
        ["reached", "reached", "reached", "ran", "reached", "reached", "reached"]
    );
    assert_eq!(items[3]["reached_s"], serde_json::Value::Null);
    // run on the step after item 2 is reached (the navigator goes on to it then)
    let (ran, reached) = (
        items[3]["ran_s"].as_f64().unwrap(),
        items[2]["reached_s"].as_f64().unwrap(),
    );
    assert!((0.0..=0.0015).contains(&(ran - reached)), "{ran} after {reached}");
    assert_eq!(items[3]["times_ran"], 1);
    let text = run(&["simulate", "tools/scenarios/mission-square.toml"]).stdout;
    let line = |seq: &str| {
        text.lines()
            .find(|l| l.starts_with(&format!("  item {seq:>3} ")))
            .unwrap_or_default()
            .to_string()
    };
    assert!(line("3").contains("cmd   178: ran         24.13 s"), "{text}");
    assert!(
        line("2").contains("cmd    16: reached     24.12 s, 4.08 m off"),
        "{text}"
    );

    let dir = common::scratch_dir("sim-mission-outcomes");
    let f = dir.join("short.toml");
    std::fs::write(
        &f,
        "duration_s = 5\n[mission]\n[[mission.item]]\ncommand = 16\nparams = [0.0, 1.0, 0.0, nan]\n\
         x = 47.3986\ny = 8.5456\nz = 20.0\n[[mission.item]]\ncommand = 178\nparams = [1.0, 3.0, -1.0, 0.0]\n",
    )
    .unwrap();
    let short = run(&["simulate", f.to_str().unwrap(), "--json"]);
    let v: serde_json::Value = serde_json::from_str(&short.stdout).unwrap();
    let outcomes: Vec<&str> = v["items"]
        .as_array()
        .unwrap()
        .iter()
        .map(|i| i["outcome"].as_str().unwrap())
        .collect();
    assert_eq!(outcomes, ["never_reached", "never_ran"]);
    let text = run(&["simulate", f.to_str().unwrap()]).stdout;
    assert!(text.contains("  item   0 cmd    16: never reached\n"), "{text}");
    assert!(text.contains("  item   1 cmd   178: never ran\n"), "{text}");
}

/// A plan the vehicle refuses is explained as the vehicle explains it: the
/// item, its altitude and the parameter it is above, with its value.
#[test]
fn a_refused_plan_names_the_item_and_the_limit() {
    let dir = common::scratch_dir("sim-mission-ceiling");
    let f = dir.join("high.toml");
    let wp = |z: f64| format!("[[mission.item]]\ncommand = 16\nx = 47.3986\ny = 8.5456\nz = {z}\n");
    let text = format!("[mission]\n{}{}{}{}", wp(10.0), wp(20.0), wp(30.0), wp(12000.0)) + &wp(10.0);
    std::fs::write(&f, text).unwrap();
    let out = run(&["simulate", f.to_str().unwrap()]);
    assert_eq!(out.code, Some(2), "{}", out.stderr);
    assert_eq!(
        out.stderr,
        format!(
            "rotorpilot: {}: mission refused: Plan rejected: item 3 at 12488 m > RP_ALT_MAX_AMSL \
             (RP_ALT_MAX_AMSL = 9000; invalid altitude / z)\n",
            f.display()
        )
    );
}

/// A misspelled airframe or parameter is refused at its line and column,
/// and a parameter close to a real one gets "did you mean".
#[test]
fn a_bad_airframe_or_parameter_is_refused_at_its_line_with_a_suggestion() {
    let dir = common::scratch_dir("sim-mission-typos");
    let item = "[mission]\n[[mission.item]]\ncommand = 16\nx = 47.4\ny = 8.5\nz = 10.0\n";
    for (name, text, expect) in [
        (
            "airframe.toml",
            format!("duration_s = 5\nairframe = \"quadx\"\n{item}"),
            ":2:12: airframe: unknown airframe `quadx`: not a file and not a built-in airframe",
        ),
        (
            "param.toml",
            format!("[params]\nMPC_XY_CRUISE = 8.0\nMPC_XY_CRUIS = 8.0\n{item}"),
            ":3:1: params.MPC_XY_CRUIS: unknown parameter MPC_XY_CRUIS (did you mean MPC_XY_CRUISE?)\n",
        ),
        (
            "plain.toml",
            "airframe = \"octa\"\nduration_s = 1\n".to_string(),
            ":1:12: airframe: unknown airframe `octa`",
        ),
    ] {
        let f = dir.join(name);
        std::fs::write(&f, text).unwrap();
        let out = run(&["simulate", f.to_str().unwrap()]);
        assert_eq!(out.code, Some(2), "{name}: {}", out.stderr);
        let want = format!("rotorpilot: {}{expect}", f.display());
        assert!(out.stderr.starts_with(&want), "{name}:\n{}\nwanted\n{want}", out.stderr);
    }
}
