//! Lockstep tests of manual control: each manual mode flown with sticks
//! (Position, Altitude, Stabilized, Acro), the refusals without sticks and
//! PX4's throttle arming checks, the loss of the sticks (`NAV_RCL_ACT`) in
//! a manual mode and not in Hold or Mission, and the reaction to losing the
//! GPS fix: Descend near where it was lost without using the horizontal
//! position, Hold when the fix returns, Position falling back to Altitude.
//! One vehicle in the lockstep core, simulated time only:
//! `cargo test --release --test lockstep_manual`.

mod common;

use common::sitl::{HOME, Sitl, real};
use nalgebra::Vector3;
use rotorpilot::autopilot::{
    Autopilot, AutopilotCommand, CommandOutcome, ControlOutput, FlightMode, ManualControl, Severity, StatusText,
    Telemetry,
};
use rotorpilot::lockstep::Pilot;
use rotorpilot::math::euler_zyx;
use rotorpilot::mission::{MissionItem, MissionType, PlanChange, cmd, frame};
use rotorpilot::params::ParamValue;
use rotorpilot::signals::{DEFAULT_STEP_S, GpsFix, SensorReadings};
use rotorpilot::sim::SimFault;

/// Sticks are sent at this period [s] (QGroundControl's joystick: 20-50 Hz).
const STICK_PERIOD_S: f64 = 0.05;

/// A pilot whose navigation solution is horizontally wrong while the GPS
/// fix is lost (position off by `offset`, velocity by `drift`): what the
/// flight stack must not steer by.
struct Misled {
    ap: Autopilot,
    offset: Vector3<f64>,
    drift: Vector3<f64>,
}

impl Pilot for Misled {
    fn decide(&mut self, readings: &SensorReadings) {
        let mut r = *readings;
        if r.gps.fix == GpsFix::None {
            r.measurement.position_ned += self.offset;
            r.measurement.velocity_ned += self.drift;
        }
        self.ap.step(&r);
    }
    fn output(&self) -> &ControlOutput {
        self.ap.output()
    }
    fn rotors_stopped(&mut self, why: &SimFault) {
        self.ap.rotors_stopped(&why.to_string());
    }
}

/// One vehicle, its world and the latest sticks (sent every [`STICK_PERIOD_S`]
/// while `sending`).
struct Vehicle {
    core: Sitl<Misled>,
    sticks: ManualControl,
    sending: bool,
    last_sent_s: f64,
    texts: Vec<StatusText>,
}

impl Vehicle {
    fn new(params: &[(&str, ParamValue)]) -> Self {
        let core = Sitl::quad().params(params).build_with(|af, store| Misled {
            ap: Autopilot::new(af, HOME, store, DEFAULT_STEP_S).unwrap(),
            offset: Vector3::zeros(),
            drift: Vector3::zeros(),
        });
        let mut v = Self {
            core,
            sticks: ManualControl::CENTRED,
            sending: false,
            last_sent_s: f64::NEG_INFINITY,
            texts: Vec::new(),
        };
        v.core.step();
        v
    }

    fn readings(&mut self) -> SensorReadings {
        self.core.readings()
    }

    fn command(&mut self, cmd: AutopilotCommand) -> CommandOutcome {
        let r = self.readings();
        self.core.pilot_mut().ap.command(cmd, &r)
    }

    fn send_sticks(&mut self, sticks: ManualControl) -> CommandOutcome {
        self.sticks = sticks;
        self.sending = true;
        self.last_sent_s = self.core.time_s();
        self.command(AutopilotCommand::ManualControl(sticks))
    }

    fn step(&mut self) {
        if self.sending && self.core.time_s() - self.last_sent_s >= STICK_PERIOD_S - 1e-9 {
            let s = self.sticks;
            assert_eq!(self.send_sticks(s), CommandOutcome::Accepted);
        }
        self.core.step();
        let texts = self.core.pilot_mut().ap.drain_status_texts();
        self.texts.extend(texts);
    }

