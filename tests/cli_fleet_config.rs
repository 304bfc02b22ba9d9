//! The fleet's configuration from the command line (`--count N`,
//! `--fleet FILE`, `--check`): the built binary refuses a bad fleet file with
//! the file, the field, its line and the problem, and lists a good one's
//! vehicles without starting them; `DaemonArgs::fleet_config` keeps the lone
//! vehicle exactly as `config()` builds it.

mod common;

use std::path::{Path, PathBuf};

use clap::Parser as _;
use rotorpilot::cli::Cli;

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/fleets")
        .join(name)
}

/// Exit status, stdout and stderr of `rotorpilot ARGS`.
fn run(args: &[&str]) -> (Option<i32>, String, String) {
    let out = common::bin::run(args);
    (out.code, out.stdout, out.stderr)
}

/// `rotorpilot --fleet FIXTURE --check`: refused with exactly `message`
/// (after the file's path), on stderr, exit status 1, nothing on stdout.
fn refused(fixture_name: &str, message: &str) {
    let file = fixture(fixture_name);
    let (status, stdout, stderr) = run(&["--fleet", file.to_str().unwrap(), "--check"]);
    assert_eq!(
        (status, stdout.as_str(), stderr.as_str()),
        (
            Some(1),
            "",
            format!("rotorpilot: {}:{message}\n", file.display()).as_str()
        )
    );
}

#[test]
fn a_duplicate_instance_is_refused_naming_the_entry_that_has_it() {
    refused(
        "duplicate-instance.toml",
        "10:12: vehicle[3].instance: instance 3 is already vehicle[1]'s (line 2: instances 0..3)",
    );
}

#[test]
fn an_unknown_airframe_is_refused_once_at_its_line() {
    refused(
        "unknown-airframe.toml",
        "6:12: vehicle[2].airframe: unknown airframe `octa`: not a file and not a built-in airframe \
         (quad, hexa, octo, fsr-quad, hexa-ppnnpn)",
    );
}

#[test]
fn more_vehicles_than_system_ids_are_refused() {
    refused(
        "too-many.toml",
        "7:9: vehicle[2].count: instances 200..259 need system ids up to 260; the most is 250 (instances 0..249)",
    );
    // clap refuses more than 250 at once, and its help and error say the real limit
    let (status, stdout, stderr) = run(&["--count", "300", "--check"]);
    assert_eq!((status, stdout.as_str()), (Some(2), ""));
    assert!(
        stderr.starts_with("error: invalid value '300' for '--count <N>': 300 is not in 1..=250\n"),
        "{stderr}"
    );
    let (status, _, stderr) = run(&["--instance", "100", "--count", "151", "--check"]);
    assert_eq!(status, Some(1));
    assert_eq!(
        stderr,
        "rotorpilot: --count 151: instances 100..250 need system ids up to 251; the most is 250 (instances 0..249)\n"
    );
}

#[test]
fn check_lists_a_good_fleets_vehicles_and_starts_nothing() {
    let file = fixture("two-groups.toml");
    let (status, stdout, stderr) = run(&[
        "--fleet",
        file.to_str().unwrap(),
        "--check",
        "--state-dir",
        "/tmp/swarm",
    ]);
    assert_eq!((status, stderr.as_str()), (Some(0), ""), "{stdout}");
    let lines: Vec<&str> = stdout.lines().collect();
    assert_eq!(lines.len(), 8, "{stdout}");
    assert!(
        lines[0].starts_with("6 vehicles on one clock; origin 47.3977420, 8.5455940, 500.0 m AMSL; proximity 1.5 m")
    );
    // instance, system id, airframe, north, east, then the links and the state directory
    let rows: Vec<Vec<&str>> = lines[2..].iter().map(|l| l.split_whitespace().collect()).collect();
    let heads: Vec<[&str; 5]> = rows.iter().map(|r| [r[0], r[1], r[2], r[3], r[4]]).collect();
    assert_eq!(
        heads,
        [
            ["0", "1", "quad", "0.00", "0.00"],
            ["1", "2", "quad", "3.00", "0.00"],
            ["2", "3", "quad", "6.00", "0.00"],
            ["3", "4", "quad", "9.00", "0.00"],
            ["10", "11", "octo", "-6.00", "5.00"],
            ["11", "12", "octo", "-3.00", "5.00"],
        ]
    );
    assert!(
        lines[7].contains(
            "GCS 0.0.0.0:18581 -> 127.0.0.1:14550, API 0.0.0.0:14591 -> 127.0.0.1:14549  state /tmp/swarm/11"
        ),
        "{}",
        lines[7]
    );
    assert!(
        lines[2].contains("API 0.0.0.0:14580 -> 127.0.0.1:14540  state /tmp/swarm/0"),
        "{}",
        lines[2]
    );
}

