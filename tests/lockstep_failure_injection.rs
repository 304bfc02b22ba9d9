//! Failure injection in the lockstep core, as MAV_CMD_INJECT_FAILURE brings it
//! (PX4's FAILURE_UNIT / FAILURE_TYPE numbers) and as a scenario's
//! `[[fault]]` does: each supported pair changes the world as it should and
//! FAILURE_TYPE_OK undoes it; instance 0 is every instance; unsupported pairs
//! are UNSUPPORTED, instances that do not exist DENIED, and both change
//! nothing; SYS_FAILURE_EN = 0 denies everything.

mod common;

use common::sitl::{Sitl, int};
use rotorpilot::autopilot::{AutopilotCommand, CommandOutcome, FlightMode, Severity, StatusText};
use rotorpilot::lockstep::failure::FailureInjection;
use rotorpilot::logs::ulog::flight::FlightUlog;
use rotorpilot::params::ParamValue;
use rotorpilot::scenario::{MissionFlight, Scenario, ScenarioError, run, run_mission};
use rotorpilot::signals::GpsFix;
use rotorpilot::sim::{ActiveFaults, DEAD_RECKONING_BIAS_M_S2, RotorHealth};
use rotorpilot::tomlfile::FileError;

const GYRO: u8 = 0;
const ACCEL: u8 = 1;
const MAG: u8 = 2;
const BARO: u8 = 3;
const GPS: u8 = 4;
const BATTERY: u8 = 100;
const MOTOR: u8 = 101;
const MAVLINK_SIGNAL: u8 = 105;
const OK: u8 = 0;
const OFF: u8 = 1;
const STUCK: u8 = 2;
const WRONG: u8 = 4;

/// `airframe` with failure injection allowed (SYS_FAILURE_EN = 1) and
/// `params`, one step after the start.
fn vehicle(airframe: &str, params: &[(&str, ParamValue)]) -> Sitl {
    let mut v = Sitl::airframe(airframe)
        .params(&[("SYS_FAILURE_EN", int(1))])
        .params(params)
        .build();
    v.step();
    v
}

fn inject(v: &mut Sitl, unit: u8, kind: u8, instance: u8) -> CommandOutcome {
    v.command(AutopilotCommand::InjectFailure { unit, kind, instance })
}

fn faults(v: &Sitl) -> ActiveFaults {
    v.core().world().faults(0).clone()
}

/// Arm and take off to MIS_TAKEOFF_ALT, then hover a moment.
fn airborne(v: &mut Sitl) {
    v.arm_and_take_off(None);
    v.run(8.0);
    assert_eq!(v.mode(), FlightMode::Hold);
}

/// GIVEN SYS_FAILURE_EN = 0 (PX4's default)
/// WHEN a client injects a supported failure
/// THEN it is DENIED with a STATUSTEXT saying why, and the world is unchanged.
#[test]
fn failure_injection_is_denied_while_sys_failure_en_is_0() {
    let mut v = vehicle("quad", &[]);
    v.set_param("SYS_FAILURE_EN", ParamValue::Int32(0));
    let before = faults(&v);
    assert!(matches!(inject(&mut v, GPS, OFF, 0), CommandOutcome::Denied(_)));
    assert_eq!(faults(&v), before);
    let t = v.texts();
    assert!(t.iter().any(|s| s.text.contains("SYS_FAILURE_EN")), "{t:?}");
    assert!(!t.iter().any(|s| s.text.starts_with("CMD_INJECT_FAILURE")), "{t:?}");
    // allowed again: accepted
    v.set_param("SYS_FAILURE_EN", ParamValue::Int32(1));
    assert_eq!(inject(&mut v, GPS, OFF, 0), CommandOutcome::Accepted);
    assert!(!faults(&v).gps_available);
}

