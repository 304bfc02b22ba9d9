//! Lockstep tests of the health and arming report (what a ground station
//! shows as the arming checks, per mode): every failing check once, the
//! modes it blocks and what it concerns; the modes arming is possible in;
//! the same first reason arming is denied with.

mod common;

use common::sitl::{Sitl, int};
use rotorpilot::autopilot::{
    AutopilotCommand, CHECK_TEXTS, CommandOutcome, FlightMode, HealthComponent, HealthReport, ModeSet,
};
use rotorpilot::sim::{Fault, RotorHealth};

/// The report now; each of its texts one the event metadata knows.
fn report(ap: &Sitl) -> HealthReport {
    let r = ap.pilot().health_report(ap.time_s());
    for c in &r.checks {
        assert!(CHECK_TEXTS.contains(&c.text), "{:?} is not in CHECK_TEXTS", c.text);
    }
    r
}

fn set(modes: &[FlightMode]) -> ModeSet {
    modes.iter().fold(ModeSet::default(), |s, m| s.with(*m))
}

const MANUAL_MODES: [FlightMode; 5] = [
    FlightMode::Position,
    FlightMode::Altitude,
    FlightMode::Stabilized,
    FlightMode::Acro,
    FlightMode::Manual,
];

#[test]
fn ready_on_the_ground_each_mode_says_what_it_lacks() {
    let mut ap = Sitl::quad().build();
    ap.step();
    let r = report(&ap);
    let check = |text: &str| {
        r.checks
            .iter()
            .find(|c| c.text == text)
            .unwrap_or_else(|| panic!("no {text}: {r:?}"))
    };

    let mission = check("no valid mission");
    assert_eq!(mission.modes, ModeSet::of(FlightMode::Mission));
    assert_eq!(mission.component, HealthComponent::Mission);
    let sticks = check("no manual control input");
    assert_eq!(sticks.modes, set(&MANUAL_MODES));
    assert_eq!(sticks.component, HealthComponent::RemoteControl);
    assert_eq!(check("no offboard signal").modes, ModeSet::of(FlightMode::Offboard));
    assert_eq!(r.checks.len(), 4, "and the modes not armable: {r:?}");

    assert_eq!(r.can_arm, ModeSet::of(FlightMode::Hold), "Hold alone is armable now");
    for m in [
        FlightMode::Hold,
        FlightMode::Takeoff,
        FlightMode::Land,
        FlightMode::ReturnToLaunch,
    ] {
        assert!(r.can_run.contains(m), "{m:?} can run");
    }
    for m in MANUAL_MODES.iter().chain(&[FlightMode::Mission, FlightMode::Offboard]) {
        assert!(!r.can_run.contains(*m), "{m:?} cannot run");
    }
    assert_eq!(r.health_errors().count(), 0, "nothing is broken");
}

#[test]
fn without_gps_the_modes_that_steer_by_position_fail_and_arming_says_the_same() {
    let mut ap = Sitl::quad().build();
    ap.step();
    ap.gps(false);
    ap.run(1.0);
    let r = report(&ap);
    let gps = r.checks.iter().find(|c| c.text == "no GPS fix").expect("a GPS check");
    assert_eq!(gps.component, HealthComponent::Gps);
    for m in [
        FlightMode::Hold,
        FlightMode::Mission,
        FlightMode::ReturnToLaunch,
        FlightMode::Position,
    ] {
        assert!(gps.modes.contains(m), "{m:?} needs the position");
        assert!(!r.can_run.contains(m), "{m:?} cannot run without it");
    }
    for m in [FlightMode::Altitude, FlightMode::Stabilized] {
        assert!(!gps.modes.contains(m), "{m:?} does not need it");
    }
    assert!(!r.can_arm.contains(FlightMode::Hold));
    assert!(r.health_errors().any(|c| c == HealthComponent::Gps));
    assert_eq!(
        ap.command(AutopilotCommand::Arm { force: false }),
        CommandOutcome::TemporarilyRejected("no GPS fix")
    );
}

/// An octo that lost a rotor in flight and landed (COM_ACT_FAIL_ACT Land):
/// every mode fails on the ESC, reported as the motors' error.
#[test]
fn a_lost_rotor_fails_every_mode_as_an_esc_error() {
    let mut ap = Sitl::airframe("octo").params(&[("COM_ACT_FAIL_ACT", int(2))]).build();
    ap.step();
    ap.take_off_to(None);
    let rotor_off = Fault::Rotor {
        rotor: 0,
        health: RotorHealth::Off,
    };
    ap.core_mut().world_mut().inject(0, rotor_off).unwrap();
    assert!(ap.run_until(60.0, |t| !t.armed).is_some(), "landed and disarmed");
    let r = report(&ap);
    let esc = r.checks.iter().find(|c| c.text == "ESC failure").expect("an ESC check");
    assert_eq!(esc.modes, ModeSet::ALL);
    assert_eq!(esc.component, HealthComponent::MotorsEscs);
    assert_eq!(r.can_arm, ModeSet::default());
    assert_eq!(r.health_errors().collect::<Vec<_>>(), [HealthComponent::MotorsEscs]);
}
