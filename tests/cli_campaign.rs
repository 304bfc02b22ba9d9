//! `rotorpilot simulate` campaigns: many files and directories flown on
//! every core with one JSON line per scenario in entry order, whatever the
//! job count; `--shard I/N` partitions the campaign; `[campaign]` grids and
//! seeded random draws vary a scenario's own values, reproducibly, and the
//! flights show the values; bad shards, bad `[campaign]` tables and bad
//! variants get clear errors while the rest still runs; `rotorpilot merge`
//! turns the shards' outputs into the whole campaign's, and refuses shards
//! that do not make one campaign. A campaign draws the `[wind]` per variant
//! and each variant flies the wind its line names.

mod common;

use common::bin::run;
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use serde_json::Value;

/// What a run gave: exit status, the JSON lines of stdout (the entries; the
/// closing line apart), stdout as printed, stderr.
struct Run {
    status: Option<i32>,
    lines: Vec<Value>,
    closing: Option<Value>,
    stdout: String,
    stderr: String,
}

fn simulate(args: &[&str]) -> Run {
    let out = run(&[&["simulate"][..], args].concat());
    let (stdout, stderr) = (out.stdout, out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    let mut lines: Vec<Value> = if args.contains(&"--json") {
        stdout
            .lines()
            .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("not one JSON object per line ({e}): {l}")))
            .collect()
    } else {
        Vec::new()
    };
    // a campaign's JSON closes with the campaign, the shard and the counts
    let closing = lines
        .last()
        .filter(|l| l.get("index").is_none() && l.get("campaign").is_some())
        .cloned();
    if closing.is_some() {
        lines.pop();
    }
    assert!(
        lines.iter().all(|l| l.get("campaign").is_none()),
        "the closing line comes last, once: {stdout}"
    );
    Run {
        status: out.code,
        lines,
        closing,
        stdout,
        stderr,
    }
}

/// The lines without what depends on the machine (the wall time).
fn results(lines: &[Value]) -> Vec<Value> {
    lines
        .iter()
        .map(|l| {
            let mut l = l.clone();
            if let Some(o) = l.as_object_mut() {
                o.remove("wall_time_s");
            }
            l
        })
        .collect()
}

fn dir(name: &str) -> PathBuf {
    common::scratch_dir(&format!("campaign-{name}"))
}

fn write(dir: &Path, name: &str, text: &str) -> String {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p.to_str().unwrap().to_string()
}

/// A quad hovering 2 m up with the geometric law for `duration_s`, a true
/// mass and external force from the start (the values a campaign varies).
fn hover(duration_s: f64) -> String {
    format!(
        "airframe = \"quad\"\ncontroller = \"geometric\"\nduration_s = {duration_s:?}\n\
         [reference]\nkind = \"hover\"\nposition_ned = [0.0, 0.0, -2.0]\n\
         [[disturbance]]\nat_s = 0.0\nforce_ned = [0.0, 0.0, 0.0]\ntrue_mass_kg = 2.0\n"
    )
}

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

fn names(lines: &[Value]) -> Vec<String> {
    lines
        .iter()
        .map(|l| {
            Path::new(l["scenario"].as_str().unwrap())
                .file_name()
                .unwrap()
                .to_string_lossy()
                .into_owned()
        })
        .collect()
}

#[test]
fn a_directory_campaign_gives_one_line_per_file_in_input_order_whatever_the_jobs() {
    let d = dir("dir");
    // the longest first: with two jobs the second finishes first
    write(&d, "a-long.toml", &hover(4.0));
    write(&d, "b-short.toml", &hover(0.5));
    write(
        &d,
        "c-mid.toml",
        &hover(1.5).replace("[0.0, 0.0, 0.0]", "[0.3, 0.0, 0.0]"),
    );
    write(&d, "README.md", "not a scenario");
    let extra = write(&dir("dir-extra"), "z-first.toml", &hover(1.0));
    let ds = d.to_str().unwrap();
    let one = simulate(&[&extra, ds, "--json", "--jobs", "1"]);
    let two = simulate(&[&extra, ds, "--json", "--jobs", "2"]);
    assert_eq!(one.status, Some(0), "{}", one.stderr);
    assert_eq!(two.status, Some(0), "{}", two.stderr);
    assert_eq!(
        names(&two.lines),
        ["z-first.toml", "a-long.toml", "b-short.toml", "c-mid.toml"]
    );
    let idx: Vec<_> = two.lines.iter().map(|l| l["index"].as_u64().unwrap()).collect();
    assert_eq!(idx, [0, 1, 2, 3]);
    assert_eq!(results(&one.lines), results(&two.lines), "results depend on --jobs");
    // each line is the scenario's own summary (plain files: no values)
    assert!((f(&two.lines[1]["sim_time_s"]) - 4.0).abs() < 1e-9);
    assert!((f(&two.lines[2]["sim_time_s"]) - 0.5).abs() < 1e-9);
    assert_eq!(two.lines[0]["values"], serde_json::json!({}));
    assert_ne!(two.lines[3]["est_force_ned"], two.lines[1]["est_force_ned"]);
    assert!(
        two.stderr.contains("4 scenarios") && two.stderr.contains("2 jobs"),
        "{}",
        two.stderr
    );
    // one job is said in the singular, as one scenario is
    assert!(
        one.stderr.contains("4 scenarios") && one.stderr.contains(" on 1 job (") && !one.stderr.contains("1 jobs"),
        "{}",
        one.stderr
    );
    // text: one line per scenario, in order
    let text = run(&["simulate", &extra, ds]).stdout;
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 4, "{text}");
    assert!(
        lines[2].starts_with("2 ") && lines[2].contains("b-short.toml"),
        "{text}"
    );
}

