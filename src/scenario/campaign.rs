//! Campaigns: many scenario files, each possibly varied over a grid or with
//! seeded random draws, enumerated in one deterministic order so that a run
//! can take a shard of them (`rotorpilot simulate --shard I/N`).
//!
//! # The `[campaign]` table
//!
//! A scenario TOML (plain or mission) may hold a `[campaign]` table that
//! varies its own values. Each key of `[campaign.grid]` and
//! `[campaign.random]` is a path into the file: dotted table keys, with
//! `[k]` picking the k-th entry of a list counted from 1 (as the scenario's
//! own error messages count `[[disturbance]]` and `[[fault]]`), e.g.
//! `"disturbance[1].true_mass_kg"`, `"disturbance[1].force_ned[2]"`,
//! `"gains.geometric.kp_n_per_m"`, `"params.MPC_XY_CRUISE"`. The value must
//! be written in the file: it fixes where the value goes and its type (a
//! number, string, boolean, or a list of them of the same length). Each
//! variant is the file with those values replaced, then read and checked
//! exactly as a plain scenario, so every field of the format can vary.
//!
//! ```toml
//! [campaign]
//! seed = 7        # random draws: draw k comes from ChaCha8 (seed, stream k) only
//! draws = 16      # random draws per grid point (needs [campaign.random])
//!
//! [campaign.grid]                       # Cartesian product, last key fastest
//! "disturbance[1].true_mass_kg" = [1.8, 2.0, 2.4]
//!
//! [campaign.random]                     # one distribution per key
//! "disturbance[1].force_ned[1]" = { normal = [0.0, 0.5] }    # mean, standard deviation
//! "disturbance[1].force_ned[2]" = { uniform = [-1.0, 1.0] }  # [a, b)
//! "seed" = { integer = [0, 1000000] }                        # whole numbers in [a, b]
//! "controller" = { choice = ["geometric", "passivity"] }     # one of the values
//! ```
//!
//! Variants: `grid points x draws`, numbered from 0 with the draw varying
//! fastest: variant `v` is grid point `v / draws` (the last grid key
//! varying fastest, keys in the order written; a bare dotted key's parts by
//! name) with draw `v % draws`. Draw `d` takes its values, keys in the order
//! written, from a ChaCha8 stream seeded by `seed` with stream number `d`:
//! it is the same whatever the shard, the job count or the other variants,
//! and every grid point sees the same draws (paired comparisons). Without a
//! `[campaign]` table a file is one variant, read exactly as before.
//!
//! # Enumeration and shards
//!
//! The campaign is the files in the order given (a directory stands for its
//! files with [`EXTENSIONS`], sorted by name), each file's variants in order;
//! entry `i` of that list goes to shard `i % N`. A file that cannot be read,
//! or whose `[campaign]` table is wrong, is one entry (its error).

use std::io::Write;
use std::path::{Path, PathBuf};

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::Distribution;
use serde::{Deserialize, Serialize};
use toml::{Spanned, Value};

use super::{MissionFlight, MissionSummary, Scenario, ScenarioError, Summary};
use crate::tomlfile::{self, FileError};

/// File extensions a directory argument contributes (a QGC WPL `.txt` must be named explicitly).
pub const EXTENSIONS: &[&str] = &["toml", "plan", "waypoints", "mission"];

/// At most this many variants in one file.
pub const MAX_VARIANTS: u64 = 1_000_000;

/// The scenario files a directory holds directly (no recursion): those with
/// one of [`EXTENSIONS`], not hidden, sorted by file name.
///
/// # Errors
/// The directory cannot be listed.
pub fn files_in(dir: &Path) -> std::io::Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    for entry in std::fs::read_dir(dir)? {
        let entry = entry?;
        let name = entry.file_name();
        let path = entry.path();
        let wanted = path
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| EXTENSIONS.contains(&e));
        if wanted && !name.to_string_lossy().starts_with('.') && path.is_file() {
            files.push((name, path));
        }
    }
    files.sort();
    Ok(files.into_iter().map(|(_, p)| p).collect())
}

/// `--shard I/N`: this run takes the entries `i` with `i % N == I` (0-based
/// `I`, as a Kubernetes Indexed Job's `JOB_COMPLETION_INDEX`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// Which shard, `0..count`.
    pub index: u64,
    /// How many shards.
    pub count: u64,
}

impl Shard {
    /// The whole campaign.
    pub const ALL: Shard = Shard { index: 0, count: 1 };

    /// Whether entry `i` of the campaign is this shard's.
    #[must_use]
    pub fn takes(&self, i: u64) -> bool {
        i % self.count == self.index
    }
}

