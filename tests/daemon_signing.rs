//! MAVLink signing in the daemon: every vehicle of a fleet reads
//! its own `signing.key` at bind (a bad one stops the start, naming the file
//! and the vehicle); a vehicle with a key answers only signed frames, and
//! signs what it sends, while its neighbour without a key answers anyone.

mod common;

use std::net::SocketAddr;
use std::time::Duration;

use common::daemon::{Client, config};
use mavlink::dialects::common::{MavMessage, PARAM_REQUEST_READ_DATA};
use mavlink::{MAVLinkV2MessageRaw, MavHeader};
use rotorpilot::daemon::{self, FleetConfig, LinkSpec};
use rotorpilot::geo::GeoPoint;
use rotorpilot::link::signing::{self, Stored};
use rotorpilot::link::wire;
use tokio::time::{Instant, timeout};

const KEY: [u8; 32] = [0x42; 32];

fn fleet(n: u8) -> FleetConfig {
    let vehicles = (0..n)
        .map(|i| {
            let mut c = config(None, None, 1.0);
            c.instance = i;
            c.links = vec![
                LinkSpec {
                    bind: "127.0.0.1:0".parse().unwrap(),
                    remote: None,
                    ..LinkSpec::px4_gcs(i)
                },
                LinkSpec {
                    bind: "127.0.0.1:0".parse().unwrap(),
                    remote: None,
                    ..LinkSpec::px4_api(i)
                },
            ];
            c.home = GeoPoint::PX4_SITL_HOME;
            c
        })
        .collect();
    FleetConfig {
        vehicles,
        origin: GeoPoint::PX4_SITL_HOME,
        proximity_m: 0.5,
    }
}

fn put_key_file(dir: &std::path::Path, bytes: &[u8]) {
    std::fs::create_dir_all(dir).unwrap();
    std::fs::write(dir.join("signing.key"), bytes).unwrap();
}

/// PARAM_REQUEST_READ of MIS_TAKEOFF_ALT for `system`, signed with KEY when `signed`.
fn read_request(system: u8, seq: u8, signed: Option<u64>) -> Vec<u8> {
    let msg = MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
        param_index: -1,
        target_system: system,
        target_component: 1,
        param_id: "MIS_TAKEOFF_ALT".into(),
    });
    let mut raw = MAVLinkV2MessageRaw::new();
    raw.serialize_message(
        MavHeader {
            system_id: 255,
            component_id: 190,
            sequence: seq,
        },
        &msg,
    );
    let mut f = raw.raw_bytes().to_vec();
    if let Some(ts) = signed {
        signing::sign_frame(&KEY, &mut f, 7, ts);
    }
    f
}

/// The PARAM_VALUE frames (22) received within `wait`: whether each was signed with KEY.
async fn param_values(c: &Client, wait: Duration) -> Vec<bool> {
    let deadline = Instant::now() + wait;
    let mut out = Vec::new();
    let mut b = vec![0u8; 65536];
    while let Some(left) = deadline.checked_duration_since(Instant::now()) {
        let Ok(Ok((n, _))) = timeout(left, c.sock.recv_from(&mut b)).await else {
            break;
        };
        for f in wire::frames(&b[..n]).filter(|f| f.message_id == 22) {
            out.push(
                f.signature()
                    .is_some_and(|s| signing::signature(&KEY, f.bytes) == s[7..13]),
            );
        }
    }
    out
}

#[tokio::test]
async fn a_bad_key_file_stops_the_start_naming_the_file_and_the_vehicle() {
    let f = fleet(2);
    put_key_file(&f.vehicles[1].state_dir, &[1; 39]);
    let dirs: Vec<_> = f.vehicles.iter().map(|c| c.state_dir.clone()).collect();
    let e = format!("{:#}", daemon::bind_fleet(f).await.unwrap_err());
    for d in dirs {
        let _ = std::fs::remove_dir_all(d);
    }
    assert!(e.contains("vehicle instance 1"), "{e}");
    assert!(e.contains("signing.key") && e.contains("39 bytes"), "{e}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn each_vehicle_of_a_fleet_has_its_own_key() {
    let f = fleet(2);
    let now_ts = signing::timestamp_from_unix_us(
        u64::try_from(
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .unwrap()
                .as_micros(),
        )
        .unwrap(),
    );
    put_key_file(
        &f.vehicles[1].state_dir,
        &Stored {
            key: KEY,
            timestamp: now_ts,
        }
        .to_bytes(),
    );
    let dirs: Vec<_> = f.vehicles.iter().map(|c| c.state_dir.clone()).collect();
    let d = daemon::bind_fleet(f).await.expect("bind");
    let gcs: Vec<SocketAddr> = (0..2).map(|i| d.vehicle_addrs(i)[0].1).collect();
    let (tx, rx) = tokio::sync::oneshot::channel::<()>();
    let run = tokio::spawn(d.run(async move {
        let _ = rx.await;
    }));
    let c = Client::new().await;
    // vehicle 0 (system 1) has no key: an unsigned read is answered, unsigned
    c.sock.send_to(&read_request(1, 0, None), gcs[0]).await.unwrap();
    let v0 = param_values(&c, Duration::from_millis(800)).await;
    assert_eq!(v0, vec![false], "vehicle 0 answers unsigned");
    // vehicle 1 (system 2) has one: unsigned gets nothing
    c.sock.send_to(&read_request(2, 1, None), gcs[1]).await.unwrap();
    assert!(
        param_values(&c, Duration::from_millis(800)).await.is_empty(),
        "unsigned answered"
    );
    // signed with the key: answered, signed with the key
    c.sock
        .send_to(&read_request(2, 2, Some(now_ts + 10)), gcs[1])
        .await
        .unwrap();
    let v1 = param_values(&c, Duration::from_millis(800)).await;
    assert!(!v1.is_empty() && v1.iter().all(|s| *s), "{v1:?}");
    // the same frame again: a replay, nothing
    c.sock
        .send_to(&read_request(2, 2, Some(now_ts + 10)), gcs[1])
        .await
        .unwrap();
    assert!(
        param_values(&c, Duration::from_millis(800)).await.is_empty(),
        "replay answered"
    );
    let _ = tx.send(());
    timeout(Duration::from_secs(10), run).await.unwrap().unwrap().unwrap();
    // the key is still there (rewritten with a later timestamp), 0600
    let stored = Stored::from_bytes(&std::fs::read(dirs[1].join("signing.key")).unwrap()).unwrap();
    assert_eq!(stored.key, KEY);
    assert!(stored.timestamp > now_ts + 10);
    assert!(!dirs[0].join("signing.key").exists(), "no key, no file");
    for d in dirs {
        let _ = std::fs::remove_dir_all(d);
    }
}