/// GIVEN a hovering quad
/// WHEN motor 2 is switched off, then made WRONG (SIM_MOT_WRONG_FR = 0.25), then OK
/// THEN the rotor PX4's quad-X numbers 2, the rear left (the file's rotor 3),
/// is hit: its ESC reads no speed, then half the others' (a quarter of the
/// thrust is half the speed), then the commanded speed again; each announced.
#[test]
fn motor_off_wrong_and_ok_reach_the_rotor() {
    let mut v = vehicle("quad", &[]);
    airborne(&mut v);
    v.texts();
    assert_eq!(inject(&mut v, MOTOR, OFF, 2), CommandOutcome::Accepted);
    assert_eq!(faults(&v).rotors[2], RotorHealth::Off);
    assert_eq!(
        v.texts(),
        vec![StatusText {
            severity: Severity::Warning,
            text: "CMD_INJECT_FAILURE, motor 2 off".into()
        }]
    );
    v.run(0.3);
    let esc = v.readings().rotor_speeds_rad_s;
    assert!(esc[2] < 1.0, "dead rotor spins at {}", esc[2]);
    assert!(esc[0] > 100.0 && esc[1] > 100.0 && esc[3] > 100.0, "{esc:?}");

    v.set_param("SIM_MOT_WRONG_FR", ParamValue::Real32(0.25));
    assert_eq!(inject(&mut v, MOTOR, WRONG, 2), CommandOutcome::Accepted);
    assert_eq!(faults(&v).rotors[2], RotorHealth::Degraded { thrust_fraction: 0.25 });
    // the flight stack has said its own piece meanwhile (the rotor monitor's verdict)
    let said = v.texts();
    assert!(
        said.iter()
            .any(|s| s.text == "CMD_INJECT_FAILURE, motor 2 wrong (25% thrust)"),
        "{said:?}"
    );

    assert_eq!(inject(&mut v, MOTOR, OK, 2), CommandOutcome::Accepted);
    assert!(!faults(&v).any());
    assert_eq!(
        v.texts(),
        vec![StatusText {
            severity: Severity::Info,
            text: "CMD_INJECT_FAILURE, motor 2 ok".into()
        }]
    );
}

/// GIVEN an octocopter
/// WHEN instance 0 (all) is switched off, then OK
/// THEN every rotor is off, then every rotor is healthy.
#[test]
fn instance_0_is_every_motor() {
    let mut v = vehicle("octo", &[]);
    assert_eq!(inject(&mut v, MOTOR, OFF, 0), CommandOutcome::Accepted);
    let f = faults(&v);
    assert_eq!(f.rotors.len(), 8);
    assert!(f.rotors.iter().all(|r| *r == RotorHealth::Off));
    assert_eq!(v.texts()[0].text, "CMD_INJECT_FAILURE, motors off");
    assert_eq!(inject(&mut v, MOTOR, OK, 0), CommandOutcome::Accepted);
    assert!(!faults(&v).any());
}

