//! Missions flown through the lockstep core (world and flight stack, no
//! sockets): upload, start, the items in order, progress and completion as
//! MAVSDK reads them, pause and resume, set current, DO_JUMP, speed changes,
//! RTL at the end, and refusals that leave the stored mission unchanged.

use std::time::Instant;

mod common;

use common::sitl::{HOME, Sitl};
use nalgebra::Vector3;
use rotorpilot::autopilot::{
    AutopilotCommand, CommandOutcome, FlightMode, ItemDone, LandedState, MissionState, Telemetry,
};
use rotorpilot::mission::{MissionItem, MissionResult, MissionType, PlanChange, cmd, frame};

fn vehicle() -> Sitl {
    Sitl::quad().build()
}

/// A point `north`, `east` [m] from home at `alt` [m] above home, as MAVSDK 4 sends it (frame 3, degE7).
fn wp(north: f64, east: f64, alt: f32, hold_s: f32, acceptance_m: f32) -> MissionItem {
    let g = HOME.offset(&Vector3::new(north, east, 0.0));
    let (x, y) = MissionItem::xy_from_int(
        frame::GLOBAL_RELATIVE_ALT,
        (g.lat_deg * 1e7).round() as i32,
        (g.lon_deg * 1e7).round() as i32,
    );
    MissionItem {
        frame: frame::GLOBAL_RELATIVE_ALT,
        command: cmd::NAV_WAYPOINT,
        autocontinue: true,
        params: [hold_s, acceptance_m, 0.0, f32::NAN],
        x,
        y,
        z: alt,
    }
}

fn item(command: u16, params: [f32; 4]) -> MissionItem {
    MissionItem {
        frame: frame::MISSION,
        command,
        autocontinue: true,
        params,
        x: 0.0,
        y: 0.0,
        z: f32::NAN,
    }
}

fn upload(v: &mut Sitl, items: Vec<MissionItem>) -> Result<u32, MissionResult> {
    v.core_mut().change_plans(
        0,
        PlanChange::Store {
            kind: MissionType::Mission,
            items,
            base_id: None,
        },
    )
}

/// Step until `done` or `max_s` simulated seconds; the items reached on the way (seq, time, distance).
fn fly(v: &mut Sitl, max_s: f64, mut done: impl FnMut(&Telemetry) -> bool) -> (bool, Vec<(u16, f64, Vector3<f64>)>) {
    let mut reached = Vec::new();
    let n = (max_s / v.dt_s()) as usize;
    for _ in 0..n {
        v.step();
        for item in v.core_mut().drain_mission_done(0) {
            let ItemDone::Reached(seq) = item else { continue };
            let t = v.telemetry();
            reached.push((seq, t.time_s, t.position_ned));
        }
        if done(&v.telemetry()) {
            return (true, reached);
        }
    }
    (false, reached)
}

fn ready(v: &mut Sitl) {
    let (ok, _) = fly(v, 3.0, |t| t.prearm_ok);
    assert!(ok, "never armable");
}

#[test]
fn a_five_waypoint_mission_flies_in_order_and_completes_in_well_under_a_second() {
    let mut v = vehicle();
    let items = vec![
        wp(0.0, 0.0, 10.0, 0.0, 0.0),
        wp(30.0, 0.0, 10.0, 0.0, 0.0),
        wp(30.0, 30.0, 15.0, 0.0, 0.0),
        wp(0.0, 30.0, 15.0, 0.0, 0.0),
        wp(0.0, 0.0, 10.0, 0.5, 0.0),
    ];
    upload(&mut v, items).unwrap();
    ready(&mut v);
    let wall = Instant::now();
    assert_eq!(
        v.command(AutopilotCommand::StartMission { first: Some(0) }),
        CommandOutcome::Accepted
    );
    let (ok, reached) = fly(&mut v, 200.0, |t| t.mission.state == MissionState::Complete);
    let wall = wall.elapsed();
    let t = v.telemetry();
    for r in &reached {
        println!("reached {} at {:.2} s, at {:.2?}", r.0, r.1, r.2);
    }
    println!("{:.1} s simulated in {:?}", t.time_s, wall);
    assert!(ok, "mission not complete: {:?}", t.mission);
    assert_eq!(reached.iter().map(|r| r.0).collect::<Vec<_>>(), vec![0, 1, 2, 3, 4]);
    assert_eq!(t.mode, FlightMode::Mission);
    assert_eq!(t.landed, LandedState::InAir);
}

