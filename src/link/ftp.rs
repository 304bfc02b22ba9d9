//! MAVLink FTP (FILE_TRANSFER_PROTOCOL) as PX4's `mavlink_ftp` serves it,
//! sans I/O: the request header, one session per link, ListDirectory,
//! OpenFileRO, ReadFile, BurstReadFile (paced by the requester's budget),
//! CreateFile, OpenFileWO, WriteFile, RemoveFile, Create/RemoveDirectory,
//! Rename, TruncateFile, CalcFileCRC32 (summed over turns), TerminateSession,
//! ResetSessions, the resent-request cache (as PX4, answers of at most 4
//! data bytes, matched by sequence number and opcode), and PX4's error codes. Files are reached through a
//! [`FileStore`] the daemon gives the link (real files, confined to the
//! vehicle's state and log directories); `@PARAM/param.pck` (PX4's packed
//! parameter file, [`param_pck`]) is served here from the parameter table,
//! and the component metadata files ([`super::events`]) from memory.
//!
//! The payload (251 bytes) as PX4 lays it out: `seq: u16, session: u8,
//! opcode: u8, size: u8, req_opcode: u8, burst_complete: u8, padding: u8,
//! offset: u32, data[239]`, little-endian. A reply carries `seq + 1`.

pub mod param_pck;

use std::net::SocketAddr;
use std::time::{Duration, Instant};

use mavlink::dialects::common::{FILE_TRANSFER_PROTOCOL_DATA, MavMessage};

use super::param::ParamAccess;
use super::{Effect, Link, ParamTicket, To};

/// Opcodes (PX4 `MavlinkFTP::Opcode`).
pub mod op {
    /// Ignored, always acked.
    pub const NONE: u8 = 0;
    /// Close the session.
    pub const TERMINATE_SESSION: u8 = 1;
    /// Close every session.
    pub const RESET_SESSIONS: u8 = 2;
    /// List `<path>` from entry `<offset>`.
    pub const LIST_DIRECTORY: u8 = 3;
    /// Open `<path>` for reading.
    pub const OPEN_FILE_RO: u8 = 4;
    /// Read from `<offset>` in the session.
    pub const READ_FILE: u8 = 5;
    /// Create (truncate) `<path>` for writing.
    pub const CREATE_FILE: u8 = 6;
    /// Write at `<offset>` in the session.
    pub const WRITE_FILE: u8 = 7;
    /// Remove `<path>`.
    pub const REMOVE_FILE: u8 = 8;
    /// Create directory `<path>`.
    pub const CREATE_DIRECTORY: u8 = 9;
    /// Remove (empty) directory `<path>`.
    pub const REMOVE_DIRECTORY: u8 = 10;
    /// Open (create) `<path>` for writing, not truncated.
    pub const OPEN_FILE_WO: u8 = 11;
    /// Truncate `<path>` to `<offset>` bytes.
    pub const TRUNCATE_FILE: u8 = 12;
    /// Rename `<path1>\0<path2>`.
    pub const RENAME: u8 = 13;
    /// CRC32 of `<path>`.
    pub const CALC_FILE_CRC32: u8 = 14;
    /// Stream the session's file from `<offset>`.
    pub const BURST_READ_FILE: u8 = 15;
    /// Positive answer.
    pub const ACK: u8 = 128;
    /// Negative answer: `data[0]` the error, `data[1]` the errno for [`super::err::FAIL_ERRNO`].
    pub const NAK: u8 = 129;
}

/// NAK error codes (PX4 `MavlinkFTP::ErrorCode`).
pub mod err {
    /// Unknown failure.
    pub const FAIL: u8 = 1;
    /// Failed; `data[1]` is the errno.
    pub const FAIL_ERRNO: u8 = 2;
    /// `size` over 239.
    pub const INVALID_DATA_SIZE: u8 = 3;
    /// No such session open.
    pub const INVALID_SESSION: u8 = 4;
    /// The session is in use.
    pub const NO_SESSIONS_AVAILABLE: u8 = 5;
    /// Offset at or past the end.
    pub const EOF: u8 = 6;
    /// Unknown opcode.
    pub const UNKNOWN_COMMAND: u8 = 7;
    /// The file exists.
    pub const FILE_EXISTS: u8 = 8;
    /// The file may not be written or removed.
    pub const FILE_PROTECTED: u8 = 9;
    /// No such file or directory.
    pub const FILE_NOT_FOUND: u8 = 10;
}

