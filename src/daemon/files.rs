//! The files a vehicle serves by MAVLink FTP and log download
//! ([`crate::link::ftp::FileStore`]), as PX4 SITL's root directory looks to
//! a client: `/` is the vehicle's state directory (its parameter and plan
//! files, read-only; the signing key and the lock are neither listed nor
//! reachable) plus `log/`, the ULogs `--log-dir` wrote for this vehicle
//! under PX4's names, `log/YYYY-MM-DD/HH_MM_SS.ulg` (UTC start; `_2`, ...
//! when two runs started in one second). `/fs/microsd/` (a flight
//! controller's SD card) is an alias of `/`. Logs are read-only but for
//! LOG_ERASE, which removes every finished log.
//!
//! Bounds: no path reaches outside the state directory and the log
//! directory (`..` refused, symbolic links not followed out), a client's
//! file is at most [`MAX_FILE`] bytes and the client's files together at
//! most [`MAX_TOTAL`]; a write past either is refused (EFBIG, ENOSPC).

use std::fs;
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::time::UNIX_EPOCH;

use crate::link::ftp::{DirEntry, FileStore, FsError, LogFile, errno};

/// The largest file a client may write [bytes].
pub(super) const MAX_FILE: u64 = 1 << 20;
/// What a client's files in the state directory may hold together [bytes].
pub(super) const MAX_TOTAL: u64 = 16 << 20;
/// Files the daemon owns in the state directory: read-only to a client.
const DAEMON_FILES: [&str; 2] = ["params.toml", "missions.json"];
/// Never listed, read or written.
const HIDDEN: [&str; 2] = [super::signing::FILE_NAME, super::lock::LOCK_FILE];
/// Directory entries listed at most.
const MAX_ENTRIES: usize = 1000;

/// One vehicle's files.
#[derive(Debug)]
pub(super) struct VehicleFiles {
    state_dir: PathBuf,
    /// `--log-dir` and the instance whose runs are this vehicle's.
    logs: Option<(PathBuf, u8)>,
    /// This run's directory (its ULog is being written: never erased).
    current_run: Option<PathBuf>,
}

/// Where an FTP path leads.
#[derive(Debug, PartialEq, Eq)]
enum Place {
    /// A path in the state directory (relative parts).
    State(Vec<String>),
    /// `log/`.
    LogRoot,
    /// `log/DATE/`.
    LogDay(String),
    /// `log/DATE/NAME.ulg`.
    Log(String, String),
}

fn io(e: &std::io::Error) -> FsError {
    match e.kind() {
        std::io::ErrorKind::NotFound => FsError::NotFound,
        std::io::ErrorKind::AlreadyExists => FsError::Exists,
        std::io::ErrorKind::PermissionDenied => FsError::Protected,
        _ => FsError::Errno(
            e.raw_os_error()
                .and_then(|n| u8::try_from(n).ok())
                .unwrap_or(errno::EIO),
        ),
    }
}

/// `(date, name)` for run directory `YYYY-MM-DDTHH-MM-SSZ-iN[_k]` of
/// `instance`: `("YYYY-MM-DD", "HH_MM_SS[_k].ulg")`.
fn log_name(run: &str, instance: u8) -> Option<(String, String)> {
    let (stamp, rest) = run.split_at_checked(20)?;
    let (inst, k) = match rest.strip_prefix("-i")?.split_once('_') {
        Some((i, k)) => (i, Some(k)),
        None => (rest.strip_prefix("-i")?, None),
    };
    if inst.parse::<u8>().ok()? != instance || !stamp.ends_with('Z') || stamp.as_bytes().get(10) != Some(&b'T') {
        return None;
    }
    let date = &stamp[..10];
    let time = stamp[11..19].replace('-', "_");
    let name = match k {
        Some(k) => format!("{time}_{k}.ulg"),
        None => format!("{time}.ulg"),
    };
    Some((date.to_string(), name))
}

