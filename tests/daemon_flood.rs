//! Issue 15 §2 and the held flood of §5, in-process: the vehicle cannot be
//! used to flood a third party (bytes out per byte in, per request kind,
//! from a new and so unproven address), a spoofed-source flood cannot push
//! the real GCS off the link, and 200,000 mixed datagrams at about 10,000/s
//! change nothing while the heartbeat keeps going.
//!
//! Figures: `cargo test --release --test daemon_flood -- --nocapture`.
#![allow(deprecated)]

mod common;

use std::net::SocketAddr;
use std::time::Duration;

use common::daemon::{Client, Vehicle, command_long_frame, config};
use mavlink::dialects::common::*;
use mavlink::{MAVLinkV1MessageRaw, MAVLinkV2MessageRaw, MavHeader};
use rotorpilot::link::budget::{UNPROVEN_FACTOR, UNPROVEN_POOL_RATE};
use rotorpilot::link::wire::{self, CommandLong};
use tokio::net::UdpSocket;
use tokio::time::{Instant, timeout};

/// The largest UDP payload over IPv4.
const MAX_UDP: usize = 65_507;

fn header(system_id: u8, component_id: u8, sequence: u8) -> MavHeader {
    MavHeader {
        system_id: u32::from(system_id),
        component_id,
        sequence,
    }
}

/// `msg` as a MAVLink 2 frame from a GCS (255/190).
fn v2(msg: &MavMessage) -> Vec<u8> {
    let mut raw = MAVLinkV2MessageRaw::new();
    raw.serialize_message(header(255, 190, 0), msg);
    raw.raw_bytes().to_vec()
}

/// `msg` as a MAVLink 1 frame from a GCS.
fn v1(msg: &MavMessage) -> Vec<u8> {
    let mut raw = MAVLinkV1MessageRaw::new();
    raw.serialize_message(header(255, 190, 0), msg);
    raw.raw_bytes().to_vec()
}

/// COMMAND_LONG `command` to `target` with `p`.
fn command(command: u16, p: [f32; 7], target: (u8, u8)) -> Vec<u8> {
    let c = CommandLong {
        params: p,
        command,
        target_system: target.0,
        target_component: target.1,
        confirmation: 0,
    };
    command_long_frame(header(255, 190, 0), &c)
}

/// The request kinds that draw the largest answers, each as one frame.
fn request_kinds() -> Vec<(&'static str, Vec<u8>)> {
    let mut ftp = [0u8; 251];
    ftp[3] = 3; // ListDirectory
    vec![
        (
            "PARAM_REQUEST_LIST",
            v2(&MavMessage::PARAM_REQUEST_LIST(PARAM_REQUEST_LIST_DATA {
                target_system: 1,
                target_component: 1,
            })),
        ),
        (
            "MISSION_REQUEST_LIST",
            v2(&MavMessage::MISSION_REQUEST_LIST(MISSION_REQUEST_LIST_DATA {
                target_system: 1,
                target_component: 1,
                mission_type: MavMissionType::MAV_MISSION_TYPE_MISSION,
            })),
        ),
        // AUTOPILOT_VERSION (148), the largest message on request
        (
            "REQUEST_MESSAGE",
            command(512, [148.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], (1, 1)),
        ),
        (
            "FTP list",
            v2(&MavMessage::FILE_TRANSFER_PROTOCOL(FILE_TRANSFER_PROTOCOL_DATA {
                target_network: 0,
                target_system: 1,
                target_component: 1,
                payload: ftp,
            })),
        ),
        (
            "PING",
            v2(&MavMessage::PING(PING_DATA {
                time_usec: 1,
                seq: 1,
                target_system: 0,
                target_component: 0,
            })),
        ),
        (
            "TIMESYNC",
            v2(&MavMessage::TIMESYNC(TIMESYNC_DATA {
                tc1: 0,
                ts1: 1,
                ..Default::default()
            })),
        ),
        // an unknown command: answered by the link (UNSUPPORTED)
        ("COMMAND_LONG", command(31_337, [0.0; 7], (1, 1))),
    ]
}

/// `frame` repeated into one datagram of at most [`MAX_UDP`] bytes.
fn filled(frames: &[Vec<u8>]) -> Vec<u8> {
    let mut d = Vec::new();
    'fill: loop {
        for f in frames {
            if d.len() + f.len() > MAX_UDP {
                break 'fill;
            }
            d.extend_from_slice(f);
        }
    }
    d
}

