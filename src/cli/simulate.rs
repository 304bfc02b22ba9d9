//! `rotorpilot simulate`: one scenario, or a campaign of many flown on every
//! core, optionally one shard of it (see [`crate::scenario::campaign`] for
//! the `[campaign]` table, the enumeration and the shards).
//!
//! One file without a `[campaign]` table (and no `--shard`) prints its full
//! summary as ever: as text, or with `--json` as one JSON object on one
//! line; `--csv FILE` writes its log. Anything else is a campaign: entry `i`
//! (files in the order given, a directory's files sorted by name, each
//! file's variants in order) is flown when `i % N == I` for `--shard I/N`,
//! by `--jobs` threads, and printed in entry order (not completion order) as
//! one line: with `--json` the summary object with `index` (the entry's
//! place in the whole campaign), `variant` (within its file) and `values`
//! (the `[campaign]` values used, `{}` for a plain file) in front; a file or
//! variant that cannot be read or flown gives `{"index", "variant",
//! "values", "scenario", "error"}` instead (`variant` null when the file
//! itself is bad), and its message goes to stderr too. `--csv DIR` writes
//! one `NNNN-STEM.csv` (`NNNN-STEM-vK.csv` for variant K) per entry into
//! DIR. A tally closes a campaign on stderr, and with `--json` the closing
//! line on stdout ([`crate::scenario::shards`]: the campaign's id, the
//! shard, the counts), which `rotorpilot merge` reads. Exit status: 0; 1
//! when a mission failed its verdict; 2 when an entry could not be read or
//! flown (it wins over 1).
//!
//! Every scenario is deterministic and independent, so the results (all but
//! `wall_time_s`) do not depend on the number of jobs or the shard.

use std::collections::BTreeMap;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use anyhow::Context as _;
use serde::Serialize;

use crate::error::error_chain;
use crate::scenario::campaign::{self, CampaignFile, EXTENSIONS, Outcome, Shard, Values};
use crate::scenario::fleet::{self, Fleet};
use crate::scenario::shards::{self, Closing};

/// The arguments of `rotorpilot simulate`.
#[derive(Debug, Clone, clap::Args)]
pub struct SimulateArgs {
    /// Scenario TOML (see tools/scenarios/), a TOML with a [mission] table, a
    /// QGroundControl .plan or a QGC WPL 110 file; or a directory (its .toml,
    /// .plan, .waypoints and .mission files, sorted by name). Several, a
    /// directory or a [campaign] table (see tools/campaigns/) make a campaign.
    #[arg(required = true, value_name = "SCENARIO")]
    pub scenarios: Vec<PathBuf>,
    /// Print each summary as one JSON object on one line.
    #[arg(long)]
    pub json: bool,
    /// Write the full time series as CSV: to this file for one scenario;
    /// for a campaign into this directory (made if missing), one
    /// NNNN-NAME.csv per entry.
    #[arg(long, value_name = "PATH")]
    pub csv: Option<PathBuf>,
    /// Write each flight's report page (one offline HTML file, `rotorpilot
    /// report`'s) into this directory (made if missing): STEM.html for one
    /// file, NNNN-STEM.html per campaign entry or fleet vehicle.
    #[arg(long, value_name = "DIR")]
    pub report: Option<PathBuf>,
    /// Scenarios flown at once (default: the cores available).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    pub jobs: Option<u32>,
    /// Fly only the campaign's entries i with i % N == I (I from 0, e.g.
    /// $JOB_COMPLETION_INDEX/N in a Kubernetes Indexed Job).
    #[arg(long, value_name = "I/N")]
    pub shard: Option<Shard>,
    /// A fleet file ([fleet] table, see tools/fleets/): step its vehicles
    /// on N threads (default 1; the flight is the same to the bit on any N).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    pub threads: Option<u32>,
}

/// Exit status: a mission failed its verdict.
const EXIT_MISSION_FAILED: u8 = 1;
/// Exit status: a scenario could not be read or flown, or the arguments name no campaign.
pub(super) const EXIT_BAD_SCENARIO: u8 = 2;

/// One entry of the campaign this run flies.
#[derive(Debug)]
struct Entry {
    /// Place in the whole campaign (what shards split).
    index: u64,
    /// Which file (into the loaded list).
    file: usize,
    /// Which variant; `None` when the file itself could not be loaded.
    variant: Option<u64>,
}

