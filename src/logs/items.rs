//! What became of each mission item in a flight, as `rotorpilot simulate`
//! and `rotorpilot replay` both report it ([`ItemTally`]): reached (when, and
//! how far from its point), ran (an item done at once), never reached or
//! never ran; and how closely the vehicle followed its shaped reference in
//! the air. Read after each step from the flight stack's item events and the
//! step's record; it never steers the flight.

use serde::Serialize;

use crate::autopilot::{Autopilot, ItemDone, LandedState};
use crate::geo::GeoPoint;
use crate::lockstep::Lockstep;
use crate::mission::{MissionItem, cmd};

/// What became of a mission item in the flight.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ItemOutcome {
    /// A navigation item whose point (or landing, or return) was reached.
    Reached,
    /// An item done at once (DO_CHANGE_SPEED, DO_JUMP, DO_SET_HOME, the
    /// accepted no-ops) that ran.
    Ran,
    /// A navigation item never reached.
    NeverReached,
    /// An item done at once that never ran: the mission never came to it.
    NeverRan,
}

impl ItemOutcome {
    /// As the text summary says it.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Reached => "reached",
            Self::Ran => "ran",
            Self::NeverReached => "never reached",
            Self::NeverRan => "never ran",
        }
    }
}

/// Whether a mission item is done at once, with no point to reach (the
/// navigator runs it and goes on to the next in the same step).
#[must_use]
pub fn done_at_once(command: u16) -> bool {
    matches!(command, cmd::DO_CHANGE_SPEED | cmd::DO_JUMP | cmd::DO_SET_HOME) || cmd::NO_OPS.contains(&command)
}

/// One item of the mission as flown.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ItemResult {
    /// MAVLink seq.
    pub seq: u16,
    /// MAV_CMD.
    pub command: u16,
    /// Reached, ran, never reached or never ran.
    pub outcome: ItemOutcome,
    /// When a navigation item was first reached [s] (`None`: never, or an item done at once).
    pub reached_s: Option<f64>,
    /// How often it was reached (DO_JUMP loops).
    pub times_reached: u32,
    /// When an item done at once first ran [s] (`None`: never, or a navigation item).
    pub ran_s: Option<f64>,
    /// How often it ran (DO_JUMP loops).
    pub times_ran: u32,
    /// Distance [m] from the true position to the item's point when first reached (positional items).
    pub distance_m: Option<f64>,
}

/// The items of one mission and the tracking error, tallied step by step.
#[derive(Clone, Debug)]
pub struct ItemTally {
    items: Vec<MissionItem>,
    /// The vehicle's NED origin (where it rested at start).
    origin: GeoPoint,
    results: Vec<ItemResult>,
    sum_sq: f64,
    n_air: u64,
    max_err: f64,
}

impl ItemTally {
    /// Before the flight of `items`, by a vehicle whose NED origin is `origin`.
    #[must_use]
    pub fn new(items: &[MissionItem], origin: GeoPoint) -> Self {
        Self {
            items: items.to_vec(),
            origin,
            results: items
                .iter()
                .enumerate()
                .map(|(k, it)| ItemResult {
                    seq: u16::try_from(k).unwrap_or(u16::MAX),
                    command: it.command,
                    outcome: if done_at_once(it.command) {
                        ItemOutcome::NeverRan
                    } else {
                        ItemOutcome::NeverReached
                    },
                    reached_s: None,
                    times_reached: 0,
                    ran_s: None,
                    times_ran: 0,
                    distance_m: None,
                })
                .collect(),
            sum_sq: 0.0,
            n_air: 0,
            max_err: 0.0,
        }
    }

