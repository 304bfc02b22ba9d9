//! Where a fleet's vehicles spawn: the one reading of a `[[vehicle]]`
//! entry's `count`, `offset_m` and `spacing_m`, shared by the daemon's fleet
//! files (`rotorpilot --fleet FILE`, and `--count N`) and headless fleets
//! (`rotorpilot simulate FLEET.toml`), so that one entry places its vehicles
//! the same way in both.
//!
//! ```toml
//! count = 4                # optional (default 1): the entry makes vehicles k = 0..count
//! offset_m = [0.0, 5.0]    # optional: vehicle k = 0 spawns NORTH, EAST [m] of the fleet's origin
//! spacing_m = [0.0, 10.0]  # optional (default [3.0, 0.0]): NORTH, EAST [m] between copies
//! ```
//!
//! Vehicle k of an entry spawns at `offset_m + k * spacing_m` (NED, on the
//! ground: down is 0). Without `offset_m` the entry's first vehicle spawns
//! in PX4's multi-vehicle layout (`sitl_multiple_run.sh` spawns instance N
//! at 3N m north): [`FLEET_SPACING_M`] times its number north, its number
//! being its instance in the daemon, its index (from 0, in file order) in a
//! headless fleet. Without `spacing_m`, copies continue that layout,
//! [`FLEET_SPACING_M`] apart to the north. Offsets and spacings are two
//! finite numbers; `count` is 1 to [`MAX_VEHICLES`]. Pure: no files.

use toml::Spanned;

/// Distance [m] between the spawn points of consecutive vehicles, north,
/// where a fleet file gives no offset or spacing, and between the
/// instances of `rotorpilot --count N` (PX4 gazebo-classic
/// `sitl_multiple_run.sh` spawns instance N at y = 3N m): instance i spawns
/// `FLEET_SPACING_M * i` north of the fleet's origin, by absolute instance,
/// so that fleets split across processes by instance ranges keep one layout.
pub const FLEET_SPACING_M: f64 = 3.0;

/// The most vehicles one entry (and one headless fleet file) may make.
pub const MAX_VEHICLES: usize = 100_000;

/// The spawn points of one fleet entry's vehicles, NORTH, EAST [m] from
/// the fleet's origin.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    count: usize,
    first_m: [f64; 2],
    spacing_m: [f64; 2],
}

impl Placement {
    /// PX4's layout: `count` vehicles numbered from `first`, vehicle `i`
    /// [`FLEET_SPACING_M`] x `i` north (what an entry without `offset_m` and
    /// `spacing_m` gives, and `rotorpilot --count N`).
    #[must_use]
    pub fn px4(first: u64, count: usize) -> Self {
        Self {
            count,
            first_m: [FLEET_SPACING_M * first as f64, 0.0],
            spacing_m: [FLEET_SPACING_M, 0.0],
        }
    }

    /// Read entry `entry`'s (counted from 1, as errors name it:
    /// `vehicle[2].count`) placement fields; `first` is the number of its
    /// first vehicle (the daemon's instance, a headless fleet's index).
    ///
    /// # Errors
    /// `(byte offset of the field, message)`: a count outside 1 to
    /// [`MAX_VEHICLES`], an offset or spacing that is not two finite numbers.
    pub fn read(
        entry: usize,
        first: u64,
        count: Option<&Spanned<i64>>,
        offset_m: Option<&Spanned<Vec<f64>>>,
        spacing_m: Option<&Spanned<Vec<f64>>>,
    ) -> Result<Self, (usize, String)> {
        let field = |name: &str| format!("vehicle[{entry}].{name}");
        let mut p = Self::px4(first, 1);
        if let Some(c) = count {
            p.count = usize::try_from(*c.get_ref())
                .ok()
                .filter(|n| (1..=MAX_VEHICLES).contains(n))
                .ok_or_else(|| {
                    (
                        c.span().start,
                        format!("{}: must be 1 to {MAX_VEHICLES}, got {}", field("count"), c.get_ref()),
                    )
                })?;
        }
        if let Some(o) = offset_m {
            p.first_m = north_east(o).map_err(|m| (o.span().start, format!("{}: {m}", field("offset_m"))))?;
        }
        if let Some(s) = spacing_m {
            p.spacing_m = north_east(s).map_err(|m| (s.span().start, format!("{}: {m}", field("spacing_m"))))?;
        }
        Ok(p)
    }

