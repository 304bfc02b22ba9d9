//! The built `rotorpilot` binary: the one way the tests run it, to its end
//! ([`run`]), bounded in time for input that, let through, would start the
//! daemon ([`run_within`]), or as a daemon on loopback until it is ready to
//! arm ([`start_until_ready`]).

use std::io::{BufRead as _, BufReader, Lines};
use std::path::Path;
use std::process::{Child, ChildStdout, Command, Output, Stdio};
use std::time::{Duration, Instant};

/// Both links on free loopback ports, no remotes: a daemon that talks to no one.
pub const LOOPBACK: [&str; 8] = [
    "--gcs-bind",
    "127.0.0.1:0",
    "--api-bind",
    "127.0.0.1:0",
    "--gcs-remote",
    "none",
    "--api-remote",
    "none",
];

/// The built binary, to be given arguments.
pub fn rotorpilot() -> Command {
    Command::new(env!("CARGO_BIN_EXE_rotorpilot"))
}

/// What a run of the binary gave: its exit code (None: killed by a signal)
/// and what it printed.
#[derive(Debug)]
pub struct Ran {
    /// The exit code.
    pub code: Option<i32>,
    /// Standard output.
    pub stdout: String,
    /// Standard error.
    pub stderr: String,
}

impl Ran {
    /// It exited with 0.
    pub fn ok(&self) -> bool {
        self.code == Some(0)
    }
}

impl From<Output> for Ran {
    fn from(o: Output) -> Self {
        Ran {
            code: o.status.code(),
            stdout: String::from_utf8_lossy(&o.stdout).into_owned(),
            stderr: String::from_utf8_lossy(&o.stderr).into_owned(),
        }
    }
}

/// Run the binary with `args` to its end.
pub fn run(args: &[&str]) -> Ran {
    rotorpilot().args(args).output().unwrap().into()
}

/// Run the binary with `args`, killed after `limit` if still running (input
/// let through would start the daemon: the status then shows it).
pub fn run_within(args: &[&str], limit: Duration) -> Ran {
    let mut child = rotorpilot()
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let t0 = Instant::now();
    while child.try_wait().unwrap().is_none() && t0.elapsed() < limit {
        std::thread::sleep(Duration::from_millis(10));
    }
    let _ = child.kill();
    child.wait_with_output().unwrap().into()
}

/// A daemon on `dir` (loopback ports), once it says it is ready to arm,
/// with its stdout still open (a closed pipe could end it early).
pub fn start_until_ready(dir: &Path) -> (Child, Lines<BufReader<ChildStdout>>) {
    let mut child = rotorpilot()
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
