//! `missions.json`: the plans a vehicle keeps in its state directory, beside
//! `params.toml`, as PX4 keeps them in its dataman across restarts.
//!
//! ```json
//! {
//!   "format": "rotorpilot-plans",
//!   "version": 1,
//!   "mission": [
//!     {"frame": 3, "command": 22, "autocontinue": true, "params": [0.0, 0.0, 0.0, "nan"], "x": 47.397742, "y": 8.545594, "z": 10.0},
//!     {"frame": 2, "command": 20, "autocontinue": true, "params": ["nan", "nan", "nan", "nan"], "x": 0.0, "y": 0.0, "z": 0.0}
//!   ],
//!   "fence": [],
//!   "rally": []
//! }
//! ```
//!
//! One item per line, its fields [`MissionItem`]'s. Every number reads back
//! bit for bit, so a restored plan keeps its id (the CRC32 covers the bits):
//! the numbers are written as [`crate::exact_json`] writes them (the flight
//! record's spelling: NaN as `"nan"`, or `"nan:0x…"` for a NaN of other bits,
//! infinities as `"inf"` and `"-inf"`). Files written before that spelled
//! the usual quiet NaN `null`; that still reads.
//!
//! Reading refuses anything it does not know (a missing or unknown field, a
//! newer version, a plan the vehicle would refuse) with an error naming the
//! file and the field (`mission[3].params[1]`). Writing is atomic
//! ([`crate::statefile`]).

use std::path::Path;

use super::{Json, MissionFileError, Origin, Shape, check_plan, join, show, utf8};
use crate::exact_json::{self, FloatError};
use crate::mission::{MissionItem, MissionType, Plan, Plans};
use crate::statefile;

/// The `format` field.
pub const STATE_FORMAT: &str = "rotorpilot-plans";
/// The `version` field this module writes and reads.
pub const STATE_VERSION: i64 = 1;

/// One item on one line.
fn item_json(it: &MissionItem) -> String {
    let [p1, p2, p3, p4] = it.params.map(exact_json::f32_value);
    format!(
        "{{\"frame\": {}, \"command\": {}, \"autocontinue\": {}, \"params\": [{p1}, {p2}, {p3}, {p4}], \"x\": {}, \"y\": {}, \"z\": {}}}",
        it.frame,
        it.command,
        it.autocontinue,
        exact_json::f64_value(it.x),
        exact_json::f64_value(it.y),
        exact_json::f32_value(it.z)
    )
}

/// The file text for `plans` (module doc).
#[must_use]
pub fn plans_to_text(plans: &Plans) -> String {
    let mut out = format!("{{\n  \"format\": \"{STATE_FORMAT}\",\n  \"version\": {STATE_VERSION},\n");
    for (n, kind) in MissionType::ALL.into_iter().enumerate() {
        let items = plans.get(kind).items();
        out.push_str(&format!("  \"{}\": [", kind.name()));
        for (i, it) in items.iter().enumerate() {
            out.push_str(if i == 0 { "\n    " } else { ",\n    " });
            out.push_str(&item_json(it));
        }
        if !items.is_empty() {
            out.push_str("\n  ");
        }
        out.push_str(if n + 1 < MissionType::ALL.len() { "],\n" } else { "]\n" });
    }
    out.push_str("}\n");
    out
}

impl Json<'_> {
    /// An f32 as [`exact_json::f32_from`] reads it (a plain number is rounded to f32).
    fn stored_f32(&self, v: &serde_json::Value, path: &str) -> Result<f32, MissionFileError> {
        exact_json::f32_from(v).map_err(|e| self.float_error(e, v, path, "a 32-bit NaN or infinity"))
    }

    /// An f64 as [`exact_json::f64_from`] reads it.
    fn stored_f64(&self, v: &serde_json::Value, path: &str) -> Result<f64, MissionFileError> {
        exact_json::f64_from(v).map_err(|e| self.float_error(e, v, path, "a NaN or infinity"))
    }

    /// Why `v` at `path` is no float; `special` names the strings it may be.
    fn float_error(&self, e: FloatError, v: &serde_json::Value, path: &str, special: &str) -> MissionFileError {
        let why = match e {
            FloatError::TooLarge(d) => format!("{} does not fit a 32-bit float", super::num(d)),
            FloatError::NotSpecial => format!("{} is not {special}", show(v)),
            FloatError::NotAFloat => format!(
                "expected a number, \"nan\", \"nan:0x…\", \"inf\", \"-inf\" or null (NaN), found {}",
                show(v)
            ),
        };
        self.invalid(path, why)
    }
}

