//! Lockstep tests of PX4's failsafes: data-link (GCS) loss, low battery,
//! geofence (polygons and circles, inclusion and exclusion, distance and
//! altitude limits) and the maximum altitude of targets. Each failsafe is
//! triggered in flight, its action checked (mode, where it goes, landing and
//! disarming), the time from the breach or threshold to the action measured
//! and printed, and the announcement checked. One vehicle in the lockstep
//! core; `cargo test --release --test lockstep_failsafes -- --nocapture` prints the figures.

mod common;

use common::sitl::{HOME, Sitl, int, point, real};
use nalgebra::Vector3;
use rotorpilot::autopilot::{
    AutopilotCommand, BatteryWarning, ClientClock, ClientTimer, CommandOutcome, FlightMode, MissionState,
    OffboardSetpoint, Severity, Targets, Telemetry,
};
use rotorpilot::geo::GeoPoint;
use rotorpilot::mission::{MissionItem, MissionType, PlanChange};
use rotorpilot::params::ParamValue;

/// `COM_FAIL_ACT_T` 0: a failsafe acts at the instant of its cause, for the
/// tests of the causes and actions (the delay's own tests are at the end).
fn at_once() -> (&'static str, ParamValue) {
    ("COM_FAIL_ACT_T", real(0.0))
}

/// The quad with `params`, on the ground at home.
fn vehicle(params: &[(&str, ParamValue)]) -> Sitl {
    Sitl::quad().params(params).build()
}

/// Arm and take off to `up` m above home; hold there.
fn take_off_to(ap: &mut Sitl, up: f64) {
    ap.run(0.2);
    ap.take_off_to(Some(up));
    ap.run(1.0);
}

fn reposition(ap: &mut Sitl, north: f64, east: f64, up: f64) -> CommandOutcome {
    let g = point(north, east, up);
    ap.command(AutopilotCommand::Reposition {
        lat_deg: Some(g.lat_deg),
        lon_deg: Some(g.lon_deg),
        alt_amsl_m: Some(g.alt_amsl_m),
        yaw_rad: None,
        speed_m_s: None,
    })
}

fn offboard_velocity(ap: &mut Sitl, v_ned: Vector3<f64>) {
    let out = ap.command(AutopilotCommand::Offboard(OffboardSetpoint::Local(Targets {
        position: None,
        velocity: Some(v_ned),
        acceleration: None,
        yaw_rad: Some(0.0),
        yaw_rate_rad_s: None,
    })));
    assert_eq!(out, CommandOutcome::Accepted);
}

/// Stream the offboard velocity `v_ned` at 20 Hz (entering Offboard)
/// until the mode leaves Offboard or `max_s` passes.
fn fly_offboard_velocity(ap: &mut Sitl, v_ned: Vector3<f64>, max_s: f64) {
    offboard_velocity(ap, v_ned);
    assert_eq!(
        ap.command(AutopilotCommand::SetMode(FlightMode::Offboard)),
        CommandOutcome::Accepted
    );
    let t0 = ap.time_s();
    while ap.mode() == FlightMode::Offboard && ap.time_s() - t0 < max_s {
        ap.run(0.05);
        offboard_velocity(ap, v_ned);
    }
}

fn land_and_disarm(ap: &mut Sitl, max_s: f64) -> Telemetry {
    ap.run_until(max_s, |t| !t.armed).expect("lands and disarms");
    ap.telemetry()
}

fn fence_item(command: u16, p1: f32, north: f64, east: f64) -> MissionItem {
    let g = point(north, east, 0.0);
    MissionItem {
        frame: 0,
        command,
        autocontinue: true,
        params: [p1, 0.0, 0.0, 0.0],
        x: rotorpilot::mission::quantise_deg(g.lat_deg),
        y: rotorpilot::mission::quantise_deg(g.lon_deg),
        z: 0.0,
    }
}

fn polygon(command: u16, corners: &[(f64, f64)]) -> Vec<MissionItem> {
    corners
        .iter()
        .map(|(n, e)| fence_item(command, corners.len() as f32, *n, *e))
        .collect()
}

/// Store a mission of waypoints 15 m above home at `(north, east)` [m]
/// (MAV_FRAME_GLOBAL_RELATIVE_ALT, 2 m acceptance radius).
fn store_mission_at_15_m(ap: &mut Sitl, points: &[(f64, f64)]) {
    let items = points
        .iter()
        .map(|&(north, east)| {
            let g = point(north, east, 15.0);
            MissionItem {
                frame: 3, // MAV_FRAME_GLOBAL_RELATIVE_ALT
                command: 16,
                autocontinue: true,
                params: [0.0, 2.0, 0.0, f32::NAN],
                x: rotorpilot::mission::quantise_deg(g.lat_deg),
                y: rotorpilot::mission::quantise_deg(g.lon_deg),
                z: 15.0,
            }
        })
        .collect();
    store_plan(ap, MissionType::Mission, items);
}

/// Store `items` as the vehicle's plan of `kind` (as a complete upload does).
fn store_plan(ap: &mut Sitl, kind: MissionType, items: Vec<MissionItem>) {
    ap.core_mut()
        .change_plans(
            0,
            PlanChange::Store {
                kind,
                items,
                base_id: None,
            },
        )
        .expect("plan stored");
}

// ----- data-link loss ------------------------------------------------------------------------

