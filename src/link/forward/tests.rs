//! Forwarding between two links of one vehicle: datagrams in on one, the
//! same bytes out on the other, by PX4's rule.

use std::time::{Duration, Instant};

use mavlink::MavHeader;
use mavlink::dialects::common::{
    HEARTBEAT_DATA, MavAutopilot, MavMessage, MavModeFlag, MavSeverity, MavState, MavType, NAMED_VALUE_FLOAT_DATA,
    PARAM_REQUEST_READ_DATA, STATUSTEXT_DATA,
};

use super::super::testing::{FakeParams, addr, link, snapshot};
use super::super::wire::{self, CommandLong};
use super::super::{Link, To};
use super::*;
use crate::params::ParamValue;

/// Vehicle 1's two links (GCS, API), forwarding to each other.
fn pair(now: Instant) -> (Link, Link) {
    let fellows = Fellows::for_links(2);
    let mut gcs = link(now);
    let mut api = link(now);
    gcs.set_forwarding(fellows[0].clone());
    api.set_forwarding(fellows[1].clone());
    (gcs, api)
}

fn frame(system: u8, component: u8, msg: &MavMessage) -> Vec<u8> {
    let mut enc = wire::Encoder::new(system, component);
    enc.message(msg)
}

fn heartbeat(system: u8, component: u8, kind: MavType) -> Vec<u8> {
    frame(
        system,
        component,
        &MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            custom_mode: 0,
            mavtype: kind,
            autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
            base_mode: MavModeFlag::empty(),
            system_status: MavState::MAV_STATE_ACTIVE,
            mavlink_version: 3,
        }),
    )
}

fn status_text(system: u8, component: u8, text: &str) -> Vec<u8> {
    frame(
        system,
        component,
        &MavMessage::STATUSTEXT(STATUSTEXT_DATA {
            severity: MavSeverity::MAV_SEVERITY_INFO,
            text: text.into(),
            id: 0,
            chunk_seq: 0,
        }),
    )
}

fn command_to(target: (u8, u8)) -> Vec<u8> {
    let c = CommandLong {
        params: [0.0; 7],
        command: 512, // REQUEST_MESSAGE
        target_system: target.0,
        target_component: target.1,
        confirmation: 0,
    };
    let header = MavHeader {
        system_id: 245,
        component_id: 190,
        sequence: 7,
    };
    wire::encode_v2(header, 76, &c.encode())
}

/// `data` received on `from_link` (from `from`), then handed to `to_link`
/// as the daemon does; the bytes `to_link` sends.
fn through(now: Instant, from_link: &mut Link, to_link: &mut Link, data: &[u8], params: &FakeParams) -> Vec<Vec<u8>> {
    let t = snapshot();
    from_link.on_datagram(now, addr(40_000), data, &t, params);
    let _ = from_link.drain();
    for f in from_link.take_forwarded() {
        to_link.pass(now, &f);
    }
    to_link
        .drain()
        .into_iter()
        .filter(|o| o.to == To::All)
        .map(|o| o.bytes)
        .collect()
}

/// Both links have a client: a GCS (255/190) on the GCS link, a companion
/// (245/190) on the API link.
fn with_clients(now: Instant, params: &FakeParams) -> (Link, Link) {
    let (mut gcs, mut api) = pair(now);
    let t = snapshot();
    gcs.on_datagram(
        now,
        addr(40_001),
        &heartbeat(255, 190, MavType::MAV_TYPE_GCS),
        &t,
        params,
    );
    api.on_datagram(
        now,
        addr(40_000),
        &heartbeat(245, 190, MavType::MAV_TYPE_ONBOARD_CONTROLLER),
        &t,
        params,
    );
    let _ = gcs.drain();
    let _ = api.drain();
    let _ = gcs.take_forwarded();
    let _ = api.take_forwarded();
    (gcs, api)
}

#[test]
fn a_status_text_from_the_api_link_reaches_the_gcs_link_byte_for_byte() {
    let now = Instant::now();
    let params = FakeParams::standard();
    let (mut gcs, mut api) = with_clients(now, &params);
    let text = status_text(245, 190, "Hello world!");
    let out = through(now, &mut api, &mut gcs, &text, &params);
    assert_eq!(out, vec![text], "the frame as sent: its sender's ids, sequence and CRC");
    assert_eq!(gcs.stats().forwarded, 1);
    // and back: a GCS's NAMED_VALUE_FLOAT reaches the companion
    let nvf = frame(
        255,
        190,
        &MavMessage::NAMED_VALUE_FLOAT(NAMED_VALUE_FLOAT_DATA {
            time_boot_ms: 1,
            name: "X".into(),
            value: 2.0,
        }),
    );
    assert_eq!(through(now, &mut gcs, &mut api, &nvf, &params), vec![nvf]);
}

