//! The stored plans across daemon restarts: `missions.json` in the state
//! directory is read before the simulation starts, written at start and at
//! shutdown, refused with the file and field named when it does not read,
//! and discarded by `--reset-plans`.
#![allow(deprecated)]

mod common;

use std::path::{Path, PathBuf};

use common::daemon::{Vehicle, config};
use rotorpilot::daemon;
use rotorpilot::mission::file::{load_mission_file, load_plans, plans_to_text, save_plans};
use rotorpilot::mission::{MissionItem, MissionType, Plans};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/missions")
        .join(name)
}

/// The fence-and-rally plan as stored plans (mission 3, fence 12, rally 2 items).
fn stored() -> Plans {
    load_mission_file(&fixture("fence-rally.plan"))
        .unwrap()
        .into_plans()
        .unwrap()
}

fn bits(it: &MissionItem) -> (u8, u16, bool, [u32; 4], u64, u64, u32) {
    (
        it.frame,
        it.command,
        it.autocontinue,
        it.params.map(f32::to_bits),
        it.x.to_bits(),
        it.y.to_bits(),
        it.z.to_bits(),
    )
}

fn assert_same(a: &Plans, b: &Plans) {
    for kind in MissionType::ALL {
        assert_eq!(a.get(kind).id(), b.get(kind).id(), "{kind:?}");
        let x: Vec<_> = a.get(kind).items().iter().map(bits).collect();
        let y: Vec<_> = b.get(kind).items().iter().map(bits).collect();
        assert_eq!(x, y, "{kind:?}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn plans_in_the_state_dir_are_restored_and_kept_across_restarts() {
    let cfg = config(None, None, 1.0);
    let dir = cfg.state_dir.clone();
    std::fs::create_dir_all(&dir).unwrap();
    let path = cfg.plans_path();
    let plans = stored();
    // as a person might write it: on one line
    std::fs::write(&path, plans_to_text(&plans).replace('\n', "")).unwrap();

    // the daemon has them before it runs, and says so
    let d = daemon::bind(cfg.clone()).await.unwrap();
    let summary = d.summary();
    assert!(
        summary.contains(&format!(
            "plans: {} (mission 3 items, fence 12, rally 2)",
            path.display()
        )),
        "{summary}"
    );
    drop(d);

    for _ in 0..2 {
        let v = Vehicle::start(cfg.clone()).await;
        tokio::time::sleep(std::time::Duration::from_millis(300)).await;
        v.stop_keep_state().await;
        // written (from the simulation's snapshot) at start and at
        // shutdown: the same plans, bit for bit, in the daemon's layout
        assert_eq!(std::fs::read_to_string(&path).unwrap(), plans_to_text(&plans));
        assert_same(&load_plans(&path).unwrap(), &plans);
    }

    // --reset-plans: none, and the file says so at once
    let mut reset = cfg.clone();
    reset.reset_plans = true;
    let v = Vehicle::start(reset).await;
    let mut cleared = false;
    for _ in 0..100 {
        tokio::time::sleep(std::time::Duration::from_millis(20)).await;
        if load_plans(&path).is_ok_and(|p| p == Plans::default()) {
            cleared = true;
            break;
        }
    }
    assert!(cleared, "--reset-plans overwrites the file at start");
    v.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_corrupt_plans_file_stops_the_start_naming_the_file_and_the_field() {
    let cfg = config(None, None, 1.0);
    let dir = cfg.state_dir.clone();
    std::fs::create_dir_all(&dir).unwrap();
    let path = cfg.plans_path();
    save_plans(&path, &stored()).unwrap();
    let good = std::fs::read_to_string(&path).unwrap();
    let bad = good.replacen("\"x\": 47.397742", "\"x\": 97.397742", 1);
    assert_ne!(bad, good);
    std::fs::write(&path, &bad).unwrap();

    let e = format!("{:#}", daemon::bind(cfg.clone()).await.unwrap_err());
    assert!(
        e.contains(&format!(
            "{}: mission[0].x: latitude 97.397742 is not within ±90°",
            path.display()
        )),
        "{e}"
    );
    assert!(e.contains("--reset-plans"), "{e}");
    assert_eq!(std::fs::read_to_string(&path).unwrap(), bad, "left as it was");

    // the binary says the same and exits at once
    let out = common::bin::rotorpilot()
        .arg("--state-dir")
        .arg(&dir)
        .args(["--gcs-bind", "127.0.0.1:0", "--api-bind", "127.0.0.1:0"])
        .args(["--gcs-remote", "none", "--api-remote", "none"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("rotorpilot: cannot restore the stored mission")
            && err.contains("mission[0].x: latitude 97.397742"),
        "{err}"
    );

    // --reset-plans starts, and shutdown leaves an empty plans file
    let mut reset = cfg;
    reset.reset_plans = true;
    let v = Vehicle::start(reset).await;
    v.stop_keep_state().await;
    assert_eq!(load_plans(&path).unwrap(), Plans::default());
    let _ = std::fs::remove_dir_all(&dir);
}
