//! Fly a [`Scenario`] flat out in lockstep and summarise it; optionally write
//! the full time series as the flight CSV ([`crate::logs::csv`]: the log
//! format `rotorpilot estimate` reads) and collect its report page
//! ([`crate::logs::report`]).

use std::io::Write;

use nalgebra::{UnitQuaternion, Vector3};
use serde::Serialize;

use super::fault::{self, AppliedFault};
use super::{ReferencePlan, Scenario};
use crate::autopilot::{ControlLoop, ControlOutput, Demand, FilterNavigation};
use crate::control::{
    ControllerKind, Reference, Setpoint, Shaper, ShaperLimits, TranslationSetpoint, feedforward_attitude,
};
use crate::geo::GeoPoint;
use crate::lockstep::{Lockstep, Pilot, StepRecord};
use crate::logs::csv::CsvLog;
use crate::logs::meta::LogMeta;
use crate::logs::report::{Collector, FlightReport, PilotState, ReportMeta, Watched};
use crate::math::{euler_zyx, from_euler_zyx};
use crate::mission::Plans;
use crate::signals::{ControlWrench, GRAVITY, Measurement, SensorReadings, WrenchEstimate};
use crate::sim::{DisturbanceSource, RigidBodyState, SensorConfig, SimFault, World};

/// Where a scenario's vehicle lies on the globe, for its raw sensors and
/// navigation filter (a scenario names no home: PX4 SITL's).
const NAV_HOME: GeoPoint = GeoPoint::PX4_SITL_HOME;

/// What `rotorpilot simulate` prints.
#[derive(Clone, Debug, Serialize)]
pub struct Summary {
    /// Scenario file.
    pub scenario: String,
    /// Airframe name.
    pub airframe: String,
    /// Law at the end.
    pub controller: String,
    /// Steps flown.
    pub steps: u64,
    /// Simulated time [s].
    pub sim_time_s: f64,
    /// Wall time [s] (filled in by the caller, which owns the clock).
    pub wall_time_s: f64,
    /// RMS of `|p - p_d|` [m].
    pub rms_pos_err_m: f64,
    /// Max of `|p - p_d|` [m].
    pub max_pos_err_m: f64,
    /// Per-axis RMS position error [m], NED.
    pub rms_pos_err_ned: [f64; 3],
    /// Per-axis max `|e|` [m], NED.
    pub max_pos_err_ned: [f64; 3],
    /// Mean position error `p - p_d` over the last 10 % of the flight [m], NED.
    pub final_pos_err_ned: [f64; 3],
    /// Max angle between the attitude and the controller's attitude setpoint [rad].
    pub max_att_err_rad: f64,
    /// Final position [m], NED.
    pub final_position_ned: [f64; 3],
    /// Final ZYX Euler angles [rad].
    pub final_euler_rad: [f64; 3],
    /// Time the allocation had to desaturate [s].
    pub saturation_time_s: f64,
    /// Body z stayed below the horizon (tilt < 90 deg) throughout.
    pub upright: bool,
    /// No NaN or infinity anywhere.
    pub finite: bool,
    /// Why the flight stopped early, if it did.
    pub fault: Option<String>,
    /// Final estimated external force [N], NED.
    pub est_force_ned: [f64; 3],
    /// Final estimated external torque [N m], FRD.
    pub est_torque_frd: [f64; 3],
    /// Final estimated external torque in Euler-angle coordinates [N m].
    pub est_torque_rpy: [f64; 3],
    /// Final real-mass estimate [kg].
    pub est_mass_kg: f64,
    /// The `[[fault]]`s applied, when and with what answer (absent when none).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub faults: Vec<AppliedFault>,
}

/// The flight software of a scenario: its reference (an analytic curve, or
/// timed setpoints through the shaper) and its controller switches, flown by
/// the loop every pilot shares, with the estimate fed back if asked.
#[derive(Debug)]
pub struct ScenarioPilot<'a> {
    scenario: &'a Scenario,
    control: ControlLoop,
    shaper: Shaper,
    next_switch: usize,
    /// The navigation filter flown on (`[navigation] source = "filter"`),
    /// started at the initial state; `None`: the readings' own solution.
    navigation: Option<Box<FilterNavigation>>,
}

