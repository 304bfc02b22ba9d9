//! The peers a link serves: its default remote (PX4 sends there from boot,
//! before anyone talks) plus the addresses that have sent it a MAVLink frame
//! within the timeout. PX4 locks onto the first sender for good; serving a set
//! of peers instead lets a GCS and a script share a link, and a client that
//! restarts on a new port is served again at once.
//!
//! A UDP source address can be forged, so a peer is learned in two stages
//! (no amplification):
//!
//! - **unproven** (any valid frame): it gets direct answers only, at most
//!   [`budget::UNPROVEN_FACTOR`] times the bytes it sent ([`budget::Credit`])
//!   and, all unproven peers of the link together, at most
//!   [`budget::UNPROVEN_POOL_RATE`] bytes/s. No streams.
//! - **proven** (a HEARTBEAT, which every GCS, MAVSDK and MAVProxy sends at
//!   1 Hz, or a mission handshake, which only a listener can carry on): it
//!   gets the streams and direct answers up to [`budget::PROVEN_RATE`]
//!   bytes/s. The default remote is proven from boot.
//!
//! The table holds at most [`MAX_PROVEN`] proven and [`MAX_UNPROVEN`]
//! unproven peers; unproven ones never displace a proven one, and a proven
//! one heard within [`LIVE`] is never displaced at all.

use std::net::SocketAddr;
use std::time::{Duration, Instant};

use super::budget::{self, Credit, TokenBucket};

/// At most this many proven peers per link (besides the default remote).
pub const MAX_PROVEN: usize = 16;
/// At most this many unproven peers per link; the one heard from longest
/// ago makes room for a new one.
pub const MAX_UNPROVEN: usize = 64;
/// A proven peer heard within this is live (a GCS heartbeats at 1 Hz) and is
/// never dropped to make room for another.
pub const LIVE: Duration = Duration::from_secs(3);

/// What a peer has shown.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Standing {
    /// The default remote: served from boot, never forgotten.
    Default,
    /// It listens: streams and direct answers within [`budget::PROVEN_RATE`].
    Proven,
    /// Only talked so far: direct answers within its credit.
    Unproven,
}

#[derive(Clone, Debug)]
struct Peer {
    addr: SocketAddr,
    heard: Instant,
    proven: bool,
    credit: Credit,
    budget: TokenBucket,
}

/// Default remote plus learned peers with their last-heard time and budgets.
#[derive(Clone, Debug)]
pub struct Peers {
    default_remote: Option<SocketAddr>,
    default_budget: TokenBucket,
    learned: Vec<Peer>,
    /// What all unproven peers together may be sent.
    pool: TokenBucket,
    timeout: Duration,
}

fn proven_bucket(now: Instant) -> TokenBucket {
    TokenBucket::new(now, budget::PROVEN_RATE, budget::PROVEN_RATE)
}

impl Peers {
    /// A table that always includes `default_remote` and forgets a learned
    /// peer after `timeout` without a frame from it.
    #[must_use]
    pub fn new(default_remote: Option<SocketAddr>, timeout: Duration, now: Instant) -> Self {
        Self {
            default_remote,
            default_budget: proven_bucket(now),
            learned: Vec::new(),
            pool: TokenBucket::new(now, budget::UNPROVEN_POOL_RATE, budget::UNPROVEN_POOL_RATE),
            timeout,
        }
    }

    /// Note a valid frame of `len` bytes from `addr` (an unproven peer earns
    /// credit for it). Returns true if the peer is new.
    pub fn heard(&mut self, now: Instant, addr: SocketAddr, len: usize) -> bool {
        if Some(addr) == self.default_remote {
            return false;
        }
        if let Some(p) = self.learned.iter_mut().find(|p| p.addr == addr) {
            p.heard = now;
            if !p.proven {
                p.credit.earn(len);
            }
            return false;
        }
        self.expire(now);
        if self.learned.iter().filter(|p| !p.proven).count() >= MAX_UNPROVEN
            && let Some(oldest) = self.oldest(|p| !p.proven)
        {
            self.learned.swap_remove(oldest);
        }
        let mut credit = Credit::default();
        credit.earn(len);
        self.learned.push(Peer {
            addr,
            heard: now,
            proven: false,
            credit,
            budget: proven_bucket(now),
        });
        true
    }

    /// `addr` has shown it listens (heard first with [`Peers::heard`]).
    /// Returns true if it became proven now. When the proven table is full
    /// the peer heard from longest ago makes room, unless it is live
    /// ([`LIVE`]): then the newcomer stays unproven.
    pub fn prove(&mut self, now: Instant, addr: SocketAddr) -> bool {
        let Some(i) = self.learned.iter().position(|p| p.addr == addr) else {
            return false;
        };
        if self.learned[i].proven {
            return false;
        }
        if self.learned.iter().filter(|p| p.proven).count() >= MAX_PROVEN {
            match self.oldest(|p| p.proven) {
                Some(o) if now.saturating_duration_since(self.learned[o].heard) > LIVE => {
                    self.learned.swap_remove(o);
                }
                _ => return false,
            }
        }
        let p = self
            .learned
            .iter_mut()
            .find(|p| p.addr == addr)
            .expect("still in the table");
        p.proven = true;
        p.budget = proven_bucket(now);
        true
    }

    /// What `addr` has shown (`None`: not in the table).
    #[must_use]
    pub fn standing(&self, addr: SocketAddr) -> Option<Standing> {
        if Some(addr) == self.default_remote {
            return Some(Standing::Default);
        }
        self.learned
            .iter()
            .find(|p| p.addr == addr)
            .map(|p| if p.proven { Standing::Proven } else { Standing::Unproven })
    }

    /// Charge `n` bytes of a direct answer to `addr`: true if they may go
    /// (and are counted), false if they must be dropped or wait. An address
    /// not in the table gets nothing.
    pub fn charge(&mut self, now: Instant, addr: SocketAddr, n: usize) -> bool {
        if Some(addr) == self.default_remote {
            return self.default_budget.take(now, n);
        }
        let Some(p) = self.learned.iter_mut().find(|p| p.addr == addr) else {
            return false;
        };
        if p.proven {
            return p.budget.take(now, n);
        }
        if p.credit.allows(n) && self.pool.take(now, n) {
            p.credit.spend(n);
            true
        } else {
            false
        }
    }

    fn oldest(&self, which: impl Fn(&Peer) -> bool) -> Option<usize> {
        self.learned
            .iter()
            .enumerate()
            .filter(|(_, p)| which(p))
            .min_by_key(|(_, p)| p.heard)
            .map(|(i, _)| i)
    }

    /// Drop peers not heard from within the timeout.
    pub fn expire(&mut self, now: Instant) {
        let timeout = self.timeout;
        self.learned
            .retain(|p| now.saturating_duration_since(p.heard) <= timeout);
    }

    /// Every address to send streams to: the default remote first, then the
    /// live proven peers (each once).
    pub fn active(&mut self, now: Instant, out: &mut Vec<SocketAddr>) {
        self.expire(now);
        out.clear();
        if let Some(d) = self.default_remote {
            out.push(d);
        }
        out.extend(self.learned.iter().filter(|p| p.proven).map(|p| p.addr));
    }

    /// How many addresses [`Peers::active`] lists now.
    pub fn active_count(&mut self, now: Instant) -> usize {
        self.expire(now);
        usize::from(self.default_remote.is_some()) + self.learned.iter().filter(|p| p.proven).count()
    }

    /// The default remote.
    #[must_use]
    pub fn default_remote(&self) -> Option<SocketAddr> {
        self.default_remote
    }
}

#[cfg(test)]
mod tests;
