//! The files a vehicle serves by MAVLink FTP and log download
//! ([`crate::link::ftp::FileStore`]), as PX4 SITL's root directory looks to
//! a client: `/` holds the daemon's `params.toml` and `missions.json` (from
//! the state directory, read-only), the files and directories clients made
//! (kept apart from the daemon's own files, in the state directory's
//! [`CLIENT_DIR`] subdirectory: no client name can touch a daemon file, its
//! temporary twin, the signing key or the lock), and `log/`, the ULogs
//! `--log-dir` wrote for this vehicle under PX4's names,
//! `log/YYYY-MM-DD/HH_MM_SS.ulg` (UTC start; `_2`, ... when two runs
//! started in one second). `/fs/microsd/` (a flight controller's SD card) is
//! an alias of `/`. Logs are read-only but for LOG_ERASE, which removes the
//! `flight.ulg` of each of this vehicle's runs that no daemon is writing
//! (the writer holds a lock on it); the run directories and their other
//! files (flight record, tlogs, CSV) stay.
//!
//! Bounds: no path reaches outside the client, state and log directories
//! (`..` refused, symbolic links not followed), a client's file is at most
//! [`MAX_FILE`] bytes, the client's files together at most [`MAX_TOTAL`]
//! bytes and [`MAX_ENTRIES`] files and directories at any depth (counted
//! once, then kept up to date by every change, shared by the vehicle's
//! links); a write past a bound is refused (EFBIG, ENOSPC).

use std::fs;
use std::io::{Seek, SeekFrom, Write};
use std::os::unix::fs::FileExt as _;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::UNIX_EPOCH;

use crate::link::ftp::{DirEntry, FileStore, FsError, LogFile, ReadFile, errno};

/// The largest file a client may write [bytes].
pub(super) const MAX_FILE: u64 = 1 << 20;
/// What a client's files may hold together [bytes].
pub(super) const MAX_TOTAL: u64 = 16 << 20;
/// Files and directories the clients may make, together, at any depth.
pub(super) const MAX_ENTRIES: u64 = 1000;
/// The state directory's subdirectory that holds the clients' files.
pub(super) const CLIENT_DIR: &str = "ftp";
/// Files the daemon owns in the state directory: listed, read-only.
const DAEMON_FILES: [&str; 2] = ["params.toml", "missions.json"];
/// Never listed, read or written.
const HIDDEN: [&str; 2] = [super::signing::FILE_NAME, super::lock::LOCK_FILE];

/// What the clients' files hold.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Usage {
    bytes: u64,
    /// Files and directories.
    entries: u64,
}

/// One vehicle's files (cloned for each of its links: the count of the
/// clients' files is shared).
#[derive(Clone, Debug)]
pub(super) struct VehicleFiles {
    state_dir: PathBuf,
    /// `--log-dir` and the instance whose runs are this vehicle's.
    logs: Option<(PathBuf, u8)>,
    /// This run's directory (its ULog is being written: never erased).
    current_run: Option<PathBuf>,
    /// The clients' files as last counted (`None`: to be counted); held
    /// through every change, so the links of one vehicle take turns.
    usage: Arc<Mutex<Option<Usage>>>,
}

/// Where an FTP path leads.
#[derive(Debug, PartialEq, Eq)]
enum Place {
    /// `/`.
    Root,
    /// One of [`DAEMON_FILES`].
    Daemon(String),
    /// A client's file or directory (relative parts below [`CLIENT_DIR`]).
    Client(Vec<String>),
    /// `log/`.
    LogRoot,
    /// `log/DATE/`.
    LogDay(String),
    /// `log/DATE/NAME.ulg`.
    Log(String, String),
}

/// A file open for reading: positioned reads, no seek.
#[derive(Debug)]
struct DiskFile(fs::File);

impl ReadFile for DiskFile {
    fn size(&self) -> Result<u64, FsError> {
        self.0.metadata().map(|m| m.len()).map_err(|e| io(&e))
    }
    fn read_at(&self, offset: u64, buf: &mut [u8]) -> Result<usize, FsError> {
        let mut n = 0;
        while n < buf.len() {
            match self.0.read_at(&mut buf[n..], offset + n as u64) {
                Ok(0) => break,
                Ok(k) => n += k,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(io(&e)),
            }
        }
        Ok(n)
    }
}

