//! Issue 16, what a new user trips over in the first hour: home where the
//! vehicle rests (relative altitude 0 on the ground, "take off to 5 m"
//! means 5 m above it), injections shown at start, arming refused when the
//! rotors cannot lift the true mass, one daemon per state directory, and
//! bad input answered once, clearly.

mod daemon_common;

use std::io::{BufRead as _, BufReader};
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use daemon_common::{Client, NAN, Vehicle, config, heartbeat, state_dir, wait_armable};
use mavlink::dialects::common::*;
use rotorpilot::airframe::Airframe;
use rotorpilot::autopilot::{AutopilotCommand, CommandOutcome};
use rotorpilot::geo::GeoPoint;
use rotorpilot::lockstep::Lockstep;
use rotorpilot::lockstep::preflight::unliftable;
use rotorpilot::params::{ParamStore, ParamValue};
use rotorpilot::sim::{RotorHealth, SensorConfig};

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
    assert!(
        rel.abs() < 0.05,
        "relative altitude on the ground {rel} m (PX4: about 0)"
    );
    assert!((z + rest_height).abs() < 0.05, "resting at z {z} m (NED, ground at 0)");
    let home = c
        .wait_for(Duration::from_secs(3), |r| match &r.msg {
            Some(MavMessage::HOME_POSITION(h)) => Some(h.z),
            _ => None,
        })
        .await
        .expect("HOME_POSITION");
    assert!(
        (f64::from(home) - z).abs() < 0.05,
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
    assert!(
        (rel - 5.0).abs() < 0.15,
        "relative altitude after takeoff to 5 m: {rel} m"
    );
    let above_rest = -z - rest_height;
    assert!(
        (above_rest - 5.0).abs() < 0.15,
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
fn lockstep_refuses_to_arm_what_cannot_hover_and_says_why() {
    let quad = quad();
    let lift_kg = quad.max_thrust_n() / rotorpilot::signals::GRAVITY;
    let mut params = ParamStore::new(&quad);
    params.set("SIM_MASS", ParamValue::Real32(10.0)).unwrap();
    let mut core = Lockstep::one_vehicle(&quad, GeoPoint::PX4_SITL_HOME, &params, SensorConfig::default()).unwrap();
    for _ in 0..50 {
        core.step();
    }
    let _ = core.drain_world_texts(0);
    let outcome = core.command(0, AutopilotCommand::Arm { force: false });
    assert!(matches!(outcome, CommandOutcome::Denied(_)), "{outcome:?}");
    assert!(!core.pilot(0).armed());
    let texts: Vec<String> = core.drain_world_texts(0).into_iter().map(|t| t.text).collect();
    assert_eq!(
        texts,
        [format!("Preflight Fail: SIM_MASS 10.0 kg > lift {lift_kg:.1} kg")]
    );
    // forced arming skips the preflight checks, as PX4's
    assert_eq!(
        core.command(0, AutopilotCommand::Arm { force: true }),
        CommandOutcome::Accepted
    );

    // nominal mass: arms
    let params = ParamStore::new(&quad);
    let mut core = Lockstep::one_vehicle(&quad, GeoPoint::PX4_SITL_HOME, &params, SensorConfig::default()).unwrap();
    for _ in 0..50 {
        core.step();
    }
    assert_eq!(
        core.command(0, AutopilotCommand::Arm { force: false }),
        CommandOutcome::Accepted
    );
}

#[test]
fn a_dead_rotor_takes_its_share_of_the_lift() {
    let quad = quad();
    let lift_kg = quad.max_thrust_n() / rotorpilot::signals::GRAVITY;
    let healthy = [RotorHealth::Healthy; 4];
    let one_dead = [
        RotorHealth::Off,
        RotorHealth::Healthy,
        RotorHealth::Healthy,
        RotorHealth::Healthy,
    ];
    let half = [
        RotorHealth::Degraded { thrust_fraction: 0.5 },
        RotorHealth::Healthy,
        RotorHealth::Healthy,
        RotorHealth::Healthy,
    ];
    let m = 0.8 * lift_kg;
    assert_eq!(unliftable(&quad, m, &healthy), None);
    assert_eq!(unliftable(&quad, m, &[]), None, "no fault list: all healthy");
    assert_eq!(unliftable(&quad, m, &half), None, "7/8 of the lift is enough");
    assert_eq!(
        unliftable(&quad, m, &one_dead),
        Some(format!(
            "Preflight Fail: SIM_MASS {m:.1} kg > lift {:.1} kg",
            0.75 * lift_kg
        ))
    );
    assert!(
        unliftable(&quad, lift_kg, &healthy).is_some(),
        "hover at full speed is no hover"
    );
    assert!(unliftable(&quad, quad.mass_kg, &healthy).is_none());
}

/// Run the binary with `args` (links on free loopback ports, no remotes);
/// its exit status, stdout and stderr.
fn run(args: &[&str]) -> (Option<i32>, String, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_rotorpilot"))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // input let through would start the daemon: stop it, and fail on the status
    let t0 = Instant::now();
    while child.try_wait().unwrap().is_none() && t0.elapsed() < Duration::from_secs(10) {
        std::thread::sleep(Duration::from_millis(10));
    }
    let _ = child.kill();
    let out = child.wait_with_output().unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

const LOOPBACK: [&str; 8] = [
    "--gcs-bind",
    "127.0.0.1:0",
    "--api-bind",
    "127.0.0.1:0",
    "--gcs-remote",
    "none",
    "--api-remote",
    "none",
];

/// A cause said twice: some text of 12 characters or more after a `: ` that
/// occurs again in the message.
fn repeated_cause(message: &str) -> Option<&str> {
    message.match_indices(": ").find_map(|(i, _)| {
        let rest = &message[i + 2..];
        let probe: String = rest.chars().take(12).collect();
        (probe.chars().count() == 12 && message.matches(probe.as_str()).count() > 1).then_some(rest)
    })
}

#[test]
fn the_cause_check_catches_a_repeat() {
    assert!(repeated_cause("file x: Not a directory (os error 20): Not a directory (os error 20)").is_some());
    assert!(repeated_cause("file x: Not a directory (os error 20)").is_none());
}

#[test]
fn bad_input_gets_one_clear_message_each() {
    let scratch = state_dir("bad-input");
    std::fs::create_dir_all(&scratch).unwrap();
    let file = scratch.join("afile");
    std::fs::write(&file, "not a directory").unwrap();
    let under_file = file.join("sub");
    let scenario = scratch.join("nosuch-airframe.toml");
    let shipped =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("tools/scenarios/quad-step-10m.toml"))
            .unwrap();
    std::fs::write(
        &scenario,
        shipped.replace("airframe = \"quad\"", "airframe = \"nosuch\""),
    )
    .unwrap();
    let known = "not a file and not a built-in airframe (quad, hexa, octo, fsr-quad, hexa-ppnnpn)";
    let with_loopback =
        |a: &[&str]| -> Vec<String> { a.iter().chain(LOOPBACK.iter()).map(ToString::to_string).collect() };
    let cases: Vec<(Vec<String>, i32, String)> = vec![
        (
            with_loopback(&["--state-dir", under_file.to_str().unwrap()]),
            1,
            format!(
                "rotorpilot: cannot make the state directory {}: Not a directory (os error 20)\n",
                under_file.display()
            ),
        ),
        (
            vec!["simulate".into(), scenario.to_str().unwrap().into()],
            2,
            format!(
                "rotorpilot: {}: airframe: unknown airframe `nosuch`: {known}\n",
                scenario.display()
            ),
        ),
        (
            with_loopback(&["--speed", "-1"]),
            1,
            "rotorpilot: --speed must be in (0, 1000], got -1\n".into(),
        ),
        (
            with_loopback(&["--home", "95,8.5,400"]),
            1,
            "rotorpilot: --home `95,8.5,400`: latitude 95 is out of range (-90 to 90 degrees)\n".into(),
        ),
        (
            with_loopback(&["--home", "47.4,-181,400"]),
            1,
            "rotorpilot: --home `47.4,-181,400`: longitude -181 is out of range (-180 to 180 degrees)\n".into(),
        ),
    ];
    for (args, status, message) in &cases {
        let a: Vec<&str> = args.iter().map(String::as_str).collect();
        let (code, stdout, stderr) = run(&a);
        assert_eq!(stderr, *message, "{a:?}");
        assert_eq!(code, Some(*status), "{a:?}");
        assert!(stdout.is_empty(), "{a:?}: {stdout}");
        assert_eq!(repeated_cause(&stderr), None, "{a:?}: {stderr}");
    }
    // a campaign of two bad files: each error once, on its table line, its path once
    let other = scratch.join("nosuch-too.toml");
    std::fs::copy(&scenario, &other).unwrap();
    let (code, stdout, stderr) = run(&["simulate", scenario.to_str().unwrap(), other.to_str().unwrap()]);
    assert_eq!(code, Some(2));
    assert_eq!(
        stdout,
        format!(
            "0 {}: ERROR: airframe: unknown airframe `nosuch`: {known}\n\
             1 {}: ERROR: airframe: unknown airframe `nosuch`: {known}\n",
            scenario.display(),
            other.display()
        )
    );
    assert_eq!(stderr.lines().count(), 1, "only the campaign's summary line: {stderr}");
    assert!(stderr.starts_with("rotorpilot simulate: 2 scenarios"), "{stderr}");
    let _ = std::fs::remove_dir_all(&scratch);
}

#[test]
fn help_states_the_speed_range_and_the_api_port_rule() {
    let (code, stdout, _) = run(&["--help"]);
    assert_eq!(code, Some(0));
    assert!(stdout.contains("(0 < FACTOR <= 1000)"), "{stdout}");
    assert!(
        stdout.contains("all API links beyond instance 9 send to 14549"),
        "{stdout}"
    );
}

/// A daemon on `dir` (loopback ports), once it says it is ready to arm,
/// with its stdout still open (a closed pipe could end it early).
fn start_until_ready(
    dir: &std::path::Path,
) -> (
    std::process::Child,
    std::io::Lines<BufReader<std::process::ChildStdout>>,
) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_rotorpilot"))
        .args(["--state-dir", dir.to_str().unwrap()])
        .args(LOOPBACK)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    let ready = lines
        .by_ref()
        .map_while(Result::ok)
        .any(|l| l.starts_with("rotorpilot: ready to arm"));
    assert!(ready, "a daemon on {} starts", dir.display());
    (child, lines)
}

#[test]
fn a_second_daemon_on_one_state_dir_is_refused_naming_the_dir_and_the_holder() {
    let dir = state_dir("locked");
    let (mut first, _stdout) = start_until_ready(&dir);
    let (code, stdout, stderr) = run(&[&["--state-dir", dir.to_str().unwrap()][..], &LOOPBACK[..]].concat());
    let _ = first.kill();
    let _ = first.wait();
    assert_eq!(
        stderr,
        format!(
            "rotorpilot: {} is in use by another rotorpilot (pid {}): one daemon per state directory \
             (stop it, or give this one another --instance or --state-dir)\n",
            dir.display(),
            first.id()
        )
    );
    assert_eq!(code, Some(1));
    assert!(stdout.is_empty());
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
