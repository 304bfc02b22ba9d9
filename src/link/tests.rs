//! Link-level tests: datagrams in, frames and effects out.

use std::time::{Duration, Instant};

use mavlink::dialects::common::{
    COMMAND_ACK_DATA, HEARTBEAT_DATA, MavMessage, MavParamType, PARAM_REQUEST_LIST_DATA, PARAM_SET_DATA, PING_DATA,
    TIMESYNC_DATA,
};
use mavlink::{MavHeader, MessageData};

use super::param::ParamAccess as _;
use super::testing::FakeParams;
use super::testing::{addr, link, snapshot};
use super::wire::{self, CommandAck, CommandLong};
use super::*;

fn gcs() -> MavHeader {
    MavHeader {
        system_id: 245,
        component_id: 190,
        sequence: 0,
    }
}

fn v2(msg: &MavMessage) -> Vec<u8> {
    let mut enc = wire::Encoder::new(245, 190);
    enc.message(msg)
}

fn cmd(command: u16, p: [f32; 7], target_component: u8) -> Vec<u8> {
    let c = CommandLong {
        params: p,
        command,
        target_system: 1,
        target_component,
        confirmation: 0,
    };
    wire::encode_v2(gcs(), 76, &c.encode())
}

/// PARAM_REQUEST_LIST to vehicle 1, all components.
fn param_request_list() -> Vec<u8> {
    v2(&MavMessage::PARAM_REQUEST_LIST(PARAM_REQUEST_LIST_DATA {
        target_system: 1,
        target_component: 0,
    }))
}

/// Decode every frame of the outbox.
fn decoded(out: &[Outgoing]) -> Vec<(To, u32, Vec<u8>)> {
    out.iter()
        .flat_map(|o| {
            wire::frames(&o.bytes)
                .map(|f| (o.to, f.message_id, f.payload.to_vec()))
                .collect::<Vec<_>>()
        })
        .collect()
}

fn acks(out: &[Outgoing]) -> Vec<CommandAck> {
    decoded(out)
        .into_iter()
        .filter(|(_, id, _)| *id == COMMAND_ACK_DATA::ID)
        .map(|(_, _, p)| CommandAck::decode(&p))
        .collect()
}

#[test]
fn speaks_first_with_a_px4_heartbeat() {
    let t0 = Instant::now();
    let mut l = link(t0);
    l.poll(t0, &snapshot(), 0);
    let out = l.drain();
    assert!(out.iter().all(|o| o.to == To::All));
    let hb = out
        .iter()
        .flat_map(|o| wire::frames(&o.bytes).collect::<Vec<_>>())
        .find(|f| f.message_id == 0)
        .expect("heartbeat");
    let Some(wire::Inbound::Other(m)) = wire::decode(&hb) else {
        panic!()
    };
    let MavMessage::HEARTBEAT(h) = *m else { panic!() };
    assert_eq!(h.custom_mode, 50_593_792);
    assert_eq!(h.base_mode.bits() & 1, 1);
    assert_eq!(h.autopilot as u8, 12);
    assert_eq!(h.mavtype as u8, 2);
    let mut d = Vec::new();
    l.destinations(t0, &mut d);
    assert_eq!(d, vec![addr(14540)]);
}

/// The raw sensors run only once something reads them: a link asks for
/// them once, when a raw sensor stream first comes due with a peer to send
/// it to; a link with no peer (and a stream set without raw messages) never.
#[test]
fn a_link_asks_for_the_raw_sensors_once_when_it_streams_them_to_a_peer() {
    let t0 = Instant::now();
    let mut l = link(t0);
    assert!(!l.take_raw_sensors_request(), "nothing polled yet");
    l.poll(t0, &snapshot(), 0);
    assert!(l.take_raw_sensors_request(), "GPS_RAW_INT and HIGHRES_IMU came due");
    l.poll(t0 + Duration::from_secs(1), &snapshot(), 0);
    assert!(!l.take_raw_sensors_request(), "asked once");
    let mut config = l.config.clone();
    config.default_remote = None;
    let mut lonely = Link::new(config.clone(), t0);
    for k in 0..3 {
        lonely.poll(t0 + Duration::from_secs(k), &snapshot(), 0);
    }
    assert!(!lonely.take_raw_sensors_request(), "no peer: nobody reads them");
    config.default_remote = Some(addr(14540));
    config.rates.retain(|(s, _)| !s.needs_raw_sensors());
    let mut plain = Link::new(config, t0);
    plain.poll(t0, &snapshot(), 0);
    assert!(!plain.take_raw_sensors_request(), "no raw sensor stream");
}

