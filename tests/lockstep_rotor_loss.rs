//! Rotor loss in the lockstep core: the world kills (or weakens) one rotor
//! (`World::inject`), the flight stack sees only its ESC speed, flags it,
//! reallocates over the rest and flies on — or lands, as `COM_ACT_FAIL_ACT`
//! says. Octo and the PPNNPN hexa, every single rotor, at hover, on a
//! figure-eight and on a mission; a degraded rotor; no false detection on
//! healthy flights. The figures are printed (`--nocapture`); the table of all
//! of them: `cargo test --release --test lockstep_rotor_loss -- --ignored --nocapture`.

mod common;

use common::sitl::{HOME, Sitl, int, real};
use nalgebra::Vector3;
use rotorpilot::airframe::{Airframe, HoverVerdict, analyse_failures};
use rotorpilot::autopilot::{
    AutopilotCommand, CommandOutcome, FlightMode, LandedState, MissionState, OffboardSetpoint, RotorAllocation,
    RotorStatus, Severity, StatusText, Targets, Telemetry,
};
use rotorpilot::math::euler_zyx;
use rotorpilot::mission::{MissionItem, MissionType, PlanChange, cmd, frame};
use rotorpilot::scenario::Trajectory;
use rotorpilot::sim::{Fault, RotorHealth, StepEvent};

const ALT_M: f64 = 10.0;
/// Detection bound: `4 tau_m` confirmation (80 ms for these 20 ms motors) plus a few steps.
const DETECT_MAX_S: f64 = 0.1;
/// Goal: position error below this [m].
const ERROR_MAX_M: f64 = 1.0;
/// Upright at touchdown [deg].
const TILT_MAX_DEG: f64 = 10.0;

/// What to do on a rotor failure (`COM_ACT_FAIL_ACT`).
#[derive(Clone, Copy, Debug, PartialEq)]
enum Action {
    Continue = 0,
    Land = 2,
    Terminate = 4,
}

fn vehicle(airframe: &str, action: Action) -> Sitl {
    Sitl::airframe(airframe)
        .params(&[("COM_ACT_FAIL_ACT", int(action as i32))])
        .build()
}

fn tilt_deg(t: &Telemetry) -> f64 {
    let e = euler_zyx(&t.attitude);
    (e.x.cos() * e.y.cos()).clamp(-1.0, 1.0).acos().to_degrees()
}

/// Arm, take off to `ALT_M` and settle in Hold.
fn take_off(v: &mut Sitl) {
    for _ in 0..v.steps(3.0) {
        v.step();
    }
    assert!(v.telemetry().prearm_ok, "never armable");
    assert_eq!(
        v.command(AutopilotCommand::Arm { force: false }),
        CommandOutcome::Accepted
    );
    let takeoff = AutopilotCommand::Takeoff {
        altitude_amsl_m: Some(HOME.alt_amsl_m + ALT_M),
    };
    assert_eq!(v.command(takeoff), CommandOutcome::Accepted);
    for _ in 0..v.steps(14.0) {
        v.step();
    }
    let t = v.telemetry();
    assert!(
        (t.position_ned.z + ALT_M).abs() < 0.2,
        "not at altitude: {:?}",
        t.position_ned
    );
    assert_eq!(t.mode, FlightMode::Hold);
    // hovering, every rotor commanded between idle and full speed
    let out = t.rotor_outputs;
    assert!(
        out.count > 0
            && out.commands[..out.count]
                .iter()
                .all(|c| c.is_some_and(|u| u > 0.0 && u < 1.0)),
        "{out:?}"
    );
}

/// Figures of one rotor-loss flight.
#[derive(Clone, Debug, Default)]
struct Figures {
    /// From the fault to the monitor's flag [s].
    detect_s: Option<f64>,
    /// Largest position error after the fault [m].
    max_error_m: f64,
    /// Largest position error from 2 s after the fault on [m].
    error_after_2s_m: f64,
    /// Tilt at touchdown [deg] (landing flights): the step before the world
    /// reports contact, or the largest tilt in the last 0.5 m above the
    /// resting height if that is larger.
    touchdown_tilt_deg: Option<f64>,
    /// Largest tilt in the air within 0.5 m of the resting height [deg].
    low_tilt_deg: f64,
    /// Disarmed at the end.
    disarmed: bool,
    /// Largest tilt in flight after the fault [deg].
    max_tilt_deg: f64,
    /// Heading change over the flight after the fault [deg] (wrapped to +-180).
    yaw_drift_deg: f64,
    /// Largest yaw rate in flight after the fault [deg/s].
    max_yaw_rate_deg_s: f64,
    /// Other rotors flagged (must be none).
    wrongly_flagged: u16,
    texts: Vec<StatusText>,
    /// Still in Offboard at the end (figure-eights).
    offboard_to_the_end: bool,
}

impl Figures {
    fn print(&self, what: &str) {
        println!(
            "{what}: detected after {} ms, max error {:.3} m, after 2 s {:.3} m, max tilt {:.1} deg, yaw drift {:.1} deg, max yaw rate {:.0} deg/s{}",
            self.detect_s.map_or("never".into(), |d| format!("{:.0}", d * 1e3)),
            self.max_error_m,
            self.error_after_2s_m,
            self.max_tilt_deg,
            self.yaw_drift_deg,
            self.max_yaw_rate_deg_s,
            self.touchdown_tilt_deg.map_or(String::new(), |t| format!(
                ", touchdown tilt {t:.3} deg, disarmed {}",
                self.disarmed
            )),
        );
    }
}