    /// After a step of vehicle `i`: the distance `e = |p - p_ref|` [m]
    /// between the true position and the shaped reference, in the air
    /// (its maximum and `sqrt(sum e^2 / n)`), and the items reached or run
    /// at this step (the flight stack's events, drained here and returned).
    pub fn after_step(&mut self, core: &mut Lockstep<Autopilot>, i: usize) -> Vec<ItemDone> {
        let rec = core.last_step(i);
        let (truth, reference) = (rec.world.truth.position_ned, rec.control.reference.position_ned);
        if core.pilot(i).landed_state() == LandedState::InAir {
            let e = (truth - reference).norm();
            self.sum_sq += e * e;
            self.n_air += 1;
            self.max_err = self.max_err.max(e);
        }
        let time_s = core.time_s();
        let events = core.drain_mission_done(i);
        for &done in &events {
            let seq = match done {
                ItemDone::Reached(seq) => seq,
                ItemDone::Ran(seq) => {
                    if let Some(r) = self.results.get_mut(usize::from(seq)) {
                        r.times_ran += 1;
                        r.ran_s.get_or_insert(time_s);
                        r.outcome = ItemOutcome::Ran;
                    }
                    continue;
                }
            };
            let first = self
                .results
                .get(usize::from(seq))
                .is_some_and(|r| r.reached_s.is_none());
            let distance_m = if first { self.distance_m(core, i, seq) } else { None };
            if let Some(r) = self.results.get_mut(usize::from(seq)) {
                r.times_reached += 1;
                r.outcome = ItemOutcome::Reached;
                if first {
                    r.reached_s = Some(time_s);
                    r.distance_m = distance_m;
                }
            }
        }
        events
    }

    /// How far vehicle `i` is now from item `seq`'s point [m]: `|p - p_item|`,
    /// `p` its true position, NED, and a relative altitude taken above the
    /// vehicle's home (where it rested), as the flight stack takes it. The
    /// one distance an item is said to be "off" by, in the summaries and on
    /// the report page; `None` for an item without a point.
    #[must_use]
    pub fn distance_m(&self, core: &mut Lockstep<Autopilot>, i: usize, seq: u16) -> Option<f64> {
        let it = self.items.get(usize::from(seq))?;
        let home_alt_amsl_m = core.telemetry(i).home.alt_amsl_m;
        it.geo_point(home_alt_amsl_m)
            .map(|g| (core.world().plant(i).state().position_ned - g.ned_from(&self.origin)).norm())
    }

    /// The items reached among `events` (seq numbers, in order).
    #[must_use]
    pub fn reached_seqs(events: &[ItemDone]) -> Vec<u16> {
        events
            .iter()
            .filter_map(|d| match d {
                ItemDone::Reached(seq) => Some(*seq),
                ItemDone::Ran(_) => None,
            })
            .collect()
    }

    /// The items, in seq order.
    #[must_use]
    pub fn results(&self) -> &[ItemResult] {
        &self.results
    }

    /// The items, in seq order, taken.
    #[must_use]
    pub fn into_results(self) -> Vec<ItemResult> {
        self.results
    }

    /// The largest distance [m] from the shaped reference, in the air.
    #[must_use]
    pub fn max_tracking_error_m(&self) -> f64 {
        self.max_err
    }

    /// The RMS distance [m] from the shaped reference, in the air (0 when never in the air).
    #[must_use]
    pub fn rms_tracking_error_m(&self) -> f64 {
        if self.n_air > 0 {
            (self.sum_sq / self.n_air as f64).sqrt()
        } else {
            0.0
        }
    }
}

/// One line per item, as the summaries print them:
/// `  item   2 cmd    16: reached     24.12 s, 4.02 m off`.
#[must_use]
pub fn item_lines(results: &[ItemResult]) -> String {
    let mut s = String::new();
    for r in results {
        let (at, times) = match r.outcome {
            ItemOutcome::Reached => (r.reached_s, r.times_reached),
            ItemOutcome::Ran => (r.ran_s, r.times_ran),
            ItemOutcome::NeverReached | ItemOutcome::NeverRan => (None, 0),
        };
        let when = at.map_or(String::new(), |t| format!(" {t:9.2} s"));
        let off = r.distance_m.map_or(String::new(), |d| format!(", {d:.2} m off"));
        let times = if times > 1 {
            format!(" ({times} times)")
        } else {
            String::new()
        };
        s.push_str(&format!(
            "  item {:3} cmd {:5}: {:<7}{when}{off}{times}\n",
            r.seq,
            r.command,
            r.outcome.name()
        ));
    }
    s
}
