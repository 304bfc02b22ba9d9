//! `rotorpilot params`: the parameter reference, generated from the one
//! parameter table ([`crate::params::PARAMS`]) as text (PX4's parameter
//! reference layout), JSON or Markdown (`docs/parameters.md`, checked by
//! `tests/cli_params.rs` to be this command's output).

use std::fmt::Write as _;

use crate::params::{Effect, PARAMS, ParamSpec, ParamType};

/// The command that writes `docs/parameters.md`.
pub const REGENERATE: &str = "cargo run --release -- params --markdown > docs/parameters.md";

/// Output formats of `rotorpilot params`.
#[derive(Debug, Clone, clap::Args)]
pub struct ParamsArgs {
    /// Print a JSON list, one object per parameter (name, index, type,
    /// default, min, max, unit, description, values, reboot_required).
    #[arg(long, conflicts_with = "markdown")]
    pub json: bool,
    /// Print the Markdown reference (`docs/parameters.md`).
    #[arg(long)]
    pub markdown: bool,
}

/// Print the reference in the format `args` asks for.
///
/// # Errors
/// Only if JSON serialization fails (it does not for this table).
pub fn run(args: &ParamsArgs) -> anyhow::Result<()> {
    if args.json {
        println!("{}", serde_json::to_string_pretty(&json())?);
    } else if args.markdown {
        print!("{}", markdown());
    } else {
        print!("{}", text());
    }
    Ok(())
}

/// A number of the table in its type: INT32 as an integer, REAL32 in the
/// shortest form that reads back (`2.5`, `100000`, `0.15`).
fn number(p: &ParamSpec, x: f64) -> String {
    match p.kind {
        // integer entries are whole numbers (a table test checks it)
        ParamType::Int32 => format!("{}", x as i64),
        // PX4 declared no bound: the range is f32's
        ParamType::Real32 if x.abs() >= f64::from(f32::MAX) => format!("{:e}", x as f32),
        ParamType::Real32 => format!("{x}"),
    }
}

/// `x unit`, or `x` for a unitless parameter.
fn with_unit(p: &ParamSpec, x: f64) -> String {
    if p.unit.is_empty() {
        number(p, x)
    } else {
        format!("{} {}", number(p, x), p.unit)
    }
}

