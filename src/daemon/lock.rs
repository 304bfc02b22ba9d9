//! One daemon per state directory: an exclusive lock on the file `lock` in
//! the vehicle's state directory, held for the daemon's life (std's
//! [`File::try_lock`]: `flock(LOCK_EX | LOCK_NB)` on Unix, released by the
//! operating system when the process ends, however it ends). The file holds
//! the holder's process id (one line) so that a second daemon can name it:
//!
//! ```text
//! rotorpilot-state/0 is in use by another rotorpilot (pid 4242): one daemon per state directory (stop it, or give this one another --instance or --state-dir)
//! ```
//!
//! The file stays behind after the daemon ends; a stale file locks nothing.
//!
//! A lock found taken is tried again for [`GRACE`] before the start is
//! refused: a process that forks (to start any program) shares its open
//! files with the child until the child's `exec` closes them, so a lock
//! released in that instant stays held for a moment by a process that never
//! wanted it (a daemon restarted in place by a test harness or supervisor).

use std::fs::{File, OpenOptions, TryLockError};
use std::io::{Read as _, Seek as _, SeekFrom, Write as _};
use std::path::Path;

use anyhow::Context as _;

/// How long a taken lock is tried again before the start is refused.
const GRACE: std::time::Duration = std::time::Duration::from_millis(500);

/// The lock file's name in a state directory.
pub(super) const LOCK_FILE: &str = "lock";

/// The exclusive lock on a state directory; released when dropped.
#[derive(Debug)]
pub(super) struct StateLock {
    /// The open, locked file (the lock lives as long as it is open).
    _file: File,
}

impl StateLock {
    /// Make `dir` (and its parents) if missing and lock it for this process.
    ///
    /// # Errors
    /// The directory cannot be made or the lock file opened (naming the
    /// path and the cause), or another daemon holds the lock (naming the
    /// directory and, if it wrote one, the holder's pid).
    pub(super) fn take(dir: &Path) -> anyhow::Result<Self> {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot make the state directory {}", dir.display()))?;
        let path = dir.join(LOCK_FILE);
        let mut file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&path)
            .with_context(|| format!("cannot open the state directory's lock file {}", path.display()))?;
        let deadline = std::time::Instant::now() + GRACE;
        let mut outcome = file.try_lock();
        while matches!(outcome, Err(TryLockError::WouldBlock)) && std::time::Instant::now() < deadline {
            std::thread::sleep(std::time::Duration::from_millis(10));
            outcome = file.try_lock();
        }
        match outcome {
            Ok(()) => {}
            Err(TryLockError::WouldBlock) => {
                let mut text = String::new();
                let _ = file.read_to_string(&mut text);
                let holder = match text.trim().parse::<u32>() {
                    Ok(pid) => format!("another rotorpilot (pid {pid})"),
                    Err(_) => "another rotorpilot".to_string(),
                };
                anyhow::bail!(
                    "{} is in use by {holder}: one daemon per state directory \
                     (stop it, or give this one another --instance or --state-dir)",
                    dir.display()
                );
            }
            Err(TryLockError::Error(e)) => {
                return Err(e).with_context(|| format!("cannot lock {}", path.display()));
            }
        }
        // ours now: say who holds it (best effort: the lock is what counts)
        let _ = file.set_len(0);
        let _ = file.seek(SeekFrom::Start(0));
        let _ = writeln!(file, "{}", std::process::id());
        let _ = file.flush();
        Ok(Self { _file: file })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::statefile::scratch_dir as scratch;

    #[test]
    fn a_second_lock_on_one_dir_is_refused_with_the_holders_pid() {
        let dir = scratch("lock-second").join("state/0");
        let first = StateLock::take(&dir).unwrap();
        let err = StateLock::take(&dir).unwrap_err().to_string();
        assert!(
            err.starts_with(&format!(
                "{} is in use by another rotorpilot (pid {})",
                dir.display(),
                std::process::id()
            )),
            "{err}"
        );
        drop(first);
        StateLock::take(&dir).expect("free again once the first is dropped");
    }

    /// A lock released within [`GRACE`] (here: a holder that lets go after
    /// 100 ms, as a forked child lets go at its exec) is taken, not refused.
    #[test]
    fn a_lock_released_within_the_grace_is_taken() {
        let dir = scratch("lock-grace").join("state/0");
        let first = StateLock::take(&dir).unwrap();
        let holder = std::thread::spawn(move || {
            std::thread::sleep(std::time::Duration::from_millis(100));
            drop(first);
        });
        StateLock::take(&dir).expect("taken once the holder lets go");
        holder.join().unwrap();
    }

    #[test]
    fn a_state_dir_below_a_file_names_the_dir_and_the_cause_once() {
        let file = scratch("lock-below-file").join("afile");
        std::fs::write(&file, "x").unwrap();
        let err = StateLock::take(&file.join("sub")).unwrap_err();
        let text = format!("{err:#}");
        assert_eq!(
            text,
            format!(
                "cannot make the state directory {}: Not a directory (os error 20)",
                file.join("sub").display()
            )
        );
    }
}
