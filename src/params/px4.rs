//! PX4's parameter surface: every parameter PX4 SITL's default multicopter
//! (gz_x500) boots with, read from `params/px4-multicopter.tsv` (generated
//! from PX4's own parameter definitions by `tools/px4_params.py`; see
//! `docs/parameters.md`). The ones rotorpilot implements are declared in
//! `table.rs` and act; the rest are stored, range-checked and persisted like
//! any parameter but change nothing here ([`Effect::StoredOnly`]), so a
//! script written for PX4 that sets one gets its value back, never
//! DOES_NOT_EXIST.
//!
//! The file is compiled in (`include_str!`) and parsed once, at first use.
//! Each line: `name type default min max unit description source`, tab
//! separated; `type` is `INT32` or `FLOAT`; an empty `min`/`max` (PX4
//! declares no bound) is the type's limit.

use super::{Effect, ParamSpec, ParamType};

/// The data file, as committed.
pub(super) const TSV: &str = include_str!("../../params/px4-multicopter.tsv");

/// One line of the data file.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Px4Param {
    /// PX4's name.
    pub name: &'static str,
    /// PX4's type (FLOAT is REAL32).
    pub kind: ParamType,
    /// The value PX4 SITL's multicopter boots with.
    pub default: f64,
    /// PX4's declared minimum, or the type's limit.
    pub min: f64,
    /// PX4's declared maximum, or the type's limit.
    pub max: f64,
    /// PX4's unit (may be empty).
    pub unit: &'static str,
    /// PX4's short description.
    pub description: &'static str,
    /// The PX4 file declaring it (and the startup script that set its default).
    pub source: &'static str,
}

/// Every line of the data file, in its (alphabetical) order.
///
/// # Panics
/// If the committed file is malformed; `every_line_parses` checks it, so a
/// build whose data file does not parse fails its tests.
#[must_use]
pub fn px4_params() -> Vec<Px4Param> {
    TSV.lines()
        .filter(|l| !l.starts_with('#') && !l.is_empty())
        .map(|l| parse_line(l).unwrap_or_else(|e| panic!("params/px4-multicopter.tsv: {e}: {l}")))
        .collect()
}

/// One data line, or what is wrong with it.
fn parse_line(line: &'static str) -> Result<Px4Param, String> {
    let cols: Vec<&'static str> = line.split('\t').collect();
    let [name, kind, default, min, max, unit, description, source] = cols[..] else {
        return Err(format!("{} columns, expected 8", cols.len()));
    };
    let kind = match kind {
        "INT32" => ParamType::Int32,
        "FLOAT" => ParamType::Real32,
        other => return Err(format!("type `{other}`")),
    };
    let (lo, hi) = kind.limits();
    let num = |s: &str, or: f64| -> Result<f64, String> {
        if s.is_empty() {
            Ok(or)
        } else {
            s.parse::<f64>().map_err(|_| format!("`{s}` is not a number"))
        }
    };
    let default = num(default, f64::NAN)?;
    if default.is_nan() {
        return Err("no default".into());
    }
    // PX4 does not check a default against its own bounds; a range here always holds it.
    let min = num(min, lo)?.min(default);
    let max = num(max, hi)?.max(default);
    Ok(Px4Param {
        name,
        kind,
        default,
        min,
        max,
        unit,
        description,
        source,
    })
}

impl Px4Param {
    /// A parameter that rotorpilot stores but does not use.
    #[must_use]
    pub fn stored_only(&self) -> ParamSpec {
        ParamSpec {
            name: self.name,
            kind: self.kind,
            default: self.default,
            min: self.min,
            max: self.max,
            unit: self.unit,
            description: self.description,
            values: &[],
            reboot_required: false,
            effect: Effect::StoredOnly,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_line_parses_and_names_are_unique_and_short() {
        let all = px4_params();
        assert!(all.len() > 1000, "{}", all.len());
        for w in all.windows(2) {
            assert!(w[0].name < w[1].name, "sorted and unique: {} {}", w[0].name, w[1].name);
        }
        for p in &all {
            assert!(p.name.len() <= 16, "{}", p.name);
            assert!(!p.description.is_empty(), "{}", p.name);
            assert!(p.min <= p.default && p.default <= p.max, "{}", p.name);
        }
    }

    #[test]
    fn bad_lines_are_named() {
        assert!(parse_line("A\tINT32\t1").unwrap_err().contains("columns"));
        assert!(parse_line("A\tDOUBLE\t1\t\t\t\td\ts").unwrap_err().contains("DOUBLE"));
        assert!(parse_line("A\tFLOAT\tx\t\t\t\td\ts").unwrap_err().contains("`x`"));
        let p = parse_line("A\tFLOAT\t-1.0\t0.0\t\tm\td\ts").unwrap();
        assert_eq!((p.min, p.default), (-1.0, -1.0));
        assert_eq!(p.max, f64::from(f32::MAX));
    }
}