/// Bytes of data a message carries (251 - 12 header bytes).
pub const MAX_DATA: usize = 239;
const HEADER: usize = 12;
/// A session without a request this long is closed (PX4: 10 s).
const SESSION_IDLE: Duration = Duration::from_secs(10);
/// A burst sends at most this many messages per turn...
const BURST_PER_TURN: usize = 16;
/// ...one turn this often.
const BURST_TURN: Duration = Duration::from_millis(5);
/// A burst held back by the requester's budget this long is dropped.
const BURST_STALL: Duration = Duration::from_secs(3);
/// A CalcFileCRC32 sums at most this many bytes per turn (a long log is
/// summed over many turns, the link serving its other traffic between)...
const CRC_PER_TURN: u64 = 1 << 20;
/// ...one turn this often.
const CRC_TURN: Duration = Duration::from_millis(2);
/// errno values PX4 sends with [`err::FAIL_ERRNO`].
pub mod errno {
    /// Is a directory.
    pub const EISDIR: u8 = 21;
    /// Not a directory.
    pub const ENOTDIR: u8 = 20;
    /// Invalid argument.
    pub const EINVAL: u8 = 22;
    /// File too large (the size cap).
    pub const EFBIG: u8 = 27;
    /// No space left (the directory's cap).
    pub const ENOSPC: u8 = 28;
    /// Directory not empty.
    pub const ENOTEMPTY: u8 = 39;
    /// Input/output error.
    pub const EIO: u8 = 5;
}

/// Why a file operation failed, as PX4 reports it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FsError {
    /// [`err::FILE_NOT_FOUND`].
    NotFound,
    /// [`err::FILE_EXISTS`].
    Exists,
    /// [`err::FILE_PROTECTED`]: outside what a client may change.
    Protected,
    /// [`err::FAIL_ERRNO`] with this errno.
    Errno(u8),
}

impl FsError {
    /// The NAK data: the error code and, for [`FsError::Errno`], the errno.
    fn nak(self) -> Vec<u8> {
        match self {
            Self::NotFound => vec![err::FILE_NOT_FOUND],
            Self::Exists => vec![err::FILE_EXISTS],
            Self::Protected => vec![err::FILE_PROTECTED],
            Self::Errno(e) => vec![err::FAIL_ERRNO, e],
        }
    }
}

/// A directory entry.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum DirEntry {
    /// A file and its size in bytes.
    File(String, u32),
    /// A directory.
    Dir(String),
}

/// One ULog the vehicle can hand out by log download.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LogFile {
    /// Its FTP path (`/log/YYYY-MM-DD/HH_MM_SS.ulg`).
    pub path: String,
    /// Bytes now.
    pub size: u32,
    /// Last modified, seconds since the Unix epoch (PX4 sends the file's mtime).
    pub time_utc: u32,
}