/// Fly `seconds` after injecting `health` on `rotor` (from 0) now; `error(t, p)`
/// is the position error [m] at time `t` and NED position `p` (None: not measured then), and
/// `each` runs before every step (to stream setpoints). With `land_after`
/// the flight goes on until disarmed (at most that long) and records the touchdown tilt.
fn fly_with_fault(
    v: &mut Sitl,
    rotor: usize,
    health: RotorHealth,
    seconds: f64,
    mut error: impl FnMut(f64, &Vector3<f64>) -> Option<f64>,
    mut each: impl FnMut(&mut Sitl),
    land_after: Option<f64>,
) -> Figures {
    v.texts();
    let t_fault = v.time_s();
    v.inject(Fault::Rotor { rotor, health });
    let yaw0 = euler_zyx(&v.telemetry().attitude).z;
    let mut f = Figures::default();
    let bit = 1u16 << rotor;
    let total = seconds + land_after.unwrap_or(0.0);
    let mut tilt_before = tilt_deg(&v.telemetry());
    for _ in 0..v.steps(total) {
        each(v);
        v.step();
        let t = v.telemetry();
        let since = t.time_s - t_fault;
        if f.detect_s.is_none() && (t.failed_rotors | t.degraded_rotors) & bit != 0 {
            f.detect_s = Some(since);
        }
        f.wrongly_flagged |= (t.failed_rotors | t.degraded_rotors) & !bit;
        if since <= seconds {
            if let Some(e) = error(t.time_s, &t.position_ned) {
                f.max_error_m = f.max_error_m.max(e);
                if since >= 2.0 {
                    f.error_after_2s_m = f.error_after_2s_m.max(e);
                }
            }
            let dyaw = (euler_zyx(&t.attitude).z - yaw0 + std::f64::consts::PI).rem_euclid(2.0 * std::f64::consts::PI)
                - std::f64::consts::PI;
            if dyaw.to_degrees().abs() > f.yaw_drift_deg.abs() {
                f.yaw_drift_deg = dyaw.to_degrees();
            }
        }
        if t.landed != LandedState::OnGround {
            f.max_tilt_deg = f.max_tilt_deg.max(tilt_deg(&t));
            f.max_yaw_rate_deg_s = f.max_yaw_rate_deg_s.max(t.rate_frd.z.abs().to_degrees());
        }
        // the world levels a vehicle that comes to rest: touchdown is the tilt just before
        if t.landed != LandedState::OnGround && t.position_ned.z > -0.7 {
            f.low_tilt_deg = f.low_tilt_deg.max(tilt_deg(&t));
        }
        if let StepEvent::Touchdown { .. } = v.core().world().last_report(0).event {
            f.touchdown_tilt_deg.get_or_insert(tilt_before.max(f.low_tilt_deg));
        }
        tilt_before = tilt_deg(&t);
        if land_after.is_some() && since > seconds && !t.armed {
            break;
        }
    }
    f.disarmed = !v.telemetry().armed;
    f.texts = v.texts();
    f
}

/// Rotor `rotor` (from 0) dies at hover at 10 m.
fn hover_loss(airframe: &str, rotor: usize, action: Action) -> Figures {
    let mut v = vehicle(airframe, action);
    take_off(&mut v);
    let p0 = v.telemetry().position_ned;
    let land = (action == Action::Land).then_some(40.0);
    let f = fly_with_fault(
        &mut v,
        rotor,
        RotorHealth::Off,
        8.0,
        |_, p| Some((p - p0).norm()),
        |_| {},
        land,
    );
    let t = v.telemetry();
    assert_eq!(
        t.failed_rotors,
        1 << rotor,
        "{airframe} rotor {}: {:?}",
        rotor + 1,
        v.pilot().rotor_status()
    );
    // the motor outputs a client sees (ACTUATOR_OUTPUT_STATUS), by motor
    // number: armed, the failed rotor's motor stopped and every other
    // commanded; disarmed, all stopped
    let out = t.rotor_outputs;
    assert_eq!(out.count, v.pilot().rotor_status().len());
    let motor = Airframe::load(airframe).unwrap().motor_of_rotor(rotor);
    for (i, c) in out.commands.iter().enumerate() {
        let running = t.armed && i < out.count && i + 1 != motor;
        assert_eq!(
            c.is_some(),
            running,
            "{airframe} rotor {} (motor {motor}) lost, motor {}: {c:?}",
            rotor + 1,
            i + 1
        );
        assert!(c.is_none_or(|u| (0.0..=1.0).contains(&u)), "{c:?}");
    }
    let failed = format!("Motor {motor} failed");
    assert!(
        f.texts
            .iter()
            .any(|s| s.severity == Severity::Critical && s.text.starts_with(&failed)),
        "{:?}",
        f.texts
    );
    f
}

/// The figure-eight flown as offboard position, velocity and acceleration setpoints.
fn eight() -> Trajectory {
    Trajectory::FigureEight {
        half_width_m: 4.0,
        rate_rad_s: 0.4,
        altitude_m: ALT_M,
    }
}

