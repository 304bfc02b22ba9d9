//! Fuzzing the MAVLink side of the vehicle: the wire parser, then every
//! handler behind it, with a time budget so that CI runs it on every change.
//!
//! The toolchain CI has is stable Rust, where libFuzzer (`cargo fuzz`) does
//! not build, so this is a mutational fuzzer of our own on a checked-in
//! corpus, seeded and reproducible:
//!
//! - **seeds**: `tests/fuzz/corpus/*.bin`, one datagram each, what real
//!   clients send (written by pymavlink: `tools/fuzz_corpus.py`), plus any
//!   input a run once failed on, kept in `tests/fuzz/regressions/`;
//! - **mutants**: a seed's bytes flipped, overwritten with boundary values,
//!   cut, repeated or spliced with another seed (most of these fail the CRC:
//!   they test the framing), and a seed's frames with their payload, length,
//!   message id or target mutated and then re-framed with a valid CRC (these
//!   reach the handlers), and frames of any message the dialect knows with
//!   arbitrary payload bytes;
//! - **targets**: [`parser`] (`wire::frames` and `wire::decode` on raw bytes:
//!   every frame found lies inside the datagram, decoding never panics) and
//!   [`vehicle`] (a `Link` in front of a real one-vehicle `Lockstep` and its
//!   `ParamStore`, whose effects are carried out as the daemon's simulation
//!   thread carries them out — commands, parameter sets, plan changes,
//!   reboots — with the outcomes handed back to the link; the world is stepped
//!   and the streams polled between inputs. Checks: no panic, every frame the
//!   link sends is one well-formed MAVLink 2 frame from our system, the
//!   parameter store holds only values within the table's bounds, and the
//!   vehicle's state stays finite).
//!
//! Budget: `ROTORPILOT_FUZZ_SECONDS` per target (default 3 s; CI's fuzz step
//! gives 20 s; a long run: `ROTORPILOT_FUZZ_SECONDS=3600 cargo test
//! --release --test fuzz -- --nocapture`). `ROTORPILOT_FUZZ_SEED` replays
//! a run (the seed is printed). On a failure the input is written to
//! `target/fuzz-failure-<target>-<seed>.bin` and its hex printed: add it to
//! `tests/fuzz/regressions/` with the fix.

use std::net::SocketAddr;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use mavlink::dialects::common::MavMessage;
use mavlink::{MavHeader, Message};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use rotorpilot::airframe::Airframe;
use rotorpilot::autopilot::{Autopilot, AutopilotCommand, PowerAction};
use rotorpilot::geo::GeoPoint;
use rotorpilot::link::streams::{self, Identity};
use rotorpilot::link::{Effect, Link, LinkConfig, wire};
use rotorpilot::lockstep::Lockstep;
use rotorpilot::params::{ParamStore, ParamValue};
use rotorpilot::sim::SensorConfig;

/// Every message id the dialect knows (frames of other ids are skipped by
/// the parser: there is no CRC_EXTRA for them).
fn known_ids() -> Vec<u32> {
    (0..=u16::MAX as u32)
        .filter(|&id| MavMessage::default_message_from_id(id).is_some())
        .collect()
}

fn read_dir_bins(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut out: Vec<(String, Vec<u8>)> = entries
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "bin"))
        .map(|p| {
            let bytes = std::fs::read(&p).unwrap();
            (p.file_name().unwrap().to_string_lossy().into_owned(), bytes)
        })
        .collect();
    out.sort();
    out
}

/// The seeds: the corpus and the regressions.
fn seeds() -> Vec<Vec<u8>> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz");
    let corpus = read_dir_bins(&root.join("corpus"));
    assert!(
        corpus.len() >= 40,
        "the corpus is missing ({} seeds): run tools/fuzz_corpus.py",
        corpus.len()
    );
    corpus
        .into_iter()
        .chain(read_dir_bins(&root.join("regressions")))
        .map(|(_, b)| b)
        .collect()
}

fn budget() -> Duration {
    let s: f64 = std::env::var("ROTORPILOT_FUZZ_SECONDS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(3.0);
    Duration::from_secs_f64(s)
}

fn seed() -> u64 {
    std::env::var("ROTORPILOT_FUZZ_SEED")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| {
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(1, |d| d.as_nanos() as u64)
        })
}

/// Boundary values a mutation writes into a byte or a field.
const INTERESTING_U8: [u8; 8] = [0, 1, 0x7F, 0x80, 0xFD, 0xFE, 0xFF, 0x10];
const INTERESTING_F32: [f32; 10] = [
    0.0,
    -0.0,
    1.0,
    -1.0,
    f32::NAN,
    f32::INFINITY,
    f32::NEG_INFINITY,
    f32::MAX,
    f32::MIN_POSITIVE,
    1e30,
];

