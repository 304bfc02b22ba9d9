//! MAVLink framing on byte slices: split a UDP datagram into checked frames
//! (MAVLink 1 and 2, signed or not), and write MAVLink 2 frames. No sockets.
//!
//! Five messages are coded by hand instead of through the `mavlink` crate's
//! types: COMMAND_LONG (76), COMMAND_INT (75), COMMAND_ACK (77), MISSION_ITEM
//! (39) and MISSION_ITEM_INT (73). The crate decodes `command` (and a mission
//! item's `frame`) into its `MavCmd` (`MavFrame`) enum and refuses a frame
//! whose number it does not know, but an unknown command must still be
//! answered: UNSUPPORTED for a command, MAV_MISSION_UNSUPPORTED (or
//! UNSUPPORTED_FRAME) for a mission item, as PX4 does; and a COMMAND_ACK for
//! such a command, or a stored item, is written from its number.

use mavlink::dialects::common::{
    COMMAND_ACK_DATA, COMMAND_INT_DATA, COMMAND_LONG_DATA, MISSION_ITEM_DATA, MISSION_ITEM_INT_DATA, MavMessage,
};
use mavlink::{MAVLinkV2MessageRaw, MavHeader, MavlinkVersion, Message, MessageData};

/// MAVLink 1 start byte.
const STX_V1: u8 = 0xFE;
/// MAVLink 2 start byte.
const STX_V2: u8 = 0xFD;
/// MAVLink 2 incompatibility flag: the frame is signed (13 more bytes).
const IFLAG_SIGNED: u8 = 0x01;
/// Length of a MAVLink 2 signature.
pub const SIGNATURE_LEN: usize = 13;

/// One checked frame inside a datagram.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Frame<'a> {
    /// MAVLink 1 or 2.
    pub version: MavlinkVersion,
    /// Sequence number.
    pub sequence: u8,
    /// Sender system id.
    pub system_id: u8,
    /// Sender component id.
    pub component_id: u8,
    /// Message id.
    pub message_id: u32,
    /// Payload as received (MAVLink 2 payloads may be zero-truncated).
    pub payload: &'a [u8],
    /// The whole frame, from the start byte to the CRC or the signature's end.
    pub bytes: &'a [u8],
}

impl<'a> Frame<'a> {
    /// The 13-byte signature block of a signed MAVLink 2 frame (link id,
    /// timestamp 48-bit LE, signature 6 bytes); `None` when unsigned.
    #[must_use]
    pub fn signature(&self) -> Option<&'a [u8]> {
        let signed = self.version == MavlinkVersion::V2 && self.bytes[2] & IFLAG_SIGNED != 0;
        signed.then(|| &self.bytes[self.bytes.len() - SIGNATURE_LEN..])
    }
}

/// The frames of one datagram with a valid CRC, in order. Bytes that do not
/// start a frame are skipped; a frame with a bad CRC or an unknown message id
/// is skipped whole (the dialect has no CRC_EXTRA for it).
#[must_use]
pub fn frames(datagram: &[u8]) -> Frames<'_> {
    Frames { rest: datagram }
}

/// Iterator returned by [`frames`].
#[derive(Debug)]
pub struct Frames<'a> {
    rest: &'a [u8],
}

impl<'a> Iterator for Frames<'a> {
    type Item = Frame<'a>;

    fn next(&mut self) -> Option<Frame<'a>> {
        loop {
            let start = self.rest.iter().position(|b| *b == STX_V1 || *b == STX_V2)?;
            let buf = &self.rest[start..];
            match parse_one(buf) {
                Parsed::Frame(frame, used) => {
                    self.rest = &buf[used..];
                    return Some(frame);
                }
                Parsed::Skip(used) => self.rest = &buf[used..],
                Parsed::Incomplete => {
                    // Not enough bytes for the frame this start byte announces:
                    // it was a payload byte, or the datagram is cut. Look further.
                    self.rest = &buf[1..];
                }
            }
        }
    }
}

enum Parsed<'a> {
    Frame(Frame<'a>, usize),
    Skip(usize),
    Incomplete,
}

