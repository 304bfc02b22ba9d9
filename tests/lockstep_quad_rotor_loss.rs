//! A quadrotor that loses a rotor at 10 m hover spins and comes down under
//! control (relaxed hover, Mueller and D'Andrea 2014/2015; doc section 3b).
//!
//! End to end (`autopilot_*` tests): the real `Lockstep<Autopilot>` hovers
//! at 10 m (or 30 m) when the world kills one rotor; the flight stack's rotor
//! monitor detects it from the ESC speeds and the stack flies relaxed hover
//! itself (Land mode, emergency descent at `MPC_LAND_SPEED`, rotors stopped
//! at touchdown, disarmed after the landing). Goals (issue): touchdown within
//! 5 m of the point below the failure, vertical speed under 2 m/s, upright.
//!
//! The controller alone (the other tests): the lockstep core flies an
//! `Autopilot` as it was before relaxed hover was wired in (its airframe
//! without rotational drag, so it cannot build relaxed hover and keeps its
//! best effort) until, after a fixed detection delay (0.05 s and 0.1 s), a
//! test-only pilot hands the vehicle to [`RelaxedHover`] with the known dead
//! rotor. The baseline (that best effort alone) is flown and shown to crash.
//!
//! The plant needs rotational drag for a spin equilibrium to exist: the
//! x500-class `quad` ships with `gamma` = [`GAMMA`] (see its doc).
//! Run with `cargo test --release --test lockstep_quad_rotor_loss -- --nocapture` to see the figures.

use std::collections::VecDeque;

mod common;

use common::sitl::{HOME, Sitl};
use nalgebra::Vector3;
use rotorpilot::airframe::Airframe;
use rotorpilot::autopilot::{
    Autopilot, AutopilotCommand, CommandOutcome, ControlOutput, FlightMode, RotorStatus, Severity, StatusText,
};
use rotorpilot::control::{RelaxedHover, RelaxedHoverPhase};
use rotorpilot::lockstep::Pilot;
use rotorpilot::signals::{ActuatorCommand, DEFAULT_STEP_S, GRAVITY, SensorReadings};
use rotorpilot::sim::{Fault, RotorHealth, SensorNoise, SimFault, StepEvent};

/// Rotational drag of the x500-class quad [N m s]: PX4's gz x500 model gives
/// each rotor the drag force `-c_d |omega_i| v_perp` (`rotorDragCoefficient`
/// `c_d = 8.06428e-5` N s^2/m); a yaw rate `r` moves each hub at
/// `l r`, so `gamma = c_d l^2 sum_i |omega_i|` = 8.06e-5 x 0.2461^2 x (2600 to 3030)
/// = 0.0127 to 0.0148 N m s (three rotors in relaxed hover, four in hover).
const GAMMA: f64 = 0.013;

/// Top rotor speed of the stronger quad the goals are flown with [rad/s] (see [`stronger_quad`]).
const STRONGER_SPEED_MAX_RAD_S: f64 = 1100.0;

/// Hover height when the rotor dies [m] (the issue's).
const HEIGHT_M: f64 = 10.0;
/// Commanded descent speed under relaxed hover [m/s].
const DESCENT_M_S: f64 = 0.7;

/// Goals of the issue.
const MAX_DISTANCE_M: f64 = 5.0;
const MAX_TOUCHDOWN_SPEED_M_S: f64 = 2.0;
/// "Upright": the thrust axis within this angle of the vertical at touchdown [deg]
/// (relaxed hover flies tilted by its equilibrium angle, about 21 deg here).
const MAX_TOUCHDOWN_TILT_DEG: f64 = 35.0;

/// The shipped x500-class quad (PX4's gz x500: `omega_max` = 1000 rad/s,
/// thrust/weight 1.74, rotational drag [`GAMMA`]) without its `[aero]`
/// table: relaxed hover's equilibrium spin is the rotational-drag model's.
fn quad() -> Airframe {
    let mut af = Airframe::load("quad").unwrap();
    af.aero = rotorpilot::airframe::AeroCoefficients::default();
    assert_eq!(af.rotational_drag_n_m_s, GAMMA, "the shipped quad's rotational drag");
    af
}

