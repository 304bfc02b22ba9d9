//! Mission files: QGroundControl `.plan` (JSON), QGC WPL 110 text, and the
//! state-dir file `missions.json` in which the vehicle keeps its plans.
//!
//! | reads | function | gives |
//! |---|---|---|
//! | a `.plan`, `.txt`, `.waypoints` or `.mission` file, by extension | [`load_mission_file`] | [`PlanFile`] |
//! | `.plan` text | [`parse_qgc_plan`] | mission, geofence and rally points as MAVSDK's `import_qgroundcontrol_mission` builds them |
//! | QGC WPL 110 text | [`parse_wpl`] | the items as MAVProxy's `wp load` sends them, seq 0 included |
//! | `missions.json` | [`load_plans`] / [`save_plans`] ([`plans_from_text`] / [`plans_to_text`]) | [`Plans`], every number bit for bit |
//!
//! A `.plan` (QGroundControl 4, read as MAVSDK 4 reads it):
//!
//! ```json
//! {"fileType": "Plan", "version": 1,
//!  "mission": {"version": 2, "items": [
//!      {"type": "SimpleItem", "command": 22, "frame": 3, "autoContinue": true,
//!       "params": [0, 0, 0, null, 47.397742, 8.5455939, 10]}]},
//!  "geoFence": {"version": 2, "circles": [], "polygons": [
//!      {"inclusion": true, "polygon": [[47.3982, 8.5451], [47.3982, 8.5461], [47.3973, 8.5456]], "version": 1}]},
//!  "rallyPoints": {"version": 2, "points": [[47.3980, 8.5450, 15]]}}
//! ```
//!
//! A QGC WPL 110 file (MAVProxy `wp save` separates with tabs; spaces do too; `#` comments):
//!
//! ```text
//! QGC WPL 110
//! 0 1 0 16 0 0 0 0 47.397742 8.545594 488.0 1
//! 1 0 3 22 0 0 0 0 47.397742 8.545594 10.0 1
//! 2 0 3 16 0 0 0 0 47.398100 8.545594 10.0 1
//! ```
//!
//! Global-frame latitudes and longitudes are quantised to MISSION_ITEM_INT's
//! degE7 (`round(v * 1e7) / 1e7`), since both clients upload integers: a
//! headless flight of a file is then bit-identical to the same file uploaded.
//! Every item is checked with [`super::validate`], as the vehicle would check
//! it; a problem is an error naming the file, where in it (the JSON path, or
//! the line and field) and what is wrong:
//!
//! ```text
//! survey.plan: mission.items[3].params[4]: latitude 123.4 is not within ±90° (MAV_MISSION_INVALID_PARAM5_X)
//! home.txt:4: field 9 (x / latitude): `47.3.9` is not a number
//! ```
//!
//! Nothing here panics on any input. Pure: file reads and the atomic write
//! of [`crate::statefile`], no runtime, no protocol, no clock.

mod qgc;
mod state;
mod wpl;

use std::path::Path;

pub use qgc::parse_qgc_plan;
pub use state::{STATE_FORMAT, STATE_VERSION, load_plans, plans_from_text, plans_to_text, save_plans};
pub use wpl::parse_wpl;

use super::{MAX_ITEMS, MissionItem, MissionResult, MissionType, Plan, Plans, cmd, frame};

/// The plans a mission file holds, each item checked, in upload order (a
/// WPL file holds one of the three).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PlanFile {
    /// The mission (MAV_MISSION_TYPE 0).
    pub mission: Vec<MissionItem>,
    /// Geofence polygon vertices and circles (type 1).
    pub fence: Vec<MissionItem>,
    /// Rally points (type 2).
    pub rally: Vec<MissionItem>,
}

impl PlanFile {
    /// The items of `kind`.
    #[must_use]
    pub fn items(&self, kind: MissionType) -> &[MissionItem] {
        match kind {
            MissionType::Mission => &self.mission,
            MissionType::Fence => &self.fence,
            MissionType::Rally => &self.rally,
        }
    }