/// The mutator: seeds in, one input out.
struct Mutator {
    rng: ChaCha8Rng,
    seeds: Vec<Vec<u8>>,
    ids: Vec<u32>,
}

impl Mutator {
    fn new(seed: u64) -> Self {
        Self {
            rng: ChaCha8Rng::seed_from_u64(seed),
            seeds: seeds(),
            ids: known_ids(),
        }
    }

    fn pick_seed(&mut self) -> Vec<u8> {
        let k = self.rng.random_range(0..self.seeds.len());
        self.seeds[k].clone()
    }

    /// One input: raw mutants (framing), re-framed mutants (handlers),
    /// arbitrary messages, in about equal shares.
    fn next(&mut self) -> Vec<u8> {
        match self.rng.random_range(0..8) {
            0..=2 => {
                let mut d = self.pick_seed();
                for _ in 0..self.rng.random_range(1..=4) {
                    self.raw(&mut d);
                }
                d
            }
            3..=6 => {
                let d = self.pick_seed();
                self.reframed(&d)
            }
            _ => {
                let n = self.rng.random_range(1..=4);
                (0..n).flat_map(|_| self.arbitrary_frame()).collect()
            }
        }
    }

    /// A byte-level mutation (CRC mostly broken: the framing is tested).
    fn raw(&mut self, d: &mut Vec<u8>) {
        let r = &mut self.rng;
        match r.random_range(0..7) {
            0 if !d.is_empty() => {
                let i = r.random_range(0..d.len());
                d[i] ^= 1 << r.random_range(0..8);
            }
            1 if !d.is_empty() => {
                let i = r.random_range(0..d.len());
                d[i] = INTERESTING_U8[r.random_range(0..INTERESTING_U8.len())];
            }
            2 if !d.is_empty() => {
                let cut = r.random_range(0..d.len());
                d.truncate(cut);
            }
            3 if !d.is_empty() => {
                let a = r.random_range(0..d.len());
                let b = r.random_range(a..=d.len());
                let chunk = d[a..b].to_vec();
                let at = r.random_range(0..=d.len());
                d.splice(at..at, chunk);
            }
            4 => {
                let k = r.random_range(0..self.seeds.len());
                let other = &self.seeds[k];
                let from = r.random_range(0..=other.len());
                let at = r.random_range(0..=d.len());
                d.splice(at..at, other[from..].iter().copied());
            }
            5 if !d.is_empty() => {
                let a = r.random_range(0..d.len());
                let b = r.random_range(a..=d.len());
                d.drain(a..b);
            }
            _ => {
                let n = r.random_range(1..32);
                let at = r.random_range(0..=d.len());
                let junk: Vec<u8> = (0..n).map(|_| r.random()).collect();
                d.splice(at..at, junk);
            }
        }
        d.truncate(65_507);
    }

    /// The seed's frames with one field mutated each, framed again with a
    /// valid CRC (MAVLink 2, or 1 where the id fits and a coin says so).
    fn reframed(&mut self, d: &[u8]) -> Vec<u8> {
        let frames: Vec<(MavHeader, u32, Vec<u8>)> = wire::frames(d)
            .map(|f| {
                (
                    MavHeader {
                        system_id: u32::from(f.system_id),
                        component_id: f.component_id,
                        sequence: f.sequence,
                    },
                    f.message_id,
                    f.payload.to_vec(),
                )
            })
            .collect();
        let mut out = Vec::new();
        for (mut header, mut id, mut payload) in frames {
            let r = &mut self.rng;
            for _ in 0..r.random_range(1..=3) {
                match r.random_range(0..9) {
                    0 if !payload.is_empty() => {
                        let i = r.random_range(0..payload.len());
                        payload[i] = r.random();
                    }
                    1 if payload.len() >= 4 => {
                        // a float field (most fields are 4-byte aligned)
                        let i = 4 * r.random_range(0..payload.len() / 4);
                        let v = INTERESTING_F32[r.random_range(0..INTERESTING_F32.len())];
                        payload[i..i + 4].copy_from_slice(&v.to_le_bytes());
                    }
                    2 if payload.len() >= 4 => {
                        let i = 4 * r.random_range(0..payload.len() / 4);
                        let v: i32 = [0, 1, -1, i32::MAX, i32::MIN, 900_000_000, -1_800_000_001][r.random_range(0..7)];
                        payload[i..i + 4].copy_from_slice(&v.to_le_bytes());
                    }
                    3 if payload.len() >= 2 => {
                        let i = r.random_range(0..payload.len() - 1);
                        let v: u16 = [0, 1, 0xFFFF, 0x7FFF, 400, 22, 176, 192, 511, 512][r.random_range(0..10)];
                        payload[i..i + 2].copy_from_slice(&v.to_le_bytes());
                    }
                    4 => {
                        let n = r.random_range(0..=payload.len());
                        payload.truncate(n);
                    }
                    5 => payload.resize(r.random_range(0..=255), r.random()),
                    6 => id = self.ids[r.random_range(0..self.ids.len())],
                    7 => {
                        header.system_id = [0, 1, 2, 245, 255][r.random_range(0..5)];
                        header.component_id = [0, 1, 190, 191, 255][r.random_range(0..5)];
                    }
                    _ => header.sequence = r.random(),
                }
            }
            payload.truncate(255);
            if id <= 255 && self.rng.random_range(0..8) == 0 {
                out.extend(wire::encode_v1(header, id as u8, &payload));
            } else {
                out.extend(wire::encode_v2(header, id, &payload));
            }
        }
        out
    }