fn eight_setpoint(t: f64) -> AutopilotCommand {
    let r = eight().at(t);
    AutopilotCommand::Offboard(OffboardSetpoint::Local(Targets {
        position: Some(r.position_ned),
        velocity: Some(r.velocity_ned),
        acceleration: Some(r.acceleration_ned),
        yaw_rad: Some(0.0),
        yaw_rate_rad_s: None,
    }))
}

/// Rotor `rotor` dies (or `health`) 4 s into a figure-eight at 10 m (`None`:
/// no fault), then 16 s more. The error is to the same instant of `healthy`
/// (the positions of the flight without fault, which this returns) when
/// given, else to the curve (which offboard guidance follows with some lag).
fn eight_loss(
    airframe: &str,
    fault: Option<(usize, RotorHealth)>,
    healthy: Option<&[Vector3<f64>]>,
) -> (Figures, Vec<Vector3<f64>>) {
    let mut v = vehicle(airframe, Action::Continue);
    take_off(&mut v);
    let t0 = v.time_s();
    assert_eq!(v.command(eight_setpoint(0.0)), CommandOutcome::Accepted);
    assert_eq!(
        v.command(AutopilotCommand::SetMode(FlightMode::Offboard)),
        CommandOutcome::Accepted
    );
    let every = v.steps(0.02);
    let mut k = 0usize;
    let mut stream = move |v: &mut Sitl| {
        if k.is_multiple_of(every) {
            let t = v.time_s() - t0;
            assert_eq!(v.command(eight_setpoint(t)), CommandOutcome::Accepted);
        }
        k += 1;
    };
    // one quarter of the eight first (the start transient is not the fault's)
    for _ in 0..v.steps(4.0) {
        stream(&mut v);
        v.step();
    }
    let mut track = Vec::new();
    let error = |t: f64, p: &Vector3<f64>| {
        let e = match healthy {
            Some(h) => (p - h.get(track.len())?).norm(),
            None => (p - eight().at(t - t0).position_ned).norm(),
        };
        track.push(*p);
        Some(e)
    };
    let (rotor, health) = fault.unwrap_or((0, RotorHealth::Healthy));
    let mut f = fly_with_fault(&mut v, rotor, health, 16.0, error, stream, None);
    f.offboard_to_the_end = v.telemetry().mode == FlightMode::Offboard;
    (f, track)
}

fn wp(north: f64, east: f64, alt: f32) -> MissionItem {
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
        params: [0.0, 0.0, 0.0, f32::NAN],
        x,
        y,
        z: alt,
    }
}

/// A square at 10 m ending with a landing at home.
fn square_mission() -> Vec<MissionItem> {
    let mut land = wp(0.0, 0.0, 0.0);
    land.command = cmd::NAV_LAND;
    vec![
        wp(0.0, 0.0, 10.0),
        wp(20.0, 0.0, 10.0),
        wp(20.0, 20.0, 10.0),
        wp(0.0, 20.0, 10.0),
        wp(0.0, 0.0, 10.0),
        land,
    ]
}

/// Distance [m] from `p` to the square's path (legs at 10 m, then the descent
/// at home), away from its corners (None within 5 m of one: guidance rounds them).
fn off_path(p: &Vector3<f64>) -> Option<f64> {
    let c = [
        Vector3::new(0.0, 0.0, -ALT_M),
        Vector3::new(20.0, 0.0, -ALT_M),
        Vector3::new(20.0, 20.0, -ALT_M),
        Vector3::new(0.0, 20.0, -ALT_M),
        Vector3::new(0.0, 0.0, -ALT_M),
        Vector3::new(0.0, 0.0, 0.0),
    ];
    if c.iter().any(|k| (p - k).norm() < 5.0) {
        return None;
    }
    let d = c
        .windows(2)
        .map(|s| {
            let d = s[1] - s[0];
            let u = ((p - s[0]).dot(&d) / d.norm_squared()).clamp(0.0, 1.0);
            (p - (s[0] + d * u)).norm()
        })
        .fold(f64::INFINITY, f64::min);
    Some(d)
}

/// The square mission with rotor `rotor` dying on the second leg (`None`: healthy).
fn mission_loss(airframe: &str, fault: Option<usize>, action: Action) -> (Figures, Telemetry) {
    let mut v = vehicle(airframe, action);
    v.core_mut()
        .change_plans(
            0,
            PlanChange::Store {
                kind: MissionType::Mission,
                items: square_mission(),
                base_id: None,
            },
        )
        .unwrap();
    for _ in 0..v.steps(3.0) {
        v.step();
    }
    assert_eq!(
        v.command(AutopilotCommand::Arm { force: false }),
        CommandOutcome::Accepted
    );
    assert_eq!(
        v.command(AutopilotCommand::StartMission { first: Some(0) }),
        CommandOutcome::Accepted
    );
    // to the middle of the second leg (north 20 m, east 10 m)
    let mut n = 0;
    while v.telemetry().position_ned.y < 10.0 {
        v.step();
        n += 1;
        assert!(n < v.steps(120.0), "never reached the second leg");
    }
    let (rotor, health) = fault.map_or((0, RotorHealth::Healthy), |r| (r, RotorHealth::Off));
    // the path error (meaningless when the land action leaves the path on purpose)
    let f = fly_with_fault(&mut v, rotor, health, 60.0, |_, p| off_path(p), |_| {}, Some(60.0));
    (f, v.telemetry())
}

