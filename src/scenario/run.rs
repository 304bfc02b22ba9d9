//! Fly a [`Scenario`] flat out in lockstep and summarise it; optionally write
//! the full time series as CSV (the log format `rotorpilot estimate` reads).
//!
//! CSV columns, one row per step `k` (state `x_k` at `t_k`, command `u_k`
//! held over `[t_k, t_{k+1})`), SI units, NED/FRD. First the measurements the
//! estimator and controller saw (the report's inputs): `time_s`,
//! `pos_n pos_e pos_d`, `vel_n vel_e vel_d`, `roll pitch yaw` [rad],
//! `roll_rate pitch_rate yaw_rate` (Euler-angle rates `eta_dot = Q^-1 omega`),
//! `p_frd q_frd r_frd` (body rates); then the truth `true_pos_n/e/d`,
//! `true_vel_n/e/d`; the reference `ref_n ref_e ref_d ref_yaw`; `thrust_n
//! tau_x tau_y tau_z` (the wrench applied over the step: what the estimator is
//! told), `cmd_thrust_n cmd_tau_x cmd_tau_y cmd_tau_z` (controller output
//! before allocation), `saturated`, `w1..wn` (rotor speed commands, rad/s),
//! `fext_n fext_e fext_d`, `text_x text_y text_z` (true external wrench),
//! `true_mass_kg`, `est_fn est_fe est_fd`, `est_tx est_ty est_tz` (body FRD),
//! `est_mass_kg`. Numbers are printed in the shortest form that reads back to
//! the same `f64`, so an offline run on the log reproduces the online one.

use std::io::Write;

use nalgebra::Vector3;
use serde::Serialize;

use super::{DisturbanceChange, ReferencePlan, Scenario};
use crate::control::{Reference, Shaper, ShaperLimits, feedforward_attitude};
use crate::estimation::input_from;
use crate::math::{euler_zyx, from_euler_zyx};
use crate::model::{ExternalWrench, PlantConfig, RigidBodyState};
use crate::vehicle::{StepRecord, Vehicle, VehicleError};

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
}

/// The disturbance in force at `t` (last change at or before `t`; values not given carry over).
fn disturbance_at(changes: &[DisturbanceChange], t: f64) -> (ExternalWrench, Option<f64>) {
    let mut w = ExternalWrench::default();
    let mut mass = None;
    for c in changes.iter().take_while(|c| c.at_s <= t) {
        if let Some(f) = c.force_ned {
            w.force_ned = f;
        }
        if let Some(tq) = c.torque_frd {
            w.torque_frd = tq;
        }
        if c.true_mass_kg.is_some() {
            mass = c.true_mass_kg;
        }
    }
    (w, mass)
}

fn csv_header(n: usize) -> String {
    let mut h = String::from(
        "time_s,pos_n,pos_e,pos_d,vel_n,vel_e,vel_d,roll,pitch,yaw,roll_rate,pitch_rate,yaw_rate,p_frd,q_frd,r_frd,\
         true_pos_n,true_pos_e,true_pos_d,true_vel_n,true_vel_e,true_vel_d,ref_n,ref_e,ref_d,ref_yaw,\
         thrust_n,tau_x,tau_y,tau_z,cmd_thrust_n,cmd_tau_x,cmd_tau_y,cmd_tau_z,saturated",
    );
    for i in 1..=n {
        h.push_str(&format!(",w{i}"));
    }
    h.push_str(
        ",fext_n,fext_e,fext_d,text_x,text_y,text_z,true_mass_kg,est_fn,est_fe,est_fd,est_tx,est_ty,est_tz,est_mass_kg",
    );
    h
}