#[test]
fn data_link_loss_returns_lands_and_is_regained() {
    let mut ap = vehicle(&[("NAV_DLL_ACT", int(2)), ("RTL_RETURN_ALT", real(15.0)), at_once()]);
    ap.heartbeat();
    take_off_to(&mut ap, 5.0);
    reposition(&mut ap, 20.0, 0.0, 5.0);
    // a GCS at 1 Hz for 10 s, then silence
    for _ in 0..10 {
        ap.run(1.0);
        ap.heartbeat();
    }
    let last = ap.time_s();
    assert_eq!(ap.mode(), FlightMode::Hold, "no loss while heartbeats arrive");
    let at = ap
        .run_until(20.0, |t| t.mode == FlightMode::ReturnToLaunch)
        .expect("data-link loss starts RTL");
    let delay = at - last;
    println!("data link: last GCS heartbeat {last:.3} s, RTL at {at:.3} s: {delay:.3} s (COM_DL_LOSS_T 10 s)");
    assert!((delay - 10.0).abs() <= 2e-3, "RTL {delay} s after the last heartbeat");
    assert_eq!(ap.count("Connection to ground station lost"), 1);
    assert_eq!(
        ap.severity_of("Connection to ground station lost"),
        Some(Severity::Critical)
    );
    assert_eq!(ap.count("Failsafe: GCS connection lost, triggering Return"), 1);
    // the link comes back during the return: announced, the return goes on
    ap.run(2.0);
    ap.heartbeat();
    assert_eq!(ap.count("Data link regained"), 1);
    assert_eq!(ap.mode(), FlightMode::ReturnToLaunch);
    let t = land_and_disarm(&mut ap, 120.0);
    let off = t.position_ned.xy().norm();
    println!("data link: landed {off:.2} m from home at {:.1} s", t.time_s);
    assert!(off < 1.0, "landed {off} m from home");
}

#[test]
fn data_link_loss_never_without_a_gcs_and_no_action_when_disabled() {
    // NAV_DLL_ACT = Return, but no GCS ever: nothing happens
    let mut ap = vehicle(&[("NAV_DLL_ACT", int(2))]);
    take_off_to(&mut ap, 3.0);
    ap.run(25.0);
    assert_eq!(ap.mode(), FlightMode::Hold);
    assert_eq!(ap.count("ground station"), 0);
    // a GCS that goes silent with PX4's default NAV_DLL_ACT = 0: announced, no mode change
    let mut ap = vehicle(&[]);
    ap.heartbeat();
    take_off_to(&mut ap, 3.0);
    ap.run(15.0);
    assert_eq!(ap.count("Connection to ground station lost"), 1);
    assert_eq!(ap.count("Failsafe"), 0);
    assert_eq!(ap.mode(), FlightMode::Hold);
    assert!(ap.armed());
}

/// GIVEN a quad at 20 m landing for a lost data link (NAV_DLL_ACT 3, Land)
/// WHEN the pilot switches to Hold (PX4's user takeover: accepted, Hold
/// flown, no failsafe in force) and then the GPS fix is lost for 2 s
/// THEN while the link is still lost the Land failsafe is in force again
/// (PX4 keeps the action while its cause lasts; the position loss ends the
/// takeover and the most severe action wins): Descend, then Land when the
/// fix returns, not Hold. With the link regained before the fix is lost,
/// the failsafe is over: Descend gives way to the pilot's Hold.
#[test]
fn a_land_failsafe_taken_over_comes_back_with_a_position_loss_while_its_cause_lasts() {
    for link_back in [false, true] {
        let mut ap = vehicle(&[("NAV_DLL_ACT", int(3)), at_once()]);
        take_off_to(&mut ap, 20.0);
        ap.heartbeat();
        ap.run_until(15.0, |t| t.mode == FlightMode::Land)
            .unwrap_or_else(|| panic!("the lost link lands: {:?} {:?}", ap.mode(), ap.texts()));
        assert!(
            ap.pilot()
                .failsafe_in_force()
                .is_some_and(|f| f.cause == "GCS connection lost")
        );
        assert_eq!(
            ap.command(AutopilotCommand::SetMode(FlightMode::Hold)),
            CommandOutcome::Accepted
        );
        assert_eq!(ap.mode(), FlightMode::Hold);
        assert!(ap.pilot().failsafe_in_force().is_none(), "taken over");
        ap.run(1.0);
        if link_back {
            ap.heartbeat();
        }
        ap.gps(false);
        ap.run(2.0);
        assert_eq!(ap.mode(), FlightMode::Descend);
        let cause = ap.pilot().failsafe_in_force().map(|f| f.cause.clone());
        ap.gps(true);
        ap.run(1.0);
        if link_back {
            assert_eq!(cause.as_deref(), Some("no GPS fix"));
            assert_eq!(ap.mode(), FlightMode::Hold);
            assert!(ap.pilot().failsafe_in_force().is_none());
            assert_eq!(ap.count("Failsafe: GCS connection lost, triggering Descend"), 0);
        } else {
            assert_eq!(cause.as_deref(), Some("GCS connection lost"));
            assert_eq!(ap.count("Failsafe: GCS connection lost, triggering Descend"), 1);
            assert_eq!(ap.mode(), FlightMode::Land);
            assert!(
                ap.pilot()
                    .failsafe_in_force()
                    .is_some_and(|f| f.cause == "GCS connection lost")
            );
            land_and_disarm(&mut ap, 60.0);
        }
    }
}

#[test]
fn data_link_loss_on_the_wall_clock_acts_on_the_runtime_timeout() {
    let mut ap = vehicle(&[("NAV_DLL_ACT", int(3)), at_once()]);
    ap.pilot_mut().set_client_clock(ClientClock::Wall);
    ap.heartbeat();
    let heard = ap.time_s();
    take_off_to(&mut ap, 3.0);
    ap.run(10.0);
    // long past COM_DL_LOSS_T in simulated time: on the wall clock only the runtime decides
    assert!(ap.time_s() - heard > 10.0);
    assert_eq!(ap.mode(), FlightMode::Hold);
    let pending = ap.pilot().client_timers();
    let timer = pending
        .iter()
        .find(|p| p.timer == ClientTimer::DataLinkLoss)
        .expect("the data-link timer is pending while armed");
    assert_eq!(timer.started_s, heard);
    assert_eq!(timer.duration_s, 10.0);
    // a stale timer (an older heartbeat) is ignored; the live one acts
    assert!(!ap.core_mut().client_timeout(0, ClientTimer::DataLinkLoss, heard - 1.0));
    assert!(ap.core_mut().client_timeout(0, ClientTimer::DataLinkLoss, heard));
    assert_eq!(ap.mode(), FlightMode::Land);
    assert!(
        ap.pilot()
            .client_timers()
            .iter()
            .all(|p| p.timer != ClientTimer::DataLinkLoss)
    );
}

// ----- battery -------------------------------------------------------------------------------