impl std::str::FromStr for Shard {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        let (i, n) = s
            .split_once('/')
            .ok_or_else(|| format!("`{s}`: expected I/N, e.g. 0/4 (0-based I below N)"))?;
        let whole = |part: &str, what: &str| {
            part.trim()
                .parse::<u64>()
                .map_err(|_| format!("`{s}`: {what} `{part}` is not a whole number (expected I/N, e.g. 0/4)"))
        };
        let (index, count) = (whole(i, "I")?, whole(n, "N")?);
        if count == 0 {
            return Err(format!("`{s}`: N must be at least 1"));
        }
        if index >= count {
            return Err(format!(
                "`{s}`: I must be below N (shards are numbered from 0, as JOB_COMPLETION_INDEX: 0..={})",
                count - 1
            ));
        }
        Ok(Shard { index, count })
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// One step of a value path: a table key, or the k-th list entry (from 1).
#[derive(Clone, Debug, PartialEq)]
enum Step {
    Key(String),
    Entry(usize),
}

/// `a.b[2].c` into steps; `Err(problem)`.
fn parse_path(path: &str) -> Result<Vec<Step>, String> {
    let mut steps = Vec::new();
    for part in path.split('.') {
        let (name, mut rest) = part.split_at(part.find('[').unwrap_or(part.len()));
        if name.is_empty() || name.contains(']') {
            return Err(format!("`{path}` is not a path like `table.key` or `list[1].key`"));
        }
        steps.push(Step::Key(name.to_string()));
        while !rest.is_empty() {
            let close = rest.find(']').filter(|_| rest.starts_with('['));
            let k = close
                .and_then(|c| rest[1..c].parse::<usize>().ok())
                .filter(|k| *k >= 1)
                .ok_or_else(|| format!("`{path}`: list entries are written [k] with k counted from 1"))?;
            steps.push(Step::Entry(k));
            rest = &rest[close.map_or(rest.len(), |c| c + 1)..];
        }
    }
    Ok(steps)
}

/// The value at `steps` in `root`; `Err(problem)` naming what is missing.
fn lookup<'a>(root: &'a mut Value, steps: &[Step]) -> Result<&'a mut Value, String> {
    let mut at = root;
    let mut walked = String::new();
    for step in steps {
        at = match step {
            Step::Key(k) => {
                let here = if walked.is_empty() {
                    "the scenario".to_string()
                } else {
                    format!("`{walked}`")
                };
                let Value::Table(t) = at else {
                    return Err(format!("{here} is not a table: it has no key `{k}`"));
                };
                walked = if walked.is_empty() {
                    k.clone()
                } else {
                    format!("{walked}.{k}")
                };
                t.get_mut(k)
                    .ok_or_else(|| format!("{here} has no `{k}` (write the value to vary in the file)"))?
            }
            Step::Entry(k) => {
                let Value::Array(a) = at else {
                    return Err(format!("`{walked}` is not a list: it has no entry [{k}]"));
                };
                let len = a.len();
                walked = format!("{walked}[{k}]");
                a.get_mut(k - 1)
                    .ok_or_else(|| format!("`{walked}`: the list has {len} entries (counted from 1)"))?
            }
        };
    }
    Ok(at)
}

/// `new` made to fit where `old` stands: the same kind of value (an integer
/// taken as a float where a float stands; a float that is a whole number as
/// an integer), a list of the same length.
fn fit(old: &Value, new: &Value) -> Result<Value, String> {
    match (old, new) {
        (Value::Float(_), Value::Integer(i)) => Ok(Value::Float(*i as f64)),
        (Value::Integer(_), Value::Float(f)) => {
            if f.is_finite() && f.fract() == 0.0 && f.abs() < 9.0e15 {
                Ok(Value::Integer(*f as i64))
            } else {
                Err(format!(
                    "must be a whole number (the file has an integer there), got {f}"
                ))
            }
        }
        (Value::Array(a), Value::Array(b)) => {
            if a.len() != b.len() {
                return Err(format!(
                    "must be a list of {} values as in the file, got {} values",
                    a.len(),
                    b.len()
                ));
            }
            a.iter()
                .zip(b)
                .map(|(o, n)| fit(o, n))
                .collect::<Result<_, _>>()
                .map(Value::Array)
        }
        (Value::Table(_), _) => Err("is a table in the file: vary the values inside it".into()),
        (o, n) if o.same_type(n) => Ok(n.clone()),
        (o, n) => Err(format!(
            "must be a {} as in the file, got a {} ({n})",
            o.type_str(),
            n.type_str()
        )),
    }
}

/// A random distribution of `[campaign.random]`.
#[derive(Clone, Debug, PartialEq)]
enum Draw {
    /// Uniform on `[a, b)`.
    Uniform(f64, f64),
    /// Normal with mean and standard deviation.
    Normal(f64, f64),
    /// Uniform over the whole numbers in `[a, b]`.
    Integer(i64, i64),
    /// One of the values, each as likely.
    Choice(Vec<Value>),
}

const DRAW_FORMS: &str = "expected { uniform = [a, b] }, { normal = [mean, std] }, \
                          { integer = [a, b] } or { choice = [v1, v2, ...] }";

fn number(v: &Value) -> Option<f64> {
    match v {
        Value::Float(f) => Some(*f),
        Value::Integer(i) => Some(*i as f64),
        _ => None,
    }
}

impl Draw {
    /// Read `{ kind = [...] }`; `Err(problem)`.
    fn parse(v: &Value) -> Result<Self, String> {
        let Some((kind, args)) = v.as_table().filter(|t| t.len() == 1).and_then(|t| t.iter().next()) else {
            return Err(DRAW_FORMS.into());
        };
        let Some(list) = args.as_array() else {
            return Err(format!("`{kind}`: {DRAW_FORMS}"));
        };
        let pair = || match list.as_slice() {
            [a, b] => number(a).zip(number(b)).filter(|(a, b)| a.is_finite() && b.is_finite()),
            _ => None,
        };
        match kind.as_str() {
            "uniform" => match pair() {
                Some((a, b)) if a < b => Ok(Draw::Uniform(a, b)),
                _ => Err(format!("uniform = [a, b] needs two finite numbers a < b, got {args}")),
            },
            "normal" => match pair() {
                Some((m, s)) if s >= 0.0 => Ok(Draw::Normal(m, s)),
                _ => Err(format!(
                    "normal = [mean, std] needs two finite numbers, std >= 0, got {args}"
                )),
            },
            "integer" => match list.as_slice() {
                [Value::Integer(a), Value::Integer(b)] if a <= b => Ok(Draw::Integer(*a, *b)),
                _ => Err(format!("integer = [a, b] needs two integers a <= b, got {args}")),
            },
            "choice" if !list.is_empty() => Ok(Draw::Choice(list.clone())),
            "choice" => Err("choice = [...] needs at least one value".into()),
            other => Err(format!("unknown distribution `{other}`: {DRAW_FORMS}")),
        }
    }