/// `0: hierarchical, 1: geometric, 2: passivity`.
fn values_line(p: &ParamSpec) -> String {
    p.values
        .iter()
        .map(|(v, meaning)| format!("{v}: {meaning}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Every parameter as PX4's reference prints one:
///
/// ```text
/// CTRL_TYPE (INT32)
///   Control law (switched bumplessly in flight)
///   Values: 0: hierarchical, 1: geometric, 2: passivity
///   Default 1, range 0 .. 2
/// ```
#[must_use]
pub fn text() -> String {
    let mut out = String::new();
    for p in PARAMS.iter() {
        let _ = writeln!(out, "{} ({})", p.name, p.kind);
        let _ = writeln!(out, "  {}", p.description);
        if p.effect == Effect::StoredOnly {
            let _ = writeln!(out, "  {NO_EFFECT}");
        }
        if !p.values.is_empty() {
            let _ = writeln!(out, "  Values: {}", values_line(p));
        }
        let _ = writeln!(
            out,
            "  Default {}, range {} .. {}",
            with_unit(p, p.default),
            number(p, p.min),
            with_unit(p, p.max)
        );
        if p.reboot_required {
            let _ = writeln!(out, "  Reboot required: used from the next start");
        }
        out.push('\n');
    }
    out
}

/// How the references mark a parameter rotorpilot stores but does not use.
const NO_EFFECT: &str = "No effect here (PX4 parameter: stored, range-checked and saved only)";

/// Every parameter as one JSON object, in index order.
#[must_use]
pub fn json() -> serde_json::Value {
    let num = |p: &ParamSpec, x: f64| match p.kind {
        ParamType::Int32 => serde_json::json!(x as i64),
        ParamType::Real32 => serde_json::json!(x),
    };
    PARAMS
        .iter()
        .enumerate()
        .map(|(index, p)| {
            serde_json::json!({
                "name": p.name,
                "index": index,
                "type": p.kind.name(),
                "default": num(p, p.default),
                "min": num(p, p.min),
                "max": num(p, p.max),
                "unit": p.unit,
                "description": p.description,
                "values": p.values.iter()
                    .map(|(v, meaning)| serde_json::json!({"value": v, "description": meaning}))
                    .collect::<Vec<_>>(),
                "reboot_required": p.reboot_required,
                "effect": match p.effect {
                    Effect::Acts => "acts",
                    Effect::StoredOnly => "none",
                },
            })
        })
        .collect()
}

/// The section of `docs/parameters.md` on where PX4's parameters come from.
const PX4_SOURCE: &str = include_str!("params_px4_source.md");

/// `docs/parameters.md`: a heading, how it is made, and one table row per
/// parameter (`|` in a text escaped).
#[must_use]
pub fn markdown() -> String {
    let cell = |s: &str| s.replace('|', "\\|");
    let mut out = String::from(
        "# Parameter reference\n\n\
         Every parameter of rotorpilot, in MAVLink index order (the order of\n\
         PARAM_REQUEST_LIST). Names, defaults and ranges of the PX4 parameters are\n\
         PX4's; INT32 values travel bytewise in MAVLink's float field, as PX4 sends\n\
         them (see [mavlink.md](mavlink.md)). A value out of range is refused with\n\
         PARAM_ERROR. Values are saved in the vehicle's state directory\n\
         (`params.toml`) and kept across restarts.\n\n\
         `SIM_MASS` and `MDL_MASS` default to the airframe's nominal mass; the\n\
         default shown is the `quad`'s.\n\n\
         The first parameters are the ones rotorpilot implements (column Acts:\n\
         yes). Then come the other parameters PX4 SITL's default multicopter\n\
         (gz_x500) boots with, with PX4's name, type, boot default, range, unit\n\
         and short description: a script written for PX4 can set and read them,\n\
         and they are saved like the others, but they have no effect here (Acts:\n\
         no). They come from `params/px4-multicopter.tsv`, which\n\
         `tools/px4_params.py` extracts from PX4's own parameter definitions;\n\
         [the section below](#where-the-px4-parameters-come-from) says which\n\
         PX4 commit, which modules, and how to refresh it.\n\n",
    );
    let _ = write!(
        out,
        "Generated from the parameter table (`src/params/table.rs`) by\n`{REGENERATE}`;\n\
         `rotorpilot params` prints it as text, `rotorpilot params --json` as JSON.\n\n"
    );
    out.push_str(PX4_SOURCE);
    let stored = PARAMS.iter().filter(|p| p.effect == Effect::StoredOnly).count();
    let _ = write!(
        out,
        "The data file lists {} PX4 parameters; {} of them are implemented here. \
         With rotorpilot's own, {} parameters in all, {} of them acting.\n\n",
        crate::params::px4_params().len(),
        crate::params::px4_params().len() - stored,
        PARAMS.len(),
        PARAMS.len() - stored,
    );
    out.push_str(
        "## The parameters\n\n\
         | Name | Type | Default | Min | Max | Unit | Acts | Description |\n|---|---|---|---|---|---|---|---|\n",
    );
    for p in PARAMS.iter() {
        let mut description = cell(p.description);
        if !p.values.is_empty() {
            let _ = write!(description, ". Values: {}", cell(&values_line(p)));
        }
        if p.reboot_required {
            description.push_str(". Reboot required (used from the next start)");
        }
        let _ = writeln!(
            out,
            "| `{}` | {} | {} | {} | {} | {} | {} | {} |",
            p.name,
            p.kind,
            number(p, p.default),
            number(p, p.min),
            number(p, p.max),
            cell(p.unit),
            match p.effect {
                Effect::Acts => "yes",
                Effect::StoredOnly => "no",
            },
            description
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_parameter_once_in_each_format() {
        let t = text();
        let md = markdown();
        let js = json();
        let list = js.as_array().unwrap();
        assert_eq!(list.len(), PARAMS.len());
        for (i, p) in PARAMS.iter().enumerate() {
            let heading = format!("{} ({})", p.name, p.kind);
            assert_eq!(t.lines().filter(|l| *l == heading).count(), 1, "{}", p.name);
            assert_eq!(md.matches(&format!("| `{}` |", p.name)).count(), 1, "{}", p.name);
            assert_eq!(list[i]["name"], p.name);
            assert_eq!(list[i]["values"].as_array().unwrap().len(), p.values.len());
        }
        assert!(t.starts_with(&format!("{} (REAL32)\n", PARAMS[0].name)));
    }

    /// Parameter `name`'s object in the JSON reference.
    fn param<'a>(js: &'a serde_json::Value, name: &str) -> &'a serde_json::Value {
        js.as_array().unwrap().iter().find(|p| p["name"] == name).unwrap()
    }

    #[test]
    fn formats_carry_type_range_unit_values_and_reboot() {
        let md = markdown();
        assert!(
            md.contains("| `MIS_TAKEOFF_ALT` | REAL32 | 2.5 | 0 | 3.4028235e38 | m | yes | Takeoff altitude"),
            "{md}"
        );
        assert!(
            md.contains("| `CTRL_TYPE` | INT32 | 1 | 0 | 2 |  | yes | Control law"),
            "{md}"
        );
        assert!(
            md.contains("Values: 0: hierarchical, 1: geometric, 2: passivity |"),
            "{md}"
        );
        assert!(md.contains("| `MAV_SYS_ID` | INT32 | 1 | 1 | 250 |  | yes | MAVLink system id: --instance + 1"));
        // a PX4 parameter rotorpilot stores without using, with PX4's range and unit
        assert!(
            md.contains(
                "| `MPC_ACC_DOWN_MAX` | REAL32 | 3 | 2 | 15 | m/s^2 | no | Maximum downwards acceleration in climb rate controlled modes |"
            ),
            "{md}"
        );
        assert!(md.contains("| `RTL_TYPE` | INT32 | 0 | -2147483648 | 2147483647 |  | no | Return type |"));
        let t = text();
        assert!(t.contains("MPC_XY_CRUISE (REAL32)\n  Cruise ground speed"));
        assert!(t.contains(&format!(
            "EKF2_MAG_TYPE (INT32)\n  Type of magnetometer fusion\n  {NO_EFFECT}\n"
        )));
        assert!(t.contains("  Default 5 m/s, range 0.5 .. 20 m/s\n"));
        assert!(t.contains("GF_ACTION (INT32)\n  Geofence breach action\n  Values: 0: none, 1: warning, 2: Hold"));
        let js = json();
        let gf = param(&js, "GF_ACTION");
        assert_eq!(gf["type"], "INT32");
        assert_eq!(gf["default"], serde_json::json!(2));
        assert_eq!(
            gf["values"][3],
            serde_json::json!({"value": 3, "description": "Return"})
        );
        assert_eq!(gf["reboot_required"], false);
        assert_eq!(gf["effect"], "acts");
        assert_eq!(param(&js, "RTL_APPR_FORCE")["effect"], "none");
        let alt = param(&js, "MIS_TAKEOFF_ALT");
        assert_eq!(alt["default"], serde_json::json!(2.5));
        assert_eq!(alt["unit"], "m");
    }
}