impl ScenarioPilot<'_> {
    /// Its scenario's step [s].
    pub(super) fn step_s(&self) -> f64 {
        self.scenario.step_s
    }

    /// The reference at `t` [s] (the shaper advances one step).
    fn reference_at(&mut self, t: f64) -> Reference {
        match &self.scenario.reference {
            ReferencePlan::Trajectory(tr) => tr.at(t),
            ReferencePlan::Setpoints(list) => {
                let sp = list
                    .iter()
                    .take_while(|(at, _)| *at <= t)
                    .last()
                    .or(list.first())
                    .map_or(Setpoint::position(Vector3::zeros(), 0.0), |(_, sp)| *sp);
                self.shaper.update(&sp, self.scenario.step_s)
            }
        }
    }
}

impl Pilot for ScenarioPilot<'_> {
    fn output(&self) -> &ControlOutput {
        self.control.output()
    }

    fn decide(&mut self, readings: &SensorReadings) {
        let s = self.scenario;
        let filtered;
        let readings = match self.navigation.as_deref_mut() {
            None => readings,
            Some(nav) => {
                nav.update(readings);
                filtered = nav.readings(readings);
                &filtered
            }
        };
        let m = &readings.measurement;
        let t = m.time_s;
        while self.next_switch < s.switches.len() && s.switches[self.next_switch].0 <= t {
            self.control.switch_controller(s.switches[self.next_switch].1);
            self.next_switch += 1;
        }
        let demand = Demand::Track(self.reference_at(t));
        let estimate = self.control.sense(m);
        let feedback = s.feedback.then_some(&estimate);
        self.control.act(m, &demand, feedback, s.step_s);
    }

    fn rotors_stopped(&mut self, _why: &SimFault) {
        self.control.rotors_stopped();
    }

    fn solution(&self, readings: &SensorReadings) -> Measurement {
        match self.navigation.as_deref() {
            None => readings.measurement,
            Some(nav) => nav.measurement(readings.measurement.time_s),
        }
    }
}

/// A bare control law as its report page shows it: always armed and in the
/// air (it starts in flight and flies its reference to the end), its mode
/// the controller flying now (the scenario's switches on the timeline); no
/// plans, no battery estimate.
impl Watched for ScenarioPilot<'_> {
    fn rotor_count(&self) -> usize {
        self.scenario.airframe.rotor_count()
    }

    fn pilot_state(&self) -> PilotState {
        PilotState {
            armed: true,
            mode: self.control.controller().kind().name().to_string(),
            in_air: true,
            airborne: true,
            failsafe: None,
            landed: "in the air (a control law, no flight stack)".into(),
        }
    }

    fn plans_at(&self) -> Option<(&Plans, GeoPoint)> {
        None
    }

    fn battery_remaining(_core: &mut Lockstep<Self>, _i: usize) -> f64 {
        f64::NAN
    }
}

/// The sidecar ([`LogMeta`]) of a scenario's flight CSV written by `producer` (`simulate`).
#[must_use]
pub fn scenario_meta(s: &Scenario, producer: &str) -> LogMeta {
    LogMeta::new(
        producer,
        &s.source,
        &s.airframe.name,
        &s.airframe.nominal(),
        &s.estimator,
        s.step_s,
    )
}

/// The scenario ready to fly: its world (the vehicle placed at the initial
/// state, the disturbance schedule set) and its pilot, at `t = 0`.
///
/// # Errors
/// Invalid gains or estimator settings.
pub fn lockstep(s: &Scenario) -> anyhow::Result<Lockstep<ScenarioPilot<'_>>> {
    let mut world = World::new(s.step_s, s.world);
    add_vehicle(&mut world, s);
    let mut core = Lockstep::new(world, vec![pilot(s)?]);
    place(&mut core, 0);
    Ok(core)
}

/// Add `s`'s vehicle to `world` (its airframe, sensors and air); its index.
pub(super) fn add_vehicle(world: &mut World, s: &Scenario) -> usize {
    let i = world.add_vehicle(
        &s.airframe,
        SensorConfig {
            noise: s.noise,
            seed: s.seed,
        },
    );
    world.set_wind(i, s.wind);
    i
}

/// `s`'s pilot, at `t = 0`, before its vehicle is [`place`]d.
///
/// # Errors
/// Invalid gains or estimator settings.
pub(super) fn pilot(s: &Scenario) -> anyhow::Result<ScenarioPilot<'_>> {
    let control = ControlLoop::new(&s.airframe, s.controller, s.gains, s.estimator.clone())
        .map_err(|e| anyhow::anyhow!("{}: {e}", s.source))?;
    Ok(ScenarioPilot {
        scenario: s,
        control,
        shaper: Shaper::new(ShaperLimits::for_airframe(&s.airframe))?,
        next_switch: 0,
        navigation: None,
    })
}

