//! Status texts (MAVLink STATUSTEXT): their severity, the queue the flight
//! stack announces into, and the one rule for fitting a text into the
//! 50 bytes one STATUSTEXT holds, used by the flight stack, the link and the
//! daemon alike.
//!
//! PX4's mavlink module sends a longer text as numbered chunks (a shared
//! `id`, `chunk_seq` 0, 1, ...: every chunk but the last exactly 50 bytes)
//! for clients to join again. A client that does not join chunks shows the
//! pieces cut mid-word, so here a longer text becomes complete lines instead
//! (`id` 0: "the only chunk, show it at once"), each at most 50 bytes, cut
//! after a space or a path separator where one lies in the second half of
//! the line ([`status_text_lines`]). The flight stack's own texts are
//! written to fit one message; one that does not is cut to its first
//! 50 bytes ([`cut_status_text`]) before it is queued.

use std::collections::VecDeque;

use serde::Serialize;

/// The most bytes of text one STATUSTEXT holds.
pub const STATUS_TEXT_LEN: usize = 50;

/// STATUSTEXT severity (MAV_SEVERITY).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum Severity {
    /// 0
    Emergency,
    /// 2
    Critical,
    /// 3
    Error,
    /// 4
    Warning,
    /// 5
    Notice,
    /// 6
    Info,
}

/// An event to announce as STATUSTEXT.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct StatusText {
    /// Severity.
    pub severity: Severity,
    /// Text (at most [`STATUS_TEXT_LEN`] bytes fit one STATUSTEXT).
    pub text: String,
}

/// The byte length of the longest start of `text` that fits one
/// STATUSTEXT: [`STATUS_TEXT_LEN`] bytes, less on a character boundary.
fn fitting_len(text: &str) -> usize {
    let mut end = text.len().min(STATUS_TEXT_LEN);
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    end
}

/// `text` cut to what one STATUSTEXT holds (its first 50 bytes, on a
/// character boundary).
#[must_use]
pub fn cut_status_text(text: &str) -> &str {
    &text[..fitting_len(text)]
}

/// `text` (trimmed) as STATUSTEXT lines of at most 50 bytes each, cut after
/// a space or `/` in the second half of a line where there is one (a path
/// and an OS error do not fit one STATUSTEXT), else at 50 bytes; the lines
/// are trimmed and none is empty (an empty text gives none).
#[must_use]
pub fn status_text_lines(text: &str) -> Vec<&str> {
    let mut lines = Vec::new();
    let mut rest = text.trim();
    while rest.len() > STATUS_TEXT_LEN {
        let end = fitting_len(rest);
        let cut = rest[..end]
            .rfind([' ', '/'])
            .filter(|&k| k > STATUS_TEXT_LEN / 2)
            .map_or(end, |k| k + 1);
        lines.push(rest[..cut].trim_end());
        rest = rest[cut..].trim_start();
    }
    if !rest.is_empty() {
        lines.push(rest);
    }
    lines
}

/// Status texts waiting to be sent, oldest first; the oldest are dropped beyond 64.
#[derive(Clone, Debug, Default)]
pub(super) struct Announcements(VecDeque<StatusText>);

impl Announcements {
    const CAPACITY: usize = 64;

    /// Queue `text` (cut to one STATUSTEXT).
    pub(super) fn announce(&mut self, severity: Severity, text: impl Into<String>) {
        if self.0.len() >= Self::CAPACITY {
            self.0.pop_front();
        }
        let mut text = text.into();
        text.truncate(fitting_len(&text));
        tracing::debug!(?severity, %text, "status");
        self.0.push_back(StatusText { severity, text });
    }

    /// Everything queued, oldest first; the queue is left empty.
    pub(super) fn drain(&mut self) -> Vec<StatusText> {
        // the lockstep looks every step: an empty queue must cost nothing
        if self.0.is_empty() {
            return Vec::new();
        }
        self.0.drain(..).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_long_text_is_cut_on_a_character_boundary() {
        let t = "x".repeat(49) + "é and more";
        assert_eq!(cut_status_text(&t), "x".repeat(49));
        assert_eq!(cut_status_text("short"), "short");
        let mut say = Announcements::default();
        say.announce(Severity::Info, "y".repeat(60));
        assert_eq!(say.drain()[0].text, "y".repeat(50));
    }

    #[test]
    fn long_texts_become_lines_cut_at_separators() {
        let t = "Parameters not saved (retrying): parameter file /tmp/rotorpilot-client-abc/.params.toml.1234.tmp: Is a directory (os error 21)";
        let lines = status_text_lines(t);
        assert!(lines.len() >= 3, "{lines:?}");
        assert!(
            lines.iter().all(|l| !l.is_empty() && l.len() <= STATUS_TEXT_LEN),
            "{lines:?}"
        );
        assert_eq!(lines.concat().replace(' ', ""), t.replace(' ', ""));
        assert!(lines.iter().any(|l| l.contains(".params.toml")), "{lines:?}");
        assert_eq!(status_text_lines("short"), vec!["short"]);
        assert!(status_text_lines("  ").is_empty());
    }

    #[test]
    fn a_text_without_separators_is_cut_at_50_bytes() {
        let t = "z".repeat(120);
        let lines = status_text_lines(&t);
        assert_eq!(lines.iter().map(|l| l.len()).collect::<Vec<_>>(), vec![50, 50, 20]);
    }

    #[test]
    fn the_queue_keeps_the_latest_64() {
        let mut say = Announcements::default();
        for i in 0..70 {
            say.announce(Severity::Info, format!("{i}"));
        }
        let all = say.drain();
        assert_eq!(all.len(), 64);
        assert_eq!(all[0].text, "6");
        assert!(say.drain().is_empty());
    }
}
