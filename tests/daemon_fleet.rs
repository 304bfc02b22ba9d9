//! A fleet in one process, in-process on loopback (`daemon::bind_fleet`):
//! each vehicle answers with its own system id on its own links, a command
//! moves only the vehicle it was sent to, proximity and collisions reach both
//! vehicles' links, so does each encounter's end with its closest approach
//! (recorded, replayed), and a client flooding one vehicle does not stall
//! another.

mod common;

use std::net::SocketAddr;
use std::path::Path;
use std::time::Duration;

use common::daemon::*;
use common::scratch_path;
use mavlink::dialects::common::MavMessage;
use nalgebra::Vector3;
use rotorpilot::daemon::{self, FleetConfig, LinkSpec};
use rotorpilot::geo::GeoPoint;
use tokio::sync::oneshot;
use tokio::task::JoinHandle;
use tokio::time::{Instant, timeout};

/// A running in-process fleet.
struct Fleet {
    /// Each vehicle's (GCS, API) link address.
    links: Vec<(SocketAddr, SocketAddr)>,
    stop: Option<oneshot::Sender<()>>,
    handle: Option<JoinHandle<anyhow::Result<()>>>,
    dirs: Vec<std::path::PathBuf>,
}

impl Fleet {
    /// `n` vehicles (instances 0..n), vehicle i spawned `spacing_m` x i north
    /// of PX4's home; every GCS link sends to `gcs`.
    async fn start(n: u8, spacing_m: f64, speed: f64, gcs: SocketAddr) -> Fleet {
        Self::start_logged(n, spacing_m, speed, gcs, None).await
    }

    /// [`Self::start`], each vehicle logging below `logs` (with the CSV).
    async fn start_logged(n: u8, spacing_m: f64, speed: f64, gcs: SocketAddr, logs: Option<&Path>) -> Fleet {
        let origin = GeoPoint::PX4_SITL_HOME;
        let vehicles: Vec<_> = (0..n)
            .map(|i| {
                let mut c = config(Some(gcs), None, speed);
                c.instance = i;
                c.links = vec![
                    LinkSpec {
                        bind: "127.0.0.1:0".parse().unwrap(),
                        remote: Some(gcs),
                        ..LinkSpec::px4_gcs(i)
                    },
                    LinkSpec {
                        bind: "127.0.0.1:0".parse().unwrap(),
                        remote: None,
                        ..LinkSpec::px4_api(i)
                    },
                ];
                c.home = origin.offset(&Vector3::new(spacing_m * f64::from(i), 0.0, 0.0));
                c.log_dir = logs.map(Path::to_path_buf);
                c.log_csv = logs.is_some();
                c
            })
            .collect();
        let dirs = vehicles.iter().map(|c| c.state_dir.clone()).collect();
        let d = daemon::bind_fleet(FleetConfig {
            vehicles,
            origin,
            proximity_m: 2.0,
        })
        .await
        .expect("bind the fleet");
        let links = (0..usize::from(n))
            .map(|i| {
                let a = d.vehicle_addrs(i);
                (a[0].1, a[1].1)
            })
            .collect();
        let (tx, rx) = oneshot::channel::<()>();
        let handle = tokio::spawn(d.run(async move {
            let _ = rx.await;
        }));
        Fleet {
            links,
            stop: Some(tx),
            handle: Some(handle),
            dirs,
        }
    }

    async fn stop(mut self) {
        if let Some(s) = self.stop.take() {
            let _ = s.send(());
        }
        if let Some(h) = self.handle.take() {
            timeout(Duration::from_secs(10), h)
                .await
                .expect("the fleet stops")
                .expect("join")
                .expect("fleet result");
        }
    }
}

impl Drop for Fleet {
    fn drop(&mut self) {
        if let Some(s) = self.stop.take() {
            let _ = s.send(());
        }
        for d in &self.dirs {
            let _ = std::fs::remove_dir_all(d);
        }
    }
}