/// A campaign of 10 entries: 3 files of a directory, a file of 2 x 3
/// variants, and a bad file.
fn ten_entries() -> Vec<String> {
    let d = dir("shards");
    for (name, t) in [("a.toml", 0.5), ("b.toml", 0.7), ("c.toml", 0.9)] {
        write(&d, name, &hover(t));
    }
    let other = dir("shards-files");
    let varied = write(
        &other,
        "varied.toml",
        &format!(
            "{}[campaign]\nseed = 5\ndraws = 3\n[campaign.grid]\n\"disturbance[1].true_mass_kg\" = [1.9, 2.1]\n\
             [campaign.random]\n\"disturbance[1].force_ned[2]\" = {{ uniform = [-0.5, 0.5] }}\n",
            hover(0.6)
        ),
    );
    let missing = other.join("missing.toml").to_str().unwrap().to_string();
    vec![d.to_str().unwrap().to_string(), varied, missing]
}

#[test]
fn shards_partition_the_campaign() {
    let args = ten_entries();
    let mut base: Vec<&str> = args.iter().map(String::as_str).collect();
    base.push("--json");
    let whole = simulate(&base);
    assert_eq!(whole.lines.len(), 10);
    assert_eq!(whole.status, Some(2), "the missing file: {}", whole.stderr);
    let mut seen = BTreeSet::new();
    for i in 0..3u64 {
        let shard = format!("{i}/3");
        let mut a = base.clone();
        a.extend(["--shard", &shard, "--jobs", "1"]);
        let part = simulate(&a);
        for l in &part.lines {
            let index = l["index"].as_u64().unwrap();
            assert_eq!(index % 3, i, "{l}");
            assert!(seen.insert(index), "entry {index} in two shards");
            assert_eq!(
                results(std::slice::from_ref(l)),
                results(&whole.lines[index as usize..=index as usize]),
                "entry {index} differs in shard {shard}"
            );
        }
        // the missing file is entry 9: only its shard fails
        assert_eq!(
            part.status,
            Some(if i == 0 { 2 } else { 0 }),
            "{shard}: {}",
            part.stderr
        );
        assert!(
            part.stderr.contains(&format!("shard {shard} of a campaign of 10")),
            "{}",
            part.stderr
        );
    }
    assert_eq!(seen, (0..10).collect::<BTreeSet<_>>(), "the shards cover the campaign");
    // the enumeration: files in order, a file's variants in order
    let variants: Vec<_> = whole.lines.iter().map(|l| l["variant"].as_u64()).collect();
    assert_eq!(
        variants,
        [
            Some(0),
            Some(0),
            Some(0),
            Some(0),
            Some(1),
            Some(2),
            Some(3),
            Some(4),
            Some(5),
            None
        ]
    );
    assert!(
        whole.lines[9]["error"]
            .as_str()
            .unwrap()
            .contains("missing.toml: cannot read")
    );
}

#[test]
fn a_true_mass_grid_shows_in_the_flights() {
    let d = dir("mass");
    let file = write(
        &d,
        "mass.toml",
        &format!(
            "{}[campaign.grid]\n\"disturbance[1].true_mass_kg\" = [1.6, 2.0, 2.4]\n",
            hover(6.0)
        ),
    );
    let run = simulate(&[&file, "--json"]);
    assert_eq!(run.status, Some(0), "{}", run.stderr);
    assert_eq!(run.lines.len(), 3);
    let mut sag = Vec::new();
    for (l, mass) in run.lines.iter().zip([1.6, 2.0, 2.4]) {
        assert_eq!(f(&l["values"]["disturbance[1].true_mass_kg"]), mass);
        assert!(l["scenario"].as_str().unwrap().ends_with("mass.toml"), "{l}");
        // the estimator finds the true mass the variant gave the plant
        assert!((f(&l["est_mass_kg"]) - mass).abs() < 0.01 * mass, "{l}");
        sag.push(f(&l["final_pos_err_ned"][2]));
    }
    // the geometric law has no integrator: (m - 2 kg) g / kp_z below (NED down > 0) the setpoint
    let kp_z = 12.5;
    for (s, mass) in sag.iter().zip([1.6, 2.0, 2.4]) {
        let expect = (mass - 2.0) * 9.80665 / kp_z;
        assert!((s - expect).abs() < 0.05, "sag {s} m for {mass} kg, expected {expect}");
    }
}