/// GIVEN a quad at rest (its true state still)
/// WHEN its GPS goes off for 10 s
/// THEN the receiver has no fix and no satellites, and the navigation solution
/// dead-reckons: horizontal velocity off by `a tau`, position by `a tau^2 / 2`
/// (a = the dead-reckoning bias), vertical untouched; GPS OK puts it back on
/// the truth at once. GPS WRONG puts it SIM_GPS_WRONG_M north.
#[test]
fn gps_off_drifts_wrong_offsets_and_ok_restores() {
    let mut v = vehicle("quad", &[]);
    assert_eq!(inject(&mut v, GPS, OFF, 1), CommandOutcome::Accepted);
    assert_eq!(v.texts()[0].text, "CMD_INJECT_FAILURE, GPS off");
    v.run(10.0);
    let truth = *v.core().world().plant(0).state();
    let r = v.readings();
    assert_eq!((r.gps.fix, r.gps.satellites), (GpsFix::None, 0));
    let t = v.telemetry();
    assert_eq!((t.gps_fix, t.gps_satellites), (GpsFix::None, 0));
    let dp = r.measurement.position_ned - truth.position_ned;
    let dv = r.measurement.velocity_ned - truth.velocity_ned;
    let a = DEAD_RECKONING_BIAS_M_S2;
    assert!((dv.norm() - a * 10.0).abs() < 1e-9, "velocity error {dv}");
    assert!((dp.norm() - a * 50.0).abs() < 1e-6, "position error {dp}");
    assert_eq!((dp.z, dv.z), (0.0, 0.0), "the drift is horizontal");
    assert!((dp.normalize() - dv.normalize()).norm() < 1e-9, "one direction");

    assert_eq!(inject(&mut v, GPS, OK, 0), CommandOutcome::Accepted);
    assert_eq!(v.texts()[0].text, "CMD_INJECT_FAILURE, GPS ok");
    let r = v.readings();
    assert_eq!(r.gps.fix, GpsFix::Fix3d);
    assert_eq!(
        r.measurement.position_ned,
        v.core().world().plant(0).state().position_ned
    );

    v.set_param("SIM_GPS_WRONG_M", ParamValue::Real32(25.0));
    assert_eq!(inject(&mut v, GPS, WRONG, 0), CommandOutcome::Accepted);
    v.run(1.0);
    let truth = v.core().world().plant(0).state().position_ned;
    let m = v.readings().measurement.position_ned;
    assert_eq!(m - truth, nalgebra::Vector3::new(25.0, 0.0, 0.0));
    assert_eq!(inject(&mut v, GPS, OK, 0), CommandOutcome::Accepted);
    let m = v.readings().measurement.position_ned;
    assert_eq!(m, v.core().world().plant(0).state().position_ned);
    assert!(!faults(&v).any());
}

/// GIVEN a full 4S pack
/// WHEN one cell fails (BATTERY OFF)
/// THEN the pack reads one cell's voltage less and the monitor (counting four
/// cells) sees an almost empty pack; BATTERY OK gives the voltage back.
#[test]
fn battery_off_loses_a_cell_and_ok_gives_it_back() {
    let mut v = vehicle("quad", &[]);
    let before = v.telemetry();
    assert!(before.battery_remaining > 0.9, "{}", before.battery_remaining);
    assert_eq!(inject(&mut v, BATTERY, OFF, 0), CommandOutcome::Accepted);
    assert_eq!(v.texts()[0].text, "CMD_INJECT_FAILURE, battery cell off");
    let failed = v.telemetry();
    let ratio = failed.battery_voltage_v / before.battery_voltage_v;
    assert!((ratio - 0.75).abs() < 0.01, "{ratio}");
    assert!(failed.battery_remaining < 0.05, "{}", failed.battery_remaining);
    assert_eq!(inject(&mut v, BATTERY, OK, 0), CommandOutcome::Accepted);
    assert_eq!(v.telemetry().battery_voltage_v, before.battery_voltage_v);
}

/// MAVLINK_SIGNAL OFF and OK set and clear the world's radio (the daemon mutes its links on it).
#[test]
fn mavlink_signal_off_and_ok_switch_the_radio() {
    let mut v = vehicle("quad", &[]);
    assert_eq!(inject(&mut v, MAVLINK_SIGNAL, OFF, 0), CommandOutcome::Accepted);
    assert!(faults(&v).link_lost);
    assert_eq!(v.texts()[0].text, "CMD_INJECT_FAILURE, MAVLink off");
    assert_eq!(inject(&mut v, MAVLINK_SIGNAL, OK, 0), CommandOutcome::Accepted);
    assert!(!faults(&v).any());
}