/// The latest GLOBAL_POSITION_INT of system `sysid` within `wait`.
async fn position(c: &mut Client, sysid: u8, wait: Duration) -> (f64, bool) {
    let mut armed = None;
    let mut alt = None;
    let deadline = Instant::now() + wait;
    while alt.is_none() || armed.is_none() {
        let left = deadline
            .checked_duration_since(Instant::now())
            .expect("telemetry in time");
        let rx = c.recv(left).await.expect("telemetry");
        if rx.sysid != sysid {
            continue;
        }
        match &rx.msg {
            Some(MavMessage::GLOBAL_POSITION_INT(p)) => alt = Some(f64::from(p.relative_alt) / 1000.0),
            Some(MavMessage::HEARTBEAT(h)) => {
                armed = Some(h.base_mode.bits() & 0x80 != 0);
            }
            _ => {}
        }
    }
    (alt.unwrap(), armed.unwrap())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn each_vehicle_is_its_own_system_and_only_the_one_commanded_flies() {
    let mut gcs = Client::with_ids(255, 190).await;
    let fleet = Fleet::start(3, 3.0, 5.0, gcs.addr()).await;
    // every vehicle's heartbeat arrives with its own system id, from its own link
    let mut seen = [false; 3];
    let deadline = Instant::now() + Duration::from_secs(5);
    while seen.iter().any(|s| !s) {
        let rx = gcs
            .recv(deadline.saturating_duration_since(Instant::now()))
            .await
            .expect("heartbeats from every vehicle");
        if let Some(MavMessage::HEARTBEAT(_)) = rx.msg {
            let i = usize::from(rx.sysid) - 1;
            assert_eq!(
                rx.from, fleet.links[i].0,
                "system {} speaks from its own GCS link",
                rx.sysid
            );
            seen[i] = true;
        }
    }
    // vehicle 1 (system 2) arms and takes off through its API link
    let mut api = Client::new().await;
    let (_, v1) = fleet.links[1];
    api.heartbeat(v1).await;
    wait_armable(&mut api).await;
    api.command_long(v1, 400, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], (2, 1))
        .await;
    let (rx, ack) = api.ack_of(400, Duration::from_secs(3)).await.expect("arm ACK");
    assert_eq!((rx.sysid, ack.result), (2, 0), "system 2 armed");
    api.command_long(v1, 22, [NAN, 0.0, 0.0, NAN, NAN, NAN, NAN], (2, 1))
        .await;
    let (_, ack) = api.ack_of(22, Duration::from_secs(3)).await.expect("takeoff ACK");
    assert_eq!(ack.result, 0);
    // a command for system 1 sent to system 2's link is not its to answer
    api.drain().await;
    api.command_long(v1, 400, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], (1, 1))
        .await;
    assert!(
        api.ack_of(400, Duration::from_millis(500)).await.is_none(),
        "system 2 ignores a command for system 1"
    );
    // at x5, two wall seconds are ten simulated: system 2 is up, the others stay put
    tokio::time::sleep(Duration::from_secs(2)).await;
    gcs.drain().await;
    let (alt2, armed2) = position(&mut gcs, 2, Duration::from_secs(3)).await;
    assert!(armed2 && alt2 > 2.0, "system 2 flies: armed {armed2}, {alt2:.2} m up");
    for s in [1, 3] {
        let (alt, armed) = position(&mut gcs, s, Duration::from_secs(3)).await;
        assert!(
            !armed && alt.abs() < 0.5,
            "system {s} stays put: armed {armed}, {alt:.2} m"
        );
    }
    fleet.stop().await;
}

