//! The peers a link serves: its default remote (PX4 sends there from boot,
//! before anyone talks) plus every address that has sent it a MAVLink frame
//! within the timeout. PX4 locks onto the first sender for good; serving a set
//! of peers instead lets a GCS and a script share a link, and a client that
//! restarts on a new port is served again at once.

use std::net::SocketAddr;
use std::time::{Duration, Instant};

/// At most this many learned peers per link; the one heard from longest ago
/// is dropped to make room.
pub const MAX_PEERS: usize = 16;

/// Default remote plus learned peers with their last-heard time.
#[derive(Clone, Debug)]
pub struct Peers {
    default_remote: Option<SocketAddr>,
    learned: Vec<(SocketAddr, Instant)>,
    timeout: Duration,
}

impl Peers {
    /// A table that always includes `default_remote` and forgets a learned
    /// peer after `timeout` without a frame from it.
    #[must_use]
    pub fn new(default_remote: Option<SocketAddr>, timeout: Duration) -> Self {
        Self {
            default_remote,
            learned: Vec::new(),
            timeout,
        }
    }

    /// Note a frame from `addr`. Returns true if the peer is new.
    pub fn heard(&mut self, now: Instant, addr: SocketAddr) -> bool {
        if let Some(p) = self.learned.iter_mut().find(|p| p.0 == addr) {
            p.1 = now;
            return false;
        }
        self.expire(now);
        if self.learned.len() >= MAX_PEERS
            && let Some(oldest) = self.learned.iter().enumerate().min_by_key(|(_, p)| p.1).map(|(i, _)| i)
        {
            self.learned.swap_remove(oldest);
        }
        self.learned.push((addr, now));
        true
    }

    /// Drop peers not heard from within the timeout.
    pub fn expire(&mut self, now: Instant) {
        let timeout = self.timeout;
        self.learned.retain(|p| now.saturating_duration_since(p.1) <= timeout);
    }

    /// Every address to send streams to: the default remote first, then the
    /// live learned peers (each once).
    pub fn active(&mut self, now: Instant, out: &mut Vec<SocketAddr>) {
        self.expire(now);
        out.clear();
        if let Some(d) = self.default_remote {
            out.push(d);
        }
        for (a, _) in &self.learned {
            if Some(*a) != self.default_remote {
                out.push(*a);
            }
        }
    }

    /// The default remote.
    #[must_use]
    pub fn default_remote(&self) -> Option<SocketAddr> {
        self.default_remote
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn addr(p: u16) -> SocketAddr {
        SocketAddr::from(([127, 0, 0, 1], p))
    }

    #[test]
    fn default_remote_is_always_served_and_peers_expire() {
        let t0 = Instant::now();
        let mut p = Peers::new(Some(addr(14540)), Duration::from_secs(10));
        let mut out = Vec::new();
        p.active(t0, &mut out);
        assert_eq!(out, vec![addr(14540)]);
        assert!(p.heard(t0, addr(50000)));
        assert!(!p.heard(t0, addr(50000)));
        assert!(p.heard(t0, addr(14540)));
        p.active(t0 + Duration::from_secs(5), &mut out);
        assert_eq!(out, vec![addr(14540), addr(50000)]);
        // a client restarting on a new port is served next to the old one
        assert!(p.heard(t0 + Duration::from_secs(6), addr(50001)));
        p.active(t0 + Duration::from_secs(12), &mut out);
        assert_eq!(out, vec![addr(14540), addr(50001)]);
    }

    #[test]
    fn table_is_bounded() {
        let t0 = Instant::now();
        let mut p = Peers::new(None, Duration::from_secs(10));
        for i in 0..(MAX_PEERS as u16 + 4) {
            p.heard(t0 + Duration::from_millis(u64::from(i)), addr(40000 + i));
        }
        let mut out = Vec::new();
        p.active(t0 + Duration::from_millis(100), &mut out);
        assert_eq!(out.len(), MAX_PEERS);
        assert!(!out.contains(&addr(40000)));
        assert!(out.contains(&addr(40000 + MAX_PEERS as u16 + 3)));
    }
}