#[test]
fn unknown_command_is_unsupported_with_target_requester() {
    let t0 = Instant::now();
    let mut l = link(t0);
    let p = FakeParams::standard();
    let e = l.on_datagram(t0, addr(50000), &cmd(31_337, [0.0; 7], 1), &snapshot(), &p);
    assert!(e.is_empty());
    let out = l.drain();
    assert_eq!(out[0].to, To::Peer(addr(50000)));
    let a = acks(&out);
    assert_eq!(a.len(), 1);
    assert_eq!((a[0].command, a[0].result), (31_337, convert::result::UNSUPPORTED));
    assert_eq!((a[0].target_system, a[0].target_component), (245, 190));
    // the sender is now a peer, unproven: it gets no streams
    let mut d = Vec::new();
    l.destinations(t0, &mut d);
    assert_eq!(d, vec![addr(14540)]);
    assert_eq!(l.standing(addr(50000)), Some(super::peers::Standing::Unproven));
}

#[test]
fn commands_for_other_components_are_ignored_component_zero_accepted() {
    let t0 = Instant::now();
    let mut l = link(t0);
    let p = FakeParams::standard();
    let e = l.on_datagram(t0, addr(50000), &cmd(400, [1.0; 7], 0), &snapshot(), &p);
    assert!(matches!(
        e.as_slice(),
        [Effect::Autopilot {
            command: AutopilotCommand::Arm { force: false },
            ack: Some(_)
        }]
    ));
    let e = l.on_datagram(t0, addr(50000), &cmd(400, [1.0; 7], 154), &snapshot(), &p);
    assert!(e.is_empty());
    assert!(l.drain().is_empty());
}

#[test]
fn outcome_acks_carry_results() {
    let t0 = Instant::now();
    let mut l = link(t0);
    let hb = v2(&MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()));
    l.on_datagram(t0, addr(50000), &hb, &snapshot(), &FakeParams::standard());
    let ticket = AckTicket {
        command: 176,
        to: addr(50000),
        requester: (255, 0),
    };
    l.on_outcome(ticket, &CommandOutcome::TemporarilyRejected("no offboard signal"));
    let out = l.drain();
    let a = acks(&out);
    assert_eq!((a[0].command, a[0].result, a[0].target_system), (176, 1, 255));
    // the autopilot announces its refusals itself: no second STATUSTEXT
    assert_eq!(decoded(&out).len(), 1);
}

#[test]
fn request_message_acks_then_sends() {
    let t0 = Instant::now();
    let mut l = link(t0);
    let p = FakeParams::standard();
    let nan = f32::NAN;
    l.on_datagram(
        t0,
        addr(50000),
        &cmd(512, [148.0, nan, nan, nan, nan, nan, nan], 1),
        &snapshot(),
        &p,
    );
    let d = decoded(&l.drain());
    assert_eq!(d.iter().map(|x| x.1).collect::<Vec<_>>(), vec![77, 148]);
    l.on_datagram(
        t0,
        addr(50000),
        &cmd(512, [9999.0, nan, nan, nan, nan, nan, nan], 1),
        &snapshot(),
        &p,
    );
    let a = acks(&l.drain());
    assert_eq!(a[0].result, convert::result::DENIED);
    l.on_datagram(t0, addr(50000), &cmd(410, [0.0; 7], 0), &snapshot(), &p);
    let d = decoded(&l.drain());
    assert_eq!(d.iter().map(|x| x.1).collect::<Vec<_>>(), vec![77, 242]);
}

#[test]
fn set_message_interval_is_per_link() {
    let t0 = Instant::now();
    let mut l = link(t0);
    let p = FakeParams::standard();
    let nan = f32::NAN;
    // from an address that has not shown it listens: DENIED, rates unchanged
    let before = l.streams().interval(Stream::DebugVect);
    l.on_datagram(
        t0,
        addr(50000),
        &cmd(511, [250.0, 50_000.0, nan, nan, nan, nan, nan], 1),
        &snapshot(),
        &p,
    );
    assert_eq!(acks(&l.drain())[0].result, convert::result::DENIED);
    assert_eq!(l.streams().interval(Stream::DebugVect), before);
    // a heartbeat proves it
    let hb = v2(&MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()));
    l.on_datagram(t0, addr(50000), &hb, &snapshot(), &p);
    l.drain();
    // the heartbeat's own rate is not for changing (every client's liveness)
    l.on_datagram(
        t0,
        addr(50000),
        &cmd(511, [0.0, -1.0, nan, nan, nan, nan, nan], 1),
        &snapshot(),
        &p,
    );
    assert_eq!(acks(&l.drain())[0].result, convert::result::DENIED);
    l.on_datagram(
        t0,
        addr(50000),
        &cmd(511, [250.0, 50_000.0, nan, nan, nan, nan, nan], 1),
        &snapshot(),
        &p,
    );
    assert_eq!(acks(&l.drain())[0].result, 0);
    assert_eq!(l.streams().interval(Stream::DebugVect), Some(Duration::from_millis(50)));
    l.on_datagram(
        t0,
        addr(50000),
        &cmd(511, [83.0, 50_000.0, nan, nan, nan, nan, nan], 1),
        &snapshot(),
        &p,
    );
    assert_eq!(acks(&l.drain())[0].result, convert::result::FAILED);
}