fn parse_one(buf: &[u8]) -> Parsed<'_> {
    if buf[0] == STX_V1 {
        // STX LEN SEQ SYS COMP MSGID payload CRC(2)
        if buf.len() < 8 {
            return Parsed::Incomplete;
        }
        let len = usize::from(buf[1]);
        let total = 6 + len + 2;
        if buf.len() < total {
            return Parsed::Incomplete;
        }
        let message_id = u32::from(buf[5]);
        if !crc_ok(&buf[1..6 + len], message_id, &buf[6 + len..total]) {
            return Parsed::Skip(1);
        }
        Parsed::Frame(
            Frame {
                version: MavlinkVersion::V1,
                sequence: buf[2],
                system_id: buf[3],
                component_id: buf[4],
                message_id,
                payload: &buf[6..6 + len],
                bytes: &buf[..total],
            },
            total,
        )
    } else {
        // STX LEN INCOMPAT COMPAT SEQ SYS COMP MSGID(3) payload CRC(2) [SIGNATURE(13)]
        if buf.len() < 12 {
            return Parsed::Incomplete;
        }
        let len = usize::from(buf[1]);
        let incompat = buf[2];
        let signed = incompat & IFLAG_SIGNED != 0;
        let total = 10 + len + 2 + if signed { SIGNATURE_LEN } else { 0 };
        if buf.len() < total {
            return Parsed::Incomplete;
        }
        let message_id = u32::from_le_bytes([buf[7], buf[8], buf[9], 0]);
        if !crc_ok(&buf[1..10 + len], message_id, &buf[10 + len..12 + len]) {
            return Parsed::Skip(1);
        }
        if incompat & !IFLAG_SIGNED != 0 {
            // A flag we do not understand (e.g. 32-bit system ids): the frame
            // is intact but not for us.
            return Parsed::Skip(total);
        }
        Parsed::Frame(
            Frame {
                version: MavlinkVersion::V2,
                sequence: buf[4],
                system_id: buf[5],
                component_id: buf[6],
                message_id,
                payload: &buf[10..10 + len],
                bytes: &buf[..total],
            },
            total,
        )
    }
}

fn crc_ok(covered: &[u8], message_id: u32, crc_bytes: &[u8]) -> bool {
    let extra = MavMessage::extra_crc(message_id);
    if extra == 0 && MavMessage::default_message_from_id(message_id).is_none() {
        return false;
    }
    mavlink::calculate_crc(covered, extra) == u16::from_le_bytes([crc_bytes[0], crc_bytes[1]])
}

/// A decoded frame's message: the crate's type, or one of the hand-coded commands.
#[derive(Clone, Debug, PartialEq)]
pub enum Inbound {
    /// COMMAND_LONG (76), with the command id as a number.
    CommandLong(CommandLong),
    /// COMMAND_INT (75), with the command id as a number.
    CommandInt(CommandInt),
    /// MISSION_ITEM (39) or MISSION_ITEM_INT (73), with command and frame as numbers.
    MissionItem(MissionItemMsg),
    /// Anything else the common dialect knows.
    Other(Box<MavMessage>),
}

/// Decode a frame's payload (zero-truncated or v1 payloads are zero-padded, as
/// the protocol says). `None` if the payload does not decode (e.g. an enum field
/// out of range).
#[must_use]
pub fn decode(frame: &Frame<'_>) -> Option<Inbound> {
    match frame.message_id {
        COMMAND_LONG_DATA::ID => Some(Inbound::CommandLong(CommandLong::decode(frame.payload))),
        COMMAND_INT_DATA::ID => Some(Inbound::CommandInt(CommandInt::decode(frame.payload))),
        MISSION_ITEM_DATA::ID => Some(Inbound::MissionItem(MissionItemMsg::decode(false, frame.payload))),
        MISSION_ITEM_INT_DATA::ID => Some(Inbound::MissionItem(MissionItemMsg::decode(true, frame.payload))),
        id => MavMessage::parse(frame.version, id, frame.payload)
            .ok()
            .map(|m| Inbound::Other(Box::new(m))),
    }
}

/// COMMAND_LONG with a numeric command id.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CommandLong {
    /// param1..param7.
    pub params: [f32; 7],
    /// MAV_CMD id.
    pub command: u16,
    /// Target system.
    pub target_system: u8,
    /// Target component.
    pub target_component: u8,
    /// Confirmation counter (0 first, then retransmissions).
    pub confirmation: u8,
}

impl CommandLong {
    /// Wire length of the payload.
    pub const LEN: usize = 33;

