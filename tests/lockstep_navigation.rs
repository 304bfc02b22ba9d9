//! Lockstep tests of the navigation source (`RP_NAV_SRC`, `[navigation]`):
//! the quad flying on the navigation filter fed by the raw sensors. Arming
//! waits for the filter; the filter's error against the world's truth in
//! hover and along the figure-eight is measured and bounded; a stuck
//! barometer with `EKF2_HGT_REF` = barometer or GNSS is dropped and the
//! flight goes on (PX4's "Continue on baro stuck" cases); a scenario that
//! does not name the source flies the ideal solution; a GNSS loss is flown
//! through on dead reckoning until the filter or `COM_POS_FS_EPH` ends it.
//! `cargo test --release --test lockstep_navigation -- --nocapture` prints the figures.

mod common;

use common::sitl::{Sitl, int, real};
use rotorpilot::autopilot::{AutopilotCommand, CommandOutcome, FlightMode};
use rotorpilot::estimation::nav::HeightSource;
use rotorpilot::lockstep::{Lockstep, Pilot, failure};
use rotorpilot::scenario::{self, Scenario};
use rotorpilot::signals::Measurement;

/// The largest errors of a navigation solution against the truth.
#[derive(Clone, Copy, Debug, Default)]
struct Errors {
    horizontal_m: f64,
    vertical_m: f64,
    velocity_m_s: f64,
    attitude_deg: f64,
}

impl Errors {
    fn add(&mut self, m: &Measurement, truth: &Measurement) {
        let dp = m.position_ned - truth.position_ned;
        self.horizontal_m = self.horizontal_m.max(dp.xy().norm());
        self.vertical_m = self.vertical_m.max(dp.z.abs());
        self.velocity_m_s = self.velocity_m_s.max((m.velocity_ned - truth.velocity_ned).norm());
        self.attitude_deg = self.attitude_deg.max(m.attitude.angle_to(&truth.attitude).to_degrees());
    }
}

/// One step of `core`'s vehicle 0: the solution it flew on against the
/// truth at the same instant (taken before the step).
fn step_and_compare<P: Pilot>(core: &mut Lockstep<P>, errors: &mut Errors) {
    let truth = core.world().plant(0).truth();
    core.step();
    errors.add(core.last_step(0).measurement, &truth);
}

/// The quad on the filter, on the ground at home, failures allowed.
fn quad_on_filter(height_ref: i32) -> Sitl {
    Sitl::quad()
        .params(&[
            ("RP_NAV_SRC", int(1)),
            ("EKF2_HGT_REF", int(height_ref)),
            ("SYS_FAILURE_EN", int(1)),
        ])
        .build()
}

/// Inject a failure as MAV_CMD_INJECT_FAILURE does (`unit`, `kind`, and the
/// instance, 0 for all), and check that it was accepted.
fn inject(v: &mut Sitl, unit: u8, kind: u8, instance: u8) {
    let cmd = AutopilotCommand::InjectFailure { unit, kind, instance };
    assert_eq!(v.command(cmd), CommandOutcome::Accepted);
}

/// Arm once the filter allows it (PX4: no valid position estimate before),
/// take off to `up` m; the time the filter took [s].
fn wait_and_take_off(v: &mut Sitl, up: f64) -> f64 {
    v.run(0.1);
    assert_eq!(
        v.command(AutopilotCommand::Arm { force: false }),
        CommandOutcome::TemporarilyRejected("no valid position estimate")
    );
    assert!(v.count("no valid position estimate") > 0, "{:?}", v.said());
    let ready = v.run_until(20.0, |t| t.prearm_ok).expect("the filter becomes valid");
    v.take_off_to(Some(up));
    ready
}