/// The files a link may serve, by FTP path (`/`-separated, as a client
/// sends it). The daemon's implementation confines every path to the
/// vehicle's directories; errors are what PX4 would NAK with.
pub trait FileStore: Send + Sync + std::fmt::Debug {
    /// The entries of a directory, in a stable order.
    ///
    /// # Errors
    /// No such directory, or not a directory.
    fn list(&self, path: &str) -> Result<Vec<DirEntry>, FsError>;
    /// Open a file for reading: the path is resolved once, and a read
    /// session, a burst, a CRC32 or a log download reads through the handle.
    ///
    /// # Errors
    /// No such file, a directory, or it cannot be opened.
    fn open(&self, path: &str) -> Result<Box<dyn ReadFile>, FsError>;
    /// Create the file if missing (`truncate`: empty it too); its size.
    ///
    /// # Errors
    /// Protected, or cannot be created.
    fn create(&mut self, path: &str, truncate: bool) -> Result<u32, FsError>;
    /// Write `data` at `offset`; bytes written.
    ///
    /// # Errors
    /// Protected, over the size cap, or cannot be written.
    fn write_at(&mut self, path: &str, offset: u32, data: &[u8]) -> Result<usize, FsError>;
    /// Remove a file.
    ///
    /// # Errors
    /// Protected, missing, or a directory.
    fn remove_file(&mut self, path: &str) -> Result<(), FsError>;
    /// Create a directory.
    ///
    /// # Errors
    /// Protected, exists, or cannot be created.
    fn create_dir(&mut self, path: &str) -> Result<(), FsError>;
    /// Remove an empty directory.
    ///
    /// # Errors
    /// Protected, missing, or not empty.
    fn remove_dir(&mut self, path: &str) -> Result<(), FsError>;
    /// Rename a file or directory.
    ///
    /// # Errors
    /// Either path protected, or the rename fails.
    fn rename(&mut self, from: &str, to: &str) -> Result<(), FsError>;
    /// Truncate (or extend) a file to `len` bytes.
    ///
    /// # Errors
    /// Protected, missing, or over the size cap.
    fn truncate(&mut self, path: &str, len: u32) -> Result<(), FsError>;
    /// The ULogs, oldest first (log download's ids are indices in this list).
    fn logs(&self) -> Vec<LogFile>;
    /// Remove every finished ULog (LOG_ERASE); the one being written stays.
    fn erase_logs(&mut self);
}

/// A file open for reading.
pub trait ReadFile: Send + Sync + std::fmt::Debug {
    /// Its size now, in bytes (a log being written grows).
    ///
    /// # Errors
    /// It cannot be looked at.
    fn size(&self) -> Result<u64, FsError>;
    /// Read up to `buf.len()` bytes at `offset` (0 at the end).
    ///
    /// # Errors
    /// It cannot be read.
    fn read_at(&self, offset: u64, buf: &mut [u8]) -> Result<usize, FsError>;
}

/// The files of a link nobody gave a store: PX4 SITL's root with an empty
/// `log` directory; nothing can be written.
#[derive(Debug, Default)]
pub struct NoFiles;

impl FileStore for NoFiles {
    fn list(&self, path: &str) -> Result<Vec<DirEntry>, FsError> {
        match path.trim_matches('/') {
            "" | "." => Ok(vec![DirEntry::Dir("log".into())]),
            "log" => Ok(Vec::new()),
            _ => Err(FsError::NotFound),
        }
    }
    fn open(&self, path: &str) -> Result<Box<dyn ReadFile>, FsError> {
        self.list(path)
            .map_or(Err(FsError::NotFound), |_| Err(FsError::Errno(errno::EISDIR)))
    }
    fn create(&mut self, _: &str, _: bool) -> Result<u32, FsError> {
        Err(FsError::Protected)
    }
    fn write_at(&mut self, _: &str, _: u32, _: &[u8]) -> Result<usize, FsError> {
        Err(FsError::Protected)
    }
    fn remove_file(&mut self, _: &str) -> Result<(), FsError> {
        Err(FsError::Protected)
    }
    fn create_dir(&mut self, _: &str) -> Result<(), FsError> {
        Err(FsError::Protected)
    }
    fn remove_dir(&mut self, _: &str) -> Result<(), FsError> {
        Err(FsError::Protected)
    }
    fn rename(&mut self, _: &str, _: &str) -> Result<(), FsError> {
        Err(FsError::Protected)
    }
    fn truncate(&mut self, _: &str, _: u32) -> Result<(), FsError> {
        Err(FsError::Protected)
    }
    fn logs(&self) -> Vec<LogFile> {
        Vec::new()
    }
    fn erase_logs(&mut self) {}
}

/// The request header.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Header {
    seq: u16,
    session: u8,
    opcode: u8,
    size: u8,
    offset: u32,
}

