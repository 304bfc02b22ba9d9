//! The daemon as a whole: the `rotorpilot` binary (startup message, system id
//! from `--instance`, SIGTERM within a second, parameters saved), bad options,
//! and a real flight over MAVLink (arm, takeoff as pymavlink sends it, land,
//! auto-disarm).
#![allow(deprecated)]

mod common;

use std::io::{BufRead as _, BufReader};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::daemon::{Client, NAN, Vehicle, config, heartbeat, wait_armable};
use common::scratch_path;
use mavlink::dialects::common::*;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn binary_prints_where_it_listens_and_stops_on_sigterm() {
    let mut gcs = Client::with_ids(255, 0).await;
    let dir = scratch_path("bin");
    let mut child = common::bin::rotorpilot()
        .args(["--instance", "3", "--speed", "2", "--state-dir"])
        .arg(&dir)
        .args([
            "--gcs-bind",
            "127.0.0.1:0",
            "--api-bind",
            "127.0.0.1:0",
            "--api-remote",
            "none",
        ])
        .args(["--gcs-remote", &gcs.addr().to_string()])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("spawn rotorpilot");
    let stdout = child.stdout.take().unwrap();
    let lines = std::thread::spawn(move || {
        BufReader::new(stdout)
            .lines()
            .map_while(Result::ok)
            .take_while(|l| !l.contains("parameters:"))
            .collect::<Vec<_>>()
    });
    // the GCS link speaks first, as system 4 (instance 3)
    let h = gcs
        .wait_for(Duration::from_secs(5), |r| {
            matches!(r.msg, Some(MavMessage::HEARTBEAT(_))).then_some((r.sysid, r.compid))
        })
        .await;
    assert_eq!(h, Some((4, 1)));
    let out = lines.join().unwrap().join("\n");
    assert!(out.contains("instance 3, system id 4"), "{out}");
    assert!(out.contains("GCS  link: udp 127.0.0.1:"), "{out}");
    assert!(out.contains("API  link: udp 127.0.0.1:"), "{out}");
    // The files written at start-up (atomically: once a file exists it is
    // whole) are replaced behind the daemon's back. No set or plan change
    // follows, so the background savers write nothing more: only the save at
    // shutdown can put the vehicle's parameters and plans back.
    let (params_file, plans_file) = (dir.join("params.toml"), dir.join("missions.json"));
    let t_files = Instant::now();
    while !(params_file.exists() && plans_file.exists()) {
        assert!(
            t_files.elapsed() < Duration::from_secs(3),
            "the start-up save wrote no files"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
    let saved_params = std::fs::read_to_string(&params_file).unwrap();
    let saved_plans = std::fs::read_to_string(&plans_file).unwrap();
    std::fs::write(&params_file, "# replaced by the test\n").unwrap();
    std::fs::write(&plans_file, "replaced by the test\n").unwrap();
    // SIGTERM: clean exit within a second, parameters saved
    let t0 = Instant::now();
    let killed = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if t0.elapsed() > Duration::from_secs(3) {
            let _ = child.kill();
            panic!("rotorpilot did not stop on SIGTERM");
        }
        std::thread::sleep(Duration::from_millis(10));
    };
    assert!(status.success(), "{status}");
    assert!(t0.elapsed() < Duration::from_secs(1), "{:?}", t0.elapsed());
    let params = std::fs::read_to_string(&params_file).expect("parameters saved");
    assert!(params.contains("MAV_SYS_ID = 4"), "{params}");
    assert_eq!(params, saved_params, "the shutdown save writes the parameters in force");
    let plans = std::fs::read_to_string(&plans_file).expect("plans saved");
    assert_eq!(plans, saved_plans, "the shutdown save writes the plans in force");
    let _ = std::fs::remove_dir_all(&dir);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn arm_takeoff_land_disarm_over_mavlink() {
    let mut c = Client::with_ids(255, 0).await;
    let v = Vehicle::start(config(Some(c.addr()), None, 5.0)).await;
    wait_armable(&mut c).await;
    assert_eq!(
        c.command(v.gcs, 400, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]).await.result,
        0
    );
    // pymavlink style: p7 = 10 "relative"; PX4 reads AMSL and raises it to home + MIS_TAKEOFF_ALT
    assert_eq!(
        c.command(v.gcs, 22, [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 10.0]).await.result,
        0
    );
    let h = heartbeat(&mut c, Duration::from_millis(1500)).await;
    assert!(h.custom_mode == 4 << 16 | 2 << 24 || h.custom_mode == 4 << 16 | 3 << 24);
    // in Hold at about 2.5 m once the takeoff is done
    let alt = c
        .wait_for(Duration::from_secs(15), |r| match &r.msg {
            Some(MavMessage::HEARTBEAT(h)) if h.custom_mode == 4 << 16 | 3 << 24 => Some(()),
            _ => None,
        })
        .await;
    assert!(alt.is_some(), "back in Hold after the takeoff");
    let rel = c
        .wait_for(Duration::from_secs(2), |r| match &r.msg {
            Some(MavMessage::GLOBAL_POSITION_INT(g)) => Some(g.relative_alt),
            _ => None,
        })
        .await
        .unwrap();
    assert!((rel - 2500).abs() < 300, "relative altitude {rel} mm");
    // land: landed_state goes to ON_GROUND and the vehicle disarms by itself
    assert_eq!(c.command(v.gcs, 21, [NAN; 7]).await.result, 0);
    c.wait_for(Duration::from_secs(20), |r| match &r.msg {
        Some(MavMessage::EXTENDED_SYS_STATE(e)) if e.landed_state == MavLandedState::MAV_LANDED_STATE_ON_GROUND => {
            Some(())
        }
        _ => None,
    })
    .await
    .expect("landed");
    c.wait_for(Duration::from_secs(10), |r| match &r.msg {
        Some(MavMessage::HEARTBEAT(h)) if h.base_mode.bits() & 128 == 0 => Some(()),
        _ => None,
    })
    .await
    .expect("disarmed after landing");
    v.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn shutdown_command_stops_the_daemon_after_the_ack() {
    let mut c = Client::with_ids(255, 0).await;
    let mut v = Vehicle::start(config(Some(c.addr()), None, 1.0)).await;
    heartbeat(&mut c, Duration::from_secs(2)).await;
    // armed: DENIED
    wait_armable(&mut c).await;
    assert_eq!(
        c.command(v.gcs, 400, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]).await.result,
        0
    );
    assert_eq!(
        c.command(v.gcs, 246, [2.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]).await.result,
        2
    );
    assert_eq!(
        c.command(v.gcs, 400, [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]).await.result,
        0
    );
    // disarmed: ACCEPTED, then the daemon ends by itself and saves its parameters
    assert_eq!(
        c.command(v.gcs, 246, [2.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]).await.result,
        0
    );
    assert!(v.ended_by_itself(Duration::from_secs(2)).await);
    assert!(v.state_dir.join("params.toml").exists());
}
