//! Unit tests of `link/wire.rs`: MAVLink framing: datagrams split into checked
//! frames, frames encoded.

use super::*;
use mavlink::dialects::common::{HEARTBEAT_DATA, PARAM_REQUEST_LIST_DATA};

fn header(seq: u8) -> MavHeader {
    MavHeader {
        system_id: 255,
        component_id: 190,
        sequence: seq,
    }
}

#[test]
fn v2_round_trip_through_the_crate_encoder() {
    let mut enc = Encoder::new(1, 1);
    let bytes = enc.message(&MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()));
    let f: Vec<_> = frames(&bytes).collect();
    assert_eq!(f.len(), 1);
    assert_eq!(f[0].version, MavlinkVersion::V2);
    assert_eq!((f[0].system_id, f[0].component_id, f[0].message_id), (1, 1, 0));
    assert!(matches!(decode(&f[0]), Some(Inbound::Other(m)) if matches!(*m, MavMessage::HEARTBEAT(_))));
    assert_eq!(enc.sequence, 1);
}

#[test]
fn v1_frames_and_garbage_around_them() {
    let msg = MavMessage::PARAM_REQUEST_LIST(PARAM_REQUEST_LIST_DATA {
        target_system: 1,
        target_component: 0,
    });
    let mut dgram = vec![0x00, 0xFD, 0x13];
    dgram.extend(encode_v1(header(7), 21, &payload_v1(&msg)));
    dgram.extend([0xFE, 0x01]);
    dgram.extend(encode_v1(header(8), 21, &payload_v1(&msg)));
    let f: Vec<_> = frames(&dgram).collect();
    assert_eq!(f.len(), 2);
    assert_eq!(f[0].version, MavlinkVersion::V1);
    assert_eq!(f[0].sequence, 7);
    assert_eq!(f[1].sequence, 8);
    assert_eq!(decode(&f[0]), Some(Inbound::Other(Box::new(msg))));
}

#[test]
fn bad_crc_is_skipped() {
    let mut enc = Encoder::new(1, 1);
    let mut bytes = enc.message(&MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()));
    let n = bytes.len();
    bytes[n - 1] ^= 0xFF;
    assert_eq!(frames(&bytes).count(), 0);
}

#[test]
fn signed_frames_are_read() {
    let mut bytes = encode_v2(header(3), 21, &[1, 1]);
    bytes[2] = IFLAG_SIGNED;
    // CRC does not cover the flags? It does: recompute.
    let len = bytes.len();
    let crc = mavlink::calculate_crc(&bytes[1..len - 2], MavMessage::extra_crc(21));
    bytes[len - 2..].copy_from_slice(&crc.to_le_bytes());
    bytes.extend([0u8; SIGNATURE_LEN]);
    let f: Vec<_> = frames(&bytes).collect();
    assert_eq!(f.len(), 1);
    assert_eq!(f[0].payload, &[1, 1]);
}

#[test]
fn unknown_command_ids_survive_decoding() {
    let cmd = CommandLong {
        params: [1.0, 21196.0, f32::NAN, 0.0, 0.0, 0.0, 7.5],
        command: 31_337,
        target_system: 1,
        target_component: 0,
        confirmation: 2,
    };
    let bytes = encode_v2(header(0), COMMAND_LONG_DATA::ID, &cmd.encode());
    let f = frames(&bytes).next().expect("frame");
    let Some(Inbound::CommandLong(back)) = decode(&f) else {
        panic!("not a command")
    };
    assert_eq!(back.command, 31_337);
    assert_eq!(back.params[1], 21196.0);
    assert!(back.params[2].is_nan());
    assert_eq!(back.confirmation, 2);
}

#[test]
fn truncated_command_int_reads_zeros() {
    let cmd = CommandInt {
        params: [0.0; 4],
        x: 473_977_420,
        y: 85_455_940,
        z: 500.0,
        command: 192,
        target_system: 1,
        target_component: 1,
        frame: 0,
        current: 0,
        autocontinue: 0,
    };
    let bytes = encode_v2(header(0), COMMAND_INT_DATA::ID, &cmd.encode());
    // frame, current and autocontinue are zero: the payload was truncated
    assert!(bytes.len() < 12 + CommandInt::LEN);
    let f = frames(&bytes).next().expect("frame");
    assert_eq!(decode(&f), Some(Inbound::CommandInt(cmd)));
}

#[test]
fn ack_extensions_round_trip() {
    let ack = CommandAck {
        command: 400,
        result: 1,
        progress: 0,
        result_param2: 0,
        target_system: 245,
        target_component: 190,
    };
    assert_eq!(CommandAck::decode(&ack.encode()), ack);
    assert_eq!(CommandAck::decode(&ack.encode()[..3]).target_system, 0);
}

#[test]
fn mission_items_match_the_crate_layout_and_keep_unknown_commands() {
    use mavlink::dialects::common::{MavCmd, MavFrame, MavMissionType};
    let ours = MissionItemMsg {
        params: [0.5, 1.0, f32::NAN, 90.0],
        xy: ItemXy::Int {
            x: 473_977_420,
            y: -85_455_940,
        },
        z: 10.0,
        seq: 3,
        command: 16,
        target_system: 1,
        target_component: 190,
        frame: 6,
        current: 1,
        autocontinue: 1,
        mission_type: 2,
    };
    let crate_msg = MavMessage::MISSION_ITEM_INT(MISSION_ITEM_INT_DATA {
        param1: 0.5,
        param2: 1.0,
        param3: f32::NAN,
        param4: 90.0,
        x: 473_977_420,
        y: -85_455_940,
        z: 10.0,
        seq: 3,
        command: MavCmd::MAV_CMD_NAV_WAYPOINT,
        target_system: 1,
        target_component: 190,
        frame: MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
        current: 1,
        autocontinue: 1,
        mission_type: MavMissionType::MAV_MISSION_TYPE_RALLY,
    });
    let mut v2 = [0u8; 255];
    let n = crate_msg.ser(MavlinkVersion::V2, &mut v2);
    assert_eq!(&ours.encode()[..], &v2[..n]);
    let mut enc = Encoder::new(1, 1);
    let bytes = enc.mission_item(&ours);
    let f = frames(&bytes).next().expect("frame");
    assert_eq!(f.message_id, 73);
    let Some(Inbound::MissionItem(back)) = decode(&f) else {
        panic!("not an item")
    };
    assert_eq!(back.encode(), ours.encode());
    // float x/y, a command the crate does not know, a MAVLink 1 frame without the extension
    let float = MissionItemMsg {
        xy: ItemXy::Float {
            x: 47.397_742,
            y: 8.545_594,
        },
        command: 31_337,
        mission_type: 0,
        ..ours
    };
    let v1 = encode_v1(header(0), 39, &float.encode()[..MissionItemMsg::LEN - 1]);
    let f = frames(&v1).next().expect("frame");
    let Some(Inbound::MissionItem(back)) = decode(&f) else {
        panic!("not an item")
    };
    assert_eq!(back.message_id(), 39);
    assert_eq!((back.command, back.mission_type), (31_337, 0));
    assert_eq!(back.encode(), float.encode());
}