/// GIVEN a hovering quad with a battery cell failed and GPS off
/// WHEN a client asks for pairs PX4 does not carry out here (gyro, GPS stuck,
/// battery wrong, radio wrong, an unknown unit) or for a part that does not
/// exist (motor 9 of four, a second GPS)
/// THEN they are UNSUPPORTED or DENIED, and neither the world's faults nor
/// the autopilot's state changes, nor is anything announced.
#[test]
fn unsupported_and_missing_parts_change_nothing() {
    let mut v = vehicle("quad", &[]);
    airborne(&mut v);
    assert_eq!(inject(&mut v, BATTERY, OFF, 0), CommandOutcome::Accepted);
    v.texts();
    let before = faults(&v);
    let state = |c: &Sitl| (c.pilot().armed(), c.pilot().mode());
    let s0 = state(&v);
    for (unit, kind) in [
        (GYRO, WRONG),
        (BARO, WRONG),
        (MAG, 3),
        (GPS, 3),
        (BATTERY, WRONG),
        (MAVLINK_SIGNAL, WRONG),
        (104, OFF),
        (255, OFF),
    ] {
        assert_eq!(
            inject(&mut v, unit, kind, 0),
            CommandOutcome::Unsupported,
            "{unit}/{kind}"
        );
    }
    for (unit, kind, instance) in [
        (MOTOR, OFF, 9),
        (MOTOR, OK, 5),
        (GPS, OFF, 2),
        (BATTERY, OK, 3),
        (BARO, STUCK, 2),
        (MAG, OFF, 2),
    ] {
        assert!(
            matches!(inject(&mut v, unit, kind, instance), CommandOutcome::Denied(_)),
            "{unit}/{kind}/{instance}"
        );
    }
    assert_eq!(faults(&v), before);
    assert_eq!(state(&v), s0);
    assert!(v.texts().is_empty());
}

/// GIVEN a hovering quad whose raw sensors are simulated (as the daemon's are)
/// WHEN the barometer is STUCK, then OFF, then OK; the magnetometer OFF then
/// OK; the gyroscope and accelerometer STUCK; the GPS STUCK, each as PX4's
/// unit numbers with instance 0 or 1
/// THEN each is ACCEPTED and announced, and over the following second the
/// samples show it: a stuck sensor repeats one value with new times, an off
/// one gives nothing, an OK one fresh noisy values again; the navigation
/// solution the vehicle flies on is untouched.
#[test]
fn raw_sensor_faults_show_in_the_samples_over_time() {
    let mut v = vehicle("quad", &[]);
    v.core_mut().enable_raw_sensors(0);
    airborne(&mut v);
    let raw = |v: &mut Sitl| *v.core().world().raw_readings(0);
    // healthy: every sensor gives fresh values
    let r0 = raw(&mut v);
    v.run(0.2);
    let r1 = raw(&mut v);
    let (b0, b1) = (r0.baro.unwrap(), r1.baro.unwrap());
    assert!(
        b1.time_s > b0.time_s && b1.pressure_pa != b0.pressure_pa,
        "{b0:?} {b1:?}"
    );
    v.texts();
    // baro stuck: one pressure, new times
    assert_eq!(inject(&mut v, BARO, STUCK, 0), CommandOutcome::Accepted);
    v.run(0.1);
    let stuck = raw(&mut v).baro.unwrap();
    for _ in 0..10 {
        v.run(0.1);
        let b = raw(&mut v).baro.unwrap();
        assert_eq!(b.pressure_pa.to_bits(), stuck.pressure_pa.to_bits());
        assert!(b.time_s > stuck.time_s);
    }
    // baro off: nothing
    assert_eq!(inject(&mut v, BARO, OFF, 1), CommandOutcome::Accepted);
    v.run(0.1);
    assert_eq!(raw(&mut v).baro, None);
    // baro ok: fresh values at the vehicle's height (ISA: about 12 Pa per metre)
    assert_eq!(inject(&mut v, BARO, OK, 0), CommandOutcome::Accepted);
    v.run(0.1);
    let live = raw(&mut v).baro.unwrap();
    v.run(0.1);
    assert_ne!(raw(&mut v).baro.unwrap().pressure_pa, live.pressure_pa);
    // mag off, then ok
    assert_eq!(inject(&mut v, MAG, OFF, 0), CommandOutcome::Accepted);
    v.run(0.1);
    assert_eq!(raw(&mut v).mag, None);
    assert_eq!(inject(&mut v, MAG, OK, 0), CommandOutcome::Accepted);
    v.run(0.1);
    assert!(raw(&mut v).mag.is_some());
    // gyro and accel stuck; gps stuck
    for unit in [GYRO, ACCEL, GPS] {
        assert_eq!(inject(&mut v, unit, STUCK, 0), CommandOutcome::Accepted);
    }
    v.run(0.3);
    let a = raw(&mut v);
    v.run(0.3);
    let b = raw(&mut v);
    assert_eq!(a.gyro.unwrap().frd, b.gyro.unwrap().frd);
    assert_eq!(a.accel.unwrap().frd, b.accel.unwrap().frd);
    assert_eq!(a.gnss.unwrap().lat_deg, b.gnss.unwrap().lat_deg);
    assert!(b.gnss.unwrap().delivered_s > a.gnss.unwrap().delivered_s);
    let texts: Vec<String> = v.texts().into_iter().map(|s| s.text).collect();
    for said in [
        "baro stuck",
        "baro off",
        "baro ok",
        "mag off",
        "mag ok",
        "gyro stuck",
        "accel stuck",
        "GPS stuck",
    ] {
        assert!(texts.iter().any(|t| t.contains(said)), "{said}: {texts:?}");
    }
    // the vehicle still hovers on its navigation solution
    assert_eq!(v.mode(), FlightMode::Hold);
    assert!(faults(&v).any());
}