/// A 100 mAh pack (BAT1_CAPACITY's minimum) that may drain to empty: about 22 s of hover.
fn small_pack() -> Vec<(&'static str, ParamValue)> {
    vec![("BAT1_CAPACITY", real(100.0)), ("SIM_BAT_MIN_PCT", real(0.0))]
}

#[test]
fn battery_drains_in_flight_through_each_threshold_return_then_land() {
    let mut params = small_pack();
    params.push(("COM_LOW_BAT_ACT", int(3)));
    params.push(("RTL_RETURN_ALT", real(8.0)));
    params.push(at_once());
    let mut ap = vehicle(&params);
    take_off_to(&mut ap, 5.0);
    assert_eq!(ap.telemetry().battery_warning, BatteryWarning::None);
    // fly away so that the return has somewhere to go
    assert_eq!(reposition(&mut ap, 10.0, 0.0, 5.0), CommandOutcome::Accepted);
    let mut crossed: Vec<(BatteryWarning, f64, f64, FlightMode)> = Vec::new();
    let thresholds = [
        (0.15, BatteryWarning::Low),
        (0.07, BatteryWarning::Critical),
        (0.05, BatteryWarning::Emergency),
    ];
    let mut level = BatteryWarning::None;
    let mut below_at = [None; 3];
    for _ in 0..ap.steps(60.0) {
        ap.step();
        let t = ap.telemetry();
        for (k, (thr, _)) in thresholds.iter().enumerate() {
            if below_at[k].is_none() && t.battery_remaining < *thr {
                below_at[k] = Some(t.time_s);
            }
        }
        if t.battery_warning != level {
            level = t.battery_warning;
            crossed.push((level, t.time_s, t.battery_remaining, t.mode));
        }
        if level == BatteryWarning::Emergency {
            break;
        }
    }
    for ((w, at, soc, mode), below) in crossed.iter().zip(below_at) {
        let below = below.expect("the charge crossed the threshold");
        println!(
            "battery: {w:?} at {at:.3} s (charge {soc:.4}, below the threshold at {below:.3} s: {:.3} s), mode {mode:?}",
            at - below
        );
        assert!(
            (at - below).abs() < 1.5e-3,
            "{w:?} acted {} s after the threshold",
            at - below
        );
    }
    let levels: Vec<_> = crossed.iter().map(|c| (c.0, c.3)).collect();
    assert_eq!(
        levels,
        [
            (BatteryWarning::Low, FlightMode::Hold),
            (BatteryWarning::Critical, FlightMode::ReturnToLaunch),
            (BatteryWarning::Emergency, FlightMode::Land),
        ]
    );
    assert_eq!(
        ap.severity_of("Low battery level, return advised"),
        Some(Severity::Warning)
    );
    assert_eq!(
        ap.severity_of("Critical battery level, land now"),
        Some(Severity::Critical)
    );
    assert_eq!(
        ap.severity_of("Emergency battery level, land immediately"),
        Some(Severity::Emergency)
    );
    assert_eq!(ap.count("Failsafe: battery critical, triggering Return"), 1);
    assert_eq!(ap.count("Failsafe: battery emergency, triggering Land"), 1);
    let t = land_and_disarm(&mut ap, 60.0);
    println!(
        "battery: landed and disarmed at {:.1} s, charge {:.3}, warning {:?}",
        t.time_s, t.battery_remaining, t.battery_warning
    );
    assert_eq!(t.battery_warning, BatteryWarning::Emergency, "never de-escalates");
}

#[test]
fn battery_critical_lands_with_com_low_bat_act_2_and_only_warns_by_default() {
    let mut params = small_pack();
    params.push(("COM_LOW_BAT_ACT", int(2)));
    params.push(at_once());
    let mut ap = vehicle(&params);
    take_off_to(&mut ap, 4.0);
    let at = ap
        .run_until(40.0, |t| t.battery_warning == BatteryWarning::Critical)
        .expect("critical");
    assert_eq!(ap.mode(), FlightMode::Land, "land at critical ({at:.2} s)");
    land_and_disarm(&mut ap, 60.0);
    // PX4's default COM_LOW_BAT_ACT = 0: warnings only, the vehicle keeps holding
    let mut ap = vehicle(&small_pack());
    take_off_to(&mut ap, 4.0);
    ap.run_until(40.0, |t| t.battery_warning == BatteryWarning::Emergency)
        .expect("emergency");
    assert_eq!(ap.mode(), FlightMode::Hold);
    assert_eq!(ap.count("Critical battery level, land now"), 1);
    assert_eq!(ap.count("Failsafe"), 0);
}

// ----- geofence ------------------------------------------------------------------------------

/// Inclusion: a 40 m square around home and a 15 m circle 60 m east;
/// exclusion: a square 10..15 m north and a 4 m circle 12 m south.
fn fence() -> Vec<MissionItem> {
    let mut items = polygon(5001, &[(-20.0, -20.0), (20.0, -20.0), (20.0, 20.0), (-20.0, 20.0)]);
    items.push(fence_item(5003, 15.0, 0.0, 60.0));
    items.extend(polygon(5002, &[(10.0, -5.0), (15.0, -5.0), (15.0, 5.0), (10.0, 5.0)]));
    items.push(fence_item(5004, 4.0, -12.0, 0.0));
    items
}

fn store_fence(ap: &mut Sitl, items: Vec<MissionItem>) {
    store_plan(ap, MissionType::Fence, items);
}

