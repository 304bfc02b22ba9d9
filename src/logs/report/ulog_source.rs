//! The report's data from a ULog ([`crate::logs::ulog::read`]): rotorpilot's
//! own `flight.ulg` (PX4's topics and `rotorpilot_*`), or a PX4 log as far
//! as it has the same topics. Every topic is sampled onto one time base (the
//! truth's, else the local position's, downsampled to
//! [`super::MAX_SAMPLES`]), holding each topic's latest sample. A ULog holds
//! no mission, geofence or rally items and no "item reached" events: the
//! page says so, and shows the flight without them.

use nalgebra::{Quaternion, UnitQuaternion};

use super::{COLUMNS, Event, FlightReport, MAX_SAMPLES, ReportMeta, RotorLimit, Series, Timeline, Verdict};
use crate::autopilot::Severity;
use crate::logs::ulog::read::{Topic, UlogFile, read_ulog};

/// A trajectory setpoint older than this [us] is not in force any more (it is logged at 5 Hz while tracked).
const SETPOINT_STALE_US: u64 = 500_000;

/// Samples of `field` of `topic` held at each instant of `grid` [us]
/// (NaN before the first sample, or when the latest is older than `stale_us`).
fn hold(topic: Option<&Topic>, field: &str, grid: &[u64], stale_us: u64) -> Vec<f64> {
    let Some((t, v)) = topic.and_then(|t| t.field(field).map(|v| (&t.timestamp_us, v))) else {
        return vec![f64::NAN; grid.len()];
    };
    let mut k = 0;
    grid.iter()
        .map(|&g| {
            while k + 1 < t.len() && t[k + 1] <= g {
                k += 1;
            }
            if t.is_empty() || t[k] > g || g - t[k] > stale_us {
                f64::NAN
            } else {
                v[k]
            }
        })
        .collect()
}

/// PX4's `nav_state` numbers to the mode names the record's timeline uses.
fn mode_name(nav_state: f64) -> String {
    match nav_state as i64 {
        0 => "Manual".into(),
        1 => "Altitude".into(),
        2 => "Position".into(),
        3 => "Mission".into(),
        4 => "Hold".into(),
        5 => "ReturnToLaunch".into(),
        10 => "Acro".into(),
        12 => "Descend".into(),
        14 => "Offboard".into(),
        15 => "Stabilized".into(),
        17 => "Takeoff".into(),
        18 => "Land".into(),
        n => format!("nav_state {n}"),
    }
}

fn severity(level: u8) -> Severity {
    match level {
        0 | 1 => Severity::Emergency,
        2 => Severity::Critical,
        3 => Severity::Error,
        4 => Severity::Warning,
        5 => Severity::Notice,
        _ => Severity::Info,
    }
}

/// Euler angles [deg] of the quaternion fields `q[0..4]` (w, x, y, z) of `topic` at each instant.
fn euler_columns(topic: Option<&Topic>, q: &str, grid: &[u64]) -> [Vec<f64>; 3] {
    let c: Vec<Vec<f64>> = (0..4)
        .map(|k| hold(topic, &format!("{q}[{k}]"), grid, u64::MAX))
        .collect();
    let mut out = [Vec::new(), Vec::new(), Vec::new()];
    for (((w, x), y), z) in c[0].iter().zip(&c[1]).zip(&c[2]).zip(&c[3]) {
        let (r, p, y) = if w.is_nan() {
            (f64::NAN, f64::NAN, f64::NAN)
        } else {
            UnitQuaternion::from_quaternion(Quaternion::new(*w, *x, *y, *z)).euler_angles()
        };
        out[0].push(r.to_degrees());
        out[1].push(p.to_degrees());
        out[2].push(y.to_degrees());
    }
    out
}

