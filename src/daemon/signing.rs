//! The vehicle's MAVLink signing key on disk (the protocol side is
//! [`crate::link::signing`]): `signing.key` in the state directory, 40 bytes
//! as PX4 keeps `mavlink/mavlink-signing-key.bin` (the 32-byte key, then the
//! last signing timestamp as a little-endian u64 [10 µs since 2015]). An
//! all-zero key means signing is off (a cleared key keeps its timestamp).
//!
//! - read at bind, for every vehicle (each its own state directory): no file,
//!   no key; a file that does not read, or is not 40 bytes, stops the start
//!   with an error naming it (never silently unsigned);
//! - written atomically (`crate::statefile`) with owner-only permissions
//!   (0600) when SETUP_SIGNING changes the key, every
//!   [`PERSIST_INTERVAL`] while a key is set (the timestamp, so that it
//!   stays monotonic across restarts), and at shutdown;
//! - never a parameter: the key is in no PARAM list.

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Instant, SystemTime, UNIX_EPOCH};

use anyhow::Context as _;
use tokio::sync::{Notify, watch};
use tracing::{debug, info, warn};

use crate::link::signing::{PERSIST_INTERVAL, Shared, Signing, Stored, lock, timestamp_from_unix_us};

/// The key file's name in the state directory.
pub(super) const FILE_NAME: &str = "signing.key";

/// A vehicle's signing state, its file, and the trigger to write it.
#[derive(Clone, Debug)]
pub(super) struct VehicleSigning {
    /// Shared with every link of the vehicle ([`crate::link::Link::set_signing`]).
    pub(super) shared: Shared,
    path: PathBuf,
    /// Notified on [`crate::link::Effect::SigningKeyChanged`].
    pub(super) changed: Arc<Notify>,
}

/// Our signing clock now [10 µs since 2015].
fn clock_now() -> u64 {
    let us = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_micros()).unwrap_or(u64::MAX));
    timestamp_from_unix_us(us)
}

/// Read `state_dir/signing.key` (none: signing off).
///
/// # Errors
/// The file exists but cannot be read or is not 40 bytes.
pub(super) fn load(state_dir: &Path) -> anyhow::Result<VehicleSigning> {
    let path = state_dir.join(FILE_NAME);
    let now = Instant::now();
    let signing = match std::fs::read(&path) {
        Ok(bytes) => {
            let stored = Stored::from_bytes(&bytes).map_err(|e| {
                anyhow::anyhow!(
                    "{}: not a signing key file: {e} (remove it to start without signing, \
                     then set the key again with SETUP_SIGNING)",
                    path.display()
                )
            })?;
            let s = Signing::restored(stored, now, clock_now());
            if s.is_keyed() {
                info!(path = %path.display(), "MAVLink signing key loaded: unsigned frames are refused");
            }
            s
        }
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Signing::unkeyed(now, clock_now()),
        Err(e) => return Err(e).with_context(|| format!("cannot read the signing key {}", path.display())),
    };
    Ok(VehicleSigning {
        shared: Arc::new(Mutex::new(signing)),
        path,
        changed: Arc::new(Notify::new()),
    })
}

/// Write `stored` to `path` atomically, owner-only (0600).
fn write(path: &Path, stored: Stored) -> anyhow::Result<()> {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    crate::statefile::write_atomic(path, &stored.to_bytes(), |f, b| {
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt as _;
            f.set_permissions(std::fs::Permissions::from_mode(0o600))?;
        }
        f.write_all(b)
    })?;
    Ok(())
}

impl VehicleSigning {
    /// Write the file if there is a key, or a file to update (a cleared key).
    fn save(&self) -> anyhow::Result<()> {
        let (keyed, stored) = {
            let s = lock(&self.shared);
            (s.is_keyed(), s.stored(Instant::now()))
        };
        if keyed || self.path.exists() {
            write(&self.path, stored)?;
            debug!(path = %self.path.display(), "signing key saved");
        }
        Ok(())
    }
}

/// Write the key file when notified, every [`PERSIST_INTERVAL`], and once
/// more when `stop` changes.
pub(super) async fn persist(v: VehicleSigning, mut stop: watch::Receiver<bool>) {
    loop {
        let stopping = tokio::select! {
            () = v.changed.notified() => false,
            () = tokio::time::sleep(PERSIST_INTERVAL) => false,
            _ = stop.changed() => true,
        };
        let w = v.clone();
        match tokio::task::spawn_blocking(move || w.save()).await {
            Ok(Ok(())) => {}
            Ok(Err(e)) => warn!("cannot save the signing key: {e:#}"),
            Err(e) => warn!(error = %e, "signing key saver failed"),
        }
        if stopping {
            return;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::signing::KEY_LEN;
    use crate::statefile::scratch_dir as scratch;

    #[test]
    fn no_file_is_no_key_and_a_bad_file_is_an_error_naming_it() {
        let d = scratch("signing-bad");
        let v = load(&d).unwrap();
        assert!(!lock(&v.shared).is_keyed());
        // nothing written without a key
        v.save().unwrap();
        assert!(!d.join(FILE_NAME).exists());
        std::fs::write(d.join(FILE_NAME), b"short").unwrap();
        let e = format!("{:#}", load(&d).unwrap_err());
        assert!(e.contains("signing.key") && e.contains("5 bytes"), "{e}");
    }

    #[test]
    fn a_key_is_written_0600_and_read_back_with_a_later_timestamp() {
        let d = scratch("signing-rw");
        let v = load(&d).unwrap();
        lock(&v.shared).setup([4; KEY_LEN], 0);
        v.save().unwrap();
        let path = d.join(FILE_NAME);
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt as _;
            assert_eq!(std::fs::metadata(&path).unwrap().permissions().mode() & 0o777, 0o600);
        }
        let first = Stored::from_bytes(&std::fs::read(&path).unwrap()).unwrap();
        assert_eq!(first.key, [4; KEY_LEN]);
        assert!(first.timestamp >= clock_now() - 100_000, "the clock, not 0");
        let again = load(&d).unwrap();
        let s = lock(&again.shared);
        assert!(s.is_keyed());
        assert!(s.timestamp() > first.timestamp);
    }
}