/// GIVEN the quad with `RP_NAV_SRC` = 1 on the ground
/// WHEN it is asked to arm at once, then once the filter is valid, and takes off to 10 m and hovers 60 s
/// THEN arming is refused first ("no valid position estimate"), then accepted;
/// the raw sensors are simulated; in hover the filter's solution stays within
/// 0.5 m horizontally, 0.5 m vertically, 0.2 m/s and 6 deg (the heading,
/// from a magnetometer with 0.02 gauss of noise) of the truth, and
/// the vehicle within 0.6 m of its hold point.
#[test]
fn the_quad_waits_for_the_filter_then_hovers_on_it() {
    let mut v = quad_on_filter(1);
    assert!(v.core().world().raw_sensors_enabled(0));
    let ready = wait_and_take_off(&mut v, 10.0);
    v.run(20.0);
    let mut e = Errors::default();
    let mut drift: f64 = 0.0;
    let hold = v.core().world().plant(0).truth().position_ned;
    for _ in 0..v.steps(60.0) {
        step_and_compare(v.core_mut(), &mut e);
        drift = drift.max((v.core().world().plant(0).truth().position_ned - hold).norm());
    }
    println!(
        "hover on the filter: ready after {ready:.2} s; largest errors after settling {e:?}; off the hold point {drift:.3} m"
    );
    assert!(e.horizontal_m < 0.5 && e.vertical_m < 0.5, "{e:?}");
    assert!(e.velocity_m_s < 0.2 && e.attitude_deg < 6.0, "{e:?}");
    assert!(drift < 0.6, "{drift}");
}

/// GIVEN the quad on the filter (the geometric law, the default) hovering at 10 m
/// WHEN it holds for 10 s
/// THEN the commanded roll and pitch torques stay calm (RMS under 0.1 N m;
/// with the raw second difference of the desired attitude, 0.45 N m) and no
/// rotor command reaches a limit: the filter's solution, propagated by
/// 250 Hz IMU samples, moves in kinks the law must not chase.
#[test]
fn in_hover_on_the_filter_the_rotors_stay_calm() {
    let mut v = quad_on_filter(1);
    wait_and_take_off(&mut v, 10.0);
    v.run(10.0);
    let (mut sum_sq, mut n, mut saturated) = (0.0, 0usize, 0usize);
    for _ in 0..v.steps(10.0) {
        v.step();
        let out = v.core().last_step(0).control;
        sum_sq += out.command.torque_frd.x.powi(2) + out.command.torque_frd.y.powi(2);
        n += 2;
        saturated += usize::from(out.saturated);
    }
    let rms = (sum_sq / n as f64).sqrt();
    println!("hover on the filter: roll/pitch torque commanded {rms:.3} N m RMS, {saturated} steps saturated");
    assert!(rms < 0.1, "{rms}");
    assert_eq!(saturated, 0);
}

/// The figure-eight of `tools/scenarios/figure-eight-geometric.toml`, 90 s, on `source`.
fn figure_eight(source: &str) -> Scenario {
    let text = format!(
        "airframe = \"quad\"\ncontroller = \"geometric\"\nduration_s = 90.0\n\
         [navigation]\nsource = \"{source}\"\n\
         [reference]\nkind = \"figure_eight\"\nhalf_width_m = 2.0\nrate_rad_s = 0.5\naltitude_m = 2.0\n"
    );
    Scenario::from_toml(&text, "figure-eight.toml", None).expect("a valid scenario")
}

/// GIVEN the figure-eight scenario with `[navigation] source = "filter"` (and "ideal")
/// WHEN it is flown 90 s
/// THEN on the filter the solution stays, after 20 s, within 0.5 m
/// horizontally and vertically, 0.3 m/s and 6 deg (the heading: the
/// magnetometer's 0.02 gauss noise on a 0.2 gauss horizontal field) of the truth, and the
/// vehicle tracks the eight within 0.8 m; on the ideal source nothing of
/// the raw sensors runs.
#[test]
fn the_figure_eight_flies_on_the_filter() {
    let s = figure_eight("filter");
    assert!(s.navigation.is_some());
    let mut core = scenario::lockstep(&s).unwrap();
    assert!(core.world().raw_sensors_enabled(0));
    let settle = (20.0 / s.step_s).round() as usize;
    let steps = (s.duration_s / s.step_s).round() as usize;
    let mut e = Errors::default();
    let mut track: f64 = 0.0;
    for k in 0..steps {
        if k < settle {
            core.step();
            continue;
        }
        step_and_compare(&mut core, &mut e);
        let rec = core.last_step(0);
        let truth = core.world().plant(0).truth();
        let reference = rec.control.reference.position_ned;
        track = track.max((truth.position_ned - reference).norm());
    }
    println!("figure-eight on the filter, after 20 s: largest errors {e:?}; tracking {track:.3} m");
    assert!(e.horizontal_m < 0.5 && e.vertical_m < 0.5, "{e:?}");
    assert!(e.velocity_m_s < 0.3 && e.attitude_deg < 6.0, "{e:?}");
    assert!(track < 0.8, "{track}");
    let ideal = figure_eight("ideal");
    assert!(ideal.navigation.is_none());
    assert!(!scenario::lockstep(&ideal).unwrap().world().raw_sensors_enabled(0));
}