/// `af` as the flight stack saw it before relaxed hover was wired in: no
/// rotational drag in its model, so it cannot build relaxed hover and keeps
/// the best effort (yaw given up, land).
fn without_drag(af: &Airframe) -> Airframe {
    let mut af = af.clone();
    af.rotational_drag_n_m_s = 0.0;
    af
}

/// The same quad with motors 10 % faster (`omega_max` = 1100 rad/s: thrust/weight
/// 2.1 instead of 1.74). The shipped x500 cannot meet the goals from 10 m on three
/// rotors: its relaxed-hover equilibrium already needs 94.5 % of the top thrust
/// of the two rotors next to the dead one (vertical thrust/weight 1.06 at full
/// speed), so the speed it gains while the spin builds up (about 2 s) cannot be
/// taken out before the ground ([`shipped_x500_reaches_relaxed_hover_but_lacks_thrust`]).
fn stronger_quad() -> Airframe {
    let mut af = quad();
    af.rotor.speed_max_rad_s = STRONGER_SPEED_MAX_RAD_S;
    af
}

/// The real autopilot until the rotor dies; after the detection delay,
/// relaxed hover with the dead rotor known (or never, for the baseline).
struct LossPilot {
    /// Without rotational drag in its model ([`without_drag`]).
    autopilot: Autopilot,
    /// The airframe relaxed hover is built for (the plant's).
    airframe: Airframe,
    /// When relaxed hover takes over [s], which rotor died, and the point to land on.
    takeover: Option<(f64, usize, Vector3<f64>)>,
    hover: Option<RelaxedHover>,
    output: ControlOutput,
}

impl Pilot for LossPilot {
    fn decide(&mut self, readings: &SensorReadings) {
        let t = readings.measurement.time_s;
        if self.hover.is_none()
            && let Some((at, dead, _)) = self.takeover
            && t >= at - 1e-9
        {
            let af = &self.airframe;
            self.hover = Some(RelaxedHover::new(af, &af.nominal(), dead).expect("relaxed hover for the quad"));
        }
        if let (Some(hover), Some((_, _, target))) = (&mut self.hover, self.takeover) {
            let speeds = hover.update(&readings.measurement, target, DESCENT_M_S, DEFAULT_STEP_S);
            self.output.actuator = match hover.phase() {
                RelaxedHoverPhase::Landed => ActuatorCommand::Stop,
                RelaxedHoverPhase::Descending => ActuatorCommand::RotorSpeeds(speeds),
            };
        } else {
            self.autopilot.step(readings);
            self.output = *self.autopilot.output();
        }
    }

    fn output(&self) -> &ControlOutput {
        &self.output
    }

    fn rotors_stopped(&mut self, why: &SimFault) {
        self.autopilot.rotors_stopped(&why.to_string());
    }
}

fn command(ls: &mut Sitl<LossPilot>, cmd: AutopilotCommand) -> CommandOutcome {
    let readings = ls.readings();
    ls.pilot_mut().autopilot.command(cmd, &readings)
}

/// The vehicle hovering at `height_m` after the autopilot's takeover and a settle.
fn hovering_at(af: &Airframe, height_m: f64) -> Sitl<LossPilot> {
    let mut ls = Sitl::of(af.clone()).build_with(|af, store| LossPilot {
        autopilot: Autopilot::new(&without_drag(af), HOME, store, DEFAULT_STEP_S).unwrap(),
        airframe: af.clone(),
        takeover: None,
        hover: None,
        output: ControlOutput::default(),
    });
    ls.step();
    assert_eq!(
        command(&mut ls, AutopilotCommand::Arm { force: false }),
        CommandOutcome::Accepted
    );
    assert_eq!(
        command(
            &mut ls,
            AutopilotCommand::Takeoff {
                altitude_amsl_m: Some(HOME.alt_amsl_m + height_m)
            }
        ),
        CommandOutcome::Accepted
    );
    // up to Hold (a noisy navigation solution may keep the takeoff from
    // declaring itself complete: then whatever holds it at the height)
    for _ in 0..120_000 {
        ls.step();
        if ls.pilot().autopilot.mode() == FlightMode::Hold {
            break;
        }
    }
    for _ in 0..3000 {
        ls.step();
    }
    let p = ls.core().world().plant(0).state().position_ned;
    assert!((-p.z - height_m).abs() < 0.3, "hovering at {height_m} m: {p}");
    ls
}