/// Put vehicle `i` at its scenario's initial state (given, or on the
/// reference with its feedforward attitude and thrust), set its disturbance
/// schedule and reset its pilot there.
pub(super) fn place(core: &mut Lockstep<ScenarioPilot<'_>>, i: usize) {
    let s = core.pilot(i).scenario;
    let r0 = match &s.reference {
        ReferencePlan::Trajectory(tr) => tr.at(0.0),
        ReferencePlan::Setpoints(list) => {
            let p = match list.first().map(|(_, sp)| sp.translation) {
                Some(TranslationSetpoint::Position(p)) => p,
                _ => Vector3::new(0.0, 0.0, -2.0),
            };
            Reference::hold(p, 0.0)
        }
    };
    let (state, hover) = match s.initial {
        Some(init) => (
            RigidBodyState {
                position_ned: init.position_ned,
                velocity_ned: init.velocity_ned,
                attitude: from_euler_zyx(&init.euler_rad),
                rate_frd: init.rate_frd,
            },
            core.pilot(i).control.hover_wrench(),
        ),
        None => {
            // on the reference with its feedforward attitude and thrust
            let g = Vector3::new(0.0, 0.0, GRAVITY);
            let f = s.airframe.mass_kg * (g - r0.acceleration_ned);
            (
                RigidBodyState {
                    position_ned: r0.position_ned,
                    velocity_ned: r0.velocity_ned,
                    attitude: feedforward_attitude(&r0.acceleration_ned, r0.yaw_rad),
                    rate_frd: Vector3::zeros(),
                },
                ControlWrench::new(f.norm(), Vector3::zeros()),
            )
        }
    };
    let world = core.world_mut();
    world.set_disturbance(i, DisturbanceSource::Schedule(s.disturbances.clone()));
    world.start_in_flight(i, state, &hover);
    if s.navigation.is_some() {
        // the filter is fed by the raw sensors, around PX4 SITL's home
        world.enable_raw_sensors(i, NAV_HOME);
    }
    let pilot = core.pilot_mut(i);
    pilot.navigation = s.navigation.clone().map(|cfg| {
        let at = Measurement {
            time_s: 0.0,
            position_ned: state.position_ned,
            velocity_ned: state.velocity_ned,
            attitude: state.attitude,
            rate_frd: state.rate_frd,
        };
        Box::new(FilterNavigation::started_at(cfg, NAV_HOME, &at))
    });
    pilot.control.restart();
    pilot
        .shaper
        .reset(state.position_ned, state.velocity_ned, euler_zyx(&state.attitude).z);
}

/// Fly the scenario. `csv` receives the time series when given.
///
/// # Errors
/// Invalid gains or estimator settings, or a failed write to `csv`.
pub fn run(s: &Scenario, csv: Option<&mut dyn Write>) -> anyhow::Result<Summary> {
    run_with(s, csv, None).map(|(summary, _)| summary)
}

/// [`run`], also collecting the flight's report page when `report` gives
/// its meta (no items: the path shows the reference and the flown track).
/// The collector only watches: the flight is the same to the bit.
///
/// # Errors
/// As [`run`].
pub fn run_with(
    s: &Scenario,
    csv: Option<&mut dyn Write>,
    report: Option<ReportMeta>,
) -> anyhow::Result<(Summary, Option<FlightReport>)> {
    let mut core = lockstep(s)?;
    let mut log = csv.map(|w| CsvLog::new(w, s.airframe.rotor_count())).transpose()?;
    let mut flight = Flown::new(s);
    let mut collector = report.as_ref().map(|_| Collector::new(&core, 0, flight.steps));
    while !flight.is_over() {
        flight.before_step(&mut core, 0);
        core.step();
        flight.after_step(core.pilot(0), &core.last_step(0), log.as_mut())?;
        if let Some(c) = &mut collector {
            watch_step(c, &mut core, 0);
        }
    }
    if let Some(l) = log {
        l.finish()?;
    }
    let page = collector.zip(report).map(|(c, meta)| c.finish(&mut core, meta));
    Ok((flight.summary(&core, 0), page))
}

/// After a step: `c` watches vehicle `i` (the texts drained are output
/// only: draining them steers nothing).
pub(super) fn watch_step<P: Watched>(c: &mut Collector, core: &mut Lockstep<P>, i: usize) {
    c.after_step(core);
    let texts = core.drain_stamped_status_texts(i);
    c.texts(&texts);
}