/// GIVEN the quad hovering at 10 m on the filter with `EKF2_HGT_REF` = `height_ref`
/// WHEN the barometer sticks (MAV_CMD_INJECT_FAILURE SENSOR_BARO STUCK) and
/// the vehicle then returns (RTL: climb to 30 m, fly home, land)
/// THEN the filter drops the barometer (stale after PX4's 100 equal
/// samples) and flies on GNSS height, the return completes and the vehicle
/// disarms within 90 s (PX4's "Continue on baro stuck during mission"), its
/// height estimate within 1 m of the truth throughout.
fn baro_stuck(height_ref: i32) {
    let mut v = quad_on_filter(height_ref);
    wait_and_take_off(&mut v, 10.0);
    v.run(10.0);
    let status = v.pilot().navigation().unwrap().filter().status();
    let configured = if height_ref == 0 {
        HeightSource::Baro
    } else {
        HeightSource::Gnss
    };
    assert_eq!(status.height_ref, Some(configured), "{status:?}");
    assert!(status.baro_hgt, "{status:?}");
    inject(&mut v, failure::UNIT_BARO, failure::TYPE_STUCK, 0);
    let t0 = v.time_s();
    let dropped = loop {
        v.step();
        let s = v.pilot().navigation().unwrap().filter().status();
        if s.baro_stale && !s.baro_hgt {
            break v.time_s() - t0;
        }
        assert!(v.time_s() - t0 < 10.0, "the stuck barometer is never dropped: {s:?}");
    };
    let status = v.pilot().navigation().unwrap().filter().status();
    assert_eq!(status.height_ref, Some(HeightSource::Gnss), "{status:?}");
    assert_eq!(
        v.command(AutopilotCommand::SetMode(FlightMode::ReturnToLaunch)),
        CommandOutcome::Accepted
    );
    let mut e = Errors::default();
    let mut top: f64 = 0.0;
    let t1 = v.time_s();
    while v.armed() {
        step_and_compare(v.core_mut(), &mut e);
        top = top.max(-v.core().world().plant(0).truth().position_ned.z);
        assert!(v.time_s() - t1 < 90.0, "still armed 90 s after the return began: {e:?}");
    }
    println!(
        "baro stuck, EKF2_HGT_REF {height_ref}: dropped {dropped:.2} s after it stuck; returned and disarmed {:.1} s later; \
         highest {top:.1} m; largest errors {e:?}",
        v.time_s() - t1
    );
    assert!(e.vertical_m < 1.0, "{e:?}");
    assert!(top < 32.0, "{top}");
}

#[test]
fn a_stuck_barometer_as_height_reference_is_dropped_and_the_return_completes() {
    baro_stuck(0);
}

#[test]
fn a_stuck_barometer_beside_gnss_height_is_dropped_and_the_return_completes() {
    baro_stuck(1);
}

