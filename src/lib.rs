//! rotorpilot: a software-in-the-loop autopilot for multirotors.
//!
//! # Layout
//!
//! | module | job | may import |
//! |---|---|---|
//! | [`math`] | SO(3) helpers (hat, vee, ZYX Euler angles) and the RPY model matrices `Q`, `M`, `C` | nalgebra |
//! | [`signals`] | values passed between blocks: measurement, nominal model, wrench estimate | nalgebra |
//! | [`tomlfile`] | TOML files to typed values, errors naming file, line/field and problem | serde, toml |
//! | [`geo`] | flat-earth NED <-> latitude/longitude/AMSL around home | nalgebra |
//! | [`airframe`] | vehicle description from `params/airframes/*.toml`, allocation (effectiveness matrix, inverse, desaturation), rotor-failure analysis, the `airframe` report | `math`, `tomlfile` |
//! | [`model`] | the plant: 6-DoF rigid body (NED/FRD), rotors with lag and limits, ground and ceiling effect, external wrench, ground contact, seeded sensor noise | `math`, `airframe` |
//! | [`control`] | the three controllers (hierarchical, geometric, passivity-based) and the reference shaper | `math`, `signals`, `airframe` (types) |
//! | [`estimation`] | momentum-based external-wrench estimator of order r, real mass | `math`, `signals`, `airframe` (types) |
//! | [`vehicle`] | the lockstep loop: sense (measure, estimate), act (control, allocate, integrate) | the pure modules above |
//! | [`scenario`] | scenario files and the flat-out runner behind `rotorpilot simulate` | `vehicle` |
//! | [`flightlog`] | flight-log CSV reading and the offline estimator sweep of `rotorpilot estimate` | `estimation` |
//! | [`params`] | the parameter table (PX4 style), typed store, validation, atomic persistence | `airframe` (types) |
//! | [`autopilot`] | arming, flight modes, takeoff/land/RTL/hold/offboard, telemetry snapshot | `vehicle`, `params`, `geo` |
//! | [`link`] | MAVLink 2 over UDP as PX4 SITL: peers, streams, handlers (protocol only, never physics) | `autopilot`, `params`, `geo` (types), mavlink |
//! | [`daemon`] | the runtime: simulation on its own thread paced against wall time, links on tokio, shutdown | everything |
//! | [`cli`] | the `rotorpilot` command line (thin: parses, calls the modules, prints) | everything |
//!
//! Everything up to `autopilot` is pure and deterministic: no sockets, no
//! tokio, no wall clock, no global RNG. The same inputs and seed give a bit-identical
//! trajectory.
//!
//! # Conventions
//! SI units. World frame NED (`_ned`), body frame FRD (`_frd`), gravity
//! `+g e3` with `g` = [`model::GRAVITY`]. Attitude is the unit quaternion
//! taking FRD body vectors into NED. Rotor thrust points along `-z_b`.
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
pub mod estimation;
pub mod flightlog;
pub mod geo;
pub mod link;
pub mod lockstep;
pub mod math;
pub mod params;
pub mod scenario;
pub mod signals;
pub mod sim;
pub mod tomlfile;