/// What happened between the rotor failure and touchdown.
#[derive(Debug)]
struct Outcome {
    /// Horizontal distance from the point below the failure at touchdown [m].
    distance_m: f64,
    /// Vertical speed at contact [m/s].
    touchdown_speed_m_s: f64,
    /// Angle of the thrust axis from the vertical just before contact [deg].
    touchdown_tilt_deg: f64,
    /// Largest such angle during the descent [deg].
    max_tilt_deg: f64,
    /// Mean yaw rate over the last 2 s before contact [rad/s], body z.
    spin_rad_s: f64,
    /// Largest horizontal excursion from the point below the failure [m].
    max_excursion_m: f64,
    /// Time from the failure to touchdown [s].
    descent_s: f64,
    /// Lowest height reached during the first 3 s after the failure [m].
    min_height_first_3s_m: f64,
    /// Rotor speeds were commanded to stop after touchdown.
    rotors_cut: bool,
}

/// Kill rotor `dead` of `af` hovering at `height_m`; relaxed hover takes over after `delay_s` (or never).
fn fly(af: &Airframe, height_m: f64, dead: usize, delay_s: Option<f64>) -> Outcome {
    fly_with(af, height_m, dead, delay_s, None)
}

/// [`fly`] with the navigation solution's noise `noise` from the failure on.
fn fly_with(af: &Airframe, height_m: f64, dead: usize, delay_s: Option<f64>, noise: Option<SensorNoise>) -> Outcome {
    let mut ls = hovering_at(af, height_m);
    let t_fail = ls.time_s();
    let p_fail = ls.core().world().plant(0).state().position_ned;
    let target = Vector3::new(p_fail.x, p_fail.y, 0.0);
    ls.inject(Fault::Rotor {
        rotor: dead,
        health: RotorHealth::Off,
    });
    if noise.is_some() {
        ls.inject(Fault::SensorNoise(noise));
    }
    if let Some(d) = delay_s {
        ls.pilot_mut().takeover = Some((t_fail + d, dead, target));
    }
    let (mut max_tilt, mut max_exc, mut min_h) = (0.0_f64, 0.0_f64, f64::INFINITY);
    let trace = std::env::var_os("QUAD_TRACE").is_some();
    let mut spins: VecDeque<f64> = VecDeque::with_capacity(2001);
    for _ in 0..300_000 {
        ls.step();
        let report = *ls.core().world().last_report(0);
        let s = report.truth;
        let tilt = (s.attitude * Vector3::z()).z.clamp(-1.0, 1.0).acos().to_degrees();
        max_tilt = max_tilt.max(tilt);
        let horizontal = Vector3::new(s.position_ned.x - p_fail.x, s.position_ned.y - p_fail.y, 0.0).norm();
        max_exc = max_exc.max(horizontal);
        if report.truth.position_ned.z.is_finite() && ls.time_s() - t_fail < 3.0 {
            min_h = min_h.min(-s.position_ned.z);
        }
        if trace && ls.core().world().plant(0).time_s().rem_euclid(0.05) < 0.5e-3 {
            let speeds = ls.core().world().plant(0).rotor_speeds();
            eprintln!(
                "t {:6.3} h {:6.2} v {:6.2} x {:6.2} y {:6.2} tilt {:5.1} w [{:6.2} {:6.2} {:6.2}] rotors [{:4.0} {:4.0} {:4.0} {:4.0}]",
                ls.time_s() - t_fail,
                -s.position_ned.z,
                s.velocity_ned.z,
                s.position_ned.x - p_fail.x,
                s.position_ned.y - p_fail.y,
                tilt,
                s.rate_frd.x,
                s.rate_frd.y,
                s.rate_frd.z,
                speeds[0],
                speeds[1],
                speeds[2],
                speeds[3]
            );
        }
        spins.push_back(s.rate_frd.z);
        if spins.len() > 2000 {
            spins.pop_front();
        }
        if let StepEvent::Touchdown { speed_m_s } = report.event {
            let after = ls.core().world().plant(0).state().position_ned;
            for _ in 0..500 {
                ls.step();
            }
            let rotors_cut = matches!(ls.pilot().output().actuator, ActuatorCommand::Stop);
            return Outcome {
                distance_m: Vector3::new(after.x - p_fail.x, after.y - p_fail.y, 0.0).norm(),
                touchdown_speed_m_s: speed_m_s,
                touchdown_tilt_deg: tilt,
                max_tilt_deg: max_tilt,
                spin_rad_s: spins.iter().sum::<f64>() / spins.len() as f64,
                max_excursion_m: max_exc.max(horizontal),
                descent_s: ls.time_s() - 0.5 - t_fail,
                min_height_first_3s_m: min_h,
                rotors_cut,
            };
        }
    }
    panic!("rotor {} dead: no touchdown within 120 s", dead + 1);
}

