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
//!
//! Also the start-up banner's line of active injections ([`injections`]):
//! every `SIM_*` parameter not at its default, as the parameter file keeps
//! them across restarts, so that a disturbance or true mass set yesterday is
//! not a silent surprise today:
//!
//! ```text
//!   injected: SIM_MASS 10.0 kg (default 1.5), SIM_FEXT_X 2.0 N (default 0.0)
//! ```

use std::io::Write as _;
use std::time::Instant;

use mavlink::dialects::common::MavMessage;
use tokio::sync::watch;

use crate::link::streams::{self, PREARM_CHECK, SENSORS, Stream};
use crate::lockstep::Snapshot;
use crate::params::{ParamStore, ParamValue};

/// The prefix of the simulator's parameters (the world's truth, not the flight stack's).
const SIM_PREFIX: &str = "SIM_";

/// `injected: NAME VALUE UNIT (default D), ...` for every `SIM_*` parameter
/// of `params` not at its default (the airframe's for `SIM_MASS`), in table
/// order; `None` when there is none.
#[must_use]
pub(super) fn injections(params: &ParamStore) -> Option<String> {
    let shown: Vec<String> = params
        .iter()
        .enumerate()
        .filter(|(_, (spec, _))| spec.name.starts_with(SIM_PREFIX))
        .filter_map(|(i, (spec, value))| {
            let default = params.default_value(i)?;
            (value != default).then(|| {
                let unit = if spec.unit.is_empty() {
                    String::new()
                } else {
                    format!(" {}", spec.unit)
                };
                format!("{} {}{unit} (default {})", spec.name, show(value), show(default))
            })
        })
        .collect();
    (!shown.is_empty()).then(|| format!("injected: {}", shown.join(", ")))
}

/// A value as the banner shows it: integers as integers, floats with at
/// least one decimal (`10.0`, `0.25`).
fn show(v: ParamValue) -> String {
    match v {
        ParamValue::Int32(i) => i.to_string(),
        ParamValue::Real32(x) => format!("{x:?}"),
    }
}

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
    fn injections_list_every_sim_parameter_off_its_default() {
        let quad = crate::airframe::Airframe::load("quad").unwrap();
        let mut p = ParamStore::new(&quad);
        assert_eq!(injections(&p), None, "defaults: nothing injected");
        p.set("MPC_XY_CRUISE", ParamValue::Real32(7.0)).unwrap();
        assert_eq!(injections(&p), None, "a flight-stack parameter is no injection");
        p.set("SIM_MASS", ParamValue::Real32(10.0)).unwrap();
        p.set("SIM_FEXT_X", ParamValue::Real32(2.0)).unwrap();
        p.set("SIM_GE_EN", ParamValue::Int32(0)).unwrap();
        let nominal = show(p.default_value(p.index_of("SIM_MASS").unwrap()).unwrap());
        assert_eq!(
            injections(&p).unwrap(),
            format!(
                "injected: SIM_FEXT_X 2.0 N (default 0.0), SIM_MASS 10.0 kg (default {nominal}), \
                 SIM_GE_EN 0 (default 1)"
            )
        );
    }

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