/// Open `p` for reading: EISDIR for a directory.
fn open_file(p: &Path) -> Result<Box<dyn ReadFile>, FsError> {
    let f = fs::File::open(p).map_err(|e| io(&e))?;
    if f.metadata().map_err(|e| io(&e))?.is_dir() {
        return Err(FsError::Errno(errno::EISDIR));
    }
    Ok(Box::new(DiskFile(f)))
}

/// The clients' files below `root`, every entry at any depth (symbolic
/// links not followed), counted until past [`MAX_ENTRIES`].
fn count(root: &Path) -> Usage {
    let mut u = Usage { bytes: 0, entries: 0 };
    let mut dirs = vec![root.to_path_buf()];
    while let Some(dir) = dirs.pop() {
        let Ok(rd) = fs::read_dir(&dir) else { continue };
        for e in rd.filter_map(Result::ok) {
            u.entries += 1;
            if u.entries > MAX_ENTRIES {
                return u;
            }
            match e.file_type() {
                Ok(t) if t.is_file() => u.bytes += e.metadata().map_or(0, |m| m.len()),
                Ok(t) if t.is_dir() => dirs.push(e.path()),
                _ => {}
            }
        }
    }
    u
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
            usage: Arc::new(Mutex::new(None)),
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
        let Some(first) = parts.first().map(String::as_str) else {
            return Ok(Place::Root);
        };
        if HIDDEN.contains(&first) {
            return Err(FsError::Protected);
        }
        Ok(match first {
            "log" => match parts.len() {
                1 => Place::LogRoot,
                2 => Place::LogDay(parts[1].clone()),
                3 => Place::Log(parts[1].clone(), parts[2].clone()),
                _ => return Err(FsError::NotFound),
            },
            f if parts.len() == 1 && DAEMON_FILES.contains(&f) => Place::Daemon(parts.remove(0)),
            _ => Place::Client(parts),
        })
    }

    fn client_root(&self) -> PathBuf {
        self.state_dir.join(CLIENT_DIR)
    }

    /// A client's path, refused if a symbolic link would lead out.
    fn client_path(&self, parts: &[String]) -> Result<PathBuf, FsError> {
        let mut p = self.client_root();
        let is_link = |p: &Path| fs::symlink_metadata(p).is_ok_and(|m| m.file_type().is_symlink());
        if is_link(&p) {
            return Err(FsError::Protected);
        }
        for part in parts {
            p.push(part);
            if is_link(&p) {
                return Err(FsError::Protected);
            }
        }
        Ok(p)
    }

    /// A path a client may change: its own files only.
    fn writable(&self, path: &str) -> Result<PathBuf, FsError> {
        match Self::place(path)? {
            Place::Client(parts) => self.client_path(&parts),
            _ => Err(FsError::Protected),
        }
    }

    /// The count of the clients' files, held while a change is made.
    fn usage(&self) -> MutexGuard<'_, Option<Usage>> {
        let mut u = self.usage.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        if u.is_none() {
            *u = Some(count(&self.client_root()));
        }
        u
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
}

/// Whether a file may grow from `old` to `new` bytes with the clients'
/// files at `u`.
fn room(u: Usage, old: u64, new: u64) -> Result<(), FsError> {
    if new > MAX_FILE {
        return Err(FsError::Errno(errno::EFBIG));
    }
    if new > old && u.bytes + (new - old) > MAX_TOTAL {
        return Err(FsError::Errno(errno::ENOSPC));
    }
    Ok(())
}

/// Whether the clients may make one more file or directory.
fn one_more(u: Usage) -> Result<(), FsError> {
    if u.entries >= MAX_ENTRIES {
        return Err(FsError::Errno(errno::ENOSPC));
    }
    Ok(())
}

