//! Signing: signatures against frames pymavlink signed
//! (tests/fixtures/mavlink/signed-frames.txt, tools/golden_signed_frames.py),
//! the replay and stale rules, the unsigned allow-list, and the link's gate.

use std::time::{Duration, Instant};

use mavlink::MavHeader;
use mavlink::dialects::common::{MavMessage, SETUP_SIGNING_DATA};

use super::*;
use crate::link::Effect;

use crate::link::testing::{FakeParams, addr, arm, link, snapshot};
use crate::link::wire;

const FIXTURE: &str = include_str!("../../../tests/fixtures/mavlink/signed-frames.txt");

struct Golden {
    name: String,
    key: Key,
    link_id: u8,
    timestamp: u64,
    bytes: Vec<u8>,
}

fn hex(s: &str) -> Vec<u8> {
    (0..s.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&s[i..i + 2], 16).expect("hex"))
        .collect()
}

fn goldens() -> Vec<Golden> {
    FIXTURE
        .lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            Golden {
                name: f[0].to_string(),
                key: hex(f[1]).try_into().expect("32-byte key"),
                link_id: f[2].parse().expect("link id"),
                timestamp: f[3].parse().expect("timestamp"),
                bytes: hex(f[4]),
            }
        })
        .collect()
}

fn golden(name: &str) -> Golden {
    goldens().into_iter().find(|g| g.name == name).expect("golden frame")
}

/// A keyed state whose clock reads `ts` at `at`.
fn keyed(key: Key, at: Instant, ts: u64) -> Signing {
    let mut s = Signing::unkeyed(at, ts);
    s.setup(key, 0);
    s
}

fn frame(bytes: &[u8]) -> Frame<'_> {
    wire::frames(bytes).next().expect("a frame")
}

#[test]
fn pymavlink_signatures_verify_and_a_wrong_key_does_not() {
    let at = Instant::now();
    let all = goldens();
    assert_eq!(all.len(), 3);
    for g in all {
        let f = frame(&g.bytes);
        let sig = f.signature().expect("signed");
        assert_eq!(sig[0], g.link_id, "{}", g.name);
        assert_eq!(signature(&g.key, f.bytes), sig[7..13], "{}", g.name);
        let mut s = keyed(g.key, at, g.timestamp);
        assert_eq!(s.check(&f, at), Ok(()), "{}", g.name);
        let mut other = g.key;
        other[0] ^= 1;
        let mut s = keyed(other, at, g.timestamp);
        assert_eq!(s.check(&f, at), Err(Refusal::BadSignature), "{}", g.name);
        assert_eq!(s.stats().bad_signature, 1);
    }
}

#[test]
fn our_signer_writes_the_bytes_pymavlink_writes() {
    for g in goldens() {
        let f = frame(&g.bytes);
        let header = MavHeader {
            system_id: u32::from(f.system_id),
            component_id: f.component_id,
            sequence: f.sequence,
        };
        let mut ours = wire::encode_v2(header, f.message_id, f.payload);
        assert!(frame(&ours).signature().is_none());
        sign_frame(&g.key, &mut ours, g.link_id, g.timestamp);
        assert_eq!(ours, g.bytes, "{}", g.name);
    }
}

#[test]
fn a_replayed_frame_is_refused_and_a_later_one_on_the_stream_accepted() {
    let g = golden("command_long_arm");
    let at = Instant::now();
    let mut s = keyed(g.key, at, g.timestamp);
    assert_eq!(s.check(&frame(&g.bytes), at), Ok(()));
    assert_eq!(s.check(&frame(&g.bytes), at), Err(Refusal::Replay));
    // the same stream, a later timestamp (re-signed): accepted once
    let unsigned = |seq| {
        let h = MavHeader {
            system_id: 255,
            component_id: 190,
            sequence: seq,
        };
        wire::encode_v2(h, 76, &arm().encode())
    };
    let mut later = unsigned(1);
    sign_frame(&g.key, &mut later, g.link_id, g.timestamp + 1);
    assert_eq!(s.check(&frame(&later), at), Ok(()));
    assert_eq!(s.check(&frame(&later), at), Err(Refusal::Replay));
    // an older timestamp on a known stream, even never seen before
    let mut older = unsigned(2);
    sign_frame(&g.key, &mut older, g.link_id, g.timestamp - 5);
    assert_eq!(s.check(&frame(&older), at), Err(Refusal::Replay));
    // another link id is another stream: its own timestamps
    let mut other_link = unsigned(3);
    sign_frame(&g.key, &mut other_link, g.link_id + 1, g.timestamp - 5);
    assert_eq!(s.check(&frame(&other_link), at), Ok(()));
    assert_eq!(s.stats().replay, 3);
    assert_eq!(s.stats().accepted_signed, 3);
}