#[test]
fn geofence_zones_hold_once_per_breach_and_rearm_inside() {
    let mut ap = vehicle(&[]);
    store_fence(&mut ap, fence());
    take_off_to(&mut ap, 5.0);
    // a target outside every inclusion zone: accepted and ignored, as PX4's
    // navigator ignores it; the vehicle holds where it is
    let before = ap.telemetry().position_ned;
    assert_eq!(reposition(&mut ap, 30.0, 0.0, 5.0), CommandOutcome::Accepted);
    assert_eq!(ap.count("Reposition is outside geofence"), 1);
    ap.run(3.0);
    assert_eq!(ap.mode(), FlightMode::Hold);
    assert!((ap.telemetry().position_ned - before).norm() < 0.5, "stayed");
    // inside the far inclusion circle: accepted, but the way there leaves the fence
    assert_eq!(reposition(&mut ap, 0.0, 60.0, 5.0), CommandOutcome::Accepted);
    let (mut crossed, mut acted) = (None, None);
    for _ in 0..ap.steps(30.0) {
        ap.step();
        let t = ap.telemetry();
        if crossed.is_none() && t.position_ned.y > 20.0 {
            crossed = Some(t.time_s);
        }
        if ap.count("Geofence breached") > 0 {
            acted = Some(t.time_s);
            break;
        }
    }
    let (crossed, at) = (crossed.expect("left the square"), acted.expect("breach announced"));
    // the telemetry after a step shows the next sample: one step is the sampling itself
    println!(
        "geofence: left the inclusion square at {crossed:.3} s, breach acted at {at:.3} s ({:.3} s)",
        at - crossed
    );
    assert!(at - crossed < 1.5e-3);
    assert_eq!(ap.mode(), FlightMode::Hold);
    assert_eq!(ap.count("Geofence breached: outside geofence"), 1);
    assert_eq!(ap.count("Failsafe: geofence breach, triggering Hold"), 1);
    ap.run(6.0);
    let t = ap.telemetry();
    println!("geofence: stopped {:.2} m beyond the fence", t.position_ned.y - 20.0);
    assert!(
        t.velocity_ned.norm() < 0.2 && t.position_ned.y < 25.0,
        "stopped near the border: {t:?}"
    );
    assert_eq!(ap.count("Failsafe: geofence breach"), 1, "one action per breach");
    // back inside re-arms it; into the exclusion square by offboard velocity: the second breach
    assert_eq!(reposition(&mut ap, 0.0, 0.0, 5.0), CommandOutcome::Accepted);
    ap.run_until(30.0, |t| {
        t.position_ned.xy().norm() < 0.3 && t.velocity_ned.norm() < 0.1
    })
    .expect("back home");
    fly_offboard_velocity(&mut ap, Vector3::new(2.0, 0.0, 0.0), 15.0);
    let t = ap.telemetry();
    assert_eq!(t.mode, FlightMode::Hold);
    assert_eq!(ap.count("Geofence breached: inside exclusion zone"), 1);
    assert_eq!(ap.count("Failsafe: geofence breach, triggering Hold"), 2);
    println!(
        "geofence: exclusion square entered, Hold at {:.2} m north",
        t.position_ned.x
    );
    assert!(
        t.position_ned.x >= 10.0 && t.position_ned.x < 10.2,
        "held at its edge: {}",
        t.position_ned.x
    );
    // a target in the exclusion circle is ignored too (announced a second time)
    assert_eq!(reposition(&mut ap, -12.0, 0.0, 5.0), CommandOutcome::Accepted);
    assert_eq!(ap.count("Reposition is outside geofence"), 2);
    ap.run(2.0);
    assert!(
        ap.telemetry().position_ned.x >= 9.5,
        "stayed: {}",
        ap.telemetry().position_ned.x
    );
}

#[test]
fn geofence_max_distance_returns_and_lands() {
    let mut ap = vehicle(&[
        ("GF_ACTION", int(3)),
        ("GF_MAX_HOR_DIST", real(15.0)),
        ("RTL_RETURN_ALT", real(8.0)),
        at_once(),
    ]);
    take_off_to(&mut ap, 5.0);
    let t0 = ap.time_s();
    fly_offboard_velocity(&mut ap, Vector3::new(0.0, 3.0, 0.0), 20.0);
    let t = ap.telemetry();
    assert_eq!(t.mode, FlightMode::ReturnToLaunch);
    let d = t.position_ned.xy().norm();
    println!(
        "geofence: max distance 15 m breached at {d:.3} m, {:.2} s after leaving",
        t.time_s - t0
    );
    assert!((15.0..15.2).contains(&d), "breach acted at {d} m");
    assert_eq!(ap.count("Geofence breached: max distance exceeded"), 1);
    assert_eq!(ap.count("Failsafe: geofence breach, triggering Return"), 1);
    let t = land_and_disarm(&mut ap, 90.0);
    assert!(t.position_ned.xy().norm() < 1.0, "landed at home: {:?}", t.position_ned);
}

/// Return from 50 m north with `fence` stored there (GF_ACTION 1: a breach
/// is only said), to the landing; the vehicle and the largest |east| [m]
/// flown, every position of the return checked against `forbidden` (north,
/// east).
fn return_with_fence(fence: Vec<MissionItem>, forbidden: impl Fn(f64, f64) -> bool) -> (Sitl, f64) {
    let mut ap = vehicle(&[("GF_ACTION", int(1)), ("RTL_RETURN_ALT", real(10.0))]);
    take_off_to(&mut ap, 10.0);
    assert_eq!(reposition(&mut ap, 50.0, 0.0, 10.0), CommandOutcome::Accepted);
    ap.run_until(40.0, |t| {
        (t.position_ned.xy() - nalgebra::Vector2::new(50.0, 0.0)).norm() < 0.3 && t.velocity_ned.norm() < 0.1
    })
    .expect("at 50 m north");
    store_fence(&mut ap, fence);
    assert_eq!(
        ap.command(AutopilotCommand::SetMode(FlightMode::ReturnToLaunch)),
        CommandOutcome::Accepted
    );
    let mut widest: f64 = 0.0;
    for _ in 0..ap.steps(120.0) {
        ap.step();
        let p = ap.telemetry().position_ned;
        assert!(!forbidden(p.x, p.y), "in the exclusion zone at {p:?}");
        widest = widest.max(p.y.abs());
        if !ap.armed() {
            break;
        }
    }
    assert!(!ap.armed(), "landed and disarmed");
    (ap, widest)
}