fn header(p: &[u8; 251]) -> Header {
    Header {
        seq: u16::from_le_bytes([p[0], p[1]]),
        session: p[2],
        opcode: p[3],
        size: p[4],
        offset: u32::from_le_bytes([p[8], p[9], p[10], p[11]]),
    }
}

/// A reply payload: `seq + 1`, the request's session and offset unless
/// given, ACK or NAK with `data`. `burst_complete` stays 0: PX4 sets it when
/// it pauses a burst for a full transmit buffer and the client asks for the
/// rest; a burst here is held back by the budget and resumed, and always
/// ends in NAK EOF.
fn payload(req: &Header, opcode: u8, session: u8, offset: u32, data: &[u8]) -> [u8; 251] {
    let mut out = [0u8; 251];
    out[0..2].copy_from_slice(&req.seq.wrapping_add(1).to_le_bytes());
    out[2] = session;
    out[3] = opcode;
    let n = data.len().min(MAX_DATA);
    out[4] = n as u8;
    out[5] = req.opcode;
    out[8..12].copy_from_slice(&offset.to_le_bytes());
    out[HEADER..HEADER + n].copy_from_slice(&data[..n]);
    out
}

/// The request's data as a path: its first `size` bytes up to a NUL (PX4
/// `_data_as_cstring`: at most 238 bytes).
fn path_of(p: &[u8; 251], size: u8) -> String {
    let data = &p[HEADER..HEADER + usize::from(size).min(MAX_DATA - 1)];
    let end = data.iter().position(|b| *b == 0).unwrap_or(data.len());
    String::from_utf8_lossy(&data[..end]).into_owned()
}

/// What the one session holds.
#[derive(Debug)]
enum Session {
    /// A file open for reading, its size at open.
    Read { file: Box<dyn ReadFile>, size: u32 },
    /// A file open for writing.
    Write { path: String },
    /// A file held in memory: `@PARAM/param.pck` as it was at open, or a
    /// component metadata file ([`super::events::metadata_file`]).
    Bytes { bytes: Vec<u8> },
    /// `@PARAM/param.pck` being uploaded.
    ParamWrite(param_pck::Upload),
}

/// A burst being streamed.
#[derive(Debug)]
struct Burst {
    to: SocketAddr,
    requester: (u8, u8),
    /// Sequence number of the next message.
    seq: u16,
    offset: u32,
    due: Instant,
    held_since: Option<Instant>,
}

/// A CalcFileCRC32 being summed, PX4's `crc32part` from 0 over the whole
/// file (to its end when the sum reaches it), a bounded part per turn.
#[derive(Debug)]
struct Crc {
    to: SocketAddr,
    requester: (u8, u8),
    req: Header,
    file: Box<dyn ReadFile>,
    /// Bytes summed so far (64 bits: a log may pass 4 GiB).
    offset: u64,
    crc: u32,
    due: Instant,
}

impl Crc {
    /// Sum up to `budget` more bytes (in 64 KiB reads); the CRC once the
    /// end of the file is reached, the error if a read fails, `None` while
    /// there is more.
    fn step(&mut self, budget: u64) -> Option<Result<u32, FsError>> {
        let mut buf = vec![0u8; 64 * 1024];
        let mut summed = 0u64;
        while summed < budget {
            match self.file.read_at(self.offset, &mut buf) {
                Ok(0) => return Some(Ok(self.crc)),
                Ok(n) => {
                    self.crc = crate::mission::crc::crc32part(&buf[..n], self.crc);
                    self.offset += n as u64;
                    summed += n as u64;
                }
                Err(e) => return Some(Err(e)),
            }
        }
        None
    }
}

/// One link's FTP server state: PX4 keeps one session per MAVLink instance.
#[derive(Debug)]
pub struct Server {
    session: Option<Session>,
    last_request: Instant,
    burst: Option<Burst>,
    crc: Option<Crc>,
    /// The last small reply and to whom: a resent request gets it again.
    last_reply: Option<(SocketAddr, [u8; 251])>,
    files: Box<dyn FileStore>,
}

