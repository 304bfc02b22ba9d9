//! Exact replay: a flight driven through the daemon by a MAVLink
//! client on UDP, with `--log-dir` and `--log-csv`, replays from its
//! `flight.record` to the live `flight.csv` byte for byte (twice, and with a
//! reboot and parameter changes in it); a record cut off by a kill replays
//! to its last input; bad records (and a record from another rotorpilot
//! version, without `--any-version`) and an unusable log directory get
//! clear errors, never a panic.
#![allow(deprecated)]

mod common;

use std::path::{Path, PathBuf};
use std::time::Duration;

use common::daemon::{Client, Vehicle, config, wait_armable};
use common::scratch_path;
use mavlink::dialects::common::*;
use rotorpilot::logs::record::read_record;
use rotorpilot::logs::replay::replay;

const ACCEPTED: u8 = 0;

async fn set_param(c: &mut Client, to: std::net::SocketAddr, id: &str, value: f32, kind: MavParamType) {
    c.param_set(to, id, value, kind).await;
    c.wait_for(Duration::from_secs(3), |r| match &r.msg {
        Some(MavMessage::PARAM_VALUE(p)) if p.param_id.to_str().unwrap() == id => Some(()),
        _ => None,
    })
    .await
    .expect("PARAM_VALUE");
}

/// This run's directory below `base` (exactly one).
fn run_dir(base: &Path) -> PathBuf {
    let runs: Vec<PathBuf> = std::fs::read_dir(base).unwrap().map(|e| e.unwrap().path()).collect();
    assert_eq!(runs.len(), 1, "{runs:?}");
    runs[0].clone()
}

fn replay_csv(record: &Path) -> (Vec<u8>, rotorpilot::logs::replay::ReplaySummary) {
    let text = std::fs::read_to_string(record).unwrap();
    let r = read_record(&text, "flight.record").unwrap();
    let mut csv = Vec::new();
    let s = replay(&r, "flight.record", Some(&mut csv)).unwrap();
    (csv, s)
}

