//! Cost of MAVLink 2 signing per message: encoding a typical frame
//! unsigned (the baseline), encoding and signing it (what the vehicle does for
//! every frame it sends once a key is set), and the gate's check of a signed
//! frame as it arrives (signature and stream timestamp). Frames: ATTITUDE (28
//! bytes of payload, the most frequent stream) and COMMAND_LONG (33).
//!
//! Run: `cargo bench --bench signing`. Figures go in docs/performance.md.

use std::hint::black_box;
use std::time::Instant;

use criterion::{Criterion, criterion_group, criterion_main};
use mavlink::MavHeader;
use mavlink::dialects::common::{ATTITUDE_DATA, MavMessage};
use rotorpilot::link::signing::{Signing, sign_frame};
use rotorpilot::link::wire::{self, CommandLong, Encoder};

const KEY: [u8; 32] = [0x5a; 32];

fn attitude() -> MavMessage {
    MavMessage::ATTITUDE(ATTITUDE_DATA {
        time_boot_ms: 123_456,
        roll: 0.1,
        pitch: -0.2,
        yaw: 1.5,
        rollspeed: 0.01,
        pitchspeed: -0.02,
        yawspeed: 0.03,
    })
}

fn command_long() -> Vec<u8> {
    let c = CommandLong {
        params: [1.0, 21196.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        command: 400,
        target_system: 1,
        target_component: 1,
        confirmation: 0,
    };
    let h = MavHeader {
        system_id: 255,
        component_id: 190,
        sequence: 0,
    };
    wire::encode_v2(h, 76, &c.encode())
}

fn signing(c: &mut Criterion) {
    let at = Instant::now();
    let mut g = c.benchmark_group("signing");
    let msg = attitude();
    let mut enc = Encoder::new(1, 1);
    g.bench_function("ATTITUDE encode unsigned", |b| {
        b.iter(|| black_box(enc.message(black_box(&msg))))
    });
    let mut s = Signing::unkeyed(at, 1);
    s.setup(KEY, 0);
    g.bench_function("ATTITUDE encode + sign", |b| {
        b.iter(|| {
            let mut f = enc.message(black_box(&msg));
            s.sign(&mut f, 0, at);
            black_box(f)
        });
    });
    let cmd = command_long();
    g.bench_function("COMMAND_LONG encode unsigned", |b| {
        b.iter(|| black_box(enc.raw(76, black_box(&cmd[10..cmd.len() - 2]))));
    });
    g.bench_function("COMMAND_LONG encode + sign", |b| {
        b.iter(|| {
            let mut f = enc.raw(76, black_box(&cmd[10..cmd.len() - 2]));
            s.sign(&mut f, 0, at);
            black_box(f)
        });
    });
    // verify: a fresh timestamp each time (a repeated one is a replay, refused
    // before the hash); frames prepared outside the timing
    for (name, unsigned) in [("ATTITUDE", enc.message(&msg)), ("COMMAND_LONG", cmd.clone())] {
        let mut rx = Signing::unkeyed(at, 1);
        rx.setup(KEY, 0);
        let mut ts = 1_000u64;
        g.bench_function(format!("{name} verify (gate)"), |b| {
            b.iter_batched(
                || {
                    ts += 1;
                    let mut f = unsigned.clone();
                    sign_frame(&KEY, &mut f, 3, ts);
                    f
                },
                |f| {
                    let frame = wire::frames(&f).next().expect("frame");
                    black_box(rx.check(&frame, at)).expect("accepted");
                },
                criterion::BatchSize::SmallInput,
            );
        });
        g.bench_function(format!("{name} parse unsigned (baseline)"), |b| {
            b.iter(|| black_box(wire::frames(black_box(&unsigned)).count()));
        });
    }
    g.finish();
}

criterion_group!(benches, signing);
criterion_main!(benches);
