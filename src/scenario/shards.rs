//! A campaign's outputs and their merge: the closing line that ends every
//! campaign's `rotorpilot simulate --json` output (which campaign, which
//! shard, the tally), and [`merge`], which turns the outputs of the N shards
//! of a campaign (`--shard I/N`, `I = 0..N`) into the output of the whole
//! campaign flown at once (`rotorpilot merge`).
//!
//! # The output of a campaign
//!
//! One JSON object per line: one per entry flown, in entry order, each with
//! its `index` in the whole campaign (see [`super::campaign`]), then the
//! closing line [`Closing`]:
//!
//! ```json
//! {"campaign":"5d0c83a1f4e2b907","rotorpilot":"0.1.0","shard":"1/3","entries":10,"ok":3,"failed":0,"errors":0}
//! ```
//!
//! `campaign` is [`campaign_id`] of the files flown (their paths as given
//! and their bytes), so shards of other files, or of the same files edited,
//! are told apart; `entries` counts the whole campaign; `ok`, `failed` (a
//! mission that failed its verdict) and `errors` (an entry that could not be
//! read or flown) count this output's entries.
//!
//! # The merge
//!
//! The merged output is every shard's entry lines, byte for byte, in index
//! order, then the closing line of shard `0/1` with the counts summed: what
//! `rotorpilot simulate --json` prints for the whole campaign at once, but
//! for each entry's `wall_time_s` (the only field that depends on the
//! machine). Refused, with the file, line and field: a file that is not a
//! campaign's output, an output cut short (entries missing, no closing
//! line), counts that disagree with the entries, shards of different
//! campaigns or rotorpilot versions or shard counts, a shard given twice
//! and a shard missing.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::PathBuf;

use serde::Serialize;
use serde_json::{Map, Value};
use sha2::{Digest, Sha256};

use super::campaign::Shard;

/// The version of rotorpilot that flies (written in every closing line).
pub const VERSION: &str = env!("CARGO_PKG_VERSION");

/// What a file needs to be, said in refusals.
const WANTED: &str = "the stdout of `rotorpilot simulate --json` for a campaign or a --shard";

/// The closing line of a campaign's JSON output (module doc).
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Closing {
    /// The campaign's id: [`campaign_id`] of its files.
    pub campaign: String,
    /// The rotorpilot version that flew it.
    pub rotorpilot: String,
    /// Which shard this output is (`0/1`: the whole campaign).
    #[serde(serialize_with = "shard_text")]
    pub shard: Shard,
    /// Entries in the whole campaign.
    pub entries: u64,
    /// This output's entries flown whose verdict (if a mission) passed.
    pub ok: u64,
    /// This output's missions that failed their verdict.
    pub failed: u64,
    /// This output's entries that could not be read or flown.
    pub errors: u64,
}

fn shard_text<S: serde::Serializer>(shard: &Shard, s: S) -> Result<S::Ok, S::Error> {
    s.collect_str(shard)
}

/// What became of an entry, as its JSON line tells.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum EntryResult {
    Ok,
    Failed,
    Error,
}

impl Closing {
    /// The closing line of `shard` of campaign `campaign` (of `entries`
    /// entries), flown by this rotorpilot, counts zero.
    #[must_use]
    pub fn new(campaign: String, shard: Shard, entries: u64) -> Self {
        Closing {
            campaign,
            rotorpilot: VERSION.to_string(),
            shard,
            entries,
            ok: 0,
            failed: 0,
            errors: 0,
        }
    }

    /// The line (JSON, no newline).
    ///
    /// # Panics
    /// Never: strings and whole numbers always serialise.
    #[must_use]
    pub fn to_line(&self) -> String {
        serde_json::to_string(self).expect("strings and integers serialise")
    }