#[test]
fn return_flies_round_an_exclusion_zone_at_the_margin() {
    // a 10 m square across the straight line home, 20..30 m north
    let square = polygon(5002, &[(20.0, -5.0), (30.0, -5.0), (30.0, 5.0), (20.0, 5.0)]);
    let inside = |n: f64, e: f64| (20.0..=30.0).contains(&n) && (-5.0..=5.0).contains(&e);
    let (mut ap, widest) = return_with_fence(square, inside);
    // round one side, on the square grown by 2 NAV_ACC_RAD (4 m)
    println!("return round a fence: widest {widest:.2} m east or west (the zone's side 5 m, margin 4 m)");
    assert!((8.5..9.5).contains(&widest), "flew round at the margin: {widest}");
    assert_eq!(ap.count("RTL: avoiding geofence"), 1);
    assert_eq!(ap.count("Geofence breached"), 0);
    assert!(ap.telemetry().position_ned.xy().norm() < 1.0, "landed at home");
}

#[test]
fn return_without_a_way_round_flies_straight_and_says_so() {
    // home itself inside an exclusion zone: PX4 flies the straight line
    let around_home = polygon(5002, &[(-5.0, -5.0), (5.0, -5.0), (5.0, 5.0), (-5.0, 5.0)]);
    let (mut ap, widest) = return_with_fence(around_home, |_, _| false);
    assert!(widest < 0.5, "straight: {widest}");
    assert_eq!(ap.count("RTL destination breaches geofence, flying directly"), 1);
    assert_eq!(
        ap.severity_of("RTL: no geofence avoidance path; flying directly"),
        Some(Severity::Critical)
    );
    assert_eq!(ap.count("RTL: avoiding geofence"), 0);
}

// ----- maximum altitude ----------------------------------------------------------------------

#[test]
fn max_altitude_refuses_targets_clamps_offboard_and_holds_on_breach() {
    let mut ap = vehicle(&[("GF_MAX_VER_DIST", real(10.0))]);
    ap.run(0.2);
    let z0 = ap.telemetry().position_ned.z;
    assert_eq!(
        ap.command(AutopilotCommand::Arm { force: false }),
        CommandOutcome::Accepted
    );
    // takeoff above the limit: DENIED and announced, never flown
    let out = ap.command(AutopilotCommand::Takeoff {
        altitude_amsl_m: Some(HOME.alt_amsl_m + 15.0),
    });
    assert!(matches!(out, CommandOutcome::Denied(_)), "{out:?}");
    assert_eq!(
        ap.severity_of("Takeoff denied: above geofence max altitude"),
        Some(Severity::Critical)
    );
    ap.run(1.0);
    assert!(ap.telemetry().position_ned.z > z0 - 0.05, "did not climb");
    take_off_to(&mut ap, 8.0);
    // a reposition above it: accepted and ignored (PX4), no climb
    assert_eq!(reposition(&mut ap, 0.0, 0.0, 12.0), CommandOutcome::Accepted);
    assert_eq!(ap.count("Reposition is outside geofence"), 1);
    let z = ap.telemetry().position_ned.z;
    ap.run(3.0);
    assert!(ap.telemetry().position_ned.z > z - 0.3, "did not climb");
    // an offboard position above it: clamped to it, announced once
    let sp = |z: f64| {
        AutopilotCommand::Offboard(OffboardSetpoint::Local(Targets {
            position: Some(Vector3::new(0.0, 0.0, z)),
            velocity: None,
            acceleration: None,
            yaw_rad: Some(0.0),
            yaw_rate_rad_s: None,
        }))
    };
    assert_eq!(ap.command(sp(-20.0)), CommandOutcome::Accepted);
    assert_eq!(
        ap.command(AutopilotCommand::SetMode(FlightMode::Offboard)),
        CommandOutcome::Accepted
    );
    let mut highest: f64 = 0.0;
    for _ in 0..200 {
        ap.run(0.05);
        ap.command(sp(-20.0));
        // above home (where the vehicle rested), as GF_MAX_VER_DIST counts
        let t = ap.telemetry();
        highest = highest.max(t.home_ned.z - t.position_ned.z);
    }
    println!(
        "max altitude: offboard setpoint 20 m clamped to 10 m, highest {highest:.3} m, mode {:?}",
        ap.mode()
    );
    assert_eq!(ap.count("Offboard setpoint clamped to max altitude"), 1);
    assert!(highest < 10.1 && highest > 9.8, "flew to the limit: {highest}");
    // a climb by velocity crosses it: Hold at once
    if ap.mode() == FlightMode::Offboard {
        fly_offboard_velocity(&mut ap, Vector3::new(0.0, 0.0, -1.0), 10.0);
    }
    assert_eq!(ap.mode(), FlightMode::Hold);
    assert_eq!(ap.count("Geofence breached: max altitude exceeded"), 1);
    ap.run(4.0);
    let up = -ap.telemetry().position_ned.z;
    println!("max altitude: held at {up:.3} m after the breach");
    assert!(up < 10.5, "held near the limit: {up}");
}

// ----- interactions between failsafes (one runner) -------------------------------------------

#[test]
fn gps_lost_then_battery_critical_still_descends_blind() {
    // COM_LOW_BAT_ACT 1: Return at critical, which needs a position
    let mut params = small_pack();
    params.push(("COM_LOW_BAT_ACT", int(1)));
    let mut ap = vehicle(&params);
    take_off_to(&mut ap, 10.0);
    ap.run_until(60.0, |t| t.battery_warning >= BatteryWarning::Low)
        .expect("low");
    ap.gps(false);
    ap.run(0.1);
    assert_eq!(ap.mode(), FlightMode::Descend);
    let at = ap
        .run_until(20.0, |t| t.battery_warning >= BatteryWarning::Critical)
        .expect("critical");
    ap.run(0.1);
    println!(
        "GPS lost, then battery critical at {at:.2} s, {:.1} m up: {:?}",
        -ap.telemetry().position_ned.z,
        ap.mode()
    );
    assert!(ap.armed(), "critical before touchdown");
    assert_eq!(ap.mode(), FlightMode::Descend, "no Return on the drifting solution");
    assert_eq!(ap.count("triggering Return"), 0);
    assert!(matches!(
        ap.command(AutopilotCommand::SetMode(FlightMode::Hold)),
        CommandOutcome::TemporarilyRejected(_)
    ));
}