    /// The three as stored plans (with their ids).
    ///
    /// # Errors
    /// Never for a file this module read (every item was checked); for a
    /// `PlanFile` built by hand, the plan type, item index and result of the
    /// first item refused.
    pub fn into_plans(self) -> Result<Plans, (MissionType, usize, MissionResult)> {
        let mut plans = Plans::default();
        for (kind, items) in [
            (MissionType::Mission, self.mission),
            (MissionType::Fence, self.fence),
            (MissionType::Rally, self.rally),
        ] {
            plans.set(kind, Plan::new(kind, items).map_err(|(i, r)| (kind, i, r))?);
        }
        Ok(plans)
    }
}

/// Why a mission file or the stored plans could not be read or written.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum MissionFileError {
    /// The file could not be read.
    #[error("{file}: cannot read: {message}")]
    Read {
        /// Path as given.
        file: String,
        /// OS message.
        message: String,
    },
    /// The file could not be written (the old one is untouched).
    #[error("{file}: cannot write: {message}")]
    Write {
        /// Path as given.
        file: String,
        /// OS message, naming the temporary file if that is where it failed.
        message: String,
    },
    /// Not well-formed JSON.
    #[error("{file}:{line}:{column}: {message}")]
    Syntax {
        /// Path or label.
        file: String,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// The parser's message.
        message: String,
    },
    /// A line of a WPL file: its header, its fields, or the item it makes.
    #[error("{file}:{line}: {field}: {problem}")]
    Line {
        /// Path or label.
        file: String,
        /// 1-based line.
        line: usize,
        /// `header`, `line`, or `field N (name)`.
        field: String,
        /// What is wrong.
        problem: String,
    },
    /// A JSON field: missing, of the wrong type, unsupported, or an item the
    /// vehicle would refuse.
    #[error("{file}: {field}: {problem}")]
    Invalid {
        /// Path or label.
        file: String,
        /// JSON path, e.g. `mission.items[3].params[4]`.
        field: String,
        /// What is wrong.
        problem: String,
    },
    /// Not a mission file this module reads (extension, encoding).
    #[error("{file}: {problem}")]
    Format {
        /// Path or label.
        file: String,
        /// What is wrong.
        problem: String,
    },
}

/// Read a mission file by its extension: `.plan` is QGroundControl JSON
/// ([`parse_qgc_plan`]); `.txt`, `.waypoints` and `.mission` are QGC WPL 110
/// ([`parse_wpl`]); any other extension is recognised by its first bytes.
///
/// # Errors
/// The file cannot be read, is not UTF-8, is neither format, or holds an
/// item the vehicle would refuse ([`MissionFileError`] names where).
pub fn load_mission_file(path: &Path) -> Result<PlanFile, MissionFileError> {
    let file = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|e| MissionFileError::Read {
        file: file.clone(),
        message: e.to_string(),
    })?;
    let text = utf8(&bytes, &file)?;
    let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase());
    match ext.as_deref() {
        Some("plan") => parse_qgc_plan(text, &file),
        Some("txt" | "waypoints" | "mission") => parse_wpl(text, &file),
        _ if text.trim_start().starts_with('{') => parse_qgc_plan(text, &file),
        _ if text.trim_start().starts_with("QGC WPL") => parse_wpl(text, &file),
        _ => Err(MissionFileError::Format {
            file,
            problem: format!(
                "not a mission file: expected a QGroundControl .plan (JSON) or a QGC WPL 110 \
                 .txt/.waypoints/.mission file, found extension {}",
                ext.map_or_else(|| "(none)".to_string(), |e| format!("`.{e}`"))
            ),
        }),
    }
}

/// The text of a file (a leading byte-order mark dropped).
fn utf8<'a>(bytes: &'a [u8], file: &str) -> Result<&'a str, MissionFileError> {
    let text = std::str::from_utf8(bytes).map_err(|e| MissionFileError::Format {
        file: file.to_string(),
        problem: format!("not UTF-8 text (byte {} is not)", e.valid_up_to()),
    })?;
    Ok(text.strip_prefix('\u{feff}').unwrap_or(text))
}

// ----- where an item came from, and what is wrong with it ----------------------------------------

/// Where an item came from in its file, to name the field a problem is in.
#[derive(Clone, Debug)]
enum Origin {
    /// A JSON object or array at `base`, laid out as `shape`.
    Json { base: String, shape: Shape },
    /// A WPL line (1-based).
    Line(usize),
}