    /// Read a closing line's object; `Err(problem)` naming the field.
    fn read(o: &Map<String, Value>) -> Result<Self, String> {
        let text = |k: &str| match o.get(k) {
            Some(Value::String(s)) => Ok(s.clone()),
            Some(v) => Err(format!("field `{k}`: expected a string, got {v}")),
            None => Err(format!("field `{k}` missing")),
        };
        let whole = |k: &str| match o.get(k) {
            Some(v) => v
                .as_u64()
                .ok_or_else(|| format!("field `{k}`: expected a whole number, got {v}")),
            None => Err(format!("field `{k}` missing")),
        };
        let shard = text("shard")?
            .parse::<Shard>()
            .map_err(|e| format!("field `shard`: {e}"))?;
        let known = ["campaign", "rotorpilot", "shard", "entries", "ok", "failed", "errors"];
        if let Some(k) = o.keys().find(|k| !known.contains(&k.as_str())) {
            return Err(format!("unknown field `{k}`"));
        }
        Ok(Closing {
            campaign: text("campaign")?,
            rotorpilot: text("rotorpilot")?,
            shard,
            entries: whole("entries")?,
            ok: whole("ok")?,
            failed: whole("failed")?,
            errors: whole("errors")?,
        })
    }

    /// Count an entry.
    fn count(&mut self, r: EntryResult) {
        match r {
            EntryResult::Ok => self.ok += 1,
            EntryResult::Failed => self.failed += 1,
            EntryResult::Error => self.errors += 1,
        }
    }

    fn counts(&self) -> String {
        format!("{} ok, {} failed, {} errors", self.ok, self.failed, self.errors)
    }
}

/// The id of the campaign made of `files` (in order, as the command line
/// expands them): the first 16 hexadecimal digits of
/// `SHA-256(for each file: len(path) path, then 1 len(bytes) bytes, or 0 when
/// it cannot be read)`, lengths as little-endian `u64`s. The path is as
/// given, since each entry's line names it.
#[must_use]
pub fn campaign_id(files: &[PathBuf]) -> String {
    let mut h = Sha256::new();
    for p in files {
        let name = p.display().to_string();
        h.update((name.len() as u64).to_le_bytes());
        h.update(name.as_bytes());
        match std::fs::read(p) {
            Ok(bytes) => {
                h.update([1]);
                h.update((bytes.len() as u64).to_le_bytes());
                h.update(&bytes);
            }
            Err(_) => h.update([0]),
        }
    }
    h.finalize()[..8].iter().fold(String::new(), |mut s, b| {
        let _ = write!(s, "{b:02x}");
        s
    })
}

/// One campaign output read and checked on its own.
struct ShardOutput<'a> {
    name: &'a str,
    closing: Closing,
    /// `(index, line)`, in the file's order.
    entries: Vec<(u64, &'a str, EntryResult)>,
}

/// What an entry line says became of its entry: an `error`, a mission's
/// `verdict` other than `pass`, or fine.
fn result_of(o: &Map<String, Value>) -> EntryResult {
    if o.get("error").is_some_and(|e| !e.is_null()) {
        EntryResult::Error
    } else if o.get("verdict").is_some_and(|v| v != "pass") {
        EntryResult::Failed
    } else {
        EntryResult::Ok
    }
}

/// Numbers as `1, 4, 7`, at most `max` of them, then `and k more`.
fn list(xs: &[u64], max: usize) -> String {
    let mut s: Vec<String> = xs.iter().take(max).map(u64::to_string).collect();
    if xs.len() > max {
        s.push(format!("and {} more", xs.len() - max));
    }
    s.join(", ")
}