fn rotors(airframe: &str) -> Vec<(usize, HoverVerdict)> {
    analyse_failures(&Airframe::load(airframe).unwrap())
        .into_iter()
        .map(|a| (a.rotor - 1, a.verdict))
        .collect()
}

#[test]
fn every_octo_rotor_lost_at_hover_is_flagged_within_100_ms_and_position_stays_within_1_m() {
    for (j, verdict) in rotors("octo") {
        assert_eq!(verdict, HoverVerdict::Feasible);
        let f = hover_loss("octo", j, Action::Continue);
        f.print(&format!("octo hover, rotor {} off", j + 1));
        let d = f.detect_s.expect("never detected");
        assert!(d > 0.0 && d <= DETECT_MAX_S, "rotor {}: detected after {d} s", j + 1);
        assert!(f.max_error_m < ERROR_MAX_M, "rotor {}: {:?}", j + 1, f);
        assert!(f.error_after_2s_m < 0.1, "rotor {}: {:?}", j + 1, f);
        assert_eq!(f.wrongly_flagged, 0);
    }
}

#[test]
fn every_recoverable_ppnnpn_hexa_rotor_lost_at_hover_keeps_position_within_1_m() {
    let table = rotors("hexa-ppnnpn");
    let feasible: Vec<usize> = table
        .iter()
        .filter(|(_, v)| *v == HoverVerdict::Feasible)
        .map(|(j, _)| *j)
        .collect();
    assert_eq!(feasible, vec![0, 1, 2, 3], "{table:?}");
    for j in feasible {
        let f = hover_loss("hexa-ppnnpn", j, Action::Continue);
        f.print(&format!("hexa-ppnnpn hover, rotor {} off", j + 1));
        let d = f.detect_s.expect("never detected");
        assert!(d > 0.0 && d <= DETECT_MAX_S, "rotor {}: detected after {d} s", j + 1);
        assert!(f.max_error_m < ERROR_MAX_M, "rotor {}: {:?}", j + 1, f);
        assert!(f.error_after_2s_m < 0.1, "rotor {}: {:?}", j + 1, f);
    }
}

#[test]
fn with_the_land_action_every_lost_rotor_ends_upright_on_the_ground_and_disarmed() {
    for (airframe, j) in (0..8).map(|j| ("octo", j)).chain((0..4).map(|j| ("hexa-ppnnpn", j))) {
        let f = hover_loss(airframe, j, Action::Land);
        f.print(&format!("{airframe} hover, rotor {} off, land", j + 1));
        let tilt = f.touchdown_tilt_deg.expect("never touched down");
        assert!(tilt < TILT_MAX_DEG, "{airframe} rotor {}: {:?}", j + 1, f);
        assert!(f.disarmed, "{airframe} rotor {}: {:?}", j + 1, f);
        assert!(
            f.texts
                .iter()
                .any(|s| s.text == "Failsafe: rotor failure, triggering Land"),
            "{:?}",
            f.texts
        );
    }
}

/// GIVEN hexa-ppnnpn hovering, `COM_ACT_FAIL_ACT` 0
/// WHEN rotor 5 or 6 dies (no hover with zero yaw torque within the
/// others' speed range)
/// THEN it flies on with its heading free, holding its position, as PX4
/// flies on with what its allocator gives; with `COM_ACT_FAIL_ACT` 2 it lands upright.
#[test]
fn an_unrecoverable_ppnnpn_rotor_is_flown_on_with_the_heading_free() {
    for j in [4, 5] {
        let f = hover_loss("hexa-ppnnpn", j, Action::Continue);
        f.print(&format!("hexa-ppnnpn hover, rotor {} off (infeasible)", j + 1));
        assert!(f.detect_s.unwrap() <= DETECT_MAX_S, "{f:?}");
        assert!(
            f.texts.iter().any(|s| s.text.ends_with("heading free")),
            "{:?}",
            f.texts
        );
        assert!(!f.disarmed && f.max_error_m < ERROR_MAX_M, "{f:?}");
        assert!(f.max_yaw_rate_deg_s < 360.0, "{f:?}");
        let f = hover_loss("hexa-ppnnpn", j, Action::Land);
        f.print(&format!("hexa-ppnnpn hover, rotor {} off (infeasible), land", j + 1));
        assert!(f.disarmed && f.touchdown_tilt_deg.unwrap() < TILT_MAX_DEG, "{f:?}");
    }
}

#[test]
fn every_octo_rotor_lost_on_a_figure_eight_stays_within_1_m_of_the_curve() {
    let (healthy, track) = eight_loss("octo", None, None);
    healthy.print("octo figure-eight, healthy (error to the curve)");
    assert!(healthy.detect_s.is_none() && healthy.wrongly_flagged == 0);
    for j in 0..8 {
        let (f, _) = eight_loss("octo", Some((j, RotorHealth::Off)), Some(&track));
        f.print(&format!("octo figure-eight, rotor {} off", j + 1));
        assert!(f.detect_s.unwrap() <= DETECT_MAX_S, "{f:?}");
        assert!(f.max_error_m < ERROR_MAX_M, "rotor {}: {:?}", j + 1, f);
        assert!(f.offboard_to_the_end, "{f:?}");
    }
}