impl VehicleFiles {
    /// The files of the vehicle with `state_dir`, and with `--log-dir`
    /// `logs` (base and instance) whose run now writes into `current_run`.
    pub(super) fn new(state_dir: PathBuf, logs: Option<(PathBuf, u8)>, current_run: Option<PathBuf>) -> Self {
        Self {
            state_dir,
            logs,
            current_run,
        }
    }

    /// Where `path` leads; `Protected` for `..` or a hidden file.
    fn place(path: &str) -> Result<Place, FsError> {
        let mut parts: Vec<String> = Vec::new();
        for p in path.split('/') {
            match p {
                "" | "." => {}
                ".." => return Err(FsError::Protected),
                p if p.contains('\\') || p.contains('\0') => return Err(FsError::Protected),
                p => parts.push(p.to_string()),
            }
        }
        if parts.len() >= 2 && parts[0] == "fs" && parts[1] == "microsd" {
            parts.drain(..2);
        }
        if parts.first().is_some_and(|p| HIDDEN.contains(&p.as_str())) {
            return Err(FsError::Protected);
        }
        Ok(match parts.first().map(String::as_str) {
            Some("log") => match parts.len() {
                1 => Place::LogRoot,
                2 => Place::LogDay(parts[1].clone()),
                3 => Place::Log(parts[1].clone(), parts[2].clone()),
                _ => return Err(FsError::NotFound),
            },
            _ => Place::State(parts),
        })
    }

    /// A state-directory path, refused if a symbolic link would lead out.
    fn state_path(&self, parts: &[String]) -> Result<PathBuf, FsError> {
        let mut p = self.state_dir.clone();
        for part in parts {
            p.push(part);
            if fs::symlink_metadata(&p).is_ok_and(|m| m.file_type().is_symlink()) {
                return Err(FsError::Protected);
            }
        }
        Ok(p)
    }

    /// A path a client may change: in the state directory, not the daemon's own files.
    fn writable(&self, path: &str) -> Result<PathBuf, FsError> {
        match Self::place(path)? {
            Place::State(parts) if !parts.is_empty() => {
                if parts.len() == 1 && DAEMON_FILES.contains(&parts[0].as_str()) {
                    return Err(FsError::Protected);
                }
                self.state_path(&parts)
            }
            _ => Err(FsError::Protected),
        }
    }

    /// This vehicle's runs: `(date, name, run directory)`, oldest first.
    fn runs(&self) -> Vec<(String, String, PathBuf)> {
        let Some((base, instance)) = &self.logs else {
            return Vec::new();
        };
        let Ok(dir) = fs::read_dir(base) else {
            return Vec::new();
        };
        let mut runs: Vec<_> = dir
            .filter_map(Result::ok)
            .take(100_000)
            .filter_map(|e| {
                let name = e.file_name().into_string().ok()?;
                let (date, file) = log_name(&name, *instance)?;
                let run = e.path();
                run.join(super::ulog_file::FILE_NAME)
                    .is_file()
                    .then_some((date, file, run))
            })
            .collect();
        runs.sort_by(|a, b| (&a.0, &a.1).cmp(&(&b.0, &b.1)));
        runs
    }

    /// The file a readable path names.
    fn readable(&self, path: &str) -> Result<PathBuf, FsError> {
        match Self::place(path)? {
            Place::State(parts) => self.state_path(&parts),
            Place::Log(date, name) => self
                .runs()
                .into_iter()
                .find(|r| r.0 == date && r.1 == name)
                .map(|r| r.2.join(super::ulog_file::FILE_NAME))
                .ok_or(FsError::NotFound),
            Place::LogRoot | Place::LogDay(_) => Err(FsError::Errno(errno::EISDIR)),
        }
    }