#[test]
fn seeded_random_disturbance_draws_are_applied_and_reproducible() {
    let d = dir("random");
    let campaign = |seed: u64| {
        write(
            &d,
            &format!("wind-{seed}.toml"),
            &format!(
                "{}[campaign]\nseed = {seed}\ndraws = 5\n[campaign.random]\n\
                 \"disturbance[1].force_ned[1]\" = {{ normal = [0.0, 0.5] }}\n\
                 \"disturbance[1].force_ned[2]\" = {{ uniform = [-0.5, 0.5] }}\n",
                hover(5.0)
            ),
        )
    };
    let file = campaign(42);
    let first = simulate(&[&file, "--json", "--jobs", "2"]);
    assert_eq!(first.status, Some(0), "{}", first.stderr);
    assert_eq!(first.lines.len(), 5);
    let mut drawn = BTreeSet::new();
    for l in &first.lines {
        let north = f(&l["values"]["disturbance[1].force_ned[1]"]);
        let east = f(&l["values"]["disturbance[1].force_ned[2]"]);
        assert!((-0.5..0.5).contains(&east), "{east}");
        drawn.insert(format!("{north} {east}"));
        // the estimator sees the force the draw applied
        assert!((f(&l["est_force_ned"][0]) - north).abs() < 0.02, "{l}");
        assert!((f(&l["est_force_ned"][1]) - east).abs() < 0.02, "{l}");
    }
    assert_eq!(drawn.len(), 5, "every draw differs");
    let again = simulate(&[&file, "--json", "--jobs", "1"]);
    assert_eq!(results(&first.lines), results(&again.lines), "a second run differs");
    // a shard's draws are the whole run's
    let odd = simulate(&[&file, "--json", "--shard", "1/2"]);
    assert_eq!(
        results(&odd.lines),
        results(&[first.lines[1].clone(), first.lines[3].clone()])
    );
    // another seed, other draws
    let other = simulate(&[&campaign(43), "--json"]);
    assert_ne!(other.lines[0]["values"], first.lines[0]["values"]);
}

#[test]
fn bad_shards_are_refused_clearly() {
    for (shard, says) in [
        ("3/3", "I must be below N"),
        ("0/0", "N must be at least 1"),
        ("x", "expected I/N"),
        ("1/", "not a whole number"),
        ("-1/2", "not a whole number"),
    ] {
        let run = simulate(&["tools/campaigns", &format!("--shard={shard}")]);
        assert_eq!(run.status, Some(2), "{shard} accepted");
        assert!(
            run.stderr.contains("--shard") && run.stderr.contains(says),
            "{shard}: {}",
            run.stderr
        );
    }
    let run = simulate(&["tools/campaigns", "--jobs", "0"]);
    assert_eq!(run.status, Some(2));
    assert!(run.stderr.contains("--jobs"), "{}", run.stderr);
    // a directory with no scenario is no campaign: 2 as well (1 only ever means a failed verdict)
    let empty = dir("empty");
    let run = simulate(&[empty.to_str().unwrap()]);
    assert_eq!(run.status, Some(2));
    assert!(run.stderr.contains("no scenario files"), "{}", run.stderr);
}

#[test]
fn bad_campaign_tables_and_variants_are_reported_and_the_rest_still_runs() {
    let d = dir("bad");
    let good = write(&d, "good.toml", &hover(0.5));
    let base = hover(0.5);
    let line = base.lines().count() + 2;
    let unknown = write(
        &d,
        "unknown.toml",
        &format!("{base}[campaign.grid]\n\"vehicle.mass_kg\" = [1.0, 2.0]\n"),
    );
    let dist = write(
        &d,
        "dist.toml",
        &format!("{base}[campaign]\ndraws = 2\n[campaign.random]\n\"duration_s\" = {{ gauss = [1.0, 0.1] }}\n"),
    );
    let range = write(
        &d,
        "range.toml",
        &format!("{base}[campaign.grid]\n\"disturbance[1].true_mass_kg\" = [2.0, -1.0]\n"),
    );
    let run = simulate(&[&good, &unknown, &dist, &range, "--json"]);
    assert_eq!(run.status, Some(2), "{}", run.stderr);
    assert_eq!(run.lines.len(), 5, "good, unknown, dist, range#0, range#1");
    assert!(run.lines[0]["error"].is_null() && run.lines[3]["error"].is_null());
    let e = run.lines[1]["error"].as_str().unwrap();
    assert!(
        e.contains(&format!("unknown.toml:{line}:"))
            && e.contains("campaign.grid.\"vehicle.mass_kg\"")
            && e.contains("has no `vehicle`"),
        "{e}"
    );
    assert!(run.lines[1]["variant"].is_null());
    let e = run.lines[2]["error"].as_str().unwrap();
    assert!(
        e.contains("dist.toml:")
            && e.contains("campaign.random.\"duration_s\"")
            && e.contains("unknown distribution `gauss`"),
        "{e}"
    );
    let e = run.lines[4]["error"].as_str().unwrap();
    assert!(
        e.contains("range.toml#1: disturbance[1].true_mass_kg: must be finite and > 0"),
        "{e}"
    );
    assert_eq!(run.lines[4]["variant"], 1);
    assert_eq!(f(&run.lines[4]["values"]["disturbance[1].true_mass_kg"]), -1.0);
    for needle in [
        "unknown.toml:",
        "dist.toml:",
        "range.toml#1",
        "2 ok, 0 missions failed, 3 errors",
    ] {
        assert!(run.stderr.contains(needle), "`{needle}` not in {}", run.stderr);
    }
}