fn report(af: &Airframe, height_m: f64, dead: usize, delay_s: f64) -> (Outcome, f64) {
    report_with(af, height_m, dead, delay_s, None)
}

fn report_with(af: &Airframe, height_m: f64, dead: usize, delay_s: f64, noise: Option<SensorNoise>) -> (Outcome, f64) {
    let hover = RelaxedHover::new(af, &af.nominal(), dead).unwrap();
    let eq = *hover.equilibrium();
    let o = fly_with(af, height_m, dead, Some(delay_s), noise);
    println!(
        "{} (omega_max {} rad/s), {height_m} m, rotor {} dead, detection {:.2} s: equilibrium spin {:.2} rad/s about n = [{:.3}, {:.3}, {:.3}], tilt {:.1} deg, rho {:.2}; \
         flown: touchdown {:.2} m from below the failure (max {:.2} m), {:.2} m/s, tilt {:.1} deg (max {:.1}), \
         mean yaw rate last 2 s {:.2} rad/s, descent {:.1} s, lowest height in the first 3 s {:.2} m",
        af.name,
        af.rotor.speed_max_rad_s,
        dead + 1,
        delay_s,
        eq.spin_rad_s,
        eq.up_frd.x,
        eq.up_frd.y,
        eq.up_frd.z,
        eq.tilt_rad.to_degrees(),
        eq.opposite_ratio,
        o.distance_m,
        o.max_excursion_m,
        o.touchdown_speed_m_s,
        o.touchdown_tilt_deg,
        o.max_tilt_deg,
        o.spin_rad_s,
        o.descent_s,
        o.min_height_first_3s_m,
    );
    // the yaw rate relaxed hover predicts: w_bar n_z
    (o, eq.spin_rad_s * eq.up_frd.z)
}

/// The controller alone after a fixed detection delay (the every-rotor cases at
/// the monitor's 0.05 s are flown end to end by the autopilot itself:
/// [`autopilot_flies_relaxed_hover_to_the_ground_on_every_rotor`]).
fn check(dead: usize, delay_s: f64) {
    check_with(dead, delay_s, None);
}