impl Server {
    /// No session, serving `files`.
    #[must_use]
    pub fn new(files: Box<dyn FileStore>, now: Instant) -> Self {
        Self {
            session: None,
            last_request: now,
            burst: None,
            crc: None,
            last_reply: None,
            files,
        }
    }

    /// The files served.
    pub(super) fn files(&mut self) -> &mut dyn FileStore {
        &mut *self.files
    }

    /// When [`Link::poll`] has FTP work: the next burst or CRC32 turn or
    /// the idle session's close.
    #[must_use]
    pub fn next_deadline(&self) -> Option<Instant> {
        let burst = self.burst.as_ref().map(|b| b.due);
        let crc = self.crc.as_ref().map(|c| c.due);
        let idle = self.session.as_ref().map(|_| self.last_request + SESSION_IDLE);
        burst.into_iter().chain(crc).chain(idle).min()
    }

    fn close(&mut self) {
        self.session = None;
        self.burst = None;
    }

    /// Bytes `len` from `offset` of the session's file (`None`: no read session).
    fn read_session(&self, offset: u32, len: usize) -> Option<Result<(u32, Vec<u8>), FsError>> {
        match self.session.as_ref()? {
            Session::Read { file, size } => {
                let mut buf = vec![0u8; len];
                Some(file.read_at(u64::from(offset), &mut buf).map(|n| {
                    buf.truncate(n);
                    (*size, buf)
                }))
            }
            Session::Bytes { bytes } => {
                let start = (offset as usize).min(bytes.len());
                let end = (start + len).min(bytes.len());
                Some(Ok((bytes.len() as u32, bytes[start..end].to_vec())))
            }
            Session::Write { .. } | Session::ParamWrite(_) => None,
        }
    }
}

/// The outcome of a request: ACK with data (and the session it names), or
/// NAK data; `None`: no direct answer (a burst started).
type Answer = Option<Result<(u8, Vec<u8>), Vec<u8>>>;

impl Link {
    /// A FILE_TRANSFER_PROTOCOL request for us.
    pub(super) fn on_ftp<P: ParamAccess + ?Sized>(
        &mut self,
        now: Instant,
        from: SocketAddr,
        requester: (u8, u8),
        m: &FILE_TRANSFER_PROTOCOL_DATA,
        params: &P,
        effects: &mut Vec<Effect>,
    ) {
        let req = header(&m.payload);
        // answers (from another server, or our own looped back) get none:
        // two servers must not talk to each other for ever
        if req.opcode == op::ACK || req.opcode == op::NAK {
            return;
        }
        if let Some(c) = &self.ftp.crc
            && c.to == from
            && c.req.seq == req.seq
            && c.req.opcode == req.opcode
        {
            // resent while the CRC32 is summed: answered when it is done
            return;
        }
        if let Some((to, last)) = &self.ftp.last_reply
            && *to == from
            && req.seq.wrapping_add(1) == u16::from_le_bytes([last[0], last[1]])
            && last[5] == req.opcode
        {
            // the answer was lost and the request resent (PX4 keeps small
            // answers); a request of another opcode with that seq is new
            let last = *last;
            self.ftp_send(from, requester, last);
            return;
        }
        // a new request: the client gave up on a CRC32 still being summed
        self.ftp.crc = None;
        self.ftp.last_request = now;
        let answer = if usize::from(req.size) > MAX_DATA {
            Some(Err(vec![err::INVALID_DATA_SIZE]))
        } else {
            self.ftp_work(now, from, requester, &req, &m.payload, params, effects)
        };
        let Some(answer) = answer else { return };
        let out = match answer {
            Ok((session, data)) => payload(&req, op::ACK, session, req.offset, &data),
            Err(data) => payload(&req, op::NAK, req.session, req.offset, &data),
        };
        self.ftp.last_reply = (out[4] <= 4).then_some((from, out));
        self.ftp_send(from, requester, out);
    }