#[test]
fn every_recoverable_ppnnpn_rotor_lost_on_a_figure_eight_stays_within_1_m_of_the_curve() {
    let (healthy, track) = eight_loss("hexa-ppnnpn", None, None);
    healthy.print("hexa-ppnnpn figure-eight, healthy (error to the curve)");
    assert!(healthy.detect_s.is_none() && healthy.wrongly_flagged == 0);
    for j in 0..4 {
        let (f, _) = eight_loss("hexa-ppnnpn", Some((j, RotorHealth::Off)), Some(&track));
        f.print(&format!("hexa-ppnnpn figure-eight, rotor {} off", j + 1));
        assert!(f.detect_s.unwrap() <= DETECT_MAX_S, "{f:?}");
        assert!(f.max_error_m < ERROR_MAX_M, "rotor {}: {:?}", j + 1, f);
        assert!(f.offboard_to_the_end, "{f:?}");
    }
}

#[test]
fn a_half_thrust_rotor_is_flagged_degraded_with_its_fraction_and_flown_on() {
    for airframe in ["octo", "hexa-ppnnpn"] {
        let mut v = vehicle(airframe, Action::Continue);
        take_off(&mut v);
        let p0 = v.telemetry().position_ned;
        let half = RotorHealth::Degraded { thrust_fraction: 0.5 };
        let f = fly_with_fault(&mut v, 2, half, 8.0, |_, p| Some((p - p0).norm()), |_| {}, None);
        f.print(&format!("{airframe} hover, rotor 3 at 50 % thrust"));
        let t = v.telemetry();
        assert_eq!((t.failed_rotors, t.degraded_rotors), (0, 1 << 2));
        let RotorStatus::Degraded { thrust_fraction } = v.pilot().rotor_status()[2] else {
            panic!("{:?}", v.pilot().rotor_status())
        };
        assert!((thrust_fraction - 0.5).abs() < 0.03, "estimated {thrust_fraction}");
        assert!(f.detect_s.unwrap() <= DETECT_MAX_S);
        assert!(f.max_error_m < ERROR_MAX_M, "{f:?}");
        assert!(matches!(v.pilot().rotor_allocation(), RotorAllocation::Reduced { .. }));
        // said by its motor number (PX4's: the hexa-X's motor 4 is its rotor 3)
        let degraded = format!(
            "Motor {} degraded: 5",
            Airframe::load(airframe).unwrap().motor_of_rotor(2)
        );
        assert!(
            f.texts
                .iter()
                .any(|s| s.severity == Severity::Warning && s.text.starts_with(&degraded)),
            "{:?}",
            f.texts
        );
        // repaired: taken back, the full allocation again
        let f = fly_with_fault(
            &mut v,
            2,
            RotorHealth::Healthy,
            2.0,
            |_, p| Some((p - p0).norm()),
            |_| {},
            None,
        );
        assert_eq!(v.telemetry().degraded_rotors, 0);
        assert_eq!(*v.pilot().rotor_allocation(), RotorAllocation::Full);
        let recovered = format!(
            "Motor {} recovered",
            Airframe::load(airframe).unwrap().motor_of_rotor(2)
        );
        assert!(f.texts.iter().any(|s| s.text == recovered), "{:?}", f.texts);
    }
}

#[test]
fn a_mission_goes_on_after_a_rotor_loss_and_lands_upright_at_its_end() {
    for (airframe, rotor) in [("octo", 2), ("hexa-ppnnpn", 0)] {
        let (f, t) = mission_loss(airframe, Some(rotor), Action::Continue);
        f.print(&format!("{airframe} mission, rotor {} off, continue", rotor + 1));
        assert!(f.detect_s.unwrap() <= DETECT_MAX_S);
        assert_eq!(t.mission.state, MissionState::Complete, "{:?}", f.texts);
        assert!(f.disarmed, "{f:?}");
        assert!(f.touchdown_tilt_deg.unwrap() < TILT_MAX_DEG, "{f:?}");
        assert!(t.position_ned.xy().norm() < 1.0, "landed at {:?}", t.position_ned);
        assert!(f.max_error_m < ERROR_MAX_M, "off the path: {f:?}");
    }
}

#[test]
fn a_mission_with_the_land_action_is_abandoned_for_an_upright_landing() {
    let (f, t) = mission_loss("octo", Some(5), Action::Land);
    f.print("octo mission, rotor 6 off, land");
    assert_ne!(t.mission.state, MissionState::Complete);
    assert!(f.disarmed && f.touchdown_tilt_deg.unwrap() < TILT_MAX_DEG, "{f:?}");
    // it landed where it was, on the second leg (east about 10 m), not at home
    assert!(t.position_ned.y > 5.0, "{:?}", t.position_ned);
}

#[test]
fn healthy_missions_and_eights_never_flag_a_rotor() {
    for airframe in ["quad", "hexa", "octo", "hexa-ppnnpn"] {
        let (f, t) = mission_loss(airframe, None, Action::Land);
        f.print(&format!("{airframe} mission, healthy"));
        assert_eq!(t.mission.state, MissionState::Complete, "{airframe}");
        assert!(f.detect_s.is_none() && f.wrongly_flagged == 0, "{airframe}: {f:?}");
        assert!(!f.texts.iter().any(|s| s.text.starts_with("Motor")), "{:?}", f.texts);
    }
    let (f, _) = eight_loss("octo", None, None);
    assert!(f.detect_s.is_none() && f.wrongly_flagged == 0);
}