/// The distance from the trajectory setpoint at each setpoint's instant
/// (the position, `truth` or the local position, held within a sample), as
/// a topic with the field `err`; and its largest value in the air with its time [s].
/// The share of `actuator_motors` samples in the air (`landed` 0 at their
/// instant) with a rotor at full thrust (control 1), and the first's instant;
/// `None` without motors or never in the air. The ULog holds no rotor's
/// minimum speed, so only the upper limit is counted.
fn rotor_limit(motors: Option<&Topic>, rotors: usize, land: Option<&Topic>) -> Option<RotorLimit> {
    let m = motors?;
    let at = &m.timestamp_us;
    let landed = hold(land, "landed", at, u64::MAX);
    let controls: Vec<&[f64]> = (0..rotors).filter_map(|k| m.field(&format!("control[{k}]"))).collect();
    let (mut air, mut full, mut first) = (0u64, 0u64, None);
    for (i, t) in at.iter().enumerate() {
        if landed[i] != 0.0 {
            continue;
        }
        air += 1;
        if controls.iter().any(|c| c[i] >= 1.0 - 1e-6) {
            full += 1;
            first.get_or_insert(*t as f64 * 1e-6);
        }
    }
    (air > 0).then(|| RotorLimit {
        share: full as f64 / air as f64,
        first_s: first,
        counted: "actuator_motors samples while not landed; a rotor at full thrust",
    })
}

fn tracking_error(
    pos: Option<&Topic>,
    truth: bool,
    sp: Option<&Topic>,
    land: Option<&Topic>,
) -> (Topic, Option<(f64, f64)>) {
    let mut out = Topic::default();
    let Some(sp) = sp else {
        return (out, None);
    };
    let at = &sp.timestamp_us;
    let f = |k: usize| {
        if truth {
            format!("position_ned[{k}]")
        } else {
            ["x", "y", "z"][k].to_string()
        }
    };
    let p: Vec<Vec<f64>> = (0..3).map(|k| hold(pos, &f(k), at, 100_000)).collect();
    let r: Vec<Vec<f64>> = (0..3)
        .map(|k| hold(Some(sp), &format!("position[{k}]"), at, 0))
        .collect();
    let landed = hold(land, "landed", at, u64::MAX);
    let mut max: Option<(f64, f64)> = None;
    let err: Vec<f64> = (0..at.len())
        .map(|i| {
            let e = (0..3).map(|k| (p[k][i] - r[k][i]).powi(2)).sum::<f64>().sqrt();
            if e.is_finite() && landed[i] == 0.0 && max.is_none_or(|(m, _)| e > m) {
                max = Some((e, at[i] as f64 * 1e-6));
            }
            e
        })
        .collect();
    out.timestamp_us.clone_from(at);
    out.fields.insert("err".into(), err);
    (out, max)
}

/// A failsafe's announcement is logged within this time [us] of `vehicle_status.failsafe` turning on.
const FAILSAFE_TEXT_US: u64 = 1_000_000;

/// The failsafes of a ULog: each instant `vehicle_status.failsafe` turns
/// on (PX4's flag; a log without it has none), with its cause as the
/// vehicle said it (the first critical or worse message logged within
/// [`FAILSAFE_TEXT_US`]) and the mode then.
fn failsafes(u: &UlogFile) -> Vec<Event> {
    let Some(status) = u.topic("vehicle_status") else {
        return Vec::new();
    };
    let (Some(flag), nav) = (status.field("failsafe"), status.field("nav_state")) else {
        return Vec::new();
    };
    let mut out = Vec::new();
    let mut was = false;
    for (k, (&t, &on)) in status.timestamp_us.iter().zip(flag).enumerate() {
        let on = on != 0.0;
        if on && !was {
            let cause = u
                .logged
                .iter()
                .find(|(at, level, _)| {
                    *at >= t.saturating_sub(FAILSAFE_TEXT_US) && *at <= t + FAILSAFE_TEXT_US && *level <= 2
                })
                .map_or("failsafe", |(_, _, text)| text.as_str());
            let mode = nav.and_then(|n| n.get(k)).map_or(String::new(), |n| mode_name(*n));
            out.push(Event::failsafe(t as f64 * 1e-6, cause, &mode));
        }
        was = on;
    }
    out
}

