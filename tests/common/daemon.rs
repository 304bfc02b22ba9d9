//! The daemon tests' vehicle and client: start a vehicle in-process on free
//! loopback ports, and a small MAVLink client on its own UDP socket. Client
//! messages are encoded with the `mavlink` crate (MAVLink 2, or 1 where a test
//! says so); received datagrams are split with rotorpilot's checked framer.
//! COMMAND_LONG and COMMAND_INT are written, and COMMAND_ACK read, with
//! rotorpilot's own codec: `tests/daemon_protocol.rs` checks those helpers
//! against frames pymavlink packed (`tests/fixtures/mavlink/command-frames.txt`).
#![allow(deprecated)]

use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

use mavlink::dialects::common::{MavMessage, MavParamType, PARAM_SET_DATA};
use mavlink::{MAVLinkV1MessageRaw, MAVLinkV2MessageRaw, MavHeader, MavlinkVersion};
use rotorpilot::daemon::{self, Config, LinkSpec};
use rotorpilot::link::wire::{self, CommandAck, CommandInt, CommandLong, Inbound};
use tokio::net::UdpSocket;
use tokio::sync::oneshot;
use tokio::task::JoinHandle;
use tokio::time::{Instant, timeout};

/// A config on loopback: both links bound to port 0, remotes as given.
pub fn config(gcs_remote: Option<SocketAddr>, api_remote: Option<SocketAddr>, speed: f64) -> Config {
    let mut c = Config::px4_sitl(0);
    c.links = vec![
        LinkSpec {
            bind: "127.0.0.1:0".parse().unwrap(),
            remote: gcs_remote,
            ..LinkSpec::px4_gcs(0)
        },
        LinkSpec {
            bind: "127.0.0.1:0".parse().unwrap(),
            remote: api_remote,
            ..LinkSpec::px4_api(0)
        },
    ];
    c.speed = speed;
    c.state_dir = super::scratch_path("v");
    c
}

/// A running in-process vehicle.
pub struct Vehicle {
    /// GCS link address.
    pub gcs: SocketAddr,
    /// API link address.
    pub api: SocketAddr,
    /// Its state directory.
    pub state_dir: PathBuf,
    stop: Option<oneshot::Sender<()>>,
    handle: Option<JoinHandle<anyhow::Result<()>>>,
    keep_state: bool,
}

impl Vehicle {
    /// Start a vehicle with `config`.
    pub async fn start(config: Config) -> Vehicle {
        let state_dir = config.state_dir.clone();
        let d = daemon::bind(config).await.expect("bind");
        let addrs = d.local_addrs();
        let (tx, rx) = oneshot::channel::<()>();
        let handle = tokio::spawn(d.run(async move {
            let _ = rx.await;
        }));
        Vehicle {
            gcs: addrs[0].1,
            api: addrs[1].1,
            state_dir,
            stop: Some(tx),
            handle: Some(handle),
            keep_state: false,
        }
    }

    /// Wait (at most `wait`) for the daemon to end by itself (a client's
    /// shutdown command); true if it did, cleanly.
    pub async fn ended_by_itself(&mut self, wait: Duration) -> bool {
        let Some(h) = self.handle.as_mut() else { return false };
        match timeout(wait, h).await {
            Ok(Ok(Ok(()))) => {
                self.handle = None;
                true
            }
            _ => false,
        }
    }

    /// Stop it but keep its state directory (for a restart).
    pub async fn stop_keep_state(mut self) -> Duration {
        self.keep_state = true;
        self.stop().await
    }

    /// Stop it and wait; returns how long it took.
    pub async fn stop(mut self) -> Duration {
        let t0 = Instant::now();
        if let Some(s) = self.stop.take() {
            let _ = s.send(());
        }
        if let Some(h) = self.handle.take() {
            timeout(Duration::from_secs(5), h)
                .await
                .expect("daemon stops")
                .expect("join")
                .expect("daemon result");
        }
        t0.elapsed()
    }
}

impl Drop for Vehicle {
    fn drop(&mut self) {
        if let Some(s) = self.stop.take() {
            let _ = s.send(());
        }
        if !self.keep_state {
            let _ = std::fs::remove_dir_all(&self.state_dir);
        }
    }
}

/// One received frame.
#[derive(Clone, Debug)]
pub struct Rx {
    /// Where it came from.
    pub from: SocketAddr,
    /// Sender system id.
    pub sysid: u8,
    /// Sender component id.
    pub compid: u8,
    /// Message id.
    pub msgid: u32,
    /// Protocol version.
    pub version: MavlinkVersion,
    /// Raw payload.
    pub payload: Vec<u8>,
    /// Decoded message (COMMAND_ACK is read with [`Rx::ack`]).
    pub msg: Option<MavMessage>,
}

impl Rx {
    /// The frame as COMMAND_ACK, with extensions.
    pub fn ack(&self) -> Option<CommandAck> {
        (self.msgid == 77).then(|| CommandAck::decode(&self.payload))
    }
}