    /// A frame of any message the dialect knows, arbitrary payload bytes,
    /// aimed at us (target bytes are where the XML puts them: not known
    /// here, so some land and some do not).
    fn arbitrary_frame(&mut self) -> Vec<u8> {
        let r = &mut self.rng;
        let id = self.ids[r.random_range(0..self.ids.len())];
        let n = r.random_range(0..=255);
        let mut payload: Vec<u8> = (0..n).map(|_| r.random()).collect();
        // small ints are more interesting than random ones for ids and enums
        for b in payload.iter_mut() {
            if r.random_range(0..4) == 0 {
                *b = r.random_range(0..4);
            }
        }
        let header = MavHeader {
            system_id: 245,
            component_id: 190,
            sequence: r.random(),
        };
        wire::encode_v2(header, id, &payload)
    }
}

/// Run `one` on mutants until the budget is spent; on a panic, write the
/// input out and fail with its seed. Returns (executions, seconds).
fn fuzz(target: &str, mut one: impl FnMut(&[u8])) -> (u64, f64) {
    let seed = seed();
    let mut m = Mutator::new(seed);
    let start = Instant::now();
    let budget = budget();
    let mut execs = 0u64;
    // every seed once as it is, then mutants
    let seeds = m.seeds.clone();
    let mut inputs = seeds.into_iter();
    loop {
        let input = match inputs.next() {
            Some(s) => s,
            None => {
                if start.elapsed() >= budget {
                    break;
                }
                m.next()
            }
        };
        if let Err(p) = catch_unwind(AssertUnwindSafe(|| one(&input))) {
            let dir = PathBuf::from(std::env::var("CARGO_TARGET_TMPDIR").unwrap_or_else(|_| "target".into()));
            let path = dir.join(format!("fuzz-failure-{target}-{seed}.bin"));
            let _ = std::fs::write(&path, &input);
            let msg = p
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| p.downcast_ref::<&str>().map(|s| (*s).to_string()))
                .unwrap_or_default();
            panic!(
                "fuzz target {target} failed after {execs} inputs (ROTORPILOT_FUZZ_SEED={seed}): {msg}\ninput written to {}\nhex: {}",
                path.display(),
                input.iter().map(|b| format!("{b:02x}")).collect::<String>()
            );
        }
        execs += 1;
    }
    let secs = start.elapsed().as_secs_f64();
    println!(
        "fuzz {target}: {execs} inputs in {secs:.1} s ({:.0}/s), seed {seed}",
        execs as f64 / secs
    );
    (execs, secs)
}

/// The parser: frames found lie inside the datagram, in order, each with a
/// payload of at most 255 bytes; decoding any of them never panics.
#[test]
fn parser() {
    let (execs, _) = fuzz("parser", |d| {
        let base = d.as_ptr() as usize;
        let mut last_end = base;
        for f in wire::frames(d) {
            let p = f.payload.as_ptr() as usize;
            assert!(
                p >= last_end && p + f.payload.len() <= base + d.len(),
                "a frame outside its datagram"
            );
            assert!(f.payload.len() <= 255);
            last_end = p + f.payload.len();
            let _ = wire::decode(&f);
        }
    });
    assert!(execs > 1000, "the fuzzer barely ran: {execs} inputs");
}

/// A link in front of a real vehicle, driven as the daemon drives it.
struct Rig {
    link: Link,
    core: Lockstep<Autopilot>,
    store: ParamStore,
    now: Instant,
    /// Frames the link has sent, all checked.
    frames_out: u64,
    /// Effects carried out.
    effects: u64,
}

const ME: Identity = Identity {
    system_id: 1,
    component_id: 1,
};