fn check_with(dead: usize, delay_s: f64, noise: Option<SensorNoise>) {
    let af = stronger_quad();
    let (o, predicted) = report_with(&af, HEIGHT_M, dead, delay_s, noise);
    assert!(o.distance_m < MAX_DISTANCE_M, "rotor {}: {o:?}", dead + 1);
    assert!(
        o.touchdown_speed_m_s < MAX_TOUCHDOWN_SPEED_M_S,
        "rotor {}: {o:?}",
        dead + 1
    );
    assert!(
        o.touchdown_tilt_deg < MAX_TOUCHDOWN_TILT_DEG,
        "rotor {}: {o:?}",
        dead + 1
    );
    assert!(
        o.rotors_cut,
        "rotor {}: rotors still commanded after touchdown",
        dead + 1
    );
    // it spins as relaxed hover predicts (yaw rate = w_bar n_z), within 20 %
    assert!(
        (o.spin_rad_s - predicted).abs() < 0.2 * predicted.abs(),
        "rotor {}: yaw rate {} vs equilibrium {predicted}",
        dead + 1,
        o.spin_rad_s
    );
    // a controlled descent, not a fall: it took at least (10 m - 0.24 m) / 2 m/s
    assert!(o.descent_s > (HEIGHT_M - 0.24) / MAX_TOUCHDOWN_SPEED_M_S, "{o:?}");
}

/// The same with the golden noisy flight's navigation noise (1 cm, 2 cm/s,
/// 2 mrad, 0.01 rad/s) from the failure on (injected as a fault: the
/// vehicle's sensor seed is the default).
#[test]
fn noisy_sensors_still_land_every_rotor() {
    let noise = SensorNoise {
        position_m: 0.01,
        velocity_m_s: 0.02,
        attitude_rad: 0.002,
        rate_rad_s: 0.01,
    };
    for dead in 0..4 {
        check_with(dead, 0.05, Some(noise));
    }
}

/// The shipped x500 on three rotors: the equilibrium needs almost all the
/// thrust of two rotors, and from 10 m it meets the ground too fast; from
/// 50 m it settles into relaxed hover (spin, tilt, position as predicted) but,
/// with 6 % of vertical thrust to spare at full speed, still cannot slow to
/// the commanded descent before the ground. Figures printed, limits asserted.
#[test]
fn shipped_x500_reaches_relaxed_hover_but_lacks_thrust() {
    let af = quad();
    let hover = RelaxedHover::new(&af, &af.nominal(), 0).unwrap();
    let eq = *hover.equilibrium();
    let top = af.rotor.c_t * af.rotor.speed_max_rad_s.powi(2);
    let largest = eq.thrust_n.iter().copied().fold(0.0, f64::max);
    println!(
        "x500 equilibrium: rotor thrusts {:.3} N of {top:.3} N at most ({:.1} %)",
        eq.thrust_n.rows(0, 4).transpose(),
        100.0 * largest / top
    );
    assert!(largest / top > 0.9 && largest / top < 1.0, "{eq:?}");
    let (low, _) = report(&af, HEIGHT_M, 0, 0.05);
    let (high, predicted) = report(&af, 50.0, 0, 0.05);
    // from 50 m: relaxed hover established and the position held, upright
    assert!((high.spin_rad_s - predicted).abs() < 0.15 * predicted.abs(), "{high:?}");
    assert!(high.distance_m < 1.0, "{high:?}");
    assert!(high.touchdown_tilt_deg < MAX_TOUCHDOWN_TILT_DEG, "{high:?}");
    // from 10 m: too little time to build the spin and brake
    println!(
        "x500 from 10 m: {:.2} m/s at touchdown; from 50 m: {:.2} m/s",
        low.touchdown_speed_m_s, high.touchdown_speed_m_s
    );
}

#[test]
fn slower_detection_still_lands_every_rotor() {
    for dead in 0..4 {
        check(dead, 0.1);
    }
}