fn csv_row(r: &StepRecord, n: usize) -> String {
    let m = &r.measurement;
    // the report's inputs exactly as the estimator derives them (eta, eta_dot = Q^-1 omega)
    let input = input_from(m, &r.applied);
    let (eta, eta_dot) = (input.eta, input.eta_dot);
    let mut v: Vec<f64> = Vec::with_capacity(64);
    v.push(m.time_s);
    v.extend(m.position_ned.iter());
    v.extend(m.velocity_ned.iter());
    v.extend(eta.iter());
    v.extend(eta_dot.iter());
    v.extend(m.rate_frd.iter());
    v.extend(r.truth.position_ned.iter());
    v.extend(r.truth.velocity_ned.iter());
    v.extend(r.reference.position_ned.iter());
    v.push(r.reference.yaw_rad);
    v.push(r.applied.thrust_n);
    v.extend(r.applied.torque_frd.iter());
    v.push(r.command.thrust_n);
    v.extend(r.command.torque_frd.iter());
    v.push(f64::from(u8::from(r.saturated)));
    v.extend(r.rotor_speed_cmd.iter().take(n));
    v.extend(r.external.force_ned.iter());
    v.extend(r.external.torque_frd.iter());
    v.push(r.true_mass_kg);
    v.extend(r.estimate.force_ned.iter());
    v.extend(r.estimate.torque_frd.iter());
    v.push(r.estimate.mass_kg);
    // `{}` prints the shortest text that parses back to the same f64: the log is exact.
    v.iter().map(|x| format!("{x}")).collect::<Vec<_>>().join(",")
}