    fn run(&mut self, seconds: f64) {
        for _ in 0..self.core.steps(seconds) {
            self.step();
        }
    }

    /// Run until `done` holds or `max_s` passes; whether it held.
    fn run_until(&mut self, max_s: f64, mut done: impl FnMut(&Telemetry) -> bool) -> bool {
        for _ in 0..self.core.steps(max_s) {
            self.step();
            if done(&self.telemetry()) {
                return true;
            }
        }
        false
    }

    fn telemetry(&mut self) -> Telemetry {
        let r = self.readings();
        self.core.pilot().ap.telemetry(&r)
    }

    /// The world's (true) measurement, never the misled one.
    /// The plant's true state (not the navigation solution, which drifts while the fix is lost).
    fn truth(&self) -> rotorpilot::sim::RigidBodyState {
        *self.core.core().world().plant(0).state()
    }

    fn mode(&self) -> FlightMode {
        self.core.pilot().ap.mode()
    }

    fn armed(&self) -> bool {
        self.core.pilot().ap.armed()
    }

    fn said(&self, severity: Severity, text: &str) -> bool {
        self.texts.iter().any(|t| t.severity == severity && t.text == text)
    }

    fn gps(&mut self, available: bool) {
        self.core.gps(available);
    }

    /// Take off in `mode` with full-ish throttle to about `height` m, then centre.
    fn climb_in(&mut self, mode: FlightMode, throttle: f64, height: f64) {
        let low = if matches!(mode, FlightMode::Position | FlightMode::Altitude) {
            0.0
        } else {
            -1.0
        };
        self.send_sticks(sticks(0.0, 0.0, low, 0.0));
        assert_eq!(self.command(AutopilotCommand::SetMode(mode)), CommandOutcome::Accepted);
        assert_eq!(
            self.command(AutopilotCommand::Arm { force: false }),
            CommandOutcome::Accepted
        );
        self.sticks = sticks(0.0, 0.0, throttle, 0.0);
        assert!(
            self.run_until(20.0, |t| -t.position_ned.z > height),
            "climbs in {mode:?}"
        );
    }
}

fn sticks(pitch: f64, roll: f64, throttle: f64, yaw: f64) -> ManualControl {
    ManualControl {
        pitch,
        roll,
        throttle,
        yaw,
    }
}

/// Take off (AUTO) to `height` m and hold.
fn auto_hover(v: &mut Vehicle, height: f64) {
    assert_eq!(
        v.command(AutopilotCommand::Arm { force: false }),
        CommandOutcome::Accepted
    );
    let alt = HOME.alt_amsl_m + height;
    assert_eq!(
        v.command(AutopilotCommand::Takeoff {
            altitude_amsl_m: Some(alt)
        }),
        CommandOutcome::Accepted
    );
    assert!(v.run_until(30.0, |t| t.mode == FlightMode::Hold), "takeoff completes");
    v.run(2.0);
}

