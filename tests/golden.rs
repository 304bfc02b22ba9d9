//! Golden flights: the `simulate --csv` log and the summary of every shipped
//! scenario (`tools/scenarios/`) and of the extra ones in `tests/golden/`
//! (sensor noise, disturbance schedules, an explicit start, a ceiling, the
//! hexa) must not change by a single bit. The logs were recorded before the
//! world and the flight stack were split apart; `tests/golden/csv.sha256`
//! holds the SHA-256 of each log, `tests/golden/*.summary.json` each summary
//! (its `wall_time_s` zeroed). Mission scenarios (a `[mission]` table) are
//! pinned the same way, flown through the flight stack.
//!
//! A change that means to change a flight (a new log column, a different
//! physics) records the new expectations with `ROTORPILOT_BLESS=1 cargo test
//! --release --test golden` and says so in its commit.

use std::io::Write;
use std::path::{Path, PathBuf};

use rotorpilot::scenario::{MissionFlight, Scenario, is_mission, run, run_mission};
use sha2::{Digest, Sha256};

/// A `Write` that only hashes.
struct HashWriter(Sha256);

impl Write for HashWriter {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.update(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Fly `path` (relative to the repository); the log's SHA-256 (hex) and the summary as JSON.
/// Missions (`[mission]` scenarios) fly through the flight stack and have their own summary.
fn fly(path: &str) -> (String, serde_json::Value) {
    let file = root().join(path);
    let mut hash = HashWriter(Sha256::new());
    let mut json = if is_mission(&file) {
        let flight = MissionFlight::from_file(&file).unwrap_or_else(|e| panic!("{path}: {e}"));
        let summary = run_mission(&flight, Some(&mut hash)).unwrap_or_else(|e| panic!("{path}: {e}"));
        serde_json::to_value(&summary).unwrap()
    } else {
        let scenario = Scenario::from_file(&file).unwrap_or_else(|e| panic!("{path}: {e}"));
        let summary = run(&scenario, Some(&mut hash)).unwrap_or_else(|e| panic!("{path}: {e}"));
        serde_json::to_value(&summary).unwrap()
    };
    let hex: String = hash.0.finalize().iter().map(|b| format!("{b:02x}")).collect();
    json["wall_time_s"] = serde_json::json!(0.0);
    // the file name only: the summary must not depend on where the checkout is
    json["scenario"] = serde_json::json!(Path::new(path).file_name().unwrap().to_string_lossy());
    (hex, json)
}

fn summary_path(path: &str) -> PathBuf {
    let stem = Path::new(path).file_stem().unwrap().to_string_lossy().to_string();
    root().join("tests/golden").join(format!("{stem}.summary.json"))
}

#[test]
fn every_golden_flight_is_bit_identical() {
    let digests = root().join("tests/golden/csv.sha256");
    let text = std::fs::read_to_string(&digests).unwrap();
    let entries: Vec<(String, String)> = text
        .lines()
        .filter(|l| !l.trim().is_empty() && !l.starts_with('#'))
        .map(|l| {
            let (hash, path) = l.split_once("  ").expect("`HASH  PATH` lines");
            (hash.to_string(), path.to_string())
        })
        .collect();
    assert!(entries.len() >= 9, "every shipped scenario and the extra golden ones");
    for scenario in std::fs::read_dir(root().join("tools/scenarios")).unwrap() {
        let name = format!("tools/scenarios/{}", scenario.unwrap().file_name().to_string_lossy());
        assert!(entries.iter().any(|(_, p)| *p == name), "{name} has no golden log");
    }
    let bless = std::env::var_os("ROTORPILOT_BLESS").is_some();
    let mut blessed = String::from("# SHA-256 of `rotorpilot simulate PATH --csv` (tests/golden.rs)\n");
    let mut failures = Vec::new();
    for (want, path) in &entries {
        let (got, summary) = fly(path);
        let json_path = summary_path(path);
        if bless {
            blessed.push_str(&format!("{got}  {path}\n"));
            std::fs::write(&json_path, serde_json::to_string_pretty(&summary).unwrap() + "\n").unwrap();
            continue;
        }
        if got != *want {
            failures.push(format!("{path}: log SHA-256 {got}, expected {want}"));
        }
        // compared as text: every number printed in its shortest exact form
        let expected = std::fs::read_to_string(&json_path).unwrap();
        let got = serde_json::to_string_pretty(&summary).unwrap() + "\n";
        if got != expected {
            failures.push(format!("{path}: summary differs:\n{got}expected\n{expected}"));
        }
    }
    if bless {
        std::fs::write(&digests, blessed).unwrap();
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The TOML text without its `[aero]` table (its header to the next header).
fn without_aero_table(text: &str) -> String {
    let mut inside = false;
    let mut out = String::new();
    for line in text.lines() {
        if line.trim_start().starts_with('[') {
            inside = line.trim_start().starts_with("[aero]");
        }
        if !inside {
            out.push_str(line);
            out.push('\n');
        }
    }
    out
}

/// GIVEN every shipped airframe with its `[aero]` table removed (every drag
/// coefficient 0) THEN each golden flight in still air (every one but the
/// wind scenarios, which fly drag by design) writes, bit for bit, the log of
/// the build before the airframes had drag: `tests/golden/drag-free.sha256`.
/// That build landed at MPC_LAND_SPEED from MPC_LAND_ALT1 down, as PX4's
/// landing does with MPC_LAND_ALT2 at MPC_LAND_ALT1 (10 m): the missions fly
/// with that setting here.
#[test]
fn drag_free_airframes_fly_the_logs_of_the_build_before() {
    let dir = std::env::temp_dir().join(format!("rotorpilot-drag-free-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut stripped = 0;
    for entry in std::fs::read_dir(root().join("params/airframes")).unwrap() {
        let path = entry.unwrap().path();
        let text = std::fs::read_to_string(&path).unwrap();
        let bare = without_aero_table(&text);
        stripped += usize::from(text.contains("\n[aero]"));
        std::fs::write(dir.join(path.file_name().unwrap()), bare).unwrap();
    }
    assert!(stripped >= 4, "the quad, hexas and octo carry [aero] tables");
    let text = std::fs::read_to_string(root().join("tests/golden/drag-free.sha256")).unwrap();
    let mut failures = Vec::new();
    for line in text.lines().filter(|l| !l.trim().is_empty() && !l.starts_with('#')) {
        let (want, path) = line.split_once("  ").expect("`HASH  PATH` lines");
        let file = root().join(path);
        let scenario_text = std::fs::read_to_string(&file).unwrap();
        let name = scenario_text
            .lines()
            .find_map(|l| l.strip_prefix("airframe = \""))
            .and_then(|l| l.split('"').next())
            .unwrap_or_else(|| panic!("{path}: no airframe line"));
        let airframe = dir.join(format!("{name}.toml"));
        assert!(airframe.is_file(), "{path}: airframe {name} is not a shipped one");
        let scenario_text = scenario_text.replacen(
            &format!("airframe = \"{name}\""),
            &format!("airframe = \"{}\"", airframe.display()),
            1,
        );
        let mut hash = HashWriter(Sha256::new());
        if is_mission(&file) {
            assert!(scenario_text.contains("\n[params]\n"), "{path}: a [params] table");
            let scenario_text = scenario_text.replacen("\n[params]\n", "\n[params]\nMPC_LAND_ALT2 = 10.0\n", 1);
            let flight =
                MissionFlight::from_toml(&scenario_text, path, file.parent()).unwrap_or_else(|e| panic!("{path}: {e}"));
            run_mission(&flight, Some(&mut hash)).unwrap_or_else(|e| panic!("{path}: {e}"));
        } else {
            let scenario =
                Scenario::from_toml(&scenario_text, path, file.parent()).unwrap_or_else(|e| panic!("{path}: {e}"));
            run(&scenario, Some(&mut hash)).unwrap_or_else(|e| panic!("{path}: {e}"));
        }
        let got: String = hash.0.finalize().iter().map(|b| format!("{b:02x}")).collect();
        if got != want {
            failures.push(format!(
                "{path} without drag: log SHA-256 {got}, the build before {want}"
            ));
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