/// The STATUSTEXTs a fleet of two spawned `spacing_m` apart tells in its
/// first 1.5 s, as (system id, text).
async fn texts_of_two(spacing_m: f64) -> Vec<(u8, String)> {
    let mut gcs = Client::with_ids(255, 190).await;
    let fleet = Fleet::start(2, spacing_m, 1.0, gcs.addr()).await;
    let mut out = Vec::new();
    let deadline = Instant::now() + Duration::from_millis(1500);
    while let Some(rx) = gcs.recv(deadline.saturating_duration_since(Instant::now())).await {
        if let Some(MavMessage::STATUSTEXT(s)) = &rx.msg {
            let text: Vec<u8> = s.text.iter().copied().take_while(|&b| b != 0).collect();
            out.push((rx.sysid, String::from_utf8_lossy(&text).into_owned()));
        }
    }
    fleet.stop().await;
    out
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn proximity_and_collisions_reach_both_vehicles_links() {
    let told = |texts: &[(u8, String)], sysid: u8, text: &str| texts.iter().any(|(s, t)| *s == sysid && t == text);
    // spawned 1.5 m apart: closer than the 2 m reported, bodies apart
    let t = texts_of_two(1.5).await;
    assert!(told(&t, 1, "Proximity: system 2 at 1.5 m"), "{t:?}");
    assert!(told(&t, 2, "Proximity: system 1 at 1.5 m"), "{t:?}");
    assert!(!t.iter().any(|(_, x)| x.starts_with("Collision")), "{t:?}");
    // spawned 0.3 m apart: the quads' bodies (0.39 m radius each) overlap
    let t = texts_of_two(0.3).await;
    assert!(told(&t, 1, "Collision with system 2 (0.30 m)"), "{t:?}");
    assert!(told(&t, 2, "Collision with system 1 (0.30 m)"), "{t:?}");
}

/// The simulated time [ms] of system `sysid`'s next ATTITUDE.
async fn boot_ms(c: &mut Client, sysid: u8) -> u32 {
    c.wait_for(Duration::from_secs(2), |r| match &r.msg {
        Some(MavMessage::ATTITUDE(a)) if r.sysid == sysid => Some(a.time_boot_ms),
        _ => None,
    })
    .await
    .expect("ATTITUDE")
}

/// A flood of COMMAND_LONGs and offboard setpoints on vehicle 0's API link,
/// from a thread of its own, about 20,000 datagrams a second (twice the rate
/// of the robustness flood; faster only fills the kernel's buffer),
/// for `for_s` seconds; the datagrams sent.
fn flood(to: SocketAddr, for_s: f64) -> std::thread::JoinHandle<u64> {
    std::thread::spawn(move || {
        use mavlink::dialects::common::{COMMAND_LONG_DATA, MavCmd, SET_POSITION_TARGET_LOCAL_NED_DATA};
        let sock = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        let header = mavlink::MavHeader {
            system_id: 245,
            component_id: 190,
            sequence: 0,
        };
        let frame = |m: &MavMessage| {
            let mut raw = mavlink::MAVLinkV2MessageRaw::new();
            raw.serialize_message(header, m);
            raw.raw_bytes().to_vec()
        };
        let command = frame(&MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            command: MavCmd::MAV_CMD_DO_SET_MODE,
            param1: 1.0,
            param2: 4.0,
            param3: 3.0,
            target_system: 1,
            target_component: 1,
            ..Default::default()
        }));
        let setpoint = frame(&MavMessage::SET_POSITION_TARGET_LOCAL_NED(
            SET_POSITION_TARGET_LOCAL_NED_DATA {
                target_system: 1,
                target_component: 1,
                type_mask: mavlink::dialects::common::PositionTargetTypemask::from_bits_truncate(0x0DF8),
                z: -2.0,
                ..Default::default()
            },
        ));
        let start = std::time::Instant::now();
        let mut sent = 0u64;
        while start.elapsed().as_secs_f64() < for_s {
            let f = if sent.is_multiple_of(2) { &command } else { &setpoint };
            if sock.send_to(f, to).is_ok() {
                sent += 1;
            }
            if sent.is_multiple_of(100) {
                std::thread::sleep(Duration::from_millis(5));
            }
        }
        sent
    })
}