#[test]
fn manual_modes_need_sticks_and_a_low_throttle_to_arm() {
    let mut v = Vehicle::new(&[]);
    for mode in [
        FlightMode::Position,
        FlightMode::Altitude,
        FlightMode::Stabilized,
        FlightMode::Acro,
        FlightMode::Manual,
    ] {
        assert_eq!(
            v.command(AutopilotCommand::SetMode(mode)),
            CommandOutcome::TemporarilyRejected("no manual control input"),
            "{mode:?} without sticks"
        );
    }
    assert_eq!(v.mode(), FlightMode::Hold);
    v.run(0.001);
    assert!(v.said(Severity::Critical, "Switching to Position denied: no manual control"));
    // sticks out of range are refused
    assert_eq!(
        v.command(AutopilotCommand::ManualControl(sticks(0.0, 0.0, 1.5, 0.0))),
        CommandOutcome::Denied("invalid manual control")
    );
    // sticks that stopped coming (older than COM_RC_LOSS_T = 0.5 s) are no sticks
    v.send_sticks(sticks(0.0, 0.0, 0.0, 0.0));
    v.sending = false;
    v.run(0.6);
    assert_eq!(
        v.command(AutopilotCommand::SetMode(FlightMode::Altitude)),
        CommandOutcome::TemporarilyRejected("no manual control input")
    );
    // Stabilized: centred throttle is thrust, not low: "high throttle"
    v.send_sticks(sticks(0.0, 0.0, 0.0, 0.0));
    assert_eq!(
        v.command(AutopilotCommand::SetMode(FlightMode::Stabilized)),
        CommandOutcome::Accepted
    );
    assert_eq!(v.mode(), FlightMode::Stabilized);
    assert_eq!(
        v.command(AutopilotCommand::Arm { force: false }),
        CommandOutcome::TemporarilyRejected("high throttle")
    );
    // Position: throttle above centre climbs: "throttle above center"
    v.send_sticks(sticks(0.0, 0.0, 0.5, 0.0));
    assert_eq!(
        v.command(AutopilotCommand::SetMode(FlightMode::Position)),
        CommandOutcome::Accepted
    );
    assert_eq!(
        v.command(AutopilotCommand::Arm { force: false }),
        CommandOutcome::TemporarilyRejected("throttle above center")
    );
    v.send_sticks(sticks(0.0, 0.0, 0.0, 0.0));
    assert_eq!(
        v.command(AutopilotCommand::Arm { force: false }),
        CommandOutcome::Accepted
    );
    // armed on the ground with centred sticks: idle, no climb
    let z0 = v.truth().position_ned.z;
    v.run(1.0);
    assert!((v.truth().position_ned.z - z0).abs() < 0.01, "stays on the ground");
    assert!(v.telemetry().throttle < 0.05, "idles");
}

#[test]
fn position_holds_centred_and_flies_at_the_stick_velocity() {
    let mut v = Vehicle::new(&[]);
    v.climb_in(FlightMode::Position, 0.6, 4.0);
    // climb rate at throttle 0.6: (0.6 - 0.1) / 0.9 * MPC_Z_VEL_MAX_UP (3 m/s) = 1.67 m/s
    let climb = -v.truth().velocity_ned.z;
    assert!((climb - 5.0 / 3.0).abs() < 0.15, "climb {climb}");
    v.sticks = ManualControl::CENTRED;
    v.run(3.0);
    let held = v.truth().position_ned;
    v.run(5.0);
    let drift = (v.truth().position_ned - held).norm();
    assert!(drift < 0.1, "centred sticks hold position: drifted {drift} m");
    assert_eq!(v.mode(), FlightMode::Position);
    // half forward: (0.5 - 0.1) / 0.9 * MPC_VEL_MANUAL (10 m/s) = 4.44 m/s north (heading north)
    let yaw = euler_zyx(&v.truth().attitude).z;
    assert!(yaw.abs() < 0.05, "{yaw}");
    v.sticks = sticks(0.5, 0.0, 0.0, 0.0);
    v.run(6.0);
    let vel = v.truth().velocity_ned;
    eprintln!(
        "Position: climb {climb:.3} m/s, hold drift {drift:.4} m in 5 s, velocity at half stick [{:.3}, {:.3}, {:.3}] m/s NED",
        vel.x, vel.y, vel.z
    );
    assert!((vel.x - 40.0 / 9.0).abs() < 0.15, "north {}", vel.x);
    assert!(vel.y.abs() < 0.1 && vel.z.abs() < 0.1, "{vel}");
    assert!((v.truth().position_ned.z - held.z).abs() < 0.2, "altitude kept");
    // centred again: it stops and holds where it stopped
    v.sticks = ManualControl::CENTRED;
    v.run(5.0);
    let stop = v.truth().position_ned;
    v.run(3.0);
    assert!((v.truth().position_ned - stop).norm() < 0.1);
    assert!(v.truth().velocity_ned.norm() < 0.05);
    // yaw stick: turns at deadzoned stick x MPC_MAN_Y_MAX (150 deg/s) -> 0.5 -> 66.7 deg/s
    v.sticks = sticks(0.0, 0.0, 0.0, 0.5);
    v.run(2.0);
    let r = v.truth().rate_frd.z.to_degrees();
    assert!((r - 400.0 / 6.0).abs() < 5.0, "yaw rate {r} deg/s");
}

