//! The `rotorpilot` binary: parse the command line and hand over to [`rotorpilot::cli`].
use clap::Parser;

fn main() -> std::process::ExitCode {
    rotorpilot::cli::run(rotorpilot::cli::Cli::parse())
}