/// Fly at `speed`: a parameter change and a reboot on the ground, another
/// parameter (one refused), arm, take off, a reposition, hover; then stop
/// cleanly. The run directory.
async fn fly(speed: f64) -> PathBuf {
    let logs = scratch_path("replay-logs");
    let mut c = Client::new().await;
    let mut cfg = config(Some(c.addr()), None, speed);
    cfg.log_dir = Some(logs.clone());
    cfg.log_csv = true;
    let v = Vehicle::start(cfg).await;
    c.heartbeat(v.gcs).await;
    set_param(
        &mut c,
        v.gcs,
        "MPC_Z_VEL_MAX_UP",
        2.0,
        MavParamType::MAV_PARAM_TYPE_REAL32,
    )
    .await;
    // a reboot: the vehicle restarts from the parameters in force
    assert_eq!(
        c.command(v.gcs, 246, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]).await.result,
        ACCEPTED
    );
    set_param(
        &mut c,
        v.gcs,
        "MIS_TAKEOFF_ALT",
        4.0,
        MavParamType::MAV_PARAM_TYPE_REAL32,
    )
    .await;
    // refused (out of range): recorded all the same
    set_param(
        &mut c,
        v.gcs,
        "MPC_XY_VEL_MAX",
        1e6,
        MavParamType::MAV_PARAM_TYPE_REAL32,
    )
    .await;
    c.heartbeat(v.gcs).await;
    wait_armable(&mut c).await;
    assert_eq!(
        c.command(v.gcs, 400, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]).await.result,
        ACCEPTED
    );
    assert_eq!(c.command(v.gcs, 22, [0.0; 7]).await.result, ACCEPTED);
    for _ in 0..5 {
        c.heartbeat(v.gcs).await;
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    let home = rotorpilot::geo::GeoPoint::PX4_SITL_HOME;
    let reposition = [
        -1.0,
        1.0,
        0.0,
        f32::NAN,
        (home.lat_deg + 3e-5) as f32,
        home.lon_deg as f32,
        495.0,
    ];
    assert_eq!(c.command(v.gcs, 192, reposition).await.result, ACCEPTED);
    for _ in 0..5 {
        c.heartbeat(v.gcs).await;
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    v.stop().await;
    run_dir(&logs)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_flight_with_a_reboot_replays_byte_for_byte() {
    let run = fly(20.0).await;
    let record = run.join("flight.record");
    let live = std::fs::read(run.join("flight.csv")).unwrap();
    let text = std::fs::read_to_string(&record).unwrap();
    for kind in [
        "\"reboot\"",
        "\"set_param\"",
        "\"gcs_heartbeat\"",
        "\"Takeoff\"",
        "\"Reposition\"",
        "\"end\"",
    ] {
        assert!(text.contains(kind), "{kind} missing from the record");
    }
    assert!(
        text.contains("Err("),
        "the refused parameter is recorded with its refusal"
    );
    let (a, s) = replay_csv(&record);
    let (b, _) = replay_csv(&record);
    assert!(s.complete);
    assert!(s.steps > 10_000, "{s:?}");
    assert_eq!(live.iter().filter(|&&b| b == b'\n').count() as u64, s.steps + 1);
    assert!(a == b, "two replays differ");
    assert!(a == live, "the replay differs from the live flight.csv");
    assert!(s.armed, "it hovers at the end: {s:?}");
    // flight.csv has its sidecar saying what flew it, and `replay --csv` writes the same
    let live_meta = rotorpilot::logs::meta::LogMeta::read_beside(&run.join("flight.csv"))
        .unwrap()
        .expect("--log-csv writes flight.csv.meta.json");
    assert_eq!((live_meta.airframe.as_str(), live_meta.step_s), ("quad", 0.001));
    assert!(
        live_meta.producer.ends_with("daemon --log-csv"),
        "{}",
        live_meta.producer
    );
    let out_csv = run.join("replayed.csv");
    let o = common::bin::rotorpilot()
        .args(["replay", record.to_str().unwrap(), "--csv", out_csv.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let replay_meta = rotorpilot::logs::meta::LogMeta::read_beside(&out_csv).unwrap().unwrap();
    assert_eq!(
        (replay_meta.nominal(), &replay_meta.estimator, &replay_meta.airframe),
        (live_meta.nominal(), &live_meta.estimator, &live_meta.airframe)
    );
    // the replay's ULog is the live flight.ulg, record for record (topic
    // samples, parameter changes, status texts at the instants they were
    // raised, the reboot's among them)
    let r = read_record(&text, "flight.record").unwrap();
    let mut ulg = Vec::new();
    rotorpilot::logs::replay::replay_logs(&r, "flight.record", None, Some(&mut ulg)).unwrap();
    let live_ulg = ulog_records(&std::fs::read(run.join("flight.ulg")).unwrap());
    let replay_ulg = ulog_records(&ulg);
    let count = |recs: &[(u8, Vec<u8>)], kind: u8| recs.iter().filter(|(t, _)| *t == kind).count();
    assert!(count(&live_ulg, b'D') > 1000, "{}", count(&live_ulg, b'D'));
    assert!(
        live_ulg
            .iter()
            .any(|(t, p)| *t == b'L' && p.windows(10).any(|w| w == b"Rebooted: ")),
        "the reboot is announced in flight.ulg"
    );
    // (the daemon writes a status text when it publishes, a batch of steps
    // later, the replay after the step that raised it: the same records,
    // interleaved differently, so each kind is compared as its own sequence)
    for kind in [b'D', b'P', b'L', b'F', b'A', b'I', b'B'] {
        let of = |recs: &[(u8, Vec<u8>)]| -> Vec<Vec<u8>> {
            recs.iter()
                .filter(|(t, _)| *t == kind)
                .map(|(_, p)| p.clone())
                .collect()
        };
        assert!(
            of(&live_ulg) == of(&replay_ulg),
            "the replay's ULog records '{}' differ from flight.ulg's",
            kind as char
        );
    }
    let params = rotorpilot::params::ParamStore::new(&rotorpilot::airframe::Airframe::load("quad").unwrap())
        .iter()
        .count();
    // every parameter at start, then the two accepted changes
    assert!(
        count(&live_ulg, b'P') >= params + 2,
        "{} parameters logged, {params} at start",
        count(&live_ulg, b'P')
    );
    assert!(count(&live_ulg, b'L') > 0, "no status text in flight.ulg");
    let _ = std::fs::remove_dir_all(run.parent().unwrap());
}

/// A ULog's records after its 16-byte header: (type, payload) of each
/// (`u16` size, `u8` type, payload: the ULog file format).
fn ulog_records(b: &[u8]) -> Vec<(u8, Vec<u8>)> {
    assert_eq!(&b[..7], b"ULog\x01\x12\x35", "not a ULog");
    let (mut at, mut out) = (16, Vec::new());
    while at + 3 <= b.len() {
        let size = usize::from(u16::from_le_bytes([b[at], b[at + 1]]));
        let kind = b[at + 2];
        out.push((kind, b[at + 3..at + 3 + size].to_vec()));
        at += 3 + size;
    }
    assert_eq!(at, b.len(), "a record cut short");
    out
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_record_without_its_end_replays_to_its_last_input() {
    let run = fly(20.0).await;
    let record = run.join("flight.record");
    let text = std::fs::read_to_string(&record).unwrap();
    // as a killed daemon leaves it: no end line
    let cut: String = text
        .lines()
        .filter(|l| !l.starts_with("{\"end\""))
        .map(|l| format!("{l}\n"))
        .collect();
    let r = read_record(&cut, "cut.record").unwrap();
    assert_eq!(r.end, None);
    let last = r.inputs.last().unwrap().step;
    let mut csv = Vec::new();
    let s = replay(&r, "cut.record", Some(&mut csv)).unwrap();
    assert_eq!(s.steps, last);
    assert!(!s.complete);
    // the live CSV's first rows, exactly
    let live = std::fs::read(run.join("flight.csv")).unwrap();
    assert!(live.starts_with(&csv) && live.len() > csv.len());
    // the CLI says so on stderr
    std::fs::write(run.join("cut.record"), &cut).unwrap();
    let out = common::bin::rotorpilot()
        .arg("replay")
        .arg(run.join("cut.record"))
        .output()
        .unwrap();
    assert!(out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("has no end line"));
    let _ = std::fs::remove_dir_all(run.parent().unwrap());
}

/// `rotorpilot replay FILE`'s exit status and stderr.
fn cli_replay(file: &Path) -> (bool, String) {
    let out = common::bin::rotorpilot().arg("replay").arg(file).output().unwrap();
    (out.status.success(), String::from_utf8_lossy(&out.stderr).into_owned())
}

#[test]
fn bad_records_get_clear_errors() {
    let dir = scratch_path("bad-records");
    std::fs::create_dir_all(&dir).unwrap();
    let a = rotorpilot::airframe::Airframe::load("quad").unwrap();
    let header = rotorpilot::logs::record::Header::new(
        rotorpilot::airframe::Airframe::load_text("quad").unwrap(),
        rotorpilot::geo::GeoPoint::PX4_SITL_HOME,
        &rotorpilot::params::ParamStore::new(&a),
        &rotorpilot::mission::Plans::default(),
        rotorpilot::sim::SensorConfig::default(),
        rotorpilot::autopilot::ClientClock::Simulated,
        rotorpilot::signals::DEFAULT_STEP_S,
    );
    let h = rotorpilot::logs::record::header_line(&header).unwrap();
    let arm = rotorpilot::logs::record::input_line(
        10,
        &rotorpilot::lockstep::input::Input::Command(rotorpilot::autopilot::AutopilotCommand::Arm { force: false }),
        "x",
    )
    .unwrap();
    let cases: Vec<(&str, String, String)> = vec![
        (
            "v2.record",
            format!("{}\n", h.replacen("\"version\":1", "\"version\":2", 1)),
            format!(
                "v2.record: format version 2, this rotorpilot reads version 1 (rotorpilot {})",
                env!("CARGO_PKG_VERSION")
            ),
        ),
        (
            "cut.record",
            format!("{h}\n{}", &arm[..20]),
            "cut.record:2: cut short".into(),
        ),
        (
            "bad.record",
            format!("{h}\nhello\n"),
            "bad.record:2: not a record line".into(),
        ),
        ("empty.record", String::new(), "empty.record: empty file".into()),
        ("other.txt", "a,b,c\n".into(), "other.txt: not a flight record".into()),
    ];
    for (name, text, want) in cases {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        let (ok, err) = cli_replay(&p);
        assert!(!ok, "{name} replayed");
        assert!(err.contains(&want), "{name}: {err}");
        assert!(!err.contains("panicked"), "{err}");
    }
    // an input whose live outcome differs: the replay says where it diverged
    let p = dir.join("diverged.record");
    std::fs::write(&p, format!("{h}\n{arm}\n")).unwrap();
    let (ok, err) = cli_replay(&p);
    assert!(
        !ok && err.contains("diverged.record:2: the replay diverged at step 10"),
        "{err}"
    );
    // another rotorpilot version: refused naming both, replayed with --any-version
    let other = h.replacen(
        &format!("\"rotorpilot\":\"{}\"", env!("CARGO_PKG_VERSION")),
        "\"rotorpilot\":\"0.0.9-other\"",
        1,
    );
    assert_ne!(other, h);
    let p = dir.join("other-version.record");
    std::fs::write(&p, format!("{other}\n")).unwrap();
    let (ok, err) = cli_replay(&p);
    assert!(!ok, "another version's record replayed: {err}");
    assert!(
        err.contains(&format!(
            "other-version.record: written by rotorpilot 0.0.9-other, this is rotorpilot {}",
            env!("CARGO_PKG_VERSION")
        )) && err.contains("--any-version"),
        "{err}"
    );
    let out = common::bin::rotorpilot()
        .args(["replay", "--any-version"])
        .arg(&p)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("warning") && err.contains("0.0.9-other"), "{err}");
    let (ok, err) = cli_replay(&dir.join("missing.record"));
    assert!(
        !ok && err.contains("cannot read") && err.contains("missing.record"),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[tokio::test]
async fn an_unusable_log_dir_is_refused_at_start_with_its_path() {
    let dir = scratch_path("not-a-dir");
    std::fs::create_dir_all(&dir).unwrap();
    // a file where the log directory should be (root ignores permissions)
    let file = dir.join("plain-file");
    std::fs::write(&file, "x").unwrap();
    let mut cfg = config(None, None, 1.0);
    cfg.log_dir = Some(file.join("logs"));
    let e = rotorpilot::daemon::bind(cfg).await.expect_err("bind must fail");
    let msg = format!("{e:#}");
    assert!(msg.contains(&file.join("logs").display().to_string()), "{msg}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A record of the shipped square (the mission stored at start, started as
/// `simulate` starts it), written into a scratch directory named for `tag`:
/// the directory and the record's path.
fn square_record(tag: &str) -> (PathBuf, PathBuf) {
    use rotorpilot::autopilot::{AutopilotCommand, ClientClock};
    use rotorpilot::lockstep::input::{Input, apply};
    use rotorpilot::logs::record::{Header, end_line, header_line, input_line};

    let scenario = "tools/scenarios/mission-square.toml";
    let f = rotorpilot::scenario::MissionFlight::from_file(Path::new(scenario)).unwrap();
    let stored = rotorpilot::scenario::mission_lockstep(&f).unwrap();
    let header = Header::new(
        rotorpilot::airframe::Airframe::load_text("quad").unwrap(),
        f.home,
        &f.params,
        stored.pilot(0).plans(),
        f.sensors,
        ClientClock::Simulated,
        rotorpilot::signals::DEFAULT_STEP_S,
    );
    // the mission started on the first step whose prearm checks pass, as simulate starts it
    let (mut core, mut params) = header.build().unwrap();
    let start = Input::Command(AutopilotCommand::StartMission { first: Some(0) });
    let outcome = loop {
        core.step();
        if core.telemetry(0).prearm_ok {
            break apply(&mut core, 0, &mut params, &start).text();
        }
    };
    let text = format!(
        "{}\n{}\n{}\n",
        header_line(&header).unwrap(),
        input_line(core.steps(), &start, &outcome).unwrap(),
        end_line(90_000)
    );
    let dir = scratch_path(tag);
    std::fs::create_dir_all(&dir).unwrap();
    let record = dir.join("flight.record");
    std::fs::write(&record, text).unwrap();
    (dir, record)
}

/// `rotorpilot replay` prints the per-item summary `simulate` gives: a
/// record of the shipped square (the mission stored at start, started as
/// `simulate` starts it) replays to the same item lines and tracking error
/// as `rotorpilot simulate` prints for that scenario.
#[test]
fn replay_prints_the_per_item_summary_simulate_gives() {
    let scenario = "tools/scenarios/mission-square.toml";
    let (dir, record) = square_record("replay-items");

    let replayed = common::bin::run(&["replay", record.to_str().unwrap()]);
    assert!(replayed.ok(), "{}", replayed.stderr);
    let simulated = common::bin::run(&["simulate", scenario]);
    let items = |out: &str| -> Vec<String> {
        out.lines()
            .filter(|l| l.starts_with("  item "))
            .map(str::to_string)
            .collect()
    };
    assert_eq!(items(&replayed.stdout).len(), 7, "{}", replayed.stdout);
    assert_eq!(items(&replayed.stdout), items(&simulated.stdout), "{}", replayed.stdout);
    assert!(replayed.stdout.contains("mission: 7 items\n"), "{}", replayed.stdout);
    let tracking = |out: &str| {
        out.lines()
            .find(|l| l.starts_with("tracking error: "))
            .and_then(|l| l.split(';').next())
            .map(str::to_string)
    };
    assert_eq!(
        tracking(&replayed.stdout),
        tracking(&simulated.stdout),
        "{}",
        replayed.stdout
    );
    let json = common::bin::run(&["replay", record.to_str().unwrap(), "--json"]);
    let v: serde_json::Value = serde_json::from_str(&json.stdout).unwrap();
    assert_eq!(v["items"][3]["outcome"], "ran");
    assert_eq!(v["items"][6]["outcome"], "reached");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The report page gives one distance per reach of an item, the one the
/// text summaries print ("N m off": from the true position to the item's
/// point, a relative altitude taken above home): the verdict's column for
/// the first reach, and the event of that reach, say the same number as
/// `rotorpilot replay` does.
#[test]
fn the_page_and_the_summary_give_an_item_the_same_distance() {
    let (dir, record) = square_record("replay-item-distance");
    let r = read_record(&std::fs::read_to_string(&record).unwrap(), "flight.record").unwrap();
    let summary = replay(&r, "flight.record", None).unwrap();
    let page = rotorpilot::logs::replay::replay_report(&r, "flight.record", Default::default()).unwrap();
    let mut checked = 0;
    for (row, item) in page.verdict.items.iter().zip(&summary.items) {
        assert_eq!(row.seq, item.seq);
        let Some(d) = item.distance_m else {
            assert_eq!(row.distance_m, None, "item {}", row.seq);
            continue;
        };
        let shown = format!("{d:.2}");
        assert_eq!(
            row.distance_m.map(|x| format!("{x:.2}")),
            Some(shown.clone()),
            "item {}",
            row.seq
        );
        let event = page
            .events
            .iter()
            .find(|e| e.text.starts_with(&format!("Reached item {} ", row.seq)))
            .unwrap_or_else(|| panic!("no event for item {}", row.seq));
        assert!(
            event.text.contains(&format!("{shown} m")),
            "item {}: {} vs {shown}",
            row.seq,
            event.text
        );
        checked += 1;
    }
    assert!(checked >= 5, "{checked} items with a distance");
    let _ = std::fs::remove_dir_all(&dir);
}