#[test]
fn options_that_name_one_vehicles_socket_are_refused_with_a_fleet() {
    for (flag, value) in [
        ("--gcs-bind", "127.0.0.1:18570"),
        ("--api-bind", "127.0.0.1:14580"),
        ("--link", "udpout:127.0.0.1:14600"),
    ] {
        let (status, _, stderr) = run(&["--count", "2", flag, value, "--check"]);
        assert_eq!(status, Some(1), "{flag}");
        assert_eq!(
            stderr,
            format!(
                "rotorpilot: {flag} cannot be used with --count: it names one vehicle's socket, and a fleet \
                 binds PX4's ports for each instance i (GCS 18570+i, API 14580+i); --gcs-remote and \
                 --api-remote apply to every vehicle\n"
            )
        );
    }
    // the file names each vehicle's instance; --count and --fleet are two ways to say the same
    let file = fixture("two-groups.toml");
    for other in [["--instance", "3"], ["--count", "2"]] {
        let (status, _, stderr) = run(&["--fleet", file.to_str().unwrap(), other[0], other[1], "--check"]);
        assert_eq!(status, Some(2), "{other:?}");
        assert!(stderr.contains("cannot be used with"), "{stderr}");
    }
}

#[test]
fn without_count_or_fleet_the_lone_vehicle_is_todays() {
    let cli = Cli::try_parse_from([
        "rotorpilot",
        "--instance",
        "12",
        "--state-dir",
        "/tmp/mine",
        "--gcs-bind",
        "127.0.0.1:0",
        "--link",
        "udpout:127.0.0.1:14600",
        "--home",
        "47.5,8.6,400",
    ])
    .unwrap();
    let c = cli.daemon.config().unwrap();
    let f = cli.daemon.fleet_config().unwrap();
    assert_eq!(f.vehicles.len(), 1);
    let v = &f.vehicles[0];
    assert_eq!((v.instance, &v.airframe, v.home), (12, &c.airframe, c.home));
    assert_eq!(v.links, c.links);
    assert_eq!(v.links.len(), 3);
    // a lone vehicle's --state-dir is its own directory, not a root
    assert_eq!(v.state_dir, PathBuf::from("/tmp/mine"));
    assert_eq!(f.origin, c.home);
    assert!(v.param_overrides.is_empty());
}

#[test]
fn count_applies_every_option_to_each_vehicle() {
    let cli = Cli::try_parse_from([
        "rotorpilot",
        "--instance",
        "8",
        "--count",
        "3",
        "--airframe",
        "hexa",
        "--speed",
        "4",
        "--api-remote",
        "127.0.0.1:9999",
        "--gcs-remote",
        "none",
        "--log-dir",
        "/tmp/logs",
        "--log-csv",
        "--reset-params",
        "--proximity",
        "0.5",
    ])
    .unwrap();
    let f = cli.daemon.fleet_config().unwrap();
    assert_eq!(f.proximity_m, 0.5);
    let instances: Vec<u8> = f.vehicles.iter().map(|v| v.instance).collect();
    assert_eq!(instances, [8, 9, 10]);
    for v in &f.vehicles {
        assert_eq!(
            (v.airframe.as_str(), v.speed, v.reset_params, v.log_csv),
            ("hexa", 4.0, true, true)
        );
        assert_eq!(v.log_dir.as_deref(), Some(Path::new("/tmp/logs")));
        assert_eq!(v.links[0].bind.port(), 18570 + u16::from(v.instance));
        assert_eq!(v.links[0].remote, None);
        assert_eq!(v.links[1].remote, Some("127.0.0.1:9999".parse().unwrap()));
        // the default root: the same directories as lone vehicles started with --instance i
        assert_eq!(v.state_dir, PathBuf::from(format!("rotorpilot-state/{}", v.instance)));
        let north = v.home.ned_from(&f.origin).x;
        assert!((north - 3.0 * f64::from(v.instance)).abs() < 1e-6, "{north}");
    }
    for bad in ["0", "-1", "nan", "inf"] {
        let cli = Cli::try_parse_from(["rotorpilot", "--count", "2", &format!("--proximity={bad}")]).unwrap();
        let e = cli.daemon.fleet_config().unwrap_err().to_string();
        assert!(
            e.starts_with("--proximity must be a finite distance > 0 m"),
            "{bad}: {e}"
        );
    }
    assert!(Cli::try_parse_from(["rotorpilot", "--count", "0"]).is_err());
}

