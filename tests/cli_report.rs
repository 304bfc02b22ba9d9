//! `rotorpilot report` and `simulate --report`: every headless flight (a
//! mission, a plain scenario, each vehicle of a fleet) gets a page with its
//! verdict and plots' data, and flies the same with or without the page
//! (the collector only watches); bad input gets one clear error naming the
//! file, never a panic.

mod common;

use common::bin::run;

/// The summary's JSON without what wall time decides (the only fields that
/// vary between two runs), its fleet results' included.
fn summary(stdout: &str) -> serde_json::Value {
    let mut v: serde_json::Value = serde_json::from_str(stdout).unwrap();
    let o = v.as_object_mut().unwrap();
    for k in ["wall_time_s", "vehicle_steps_per_s", "real_time_factor"] {
        o.remove(k);
    }
    for r in o
        .get_mut("results")
        .and_then(|r| r.as_array_mut())
        .into_iter()
        .flatten()
    {
        r.as_object_mut().unwrap().remove("wall_time_s");
    }
    v
}

/// Fly `file` with `simulate --json`, then again with `--report` into a
/// fresh directory named for `tag`: the summaries must be equal (the page
/// only watches). The directory the pages went to, and the summary.
fn flown_with_and_without_report(file: &str, tag: &str) -> (std::path::PathBuf, serde_json::Value) {
    let dir = common::scratch_dir(tag);
    let plain = run(&["simulate", file, "--json"]);
    assert!(plain.ok(), "{}", plain.stderr);
    let with = run(&["simulate", file, "--json", "--report", dir.to_str().unwrap()]);
    assert!(with.ok(), "{}", with.stderr);
    assert_eq!(
        summary(&plain.stdout),
        summary(&with.stdout),
        "the page changed the flight"
    );
    (dir, summary(&plain.stdout))
}

#[test]
fn simulate_report_writes_a_mission_page_and_the_flight_is_the_same() {
    let (dir, flown) = flown_with_and_without_report("tools/scenarios/octo-mission-rotor-loss.toml", "sim-report");
    let page = std::fs::read_to_string(dir.join("octo-mission-rotor-loss.html")).unwrap();
    // the header's largest tracking error is the summary's, counted alike
    let e = flown["max_tracking_error_m"].as_f64().unwrap();
    let said = format!("largest tracking error {e:.3} m at ");
    assert!(page.contains(&said), "{said}");
    assert!(page.contains("takeoff and landing excluded, as the mission summary counts it"));
    assert!(page.len() < 5_000_000, "{} bytes", page.len());
    assert!(page.contains("<span class=\"badge pass\">PASS</span>"));
    assert!(
        page.contains("CMD_INJECT_FAILURE, motor 3 off"),
        "the rotor loss is an event"
    );
    for id in ["verdict", "path", "timeline", "plots", "events"] {
        assert!(page.contains(&format!("id=\"{id}\"")), "section {id}");
    }
    assert!(page.contains("<g class=\"item reached\">"), "items on the path");
    assert!(page.contains("id=\"report-data\""));
    // nothing to fetch: every script and style is inline
    assert!(!page.contains("src=\"http") && !page.contains("href=\"http"));
    assert!(!page.contains("<script src") && !page.contains("<link"));
}

/// A page that stands alone: under 5 MB, nothing fetched, every section
/// there, its data embedded, the flown track and the reference drawn.
fn assert_self_contained(page: &str) {
    assert!(page.len() < 5_000_000, "{} bytes", page.len());
    assert!(!page.contains("src=\"http") && !page.contains("href=\"http"));
    assert!(!page.contains("<script src") && !page.contains("<link"));
    for id in ["verdict", "path", "timeline", "plots", "events"] {
        assert!(page.contains(&format!("id=\"{id}\"")), "section {id}");
    }
    assert!(page.contains("id=\"report-data\""));
    let drawn = |id: &str| {
        let at = page
            .find(&format!("id=\"{id}\""))
            .unwrap_or_else(|| panic!("no {id} on the path"));
        let n: usize = page[at..]
            .split("data-points=\"")
            .nth(1)
            .and_then(|r| r.split('"').next())
            .and_then(|n| n.parse().ok())
            .unwrap();
        assert!(n > 100, "{id}: {n} points");
    };
    drawn("track");
    drawn("reference");
}