/// GIVEN two flights of one quad at rest whose raw sensors are simulated,
/// with the same inputs
/// WHEN one is watched between every pair of steps (a link's snapshot and
/// the ULog writer read it) and both get raw-sensor faults injected between
/// steps, right before instants at which every sensor is due (as a
/// scenario's `[[fault]]` injects them: nothing reads the sensors first)
/// THEN the raw samples the steps drew are the same bit for bit: what an
/// observer reads, and when, changes no number of the flight (a live flight's
/// raw topics are its replay's).
#[test]
fn observers_between_steps_change_no_raw_sample() {
    // every sensor is due at the instants that are multiples of 0.5 s
    let faults = [
        (500, BARO, STUCK),
        (500, ACCEL, OFF),
        (1000, BARO, OFF),
        (1000, MAG, OFF),
        (1000, GPS, STUCK),
        (1500, BARO, OK),
        (1500, ACCEL, OK),
        (1500, MAG, OK),
        (1500, GPS, OK),
    ];
    let fly = |watched: bool| {
        let mut v = vehicle("quad", &[]);
        v.core_mut().enable_raw_sensors(0);
        let mut ulog = watched.then(|| FlightUlog::new(Vec::new(), v.params(), v.core(), 0).unwrap());
        let mut samples = Vec::new();
        while v.core().steps() < 2000 {
            for &(at, unit, kind) in &faults {
                if at == v.core().steps() {
                    let inj = FailureInjection {
                        unit,
                        kind,
                        instance: 0,
                    };
                    assert_eq!(v.core_mut().inject_failure(0, inj), CommandOutcome::Accepted);
                }
            }
            v.step();
            samples.push(*v.core().world().raw_readings(0));
            if let Some(log) = &mut ulog {
                log.on_step(v.core_mut(), 0).unwrap();
                let _ = v.core_mut().snapshot(0);
            }
        }
        samples
    };
    let (quiet, watched) = (fly(false), fly(true));
    assert!(quiet.iter().any(|r| r.baro.is_none()) && quiet.iter().any(|r| r.accel.is_none()));
    for (k, (a, b)) in quiet.iter().zip(&watched).enumerate() {
        assert_eq!(format!("{a:?}"), format!("{b:?}"), "after step {k}");
    }
}

