//! MAVLink 2 message signing (<https://mavlink.io/en/guide/message_signing.html>),
//! sans I/O: the vehicle's secret key, its signing timestamp and the
//! per-stream timestamps of what it accepted. The cryptography is the
//! `mavlink` crate's (`MAVLinkV2MessageRaw::calculate_signature`):
//!
//! ```text
//! signature = SHA-256(key[32] ‖ frame from STX to CRC ‖ link_id ‖ timestamp[6 LE])[0..6]
//! timestamp = 10 µs units since 2015-01-01 00:00:00 UTC (48 bits)
//! ```
//!
//! One [`Signing`] per vehicle, shared by its links ([`Shared`]); each link
//! signs with its own link id (its index: gcs 0, api 1, extra links 2...).
//!
//! **With no key** every frame is accepted and nothing is signed; a
//! SETUP_SIGNING (256) aimed at the vehicle, signed or not, installs a key.
//!
//! **With a key**, what [`Signing::check`] accepts (as PX4's
//! `MavlinkSignControl` with `MAV_x_SIGN` = always, the mode a key is for):
//! - a signed MAVLink 2 frame whose signature matches the key, whose
//!   timestamp is above the last one accepted on its stream (link id, system,
//!   component), and, on a stream not seen yet, no more than one minute
//!   ([`NEW_STREAM_WINDOW`]) behind our latest timestamp;
//! - unsigned (MAVLink 1, or MAVLink 2 without signature) only the messages
//!   of [`UNSIGNED_ALLOWED`]: RADIO_STATUS (109), ADSB_VEHICLE (246) and
//!   COLLISION (247). PX4 takes these unsigned because they come from
//!   equipment that cannot hold the key (a telemetry radio's own status, an
//!   ADS-B receiver, a traffic/collision service), and none commands the vehicle.
//!
//! Everything else is refused: counted ([`SigningStats`]), not answered (PX4
//! answers nothing either), and never learned as a peer. A SETUP_SIGNING can
//! then only arrive signed with the current key: it changes the key, or an
//! all-zero key clears it (signing off).
//!
//! Outgoing frames are signed with our timestamp = max(now, last + 1), which
//! also never falls below a timestamp we accepted; at start it begins above
//! the stored one plus [`PERSIST_INTERVAL`] (the daemon stores it that often),
//! so it stays monotonic across restarts and crashes.

use std::collections::HashMap;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use mavlink::MAVLinkV2MessageRaw;

use super::wire::Frame;

/// Length of the secret key [bytes].
pub const KEY_LEN: usize = 32;
/// SETUP_SIGNING message id.
pub const SETUP_SIGNING_ID: u32 = 256;
/// Messages accepted unsigned while a key is set (PX4's `unsigned_messages`):
/// RADIO_STATUS, ADSB_VEHICLE, COLLISION.
pub const UNSIGNED_ALLOWED: [u32; 3] = [109, 246, 247];
/// A new stream's first timestamp may be this far behind ours: one minute [10 µs].
pub const NEW_STREAM_WINDOW: u64 = 60 * 100_000;
/// 2015-01-01 00:00:00 UTC in Unix seconds: the signing timestamp's epoch.
pub const EPOCH_2015_UNIX_S: u64 = 1_420_070_400;
/// How often the daemon stores the timestamp; a restart begins this far above
/// the stored one.
pub const PERSIST_INTERVAL: Duration = Duration::from_secs(10);
/// Length of a signature block: link id, timestamp, signature [bytes].
const SIGNATURE_LEN: usize = 13;
/// MAVLink 2 incompatibility flag: signed.
const IFLAG_SIGNED: u8 = 0x01;

/// A secret key.
pub type Key = [u8; KEY_LEN];

/// The signing timestamp [10 µs since 2015-01-01] of a Unix time [µs].
#[must_use]
pub fn timestamp_from_unix_us(unix_us: u64) -> u64 {
    unix_us.saturating_sub(EPOCH_2015_UNIX_S * 1_000_000) / 10
}

/// `d` in timestamp units [10 µs].
fn ticks(d: Duration) -> u64 {
    u64::try_from(d.as_micros() / 10).unwrap_or(u64::MAX)
}

/// What the vehicle keeps on disk: the key (all zeros: none) and the last
/// timestamp. File format (PX4's `mavlink/mavlink-signing-key.bin`): the 32
/// key bytes, then the timestamp as a little-endian u64: 40 bytes.
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct Stored {
    /// The key; all zeros when signing is off.
    pub key: Key,
    /// Our latest signing timestamp [10 µs since 2015].
    pub timestamp: u64,
}

impl std::fmt::Debug for Stored {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // never print the key
        f.debug_struct("Stored")
            .field("keyed", &(self.key != [0; KEY_LEN]))
            .field("timestamp", &self.timestamp)
            .finish()
    }
}