/// A scenario vehicle's flight as it goes, step by step: its `[[fault]]`s
/// applied when due, its errors tallied, its log written, until its
/// duration or a fault of the world stops it; then its [`Summary`]. The
/// same code judges a vehicle flown alone ([`run`]) and one of a fleet.
#[derive(Debug)]
pub(super) struct Flown {
    /// Steps to fly: `round(duration / dt)`.
    steps: u64,
    /// The step `k` to fly next.
    k: u64,
    tail_from: u64,
    sum_sq: Vector3<f64>,
    max_abs: Vector3<f64>,
    max_norm: f64,
    tail_sum: Vector3<f64>,
    tail_n: u64,
    /// The largest attitude error so far [rad], `2 atan2(|delta_v|, |delta_w|)`
    /// of the rotation `delta` from the true attitude to the set one.
    max_att: f64,
    /// `tan(max_att / 2)`: an error with `|delta_v| < |delta_w| tan(max_att / 2)`
    /// is smaller, and needs no `atan2`.
    max_att_tan_half: f64,
    saturated_steps: u64,
    upright: bool,
    finite: bool,
    fault: Option<String>,
    flown: u64,
    applied: Vec<AppliedFault>,
    next_fault: usize,
    /// How many `[[fault]]`s the scenario has (none left to apply: the
    /// step before needs nothing of the core).
    faults: usize,
    /// What the summary reads of the vehicle, taken when the flight ended.
    end: Option<End>,
}

/// What a flight's summary reads of its vehicle, taken at the flight's end
/// (a fleet's vehicle flies on after its own flight is over).
#[derive(Clone, Copy, Debug)]
struct End {
    state: RigidBodyState,
    estimate: WrenchEstimate,
    controller: ControllerKind,
}

impl End {
    /// `pilot`'s vehicle, whose true state is `state`, now.
    fn of(pilot: &ScenarioPilot<'_>, state: &RigidBodyState) -> Self {
        Self {
            state: *state,
            estimate: pilot.control.estimate(),
            controller: pilot.control.controller().kind(),
        }
    }
}

impl Flown {
    /// Before the first step of `s`.
    pub(super) fn new(s: &Scenario) -> Self {
        let steps = (s.duration_s / s.step_s).round() as u64;
        Self {
            steps,
            k: 0,
            tail_from: (steps as f64 * 0.9) as u64,
            sum_sq: Vector3::zeros(),
            max_abs: Vector3::zeros(),
            max_norm: 0.0,
            tail_sum: Vector3::zeros(),
            tail_n: 0,
            max_att: 0.0,
            max_att_tan_half: 0.0,
            saturated_steps: 0,
            upright: true,
            finite: true,
            fault: None,
            flown: 0,
            applied: Vec::new(),
            next_fault: 0,
            faults: s.faults.len(),
            end: None,
        }
    }

    /// The flight is over (its duration flown, or stopped on a fault).
    pub(super) fn is_over(&self) -> bool {
        self.k >= self.steps || self.fault.is_some()
    }

    /// Before step `k` of vehicle `i`: the faults due at `t_k = k dt`.
    pub(super) fn before_step(&mut self, core: &mut Lockstep<ScenarioPilot<'_>>, i: usize) {
        if self.next_fault == self.faults {
            return;
        }
        let s = core.pilot(i).scenario;
        let t = self.k as f64 * s.step_s;
        for f in &s.faults[fault::due(&s.faults, &mut self.next_fault, t)] {
            // a bare control law: no flight stack to ask (SYS_FAILURE_EN)
            self.applied
                .push(fault::apply(core, i, f, |c, inj| c.inject_failure(i, inj)));
        }
    }

    /// The steps left to fly.
    pub(super) fn steps_left(&self) -> u64 {
        self.steps.saturating_sub(self.k)
    }

    /// The flight was over once its vehicle had taken `steps` steps (its
    /// last step is step `k - 1`).
    pub(super) fn over_by(&self, steps: u64) -> bool {
        self.is_over() && self.k <= steps
    }