    /// Bytes in the client's files (the state directory but the daemon's).
    fn client_bytes(&self) -> u64 {
        fn walk(dir: &Path, depth: usize, top: bool) -> u64 {
            let Ok(rd) = fs::read_dir(dir) else { return 0 };
            rd.filter_map(Result::ok)
                .take(MAX_ENTRIES)
                .map(|e| {
                    let name = e.file_name();
                    let daemon = top
                        && name
                            .to_str()
                            .is_some_and(|n| DAEMON_FILES.contains(&n) || HIDDEN.contains(&n));
                    match e.file_type() {
                        Ok(t) if t.is_file() && !daemon => e.metadata().map_or(0, |m| m.len()),
                        Ok(t) if t.is_dir() && depth < 8 => walk(&e.path(), depth + 1, false),
                        _ => 0,
                    }
                })
                .sum()
        }
        walk(&self.state_dir, 0, true)
    }

    /// Whether a file may grow from `old` to `new` bytes.
    fn room(&self, old: u64, new: u64) -> Result<(), FsError> {
        if new > MAX_FILE {
            return Err(FsError::Errno(errno::EFBIG));
        }
        if new > old && self.client_bytes() + (new - old) > MAX_TOTAL {
            return Err(FsError::Errno(errno::ENOSPC));
        }
        Ok(())
    }
}

impl FileStore for VehicleFiles {
    fn list(&self, path: &str) -> Result<Vec<DirEntry>, FsError> {
        match Self::place(path)? {
            Place::State(parts) => {
                let dir = self.state_path(&parts)?;
                let rd = fs::read_dir(&dir).map_err(|e| io(&e))?;
                let mut out: Vec<DirEntry> = Vec::new();
                if parts.is_empty() {
                    out.push(DirEntry::Dir("log".into()));
                }
                let mut names: Vec<_> = rd
                    .filter_map(Result::ok)
                    .take(MAX_ENTRIES)
                    .filter_map(|e| {
                        Some((
                            e.file_name().into_string().ok()?,
                            e.file_type().ok()?,
                            e.metadata().ok()?,
                        ))
                    })
                    .filter(|(n, _, _)| !(parts.is_empty() && (HIDDEN.contains(&n.as_str()) || n == "log")))
                    .collect();
                names.sort_by(|a, b| a.0.cmp(&b.0));
                for (name, t, m) in names {
                    if t.is_file() {
                        out.push(DirEntry::File(name, u32::try_from(m.len()).unwrap_or(u32::MAX)));
                    } else if t.is_dir() {
                        out.push(DirEntry::Dir(name));
                    }
                }
                Ok(out)
            }
            Place::LogRoot => {
                let mut days: Vec<String> = self.runs().into_iter().map(|r| r.0).collect();
                days.dedup();
                Ok(days.into_iter().map(DirEntry::Dir).collect())
            }
            Place::LogDay(day) => {
                let files: Vec<DirEntry> = self
                    .runs()
                    .into_iter()
                    .filter(|r| r.0 == day)
                    .map(|r| {
                        let size = fs::metadata(r.2.join(super::ulog_file::FILE_NAME)).map_or(0, |m| m.len());
                        DirEntry::File(r.1, u32::try_from(size).unwrap_or(u32::MAX))
                    })
                    .collect();
                if files.is_empty() {
                    return Err(FsError::NotFound);
                }
                Ok(files)
            }
            Place::Log(..) => Err(FsError::Errno(errno::ENOTDIR)),
        }
    }

    fn size(&self, path: &str) -> Result<u32, FsError> {
        let p = self.readable(path)?;
        let m = fs::metadata(&p).map_err(|e| io(&e))?;
        if m.is_dir() {
            return Err(FsError::Errno(errno::EISDIR));
        }
        Ok(u32::try_from(m.len()).unwrap_or(u32::MAX))
    }