#[test]
fn altitude_holds_height_centred_and_tilts_with_the_sticks() {
    let mut v = Vehicle::new(&[]);
    v.climb_in(FlightMode::Altitude, 0.6, 4.0);
    v.sticks = ManualControl::CENTRED;
    v.run(3.0);
    let z = v.truth().position_ned.z;
    v.run(4.0);
    assert!(
        (v.truth().position_ned.z - z).abs() < 0.05,
        "centred throttle holds the altitude"
    );
    // roll stick 0.4: tilt 0.4 x MPC_MAN_TILT_MAX (35 deg) = 14 deg, accelerating east
    v.sticks = sticks(0.0, 0.4, 0.0, 0.0);
    v.run(2.0);
    let roll = euler_zyx(&v.truth().attitude).x.to_degrees();
    assert!((roll - 14.0).abs() < 1.0, "roll {roll} deg");
    let east = v.truth().velocity_ned.y;
    assert!(east > 3.0, "accelerates east: {east} m/s");
    assert!((v.truth().position_ned.z - z).abs() < 0.3, "altitude held while tilted");
    // centred: level again, altitude still held; the vehicle drifts on (no position hold)
    v.sticks = ManualControl::CENTRED;
    v.run(2.0);
    let tilt = euler_zyx(&v.truth().attitude).xy().norm().to_degrees();
    assert!(tilt < 1.0, "level {tilt} deg");
    assert!(v.truth().velocity_ned.y > 2.0, "no position hold in Altitude");
    assert!((v.truth().position_ned.z - z).abs() < 0.3);
    // throttle down descends at (0.5 - 0.1) / 0.9 x MPC_Z_VEL_MAX_DN (1.5 m/s) = 0.67 m/s
    v.sticks = sticks(0.0, 0.0, -0.5, 0.0);
    v.run(2.0);
    let sink = v.truth().velocity_ned.z;
    assert!((sink - 2.0 / 3.0).abs() < 0.08, "sink {sink}");
}