#[test]
fn simulate_report_writes_a_plain_scenario_page_and_the_flight_is_the_same() {
    let (dir, _) = flown_with_and_without_report("tools/scenarios/figure-eight-geometric.toml", "sim-report-plain");
    let page = std::fs::read_to_string(dir.join("figure-eight-geometric.html")).unwrap();
    assert_self_contained(&page);
    assert!(page.contains("<h1>tools/scenarios/figure-eight-geometric.toml</h1>"));
    assert!(page.contains("largest tracking error"), "the verdict's tracking error");
    assert!(!page.contains("class=\"items\""), "no mission, no items");
    assert!(page.contains("mode geometric"), "the controller in force");
}

#[test]
fn simulate_report_writes_a_page_per_fleet_vehicle_and_the_fleet_is_the_same() {
    let (dir, _) = flown_with_and_without_report("tools/fleets/fleet-collision.toml", "sim-report-fleet");
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["0-figure-eight-4m.html", "1-hover-2m.html"]);
    for (name, vehicle) in [
        (
            "0-figure-eight-4m.html",
            "vehicle 0 of tools/fleets/fleet-collision.toml: tools/fleets/vehicles/figure-eight-4m.toml",
        ),
        (
            "1-hover-2m.html",
            "vehicle 1 of tools/fleets/fleet-collision.toml: tools/fleets/vehicles/hover-2m.toml",
        ),
    ] {
        let page = std::fs::read_to_string(dir.join(name)).unwrap();
        assert_self_contained(&page);
        assert!(page.contains(&format!("<h1>{vehicle}</h1>")), "{name}: its vehicle");
        assert!(page.contains("collision"), "{name}: the collision is an event");
    }
}

#[test]
fn bad_input_gets_one_clear_error_naming_the_file() {
    let dir = common::scratch_dir("report-bad");
    let out = dir.join("x.html");
    let o = out.to_str().unwrap();
    let missing = dir.join("nothing.record");
    let r = run(&["report", missing.to_str().unwrap(), "-o", o]);
    assert_eq!(r.code, Some(1));
    assert!(r.stderr.contains("nothing.record"), "{}", r.stderr);
    let text = dir.join("text.record");
    std::fs::write(&text, "hello\n").unwrap();
    let r = run(&["report", text.to_str().unwrap(), "-o", o]);
    assert_eq!(r.code, Some(1));
    assert!(r.stderr.contains("text.record: not a flight record"), "{}", r.stderr);
    let binary = dir.join("binary.bin");
    std::fs::write(&binary, [0xff, 0xfe, 0x00, 0x01]).unwrap();
    let r = run(&["report", binary.to_str().unwrap(), "-o", o]);
    assert_eq!(r.code, Some(1));
    assert!(r.stderr.contains("neither a flight record"), "{}", r.stderr);
    // a ULog with its header and no topic
    let ulog = dir.join("empty.ulg");
    let mut bytes = vec![b'U', b'L', b'o', b'g', 0x01, 0x12, 0x35, 0x01];
    bytes.extend_from_slice(&0u64.to_le_bytes());
    std::fs::write(&ulog, bytes).unwrap();
    let r = run(&["report", ulog.to_str().unwrap(), "-o", o]);
    assert_eq!(r.code, Some(1));
    assert!(r.stderr.contains("empty.ulg: no rotorpilot_sim_truth"), "{}", r.stderr);
    assert!(!out.exists(), "no page for bad input");
    // a page that cannot be written
    let r = run(&[
        "simulate",
        "tools/scenarios/mission-square.toml",
        "--report",
        "/dev/null/x",
    ]);
    assert_eq!(r.code, Some(2));
    assert!(r.stderr.contains("--report /dev/null/x"), "{}", r.stderr);
}

/// The header's failsafe line of a page (`failsafes: ...`).
fn failsafe_line(page: &str) -> &str {
    let at = page.find("failsafes: ").expect("a failsafe line in the header");
    let rest = &page[at..];
    &rest[..rest.find("</li>").unwrap()]
}