    fn ftp_send(&mut self, to: SocketAddr, requester: (u8, u8), payload: [u8; 251]) -> bool {
        let msg = MavMessage::FILE_TRANSFER_PROTOCOL(FILE_TRANSFER_PROTOCOL_DATA {
            target_network: 0,
            target_system: requester.0,
            target_component: requester.1,
            payload,
        });
        let bytes = self.encoder.message(&msg);
        self.queue(To::Peer(to), bytes)
    }

    #[allow(clippy::too_many_arguments)]
    fn ftp_work<P: ParamAccess + ?Sized>(
        &mut self,
        now: Instant,
        from: SocketAddr,
        requester: (u8, u8),
        req: &Header,
        p: &[u8; 251],
        params: &P,
        effects: &mut Vec<Effect>,
    ) -> Answer {
        let ftp = &mut self.ftp;
        let path = || path_of(p, req.size);
        let done = |r: Result<(), FsError>| Some(r.map(|()| (req.session, Vec::new())).map_err(FsError::nak));
        match req.opcode {
            op::NONE => Some(Ok((req.session, Vec::new()))),
            op::TERMINATE_SESSION => {
                if req.session != 0 || ftp.session.is_none() {
                    return Some(Err(vec![err::INVALID_SESSION]));
                }
                let session = ftp.session.take();
                ftp.burst = None;
                if let Some(Session::ParamWrite(upload)) = session {
                    return Some(self.finish_param_upload(from, requester, &upload, params, effects));
                }
                Some(Ok((0, Vec::new())))
            }
            op::RESET_SESSIONS => {
                ftp.close();
                Some(Ok((req.session, Vec::new())))
            }
            op::LIST_DIRECTORY => Some(list(&*ftp.files, &path(), req.offset)),
            op::OPEN_FILE_RO | op::CREATE_FILE | op::OPEN_FILE_WO => {
                if ftp.session.is_some() {
                    return Some(Err(vec![err::NO_SESSIONS_AVAILABLE]));
                }
                let path = path();
                let opened = if let (op::OPEN_FILE_RO, Some(file)) = (req.opcode, super::events::metadata_file(&path)) {
                    let bytes = file.to_vec();
                    let size = bytes.len() as u32;
                    Ok((Session::Bytes { bytes }, size))
                } else if param_pck::is_param_path(&path) {
                    match req.opcode {
                        op::OPEN_FILE_RO => param_pck::download(&path, params, MAX_DATA)
                            .map(|bytes| {
                                let size = bytes.len() as u32;
                                (Session::Bytes { bytes }, size)
                            })
                            .map_err(|param_pck::Refused| FsError::Errno(errno::EINVAL)),
                        _ => Ok((Session::ParamWrite(param_pck::Upload::default()), 0)),
                    }
                } else {
                    match req.opcode {
                        op::OPEN_FILE_RO => ftp.files.open(&path).and_then(|file| {
                            // PX4 sends st_size as a u32
                            let size = u32::try_from(file.size()?).unwrap_or(u32::MAX);
                            Ok((Session::Read { file, size }, size))
                        }),
                        op::CREATE_FILE => ftp
                            .files
                            .create(&path, true)
                            .map(|size| (Session::Write { path }, size)),
                        _ => ftp
                            .files
                            .create(&path, false)
                            .map(|size| (Session::Write { path }, size)),
                    }
                };
                Some(match opened {
                    Ok((s, size)) => {
                        ftp.session = Some(s);
                        Ok((0, size.to_le_bytes().to_vec()))
                    }
                    Err(e) => Err(e.nak()),
                })
            }
            op::READ_FILE => {
                if req.session != 0 {
                    return Some(Err(vec![err::INVALID_SESSION]));
                }
                Some(match ftp.read_session(req.offset, MAX_DATA) {
                    None => Err(vec![err::INVALID_SESSION]),
                    Some(Ok((size, _))) if req.offset >= size => Err(vec![err::EOF]),
                    Some(Ok((_, data))) => Ok((0, data)),
                    Some(Err(e)) => Err(e.nak()),
                })
            }
            op::BURST_READ_FILE => {
                if req.session != 0 || !matches!(ftp.session, Some(Session::Read { .. } | Session::Bytes { .. })) {
                    return Some(Err(vec![err::INVALID_SESSION]));
                }
                ftp.burst = Some(Burst {
                    to: from,
                    requester,
                    seq: req.seq.wrapping_add(1),
                    offset: req.offset,
                    due: now,
                    held_since: None,
                });
                self.ftp_burst(now);
                None
            }
            op::WRITE_FILE => {
                let data = &p[HEADER..HEADER + usize::from(req.size)];
                Some(match (&mut ftp.session, req.session) {
                    (Some(Session::Write { path }), 0) => {
                        let path = path.clone();
                        ftp.files
                            .write_at(&path, req.offset, data)
                            .map(|n| (0, (n as u32).to_le_bytes().to_vec()))
                            .map_err(FsError::nak)
                    }
                    (Some(Session::ParamWrite(upload)), 0) => match upload.write(req.offset, data) {
                        Ok(()) => Ok((0, (data.len() as u32).to_le_bytes().to_vec())),
                        Err(param_pck::Refused) => Err(vec![err::FAIL]),
                    },
                    _ => Err(vec![err::INVALID_SESSION]),
                })
            }
            op::REMOVE_FILE => done(ftp.files.remove_file(&path())),
            op::CREATE_DIRECTORY => done(ftp.files.create_dir(&path())),
            op::REMOVE_DIRECTORY => done(ftp.files.remove_dir(&path())),
            op::TRUNCATE_FILE => done(ftp.files.truncate(&path(), req.offset)),
            op::RENAME => {
                let data = &p[HEADER..HEADER + usize::from(req.size)];
                let Some(split) = data.iter().position(|b| *b == 0).filter(|i| i + 1 < data.len()) else {
                    return Some(Err(vec![err::FAIL_ERRNO, errno::EINVAL]));
                };
                let from_path = String::from_utf8_lossy(&data[..split]).into_owned();
                let rest = &data[split + 1..];
                let end = rest.iter().position(|b| *b == 0).unwrap_or(rest.len());
                let to_path = String::from_utf8_lossy(&rest[..end]).into_owned();
                done(ftp.files.rename(&from_path, &to_path))
            }
            op::CALC_FILE_CRC32 => match ftp.files.open(&path()) {
                Err(e) => Some(Err(e.nak())),
                Ok(file) => {
                    ftp.crc = Some(Crc {
                        to: from,
                        requester,
                        req: *req,
                        file,
                        offset: 0,
                        crc: 0,
                        due: now,
                    });
                    self.ftp_crc(now);
                    None
                }
            },
            _ => Some(Err(vec![err::UNKNOWN_COMMAND])),
        }
    }

