//! `rotorpilot replay RECORD [--csv OUT] [--ulog OUT] [--json] [--any-version]`: re-fly a daemon's flight
//! record headless and flat out ([`crate::logs::record`]); the CSV is byte for byte
//! the live flight's `flight.csv`, with the same sidecar `<csv>.meta.json`
//! (but for its `producer` and `source`).

use std::path::Path;

use anyhow::Context as _;

use crate::logs::record::read_record;
use crate::logs::replay::replay_logs;

/// Read, replay, report. A record written by another rotorpilot version is
/// refused (a different build cannot promise the same flight bit for bit)
/// unless `any_version`, then replayed with a warning on stderr. A record
/// without an end line (the daemon was killed) replays to its last input,
/// with a warning on stderr.
///
/// # Errors
/// An unreadable or bad record (with the file and line), a record from
/// another rotorpilot version without `any_version`, a diverging replay, a
/// CSV that cannot be written.
pub(super) fn run(
    path: &Path,
    csv: Option<&Path>,
    ulog: Option<&Path>,
    json: bool,
    any_version: bool,
) -> anyhow::Result<()> {
    let label = path.display().to_string();
    let bytes = std::fs::read(path).with_context(|| format!("cannot read {label}"))?;
    let text =
        String::from_utf8(bytes).map_err(|e| anyhow::anyhow!("{label}: not a flight record (not UTF-8: {e})"))?;
    let record = read_record(&text, &label).map_err(anyhow::Error::msg)?;
    let (written_by, this) = (&record.header.rotorpilot, crate::logs::record::ROTORPILOT_VERSION);
    if written_by != this {
        anyhow::ensure!(
            any_version,
            "{label}: written by rotorpilot {written_by}, this is rotorpilot {this}: another build cannot promise \
             the same flight bit for bit (replay it with that version, or give --any-version to try anyway)"
        );
        eprintln!(
            "rotorpilot: warning: {label} was written by rotorpilot {written_by}, this is {this} (--any-version): \
             the replay is exact only when both fly alike (every input's outcome is still checked)"
        );
    }
    if record.end.is_none() {
        eprintln!(
            "rotorpilot: warning: {label} has no end line (the daemon did not stop cleanly); replaying up to its last input"
        );
    }
    let mut writer = csv
        .map(crate::logs::csv::create_csv_file)
        .transpose()
        .map_err(anyhow::Error::msg)?;
    if let Some(csv) = csv {
        // the sidecar of the CSV: the vehicle as the record's header builds it
        let (core, _) = record
            .header
            .build()
            .map_err(|e| anyhow::anyhow!("{label}:1: header: {e}"))?;
        crate::logs::meta::autopilot_meta(core.pilot(0), "replay", &label)
            .write_beside(csv)
            .map_err(anyhow::Error::msg)?;
    }
    let mut ulog_writer = ulog
        .map(crate::logs::csv::create_csv_file)
        .transpose()
        .map_err(anyhow::Error::msg)?;
    let start = std::time::Instant::now();
    let s = replay_logs(
        &record,
        &label,
        writer.as_mut().map(|w| w as &mut dyn std::io::Write),
        ulog_writer.as_mut().map(|w| w as &mut dyn std::io::Write),
    )
    .map_err(anyhow::Error::msg)?;
    let wall_s = start.elapsed().as_secs_f64();
    let steps_per_s = s.steps as f64 / wall_s.max(1e-9);
    if json {
        let mut v = serde_json::to_value(&s)?;
        v["wall_time_s"] = wall_s.into();
        v["steps_per_s"] = steps_per_s.into();
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        let [n, e, d] = s.position_ned_m;
        println!(
            "replayed {label}: {} steps, {:.3} s simulated in {:.3} s wall ({:.0} steps/s), {} inputs{}",
            s.steps,
            s.sim_time_s,
            wall_s,
            steps_per_s,
            s.inputs,
            if s.complete { "" } else { " (no end line)" }
        );
        // the per-item summary `simulate` gives a mission
        if !s.items.is_empty() {
            println!("mission: {} items", s.items.len());
            print!("{}", crate::logs::items::item_lines(&s.items));
            println!(
                "tracking error: max {:.3} m, RMS {:.3} m",
                s.max_tracking_error_m, s.rms_tracking_error_m
            );
        }
        println!(
            "final state: {}, mode {}, {}, position NED {n:.2}, {e:.2}, {d:.2} m",
            if s.armed { "armed" } else { "disarmed" },
            s.mode,
            s.landed_state
        );
    }
    Ok(())
}