#[test]
fn param_list_goes_to_the_requester_in_order() {
    let t0 = Instant::now();
    let mut l = link(t0);
    let p = FakeParams::standard();
    let req = param_request_list();
    // unproven: three times the request's bytes, one PARAM_VALUE
    l.on_datagram(t0, addr(50000), &req, &snapshot(), &p);
    assert_eq!(decoded(&l.drain()).len(), 1);
    // after a heartbeat (proven) the rest of the list follows
    let hb = v2(&MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()));
    l.on_datagram(t0, addr(50000), &hb, &snapshot(), &p);
    l.poll(t0 + Duration::from_millis(20), &snapshot(), 0);
    let d: Vec<_> = decoded(&l.drain())
        .into_iter()
        .filter(|(to, _, _)| *to != To::All)
        .collect();
    assert_eq!(d.len(), 4);
    assert!(d.iter().all(|(to, id, _)| *to == To::Peer(addr(50000)) && *id == 22));
}

/// A list held back (here: its requester not yet proven) sends a value set
/// in the meantime as it is now, not as it was when the list was asked for.
#[test]
fn a_list_in_progress_sends_a_value_set_meanwhile() {
    let t0 = Instant::now();
    let mut l = link(t0);
    let p = FakeParams::standard();
    let req = param_request_list();
    l.on_datagram(t0, addr(50000), &req, &snapshot(), &p);
    l.drain();
    let MavMessage::PARAM_VALUE(mut last) = super::param::list(&p).pop().unwrap() else {
        panic!()
    };
    last.param_value = 42.0;
    l.broadcast_param(t0, &MavMessage::PARAM_VALUE(last.clone()));
    let hb = v2(&MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()));
    l.on_datagram(t0, addr(50000), &hb, &snapshot(), &p);
    l.poll(t0 + Duration::from_millis(20), &snapshot(), 0);
    let sent: Vec<_> = decoded(&l.drain())
        .into_iter()
        .filter(|(to, id, _)| *to == To::Peer(addr(50000)) && *id == 22)
        .collect();
    let (_, _, payload) = sent.last().unwrap();
    assert_eq!(f32::from_le_bytes(payload[0..4].try_into().unwrap()), 42.0);
}

#[test]
fn param_set_echoes_then_rebroadcasts_via_the_daemon() {
    let t0 = Instant::now();
    let mut l = link(t0);
    let mut p = FakeParams::standard();
    let set = v2(&MavMessage::PARAM_SET(PARAM_SET_DATA {
        param_value: f32::from_bits(1),
        target_system: 1,
        target_component: 1,
        param_id: "SYS_FAILURE_EN".into(),
        param_type: MavParamType::MAV_PARAM_TYPE_INT32,
    }));
    let e = l.on_datagram(t0, addr(50000), &set, &snapshot(), &p);
    let [Effect::SetParam { ticket, value }] = e.as_slice() else {
        panic!("{e:?}")
    };
    assert_eq!(ticket.index, 3);
    assert!(l.drain().is_empty());
    let stored = p.set(&ticket.name, *value);
    let value = l.on_param_set(ticket, stored, &p).expect("changed");
    assert_eq!(decoded(&l.drain()).len(), 1);
    l.broadcast_param(t0, &value);
    assert_eq!(l.next_deadline(), Some(t0));
    l.poll(t0 + Duration::from_millis(1), &snapshot(), 0);
    let early: Vec<_> = decoded(&l.drain()).into_iter().filter(|x| x.1 == 22).collect();
    assert!(early.is_empty());
    l.poll(t0 + Duration::from_millis(6), &snapshot(), 0);
    let late: Vec<_> = decoded(&l.drain()).into_iter().filter(|x| x.1 == 22).collect();
    assert_eq!(late.len(), 1);
    assert_eq!(late[0].0, To::All);
}

