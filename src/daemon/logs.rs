//! The run's log directory (`--log-dir DIR`): each start of the daemon
//! writes into a new directory `DIR/YYYY-MM-DDTHH-MM-SSZ-iN` (UTC start
//! time, instance N; `_2`, `_3`, ... when that name is taken), as PX4 puts
//! each log in a dated directory. It holds the flight record, the ULog, one
//! `.tlog` per link and, with `--log-csv`, the flight CSV.

use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

use anyhow::Context as _;

/// Create this run's directory below `base` (creating `base` too).
///
/// # Errors
/// `base` or the run directory cannot be created (read-only, not a
/// directory), with the path in the message.
pub(super) fn create_run_dir(base: &Path, instance: u8) -> anyhow::Result<PathBuf> {
    std::fs::create_dir_all(base).with_context(|| format!("--log-dir: cannot create {}", base.display()))?;
    let secs = SystemTime::now().duration_since(UNIX_EPOCH).map_or(0, |d| d.as_secs());
    let stem = format!("{}-i{instance}", utc_stamp(secs));
    for k in 1..1000 {
        let name = if k == 1 { stem.clone() } else { format!("{stem}_{k}") };
        let dir = base.join(name);
        match std::fs::create_dir(&dir) {
            Ok(()) => return Ok(dir),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
            Err(e) => return Err(e).with_context(|| format!("--log-dir: cannot create {}", dir.display())),
        }
    }
    anyhow::bail!("--log-dir: {} holds 999 runs started this second", base.display())
}

/// `YYYY-MM-DDTHH-MM-SSZ` for seconds since the Unix epoch (UTC; the
/// civil-from-days algorithm of H. Hinnant).
fn utc_stamp(secs: u64) -> String {
    let days = i64::try_from(secs / 86_400).unwrap_or(0);
    let rem = secs % 86_400;
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}-{month:02}-{day:02}T{:02}-{:02}-{:02}Z",
        rem / 3600,
        rem % 3600 / 60,
        rem % 60
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn utc_stamps() {
        assert_eq!(utc_stamp(0), "1970-01-01T00-00-00Z");
        // 2026-12-02 03:08:14 UTC
        assert_eq!(utc_stamp(1_796_180_894), "2026-12-02T03-08-14Z");
        // 2024-02-29 23:59:59 UTC (leap day)
        assert_eq!(utc_stamp(1_709_251_199), "2024-02-29T23-59-59Z");
    }

    #[test]
    fn run_dirs_do_not_collide() {
        let base = std::env::temp_dir().join(format!("rotorpilot-logs-test-{}", std::process::id()));
        let a = create_run_dir(&base, 3).unwrap();
        let b = create_run_dir(&base, 3).unwrap();
        assert_ne!(a, b);
        assert!(
            a.file_name().unwrap().to_string_lossy().ends_with("-i3")
                || b.file_name().unwrap().to_string_lossy().contains("-i3")
        );
        std::fs::remove_dir_all(&base).unwrap();
    }
}
