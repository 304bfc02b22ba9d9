//! The daemon on loopback, driven by a MAVLink client: identity, streams,
//! the command protocol and its refusals, peers, MAVLink 1 input, timesync,
//! ping, FTP. Every test starts its own vehicle on free ports.
#![allow(deprecated)]

mod common;

use std::collections::HashMap;
use std::time::Duration;

use common::daemon::{Client, NAN, Vehicle, config, heartbeat, wait_armable};
use mavlink::MavlinkVersion;
use mavlink::dialects::common::*;
use rotorpilot::link::wire::CommandInt;

const S1: Duration = Duration::from_secs(1);
const S3: Duration = Duration::from_secs(3);

/// Send COMMAND_LONG to 1/1; its ACK and the STATUSTEXTs heard until 300 ms
/// after it (a refusal's text comes with the ACK, not necessarily before it).
async fn command_and_texts(c: &mut Client, to: std::net::SocketAddr, command: u16, p: [f32; 7]) -> (u8, Vec<String>) {
    c.command_long(to, command, p, (1, 1)).await;
    let mut texts = Vec::new();
    let mut result = None;
    let deadline = tokio::time::Instant::now() + S3;
    let mut until = deadline;
    while let Some(left) = until.checked_duration_since(tokio::time::Instant::now()) {
        let Some(r) = c.recv(left).await else { break };
        if let Some(a) = r.ack().filter(|a| a.command == command) {
            result = Some(a.result);
            until = tokio::time::Instant::now() + Duration::from_millis(300);
        }
        if let Some(MavMessage::STATUSTEXT(s)) = &r.msg {
            texts.push(s.text.to_str().unwrap_or_default().to_string());
        }
    }
    (result.unwrap_or_else(|| panic!("no ACK for command {command}")), texts)
}

/// The mode in a HEARTBEAT's custom_mode: PX4's (main, sub) mode.
fn px4_mode(h: &HEARTBEAT_DATA) -> (u32, u32) {
    ((h.custom_mode >> 16) & 0xFF, h.custom_mode >> 24)
}

/// Hold: PX4 main mode AUTO (4), sub mode LOITER (3).
const HOLD: (u32, u32) = (4, 3);

