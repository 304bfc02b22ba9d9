//! Log download as PX4's `mavlink_log_handler` answers it, sans I/O:
//! LOG_REQUEST_LIST gets one LOG_ENTRY per ULog in the range (id, num_logs,
//! last_log_num, time_utc, size), none when the range starts past the last
//! log (as PX4's handler since its 2024 rewrite), or one LOG_ENTRY with
//! num_logs 0 when there is no log at all; LOG_REQUEST_DATA opens the log
//! once and streams LOG_DATA of 90 bytes from `ofs` for `count` bytes (a
//! shorter one ends the file; a read error stops the transfer with a
//! warning rather than end the file short); LOG_REQUEST_END stops;
//! LOG_ERASE removes the logs. The list is taken afresh when a request's
//! range is wider than the list held (the flight being written is in it, at
//! its size then, as PX4 lists it) and kept for LOG_REQUEST_DATA until
//! LOG_REQUEST_END or LOG_ERASE. Everything sent is paced by the
//! requester's budget ([`super::budget`]).

use std::net::SocketAddr;
use std::time::{Duration, Instant};

use mavlink::dialects::common::{LOG_DATA_DATA, LOG_ENTRY_DATA, MavMessage};

use super::ftp::{LogFile, ReadFile};
use super::{Link, To};

/// Bytes of log a LOG_DATA carries.
pub const CHUNK: usize = 90;
/// Messages per turn...
const PER_TURN: usize = 32;
/// ...one turn this often.
const TURN: Duration = Duration::from_millis(5);
/// A transfer held back by the budget this long is dropped.
const STALL: Duration = Duration::from_secs(3);

/// What is being sent.
#[derive(Debug)]
enum Sending {
    /// LOG_ENTRY `next` to `last` (inclusive).
    Listing { next: u16, last: u16 },
    /// LOG_DATA of log `id` (open as `file`) from `ofs`, `remaining` bytes.
    Data {
        id: u16,
        file: Box<dyn ReadFile>,
        ofs: u32,
        remaining: u32,
    },
}

#[derive(Debug)]
struct Transfer {
    to: SocketAddr,
    sending: Sending,
    due: Instant,
    held_since: Option<Instant>,
}

/// One link's log-download state.
#[derive(Debug, Default)]
pub struct Server {
    /// The logs as listed at the first request (`None`: not listed).
    logs: Option<Vec<LogFile>>,
    transfer: Option<Transfer>,
}

impl Server {
    /// When [`Link::poll`] has log messages to send.
    #[must_use]
    pub fn next_deadline(&self) -> Option<Instant> {
        self.transfer.as_ref().map(|t| t.due)
    }
}

impl Link {
    /// LOG_REQUEST_LIST for us: list `start..=end` (clamped).
    pub(super) fn on_log_request_list(&mut self, now: Instant, from: SocketAddr, start: u16, end: u16) {
        // PX4 lists afresh when the range asked for is wider than the list
        // it holds (MAVSDK and QGroundControl ask for 0..0xFFFF)
        if self
            .logs
            .logs
            .as_ref()
            .is_none_or(|l| usize::from(end.saturating_sub(start)) > l.len())
        {
            self.logs.logs = Some(self.ftp.files().logs());
        }
        let logs = self.logs.logs.get_or_insert_with(Vec::new);
        let count = logs.len().min(usize::from(u16::MAX)) as u16;
        let (next, last) = if count == 0 {
            (0, 0)
        } else if start >= count {
            // PX4 skips the ids below `start` and sends none past its last
            return;
        } else {
            (start, end.min(count - 1))
        };
        self.logs.transfer = Some(Transfer {
            to: from,
            sending: Sending::Listing { next, last },
            due: now,
            held_since: None,
        });
        self.log_send(now);
    }