/// Bytes `sock` receives until it has been quiet for `quiet` (at most `most`).
async fn bytes_received(sock: &UdpSocket, quiet: Duration, most: Duration) -> usize {
    let end = Instant::now() + most;
    let mut buf = vec![0u8; 65_536];
    let mut total = 0;
    while let Some(left) = end.checked_duration_since(Instant::now()) {
        match timeout(quiet.min(left), sock.recv_from(&mut buf)).await {
            Ok(Ok((n, _))) => total += n,
            _ => break,
        }
    }
    total
}

/// Bytes out for `datagrams` sent from a fresh address (a spoofed source:
/// it never heartbeats), `gap` apart, counted until the link is quiet.
async fn answer_to(link: SocketAddr, datagrams: &[Vec<u8>], gap: Duration) -> (usize, usize) {
    let sock = UdpSocket::bind("127.0.0.1:0").await.unwrap();
    let mut sent = 0;
    let mut got = 0;
    let mut buf = vec![0u8; 65_536];
    for d in datagrams {
        sock.send_to(d, link).await.unwrap();
        sent += d.len();
        let until = Instant::now() + gap;
        while let Ok(Ok((n, _))) = timeout(
            until.saturating_duration_since(Instant::now()),
            sock.recv_from(&mut buf),
        )
        .await
        {
            got += n;
        }
    }
    got += bytes_received(&sock, Duration::from_millis(300), Duration::from_secs(5)).await;
    (sent, got)
}