    /// A finished `@PARAM/param.pck` upload: ACK and set every known
    /// parameter whose value it changes, or NAK [`err::FAIL`] for a file
    /// that is not complete and well formed (then nothing is set).
    fn finish_param_upload<P: ParamAccess + ?Sized>(
        &mut self,
        from: SocketAddr,
        requester: (u8, u8),
        upload: &param_pck::Upload,
        params: &P,
        effects: &mut Vec<Effect>,
    ) -> Result<(u8, Vec<u8>), Vec<u8>> {
        let Ok(entries) = upload.finish() else {
            return Err(vec![err::FAIL]);
        };
        for (name, value) in param_pck::changes(&entries, params) {
            let (raw, kind) = super::param::to_wire(value);
            match super::param::check_set(params, &name, kind, raw, requester) {
                Ok((index, value)) => effects.push(Effect::SetParam {
                    ticket: ParamTicket {
                        name,
                        index,
                        to: from,
                        requester,
                    },
                    value,
                }),
                Err(r) => self.param_reply(To::Peer(from), &r),
            }
        }
        Ok((0, Vec::new()))
    }

    /// FTP's timed work: close an idle session, sum a CRC32 on, send a burst on.
    pub(super) fn ftp_poll(&mut self, now: Instant) {
        if self.ftp.session.is_some() && now.saturating_duration_since(self.ftp.last_request) > SESSION_IDLE {
            tracing::debug!(link = %self.config.name, "FTP session closed without activity");
            self.ftp.close();
            self.ftp.last_reply = None;
        }
        self.ftp_crc(now);
        self.ftp_burst(now);
    }

