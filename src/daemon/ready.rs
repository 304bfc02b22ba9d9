//! The one-time `ready to arm` line on stdout, for scripts and the pytest
//! fixture (`python/rotorpilot`) that start a vehicle and wait for it:
//!
//! ```text
//! rotorpilot: ready to arm (0.043 s after start)
//! ```
//!
//! "Ready" is what a client sees in SYS_STATUS: every sensor bit healthy and
//! MAV_SYS_STATUS_PREARM_CHECK set (the prearm checks pass, which include a
//! valid home; HOME_POSITION is streamed from the first message on). The
//! health word is built by the same function the links use
//! ([`streams::build`]), so the line cannot disagree with the link. The time
//! is wall time since the process started ([`super::Config::started`]):
//! loading the airframe, parameters and plans and binding the sockets count.

use std::io::Write as _;
use std::time::Instant;

use mavlink::dialects::common::MavMessage;
use tokio::sync::watch;

use crate::link::streams::{self, PREARM_CHECK, SENSORS, Stream};
use crate::lockstep::Snapshot;

/// The SYS_STATUS health word equals present-and-enabled (`SENSORS | PREARM_CHECK`).
#[must_use]
pub(super) fn ready_to_arm(snapshot: &Snapshot) -> bool {
    match streams::build(Stream::SysStatus, snapshot, 0).first() {
        Some(MavMessage::SYS_STATUS(s)) => s.onboard_control_sensors_health.bits() == SENSORS | PREARM_CHECK,
        _ => false,
    }
}

/// Watch the telemetry until the vehicle is first ready to arm, print the
/// line (flushed) and end; end silently at shutdown.
pub(super) async fn announce(
    started: Instant,
    mut tels: Vec<watch::Receiver<Snapshot>>,
    mut stop: watch::Receiver<bool>,
) {
    // a fleet is ready when every vehicle has been ready once (one may be
    // armed, or faulted, before the last is ready)
    let mut was_ready = vec![false; tels.len()];
    loop {
        for (t, r) in tels.iter_mut().zip(&mut was_ready) {
            *r = *r || ready_to_arm(&t.borrow_and_update());
        }
        let waiting = was_ready.iter().position(|r| !r);
        let Some(i) = waiting else {
            let mut out = std::io::stdout().lock();
            // a closed stdout (the starter went away) is no reason to stop the vehicle
            let _ = writeln!(
                out,
                "rotorpilot: ready to arm ({:.3} s after start)",
                started.elapsed().as_secs_f64()
            );
            let _ = out.flush();
            return;
        };
        tokio::select! {
            changed = tels[i].changed() => if changed.is_err() { return },
            _ = stop.changed() => return,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::testing::snapshot;

    #[test]
    fn ready_follows_the_prearm_checks_and_the_gps_fix() {
        let mut s = snapshot();
        assert!(ready_to_arm(&s), "the test snapshot passes prearm with a 3D fix");
        s.telemetry.prearm_ok = false;
        assert!(!ready_to_arm(&s), "prearm failing");
        s.telemetry.prearm_ok = true;
        s.telemetry.gps_fix = crate::signals::GpsFix::None;
        assert!(!ready_to_arm(&s), "no GPS fix");
    }
}