#[test]
fn a_command_for_the_autopilot_is_kept_and_one_for_a_component_goes_where_it_was_seen() {
    let now = Instant::now();
    let params = FakeParams::standard();
    let (mut gcs, mut api) = with_clients(now, &params);
    // for 1/1: the vehicle answers it, nobody else sees it
    assert!(through(now, &mut api, &mut gcs, &command_to((1, 1)), &params).is_empty());
    // for the GCS (255/190), heard on the GCS link: passed there
    let to_gcs = command_to((255, 190));
    assert_eq!(through(now, &mut api, &mut gcs, &to_gcs, &params), vec![to_gcs]);
    // for any component of system 255: passed too
    let to_255 = command_to((255, 0));
    assert_eq!(through(now, &mut api, &mut gcs, &to_255, &params), vec![to_255]);
    // for a component never heard on the GCS link: dropped (PX4's component_was_seen)
    assert!(through(now, &mut api, &mut gcs, &command_to((77, 1)), &params).is_empty());
    assert!(through(now, &mut api, &mut gcs, &command_to((255, 1)), &params).is_empty());
    // for system 1, any component: only where a component of system 1 was heard
    let read = frame(
        245,
        190,
        &MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
            param_index: 0,
            target_system: 1,
            target_component: 0,
            param_id: "SYS_FAILURE_EN".into(),
        }),
    );
    assert!(through(now, &mut api, &mut gcs, &read, &params).is_empty());
}

#[test]
fn heartbeats_are_forwarded_unless_mav_hb_forw_en_is_0() {
    let now = Instant::now();
    let mut params = FakeParams::standard();
    let (mut gcs, mut api) = with_clients(now, &params);
    let hb = heartbeat(245, 190, MavType::MAV_TYPE_ONBOARD_CONTROLLER);
    assert_eq!(
        through(now, &mut api, &mut gcs, &hb, &params),
        vec![hb.clone()],
        "PX4's default: 1"
    );
    params.0.push((HEARTBEAT_PARAM, ParamValue::Int32(0), 0.0, 1.0));
    assert!(through(now, &mut api, &mut gcs, &hb, &params).is_empty());
    params.0.last_mut().unwrap().1 = ParamValue::Int32(1);
    assert_eq!(through(now, &mut api, &mut gcs, &hb, &params), vec![hb]);
}

#[test]
fn nothing_is_forwarded_to_a_link_that_heard_no_one_and_nothing_comes_back() {
    let now = Instant::now();
    let params = FakeParams::standard();
    let (mut gcs, mut api) = pair(now);
    let t = snapshot();
    api.on_datagram(
        now,
        addr(40_000),
        &heartbeat(245, 190, MavType::MAV_TYPE_GCS),
        &t,
        &params,
    );
    // the GCS link heard no one: the API link keeps nothing for it
    api.on_datagram(now, addr(40_000), &status_text(245, 190, "hi"), &t, &params);
    assert!(api.take_forwarded().is_empty());
    // a client that talks on both links (or a frame looped back by a
    // router): never sent onto a link where its sender was heard
    gcs.on_datagram(
        now,
        addr(40_001),
        &heartbeat(245, 190, MavType::MAV_TYPE_GCS),
        &t,
        &params,
    );
    let _ = gcs.drain();
    let text = status_text(245, 190, "twice");
    assert!(through(now, &mut api, &mut gcs, &text, &params).is_empty());
    let _ = gcs.take_forwarded();
    // our own frames coming back are ignored, never forwarded
    assert!(through(now, &mut gcs, &mut api, &status_text(1, 1, "me"), &params).is_empty());
}

#[test]
fn a_lone_link_keeps_nothing_and_a_flood_is_held_to_the_budget() {
    let now = Instant::now();
    let params = FakeParams::standard();
    let t = snapshot();
    let mut lone = link(now);
    lone.on_datagram(now, addr(40_000), &status_text(245, 190, "hi"), &t, &params);
    assert!(lone.take_forwarded().is_empty());
    let (mut gcs, mut api) = with_clients(now, &params);
    let text = status_text(245, 190, "flood");
    let mut datagram = Vec::new();
    for _ in 0..30 {
        datagram.extend_from_slice(&text);
    }
    let mut sent = 0;
    for _ in 0..200 {
        sent += through(now, &mut api, &mut gcs, &datagram, &params).len();
    }
    // two peers (the default remote and the GCS): each frame counts twice
    let fanout = 2;
    let allowed = (2.0 * FORWARD_RATE) as usize / (text.len() * fanout);
    assert_eq!(sent, allowed, "the burst, then nothing at the same instant");
    assert!(gcs.stats().forward_shed > 0);
    // a second later the rate has refilled part of it
    let later = now + Duration::from_secs(1);
    let n = through(later, &mut api, &mut gcs, &text, &params).len();
    assert_eq!(n, 1);
}

#[test]
fn components_are_remembered_as_px4_does() {
    let mut c = Components::default();
    assert!(!c.was_seen(0, 0));
    assert!(c.note(255, 190));
    assert!(!c.note(255, 190));
    assert!(c.was_seen(0, 0) && c.was_seen(255, 0) && c.was_seen(255, 190));
    assert!(!c.was_seen(255, 1) && !c.was_seen(1, 0));
    for i in 0..40 {
        c.note(10, i);
    }
    assert_eq!(c.ids.len(), MAX_REMOTE_COMPONENTS, "bounded, as PX4's table");
}