#[test]
fn stabilized_and_acro_respond_to_the_sticks() {
    let mut v = Vehicle::new(&[]);
    v.climb_in(FlightMode::Stabilized, 0.4, 3.0);
    // pitch stick forward 0.5: nose down 0.5 x 35 deg
    v.sticks = sticks(0.5, 0.0, 0.1, 0.0);
    v.run(1.0);
    let pitch = euler_zyx(&v.truth().attitude).y.to_degrees();
    assert!((pitch + 17.5).abs() < 1.0, "pitch {pitch} deg");
    assert!(v.truth().velocity_ned.x > 1.0, "flies forward");
    // level, then Acro at about hover thrust: centred sticks keep the attitude
    v.sticks = sticks(0.0, 0.0, 0.0, 0.0);
    v.run(2.0);
    let tel = v.telemetry();
    let hover_throttle = 2.0 * tel.throttle - 1.0;
    v.sticks = sticks(0.0, 0.0, hover_throttle, 0.0);
    assert_eq!(
        v.command(AutopilotCommand::SetMode(FlightMode::Acro)),
        CommandOutcome::Accepted
    );
    let q0 = v.truth().attitude;
    v.run(1.0);
    assert!(
        v.truth().attitude.angle_to(&q0) < 0.05,
        "centred sticks hold the attitude"
    );
    // yaw stick 0.5: superexpo(0.5, 0.69, 0.7) x MC_ACRO_Y_MAX (540 deg/s) = 60.1 deg/s
    v.sticks = sticks(0.0, 0.0, hover_throttle, 0.5);
    v.run(1.0);
    let r = v.truth().rate_frd.z.to_degrees();
    let e = 0.69;
    let g = 0.7;
    let want = ((1.0 - e) * 0.5 + e * 0.125) * (1.0 - g) / (1.0 - 0.5 * g) * 540.0;
    assert!((r - want).abs() < 0.05 * want, "yaw rate {r}, want {want} deg/s");
    // a roll stick pulse of 0.3 s rolls by its rate x 0.3 s and stays there; the opposite pulse rolls back
    v.sticks = sticks(0.0, 0.0, hover_throttle, 0.0);
    v.run(0.5);
    let roll0 = euler_zyx(&v.truth().attitude).x;
    v.sticks = sticks(0.0, 0.3, hover_throttle, 0.0);
    v.run(0.15);
    let p = v.truth().rate_frd.x.to_degrees();
    v.run(0.15);
    v.sticks = sticks(0.0, 0.0, hover_throttle, 0.0);
    v.run(0.3);
    let rolled = (euler_zyx(&v.truth().attitude).x - roll0).to_degrees();
    let want = ((1.0 - e) * 0.3 + e * 0.027) * (1.0 - g) / (1.0 - 0.3 * g) * 720.0;
    assert!(
        (rolled - 0.3 * want).abs() < 0.05 * 0.3 * want,
        "rolled {rolled} deg, want {} deg",
        0.3 * want
    );
    assert!((p - want).abs() < 0.2 * want, "roll rate {p}, want {want} deg/s");
    v.sticks = sticks(0.0, -0.3, hover_throttle, 0.0);
    v.run(0.3);
    v.sticks = sticks(0.0, 0.0, hover_throttle, 0.0);
    v.run(0.5);
    let roll = euler_zyx(&v.truth().attitude).x.to_degrees();
    assert!(roll.abs() < 2.0, "rolled back: {roll} deg");
    assert!(v.armed() && -v.truth().position_ned.z > 1.0);
}

#[test]
fn losing_the_sticks_in_a_manual_mode_returns_and_not_in_hold_or_mission() {
    // Position: NAV_RCL_ACT default (2) returns (at once: COM_FAIL_ACT_T 0)
    let mut v = Vehicle::new(&[("COM_FAIL_ACT_T", real(0.0))]);
    v.climb_in(FlightMode::Position, 0.6, 4.0);
    v.sticks = ManualControl::CENTRED;
    v.run(1.0);
    v.sending = false;
    let last = v.last_sent_s;
    assert!(v.run_until(2.0, |t| t.mode == FlightMode::ReturnToLaunch));
    let after = v.core.time_s() - last;
    assert!(
        after > 0.5 && after < 0.5 + 0.01,
        "lost COM_RC_LOSS_T after the last sticks: {after} s"
    );
    assert!(v.said(Severity::Critical, "Manual control lost"));
    // NAV_RCL_ACT 3: land, after PX4's COM_FAIL_ACT_T (5 s) in Hold
    let mut v = Vehicle::new(&[("NAV_RCL_ACT", ParamValue::Int32(3))]);
    v.climb_in(FlightMode::Altitude, 0.6, 3.0);
    v.sending = false;
    assert!(v.run_until(1.0, |t| t.mode == FlightMode::Hold));
    let held = v.core.time_s();
    assert!(v.run_until(6.0, |t| t.mode == FlightMode::Land));
    let waited = v.core.time_s() - held;
    assert!((waited - 5.0).abs() < 0.01, "landed {waited} s after Hold");
    // Hold with sticks that stop: nothing happens
    let mut v = Vehicle::new(&[]);
    auto_hover(&mut v, 5.0);
    v.send_sticks(ManualControl::CENTRED);
    v.run(1.0);
    v.sending = false;
    v.run(3.0);
    assert_eq!(v.mode(), FlightMode::Hold);
    assert!(!v.said(Severity::Critical, "Manual control lost"));
    // Mission with sticks that stop: nothing happens either
    let mut v = Vehicle::new(&[]);
    let target = HOME.offset(&Vector3::new(30.0, 0.0, -5.0));
    let at = |command: u16, lat_deg: f64, lon_deg: f64| MissionItem {
        frame: frame::GLOBAL_RELATIVE_ALT,
        command,
        autocontinue: true,
        params: [0.0, 0.0, 0.0, f32::NAN],
        x: lat_deg,
        y: lon_deg,
        z: 5.0,
    };
    let items = vec![
        at(cmd::NAV_TAKEOFF, HOME.lat_deg, HOME.lon_deg),
        at(cmd::NAV_WAYPOINT, target.lat_deg, target.lon_deg),
    ];
    v.core
        .pilot_mut()
        .ap
        .change_plans(PlanChange::Store {
            kind: MissionType::Mission,
            items,
            base_id: None,
        })
        .unwrap();
    v.send_sticks(ManualControl::CENTRED);
    assert_eq!(
        v.command(AutopilotCommand::StartMission { first: None }),
        CommandOutcome::Accepted
    );
    v.run(1.0);
    v.sending = false;
    v.run(4.0);
    assert_eq!(v.mode(), FlightMode::Mission);
    assert!(!v.said(Severity::Critical, "Manual control lost"));
}