/// `--check` refuses what a real start refuses, with the same message: a
/// check that passes options a start then rejects tells the user nothing.
#[test]
fn check_refuses_what_a_real_start_refuses_with_the_same_message() {
    let state = common::scratch_dir("check-as-start");
    let state = state.to_str().unwrap();
    for bad in [
        &["--airframe", "quadx"][..],
        &["--speed", "0"],
        &["--speed", "2000"],
        &["--count", "3", "--airframe", "quadx"],
        &["--count", "2", "--speed", "0"],
    ] {
        // a start that got through would bind PX4's ports: the refusal comes first
        let mut start: Vec<&str> = bad.to_vec();
        start.extend(["--state-dir", state]);
        let started = common::bin::run_within(&start, std::time::Duration::from_secs(20));
        assert_eq!(started.code, Some(1), "a real start with {bad:?}: {}", started.stderr);
        let mut check = start.clone();
        check.push("--check");
        let (status, stdout, stderr) = run(&check);
        assert_eq!(
            (status, stdout.as_str(), stderr.as_str()),
            (Some(1), "", started.stderr.as_str()),
            "--check with {bad:?}"
        );
    }
}

/// A malformed address names the option that gave it and what it takes.
#[test]
fn a_bad_address_names_its_option() {
    for (flag, takes) in [
        ("--gcs-remote", "HOST:PORT or none"),
        ("--api-remote", "HOST:PORT or none"),
        ("--gcs-bind", "HOST:PORT"),
        ("--api-bind", "HOST:PORT"),
    ] {
        let (status, stdout, stderr) = run(&[flag, "nowhere", "--check"]);
        assert_eq!(
            (status, stdout.as_str(), stderr.as_str()),
            (
                Some(1),
                "",
                format!("rotorpilot: {flag} takes {takes}: `nowhere` is not HOST:PORT: invalid socket address\n")
                    .as_str()
            )
        );
    }
    let (status, _, stderr) = run(&["--count", "2", "--api-remote", "nowhere", "--check"]);
    assert_eq!(status, Some(1));
    assert!(
        stderr.starts_with("rotorpilot: --api-remote takes HOST:PORT or none: "),
        "{stderr}"
    );
}

/// Log lines name a vehicle by the instance and system id the user set,
/// never by its place in the process: the proximity of instances 200 and
/// 201 (spawned 3 m apart, reported below 5 m) is logged for each.
#[test]
fn log_lines_name_the_instance_and_system_id() {
    let state = common::scratch_dir("log-names");
    let out = common::bin::run_within(
        &[
            "--count",
            "2",
            "--instance",
            "200",
            "--proximity",
            "5",
            "--state-dir",
            state.to_str().unwrap(),
            "--gcs-remote",
            "none",
            "--api-remote",
            "none",
        ],
        std::time::Duration::from_secs(3),
    );
    let proximity: Vec<&str> = out.stderr.lines().filter(|l| l.contains(" proximity ")).collect();
    assert_eq!(proximity.len(), 2, "{}", out.stderr);
    assert!(
        proximity[0].contains("instance=200 sysid=201 other=system 202"),
        "{}",
        out.stderr
    );
    assert!(
        proximity[1].contains("instance=201 sysid=202 other=system 201"),
        "{}",
        out.stderr
    );
    assert!(!out.stderr.contains("vehicle="), "{}", out.stderr);
}
