//! Unit tests of `link/peers.rs`: the peers a link serves (default remote,
//! proven and unproven peers).

use super::*;
use crate::link::testing::addr;

#[test]
fn default_remote_is_always_served_and_peers_expire() {
    let t0 = Instant::now();
    let mut p = Peers::new(Some(addr(14540)), Duration::from_secs(10), t0);
    let mut out = Vec::new();
    p.active(t0, &mut out);
    assert_eq!(out, vec![addr(14540)]);
    assert!(p.heard(t0, addr(50000), 20));
    assert!(!p.heard(t0, addr(50000), 20));
    assert!(!p.heard(t0, addr(14540), 20), "the default remote is known from boot");
    // talking is not listening: no streams yet
    p.active(t0, &mut out);
    assert_eq!(out, vec![addr(14540)]);
    assert_eq!(p.standing(addr(50000)), Some(Standing::Unproven));
    assert!(p.prove(t0, addr(50000)));
    assert!(!p.prove(t0, addr(50000)), "once");
    p.active(t0 + Duration::from_secs(5), &mut out);
    assert_eq!(out, vec![addr(14540), addr(50000)]);
    // a client restarting on a new port is served next to the old one
    p.heard(t0 + Duration::from_secs(6), addr(50001), 20);
    p.prove(t0 + Duration::from_secs(6), addr(50001));
    p.active(t0 + Duration::from_secs(12), &mut out);
    assert_eq!(out, vec![addr(14540), addr(50001)]);
    assert_eq!(p.active_count(t0 + Duration::from_secs(12)), 2);
    assert_eq!(p.standing(addr(50000)), None);
}

#[test]
fn an_unproven_peer_gets_three_times_what_it_sent_and_a_stranger_nothing() {
    let t0 = Instant::now();
    let mut p = Peers::new(None, Duration::from_secs(10), t0);
    assert!(!p.charge(t0, addr(40000), 1), "never heard");
    p.heard(t0, addr(40000), 13);
    assert!(!p.charge(t0, addr(40000), 40));
    assert!(p.charge(t0, addr(40000), 39));
    assert!(!p.charge(t0, addr(40000), 1), "spent");
    // proven: the proven budget, whatever it sent
    p.prove(t0, addr(40000));
    assert!(p.charge(t0, addr(40000), 20_000));
    assert!(!p.charge(t0, addr(40000), budget::PROVEN_RATE as usize));
}

#[test]
fn unproven_peers_together_share_one_pool() {
    let t0 = Instant::now();
    let mut p = Peers::new(None, Duration::from_secs(10), t0);
    let mut sent = 0;
    for i in 0..MAX_UNPROVEN as u16 {
        p.heard(t0, addr(40000 + i), 1000);
        while p.charge(t0, addr(40000 + i), 100) {
            sent += 100;
        }
    }
    assert_eq!(sent, budget::UNPROVEN_POOL_RATE as usize / 100 * 100);
}

#[test]
fn strangers_never_displace_a_proven_peer_and_a_live_one_is_never_displaced() {
    let t0 = Instant::now();
    let mut p = Peers::new(None, Duration::from_secs(10), t0);
    let gcs = addr(14550);
    p.heard(t0, gcs, 20);
    p.prove(t0, gcs);
    for i in 0..1000u16 {
        p.heard(t0 + Duration::from_millis(u64::from(i)), addr(20000 + i), 13);
    }
    assert_eq!(p.standing(gcs), Some(Standing::Proven));
    assert_eq!(p.learned.len(), MAX_UNPROVEN + 1);
    // the newest unproven peers are kept
    assert_eq!(p.standing(addr(20999)), Some(Standing::Unproven));
    assert_eq!(p.standing(addr(20000)), None);
    // forged heartbeats from many ports fill the proven table, but the
    // live GCS stays
    let t1 = t0 + Duration::from_secs(1);
    p.heard(t1, gcs, 20);
    for i in 0..100u16 {
        p.heard(t1, addr(30000 + i), 20);
        p.prove(t1, addr(30000 + i));
    }
    let mut out = Vec::new();
    p.active(t1, &mut out);
    assert_eq!(out.len(), MAX_PROVEN);
    assert!(out.contains(&gcs));
    // a silent proven peer makes room once it is no longer live
    let t2 = t1 + LIVE + Duration::from_millis(1);
    p.heard(t2, addr(31000), 20);
    assert!(p.prove(t2, addr(31000)));
    p.active(t2, &mut out);
    assert_eq!(out.len(), MAX_PROVEN);
    assert!(out.contains(&addr(31000)));
}