/// What became of an entry.
type Done = Result<Outcome, String>;

/// `values` as a JSON object in the order of the `[campaign]` table.
struct JsonValues<'a>(&'a Values);

impl Serialize for JsonValues<'_> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_map(self.0.iter().map(|(k, v)| (k, v)))
    }
}

#[derive(Serialize)]
struct Line<'a> {
    index: u64,
    variant: Option<u64>,
    values: JsonValues<'a>,
    #[serde(flatten)]
    outcome: &'a Outcome,
}

#[derive(Serialize)]
struct ErrorLine<'a> {
    index: u64,
    variant: Option<u64>,
    values: JsonValues<'a>,
    scenario: String,
    error: &'a str,
}

/// The files the arguments name, in order (a directory's sorted by name).
fn expand(paths: &[PathBuf]) -> anyhow::Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    for p in paths {
        if p.is_dir() {
            let list = campaign::files_in(p).with_context(|| format!("{}: cannot list the directory", p.display()))?;
            anyhow::ensure!(
                !list.is_empty(),
                "{}: no scenario files in the directory (looked for .{})",
                p.display(),
                EXTENSIONS.join(", .")
            );
            files.extend(list);
        } else {
            files.push(p.clone());
        }
    }
    Ok(files)
}

/// A number in at most 6 significant digits, shortest form (for text lines).
fn short(v: &toml::Value) -> String {
    match v {
        toml::Value::Float(x) if x.is_finite() => {
            let r: f64 = format!("{x:.5e}").parse().unwrap_or(*x);
            format!("{r}")
        }
        toml::Value::String(s) => s.clone(),
        toml::Value::Array(a) => format!("[{}]", a.iter().map(short).collect::<Vec<_>>().join(", ")),
        other => other.to_string(),
    }
}

/// Run `rotorpilot simulate`; the exit status: 0, [`EXIT_MISSION_FAILED`],
/// or [`EXIT_BAD_SCENARIO`] (also for arguments that name no campaign, such
/// as an empty directory, printed to stderr), so that 1 always means a
/// failed verdict.
#[must_use]
pub(super) fn main(args: &SimulateArgs) -> u8 {
    run(args).unwrap_or_else(|e| {
        eprintln!("rotorpilot: {}", error_chain(&e));
        EXIT_BAD_SCENARIO
    })
}

