//! Parameters declared once as data (PX4 style): name (<= 16 characters),
//! type, default, range, unit and description in one table; MAVLink's
//! PARAM_* protocol, the persisted file and the parameter reference
//! (`rotorpilot params`, `docs/parameters.md`) derive from it.
//!
//! * [`PARAMS`] (`table.rs`): the table, in MAVLink index order: the
//!   parameters rotorpilot implements, then the rest of PX4 SITL's
//!   multicopter parameters (`px4.rs`, from `params/px4-multicopter.tsv`),
//!   stored without effect ([`Effect`]).
//! * [`ParamStore`] (`store.rs`): typed values with airframe-dependent
//!   defaults, checked `set` that changes nothing on refusal ([`ParamError`]).
//! * persistence (`file.rs`): [`ParamStore::save`] writes a small TOML file
//!   (`NAME = value`, one per line) atomically; [`ParamStore::load`] reads it
//!   line by line, skipping bad entries with a warning and keeping the rest.
//!
//! INT32 values travel *bytewise* in MAVLink's float field, as PX4 sends them
//! ([`ParamValue::to_mavlink_float`], [`ParamValue::from_mavlink`]).
//!
//! Pure: no clock, no global state; only `save`/`load` touch the file system.

mod file;
mod px4;
mod store;
mod table;

pub use file::{Loaded, ParamFileError, set_aside_path};
pub use px4::{Px4Param, px4_params};
pub use store::{ParamError, ParamStore};
pub use table::{PARAMS, Param};

/// ` (did you mean NAME?)` for an unknown parameter name within two edits
/// (insertions, deletions, substitutions; letters compared case-blind) of
/// a real one, the closest first in table order; else empty.
#[must_use]
pub fn did_you_mean(name: &str) -> String {
    let wanted = name.to_ascii_uppercase();
    PARAMS
        .iter()
        .map(|p| (edit_distance(&wanted, p.name), p.name))
        .filter(|&(d, _)| d <= 2)
        .min_by_key(|&(d, _)| d)
        .map_or_else(String::new, |(_, n)| format!(" (did you mean {n}?)"))
}

/// Levenshtein distance between two ASCII strings (bytes).
fn edit_distance(a: &str, b: &str) -> usize {
    let (a, b) = (a.as_bytes(), b.as_bytes());
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, &x) in a.iter().enumerate() {
        let mut diagonal = row[0];
        row[0] = i + 1;
        for (j, &y) in b.iter().enumerate() {
            let next = (diagonal + usize::from(x != y)).min(row[j] + 1).min(row[j + 1] + 1);
            diagonal = row[j + 1];
            row[j + 1] = next;
        }
    }
    row[b.len()]
}

use serde::Serialize;

/// MAVLink parameter types rotorpilot uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum ParamType {
    /// MAV_PARAM_TYPE_INT32 (6), sent bytewise in the float field as PX4 does.
    Int32,
    /// MAV_PARAM_TYPE_REAL32 (9).
    Real32,
}

impl ParamType {
    /// The MAV_PARAM_TYPE number: 6 for INT32, 9 for REAL32.
    #[must_use]
    pub fn mavlink_id(self) -> u8 {
        match self {
            ParamType::Int32 => 6,
            ParamType::Real32 => 9,
        }
    }

    /// The smallest and largest value the type holds, as f64: a bound PX4
    /// leaves undeclared is this limit.
    #[must_use]
    pub fn limits(self) -> (f64, f64) {
        match self {
            ParamType::Int32 => (f64::from(i32::MIN), f64::from(i32::MAX)),
            ParamType::Real32 => (f64::from(f32::MIN), f64::from(f32::MAX)),
        }
    }

    /// The type of a MAV_PARAM_TYPE number (only 6 and 9 are used, as in PX4).
    #[must_use]
    pub fn from_mavlink_id(id: u8) -> Option<ParamType> {
        match id {
            6 => Some(ParamType::Int32),
            9 => Some(ParamType::Real32),
            _ => None,
        }
    }

    /// `INT32` or `REAL32`.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            ParamType::Int32 => "INT32",
            ParamType::Real32 => "REAL32",
        }
    }
}

impl std::fmt::Display for ParamType {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A typed parameter value.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, serde::Deserialize)]
pub enum ParamValue {
    /// An integer.
    Int32(i32),
    /// A float.
    Real32(f32),
}

impl ParamValue {
    /// The type of this value.
    #[must_use]
    pub fn kind(&self) -> ParamType {
        match self {
            ParamValue::Int32(_) => ParamType::Int32,
            ParamValue::Real32(_) => ParamType::Real32,
        }
    }

    /// The value as `f64` (exact for both types).
    #[must_use]
    pub fn as_f64(&self) -> f64 {
        match *self {
            ParamValue::Int32(i) => f64::from(i),
            ParamValue::Real32(x) => f64::from(x),
        }
    }

