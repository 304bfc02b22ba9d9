//! Command-line interface: `rotorpilot <command>`.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

use crate::airframe::{Airframe, AirframeReport, DEFAULT_AIRFRAME};

/// rotorpilot: software-in-the-loop multirotor autopilot.
#[derive(Debug, Parser)]
#[command(name = "rotorpilot", version, about)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Option<Command>,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Print an airframe's allocation matrix, ranks, degrees of freedom, hover
    /// rotor speeds and single-rotor-failure verdicts.
    Airframe {
        /// Built-in airframe name (quad, hexa, octo, fsr-quad) or path to a TOML file.
        #[arg(default_value = DEFAULT_AIRFRAME)]
        airframe: String,
        /// Print one JSON object instead of text.
        #[arg(long)]
        json: bool,
    },
}

/// Run the CLI; errors are printed to stderr and give exit code 1.
#[must_use]
pub fn run(cli: Cli) -> ExitCode {
    match execute(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("rotorpilot: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn execute(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Some(Command::Airframe { airframe, json }) => {
            let a = Airframe::load(&airframe)?;
            let report = AirframeReport::new(&a);
            if json {
                println!("{}", serde_json::to_string_pretty(&report)?);
            } else {
                print!("{}", report.to_text());
            }
            Ok(())
        }
        None => {
            anyhow::bail!("no command given; try `rotorpilot --help` (the MAVLink daemon is not built yet)")
        }
    }
}
