//! Atomic replacement of the files in the state directory (`params.toml`,
//! `missions.json`): the new text goes to a hidden temporary twin in the same
//! directory (`.params.toml.<pid>.tmp`), which is flushed to disk (`fsync`),
//! renamed over the target, and the directory is synced, so a crash at any
//! point leaves either the old file or the new one, never a truncated one.
//!
//! ```no_run
//! # use std::io::Write as _;
//! # use std::path::Path;
//! rotorpilot::statefile::write_atomic(Path::new("state/params.toml"), b"MIS_TAKEOFF_ALT = 5.0\n", |f, b| {
//!     f.write_all(b)
//! })?;
//! # Ok::<(), rotorpilot::statefile::WriteError>(())
//! ```
//!
//! The file gets the permissions a new file gets (`0666` less the umask:
//! readable and writable by its owner). Pure apart from the file system: no
//! clock, no runtime.

use std::fs;
use std::path::{Path, PathBuf};

/// A state file could not be written; the old file, if any, is untouched.
#[derive(Debug, thiserror::Error)]
pub enum WriteError {
    /// Creating, writing, syncing or renaming failed.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file (or its temporary twin).
        path: PathBuf,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// The path names no file (e.g. `/` or `..`).
    #[error("{}: not a file name", .0.display())]
    NotAFile(PathBuf),
}

/// The temporary twin of `path`: same directory (so the rename is atomic),
/// hidden, per process.
///
/// # Errors
/// [`WriteError::NotAFile`].
pub fn temp_path(path: &Path) -> Result<PathBuf, WriteError> {
    let name = path
        .file_name()
        .ok_or_else(|| WriteError::NotAFile(path.to_path_buf()))?;
    let tmp_name = format!(".{}.{}.tmp", name.to_string_lossy(), std::process::id());
    Ok(path.with_file_name(tmp_name))
}

/// Write `bytes` to the temporary twin of `path` with `write`, `fsync` it,
/// rename it over `path` and `fsync` the directory (best effort: not every
/// platform can open one).
///
/// # Errors
/// Any step but the directory sync failed; the temporary file is then removed
/// and `path` keeps its old content.
pub fn write_atomic(
    path: &Path,
    bytes: &[u8],
    write: impl FnOnce(&mut fs::File, &[u8]) -> std::io::Result<()>,
) -> Result<(), WriteError> {
    let tmp = temp_path(path)?;
    let io = |p: &Path| {
        let p = p.to_path_buf();
        move |source| WriteError::Io { path: p, source }
    };
    let result = (|| {
        let mut f = fs::OpenOptions::new()
            .write(true)
            .create(true)
            .truncate(true)
            .open(&tmp)
            .map_err(io(&tmp))?;
        write(&mut f, bytes).map_err(io(&tmp))?;
        f.sync_all().map_err(io(&tmp))?;
        drop(f);
        fs::rename(&tmp, path).map_err(io(path))
    })();
    if result.is_err() {
        let _ = fs::remove_file(&tmp);
        return result;
    }
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if let Ok(d) = fs::File::open(dir) {
        let _ = d.sync_all();
    }
    Ok(())
}

/// A fresh, empty directory under the system temp dir for one unit test:
/// `rotorpilot-unit-PID-N-TAG`, unique in the process whatever the tag.
#[cfg(test)]
pub(crate) fn scratch_dir(tag: &str) -> PathBuf {
    use std::sync::atomic::{AtomicU32, Ordering};
    static N: AtomicU32 = AtomicU32::new(0);
    let n = N.fetch_add(1, Ordering::Relaxed);
    let d = std::env::temp_dir().join(format!("rotorpilot-unit-{}-{n}-{tag}", std::process::id()));
    let _ = fs::remove_dir_all(&d);
    fs::create_dir_all(&d).unwrap();
    d
}

#[cfg(test)]
mod tests {
    use std::io::Write as _;

    use super::*;

    use super::scratch_dir as scratch;

    #[test]
    fn the_writer_sees_the_temp_file_and_the_rename_leaves_only_the_target() {
        let dir = scratch("temp-rename");
        let path = dir.join("state.txt");
        let tmp = temp_path(&path).unwrap();
        assert_eq!(tmp.parent(), path.parent(), "same directory: rename is atomic");
        write_atomic(&path, b"new", |f, b| {
            assert!(tmp.exists() && !path.exists());
            f.write_all(b)
        })
        .unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"new");
        assert_eq!(fs::read_dir(&dir).unwrap().count(), 1, "no temporary file left");
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt as _;
            let mode = fs::metadata(&path).unwrap().permissions().mode();
            assert_eq!(mode & 0o600, 0o600, "owner reads and writes: {mode:o}");
        }
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_write_failing_half_way_never_replaces_the_good_file() {
        let dir = scratch("crash");
        let path = dir.join("state.txt");
        write_atomic(&path, b"good", |f, b| f.write_all(b)).unwrap();
        let err = write_atomic(&path, b"replacement", |f, b| {
            f.write_all(&b[..b.len() / 2])?;
            Err(std::io::Error::other("disk full"))
        })
        .unwrap_err();
        assert!(err.to_string().contains("disk full"), "{err}");
        assert!(err.to_string().contains(".state.txt."), "names the temp file: {err}");
        assert_eq!(fs::read(&path).unwrap(), b"good");
        assert!(!temp_path(&path).unwrap().exists(), "temp file removed");
        // A crash (no cleanup) leaves a truncated temp file; the next write replaces it.
        let tmp = temp_path(&path).unwrap();
        fs::write(&tmp, b"repl").unwrap();
        write_atomic(&path, b"replacement", |f, b| f.write_all(b)).unwrap();
        assert!(!tmp.exists());
        assert_eq!(fs::read(&path).unwrap(), b"replacement");
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn unwritable_target_is_an_error_naming_the_path() {
        let dir = scratch("unwritable");
        // a directory in the way of the rename
        let path = dir.join("state.txt");
        fs::create_dir_all(path.join("inside")).unwrap();
        let err = write_atomic(&path, b"x", |f, b| f.write_all(b)).unwrap_err();
        assert!(err.to_string().contains("state.txt"), "{err}");
        assert!(path.join("inside").exists());
        assert!(!temp_path(&path).unwrap().exists());
        assert!(matches!(
            write_atomic(Path::new("/"), b"x", |f, b| f.write_all(b)),
            Err(WriteError::NotAFile(_))
        ));
        fs::remove_dir_all(&dir).unwrap();
    }
}