    /// A sample from `rng`.
    fn sample(&self, rng: &mut ChaCha8Rng) -> Value {
        use rand::RngExt as _;
        match self {
            // u in [0, 1) from the top 53 bits: a + (b - a) u
            Draw::Uniform(a, b) => Value::Float(a + (b - a) * rng.random::<f64>()),
            Draw::Normal(m, s) => {
                let z: f64 = rand_distr::StandardNormal.sample(rng);
                Value::Float(m + s * z)
            }
            Draw::Integer(a, b) => Value::Integer(rng.random_range(*a..=*b)),
            Draw::Choice(list) => list[rng.random_range(0..list.len())].clone(),
        }
    }

    /// The kind of value it gives, checked against the file's `old` up front,
    /// so no draw can fail to fit.
    fn check_fits(&self, old: &Value) -> Result<(), String> {
        match self {
            Draw::Uniform(..) | Draw::Normal(..) if !matches!(old, Value::Float(_)) => Err(format!(
                "draws real numbers, but the file has a {} there{}",
                old.type_str(),
                if matches!(old, Value::Integer(_)) {
                    ": use integer = [a, b]"
                } else {
                    ""
                }
            )),
            Draw::Uniform(..) | Draw::Normal(..) => Ok(()),
            Draw::Integer(..) => fit(old, &Value::Integer(0)).map(|_| ()),
            Draw::Choice(list) => list.iter().try_for_each(|v| fit(old, v).map(|_| ())),
        }
    }
}

#[derive(Deserialize)]
struct Outer {
    campaign: Option<Spanned<RawCampaign>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCampaign {
    #[serde(default)]
    seed: u64,
    draws: Option<Spanned<u64>>,
    #[serde(default)]
    grid: std::collections::BTreeMap<Spanned<String>, Spanned<Value>>,
    #[serde(default)]
    random: std::collections::BTreeMap<Spanned<String>, Spanned<Value>>,
}

/// A table's entries as `(path, value, byte offset)` in the order written;
/// a bare dotted key (a nested table) is followed down to `stop_at` values.
fn entries(
    map: std::collections::BTreeMap<Spanned<String>, Spanned<Value>>,
    stop_at: impl Fn(&Value) -> bool,
) -> Vec<(String, Value, usize)> {
    fn walk(
        prefix: &str,
        v: Value,
        at: usize,
        stop_at: &dyn Fn(&Value) -> bool,
        out: &mut Vec<(String, Value, usize)>,
    ) {
        if !stop_at(&v)
            && let Value::Table(t) = v
        {
            for (k, v) in t {
                walk(&format!("{prefix}.{k}"), v, at, stop_at, out);
            }
        } else {
            out.push((prefix.to_string(), v, at));
        }
    }
    let mut list: Vec<_> = map.into_iter().collect();
    list.sort_by_key(|(k, _)| k.span().start);
    let mut out = Vec::new();
    for (k, v) in list {
        let at = k.span().start;
        walk(k.get_ref(), v.into_inner(), at, &stop_at, &mut out);
    }
    out
}

/// The steps of `path` and the file's value there; `Err(problem)` when the
/// file has no such value or `path` overlaps one in `seen` (then added).
fn locate(base: &mut Value, seen: &mut Vec<(String, Vec<Step>)>, path: &str) -> Result<(Vec<Step>, Value), String> {
    let steps = parse_path(path)?;
    let old = lookup(base, &steps)?.clone();
    if let Some((other, _)) = seen.iter().find(|(_, s)| s.iter().zip(&steps).all(|(a, b)| a == b)) {
        return Err(format!("overlaps `{other}`, varied already"));
    }
    seen.push((path.to_string(), steps.clone()));
    Ok((steps, old))
}

/// How a file's variants differ.
#[derive(Clone, Debug)]
struct Variation {
    /// `(path, steps, values)`, the last varying fastest.
    grid: Vec<(String, Vec<Step>, Vec<Value>)>,
    /// `(path, steps, distribution)`.
    random: Vec<(String, Vec<Step>, Draw)>,
    seed: u64,
    /// Draws per grid point (1 without random keys).
    draws: u64,
    /// Grid points times draws.
    count: u64,
    /// Byte offset of the `[campaign]` table in the file.
    table_at: usize,
}

impl Variation {
    /// Read the `[campaign]` table of `text` against the file's own values in
    /// `base` (the file without it). `Ok(None)` without a `[campaign]` table.
    fn parse(text: &str, file: &str, base: &mut Value) -> Result<Option<Self>, FileError> {
        let Outer { campaign } = tomlfile::parse(text, file)?;
        let Some(campaign) = campaign else {
            return Ok(None);
        };
        let table_at = campaign.span().start;
        let raw = campaign.into_inner();
        let at = |offset: usize, message: String| tomlfile::error_at(text, file, offset, message);
        let (mut grid, mut random) = (Vec::new(), Vec::new());
        let mut seen: Vec<(String, Vec<Step>)> = Vec::new();
        for (path, v, offset) in entries(raw.grid, |_| false) {
            let field = format!("campaign.grid.\"{path}\"");
            let (steps, old) = locate(base, &mut seen, &path).map_err(|p| at(offset, format!("{field}: {p}")))?;
            let Value::Array(values) = v else {
                return Err(at(
                    offset,
                    format!("{field}: must be a list of the values to try, got {v}"),
                ));
            };
            if values.is_empty() {
                return Err(at(offset, format!("{field}: the list of values is empty")));
            }
            let values: Vec<Value> = values
                .iter()
                .map(|n| fit(&old, n).map_err(|p| at(offset, format!("{field}: {n}: {p}"))))
                .collect::<Result<_, _>>()?;
            grid.push((path, steps, values));
        }
        // `{ kind = [...] }`; a table of tables is a bare dotted key to follow
        let is_draw = |v: &Value| v.as_table().is_none_or(|t| t.values().any(|x| !x.is_table()));
        for (path, v, offset) in entries(raw.random, is_draw) {
            let field = format!("campaign.random.\"{path}\"");
            let (steps, old) = locate(base, &mut seen, &path).map_err(|p| at(offset, format!("{field}: {p}")))?;
            let draw = Draw::parse(&v)
                .and_then(|d| d.check_fits(&old).map(|()| d))
                .map_err(|p| at(offset, format!("{field}: {p}")))?;
            random.push((path, steps, draw));
        }
        let draws = match (raw.draws, random.is_empty()) {
            (None, true) => 1,
            (Some(d), false) if (1..=MAX_VARIANTS).contains(d.get_ref()) => *d.get_ref(),
            (Some(d), false) => {
                return Err(at(
                    d.span().start,
                    format!("campaign.draws: must be in 1..={MAX_VARIANTS}, got {}", d.get_ref()),
                ));
            }
            (None, false) => {
                return Err(at(table_at, "campaign.draws: missing: how many random draws?".into()));
            }
            (Some(d), true) => {
                return Err(at(
                    d.span().start,
                    "campaign.draws: given without [campaign.random]: nothing to draw".into(),
                ));
            }
        };
        if grid.is_empty() && random.is_empty() {
            return Err(at(
                table_at,
                "campaign: varies nothing: give [campaign.grid] or [campaign.random]".into(),
            ));
        }
        let count = grid
            .iter()
            .try_fold(draws, |n, (_, _, v)| n.checked_mul(v.len() as u64))
            .filter(|n| *n <= MAX_VARIANTS)
            .ok_or_else(|| at(table_at, format!("campaign: more than {MAX_VARIANTS} variants")))?;
        Ok(Some(Variation {
            grid,
            random,
            seed: raw.seed,
            draws,
            count,
            table_at,
        }))
    }