#[test]
fn a_failed_mission_in_a_campaign_gives_exit_status_1() {
    let d = dir("mission");
    let good = write(&d, "good.toml", &hover(0.5));
    let short = write(
        &d,
        "short.toml",
        "duration_s = 5\n[mission]\n[[mission.item]]\ncommand = 16\nparams = [0.0, 1.0, 0.0, nan]\n\
         x = 47.3986\ny = 8.5456\nz = 20.0\n",
    );
    let run = simulate(&[&good, &short, "--json"]);
    assert_eq!(run.status, Some(1), "{}", run.stderr);
    assert_eq!(run.lines[1]["verdict"], "fail");
    assert!(
        run.stderr.contains("1 ok, 1 mission failed, 0 errors"),
        "{}",
        run.stderr
    );
    // an error as well: 2 wins
    let run = simulate(&[&good, &short, "no-such-file.toml", "--json"]);
    assert_eq!(run.status, Some(2));
}

#[test]
fn campaign_logs_go_into_a_directory_and_an_unchanged_variant_logs_the_same_bytes() {
    let d = dir("csv");
    let plain = write(&d, "plain.toml", &hover(0.8));
    let varied = write(
        &d,
        "varied.toml",
        &format!(
            "{}[campaign.grid]\n\"disturbance[1].true_mass_kg\" = [2.0, 2.2]\n",
            hover(0.8)
        ),
    );
    let logs = d.join("logs");
    let run = simulate(&[&plain, &varied, "--csv", logs.to_str().unwrap()]);
    assert_eq!(run.status, Some(0), "{}", run.stderr);
    let mut files: Vec<String> = std::fs::read_dir(&logs)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    files.sort();
    // each CSV with its sidecar saying what flew it (docs/logs.md)
    assert_eq!(
        files,
        [
            "0-plain.csv",
            "0-plain.csv.meta.json",
            "1-varied-v0.csv",
            "1-varied-v0.csv.meta.json",
            "2-varied-v1.csv",
            "2-varied-v1.csv.meta.json"
        ]
    );
    let read = |n: &str| std::fs::read(logs.join(n)).unwrap();
    // the variant is written back as TOML and read again: not a bit moves
    assert_eq!(read("0-plain.csv"), read("1-varied-v0.csv"));
    assert_ne!(read("1-varied-v0.csv"), read("2-varied-v1.csv"));
    // one file: --csv is the file, as ever
    let single = d.join("single.csv");
    let run = simulate(&[&plain, "--csv", single.to_str().unwrap()]);
    assert_eq!(run.status, Some(0));
    assert_eq!(std::fs::read(&single).unwrap(), read("0-plain.csv"));
}

#[test]
fn the_shipped_monte_carlo_campaign_has_16_reproducible_draws() {
    let file = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tools/campaigns/figure-eight-monte-carlo.toml"
    );
    let run = simulate(&[file, "--json", "--shard", "3/8"]);
    assert_eq!(run.status, Some(0), "{}", run.stderr);
    assert!(run.stderr.contains("shard 3/8 of a campaign of 16"), "{}", run.stderr);
    let idx: Vec<_> = run.lines.iter().map(|l| l["index"].as_u64().unwrap()).collect();
    assert_eq!(idx, [3, 11]);
    for l in &run.lines {
        let mass = f(&l["values"]["disturbance[1].true_mass_kg"]);
        assert!((1.8..2.2).contains(&mass));
        assert!((f(&l["est_mass_kg"]) - mass).abs() < 0.01, "{l}");
        assert!((f(&l["sim_time_s"]) - 60.0).abs() < 1e-9);
        assert_eq!(l["upright"], true);
    }
}

/// The shipped hover in drawn wind (`tools/campaigns/hover-wind-draws.toml`).
const WIND_DRAWS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tools/campaigns/hover-wind-draws.toml");