/// Read `text` (the file `name`) as a campaign's output.
fn read<'a>(name: &'a str, text: &'a str) -> Result<ShardOutput<'a>, String> {
    let mut entries = Vec::new();
    let mut closing: Option<(usize, Closing)> = None;
    let mut seen: BTreeMap<u64, usize> = BTreeMap::new();
    for (k, line) in text.lines().enumerate() {
        let n = k + 1;
        if line.trim().is_empty() {
            continue;
        }
        let at = format!("{name}:{n}");
        let value: Value =
            serde_json::from_str(line).map_err(|e| format!("{at}: not JSON ({e}): expected {WANTED}"))?;
        let Value::Object(o) = value else {
            return Err(format!("{at}: not a JSON object: expected {WANTED}"));
        };
        if let Some((m, _)) = closing {
            return Err(format!("{at}: a line after the closing line (line {m})"));
        }
        if let Some(i) = o.get("index") {
            let i = i
                .as_u64()
                .ok_or_else(|| format!("{at}: field `index`: expected a whole number, got {i}"))?;
            if let Some(m) = seen.insert(i, n) {
                return Err(format!("{at}: entry {i} a second time (line {m})"));
            }
            entries.push((i, line, result_of(&o), n));
        } else if o.contains_key("campaign") {
            closing = Some((n, Closing::read(&o).map_err(|e| format!("{at}: closing line: {e}"))?));
        } else {
            return Err(format!(
                "{at}: neither an entry (field `index`) nor the closing line (field `campaign`): expected {WANTED}"
            ));
        }
    }
    let Some((m, closing)) = closing else {
        return Err(if entries.is_empty() {
            format!("{name}: empty: expected {WANTED}")
        } else {
            format!(
                "{name}: no closing line (field `campaign`) after its {} entries: the run was cut short, \
                 or this is not {WANTED}",
                entries.len()
            )
        });
    };
    let shard = closing.shard;
    let mut counted = Closing::new(String::new(), shard, closing.entries);
    for &(i, _, r, n) in &entries {
        if i >= closing.entries {
            return Err(format!(
                "{name}:{n}: entry {i} is beyond the campaign's {} entries (line {m})",
                closing.entries
            ));
        }
        if !shard.takes(i) {
            return Err(format!(
                "{name}:{n}: entry {i} is not shard {shard}'s (line {m}: index % {} == {})",
                shard.count, shard.index
            ));
        }
        counted.count(r);
    }
    let missing: Vec<u64> = (shard.index..closing.entries)
        .step_by(usize::try_from(shard.count).unwrap_or(usize::MAX))
        .filter(|i| !seen.contains_key(i))
        .collect();
    if !missing.is_empty() {
        return Err(format!(
            "{name}: shard {shard} of a campaign of {}: entries {} missing",
            closing.entries,
            list(&missing, 8)
        ));
    }
    if counted.counts() != closing.counts() {
        return Err(format!(
            "{name}:{m}: closing line: fields `ok`, `failed`, `errors` say {}, but the file's entries are {}",
            closing.counts(),
            counted.counts()
        ));
    }
    Ok(ShardOutput {
        name,
        closing,
        entries: entries.into_iter().map(|(i, l, r, _)| (i, l, r)).collect(),
    })
}

/// The merged output: the whole campaign's.
#[derive(Debug)]
pub struct Merged {
    /// The text: entry lines in index order, then the closing line; each
    /// line ends with a newline.
    pub text: String,
    /// The closing line (shard `0/1`, the counts summed).
    pub closing: Closing,
    /// For each entry that failed its verdict or could not be flown, its
    /// index and line, in index order.
    pub problems: Vec<(u64, String)>,
}

