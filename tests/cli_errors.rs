//! The binary's answers to bad input: each refusal said once, clearly (the
//! value as given, the range or the file and field, no cause repeated), with
//! exit status 1 from rotorpilot's own checks and 2 from the argument
//! parser's, nothing on stdout, and no state directory made; `--help` states
//! the ranges and port rules.

mod common;

use std::path::Path;
use std::time::Duration;

use common::bin::{LOOPBACK, run_within};
use common::scratch_path;

/// Run the binary with `args`, stopped after 10 s if it started the daemon
/// (a bad input let through); its exit status, stdout and stderr.
fn run(args: &[&str]) -> (Option<i32>, String, String) {
    let ran = run_within(args, Duration::from_secs(10));
    (ran.code, ran.stdout, ran.stderr)
}

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
    let scratch = common::scratch_dir("bad-input");
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
                "rotorpilot: {}:3:12: airframe: unknown airframe `nosuch`: {known}\n",
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
            "0 {}: ERROR: 3:12: airframe: unknown airframe `nosuch`: {known}\n\
             1 {}: ERROR: 3:12: airframe: unknown airframe `nosuch`: {known}\n",
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

#[test]
fn bad_options_are_refused_with_a_message() {
    for args in [
        vec!["--airframe", "no-such-frame"],
        vec!["--home", "47.3,8.5"],
        vec!["--speed", "0"],
        vec!["--link", "tcp:127.0.0.1:5760"],
    ] {
        let dir = scratch_path("bad");
        let d = dir.to_str().unwrap();
        let out = common::bin::run(
            &[
                &args[..],
                &[
                    "--state-dir",
                    d,
                    "--gcs-bind",
                    "127.0.0.1:0",
                    "--api-bind",
                    "127.0.0.1:0",
                ],
            ]
            .concat(),
        );
        assert!(!out.ok(), "{args:?}");
        assert!(out.stderr.contains("rotorpilot:"), "{args:?}: {}", out.stderr);
        let _ = std::fs::remove_dir_all(&dir);
    }
    // the whole message, once: no empty context before the cause
    let dir = scratch_path("bad");
    let out = common::bin::run(&["--airframe", "no-such-frame", "--state-dir", dir.to_str().unwrap()]);
    assert_eq!(
        out.stderr,
        "rotorpilot: unknown airframe `no-such-frame`: not a file and not a built-in airframe \
         (quad, hexa, octo, fsr-quad, hexa-ppnnpn)\n"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Out-of-range numbers are refused with the whole message (the value as
/// given, the range), the exit status 1 from rotorpilot's own check and 2
/// from the argument parser's, and nothing else on stderr.
#[test]
fn out_of_range_speed_and_instance_are_refused_with_the_whole_message() {
    for (args, status, message) in [
        (
            ["--speed", "1000.5"],
            1,
            "rotorpilot: --speed must be in (0, 1000], got 1000.5\n",
        ),
        (
            ["--speed", "NaN"],
            1,
            "rotorpilot: --speed must be in (0, 1000], got NaN\n",
        ),
        (
            ["--instance", "250"],
            2,
            "error: invalid value '250' for '--instance <INSTANCE>': 250 is not in 0..=249\n\n\
             For more information, try '--help'.\n",
        ),
    ] {
        let dir = scratch_path("range");
        let d = dir.to_str().unwrap();
        // a value let through would start the daemon: stopped, it fails below
        let out = run_within(
            &[&args[..], &["--state-dir", d], &LOOPBACK[..]].concat(),
            Duration::from_secs(5),
        );
        let made_state = dir.exists();
        let _ = std::fs::remove_dir_all(&dir);
        assert_eq!(out.code, Some(status), "{args:?}");
        assert_eq!(out.stderr, message, "{args:?}");
        assert!(out.stdout.is_empty(), "{args:?}");
        assert!(!made_state, "{args:?}: refused before making the state directory");
    }
}
