//! One link's MAVLink telemetry log (`<run dir>/<link>.tlog`), the format
//! MAVProxy, MAVExplorer, QGroundControl and pymavlink's `mavlogfile` read:
//! for every frame the link sent or received,
//!
//! ```text
//! unix_time_us u64 big-endian | the frame's bytes (MAVLink 1 or 2, as on the wire)
//! ```
//!
//! Received datagrams are split into frames by the mavlink crate's reader
//! (CRC-checked; bytes that are not a frame are left out). Times are the
//! wall clock's, kept non-decreasing within a file. Writes are buffered and
//! flushed once a second and when the link stops; a write error disables
//! the file with one warning and never stops the link.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use mavlink::dialects::common::MavMessage;
use mavlink::{MAVLinkMessageRaw, MavlinkReader};
use tracing::warn;

/// How often buffered frames reach the file.
const FLUSH_EVERY: Duration = Duration::from_secs(1);

/// The file name of link `index`'s telemetry log: `gcs.tlog` and
/// `api.tlog` for PX4's two links, `link2.tlog`, `link3.tlog`, ... for the
/// extra links, by their index among the daemon's links.
pub(super) fn file_name(index: usize, link_name: &str) -> String {
    match link_name {
        "GCS" => "gcs.tlog".into(),
        "API" => "api.tlog".into(),
        _ => format!("link{index}.tlog"),
    }
}

/// A link's telemetry log, or nothing (no `--log-dir`, or disabled after an error).
#[derive(Debug, Default)]
pub(super) struct Tlog {
    out: Option<(BufWriter<File>, PathBuf)>,
    last_us: u64,
    last_flush: Option<Instant>,
}

impl Tlog {
    /// Create `dir/name` (a warning and no log if it cannot be created).
    pub(super) fn create(dir: &Path, name: &str) -> Self {
        let path = dir.join(name);
        match File::create(&path) {
            Ok(f) => Self {
                out: Some((BufWriter::with_capacity(64 * 1024, f), path)),
                last_us: 0,
                last_flush: None,
            },
            Err(e) => {
                warn!(path = %path.display(), error = %e, "cannot create the telemetry log; the link runs without it");
                Self::default()
            }
        }
    }

    fn now_us(&mut self) -> u64 {
        let t = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| u64::try_from(d.as_micros()).unwrap_or(u64::MAX));
        self.last_us = self.last_us.max(t);
        self.last_us
    }

    /// Log one frame sent (a complete frame, as the link encoded it).
    pub(super) fn sent(&mut self, frame: &[u8]) {
        if self.out.is_none() {
            return;
        }
        let t = self.now_us();
        self.write(t, frame);
    }

    /// Log the frames of a datagram received.
    pub(super) fn received(&mut self, datagram: &[u8]) {
        if self.out.is_none() {
            return;
        }
        let t = self.now_us();
        let mut reader = MavlinkReader::new(datagram);
        // the reader ends with an error at the datagram's end
        while let Ok(raw) = reader.read_any_raw_message::<MavMessage>() {
            let bytes = match &raw {
                MAVLinkMessageRaw::V1(m) => m.raw_bytes(),
                MAVLinkMessageRaw::V2(m) => m.raw_bytes(),
            };
            self.write(t, bytes);
        }
    }

    fn write(&mut self, t_us: u64, frame: &[u8]) {
        let Some((w, path)) = &mut self.out else { return };
        let r = w.write_all(&t_us.to_be_bytes()).and_then(|()| w.write_all(frame));
        if let Err(e) = r {
            warn!(path = %path.display(), error = %e, "telemetry log write failed; logging stops for this link");
            self.out = None;
        }
    }

    /// Flush if the last flush is a second old (called from the link's timer).
    pub(super) fn flush_if_due(&mut self) {
        let now = Instant::now();
        if self.last_flush.is_some_and(|t| now.duration_since(t) < FLUSH_EVERY) {
            return;
        }
        self.last_flush = Some(now);
        self.flush();
    }

    /// Flush what is buffered.
    pub(super) fn flush(&mut self) {
        let Some((w, path)) = &mut self.out else { return };
        if let Err(e) = w.flush() {
            warn!(path = %path.display(), error = %e, "telemetry log write failed; logging stops for this link");
            self.out = None;
        }
    }
}

impl Drop for Tlog {
    fn drop(&mut self) {
        self.flush();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_by_link() {
        assert_eq!(file_name(0, "GCS"), "gcs.tlog");
        assert_eq!(file_name(1, "API"), "api.tlog");
        assert_eq!(file_name(2, "udpout:127.0.0.1:14560"), "link2.tlog");
    }

    #[test]
    fn a_datagram_of_two_frames_and_garbage_logs_two_records() {
        use crate::link::wire::Encoder;
        use mavlink::dialects::common::{HEARTBEAT_DATA, MavMessage};
        let dir = std::env::temp_dir().join(format!("rotorpilot-tlog-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut enc = Encoder::new(1, 1);
        let a = enc.message(&MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()));
        let b = enc.message(&MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()));
        let mut datagram = vec![0x00, 0x13];
        datagram.extend_from_slice(&a);
        datagram.extend_from_slice(&b);
        {
            let mut t = Tlog::create(&dir, "x.tlog");
            t.received(&datagram);
            t.sent(&a);
        }
        let bytes = std::fs::read(dir.join("x.tlog")).unwrap();
        assert_eq!(bytes.len(), 3 * 8 + 2 * a.len() + b.len());
        let rec = 8 + a.len();
        assert_eq!(&bytes[8..rec], &a[..]);
        assert_eq!(&bytes[rec + 8..2 * rec], &b[..]);
        let t0 = u64::from_be_bytes(bytes[..8].try_into().unwrap());
        let t2 = u64::from_be_bytes(bytes[2 * rec..2 * rec + 8].try_into().unwrap());
        assert!(t0 > 1_600_000_000_000_000 && t2 >= t0, "Unix microseconds, big-endian");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