#[tokio::test(flavor = "current_thread")]
async fn a_client_flooding_one_vehicle_does_not_stall_another() {
    // the links share one thread, as in `rotorpilot`
    let gcs = Client::with_ids(255, 190).await;
    let fleet = Fleet::start(2, 3.0, 1.0, gcs.addr()).await;
    let (_, api0) = fleet.links[0];
    let (_, api1) = fleet.links[1];
    let mut c1 = Client::new().await;
    c1.heartbeat(api1).await;
    let t0 = boot_ms(&mut c1, 2).await;
    let wall0 = Instant::now();
    let flooder = flood(api0, 3.0);
    // system 2 is commanded every 100 ms meanwhile: each answered, at once
    let mut worst = Duration::ZERO;
    for _ in 0..25 {
        c1.drain().await;
        let sent = Instant::now();
        c1.command_long(api1, 176, [1.0, 4.0, 3.0, 0.0, 0.0, 0.0, 0.0], (2, 1))
            .await;
        let (rx, ack) = c1
            .ack_of(176, Duration::from_secs(2))
            .await
            .expect("system 2 answers during the flood");
        // ACCEPTED: neither "busy" nor "did not answer"
        assert_eq!((rx.sysid, ack.result), (2, 0));
        worst = worst.max(sent.elapsed());
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    c1.drain().await;
    let t1 = boot_ms(&mut c1, 2).await;
    let wall = wall0.elapsed().as_secs_f64();
    let sent = tokio::task::spawn_blocking(move || flooder.join().unwrap())
        .await
        .unwrap();
    let sim = f64::from(t1 - t0) / 1000.0;
    eprintln!("flood: {sent} datagrams in 3 s; system 2: worst ACK {worst:?}, {sim:.2} s simulated in {wall:.2} s");
    assert!(sent > 10_000, "the flood was a flood: {sent} datagrams");
    // a few requests of the flood at most go before it (a few microseconds
    // each); 50 ms leaves room for a loaded test machine
    assert!(worst < Duration::from_millis(50), "worst ACK {worst:?}");
    assert!(
        sim > 0.9 * wall - 0.2,
        "system 2's clock kept pace: {sim:.2} s in {wall:.2} s"
    );
    // and the flooded vehicle still answers afterwards, once the datagrams
    // queued in its socket are read: a client retries as MAVSDK does (on a
    // loaded machine the backlog can take longer than one timeout)
    let mut c0 = Client::new().await;
    let mut answered = false;
    for _ in 0..5 {
        c0.command_long(api0, 176, [1.0, 4.0, 3.0, 0.0, 0.0, 0.0, 0.0], (1, 1))
            .await;
        if c0.ack_of(176, Duration::from_secs(2)).await.is_some() {
            answered = true;
            break;
        }
    }
    assert!(answered, "system 1 answers after the flood");
    fleet.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn each_vehicle_of_a_fleet_replays_alone_bit_for_bit_proximity_included() {
    let logs = scratch_path("fleet-logs");
    let gcs = Client::with_ids(255, 190).await;
    // 1.5 m apart: a proximity event at the first step, for both
    let fleet = Fleet::start_logged(2, 1.5, 10.0, gcs.addr(), Some(&logs)).await;
    let (_, api1) = fleet.links[1];
    let mut c = Client::new().await;
    c.heartbeat(api1).await;
    wait_armable(&mut c).await;
    c.command_long(api1, 400, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], (2, 1))
        .await;
    assert_eq!(c.ack_of(400, Duration::from_secs(3)).await.expect("arm").1.result, 0);
    c.command_long(api1, 22, [NAN, 0.0, 0.0, NAN, NAN, NAN, NAN], (2, 1))
        .await;
    assert_eq!(c.ack_of(22, Duration::from_secs(3)).await.expect("takeoff").1.result, 0);
    tokio::time::sleep(Duration::from_millis(800)).await;
    fleet.stop().await;
    let mut runs: Vec<_> = std::fs::read_dir(&logs).unwrap().map(|e| e.unwrap().path()).collect();
    runs.sort();
    assert_eq!(runs.len(), 2, "a run directory per vehicle: {runs:?}");
    for (i, run) in runs.iter().enumerate() {
        assert!(
            run.to_string_lossy().ends_with(&format!("-i{i}")),
            "{} is vehicle {i}'s",
            run.display()
        );
        let text = std::fs::read_to_string(run.join("flight.record")).unwrap();
        let other = 2 - i;
        assert!(
            text.lines().any(|l| l.contains("\"proximity\":")
                && l.contains(&format!("\"other\":\"system {other}\""))
                && l.contains("\"kind\":\"near\"")),
            "vehicle {i}'s record holds the proximity event"
        );
        let r = rotorpilot::logs::record::read_record(&text, "flight.record").unwrap();
        let mut csv = Vec::new();
        rotorpilot::logs::replay::replay(&r, "flight.record", Some(&mut csv)).unwrap();
        let live = std::fs::read(run.join("flight.csv")).unwrap();
        assert!(live.len() > 1000);
        assert!(
            csv == live,
            "vehicle {i}: the replay's CSV is the live flight.csv, byte for byte"
        );
        // the status texts (logged messages, with their timestamps) of the
        // replay's ULog are the live ones, the proximity text included
        let mut ulg = Vec::new();
        rotorpilot::logs::replay::replay_logs(&r, "flight.record", None, Some(&mut ulg)).unwrap();
        let texts = |b: &[u8]| -> Vec<Vec<u8>> {
            ulog_records(b)
                .into_iter()
                .filter(|(t, _)| *t == b'L')
                .map(|(_, p)| p)
                .collect()
        };
        let live_texts = texts(&std::fs::read(run.join("flight.ulg")).unwrap());
        let proximity = format!("Proximity: system {other} at 1.5 m");
        assert!(
            live_texts
                .iter()
                .any(|p| p.windows(proximity.len()).any(|w| w == proximity.as_bytes())),
            "vehicle {i}'s flight.ulg logs {proximity:?}"
        );
        assert!(
            texts(&ulg) == live_texts,
            "vehicle {i}: the replay's ULog messages are the live ones"
        );
    }
    let _ = std::fs::remove_dir_all(&logs);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn each_vehicle_saves_its_own_parameters_at_shutdown() {
    let gcs = Client::with_ids(255, 190).await;
    let fleet = Fleet::start(3, 3.0, 1.0, gcs.addr()).await;
    let dirs = fleet.dirs.clone();
    let (_, api1) = fleet.links[1];
    let mut c = Client::new().await;
    c.send(
        api1,
        &MavMessage::PARAM_SET(mavlink::dialects::common::PARAM_SET_DATA {
            param_value: 7.5,
            target_system: 2,
            target_component: 1,
            param_id: "MPC_XY_CRUISE".into(),
            param_type: mavlink::dialects::common::MavParamType::MAV_PARAM_TYPE_REAL32,
        }),
    )
    .await;
    c.wait_for(Duration::from_secs(3), |r| match &r.msg {
        Some(MavMessage::PARAM_VALUE(p)) if r.sysid == 2 && p.param_value == 7.5 => Some(()),
        _ => None,
    })
    .await
    .expect("system 2 took the value");
    // the files now, then wipe them: only the shutdown saves can write them back
    for d in &dirs {
        std::fs::write(d.join("params.toml"), "# wiped by the test\n").unwrap();
    }
    let mut fleet = fleet;
    fleet.dirs.clear(); // keep them for the check
    fleet.stop().await;
    for (i, d) in dirs.iter().enumerate() {
        let text = std::fs::read_to_string(d.join("params.toml")).unwrap();
        assert!(
            // vehicle 0's MAV_SYS_ID = 1 is the default: commented out
            text.lines().any(|l| l
                .trim_start_matches("# ")
                .starts_with(&format!("MAV_SYS_ID = {} ", i + 1))
                || l == format!("MAV_SYS_ID = {}", i + 1)),
            "vehicle {i}'s own file, saved at shutdown: {text}"
        );
        let set = text.lines().any(|l| l.starts_with("MPC_XY_CRUISE = 7.5"));
        assert_eq!(set, i == 1, "only system 2 had MPC_XY_CRUISE set: vehicle {i}");
        let _ = std::fs::remove_dir_all(d);
    }
}

/// A ULog's records after its 16-byte header: (type, payload) of each
/// (`u16` size, `u8` type, payload: the ULog file format).
fn ulog_records(b: &[u8]) -> Vec<(u8, Vec<u8>)> {
    assert_eq!(&b[..7], b"ULog\x01\x12\x35", "not a ULog");
    let (mut at, mut out) = (16, Vec::new());
    while at + 3 <= b.len() {
        let size = usize::from(u16::from_le_bytes([b[at], b[at + 1]]));
        out.push((b[at + 2], b[at + 3..at + 3 + size].to_vec()));
        at += 3 + size;
    }
    assert_eq!(at, b.len(), "a record cut short");
    out
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn each_vehicle_forwards_among_its_own_links_only() {
    use mavlink::dialects::common::{MavSeverity, STATUSTEXT_DATA};
    // one GCS on both vehicles' GCS links, a companion on vehicle 0's API link
    let mut gcs = Client::with_ids(255, 190).await;
    let fleet = Fleet::start(2, 3.0, 1.0, gcs.addr()).await;
    for (g, _) in &fleet.links {
        gcs.heartbeat(*g).await;
    }
    let mut api = Client::with_ids(245, 191).await;
    let (_, api0) = fleet.links[0];
    api.heartbeat(api0).await;
    api.wait_for(Duration::from_secs(3), |r| (r.sysid == 1).then_some(()))
        .await
        .expect("vehicle 0 answers on its API link");
    gcs.drain().await;
    let text = MavMessage::STATUSTEXT(STATUSTEXT_DATA {
        severity: MavSeverity::MAV_SEVERITY_INFO,
        text: "from the companion of system 1".into(),
        id: 0,
        chunk_seq: 0,
    });
    api.send(api0, &text).await;
    let mut from = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(1);
    while let Some(left) = deadline.checked_duration_since(Instant::now()) {
        let Some(r) = gcs.recv(left).await else { break };
        if (r.sysid, r.compid, r.msgid) == (245, 191, 253) {
            from.push(r.from);
        }
    }
    assert_eq!(
        from,
        vec![fleet.links[0].0],
        "once, from vehicle 0's GCS link; vehicle 1 never heard the companion"
    );
    fleet.stop().await;
}

/// Each row's true position (NED [m], the vehicle's own frame) of a flight CSV.
fn true_positions(csv: &str) -> Vec<[f64; 3]> {
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().expect("a header").split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).expect(name);
    let cols = [col("true_pos_n"), col("true_pos_e"), col("true_pos_d")];
    lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            cols.map(|c| f[c].parse().unwrap())
        })
        .collect()
}