/// The baseline: the normal controller alone (the flight stack's best effort
/// without relaxed hover: yaw given up, land) cannot hold attitude with three
/// rotors (no static hover exists, doc section 3b) and comes down out of
/// control, on the stronger quad the goals are flown with as on the shipped one.
#[test]
fn normal_controller_alone_crashes() {
    for (af, dead) in [stronger_quad(), quad()]
        .iter()
        .flat_map(|af| (0..4).map(move |d| (af, d)))
    {
        let o = fly(af, HEIGHT_M, dead, None);
        println!(
            "baseline, {} (omega_max {} rad/s), rotor {} dead, normal controller only: touchdown {:.2} m away, {:.2} m/s, tilt {:.1} deg (max {:.1}), after {:.2} s",
            af.name,
            af.rotor.speed_max_rad_s,
            dead + 1,
            o.distance_m,
            o.touchdown_speed_m_s,
            o.touchdown_tilt_deg,
            o.max_tilt_deg,
            o.descent_s
        );
        assert!(
            o.touchdown_speed_m_s > MAX_TOUCHDOWN_SPEED_M_S || o.max_tilt_deg > 90.0,
            "the normal controller was expected to lose the vehicle: {o:?}"
        );
    }
}

// ----- end to end: the flight stack flies relaxed hover itself -------------------------------------

/// What the real autopilot made of a rotor loss.
#[derive(Debug)]
struct EndToEnd {
    /// From the failure to the monitor's verdict Failed [s].
    detect_s: f64,
    /// Horizontal distance from the point below the failure at touchdown [m].
    distance_m: f64,
    /// Vertical speed at contact [m/s].
    touchdown_speed_m_s: f64,
    /// Angle of the thrust axis from the vertical at contact [deg].
    touchdown_tilt_deg: f64,
    /// Largest such angle during the descent [deg].
    max_tilt_deg: f64,
    /// Mean yaw rate over the last 2 s before contact [rad/s], body z.
    spin_rad_s: f64,
    /// From the failure to touchdown [s].
    descent_s: f64,
    /// Flight mode every step between the detection and touchdown was Land.
    land_mode: bool,
    /// The actuators were commanded Stop from 0.1 s after touchdown on.
    rotors_stopped: bool,
    /// From touchdown to disarm [s] (None: still armed 10 s after touchdown).
    disarm_after_s: Option<f64>,
    /// Every status text from the failure on.
    texts: Vec<StatusText>,
}

/// The real `Lockstep<Autopilot>` on `af`, hovering at `height_m`, loses rotor `dead`.
fn autopilot_loss(af: &Airframe, height_m: f64, dead: usize) -> EndToEnd {
    let mut ls = Sitl::of(af.clone()).build();
    ls.step();
    ls.arm_and_take_off(Some(height_m));
    for _ in 0..120_000 {
        ls.step();
        if ls.pilot().mode() == FlightMode::Hold {
            break;
        }
    }
    for _ in 0..3000 {
        ls.step();
    }
    let p_fail = ls.core().world().plant(0).state().position_ned;
    assert!((-p_fail.z - height_m).abs() < 0.3, "hovering at {height_m} m: {p_fail}");
    ls.texts();
    let t_fail = ls.time_s();
    ls.inject(Fault::Rotor {
        rotor: dead,
        health: RotorHealth::Off,
    });
    let mut texts = Vec::new();
    let (mut detect_s, mut max_tilt, mut land_mode) = (None, 0.0_f64, true);
    let mut spins: VecDeque<f64> = VecDeque::with_capacity(2001);
    for _ in 0..300_000 {
        ls.step();
        texts.extend(ls.texts());
        let report = *ls.core().world().last_report(0);
        let s = report.truth;
        let tilt = (s.attitude * Vector3::z()).z.clamp(-1.0, 1.0).acos().to_degrees();
        max_tilt = max_tilt.max(tilt);
        spins.push_back(s.rate_frd.z);
        if spins.len() > 2000 {
            spins.pop_front();
        }
        if detect_s.is_none() && ls.pilot().rotor_status()[dead] == RotorStatus::Failed {
            detect_s = Some(ls.time_s() - t_fail);
        }
        if detect_s.is_some() {
            land_mode &= ls.pilot().mode() == FlightMode::Land;
        }
        if let StepEvent::Touchdown { speed_m_s } = report.event {
            let t_down = ls.time_s();
            let after = ls.core().world().plant(0).state().position_ned;
            let mut rotors_stopped = true;
            let mut disarm_after_s = None;
            for k in 0..10_000 {
                ls.step();
                texts.extend(ls.texts());
                if k >= 100 && ls.pilot().armed() {
                    rotors_stopped &= matches!(ls.pilot().output().actuator, ActuatorCommand::Stop);
                }
                if !ls.pilot().armed() {
                    disarm_after_s = Some(ls.time_s() - t_down);
                    break;
                }
            }
            return EndToEnd {
                detect_s: detect_s.expect("the monitor flagged the rotor before touchdown"),
                distance_m: Vector3::new(after.x - p_fail.x, after.y - p_fail.y, 0.0).norm(),
                touchdown_speed_m_s: speed_m_s,
                touchdown_tilt_deg: tilt,
                max_tilt_deg: max_tilt,
                spin_rad_s: spins.iter().sum::<f64>() / spins.len() as f64,
                descent_s: t_down - t_fail,
                land_mode,
                rotors_stopped,
                disarm_after_s,
                texts,
            };
        }
    }
    panic!("rotor {} dead: no touchdown within 300 s", dead + 1);
}