#[test]
fn the_shipped_wind_draws_fly_the_wind_each_line_names_on_any_job_count() {
    let whole = simulate(&[WIND_DRAWS, "--json", "--jobs", "2"]);
    assert_eq!(whole.status, Some(0), "{}", whole.stderr);
    assert_eq!(whole.lines.len(), 12);
    let mut drawn = BTreeSet::new();
    let mut by_speed = Vec::new();
    for l in &whole.lines {
        let v = &l["values"];
        let (speed, from) = (f(&v["wind.speed_m_s"]), f(&v["wind.from_deg"]));
        let turbulence = f(&v["wind.turbulence_m_s"]);
        assert!((2.0..10.0).contains(&speed) && (0.0..360.0).contains(&from), "{l}");
        assert!((0.0..0.5).contains(&turbulence), "{l}");
        drawn.insert(format!("{speed} {from} {turbulence}"));
        assert_eq!(l["upright"], true, "{l}");
        // the drag the estimator finds blows where the drawn wind does (to from + 180 deg)
        let force = [f(&l["est_force_ned"][0]), f(&l["est_force_ned"][1])];
        let towards = force[1].atan2(force[0]).to_degrees();
        let off = (towards - (from + 180.0) + 540.0).rem_euclid(360.0) - 180.0;
        assert!(
            off.abs() < 10.0,
            "force {force:?} points {towards} deg, the wind from {from} deg: {l}"
        );
        by_speed.push((speed, force[0].hypot(force[1])));
    }
    assert_eq!(drawn.len(), 12, "every draw differs");
    // a stronger wind pushes harder: the strongest draw's drag is over twice the weakest's
    by_speed.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (weak, strong) = (by_speed[0], by_speed[11]);
    assert!(strong.1 > 2.0 * weak.1, "{weak:?} vs {strong:?}");
    // the same draws and flights, bit for bit, on one job and in a shard
    let one = simulate(&[WIND_DRAWS, "--json", "--jobs", "1"]);
    assert_eq!(results(&whole.lines), results(&one.lines));
    let shard = simulate(&[WIND_DRAWS, "--json", "--shard", "2/5"]);
    let picked: Vec<Value> = [2, 7].iter().map(|&i| whole.lines[i].clone()).collect();
    assert_eq!(results(&shard.lines), results(&picked));
}

/// GIVEN the shipped wind grid (`tools/campaigns/mission-wind-grid.toml`:
/// the square mission, estimate fed back, 0 to 20 m/s from each quarter)
/// WHEN it is flown
/// THEN every variant up to 15 m/s passes (the worst within 1.1 m of the
/// 2 m allowed); at 17.5 m/s only the wind from the north fails (the 8 m/s
/// legs fly north and east into it); at 20 m/s from the north and east, not
/// from the south and west, as `docs/estimator.md` ("Flying in wind") says;
/// the campaign exits 1 for its failed variants.
#[test]
fn the_wind_grid_starts_to_fail_where_the_docs_say() {
    let file = concat!(env!("CARGO_MANIFEST_DIR"), "/tools/campaigns/mission-wind-grid.toml");
    let run = simulate(&[file, "--json", "--jobs", "2"]);
    assert_eq!(run.status, Some(1), "{}", run.stderr);
    assert_eq!(run.lines.len(), 28);
    let mut worst_calm_to_15: f64 = 0.0;
    let mut failed = Vec::new();
    for l in &run.lines {
        let (speed, from) = (
            f(&l["values"]["params.SIM_WIND_SPD"]),
            f(&l["values"]["params.SIM_WIND_DIR"]),
        );
        let pass = l["verdict"] == "pass";
        if speed <= 15.0 {
            assert!(pass, "{l}");
            worst_calm_to_15 = worst_calm_to_15.max(f(&l["max_tracking_error_m"]));
        } else if !pass {
            failed.push(format!("{speed} from {from}"));
        }
    }
    assert!(worst_calm_to_15 < 1.1, "{worst_calm_to_15}");
    failed.sort();
    assert_eq!(failed, ["17.5 from 0", "20 from 0", "20 from 90"]);
}

#[test]
fn a_bad_wind_draw_is_refused_naming_file_line_and_field() {
    let d = dir("wind-draws");
    let shipped = std::fs::read_to_string(WIND_DRAWS).unwrap().replace(
        "../airframes/",
        &format!("{}/tools/airframes/", env!("CARGO_MANIFEST_DIR")),
    );
    // a spec the table cannot draw from: refused before any flight, at its line
    for (from, to, key, says) in [
        (
            "{ uniform = [2.0, 10.0] }",
            "{ uniform = [10.0, 2.0] }",
            "\"wind.speed_m_s\"",
            "uniform = [a, b] needs two finite numbers a < b",
        ),
        (
            "\"wind.speed_m_s\"",
            "\"wind.speed\"",
            "\"wind.speed\"",
            "`wind` has no `speed`",
        ),
        (
            "{ uniform = [0.0, 0.5] }",
            "{ choice = [\"moderate\"] }",
            "\"wind.turbulence_m_s\"",
            "must be a float as in the file, got a string",
        ),
    ] {
        let text = shipped.replace(from, to);
        assert_ne!(text, shipped, "{from}");
        let file = write(&d, "bad.toml", &text);
        let line = 1 + text.lines().position(|l| l.starts_with(&format!("{key} ="))).unwrap();
        let run = simulate(&[&file, "--json"]);
        assert_eq!(run.status, Some(2), "{}", run.stderr);
        assert_eq!(run.lines.len(), 1, "one error for the file, no flight: {:?}", run.lines);
        let e = run.lines[0]["error"].as_str().unwrap();
        let head = format!("{file}:{line}:1: campaign.random.{key}: {says}");
        assert!(e.starts_with(&head), "{e}\nnot {head}");
        assert!(run.stderr.contains(&head), "{}", run.stderr);
    }
    // a draw the wind refuses (a negative speed) fails its variant only, naming the value
    let text = shipped.replace("{ uniform = [2.0, 10.0] }", "{ normal = [0.0, 3.0] }");
    let file = write(&d, "negative.toml", &text);
    let run = simulate(&[&file, "--json"]);
    assert_eq!(run.status, Some(2), "{}", run.stderr);
    let (bad, good): (Vec<&Value>, Vec<&Value>) = run.lines.iter().partition(|l| l["error"].is_string());
    assert!(!bad.is_empty() && !good.is_empty(), "{:?}", run.lines);
    for l in bad {
        let speed = f(&l["values"]["wind.speed_m_s"]);
        assert!(speed < 0.0, "{l}");
        let e = l["error"].as_str().unwrap();
        let says = format!(
            "{file}#{}: wind.speed_m_s: must be a finite number >= 0, got {speed}",
            l["variant"]
        );
        assert_eq!(e, says);
    }
}