    fn read_at(&self, path: &str, offset: u32, buf: &mut [u8]) -> Result<usize, FsError> {
        let p = self.readable(path)?;
        let mut f = fs::File::open(&p).map_err(|e| io(&e))?;
        f.seek(SeekFrom::Start(u64::from(offset))).map_err(|e| io(&e))?;
        let mut n = 0;
        while n < buf.len() {
            match f.read(&mut buf[n..]) {
                Ok(0) => break,
                Ok(k) => n += k,
                Err(e) => return Err(io(&e)),
            }
        }
        Ok(n)
    }

    fn create(&mut self, path: &str, truncate: bool) -> Result<u32, FsError> {
        let p = self.writable(path)?;
        let f = fs::OpenOptions::new()
            .create(true)
            .write(true)
            .truncate(truncate)
            .open(&p)
            .map_err(|e| io(&e))?;
        let len = f.metadata().map_err(|e| io(&e))?.len();
        Ok(u32::try_from(len).unwrap_or(u32::MAX))
    }

    fn write_at(&mut self, path: &str, offset: u32, data: &[u8]) -> Result<usize, FsError> {
        let p = self.writable(path)?;
        let old = fs::metadata(&p).map_err(|e| io(&e))?.len();
        self.room(old, old.max(u64::from(offset) + data.len() as u64))?;
        let mut f = fs::OpenOptions::new().write(true).open(&p).map_err(|e| io(&e))?;
        f.seek(SeekFrom::Start(u64::from(offset))).map_err(|e| io(&e))?;
        f.write_all(data).map_err(|e| io(&e))?;
        Ok(data.len())
    }

    fn remove_file(&mut self, path: &str) -> Result<(), FsError> {
        let p = self.writable(path)?;
        fs::remove_file(&p).map_err(|e| io(&e))
    }

    fn create_dir(&mut self, path: &str) -> Result<(), FsError> {
        let p = self.writable(path)?;
        fs::create_dir(&p).map_err(|e| io(&e))
    }

    fn remove_dir(&mut self, path: &str) -> Result<(), FsError> {
        let p = self.writable(path)?;
        fs::remove_dir(&p).map_err(|e| match e.kind() {
            std::io::ErrorKind::DirectoryNotEmpty => FsError::Errno(errno::ENOTEMPTY),
            _ => io(&e),
        })
    }

    fn rename(&mut self, from: &str, to: &str) -> Result<(), FsError> {
        let a = self.writable(from)?;
        let b = self.writable(to)?;
        fs::rename(&a, &b).map_err(|e| io(&e))
    }

    fn truncate(&mut self, path: &str, len: u32) -> Result<(), FsError> {
        let p = self.writable(path)?;
        let old = fs::metadata(&p).map_err(|e| io(&e))?.len();
        self.room(old, u64::from(len))?;
        let f = fs::OpenOptions::new().write(true).open(&p).map_err(|e| io(&e))?;
        f.set_len(u64::from(len)).map_err(|e| io(&e))
    }

    fn logs(&self) -> Vec<LogFile> {
        self.runs()
            .into_iter()
            .filter_map(|(date, name, run)| {
                let m = fs::metadata(run.join(super::ulog_file::FILE_NAME)).ok()?;
                let mtime = m.modified().ok()?.duration_since(UNIX_EPOCH).ok()?.as_secs();
                Some(LogFile {
                    path: format!("/log/{date}/{name}"),
                    size: u32::try_from(m.len()).unwrap_or(u32::MAX),
                    time_utc: u32::try_from(mtime).unwrap_or(u32::MAX),
                })
            })
            .collect()
    }

