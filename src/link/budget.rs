//! Byte budgets that bound what a link sends, so that the vehicle cannot be
//! used to flood a third party:
//!
//! - [`TokenBucket`]: at most `rate` bytes per second on average and `burst`
//!   at once. A proven peer's direct answers, the answers to all unproven
//!   peers together, and a link's streams each draw from one.
//! - [`Credit`]: an unproven peer (one that has not shown it listens) may be
//!   sent at most [`UNPROVEN_FACTOR`] times the bytes it has sent, as QUIC
//!   limits a server before address validation (RFC 9000 §8.1), so a spoofed
//!   source draws at most that factor, whatever it asks for.
//!
//! Sans-I/O: the time comes in as an argument.

use std::time::Instant;

/// An unproven peer is sent at most this many bytes per byte it sent
/// (RFC 9000 §8.1's anti-amplification factor).
pub const UNPROVEN_FACTOR: usize = 3;
/// The most an unproven peer may have in hand [bytes]: a long flood from a
/// spoofed source does not buy a large burst later.
pub const UNPROVEN_MAX_CREDIT: usize = 4096;
/// Every unproven peer of a link together [bytes/s] (and as a burst).
pub const UNPROVEN_POOL_RATE: f64 = 8192.0;
/// A proven peer's direct answers (not streams) [bytes/s] (and as a burst):
/// a full parameter list is about 49 kB (PX4 SITL's multicopter parameters,
/// about 1,300 PARAM_VALUEs of 37 bytes; 66 kB signed), a mission item about
/// 50 bytes.
pub const PROVEN_RATE: f64 = 65_536.0;
/// A link's streams to all its peers together [bytes/s] (and twice as a
/// burst); heartbeats are never held back. Default rates to one peer are
/// estimated at about 12 kB/s (GCS link) and 20 kB/s (API link).
pub const LINK_STREAM_RATE: f64 = 1_000_000.0;

/// `tokens(t) = min(burst, tokens(t0) + rate · (t − t0))`; a take of `n`
/// bytes succeeds when `tokens ≥ n` and removes them.
#[derive(Clone, Debug)]
pub struct TokenBucket {
    rate: f64,
    burst: f64,
    tokens: f64,
    last: Instant,
}

impl TokenBucket {
    /// A full bucket at `now`: `rate` bytes/s, at most `burst` bytes in hand.
    #[must_use]
    pub fn new(now: Instant, rate: f64, burst: f64) -> Self {
        Self {
            rate,
            burst,
            tokens: burst,
            last: now,
        }
    }

    fn refill(&mut self, now: Instant) {
        let dt = now.saturating_duration_since(self.last).as_secs_f64();
        self.tokens = (self.tokens + self.rate * dt).min(self.burst);
        if now > self.last {
            self.last = now;
        }
    }

    /// Whether `n` bytes may go now (without taking them).
    pub fn allows(&mut self, now: Instant, n: usize) -> bool {
        self.refill(now);
        self.tokens >= n as f64
    }

    /// Take `n` bytes if they are in hand; false (nothing taken) if not.
    pub fn take(&mut self, now: Instant, n: usize) -> bool {
        let ok = self.allows(now, n);
        if ok {
            self.tokens -= n as f64;
        }
        ok
    }
}

/// What an unproven peer may still be sent:
/// `credit = min(UNPROVEN_MAX_CREDIT, UNPROVEN_FACTOR · received − sent)`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Credit(usize);

impl Credit {
    /// `n` bytes (a valid frame) were received from the peer.
    pub fn earn(&mut self, n: usize) {
        self.0 = (self.0 + UNPROVEN_FACTOR * n).min(UNPROVEN_MAX_CREDIT);
    }

    /// Whether `n` bytes may be sent.
    #[must_use]
    pub fn allows(self, n: usize) -> bool {
        self.0 >= n
    }

    /// Spend `n` bytes (checked with [`Credit::allows`] first).
    pub fn spend(&mut self, n: usize) {
        self.0 = self.0.saturating_sub(n);
    }
}

#[cfg(test)]
mod tests;