impl FileStore for VehicleFiles {
    fn list(&self, path: &str) -> Result<Vec<DirEntry>, FsError> {
        let dir = match Self::place(path)? {
            Place::Root => None,
            Place::Client(parts) => Some(self.client_path(&parts)?),
            Place::Daemon(_) | Place::Log(..) => return Err(FsError::Errno(errno::ENOTDIR)),
            Place::LogRoot => {
                let mut days: Vec<String> = self.runs().into_iter().map(|r| r.0).collect();
                days.dedup();
                return Ok(days.into_iter().map(DirEntry::Dir).collect());
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
                return Ok(files);
            }
        };
        let root = dir.is_none();
        let mut found: Vec<(String, fs::FileType, fs::Metadata)> = Vec::new();
        match fs::read_dir(dir.as_ref().unwrap_or(&self.client_root())) {
            Ok(rd) => found.extend(
                rd.filter_map(Result::ok)
                    .take(MAX_ENTRIES as usize)
                    .filter_map(|e| {
                        Some((
                            e.file_name().into_string().ok()?,
                            e.file_type().ok()?,
                            e.metadata().ok()?,
                        ))
                    })
                    .filter(|(n, _, _)| {
                        !(root && (n == "log" || DAEMON_FILES.contains(&n.as_str()) || HIDDEN.contains(&n.as_str())))
                    }),
            ),
            // no client has written yet
            Err(e) if root && e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(io(&e)),
        }
        if root {
            for name in DAEMON_FILES {
                if let Ok(m) = fs::symlink_metadata(self.state_dir.join(name)) {
                    found.push((name.to_string(), m.file_type(), m));
                }
            }
        }
        found.sort_by(|a, b| a.0.cmp(&b.0));
        let mut out: Vec<DirEntry> = Vec::new();
        if root {
            out.push(DirEntry::Dir("log".into()));
        }
        for (name, t, m) in found {
            if t.is_file() {
                out.push(DirEntry::File(name, u32::try_from(m.len()).unwrap_or(u32::MAX)));
            } else if t.is_dir() {
                out.push(DirEntry::Dir(name));
            }
        }
        Ok(out)
    }

    fn open(&self, path: &str) -> Result<Box<dyn ReadFile>, FsError> {
        match Self::place(path)? {
            Place::Daemon(name) => open_file(&self.state_dir.join(name)),
            Place::Client(parts) => open_file(&self.client_path(&parts)?),
            Place::Log(date, name) => {
                let run = self
                    .runs()
                    .into_iter()
                    .find(|r| r.0 == date && r.1 == name)
                    .ok_or(FsError::NotFound)?;
                open_file(&run.2.join(super::ulog_file::FILE_NAME))
            }
            Place::Root | Place::LogRoot | Place::LogDay(_) => Err(FsError::Errno(errno::EISDIR)),
        }
    }

    fn create(&mut self, path: &str, truncate: bool) -> Result<u32, FsError> {
        let p = self.writable(path)?;
        let mut usage = self.usage();
        let u = usage.unwrap_or(Usage { bytes: 0, entries: 0 });
        let old = fs::symlink_metadata(&p).ok().map(|m| m.len());
        if old.is_none() {
            one_more(u)?;
        }
        fs::create_dir_all(self.client_root()).map_err(|e| io(&e))?;
        let opened = fs::OpenOptions::new()
            .create(true)
            .write(true)
            .truncate(truncate)
            .open(&p)
            .and_then(|f| f.metadata());
        let len = match opened {
            Ok(m) => m.len(),
            Err(e) => {
                *usage = None;
                return Err(io(&e));
            }
        };
        *usage = Some(match old {
            None => Usage {
                entries: u.entries + 1,
                ..u
            },
            Some(old) => Usage {
                bytes: u.bytes - old.min(u.bytes) + len,
                ..u
            },
        });
        Ok(u32::try_from(len).unwrap_or(u32::MAX))
    }