/// A MAVLink client on its own socket.
pub struct Client {
    /// The socket.
    pub sock: UdpSocket,
    /// Our system id.
    pub sysid: u8,
    /// Our component id.
    pub compid: u8,
    seq: u8,
    buf: Vec<Rx>,
}

impl Client {
    /// A client on a free loopback port, as MAVSDK (245/190).
    pub async fn new() -> Client {
        Self::with_ids(245, 190).await
    }

    /// A client with given ids.
    pub async fn with_ids(sysid: u8, compid: u8) -> Client {
        Client {
            sock: UdpSocket::bind("127.0.0.1:0").await.unwrap(),
            sysid,
            compid,
            seq: 0,
            buf: Vec::new(),
        }
    }

    /// Our address.
    pub fn addr(&self) -> SocketAddr {
        self.sock.local_addr().unwrap()
    }

    fn header(&mut self) -> MavHeader {
        self.seq = self.seq.wrapping_add(1);
        MavHeader {
            system_id: u32::from(self.sysid),
            component_id: self.compid,
            sequence: self.seq,
        }
    }

    /// Send a MAVLink 2 message.
    pub async fn send(&mut self, to: SocketAddr, msg: &MavMessage) {
        let mut raw = MAVLinkV2MessageRaw::new();
        raw.serialize_message(self.header(), msg);
        self.sock.send_to(raw.raw_bytes(), to).await.unwrap();
    }

    /// Send PARAM_SET for `id` to system 1 (after dropping what is queued,
    /// so that the answers read next are this set's).
    pub async fn param_set(&mut self, to: SocketAddr, id: &str, value: f32, kind: MavParamType) {
        self.drain().await;
        self.send(
            to,
            &MavMessage::PARAM_SET(PARAM_SET_DATA {
                param_value: value,
                target_system: 1,
                target_component: 0,
                param_id: id.into(),
                param_type: kind,
            }),
        )
        .await;
    }

    /// Send a MAVLink 1 message.
    pub async fn send_v1(&mut self, to: SocketAddr, msg: &MavMessage) {
        let mut raw = MAVLinkV1MessageRaw::new();
        raw.serialize_message(self.header(), msg);
        self.sock.send_to(raw.raw_bytes(), to).await.unwrap();
    }

    /// Send a COMMAND_LONG (any command id).
    pub async fn command_long(&mut self, to: SocketAddr, command: u16, p: [f32; 7], target: (u8, u8)) {
        let c = CommandLong {
            params: p,
            command,
            target_system: target.0,
            target_component: target.1,
            confirmation: 0,
        };
        let h = self.header();
        self.sock.send_to(&command_long_frame(h, &c), to).await.unwrap();
    }

    /// Send a COMMAND_INT.
    pub async fn command_int(&mut self, to: SocketAddr, c: CommandInt) {
        let h = self.header();
        self.sock.send_to(&command_int_frame(h, &c), to).await.unwrap();
    }

    /// Send a HEARTBEAT as a GCS.
    pub async fn heartbeat(&mut self, to: SocketAddr) {
        use mavlink::dialects::common::*;
        let hb = MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            custom_mode: 0,
            mavtype: MavType::MAV_TYPE_GCS,
            autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
            base_mode: MavModeFlag::empty(),
            system_status: MavState::MAV_STATE_ACTIVE,
            mavlink_version: 3,
        });
        self.send(to, &hb).await;
    }

    /// The next frame, waiting at most `wait`.
    pub async fn recv(&mut self, wait: Duration) -> Option<Rx> {
        if !self.buf.is_empty() {
            return Some(self.buf.remove(0));
        }
        let deadline = Instant::now() + wait;
        let mut b = vec![0u8; 65536];
        loop {
            let left = deadline.checked_duration_since(Instant::now())?;
            let (n, from) = timeout(left, self.sock.recv_from(&mut b)).await.ok()?.ok()?;
            self.buf.extend(received(&b[..n], from));
            if !self.buf.is_empty() {
                return Some(self.buf.remove(0));
            }
        }
    }

    /// Wait (at most `wait`) for a frame `f` maps to `Some`.
    pub async fn wait_for<T>(&mut self, wait: Duration, mut f: impl FnMut(&Rx) -> Option<T>) -> Option<T> {
        let deadline = Instant::now() + wait;
        loop {
            let left = deadline.checked_duration_since(Instant::now())?;
            let rx = self.recv(left).await?;
            if let Some(t) = f(&rx) {
                return Some(t);
            }
        }
    }

    /// Wait for the COMMAND_ACK of `command`.
    pub async fn ack_of(&mut self, command: u16, wait: Duration) -> Option<(Rx, CommandAck)> {
        self.wait_for(wait, |r| {
            r.ack().filter(|a| a.command == command).map(|a| (r.clone(), a))
        })
        .await
    }

    /// Send a COMMAND_LONG and wait for its ACK, sending it again each
    /// second while none comes, as MAVSDK retries a command, but for up to
    /// 10 s (MAVSDK gives up after 3 tries): on a machine just busy with a
    /// build an ACK has failed to come within 3 s (cause not found), and
    /// one late or lost answer is not what a test that uses this checks.
    pub async fn command_long_acked(
        &mut self,
        to: SocketAddr,
        command: u16,
        p: [f32; 7],
        target: (u8, u8),
    ) -> Option<CommandAck> {
        for _ in 0..10 {
            self.command_long(to, command, p, target).await;
            if let Some((_, ack)) = self.ack_of(command, Duration::from_secs(1)).await {
                return Some(ack);
            }
        }
        None
    }

    /// Send COMMAND_LONG to 1/1 and wait for its ACK.
    pub async fn command(&mut self, to: SocketAddr, command: u16, p: [f32; 7]) -> CommandAck {
        self.command_long(to, command, p, (1, 1)).await;
        self.ack_of(command, Duration::from_secs(3))
            .await
            .unwrap_or_else(|| panic!("no ACK for command {command}"))
            .1
    }

    /// Drop everything received so far.
    pub async fn drain(&mut self) {
        self.buf.clear();
        while self.recv(Duration::from_millis(1)).await.is_some() {}
    }
}