impl Stored {
    /// Length of the file [bytes].
    pub const LEN: usize = KEY_LEN + 8;

    /// The file's bytes.
    #[must_use]
    pub fn to_bytes(&self) -> [u8; Self::LEN] {
        let mut b = [0u8; Self::LEN];
        b[..KEY_LEN].copy_from_slice(&self.key);
        b[KEY_LEN..].copy_from_slice(&self.timestamp.to_le_bytes());
        b
    }

    /// Read the file's bytes.
    ///
    /// # Errors
    /// The length is not [`Stored::LEN`] (the message says what it is).
    pub fn from_bytes(b: &[u8]) -> Result<Self, String> {
        if b.len() != Self::LEN {
            return Err(format!(
                "{} bytes, expected {} (32-byte key, then the timestamp as a little-endian u64)",
                b.len(),
                Self::LEN
            ));
        }
        let mut key = [0u8; KEY_LEN];
        key.copy_from_slice(&b[..KEY_LEN]);
        let mut ts = [0u8; 8];
        ts.copy_from_slice(&b[KEY_LEN..]);
        Ok(Self {
            key,
            timestamp: u64::from_le_bytes(ts),
        })
    }
}

/// Why a frame was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Refusal {
    /// Unsigned (MAVLink 1 or 2) and not in [`UNSIGNED_ALLOWED`].
    Unsigned,
    /// The signature does not match the key.
    BadSignature,
    /// The timestamp is not above the last one accepted on its stream.
    Replay,
    /// A new stream more than [`NEW_STREAM_WINDOW`] behind our timestamp.
    Stale,
}

/// What the gate counted.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SigningStats {
    /// Signed frames accepted.
    pub accepted_signed: u64,
    /// Refused: unsigned.
    pub unsigned: u64,
    /// Refused: wrong signature.
    pub bad_signature: u64,
    /// Refused: replayed (timestamp not increasing on its stream).
    pub replay: u64,
    /// Refused: a new stream with a stale timestamp.
    pub stale: u64,
}

/// A vehicle's signing state, shared by its links.
pub type Shared = Arc<Mutex<Signing>>;

/// Lock a [`Shared`] (a poisoned lock still holds a consistent state: every
/// change is one assignment).
pub fn lock(s: &Shared) -> MutexGuard<'_, Signing> {
    s.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// One vehicle's key, timestamp and accepted streams.
#[derive(Debug)]
pub struct Signing {
    key: Option<Key>,
    /// Our latest timestamp: the last one we signed with, or a higher one we accepted.
    timestamp: u64,
    /// The clock: the timestamp at `at` [10 µs since 2015].
    clock: (Instant, u64),
    /// Last accepted timestamp per (link id, system, component).
    streams: HashMap<(u8, u8, u8), u64>,
    stats: SigningStats,
}

impl Signing {
    /// A vehicle without a key (signing off) whose clock reads `now_ts` at `at`.
    #[must_use]
    pub fn unkeyed(at: Instant, now_ts: u64) -> Self {
        Self {
            key: None,
            timestamp: 0,
            clock: (at, now_ts),
            streams: HashMap::new(),
            stats: SigningStats::default(),
        }
    }

    /// The state a stored file gives, started at `at` when the clock reads
    /// `now_ts`: the key (none if all zeros) and a timestamp above the stored
    /// one by [`PERSIST_INTERVAL`] (what may have been sent after the last store).
    #[must_use]
    pub fn restored(stored: Stored, at: Instant, now_ts: u64) -> Self {
        let mut s = Self::unkeyed(at, now_ts);
        s.key = (stored.key != [0; KEY_LEN]).then_some(stored.key);
        s.timestamp = stored.timestamp.saturating_add(ticks(PERSIST_INTERVAL));
        s
    }

    /// True when a key is set (frames are checked and signed).
    #[must_use]
    pub fn is_keyed(&self) -> bool {
        self.key.is_some()
    }

    /// Counters.
    #[must_use]
    pub fn stats(&self) -> SigningStats {
        self.stats
    }

    /// Our latest timestamp [10 µs since 2015].
    #[must_use]
    pub fn timestamp(&self) -> u64 {
        self.timestamp
    }

    /// What to store: key (zeros: none) and timestamp, raised to the clock at `at`.
    #[must_use]
    pub fn stored(&self, at: Instant) -> Stored {
        Stored {
            key: self.key.unwrap_or([0; KEY_LEN]),
            timestamp: self.timestamp.max(self.clock_at(at)),
        }
    }

    fn clock_at(&self, at: Instant) -> u64 {
        self.clock.1 + ticks(at.saturating_duration_since(self.clock.0))
    }