    /// Sum the CRC32 on for a turn; answer once it is done (the answer is
    /// kept for a resent request, as any small answer).
    fn ftp_crc(&mut self, now: Instant) {
        let Some(mut c) = self.ftp.crc.take() else { return };
        if c.due > now {
            self.ftp.crc = Some(c);
            return;
        }
        let out = match c.step(CRC_PER_TURN) {
            None => {
                c.due = now + CRC_TURN;
                self.ftp.crc = Some(c);
                return;
            }
            Some(Ok(crc)) => payload(&c.req, op::ACK, c.req.session, c.req.offset, &crc.to_le_bytes()),
            Some(Err(e)) => payload(&c.req, op::NAK, c.req.session, c.req.offset, &e.nak()),
        };
        self.ftp.last_reply = Some((c.to, out));
        self.ftp_send(c.to, c.requester, out);
    }

    /// Send the burst's next messages the requester's budget allows; the
    /// last is a NAK EOF (PX4).
    fn ftp_burst(&mut self, now: Instant) {
        let Some(mut b) = self.ftp.burst.take() else { return };
        if b.due > now {
            self.ftp.burst = Some(b);
            return;
        }
        for _ in 0..BURST_PER_TURN {
            let req = Header {
                seq: b.seq.wrapping_sub(1),
                session: 0,
                opcode: op::BURST_READ_FILE,
                size: 0,
                offset: b.offset,
            };
            let (out, last) = match self.ftp.read_session(b.offset, MAX_DATA) {
                Some(Ok((size, data))) if b.offset < size && !data.is_empty() => {
                    (payload(&req, op::ACK, 0, b.offset, &data), false)
                }
                Some(Ok(_)) => (payload(&req, op::NAK, 0, b.offset, &[err::EOF]), true),
                Some(Err(e)) => (payload(&req, op::NAK, 0, b.offset, &e.nak()), true),
                None => return,
            };
            if !self.ftp_send(b.to, b.requester, out) {
                let since = *b.held_since.get_or_insert(now);
                if now.saturating_duration_since(since) <= BURST_STALL {
                    b.due = now + BURST_TURN;
                    self.ftp.burst = Some(b);
                }
                return;
            }
            b.held_since = None;
            // a long burst is activity: the session stays open through it
            self.ftp.last_request = now;
            if last {
                return;
            }
            b.offset += u32::from(out[4]);
            b.seq = b.seq.wrapping_add(1);
        }
        b.due = now + BURST_TURN;
        self.ftp.burst = Some(b);
    }
}

/// A ListDirectory answer: entries from index `offset` (PX4 counts `.`
/// and `..` first, sent as skip entries), as many as fit; EOF when
/// `offset` is past the last.
fn list(files: &dyn FileStore, path: &str, offset: u32) -> Result<(u8, Vec<u8>), Vec<u8>> {
    let entries = files.list(path).map_err(FsError::nak)?;
    let mut data = Vec::new();
    let mut sent = 0;
    let all = [None, None].into_iter().chain(entries.iter().map(Some));
    for e in all.skip(offset as usize) {
        let text = match e {
            None => "S".to_string(),
            Some(DirEntry::File(name, size)) => format!("F{name}\t{size}"),
            Some(DirEntry::Dir(name)) => format!("D{name}"),
        };
        if data.len() + text.len() + 1 > MAX_DATA {
            break;
        }
        data.extend_from_slice(text.as_bytes());
        data.push(0);
        sent += 1;
    }
    if offset != 0 && sent == 0 {
        return Err(vec![err::EOF]);
    }
    Ok((0, data))
}

#[cfg(test)]
mod tests;
