//! The daemon from its start to its first takeoff: home where the vehicle
//! rests (relative altitude 0 on the ground, "take off to 5 m" means 5 m
//! above it), the injections it kept listed in the start-up banner, arming
//! refused when the rotors cannot lift the true mass, and one daemon per
//! state directory (another process or the same one is refused).

mod common;

use std::time::Duration;

use common::bin::{LOOPBACK, run_within, start_until_ready};
use common::daemon::{Client, NAN, Vehicle, config, heartbeat, wait_armable};
use common::scratch_path;
use mavlink::dialects::common::*;
use rotorpilot::airframe::Airframe;

fn quad() -> Airframe {
    Airframe::load("quad").unwrap()
}

/// The latest GLOBAL_POSITION_INT relative altitude [m] and LOCAL_POSITION_NED z [m].
async fn altitudes(c: &mut Client) -> (f64, f64) {
    let rel = c
        .wait_for(Duration::from_secs(3), |r| match &r.msg {
            Some(MavMessage::GLOBAL_POSITION_INT(g)) => Some(f64::from(g.relative_alt) / 1000.0),
            _ => None,
        })
        .await
        .expect("GLOBAL_POSITION_INT");
    let z = c
        .wait_for(Duration::from_secs(3), |r| match &r.msg {
            Some(MavMessage::LOCAL_POSITION_NED(p)) => Some(f64::from(p.z)),
            _ => None,
        })
        .await
        .expect("LOCAL_POSITION_NED");
    (rel, z)
}

/// Set a parameter and wait for its echo.
async fn set_param(c: &mut Client, to: std::net::SocketAddr, name: &str, value: f32) {
    c.param_set(to, name, value, MavParamType::MAV_PARAM_TYPE_REAL32).await;
    let echoed = c
        .wait_for(Duration::from_secs(3), |r| match &r.msg {
            Some(MavMessage::PARAM_VALUE(p)) if p.param_id.to_str().is_ok_and(|s| s == name) => Some(p.param_value),
            _ => None,
        })
        .await
        .unwrap_or_else(|| panic!("no PARAM_VALUE echo of {name}"));
    assert_eq!(echoed, value, "{name}");
}