impl Rig {
    fn new() -> Self {
        let af = Airframe::load("quad").unwrap();
        let mut store = ParamStore::new(&af);
        // failure injection reachable, as tests and CI users enable it
        store.set("SYS_FAILURE_EN", ParamValue::Int32(1)).unwrap();
        let core = Lockstep::one_vehicle(&af, GeoPoint::PX4_SITL_HOME, &store, SensorConfig::default()).unwrap();
        let now = Instant::now();
        let link = Link::new(
            LinkConfig {
                name: "fuzz".into(),
                identity: ME,
                default_remote: Some(SocketAddr::from(([127, 0, 0, 1], 14550))),
                rates: streams::gcs_rates(),
                peer_timeout: Duration::from_secs(5),
            },
            now,
        );
        Self {
            link,
            core,
            store,
            now,
            frames_out: 0,
            effects: 0,
        }
    }

    fn input(&mut self, from: SocketAddr, data: &[u8]) {
        let t = self.core.snapshot(0);
        let effects = self.link.on_datagram(self.now, from, data, &t, &self.store);
        for e in effects {
            self.effect(e);
        }
        self.check_out();
    }

    /// As the daemon's simulation thread and link task carry out `e`.
    fn effect(&mut self, e: Effect) {
        self.effects += 1;
        match e {
            Effect::Autopilot { command, ack } => {
                let outcome = self.core.command(0, command);
                if command == AutopilotCommand::Power(PowerAction::Reboot)
                    && outcome == rotorpilot::autopilot::CommandOutcome::Accepted
                {
                    self.core.reboot(0, &self.store).unwrap();
                }
                if let Some(ticket) = ack {
                    self.link.on_outcome(ticket, &outcome);
                }
            }
            Effect::SetParam { ticket, value } => {
                let outcome = self.core.set_param(0, &mut self.store, &ticket.name, value);
                let _ = self.link.on_param_set(&ticket, outcome, &self.store);
            }
            Effect::Plans { ticket, change } => {
                let outcome = self.core.change_plans(0, change);
                self.link.on_plans_changed(ticket, outcome);
            }
            Effect::SetMissionCurrent { seq } => {
                let outcome = self.core.command(0, AutopilotCommand::SetMissionCurrent { seq });
                let t = self.core.snapshot(0);
                self.link.on_mission_current_set(seq, &outcome, &t);
            }
            Effect::GcsHeartbeat => self.core.gcs_heartbeat(0),
            #[allow(unreachable_patterns)]
            _ => {}
        }
    }

    /// Every frame out is one well-formed MAVLink 2 frame from us.
    fn check_out(&mut self) {
        for o in self.link.drain() {
            let frames: Vec<_> = wire::frames(&o.bytes).collect();
            assert_eq!(
                frames.len(),
                1,
                "an outgoing frame does not parse back: {:02x?}",
                o.bytes
            );
            let f = frames[0];
            assert_eq!((f.system_id, f.component_id), (ME.system_id, ME.component_id));
            assert_eq!(f.version, mavlink::MavlinkVersion::V2);
            self.frames_out += 1;
        }
    }

    /// Time passes: the world steps `n` times, the streams are polled.
    fn pass(&mut self, n: usize) {
        for _ in 0..n {
            self.core.step();
        }
        self.now += Duration::from_secs_f64(n as f64 * self.core.dt_s());
        let t = self.core.snapshot(0);
        self.link.poll(self.now, &t, 1_700_000_000_000_000);
        self.check_out();
    }

    /// The parameters stay within the table's bounds and the vehicle's state finite.
    fn check_state(&mut self) {
        for (spec, value) in self.store.iter() {
            assert!(
                ParamStore::check(spec, value).is_ok(),
                "{} = {value:?} is out of its bounds",
                spec.name
            );
        }
        let tel = self.core.telemetry(0);
        assert!(
            tel.position_ned
                .iter()
                .chain(tel.velocity_ned.iter())
                .all(|x| x.is_finite()),
            "the vehicle's state is not finite: {tel:?}"
        );
    }
}

/// Every handler: datagrams from a GCS, a script and spoofed addresses into
/// a link in front of a real vehicle.
#[test]
fn vehicle() {
    let senders: Vec<SocketAddr> = [14550u16, 14540, 40000, 1]
        .iter()
        .map(|&p| SocketAddr::from(([127, 0, 0, 1], p)))
        .collect();
    let mut rig = Rig::new();
    let mut k = 0usize;
    let (execs, _) = fuzz("vehicle", |d| {
        k += 1;
        // a fresh vehicle now and then: state machines from the start again
        if k.is_multiple_of(5000) {
            rig = Rig::new();
        }
        rig.input(senders[k % senders.len()], d);
        if k.is_multiple_of(4) {
            rig.pass(1 + k % 20);
        }
        if k.is_multiple_of(64) {
            rig.check_state();
        }
    });
    rig.check_state();
    println!(
        "fuzz vehicle: {} effects carried out, {} frames sent",
        rig.effects, rig.frames_out
    );
    assert!(execs > 200, "the fuzzer barely ran: {execs} inputs");
    assert!(rig.frames_out > 0, "the link never answered: the harness is broken");
}
