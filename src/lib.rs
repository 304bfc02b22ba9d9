//! rotorpilot: a software-in-the-loop autopilot for multirotors. The
//! simulated world ([`sim`]) and the flight stack ([`autopilot`]) never import
//! each other: they meet in [`signals`] and are stepped together by
//! [`lockstep`], which the headless runner ([`scenario`]) and the live daemon
//! ([`daemon`], with the MAVLink translation in [`link`]) both drive. Each
//! module is a room with one job; `docs/architecture.md` maps the rooms, their
//! floors, who may import whom and what stays pure, and
//! `tests/architecture.rs` holds the code to it. SI units; world frame NED
//! (`_ned`), body frame FRD (`_frd`); attitude is the unit quaternion taking
//! FRD body vectors into NED.
#![forbid(unsafe_code)]
// Units sit in brackets in doc comments (`[m/s]`, PX4's habit), which rustdoc
// would otherwise read as links.
#![allow(rustdoc::broken_intra_doc_links)]
#![warn(missing_docs, missing_debug_implementations, unreachable_pub)]

pub mod airframe;
pub mod autopilot;
pub mod cli;
pub mod control;
pub mod daemon;
pub mod error;
pub mod estimation;
pub mod exact_json;
pub mod geo;
pub mod link;
pub mod lockstep;
pub mod logs;
pub mod math;
pub mod mission;
pub mod params;
pub mod scenario;
pub mod signals;
pub mod sim;
pub mod statefile;
pub mod tomlfile;