#[test]
fn a_quad_losing_a_rotor_gives_up_yaw_and_lands() {
    // flagged, the rank-3 allocation chosen, an emergency landing commanded
    // (the relaxed-hover descent itself: tests/lockstep_quad_rotor_loss.rs)
    let mut v = vehicle("quad", Action::Continue);
    take_off(&mut v);
    let p0 = v.telemetry().position_ned;
    let f = fly_with_fault(
        &mut v,
        0,
        RotorHealth::Off,
        1.0,
        |_, p| Some((p - p0).norm()),
        |_| {},
        None,
    );
    f.print("quad hover, rotor 1 off (first second)");
    assert!(f.detect_s.unwrap() <= DETECT_MAX_S, "{f:?}");
    assert!(matches!(
        v.pilot().rotor_allocation(),
        RotorAllocation::RelaxedHover { .. }
    ));
    assert_eq!(v.telemetry().mode, FlightMode::Land);
    assert!(
        f.texts.iter().any(|s| s.severity == Severity::Emergency),
        "{:?}",
        f.texts
    );
}

/// GIVEN an octo hovering at 10 m with COM_ACT_FAIL_ACT 4, the value PX4
/// documents as Terminate and acts on (its failsafe maps it to flight
/// termination, though its metadata bounds the parameter at 3)
/// WHEN rotor 1 dies
/// THEN the flight stack terminates as soon as the monitor flags the rotor:
/// disarmed by the failsafe (an Emergency text triggering flight
/// termination, cut at STATUSTEXT's 50 characters), and the vehicle falls.
#[test]
fn with_the_terminate_action_a_lost_rotor_disarms_at_once() {
    let mut v = vehicle("octo", Action::Terminate);
    take_off(&mut v);
    v.texts();
    v.core_mut()
        .world_mut()
        .inject(
            0,
            Fault::Rotor {
                rotor: 0,
                health: RotorHealth::Off,
            },
        )
        .unwrap();
    let mut disarmed_after = None;
    for k in 1..=v.steps(1.0) {
        v.step();
        if !v.pilot().armed() {
            disarmed_after = Some(k);
            break;
        }
    }
    let said = v.texts();
    let k = disarmed_after.unwrap_or_else(|| panic!("still armed 1 s after the loss: {said:?}"));
    assert!(k <= v.steps(DETECT_MAX_S), "disarmed {k} steps after the loss");
    assert!(
        said.iter().any(|s| s.severity == Severity::Emergency
            && s.text.starts_with("Failsafe: rotor failure, triggering flight termin")),
        "{said:?}"
    );
    let z0 = v.telemetry().position_ned.z;
    for _ in 0..v.steps(1.0) {
        v.step();
    }
    assert!(
        v.telemetry().position_ned.z > z0 + 3.0,
        "not falling: {:?}",
        v.telemetry().position_ned
    );
}

/// GIVEN an octo that lost rotor 1 in a hover and landed (COM_ACT_FAIL_ACT Land)
/// WHEN it is armed again
/// THEN arming is refused ("Arming denied: ESC failure"), as PX4 refuses an
/// ESC failure; forced arming still goes (the pilot's call).
#[test]
fn a_vehicle_that_lost_a_rotor_refuses_to_arm_again() {
    let mut v = vehicle("octo", Action::Land);
    take_off(&mut v);
    v.core_mut()
        .world_mut()
        .inject(
            0,
            Fault::Rotor {
                rotor: 0,
                health: RotorHealth::Off,
            },
        )
        .unwrap();
    for _ in 0..v.steps(40.0) {
        v.step();
        if !v.pilot().armed() {
            break;
        }
    }
    assert!(!v.pilot().armed(), "landed and disarmed");
    v.texts();
    assert_eq!(
        v.command(AutopilotCommand::Arm { force: false }),
        CommandOutcome::TemporarilyRejected("ESC failure")
    );
    let said = v.texts();
    assert!(
        said.iter()
            .any(|s| s.severity == Severity::Critical && s.text == "Arming denied: ESC failure"),
        "{said:?}"
    );
    assert_eq!(
        v.command(AutopilotCommand::Arm { force: true }),
        CommandOutcome::Accepted
    );
}

/// The figures as one markdown table.
#[test]
#[ignore = "a report: run with --ignored --nocapture"]
fn rotor_loss_table() {
    println!(
        "| airframe | flight | rotor | detection [ms] | max error [m] | error after 2 s [m] | max tilt [deg] | yaw drift [deg] |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    let row = |a: &str, what: &str, j: usize, f: &Figures| {
        println!(
            "| {a} | {what} | {} | {} | {:.3} | {:.3} | {:.1} | {:.1} |",
            j + 1,
            f.detect_s.map_or("-".into(), |d| format!("{:.0}", d * 1e3)),
            f.max_error_m,
            f.error_after_2s_m,
            f.max_tilt_deg,
            f.yaw_drift_deg
        );
    };
    for (a, n) in [("octo", 8), ("hexa-ppnnpn", 6)] {
        for j in 0..n {
            row(a, "hover", j, &hover_loss(a, j, Action::Continue));
        }
        let (_, track) = eight_loss(a, None, None);
        // (rotors 5 and 6 of hexa-ppnnpn have no hover: the vehicle lands)
        for j in (0..n).filter(|j| a == "octo" || *j < 4) {
            row(
                a,
                "figure-eight",
                j,
                &eight_loss(a, Some((j, RotorHealth::Off)), Some(&track)).0,
            );
        }
        let half = RotorHealth::Degraded { thrust_fraction: 0.5 };
        row(
            a,
            "figure-eight, 50 % thrust",
            2,
            &eight_loss(a, Some((2, half)), Some(&track)).0,
        );
    }
}