    fn write_at(&mut self, path: &str, offset: u32, data: &[u8]) -> Result<usize, FsError> {
        let p = self.writable(path)?;
        let mut usage = self.usage();
        let u = usage.unwrap_or(Usage { bytes: 0, entries: 0 });
        let old = fs::metadata(&p).map_err(|e| io(&e))?.len();
        let new = old.max(u64::from(offset) + data.len() as u64);
        room(u, old, new)?;
        let written = fs::OpenOptions::new().write(true).open(&p).and_then(|mut f| {
            f.seek(SeekFrom::Start(u64::from(offset)))?;
            f.write_all(data)
        });
        match written {
            Ok(()) => {
                *usage = Some(Usage {
                    bytes: u.bytes + (new - old),
                    ..u
                });
                Ok(data.len())
            }
            Err(e) => {
                *usage = None;
                Err(io(&e))
            }
        }
    }

    fn remove_file(&mut self, path: &str) -> Result<(), FsError> {
        let p = self.writable(path)?;
        let mut usage = self.usage();
        let r = fs::remove_file(&p).map_err(|e| io(&e));
        // counted afresh at the next change
        *usage = None;
        r
    }

    fn create_dir(&mut self, path: &str) -> Result<(), FsError> {
        let p = self.writable(path)?;
        let mut usage = self.usage();
        let u = usage.unwrap_or(Usage { bytes: 0, entries: 0 });
        one_more(u)?;
        fs::create_dir_all(self.client_root()).map_err(|e| io(&e))?;
        fs::create_dir(&p).map_err(|e| io(&e))?;
        *usage = Some(Usage {
            entries: u.entries + 1,
            ..u
        });
        Ok(())
    }

    fn remove_dir(&mut self, path: &str) -> Result<(), FsError> {
        let p = self.writable(path)?;
        let mut usage = self.usage();
        let r = fs::remove_dir(&p).map_err(|e| match e.kind() {
            std::io::ErrorKind::DirectoryNotEmpty => FsError::Errno(errno::ENOTEMPTY),
            _ => io(&e),
        });
        *usage = None;
        r
    }

    fn rename(&mut self, from: &str, to: &str) -> Result<(), FsError> {
        let a = self.writable(from)?;
        let b = self.writable(to)?;
        let mut usage = self.usage();
        let r = fs::rename(&a, &b).map_err(|e| io(&e));
        *usage = None;
        r
    }