    /// How many of the next steps (at least 1, at most `most`) vehicle
    /// `i` flies with nothing from the core but [`Self::before_step`]
    /// before the first: up to the step the next fault is due at (past the
    /// flight's end, the vehicle flies on unwatched).
    pub(super) fn steps_alone(&self, core: &Lockstep<ScenarioPilot<'_>>, i: usize, most: u64) -> u64 {
        let most = most.max(1);
        let s = core.pilot(i).scenario;
        let Some(f) = s.faults.get(self.next_fault) else {
            return most;
        };
        // the first step whose instant `fault::due` finds the fault due at
        (1..most)
            .find(|d| f.at_s <= (self.k + d) as f64 * s.step_s + 1e-9)
            .unwrap_or(most)
    }

    /// After step `k` of its vehicle, flown by `pilot`, whose record is
    /// `rec`: tally it and log it; at the flight's end, keep its state and
    /// estimate for [`Self::summary`].
    ///
    /// # Errors
    /// A failed write to `log`.
    pub(super) fn after_step<W: Write>(
        &mut self,
        pilot: &ScenarioPilot<'_>,
        rec: &StepRecord<'_>,
        log: Option<&mut CsvLog<W>>,
    ) -> std::io::Result<()> {
        self.tally(pilot.step_s(), rec, log)?;
        if self.is_over() {
            self.end = Some(End::of(pilot, rec.end));
        }
        Ok(())
    }

    /// Step `k` (of `step_s` [s]) tallied and logged.
    fn tally<W: Write>(
        &mut self,
        step_s: f64,
        rec: &StepRecord<'_>,
        log: Option<&mut CsvLog<W>>,
    ) -> std::io::Result<()> {
        let t = self.k as f64 * step_s;
        let k = self.k;
        self.k += 1;
        if let Some(e) = rec.world.fault {
            self.fault = Some(format!("t = {t:.3} s: {e}"));
            self.finite = false;
            return Ok(());
        }
        self.flown += 1;
        let (truth, control) = (&rec.world.truth, rec.control);
        let e = truth.position_ned - control.reference.position_ned;
        self.sum_sq += e.component_mul(&e);
        self.max_abs = self.max_abs.sup(&e.abs());
        self.max_norm = self.max_norm.max(e.norm());
        if k >= self.tail_from {
            self.tail_sum += e;
            self.tail_n += 1;
        }
        self.tally_attitude_error(&truth.attitude, &control.attitude_sp);
        self.saturated_steps += u64::from(control.saturated);
        self.upright &= (truth.attitude * Vector3::z()).z > 0.0;
        self.finite &= e.as_slice().iter().all(|x| x.is_finite())
            && control.command.thrust_n.is_finite()
            && control.command.torque_frd.as_slice().iter().all(|x| x.is_finite());
        if let Some(l) = log {
            l.row(rec)?;
        }
        Ok(())
    }

    /// Keep the largest angle of the rotation `delta` from `attitude` to
    /// `setpoint`, `2 atan2(|delta_v|, |delta_w|)` (nalgebra's `angle_to`, to
    /// the bit). An error whose tangent ratio `|delta_v| / |delta_w|` lies
    /// below `tan(max / 2)` by a margin far above rounding (1e-9 relative)
    /// cannot be the largest and skips the `atan2`: most steps do.
    fn tally_attitude_error(&mut self, attitude: &UnitQuaternion<f64>, setpoint: &UnitQuaternion<f64>) {
        let delta = attitude.rotation_to(setpoint);
        let (v, w) = (delta.imag().norm(), delta.scalar().abs());
        if v < w * self.max_att_tan_half * (1.0 - 1e-9) {
            return;
        }
        let angle = delta.angle();
        if angle.is_finite() && angle > self.max_att {
            self.max_att = angle;
            self.max_att_tan_half = (0.5 * angle).tan();
        }
    }

    /// The summary of vehicle `i`'s flight (at its end).
    pub(super) fn summary(self, core: &Lockstep<ScenarioPilot<'_>>, i: usize) -> Summary {
        let s = core.pilot(i).scenario;
        let dt = s.step_s;
        let flown = self.flown;
        let End {
            state,
            estimate: est,
            controller,
        } = self
            .end
            .unwrap_or_else(|| End::of(core.pilot(i), core.world().plant(i).state()));
        let flown_f = flown.max(1) as f64;
        let rms = (self.sum_sq / flown_f).map(f64::sqrt);
        let tail = if self.tail_n > 0 {
            self.tail_sum / self.tail_n as f64
        } else {
            Vector3::zeros()
        };
        let arr = |v: Vector3<f64>| [v.x, v.y, v.z];
        Summary {
            scenario: s.source.clone(),
            airframe: s.airframe.name.clone(),
            controller: controller.name().to_string(),
            steps: flown,
            sim_time_s: flown as f64 * dt,
            wall_time_s: 0.0,
            rms_pos_err_m: (self.sum_sq.sum() / flown_f).sqrt(),
            max_pos_err_m: self.max_norm,
            rms_pos_err_ned: arr(rms),
            max_pos_err_ned: arr(self.max_abs),
            final_pos_err_ned: arr(tail),
            max_att_err_rad: self.max_att,
            final_position_ned: arr(state.position_ned),
            final_euler_rad: arr(euler_zyx(&state.attitude)),
            saturation_time_s: self.saturated_steps as f64 * dt,
            upright: self.upright,
            finite: self.finite,
            fault: self.fault,
            est_force_ned: arr(est.force_ned),
            est_torque_frd: arr(est.torque_frd),
            est_torque_rpy: arr(est.torque_rpy),
            est_mass_kg: est.mass_kg,
            faults: self.applied,
        }
    }
}