/// A table row: request kind, bytes in, bytes out, ratio.
fn row(kind: &str, case: &str, (i, o): (usize, usize)) -> String {
    format!(
        "{kind:<22} {case:<28} in {i:>7} B  out {o:>7} B  out/in {:>7.3}",
        o as f64 / i as f64
    )
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn one_datagram_or_a_stream_from_an_unproven_source_draws_at_most_three_times_its_bytes() {
    let v = Vehicle::start(config(None, None, 1.0)).await;
    let mut kinds = request_kinds();
    let mix: Vec<Vec<u8>> = kinds.iter().map(|(_, f)| f.clone()).collect();
    kinds.push(("mix", mix.concat()));
    let mut rows = Vec::new();
    let mut worst: f64 = 0.0;
    for (kind, frame) in &kinds {
        let frames: Vec<Vec<u8>> = if *kind == "mix" {
            mix.clone()
        } else {
            vec![frame.clone()]
        };
        let cases = [
            ("one frame", vec![frame.clone()], Duration::ZERO),
            ("one 64 KB datagram", vec![filled(&frames)], Duration::ZERO),
            // sustained: 500 datagrams of one frame at 1 kHz
            (
                "500 frames at 1 kHz",
                vec![frame.clone(); 500],
                Duration::from_millis(1),
            ),
        ];
        for (case, datagrams, gap) in cases {
            let t0 = Instant::now();
            let (i, o) = answer_to(v.gcs, &datagrams, gap).await;
            let elapsed = t0.elapsed().as_secs_f64();
            rows.push(row(kind, case, (i, o)));
            worst = worst.max(o as f64 / i as f64);
            assert!(o <= UNPROVEN_FACTOR * i, "{kind}, {case}: {o} bytes out for {i} in");
            // all unproven peers together: the pool's burst plus its rate
            assert!(
                o as f64 <= UNPROVEN_POOL_RATE * (1.0 + elapsed),
                "{kind}, {case}: {o} bytes out in {elapsed:.2} s"
            );
        }
    }
    // the answers are real: a request from an unproven peer is answered
    // (PING's echo is the same size as the request), once the pool refilled
    tokio::time::sleep(Duration::from_millis(1100)).await;
    let ping = &kinds.iter().find(|(k, _)| *k == "PING").unwrap().1;
    let (i, o) = answer_to(v.gcs, std::slice::from_ref(ping), Duration::ZERO).await;
    assert!(o > 0 && o <= UNPROVEN_FACTOR * i, "one PING ({i} B), one echo ({o} B)");
    eprintln!("bytes out per byte in, unproven source (GCS link, 39 parameters):");
    for r in &rows {
        eprintln!("  {r}");
    }
    eprintln!("  worst out/in: {worst:.3}");
    v.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_heartbeat_proves_a_peer_it_then_gets_streams_and_whole_answers() {
    let v = Vehicle::start(config(None, None, 1.0)).await;
    let mut c = Client::with_ids(255, 190).await;
    // before: a PARAM_REQUEST_LIST draws a few values only, and no streams
    let list = MavMessage::PARAM_REQUEST_LIST(PARAM_REQUEST_LIST_DATA {
        target_system: 1,
        target_component: 1,
    });
    c.send(v.gcs, &list).await;
    let mut seen = std::collections::BTreeSet::new();
    let mut count = 0;
    let mut streamed = 0;
    while let Some(r) = c.recv(Duration::from_millis(500)).await {
        match &r.msg {
            Some(MavMessage::PARAM_VALUE(p)) => {
                seen.insert(p.param_index);
            }
            _ => streamed += 1,
        }
    }
    assert_eq!(
        (seen.len(), streamed),
        (1, 0),
        "unproven: 3 x 14 bytes is one PARAM_VALUE"
    );
    // after a heartbeat: streams, and the rest of the list (the list in
    // progress goes on; the repeated request does not restart it)
    c.heartbeat(v.gcs).await;
    c.send(v.gcs, &list).await;
    let mut attitude = 0;
    let end = Instant::now() + Duration::from_secs(2);
    while let Some(r) = c.recv(end.saturating_duration_since(Instant::now())).await {
        match &r.msg {
            Some(MavMessage::PARAM_VALUE(p)) => {
                seen.insert(p.param_index);
                count = p.param_count;
            }
            Some(MavMessage::ATTITUDE(_)) => attitude += 1,
            _ => {}
        }
    }
    assert!(
        count > 10 && seen.len() == usize::from(count),
        "{} of {count}",
        seen.len()
    );
    assert!(attitude > 50, "ATTITUDE at 50 Hz: {attitude} in 2 s");
    v.stop().await;
}

/// What a listening GCS saw: its longest gap between heartbeats, ATTITUDEs
/// and command ACKs, over `for_s` seconds of heartbeating at 1 Hz and
/// asking for an unknown command every 500 ms.
#[derive(Debug, Default)]
struct Seen {
    heartbeat_gap: Duration,
    heartbeats: u32,
    attitudes: u32,
    acks: u32,
    asked: u32,
    last_heartbeat: Option<HEARTBEAT_DATA>,
}

async fn listen(c: &mut Client, link: SocketAddr, for_s: f64) -> Seen {
    let mut s = Seen::default();
    let t0 = Instant::now();
    let end = t0 + Duration::from_secs_f64(for_s);
    let mut last_hb = t0;
    let mut next_beat = t0;
    let mut next_ask = t0;
    loop {
        let now = Instant::now();
        if now >= end {
            break;
        }
        if now >= next_beat {
            c.heartbeat(link).await;
            next_beat += Duration::from_secs(1);
        }
        if now >= next_ask {
            c.command_long(link, 31_337, [0.0; 7], (1, 1)).await;
            s.asked += 1;
            next_ask += Duration::from_millis(500);
        }
        let wait = next_beat
            .min(next_ask)
            .min(end)
            .saturating_duration_since(Instant::now());
        if let Some(r) = c.recv(wait).await {
            match &r.msg {
                Some(MavMessage::HEARTBEAT(h)) if r.sysid == 1 => {
                    let now = Instant::now();
                    s.heartbeat_gap = s.heartbeat_gap.max(now.duration_since(last_hb));
                    last_hb = now;
                    s.heartbeats += 1;
                    s.last_heartbeat = Some(h.clone());
                }
                Some(MavMessage::ATTITUDE(_)) => s.attitudes += 1,
                _ => {}
            }
            if r.ack().is_some_and(|a| a.command == 31_337 && a.result == 3) {
                s.acks += 1;
            }
        }
    }
    s.heartbeat_gap = s.heartbeat_gap.max(end.duration_since(last_hb));
    s
}

/// Valid frames from many spoofed sources (127.0.0.2 to 127.0.0.41, five
/// ports each): heartbeats (to be proven and crowd the table), parameter
/// lists, pings and commands, about 10,000 datagrams/s for `for_s`.
fn spoofed_flood(to: SocketAddr, for_s: f64) -> std::thread::JoinHandle<u64> {
    std::thread::spawn(move || {
        let socks: Vec<std::net::UdpSocket> = (2..42u8)
            .flat_map(|host| (0..5).map(move |_| host))
            .filter_map(|host| std::net::UdpSocket::bind(SocketAddr::from(([127, 0, 0, host], 0))).ok())
            .collect();
        let hb = v2(&MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            mavtype: MavType::MAV_TYPE_GCS,
            ..Default::default()
        }));
        let mut frames: Vec<Vec<u8>> = request_kinds().into_iter().map(|(_, f)| f).collect();
        frames.push(hb);
        let start = std::time::Instant::now();
        let mut sent = 0u64;
        while start.elapsed().as_secs_f64() < for_s {
            let s = &socks[(sent as usize) % socks.len()];
            let f = &frames[(sent as usize / socks.len()) % frames.len()];
            if s.send_to(f, to).is_ok() {
                sent += 1;
            }
            if sent.is_multiple_of(50) {
                std::thread::sleep(Duration::from_millis(5));
            }
        }
        sent
    })
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_spoofed_source_flood_cannot_push_the_real_gcs_off_the_link() {
    let v = Vehicle::start(config(None, None, 1.0)).await;
    let mut gcs = Client::with_ids(255, 190).await;
    // the GCS is learned (not the default remote) before the flood
    let before = listen(&mut gcs, v.gcs, 2.0).await;
    assert!(before.attitudes > 50, "{before:?}");
    let flood = spoofed_flood(v.gcs, 6.0);
    let during = listen(&mut gcs, v.gcs, 6.0).await;
    let sent = tokio::task::spawn_blocking(move || flood.join().unwrap())
        .await
        .unwrap();
    let after = listen(&mut gcs, v.gcs, 2.0).await;
    eprintln!("spoofed flood: {sent} datagrams in 6 s from 200 sources; the GCS saw {during:?}");
    assert!(sent > 30_000, "the flood was a flood: {sent}");
    assert!(during.heartbeat_gap < Duration::from_millis(1500), "{during:?}");
    assert!(during.attitudes > 250, "ATTITUDE at 50 Hz kept coming: {during:?}");
    assert!(during.acks + 1 >= during.asked, "every command answered: {during:?}");
    // still a proven peer afterwards: streams and answers
    assert!(after.attitudes > 50 && after.acks + 1 >= after.asked, "{after:?}");
    v.stop().await;
}

/// A small deterministic generator (xorshift64*).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }

    fn bytes(&mut self, n: usize) -> Vec<u8> {
        (0..n).map(|_| self.next() as u8).collect()
    }
}

