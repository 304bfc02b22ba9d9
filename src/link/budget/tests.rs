//! Unit tests of `link/budget.rs`: the byte budgets that bound what a link
//! sends.

use super::*;
use std::time::Duration;

#[test]
fn a_bucket_gives_its_burst_then_its_rate() {
    let t0 = Instant::now();
    let mut b = TokenBucket::new(t0, 1000.0, 500.0);
    assert!(b.take(t0, 400));
    assert!(!b.take(t0, 200), "only 100 left");
    assert!(b.take(t0, 100));
    // 0.1 s later: 100 bytes more, not more
    let t1 = t0 + Duration::from_millis(100);
    assert!(!b.take(t1, 101));
    assert!(b.take(t1, 100));
    // a long pause refills to the burst only
    let t2 = t1 + Duration::from_secs(60);
    assert!(!b.take(t2, 501));
    assert!(b.take(t2, 500));
}

#[test]
fn credit_is_three_times_what_came_in_and_capped() {
    let mut c = Credit::default();
    assert!(!c.allows(1));
    c.earn(13);
    assert!(c.allows(39) && !c.allows(40));
    c.spend(30);
    assert!(c.allows(9) && !c.allows(10));
    for _ in 0..10_000 {
        c.earn(64);
    }
    assert!(c.allows(UNPROVEN_MAX_CREDIT) && !c.allows(UNPROVEN_MAX_CREDIT + 1));
}