/// An airframe whose thrust and torque act directly has no motor to fail: DENIED.
#[test]
fn ideal_actuation_has_no_motor_to_fail() {
    let mut v = vehicle("fsr-quad", &[]);
    let before = faults(&v);
    assert!(matches!(inject(&mut v, MOTOR, OFF, 1), CommandOutcome::Denied(_)));
    assert_eq!(faults(&v), before);
    // its GPS fails as any other
    assert_eq!(inject(&mut v, GPS, OFF, 0), CommandOutcome::Accepted);
}

/// GIVEN two identical hovering vehicles
/// WHEN one gets every failure switched off and back OK at one instant
/// THEN both fly on bit for bit: OK restores exactly what was.
#[test]
fn off_then_ok_at_one_instant_leaves_the_flight_as_it_was() {
    let mut a = vehicle("quad", &[]);
    let mut b = vehicle("quad", &[]);
    airborne(&mut a);
    airborne(&mut b);
    for (unit, instance) in [
        (MOTOR, 0),
        (GPS, 0),
        (BATTERY, 0),
        (MAVLINK_SIGNAL, 0),
        (GYRO, 0),
        (ACCEL, 1),
        (MAG, 0),
        (BARO, 1),
    ] {
        assert_eq!(inject(&mut b, unit, OFF, instance), CommandOutcome::Accepted);
        assert_eq!(inject(&mut b, unit, OK, instance), CommandOutcome::Accepted);
    }
    a.run(3.0);
    b.run(3.0);
    assert_eq!(a.core().world().plant(0).state(), b.core().world().plant(0).state());
    assert_eq!(a.telemetry(), b.telemetry());
}

/// The lockstep's own injection (what a scenario without an autopilot uses)
/// does not ask SYS_FAILURE_EN but maps the same way.
#[test]
fn inject_failure_maps_without_the_autopilot_gate() {
    let mut v = vehicle("quad", &[]);
    v.set_param("SYS_FAILURE_EN", ParamValue::Int32(0));
    let inj = |unit, kind, instance| FailureInjection { unit, kind, instance };
    assert_eq!(
        v.core_mut().inject_failure(0, inj(MOTOR, OFF, 4)),
        CommandOutcome::Accepted
    );
    // PX4's motor 4 of a quad-X: the rear right, the file's rotor 2
    assert_eq!(faults(&v).rotors[1], RotorHealth::Off);
    assert_eq!(
        v.core_mut().inject_failure(0, inj(GPS, 3, 0)),
        CommandOutcome::Unsupported
    );
    assert!(matches!(
        v.core_mut().inject_failure(0, inj(MOTOR, OFF, 5)),
        CommandOutcome::Denied(_)
    ));
    assert_eq!(v.core_mut().drain_world_texts(0).len(), 1);
}

// --- scenarios -------------------------------------------------------------------------------

const HOVER: &str = r#"
airframe = "quad"
duration_s = 3.0

[[setpoint]]
at_s = 0.0
position_ned = [0.0, 0.0, -2.0]
"#;

fn scenario(extra: &str) -> Result<Scenario, ScenarioError> {
    Scenario::from_toml(&format!("{HOVER}{extra}"), "hover.toml", None)
}

fn invalid(extra: &str) -> (String, String) {
    match scenario(extra) {
        Err(ScenarioError::File(FileError::Invalid { file, field, problem })) => {
            assert_eq!(file, "hover.toml");
            (field, problem)
        }
        other => panic!("expected an invalid field, got {other:?}"),
    }
}