#[test]
fn a_new_stream_more_than_a_minute_behind_is_stale() {
    let g = golden("heartbeat");
    let at = Instant::now();
    // our clock one minute ahead of the frame: still accepted
    let mut s = keyed(g.key, at, g.timestamp + NEW_STREAM_WINDOW);
    assert_eq!(s.check(&frame(&g.bytes), at), Ok(()));
    // one tick more: stale
    let mut s = keyed(g.key, at, g.timestamp + NEW_STREAM_WINDOW + 1);
    assert_eq!(s.check(&frame(&g.bytes), at), Err(Refusal::Stale));
    // the clock runs: the same frame, checked 61 s later, is stale
    let mut s = keyed(g.key, at, g.timestamp);
    assert_eq!(
        s.check(&frame(&g.bytes), at + Duration::from_secs(61)),
        Err(Refusal::Stale)
    );
    assert_eq!(s.stats().stale, 1);
}

#[test]
fn with_a_key_only_the_allow_list_passes_unsigned_and_mavlink_1_is_unsigned() {
    let at = Instant::now();
    let h = MavHeader {
        system_id: 255,
        component_id: 190,
        sequence: 0,
    };
    let mut s = keyed([7; KEY_LEN], at, 0);
    let mut unkeyed = Signing::unkeyed(at, 0);
    for id in [0u32, 76, 23, 11, 256, 109, 246, 247] {
        let payload = [1u8; 8];
        let v2 = wire::encode_v2(h, id, &payload);
        let want = if UNSIGNED_ALLOWED.contains(&id) {
            Ok(())
        } else {
            Err(Refusal::Unsigned)
        };
        assert_eq!(s.check(&frame(&v2), at), want, "v2 {id}");
        assert_eq!(unkeyed.check(&frame(&v2), at), Ok(()), "no key: v2 {id}");
        if let Ok(id1) = u8::try_from(id) {
            let v1 = wire::encode_v1(h, id1, &payload);
            assert_eq!(s.check(&frame(&v1), at), want, "v1 {id}");
        }
    }
    assert_eq!(s.stats().unsigned, 5 + 4);
}

#[test]
fn outgoing_timestamps_follow_the_clock_and_never_repeat() {
    let at = Instant::now();
    let key = [9; KEY_LEN];
    let mut s = keyed(key, at, 1_000);
    let mut ts = Vec::new();
    for k in 0..3 {
        let mut f = wire::encode_v2(MavHeader::default(), 0, &[0; 9]);
        s.sign(&mut f, 2, at);
        let sig = frame(&f).signature().expect("signed").to_vec();
        assert_eq!(sig[0], 2);
        ts.push(u64::from_le_bytes([
            sig[1], sig[2], sig[3], sig[4], sig[5], sig[6], 0, 0,
        ]));
        assert_eq!(signature(&key, &f), sig[7..13], "frame {k}");
    }
    // same instant: last + 1
    assert_eq!(ts, vec![1_000, 1_001, 1_002]);
    let mut f = wire::encode_v2(MavHeader::default(), 0, &[0; 9]);
    s.sign(&mut f, 2, at + Duration::from_millis(1));
    assert_eq!(s.timestamp(), 1_100);
    // no key: left alone
    let mut none = Signing::unkeyed(at, 0);
    let mut g = wire::encode_v2(MavHeader::default(), 0, &[0; 9]);
    let before = g.clone();
    none.sign(&mut g, 0, at);
    assert_eq!(g, before);
}