#[test]
fn no_geofence_breach_while_the_fix_is_lost() {
    let mut ap = vehicle(&[("GF_ACTION", int(3))]);
    take_off_to(&mut ap, 20.0);
    ap.gps(false);
    ap.run(0.1);
    assert_eq!(ap.mode(), FlightMode::Descend);
    // a fence that excludes where the vehicle is: not checked without a position
    store_fence(&mut ap, vec![fence_item(5004, 30.0, 0.0, 0.0)]);
    ap.run(2.0);
    assert_eq!(ap.count("Geofence breached"), 0);
    assert_eq!(ap.mode(), FlightMode::Descend);
    // with the fix back it is checked (the control: the test can fail)
    ap.gps(true);
    ap.run(0.5);
    assert_eq!(ap.count("Geofence breached"), 1);
}

#[test]
fn a_geofence_hold_does_not_interrupt_a_landing() {
    let mut ap = vehicle(&[("GF_ACTION", int(2))]);
    take_off_to(&mut ap, 10.0);
    assert_eq!(ap.command(AutopilotCommand::Land), CommandOutcome::Accepted);
    ap.run(1.0);
    assert_eq!(ap.mode(), FlightMode::Land);
    store_fence(&mut ap, vec![fence_item(5004, 30.0, 0.0, 0.0)]);
    ap.run(1.0);
    assert_eq!(ap.count("Geofence breached"), 1, "announced");
    assert_eq!(ap.count("triggering Hold"), 0);
    assert_eq!(ap.mode(), FlightMode::Land, "keeps landing");
    land_and_disarm(&mut ap, 40.0);
}

#[test]
fn fix_back_during_a_land_started_descend_keeps_landing() {
    let mut ap = vehicle(&[]);
    take_off_to(&mut ap, 20.0);
    assert_eq!(ap.command(AutopilotCommand::Land), CommandOutcome::Accepted);
    ap.run(1.0);
    ap.gps(false);
    ap.run(2.0);
    assert_eq!(ap.mode(), FlightMode::Descend);
    ap.gps(true);
    ap.run(0.1);
    assert_eq!(ap.mode(), FlightMode::Land, "the landing goes on with the position");
    assert_eq!(ap.count("GPS fix regained: landing"), 1);
    land_and_disarm(&mut ap, 60.0);
}

#[test]
fn a_mode_that_needs_a_position_entered_without_fix_is_corrected_and_mission_start_refused() {
    let mut ap = vehicle(&[]);
    take_off_to(&mut ap, 20.0);
    ap.gps(false);
    ap.run(0.1);
    assert_eq!(ap.mode(), FlightMode::Descend);
    // Return is refused; Offboard with a velocity setpoint too
    assert!(matches!(
        ap.command(AutopilotCommand::SetMode(FlightMode::ReturnToLaunch)),
        CommandOutcome::TemporarilyRejected(_)
    ));
    offboard_velocity(&mut ap, Vector3::zeros());
    assert!(matches!(
        ap.command(AutopilotCommand::SetMode(FlightMode::Offboard)),
        CommandOutcome::TemporarilyRejected(_)
    ));
    assert_eq!(ap.count("Switching to Offboard denied: no GPS fix"), 1);
    assert_eq!(ap.mode(), FlightMode::Descend);
}

#[test]
fn arming_is_refused_with_the_data_link_lost_and_nav_dll_act_set() {
    // the link is tracked disarmed: lost 10 s after the last GCS HEARTBEAT
    let mut ap = vehicle(&[("NAV_DLL_ACT", int(2))]);
    ap.heartbeat();
    ap.run(11.0);
    assert_eq!(ap.count("Connection to ground station lost"), 1);
    assert!(matches!(
        ap.command(AutopilotCommand::Arm { force: false }),
        CommandOutcome::TemporarilyRejected(_)
    ));
    assert_eq!(
        ap.count("Arming denied: no ground station connection"),
        1,
        "{:?}",
        ap.said()
    );
    // the link back: arming works and the loss does not fire at once
    ap.heartbeat();
    assert_eq!(ap.count("Data link regained"), 1);
    assert_eq!(
        ap.command(AutopilotCommand::Arm { force: false }),
        CommandOutcome::Accepted
    );
    ap.run(1.0);
    assert!(ap.armed());
    assert_eq!(ap.count("Failsafe"), 0);
    // NAV_DLL_ACT 0 (PX4's default): the lost link does not stop arming
    let mut ap = vehicle(&[]);
    ap.heartbeat();
    ap.run(11.0);
    assert_eq!(ap.count("Connection to ground station lost"), 1);
    assert_eq!(
        ap.command(AutopilotCommand::Arm { force: false }),
        CommandOutcome::Accepted
    );
}

#[test]
fn arming_is_refused_at_critical_battery() {
    // land at critical (COM_LOW_BAT_ACT 2), then try again on the ground
    let mut params = small_pack();
    params.push(("COM_LOW_BAT_ACT", int(2)));
    let mut ap = vehicle(&params);
    take_off_to(&mut ap, 4.0);
    ap.run_until(60.0, |t| t.battery_warning == BatteryWarning::Critical)
        .expect("critical");
    land_and_disarm(&mut ap, 60.0);
    ap.run(0.5);
    assert!(matches!(
        ap.command(AutopilotCommand::Arm { force: false }),
        CommandOutcome::TemporarilyRejected(_)
    ));
    assert_eq!(ap.count("Arming denied: battery critical"), 1);
}