    /// SETUP_SIGNING accepted: install `key` (all zeros: clear it); our
    /// timestamp becomes at least `initial_timestamp`. Streams start afresh.
    pub fn setup(&mut self, key: Key, initial_timestamp: u64) {
        self.key = (key != [0; KEY_LEN]).then_some(key);
        self.timestamp = self.timestamp.max(initial_timestamp);
        self.streams.clear();
    }

    /// The gate: may `frame` (received at `at`) be handled? Without a key, yes.
    /// With one: see the module doc. Refusals are counted.
    pub fn check(&mut self, frame: &Frame<'_>, at: Instant) -> Result<(), Refusal> {
        let Some(key) = self.key else {
            return Ok(());
        };
        let r = self.verify(&key, frame, at);
        match r {
            Ok(true) => self.stats.accepted_signed += 1,
            Ok(false) => {}
            Err(Refusal::Unsigned) => self.stats.unsigned += 1,
            Err(Refusal::BadSignature) => self.stats.bad_signature += 1,
            Err(Refusal::Replay) => self.stats.replay += 1,
            Err(Refusal::Stale) => self.stats.stale += 1,
        }
        r.map(|_| ())
    }

    /// `Ok(true)`: signed and valid; `Ok(false)`: unsigned but allowed.
    fn verify(&mut self, key: &Key, frame: &Frame<'_>, at: Instant) -> Result<bool, Refusal> {
        let Some(sig) = frame.signature() else {
            return if UNSIGNED_ALLOWED.contains(&frame.message_id) {
                Ok(false)
            } else {
                Err(Refusal::Unsigned)
            };
        };
        let link_id = sig[0];
        let mut ts = [0u8; 8];
        ts[..6].copy_from_slice(&sig[1..7]);
        let timestamp = u64::from_le_bytes(ts);
        let stream = (link_id, frame.system_id, frame.component_id);
        self.timestamp = self.timestamp.max(self.clock_at(at));
        match self.streams.get(&stream) {
            Some(last) if timestamp <= *last => return Err(Refusal::Replay),
            None if timestamp + NEW_STREAM_WINDOW < self.timestamp => return Err(Refusal::Stale),
            _ => {}
        }
        if signature(key, frame.bytes) != sig[7..13] {
            return Err(Refusal::BadSignature);
        }
        self.streams.insert(stream, timestamp);
        self.timestamp = self.timestamp.max(timestamp);
        Ok(true)
    }

    /// Sign an unsigned MAVLink 2 frame in place with `link_id` (no key: leave it).
    /// Timestamp: max(clock at `at`, last + 1).
    pub fn sign(&mut self, frame: &mut Vec<u8>, link_id: u8, at: Instant) {
        let Some(key) = self.key else {
            return;
        };
        self.timestamp = self.clock_at(at).max(self.timestamp + 1);
        sign_frame(&key, frame, link_id, self.timestamp);
    }
}

/// The 6-byte signature of a signed MAVLink 2 `frame` (its signature block's
/// link id and timestamp included, its signature bytes not): the crate's
/// `calculate_signature`. A frame too long for the crate's buffer gets zeros
/// (it cannot be a valid frame).
#[must_use]
pub fn signature(key: &Key, frame: &[u8]) -> [u8; 6] {
    let mut out = [0u8; 6];
    let mut buf = [0u8; mavlink::consts::MAX_FRAME_SIZE];
    if frame.len() > buf.len() {
        return out;
    }
    buf[..frame.len()].copy_from_slice(frame);
    MAVLinkV2MessageRaw::from_bytes_unparsed(buf).calculate_signature(key, &mut out);
    out
}

/// Turn an unsigned MAVLink 2 frame into a signed one: set the signed flag,
/// recompute the CRC (it covers the flags), append link id, `timestamp` (48
/// bits LE) and the signature. Anything else (MAVLink 1, already signed) is
/// left alone.
pub fn sign_frame(key: &Key, frame: &mut Vec<u8>, link_id: u8, timestamp: u64) {
    if frame.len() < 12 || frame[0] != 0xFD || frame[2] & IFLAG_SIGNED != 0 {
        return;
    }
    let n = frame.len();
    frame[2] |= IFLAG_SIGNED;
    let message_id = u32::from_le_bytes([frame[7], frame[8], frame[9], 0]);
    let crc = mavlink::calculate_crc(
        &frame[1..n - 2],
        <mavlink::dialects::common::MavMessage as mavlink::Message>::extra_crc(message_id),
    );
    frame[n - 2..].copy_from_slice(&crc.to_le_bytes());
    frame.push(link_id);
    frame.extend_from_slice(&timestamp.to_le_bytes()[..6]);
    frame.extend_from_slice(&[0; 6]);
    let sig = signature(key, frame);
    let m = frame.len();
    frame[m - 6..].copy_from_slice(&sig);
    debug_assert_eq!(frame.len(), n + SIGNATURE_LEN);
}

#[cfg(test)]
mod tests;