/// The header lists the failsafes the flight stack put in force, whatever
/// its status texts say: the square losing its GPS fix in flight descends
/// blind ("No GPS fix: descending without position"), and its page names
/// that failsafe with its instant and cause; the same square without the
/// loss has none.
#[test]
fn the_header_lists_the_failsafes_the_flight_stack_put_in_force() {
    let square = std::fs::read_to_string("tools/scenarios/mission-square.toml")
        .unwrap()
        .replace("duration_s = 300", "duration_s = 40");
    let dir = common::scratch_dir("report-failsafes");
    let lost = dir.join("gps-lost.toml");
    let kept = dir.join("gps-kept.toml");
    std::fs::write(
        &lost,
        format!("{square}\n[[fault]]\nat_s = 25.0\nunit = \"gps\"\ntype = \"off\"\n"),
    )
    .unwrap();
    std::fs::write(&kept, &square).unwrap();
    let pages = dir.join("pages");
    for file in [&lost, &kept] {
        let out = run(&["simulate", file.to_str().unwrap(), "--report", pages.to_str().unwrap()]);
        assert!(!out.stderr.contains("panicked"), "{}", out.stderr);
    }
    let page = std::fs::read_to_string(pages.join("gps-lost.html")).unwrap();
    assert!(
        page.contains("No GPS fix: descending without position"),
        "the announcement is an event"
    );
    let line = failsafe_line(&page);
    assert!(line.contains("no GPS fix") && line.contains("at 25.0"), "{line}");
    let page = std::fs::read_to_string(pages.join("gps-kept.html")).unwrap();
    assert_eq!(failsafe_line(&page), "failsafes: none");
    let _ = std::fs::remove_dir_all(&dir);
}

fn rotor_limit_line(page: &str) -> &str {
    let at = page
        .find("rotor commands at a limit")
        .expect("a rotor-limit line in the header");
    let rest = &page[at..];
    &rest[..rest.find("</li>").unwrap()]
}

/// The header says how long a rotor command sat at a limit in the air (the
/// controller asked for more than the rotors give): the square flown by a
/// quad 1.6 times as heavy as its model (`SIM_MASS`, hover near full
/// speed) climbs on saturated rotors, and its page gives the share and the
/// first instant; the square at the nominal mass never saturates.
#[test]
fn the_header_says_how_long_the_rotors_sat_at_a_limit() {
    let square = std::fs::read_to_string("tools/scenarios/mission-square.toml")
        .unwrap()
        .replace("duration_s = 300", "duration_s = 30");
    let dir = common::scratch_dir("report-rotor-limit");
    let heavy = dir.join("heavy.toml");
    let nominal = dir.join("nominal.toml");
    std::fs::write(&heavy, square.replace("[params]", "[params]\nSIM_MASS = 3.2")).unwrap();
    std::fs::write(&nominal, &square).unwrap();
    let pages = dir.join("pages");
    for file in [&heavy, &nominal] {
        let out = run(&["simulate", file.to_str().unwrap(), "--report", pages.to_str().unwrap()]);
        assert!(!out.stderr.contains("panicked"), "{}", out.stderr);
    }
    let page = std::fs::read_to_string(pages.join("heavy.html")).unwrap();
    let line = rotor_limit_line(&page);
    let share: f64 = line
        .trim_start_matches("rotor commands at a limit ")
        .split(' ')
        .next()
        .and_then(|x| x.parse().ok())
        .unwrap_or_else(|| panic!("{line}"));
    assert!(share > 1.0 && share < 100.0 && line.contains("first at"), "{line}");
    let page = std::fs::read_to_string(pages.join("nominal.html")).unwrap();
    assert!(rotor_limit_line(&page).starts_with("rotor commands at a limit: never in the air"));
    let _ = std::fs::remove_dir_all(&dir);
}

/// A 10-minute flight's page stays under 5 MB: the quad hovering in gusty
/// wind (`tools/scenarios/hover-wind-quad.toml`) for 590 s instead of 60,
/// then landing; the series are sampled to at most 6,000 instants whatever
/// the length.
#[test]
fn a_ten_minute_flights_page_stays_under_5_mb() {
    let scenario = std::fs::read_to_string("tools/scenarios/hover-wind-quad.toml").unwrap();
    let long = scenario
        .replace("duration_s = 120", "duration_s = 700")
        .replace("params = [60.0, 0.0, 0.0, nan]", "params = [590.0, 0.0, 0.0, nan]");
    assert_ne!(long, scenario);
    let dir = common::scratch_dir("report-ten-minutes");
    let file = dir.join("ten-minutes.toml");
    std::fs::write(&file, long).unwrap();
    let pages = dir.join("pages");
    let out = run(&[
        "simulate",
        file.to_str().unwrap(),
        "--json",
        "--report",
        pages.to_str().unwrap(),
    ]);
    assert!(out.ok(), "{}", out.stderr);
    let flown: serde_json::Value = serde_json::from_str(&out.stdout).unwrap();
    let t = flown["sim_time_s"].as_f64().unwrap();
    assert!(t > 600.0, "a {t} s flight");
    let page = std::fs::read_to_string(pages.join("ten-minutes.html")).unwrap();
    assert_self_contained(&page);
    println!("a {t:.0} s flight's page: {} bytes", page.len());
    let _ = std::fs::remove_dir_all(&dir);
}