/// How an item's fields sit in its JSON.
#[derive(Clone, Copy, Debug)]
enum Shape {
    /// A QGC SimpleItem: `frame`, `command`, `params[0..7]`.
    Simple,
    /// An item of `missions.json`: `frame`, `command`, `params[0..4]`, `x`, `y`, `z`.
    Stored,
    /// Vertex `vertex` of a QGC fence polygon at `base` (`polygon[vertex][0..2]`).
    Vertex { vertex: usize },
    /// A QGC fence circle (`circle.center[0..2]`, `circle.radius`).
    Circle,
    /// A QGC rally point (`[lat, lon, alt]`).
    Rally,
}

/// The WPL fields, in file order.
const WPL_FIELDS: [&str; 12] = [
    "seq",
    "current",
    "frame",
    "command",
    "param1",
    "param2",
    "param3",
    "param4",
    "x / latitude",
    "y / longitude",
    "z / altitude",
    "autocontinue",
];

/// `field N (name)` for WPL field index `i` (0-based).
fn wpl_field(i: usize) -> String {
    format!("field {} ({})", i + 1, WPL_FIELDS.get(i).copied().unwrap_or("?"))
}

/// `path.key`, or `key` at the top level.
fn join(path: &str, key: &str) -> String {
    if path.is_empty() {
        key.to_string()
    } else {
        format!("{path}.{key}")
    }
}

impl Origin {
    /// The error for `item` refused with `r` in a plan of `kind`.
    fn error(&self, file: &str, kind: MissionType, item: &MissionItem, r: MissionResult) -> MissionFileError {
        use MissionResult as R;
        let problem = describe(kind, item, r);
        match self {
            Origin::Line(line) => {
                let field = match r {
                    R::UnsupportedFrame => wpl_field(2),
                    R::Unsupported => wpl_field(3),
                    R::InvalidParam1 => wpl_field(4),
                    R::InvalidParam2 => wpl_field(5),
                    R::InvalidParam3 => wpl_field(6),
                    R::InvalidParam4 => wpl_field(7),
                    R::InvalidParam5X => wpl_field(8),
                    R::InvalidParam6Y => wpl_field(9),
                    R::InvalidParam7 => wpl_field(10),
                    _ => "item".to_string(),
                };
                MissionFileError::Line {
                    file: file.to_string(),
                    line: *line,
                    field,
                    problem,
                }
            }
            Origin::Json { base, shape } => {
                let param = |k: usize| format!("{base}.params[{k}]");
                let field = match (shape, r) {
                    (Shape::Simple | Shape::Stored, R::UnsupportedFrame) => join(base, "frame"),
                    (Shape::Simple | Shape::Stored, R::Unsupported) => join(base, "command"),
                    (Shape::Simple | Shape::Stored, R::InvalidParam1) => param(0),
                    (Shape::Simple | Shape::Stored, R::InvalidParam2) => param(1),
                    (Shape::Simple | Shape::Stored, R::InvalidParam3) => param(2),
                    (Shape::Simple | Shape::Stored, R::InvalidParam4) => param(3),
                    (Shape::Simple, R::InvalidParam5X) => param(4),
                    (Shape::Simple, R::InvalidParam6Y) => param(5),
                    (Shape::Simple, R::InvalidParam7) => param(6),
                    (Shape::Stored, R::InvalidParam5X) => join(base, "x"),
                    (Shape::Stored, R::InvalidParam6Y) => join(base, "y"),
                    (Shape::Stored, R::InvalidParam7) => join(base, "z"),
                    (Shape::Vertex { .. }, R::InvalidParam1) => join(base, "polygon"),
                    (Shape::Vertex { vertex }, R::InvalidParam5X) => format!("{base}.polygon[{vertex}][0]"),
                    (Shape::Vertex { vertex }, R::InvalidParam6Y) => format!("{base}.polygon[{vertex}][1]"),
                    (Shape::Vertex { vertex }, _) => format!("{base}.polygon[{vertex}]"),
                    (Shape::Circle, R::InvalidParam1) => format!("{base}.circle.radius"),
                    (Shape::Circle, R::InvalidParam5X) => format!("{base}.circle.center[0]"),
                    (Shape::Circle, R::InvalidParam6Y) => format!("{base}.circle.center[1]"),
                    (Shape::Rally, R::InvalidParam5X) => format!("{base}[0]"),
                    (Shape::Rally, R::InvalidParam6Y) => format!("{base}[1]"),
                    (Shape::Rally, R::InvalidParam7) => format!("{base}[2]"),
                    _ => base.clone(),
                };
                MissionFileError::Invalid {
                    file: file.to_string(),
                    field,
                    problem,
                }
            }
        }
    }
}