    /// The values of variant `v`, grid keys then random keys, in order.
    fn values(&self, v: u64) -> Vec<(String, Vec<Step>, Value)> {
        let (mut point, draw) = (v / self.draws, v % self.draws);
        let mut out = Vec::new();
        for (path, steps, values) in self.grid.iter().rev() {
            let n = values.len() as u64;
            out.push((path.clone(), steps.clone(), values[(point % n) as usize].clone()));
            point /= n;
        }
        out.reverse();
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
        rng.set_stream(draw);
        for (path, steps, d) in &self.random {
            out.push((path.clone(), steps.clone(), d.sample(&mut rng)));
        }
        out
    }
}

/// `text` with the lines of its `[campaign]` table made empty: each
/// `[campaign]` or `[campaign.*]` header and the lines after it up to the
/// next header, and a one-line `campaign = {...}` or `campaign.k = ...`
/// before the first header. Every other line keeps its number and columns.
fn without_campaign(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    // the first key of the table header the line is under; `None` before any
    let mut under: Option<String> = None;
    for line in text.split_inclusive('\n') {
        let root = first_key(line);
        let header = line.trim_start().starts_with('[') && root.is_some();
        if header {
            under.clone_from(&root);
        }
        let blank = if header || under.is_some() {
            under.as_deref() == Some("campaign")
        } else {
            root.as_deref() == Some("campaign")
        };
        out.push_str(if blank {
            &line[line.trim_end_matches(['\r', '\n']).len()..]
        } else {
            line
        });
    }
    out
}

/// The one top key a line defines when read alone as TOML (`[a.b]` and
/// `[[a]]` headers, `a = 1`, `a.b = 1`); `None` for any other line. A line
/// of a multi-line value that reads so is caught by the caller, which checks
/// that the text without the table reads as the file without it.
fn first_key(line: &str) -> Option<String> {
    let t = line.parse::<toml::Table>().ok()?;
    (t.len() == 1).then(|| t.keys().next().cloned()).flatten()
}

/// `a == b`, with a NaN equal to itself (a mission item may hold `nan`).
fn same(a: &Value, b: &Value) -> bool {
    match (a, b) {
        (Value::Float(x), Value::Float(y)) => x == y || (x.is_nan() && y.is_nan()),
        (Value::Array(x), Value::Array(y)) => x.len() == y.len() && x.iter().zip(y).all(|(x, y)| same(x, y)),
        (Value::Table(x), Value::Table(y)) => {
            x.len() == y.len() && x.iter().all(|(k, v)| y.get(k).is_some_and(|w| same(v, w)))
        }
        _ => a == b,
    }
}

/// A flight ready to fly: a scenario or a mission.
#[derive(Clone, Debug)]
pub enum Flight {
    /// A plain scenario.
    Scenario(Box<Scenario>),
    /// A mission.
    Mission(Box<MissionFlight>),
}

/// What a flight gave.
#[derive(Clone, Debug, Serialize)]
#[serde(untagged)]
pub enum Outcome {
    /// A plain scenario's summary.
    Scenario(Box<Summary>),
    /// A mission's summary with its verdict.
    Mission(Box<MissionSummary>),
}

impl Flight {
    /// Fly it flat out; `csv` receives the log of `rotorpilot simulate --csv`.
    ///
    /// # Errors
    /// As [`super::run`] and [`super::run_mission`].
    pub fn fly(&self, csv: Option<&mut dyn Write>) -> anyhow::Result<Outcome> {
        self.fly_with(csv, None).map(|(o, _)| o)
    }