/// Fly [`autopilot_loss`], print the figures, check what every case must
/// show: detected by the monitor within 0.1 s, Land mode throughout, the
/// emergency announced (Emergency, and the Critical "Motor j failed: yaw
/// given up, descending"), upright (thrust axis within 35 deg of vertical),
/// rotors stopped after touchdown, disarmed by the landing.
fn autopilot_case(af: &Airframe, height_m: f64, dead: usize) -> EndToEnd {
    let o = autopilot_loss(af, height_m, dead);
    println!(
        "autopilot, {} (omega_max {} rad/s), {height_m} m, rotor {} dead: detected after {:.3} s; touchdown {:.2} m from below the failure, \
         {:.2} m/s, tilt {:.1} deg (max {:.1}), mean yaw rate last 2 s {:.2} rad/s, descent {:.1} s, disarmed {:?} s after touchdown",
        af.name,
        af.rotor.speed_max_rad_s,
        dead + 1,
        o.detect_s,
        o.distance_m,
        o.touchdown_speed_m_s,
        o.touchdown_tilt_deg,
        o.max_tilt_deg,
        o.spin_rad_s,
        o.descent_s,
        o.disarm_after_s
    );
    // the texts name the motor by its number (PX4's quad-X numbering)
    let label = af.motor_of_rotor(dead);
    assert!(o.detect_s < 0.1, "motor {label}: {o:?}");
    assert!(o.land_mode, "motor {label}: not in Land mode throughout: {o:?}");
    assert!(
        o.texts
            .iter()
            .any(|t| t.severity == Severity::Critical
                && t.text == format!("Motor {label} failed: yaw given up, descending")),
        "{:?}",
        o.texts
    );
    assert!(
        o.texts
            .iter()
            .any(|t| t.severity == Severity::Emergency && t.text.contains("emergency descent")),
        "{:?}",
        o.texts
    );
    assert!(o.touchdown_tilt_deg < MAX_TOUCHDOWN_TILT_DEG, "motor {label}: {o:?}");
    assert!(
        o.rotors_stopped,
        "motor {label}: rotors still commanded after touchdown: {o:?}"
    );
    assert!(o.disarm_after_s.is_some(), "motor {label}: not disarmed: {o:?}");
    assert!(o.texts.iter().any(|t| t.text == "Disarmed by landing"), "{:?}", o.texts);
    o
}