/// Bad `[[fault]]` entries are errors that name the file and the field (and
/// for a wrong name or key, the line).
#[test]
fn scenario_fault_errors_name_file_field_and_line() {
    // an unknown unit: a syntax error at its line
    match scenario("\n[[fault]]\nat_s = 1.0\nunit = \"rotor\"\ntype = \"off\"\n") {
        Err(ScenarioError::File(FileError::Syntax {
            file, line, message, ..
        })) => {
            assert_eq!(file, "hover.toml");
            assert_eq!(line, 11, "{message}");
            assert!(message.contains("rotor") && message.contains("motor"), "{message}");
        }
        other => panic!("{other:?}"),
    }
    match scenario("\n[[fault]]\nat_s = 1.0\nunit = \"gps\"\ntype = \"drift\"\n") {
        Err(ScenarioError::File(FileError::Syntax { line, .. })) => assert_eq!(line, 12),
        other => panic!("{other:?}"),
    }
    match scenario("\n[[fault]]\nat_s = 1.0\nunit = \"gps\"\ntype = \"off\"\nfraction = 1\n") {
        Err(ScenarioError::File(FileError::Syntax { message, .. })) => assert!(message.contains("fraction")),
        other => panic!("{other:?}"),
    }
    let two = "\n[[fault]]\nat_s = 1.0\nunit = \"gps\"\ntype = \"off\"\n[[fault]]\n";
    let (field, problem) = invalid(&format!(
        "{two}at_s = 9.0\nunit = \"motor\"\ntype = \"off\"\ninstance = 1\n"
    ));
    assert_eq!(field, "fault[2].at_s");
    assert!(problem.contains("duration_s"), "{problem}");
    let (field, problem) = invalid(&format!(
        "{two}at_s = 2.0\nunit = \"motor\"\ntype = \"off\"\ninstance = 9\n"
    ));
    assert_eq!(field, "fault[2].instance");
    assert!(problem.contains("4 motors"), "{problem}");
    let (field, _) = invalid(&format!("{two}at_s = 2.0\nunit = \"battery\"\ntype = \"wrong\"\n"));
    assert_eq!(field, "fault[2].type");
    let (field, _) = invalid(&format!(
        "{two}at_s = 2.0\nunit = \"gps\"\ntype = \"wrong\"\nthrust_fraction = 0.5\n"
    ));
    assert_eq!(field, "fault[2].thrust_fraction");
    let (field, problem) = invalid(&format!(
        "{two}at_s = 2.0\nunit = \"motor\"\ntype = \"wrong\"\ninstance = 1\nthrust_fraction = 1.5\n"
    ));
    assert_eq!(field, "fault[2].thrust_fraction");
    assert!(problem.contains("[0, 1]"), "{problem}");
}

/// GIVEN a hover scenario with motor 1 made WRONG at 1 s (thrust fraction 0.3)
/// and GPS off at 2 s
/// THEN the summary lists both, at their instants, accepted, in time order,
/// and the JSON carries them; a scenario without faults has no `faults` key.
#[test]
fn scenario_faults_are_applied_at_their_instant_and_listed() {
    let s = scenario(
        "\n[[fault]]\nat_s = 2.0\nunit = \"gps\"\ntype = \"off\"\n\
         \n[[fault]]\nat_s = 1.0\nunit = \"motor\"\ntype = \"wrong\"\ninstance = 1\nthrust_fraction = 0.3\n",
    )
    .unwrap();
    let summary = run(&s, None).unwrap();
    let lines: Vec<String> = summary.faults.iter().map(|f| f.to_line()).collect();
    assert_eq!(
        lines,
        vec![
            "t = 1.000 s: motor 1 wrong: accepted".to_string(),
            "t = 2.000 s: gps (all) off: accepted".to_string()
        ]
    );
    let json = serde_json::to_value(&summary).unwrap();
    assert_eq!(json["faults"][0]["unit"], "motor");
    assert_eq!(json["faults"][0]["type"], "wrong");
    assert_eq!(json["faults"][0]["time_s"], 1.0);
    assert_eq!(json["faults"][1]["outcome"], "accepted");
    // the flight felt it: a weak rotor pulls the hover off its point
    let clean = run(&scenario("").unwrap(), None).unwrap();
    assert!(summary.max_pos_err_m > clean.max_pos_err_m + 1e-3);
    assert!(serde_json::to_value(&clean).unwrap().get("faults").is_none());
}