    /// [`Self::fly`], also collecting the flight's report page when `report`
    /// gives its meta ([`super::run_with`], [`super::run_mission_with`]).
    ///
    /// # Errors
    /// As [`Self::fly`].
    pub fn fly_with(
        &self,
        csv: Option<&mut dyn Write>,
        report: Option<crate::logs::report::ReportMeta>,
    ) -> anyhow::Result<(Outcome, Option<crate::logs::report::FlightReport>)> {
        Ok(match self {
            Flight::Scenario(s) => {
                let (summary, page) = super::run_with(s, csv, report)?;
                (Outcome::Scenario(Box::new(summary)), page)
            }
            Flight::Mission(m) => {
                let (summary, page) = super::run_mission_with(m, csv, report)?;
                (Outcome::Mission(Box::new(summary)), page)
            }
        })
    }
}

impl Outcome {
    /// Fill in the wall time [s] (the caller owns the clock).
    pub fn set_wall_time_s(&mut self, s: f64) {
        match self {
            Outcome::Scenario(x) => x.wall_time_s = s,
            Outcome::Mission(x) => x.wall_time_s = s,
        }
    }

    /// `false` only for a mission that failed its verdict.
    #[must_use]
    pub fn passed(&self) -> bool {
        match self {
            Outcome::Scenario(_) => true,
            Outcome::Mission(m) => m.verdict == "pass",
        }
    }

    /// The full human-readable summary.
    #[must_use]
    pub fn to_text(&self) -> String {
        match self {
            Outcome::Scenario(s) => s.to_text(),
            Outcome::Mission(m) => m.to_text(),
        }
    }

    /// The summary in one line (without the scenario's name).
    #[must_use]
    pub fn to_line(&self) -> String {
        match self {
            Outcome::Scenario(s) => format!(
                "{}: position error RMS {:.4e} m, max {:.4e} m; est. mass {:.4} kg; {}{}{:.1} s simulated in {:.3} s",
                s.controller,
                s.rms_pos_err_m,
                s.max_pos_err_m,
                s.est_mass_kg,
                if s.upright && s.finite {
                    ""
                } else {
                    "NOT UPRIGHT OR NOT FINITE; "
                },
                s.fault.as_ref().map_or(String::new(), |f| format!("stopped: {f}; ")),
                s.sim_time_s,
                s.wall_time_s
            ),
            Outcome::Mission(m) => format!(
                "{}{}; tracking error max {:.3} m; {:.1} s simulated in {:.3} s",
                m.verdict.to_uppercase(),
                if m.reasons.is_empty() {
                    String::new()
                } else {
                    format!(" ({})", m.reasons.join("; "))
                },
                m.max_tracking_error_m,
                m.sim_time_s,
                m.wall_time_s
            ),
        }
    }
}

/// The values a variant uses, `(path, value)` in the order of the `[campaign]` table.
pub type Values = Vec<(String, Value)>;

/// One file of a campaign, its variants enumerable.
#[derive(Clone, Debug)]
pub struct CampaignFile {
    /// The path as given.
    pub path: PathBuf,
    body: Body,
}

#[derive(Clone, Debug)]
enum Body {
    /// No `[campaign]`: the file as `rotorpilot simulate FILE` reads it
    /// (`text` when it is TOML).
    Plain { text: Option<String>, mission: bool },
    /// The file's values (without `[campaign]`) and how they vary.
    Varied {
        base: Value,
        mission: bool,
        variation: Variation,
    },
}

impl CampaignFile {
    /// Read `path` and its `[campaign]` table, if any (a `.plan` or WPL
    /// file has none and is read when flown). A file with a `[campaign]`
    /// table has its own values read and checked here, once, as a scenario
    /// or mission, against the file's own text with the table's lines made
    /// empty: an error in them names this file's line, not a variant's.
    ///
    /// # Errors
    /// The file cannot be read, its `[campaign]` table is wrong, or its own
    /// values are (file, line or field, problem).
    pub fn load(path: &Path) -> anyhow::Result<Self> {
        let plain = |text, mission| CampaignFile {
            path: path.to_path_buf(),
            body: Body::Plain { text, mission },
        };
        if path.extension().and_then(|e| e.to_str()) != Some("toml") {
            return Ok(plain(None, true));
        }
        let text = tomlfile::read(path)?;
        let file = path.display().to_string();
        // not TOML: the scenario reader reports it, as for a single file
        let Ok(Value::Table(mut table)) = text.parse::<toml::Table>().map(Value::Table) else {
            return Ok(plain(Some(text), false));
        };
        let mission = table.contains_key("mission");
        if table.remove("campaign").is_none() {
            return Ok(plain(Some(text), mission));
        }
        let mut base = Value::Table(table);
        let Some(variation) = Variation::parse(&text, &file, &mut base)? else {
            return Ok(plain(Some(text), mission));
        };
        let own = without_campaign(&text);
        if !own.parse::<toml::Table>().is_ok_and(|t| same(&Value::Table(t), &base)) {
            return Err(tomlfile::error_at(
                &text,
                &file,
                variation.table_at,
                "campaign: write it as [campaign], [campaign.grid] and [campaign.random] tables \
                 (not as a multi-line inline table) so that the file's own lines can be checked"
                    .into(),
            )
            .into());
        }
        // the one check of the file's own values; a variant then only puts
        // in values the table's checks have fitted to them
        let checked = if mission {
            MissionFlight::from_toml(&own, &file, path.parent()).map(drop)
        } else {
            Scenario::from_toml(&own, &file, path.parent())
                .map(drop)
                .map_err(anyhow::Error::from)
        };
        checked.map_err(|e| anyhow::anyhow!("{e:#}"))?;
        Ok(CampaignFile {
            path: path.to_path_buf(),
            body: Body::Varied {
                base,
                mission,
                variation,
            },
        })
    }