/// GIVEN the quad hovering 10 m up, on the filter and on the ideal solution
/// WHEN its telemetry is read once a second for 20 s
/// THEN on the filter the navigation report (ESTIMATOR_STATUS, ODOMETRY) is a
/// good GNSS-aided solution, every innovation ratio within its gate, the
/// solution within three reported standard deviations of the truth
/// (horizontally `3 sqrt(P_nn + P_ee)`, vertically `3 sqrt(P_dd)`), every
/// variance positive, and the IMU's vibration metric small and positive;
/// on the ideal solution the report is a healthy EKF's with no covariance,
/// and without raw sensors there is no vibration metric.
#[test]
fn the_navigation_report_is_the_filters_and_consistent_with_the_truth() {
    let mut v = quad_on_filter(1);
    wait_and_take_off(&mut v, 10.0);
    v.run(20.0);
    let (mut worst_h, mut worst_v): (f64, f64) = (0.0, 0.0);
    for _ in 0..20 {
        v.run(1.0);
        let t = v.telemetry();
        let truth = v.core().world().plant(0).truth();
        let n = t.navigation;
        let s = n.solution;
        assert!(
            s.attitude && s.velocity_horiz && s.velocity_vert && s.pos_horiz_abs && s.pos_vert_abs,
            "{n:?}"
        );
        assert!(!s.const_pos_mode && !s.gps_glitch, "{n:?}");
        for r in [n.ratios.vel, n.ratios.pos_horiz, n.ratios.pos_vert, n.ratios.mag] {
            assert!(r.is_some_and(|r| (0.0..1.0).contains(&r)), "{n:?}");
        }
        let var = n.variances.expect("the filter's covariance");
        for x in [var.position_ned_m2, var.velocity_ned_m2_s2, var.attitude_frd_rad2] {
            assert!(x.iter().all(|&x| x > 0.0 && x.is_finite()), "{var:?}");
        }
        let dp = t.position_ned - truth.position_ned;
        worst_h = worst_h.max(dp.xy().norm() / n.pos_horiz_accuracy_m);
        worst_v = worst_v.max(dp.z.abs() / n.pos_vert_accuracy_m);
        let vib = t.vibration.expect("the IMU's vibration metric");
        assert!(vib.accel_m_s2 > 0.0 && vib.accel_m_s2 < 0.5, "{vib:?}");
    }
    println!("position error over the reported accuracy: horizontal {worst_h:.2}, vertical {worst_v:.2} sigma");
    assert!(worst_h < 3.0 && worst_v < 3.0, "{worst_h} {worst_v}");

    let mut ideal = Sitl::quad().run_for(5.0);
    ideal.arm_and_take_off(Some(10.0));
    ideal.run(5.0);
    let t = ideal.telemetry();
    assert_eq!(t.navigation.variances, None);
    assert!(t.navigation.solution.pos_horiz_abs && t.navigation.ratios.vel == Some(0.0));
    assert_eq!(t.vibration, None, "no raw sensors on the ideal solution");
}

/// The solution `v` flies on and the truth, every step for `seconds`.
fn record(v: &mut Sitl, seconds: f64) -> Vec<(Measurement, Measurement)> {
    (0..v.steps(seconds))
        .map(|_| {
            v.step();
            let rec = v.core().last_step(0);
            (*rec.measurement, v.core().world().plant(0).truth())
        })
        .collect()
}

/// GIVEN the quad on the filter, flown to 10 m and landed, then rebooted
/// WHEN it waits for the filter and takes off again
/// THEN every step after the reboot is the fresh vehicle's: the raw sensors
/// power-cycle with it (their stream and their sample instants start
/// again), and so do the filter and the flight stack. Equal to the bit
/// until the filter aligns; after that within 0.01 (m, m/s, rad/s and the
/// quaternion's components; measured 1.2e-3 over this takeoff): the filter
/// and its output predictor take intervals and latencies as differences of
/// time stamps, which round differently 30 s into a flight than at 0 s.
#[test]
fn a_flight_after_a_reboot_on_the_filter_is_a_fresh_vehicles() {
    let fly = |v: &mut Sitl| {
        // the filter valid, then a second of probation before arming (PX4's commander)
        let mut steps = record(v, 2.5);
        assert_eq!(
            v.command(AutopilotCommand::Arm { force: false }),
            CommandOutcome::Accepted
        );
        v.take_off_to(Some(3.0));
        steps.extend(record(v, 3.0));
        steps
    };
    let mut fresh = quad_on_filter(1);
    let fresh_steps = fly(&mut fresh);

    let mut used = quad_on_filter(1);
    wait_and_take_off(&mut used, 10.0);
    used.run(5.0);
    used.command(AutopilotCommand::SetMode(FlightMode::Land));
    assert!(used.run_until(60.0, |t| !t.armed).is_some(), "landed and disarmed");
    // a reboot at a step that is no multiple of any sensor's interval
    used.run(0.0137);
    let store = used.params().clone();
    used.core_mut().reboot(0, &store).expect("rebooted");
    let used_steps = fly(&mut used);
    assert_eq!(fresh_steps.len(), used_steps.len());
    let mut largest: f64 = 0.0;
    for (k, (a, b)) in fresh_steps.iter().zip(&used_steps).enumerate() {
        for (x, y) in [(&a.0, &b.0), (&a.1, &b.1)] {
            let d = [
                (x.position_ned - y.position_ned).amax(),
                (x.velocity_ned - y.velocity_ned).amax(),
                (x.rate_frd - y.rate_frd).amax(),
                (x.attitude.coords - y.attitude.coords).amax(),
            ];
            let d = d.into_iter().fold(0.0, f64::max);
            if k < 200 {
                assert_eq!(d, 0.0, "step {k} after the reboot: before the alignment, to the bit");
            }
            assert!(d < 1e-2, "step {k} after the reboot: {d}");
            largest = largest.max(d);
        }
    }
    println!("a flight after a reboot on the filter: at most {largest:.1e} off a fresh vehicle's");
}