impl Summary {
    /// Human-readable rendering.
    #[must_use]
    pub fn to_text(&self) -> String {
        let mm = |v: [f64; 3]| format!("[{:.4}, {:.4}, {:.4}] mm", v[0] * 1e3, v[1] * 1e3, v[2] * 1e3);
        // 4 decimals as the other lines (the JSON keeps every digit)
        let v4 = |v: [f64; 3]| format!("[{:.4}, {:.4}, {:.4}]", v[0], v[1], v[2]);
        let mut s = format!(
            "scenario {} — {} with the {} controller\n\
             flew {:.3} s simulated in {:.3} s wall ({:.0}x real time), {} steps\n\
             position error: RMS {:.4e} m, max {:.4e} m\n  per axis RMS {}, max {}\n  mean over the last 10 %: {}\n\
             attitude error (to the controller's setpoint): max {:.4} rad\n\
             final position {} m NED, final Euler {} rad\n\
             rotor saturation {:.3} s; upright: {}; finite: {}\n\
             estimate: force [{:.4}, {:.4}, {:.4}] N NED, torque [{:.4}, {:.4}, {:.4}] N m FRD, mass {:.4} kg\n",
            self.scenario,
            self.airframe,
            self.controller,
            self.sim_time_s,
            self.wall_time_s,
            if self.wall_time_s > 0.0 {
                self.sim_time_s / self.wall_time_s
            } else {
                f64::INFINITY
            },
            self.steps,
            self.rms_pos_err_m,
            self.max_pos_err_m,
            mm(self.rms_pos_err_ned),
            mm(self.max_pos_err_ned),
            mm(self.final_pos_err_ned),
            self.max_att_err_rad,
            v4(self.final_position_ned),
            v4(self.final_euler_rad),
            self.saturation_time_s,
            self.upright,
            self.finite,
            self.est_force_ned[0],
            self.est_force_ned[1],
            self.est_force_ned[2],
            self.est_torque_frd[0],
            self.est_torque_frd[1],
            self.est_torque_frd[2],
            self.est_mass_kg,
        );
        for f in &self.faults {
            s.push_str(&format!("fault injected: {}\n", f.to_line()));
        }
        if let Some(f) = &self.fault {
            s.push_str(&format!("stopped early: {f}\n"));
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use super::*;

    /// The tally that skips the `atan2` of errors that cannot be the largest
    /// keeps the same largest error, to the bit, as taking every angle.
    #[test]
    fn the_largest_attitude_error_is_the_plain_maximum_to_the_bit() {
        let text = include_str!("../../tools/scenarios/figure-eight-geometric.toml");
        let s = Scenario::from_toml(text, "figure-eight", Some(std::path::Path::new("tools/scenarios"))).unwrap();
        let mut flown = Flown::new(&s);
        let mut plain = 0.0_f64;
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut rpy = |scale: f64| {
            let mut r = || scale * (rng.random::<f64>() - 0.5);
            UnitQuaternion::from_euler_angles(r(), r(), r())
        };
        for k in 0..20_000 {
            // errors that grow and shrink, many near the largest so far
            let scale = 0.01 + 0.2 * (k as f64 * 1e-3).sin().abs();
            let (a, b) = (rpy(6.0), rpy(scale));
            let sp = b * a;
            plain = plain.max(a.angle_to(&sp));
            flown.tally_attitude_error(&a, &sp);
            assert_eq!(flown.max_att.to_bits(), plain.to_bits(), "step {k}");
        }
        assert!(plain > 0.1);
    }
}