    /// Decode (zero-padded if truncated).
    #[must_use]
    pub fn decode(payload: &[u8]) -> Self {
        let p = padded::<{ Self::LEN }>(payload);
        Self {
            params: f32s_at(&p, 0),
            command: u16_at(&p, 28),
            target_system: p[30],
            target_component: p[31],
            confirmation: p[32],
        }
    }

    /// Encode the payload (full length; the framer truncates zeros).
    #[must_use]
    pub fn encode(&self) -> [u8; Self::LEN] {
        let mut p = [0u8; Self::LEN];
        put_f32s(&mut p, 0, &self.params);
        put(&mut p, 28, &self.command.to_le_bytes());
        p[30] = self.target_system;
        p[31] = self.target_component;
        p[32] = self.confirmation;
        p
    }
}

/// COMMAND_INT with a numeric command id and frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CommandInt {
    /// param1..param4.
    pub params: [f32; 4],
    /// x: latitude [degE7] in global frames.
    pub x: i32,
    /// y: longitude [degE7] in global frames.
    pub y: i32,
    /// z: altitude [m].
    pub z: f32,
    /// MAV_CMD id.
    pub command: u16,
    /// Target system.
    pub target_system: u8,
    /// Target component.
    pub target_component: u8,
    /// MAV_FRAME.
    pub frame: u8,
    /// Unused (0).
    pub current: u8,
    /// Unused (0).
    pub autocontinue: u8,
}

impl CommandInt {
    /// Wire length of the payload.
    pub const LEN: usize = 35;

    /// Decode (zero-padded if truncated).
    #[must_use]
    pub fn decode(payload: &[u8]) -> Self {
        let p = padded::<{ Self::LEN }>(payload);
        Self {
            params: f32s_at(&p, 0),
            x: i32_at(&p, 16),
            y: i32_at(&p, 20),
            z: f32_at(&p, 24),
            command: u16_at(&p, 28),
            target_system: p[30],
            target_component: p[31],
            frame: p[32],
            current: p[33],
            autocontinue: p[34],
        }
    }

    /// Encode the payload.
    #[must_use]
    pub fn encode(&self) -> [u8; Self::LEN] {
        let mut p = [0u8; Self::LEN];
        put_f32s(&mut p, 0, &self.params);
        put(&mut p, 16, &self.x.to_le_bytes());
        put(&mut p, 20, &self.y.to_le_bytes());
        put(&mut p, 24, &self.z.to_le_bytes());
        put(&mut p, 28, &self.command.to_le_bytes());
        p[30] = self.target_system;
        p[31] = self.target_component;
        p[32] = self.frame;
        p[33] = self.current;
        p[34] = self.autocontinue;
        p
    }
}

/// MISSION_ITEM (39) and MISSION_ITEM_INT (73): one layout, `x` and `y`
/// read as floats (degrees in global frames) or integers (degE7).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MissionItemMsg {
    /// param1..param4.
    pub params: [f32; 4],
    /// param5 and param6, as the message carries them.
    pub xy: ItemXy,
    /// param7 (altitude [m] in global frames).
    pub z: f32,
    /// Sequence number.
    pub seq: u16,
    /// MAV_CMD id.
    pub command: u16,
    /// Target system.
    pub target_system: u8,
    /// Target component.
    pub target_component: u8,
    /// MAV_FRAME.
    pub frame: u8,
    /// 1 on the current item.
    pub current: u8,
    /// Continue to the next item when done.
    pub autocontinue: u8,
    /// MAV_MISSION_TYPE; extension (0, the mission, when absent).
    pub mission_type: u8,
}

/// A mission item's `x` and `y` in either message.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ItemXy {
    /// MISSION_ITEM: floats.
    Float {
        /// param5.
        x: f32,
        /// param6.
        y: f32,
    },
    /// MISSION_ITEM_INT: integers (degE7 in global frames).
    Int {
        /// param5.
        x: i32,
        /// param6.
        y: i32,
    },
}

impl MissionItemMsg {
    /// Wire length of the payload with the extension.
    pub const LEN: usize = 38;

    /// Decode MISSION_ITEM_INT (`int`) or MISSION_ITEM (zero-padded if truncated).
    #[must_use]
    pub fn decode(int: bool, payload: &[u8]) -> Self {
        let p = padded::<{ Self::LEN }>(payload);
        let xy = if int {
            ItemXy::Int {
                x: i32_at(&p, 16),
                y: i32_at(&p, 20),
            }
        } else {
            ItemXy::Float {
                x: f32_at(&p, 16),
                y: f32_at(&p, 20),
            }
        };
        Self {
            params: f32s_at(&p, 0),
            xy,
            z: f32_at(&p, 24),
            seq: u16_at(&p, 28),
            command: u16_at(&p, 30),
            target_system: p[32],
            target_component: p[33],
            frame: p[34],
            current: p[35],
            autocontinue: p[36],
            mission_type: p[37],
        }
    }