/// Take `v` (on the filter) to `up` m, hover 5 s, turn its GNSS receiver
/// off; the time of the loss [s].
fn gnss_off_in_hover(v: &mut Sitl, up: f64) -> f64 {
    wait_and_take_off(v, up);
    v.run(5.0);
    inject(v, failure::UNIT_GPS, failure::TYPE_OFF, 0);
    v.time_s()
}

/// The time after `t0` [s] at which the mode is first `mode` (within `max_s`),
/// with the filter's `eph` [m] and horizontal validity at that step.
fn until_mode(v: &mut Sitl, t0: f64, mode: FlightMode, max_s: f64) -> (f64, f64, bool) {
    while v.mode() != mode {
        assert!(v.time_s() - t0 < max_s, "not {mode:?} within {max_s} s: {:?}", v.mode());
        v.step();
    }
    let f = v.pilot().navigation().unwrap().filter();
    (v.time_s() - t0, f.eph_m(), f.status().horizontal_position_valid)
}

/// GIVEN the quad on the filter hovering 20 m up in Hold (PX4's defaults:
/// `COM_POS_FS_EPH` 5 m, `EKF2_NOAID_TOUT` 5 s)
/// WHEN its GNSS receiver is turned off, and back on 12 s later
/// THEN it holds on the filter's dead reckoning until the filter declares
/// its horizontal position invalid (5 s: PX4's `xy_valid`), drifting less
/// than 1 m meanwhile, and only then descends without a position ("No GPS
/// fix: descending without position"), a failsafe in force; once the fix is
/// back the filter is aided again at once but the commander waits a second
/// of probation before it holds again ("GPS fix regained: holding
/// position") and the failsafe ends; a landing then ends on the ground
/// and disarms.
#[test]
fn a_gnss_loss_is_flown_through_on_dead_reckoning_until_the_filter_gives_up() {
    let mut v = quad_on_filter(1);
    let t0 = gnss_off_in_hover(&mut v, 20.0);
    let p0 = v.core().world().plant(0).truth().position_ned;
    let (lost_s, eph, valid) = until_mode(&mut v, t0, FlightMode::Descend, 10.0);
    let drift = (v.core().world().plant(0).truth().position_ned - p0).xy().norm();
    println!(
        "GNSS off in hover: Hold on dead reckoning for {lost_s:.2} s (eph {eph:.2} m, drift {drift:.2} m), then Descend"
    );
    assert!((4.5..5.5).contains(&lost_s) && !valid, "{lost_s} {valid}");
    assert!(drift < 1.0, "{drift}");
    assert_eq!(v.count("No GPS fix: descending without position"), 1, "{:?}", v.said());
    assert!(
        v.pilot()
            .failsafe_in_force()
            .is_some_and(|f| (f.cause.as_str(), f.triggered) == ("no GPS fix", "Descend"))
    );
    v.run(12.0 - lost_s);
    inject(&mut v, failure::UNIT_GPS, failure::TYPE_OK, 0);
    let t1 = v.time_s();
    let (back_s, _, valid) = until_mode(&mut v, t1, FlightMode::Hold, 5.0);
    println!("GNSS back: Hold again {back_s:.2} s later");
    assert!(valid && (1.0..3.0).contains(&back_s), "{back_s}");
    assert_eq!(v.count("GPS fix regained: holding position"), 1, "{:?}", v.said());
    assert!(v.pilot().failsafe_in_force().is_none());
    // the height estimate jumped when GNSS height came back mid-descent:
    // that stop in the air is no ground; the landing ends on the ground
    assert_eq!(
        v.command(AutopilotCommand::SetMode(FlightMode::Land)),
        CommandOutcome::Accepted
    );
    let (t2, mut fastest): (f64, f64) = (v.time_s(), 0.0);
    while v.armed() {
        v.step();
        fastest = fastest.max(v.core().world().plant(0).truth().velocity_ned.z);
        assert!(v.time_s() - t2 < 60.0, "still armed 60 s after Land");
    }
    let up = -v.core().world().plant(0).truth().position_ned.z;
    assert!(
        up < 0.5 && fastest < 2.0,
        "disarmed {up} m up, fastest descent {fastest} m/s"
    );
}