/// Fly the scenario. `csv` receives the time series when given.
///
/// # Errors
/// Invalid gains or estimator settings, or a failed write to `csv`.
#[allow(clippy::too_many_lines)]
pub fn run(s: &Scenario, mut csv: Option<&mut dyn Write>) -> anyhow::Result<Summary> {
    let plant = PlantConfig {
        dt_s: s.step_s,
        world: s.world,
        noise: s.noise,
        seed: s.seed,
    };
    let mut vehicle = Vehicle::new(&s.airframe, plant, s.controller, s.gains, s.estimator.clone())
        .map_err(|e: VehicleError| anyhow::anyhow!("{}: {e}", s.source))?;
    vehicle.set_feedback(s.feedback);

    let mut shaper = Shaper::new(ShaperLimits::for_airframe(&s.airframe))?;
    let reference_at = |shaper: &mut Shaper, t: f64, dt: f64| -> Reference {
        match &s.reference {
            ReferencePlan::Trajectory(tr) => tr.at(t),
            ReferencePlan::Setpoints(list) => {
                let sp = list
                    .iter()
                    .take_while(|(at, _)| *at <= t)
                    .last()
                    .map_or(list[0].1, |(_, sp)| *sp);
                shaper.update(&sp, dt)
            }
        }
    };

    // Initial state.
    let r0 = match &s.reference {
        ReferencePlan::Trajectory(tr) => tr.at(0.0),
        ReferencePlan::Setpoints(list) => {
            let p = match list[0].1.translation {
                crate::control::TranslationSetpoint::Position(p) => p,
                _ => Vector3::new(0.0, 0.0, -2.0),
            };
            Reference::hold(p, 0.0)
        }
    };
    let (state, hover) = match s.initial {
        Some(i) => (
            RigidBodyState {
                position_ned: i.position_ned,
                velocity_ned: i.velocity_ned,
                attitude: from_euler_zyx(&i.euler_rad),
                rate_frd: i.rate_frd,
            },
            vehicle.hover_wrench(),
        ),
        None => {
            // on the reference with its feedforward attitude and thrust
            let g = Vector3::new(0.0, 0.0, crate::airframe::GRAVITY);
            let f = s.airframe.mass_kg * (g - r0.acceleration_ned);
            (
                RigidBodyState {
                    position_ned: r0.position_ned,
                    velocity_ned: r0.velocity_ned,
                    attitude: feedforward_attitude(&r0.acceleration_ned, r0.yaw_rad),
                    rate_frd: Vector3::zeros(),
                },
                crate::airframe::ControlWrench::new(f.norm(), Vector3::zeros()),
            )
        }
    };
    vehicle.start_in_flight(state, hover);
    shaper.reset(state.position_ned, state.velocity_ned, euler_zyx(&state.attitude).z);
    let n = s.airframe.rotor_count();
    if let Some(w) = csv.as_deref_mut() {
        writeln!(w, "{}", csv_header(n))?;
    }

    let dt = s.step_s;
    let steps = (s.duration_s / dt).round() as u64;
    let tail_from = (steps as f64 * 0.9) as u64;
    let mut sum_sq = Vector3::<f64>::zeros();
    let mut max_abs = Vector3::<f64>::zeros();
    let mut max_norm: f64 = 0.0;
    let mut tail_sum = Vector3::<f64>::zeros();
    let mut tail_n = 0u64;
    let mut max_att: f64 = 0.0;
    let mut saturated_steps = 0u64;
    let mut upright = true;
    let mut finite = true;
    let mut fault = None;
    let mut next_switch = 0usize;
    let mut flown = 0u64;
    let mut current_mass = None;
    for k in 0..steps {
        let t = k as f64 * dt;
        while next_switch < s.switches.len() && s.switches[next_switch].0 <= t {
            vehicle.switch_controller(s.switches[next_switch].1);
            next_switch += 1;
        }
        let (_, mass) = disturbance_at(&s.disturbances, t);
        if mass != current_mass {
            if let Some(m) = mass {
                vehicle.plant_mut().set_true_mass(m);
            }
            current_mass = mass;
        }
        let reference = reference_at(&mut shaper, t, dt);
        let schedule = |tt: f64| disturbance_at(&s.disturbances, tt).0;
        let rec = match vehicle.step(&reference, &schedule) {
            Ok(r) => r,
            Err(e) => {
                fault = Some(format!("t = {t:.3} s: {e}"));
                finite = false;
                break;
            }
        };
        flown += 1;
        let e = rec.truth.position_ned - rec.reference.position_ned;
        sum_sq += e.component_mul(&e);
        max_abs = max_abs.sup(&e.abs());
        max_norm = max_norm.max(e.norm());
        if k >= tail_from {
            tail_sum += e;
            tail_n += 1;
        }
        let att_err = rec.truth.attitude.angle_to(&rec.attitude_sp);
        if att_err.is_finite() {
            max_att = max_att.max(att_err);
        }
        saturated_steps += u64::from(rec.saturated);
        upright &= (rec.truth.attitude * Vector3::z()).z > 0.0;
        finite &= e.as_slice().iter().all(|x| x.is_finite())
            && rec.command.thrust_n.is_finite()
            && rec.command.torque_frd.as_slice().iter().all(|x| x.is_finite());
        if let Some(w) = csv.as_deref_mut() {
            writeln!(w, "{}", csv_row(&rec, n))?;
        }
    }
    let state = vehicle.plant().state();
    let est = vehicle.estimate();
    let flown_f = flown.max(1) as f64;
    let rms = (sum_sq / flown_f).map(f64::sqrt);
    let tail = if tail_n > 0 {
        tail_sum / tail_n as f64
    } else {
        Vector3::zeros()
    };
    let arr = |v: Vector3<f64>| [v.x, v.y, v.z];
    Ok(Summary {
        scenario: s.source.clone(),
        airframe: s.airframe.name.clone(),
        controller: vehicle.controller().kind().name().to_string(),
        steps: flown,
        sim_time_s: flown as f64 * dt,
        wall_time_s: 0.0,
        rms_pos_err_m: (sum_sq.sum() / flown_f).sqrt(),
        max_pos_err_m: max_norm,
        rms_pos_err_ned: arr(rms),
        max_pos_err_ned: arr(max_abs),
        final_pos_err_ned: arr(tail),
        max_att_err_rad: max_att,
        final_position_ned: arr(state.position_ned),
        final_euler_rad: arr(euler_zyx(&state.attitude)),
        saturation_time_s: saturated_steps as f64 * dt,
        upright,
        finite,
        fault,
        est_force_ned: arr(est.force_ned),
        est_torque_frd: arr(est.torque_frd),
        est_torque_rpy: arr(est.torque_rpy),
        est_mass_kg: est.mass_kg,
    })
}

impl Summary {
    /// Human-readable rendering.
    #[must_use]
    pub fn to_text(&self) -> String {
        let mm = |v: [f64; 3]| format!("[{:.4}, {:.4}, {:.4}] mm", v[0] * 1e3, v[1] * 1e3, v[2] * 1e3);
        let mut s = format!(
            "scenario {} — {} with the {} controller\n\
             flew {:.3} s simulated in {:.3} s wall ({:.0}x real time), {} steps\n\
             position error: RMS {:.4e} m, max {:.4e} m\n  per axis RMS {}, max {}\n  mean over the last 10 %: {}\n\
             attitude error (to the controller's setpoint): max {:.4} rad\n\
             final position {:?} m NED, final Euler {:?} rad\n\
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
            self.final_position_ned,
            self.final_euler_rad,
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
        if let Some(f) = &self.fault {
            s.push_str(&format!("stopped early: {f}\n"));
        }
        s
    }
}