/// The report of a ULog file's bytes; `file` labels it, `test` names the test.
///
/// # Errors
/// Not a ULog, or one with neither `rotorpilot_sim_truth` nor `vehicle_local_position`.
pub fn from_ulog(bytes: &[u8], file: &str, test: Option<&str>) -> Result<FlightReport, String> {
    let u = read_ulog(bytes, file)?;
    report(&u, file, test)
}

#[allow(clippy::too_many_lines)]
fn report(u: &UlogFile, file: &str, test: Option<&str>) -> Result<FlightReport, String> {
    let truth = u.topic("rotorpilot_sim_truth");
    let local = u.topic("vehicle_local_position");
    let base = truth.or(local).ok_or_else(|| {
        format!("{file}: no rotorpilot_sim_truth or vehicle_local_position topic: no position to show")
    })?;
    let every = (base.timestamp_us.len() as u64).div_ceil(MAX_SAMPLES).max(1) as usize;
    let grid: Vec<u64> = base.timestamp_us.iter().step_by(every).copied().collect();
    let sp = u.topic("trajectory_setpoint");
    let est = u.topic("rotorpilot_wrench_estimate");
    let motors = u.topic("actuator_motors");
    let rotors = motors.map_or(0, |m| {
        (0..12)
            .take_while(|k| {
                m.field(&format!("control[{k}]"))
                    .is_some_and(|v| v.first().is_some_and(|x| !x.is_nan()))
            })
            .count()
    });
    let h = |t: Option<&Topic>, f: &str| hold(t, f, &grid, u64::MAX);
    let (n, e, d, vn, ve, vd) = if truth.is_some() {
        (
            h(truth, "position_ned[0]"),
            h(truth, "position_ned[1]"),
            h(truth, "position_ned[2]"),
            h(truth, "velocity_ned[0]"),
            h(truth, "velocity_ned[1]"),
            h(truth, "velocity_ned[2]"),
        )
    } else {
        (
            h(local, "x"),
            h(local, "y"),
            h(local, "z"),
            h(local, "vx"),
            h(local, "vy"),
            h(local, "vz"),
        )
    };
    let spd = |k: usize, f: &str| hold(sp, &format!("{f}[{k}]"), &grid, SETPOINT_STALE_US);
    let (rn, re, rd) = (spd(0, "position"), spd(1, "position"), spd(2, "position"));
    let (rvn, rve) = (spd(0, "velocity"), spd(1, "velocity"));
    let att = euler_columns(truth.or(u.topic("vehicle_attitude")), "q", &grid);
    let att_sp = euler_columns(u.topic("vehicle_attitude_setpoint"), "q_d", &grid);
    let status = u.topic("vehicle_status");
    let armed = h(status, "arming_state");
    let nav = h(status, "nav_state");
    let landed = h(u.topic("vehicle_land_detected"), "landed");
    let mut series = Series::new(rotors, "0..1");
    let mut cols: Vec<Vec<f64>> = Vec::with_capacity(COLUMNS.len() + rotors);
    let hyp = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x.hypot(*y)).collect::<Vec<_>>();
    // the tracking error at the setpoints' own instants (held between two
    // setpoints it would count the vehicle's motion over 0.2 s as error)
    let (err_topic, max_err) = tracking_error(truth.or(local), truth.is_some(), sp, u.topic("vehicle_land_detected"));
    let err = hold(Some(&err_topic), "err", &grid, SETPOINT_STALE_US);
    cols.extend([
        n.clone(),
        e.clone(),
        d,
        rn,
        re,
        rd,
        h(local, "z"),
        hyp(&vn, &ve),
        vd,
        hyp(&rvn, &rve),
    ]);
    cols.extend(att);
    cols.extend(att_sp);
    cols.push(err);
    for f in ["force_ned", "external_force_ned", "torque_frd", "external_torque_frd"] {
        let t = if f.starts_with("external") { truth } else { est };
        for k in 0..3 {
            cols.push(h(t, &format!("{f}[{k}]")));
        }
    }
    // the order of COLUMNS: f_*, tf_*, tq_*, ttq_*
    cols.push(h(est, "mass_kg"));
    cols.push(h(truth, "mass_kg"));
    cols.push(h(u.topic("battery_status"), "remaining"));
    for k in 0..rotors {
        cols.push(h(motors, &format!("control[{k}]")));
    }
    series.t = grid.iter().map(|t| *t as f64 * 1e-6).collect();
    series.columns = cols;
    let mut modes = Timeline::default();
    let mut arming = Timeline::default();
    for (i, t) in series.t.iter().enumerate() {
        if !nav[i].is_nan() {
            modes.at(*t, &mode_name(nav[i]));
        }
        if !armed[i].is_nan() {
            arming.at(*t, if armed[i] == 2.0 { "armed" } else { "disarmed" });
        }
    }
    let duration_s = series.t.last().copied().unwrap_or(0.0);
    let last = |v: &[f64]| v.last().copied().unwrap_or(f64::NAN);
    let final_state = format!(
        "{}, mode {}, {}",
        if last(&armed) == 2.0 { "armed" } else { "disarmed" },
        mode_name(last(&nav)),
        if last(&landed) == 1.0 { "OnGround" } else { "InAir" }
    );
    let mut events: Vec<Event> = u
        .logged
        .iter()
        .map(|(t, level, text)| Event::from_text(*t as f64 * 1e-6, severity(*level), text))
        .collect();
    events.extend(failsafes(u));
    events.sort_by(|a, b| a.t_s.total_cmp(&b.t_s));
    let mut notes = vec![
        "from a ULog: it holds no mission, geofence or rally items and no item-reached events, so the path shows \
         the flight alone (the flight record has them: rotorpilot report flight.record)"
            .to_string(),
    ];
    if truth.is_none() {
        notes.push("no rotorpilot_sim_truth topic: positions and attitude are the navigation solution".into());
    }
    if rotors > 0 {
        notes.push("rotor plots show actuator_motors: thrust over full thrust, 0..1".into());
    }
    Ok(FlightReport {
        meta: ReportMeta {
            title: test.map_or_else(|| file.to_string(), str::to_string),
            test: test.map(str::to_string),
            source: file.into(),
            method: "ULog".into(),
            airframe: u
                .info
                .get("rotorpilot_airframe")
                .or_else(|| u.info.get("sys_name"))
                .cloned()
                .unwrap_or_default(),
            rotorpilot: u.info.get("ver_sw").cloned().unwrap_or_default(),
            reproduce: None,
            notes,
        },
        duration_s,
        verdict: Verdict {
            max_tracking_error: max_err,
            tracking_counted: "while not landed",
            rotor_limit: rotor_limit(motors, rotors, u.topic("vehicle_land_detected")),
            final_state,
            ..Verdict::default()
        },
        plans: super::PlanView::default(),
        series,
        modes: modes.spans,
        arming: arming.spans,
        events,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hold_keeps_the_latest_sample_until_it_is_stale() {
        let t = Topic {
            timestamp_us: vec![100, 200],
            fields: [("x".to_string(), vec![1.0, 2.0])].into_iter().collect(),
        };
        let got = hold(Some(&t), "x", &[50, 100, 150, 200, 900], 500);
        assert!(got[0].is_nan());
        assert_eq!(&got[1..4], &[1.0, 1.0, 2.0]);
        assert!(got[4].is_nan(), "700 us after the last sample, stale at 500");
    }

    /// Two motors at 10 Hz: on the ground at full thrust (not counted), then
    /// four samples in the air, one with a motor at full thrust.
    #[test]
    fn the_rotor_limit_counts_full_thrust_samples_in_the_air() {
        let motors = Topic {
            timestamp_us: vec![0, 100_000, 200_000, 300_000, 400_000, 500_000],
            fields: [
                ("control[0]".to_string(), vec![1.0, 0.6, 0.6, 1.0, 0.6, 0.6]),
                ("control[1]".to_string(), vec![1.0, 0.6, 0.6, 0.6, 0.9, 0.6]),
            ]
            .into_iter()
            .collect(),
        };
        let land = Topic {
            timestamp_us: vec![0, 150_000],
            fields: [("landed".to_string(), vec![1.0, 0.0])].into_iter().collect(),
        };
        let l = rotor_limit(Some(&motors), 2, Some(&land)).unwrap();
        assert!((l.share - 0.25).abs() < 1e-12, "{l:?}");
        assert_eq!(l.first_s, Some(0.3));
        assert!(rotor_limit(None, 0, Some(&land)).is_none());
    }

    #[test]
    fn a_flight_ulog_gives_the_plots_and_the_timeline() {
        use crate::autopilot::AutopilotCommand;
        use crate::logs::ulog::flight::FlightUlog;
        let (mut core, params) = crate::lockstep::test_quad();
        let mut log = FlightUlog::new(Vec::new(), &params, &core, 0).unwrap();
        for k in 0..4000 {
            if k == 2000 {
                let _ = core.command(0, AutopilotCommand::Arm { force: false });
            }
            core.step();
            log.on_step(&mut core, 0).unwrap();
        }
        let bytes = log.finish().unwrap();
        let r = from_ulog(&bytes, "flight.ulg", Some("t::x")).unwrap();
        assert_eq!(r.meta.title, "t::x");
        assert_eq!(r.meta.airframe, "quad");
        assert_eq!(r.series.t.len(), 200, "the truth at 50 Hz for 4 s");
        assert_eq!(r.series.names.iter().filter(|n| n.starts_with('w')).count(), 4);
        assert!(r.series.column("true_mass").iter().all(|m| *m > 0.0));
        assert_eq!(
            r.arming.iter().map(|s| s.label.as_str()).collect::<Vec<_>>(),
            ["disarmed", "armed"]
        );
        assert!(r.plans.mission.is_empty() && !r.meta.notes.is_empty());
    }

    #[test]
    fn a_ulog_gives_the_failsafes_its_vehicle_status_flag_turned_on() {
        use crate::autopilot::AutopilotCommand;
        use crate::logs::report::EventKind;
        use crate::logs::ulog::flight::FlightUlog;
        use crate::sim::Fault;
        let (mut core, params) = crate::lockstep::test_quad();
        let mut log = FlightUlog::new(Vec::new(), &params, &core, 0).unwrap();
        for k in 0..12_000 {
            match k {
                2000 => {
                    let _ = core.command(0, AutopilotCommand::Arm { force: false });
                }
                2001 => {
                    let _ = core.command(0, AutopilotCommand::Takeoff { altitude_amsl_m: None });
                }
                8000 => core.world_mut().inject(0, Fault::Gps { available: false }).unwrap(),
                _ => {}
            }
            core.step();
            log.on_step(&mut core, 0).unwrap();
            for (t, s) in core.drain_stamped_status_texts(0) {
                log.status_text(t, &s).unwrap();
            }
        }
        let r = from_ulog(&log.finish().unwrap(), "flight.ulg", None).unwrap();
        let failsafes: Vec<_> = r.events.iter().filter(|e| e.kind == EventKind::Failsafe).collect();
        assert_eq!(failsafes.len(), 1, "{:?}", r.events);
        let f = failsafes[0];
        assert_eq!(f.text, "No GPS fix: descending without position (Descend)");
        assert!((f.t_s - 8.0).abs() < 0.05, "{}", f.t_s);
    }
}