/// MAV_MISSION_RESULT's name.
fn mav_name(r: MissionResult) -> &'static str {
    use MissionResult as R;
    match r {
        R::Accepted => "MAV_MISSION_ACCEPTED",
        R::Error => "MAV_MISSION_ERROR",
        R::UnsupportedFrame => "MAV_MISSION_UNSUPPORTED_FRAME",
        R::Unsupported => "MAV_MISSION_UNSUPPORTED",
        R::NoSpace => "MAV_MISSION_NO_SPACE",
        R::Invalid => "MAV_MISSION_INVALID",
        R::InvalidParam1 => "MAV_MISSION_INVALID_PARAM1",
        R::InvalidParam2 => "MAV_MISSION_INVALID_PARAM2",
        R::InvalidParam3 => "MAV_MISSION_INVALID_PARAM3",
        R::InvalidParam4 => "MAV_MISSION_INVALID_PARAM4",
        R::InvalidParam5X => "MAV_MISSION_INVALID_PARAM5_X",
        R::InvalidParam6Y => "MAV_MISSION_INVALID_PARAM6_Y",
        R::InvalidParam7 => "MAV_MISSION_INVALID_PARAM7",
        R::InvalidSequence => "MAV_MISSION_INVALID_SEQUENCE",
        R::Denied => "MAV_MISSION_DENIED",
        R::OperationCancelled => "MAV_MISSION_OPERATION_CANCELLED",
    }
}

/// A number for a message: plain in everyday magnitudes, else with an exponent.
fn num(v: f64) -> String {
    if v == 0.0 || !v.is_finite() || (1e-5..1e15).contains(&v.abs()) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

/// An f32 for a message (its own shortest digits, not its double's).
fn num32(v: f32) -> String {
    if v == 0.0 || !v.is_finite() || (1e-5..1e15).contains(&v.abs()) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

/// What is wrong with `item`, refused with `r` in a plan of `kind`, in
/// words, with the answer the vehicle would give.
fn describe(kind: MissionType, item: &MissionItem, r: MissionResult) -> String {
    use MissionResult as R;
    let c = item.command;
    let what = match r {
        R::UnsupportedFrame if frame::is_supported(item.frame) => format!(
            "command {c} needs a position, and frame {} (MAV_FRAME_MISSION) has none: use 0, 3, 5, 6, 10 or 11",
            item.frame
        ),
        R::UnsupportedFrame => format!("frame {} is not supported (0, 2, 3, 5, 6, 10 and 11 are)", item.frame),
        R::Unsupported => match kind {
            MissionType::Mission => format!("command {c} is not a mission command the vehicle stores"),
            MissionType::Fence => format!("command {c} is not a fence item (5000 to 5004 are)"),
            MissionType::Rally => format!("command {c} is not a rally point (5100 is)"),
        },
        R::InvalidParam5X => format!("latitude {} is not within ±90°", num(item.x)),
        R::InvalidParam6Y => format!("longitude {} is not within ±180°", num(item.y)),
        R::InvalidParam7 => format!("altitude {} is not a number", num32(item.z)),
        R::InvalidParam1 | R::InvalidParam2 | R::InvalidParam3 | R::InvalidParam4 => {
            let k = match r {
                R::InvalidParam1 => 0,
                R::InvalidParam2 => 1,
                R::InvalidParam3 => 2,
                _ => 3,
            };
            let v = num32(item.params[k]);
            let needs = match (c, k) {
                (cmd::NAV_WAYPOINT, 0) => "a hold time ≥ 0 s",
                (cmd::NAV_WAYPOINT, 1) => "an acceptance radius ≥ 0 m",
                (cmd::NAV_LOITER_TIME | cmd::NAV_DELAY, 0) => "a time ≥ 0 s",
                (cmd::NAV_LOITER_TURNS, 0) => "a number of turns ≥ 0",
                (cmd::DO_JUMP, 0) => "a whole item number ≥ 0",
                (cmd::DO_JUMP, 1) => "a whole repeat count, -1 for ever",
                (cmd::DO_CHANGE_SPEED, 1) => "a speed (-1 keeps it)",
                (cmd::FENCE_POLYGON_VERTEX_INCLUSION | cmd::FENCE_POLYGON_VERTEX_EXCLUSION, 0) => {
                    "a vertex count of 3 or more (a polygon has at least 3 vertices)"
                }
                (cmd::FENCE_CIRCLE_INCLUSION | cmd::FENCE_CIRCLE_EXCLUSION, 0) => "a radius ≥ 0 m",
                _ => "another value",
            };
            format!("param{} = {v} is refused: command {c} needs {needs}", k + 1)
        }
        R::NoSpace => format!("more than {MAX_ITEMS} items, the most a plan holds"),
        other => other.reason().to_string(),
    };
    format!("{what} ({})", mav_name(r))
}

/// Check `items` as a plan of `kind` (count, then each item as the vehicle
/// would), naming the first problem where it sits in `file`.
fn check_plan(
    file: &str,
    kind: MissionType,
    items: Vec<(MissionItem, Origin)>,
    list: &Origin,
) -> Result<Vec<MissionItem>, MissionFileError> {
    if items.len() > MAX_ITEMS {
        let at = match &items[MAX_ITEMS].1 {
            Origin::Line(l) => Origin::Line(*l),
            Origin::Json { .. } => list.clone(),
        };
        let item = items[MAX_ITEMS].0;
        return Err(at.error(file, kind, &item, MissionResult::NoSpace));
    }
    for (item, origin) in &items {
        if let Err(r) = super::validate(kind, item) {
            return Err(origin.error(file, kind, item, r));
        }
    }
    Ok(items.into_iter().map(|(it, _)| it).collect())
}

// ----- JSON access with paths ---------------------------------------------------------------------

/// JSON reading that names the file and the path of every problem.
struct Json<'a> {
    file: &'a str,
}

/// A JSON value's type, for messages.
fn type_name(v: &serde_json::Value) -> &'static str {
    use serde_json::Value as V;
    match v {
        V::Null => "null",
        V::Bool(_) => "a boolean",
        V::Number(_) => "a number",
        V::String(_) => "a string",
        V::Array(_) => "an array",
        V::Object(_) => "an object",
    }
}