/// Datagram `k` of the held flood: random bytes, truncated and bad-CRC
/// frames, valid frames for other systems (arm, mode, parameter, mission
/// clear, reboot: all for system 2), oversized datagrams, v1 and v2, and
/// valid harmless requests.
fn held_flood_datagram(rng: &mut Rng, k: u64) -> Vec<u8> {
    let other = |m: &MavMessage, v1_frame: bool| if v1_frame { v1(m) } else { v2(m) };
    let harmless = request_kinds();
    match k % 10 {
        0 => {
            let n = 1 + rng.below(300);
            rng.bytes(n)
        }
        1 => {
            let (_, f) = &harmless[rng.below(harmless.len())];
            f[..1 + rng.below(f.len() - 1)].to_vec()
        }
        2 => {
            let (_, f) = &harmless[rng.below(harmless.len())];
            let mut f = f.clone();
            let i = 1 + rng.below(f.len() - 1);
            f[i] ^= 1 + rng.below(255) as u8;
            f
        }
        3 => command(400, [1.0, 21196.0, 0.0, 0.0, 0.0, 0.0, 0.0], (2, 1)),
        4 => other(
            &MavMessage::SET_MODE(SET_MODE_DATA {
                custom_mode: 4 << 16,
                target_system: 2,
                base_mode: MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED,
            }),
            k % 20 == 4,
        ),
        5 => other(
            &MavMessage::PARAM_SET(PARAM_SET_DATA {
                param_value: 9.0,
                target_system: 2,
                target_component: 1,
                param_id: "MPC_XY_VEL_MAX".into(),
                param_type: MavParamType::MAV_PARAM_TYPE_REAL32,
            }),
            k % 20 == 5,
        ),
        6 => other(
            &MavMessage::MISSION_CLEAR_ALL(MISSION_CLEAR_ALL_DATA {
                target_system: 2,
                target_component: 1,
                mission_type: MavMissionType::MAV_MISSION_TYPE_ALL,
            }),
            k % 20 == 6,
        ),
        7 if k % 1000 == 7 => vec![0xFD; MAX_UDP],
        7 => command(246, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], (2, 1)),
        _ => {
            let (_, f) = &harmless[rng.below(harmless.len())];
            if k % 20 == 8 {
                // the same request as MAVLink 1 where it fits
                match wire::frames(f).next().and_then(|fr| wire::decode(&fr)) {
                    Some(wire::Inbound::Other(m)) if fr_v1_ok(&m) => v1(&m),
                    _ => f.clone(),
                }
            } else {
                f.clone()
            }
        }
    }
}