/// The fields of an item, in file order.
const ITEM_FIELDS: [&str; 7] = ["frame", "command", "autocontinue", "params", "x", "y", "z"];

/// Read the file text (module doc); `file` labels errors.
///
/// # Errors
/// Not JSON, not this format or version, a field missing, unknown or of the
/// wrong kind, or a plan the vehicle would refuse: each names the file, the
/// field and the problem.
pub fn plans_from_text(text: &str, file: &str) -> Result<Plans, MissionFileError> {
    let j = Json { file };
    let root = j.parse(text)?;
    let root = j.object(&root, "")?;
    match root.get("format").and_then(serde_json::Value::as_str) {
        Some(STATE_FORMAT) => {}
        _ => {
            return Err(j.invalid(
                "format",
                format!("expected \"{STATE_FORMAT}\": not a rotorpilot plans file"),
            ));
        }
    }
    let version = j.required(root, "", "version")?;
    match j.whole::<i64>(version, "version")? {
        STATE_VERSION => {}
        v => {
            return Err(j.invalid(
                "version",
                format!("version {v} is not read by this rotorpilot (it reads version {STATE_VERSION})"),
            ));
        }
    }
    for key in root.keys() {
        if !matches!(key.as_str(), "format" | "version" | "mission" | "fence" | "rally") {
            return Err(j.invalid(key, "unknown field"));
        }
    }
    let mut plans = Plans::default();
    for kind in MissionType::ALL {
        let name = kind.name();
        let list = j.array(j.required(root, "", name)?, name)?;
        let mut items = Vec::with_capacity(list.len());
        for (i, v) in list.iter().enumerate() {
            let base = format!("{name}[{i}]");
            let item = stored_item(&j, v, &base)?;
            items.push((
                item,
                Origin::Json {
                    base,
                    shape: Shape::Stored,
                },
            ));
        }
        let whole_list = Origin::Json {
            base: name.to_string(),
            shape: Shape::Stored,
        };
        let items = check_plan(file, kind, items, &whole_list)?;
        match Plan::new(kind, items) {
            Ok(plan) => plans.set(kind, plan),
            // check_plan ran the same checks; kept for the types
            Err((i, r)) => return Err(j.invalid(&format!("{name}[{i}]"), r.reason())),
        }
    }
    Ok(plans)
}

/// One item of the file.
fn stored_item(j: &Json<'_>, v: &serde_json::Value, base: &str) -> Result<MissionItem, MissionFileError> {
    let obj = j.object(v, base)?;
    for key in obj.keys() {
        if !ITEM_FIELDS.contains(&key.as_str()) {
            return Err(j.invalid(&join(base, key), "unknown field"));
        }
    }
    let field = |k: &str| j.required(obj, base, k);
    let params_path = join(base, "params");
    let params = j.array(field("params")?, &params_path)?;
    if params.len() != 4 {
        return Err(j.invalid(
            &params_path,
            format!("expected 4 params (p1 to p4), found {}", params.len()),
        ));
    }
    let mut p = [0.0_f32; 4];
    for (k, v) in params.iter().enumerate() {
        p[k] = j.stored_f32(v, &format!("{params_path}[{k}]"))?;
    }
    let autocontinue = match field("autocontinue")? {
        serde_json::Value::Bool(b) => *b,
        other => {
            return Err(j.invalid(
                &join(base, "autocontinue"),
                format!("expected true or false, found {}", show(other)),
            ));
        }
    };
    Ok(MissionItem {
        frame: j.whole(field("frame")?, &join(base, "frame"))?,
        command: j.whole(field("command")?, &join(base, "command"))?,
        autocontinue,
        params: p,
        x: j.stored_f64(field("x")?, &join(base, "x"))?,
        y: j.stored_f64(field("y")?, &join(base, "y"))?,
        z: j.stored_f32(field("z")?, &join(base, "z"))?,
    })
}