/// A fleet of two, 3 m apart (not near), each logging below `logs` when
/// given, at x5: system 2 takes off (1 m asked), then flies south over
/// system 1 to 3.3 m beyond it. The closest approach each is told when
/// the encounter ends, naming the other (its "Passed" STATUSTEXT,
/// sorted by system id).
async fn encounter_told(logs: Option<&Path>) -> Vec<(u8, String)> {
    let mut gcs = Client::with_ids(255, 190).await;
    let fleet = Fleet::start_logged(2, 3.0, 5.0, gcs.addr(), logs).await;
    let (_, api1) = fleet.links[1];
    let mut c = Client::new().await;
    c.heartbeat(api1).await;
    wait_armable(&mut c).await;
    let home = rotorpilot::geo::GeoPoint::PX4_SITL_HOME;
    let low = (home.alt_amsl_m + 1.0) as f32;
    let arm = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    assert_eq!(
        c.command_long_acked(api1, 400, arm, (2, 1)).await.expect("arm").result,
        0
    );
    let takeoff = [NAN, 0.0, 0.0, NAN, NAN, NAN, low];
    assert_eq!(
        c.command_long_acked(api1, 22, takeoff, (2, 1))
            .await
            .expect("takeoff")
            .result,
        0
    );
    tokio::time::sleep(Duration::from_millis(1500)).await;
    let south = [
        -1.0,
        1.0,
        0.0,
        NAN,
        (home.lat_deg - 3e-5) as f32,
        home.lon_deg as f32,
        low,
    ];
    assert_eq!(
        c.command_long_acked(api1, 192, south, (2, 1))
            .await
            .expect("reposition")
            .result,
        0
    );
    // both are told, each naming the other
    let mut passed: Vec<(u8, String)> = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(15);
    while passed.len() < 2 {
        let rx = gcs
            .recv(deadline.saturating_duration_since(Instant::now()))
            .await
            .unwrap_or_else(|| panic!("both told of the encounter's end in time: {passed:?}"));
        if let Some(MavMessage::STATUSTEXT(s)) = &rx.msg {
            let text: Vec<u8> = s.text.iter().copied().take_while(|&b| b != 0).collect();
            let text = String::from_utf8_lossy(&text).into_owned();
            if text.starts_with("Passed") {
                assert_eq!(s.severity, mavlink::dialects::common::MavSeverity::MAV_SEVERITY_INFO);
                passed.push((rx.sysid, text));
            }
        }
    }
    fleet.stop().await;
    passed.sort();
    passed
}