/// [`main`]; `Err` for arguments that name no campaign (an empty or
/// unreadable directory), a CSV directory that cannot be made, or stdout
/// closed. Bad scenario files are entries, not errors.
#[allow(clippy::too_many_lines)]
fn run(args: &SimulateArgs) -> anyhow::Result<u8> {
    let paths = expand(&args.scenarios)?;
    match (paths.as_slice(), args.shard) {
        ([one], None) if !args.scenarios[0].is_dir() && fleet::is_fleet(one) => return run_fleet(args, one),
        _ => {
            if let Some(f) = paths.iter().find(|p| fleet::is_fleet(p)) {
                anyhow::bail!(
                    "{}: a fleet flies on its own, not in a campaign or a directory (`rotorpilot simulate {0}`)",
                    f.display()
                );
            }
            anyhow::ensure!(
                args.threads.is_none(),
                "--threads steps the vehicles of one fleet file; scenarios are flown at once with --jobs"
            );
        }
    }
    let files: Vec<Result<CampaignFile, String>> = paths
        .iter()
        .map(|p| CampaignFile::load(p).map_err(|e| e.to_string()))
        .collect();
    let shard = args.shard.unwrap_or(Shard::ALL);
    let campaign_id = shards::campaign_id(&paths);
    let mut total = 0u64;
    let mut entries = Vec::new();
    for (file, f) in files.iter().enumerate() {
        let (n, varied) = match f {
            Ok(f) => (f.variants(), true),
            Err(_) => (1, false),
        };
        for v in 0..n {
            if shard.takes(total) {
                entries.push(Entry {
                    index: total,
                    file,
                    variant: varied.then_some(v),
                });
            }
            total += 1;
        }
    }
    let single = args.shard.is_none()
        && args.scenarios.len() == 1
        && !args.scenarios[0].is_dir()
        && files
            .first()
            .is_none_or(|f| f.as_ref().map_or(true, |f| !f.is_varied()));
    let csv_dir = match (&args.csv, single) {
        (Some(dir), false) => {
            std::fs::create_dir_all(dir)
                .with_context(|| format!("--csv {}: cannot make the directory", dir.display()))?;
            Some(dir.as_path())
        }
        _ => None,
    };
    let report_dir = match &args.report {
        Some(dir) => {
            std::fs::create_dir_all(dir)
                .with_context(|| format!("--report {}: cannot make the directory", dir.display()))?;
            Some(dir.as_path())
        }
        None => None,
    };
    let width = (total.max(2) - 1).to_string().len();
    let csv_path = |e: &Entry| -> Option<PathBuf> {
        if single {
            return args.csv.clone();
        }
        let varied = files[e.file].as_ref().is_ok_and(CampaignFile::is_varied);
        let variant = e.variant.filter(|_| varied);
        csv_dir.map(|d| d.join(csv_name(e.index, width, &paths[e.file], variant)))
    };
    let fly = |e: &Entry| -> Done {
        let f = files[e.file].as_ref().map_err(Clone::clone)?;
        let v = e.variant.unwrap_or(0);
        let start = Instant::now();
        let flight = f.flight(v).map_err(|e| error_chain(&e))?;
        let path = csv_path(e);
        let mut writer = path.as_deref().map(crate::logs::csv::create_csv_file).transpose()?;
        if let Some(p) = &path {
            flight_meta(&flight).map_err(|e| error_chain(&e))?.write_beside(p)?;
        }
        let page_path = report_dir.map(|d| {
            let varied = files[e.file].as_ref().is_ok_and(CampaignFile::is_varied);
            let mut name = csv_name(e.index, width, &paths[e.file], e.variant.filter(|_| varied));
            if single {
                name = paths[e.file]
                    .file_stem()
                    .map_or("flight".into(), |s| s.to_string_lossy().into_owned());
                name.push_str(".csv");
            }
            d.join(name.replace(".csv", ".html"))
        });
        let meta = page_path.as_ref().map(|_| crate::logs::report::ReportMeta {
            title: paths[e.file].display().to_string(),
            source: paths[e.file].display().to_string(),
            method: "rotorpilot simulate (headless)".into(),
            rotorpilot: crate::logs::record::ROTORPILOT_VERSION.into(),
            reproduce: Some(format!("rotorpilot simulate {}", paths[e.file].display())),
            ..Default::default()
        });
        let (mut outcome, page) = flight
            .fly_with(writer.as_mut().map(|w| w as &mut dyn std::io::Write), meta)
            .map_err(|e| error_chain(&e))?;
        if let (Some(p), Some(mut page)) = (page_path, page) {
            page.meta.airframe.clone_from(&outcome_airframe(&outcome));
            std::fs::write(&p, crate::logs::report::html::page(&page))
                .map_err(|err| format!("--report {}: cannot write the page: {err}", p.display()))?;
        }
        outcome.set_wall_time_s(start.elapsed().as_secs_f64());
        Ok(outcome)
    };
    let print = |out: &mut dyn std::io::Write, e: &Entry, done: &Done| -> std::io::Result<()> {
        let values = match (&files[e.file], e.variant) {
            (Ok(f), Some(v)) => f.values(v),
            _ => Vec::new(),
        };
        let label = match (&files[e.file], e.variant) {
            (Ok(f), Some(v)) if f.is_varied() => format!("{}#{v}", paths[e.file].display()),
            _ => paths[e.file].display().to_string(),
        };
        // the text table's line carries the error (once, below); alone or
        // as JSON, stderr does
        if let Err(msg) = done
            && (single || args.json)
        {
            eprintln!("rotorpilot: {msg}");
        }
        if args.json {
            let values = JsonValues(&values);
            let line = match done {
                Ok(outcome) => serde_json::to_string(&Line {
                    index: e.index,
                    variant: e.variant,
                    values,
                    outcome,
                }),
                Err(error) => serde_json::to_string(&ErrorLine {
                    index: e.index,
                    variant: e.variant,
                    values,
                    scenario: paths[e.file].display().to_string(),
                    error,
                }),
            }
            .map_err(std::io::Error::other)?;
            writeln!(out, "{line}")
        } else if single {
            match done {
                Ok(outcome) => write!(out, "{}", outcome.to_text()),
                Err(_) => Ok(()),
            }
        } else {
            let values: String = values.iter().map(|(k, v)| format!(" {k}={}", short(v))).collect();
            let what = match done {
                Ok(outcome) => outcome.to_line(),
                // the line names the file: a message that starts with it keeps
                // only what follows (its line:column, when it has one)
                Err(msg) => format!(
                    "ERROR: {}",
                    msg.strip_prefix(&format!("{label}: "))
                        .or_else(|| msg.strip_prefix(&format!("{label}:")))
                        .unwrap_or(msg)
                ),
            };
            writeln!(out, "{:>width$} {label}{values}: {what}", e.index)
        }
    };

    let jobs = args.jobs.map_or_else(
        || std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get),
        |j| j as usize,
    );
    let threads = jobs.min(entries.len()).max(1);
    let start = Instant::now();
    let next = AtomicUsize::new(0);
    let (mut ran, mut failed, mut errors) = (0u64, 0u64, 0u64);
    let (tx, rx) = std::sync::mpsc::channel::<(usize, Done)>();
    std::thread::scope(|scope| -> anyhow::Result<()> {
        for _ in 0..threads {
            let tx = tx.clone();
            let (entries, next, fly) = (&entries, &next, &fly);
            scope.spawn(move || {
                loop {
                    let k = next.fetch_add(1, Ordering::Relaxed);
                    let Some(e) = entries.get(k) else { break };
                    // a panic is a bug, but it costs one entry, not the campaign
                    let done = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| fly(e)))
                        .unwrap_or_else(|_| Err(format!("internal error: flying entry {} panicked", e.index)));
                    if tx.send((k, done)).is_err() {
                        break;
                    }
                }
            });
        }
        drop(tx);
        // in entry order, as soon as each is done and all before it
        let stdout = std::io::stdout();
        let mut out = stdout.lock();
        let mut pending = BTreeMap::new();
        let mut want = 0;
        for (k, done) in rx {
            pending.insert(k, done);
            while let Some(done) = pending.remove(&want) {
                match &done {
                    Ok(o) if o.passed() => ran += 1,
                    Ok(_) => failed += 1,
                    Err(_) => errors += 1,
                }
                print(&mut out, &entries[want], &done).context("writing the results")?;
                out.flush().context("writing the results")?;
                want += 1;
            }
        }
        if args.json && !single {
            let closing = Closing {
                ok: ran,
                failed,
                errors,
                ..Closing::new(campaign_id, shard, total)
            };
            writeln!(out, "{}", closing.to_line()).context("writing the results")?;
        }
        Ok(())
    })?;
    if !single {
        let wall = start.elapsed().as_secs_f64();
        let n = entries.len() as u64;
        let of = if args.shard.is_some() {
            format!(" (shard {shard} of a campaign of {total})")
        } else {
            String::new()
        };
        let count = |n: u64, one, many| fleet::count(usize::try_from(n).unwrap_or(usize::MAX), one, many);
        eprintln!(
            "rotorpilot simulate: {}{of} in {wall:.3} s wall on {} ({:.1} per s): {ran} ok, {}, {}",
            count(n, "scenario", "scenarios"),
            count(threads as u64, "job", "jobs"),
            n as f64 / wall.max(1e-9),
            count(failed, "mission failed", "missions failed"),
            count(errors, "error", "errors"),
        );
    }
    Ok(exit_status(failed, errors))
}