    /// The message id: MISSION_ITEM_INT for integer `x`, `y`, else MISSION_ITEM.
    #[must_use]
    pub fn message_id(&self) -> u32 {
        match self.xy {
            ItemXy::Float { .. } => MISSION_ITEM_DATA::ID,
            ItemXy::Int { .. } => MISSION_ITEM_INT_DATA::ID,
        }
    }

    /// Encode the payload.
    #[must_use]
    pub fn encode(&self) -> [u8; Self::LEN] {
        let mut p = [0u8; Self::LEN];
        put_f32s(&mut p, 0, &self.params);
        let (x, y) = match self.xy {
            ItemXy::Float { x, y } => (x.to_le_bytes(), y.to_le_bytes()),
            ItemXy::Int { x, y } => (x.to_le_bytes(), y.to_le_bytes()),
        };
        put(&mut p, 16, &x);
        put(&mut p, 20, &y);
        put(&mut p, 24, &self.z.to_le_bytes());
        put(&mut p, 28, &self.seq.to_le_bytes());
        put(&mut p, 30, &self.command.to_le_bytes());
        p[32] = self.target_system;
        p[33] = self.target_component;
        p[34] = self.frame;
        p[35] = self.current;
        p[36] = self.autocontinue;
        p[37] = self.mission_type;
        p
    }
}

/// COMMAND_ACK with its MAVLink 2 extension fields.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CommandAck {
    /// MAV_CMD id being acknowledged.
    pub command: u16,
    /// MAV_RESULT.
    pub result: u8,
    /// Progress (0..100, 255 unknown); extension.
    pub progress: u8,
    /// Additional result information; extension.
    pub result_param2: i32,
    /// The requester's system id; extension.
    pub target_system: u8,
    /// The requester's component id; extension.
    pub target_component: u8,
}

impl CommandAck {
    /// Wire length of the payload with extensions.
    pub const LEN: usize = 10;

    /// Decode (missing extensions read as zero).
    #[must_use]
    pub fn decode(payload: &[u8]) -> Self {
        let p = padded::<{ Self::LEN }>(payload);
        Self {
            command: u16_at(&p, 0),
            result: p[2],
            progress: p[3],
            result_param2: i32_at(&p, 4),
            target_system: p[8],
            target_component: p[9],
        }
    }

    /// Encode the payload.
    #[must_use]
    pub fn encode(&self) -> [u8; Self::LEN] {
        let mut p = [0u8; Self::LEN];
        put(&mut p, 0, &self.command.to_le_bytes());
        p[2] = self.result;
        p[3] = self.progress;
        put(&mut p, 4, &self.result_param2.to_le_bytes());
        p[8] = self.target_system;
        p[9] = self.target_component;
        p
    }
}

// A payload is little-endian fields at fixed byte offsets.

/// The payload zero-padded to `N` bytes (MAVLink 2 cuts trailing zeros off
/// the wire, and a missing extension reads as zero).
fn padded<const N: usize>(payload: &[u8]) -> [u8; N] {
    let mut p = [0u8; N];
    let n = payload.len().min(N);
    p[..n].copy_from_slice(&payload[..n]);
    p
}

fn u16_at(p: &[u8], i: usize) -> u16 {
    u16::from_le_bytes([p[i], p[i + 1]])
}

fn i32_at(p: &[u8], i: usize) -> i32 {
    i32::from_le_bytes([p[i], p[i + 1], p[i + 2], p[i + 3]])
}

fn f32_at(p: &[u8], i: usize) -> f32 {
    f32::from_le_bytes([p[i], p[i + 1], p[i + 2], p[i + 3]])
}

/// `N` floats one after another from byte `i` (param1..paramN).
fn f32s_at<const N: usize>(p: &[u8], i: usize) -> [f32; N] {
    std::array::from_fn(|k| f32_at(p, i + 4 * k))
}

/// `bytes` written at byte `i`.
fn put(p: &mut [u8], i: usize, bytes: &[u8]) {
    p[i..i + bytes.len()].copy_from_slice(bytes);
}