/// The COMMAND_LONG frame [`Client::command_long`] sends.
pub fn command_long_frame(header: MavHeader, c: &CommandLong) -> Vec<u8> {
    wire::encode_v2(header, 76, &c.encode())
}

/// The COMMAND_INT frame [`Client::command_int`] sends.
pub fn command_int_frame(header: MavHeader, c: &CommandInt) -> Vec<u8> {
    wire::encode_v2(header, 75, &c.encode())
}

/// The frames of one datagram as [`Client::recv`] hands them out.
pub fn received(datagram: &[u8], from: SocketAddr) -> Vec<Rx> {
    wire::frames(datagram)
        .map(|f| {
            let msg = match wire::decode(&f) {
                Some(Inbound::Other(m)) => Some(*m),
                _ => None,
            };
            Rx {
                from,
                sysid: f.system_id,
                compid: f.component_id,
                msgid: f.message_id,
                version: f.version,
                payload: f.payload.to_vec(),
                msg,
            }
        })
        .collect()
}

/// One frame of `tests/fixtures/mavlink/command-frames.txt`, packed by
/// pymavlink (tools/golden_frames.py): an encoder independent of ours.
#[derive(Clone, Debug)]
pub struct GoldenFrame {
    /// `command_long`, `command_int` or `command_ack`.
    pub name: String,
    /// The sender and the sequence number.
    pub header: MavHeader,
    /// The message's fields as pymavlink was given them.
    pub fields: std::collections::HashMap<String, String>,
    /// The frame's bytes.
    pub bytes: Vec<u8>,
}

impl GoldenFrame {
    /// A field as a number (`nan` for NaN).
    pub fn get<T: std::str::FromStr>(&self, name: &str) -> T {
        let text = &self.fields[name];
        text.parse()
            .unwrap_or_else(|_| panic!("{}: field {name} = {text} is not a number", self.name))
    }
}

/// Every frame of the golden file.
pub fn golden_frames() -> Vec<GoldenFrame> {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures/mavlink/command-frames.txt");
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let w: Vec<&str> = l.split_whitespace().collect();
            let hex = w[w.len() - 1];
            GoldenFrame {
                name: w[0].to_string(),
                header: MavHeader {
                    system_id: w[1].parse().unwrap(),
                    component_id: w[2].parse().unwrap(),
                    sequence: w[3].parse().unwrap(),
                },
                fields: w[4..w.len() - 1]
                    .iter()
                    .map(|kv| {
                        let (k, v) = kv.split_once('=').unwrap();
                        (k.to_string(), v.to_string())
                    })
                    .collect(),
                bytes: (0..hex.len())
                    .step_by(2)
                    .map(|i| u8::from_str_radix(&hex[i..i + 2], 16).unwrap())
                    .collect(),
            }
        })
        .collect()
}

/// NaN, MAVSDK's "unset".
pub const NAN: f32 = f32::NAN;

/// The latest HEARTBEAT within `wait`.
pub async fn heartbeat(c: &mut Client, wait: Duration) -> mavlink::dialects::common::HEARTBEAT_DATA {
    c.wait_for(wait, |r| match &r.msg {
        Some(MavMessage::HEARTBEAT(h)) if r.sysid == 1 && r.compid == 1 => Some(h.clone()),
        _ => None,
    })
    .await
    .expect("heartbeat")
}

/// Wait until SYS_STATUS says arming would pass (PREARM_CHECK healthy), as
/// MAVSDK's `is_armable` does.
pub async fn wait_armable(c: &mut Client) {
    c.wait_for(Duration::from_secs(5), |r| match &r.msg {
        Some(MavMessage::SYS_STATUS(s)) if s.onboard_control_sensors_health.bits() & 0x1000_0000 != 0 => Some(()),
        _ => None,
    })
    .await
    .expect("armable");
}