    /// How many variants: 1 without a `[campaign]` table.
    #[must_use]
    pub fn variants(&self) -> u64 {
        match &self.body {
            Body::Plain { .. } => 1,
            Body::Varied { variation, .. } => variation.count,
        }
    }

    /// Whether the file has a `[campaign]` table.
    #[must_use]
    pub fn is_varied(&self) -> bool {
        matches!(self.body, Body::Varied { .. })
    }

    /// The values variant `v` uses (empty for a plain file).
    #[must_use]
    pub fn values(&self, v: u64) -> Values {
        match &self.body {
            Body::Plain { .. } => Vec::new(),
            Body::Varied { variation, .. } => variation.values(v).into_iter().map(|(p, _, x)| (p, x)).collect(),
        }
    }

    /// The TOML text of variant `v` (the file's values with the variant's in
    /// place, no `[campaign]` table); `None` for a plain file.
    #[must_use]
    pub fn variant_text(&self, v: u64) -> Option<String> {
        let Body::Varied { base, variation, .. } = &self.body else {
            return None;
        };
        let mut doc = base.clone();
        for (_, steps, value) in variation.values(v) {
            if let Ok(slot) = lookup(&mut doc, &steps) {
                // fit was checked when the table was read: this cannot fail
                if let Ok(x) = fit(slot, &value) {
                    *slot = x;
                }
            }
        }
        toml::to_string(&doc).ok()
    }

    /// Variant `v` read and checked as a scenario or mission. A plain file is
    /// read exactly as `rotorpilot simulate FILE` always has; a variant's
    /// errors are labelled `FILE#v`, its summary names `FILE`.
    ///
    /// # Errors
    /// The scenario's own errors (file, field, problem).
    pub fn flight(&self, v: u64) -> anyhow::Result<Flight> {
        let file = self.path.display().to_string();
        let dir = self.path.parent();
        let (text, label, mission) = match &self.body {
            Body::Plain { text: None, .. } => {
                return Ok(Flight::Mission(Box::new(MissionFlight::from_file(&self.path)?)));
            }
            Body::Plain { text: Some(t), mission } => (t.clone(), file.clone(), *mission),
            Body::Varied { mission, .. } => (
                self.variant_text(v)
                    .ok_or_else(|| anyhow::anyhow!("{file}#{v}: cannot write the variant as TOML"))?,
                format!("{file}#{v}"),
                *mission,
            ),
        };
        let flight = if mission {
            MissionFlight::from_toml(&text, &label, dir).map(|mut m| {
                m.source.clone_from(&file);
                Flight::Mission(Box::new(m))
            })
        } else {
            Scenario::from_toml(&text, &label, dir)
                .map(|mut s| {
                    s.source.clone_from(&file);
                    Flight::Scenario(Box::new(s))
                })
                .map_err(anyhow::Error::from)
        };
        flight.map_err(|e| self.variant_error(e, v))
    }