/// A mission TOML's `[[fault]]` goes through the autopilot's command (as a
/// client's MAV_CMD_INJECT_FAILURE), SYS_FAILURE_EN set for it; one the
/// scenario's parameters forbid is listed as denied.
#[test]
fn mission_faults_go_through_the_command() {
    let mission = "duration_s = 40\n\
        [[fault]]\nat_s = 5.0\nunit = \"battery\"\ntype = \"off\"\n\
        [[fault]]\nat_s = 6.0\nunit = \"battery\"\ntype = \"ok\"\n\
        [mission]\n\
        [[mission.item]]\ncommand = 22\nx = 47.397742\ny = 8.545594\nz = 5.0\n";
    let f = MissionFlight::from_toml(mission, "m.toml", None).unwrap();
    let s = run_mission(&f, None).unwrap();
    let outcomes: Vec<&str> = s.faults.iter().map(|f| f.outcome.as_str()).collect();
    assert_eq!(outcomes, ["accepted", "accepted"]);
    assert_eq!(s.faults[0].time_s, 5.0);
    let forbidden = mission.replace("[mission]", "[params]\nSYS_FAILURE_EN = 0\n[mission]");
    let f = MissionFlight::from_toml(&forbidden, "m.toml", None).unwrap();
    let s = run_mission(&f, None).unwrap();
    assert!(s.faults[0].outcome.starts_with("denied"), "{:?}", s.faults);
}

/// GIVEN a quad in the air
/// WHEN a client turns every motor off at once (instance 0 = all)
/// THEN the vehicle falls and is stepped on, rather than the simulation
/// panicking on the empty allocation left (found by tests/fuzz.rs: the
/// rank of an effectiveness matrix with no column).
#[test]
fn every_motor_off_at_once_drops_the_vehicle_without_a_panic() {
    let mut v = vehicle("quad", &[]);
    airborne(&mut v);
    let z0 = v.telemetry().position_ned.z;
    assert_eq!(inject(&mut v, 101, 1, 0), CommandOutcome::Accepted);
    v.run(3.0);
    let t = v.telemetry();
    assert!(t.position_ned.z > z0 + 1.0, "it fell: z {z0} -> {}", t.position_ned.z);
    assert!(t.position_ned.iter().all(|x| x.is_finite()));
}

/// GIVEN an octo whose motor 3 was switched off in a hover, which then
/// landed (COM_ACT_FAIL_ACT Land) and disarmed, arming refused ("ESC failure")
/// WHEN motor 3 is made OK again (FAILURE_TYPE_OK)
/// THEN "Motor 3 recovered" is said and arming is allowed, as PX4 arms once
/// its ESC reports healthy (its failure injector cleared).
#[test]
fn motor_off_then_ok_arms_again() {
    let mut v = vehicle("octo", &[("COM_ACT_FAIL_ACT", int(2))]);
    airborne(&mut v);
    assert_eq!(inject(&mut v, MOTOR, OFF, 3), CommandOutcome::Accepted);
    for _ in 0..v.steps(60.0) {
        v.step();
        if !v.pilot().armed() {
            break;
        }
    }
    assert!(!v.pilot().armed(), "landed and disarmed");
    v.run(1.0);
    assert_eq!(
        v.command(AutopilotCommand::Arm { force: false }),
        CommandOutcome::TemporarilyRejected("ESC failure")
    );
    v.texts();
    assert_eq!(inject(&mut v, MOTOR, OK, 3), CommandOutcome::Accepted);
    let said = v.texts();
    assert!(said.iter().any(|s| s.text == "Motor 3 recovered"), "{said:?}");
    v.run(0.5);
    assert_eq!(
        v.command(AutopilotCommand::Arm { force: false }),
        CommandOutcome::Accepted
    );
    assert!(v.pilot().armed());
}