/// Whether a message has a MAVLink 1 id (below 256).
fn fr_v1_ok(m: &MavMessage) -> bool {
    mavlink::Message::message_id(m) < 256
}

/// Everything a client can read of the vehicle's state: armed, mode, every
/// parameter, and the stored plans' counts.
async fn vehicle_state(c: &mut Client, link: SocketAddr) -> (bool, u32, Vec<(String, u32)>, Vec<u16>) {
    c.heartbeat(link).await;
    let h = common::daemon::heartbeat(c, Duration::from_secs(3)).await;
    c.drain().await;
    c.send(
        link,
        &MavMessage::PARAM_REQUEST_LIST(PARAM_REQUEST_LIST_DATA {
            target_system: 1,
            target_component: 1,
        }),
    )
    .await;
    let mut params = std::collections::BTreeMap::new();
    let mut count = u16::MAX;
    let end = Instant::now() + Duration::from_secs(5);
    while params.len() < usize::from(count) {
        let Some(r) = c.recv(end.saturating_duration_since(Instant::now())).await else {
            break;
        };
        if let Some(MavMessage::PARAM_VALUE(p)) = r.msg {
            count = p.param_count;
            params.insert(
                p.param_index,
                (p.param_id.to_str().unwrap_or("").to_string(), p.param_value.to_bits()),
            );
        }
    }
    assert_eq!(params.len(), usize::from(count), "the whole parameter list");
    let mut plans = Vec::new();
    for mission_type in [
        MavMissionType::MAV_MISSION_TYPE_MISSION,
        MavMissionType::MAV_MISSION_TYPE_FENCE,
        MavMissionType::MAV_MISSION_TYPE_RALLY,
    ] {
        c.send(
            link,
            &MavMessage::MISSION_REQUEST_LIST(MISSION_REQUEST_LIST_DATA {
                target_system: 1,
                target_component: 1,
                mission_type,
            }),
        )
        .await;
        let n = c
            .wait_for(Duration::from_secs(3), |r| match &r.msg {
                Some(MavMessage::MISSION_COUNT(n)) if n.mission_type == mission_type => Some(n.count),
                _ => None,
            })
            .await
            .expect("MISSION_COUNT");
        plans.push(n);
    }
    (
        h.base_mode.contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED),
        h.custom_mode,
        params.into_values().collect(),
        plans,
    )
}

/// Issue 15 §5's held robustness flood; CI runs it (`cargo test --release`
/// runs every test of this file; about 25 s).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn held_flood_of_200000_mixed_datagrams_at_10000_per_s_changes_nothing() {
    const DATAGRAMS: u64 = 200_000;
    const RATE: f64 = 10_000.0;
    let v = Vehicle::start(config(None, None, 1.0)).await;
    let mut gcs = Client::with_ids(255, 190).await;
    let before = vehicle_state(&mut gcs, v.gcs).await;
    assert!(!before.0, "disarmed");
    let to = v.gcs;
    let flood = std::thread::spawn(move || {
        let sock = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
        let start = std::time::Instant::now();
        for k in 0..DATAGRAMS {
            let d = held_flood_datagram(&mut rng, k);
            let _ = sock.send_to(&d, to);
            // pace: datagram k leaves at k / RATE
            let due = Duration::from_secs_f64(k as f64 / RATE);
            if let Some(wait) = due.checked_sub(start.elapsed())
                && k % 50 == 0
            {
                std::thread::sleep(wait);
            }
        }
        start.elapsed()
    });
    let seen = listen(&mut gcs, v.gcs, DATAGRAMS as f64 / RATE).await;
    let took = tokio::task::spawn_blocking(move || flood.join().unwrap())
        .await
        .unwrap();
    let after = vehicle_state(&mut gcs, v.gcs).await;
    eprintln!(
        "held flood: {DATAGRAMS} datagrams in {:.1} s; the GCS saw {} heartbeats (longest gap {:?}), {} ATTITUDEs, {}/{} ACKs",
        took.as_secs_f64(),
        seen.heartbeats,
        seen.heartbeat_gap,
        seen.attitudes,
        seen.acks,
        seen.asked
    );
    assert!(took.as_secs_f64() < 30.0, "about 10,000 datagrams/s: {took:?}");
    assert!(seen.heartbeat_gap < Duration::from_millis(1500), "{seen:?}");
    assert_eq!(after, before, "armed, mode, parameters and plans unchanged");
    v.stop().await;
}