/// GIVEN the stock hexa (PNPNPN) hovering, `COM_ACT_FAIL_ACT` 0 (PX4's default)
/// WHEN any one rotor dies: rotors 1, 3, 4, 6 leave hover with zero yaw
/// torque on the edge of what the others give, 2 and 5 beyond it (doc
/// section 3)
/// THEN the heading is given up and the yaw gets what roll, pitch and thrust
/// leave (`YawPriority::Last`): it flies on as PX4 does, a warning and no
/// landing, holding its position within 0.25 m and its yaw rate bounded by
/// the rotors' drag; with `COM_ACT_FAIL_ACT` 2 it lands upright below where it was.
#[test]
fn the_stock_hexa_flies_on_with_its_heading_free_after_losing_any_rotor() {
    for (j, verdict) in rotors("hexa") {
        assert!(
            matches!(verdict, HoverVerdict::Boundary | HoverVerdict::Infeasible),
            "stock hexa rotor {}: {verdict:?}",
            j + 1
        );
        let mut v = vehicle("hexa", Action::Continue);
        take_off(&mut v);
        let p0 = v.telemetry().position_ned;
        let f = fly_with_fault(
            &mut v,
            j,
            RotorHealth::Off,
            40.0,
            |_, p| Some((p - p0).norm()),
            |_| {},
            None,
        );
        f.print(&format!("hexa hover, rotor {} off ({verdict:?})", j + 1));
        assert!(f.detect_s.unwrap() <= DETECT_MAX_S, "{f:?}");
        assert!(matches!(v.pilot().rotor_allocation(), RotorAllocation::LostYaw { .. }));
        assert!(
            f.texts.iter().any(|s| s.text.ends_with("heading free")),
            "{:?}",
            f.texts
        );
        assert!(
            f.texts.iter().all(|s| s.severity != Severity::Emergency),
            "{:?}",
            f.texts
        );
        assert_eq!(v.mode(), FlightMode::Hold, "{:?}", f.texts);
        assert!(!f.disarmed && f.max_error_m < 0.25, "{f:?}");
        assert!(f.max_tilt_deg < 15.0 && f.max_yaw_rate_deg_s < 360.0, "{f:?}");
    }
    let mut v = vehicle("hexa", Action::Land);
    take_off(&mut v);
    let p0 = v.telemetry().position_ned;
    let f = fly_with_fault(&mut v, 1, RotorHealth::Off, 8.0, |_, _| None, |_| {}, Some(40.0));
    f.print("hexa hover, rotor 2 off, COM_ACT_FAIL_ACT 2");
    assert!(f.disarmed && f.touchdown_tilt_deg.unwrap() < TILT_MAX_DEG, "{f:?}");
    assert!(v.telemetry().position_ned.xy().metric_distance(&p0.xy()) < 1.0, "{f:?}");
}

/// GIVEN hexa-ppnnpn hovering at 40 m with a mission stored and
/// `COM_ACT_FAIL_ACT` 2, losing its neighbouring rotors 1 and 2 one second
/// apart: the failsafe "rotor failure" lands it
/// WHEN the position is lost and comes back during that landing, the pilot
/// then switches to Mission, and the position is lost again for a second
/// and comes back
/// THEN the first loss is a Descend and a landing again, the rotor failure's
/// failsafe in force throughout; the switch is accepted and flown (PX4's user takeover: a Land
/// failsafe allows a mode switch, `FailsafeBase::getSelectedAction`), but
/// the position loss ends the takeover and the landing, whose cause (the
/// dead rotors) is still there, is in force again: Descend while blind, Land
/// when the position is back (not Hold), still a failsafe; it lands and disarms.
#[test]
fn a_mission_taken_over_from_a_rotor_failure_landing_lands_again_after_a_position_loss() {
    let mut v = vehicle("hexa-ppnnpn", Action::Land);
    // the Land at the instant of the failure (no COM_FAIL_ACT_T Hold first)
    v.set_param("COM_FAIL_ACT_T", real(0.0));
    v.core_mut()
        .change_plans(
            0,
            PlanChange::Store {
                kind: MissionType::Mission,
                items: vec![wp(20.0, 0.0, 40.0), wp(20.0, 20.0, 40.0)],
                base_id: None,
            },
        )
        .unwrap();
    v.run(3.0);
    v.take_off_to(Some(40.0));
    v.run(3.0);
    v.texts();
    for rotor in [0, 1] {
        v.inject(Fault::Rotor {
            rotor,
            health: RotorHealth::Off,
        });
        v.run(1.0);
    }
    let said = v.texts();
    assert!(
        said.iter()
            .any(|s| s.text == "Failsafe: rotor failure, triggering Land"),
        "{said:?}"
    );
    assert_eq!(v.mode(), FlightMode::Land, "{said:?}");
    let in_failsafe = |v: &Sitl| {
        v.pilot()
            .failsafe_in_force()
            .is_some_and(|f| f.cause == "rotor failure")
    };
    assert!(in_failsafe(&v));

    // the position lost and back during the landing: still the failsafe landing
    v.gps(false);
    v.run(0.5);
    assert_eq!(v.mode(), FlightMode::Descend);
    assert!(in_failsafe(&v), "{:?}", v.pilot().failsafe_in_force());
    v.gps(true);
    v.run(0.5);
    assert_eq!(v.mode(), FlightMode::Land, "{:?}", v.texts());
    assert!(in_failsafe(&v), "{:?}", v.pilot().failsafe_in_force());

    // the pilot takes over: accepted and flown
    assert_eq!(
        v.command(AutopilotCommand::SetMode(FlightMode::Mission)),
        CommandOutcome::Accepted
    );
    assert_eq!(v.mode(), FlightMode::Mission);
    assert!(v.pilot().failsafe_in_force().is_none(), "taken over");
    v.run(0.5);
    assert_eq!(v.mode(), FlightMode::Mission);
    v.texts();

    // the position lost: a blind descent, the landing failsafe in force again
    v.gps(false);
    v.run(1.0);
    let said = v.texts();
    assert_eq!(v.mode(), FlightMode::Descend, "{said:?}");
    assert!(in_failsafe(&v), "{said:?}");
    assert!(
        said.iter()
            .any(|s| s.severity == Severity::Critical && s.text == "Failsafe: rotor failure, triggering Descend"),
        "{said:?}"
    );

    // the position back: the landing goes on, not Hold
    v.gps(true);
    v.run(1.0);
    let said = v.texts();
    assert_eq!(v.mode(), FlightMode::Land, "{said:?}");
    assert!(in_failsafe(&v), "{said:?}");
    assert!(said.iter().any(|s| s.text == "GPS fix regained: landing"), "{said:?}");
    let landed = v.run_until(60.0, |t| !t.armed);
    assert!(landed.is_some(), "not landed and disarmed: {:?}", v.texts());
}