#[test]
fn stored_round_trip_restart_begins_above_and_a_zero_key_is_no_key() {
    let at = Instant::now();
    let st = Stored {
        key: [3; KEY_LEN],
        timestamp: 5_000_000,
    };
    assert_eq!(Stored::from_bytes(&st.to_bytes()), Ok(st));
    assert!(Stored::from_bytes(&[0; 39]).unwrap_err().contains("39 bytes"));
    // the clock behind the stored timestamp (wall clock stepped back)
    let s = Signing::restored(st, at, 10);
    assert!(s.is_keyed());
    assert_eq!(s.timestamp(), 5_000_000 + 1_000_000);
    assert_eq!(s.stored(at).timestamp, 6_000_000);
    assert!(!format!("{st:?}").contains("3, 3"), "Debug must not show the key");
    let off = Signing::restored(
        Stored {
            key: [0; KEY_LEN],
            timestamp: 7,
        },
        at,
        10,
    );
    assert!(!off.is_keyed());
    assert_eq!(timestamp_from_unix_us(EPOCH_2015_UNIX_S * 1_000_000 + 25), 2);
    assert_eq!(timestamp_from_unix_us(0), 0);
}

fn setup_signing(key: Key, target_system: u8) -> MavMessage {
    MavMessage::SETUP_SIGNING(SETUP_SIGNING_DATA {
        initial_timestamp: 1_000,
        target_system,
        target_component: 0,
        secret_key: key,
    })
}

fn peers(l: &mut crate::link::Link, at: Instant) -> usize {
    let mut out = Vec::new();
    l.destinations(at, &mut out);
    out.len()
}

#[test]
fn the_link_gate_setup_signing_refusals_and_no_learned_peers() {
    let at = Instant::now();
    let t = snapshot();
    let p = FakeParams::standard();
    let mut l = link(at);
    let mut gcs = wire::Encoder::new(255, 190);
    let key = [5; KEY_LEN];
    // for another system: ignored, still no key
    let fx = l.on_datagram(at, addr(1), &gcs.message(&setup_signing(key, 9)), &t, &p);
    assert!(fx.is_empty() && !lock(l.signing()).is_keyed());
    // unsigned, no key yet: installed
    let fx = l.on_datagram(at, addr(1), &gcs.message(&setup_signing(key, 1)), &t, &p);
    assert_eq!(fx, vec![Effect::SigningKeyChanged]);
    assert!(lock(l.signing()).is_keyed());
    let before = peers(&mut l, at);
    // unsigned arm from a new address: refused, no effect, no answer, not a peer
    let arm = gcs.raw(76, &arm().encode());
    assert!(l.on_datagram(at, addr(2), &arm, &t, &p).is_empty());
    assert!(l.drain().iter().all(|o| o.to != crate::link::To::Peer(addr(2))));
    assert_eq!(peers(&mut l, at), before);
    assert_eq!(l.standing(addr(2)), None);
    // an unsigned SETUP_SIGNING cannot change the key now
    let fx = l.on_datagram(at, addr(2), &gcs.message(&setup_signing([0; KEY_LEN], 1)), &t, &p);
    assert!(fx.is_empty() && lock(l.signing()).is_keyed());
    // the arm signed with the key: an autopilot command, from a new peer
    let mut signed_arm = arm.clone();
    sign_frame(&key, &mut signed_arm, 0, 2_000);
    let fx = l.on_datagram(at, addr(3), &signed_arm, &t, &p);
    assert!(
        matches!(fx.as_slice(), [Effect::Autopilot { ack: Some(_), .. }]),
        "{fx:?}"
    );
    // learned (unproven until it heartbeats: no streams yet)
    assert_eq!(l.standing(addr(3)), Some(crate::link::peers::Standing::Unproven));
    assert_eq!(peers(&mut l, at), before);
    // replayed: nothing
    assert!(l.on_datagram(at, addr(3), &signed_arm, &t, &p).is_empty());
    // what the link sends now is signed with the key
    l.poll(at + Duration::from_secs(1), &t, 0);
    let out = l.drain();
    assert!(!out.is_empty());
    for o in &out {
        for f in wire::frames(&o.bytes) {
            let sig = f.signature().expect("signed");
            assert_eq!(signature(&key, f.bytes), sig[7..13]);
        }
    }
    // a signed all-zero key clears it: unsigned frames pass again
    let mut clear = gcs.message(&setup_signing([0; KEY_LEN], 1));
    sign_frame(&key, &mut clear, 0, 2_001);
    assert_eq!(
        l.on_datagram(at, addr(3), &clear, &t, &p),
        vec![Effect::SigningKeyChanged]
    );
    assert!(!lock(l.signing()).is_keyed());
    assert!(!l.on_datagram(at, addr(2), &arm, &t, &p).is_empty());
    let s = lock(l.signing()).stats();
    assert_eq!((s.unsigned, s.replay), (2, 1));
}