/// GIVEN the quad on the filter hovering 10 m up in Hold with
/// `COM_POS_FS_EPH` = 0.5 m (its `eph` in hover about 0.3 m)
/// WHEN its GNSS receiver is turned off
/// THEN the autonomous mode gives up as soon as the filter's `eph` passes
/// 2.5 times the threshold (PX4's hysteresis for a valid solution), while
/// the filter still calls its position valid: before its 5 s dead-reckoning
/// limit. Arming waited for the accuracy as well.
#[test]
fn com_pos_fs_eph_ends_the_dead_reckoning_when_the_filter_grows_unsure() {
    let mut v = Sitl::quad()
        .params(&[
            ("RP_NAV_SRC", int(1)),
            ("SYS_FAILURE_EN", int(1)),
            ("COM_POS_FS_EPH", real(0.5)),
        ])
        .build();
    let t0 = gnss_off_in_hover(&mut v, 10.0);
    let (lost_s, eph, valid) = until_mode(&mut v, t0, FlightMode::Descend, 10.0);
    println!("GNSS off, COM_POS_FS_EPH 0.5 m: Descend after {lost_s:.2} s at eph {eph:.2} m");
    assert!(valid && lost_s < 4.8, "{lost_s} {valid}");
    assert!((1.25..1.4).contains(&eph), "{eph}");
}
/// GIVEN the quad on the filter hovering 10 m up in Hold
/// WHEN motor 2 stops (the emergency descent, its heading given up: it
/// comes down tilted and lands hard)
/// THEN the filter keeps a valid position through the touchdown, which stops
/// the vehicle and levels it in one step (the IMU feels both: the stop's
/// impulse and the levelling's rotation), its solution stays within 0.8 m
/// of the truth on the ground (from 1 s after the touchdown, within 0.45 m/s
/// and 3 deg), and the landing is detected although the solution is not yet
/// back on the height the vehicle took off from (the ground stopped a
/// commanded descent: the emergency commands one): the vehicle disarms
/// within 10 s of the failure.
#[test]
fn a_hard_tilted_touchdown_after_a_rotor_loss_leaves_the_filter_on_the_ground() {
    let mut v = quad_on_filter(1);
    wait_and_take_off(&mut v, 10.0);
    v.run(5.0);
    inject(&mut v, failure::UNIT_MOTOR, failure::TYPE_OFF, 2);
    let t0 = v.time_s();
    // the largest errors on the ground, and from 1 s after the touchdown
    let (mut e, mut settled) = (Errors::default(), Errors::default());
    let mut landed_s = None;
    while v.armed() {
        assert!(
            v.time_s() - t0 < 10.0,
            "still armed 10 s after the failure: {:?}",
            v.said()
        );
        let truth = v.core().world().plant(0).truth();
        if truth.position_ned.z <= -0.3 {
            v.step();
            continue;
        }
        let since = v.time_s() - t0 - *landed_s.get_or_insert(v.time_s() - t0);
        v.step();
        let m = v.core().last_step(0).measurement;
        e.add(m, &truth);
        if since >= 1.0 {
            settled.add(m, &truth);
        }
    }
    let disarmed_s = v.time_s() - t0;
    println!(
        "rotor loss on the filter: on the ground {:.2} s after the failure, disarmed after {disarmed_s:.2} s; \
         largest errors on the ground {e:?}; from 1 s after the touchdown {settled:?}",
        landed_s.unwrap_or(f64::NAN)
    );
    assert_eq!(v.count("No valid position estimate"), 0, "{:?}", v.said());
    assert!(e.vertical_m < 0.8 && e.horizontal_m < 0.8, "{e:?}");
    assert!(settled.velocity_m_s < 0.45 && settled.attitude_deg < 3.0, "{settled:?}");
}