/// Floats one after another from byte `i`.
fn put_f32s(p: &mut [u8], i: usize, values: &[f32]) {
    for (k, v) in values.iter().enumerate() {
        put(p, i + 4 * k, &v.to_le_bytes());
    }
}

/// Sender identity and sequence counter for the frames a link writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Encoder {
    /// Our system id.
    pub system_id: u8,
    /// Our component id.
    pub component_id: u8,
    /// Sequence number of the next frame.
    pub sequence: u8,
}

impl Encoder {
    /// A new encoder starting at sequence 0.
    #[must_use]
    pub fn new(system_id: u8, component_id: u8) -> Self {
        Self {
            system_id,
            component_id,
            sequence: 0,
        }
    }

    fn next_header(&mut self) -> MavHeader {
        let h = MavHeader {
            system_id: u32::from(self.system_id),
            component_id: self.component_id,
            sequence: self.sequence,
        };
        self.sequence = self.sequence.wrapping_add(1);
        h
    }

    /// A MAVLink 2 frame of a dialect message (payload zero-truncated).
    #[must_use]
    pub fn message(&mut self, msg: &MavMessage) -> Vec<u8> {
        let header = self.next_header();
        let mut raw = MAVLinkV2MessageRaw::new();
        raw.serialize_message(header, msg);
        raw.raw_bytes().to_vec()
    }

    /// A MAVLink 2 frame from a raw payload (trailing zeros truncated).
    #[must_use]
    pub fn raw(&mut self, message_id: u32, payload: &[u8]) -> Vec<u8> {
        let header = self.next_header();
        encode_v2(header, message_id, payload)
    }

    /// A COMMAND_ACK frame.
    #[must_use]
    pub fn command_ack(&mut self, ack: &CommandAck) -> Vec<u8> {
        self.raw(COMMAND_ACK_DATA::ID, &ack.encode())
    }

    /// A MISSION_ITEM or MISSION_ITEM_INT frame.
    #[must_use]
    pub fn mission_item(&mut self, item: &MissionItemMsg) -> Vec<u8> {
        self.raw(item.message_id(), &item.encode())
    }
}

/// Write one MAVLink 2 frame (unsigned) for `payload`, truncating trailing zero
/// bytes (at least one payload byte stays, as the protocol requires).
#[must_use]
pub fn encode_v2(header: MavHeader, message_id: u32, payload: &[u8]) -> Vec<u8> {
    let mut len = payload.len();
    while len > 1 && payload[len - 1] == 0 {
        len -= 1;
    }
    let payload = &payload[..len];
    let mut out = Vec::with_capacity(12 + len);
    let id = message_id.to_le_bytes();
    out.extend_from_slice(&[
        STX_V2,
        u8::try_from(len).unwrap_or(u8::MAX),
        0,
        0,
        header.sequence,
        u8::try_from(header.system_id).unwrap_or(u8::MAX),
        header.component_id,
        id[0],
        id[1],
        id[2],
    ]);
    out.extend_from_slice(payload);
    let crc = mavlink::calculate_crc(&out[1..], MavMessage::extra_crc(message_id));
    out.extend_from_slice(&crc.to_le_bytes());
    out
}

/// Write one MAVLink 1 frame for `payload` (for tests and clients that
/// check MAVLink 1 input). Message ids above 255 cannot be sent as v1.
#[must_use]
pub fn encode_v1(header: MavHeader, message_id: u8, payload: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(8 + payload.len());
    out.extend_from_slice(&[
        STX_V1,
        u8::try_from(payload.len()).unwrap_or(u8::MAX),
        header.sequence,
        u8::try_from(header.system_id).unwrap_or(u8::MAX),
        header.component_id,
        message_id,
    ]);
    out.extend_from_slice(payload);
    let crc = mavlink::calculate_crc(&out[1..], MavMessage::extra_crc(u32::from(message_id)));
    out.extend_from_slice(&crc.to_le_bytes());
    out
}

/// The full (untruncated, MAVLink 1 layout) payload of a dialect message.
#[must_use]
pub fn payload_v1(msg: &MavMessage) -> Vec<u8> {
    let mut buf = [0u8; 255];
    let n = msg.ser(MavlinkVersion::V1, &mut buf);
    buf[..n].to_vec()
}

#[cfg(test)]
mod tests;