/// A short rendering of a JSON value for messages.
fn show(v: &serde_json::Value) -> String {
    let s = v.to_string();
    if s.chars().count() > 40 {
        format!("{}…", s.chars().take(40).collect::<String>())
    } else {
        s
    }
}

type Map = serde_json::Map<String, serde_json::Value>;

impl Json<'_> {
    fn invalid(&self, path: &str, problem: impl Into<String>) -> MissionFileError {
        MissionFileError::Invalid {
            file: self.file.to_string(),
            field: if path.is_empty() {
                "(top level)".to_string()
            } else {
                path.to_string()
            },
            problem: problem.into(),
        }
    }

    /// Parse the text (syntax errors carry line and column).
    fn parse(&self, text: &str) -> Result<serde_json::Value, MissionFileError> {
        serde_json::from_str(text).map_err(|e| {
            let full = e.to_string();
            let message = full
                .rsplit_once(" at line ")
                .map_or(full.as_str(), |(m, _)| m)
                .to_string();
            MissionFileError::Syntax {
                file: self.file.to_string(),
                line: e.line(),
                column: e.column(),
                message,
            }
        })
    }

    fn object<'v>(&self, v: &'v serde_json::Value, path: &str) -> Result<&'v Map, MissionFileError> {
        v.as_object()
            .ok_or_else(|| self.invalid(path, format!("expected an object, found {}", type_name(v))))
    }

    fn array<'v>(&self, v: &'v serde_json::Value, path: &str) -> Result<&'v [serde_json::Value], MissionFileError> {
        v.as_array()
            .map(Vec::as_slice)
            .ok_or_else(|| self.invalid(path, format!("expected an array, found {}", type_name(v))))
    }

    /// `obj[key]`, required.
    fn required<'v>(&self, obj: &'v Map, path: &str, key: &str) -> Result<&'v serde_json::Value, MissionFileError> {
        obj.get(key).ok_or_else(|| self.invalid(&join(path, key), "missing"))
    }

    /// A whole number that fits `T` (`16` or `16.0`).
    fn whole<T: TryFrom<i64>>(&self, v: &serde_json::Value, path: &str) -> Result<T, MissionFileError> {
        let bad = || {
            let lo = std::any::type_name::<T>();
            self.invalid(
                path,
                format!("expected a whole number that fits {lo}, found {}", show(v)),
            )
        };
        let i = match v.as_i64() {
            Some(i) => i,
            None => match v.as_f64() {
                Some(f) if f.fract() == 0.0 && f.abs() < 9.0e15 => f as i64,
                _ => return Err(bad()),
            },
        };
        T::try_from(i).map_err(|_| bad())
    }

    /// A number.
    fn number(&self, v: &serde_json::Value, path: &str) -> Result<f64, MissionFileError> {
        v.as_f64()
            .ok_or_else(|| self.invalid(path, format!("expected a number, found {}", show(v))))
    }

    /// A number, or null (`None`).
    fn number_or_null(&self, v: &serde_json::Value, path: &str) -> Result<Option<f64>, MissionFileError> {
        if v.is_null() {
            return Ok(None);
        }
        v.as_f64()
            .map(Some)
            .ok_or_else(|| self.invalid(path, format!("expected a number or null, found {}", show(v))))
    }

    /// `true`/`false`, or 1/0 as QGC's ancestors wrote them.
    fn boolean(&self, v: &serde_json::Value, path: &str) -> Result<bool, MissionFileError> {
        match v {
            serde_json::Value::Bool(b) => Ok(*b),
            serde_json::Value::Number(n) if n.as_f64() == Some(1.0) => Ok(true),
            serde_json::Value::Number(n) if n.as_f64() == Some(0.0) => Ok(false),
            _ => Err(self.invalid(path, format!("expected true or false, found {}", show(v)))),
        }
    }

    /// `obj.version` is `expected`.
    fn version(&self, obj: &Map, path: &str, expected: i64, what: &str) -> Result<(), MissionFileError> {
        let at = join(path, "version");
        let v = obj
            .get("version")
            .ok_or_else(|| self.invalid(&at, format!("missing (a QGC .plan's {what} is version {expected})")))?;
        match self.whole::<i64>(v, &at) {
            Ok(n) if n == expected => Ok(()),
            _ => Err(self.invalid(
                &at,
                format!(
                    "{what} version {} is not supported (version {expected} is, as in MAVSDK)",
                    show(v)
                ),
            )),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fixture under `tests/fixtures/missions/`.
    pub(super) fn fixture(name: &str) -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/fixtures/missions")
            .join(name)
    }

    use crate::statefile::scratch_dir as scratch;

    #[test]
    fn files_load_by_extension_or_by_their_first_bytes() {
        let plan = load_mission_file(&fixture("example-mission.plan")).unwrap();
        assert_eq!(plan.mission.len(), 5);
        let wpl = load_mission_file(&fixture("mavproxy-home.txt")).unwrap();
        assert_eq!(wpl.mission.len(), 5);

        let dir = scratch("ext");
        let plan_text = std::fs::read_to_string(fixture("example-mission.plan")).unwrap();
        let wpl_text = std::fs::read_to_string(fixture("mavproxy-home.txt")).unwrap();
        for (name, text, n) in [
            ("a.json", plan_text.as_str(), 5),
            ("a.waypoints", wpl_text.as_str(), 5),
            ("a.MISSION", wpl_text.as_str(), 5),
            ("a", wpl_text.as_str(), 5),
        ] {
            let p = dir.join(name);
            std::fs::write(&p, text).unwrap();
            assert_eq!(load_mission_file(&p).unwrap().mission.len(), n, "{name}");
        }
        // a byte-order mark is skipped
        let p = dir.join("bom.plan");
        std::fs::write(&p, format!("\u{feff}{plan_text}")).unwrap();
        assert_eq!(load_mission_file(&p).unwrap().mission.len(), 5);

        // a .plan in a .txt: the WPL reader says what it found
        let p = dir.join("json.txt");
        std::fs::write(&p, &plan_text).unwrap();
        let e = load_mission_file(&p).unwrap_err().to_string();
        assert!(e.contains("json.txt:1: header:") && e.contains(".plan"), "{e}");

        let p = dir.join("notes.doc");
        std::fs::write(&p, "hello").unwrap();
        let e = load_mission_file(&p).unwrap_err().to_string();
        assert!(
            e.contains("notes.doc: not a mission file") && e.contains("`.doc`"),
            "{e}"
        );

        let p = dir.join("latin1.txt");
        std::fs::write(&p, b"QGC WPL 110\n\xe9\n").unwrap();
        let e = load_mission_file(&p).unwrap_err().to_string();
        assert!(e.contains("latin1.txt: not UTF-8 text (byte 12"), "{e}");

        let e = load_mission_file(&dir.join("none.plan")).unwrap_err().to_string();
        assert!(e.contains("none.plan: cannot read:"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn into_plans_gives_the_ids_and_refuses_a_hand_made_bad_item() {
        let plan = load_mission_file(&fixture("fence-rally.plan")).unwrap();
        let mission = plan.mission.clone();
        let plans = plan.into_plans().unwrap();
        assert_eq!(plans.get(MissionType::Mission).len(), mission.len());
        assert_eq!(
            plans.get(MissionType::Mission).id(),
            crate::mission::crc::plan_id(&mission)
        );
        assert!(plans.get(MissionType::Fence).id() != 0 && plans.get(MissionType::Rally).id() != 0);
        let mut bad = PlanFile::default();
        bad.rally.push(mission[0]);
        assert_eq!(
            bad.into_plans(),
            Err((MissionType::Rally, 0, MissionResult::Unsupported))
        );
    }

    #[test]
    fn every_refusal_reads_as_a_sentence_with_the_vehicles_answer() {
        use MissionResult as R;
        let wp = MissionItem {
            frame: 3,
            command: cmd::NAV_WAYPOINT,
            autocontinue: true,
            params: [0.0; 4],
            x: 47.0,
            y: 8.0,
            z: 10.0,
        };
        for (kind, item, r, want) in [
            (
                MissionType::Mission,
                MissionItem { frame: 2, ..wp },
                R::UnsupportedFrame,
                "needs a position",
            ),
            (
                MissionType::Mission,
                MissionItem { frame: 1, ..wp },
                R::UnsupportedFrame,
                "frame 1 is not supported",
            ),
            (MissionType::Fence, wp, R::Unsupported, "not a fence item (5000 to 5004"),
            (MissionType::Rally, wp, R::Unsupported, "not a rally point"),
            (
                MissionType::Mission,
                MissionItem { x: 123.4, ..wp },
                R::InvalidParam5X,
                "latitude 123.4 is not within ±90°",
            ),
            (
                MissionType::Mission,
                MissionItem {
                    params: [-1.0, 0.0, 0.0, 0.0],
                    ..wp
                },
                R::InvalidParam1,
                "param1 = -1 is refused: command 16 needs a hold time",
            ),
            (MissionType::Mission, wp, R::NoSpace, "more than 20000 items"),
            (MissionType::Mission, wp, R::Denied, "denied"),
        ] {
            let d = describe(kind, &item, r);
            assert!(d.contains(want) && d.ends_with(&format!("({})", mav_name(r))), "{d}");
        }
    }

    #[test]
    fn quantising_rounds_to_the_nearest_dege7_and_keeps_what_cannot_be_sent() {
        assert_eq!(crate::mission::quantise_deg(47.397_742_04), 47.397_742);
        assert_eq!(crate::mission::quantise_deg(47.397_741_96), 47.397_742);
        assert_eq!(crate::mission::quantise_deg(-8.545_593_95), -8.545_594);
        assert_eq!(
            crate::mission::quantise_deg(0.000_000_05),
            0.000_000_1,
            "half away from zero, as std::round"
        );
        assert_eq!(crate::mission::quantise_deg(250.0), 250.0);
        assert!(crate::mission::quantise_deg(f64::NAN).is_nan());
        assert_eq!(crate::mission::quantise_deg(f64::INFINITY), f64::INFINITY);
        // the stored value gives the integer back
        let it = MissionItem {
            frame: 3,
            command: 16,
            autocontinue: true,
            params: [0.0; 4],
            x: crate::mission::quantise_deg(47.398_226_644_791_98),
            y: crate::mission::quantise_deg(8.545_560_383_312_846),
            z: 50.0,
        };
        assert_eq!((it.x_int(), it.y_int()), (473_982_266, 85_455_604));
    }
}