#[test]
fn a_mission_campaign_varies_a_px4_parameter() {
    let d = dir("mission-params");
    let square = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tools/scenarios/mission-square.toml"
    ))
    .unwrap();
    let file = write(
        &d,
        "square.toml",
        &format!("{square}\n[campaign.grid]\n\"params.MPC_XY_CRUISE\" = [4, 12.0]\n"),
    );
    let run = simulate(&[&file, "--json"]);
    assert_eq!(run.status, Some(0), "{}", run.stderr);
    assert_eq!(run.lines.len(), 2);
    assert_eq!(
        run.lines[0]["values"]["params.MPC_XY_CRUISE"], 4.0,
        "an integer where the file has a float"
    );
    assert!(run.lines.iter().all(|l| l["verdict"] == "pass"));
    // faster cruise, shorter mission
    let (slow, fast) = (f(&run.lines[0]["mission_time_s"]), f(&run.lines[1]["mission_time_s"]));
    assert!(slow > fast + 5.0, "{slow} s at 4 m/s, {fast} s at 12 m/s");
}

/// A campaign file whose own values are wrong: the `[campaign]` table sits
/// between `[reference]` and `[[disturbance]]`, and the disturbance has an
/// unknown key on line 15 of the file (line 11 of the TOML a variant is
/// written as, were it read there).
fn with_unknown_key(campaign: &str) -> String {
    format!(
        "airframe = \"quad\"\ncontroller = \"geometric\"\nduration_s = 0.5\n\
         [reference]\nkind = \"hover\"\nposition_ned = [0.0, 0.0, -2.0]\n\
         {campaign}\
         [[disturbance]]\nat_s = 0.0\nforce_ned = [0.0, 0.0, 0.0]\ntrue_mass_kg = 2.0\nthrust_kg = 1.0\n"
    )
}

#[test]
fn an_error_in_a_campaign_files_own_values_names_its_line_once() {
    let d = dir("base");
    let table = "[campaign]\nseed = 1\n[campaign.grid]\n\"disturbance[1].true_mass_kg\" = [1.8, 2.0, 2.2]\n";
    let varied = write(&d, "varied.toml", &with_unknown_key(table));
    // the same file without the table: 4 lines fewer above the error
    let plain = write(&d, "plain.toml", &with_unknown_key(""));
    let run = simulate(&[&varied, &plain, "--json"]);
    assert_eq!(run.status, Some(2), "{}", run.stderr);
    assert_eq!(
        run.lines.len(),
        2,
        "one entry per file, not one per variant: {:?}",
        run.lines
    );
    let (ev, ep) = (
        run.lines[0]["error"].as_str().unwrap(),
        run.lines[1]["error"].as_str().unwrap(),
    );
    assert!(run.lines[0]["variant"].is_null(), "{}", run.lines[0]);
    assert!(ev.starts_with(&format!("{varied}:15:")), "the file's own line: {ev}");
    assert!(ep.starts_with(&format!("{plain}:11:")), "a plain file as before: {ep}");
    assert!(ev.contains("unknown field `thrust_kg`"), "{ev}");
    // the same message but for the file and the line
    let rest = |e: &str| e.splitn(4, ':').nth(3).unwrap().to_string();
    assert_eq!(rest(ev), rest(ep));
    assert_eq!(
        run.stderr.matches("unknown field `thrust_kg`").count(),
        2,
        "{}",
        run.stderr
    );
    assert!(!run.stderr.contains("varied.toml#"), "{}", run.stderr);
    // the table's own lines still count: an error in it names its line
    let bad = write(
        &d,
        "bad.toml",
        &with_unknown_key("[campaign.grid]\n\"disturbance[1].mass\" = [1.8]\n"),
    );
    let run = simulate(&[&bad, "--json"]);
    let e = run.lines[0]["error"].as_str().unwrap();
    assert!(
        e.starts_with(&format!("{bad}:8:")) && e.contains("has no `mass`"),
        "{e}"
    );
}

#[test]
fn a_variant_whose_value_the_scenario_refuses_names_the_value_not_a_line() {
    let d = dir("typed");
    // the grid fits the file's integer, but a seed is unsigned
    let file = write(
        &d,
        "seed.toml",
        &format!("seed = 0\n{}[campaign.grid]\n\"seed\" = [1, -1]\n", hover(0.5)),
    );
    let run = simulate(&[&file, "--json"]);
    assert_eq!(run.status, Some(2), "{}", run.stderr);
    assert_eq!(run.lines.len(), 2);
    assert!(run.lines[0]["error"].is_null(), "{}", run.lines[0]);
    let e = run.lines[1]["error"].as_str().unwrap();
    assert!(
        e.starts_with(&format!("{file}#1: seed = -1: invalid value: integer `-1`")),
        "{e}"
    );
}