    /// How many vehicles the entry makes.
    #[must_use]
    pub fn count(&self) -> usize {
        self.count
    }

    /// Vehicle `k`'s spawn point (`k` from 0): `offset + k * spacing`,
    /// NORTH, EAST [m].
    #[must_use]
    pub fn spawn(&self, k: usize) -> [f64; 2] {
        let k = k as f64;
        [
            self.first_m[0] + k * self.spacing_m[0],
            self.first_m[1] + k * self.spacing_m[1],
        ]
    }
}

/// `[NORTH, EAST]` in metres, two finite numbers, or what is wrong.
fn north_east(v: &Spanned<Vec<f64>>) -> Result<[f64; 2], String> {
    match v.get_ref()[..] {
        [north, east] if north.is_finite() && east.is_finite() => Ok([north, east]),
        _ => Err(format!(
            "expected [NORTH, EAST] in metres, two finite numbers, got {:?}",
            v.get_ref()
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::Deserialize;

    #[derive(Deserialize)]
    struct Entry {
        count: Option<Spanned<i64>>,
        offset_m: Option<Spanned<Vec<f64>>>,
        spacing_m: Option<Spanned<Vec<f64>>>,
    }

    fn read(text: &str, first: u64) -> Result<Placement, String> {
        let e: Entry = toml::from_str(text).unwrap();
        Placement::read(1, first, e.count.as_ref(), e.offset_m.as_ref(), e.spacing_m.as_ref()).map_err(|(_, m)| m)
    }

    #[test]
    fn an_entry_spawns_at_its_offset_plus_k_spacings() {
        let p = read("count = 3\noffset_m = [50.0, 1.0]\nspacing_m = [0.0, 10.0]\n", 7).unwrap();
        assert_eq!(p.count(), 3);
        assert_eq!(
            [p.spawn(0), p.spawn(1), p.spawn(2)],
            [[50.0, 1.0], [50.0, 11.0], [50.0, 21.0]]
        );
    }

    #[test]
    fn without_offset_or_spacing_it_is_px4s_layout_3_m_north_per_number() {
        let p = read("count = 2\n", 4).unwrap();
        assert_eq!(p, Placement::px4(4, 2));
        assert_eq!([p.spawn(0), p.spawn(1)], [[12.0, 0.0], [15.0, 0.0]]);
        // an offset without spacing: the copies 3 m apart to the north
        let p = read("count = 2\noffset_m = [-6.0, 5.0]\n", 10).unwrap();
        assert_eq!([p.spawn(0), p.spawn(1)], [[-6.0, 5.0], [-3.0, 5.0]]);
        assert_eq!(read("", 0).unwrap().count(), 1);
    }

    #[test]
    fn a_bad_count_offset_or_spacing_is_named() {
        assert_eq!(
            read("count = 0\n", 0).unwrap_err(),
            "vehicle[1].count: must be 1 to 100000, got 0"
        );
        assert_eq!(
            read("offset_m = [1.0]\n", 0).unwrap_err(),
            "vehicle[1].offset_m: expected [NORTH, EAST] in metres, two finite numbers, got [1.0]"
        );
        assert_eq!(
            read("spacing_m = [1.0, inf]\n", 0).unwrap_err(),
            "vehicle[1].spacing_m: expected [NORTH, EAST] in metres, two finite numbers, got [1.0, inf]"
        );
    }
}