#[test]
fn gps_loss_descends_where_it_was_lost_without_the_horizontal_position() {
    let mut v = Vehicle::new(&[]);
    auto_hover(&mut v, 8.0);
    let lost_at = v.truth().position_ned;
    // while the fix is lost, the navigation solution says 40 m off and drifting 1 m/s
    {
        let p = v.core.pilot_mut();
        p.offset = Vector3::new(40.0, -25.0, 0.0);
        p.drift = Vector3::new(1.0, 0.5, 0.0);
    }
    v.gps(false);
    v.run(0.01);
    assert_eq!(v.mode(), FlightMode::Descend);
    assert!(v.said(Severity::Critical, "No GPS fix: descending without position"));
    // the heartbeat shows AUTO.LAND for Descend
    assert_eq!(rotorpilot::link::convert::custom_mode(v.telemetry().mode), 100_925_440);
    // modes that need a position are refused meanwhile
    assert_eq!(
        v.command(AutopilotCommand::SetMode(FlightMode::Hold)),
        CommandOutcome::TemporarilyRejected("no position estimate")
    );
    let mut worst: f64 = 0.0;
    let mut max_tilt: f64 = 0.0;
    let mut landed = false;
    for _ in 0..30_000 {
        v.step();
        let truth = v.truth();
        worst = worst.max((truth.position_ned.xy() - lost_at.xy()).norm());
        max_tilt = max_tilt.max(euler_zyx(&truth.attitude).xy().norm());
        if !v.armed() {
            landed = true;
            break;
        }
    }
    eprintln!(
        "GPS loss at {:.1} m: landed {worst:.3} m from where the fix was lost, largest tilt {:.2} deg, at {:.1} s",
        -lost_at.z,
        max_tilt.to_degrees(),
        v.core.time_s()
    );
    assert!(landed, "lands and disarms");
    assert_eq!(v.mode(), FlightMode::Hold, "disarmed: Hold");
    assert!(worst < 1.0, "landed {worst} m from where the fix was lost");
    assert!(
        max_tilt.to_degrees() < 2.0,
        "level all the way down: {} deg",
        max_tilt.to_degrees()
    );
    assert!(v.truth().position_ned.z > -0.3, "on the ground");
}