fn reached_seqs(r: &[(u16, f64, Vector3<f64>)]) -> Vec<u16> {
    r.iter().map(|x| x.0).collect()
}

fn square() -> Vec<MissionItem> {
    vec![
        wp(0.0, 0.0, 10.0, 0.0, 0.0),
        wp(25.0, 0.0, 10.0, 0.0, 0.0),
        wp(25.0, 25.0, 10.0, 0.0, 0.0),
        wp(0.0, 25.0, 10.0, 1.0, 0.0),
    ]
}

#[test]
fn hold_pauses_the_mission_and_mission_mode_resumes_at_the_same_item() {
    let mut v = vehicle();
    upload(&mut v, square()).unwrap();
    ready(&mut v);
    v.command(AutopilotCommand::StartMission { first: None });
    let (_, r) = fly(&mut v, 100.0, |t| t.mission.seq == 2);
    assert_eq!(reached_seqs(&r), vec![0, 1]);
    assert_eq!(
        v.command(AutopilotCommand::SetMode(FlightMode::Hold)),
        CommandOutcome::Accepted
    );
    let (_, r) = fly(&mut v, 5.0, |_| false);
    assert!(r.is_empty(), "paused, yet reached {r:?}");
    let t = v.telemetry();
    assert_eq!((t.mission.seq, t.mission.state), (2, MissionState::Paused));
    assert!(t.velocity_ned.norm() < 0.3, "not holding: {:?}", t.velocity_ned);
    assert_eq!(
        v.command(AutopilotCommand::SetMode(FlightMode::Mission)),
        CommandOutcome::Accepted
    );
    assert_eq!(v.telemetry().mission.state, MissionState::Active);
    let (ok, r) = fly(&mut v, 100.0, |t| t.mission.state == MissionState::Complete);
    assert!(ok);
    assert_eq!(reached_seqs(&r), vec![2, 3]);
}

#[test]
fn set_current_in_flight_flies_to_that_item_next() {
    let mut v = vehicle();
    upload(&mut v, square()).unwrap();
    ready(&mut v);
    v.command(AutopilotCommand::StartMission { first: None });
    fly(&mut v, 100.0, |t| t.mission.seq == 1);
    assert_eq!(
        v.command(AutopilotCommand::SetMissionCurrent { seq: 3 }),
        CommandOutcome::Accepted
    );
    assert_eq!(v.telemetry().mission.seq, 3);
    let (ok, r) = fly(&mut v, 100.0, |t| t.mission.state == MissionState::Complete);
    assert!(ok);
    assert_eq!(reached_seqs(&r), vec![3]);
    let beyond = v.command(AutopilotCommand::SetMissionCurrent { seq: 4 });
    assert!(matches!(beyond, CommandOutcome::Denied(_)), "{beyond:?}");
}

#[test]
fn do_jump_repeats_the_loop_the_given_number_of_times() {
    let mut v = vehicle();
    let mut items = vec![
        wp(0.0, 0.0, 8.0, 0.0, 0.0),
        wp(10.0, 0.0, 8.0, 0.0, 0.0),
        wp(10.0, 10.0, 8.0, 0.0, 0.0),
        item(cmd::DO_JUMP, [1.0, 2.0, f32::NAN, f32::NAN]),
        wp(0.0, 0.0, 8.0, 0.5, 0.0),
    ];
    items[3].z = 0.0;
    upload(&mut v, items).unwrap();
    ready(&mut v);
    v.command(AutopilotCommand::StartMission { first: Some(0) });
    let (ok, r) = fly(&mut v, 200.0, |t| t.mission.state == MissionState::Complete);
    assert!(ok);
    assert_eq!(reached_seqs(&r), vec![0, 1, 2, 1, 2, 1, 2, 4]);
    // every repeat is flown: reached where its waypoint is (a loop that turns
    // back on itself stops at each point rather than cutting it)
    let at = |seq: u16| match seq {
        1 => Vector3::new(10.0, 0.0, -8.0),
        2 => Vector3::new(10.0, 10.0, -8.0),
        _ => Vector3::new(0.0, 0.0, -8.0),
    };
    for x in &r[1..] {
        let off = (x.2 - at(x.0)).norm();
        assert!(off < 3.5, "item {} reached {off:.2} m away at {:.2} s", x.0, x.1);
    }
}