#[test]
fn a_mission_outside_the_geofence_is_refused_at_start() {
    let mut ap = vehicle(&[("GF_MAX_VER_DIST", real(20.0))]);
    ap.run(0.2);
    let g = point(10.0, 0.0, 30.0);
    let wp = |command: u16, g: GeoPoint, up: f32| MissionItem {
        frame: 3, // MAV_FRAME_GLOBAL_RELATIVE_ALT
        command,
        autocontinue: true,
        params: [0.0, 0.0, 0.0, f32::NAN],
        x: rotorpilot::mission::quantise_deg(g.lat_deg),
        y: rotorpilot::mission::quantise_deg(g.lon_deg),
        z: up,
    };
    let store = |ap: &mut Sitl, items: Vec<MissionItem>| store_plan(ap, MissionType::Mission, items);
    // 30 m up, above GF_MAX_VER_DIST = 20 m: denied, announced, still disarmed
    store(&mut ap, vec![wp(22, HOME, 5.0), wp(16, g, 30.0)]);
    assert!(matches!(
        ap.command(AutopilotCommand::StartMission { first: None }),
        CommandOutcome::Denied(_)
    ));
    assert_eq!(ap.count("Mission start denied: item 1 outside geofence"), 1);
    assert!(!ap.armed());
    // the same point at 15 m starts
    store(&mut ap, vec![wp(22, HOME, 5.0), wp(16, g, 15.0)]);
    assert_eq!(
        ap.command(AutopilotCommand::StartMission { first: None }),
        CommandOutcome::Accepted
    );
    assert!(ap.armed());
}

/// GIVEN a mission under way, 40 m north then 40 m east at 15 m
/// WHEN the GNSS fix is lost on the first leg for 2 s and comes back
/// THEN the vehicle descends blind meanwhile (Descend, "No GPS fix:
/// descending without position"), and with the fix back flies the mission
/// on from the item it stood at ("GPS fix regained: resuming mission"), as
/// PX4 gives the pilot's mode back once its requirements hold again; the
/// mission completes.
#[test]
fn a_mission_interrupted_by_a_position_loss_resumes_when_it_returns() {
    let mut ap = vehicle(&[]);
    store_mission_at_15_m(&mut ap, &[(40.0, 0.0), (40.0, 40.0)]);
    take_off_to(&mut ap, 15.0);
    assert_eq!(
        ap.command(AutopilotCommand::StartMission { first: None }),
        CommandOutcome::Accepted
    );
    ap.run(4.0);
    assert_eq!(ap.mode(), FlightMode::Mission);
    ap.gps(false);
    ap.run(2.0);
    assert_eq!(ap.mode(), FlightMode::Descend, "{:?}", ap.said());
    ap.gps(true);
    ap.run_until(5.0, |t| t.mode != FlightMode::Descend)
        .unwrap_or_else(|| panic!("still descending: {:?}", ap.said()));
    assert_eq!(ap.mode(), FlightMode::Mission, "{:?}", ap.said());
    assert_eq!(ap.count("GPS fix regained: resuming mission"), 1, "{:?}", ap.said());
    assert!(ap.pilot().failsafe_in_force().is_none());
    ap.run_until(60.0, |t| t.mission.state == MissionState::Complete)
        .unwrap_or_else(|| panic!("mission not completed: {:?} {:?}", ap.mode(), ap.said()));
}

// ----- the failsafe delay (COM_FAIL_ACT_T) ----------------------------------------------------

/// A quad flying a mission north at 15 m with `NAV_DLL_ACT` Return and
/// `params`, a GCS heard for the first 5 s of the mission and then 9 s of
/// silence; returns it with the time of the last GCS HEARTBEAT [s].
fn mission_then_silence(params: &[(&str, ParamValue)]) -> (Sitl, f64) {
    let mut all = vec![("NAV_DLL_ACT", int(2))];
    all.extend_from_slice(params);
    let mut ap = vehicle(&all);
    store_mission_at_15_m(&mut ap, &[(300.0, 0.0)]);
    take_off_to(&mut ap, 15.0);
    assert_eq!(
        ap.command(AutopilotCommand::StartMission { first: None }),
        CommandOutcome::Accepted
    );
    for _ in 0..5 {
        ap.run(1.0);
        ap.heartbeat();
    }
    assert_eq!(ap.mode(), FlightMode::Mission);
    let last = ap.time_s();
    ap.run(9.0);
    assert_eq!(ap.mode(), FlightMode::Mission);
    (ap, last)
}

/// GIVEN a quad on a mission with `NAV_DLL_ACT` Return and PX4's default
/// `COM_FAIL_ACT_T` of 5 s
/// WHEN the data link is lost
/// THEN it holds first — Hold, the failsafe in force, "Failsafe: GCS
/// connection lost, Return in 5 s" — stops within a few metres, and returns
/// 5 s later ("... triggering Return"), as PX4's failsafe framework delays
/// an action the user may take over (`FailsafeBase::checkFailsafe`,
/// `getSelectedAction`).
#[test]
fn a_failsafe_holds_for_com_fail_act_t_before_it_returns() {
    let (mut ap, last) = mission_then_silence(&[]);
    let lost = ap
        .run_until(3.0, |t| t.mode != FlightMode::Mission)
        .expect("the data-link loss stops the mission");
    assert!(
        (lost - last - 10.0).abs() <= 2e-3,
        "left the mission {} s after the last heartbeat",
        lost - last
    );
    assert_eq!(ap.mode(), FlightMode::Hold, "{:?}", ap.said());
    let f = ap
        .pilot()
        .failsafe_in_force()
        .expect("a failsafe in force while it holds");
    assert_eq!((f.cause.as_str(), f.triggered), ("GCS connection lost", "Hold"));
    assert_eq!(
        ap.count("Failsafe: GCS connection lost, Return in 5 s"),
        1,
        "{:?}",
        ap.said()
    );
    assert_eq!(
        ap.severity_of("Failsafe: GCS connection lost, Return in 5 s"),
        Some(Severity::Critical)
    );
    assert!(ap.telemetry().failsafe);
    let stop = ap.telemetry().position_ned;
    let rtl = ap
        .run_until(10.0, |t| t.mode == FlightMode::ReturnToLaunch)
        .expect("returns after the delay");
    let t = ap.telemetry();
    let held = t.position_ned - stop;
    println!(
        "failsafe delay: Hold at {lost:.3} s, Return at {rtl:.3} s ({:.3} s); braked within {:.2} m, {:.3} m/s at the end",
        rtl - lost,
        held.norm(),
        t.velocity_ned.norm()
    );
    assert!((rtl - lost - 5.0).abs() <= 2e-3, "Return {} s after Hold", rtl - lost);
    // from the mission's 5 m/s: PX4's braking (MPC_ACC_HOR 3 m/s^2) stops within about 5 m
    assert!(held.norm() < 8.0, "moved {held} m while holding");
    assert!(
        t.velocity_ned.norm() < 0.3,
        "still moving at {} m/s",
        t.velocity_ned.norm()
    );
    assert_eq!(
        ap.count("Failsafe: GCS connection lost, triggering Return"),
        1,
        "{:?}",
        ap.said()
    );
    let f = ap.pilot().failsafe_in_force().expect("the return is the failsafe");
    assert_eq!(f.triggered, "Return");
}