    /// A variant's error as it is, unless it is a TOML type error: the file's
    /// own values were checked by [`CampaignFile::load`], so the variant's
    /// values caused it, and its line would be one of the TOML written for
    /// the variant, which the user never sees: name the values instead.
    fn variant_error(&self, e: anyhow::Error, v: u64) -> anyhow::Error {
        let syntax = match e.downcast_ref::<ScenarioError>() {
            Some(ScenarioError::File(f)) => Some(f),
            _ => e.downcast_ref::<FileError>(),
        };
        match syntax {
            Some(FileError::Syntax { message, .. }) if self.is_varied() => {
                let values: Vec<String> = self.values(v).iter().map(|(p, x)| format!("{p} = {x}")).collect();
                anyhow::anyhow!("{}#{v}: {}: {message}", self.path.display(), values.join(", "))
            }
            _ => e,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const FIG8: &str = "airframe = \"quad\"\ncontroller = \"geometric\"\nduration_s = 2.0\nseed = 3\n\
        [reference]\nkind = \"figure_eight\"\nhalf_width_m = 2.0\nrate_rad_s = 0.5\naltitude_m = 2.0\n\
        [[disturbance]]\nat_s = 0.0\nforce_ned = [0.0, 0.0, 0.0]\ntrue_mass_kg = 2.0\n";

    fn load(text: &str) -> anyhow::Result<CampaignFile> {
        let dir = std::env::temp_dir().join(format!("rp-campaign-unit-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        // a file per text: the tests run in parallel
        let name = format!("{:016x}.toml", {
            use std::hash::{Hash, Hasher};
            let mut h = std::collections::hash_map::DefaultHasher::new();
            text.hash(&mut h);
            h.finish()
        });
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        CampaignFile::load(&path)
    }

    fn err(text: &str) -> String {
        load(text).unwrap_err().to_string()
    }

    #[test]
    fn shards_parse_and_partition() {
        assert_eq!("1/3".parse::<Shard>(), Ok(Shard { index: 1, count: 3 }));
        for (bad, says) in [
            ("3/3", "below N"),
            ("0/0", "at least 1"),
            ("1", "expected I/N"),
            ("a/2", "not a whole number"),
            ("-1/2", "not a whole number"),
            ("1/2/3", "not a whole number"),
        ] {
            let e = bad.parse::<Shard>().unwrap_err();
            assert!(e.contains(says), "{bad}: {e}");
        }
        let shards: Vec<Shard> = (0..3).map(|i| Shard { index: i, count: 3 }).collect();
        for i in 0..100 {
            assert_eq!(shards.iter().filter(|s| s.takes(i)).count(), 1);
        }
    }

    #[test]
    fn paths_parse_with_entries_from_one() {
        assert_eq!(
            parse_path("disturbance[1].force_ned[3]").unwrap(),
            vec![
                Step::Key("disturbance".into()),
                Step::Entry(1),
                Step::Key("force_ned".into()),
                Step::Entry(3)
            ]
        );
        for bad in ["a..b", "a[0]", "a[x]", "a[1", "[1]", "a]"] {
            assert!(parse_path(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn a_plain_file_is_one_variant_read_as_before() {
        let f = load(FIG8).unwrap();
        assert!(!f.is_varied());
        assert_eq!(f.variants(), 1);
        assert!(f.values(0).is_empty());
        assert!(matches!(f.flight(0).unwrap(), Flight::Scenario(_)));
    }

    #[test]
    fn a_grid_is_the_cartesian_product_last_key_fastest() {
        let f = load(&format!(
            "{FIG8}[campaign.grid]\n\"disturbance[1].true_mass_kg\" = [1.8, 2.2]\n\
             \"disturbance[1].force_ned[1]\" = [0, 0.5, 1]\n"
        ))
        .unwrap();
        assert_eq!(f.variants(), 6);
        let got: Vec<(f64, f64)> = (0..6)
            .map(|v| {
                let vals = f.values(v);
                assert_eq!(vals[0].0, "disturbance[1].true_mass_kg");
                (vals[0].1.as_float().unwrap(), vals[1].1.as_float().unwrap())
            })
            .collect();
        assert_eq!(
            got,
            vec![(1.8, 0.0), (1.8, 0.5), (1.8, 1.0), (2.2, 0.0), (2.2, 0.5), (2.2, 1.0)]
        );
        // the values land in the scenario (the integer 0 as a float)
        let Flight::Scenario(s) = f.flight(4).unwrap() else {
            panic!()
        };
        assert_eq!(s.disturbances[0].true_mass_kg, Some(2.2));
        assert_eq!(s.disturbances[0].force_ned.unwrap().x, 0.5);
        assert!(s.source.ends_with(".toml"), "the summary names the file: {}", s.source);
    }

    #[test]
    fn draws_depend_on_the_seed_and_the_draw_only() {
        let campaign = |draws: u64, seed: u64, grid: &str| {
            load(&format!(
                "{FIG8}[campaign]\nseed = {seed}\ndraws = {draws}\n[campaign.grid]\n{grid}\n[campaign.random]\n\
                 \"disturbance[1].force_ned[1]\" = {{ normal = [0.0, 1.0] }}\n\
                 \"disturbance[1].force_ned[2]\" = {{ uniform = [-1.0, 1.0] }}\n\
                 \"seed\" = {{ integer = [0, 9] }}\n\"controller\" = {{ choice = [\"geometric\", \"passivity\"] }}\n"
            ))
            .unwrap()
        };
        let a = campaign(4, 7, "");
        let b = campaign(9, 7, "\"duration_s\" = [2.0, 3.0]");
        assert_eq!((a.variants(), b.variants()), (4, 18));
        for d in 0..4 {
            let va = a.values(d);
            // the same draw at every grid point, whatever the number of draws
            assert_eq!(va, b.values(d)[1..]);
            assert_eq!(va, b.values(9 + d)[1..]);
            let north = va[0].1.as_float().unwrap();
            let east = va[1].1.as_float().unwrap();
            assert!((-1.0..1.0).contains(&east), "{east}");
            assert!((0..=9).contains(&va[2].1.as_integer().unwrap()));
            assert!(north.is_finite());
        }
        assert_ne!(a.values(0), a.values(1), "draws differ");
        assert_ne!(a.values(0), campaign(4, 8, "").values(0), "seeds differ");
        // a normal draw over many variants has about the mean and std asked for
        let many = campaign(2000, 1, "");
        let xs: Vec<f64> = (0..2000).map(|d| many.values(d)[0].1.as_float().unwrap()).collect();
        let mean = xs.iter().sum::<f64>() / 2000.0;
        let std = (xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / 1999.0).sqrt();
        assert!(mean.abs() < 0.1 && (std - 1.0).abs() < 0.1, "{mean} {std}");
    }

    #[test]
    fn a_variant_unchanged_is_the_file_itself() {
        // the TOML written for a variant reads back to the same scenario
        let plain = load(FIG8).unwrap();
        let same = load(&format!(
            "{FIG8}[campaign.grid]\n\"disturbance[1].true_mass_kg\" = [2.0]\n"
        ))
        .unwrap();
        let (Flight::Scenario(mut a), Flight::Scenario(b)) = (plain.flight(0).unwrap(), same.flight(0).unwrap()) else {
            panic!()
        };
        a.source.clone_from(&b.source);
        assert_eq!(format!("{a:?}"), format!("{b:?}"));
    }

    #[test]
    fn bad_campaign_tables_name_the_line_and_the_field() {
        let line = FIG8.lines().count() + 2;
        for (table, says) in [
            ("[campaign.grid]\n\"vehicle.mass\" = [1.0]\n", "has no `vehicle`"),
            ("[campaign.grid]\n\"disturbance[2].at_s\" = [1.0]\n", "has 1 entries"),
            ("[campaign.grid]\n\"disturbance[0].at_s\" = [1.0]\n", "counted from 1"),
            (
                "[campaign.grid]\n\"duration_s\" = 3.0\n",
                "must be a list of the values",
            ),
            ("[campaign.grid]\n\"duration_s\" = []\n", "empty"),
            ("[campaign.grid]\n\"airframe\" = [1.0]\n", "must be a string"),
            ("[campaign.grid]\n\"seed\" = [1.5]\n", "whole number"),
            (
                "[campaign.grid]\n\"disturbance[1].force_ned\" = [[1.0, 2.0]]\n",
                "list of 3 values",
            ),
            ("[campaign.grid]\n\"reference\" = [1.0]\n", "is a table"),
            (
                "[campaign]\ndraws = 3\n[campaign.random]\n\"duration_s\" = { uniform = [2.0, 1.0] }\n",
                "a < b",
            ),
            (
                "[campaign]\ndraws = 3\n[campaign.random]\n\"duration_s\" = { normal = [1.0, -1.0] }\n",
                "std >= 0",
            ),
            (
                "[campaign]\ndraws = 3\n[campaign.random]\n\"duration_s\" = { gauss = [1.0, 1.0] }\n",
                "unknown distribution `gauss`",
            ),
            (
                "[campaign]\ndraws = 3\n[campaign.random]\n\"duration_s\" = [1.0, 2.0]\n",
                "expected { uniform",
            ),
            (
                "[campaign]\ndraws = 3\n[campaign.random]\n\"seed\" = { uniform = [0.0, 1.0] }\n",
                "use integer",
            ),
            (
                "[campaign]\ndraws = 3\n[campaign.random]\n\"duration_s\" = { integer = [1.0, 3.0] }\n",
                "two integers",
            ),
            (
                "[campaign]\ndraws = 0\n[campaign.random]\n\"duration_s\" = { uniform = [1.0, 3.0] }\n",
                "campaign.draws",
            ),
            (
                "[campaign]\n[campaign.random]\n\"duration_s\" = { uniform = [1.0, 3.0] }\n",
                "draws: missing",
            ),
            ("[campaign]\ndraws = 4\n", "without [campaign.random]"),
            ("[campaign]\nseed = 1\n", "varies nothing"),
            ("[campaign]\ndrwas = 1\n", "unknown field `drwas`"),
            (
                "[campaign.grid]\n\"disturbance[1].force_ned\" = [[1, 2, 3]]\n\"disturbance[1].force_ned[1]\" = [1.0]\n",
                "overlaps",
            ),
            ("[campaign.grid]\n\"a[\" = [1.0]\n", "counted from 1"),
        ] {
            let e = err(&format!("{FIG8}{table}"));
            assert!(e.contains(says), "{table}: {e}");
            assert!(e.contains(".toml:"), "names the file: {e}");
            if !says.contains("unknown field") {
                assert!(e.contains("campaign"), "names the field: {e}");
            }
            // the line of the key (or of the table), not of the scenario
            let at: usize = e.split(':').nth(1).unwrap().parse().unwrap();
            assert!(at >= line - 1, "{e}");
        }
    }

    #[test]
    fn the_file_without_its_table_keeps_its_own_lines() {
        let text = "campaign.seed = 4\nduration_s = 2.0 # s\n[campaign]\ndraws = 2\n[reference]\nkind = \"hover\"\n\
                    [campaign.random]\n\"seed\" = { integer = [0, 9] }\n[[disturbance]]\nat_s = [\n  [1],\n]\n";
        let own = without_campaign(text);
        assert_eq!(
            own.lines().collect::<Vec<_>>(),
            [
                "",
                "duration_s = 2.0 # s",
                "",
                "",
                "[reference]",
                "kind = \"hover\"",
                "",
                "",
                "[[disturbance]]",
                "at_s = [",
                "  [1],",
                "]"
            ]
        );
        // a NaN (as a mission item may hold) is the same value as itself
        let nan: toml::Table = "x = [nan]".parse().unwrap();
        assert!(same(&Value::Table(nan.clone()), &Value::Table(nan)));
    }

    #[test]
    fn a_campaign_files_own_values_are_checked_once_at_its_own_lines() {
        let text = format!("{FIG8}[campaign.grid]\n\"duration_s\" = [1.0, 2.0]\n").replace("seed = 3", "sede = 3");
        let e = err(&text);
        assert!(e.contains(".toml:4:1: unknown field `sede`"), "{e}");
        // a table that cannot be blanked line by line is refused, not misread
        let e = err(&format!(
            "campaign = {{\n grid = {{ \"duration_s\" = [1.0] }} }}\n{FIG8}"
        ));
        assert!(e.contains(".toml:1:") && e.contains("multi-line inline table"), "{e}");
        // one line is fine
        let f = load(&format!(
            "campaign = {{ grid = {{ \"duration_s\" = [1.0, 3.0] }} }}\n{FIG8}"
        ))
        .unwrap();
        assert_eq!(f.variants(), 2);
    }

    #[test]
    fn a_value_out_of_range_fails_its_variant_only() {
        let f = load(&format!(
            "{FIG8}[campaign.grid]\n\"disturbance[1].true_mass_kg\" = [2.0, -1.0]\n"
        ))
        .unwrap();
        assert!(f.flight(0).is_ok());
        let e = f.flight(1).unwrap_err().to_string();
        assert!(
            e.contains(".toml#1: disturbance[1].true_mass_kg: must be finite and > 0"),
            "{e}"
        );
    }

    #[test]
    fn directories_give_their_scenario_files_sorted() {
        let dir = std::env::temp_dir().join(format!("rp-campaign-dir-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("sub.toml")).unwrap();
        for f in [
            "b.toml",
            "a.plan",
            "c.waypoints",
            "README.md",
            ".hidden.toml",
            "notes.txt",
        ] {
            std::fs::write(dir.join(f), "").unwrap();
        }
        let names: Vec<String> = files_in(&dir)
            .unwrap()
            .iter()
            .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
            .collect();
        assert_eq!(names, ["a.plan", "b.toml", "c.waypoints"]);
        std::fs::remove_dir_all(&dir).ok();
    }
}