#[test]
fn mavlink1_and_timesync_and_ping() {
    let t0 = Instant::now();
    let mut l = link(t0);
    let p = FakeParams::standard();
    let ts = MavMessage::TIMESYNC(TIMESYNC_DATA {
        tc1: 0,
        ts1: 12345,
        ..Default::default()
    });
    let frame = wire::encode_v1(gcs(), 111, &wire::payload_v1(&ts));
    l.on_datagram(t0, addr(50000), &frame, &snapshot(), &p);
    let d = decoded(&l.drain());
    assert_eq!(d[0].1, TIMESYNC_DATA::ID);
    let ping = MavMessage::PING(PING_DATA {
        time_usec: 5,
        seq: 9,
        target_system: 0,
        target_component: 0,
    });
    l.on_datagram(t0, addr(50000), &v2(&ping), &snapshot(), &p);
    let d = decoded(&l.drain());
    assert_eq!(d[0].1, 4);
    // a heartbeat only teaches the peer
    let hb = v2(&MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()));
    assert!(l.on_datagram(t0, addr(50001), &hb, &snapshot(), &p).is_empty());
    assert!(l.drain().is_empty());
    let mut dst = Vec::new();
    l.destinations(t0, &mut dst);
    // the default remote and the peer that heartbeats (talking is not listening)
    assert_eq!(dst, vec![addr(14540), addr(50001)]);
}

#[test]
fn a_gcs_heartbeat_tells_the_autopilot_the_data_link_is_alive() {
    let t0 = Instant::now();
    let mut l = link(t0);
    let p = FakeParams::standard();
    let gcs_hb = v2(&MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        mavtype: mavlink::dialects::common::MavType::MAV_TYPE_GCS,
        ..HEARTBEAT_DATA::default()
    }));
    assert_eq!(
        l.on_datagram(t0, addr(50000), &gcs_hb, &snapshot(), &p),
        vec![Effect::GcsHeartbeat]
    );
    assert!(l.drain().is_empty(), "no answer");
    // an onboard computer's heartbeat is no ground station
    let other = v2(&MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        mavtype: mavlink::dialects::common::MavType::MAV_TYPE_ONBOARD_CONTROLLER,
        ..HEARTBEAT_DATA::default()
    }));
    assert!(l.on_datagram(t0, addr(50001), &other, &snapshot(), &p).is_empty());
}

#[test]
fn component_metadata_names_the_general_file_and_its_crc() {
    let t0 = Instant::now();
    let mut l = link(t0);
    let p = FakeParams::standard();
    let nan = f32::NAN;
    l.on_datagram(
        t0,
        addr(50000),
        &cmd(512, [397.0, nan, nan, nan, nan, nan, nan], 1),
        &snapshot(),
        &p,
    );
    let d = decoded(&l.drain());
    assert_eq!(d.iter().map(|x| x.1).collect::<Vec<_>>(), vec![77, 397]);
    let m = mavlink::dialects::common::COMPONENT_METADATA_DATA::deser(mavlink::MavlinkVersion::V2, &d[1].2).unwrap();
    assert_eq!(m.uri.to_str().unwrap(), "mftp://etc/extras/component_general.json");
    assert_eq!(m.file_crc, crate::mission::crc::crc32part(events::general_json(), 0));
}

#[test]
fn events_go_to_every_peer_and_a_lost_one_is_sent_again_on_request() {
    let t0 = Instant::now();
    let mut l = link(t0);
    let p = FakeParams::standard();
    l.poll(t0, &snapshot(), 0);
    let current: Vec<_> = decoded(&l.drain()).into_iter().filter(|d| d.1 == 411).collect();
    assert_eq!(current.len(), 1, "CURRENT_EVENT_SEQUENCE at once");
    let mut reporter = events::Reporter::default();
    let ready = crate::autopilot::HealthReport {
        can_arm: crate::autopilot::ModeSet::ALL,
        ..Default::default()
    };
    let sent = reporter.update(0.0, ready, true);
    l.send_events(t0, &sent);
    let out = decoded(&l.drain());
    assert_eq!(out.iter().filter(|d| d.1 == 410).count(), 2);
    assert!(out.iter().all(|d| d.0 == To::All));
    let ask = v2(&MavMessage::REQUEST_EVENT(
        mavlink::dialects::common::REQUEST_EVENT_DATA {
            target_system: 1,
            target_component: 1,
            first_sequence: 1,
            last_sequence: 2,
        },
    ));
    l.on_datagram(t0, addr(50000), &ask, &snapshot(), &p);
    let again = decoded(&l.drain());
    assert_eq!(
        again.iter().map(|d| d.1).collect::<Vec<_>>(),
        [410, 413],
        "1 again, 2 not yet"
    );
    assert!(again.iter().all(|d| d.0 == To::Peer(addr(50000))));
    l.poll(t0 + events::CURRENT_SEQUENCE_PERIOD, &snapshot(), 0);
    let later: Vec<_> = decoded(&l.drain()).into_iter().filter(|d| d.1 == 411).collect();
    assert_eq!(later.len(), 1, "every 3 s");
}