#[test]
fn an_airframe_error_is_said_once() {
    let d = dir("airframe");
    let said = "unknown airframe `nope`";
    let base = write(&d, "base.toml", &hover(0.5).replace("\"quad\"", "\"nope\""));
    let varied = write(
        &d,
        "varied.toml",
        &format!("{}[campaign.grid]\n\"airframe\" = [\"quad\", \"nope\"]\n", hover(0.5)),
    );
    for (args, n) in [(vec![&base], 1), (vec![&varied], 1), (vec![&base, &varied], 2)] {
        let mut args: Vec<&str> = args.iter().map(|s| s.as_str()).collect();
        args.push("--json");
        let run = simulate(&args);
        let errors: Vec<&str> = run.lines.iter().filter_map(|l| l["error"].as_str()).collect();
        assert_eq!(errors.len(), n, "{:?}", run.lines);
        for e in errors {
            assert_eq!(e.matches(said).count(), 1, "said once: {e}");
        }
    }
    // a single file, as `rotorpilot simulate FILE` always reported it
    let run = simulate(&[&base]);
    assert_eq!(run.stderr.matches(said).count(), 1, "{}", run.stderr);
}

/// `rotorpilot merge FILES...`, each file's text written first; the exit
/// status, stdout and stderr.
fn merge(dir: &Path, shards: &[(&str, &str)]) -> common::bin::Ran {
    let paths: Vec<String> = shards.iter().map(|(name, text)| write(dir, name, text)).collect();
    let args: Vec<&str> = std::iter::once("merge")
        .chain(paths.iter().map(String::as_str))
        .collect();
    let out = run(&args);
    assert!(!out.stderr.contains("panicked"), "{}", out.stderr);
    out
}

/// The whole campaign's lines and each shard's output, `--shard I/3`, flown
/// by the binary: ten entries (one an error) and a mission that fails.
fn whole_and_three_shards() -> (Run, Vec<String>) {
    let mut args = ten_entries();
    args.push(write(
        &dir("merge-mission"),
        "short.toml",
        "duration_s = 5\n[mission]\n[[mission.item]]\ncommand = 16\nparams = [0.0, 1.0, 0.0, nan]\n\
         x = 47.3986\ny = 8.5456\nz = 20.0\n",
    ));
    let mut base: Vec<&str> = args.iter().map(String::as_str).collect();
    base.extend(["--json", "--jobs", "2"]);
    let whole = simulate(&base);
    let shards = (0..3)
        .map(|i| {
            let shard = format!("{i}/3");
            let mut a = base.clone();
            a.extend(["--shard", &shard]);
            let part = simulate(&a);
            assert!(
                part.closing.is_some(),
                "shard {shard} has no closing line: {}",
                part.stdout
            );
            part.stdout
        })
        .collect();
    (whole, shards)
}

#[test]
fn merged_shards_are_the_whole_campaign_field_for_field() {
    let (whole, shards) = whole_and_three_shards();
    assert_eq!(whole.lines.len(), 11);
    assert_eq!(whole.status, Some(2), "the missing file: {}", whole.stderr);
    let closing = whole.closing.clone().expect("the whole campaign's closing line");
    assert_eq!(closing["shard"], "0/1");
    assert_eq!(closing["entries"], 11);
    assert_eq!(
        (&closing["ok"], &closing["failed"], &closing["errors"]),
        (&9.into(), &1.into(), &1.into())
    );
    assert_eq!(closing["campaign"].as_str().map(str::len), Some(16), "{closing}");
    let d = dir("merge-ok");
    // in any order
    let out = merge(
        &d,
        &[
            ("s2.jsonl", shards[2].as_str()),
            ("s0.jsonl", shards[0].as_str()),
            ("s1.jsonl", shards[1].as_str()),
        ],
    );
    assert_eq!(
        out.code, whole.status,
        "the whole campaign's exit status: {}",
        out.stderr
    );
    let merged: Vec<Value> = out.stdout.lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(merged.len(), 12);
    // every field but the wall time, and the closing line whole
    assert_eq!(results(&merged[..11]), results(&whole.lines));
    assert_eq!(merged[11], closing);
    // each entry line is the shard's, byte for byte
    for line in out.stdout.lines().take(11) {
        assert!(shards.iter().any(|s| s.lines().any(|l| l == line)), "{line}");
    }
    // the cause in the log: the failed mission and the error, then the tally
    for needle in [
        "entry 9: ",
        "missing.toml: cannot read",
        "entry 10: ",
        "\"verdict\":\"fail\"",
        "11 scenarios from 3 shards of campaign",
        "9 ok, 1 missions failed, 1 errors",
    ] {
        assert!(out.stderr.contains(needle), "`{needle}` not in {}", out.stderr);
    }
    // a campaign with no error: the failed mission gives 1, as unsharded
    let d2 = dir("merge-fail");
    let good = write(&d2, "good.toml", &hover(0.5));
    let short = write(
        &d2,
        "short.toml",
        "duration_s = 5\n[mission]\n[[mission.item]]\ncommand = 16\nparams = [0.0, 1.0, 0.0, nan]\n\
         x = 47.3986\ny = 8.5456\nz = 20.0\n",
    );
    let parts: Vec<String> = ["0/2", "1/2"]
        .iter()
        .map(|s| simulate(&[&good, &short, "--json", "--shard", s]).stdout)
        .collect();
    let out = merge(&d2, &[("a.jsonl", parts[0].as_str()), ("b.jsonl", parts[1].as_str())]);
    assert_eq!(out.code, Some(1), "{}", out.stderr);
    assert_eq!(simulate(&[&good, &short, "--json"]).status, Some(1));
    // and the whole campaign's own output is its own merge
    let out = merge(
        &d2,
        &[(
            "whole.jsonl",
            simulate(&[&good, "--json", "--shard", "0/1"]).stdout.as_str(),
        )],
    );
    assert_eq!(out.code, Some(0), "{}", out.stderr);
}