/// The closest approach that `passed` (of [`encounter_told`]) tells system
/// `other`'s partner, as its text gives it [m].
fn closest(passed: &[(u8, String)], other: u8) -> String {
    let prefix = format!("Passed system {other}: closest approach ");
    let (_, t) = passed
        .iter()
        .find(|(_, t)| t.starts_with(&prefix))
        .unwrap_or_else(|| panic!("{passed:?}"));
    t[prefix.len()..].strip_suffix(" m").expect("in metres").to_string()
}

/// Unlogged, the fleet steps each vehicle ahead through a chunk of steps
/// (`Lockstep::step_ahead`): the encounter is still followed instant by
/// instant and told to both.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_unlogged_fleet_tells_both_of_an_encounter_and_its_closest_approach() {
    let passed = encounter_told(None).await;
    assert_eq!((passed[0].0, passed[1].0), (1, 2), "{passed:?}");
    let told = closest(&passed, 2);
    assert_eq!(closest(&passed, 1), told, "both told the same closest approach");
    let d: f64 = told.parse().unwrap();
    assert!(d > 0.0 && d < 2.0, "they crossed closer than the 2 m reported: {d}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_encounter_ends_with_its_closest_approach_told_to_both_and_replayed() {
    let logs = scratch_path("fleet-encounter");
    let passed = encounter_told(Some(&logs)).await;
    let closest = |other: u8| closest(&passed, other);
    assert_eq!((passed[0].0, passed[1].0), (1, 2), "{passed:?}");
    let told = closest(2);
    assert_eq!(closest(1), told, "both told the same closest approach");
    // the least distance between the two over the flight (the CSVs: each
    // in its own frame, system 2's spawned 3 m north of system 1's)
    let mut runs: Vec<_> = std::fs::read_dir(&logs).unwrap().map(|e| e.unwrap().path()).collect();
    runs.sort();
    let p: Vec<_> = runs
        .iter()
        .map(|r| true_positions(&std::fs::read_to_string(r.join("flight.csv")).unwrap()))
        .collect();
    let d_min = p[0]
        .iter()
        .zip(&p[1])
        .map(|(a, b)| ((b[0] + 3.0 - a[0]).powi(2) + (b[1] - a[1]).powi(2) + (b[2] - a[2]).powi(2)).sqrt())
        .fold(f64::INFINITY, f64::min);
    assert!(d_min < 2.0, "they crossed closer than the 2 m reported: {d_min}");
    assert_eq!(
        told,
        format!("{d_min:.2}"),
        "the closest approach told is the least distance"
    );
    // each record holds it, and its replay announces it at the same step
    for (i, run) in runs.iter().enumerate() {
        let text = std::fs::read_to_string(run.join("flight.record")).unwrap();
        let other = 2 - i;
        assert!(
            text.lines()
                .any(|l| l.contains("\"encounter_ended\":") && l.contains(&format!("\"other\":\"system {other}\""))),
            "vehicle {i}'s record holds the encounter's end"
        );
        let r = rotorpilot::logs::record::read_record(&text, "flight.record").unwrap();
        let mut ulg = Vec::new();
        rotorpilot::logs::replay::replay_logs(&r, "flight.record", None, Some(&mut ulg)).unwrap();
        let texts = |b: &[u8]| -> Vec<Vec<u8>> {
            ulog_records(b)
                .into_iter()
                .filter(|(t, _)| *t == b'L')
                .map(|(_, p)| p)
                .collect()
        };
        let live_texts = texts(&std::fs::read(run.join("flight.ulg")).unwrap());
        let passed = format!("Passed system {other}: closest approach {told} m");
        assert!(
            live_texts
                .iter()
                .any(|p| p.windows(passed.len()).any(|w| w == passed.as_bytes())),
            "vehicle {i}'s flight.ulg logs {passed:?}"
        );
        assert!(
            texts(&ulg) == live_texts,
            "vehicle {i}: the replay's ULog messages (text and instant) are the live ones"
        );
    }
    let _ = std::fs::remove_dir_all(&logs);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_encounter_still_open_at_shutdown_ends_there_in_both_records() {
    let logs = scratch_path("fleet-encounter-stop");
    let gcs = Client::with_ids(255, 190).await;
    // 1.5 m apart on the ground: near from the first step until the end
    let fleet = Fleet::start_logged(2, 1.5, 5.0, gcs.addr(), Some(&logs)).await;
    tokio::time::sleep(Duration::from_millis(300)).await;
    fleet.stop().await;
    let mut runs: Vec<_> = std::fs::read_dir(&logs).unwrap().map(|e| e.unwrap().path()).collect();
    runs.sort();
    for (i, run) in runs.iter().enumerate() {
        let text = std::fs::read_to_string(run.join("flight.record")).unwrap();
        let r = rotorpilot::logs::record::read_record(&text, "flight.record").unwrap();
        let last = r.inputs.last().expect("inputs");
        let closest_m = match &last.input {
            rotorpilot::lockstep::input::Input::EncounterEnded { other, closest_m, .. } => {
                assert_eq!(other, &format!("system {}", 2 - i));
                *closest_m
            }
            other => panic!("vehicle {i}'s last input is the encounter's end, not {other:?}"),
        };
        assert_eq!(Some(last.step), r.end, "at the last step");
        assert!(closest_m <= 1.5 + 1e-6, "{closest_m}");
        // the live flight.ulg logs it as the daemon stops; the replay's too
        let mut ulg = Vec::new();
        rotorpilot::logs::replay::replay_logs(&r, "flight.record", None, Some(&mut ulg)).unwrap();
        let texts = |b: &[u8]| -> Vec<Vec<u8>> {
            ulog_records(b)
                .into_iter()
                .filter(|(t, _)| *t == b'L')
                .map(|(_, p)| p)
                .collect()
        };
        let live_texts = texts(&std::fs::read(run.join("flight.ulg")).unwrap());
        let passed = format!("Passed system {}: closest approach {closest_m:.2} m", 2 - i);
        assert!(
            live_texts
                .iter()
                .any(|p| p.windows(passed.len()).any(|w| w == passed.as_bytes())),
            "vehicle {i}'s flight.ulg logs {passed:?}"
        );
        assert!(
            texts(&ulg) == live_texts,
            "vehicle {i}: the replay's ULog messages are the live ones"
        );
    }
    let _ = std::fs::remove_dir_all(&logs);
}
