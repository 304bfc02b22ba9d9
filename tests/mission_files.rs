//! The mission files users fly: the examples under `tools/missions/` read
//! and stay near PX4's SITL home, and `tools/fly_mission.py` builds exactly
//! the items the Rust reader builds (so a pymavlink upload of a file and a
//! headless flight of it are the same plan).

use std::path::{Path, PathBuf};
use std::process::Command;

use rotorpilot::geo::GeoPoint;
use rotorpilot::mission::file::{PlanFile, load_mission_file};
use rotorpilot::mission::{MissionItem, MissionType, frame};

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// Every mission file under `dir`.
fn files(dir: &str) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(root().join(dir))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            p.extension()
                .is_some_and(|e| ["plan", "txt", "waypoints", "mission"].contains(&e.to_string_lossy().as_ref()))
        })
        .collect();
    v.sort();
    v
}

/// Horizontal distance [m] of a global item from PX4's SITL home.
fn from_home(it: &MissionItem) -> f64 {
    let p = GeoPoint {
        lat_deg: it.x,
        lon_deg: it.y,
        alt_amsl_m: GeoPoint::PX4_SITL_HOME.alt_amsl_m,
    };
    p.ned_from(&GeoPoint::PX4_SITL_HOME).xy().norm()
}

fn commands(items: &[MissionItem]) -> Vec<u16> {
    items.iter().map(|i| i.command).collect()
}

#[test]
fn the_example_files_read_and_stay_near_px4s_sitl_home() {
    let found = files("tools/missions");
    assert!(found.len() >= 2, "{found:?}");
    for f in &found {
        let p = load_mission_file(f).unwrap_or_else(|e| panic!("{e}"));
        assert!(!p.mission.is_empty(), "{}", f.display());
        assert_eq!(p.mission[0].command, 22, "{}: starts with a takeoff", f.display());
        assert_eq!(p.mission.last().unwrap().command, 20, "{}: ends with RTL", f.display());
        for it in p.mission.iter().chain(&p.rally) {
            if frame::is_global(it.frame) && it.has_position() {
                assert!(
                    from_home(it) < 70.0,
                    "{}: {it:?} is {} m out",
                    f.display(),
                    from_home(it)
                );
            }
        }
    }
    let plan = load_mission_file(&root().join("tools/missions/home-square.plan")).unwrap();
    assert_eq!(commands(&plan.mission), [22, 16, 16, 16, 16, 20]);
    assert_eq!(commands(&plan.fence), [5001, 5001, 5001, 5001, 5004]);
    assert_eq!(commands(&plan.rally), [5100, 5100]);
    let wpl = load_mission_file(&root().join("tools/missions/five-waypoints.txt")).unwrap();
    assert_eq!(commands(&wpl.mission), [22, 16, 16, 16, 16, 16, 20]);
    let takeoff = wpl.mission[0];
    assert_eq!((takeoff.frame, takeoff.z), (3, 10.0), "takeoff to 10 m relative");
    assert!(wpl.fence.is_empty() && wpl.rally.is_empty());
    // and they are plans a vehicle stores
    plan.into_plans().unwrap();
    wpl.into_plans().unwrap();
}

/// `fly_mission.py --list`: (kind, item) per line.
fn python_items(path: &Path) -> Option<Vec<(MissionType, MissionItem)>> {
    let out = Command::new("python3")
        .arg(root().join("tools/fly_mission.py"))
        .arg(path)
        .arg("--list")
        .output()
        .ok()?;
    assert!(
        out.status.success(),
        "{}: {}",
        path.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    let items = text
        .lines()
        .map(|l| {
            // "mission 0: frame 3 command 22 autocontinue 1 params 0.0 0.0 0.0 nan x 47.39 y 8.54 z 15.0"
            let t: Vec<&str> = l.split_whitespace().collect();
            let kind = match t[0] {
                "mission" => MissionType::Mission,
                "fence" => MissionType::Fence,
                "rally" => MissionType::Rally,
                other => panic!("kind {other} in `{l}`"),
            };
            let f32_at = |i: usize| t[i].parse::<f64>().unwrap() as f32;
            let item = MissionItem {
                frame: t[3].parse().unwrap(),
                command: t[5].parse().unwrap(),
                autocontinue: t[7] == "1",
                params: [f32_at(9), f32_at(10), f32_at(11), f32_at(12)],
                x: t[14].parse().unwrap(),
                y: t[16].parse().unwrap(),
                z: f32_at(18),
            };
            (kind, item)
        })
        .collect();
    Some(items)
}

fn bits(it: &MissionItem) -> (u8, u16, bool, [u32; 4], u64, u64, u32) {
    // NaN: compare as "is NaN" (Python cannot print a payload)
    let f = |v: f32| if v.is_nan() { f32::NAN.to_bits() } else { v.to_bits() };
    (
        it.frame,
        it.command,
        it.autocontinue,
        it.params.map(f),
        it.x.to_bits(),
        it.y.to_bits(),
        f(it.z),
    )
}

#[test]
fn the_pymavlink_script_builds_the_same_items_as_the_vehicle() {
    if Command::new("python3").arg("--version").output().is_err() {
        eprintln!("python3 not found: skipped");
        return;
    }
    let mut all = files("tools/missions");
    all.extend(files("tests/fixtures/missions"));
    for f in all {
        let rust: PlanFile = load_mission_file(&f).unwrap();
        let python = python_items(&f).expect("python3 runs");
        for kind in MissionType::ALL {
            let py: Vec<_> = python
                .iter()
                .filter(|(k, _)| *k == kind)
                .map(|(_, it)| bits(it))
                .collect();
            let rs: Vec<_> = rust.items(kind).iter().map(bits).collect();
            assert_eq!(py, rs, "{} {kind:?}", f.display());
        }
    }
}