    fn truncate(&mut self, path: &str, len: u32) -> Result<(), FsError> {
        let p = self.writable(path)?;
        let mut usage = self.usage();
        let u = usage.unwrap_or(Usage { bytes: 0, entries: 0 });
        let old = fs::metadata(&p).map_err(|e| io(&e))?.len();
        room(u, old, u64::from(len))?;
        let r = fs::OpenOptions::new()
            .write(true)
            .open(&p)
            .and_then(|f| f.set_len(u64::from(len)));
        *usage = match r {
            Ok(()) => Some(Usage {
                bytes: u.bytes - old.min(u.bytes) + u64::from(len),
                ..u
            }),
            Err(_) => None,
        };
        r.map_err(|e| io(&e))
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
            let ulog = run.join(super::ulog_file::FILE_NAME);
            // a daemon writing the ULog holds a lock on it: that one stays
            let free = fs::File::open(&ulog).map(|f| match f.try_lock() {
                Ok(()) => Some(f),
                Err(_) => None,
            });
            match free {
                Ok(Some(_locked)) => {
                    if let Err(e) = fs::remove_file(&ulog) {
                        tracing::warn!(log = %ulog.display(), error = %e, "LOG_ERASE: cannot remove the ULog");
                    }
                }
                Ok(None) => tracing::debug!(log = %ulog.display(), "LOG_ERASE: the ULog is being written; kept"),
                Err(e) => tracing::warn!(log = %ulog.display(), error = %e, "LOG_ERASE: cannot open the ULog"),
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

    fn read_all(f: &VehicleFiles, path: &str) -> Result<Vec<u8>, FsError> {
        let file = f.open(path)?;
        let mut buf = vec![0u8; usize::try_from(file.size()?).unwrap()];
        let n = file.read_at(0, &mut buf)?;
        buf.truncate(n);
        Ok(buf)
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
        fs::create_dir_all(state.join(CLIENT_DIR)).unwrap();
        fs::write(state.join("params.toml"), "x").unwrap();
        fs::write(state.join(super::super::signing::FILE_NAME), [0u8; 40]).unwrap();
        fs::write(root.join("secret"), "s").unwrap();
        std::os::unix::fs::symlink(&root, state.join(CLIENT_DIR).join("up")).unwrap();
        let mut f = VehicleFiles::new(state.clone(), None, None);
        let names: Vec<_> = f.list("/").unwrap();
        assert_eq!(
            names,
            vec![DirEntry::Dir("log".into()), DirEntry::File("params.toml".into(), 1)]
        );
        assert_eq!(read_all(&f, "/params.toml"), Ok(b"x".to_vec()));
        assert_eq!(read_all(&f, "/fs/microsd/params.toml"), Ok(b"x".to_vec()));
        assert_eq!(f.open("/../secret").unwrap_err(), FsError::Protected);
        assert_eq!(f.open("/up/secret").unwrap_err(), FsError::Protected);
        assert_eq!(f.open("/signing.key").unwrap_err(), FsError::Protected);
        assert_eq!(f.open("/").unwrap_err(), FsError::Errno(errno::EISDIR));
        assert_eq!(f.create("/params.toml", true), Err(FsError::Protected));
        assert_eq!(f.create("/log/x.ulg", true), Err(FsError::Protected));
        assert_eq!(f.create("/mine.txt", true), Ok(0));
        assert_eq!(f.write_at("/mine.txt", 0, b"abc"), Ok(3));
        assert_eq!(
            f.write_at("/mine.txt", MAX_FILE as u32, b"x"),
            Err(FsError::Errno(errno::EFBIG))
        );
        assert_eq!(
            f.list("/").unwrap(),
            vec![
                DirEntry::Dir("log".into()),
                DirEntry::File("mine.txt".into(), 3),
                DirEntry::File("params.toml".into(), 1),
            ],
            "the symbolic link is not listed"
        );
        assert_eq!(f.remove_file("/mine.txt"), Ok(()));
        assert_eq!(fs::read_to_string(root.join("secret")).unwrap(), "s");
        fs::remove_dir_all(&root).unwrap();
    }

    /// A client's names, dot-names and the daemon's temporary twins
    /// included, land in its own directory: a parameter save still works.
    #[test]
    fn a_client_cannot_block_the_daemons_saves_with_its_names() {
        let root = scratch("twins");
        let state = root.join("state");
        fs::create_dir_all(&state).unwrap();
        let mut f = VehicleFiles::new(state.clone(), None, None);
        let params = state.join("params.toml");
        let twin = crate::statefile::temp_path(&params).unwrap();
        let twin_name = format!("/{}", twin.file_name().unwrap().to_str().unwrap());
        assert_eq!(f.create_dir(&twin_name), Ok(()));
        assert_eq!(f.create("/.missions.json.tmp", true), Ok(0));
        assert!(!twin.exists(), "not in the state directory");
        assert!(state.join(CLIENT_DIR).join(twin.file_name().unwrap()).is_dir());
        crate::statefile::write_atomic(&params, b"MIS_TAKEOFF_ALT = 3.0\n", |w, b| w.write_all(b))
            .expect("the daemon's save");
        assert_eq!(read_all(&f, "/params.toml"), Ok(b"MIS_TAKEOFF_ALT = 3.0\n".to_vec()));
        for name in [
            "/params.toml",
            "/missions.json",
            "/lock",
            "/signing.key",
            "/fs/microsd/missions.json",
        ] {
            assert_eq!(f.create_dir(name), Err(FsError::Protected), "{name}");
            assert_eq!(f.create(name, false), Err(FsError::Protected), "{name}");
        }
        fs::remove_dir_all(&root).unwrap();
    }

    /// Empty files and directories count (at most [`MAX_ENTRIES`]), and so
    /// do files at any depth, however they came.
    #[test]
    fn the_clients_files_are_counted_whole_and_capped() {
        let root = scratch("quota");
        let state = root.join("state");
        fs::create_dir_all(&state).unwrap();
        let mut f = VehicleFiles::new(state.clone(), None, None);
        assert_eq!(f.create_dir("/d"), Ok(()));
        for i in 1..MAX_ENTRIES {
            assert_eq!(f.create(&format!("/d/{i}"), true), Ok(0), "entry {i}");
        }
        assert_eq!(f.create("/one-more", true), Err(FsError::Errno(errno::ENOSPC)));
        assert_eq!(f.create_dir("/one-more"), Err(FsError::Errno(errno::ENOSPC)));
        // an existing file is opened again, not counted twice
        assert_eq!(f.create("/d/7", false), Ok(0));
        assert_eq!(f.remove_file("/d/7"), Ok(()));
        assert_eq!(f.create("/now-there-is-room", true), Ok(0));
        fs::remove_dir_all(&root).unwrap();

        // 16 MiB ten directories deep (sparse files): no room for a byte more
        let root = scratch("quota-deep");
        let state = root.join("state");
        let mut deep = state.join(CLIENT_DIR);
        for k in 0..10 {
            deep.push(format!("level{k}"));
        }
        fs::create_dir_all(&deep).unwrap();
        for i in 0..16 {
            fs::File::create(deep.join(format!("big{i}")))
                .unwrap()
                .set_len(MAX_FILE)
                .unwrap();
        }
        let mut f = VehicleFiles::new(state.clone(), None, None);
        assert_eq!(f.create("/small", true), Ok(0));
        assert_eq!(f.write_at("/small", 0, b"x"), Err(FsError::Errno(errno::ENOSPC)));
        assert_eq!(f.truncate("/small", 1), Err(FsError::Errno(errno::ENOSPC)));
        // the vehicle's other links share the count
        let mut other = f.clone();
        assert_eq!(other.write_at("/small", 0, b"x"), Err(FsError::Errno(errno::ENOSPC)));
        fs::remove_dir_all(&root).unwrap();
    }

    fn run_with_ulog(base: &Path, run: &str) -> PathBuf {
        let dir = base.join(run);
        fs::create_dir_all(&dir).unwrap();
        fs::write(dir.join(super::super::ulog_file::FILE_NAME), run).unwrap();
        fs::write(dir.join("flight.record"), "{}").unwrap();
        dir
    }

    #[test]
    fn the_logs_are_this_vehicles_runs_and_erase_keeps_what_is_being_written() {
        let root = scratch("logs");
        let base = root.join("logs");
        let finished = run_with_ulog(&base, "2026-12-03T18-00-00Z-i0");
        // another live daemon of instance 0 under the same --log-dir
        let foreign = run_with_ulog(&base, "2026-12-03T18-02-00Z-i0");
        let current = run_with_ulog(&base, "2026-12-03T18-05-00Z-i0");
        let other_instance = run_with_ulog(&base, "2026-12-03T18-05-00Z-i1");
        let writer = fs::File::open(foreign.join(super::super::ulog_file::FILE_NAME)).unwrap();
        writer.try_lock().unwrap();
        let mut f = VehicleFiles::new(root.join("state"), Some((base.clone(), 0)), Some(current.clone()));
        let logs = f.logs();
        let paths: Vec<_> = logs.iter().map(|l| l.path.as_str()).collect();
        assert_eq!(
            paths,
            [
                "/log/2026-12-03/18_00_00.ulg",
                "/log/2026-12-03/18_02_00.ulg",
                "/log/2026-12-03/18_05_00.ulg"
            ]
        );
        assert_eq!(f.list("/log").unwrap(), vec![DirEntry::Dir("2026-12-03".into())]);
        assert_eq!(
            read_all(&f, "/log/2026-12-03/18_00_00.ulg"),
            Ok(b"2026-12-03T18-00-00Z-i0".to_vec())
        );
        f.erase_logs();
        let ulog = |d: &Path| d.join(super::super::ulog_file::FILE_NAME).exists();
        assert!(!ulog(&finished), "the finished ULog is erased");
        assert!(finished.join("flight.record").exists(), "its run keeps its record");
        assert!(ulog(&foreign), "a ULog another daemon writes stays");
        assert!(ulog(&current) && ulog(&other_instance));
        assert_eq!(f.logs().len(), 2);
        drop(writer);
        fs::remove_dir_all(&root).unwrap();
    }
}
