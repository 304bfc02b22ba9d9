//! What the integration tests share: a scratch directory of their own
//! ([`scratch_path`], [`scratch_dir`]), the built binary ([`bin`]), the
//! in-process daemon and a MAVLink client on loopback ([`daemon`]), and one
//! vehicle flown in the lockstep core ([`sitl`]). A test file takes it with
//! `mod common;`; each uses a part, so unused items are allowed here.
#![allow(dead_code, unreachable_pub)]

pub mod bin;
pub mod daemon;
pub mod sitl;

use std::path::PathBuf;
use std::sync::atomic::{AtomicU32, Ordering};

/// A path of its own for one test, with nothing there yet (a state
/// directory the code under test is to make): `rotorpilot-test-TAG-PID-N`
/// in the system's temporary directory.
pub fn scratch_path(tag: &str) -> PathBuf {
    static N: AtomicU32 = AtomicU32::new(0);
    let d = std::env::temp_dir().join(format!(
        "rotorpilot-test-{tag}-{}-{}",
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed)
    ));
    let _ = std::fs::remove_dir_all(&d);
    d
}

/// A fresh, empty directory of its own for one test ([`scratch_path`], made).
pub fn scratch_dir(tag: &str) -> PathBuf {
    let d = scratch_path(tag);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The repository's root (where `tools/`, `tests/fixtures/` and the shipped scenarios are).
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}
