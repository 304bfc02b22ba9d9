//! Encounters: each proximity event of a fleet followed to its closest
//! approach, until the pair is apart again or the flight ends. The one
//! piece of code both the headless fleet (`rotorpilot simulate FLEET.toml`)
//! and the live daemon's fleet follow their encounters with.
//!
//! An encounter opens with a [`ProximityEvent`] and stays open while the
//! core holds its pair near or touching ([`Lockstep::proximity_pairs`]: until
//! the pair is farther than the reporting distance x 1.1). After every step
//! its closest approach is `min |p_b - p_a|` (world NED positions, centre to
//! centre) over the steps since it opened.

use super::FleetEvent;
use crate::lockstep::{Lockstep, Pilot};
use crate::sim::proximity::ProximityEvent;

/// The open encounters (only these are looked at after a step: nothing to
/// do when there is none).
#[derive(Clone, Debug, Default)]
pub struct Encounters {
    /// In the order they opened.
    open: Vec<FleetEvent>,
}

impl Encounters {
    /// Open an encounter with `event`, raised by the step that ended at
    /// simulated time `time_s` [s].
    pub fn open(&mut self, time_s: f64, event: ProximityEvent) {
        self.open.push(FleetEvent::from((time_s, event)));
    }

    /// After a step of `core`: each open encounter's closest approach so
    /// far; the encounters whose pair is apart again are closed and
    /// returned, in the order they opened.
    pub fn follow<P: Pilot>(&mut self, core: &Lockstep<P>) -> Vec<FleetEvent> {
        let mut ended = Vec::new();
        if self.open.is_empty() {
            return ended;
        }
        let pairs = core.proximity_pairs();
        let t = core.time_s();
        self.open.retain_mut(|e| {
            if pairs.binary_search_by(|&(a, b, _)| (a, b).cmp(&(e.a, e.b))).is_err() {
                ended.push(*e);
                return false;
            }
            let d = (core.noted_position_ned(e.b) - core.noted_position_ned(e.a)).norm();
            if d < e.closest_m {
                e.closest_m = d;
                e.closest_s = t;
            }
            true
        });
        ended
    }

    /// The flight is over: the encounters still open, as they stand, in
    /// the order they opened.
    #[must_use]
    pub fn finish(self) -> Vec<FleetEvent> {
        self.open
    }
}