#[test]
fn do_change_speed_sets_the_cruise_speed_of_the_legs_after_it() {
    let mut v = vehicle();
    let items = vec![
        wp(0.0, 0.0, 10.0, 0.0, 0.0),
        item(cmd::DO_CHANGE_SPEED, [1.0, 2.0, -1.0, 0.0]),
        wp(60.0, 0.0, 10.0, 0.0, 0.0),
        item(cmd::DO_CHANGE_SPEED, [1.0, 9.0, -1.0, 0.0]),
        wp(60.0, 80.0, 10.0, 1.0, 0.0),
    ];
    upload(&mut v, items).unwrap();
    ready(&mut v);
    v.command(AutopilotCommand::StartMission { first: Some(0) });
    let mut top = [0.0_f64; 5];
    let n = (200.0 / v.dt_s()) as usize;
    for _ in 0..n {
        v.step();
        let t = v.telemetry();
        let seq = usize::from(t.mission.seq);
        top[seq] = top[seq].max(t.velocity_ned.xy().norm());
        if t.mission.state == MissionState::Complete {
            break;
        }
    }
    println!("top speed per current item: {top:.2?}");
    assert!((top[2] - 2.0).abs() < 0.15, "leg at 2 m/s flew {:.2}", top[2]);
    assert!((top[4] - 9.0).abs() < 0.3, "leg at 9 m/s flew {:.2}", top[4]);
}

#[test]
fn an_rtl_item_ends_the_mission_and_returns_home_to_land_and_disarm() {
    let mut v = vehicle();
    let mut items = vec![wp(0.0, 0.0, 10.0, 0.0, 0.0), wp(20.0, 10.0, 10.0, 0.0, 0.0)];
    let mut rtl = item(cmd::NAV_RETURN_TO_LAUNCH, [f32::NAN; 4]);
    rtl.z = 0.0;
    items.push(rtl);
    upload(&mut v, items).unwrap();
    ready(&mut v);
    v.command(AutopilotCommand::StartMission { first: Some(0) });
    let (ok, _) = fly(&mut v, 100.0, |t| t.mission.state == MissionState::Complete);
    assert!(ok);
    assert_eq!(v.telemetry().mode, FlightMode::ReturnToLaunch);
    let (ok, _) = fly(&mut v, 200.0, |t| !t.armed);
    assert!(ok, "never landed and disarmed");
    let t = v.telemetry();
    assert!(t.position_ned.xy().norm() < 1.0, "landed at {:?}", t.position_ned);
    assert_eq!(t.mission.state, MissionState::Complete);
}

#[test]
fn takeoff_then_land_items_land_at_the_point_and_disarm() {
    let mut v = vehicle();
    let g = HOME.offset(&Vector3::new(15.0, -5.0, 0.0));
    let mut takeoff = wp(0.0, 0.0, 6.0, 0.0, 0.0);
    takeoff.command = cmd::NAV_TAKEOFF;
    takeoff.params = [f32::NAN; 4];
    let mut land = wp(0.0, 0.0, 0.0, 0.0, 0.0);
    land.command = cmd::NAV_LAND;
    land.params = [f32::NAN; 4];
    (land.x, land.y) = (g.lat_deg, g.lon_deg);
    upload(&mut v, vec![takeoff, land]).unwrap();
    ready(&mut v);
    v.command(AutopilotCommand::StartMission { first: Some(0) });
    let mut top = 0.0_f64;
    let (ok, r) = fly(&mut v, 120.0, |t| {
        top = top.max(-t.position_ned.z);
        !t.armed
    });
    assert!(ok, "never disarmed");
    assert_eq!(reached_seqs(&r), vec![0, 1]);
    assert!((top - 6.0).abs() < 0.5, "took off to {top:.2} m");
    let t = v.telemetry();
    assert!(
        (t.position_ned.xy() - Vector3::new(15.0, -5.0, 0.0).xy()).norm() < 0.5,
        "landed at {:?}",
        t.position_ned
    );
    assert_eq!(t.landed, LandedState::OnGround);
}