/// A campaign's exit status: [`EXIT_BAD_SCENARIO`] when an entry could not
/// be read or flown, else [`EXIT_MISSION_FAILED`] when a mission failed its
/// verdict, else 0.
pub(super) fn exit_status(failed: u64, errors: u64) -> u8 {
    if errors > 0 {
        EXIT_BAD_SCENARIO
    } else if failed > 0 {
        EXIT_MISSION_FAILED
    } else {
        0
    }
}

/// The airframe a flight's outcome names.
fn outcome_airframe(o: &Outcome) -> String {
    match o {
        Outcome::Scenario(s) => s.airframe.clone(),
        Outcome::Mission(m) => m.airframe.clone(),
    }
}

/// The sidecar of a flight's CSV (`<csv>.meta.json`, [`crate::logs::meta::LogMeta`]).
///
/// # Errors
/// A mission whose vehicle cannot be built.
fn flight_meta(flight: &crate::scenario::campaign::Flight) -> anyhow::Result<crate::logs::meta::LogMeta> {
    use crate::scenario::campaign::Flight;
    match flight {
        Flight::Scenario(s) => Ok(crate::scenario::scenario_meta(s, "simulate")),
        Flight::Mission(m) => crate::scenario::mission_meta(m, "simulate"),
    }
}