#[test]
fn merge_refuses_shards_that_do_not_make_one_campaign() {
    let (_, shards) = whole_and_three_shards();
    let d = dir("merge-refused");
    // another campaign: the same entries with one file edited
    let other_dir = dir("merge-other");
    let a = write(&other_dir, "a.toml", &hover(0.5));
    let b = write(&other_dir, "b.toml", &hover(0.6));
    let other = |shard: &str| simulate(&[&a, &b, "--json", "--shard", shard]).stdout;
    let other0 = other("0/2");
    write(&other_dir, "b.toml", &hover(0.7));
    let other1 = other("1/2");
    let single = simulate(&[&a, "--json"]).stdout;
    let text = run(&["simulate", &a, &b, "--shard", "0/1"]).stdout;
    let cut: String = shards[1].lines().take(2).map(|l| format!("{l}\n")).collect();
    let bad_field = shards[1].replace("\"shard\":\"1/3\"", "\"shard\":\"one\"");
    for (list, says) in [
        (
            vec![("x0.jsonl", other0.as_str()), ("x1.jsonl", other1.as_str())],
            "shards of different campaigns: ",
        ),
        (
            vec![("s0.jsonl", shards[0].as_str()), ("s2.jsonl", shards[2].as_str())],
            "shard 1/3 missing (given: 0/3 in ",
        ),
        (
            vec![
                ("s0.jsonl", shards[0].as_str()),
                ("s1.jsonl", shards[1].as_str()),
                ("again.jsonl", shards[1].as_str()),
                ("s2.jsonl", shards[2].as_str()),
            ],
            "shard 1/3 given twice: ",
        ),
        (
            vec![
                ("s0.jsonl", shards[0].as_str()),
                ("x1.jsonl", other1.as_str()),
                ("s2.jsonl", shards[2].as_str()),
            ],
            "shards of different campaigns: ",
        ),
        // one scenario's summary: an entry, but no campaign's closing line
        (
            vec![("single.json", single.as_str())],
            "single.json: no closing line (field `campaign`) after its 1 entries",
        ),
        (
            vec![("summary.json", "{\"scenario\": \"a.toml\", \"verdict\": \"pass\"}\n")],
            "summary.json:1: neither an entry (field `index`) nor the closing line (field `campaign`)",
        ),
        (vec![("text.txt", text.as_str())], "text.txt:1: not JSON"),
        (
            vec![
                ("s0.jsonl", shards[0].as_str()),
                ("cut.jsonl", cut.as_str()),
                ("s2.jsonl", shards[2].as_str()),
            ],
            "cut.jsonl: no closing line",
        ),
        (
            vec![
                ("s0.jsonl", shards[0].as_str()),
                ("field.jsonl", bad_field.as_str()),
                ("s2.jsonl", shards[2].as_str()),
            ],
            "field.jsonl:5: closing line: field `shard`: `one`",
        ),
    ] {
        let out = merge(&d, &list);
        assert_eq!(out.code, Some(2), "{says}: {}", out.stderr);
        assert!(out.stdout.is_empty(), "nothing merged: {}", out.stdout);
        assert!(
            out.stderr.contains("merge refused: ") && out.stderr.contains(says),
            "want `{says}`, got: {}",
            out.stderr
        );
        // the file the problem is in, named with its directory
        if let Some((name, _)) = list.iter().find(|(n, _)| says.starts_with(n)) {
            assert!(
                out.stderr.contains(&d.join(name).display().to_string()),
                "{}",
                out.stderr
            );
        }
    }
    // the campaign ids differ where the files do, and the different shards are named
    let out = merge(&d, &[("x0.jsonl", other0.as_str()), ("x1.jsonl", other1.as_str())]);
    assert!(
        out.stderr.contains("x0.jsonl is campaign ") && out.stderr.contains("x1.jsonl is campaign "),
        "{}",
        out.stderr
    );
    let missing = run(&["merge", d.join("nope.jsonl").to_str().unwrap()]);
    assert_eq!(missing.code, Some(2));
    assert!(missing.stderr.contains("nope.jsonl: cannot read"), "{}", missing.stderr);
}