#[test]
fn loiter_time_and_delay_wait_in_simulated_time() {
    let mut v = vehicle();
    let mut loiter = wp(10.0, 0.0, 8.0, 0.0, 0.0);
    loiter.command = cmd::NAV_LOITER_TIME;
    loiter.params = [4.0, 0.0, 0.0, f32::NAN];
    let mut delay = item(cmd::NAV_DELAY, [3.0, -1.0, -1.0, -1.0]);
    delay.z = 0.0;
    upload(
        &mut v,
        vec![wp(0.0, 0.0, 8.0, 0.0, 0.0), loiter, delay, wp(0.0, 0.0, 8.0, 0.5, 0.0)],
    )
    .unwrap();
    ready(&mut v);
    v.command(AutopilotCommand::StartMission { first: Some(0) });
    let (ok, r) = fly(&mut v, 120.0, |t| t.mission.state == MissionState::Complete);
    assert!(ok);
    assert_eq!(reached_seqs(&r), vec![0, 1, 2, 3]);
    // reached 1 at arrival, then 4 s of loiter, then the delay's 3 s before 2 counts
    let (t1, t2) = (r[1].1, r[2].1);
    assert!((t2 - t1 - 7.0).abs() < 0.01, "loiter + delay took {:.3} s", t2 - t1);
}

#[test]
fn refusals_leave_the_stored_mission_and_the_vehicle_unchanged() {
    let mut v = vehicle();
    ready(&mut v);
    // no mission
    assert!(matches!(
        v.command(AutopilotCommand::StartMission { first: Some(0) }),
        CommandOutcome::Denied(_)
    ));
    assert!(matches!(
        v.command(AutopilotCommand::SetMode(FlightMode::Mission)),
        CommandOutcome::TemporarilyRejected(_)
    ));
    assert_eq!(v.telemetry().mission.state, MissionState::NoMission);
    let id = upload(&mut v, square()).unwrap();
    let before = v.pilot().plans().clone();
    let mut bad = square();
    bad[2].x = 91.0;
    assert_eq!(upload(&mut v, bad), Err(MissionResult::InvalidParam5X));
    let mut bad = square();
    bad[1].z = f32::NAN;
    assert_eq!(upload(&mut v, bad), Err(MissionResult::InvalidParam7));
    let mut bad = square();
    bad[1].frame = 1;
    assert_eq!(upload(&mut v, bad), Err(MissionResult::UnsupportedFrame));
    let mut bad = square();
    bad[1].command = 5001;
    assert_eq!(upload(&mut v, bad), Err(MissionResult::Unsupported));
    let too_many = vec![wp(0.0, 0.0, 5.0, 0.0, 0.0); rotorpilot::mission::MAX_ITEMS + 1];
    assert_eq!(upload(&mut v, too_many), Err(MissionResult::NoSpace));
    let stale = v.core_mut().change_plans(
        0,
        PlanChange::Store {
            kind: MissionType::Mission,
            items: vec![wp(0.0, 0.0, 5.0, 0.0, 0.0)],
            base_id: Some(id ^ 1),
        },
    );
    assert_eq!(stale, Err(MissionResult::Denied));
    assert_eq!(v.pilot().plans(), &before);
    assert!(matches!(
        v.command(AutopilotCommand::StartMission { first: Some(4) }),
        CommandOutcome::Denied(_)
    ));
    assert!(!v.pilot().armed());
    assert_eq!(v.telemetry().mission.state, MissionState::NotStarted);
}