#[test]
fn gps_back_before_touchdown_holds_there() {
    let mut v = Vehicle::new(&[]);
    auto_hover(&mut v, 8.0);
    v.gps(false);
    v.run(3.0);
    assert_eq!(v.mode(), FlightMode::Descend);
    let z_lost = v.truth().position_ned.z;
    assert!(z_lost > -7.5, "descending: {z_lost}");
    v.gps(true);
    v.run(0.01);
    assert_eq!(v.mode(), FlightMode::Hold);
    assert!(v.said(Severity::Warning, "GPS fix regained: holding position"));
    v.run(3.0);
    let p = v.truth().position_ned;
    v.run(3.0);
    assert!((v.truth().position_ned - p).norm() < 0.05, "holds");
    assert!(v.armed() && -p.z > 5.0, "stopped descending at {}", -p.z);
}

#[test]
fn position_falls_back_to_altitude_without_gps_and_back() {
    let mut v = Vehicle::new(&[]);
    v.climb_in(FlightMode::Position, 0.6, 4.0);
    v.sticks = ManualControl::CENTRED;
    v.run(2.0);
    v.gps(false);
    v.run(0.01);
    assert_eq!(v.mode(), FlightMode::Altitude);
    assert!(v.said(Severity::Critical, "No GPS fix: Position falls back to Altitude"));
    // the pilot still flies it: throttle climbs
    let z = v.truth().position_ned.z;
    v.sticks = sticks(0.0, 0.0, 0.6, 0.0);
    v.run(2.0);
    assert!(v.truth().position_ned.z < z - 2.0, "climbs");
    v.sticks = ManualControl::CENTRED;
    v.gps(true);
    v.run(0.01);
    assert_eq!(v.mode(), FlightMode::Position);
    assert!(v.said(Severity::Warning, "GPS fix regained: back to Position"));
}

#[test]
fn above_real_time_the_runtime_times_the_stick_loss_on_the_wall_clock() {
    use rotorpilot::autopilot::{ClientClock, ClientTimer};
    let mut v = Vehicle::new(&[("COM_FAIL_ACT_T", real(0.0))]);
    v.core.pilot_mut().ap.set_client_clock(ClientClock::Wall);
    v.climb_in(FlightMode::Altitude, 0.6, 3.0);
    v.sending = false;
    let last = v.last_sent_s;
    // simulated time alone never declares it lost
    v.run(2.0);
    assert_eq!(v.mode(), FlightMode::Altitude);
    let timers = v.core.pilot().ap.client_timers();
    let t = timers
        .iter()
        .find(|p| p.timer == ClientTimer::ManualControlLoss)
        .expect("the loss timer runs");
    assert_eq!((t.started_s, t.duration_s), (last, 0.5));
    // a stale expiry (a timer since restarted) is ignored; the running one acts
    let r = v.readings();
    let ap = &mut v.core.pilot_mut().ap;
    assert!(!ap.client_timeout(ClientTimer::ManualControlLoss, last - 0.05, &r));
    assert!(ap.client_timeout(ClientTimer::ManualControlLoss, last, &r));
    assert_eq!(ap.mode(), FlightMode::ReturnToLaunch);
    assert!(
        ap.client_timers()
            .iter()
            .all(|p| p.timer != ClientTimer::ManualControlLoss)
    );
}

#[test]
fn nav_rcl_act_0_reads_centred_sticks_after_the_loss() {
    // Altitude, climbing on a high throttle, then the sticks stop: PX4 zeroes
    // the timed-out sticks, so the height is held instead of climbing on
    let mut v = Vehicle::new(&[("NAV_RCL_ACT", ParamValue::Int32(0))]);
    v.climb_in(FlightMode::Altitude, 0.6, 3.0);
    v.sending = false;
    v.run(2.0);
    assert_eq!(v.mode(), FlightMode::Altitude, "NAV_RCL_ACT 0 keeps the mode");
    assert!(v.said(Severity::Critical, "Manual control lost"));
    let z0 = v.truth().position_ned.z;
    v.run(3.0);
    let climbed = z0 - v.truth().position_ned.z;
    println!("NAV_RCL_ACT 0: climbed {climbed:.3} m in 3 s after the loss");
    assert!(climbed.abs() < 0.3, "holds the height, climbed {climbed} m");
}