/// How far the daemon's height may be from the truth: it flies on the
/// navigation filter, whose height reference is GNSS height (0.5 m white
/// noise at 10 Hz, fused as PX4's EKF2 does); its vertical error in a hover
/// after settling is within 0.18 m (docs/navigation.md). On the ideal
/// solution these heights agree within 0.05 m.
const FILTER_HEIGHT_M: f64 = 0.3;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn relative_altitude_reads_zero_on_the_ground_and_takeoff_to_5_m_is_5_m_above_it() {
    let rest_height = quad().gear_height_m;
    assert!(
        rest_height > 0.1,
        "the quad rests {rest_height} m above the ground: the test can tell"
    );
    let mut c = Client::with_ids(255, 0).await;
    let v = Vehicle::start(config(Some(c.addr()), None, 5.0)).await;
    wait_armable(&mut c).await;
    let (rel, z) = altitudes(&mut c).await;
    eprintln!(
        "on the ground: relative altitude {rel:.3} m, z {z:.3} m (resting at {:.3} m)",
        -rest_height
    );
    assert!(
        rel.abs() < FILTER_HEIGHT_M,
        "relative altitude on the ground {rel} m (PX4: about 0)"
    );
    assert!(
        (z + rest_height).abs() < FILTER_HEIGHT_M,
        "resting at z {z} m (NED, ground at 0)"
    );
    let home = c
        .wait_for(Duration::from_secs(3), |r| match &r.msg {
            Some(MavMessage::HOME_POSITION(h)) => Some(h.z),
            _ => None,
        })
        .await
        .expect("HOME_POSITION");
    assert!(
        (f64::from(home) - z).abs() < FILTER_HEIGHT_M,
        "home z {home} m is where the vehicle rests ({z} m)"
    );

    set_param(&mut c, v.gcs, "MIS_TAKEOFF_ALT", 5.0).await;
    assert_eq!(
        c.command(v.gcs, 400, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]).await.result,
        0,
        "arm"
    );
    // NaN altitude: home + MIS_TAKEOFF_ALT
    assert_eq!(c.command(v.gcs, 22, [NAN; 7]).await.result, 0, "takeoff");
    let _ = heartbeat(&mut c, Duration::from_millis(1500)).await;
    c.wait_for(Duration::from_secs(20), |r| match &r.msg {
        Some(MavMessage::HEARTBEAT(h)) if h.custom_mode == 4 << 16 | 3 << 24 => Some(()),
        _ => None,
    })
    .await
    .expect("in Hold after the takeoff");
    tokio::time::sleep(Duration::from_millis(300)).await;
    c.drain().await;
    let (rel, z) = altitudes(&mut c).await;
    eprintln!("after the takeoff: relative altitude {rel:.3} m, z {z:.3} m");
    assert!(
        (rel - 5.0).abs() < FILTER_HEIGHT_M,
        "relative altitude after takeoff to 5 m: {rel} m"
    );
    let above_rest = -z - rest_height;
    assert!(
        (above_rest - 5.0).abs() < FILTER_HEIGHT_M,
        "{above_rest} m above where it rested (z {z} m)"
    );
    v.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_restart_lists_the_injections_it_kept_in_the_banner() {
    let mut c = Client::with_ids(255, 0).await;
    let cfg = config(Some(c.addr()), None, 1.0);
    let v = Vehicle::start(cfg.clone()).await;
    heartbeat(&mut c, Duration::from_secs(3)).await;
    set_param(&mut c, v.gcs, "SIM_MASS", 10.0).await;
    set_param(&mut c, v.gcs, "SIM_FEXT_X", 2.0).await;
    v.stop_keep_state().await;

    let d = rotorpilot::daemon::bind(cfg.clone()).await.expect("restart");
    let banner = d.summary();
    let nominal = f64::from(quad().mass_kg as f32);
    let line = format!("  injected: SIM_FEXT_X 2.0 N (default 0.0), SIM_MASS 10.0 kg (default {nominal:?})");
    assert!(banner.lines().any(|l| l == line), "want {line:?} in:\n{banner}");
    drop(d);
    // --reset-params: nothing injected, no line
    let mut fresh = cfg.clone();
    fresh.reset_params = true;
    let d = rotorpilot::daemon::bind(fresh)
        .await
        .expect("restart with --reset-params");
    assert!(!d.summary().contains("injected"), "{}", d.summary());
    drop(d);
    let _ = std::fs::remove_dir_all(&cfg.state_dir);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn arming_an_unliftable_vehicle_is_denied_with_its_reason() {
    let mut c = Client::with_ids(255, 0).await;
    let v = Vehicle::start(config(Some(c.addr()), None, 1.0)).await;
    wait_armable(&mut c).await;
    set_param(&mut c, v.gcs, "SIM_MASS", 100.0).await;
    c.drain().await;
    let ack = c.command(v.gcs, 400, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]).await;
    assert_eq!(ack.result, 2, "DENIED");
    let text = c
        .wait_for(Duration::from_secs(2), |r| match &r.msg {
            Some(MavMessage::STATUSTEXT(s)) => {
                let t = s.text.to_str().unwrap_or("").to_string();
                t.starts_with("Preflight Fail").then_some((t, s.severity))
            }
            _ => None,
        })
        .await
        .expect("a Preflight Fail STATUSTEXT");
    let lift = quad().max_thrust_n() / rotorpilot::signals::GRAVITY;
    assert_eq!(text.0, format!("Preflight Fail: SIM_MASS 100.0 kg > lift {lift:.1} kg"));
    assert_eq!(text.1, MavSeverity::MAV_SEVERITY_CRITICAL);
    let h = heartbeat(&mut c, Duration::from_secs(2)).await;
    assert_eq!(h.base_mode.bits() & 0x80, 0, "still disarmed");
    // back to the nominal mass: arms
    set_param(&mut c, v.gcs, "SIM_MASS", quad().mass_kg as f32).await;
    assert_eq!(
        c.command(v.gcs, 400, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]).await.result,
        0
    );
    v.stop().await;
}

#[test]
fn a_second_daemon_on_one_state_dir_is_refused_naming_the_dir_and_the_holder() {
    let dir = scratch_path("locked");
    let (mut first, _stdout) = start_until_ready(&dir);
    let second = run_within(
        &[&["--state-dir", dir.to_str().unwrap()][..], &LOOPBACK[..]].concat(),
        Duration::from_secs(10),
    );
    let _ = first.kill();
    let _ = first.wait();
    assert_eq!(
        second.stderr,
        format!(
            "rotorpilot: {} is in use by another rotorpilot (pid {}): one daemon per state directory \
             (stop it, or give this one another --instance or --state-dir)\n",
            dir.display(),
            first.id()
        )
    );
    assert_eq!(second.code, Some(1));
    assert!(second.stdout.is_empty());
    // the first gone (killed: the system released its lock), a new one starts
    // (it asserts that it starts: a stale lock file locks nothing)
    let (mut again, _stdout) = start_until_ready(&dir);
    let _ = again.kill();
    let _ = again.wait();
    let _ = std::fs::remove_dir_all(&dir);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_second_daemon_in_one_process_is_refused_too() {
    let c = Client::with_ids(255, 0).await;
    let cfg = config(Some(c.addr()), None, 1.0);
    let v = Vehicle::start(cfg.clone()).await;
    let err = rotorpilot::daemon::bind(cfg.clone()).await.unwrap_err();
    assert!(
        format!("{err:#}").starts_with(&format!(
            "{} is in use by another rotorpilot (pid {})",
            cfg.state_dir.display(),
            std::process::id()
        )),
        "{err:#}"
    );
    v.stop().await;
}