    /// LOG_REQUEST_DATA for us: stream `count` bytes of log `id` from `ofs`
    /// (PX4 ignores a request for a log it has not listed).
    pub(super) fn on_log_request_data(&mut self, now: Instant, from: SocketAddr, id: u16, ofs: u32, count: u32) {
        let Some(log) = self.logs.logs.as_ref().and_then(|l| l.get(usize::from(id))) else {
            return;
        };
        let file = match self.ftp.files().open(&log.path) {
            Ok(f) => f,
            Err(e) => {
                tracing::warn!(link = %self.config.name, log = %log.path, error = ?e, "log download: cannot open the log");
                return;
            }
        };
        // the size now: the flight being written grows
        let size = file.size().map_or(log.size, |s| u32::try_from(s).unwrap_or(u32::MAX));
        let remaining = size.saturating_sub(ofs).min(count);
        self.logs.transfer = Some(Transfer {
            to: from,
            sending: Sending::Data {
                id,
                file,
                ofs,
                remaining,
            },
            due: now,
            held_since: None,
        });
        self.log_send(now);
    }

    /// LOG_REQUEST_END: stop and forget the list.
    pub(super) fn on_log_request_end(&mut self) {
        self.logs = Server::default();
    }

    /// LOG_ERASE: remove the logs and forget the list.
    pub(super) fn on_log_erase(&mut self) {
        self.logs = Server::default();
        self.ftp.files().erase_logs();
    }

    /// Send what the transfer has due, as the budget allows.
    pub(super) fn log_send(&mut self, now: Instant) {
        let Some(mut t) = self.logs.transfer.take() else { return };
        if t.due > now {
            self.logs.transfer = Some(t);
            return;
        }
        for _ in 0..PER_TURN {
            // the message, the bytes of log it carries, whether the
            // transfer goes on after it (the state moves on once it is queued)
            let (msg, n, more) = match &t.sending {
                Sending::Listing { next, last } => {
                    let logs = self.logs.logs.as_deref().unwrap_or_default();
                    let entry = logs.get(usize::from(*next));
                    let msg = MavMessage::LOG_ENTRY(LOG_ENTRY_DATA {
                        time_utc: entry.map_or(0, |e| e.time_utc),
                        size: entry.map_or(0, |e| e.size),
                        id: *next,
                        num_logs: logs.len().min(usize::from(u16::MAX)) as u16,
                        last_log_num: *last,
                    });
                    (msg, 0, *next < *last)
                }
                Sending::Data {
                    id,
                    file,
                    ofs,
                    remaining,
                } => {
                    let mut data = [0u8; CHUNK];
                    let want = (*remaining as usize).min(CHUNK);
                    let n = match file.read_at(u64::from(*ofs), &mut data[..want]) {
                        Ok(n) => n,
                        Err(e) => {
                            // a short LOG_DATA would tell the client the log ends here
                            tracing::warn!(
                                link = %self.config.name, id = *id, ofs = *ofs, error = ?e,
                                "log download: cannot read the log; the transfer stops"
                            );
                            return;
                        }
                    };
                    let msg = MavMessage::LOG_DATA(LOG_DATA_DATA {
                        ofs: *ofs,
                        id: *id,
                        count: n as u8,
                        data,
                    });
                    let n = n as u32;
                    (msg, n, n as usize == CHUNK && *remaining > n)
                }
            };
            let bytes = self.encoder.message(&msg);
            if !self.queue(To::Peer(t.to), bytes) {
                let since = *t.held_since.get_or_insert(now);
                if now.saturating_duration_since(since) <= STALL {
                    t.due = now + TURN;
                    self.logs.transfer = Some(t);
                }
                return;
            }
            t.held_since = None;
            if !more {
                return;
            }
            match &mut t.sending {
                Sending::Listing { next, .. } => *next += 1,
                Sending::Data { ofs, remaining, .. } => {
                    *ofs += n;
                    *remaining -= n;
                }
            }
        }
        t.due = now + TURN;
        self.logs.transfer = Some(t);
    }
}

#[cfg(test)]
mod tests;