/// GIVEN the same loss
/// WHEN the pilot selects Hold (the mode flown) 2 s into the delay, or
/// repositions 1 s into it
/// THEN the Return never comes and no failsafe is in force (PX4's user
/// takeover: a mode switch during the delay); and with `COM_FAIL_ACT_T` 0
/// the Return comes at once.
#[test]
fn selecting_a_mode_during_the_delay_takes_over_and_com_fail_act_t_0_acts_at_once() {
    let (mut ap, _) = mission_then_silence(&[]);
    ap.run_until(3.0, |t| t.mode != FlightMode::Mission).expect("holds");
    ap.run(2.0);
    assert_eq!(
        ap.command(AutopilotCommand::SetMode(FlightMode::Hold)),
        CommandOutcome::Accepted
    );
    assert!(ap.pilot().failsafe_in_force().is_none());
    ap.run(10.0);
    assert_eq!(ap.mode(), FlightMode::Hold, "{:?}", ap.said());
    assert_eq!(ap.count("triggering Return"), 0, "{:?}", ap.said());

    // a reposition during the delay takes over too (PX4: DO_REPOSITION changes the mode the user means)
    let (mut ap, _) = mission_then_silence(&[]);
    ap.run_until(3.0, |t| t.mode != FlightMode::Mission).expect("holds");
    ap.run(1.0);
    assert_eq!(reposition(&mut ap, 20.0, 20.0, 15.0), CommandOutcome::Accepted);
    assert!(ap.pilot().failsafe_in_force().is_none());
    ap.run(10.0);
    assert_eq!(ap.mode(), FlightMode::Hold, "{:?}", ap.said());
    assert_eq!(ap.count("triggering Return"), 0, "{:?}", ap.said());

    let (mut ap, last) = mission_then_silence(&[("COM_FAIL_ACT_T", real(0.0))]);
    let at = ap
        .run_until(3.0, |t| t.mode != FlightMode::Mission)
        .expect("the data-link loss stops the mission");
    assert!((at - last - 10.0).abs() <= 2e-3);
    assert_eq!(ap.mode(), FlightMode::ReturnToLaunch, "{:?}", ap.said());
    assert_eq!(ap.count(" in 5 s"), 0);
}

/// GIVEN a quad with a 100 mAh pack, `COM_LOW_BAT_ACT` 3 (Return at
/// critical, Land at emergency) and PX4's 5 s delay
/// WHEN the charge falls through critical, and half a second later through
/// emergency
/// THEN the critical Return holds first, the emergency's Land joins the
/// delay, and when it runs out the vehicle lands: one delay for all, the
/// most severe action after it (PX4's `FailsafeBase`).
#[test]
fn a_more_severe_failsafe_joins_the_delay_and_follows_it() {
    let mut params = small_pack();
    params.push(("COM_LOW_BAT_ACT", int(3)));
    let mut ap = vehicle(&params);
    take_off_to(&mut ap, 5.0);
    let critical = ap
        .run_until(40.0, |t| t.battery_warning == BatteryWarning::Critical)
        .expect("critical");
    assert_eq!(ap.mode(), FlightMode::Hold);
    assert_eq!(
        ap.count("Failsafe: battery critical, Return in 5 s"),
        1,
        "{:?}",
        ap.said()
    );
    let emergency = ap
        .run_until(3.0, |t| t.battery_warning == BatteryWarning::Emergency)
        .expect("emergency");
    assert_eq!(ap.mode(), FlightMode::Hold, "the Land joins the delay");
    assert_eq!(
        ap.count("Failsafe: battery emergency, Land in 5 s"),
        1,
        "{:?}",
        ap.said()
    );
    let landing = ap
        .run_until(6.0, |t| t.mode != FlightMode::Hold)
        .expect("acts when the delay runs out");
    println!(
        "battery: critical at {critical:.3} s, emergency at {emergency:.3} s, {:?} at {landing:.3} s",
        ap.mode()
    );
    assert_eq!(ap.mode(), FlightMode::Land, "{:?}", ap.said());
    assert!(
        (landing - critical - 5.0).abs() <= 2e-3,
        "acted {} s after critical",
        landing - critical
    );
    assert_eq!(
        ap.count("Failsafe: battery emergency, triggering Land"),
        1,
        "{:?}",
        ap.said()
    );
    assert_eq!(ap.count("triggering Return"), 0, "{:?}", ap.said());
}

/// GIVEN the client timers on the wall clock (a daemon above real time)
/// WHEN a data-link loss starts the failsafe delay
/// THEN the delay is a client timer (it waits for the pilot to take over):
/// simulated time alone never ends it, and the runtime's expiry does.
#[test]
fn the_failsafe_delay_runs_on_the_client_clock() {
    let (mut ap, _) = mission_then_silence(&[]);
    ap.run_until(3.0, |t| t.mode != FlightMode::Mission).expect("holds");
    let started = ap.time_s();
    ap.pilot_mut().set_client_clock(ClientClock::Wall);
    ap.run(20.0);
    assert_eq!(ap.mode(), FlightMode::Hold, "{:?}", ap.said());
    let timer = ap
        .pilot()
        .client_timers()
        .into_iter()
        .find(|p| p.timer == ClientTimer::FailsafeDelay)
        .expect("the delay is pending");
    assert!(
        (timer.started_s - started).abs() < 2e-3 && timer.duration_s == 5.0,
        "{timer:?}"
    );
    assert!(
        ap.core_mut()
            .client_timeout(0, ClientTimer::FailsafeDelay, timer.started_s)
    );
    assert_eq!(ap.mode(), FlightMode::ReturnToLaunch);
    assert_eq!(ap.count("Failsafe: GCS connection lost, triggering Return"), 1);
}