/// The name of an entry's CSV in a campaign's `--csv` directory:
/// `NNNN-STEM.csv`, `NNNN-STEM-vK.csv` for variant K of a varied file (NNNN
/// the entry's index, zero-padded to the width of the campaign's last).
fn csv_name(index: u64, width: usize, path: &Path, variant: Option<u64>) -> String {
    let stem = path
        .file_stem()
        .map_or_else(|| "scenario".into(), |s| s.to_string_lossy().into_owned());
    match variant {
        Some(v) => format!("{index:0width$}-{stem}-v{v}.csv"),
        None => format!("{index:0width$}-{stem}.csv"),
    }
}

/// `rotorpilot simulate FLEET.toml`: fly the fleet on `--threads` threads;
/// print its summary (text: a header, a line per vehicle, a line per
/// proximity event; `--json`: one object on one line); `--csv DIR` writes
/// one `NNNN-STEM.csv` per vehicle into DIR (made if missing), each the
/// bytes its file flown alone writes. Exit status as for a campaign: 2 for
/// a fleet that cannot be read or flown, 1 when a mission vehicle failed.
/// `--report DIR` writes one page per vehicle, named as its CSV
/// (`NNNN-STEM.html`).
fn run_fleet(args: &SimulateArgs, path: &Path) -> anyhow::Result<u8> {
    let threads = args.threads.map_or(1, |t| t as usize);
    anyhow::ensure!(
        args.jobs.is_none(),
        "--jobs flies several scenarios at once; a fleet's vehicles are stepped on --threads"
    );
    let fleet = match Fleet::load(path) {
        Ok(f) => f,
        Err(e) => {
            eprintln!("rotorpilot: {}", error_chain(&e));
            return Ok(EXIT_BAD_SCENARIO);
        }
    };
    if let Some(dir) = &args.csv {
        std::fs::create_dir_all(dir).with_context(|| format!("--csv {}: cannot make the directory", dir.display()))?;
    }
    if let Some(dir) = &args.report {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("--report {}: cannot make the directory", dir.display()))?;
    }
    let meta = args.report.as_ref().map(|_| crate::logs::report::ReportMeta {
        method: "rotorpilot simulate (headless fleet)".into(),
        rotorpilot: crate::logs::record::ROTORPILOT_VERSION.into(),
        reproduce: Some(format!("rotorpilot simulate {}", path.display())),
        ..Default::default()
    });
    let start = Instant::now();
    let (mut summary, pages) = match fleet::fly_with(&fleet, threads, args.csv.as_deref(), meta.as_ref()) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("rotorpilot: {}", error_chain(&e));
            return Ok(EXIT_BAD_SCENARIO);
        }
    };
    summary.set_wall_time_s(start.elapsed().as_secs_f64());
    if let Some(dir) = &args.report {
        let n = fleet.len();
        for ((i, mut page), result) in pages.into_iter().enumerate().zip(&summary.results) {
            page.meta.airframe = outcome_airframe(&result.outcome);
            let p = dir.join(fleet::csv_name(i, n, fleet.source_of(i)).replace(".csv", ".html"));
            std::fs::write(&p, crate::logs::report::html::page(&page))
                .with_context(|| format!("--report {}: cannot write the page", p.display()))?;
        }
    }
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    if args.json {
        writeln!(out, "{}", serde_json::to_string(&summary)?).context("writing the results")?;
    } else {
        write!(out, "{}", summary.to_text()).context("writing the results")?;
    }
    out.flush().context("writing the results")?;
    Ok(if summary.passed() { 0 } else { EXIT_MISSION_FAILED })
}