/// A vehicle whose GCS link sends to `gcs` from boot.
async fn vehicle_for(gcs: &Client) -> Vehicle {
    Vehicle::start(config(Some(gcs.addr()), None, 1.0)).await
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn speaks_first_with_px4_identity_and_default_streams() {
    let mut gcs = Client::new().await;
    let v = vehicle_for(&gcs).await;
    // GIVEN a client that only listens WHEN 2.5 s pass THEN it has every default stream
    let mut seen: HashMap<u32, Vec<MavMessage>> = HashMap::new();
    let deadline = tokio::time::Instant::now() + Duration::from_millis(2600);
    while let Some(r) = gcs.recv(deadline - tokio::time::Instant::now()).await {
        assert_eq!((r.sysid, r.compid), (1, 1), "all from 1/1");
        assert_eq!(r.version, MavlinkVersion::V2);
        assert_eq!(r.from, v.gcs);
        if let Some(m) = r.msg {
            seen.entry(r.msgid).or_default().push(m);
        }
        if tokio::time::Instant::now() >= deadline {
            break;
        }
    }
    for id in [0, 1, 2, 24, 30, 31, 32, 33, 74, 141, 147, 242, 245, 250, 251] {
        assert!(seen.contains_key(&id), "stream {id} missing; got {:?}", seen.keys());
    }
    let hbs = &seen[&0];
    assert!((2..=4).contains(&hbs.len()), "1 Hz heartbeat, got {}", hbs.len());
    let MavMessage::HEARTBEAT(h) = &hbs[0] else { panic!() };
    assert_eq!(h.mavtype, MavType::MAV_TYPE_QUADROTOR);
    assert_eq!(h.autopilot, MavAutopilot::MAV_AUTOPILOT_PX4);
    assert_eq!(h.base_mode.bits() & 1, 1);
    assert_eq!(h.base_mode.bits() & 128, 0);
    assert_eq!(h.custom_mode, 4 << 16 | 3 << 24, "Hold = AUTO.LOITER");
    assert_eq!(h.system_status, MavState::MAV_STATE_STANDBY);
    // SYS_STATUS: GPS and prearm healthy (once the estimator has started)
    let MavMessage::SYS_STATUS(s) = seen[&1].last().unwrap() else {
        panic!()
    };
    assert_eq!(s.onboard_control_sensors_health.bits() & 0x1020_002F, 0x1020_002F);
    assert_eq!(s.onboard_control_sensors_present.bits() & 0x20, 0x20);
    let MavMessage::GPS_RAW_INT(g) = &seen[&24][0] else {
        panic!()
    };
    assert_eq!(g.fix_type, GpsFixType::GPS_FIX_TYPE_3D_FIX);
    assert!(g.satellites_visible >= 10);
    let MavMessage::HOME_POSITION(hp) = &seen[&242][0] else {
        panic!()
    };
    // home is where the vehicle rests, as PX4 sets it: the quad's body
    // 0.24 m above the ground at 488 m AMSL
    assert_eq!(
        (hp.latitude, hp.longitude, hp.altitude),
        (473_977_420, 85_455_940, 488_240)
    );
    let MavMessage::GLOBAL_POSITION_INT(gp) = &seen[&33][0] else {
        panic!()
    };
    assert!((gp.lat - 473_977_420).abs() < 10 && (gp.alt - 488_000).abs() < 500);
    let MavMessage::EXTENDED_SYS_STATE(e) = &seen[&245][0] else {
        panic!()
    };
    assert_eq!(e.landed_state, MavLandedState::MAV_LANDED_STATE_ON_GROUND);
    assert_eq!(e.vtol_state, MavVtolState::MAV_VTOL_STATE_UNDEFINED);
    let MavMessage::BATTERY_STATUS(b) = &seen[&147][0] else {
        panic!()
    };
    assert!(b.voltages[0] > 10_000 && b.voltages[0] < 65_535);
    assert!(b.voltages[1..].iter().all(|x| *x == u16::MAX));
    // the estimator streams carry their names
    let names: Vec<String> = seen[&250]
        .iter()
        .map(|m| match m {
            MavMessage::DEBUG_VECT(d) => d.name.to_str().unwrap().to_string(),
            _ => String::new(),
        })
        .collect();
    assert!(names.iter().any(|n| n == "EST_FORCE") && names.iter().any(|n| n == "EST_TORQUE"));
    assert!(
        seen[&251]
            .iter()
            .any(|m| matches!(m, MavMessage::NAMED_VALUE_FLOAT(n) if n.name.to_str().unwrap() == "EST_MASS"))
    );
    // about 10 Hz each
    let est_force = names.iter().filter(|n| *n == "EST_FORCE").count();
    assert!(
        (15..=35).contains(&est_force),
        "EST_FORCE at 10 Hz: {est_force} in 2.6 s"
    );
    v.stop().await;
}

/// The test client's codec (and the daemon's) against an independent
/// encoder: the COMMAND_LONG and COMMAND_INT frames the client sends are
/// byte for byte pymavlink's for the same fields, the daemon's decoders read
/// pymavlink's frames back to those fields, the client reads pymavlink's
/// COMMAND_ACKs (extensions included, trailing zeros truncated) to its
/// fields, and the daemon's ACK encoder writes the same bytes.
#[test]
fn command_codec_matches_pymavlink_golden_frames() {
    use common::daemon::{command_int_frame, command_long_frame, golden_frames, received};
    use rotorpilot::link::wire::{CommandAck, CommandLong, Encoder};
    let hex = |b: &[u8]| b.iter().map(|x| format!("{x:02x}")).collect::<String>();
    let bits = |p: &[f32]| p.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    let mut seen = HashMap::new();
    for g in golden_frames() {
        *seen.entry(g.name.clone()).or_insert(0) += 1;
        let want = hex(&g.bytes);
        let param = |k: usize| g.get::<f32>(&format!("param{k}"));
        match g.name.as_str() {
            "command_long" => {
                let c = CommandLong {
                    params: [param(1), param(2), param(3), param(4), param(5), param(6), param(7)],
                    command: g.get("command"),
                    target_system: g.get("target_system"),
                    target_component: g.get("target_component"),
                    confirmation: g.get("confirmation"),
                };
                assert_eq!(hex(&command_long_frame(g.header, &c)), want, "{g:?}");
                let rx = received(&g.bytes, "127.0.0.1:1".parse().unwrap());
                assert_eq!(rx.len(), 1, "{g:?}");
                let back = CommandLong::decode(&rx[0].payload);
                assert_eq!(bits(&back.params), bits(&c.params), "{g:?}");
                assert_eq!(
                    (
                        back.command,
                        back.target_system,
                        back.target_component,
                        back.confirmation
                    ),
                    (c.command, c.target_system, c.target_component, c.confirmation),
                    "{g:?}"
                );
            }
            "command_int" => {
                let c = CommandInt {
                    params: [param(1), param(2), param(3), param(4)],
                    x: g.get("x"),
                    y: g.get("y"),
                    z: g.get("z"),
                    command: g.get("command"),
                    target_system: g.get("target_system"),
                    target_component: g.get("target_component"),
                    frame: g.get("frame"),
                    current: g.get("current"),
                    autocontinue: g.get("autocontinue"),
                };
                assert_eq!(hex(&command_int_frame(g.header, &c)), want, "{g:?}");
                let rx = received(&g.bytes, "127.0.0.1:1".parse().unwrap());
                assert_eq!(CommandInt::decode(&rx[0].payload), c, "{g:?}");
            }
            "command_ack" => {
                let rx = received(&g.bytes, "127.0.0.1:1".parse().unwrap());
                assert_eq!(rx.len(), 1, "{g:?}");
                assert_eq!(
                    (u32::from(rx[0].sysid), rx[0].compid, rx[0].msgid),
                    (g.header.system_id, g.header.component_id, 77)
                );
                let a = rx[0].ack().expect("a COMMAND_ACK");
                let want_ack = CommandAck {
                    command: g.get("command"),
                    result: g.get("result"),
                    progress: g.get("progress"),
                    result_param2: g.get("result_param2"),
                    target_system: g.get("target_system"),
                    target_component: g.get("target_component"),
                };
                assert_eq!(a, want_ack, "{g:?}");
                let mut e = Encoder::new(rx[0].sysid, rx[0].compid);
                e.sequence = g.header.sequence;
                assert_eq!(hex(&e.command_ack(&want_ack)), want, "{g:?}");
            }
            other => panic!("unknown golden frame {other}"),
        }
    }
    assert_eq!(seen.get("command_long"), Some(&3), "{seen:?}");
    assert_eq!(seen.get("command_int"), Some(&2), "{seen:?}");
    assert_eq!(seen.get("command_ack"), Some(&3), "{seen:?}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_command_is_acked_from_1_1_to_the_requester() {
    let mut c = Client::new().await;
    let v = vehicle_for(&c).await;
    // unknown command: UNSUPPORTED
    c.command_long(v.gcs, 31_337, [0.0; 7], (1, 1)).await;
    let (rx, a) = c.ack_of(31_337, S3).await.expect("ack");
    assert_eq!((rx.sysid, rx.compid), (1, 1));
    assert_eq!(a.result, 3);
    assert_eq!((a.target_system, a.target_component), (245, 190));
    // arm: ACCEPTED, and the heartbeat shows it
    wait_armable(&mut c).await;
    let a = c.command(v.gcs, 400, [1.0, NAN, NAN, NAN, NAN, NAN, NAN]).await;
    assert_eq!(a.result, 0);
    let h = heartbeat(&mut c, Duration::from_millis(1500)).await;
    assert_eq!(h.base_mode.bits() & 128, 128);
    assert_eq!(h.system_status, MavState::MAV_STATE_ACTIVE);
    // disarm
    assert_eq!(
        c.command(v.gcs, 400, [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]).await.result,
        0
    );
    // MISSION_START without a mission: DENIED (PX4)
    assert_eq!(c.command(v.gcs, 300, [0.0; 7]).await.result, 2);
    // DO_SET_MODE to a manual mode we cannot fly: TEMPORARILY_REJECTED
    assert_eq!(
        c.command(v.gcs, 176, [81.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0]).await.result,
        1
    );
    // DO_REPOSITION without the CHANGE_MODE flag: UNSUPPORTED (PX4)
    assert_eq!(
        c.command(v.gcs, 192, [NAN, 0.0, NAN, NAN, 47.0, 8.0, 500.0])
            .await
            .result,
        3
    );
    // PREFLIGHT_REBOOT_SHUTDOWN p1 = 0: ACCEPTED, nothing happens
    assert_eq!(c.command(v.gcs, 246, [0.0; 7]).await.result, 0);
    // INJECT_FAILURE with SYS_FAILURE_EN = 0: DENIED
    assert_eq!(
        c.command(v.gcs, 420, [4.0, 1.0, 0.0, NAN, NAN, NAN, NAN]).await.result,
        2
    );
    v.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn offboard_needs_a_fresh_setpoint_stream() {
    let mut c = Client::new().await;
    let v = vehicle_for(&c).await;
    // (a position setpoint needs a valid position: the filter's, as in PX4)
    wait_armable(&mut c).await;
    // WHEN offboard is asked without setpoints THEN TEMPORARILY_REJECTED
    let a = c.command(v.gcs, 176, [1.0, 6.0, 0.0, NAN, NAN, NAN, NAN]).await;
    assert_eq!(a.result, 1);
    // WHEN setpoints stream (MAVSDK's set_position_ned mask 2552) THEN accepted,
    // and OFFBOARD (main mode 6) shows in the next heartbeat
    let sp = MavMessage::SET_POSITION_TARGET_LOCAL_NED(SET_POSITION_TARGET_LOCAL_NED_DATA {
        time_boot_ms: 0,
        x: 0.0,
        y: 0.0,
        z: -2.0,
        vx: 0.0,
        vy: 0.0,
        vz: 0.0,
        afx: 0.0,
        afy: 0.0,
        afz: 0.0,
        yaw: 0.0,
        yaw_rate: 0.0,
        type_mask: PositionTargetTypemask::from_bits_retain(2552),
        target_system: 1,
        target_component: 1,
        coordinate_frame: MavFrame::MAV_FRAME_LOCAL_NED,
    });
    for _ in 0..3 {
        c.send(v.gcs, &sp).await;
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    let a = c.command(v.gcs, 176, [129.0, 6.0, 0.0, NAN, NAN, NAN, NAN]).await;
    assert_eq!(a.result, 0);
    c.send(v.gcs, &sp).await;
    let h = heartbeat(&mut c, Duration::from_millis(1500)).await;
    assert_eq!((h.custom_mode >> 16) & 0xFF, 6);
    // WHEN the stream stops THEN the vehicle leaves offboard for Hold (COM_OF_LOSS_T 1 s)
    let left = c
        .wait_for(Duration::from_secs(4), |r| match &r.msg {
            Some(MavMessage::HEARTBEAT(h)) if (h.custom_mode >> 16) & 0xFF != 6 => Some(h.custom_mode),
            _ => None,
        })
        .await;
    assert_eq!(left, Some(4 << 16 | 3 << 24));
    // WHEN offboard is asked again after the stream went stale (it existed,
    // it is older than COM_OF_LOSS_T) THEN TEMPORARILY_REJECTED with PX4's
    // text on the wire, and the vehicle stays in Hold
    let (result, texts) = command_and_texts(&mut c, v.gcs, 176, [129.0, 6.0, 0.0, NAN, NAN, NAN, NAN]).await;
    assert_eq!(result, 1, "offboard on a stale stream");
    assert!(
        texts
            .iter()
            .any(|t| t == "Switching to Offboard denied: no offboard signal"),
        "{texts:?}"
    );
    let h = heartbeat(&mut c, Duration::from_millis(1500)).await;
    assert_eq!(px4_mode(&h), HOLD);
    v.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn set_mode_message_is_acked_as_do_set_mode() {
    let mut c = Client::with_ids(255, 0).await;
    let v = vehicle_for(&c).await;
    c.send(
        v.gcs,
        &MavMessage::SET_MODE(SET_MODE_DATA {
            custom_mode: 4 << 16 | 3 << 24,
            target_system: 1,
            base_mode: MavModeFlag::from_bits_retain(1),
        }),
    )
    .await;
    let (_, a) = c.ack_of(176, S3).await.expect("ack 176");
    assert_eq!(a.result, 0);
    assert_eq!((a.target_system, a.target_component), (255, 0));
    v.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn target_component_zero_accepted_other_components_ignored() {
    let mut c = Client::with_ids(255, 0).await;
    let v = vehicle_for(&c).await;
    // pymavlink's default: target_component 0
    c.command_long(v.gcs, 31_000, [0.0; 7], (1, 0)).await;
    assert!(c.ack_of(31_000, S3).await.is_some());
    // target system 0 (broadcast) too
    c.command_long(v.gcs, 31_001, [0.0; 7], (0, 0)).await;
    assert!(c.ack_of(31_001, S3).await.is_some());
    // another component or another system: not for us
    c.command_long(v.gcs, 31_002, [0.0; 7], (1, 154)).await;
    c.command_long(v.gcs, 31_003, [0.0; 7], (7, 1)).await;
    assert!(
        c.wait_for(Duration::from_millis(700), |r| r.ack().filter(|a| a.command >= 31_002))
            .await
            .is_none()
    );
    v.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn mavlink1_input_is_accepted_and_answered_in_mavlink2() {
    let mut c = Client::with_ids(255, 0).await;
    let v = vehicle_for(&c).await;
    // PARAM_REQUEST_READ by name as MAVLink 1
    c.send_v1(
        v.gcs,
        &MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
            param_index: -1,
            target_system: 1,
            target_component: 0,
            param_id: "MIS_TAKEOFF_ALT".into(),
        }),
    )
    .await;
    let (version, value) = c
        .wait_for(S3, |r| match &r.msg {
            Some(MavMessage::PARAM_VALUE(p)) => Some((r.version, p.param_value)),
            _ => None,
        })
        .await
        .expect("PARAM_VALUE");
    assert_eq!(version, MavlinkVersion::V2);
    assert_eq!(value, 2.5);
    // COMMAND_LONG as MAVLink 1 (known command so the crate can encode it)
    c.send_v1(
        v.gcs,
        &MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            param1: 148.0,
            command: MavCmd::MAV_CMD_REQUEST_MESSAGE,
            target_system: 1,
            target_component: 0,
            ..Default::default()
        }),
    )
    .await;
    let (_, a) = c.ack_of(512, S3).await.expect("ack");
    assert_eq!(a.result, 0);
    v.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn requests_answered_per_link() {
    let mut c = Client::new().await;
    let v = vehicle_for(&c).await;
    // REQUEST_MESSAGE AUTOPILOT_VERSION: ACK first, then the message from 1/1
    c.command_long(v.gcs, 512, [148.0, NAN, NAN, NAN, NAN, NAN, NAN], (1, 1))
        .await;
    let mut order = Vec::new();
    let ver = c
        .wait_for(S3, |r| {
            if r.msgid == 77 || r.msgid == 148 {
                order.push(r.msgid);
            }
            match &r.msg {
                Some(MavMessage::AUTOPILOT_VERSION(a)) if r.compid == 1 => Some(a.clone()),
                _ => None,
            }
        })
        .await
        .expect("AUTOPILOT_VERSION");
    assert_eq!(order, vec![77, 148]);
    assert_eq!(ver.capabilities.bits() & 4, 4, "MISSION_INT");
    assert_eq!(ver.flight_sw_version, 0x0110_00FF);
    // legacy forms
    assert_eq!(
        c.command(v.gcs, 520, [1.0, NAN, NAN, NAN, NAN, NAN, NAN]).await.result,
        0
    );
    assert_eq!(c.command(v.gcs, 410, [0.0; 7]).await.result, 0);
    assert!(
        c.wait_for(S1, |r| matches!(r.msg, Some(MavMessage::HOME_POSITION(_)))
            .then_some(()))
            .await
            .is_some()
    );
    // unknown message: DENIED
    assert_eq!(
        c.command(v.gcs, 512, [9999.0, NAN, NAN, NAN, NAN, NAN, NAN])
            .await
            .result,
        2
    );
    // SET_MESSAGE_INTERVAL for EST_* at 50 Hz on this link only
    assert_eq!(
        c.command(v.gcs, 511, [250.0, 20_000.0, NAN, NAN, NAN, NAN, NAN])
            .await
            .result,
        0
    );
    c.drain().await;
    let mut n = 0;
    let t0 = tokio::time::Instant::now();
    while t0.elapsed() < S1 {
        if let Some(r) = c.recv(Duration::from_millis(100)).await
            && matches!(&r.msg, Some(MavMessage::DEBUG_VECT(d)) if d.name.to_str().unwrap() == "EST_FORCE")
        {
            n += 1;
        }
    }
    assert!((30..=70).contains(&n), "50 Hz after SET_MESSAGE_INTERVAL, got {n}");
    // -1 stops it
    assert_eq!(
        c.command(v.gcs, 511, [251.0, -1.0, NAN, NAN, NAN, NAN, NAN])
            .await
            .result,
        0
    );
    c.drain().await;
    assert!(
        c.wait_for(Duration::from_millis(500), |r| matches!(
            r.msg,
            Some(MavMessage::NAMED_VALUE_FLOAT(_))
        )
        .then_some(()))
            .await
            .is_none()
    );
    // an unknown stream: FAILED
    assert_eq!(
        c.command(v.gcs, 511, [83.0, 1e5, NAN, NAN, NAN, NAN, NAN]).await.result,
        4
    );
    // an absurd interval is capped, and the link keeps answering
    assert_eq!(
        c.command(v.gcs, 511, [250.0, 1e30, NAN, NAN, NAN, NAN, NAN])
            .await
            .result,
        0
    );
    assert_eq!(
        c.command(v.gcs, 512, [148.0, NAN, NAN, NAN, NAN, NAN, NAN])
            .await
            .result,
        0
    );
    v.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn timesync_ping_and_ftp_are_answered() {
    let mut c = Client::new().await;
    let v = vehicle_for(&c).await;
    c.send(
        v.gcs,
        &MavMessage::TIMESYNC(TIMESYNC_DATA {
            tc1: 0,
            ts1: 123_456_789,
            ..Default::default()
        }),
    )
    .await;
    let ts = c
        .wait_for(S3, |r| match &r.msg {
            Some(MavMessage::TIMESYNC(t)) => Some(t.clone()),
            _ => None,
        })
        .await
        .expect("TIMESYNC");
    assert_eq!(ts.ts1, 123_456_789);
    assert!(ts.tc1 > 0);
    c.send(
        v.gcs,
        &MavMessage::PING(PING_DATA {
            time_usec: 42,
            seq: 7,
            target_system: 0,
            target_component: 0,
        }),
    )
    .await;
    let p = c
        .wait_for(S3, |r| match &r.msg {
            Some(MavMessage::PING(p)) => Some(p.clone()),
            _ => None,
        })
        .await
        .expect("PING");
    assert_eq!(
        (p.time_usec, p.seq, p.target_system, p.target_component),
        (42, 7, 245, 190)
    );
    // FTP OpenFileRO of a file that is not there gets NAK FileNotFound at once
    let mut payload = [0u8; 251];
    payload[0] = 3;
    payload[3] = 4;
    payload[4] = 9;
    payload[12..21].copy_from_slice(b"/nope.txt");
    c.send(
        v.gcs,
        &MavMessage::FILE_TRANSFER_PROTOCOL(FILE_TRANSFER_PROTOCOL_DATA {
            target_network: 0,
            target_system: 1,
            target_component: 1,
            payload,
        }),
    )
    .await;
    let f = c
        .wait_for(S1, |r| match &r.msg {
            Some(MavMessage::FILE_TRANSFER_PROTOCOL(f)) => Some(f.payload),
            _ => None,
        })
        .await
        .expect("FTP answer");
    assert_eq!((f[0], f[3], f[5], f[12]), (4, 129, 4, 10));
    v.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_peers_are_both_served_and_a_new_port_is_served_again() {
    let mut gcs = Client::new().await;
    let mut api_default = Client::new().await;
    let v = Vehicle::start(config(Some(gcs.addr()), Some(api_default.addr()), 1.0)).await;
    // a second client on the GCS link (udpout-style: talks first)
    let mut other = Client::with_ids(255, 0).await;
    other.heartbeat(v.gcs).await;
    for c in [&mut gcs, &mut other, &mut api_default] {
        heartbeat(c, Duration::from_millis(2500)).await;
    }
    // the API link streams at its own rates to its own peer
    let r = api_default.recv(S1).await.expect("api traffic");
    assert_eq!(r.from, v.api);
    // both GCS-link clients keep getting streams
    for c in [&mut gcs, &mut other] {
        assert!(
            c.wait_for(S1, |r| matches!(r.msg, Some(MavMessage::ATTITUDE(_))).then_some(()))
                .await
                .is_some()
        );
    }
    // the second client restarts on a new port: served again at once
    drop(other);
    // (it heartbeats, as every client does: what proves it listens)
    let mut again = Client::with_ids(255, 0).await;
    again.heartbeat(v.gcs).await;
    again.command_long(v.gcs, 31_000, [0.0; 7], (1, 0)).await;
    assert!(again.ack_of(31_000, S3).await.is_some());
    assert!(
        again
            .wait_for(S1, |r| matches!(r.msg, Some(MavMessage::ATTITUDE(_))).then_some(()))
            .await
            .is_some()
    );
    heartbeat(&mut again, Duration::from_millis(2500)).await;
    v.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn time_boot_ms_is_simulated_and_monotonic() {
    let mut c = Client::new().await;
    let v = Vehicle::start(config(Some(c.addr()), None, 4.0)).await;
    let mut times = Vec::new();
    let t0 = tokio::time::Instant::now();
    while t0.elapsed() < Duration::from_millis(1500) {
        if let Some(r) = c.recv(Duration::from_millis(200)).await
            && let Some(MavMessage::ATTITUDE(a)) = r.msg
        {
            times.push((tokio::time::Instant::now(), a.time_boot_ms));
        }
    }
    assert!(times.len() > 50);
    assert!(times.windows(2).all(|w| w[1].1 >= w[0].1), "monotonic");
    // at --speed 4, simulated time runs about 4x wall time
    let (first, last) = (times[0], times[times.len() - 1]);
    let rate = f64::from(last.1 - first.1) / 1e3 / (last.0 - first.0).as_secs_f64();
    assert!((2.5..5.5).contains(&rate), "sim/wall = {rate}");
    // reboot (disarmed): ACK, and the clock does not go back
    assert_eq!(
        c.command(v.gcs, 246, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]).await.result,
        0
    );
    let after = c
        .wait_for(S1, |r| match &r.msg {
            Some(MavMessage::ATTITUDE(a)) => Some(a.time_boot_ms),
            _ => None,
        })
        .await
        .unwrap();
    assert!(after >= last.1);
    v.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn heartbeats_keep_wall_time_when_the_simulation_crawls() {
    let mut c = Client::new().await;
    let v = Vehicle::start(config(Some(c.addr()), None, 0.01)).await;
    let mut n = 0;
    let t0 = tokio::time::Instant::now();
    while t0.elapsed() < Duration::from_millis(2200) {
        if let Some(r) = c.recv(Duration::from_millis(200)).await
            && r.msgid == 0
        {
            n += 1;
        }
    }
    assert!(n >= 2, "heartbeats at 1 Hz wall time, got {n}");
    v.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn reposition_as_command_int_from_both_mavsdk_generations() {
    let mut c = Client::new().await;
    let v = Vehicle::start(config(Some(c.addr()), None, 5.0)).await;
    wait_armable(&mut c).await;
    assert_eq!(
        c.command(v.gcs, 400, [1.0, NAN, NAN, NAN, NAN, NAN, NAN]).await.result,
        0
    );
    assert_eq!(c.command(v.gcs, 22, [NAN; 7]).await.result, 0);
    // wait until airborne
    c.wait_for(Duration::from_secs(10), |r| match &r.msg {
        Some(MavMessage::EXTENDED_SYS_STATE(e)) if e.landed_state == MavLandedState::MAV_LANDED_STATE_IN_AIR => {
            Some(())
        }
        _ => None,
    })
    .await
    .expect("in air");
    // MAVSDK goto_location: Hold first, then DO_REPOSITION p2 = 1, yaw in
    // rad; MAVSDK 3 sends frame 0 (GLOBAL), MAVSDK 4 frame 5 (GLOBAL_INT),
    // both AMSL. Each goes to its own point, reached before the next is sent,
    // so neither frame can be ignored; north and east both checked (1e-7 deg:
    // 11.12 mm north, 7.53 mm east at home's latitude).
    let reposition = |frame: u8, lat: i32, lon: i32, alt: f32| CommandInt {
        params: [NAN, 1.0, NAN, 0.5],
        x: lat,
        y: lon,
        z: alt,
        command: 192,
        target_system: 1,
        target_component: 1,
        frame,
        current: 0,
        autocontinue: 0,
    };
    let (lat0, lon0) = (473_977_420, 85_455_940);
    for (frame, d_lat, d_lon, alt, want) in [
        (0, 450, 398, 493.0, [5.0, 3.0, -5.0]),
        (5, -270, -531, 494.0, [-3.0, -4.0, -6.0]),
    ] {
        c.command_int(v.gcs, reposition(frame, lat0 + d_lat, lon0 + d_lon, alt))
            .await;
        let (_, a) = c.ack_of(192, S3).await.expect("ack");
        assert_eq!(a.result, 0, "frame {frame}");
        // it flies there
        let close = |p: &LOCAL_POSITION_NED_DATA| {
            (f64::from(p.x) - want[0]).abs() < 0.3
                && (f64::from(p.y) - want[1]).abs() < 0.3
                && (f64::from(p.z) - want[2]).abs() < 0.3
        };
        let reached = c
            .wait_for(Duration::from_secs(15), |r| match &r.msg {
                Some(MavMessage::LOCAL_POSITION_NED(p)) if close(p) => Some(()),
                _ => None,
            })
            .await;
        assert!(reached.is_some(), "frame {frame}: never reached {want:?}");
    }
    // Refusals in flight change neither the mode nor the position target:
    // DO_REPOSITION to latitude 91 deg (DENIED), MISSION_START without a
    // mission (DENIED), OFFBOARD without setpoints (TEMPORARILY_REJECTED).
    c.command_int(v.gcs, reposition(5, 910_000_000, lon0, 493.0)).await;
    let (_, a) = c.ack_of(192, S3).await.expect("ack");
    assert_eq!(a.result, 2, "reposition to 91 deg");
    assert_eq!(c.command(v.gcs, 300, [0.0; 7]).await.result, 2);
    assert_eq!(
        c.command(v.gcs, 176, [129.0, 6.0, 0.0, NAN, NAN, NAN, NAN])
            .await
            .result,
        1
    );
    let h = heartbeat(&mut c, Duration::from_millis(1500)).await;
    assert_eq!(px4_mode(&h), HOLD, "the mode after the refusals");
    // the vehicle stays at the last accepted point for 2 s wall (10 s simulated)
    let t0 = tokio::time::Instant::now();
    let mut seen = 0;
    while t0.elapsed() < Duration::from_secs(2) {
        let Some(r) = c.recv(S1).await else { break };
        if let Some(MavMessage::LOCAL_POSITION_NED(p)) = &r.msg {
            let off = [f64::from(p.x) + 3.0, f64::from(p.y) + 4.0, f64::from(p.z) + 6.0];
            assert!(
                off.iter().all(|d| d.abs() < 0.3),
                "moved off the target after a refusal: {p:?}"
            );
            seen += 1;
        }
    }
    assert!(seen > 10, "{seen} positions in 2 s");
    v.stop().await;
}

/// Every frame from `(sysid, compid)` with message id `msgid` that `c`
/// hears within `wait`.
async fn heard_from(c: &mut Client, wait: Duration, sysid: u8, compid: u8, msgid: u32) -> Vec<common::daemon::Rx> {
    let mut got = Vec::new();
    let deadline = tokio::time::Instant::now() + wait;
    while let Some(left) = deadline.checked_duration_since(tokio::time::Instant::now()) {
        let Some(r) = c.recv(left).await else { break };
        if (r.sysid, r.compid, r.msgid) == (sysid, compid, msgid) {
            got.push(r);
        }
    }
    got
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn messages_are_forwarded_between_the_links_as_px4_sitl_does() {
    // a GCS (255/190) on the GCS link and a companion (245/190) on the API link
    let mut gcs = Client::with_ids(255, 190).await;
    let mut api = Client::with_ids(245, 190).await;
    let v = vehicle_for(&gcs).await;
    gcs.heartbeat(v.gcs).await;
    api.heartbeat(v.api).await;
    heartbeat(&mut api, S3).await;
    gcs.drain().await;
    // GIVEN the companion's STATUSTEXT WHEN sent on the API link THEN the
    // GCS gets it with the companion's ids, payload as sent
    let text = MavMessage::STATUSTEXT(STATUSTEXT_DATA {
        severity: MavSeverity::MAV_SEVERITY_INFO,
        text: "Hello world!".into(),
        id: 0,
        chunk_seq: 0,
    });
    api.send(v.api, &text).await;
    let got = heard_from(&mut gcs, S1, 245, 190, 253).await;
    assert_eq!(got.len(), 1, "one STATUSTEXT from 245/190 on the GCS link");
    assert_eq!(got[0].msg, Some(text));
    assert_eq!(got[0].from, v.gcs, "sent from the GCS link");
    // a COMMAND_LONG for the autopilot (1/1) is answered, not forwarded
    api.command_long(v.api, 512, [242.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], (1, 1))
        .await;
    assert!(api.ack_of(512, S3).await.is_some(), "the vehicle answers it");
    assert!(heard_from(&mut gcs, S1, 245, 190, 76).await.is_empty(), "not forwarded");
    // one for the GCS's component (seen only on the GCS link) is passed there,
    // and the vehicle does not answer it
    api.command_long(v.api, 512, [242.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], (255, 190))
        .await;
    let got = heard_from(&mut gcs, S1, 245, 190, 76).await;
    assert_eq!(got.len(), 1, "forwarded to the component it is aimed at");
    assert!(api.ack_of(512, Duration::from_millis(300)).await.is_none());
    // one for a component heard nowhere is dropped
    api.command_long(v.api, 512, [242.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], (77, 1))
        .await;
    assert!(heard_from(&mut gcs, S1, 245, 190, 76).await.is_empty());
    // the companion's heartbeat reaches the GCS (MAV_HB_FORW_EN 1, PX4's default) ...
    api.heartbeat(v.api).await;
    assert_eq!(heard_from(&mut gcs, S1, 245, 190, 0).await.len(), 1);
    // ... and not once MAV_HB_FORW_EN is 0
    gcs.param_set(
        v.gcs,
        "MAV_HB_FORW_EN",
        f32::from_bits(0),
        MavParamType::MAV_PARAM_TYPE_INT32,
    )
    .await;
    gcs.wait_for(S3, |r| match &r.msg {
        Some(MavMessage::PARAM_VALUE(p)) if p.param_id.to_str().ok() == Some("MAV_HB_FORW_EN") => Some(()),
        _ => None,
    })
    .await
    .expect("MAV_HB_FORW_EN set");
    gcs.drain().await;
    api.heartbeat(v.api).await;
    assert!(heard_from(&mut gcs, S1, 245, 190, 0).await.is_empty());
    // the other way: the GCS's NAMED_VALUE_FLOAT reaches the companion
    let nvf = MavMessage::NAMED_VALUE_FLOAT(NAMED_VALUE_FLOAT_DATA {
        time_boot_ms: 5,
        name: "GCS".into(),
        value: 1.5,
    });
    // (the API link's streams unread so far could fill the socket's buffer)
    api.drain().await;
    gcs.send(v.gcs, &nvf).await;
    let got = heard_from(&mut api, S1, 255, 190, 251).await;
    assert_eq!(got.len(), 1);
    assert_eq!(got[0].msg, Some(nvf));
    v.stop().await;
}
