//! `rotorpilot report RECORD-or-ULOG -o flight.html [--test NAME]`: the
//! flight report page ([`crate::logs::report`]): one self-contained HTML
//! file that opens offline. A flight record is replayed exactly (the full
//! state at every step); a ULog is read topic by topic (no mission items).

use std::path::Path;

use anyhow::Context as _;

use crate::logs::record::read_record;
use crate::logs::report::{self, FlightReport};
use crate::logs::ulog::MAGIC;

/// Read `input` (a flight record or a ULog, told apart by the ULog magic),
/// build its page and write it to `out`; one line on stdout says what was
/// written.
///
/// # Errors
/// An unreadable or bad input (with the file and line), a record from
/// another rotorpilot version (it would not replay bit for bit), a page that
/// cannot be written.
pub(super) fn run(input: &Path, out: &Path, test: Option<&str>) -> anyhow::Result<()> {
    let start = std::time::Instant::now();
    let r = build(input, test)?;
    let page = report::html::page(&r);
    std::fs::write(out, &page).with_context(|| format!("-o {}: cannot write the page", out.display()))?;
    println!(
        "wrote {} ({:.1} MB, {} samples over {:.1} s, {} events) in {:.2} s",
        out.display(),
        page.len() as f64 / 1e6,
        report::html::samples(&r.series),
        r.duration_s,
        r.events.len(),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

/// The report's data of `input`.
fn build(input: &Path, test: Option<&str>) -> anyhow::Result<FlightReport> {
    let label = input.display().to_string();
    let bytes = std::fs::read(input).with_context(|| format!("cannot read {label}"))?;
    if bytes.starts_with(&MAGIC[..7]) {
        return report::from_ulog(&bytes, &label, test).map_err(anyhow::Error::msg);
    }
    let text = String::from_utf8(bytes)
        .map_err(|_| anyhow::anyhow!("{label}: neither a flight record (JSON Lines) nor a ULog (no ULog magic)"))?;
    let record = read_record(&text, &label).map_err(anyhow::Error::msg)?;
    let (written_by, this) = (&record.header.rotorpilot, crate::logs::record::ROTORPILOT_VERSION);
    anyhow::ensure!(
        written_by == this,
        "{label}: written by rotorpilot {written_by}, this is rotorpilot {this}: the page replays the record, which \
         only that version flies bit for bit (use that version, or give the flight's ULog)"
    );
    let meta = report::ReportMeta {
        title: test.map_or_else(|| label.clone(), str::to_string),
        test: test.map(str::to_string),
        source: label.clone(),
        method: "flight record, replayed exactly".into(),
        rotorpilot: record.header.rotorpilot.clone(),
        reproduce: Some(format!("rotorpilot replay {label}")),
        ..report::ReportMeta::default()
    };
    crate::logs::replay::replay_report(&record, &label, meta).map_err(anyhow::Error::msg)
}