    fn erase_logs(&mut self) {
        for (_, _, run) in self.runs() {
            if Some(&run) == self.current_run.as_ref() {
                continue;
            }
            if let Err(e) = fs::remove_dir_all(&run) {
                tracing::warn!(run = %run.display(), error = %e, "LOG_ERASE: cannot remove the run");
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("rotorpilot-files-{name}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&d);
        fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn run_directories_get_px4s_log_names() {
        assert_eq!(
            log_name("2026-12-03T18-14-46Z-i0", 0),
            Some(("2026-12-03".into(), "18_14_46.ulg".into()))
        );
        assert_eq!(
            log_name("2026-12-03T18-14-46Z-i2_3", 2),
            Some(("2026-12-03".into(), "18_14_46_3.ulg".into()))
        );
        assert_eq!(log_name("2026-12-03T18-14-46Z-i1", 0), None, "another vehicle's");
        assert_eq!(log_name("notes", 0), None);
    }

    #[test]
    fn no_path_leads_out_and_the_daemons_files_are_read_only() {
        let root = scratch("bounds");
        let state = root.join("state");
        fs::create_dir_all(&state).unwrap();
        fs::write(state.join("params.toml"), "x").unwrap();
        fs::write(state.join(super::super::signing::FILE_NAME), [0u8; 40]).unwrap();
        fs::write(root.join("secret"), "s").unwrap();
        std::os::unix::fs::symlink(&root, state.join("up")).unwrap();
        let mut f = VehicleFiles::new(state.clone(), None, None);
        let names: Vec<_> = f.list("/").unwrap();
        assert_eq!(
            names,
            vec![DirEntry::Dir("log".into()), DirEntry::File("params.toml".into(), 1)]
        );
        assert_eq!(f.size("/params.toml"), Ok(1));
        assert_eq!(f.size("/fs/microsd/params.toml"), Ok(1));
        assert_eq!(f.size("/../secret"), Err(FsError::Protected));
        assert_eq!(f.size("/up/secret"), Err(FsError::Protected));
        assert_eq!(f.size("/signing.key"), Err(FsError::Protected));
        assert_eq!(f.create("/params.toml", true), Err(FsError::Protected));
        assert_eq!(f.create("/log/x.ulg", true), Err(FsError::Protected));
        assert_eq!(f.create("/mine.txt", true), Ok(0));
        assert_eq!(f.write_at("/mine.txt", 0, b"abc"), Ok(3));
        assert_eq!(
            f.write_at("/mine.txt", MAX_FILE as u32, b"x"),
            Err(FsError::Errno(errno::EFBIG))
        );
        assert_eq!(f.remove_file("/mine.txt"), Ok(()));
        assert_eq!(fs::read_to_string(root.join("secret")).unwrap(), "s");
        fs::remove_dir_all(&root).unwrap();
    }

    #[test]
    fn the_logs_are_this_vehicles_runs_and_erase_keeps_the_current_one() {
        let root = scratch("logs");
        let base = root.join("logs");
        for run in [
            "2026-12-03T18-00-00Z-i0",
            "2026-12-03T18-05-00Z-i0",
            "2026-12-03T18-05-00Z-i1",
        ] {
            fs::create_dir_all(base.join(run)).unwrap();
            fs::write(base.join(run).join(super::super::ulog_file::FILE_NAME), run).unwrap();
        }
        let current = base.join("2026-12-03T18-05-00Z-i0");
        let mut f = VehicleFiles::new(root.join("state"), Some((base.clone(), 0)), Some(current.clone()));
        let logs = f.logs();
        let paths: Vec<_> = logs.iter().map(|l| l.path.as_str()).collect();
        assert_eq!(paths, ["/log/2026-12-03/18_00_00.ulg", "/log/2026-12-03/18_05_00.ulg"]);
        assert_eq!(f.list("/log").unwrap(), vec![DirEntry::Dir("2026-12-03".into())]);
        let mut buf = [0u8; 64];
        let n = f.read_at("/log/2026-12-03/18_00_00.ulg", 0, &mut buf).unwrap();
        assert_eq!(&buf[..n], b"2026-12-03T18-00-00Z-i0");
        f.erase_logs();
        assert_eq!(f.logs().len(), 1);
        assert!(current.exists() && base.join("2026-12-03T18-05-00Z-i1").exists());
        fs::remove_dir_all(&root).unwrap();
    }
}