#[test]
fn a_mission_cleared_in_flight_gives_way_to_hold() {
    let mut v = vehicle();
    upload(&mut v, square()).unwrap();
    ready(&mut v);
    v.command(AutopilotCommand::StartMission { first: Some(0) });
    fly(&mut v, 100.0, |t| t.mission.seq == 2);
    assert_eq!(v.core_mut().change_plans(0, PlanChange::Clear(None)), Ok(0));
    let t = v.telemetry();
    assert_eq!(
        (t.mode, t.mission.state, t.mission.total),
        (FlightMode::Hold, MissionState::NoMission, 0)
    );
}

#[test]
fn the_same_mission_flies_bit_identically_twice() {
    let run = || {
        let mut v = vehicle();
        upload(&mut v, square()).unwrap();
        ready(&mut v);
        v.command(AutopilotCommand::StartMission { first: Some(0) });
        fly(&mut v, 100.0, |t| t.mission.state == MissionState::Complete);
        let t = v.telemetry();
        (t.time_s.to_bits(), t.position_ned.map(f64::to_bits))
    };
    assert_eq!(run(), run());
}

#[test]
fn rtl_lands_at_a_rally_point_closer_than_home() {
    let mut v = vehicle();
    let mut rally = wp(40.0, 5.0, 0.0, 0.0, 0.0);
    rally.command = cmd::RALLY_POINT;
    rally.params = [0.0; 4];
    let mut far = wp(-200.0, 0.0, 0.0, 0.0, 0.0);
    far.command = cmd::RALLY_POINT;
    far.params = [0.0; 4];
    v.core_mut()
        .change_plans(
            0,
            PlanChange::Store {
                kind: MissionType::Rally,
                items: vec![far, rally],
                base_id: None,
            },
        )
        .unwrap();
    let mut rtl = item(cmd::NAV_RETURN_TO_LAUNCH, [f32::NAN; 4]);
    rtl.z = 0.0;
    upload(&mut v, vec![wp(45.0, 0.0, 10.0, 0.0, 0.0), rtl]).unwrap();
    ready(&mut v);
    v.command(AutopilotCommand::StartMission { first: Some(0) });
    let (ok, _) = fly(&mut v, 300.0, |t| !t.armed && t.mission.state == MissionState::Complete);
    assert!(ok, "never landed");
    let p = v.telemetry().position_ned;
    assert!(
        (p.xy() - Vector3::new(40.0, 5.0, 0.0).xy()).norm() < 1.0,
        "landed at {p:?}, not the rally point"
    );
}

/// GIVEN RP_ALT_MAX_AMSL (9,000 m by default)
/// WHEN a plan holds a waypoint above it (relative to home or AMSL)
/// THEN the whole plan is refused with MAV_MISSION_INVALID_PARAM7 and a
/// critical text naming the item, and the stored mission is unchanged; the
/// same waypoint just below the ceiling is stored.
#[test]
fn a_plan_with_a_point_above_rp_alt_max_amsl_is_refused_whole() {
    let mut v = vehicle();
    v.step();
    let home_alt = v.telemetry().home.alt_amsl_m;
    let before = v.core_mut().snapshot(0).plans;
    let high = 9_001.0; // m AMSL
    let mut square_high = square();
    square_high[2].z = (high - home_alt) as f32; // a relative frame
    assert_eq!(upload(&mut v, square_high), Err(MissionResult::InvalidParam7));
    let texts = v.texts();
    assert!(
        texts
            .iter()
            .any(|t| t.text.starts_with("Plan rejected: item 2 at 9001 m")),
        "{texts:?}"
    );
    assert_eq!(v.core_mut().snapshot(0).plans, before, "nothing stored");
    let mut square_ok = square();
    square_ok[2].z = (8_990.0 - home_alt) as f32;
    assert!(upload(&mut v, square_ok).is_ok());
}
