//! One link's MAVLink telemetry log (`<run dir>/<link>.tlog`), the format
//! MAVProxy, MAVExplorer, QGroundControl and pymavlink's `mavlogfile` read:
//! for every frame the link sent or received,
//!
//! ```text
//! unix_time_us u64 big-endian | the frame's bytes (MAVLink 1 or 2, as on the wire)
//! ```
//!
//! What is logged:
//! - every frame the link sends, as encoded;
//! - every frame in a datagram the link receives, of any dialect and any
//!   message id, split by the header's length fields alone (no CRC check,
//!   no dialect lookup; [`split_frames`]): a MAVLink 1 frame (`0xFE`) is
//!   `6 + len + 2` bytes, a MAVLink 2 frame (`0xFD`) `10 + len + 2`, plus a
//!   13-byte signature when `incompat_flags & 1`. Bytes before a start
//!   marker are skipped; a frame cut short at the datagram's end is left
//!   out (it cannot be a frame that went over the wire whole, and a log
//!   reader would take the next record's timestamp for its missing bytes).
//!   A frame with a bad CRC is logged as received: the log shows the wire.
//!
//! Times are the wall clock's, kept non-decreasing within a file. Writes are
//! buffered and flushed once a second and when the link stops; a write error
//! disables the file with one warning and never stops the link.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

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
        for frame in split_frames(datagram) {
            self.write(t, frame);
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

/// MAVLink 1 start marker; a frame is `6 + len + 2` bytes (header, payload, CRC).
const STX_V1: u8 = 0xFE;
/// MAVLink 2 start marker; a frame is `10 + len + 2` bytes, `+ 13` when signed.
const STX_V2: u8 = 0xFD;
/// MAVLink 2 `incompat_flags` bit: the frame carries a 13-byte signature.
const IFLAG_SIGNED: u8 = 0x01;

/// The frames of a received datagram, split by the header's length fields
/// (byte 1 is the payload length in both versions; byte 2 of a MAVLink 2
/// frame is `incompat_flags`). Bytes before a start marker are skipped; a
/// frame running past the datagram's end is dropped. No CRC or message-id
/// check: frames of every dialect are kept.
fn split_frames(datagram: &[u8]) -> Vec<&[u8]> {
    let mut frames = Vec::new();
    let mut i = 0;
    while i < datagram.len() {
        let rest = &datagram[i..];
        let need = match rest[0] {
            STX_V1 if rest.len() >= 2 => 6 + usize::from(rest[1]) + 2,
            STX_V2 if rest.len() >= 3 => {
                let sig = if rest[2] & IFLAG_SIGNED != 0 { 13 } else { 0 };
                10 + usize::from(rest[1]) + 2 + sig
            }
            STX_V1 | STX_V2 => break, // a header cut short
            _ => {
                i += 1;
                continue;
            }
        };
        if rest.len() < need {
            break;
        }
        frames.push(&rest[..need]);
        i += need;
    }
    frames
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

    /// A MAVLink 2 frame built by hand: header, payload, a CRC that is not
    /// checked, and the signature when `signed`.
    fn v2_frame(msgid: u32, payload: &[u8], signed: bool) -> Vec<u8> {
        let len = u8::try_from(payload.len()).unwrap();
        let mut f = vec![STX_V2, len, u8::from(signed), 0, 7, 1, 1];
        f.extend_from_slice(&msgid.to_le_bytes()[..3]);
        f.extend_from_slice(payload);
        f.extend_from_slice(&[0xAB, 0xCD]);
        if signed {
            f.extend(1..=13u8);
        }
        f
    }

    #[test]
    fn split_keeps_common_unknown_and_signed_frames_and_skips_garbage() {
        use crate::link::wire::Encoder;
        use mavlink::dialects::common::{HEARTBEAT_DATA, MavMessage};
        let common = Encoder::new(1, 1).message(&MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()));
        // 11020 is ardupilotmega's ESC_TELEMETRY_1_TO_4, not in `common`
        let unknown = v2_frame(11_020, &[0x55; 44], false);
        let signed = v2_frame(0, &[1, 2, 3, 4, 5, 6, 7, 8, 9], true);
        let v1 = [STX_V1, 2, 9, 1, 1, 150, 0x10, 0x20, 0x33, 0x44];
        let mut d = vec![0x00, 0x13];
        d.extend_from_slice(&common);
        d.extend_from_slice(&[0x42, 0x99, 0x00]);
        d.extend_from_slice(&unknown);
        d.extend_from_slice(&signed);
        d.push(0x07);
        d.extend_from_slice(&v1);
        let frames = split_frames(&d);
        assert_eq!(frames, vec![&common[..], &unknown[..], &signed[..], &v1[..]]);
        assert_eq!(signed.len(), 10 + 9 + 2 + 13);
    }

    #[test]
    fn split_drops_a_frame_cut_short() {
        let whole = v2_frame(30, &[0; 28], false);
        let mut d = whole.clone();
        d.extend_from_slice(&whole[..whole.len() - 1]);
        assert_eq!(split_frames(&d), vec![&whole[..]]);
        assert_eq!(split_frames(&[STX_V2, 5]), Vec::<&[u8]>::new());
        assert_eq!(split_frames(&[]), Vec::<&[u8]>::new());
        // a signed frame without its whole signature
        let signed = v2_frame(0, &[0; 9], true);
        assert_eq!(split_frames(&signed[..signed.len() - 1]), Vec::<&[u8]>::new());
    }
}
