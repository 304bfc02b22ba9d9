//! rotorpilot: a software-in-the-loop autopilot for multirotors.
//!
//! # Layout
//!
//! Two halves and what joins them: the simulated world ([`sim`]) and the
//! flight stack ([`autopilot`]) never import each other; they meet in
//! [`signals`] (sensor readings in, actuator commands out) and are stepped
//! together by the lockstep core ([`lockstep`]), which the scenario runner
//! and the daemon both use.
//!
//! | module | job | may import |
//! |---|---|---|
//! | [`math`] | SO(3) helpers (hat, vee, ZYX Euler angles) and the RPY model matrices `Q`, `M`, `C` | nalgebra |
//! | [`signals`] | what crosses between world and flight stack and between blocks: sensor readings, actuator commands, measurement, control wrench, nominal model, wrench estimate; gravity and the step | nalgebra |
//! | [`tomlfile`] | TOML files to typed values, errors naming file, line/field and problem | serde, toml |
//! | [`error`] | an error and its causes said once, on one line | anyhow |
//! | [`statefile`] | atomic replacement of the state directory's files (temp file, fsync, rename) | std |
//! | [`geo`] | flat-earth NED <-> latitude/longitude/AMSL around home | nalgebra |
//! | [`params`] | the parameter table (PX4 style, a typed [`params::Param`] per entry), store, validation, atomic persistence | `airframe` (types) |
//! | [`airframe`] | vehicle description from `params/airframes/*.toml`, allocation, rotor-failure analysis, the `airframe` report | `math`, `signals`, `tomlfile` |
//! | [`sim`] | the simulated world: plants (6-DoF rigid body, rotors, ground and ceiling effect, contact), sensors, battery, disturbances, faults; N vehicles on one clock; the `SIM_*` parameters | `math`, `signals`, `airframe`, `params` |
//! | [`control`] | the three controllers (hierarchical, geometric, passivity-based), their gains (checking an airframe's `[control]` table), the reference shaper | `math`, `signals`, `airframe` |
//! | [`estimation`] | momentum-based external-wrench estimator of order r, real mass | `math`, `signals` |
//! | [`autopilot`] | the flight stack: commander, navigators, failsafes, land detector, control loop, telemetry; sees only sensor readings | `signals`, `control`, `estimation`, `params`, `geo`, `airframe` — never `sim` |
//! | [`mission`] | missions, geofences and rally points as data: items as stored, PX4's checks, result codes and CRC32 id; `.plan`, WPL 110 and `missions.json` files | `statefile`, serde_json |
//! | [`lockstep`] | the one loop: sense, decide, act, integrate for every vehicle; parameter routing and transaction; telemetry with the injected truth | `sim`, `autopilot`, `signals`, `params`, `airframe`, `geo` |
//! | [`scenario`] | scenario files and the flat-out runner behind `rotorpilot simulate` | `lockstep`, `sim`, `autopilot`, `control`, `estimation` |
//! | [`record`] | flight records (JSON Lines: header, every input with its step, end) and exact replay behind `rotorpilot replay` | `lockstep`, `autopilot`, `mission`, `params`, `scenario` (the CSV), serde_json |
//! | [`flightlog`] | flight-log CSV reading and the offline estimator sweep of `rotorpilot estimate` | `estimation` |
//! | [`ulog`] | PX4's ULog format written to any `io::Write`; `ulog::flight` fills PX4-named topics from the lockstep core (the daemon's `flight.ulg`) | `lockstep`, `autopilot`, `params` |
//! | [`link`] | MAVLink 2 over UDP as PX4 SITL, sans I/O: translates messages to autopilot commands and telemetry to messages (never physics, never a decision) | `autopilot`, `lockstep::Snapshot` (with the world's `sim::Truth` in it), `params`, `geo`, mavlink |
//! | [`daemon`] | the runtime: the simulation thread paced against wall time, link tasks on tokio, parameter and plan saving, shutdown | everything |
//! | [`cli`] | the `rotorpilot` command line (thin: parses, calls the modules, prints); `cli::simulate` one scenario or a campaign on every core, one shard of it, a headless fleet | everything |
//!
//! Everything up to `scenario` is pure and deterministic: no sockets, no
//! tokio, no wall clock, no global RNG. The same inputs and seed give a
//! bit-identical trajectory. `tools/test-all.sh` checks both rules with a grep.
//!
//! # Conventions
//! SI units. World frame NED (`_ned`), body frame FRD (`_frd`), gravity
//! `+g e3` with `g` = [`signals::GRAVITY`]. Attitude is the unit quaternion
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
pub mod error;
pub mod estimation;
pub mod flightlog;
pub mod geo;
pub mod link;
pub mod lockstep;
pub mod math;
pub mod mission;
pub mod params;
pub mod record;
pub mod scenario;
pub mod signals;
pub mod sim;
pub mod statefile;
pub mod tomlfile;
pub mod ulog;
