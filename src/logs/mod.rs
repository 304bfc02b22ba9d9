//! The log and record formats a flight leaves behind, and exact replay:
//!
//! - [`record`]: the flight record (`flight.record`, JSON Lines: the header
//!   that rebuilds the core, every input with its step, the end);
//! - [`replay`]: re-flying a record bit for bit (`rotorpilot replay`);
//! - [`report`]: the flight report page (`rotorpilot report`), one offline HTML file;
//! - [`csv`]: the flight CSV, written one row per step and read back for
//!   `rotorpilot estimate`, and the estimates CSV;
//! - [`meta`]: the CSV's `<csv>.meta.json` sidecar (what produced it);
//! - [`items`]: what became of each mission item (reached, ran, never), as
//!   `simulate` and `replay` report it;
//! - [`ulog`]: PX4's ULog format, and the flight's PX4-named topics
//!   ([`ulog::flight`], the daemon's `flight.ulg`).
//!
//! Pure and deterministic, as everything below the runtimes: any
//! [`std::io::Write`], no clock.

pub mod csv;
pub mod items;
pub mod meta;
pub mod record;
pub mod replay;
pub mod report;
pub mod ulog;