/// GIVEN the stock hexa hovering, `COM_ACT_FAIL_ACT` 0
/// WHEN its motors 1 and 2 die one second apart (PX4's numbering: the right
/// and left rotors, an opposite pair, as PX4's "Remove two motors" takes them)
/// THEN the four left have rank 3 (roll and yaw torque move together), so
/// the heading is given up with no yaw correction (`YawPriority::Dropped`),
/// and it flies on: it holds its position within 0.5 m with no emergency and
/// no landing, as PX4 flies on with what its allocator gives.
#[test]
fn the_stock_hexa_without_an_opposite_pair_flies_on() {
    let af = Airframe::load("hexa").unwrap();
    let mut v = vehicle("hexa", Action::Continue);
    take_off(&mut v);
    let p0 = v.telemetry().position_ned;
    v.texts();
    for motor in [1, 2] {
        let rotor = af.rotor_of_motor(motor).unwrap();
        v.inject(Fault::Rotor {
            rotor,
            health: RotorHealth::Off,
        });
        v.run(1.0);
    }
    let mut worst = 0.0f64;
    for _ in 0..300 {
        v.run(0.1);
        worst = worst.max((v.telemetry().position_ned - p0).norm());
    }
    let said = v.texts();
    println!("hexa without motors 1 and 2: largest position error {worst:.3} m; {said:?}");
    assert!(
        matches!(
            v.pilot().rotor_allocation(),
            RotorAllocation::LostYaw {
                verdict: HoverVerdict::RankDeficient,
                ..
            }
        ),
        "{:?}",
        v.pilot().rotor_allocation()
    );
    assert!(
        said.iter().any(|s| s.text == "Motor 2 failed: heading free"),
        "{said:?}"
    );
    assert!(said.iter().all(|s| s.severity != Severity::Emergency), "{said:?}");
    assert!(v.armed() && v.mode() == FlightMode::Hold, "{said:?}");
    assert!(worst < 0.5, "{worst}");
}

/// GIVEN a quad that lost a rotor and flies its emergency landing, with
/// `NAV_DLL_ACT` Return and a GCS heard
/// WHEN the pilot takes over (selects Hold) and the data link is then lost
/// THEN the landing taken over, the more severe action, comes back at once:
/// the data link's Return would hold for `COM_FAIL_ACT_T` first, but a
/// rotor loss's landing never waits.
#[test]
fn a_rotor_loss_landing_taken_over_comes_back_at_once_with_the_next_failsafe() {
    let mut v = Sitl::airframe("quad")
        .params(&[("NAV_DLL_ACT", int(2)), ("COM_DL_LOSS_T", int(5))])
        .build();
    take_off(&mut v);
    v.heartbeat();
    let heard = v.time_s();
    fly_with_fault(&mut v, 0, RotorHealth::Off, 0.5, |_, _| None, |_| {}, None);
    assert_eq!(v.mode(), FlightMode::Land);
    assert_eq!(
        v.command(AutopilotCommand::SetMode(FlightMode::Hold)),
        CommandOutcome::Accepted
    );
    assert_eq!(v.mode(), FlightMode::Hold);
    let back = v
        .run_until(6.0, |t| t.mode != FlightMode::Hold)
        .unwrap_or_else(|| panic!("no failsafe: {:?}", v.texts()));
    assert!(
        (back - heard - 5.0).abs() < 2e-3,
        "{} s after the last heartbeat",
        back - heard
    );
    assert_eq!(v.mode(), FlightMode::Land, "{:?}", v.texts());
    assert_eq!(v.count(" in 5 s"), 0, "{:?}", v.texts());
}