    /// The `param_value` float of PARAM_VALUE / PARAM_SET as PX4 sends it:
    /// REAL32 as is, INT32 *bytewise* (`f32::from_bits(i as u32)`, so INT32 1
    /// travels as about 1.4e-45).
    #[must_use]
    pub fn to_mavlink_float(&self) -> f32 {
        match *self {
            ParamValue::Int32(i) => f32::from_bits(i.cast_unsigned()),
            ParamValue::Real32(x) => x,
        }
    }

    /// Decode a `param_value` float with its MAV_PARAM_TYPE number (6 INT32
    /// bytewise, 9 REAL32); `None` for any other type.
    #[must_use]
    pub fn from_mavlink(kind: u8, value: f32) -> Option<ParamValue> {
        match ParamType::from_mavlink_id(kind)? {
            ParamType::Int32 => Some(ParamValue::Int32(value.to_bits().cast_signed())),
            ParamType::Real32 => Some(ParamValue::Real32(value)),
        }
    }
}

impl std::fmt::Display for ParamValue {
    /// Integers as integers; floats in the shortest form that reads back to the same `f32`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ParamValue::Int32(i) => write!(f, "{i}"),
            ParamValue::Real32(x) => write!(f, "{x}"),
        }
    }
}

/// One declared parameter.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ParamSpec {
    /// MAVLink name, upper case, at most 16 characters.
    pub name: &'static str,
    /// Type.
    pub kind: ParamType,
    /// Default value. For the few parameters whose default depends on the
    /// airframe (`SIM_MASS`, `MDL_MASS`) this is the default vehicle's
    /// (`quad`) and the description says so; [`ParamStore::default_value`]
    /// gives the one in force.
    pub default: f64,
    /// Smallest allowed value.
    pub min: f64,
    /// Largest allowed value.
    pub max: f64,
    /// Unit (`m`, `m/s`, `N`, `N m`, `kg`, `rad/s`, `s`, `mAh`, `%`, or empty).
    pub unit: &'static str,
    /// One-line description.
    pub description: &'static str,
    /// For a parameter that selects one of a few meanings (an action, a
    /// law, a switch): each value with its meaning, ascending; empty for a
    /// quantity.
    pub values: &'static [(i32, &'static str)],
    /// The value is stored and persisted at once but used only from the next
    /// start (PX4's `reboot_required`), e.g. `MAV_SYS_ID`.
    pub reboot_required: bool,
    /// Whether setting it changes anything here.
    pub effect: Effect,
}

/// What a parameter does in rotorpilot.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum Effect {
    /// rotorpilot implements it: its value is used.
    Acts,
    /// One of PX4's parameters that rotorpilot does not implement: stored,
    /// range-checked and persisted so a script written for PX4 can set and
    /// read it, but it changes nothing here.
    StoredOnly,
}

impl ParamSpec {
    /// The declared default as a typed value.
    #[must_use]
    pub fn default_value(&self) -> ParamValue {
        match self.kind {
            // the table's integer defaults are small whole numbers (checked by a test)
            ParamType::Int32 => ParamValue::Int32(self.default as i32),
            ParamType::Real32 => ParamValue::Real32(self.default as f32),
        }
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_misspelled_parameter_gets_the_closest_name() {
        assert_eq!(super::did_you_mean("MPC_XY_CRUIS"), " (did you mean MPC_XY_CRUISE?)");
        assert_eq!(
            super::did_you_mean("mis_takeoff_alt"),
            " (did you mean MIS_TAKEOFF_ALT?)"
        );
        assert_eq!(super::did_you_mean("NOTHING_LIKE_IT"), "");
    }

    use super::*;

    #[test]
    fn int32_travels_bytewise_and_real32_as_is() {
        let one = ParamValue::Int32(1);
        let f = one.to_mavlink_float();
        assert_eq!(f.to_bits(), 1);
        assert!(f > 0.0 && f < 1e-44, "denormal, as PX4 sends it");
        assert_eq!(ParamValue::from_mavlink(6, f), Some(one));
        let neg = ParamValue::Int32(-7);
        assert_eq!(ParamValue::from_mavlink(6, neg.to_mavlink_float()), Some(neg));
        let big = ParamValue::Int32(i32::MAX);
        assert_eq!(ParamValue::from_mavlink(6, big.to_mavlink_float()), Some(big));
        let r = ParamValue::Real32(2.5);
        assert_eq!(r.to_mavlink_float(), 2.5);
        assert_eq!(ParamValue::from_mavlink(9, 2.5), Some(r));
        assert_eq!(ParamValue::from_mavlink(4, 1.0), None);
        assert_eq!(ParamType::Int32.mavlink_id(), 6);
        assert_eq!(ParamType::Real32.mavlink_id(), 9);
        assert_eq!(ParamType::from_mavlink_id(10), None);
    }

    #[test]
    fn display_round_trips() {
        for v in [0.1f32, 2.5, 1e-7, 123_456.79, -3.0] {
            let s = ParamValue::Real32(v).to_string();
            assert_eq!(s.parse::<f32>().unwrap(), v);
        }
        assert_eq!(ParamValue::Int32(-3).to_string(), "-3");
    }
}