/// Merge the outputs of all N shards of one campaign, `(name, text)` each
/// (the name, a file's path, is what refusals say): see the module doc.
///
/// # Errors
/// The problem, naming the file (and line and field), or the shards
/// missing or given twice.
pub fn merge(outputs: &[(String, String)]) -> Result<Merged, String> {
    if outputs.is_empty() {
        return Err("no shard outputs given".into());
    }
    let shards = outputs
        .iter()
        .map(|(name, text)| read(name, text))
        .collect::<Result<Vec<_>, _>>()?;
    let first = &shards[0];
    let c0 = &first.closing;
    for s in &shards[1..] {
        let c = &s.closing;
        if c.campaign != c0.campaign {
            return Err(format!(
                "shards of different campaigns: {} is campaign {} ({} entries), {} is campaign {} ({} entries); \
                 every shard must fly the same files, named the same way",
                first.name, c0.campaign, c0.entries, s.name, c.campaign, c.entries
            ));
        }
        if c.rotorpilot != c0.rotorpilot {
            return Err(format!(
                "{} was flown by rotorpilot {}, {} by rotorpilot {}: fly every shard with one version",
                first.name, c0.rotorpilot, s.name, c.rotorpilot
            ));
        }
        if c.shard.count != c0.shard.count || c.entries != c0.entries {
            return Err(format!(
                "{} is shard {} and {} is shard {}: the shards of one run are I/N for one N",
                first.name, c0.shard, s.name, c.shard
            ));
        }
    }
    let mut by_shard: BTreeMap<u64, &str> = BTreeMap::new();
    for s in &shards {
        if let Some(other) = by_shard.insert(s.closing.shard.index, s.name) {
            return Err(format!("shard {} given twice: {other} and {}", s.closing.shard, s.name));
        }
    }
    let n = c0.shard.count;
    let missing: Vec<String> = (0..n)
        .filter(|i| !by_shard.contains_key(i))
        .map(|i| format!("{i}/{n}"))
        .collect();
    if !missing.is_empty() {
        let given: Vec<String> = by_shard.iter().map(|(i, name)| format!("{i}/{n} in {name}")).collect();
        return Err(format!(
            "shard{} {} missing (given: {})",
            if missing.len() == 1 { "" } else { "s" },
            missing.join(", "),
            given.join(", ")
        ));
    }
    let mut closing = Closing {
        shard: Shard::ALL,
        ok: 0,
        failed: 0,
        errors: 0,
        ..c0.clone()
    };
    let mut all: Vec<(u64, &str, EntryResult)> = shards.iter().flat_map(|s| s.entries.iter().copied()).collect();
    all.sort_by_key(|(i, _, _)| *i);
    let mut text = String::new();
    let mut problems = Vec::new();
    for (i, line, r) in all {
        closing.count(r);
        if r != EntryResult::Ok {
            problems.push((i, line.to_string()));
        }
        text.push_str(line);
        text.push('\n');
    }
    text.push_str(&closing.to_line());
    text.push('\n');
    Ok(Merged {
        text,
        closing,
        problems,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A shard's output of a campaign of `entries` entries, entry 4 an
    /// error and entry 5 a failed mission.
    fn output(shard: &str, entries: u64) -> String {
        let shard: Shard = shard.parse().unwrap();
        let mut c = Closing::new("00ff".into(), shard, entries);
        let mut text = String::new();
        for i in (0..entries).filter(|i| shard.takes(*i)) {
            let (line, r) = match i {
                4 => (
                    format!("{{\"index\":{i},\"scenario\":\"x\",\"error\":\"bad\"}}"),
                    EntryResult::Error,
                ),
                5 => (format!("{{\"index\":{i},\"verdict\":\"fail\"}}"), EntryResult::Failed),
                _ => (
                    format!("{{\"index\":{i},\"verdict\":\"pass\",\"x\":0.1}}"),
                    EntryResult::Ok,
                ),
            };
            c.count(r);
            text.push_str(&line);
            text.push('\n');
        }
        text + &c.to_line() + "\n"
    }

    fn named(list: &[(&str, String)]) -> Vec<(String, String)> {
        list.iter().map(|(n, t)| ((*n).to_string(), t.clone())).collect()
    }

    #[test]
    fn three_shards_merge_into_the_whole() {
        let whole = output("0/1", 7);
        let m = merge(&named(&[
            ("c", output("2/3", 7)),
            ("a", output("0/3", 7)),
            ("b", output("1/3", 7)),
        ]))
        .unwrap();
        assert_eq!(m.text, whole);
        assert_eq!((m.closing.ok, m.closing.failed, m.closing.errors), (5, 1, 1));
        let idx: Vec<u64> = m.problems.iter().map(|p| p.0).collect();
        assert_eq!(idx, [4, 5]);
        // the whole run is its own merge; a shard with no entries is fine
        assert_eq!(merge(&named(&[("w", whole.clone())])).unwrap().text, whole);
        let few = merge(&named(&[
            ("a", output("0/3", 2)),
            ("b", output("1/3", 2)),
            ("c", output("2/3", 2)),
        ]));
        assert_eq!(few.unwrap().text, output("0/1", 2));
    }

    #[test]
    fn refusals_name_the_file_line_and_field() {
        let a = output("0/2", 6);
        let b = output("1/2", 6);
        let cut: String = b.lines().take(2).map(|l| format!("{l}\n")).collect();
        let dropped: String = b.lines().skip(1).map(|l| format!("{l}\n")).collect();
        for (list, says) in [
            (vec![("a", a.clone())], "shard 1/2 missing (given: 0/2 in a)"),
            (
                vec![("a", a.clone()), ("a2", a.clone())],
                "shard 0/2 given twice: a and a2",
            ),
            (
                vec![("a", a.clone()), ("b", cut)],
                "b: no closing line (field `campaign`) after its 2 entries",
            ),
            (
                vec![("a", a.clone()), ("b", dropped)],
                "b: shard 1/2 of a campaign of 6: entries 1 missing",
            ),
            (vec![("a", a.clone()), ("b", String::new())], "b: empty"),
            (
                vec![("a", a.clone()), ("b", "{\"x\": 1}\n".into())],
                "b:1: neither an entry",
            ),
            (vec![("a", a.clone()), ("b", "x\n".into())], "b:1: not JSON"),
            (vec![("a", a.clone()), ("b", "[1]\n".into())], "b:1: not a JSON object"),
            (
                vec![("a", a.clone()), ("b", b.replace("\"index\":3", "\"index\":\"3\""))],
                "b:2: field `index`: expected a whole number",
            ),
            (
                vec![
                    ("a", a.clone()),
                    ("b", b.replace("\"shard\":\"1/2\"", "\"shard\":\"2/2\"")),
                ],
                "b:4: closing line: field `shard`: `2/2`: I must be below N",
            ),
            (
                vec![("a", a.clone()), ("b", b.replace("\"entries\":6", "\"entries\":\"6\""))],
                "b:4: closing line: field `entries`: expected a whole number",
            ),
            (
                vec![("a", a.clone()), ("b", b.replace("\"ok\":2", "\"ok\":3"))],
                "b:4: closing line: fields `ok`, `failed`, `errors` say 3 ok, 1 failed, 0 errors, but",
            ),
            (
                vec![("a", a.clone()), ("b", b.replace("00ff", "00fe"))],
                "shards of different campaigns: a is campaign 00ff (6 entries), b is campaign 00fe",
            ),
            (
                vec![("a", a.clone()), ("b", b.replace(VERSION, "0.0.0-other"))],
                "b by rotorpilot 0.0.0-other",
            ),
            (
                vec![("a", a.clone()), ("b", output("1/3", 6))],
                "a is shard 0/2 and b is shard 1/3",
            ),
            (
                vec![("a", a.clone()), ("b", b.replace("\"index\":3", "\"index\":2"))],
                "b:2: entry 2 is not shard 1/2's",
            ),
            (
                vec![("a", a.clone()), ("b", b.replace("\"index\":3", "\"index\":1"))],
                "b:2: entry 1 a second time (line 1)",
            ),
        ] {
            let e = merge(&named(&list)).unwrap_err();
            assert!(e.contains(says), "want `{says}`, got: {e}");
        }
    }

    #[test]
    fn the_campaign_id_covers_paths_and_bytes() {
        let dir = std::env::temp_dir().join(format!("rp-shards-unit-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (a, b) = (dir.join("a.toml"), dir.join("b.toml"));
        std::fs::write(&a, "x = 1\n").unwrap();
        std::fs::write(&b, "x = 1\n").unwrap();
        let id = campaign_id(std::slice::from_ref(&a));
        assert_eq!(id.len(), 16);
        assert_eq!(id, campaign_id(std::slice::from_ref(&a)));
        assert_ne!(id, campaign_id(std::slice::from_ref(&b)), "another path");
        assert_ne!(
            campaign_id(&[a.clone(), b.clone()]),
            campaign_id(&[b.clone(), a.clone()]),
            "another order"
        );
        std::fs::write(&a, "x = 2\n").unwrap();
        assert_ne!(id, campaign_id(std::slice::from_ref(&a)), "other bytes");
        std::fs::remove_dir_all(&dir).ok();
        assert_ne!(
            campaign_id(std::slice::from_ref(&a)),
            campaign_id(&[b]),
            "unreadable files differ by path"
        );
    }
}