/// Write `plans` to `path` atomically (temporary file, fsync, rename).
///
/// # Errors
/// The file cannot be written; the old one is then untouched.
pub fn save_plans(path: &Path, plans: &Plans) -> Result<(), MissionFileError> {
    use std::io::Write as _;
    statefile::write_atomic(path, plans_to_text(plans).as_bytes(), |f, b| f.write_all(b)).map_err(|e| {
        MissionFileError::Write {
            file: path.display().to_string(),
            message: e.to_string(),
        }
    })
}

/// Read the plans kept at `path`; no file yet means no plans.
///
/// # Errors
/// The file exists but cannot be read, or is not a valid plans file
/// ([`plans_from_text`]).
pub fn load_plans(path: &Path) -> Result<Plans, MissionFileError> {
    let file = path.display().to_string();
    let bytes = match std::fs::read(path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Plans::default()),
        Err(e) => {
            return Err(MissionFileError::Read {
                file,
                message: e.to_string(),
            });
        }
    };
    plans_from_text(utf8(&bytes, &file)?, &file)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mission::{MAX_ITEMS, MissionResult, cmd};
    use crate::statefile::scratch_dir as scratch;

    fn wp(x: f64, y: f64, z: f32) -> MissionItem {
        MissionItem {
            frame: 3,
            command: cmd::NAV_WAYPOINT,
            autocontinue: true,
            params: [0.0, 1.0, 0.0, f32::NAN],
            x,
            y,
            z,
        }
    }

    fn plans(mission: Vec<MissionItem>, fence: Vec<MissionItem>, rally: Vec<MissionItem>) -> Plans {
        let mut p = Plans::default();
        p.set(MissionType::Mission, Plan::new(MissionType::Mission, mission).unwrap());
        p.set(MissionType::Fence, Plan::new(MissionType::Fence, fence).unwrap());
        p.set(MissionType::Rally, Plan::new(MissionType::Rally, rally).unwrap());
        p
    }

    /// Bit-for-bit equality of every field (NaN included).
    fn same_bits(a: &Plans, b: &Plans) {
        for kind in MissionType::ALL {
            let (x, y) = (a.get(kind), b.get(kind));
            assert_eq!(x.id(), y.id(), "{kind:?} id");
            assert_eq!(x.len(), y.len(), "{kind:?} length");
            for (i, (p, q)) in x.items().iter().zip(y.items()).enumerate() {
                let bits = |it: &MissionItem| {
                    (
                        it.frame,
                        it.command,
                        it.autocontinue,
                        it.params.map(f32::to_bits),
                        it.x.to_bits(),
                        it.y.to_bits(),
                        it.z.to_bits(),
                    )
                };
                assert_eq!(bits(p), bits(q), "{kind:?}[{i}]");
            }
        }
    }

    fn round_trip(p: &Plans) -> Plans {
        plans_from_text(&plans_to_text(p), "m.json").unwrap()
    }

    fn sample() -> Plans {
        let takeoff = MissionItem {
            command: cmd::NAV_TAKEOFF,
            params: [f32::NAN; 4],
            ..wp(47.397_742, 8.545_594, 10.0)
        };
        let speed = MissionItem {
            frame: 2,
            command: cmd::DO_CHANGE_SPEED,
            autocontinue: true,
            params: [1.0, 10.0, -1.0, 0.0],
            x: 0.0,
            y: 0.0,
            z: f32::NAN,
        };
        let vertex = |x: f64, y: f64| MissionItem {
            frame: 0,
            command: cmd::FENCE_POLYGON_VERTEX_INCLUSION,
            autocontinue: false,
            params: [3.0, 0.0, 0.0, 0.0],
            x,
            y,
            z: 0.0,
        };
        let rally = MissionItem {
            frame: 3,
            command: cmd::RALLY_POINT,
            autocontinue: false,
            params: [0.0; 4],
            x: 47.398,
            y: 8.545,
            z: 15.0,
        };
        plans(
            vec![takeoff, speed, wp(47.398_226_6, 8.545_560_4, 50.0)],
            vec![vertex(47.1, 8.1), vertex(47.2, 8.1), vertex(47.2, 8.2)],
            vec![rally],
        )
    }

    #[test]
    fn the_file_reads_back_bit_for_bit_with_the_same_ids() {
        let p = sample();
        let text = plans_to_text(&p);
        assert!(text.starts_with("{\n  \"format\": \"rotorpilot-plans\",\n  \"version\": 1,\n  \"mission\": [\n    {\"frame\": 3, \"command\": 22, \"autocontinue\": true, \"params\": [\"nan\", \"nan\", \"nan\", \"nan\"], \"x\": 47.397742, \"y\": 8.545594, \"z\": 10.0},\n"), "{text}");
        assert!(
            text.contains("\"rally\": [\n    {\"frame\": 3, \"command\": 5100"),
            "{text}"
        );
        serde_json::from_str::<serde_json::Value>(&text).expect("valid JSON");
        same_bits(&round_trip(&p), &p);
        // empty plans: empty lists
        let e = plans_to_text(&Plans::default());
        assert_eq!(
            e,
            "{\n  \"format\": \"rotorpilot-plans\",\n  \"version\": 1,\n  \"mission\": [],\n  \"fence\": [],\n  \"rally\": []\n}\n"
        );
        same_bits(&round_trip(&Plans::default()), &Plans::default());
    }

    #[test]
    fn extreme_values_nan_payloads_and_infinities_round_trip() {
        let mut items = Vec::new();
        let specials32 = [
            0.0,
            -0.0,
            f32::MIN_POSITIVE,
            f32::from_bits(1),
            -f32::from_bits(0x007f_ffff),
            f32::MAX,
            f32::MIN,
            f32::EPSILON,
            0.1,
            16_777_217.0,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            -f32::NAN,
            f32::from_bits(0x7fc0_0001),
            f32::from_bits(0x7f80_0001),
        ];
        let specials64 = [
            0.0,
            -0.0,
            1e-300,
            f64::from_bits(1),
            f64::MAX,
            f64::MIN,
            0.1,
            f64::from(0.1_f32),
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            -f64::NAN,
            f64::from_bits(0x7ff0_0000_0000_0001),
            f64::from(f32::from_bits(0xffc0_0123)),
        ];
        // DO_SET_SERVO stores any params and x/y in frame 2: every value a wire can carry
        for (k, &a) in specials32.iter().enumerate() {
            items.push(MissionItem {
                frame: 2,
                command: cmd::DO_SET_SERVO,
                autocontinue: k % 2 == 0,
                params: [a, -a, specials32[(k + 3) % specials32.len()], a],
                x: specials64[k % specials64.len()],
                y: specials64[(k + 5) % specials64.len()],
                z: a,
            });
        }
        let p = plans(items, vec![], vec![]);
        same_bits(&round_trip(&p), &p);
        let text = plans_to_text(&p);
        assert!(text.contains("\"nan:0x7fc00001\"") && text.contains("\"-inf\"") && text.contains("\"nan\""));
    }

    #[test]
    fn random_bit_patterns_round_trip() {
        // xorshift: every f32 and f64 bit pattern is fair game for a MISSION_ITEM
        let mut s: u64 = 0x9e37_79b9_7f4a_7c15;
        let mut next = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            s
        };
        let items: Vec<MissionItem> = (0..4000)
            .map(|_| {
                let r = next();
                MissionItem {
                    frame: 2,
                    command: cmd::DO_SET_SERVO,
                    autocontinue: r & 1 == 1,
                    params: [
                        f32::from_bits(r as u32),
                        f32::from_bits((r >> 32) as u32),
                        f32::from_bits(next() as u32),
                        // f32 values of a coordinate's size, whose shortest form is long
                        (47.0 + (next() % 1_000_000) as f32 * 1e-6),
                    ],
                    x: f64::from_bits(next()),
                    y: 47.0 + (next() % 10_000_000_000) as f64 * 1e-12,
                    z: f32::from_bits(next() as u32),
                }
            })
            .collect();
        let p = plans(items, vec![], vec![]);
        same_bits(&round_trip(&p), &p);
    }

    #[test]
    fn twenty_thousand_items_save_and_load() {
        let dir = scratch("big");
        let path = dir.join("missions.json");
        let items: Vec<MissionItem> = (0..MAX_ITEMS)
            .map(|i| wp(47.0 + i as f64 * 1e-7, 8.0 - i as f64 * 1e-7, i as f32 * 0.1))
            .collect();
        let p = plans(
            items.clone(),
            vec![],
            items
                .iter()
                .map(|it| MissionItem {
                    command: cmd::RALLY_POINT,
                    ..*it
                })
                .collect(),
        );
        save_plans(&path, &p).unwrap();
        let back = load_plans(&path).unwrap();
        same_bits(&back, &p);
        assert_eq!(back.get(MissionType::Mission).len(), MAX_ITEMS);
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1, "no temporary file left");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_missing_file_is_no_plans_and_saving_replaces_the_old_file() {
        let dir = scratch("missing");
        let path = dir.join("missions.json");
        assert_eq!(load_plans(&path).unwrap(), Plans::default());
        save_plans(&path, &sample()).unwrap();
        save_plans(&path, &Plans::default()).unwrap();
        same_bits(&load_plans(&path).unwrap(), &Plans::default());
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt as _;
            let mode = std::fs::metadata(&path).unwrap().permissions().mode();
            assert_eq!(mode & 0o600, 0o600, "owner reads and writes: {mode:o}");
        }
        // a directory in the way: errors name the file
        let blocked = dir.join("blocked.json");
        std::fs::create_dir_all(blocked.join("x")).unwrap();
        let e = save_plans(&blocked, &sample()).unwrap_err().to_string();
        assert!(e.contains("blocked.json: cannot write:"), "{e}");
        let e = load_plans(&blocked).unwrap_err().to_string();
        assert!(e.contains("blocked.json: cannot read:"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_corrupt_file_is_an_error_naming_the_file_and_the_field() {
        let good = plans_to_text(&sample());
        let line = |n: usize| good.lines().nth(n).unwrap().to_string();
        let takeoff = line(4);
        let whole = [
            (String::new(), "m.json:1:0: EOF while parsing a value"),
            (good[..good.len() / 2].to_string(), "m.json:"),
            ("[]".into(), "m.json: (top level): expected an object, found an array"),
            ("{}".into(), "m.json: format: expected \"rotorpilot-plans\""),
            (
                good.replace(&format!("{takeoff}\n"), "")
                    .replace("  \"fence\": [", "  \"fencing\": ["),
                "m.json: fencing: unknown field",
            ),
        ];
        // the good file with one text replaced by another
        let edited = [
            ("rotorpilot-plans", "qgc-plan", "m.json: format:"),
            (
                "\"version\": 1",
                "\"version\": 2",
                "m.json: version: version 2 is not read by this rotorpilot",
            ),
            (
                "\"version\": 1",
                "\"version\": \"1\"",
                "m.json: version: expected a whole number",
            ),
            (
                "  \"rally\": [",
                "  \"extra\": 1,\n  \"rally\": [",
                "m.json: extra: unknown field",
            ),
            (
                "\"autocontinue\": true, \"params\": [\"nan\"",
                "\"autocontinue\": 1, \"params\": [\"nan\"",
                "m.json: mission[0].autocontinue: expected true or false, found 1",
            ),
            (
                "\"params\": [\"nan\", \"nan\", \"nan\", \"nan\"]",
                "\"params\": [\"nan\", \"nan\", \"nan\"]",
                "m.json: mission[0].params: expected 4 params",
            ),
            (
                "\"params\": [\"nan\", \"nan\", \"nan\", \"nan\"]",
                "\"params\": [\"nan\", \"x\", \"nan\", \"nan\"]",
                "m.json: mission[0].params[1]: \"x\" is not a 32-bit NaN or infinity",
            ),
            (
                "\"params\": [\"nan\", \"nan\", \"nan\", \"nan\"]",
                "\"params\": [\"nan\", 1e39, \"nan\", \"nan\"]",
                "m.json: mission[0].params[1]: 1e39 does not fit a 32-bit float",
            ),
            (
                "\"params\": [\"nan\", \"nan\", \"nan\", \"nan\"]",
                "\"params\": [\"nan\", \"nan:0x3f800000\", \"nan\", \"nan\"]",
                "mission[0].params[1]: \"nan:0x3f800000\" is not a 32-bit NaN",
            ),
            (
                "\"params\": [\"nan\", \"nan\", \"nan\", \"nan\"]",
                "\"params\": [\"nan\", [], \"nan\", \"nan\"]",
                "mission[0].params[1]: expected a number, \"nan\"",
            ),
            (
                "\"x\": 47.397742",
                "\"x\": \"far\"",
                "m.json: mission[0].x: \"far\" is not a NaN or infinity",
            ),
            (
                "\"x\": 47.397742",
                "\"lat\": 47.397742",
                "m.json: mission[0].lat: unknown field",
            ),
            (
                "\"frame\": 3, \"command\": 22",
                "\"command\": 22",
                "m.json: mission[0].frame: missing",
            ),
            (
                "\"frame\": 3, \"command\": 22",
                "\"frame\": 3, \"command\": -22",
                "m.json: mission[0].command: expected a whole number that fits u16, found -22",
            ),
            (
                "\"x\": 47.397742",
                "\"x\": 97.397742",
                "m.json: mission[0].x: latitude 97.397742 is not within ±90° (MAV_MISSION_INVALID_PARAM5_X)",
            ),
            (
                "\"z\": 10.0",
                "\"z\": null",
                "m.json: mission[0].z: altitude NaN is not a number",
            ),
            (
                "\"command\": 5001",
                "\"command\": 5009",
                "m.json: fence[0].command: command 5009 is not a fence item",
            ),
            (
                "\"params\": [3.0, 0.0, 0.0, 0.0]",
                "\"params\": [2.0, 0.0, 0.0, 0.0]",
                "m.json: fence[0].params[0]: param1 = 2 is refused",
            ),
            ("\"command\": 22", "\"command\": 22, \"frame\": 2", "m.json:"),
        ]
        .map(|(from, to, want)| {
            assert!(good.contains(from), "{from}");
            (good.replace(from, to), want)
        });
        for (text, want) in whole.into_iter().chain(edited) {
            let e = plans_from_text(&text, "m.json").unwrap_err().to_string();
            assert!(e.contains(want), "want `{want}` in\n{e}");
        }
        // via the file: the path is named; non-UTF-8 too
        let dir = scratch("corrupt");
        let path = dir.join("missions.json");
        std::fs::write(&path, good.replace("\"z\": 10.0", "\"z\": true")).unwrap();
        let e = load_plans(&path).unwrap_err().to_string();
        assert!(e.contains("missions.json: mission[0].z: expected a number"), "{e}");
        std::fs::write(&path, b"{\xff}").unwrap();
        let e = load_plans(&path).unwrap_err().to_string();
        assert!(e.contains("missions.json: not UTF-8 text"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn more_items_than_the_vehicle_stores_is_refused() {
        let one = item_json(&wp(47.0, 8.0, 10.0));
        let text = format!(
            "{{\"format\": \"rotorpilot-plans\", \"version\": 1, \"mission\": [{}], \"fence\": [], \"rally\": []}}",
            vec![one.as_str(); MAX_ITEMS + 1].join(",")
        );
        let e = plans_from_text(&text, "m.json").unwrap_err().to_string();
        assert!(e.contains("m.json: mission: more than 20000 items"), "{e}");
        assert_eq!(MissionResult::NoSpace.to_mav(), 4);
    }

    #[test]
    fn a_hand_written_number_is_rounded_as_a_wire_would() {
        let text = "{\"format\": \"rotorpilot-plans\", \"version\": 1, \"fence\": [], \"rally\": [], \"mission\": [\
                    {\"frame\": 3, \"command\": 16, \"autocontinue\": true, \"params\": [0, 0.1, null, \"nan\"], \"x\": 47.4, \"y\": 8.5, \"z\": 12}]}";
        let p = plans_from_text(text, "hand.json").unwrap();
        let it = p.get(MissionType::Mission).items()[0];
        assert_eq!((it.params[1], it.z, it.x), (0.1_f32, 12.0, 47.4));
        assert!(it.params[3].is_nan());
        // `null`: the quiet NaN, as files written before the exact-float codec spelled it
        assert_eq!(it.params[2].to_bits(), f32::NAN.to_bits());
    }
}