/// The goals, end to end, on the quad with 1100 rad/s motors: every
/// rotor lost at 10 m lands within 5 m of the point below the failure, under
/// 2 m/s, upright, spinning as relaxed hover predicts, a descent not a fall.
#[test]
fn autopilot_flies_relaxed_hover_to_the_ground_on_every_rotor() {
    let af = stronger_quad();
    for dead in 0..4 {
        let o = autopilot_case(&af, HEIGHT_M, dead);
        assert!(o.distance_m < MAX_DISTANCE_M, "rotor {}: {o:?}", dead + 1);
        assert!(
            o.touchdown_speed_m_s < MAX_TOUCHDOWN_SPEED_M_S,
            "rotor {}: {o:?}",
            dead + 1
        );
        let eq = *RelaxedHover::new(&af, &af.nominal(), dead).unwrap().equilibrium();
        let predicted = eq.spin_rad_s * eq.up_frd.z;
        assert!(
            (o.spin_rad_s - predicted).abs() < 0.2 * predicted.abs(),
            "rotor {}: yaw rate {} vs equilibrium {predicted}",
            dead + 1,
            o.spin_rad_s
        );
        assert!(o.descent_s > (HEIGHT_M - 0.24) / MAX_TOUCHDOWN_SPEED_M_S, "{o:?}");
    }
}

/// The shipped x500 (1000 rad/s), end to end: from 10 m it lands upright,
/// within 5 m, slower than a free fall but too fast for the goal (5.9 m/s: too
/// little thrust to brake while the spin builds up); from 30 m no better
/// (6.0 m/s); from 80 m it has the time to brake and meets the goals
/// (`autopilot_touchdown_by_height_table` for the figures between).
#[test]
fn autopilot_on_the_shipped_quad_comes_down_upright_and_braked() {
    let af = quad();
    for (height, dead) in [(HEIGHT_M, 0), (HEIGHT_M, 1), (30.0, 0), (80.0, 2)] {
        let o = autopilot_case(&af, height, dead);
        let free_fall = (2.0 * GRAVITY * (height - af.gear_height_m)).sqrt();
        assert!(o.distance_m < MAX_DISTANCE_M, "{o:?}");
        assert!(
            o.touchdown_speed_m_s < 0.8 * free_fall,
            "free fall {free_fall:.2} m/s: {o:?}"
        );
        if height >= 80.0 {
            assert!(o.touchdown_speed_m_s < MAX_TOUCHDOWN_SPEED_M_S, "{o:?}");
        }
    }
}

/// Without rotational drag in the airframe relaxed hover cannot be built:
/// the stack keeps its best effort (yaw given up, land) and says why.
#[test]
fn autopilot_without_rotational_drag_says_it_keeps_the_best_effort() {
    let af = without_drag(&quad());
    let mut ls = Sitl::of(af).build();
    ls.step();
    ls.arm_and_take_off(Some(HEIGHT_M));
    for _ in 0..20_000 {
        ls.step();
    }
    ls.inject(Fault::Rotor {
        rotor: 1,
        health: RotorHealth::Off,
    });
    let mut texts = Vec::new();
    for _ in 0..200 {
        ls.step();
        texts.extend(ls.texts());
    }
    assert_eq!(ls.pilot().mode(), FlightMode::Land);
    assert!(
        texts
            .iter()
            .any(|t| t.severity == Severity::Critical && t.text == "Motor 4 failed: no hover"),
        "{texts:?}"
    );
    assert!(
        texts
            .iter()
            .any(|t| t.severity == Severity::Emergency && t.text == "Rotor loss: yaw lost, landing: no rotational drag"),
        "{texts:?}"
    );
}

/// Touchdown speed of the shipped quad (and the 1100 rad/s one) against the
/// hover height at which rotor 1 dies, end to end.
#[test]
#[ignore = "a report: run with --ignored --nocapture"]
fn autopilot_touchdown_by_height_table() {
    println!("| omega_max [rad/s] | height [m] | touchdown [m/s] | distance [m] | tilt [deg] | descent [s] |");
    println!("|---|---|---|---|---|---|");
    for af in [quad(), stronger_quad()] {
        for height in [10.0, 20.0, 30.0, 50.0, 80.0] {
            let o = autopilot_loss(&af, height, 0);
            println!(
                "| {} | {height} | {:.2} | {:.2} | {:.1} | {:.1} |",
                af.rotor.speed_max_rad_s, o.touchdown_speed_m_s, o.distance_m, o.touchdown_tilt_deg, o.descent_s
            );
        }
    }
}
