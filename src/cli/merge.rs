//! `rotorpilot merge SHARD...`: the outputs of a campaign's shards
//! (`rotorpilot simulate ... --json --shard I/N > shard-I.jsonl`, one per
//! `I = 0..N`) merged into the output of the whole campaign, as
//! `rotorpilot simulate ... --json` prints it flown at once (the merge
//! itself: [`crate::scenario::shards`]).
//!
//! Prints the merged output on stdout; on stderr each entry that failed its
//! verdict or could not be flown, and a tally. Exit status as the whole
//! campaign's: 0; 1 when a mission failed its verdict; 2 when an entry could
//! not be read or flown, or when the shards are refused (the reason, naming
//! the file, line and field, on stderr; nothing on stdout).

use std::io::Write as _;
use std::path::PathBuf;

use anyhow::Context as _;

use super::simulate::{EXIT_BAD_SCENARIO, exit_status};
use crate::error::error_chain;
use crate::scenario::shards;

/// The arguments of `rotorpilot merge`.
#[derive(Debug, Clone, clap::Args)]
pub struct MergeArgs {
    /// The output of each shard: what `rotorpilot simulate ... --json
    /// --shard I/N` printed, one file per I (in any order).
    #[arg(required = true, value_name = "SHARD")]
    pub shards: Vec<PathBuf>,
}

/// Run `rotorpilot merge`; the exit status (module doc).
#[must_use]
pub(super) fn main(args: &MergeArgs) -> u8 {
    run(args).unwrap_or_else(|e| {
        eprintln!("rotorpilot: {}", error_chain(&e));
        EXIT_BAD_SCENARIO
    })
}

fn run(args: &MergeArgs) -> anyhow::Result<u8> {
    let outputs = args
        .shards
        .iter()
        .map(|p| {
            let name = p.display().to_string();
            std::fs::read_to_string(p)
                .with_context(|| format!("{name}: cannot read"))
                .map(|text| (name, text))
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let merged = shards::merge(&outputs).map_err(|e| anyhow::anyhow!("merge refused: {e}"))?;
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    out.write_all(merged.text.as_bytes())
        .and_then(|()| out.flush())
        .context("writing the merged output")?;
    for (index, line) in &merged.problems {
        eprintln!("rotorpilot merge: entry {index}: {line}");
    }
    let c = &merged.closing;
    eprintln!(
        "rotorpilot merge: {} scenarios from {} shards of campaign {}: {} ok, {} missions failed, {} errors",
        c.entries,
        outputs.len(),
        c.campaign,
        c.ok,
        c.failed,
        c.errors
    );
    Ok(exit_status(c.failed, c.errors))
}
