//! Command-line interface: `rotorpilot <command>`: parse the command line
//! and hand each command to its file (thin: the modules do the work).
//!
//! | file | command |
//! |---|---|
//! | `daemon_args` | none: the vehicle daemon (a lone vehicle or a fleet), `--check` |
//! | `simulate` | `simulate`: a scenario, a campaign, a headless fleet |
//! | `estimate` | `estimate`: the offline estimator sweep over a flight log |
//! | `merge` | `merge`: a campaign's shard outputs merged into the whole campaign's |
//! | `replay` | `replay`: a daemon's flight record re-flown |
//! | `report` | `report`: a flight's report page (one offline HTML file) |
//! | `params` | `params`: the parameter reference |
//!
//! `airframe` (the airframe report) is a few lines and stays here.

mod daemon_args;
mod estimate;
mod merge;
pub mod params;
mod replay;
mod report;
mod simulate;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

pub use daemon_args::DaemonArgs;
pub use estimate::EstimateArgs;
pub use merge::MergeArgs;
pub use simulate::SimulateArgs;

use crate::airframe::{Airframe, AirframeReport, DEFAULT_AIRFRAME};
use crate::error::error_chain;

/// rotorpilot: software-in-the-loop multirotor autopilot.
///
/// Without a command it runs one simulated vehicle that speaks MAVLink 2 over
/// UDP where PX4 SITL does (GCS link 18570+N -> 14550, API link 14580+N ->
/// 14540+N; all API links beyond instance 9 send to 14549, as PX4), until
/// Ctrl-C or SIGTERM; with --count N or --fleet FILE, a fleet of such
/// vehicles in one process on one simulated clock.
#[derive(Debug, Parser)]
#[command(name = "rotorpilot", version, about, args_conflicts_with_subcommands = true)]
pub struct Cli {
    /// What to do (none: run the vehicle).
    #[command(subcommand)]
    pub command: Option<Command>,
    /// Options of the vehicle daemon.
    #[command(flatten)]
    pub daemon: DaemonArgs,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Print an airframe's allocation matrix, ranks, degrees of freedom, hover
    /// rotor speeds and single-rotor-failure verdicts.
    Airframe {
        /// Built-in airframe name (quad, hexa, hexa-ppnnpn, octo, fsr-quad) or path to a TOML file.
        #[arg(default_value = DEFAULT_AIRFRAME)]
        airframe: String,
        /// Print one JSON object instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Fly a scenario or a mission flat out in lockstep and print a summary
    /// (for a mission: each item reached, when and how far off, and a
    /// pass/fail verdict; the exit status is 1 on fail). Several files, a
    /// directory or a [campaign] table make a campaign: flown on every core,
    /// one line per scenario, optionally one shard of it (exit status 2 when
    /// a file or variant cannot be read or flown).
    Simulate(SimulateArgs),
    /// Merge the outputs of a campaign's shards (`simulate ... --json
    /// --shard I/N`, one file per I) into the whole campaign's output, as
    /// `simulate ... --json` prints it flown at once, and exit as it would
    /// (1: a mission failed, 2: an entry could not be flown, or the shards
    /// are refused: from different campaigns, one missing or given twice, a
    /// file that is no shard's output).
    Merge(MergeArgs),
    /// Run the momentum-based estimator over a recorded flight for several
    /// orders and polynomials; write the estimates as CSV and print metrics.
    /// The nominal model is the one the log's sidecar LOG.meta.json records
    /// (docs/logs.md). Time must increase; the step may vary (each sample is
    /// integrated over its own interval).
    Estimate(EstimateArgs),
    /// Re-fly a daemon's flight record (`flight.record` in its `--log-dir`
    /// run directory) headless and flat out, bit for bit: `--csv` writes the
    /// same per-step CSV as the live flight's `flight.csv`.
    Replay {
        /// The flight record.
        record: PathBuf,
        /// Write the per-step CSV (`simulate --csv`'s format) here.
        #[arg(long)]
        csv: Option<PathBuf>,
        /// Print the summary as one JSON object.
        #[arg(long)]
        json: bool,
        /// Write the replayed flight's PX4 ULog (the topics of the daemon's
        /// `flight.ulg`) here.
        #[arg(long)]
        ulog: Option<PathBuf>,
        /// Replay a record written by another rotorpilot version (with a
        /// warning) instead of refusing it.
        #[arg(long)]
        any_version: bool,
    },
    /// Write a flight's report page: one self-contained HTML file (scripts
    /// and styles inlined; it opens offline in any browser) with the
    /// verdict, the north/east path with the mission items, geofence and
    /// rally points, altitude, speed, attitude, modes and arming, every
    /// status text, failure and failsafe at its instant, the rotor speeds and
    /// the estimated wrench and mass beside the injected truth. From a
    /// flight record (replayed exactly) or a ULog (no mission items).
    Report {
        /// The flight record (`flight.record`) or ULog (`flight.ulg`).
        input: PathBuf,
        /// The page to write.
        #[arg(short, long, value_name = "HTML")]
        output: PathBuf,
        /// The test's name for the page's title (the pytest plugin gives its node id).
        #[arg(long, value_name = "NAME")]
        test: Option<String>,
    },
    /// Print the parameter reference (every parameter: type, default, range,
    /// unit, description, values, reboot required) as text, JSON or Markdown.
    Params(params::ParamsArgs),
}

/// Run the CLI; errors are printed to stderr and give exit code 1.
#[must_use]
pub fn run(cli: Cli) -> ExitCode {
    match execute(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("rotorpilot: {}", error_chain(&e));
            ExitCode::FAILURE
        }
    }
}

fn execute(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Some(Command::Airframe { airframe, json }) => {
            let a = Airframe::load(&airframe)?;
            // the airframe file's [control] table is the control laws' to check
            crate::control::ControlGains::for_airframe(&a, a.mass_kg)
                .map_err(|e| anyhow::anyhow!("{}: {e}", a.source))?;
            let report = AirframeReport::new(&a);
            if json {
                println!("{}", serde_json::to_string_pretty(&report)?);
            } else {
                print!("{}", report.to_text());
            }
            Ok(())
        }
        Some(Command::Simulate(args)) => match simulate::main(&args) {
            0 => Ok(()),
            // 1: a mission failed its verdict, 2: a scenario could not be read or flown (printed)
            status => std::process::exit(i32::from(status)),
        },
        Some(Command::Merge(args)) => match merge::main(&args) {
            0 => Ok(()),
            // as simulate: 1 a mission failed, 2 an entry could not be flown or the shards were refused (printed)
            status => std::process::exit(i32::from(status)),
        },
        Some(Command::Estimate(args)) => estimate::run(&args),
        Some(Command::Replay {
            record,
            csv,
            ulog,
            json,
            any_version,
        }) => replay::run(&record, csv.as_deref(), ulog.as_deref(), json, any_version),
        Some(Command::Report { input, output, test }) => report::run(&input, &output, test.as_deref()),
        Some(Command::Params(args)) => params::run(&args),
        None if cli.daemon.check => {
            let fleet = cli.daemon.fleet_config()?;
            // what a real start refuses, --check refuses too
            crate::daemon::check_fleet(&fleet)?;
            print!("{}", fleet.to_text());
            Ok(())
        }
        None => daemon_args::run(&cli.daemon),
    }
}
