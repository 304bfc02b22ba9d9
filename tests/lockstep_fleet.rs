//! Headless fleets: several vehicles in one scenario, flown flat
//! out in lockstep. Each vehicle flies exactly as it would alone (its log
//! byte for byte), the proximity events come at the instant the references
//! say, the same on every run and on any number of threads, and bad fleet
//! files are answered with the file, the field's line and the problem.

mod common;

use common::bin::run as rotorpilot;
use common::{root, scratch_dir as scratch};
use std::path::{Path, PathBuf};

use rotorpilot::scenario::campaign::Outcome;
use rotorpilot::scenario::fleet::{self, Fleet, FleetEvent, FleetFlights, FleetSummary};
use rotorpilot::scenario::{MissionFlight, ReferencePlan, Scenario, run, run_mission};
use rotorpilot::sim::ProximityKind;

/// A fleet file in `dir` whose vehicle paths are relative to the repository's tools/fleets.
fn fleet_file(dir: &Path, name: &str, text: &str) -> PathBuf {
    let fleets = root().join("tools/fleets");
    let text = text.replace("FLEETS/", &format!("{}/", fleets.display()));
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// Events compared to the bit.
fn bits(events: &[FleetEvent]) -> Vec<(u64, usize, usize, u64, ProximityKind)> {
    events
        .iter()
        .map(|e| (e.time_s.to_bits(), e.a, e.b, e.distance_m.to_bits(), e.kind))
        .collect()
}

/// The summary without its wall times, as JSON text.
fn without_wall(s: &FleetSummary) -> String {
    let mut v = serde_json::to_value(s).unwrap();
    for k in ["wall_time_s", "vehicle_steps_per_s", "real_time_factor", "threads"] {
        v[k] = serde_json::json!(0);
    }
    for r in v["results"].as_array_mut().unwrap() {
        r["wall_time_s"] = serde_json::json!(0);
    }
    v.to_string()
}

fn max_err(o: &Outcome) -> f64 {
    match o {
        Outcome::Scenario(s) => s.max_pos_err_m,
        Outcome::Mission(m) => m.max_tracking_error_m,
    }
}

/// Vehicle `i`'s reference position in the world at `t` [m, NED].
fn reference_world(fleet: &Fleet, i: usize, t: f64) -> nalgebra::Vector3<f64> {
    let FleetFlights::Plain(list) = &fleet.flights else {
        panic!("a plain fleet")
    };
    let ReferencePlan::Trajectory(tr) = &list[i].reference else {
        panic!("vehicle {i} flies an analytic reference")
    };
    let o = fleet.offsets_m[i];
    tr.at(t).position_ned + nalgebra::Vector3::new(o[0], o[1], 0.0)
}

/// The fleet of 100: vehicle 0's figure-eight and vehicle 1's circle cross;
/// the first instant their references are closer than the reporting
/// distance `d` is found from the analytic curves (a fine scan, then
/// bisection). The flown event must come within
/// `dt + (e_0 + e_1) / rate`: the true distance differs from the
/// references' by at most the two tracking errors `e_i` (each vehicle's
/// measured max `|p - p_d|`, ~2 mm), which shifts the crossing by at most
/// that over the closing rate `rate = -d|dp|/dt` there; and the event is
/// stamped after the step that crosses (at most one step `dt` late). That
/// bound is a few ms; the event must be the only one (the 98 parked
/// vehicles, 10 m apart and 50 m away, raise none) and two runs (one of
/// them on 2 threads) must give the same events and summaries to the bit.
#[test]
fn crossing_paths_report_the_event_at_the_expected_instant_every_run() {
    let path = root().join("tools/fleets/fleet-crossing.toml");
    let fleet = Fleet::load(&path).unwrap();
    assert_eq!(fleet.len(), 100);
    let d = fleet.proximity_m;
    let gap = |t: f64| (reference_world(&fleet, 0, t) - reference_world(&fleet, 1, t)).norm();
    assert!(gap(0.0) > 2.0 * d, "they start apart");
    let scan = 1e-4;
    let k = (0..100_000)
        .find(|&k| gap(k as f64 * scan) < d)
        .expect("the references cross");
    let (mut lo, mut hi) = ((k - 1) as f64 * scan, k as f64 * scan);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if gap(mid) < d {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    let expected = hi;
    let rate = (gap(expected - 1e-6) - gap(expected + 1e-6)) / 2e-6;
    assert!(rate > 0.5, "a real crossing, closing at {rate} m/s");

    let first = fleet::fly(&fleet, 1, None).unwrap();
    let e01 = max_err(&first.results[0].outcome) + max_err(&first.results[1].outcome);
    let dt = 1e-3;
    let tolerance = dt + e01 / rate;
    // the vehicles' tracking errors, with the quad's drag and no estimate fed
    // back, make it 39.6 ms (1.7 ms drag-free)
    assert!(tolerance < 0.05, "a sharp bound: {tolerance} s");
    assert_eq!(
        first.events.len(),
        1,
        "one event, none among the parked: {:?}",
        first.events
    );
    let e = first.events[0];
    assert_eq!((e.a, e.b, e.kind), (0, 1, ProximityKind::Near));
    assert!(
        (e.time_s - expected).abs() <= tolerance,
        "event at {} s, the references cross at {expected} s (within {tolerance} s)",
        e.time_s
    );
    assert!(
        e.distance_m < d && e.distance_m > d - rate * dt - e01,
        "{}",
        e.distance_m
    );
    for r in &first.results {
        let Outcome::Scenario(s) = &r.outcome else { panic!() };
        assert!(s.upright && s.finite && s.fault.is_none(), "vehicle {}", r.vehicle);
        assert_eq!(s.steps, 8000);
    }
    assert_eq!(first.vehicle_steps, 800_000);

    let again = fleet::fly(&fleet, 1, None).unwrap();
    let threaded = fleet::fly(&fleet, 2, None).unwrap();
    assert_eq!(bits(&first.events), bits(&again.events));
    assert_eq!(bits(&first.events), bits(&threaded.events));
    assert_eq!(without_wall(&first), without_wall(&again));
    assert_eq!(without_wall(&first), without_wall(&threaded));
}

/// A fleet event tells the encounter's closest approach (distance and
/// instant), not only the threshold it crossed: the crossing fleet's two
/// vehicles pass 1.1 m apart, where their references come closest.
#[test]
fn an_encounter_reports_its_closest_approach() {
    let path = root().join("tools/fleets/fleet-crossing.toml");
    let fleet = Fleet::load(&path).unwrap();
    let flown = fleet::fly(&fleet, 1, None).unwrap();
    let e = flown.events[0];
    // the references' closest approach after the event, scanned at 0.1 ms
    let gap = |t: f64| (reference_world(&fleet, 0, t) - reference_world(&fleet, 1, t)).norm();
    let (t_min, d_min) = (0..40_000)
        .map(|k| e.time_s + k as f64 * 1e-4)
        .take_while(|&t| t <= 8.0 && gap(t) <= fleet.proximity_m * 1.1)
        .map(|t| (t, gap(t)))
        .fold((0.0, f64::INFINITY), |m, x| if x.1 < m.1 { x } else { m });
    let e01 = max_err(&flown.results[0].outcome) + max_err(&flown.results[1].outcome);
    println!(
        "event at {:.3} s, {:.3} m; closest {:.4} m at {:.3} s; references {d_min:.4} m at {t_min:.3} s",
        e.time_s, e.distance_m, e.closest_m, e.closest_s
    );
    assert!(e.closest_m < e.distance_m - 0.5, "{e:?}");
    assert!((e.closest_m - d_min).abs() <= e01 + 1e-3, "{e:?} vs {d_min}");
    assert!((e.closest_s - t_min).abs() <= 0.05, "{e:?} vs {t_min}");
    let text = flown.to_text();
    assert!(
        text.contains(&format!(
            "closest approach {:.3} m at t = {:.3} s",
            e.closest_m, e.closest_s
        )),
        "{text}"
    );
    assert!(
        text.contains("proximity (closer than 2 m): 1 event, 0 collisions"),
        "{text}"
    );
}

/// Two paths that meet (vehicle 0's figure-eight through the point where
/// vehicle 1 hovers, reached at `t = pi`): near first, then a collision
/// before the references meet, bodies closer than the sum of their radii.
#[test]
fn paths_that_meet_report_a_collision() {
    let fleet = Fleet::load(&root().join("tools/fleets/fleet-collision.toml")).unwrap();
    let s = fleet::fly(&fleet, 1, None).unwrap();
    let kinds: Vec<_> = s.events.iter().map(|e| (e.a, e.b, e.kind)).collect();
    assert_eq!(
        kinds,
        [(0, 1, ProximityKind::Near), (0, 1, ProximityKind::Collision)],
        "{:?}",
        s.events
    );
    let (near, hit) = (s.events[0], s.events[1]);
    let meet = std::f64::consts::PI;
    assert!((reference_world(&fleet, 0, meet) - reference_world(&fleet, 1, meet)).norm() < 1e-9);
    assert!(near.time_s < hit.time_s && hit.time_s < meet, "{near:?} {hit:?}");
    assert!(
        hit.distance_m < 1.0 && hit.distance_m > 0.3,
        "quad bodies touch below ~0.8 m: {hit:?}"
    );
}

/// Every vehicle's log in `simulate FLEET --csv DIR` is the bytes of its
/// file flown alone (`simulate FILE --csv`): plain scenarios of different
/// airframes, references, faults and durations (each its own), and, in a
/// fleet of missions, the flight stack's flights. Stepped on 2 threads with
/// 18 vehicles (parallel from 16), the logs are the same to the bit.
#[test]
fn each_vehicle_flies_exactly_as_alone_on_any_threads() {
    let dir = scratch("alone");
    let scen = root().join("tools/scenarios");
    let fleet = fleet_file(
        &dir,
        "mixed.toml",
        &format!(
            "[fleet]\nproximity_m = 3.0\n\
             [[vehicle]]\nscenario = \"{s}/quad-step-10m.toml\"\noffset_m = [0.0, 0.0]\n\
             [[vehicle]]\nscenario = \"{s}/octo-rotor-loss.toml\"\noffset_m = [2.0, 0.0]\n\
             [[vehicle]]\nscenario = \"FLEETS/vehicles/circle-3m.toml\"\noffset_m = [0.0, 1.0]\n\
             [[vehicle]]\nscenario = \"FLEETS/vehicles/hover-2m.toml\"\noffset_m = [40.0, 0.0]\ncount = 15\nspacing_m = [5.0, 0.0]\n",
            s = scen.display()
        ),
    );
    let csv = |threads: &str| {
        let out = dir.join(format!("csv-{threads}"));
        let o = rotorpilot(&[
            "simulate",
            fleet.to_str().unwrap(),
            "--threads",
            threads,
            "--json",
            "--csv",
            out.to_str().unwrap(),
        ]);
        assert!(o.ok(), "{}", o.stderr);
        let v: serde_json::Value = serde_json::from_str(&o.stdout).unwrap();
        (out, v)
    };
    let (one, v1) = csv("1");
    let (two, v2) = csv("2");
    assert_eq!(v1["vehicles"], 18);
    assert_eq!(v1["events"], v2["events"]);
    assert!(
        !v1["events"].as_array().unwrap().is_empty(),
        "they start within 3 m: {}",
        v1["events"]
    );
    let loaded = Fleet::load(&fleet).unwrap();
    let FleetFlights::Plain(list) = &loaded.flights else {
        panic!()
    };
    for (i, s) in list.iter().enumerate() {
        let name = fleet::csv_name(i, 18, &s.source);
        let a = std::fs::read(one.join(&name)).unwrap();
        let b = std::fs::read(two.join(&name)).unwrap();
        assert!(a == b, "{name}: 1 and 2 threads differ");
        if i < 4 {
            let mut alone = Vec::new();
            let summary = run(&Scenario::from_file(Path::new(&s.source)).unwrap(), Some(&mut alone)).unwrap();
            assert!(a == alone, "{name}: not the bytes of {} alone", s.source);
            // its summary too: the state and estimate at its own end, though
            // the fleet flies on until its longest flight ends
            let serde_json::Value::Object(fields) = serde_json::to_value(&summary).unwrap() else {
                panic!()
            };
            for (key, value) in fields.iter().filter(|(k, _)| k.as_str() != "wall_time_s") {
                assert_eq!(&v1["results"][i][key], value, "{name}: {key} differs from alone");
            }
        }
    }
    // the rotor loss was applied to its own vehicle only
    let faults = |i: usize| v1["results"][i]["faults"].as_array().map_or(0, Vec::len);
    assert!(faults(1) > 0 && faults(0) == 0 && faults(2) == 0);

    // a fleet of missions: each the flight stack's flight alone
    let mission = root().join("tools/scenarios/mission-square.toml");
    let mfleet = fleet_file(
        &dir,
        "missions.toml",
        &format!(
            "[fleet]\nproximity_m = 2.0\n[[vehicle]]\nscenario = \"{}\"\noffset_m = [0.0, 0.0]\ncount = 2\nspacing_m = [0.0, 30.0]\n",
            mission.display()
        ),
    );
    let out = dir.join("csv-missions");
    let o = rotorpilot(&["simulate", mfleet.to_str().unwrap(), "--csv", out.to_str().unwrap()]);
    assert!(o.ok(), "{}", o.stderr);
    let text = o.stdout;
    assert_eq!(text.matches("PASS").count(), 2, "{text}");
    let mut alone = Vec::new();
    run_mission(&MissionFlight::from_file(&mission).unwrap(), Some(&mut alone)).unwrap();
    for i in 0..2 {
        let name = fleet::csv_name(i, 2, &mission.display().to_string());
        assert!(std::fs::read(out.join(&name)).unwrap() == alone, "mission vehicle {i}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A bad fleet file is answered with the file, the field and its line; a
/// vehicle's file's own errors are that file's; a fleet is refused in a
/// campaign or a directory, and `--threads` outside a fleet.
#[test]
fn bad_fleets_are_answered_clearly() {
    let dir = scratch("bad");
    let hover = "scenario = \"FLEETS/vehicles/hover-2m.toml\"\noffset_m = [0.0, 0.0]\n";
    for (text, says) in [
        (
            format!("[fleet]\nproximity_m = -1.0\n[[vehicle]]\n{hover}"),
            ":2:15: fleet.proximity_m: must be a positive",
        ),
        (
            format!("[fleet]\nproximity_m = 2.0\n[[vehicle]]\n{hover}speed = 3\n"),
            ":6:1: unknown field `speed`",
        ),
        (
            format!("[fleet]\nproximity_m = 2.0\n[[vehicle]]\n{hover}count = 0\n"),
            ":6:9: vehicle[1].count: must be 1",
        ),
        (
            format!("[fleet]\nproximity_m = 2.0\n[[vehicle]]\n{hover}count = 3\nspacing_m = [1.0, inf]\n"),
            ":7:13: vehicle[1].spacing_m: expected [NORTH, EAST]",
        ),
        ("[fleet]\nproximity_m = 2.0\n".into(), "no [[vehicle]]"),
        (
            format!(
                "[fleet]\nproximity_m = 2.0\n[[vehicle]]\n{hover}[[vehicle]]\nscenario = \"{}\"\noffset_m = [9.0, 0.0]\n",
                root().join("tools/scenarios/mission-square.toml").display()
            ),
            ":7:12: vehicle[2].scenario: ",
        ),
        (
            "[fleet]\nproximity_m = 2.0\n[[vehicle]]\nscenario = \"nowhere.toml\"\noffset_m = [0.0, 0.0]\n".into(),
            ":4:12: vehicle[1].scenario: ",
        ),
    ] {
        let p = fleet_file(&dir, "bad.toml", &text);
        let e = format!("{:#}", Fleet::load(&p).unwrap_err());
        assert!(
            e.contains("bad.toml") && e.contains(says),
            "{text}\n-> {e}\n(wanted {says})"
        );
    }
    let mixed = fleet_file(
        &dir,
        "mixed.toml",
        &format!(
            "[fleet]\nproximity_m = 2.0\n[[vehicle]]\n{hover}[[vehicle]]\nscenario = \"{}\"\noffset_m = [9.0, 0.0]\n",
            root().join("tools/scenarios/mission-square.toml").display()
        ),
    );
    let e = format!("{:#}", Fleet::load(&mixed).unwrap_err());
    assert!(e.contains("all plain scenarios or all missions"), "{e}");
    // a vehicle's own file's error names that file and its line
    let broken = dir.join("broken.toml");
    std::fs::write(&broken, "airframe = \"quad\"\nduration_s = 5.0\nwobble = 1\n").unwrap();
    let p = fleet_file(
        &dir,
        "outer.toml",
        &format!(
            "[fleet]\nproximity_m = 2.0\n[[vehicle]]\nscenario = \"{}\"\noffset_m = [0.0, 0.0]\n",
            broken.display()
        ),
    );
    let e = format!("{:#}", Fleet::load(&p).unwrap_err());
    assert!(
        e.contains("outer.toml") && e.contains("broken.toml:3:1") && e.contains("wobble"),
        "{e}"
    );
    // through the CLI: exit 2 and the message
    let o = rotorpilot(&["simulate", p.to_str().unwrap()]);
    assert_eq!(o.code, Some(2));
    assert!(o.stderr.contains("broken.toml:3:1"));
    let o = rotorpilot(&["simulate", root().join("tools/fleets").to_str().unwrap()]);
    assert_eq!(o.code, Some(2));
    assert!(o.stderr.contains("a fleet flies on its own"));
    let quad = root().join("tools/scenarios/quad-step-10m.toml");
    let o = rotorpilot(&["simulate", quad.to_str().unwrap(), "--threads", "2"]);
    assert_eq!(o.code, Some(2));
    assert!(o.stderr.contains("--threads"));
    let _ = std::fs::remove_dir_all(&dir);
}

/// The work a fleet does after each vehicle's step on the thread that
/// stepped it (`Lockstep::step_each`: the tally and the log row) sees that
/// vehicle's own record, the one `last_step` gives once the step is done,
/// the same on 1 and 2 threads.
#[test]
fn the_work_after_each_vehicles_step_sees_its_own_record_on_any_threads() {
    use rotorpilot::airframe::Airframe;
    use rotorpilot::geo::GeoPoint;
    use rotorpilot::lockstep::{FleetVehicle, Lockstep};
    use rotorpilot::params::ParamStore;
    use rotorpilot::sim::{SensorConfig, SensorNoise};

    let airframe = Airframe::load("quad").unwrap();
    let params = ParamStore::new(&airframe);
    let noise = SensorNoise {
        position_m: 0.1,
        velocity_m_s: 0.1,
        attitude_rad: 0.01,
        rate_rad_s: 0.01,
    };
    // more vehicles than one parallel task takes, each with its own noise
    let vehicles: Vec<FleetVehicle<'_>> = (0..24)
        .map(|seed| FleetVehicle {
            airframe: &airframe,
            home: GeoPoint::PX4_SITL_HOME,
            params: &params,
            sensors: SensorConfig { noise, seed },
        })
        .collect();
    let fly = |threads: usize| {
        let mut core = Lockstep::fleet(GeoPoint::PX4_SITL_HOME, &vehicles).unwrap();
        core.set_threads(threads).unwrap();
        let mut seen: Vec<Vec<String>> = vec![Vec::new(); vehicles.len()];
        for _ in 0..20 {
            core.step_each(&mut seen, |s, _, rec| {
                s.push(format!("{:?} {:?}", rec.measurement, rec.world.truth));
            });
            for (i, s) in seen.iter().enumerate() {
                let rec = core.last_step(i);
                assert_eq!(
                    s.last().unwrap(),
                    &format!("{:?} {:?}", rec.measurement, rec.world.truth),
                    "vehicle {i} on {threads} threads"
                );
            }
        }
        seen
    };
    let one = fly(1);
    assert_ne!(one[0], one[1], "each vehicle reads its own noise");
    assert_eq!(one, fly(2));
}

/// A fleet without pages steps each vehicle ahead on its own
/// (`Lockstep::step_ahead`); a fleet whose pages are collected
/// (`--report`) steps one step at a time. Both judge every flight, raise
/// every event and end the fleet at the same step: with flights of
/// different lengths, one stopped by the simulation inside the steps ahead
/// (its state driven non-finite at 0.3 s, after the others ended), a
/// controller switched at another flight's last instant, and vehicles that
/// start within the proximity distance.
#[test]
fn stepping_ahead_judges_every_flight_and_ends_the_fleet_where_one_step_at_a_time_does() {
    use rotorpilot::logs::report::ReportMeta;

    let dir = scratch("ahead");
    let hover = |duration_s: f64, extra: &str| {
        format!(
            "airframe = \"quad\"\ncontroller = \"geometric\"\nduration_s = {duration_s}\n\
             [reference]\nkind = \"hover\"\nposition_ned = [0.0, 0.0, -2.0]\n{extra}"
        )
    };
    let files = [
        (
            "boom.toml",
            hover(1.0, "[[disturbance]]\nat_s = 0.3\nforce_ned = [1e308, 0.0, 0.0]\n"),
        ),
        (
            "switch.toml",
            hover(0.2, "[[switch]]\nat_s = 0.2\ncontroller = \"hierarchical\"\n"),
        ),
        ("short.toml", hover(0.25, "")),
    ];
    for (name, text) in &files {
        std::fs::write(dir.join(name), text).unwrap();
    }
    let path = fleet_file(
        &dir,
        "ends.toml",
        "[fleet]\nproximity_m = 3.0\n\
         [[vehicle]]\nscenario = \"boom.toml\"\noffset_m = [0.0, 0.0]\n\
         [[vehicle]]\nscenario = \"switch.toml\"\noffset_m = [2.0, 0.0]\n\
         [[vehicle]]\nscenario = \"short.toml\"\noffset_m = [0.0, 2.5]\ncount = 16\nspacing_m = [0.0, 1.0]\n",
    );
    let fleet = Fleet::load(&path).unwrap();
    for threads in [1, 2] {
        let ahead = fleet::fly(&fleet, threads, None).unwrap();
        let (one_at_a_time, pages) = fleet::fly_with(&fleet, threads, None, Some(&ReportMeta::default())).unwrap();
        assert_eq!(pages.len(), 18);
        let (a, b) = (without_wall(&ahead), without_wall(&one_at_a_time));
        let first = a.bytes().zip(b.bytes()).position(|(x, y)| x != y);
        assert!(
            a == b,
            "{threads} threads: they differ from byte {first:?}: {}",
            &a[first.unwrap_or(0).saturating_sub(80)..][..160]
        );
        // the fleet ends with the step that stopped the last flight
        assert_eq!(ahead.steps, 301, "{threads} threads");
        let Outcome::Scenario(boom) = &ahead.results[0].outcome else {
            panic!()
        };
        assert!(boom.fault.is_some() && boom.steps == 300, "{boom:?}");
        let Outcome::Scenario(switch) = &ahead.results[1].outcome else {
            panic!()
        };
        assert_eq!(switch.controller, "geometric", "the switch comes after its flight");
        assert!(!ahead.events.is_empty());
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A fleet of flight stacks (the daemon's) stepped ahead
/// (`Lockstep::step_ahead`, as the daemon steps a chunk when nothing logs
/// every step) flies as one step at a time: between chunks of several
/// lengths, where the daemon serves its requests (arming, a takeoff) and
/// publishes, every vehicle's snapshot and stamped status texts are the
/// same to the bit, and so is what the daemon reads at every instant: the
/// time, the proximity events, the encounters followed to their closest
/// approach (one vehicle comes near others and leaves them inside chunks)
/// and the places the steps noted, on 1 and 2 threads.
#[test]
fn flight_stacks_stepped_ahead_fly_as_one_step_at_a_time() {
    use std::ops::ControlFlow;

    use nalgebra::Vector3;
    use rotorpilot::airframe::Airframe;
    use rotorpilot::autopilot::{Autopilot, AutopilotCommand, CommandOutcome};
    use rotorpilot::geo::GeoPoint;
    use rotorpilot::lockstep::{FleetVehicle, Lockstep};
    use rotorpilot::params::ParamStore;
    use rotorpilot::scenario::fleet::encounters::Encounters;
    use rotorpilot::sim::{SensorConfig, SensorNoise};

    let airframe = Airframe::load("quad").unwrap();
    let params = ParamStore::new(&airframe);
    let origin = GeoPoint::PX4_SITL_HOME;
    let noise = SensorNoise {
        position_m: 0.05,
        velocity_m_s: 0.05,
        attitude_rad: 0.005,
        rate_rad_s: 0.005,
    };
    // more vehicles than one parallel task takes, 3 m apart in a row, but
    // vehicle 1 within the 2 m proximity distance of vehicle 0
    let vehicles: Vec<FleetVehicle<'_>> = (0..24_u64)
        .map(|i| FleetVehicle {
            airframe: &airframe,
            home: origin.offset(&Vector3::new(if i == 1 { 1.5 } else { 3.0 * i as f64 }, 0.0, 0.0)),
            params: &params,
            sensors: SensorConfig { noise, seed: i },
        })
        .collect();
    // what the daemon reads at each instant: the time, the proximity
    // events, the encounters it follows (opened, then ended with their
    // closest approach) and the places the vehicles' steps noted
    fn instant(core: &mut Lockstep<Autopilot>, encounters: &mut Encounters) -> String {
        let events = core.drain_proximity_events();
        for (t, e) in &events {
            encounters.open(*t, *e);
        }
        let ended = encounters.follow(core);
        let places: Vec<_> = (0..core.world().len()).map(|i| core.noted_position_ned(i)).collect();
        format!("{} {events:?} {ended:?} {places:?}", core.time_s())
    }
    let chunks = [1_usize, 7, 64, 13, 64, 40, 2, 64];
    let fly = |ahead: bool, threads: usize| {
        let mut core = Lockstep::fleet(origin, &vehicles).unwrap();
        core.set_threads(threads).unwrap();
        core.watch_proximity(2.0);
        let mut seen: Vec<String> = Vec::new();
        let mut encounters = Encounters::default();
        let mut flying = vec![false; vehicles.len()];
        for (c, k) in chunks.iter().cycle().take(240).enumerate() {
            if ahead {
                let mut none = vec![(); vehicles.len()];
                core.step_ahead(
                    *k,
                    &mut none,
                    |(), _, _| {},
                    |core, _| {
                        seen.push(instant(core, &mut encounters));
                        ControlFlow::Continue(())
                    },
                );
            } else {
                for _ in 0..*k {
                    core.step();
                    seen.push(instant(&mut core, &mut encounters));
                }
            }
            // between chunks: every even vehicle arms as soon as it may and
            // takes off to 4 m (vehicle 0 rises away from vehicle 1)
            for (i, up) in flying.iter_mut().enumerate().step_by(2) {
                if !*up && core.command(i, AutopilotCommand::Arm { force: false }) == CommandOutcome::Accepted {
                    let home = core.snapshot(i).telemetry.home.alt_amsl_m;
                    let takeoff = AutopilotCommand::Takeoff {
                        altitude_amsl_m: Some(home + 4.0),
                    };
                    assert_eq!(core.command(i, takeoff), CommandOutcome::Accepted);
                    *up = true;
                }
            }
            // then vehicle 2 flies north, down to 1.5 m, over vehicles 3
            // to 5, coming near them inside chunks
            if c == 100 {
                let to = vehicles[6].home;
                let over = AutopilotCommand::Reposition {
                    lat_deg: Some(to.lat_deg),
                    lon_deg: Some(to.lon_deg),
                    alt_amsl_m: Some(to.alt_amsl_m + 1.5),
                    yaw_rad: None,
                    speed_m_s: None,
                };
                assert_eq!(core.command(2, over), CommandOutcome::Accepted);
            }
            for i in 0..vehicles.len() {
                seen.push(format!(
                    "{i} {:?} {:?}",
                    core.snapshot(i),
                    core.drain_stamped_status_texts(i)
                ));
            }
        }
        assert!(flying.iter().step_by(2).all(|&up| up), "every even vehicle took off");
        let height = -core.world().plant(0).state().position_ned.z;
        assert!(height > 1.0, "vehicle 0 climbs: {height} m");
        seen
    };
    let one_at_a_time = fly(false, 1);
    let near = |s: &String| s.matches("kind: Near").count();
    let ended = |s: &String| s.matches("closest_m").count();
    assert!(
        one_at_a_time.iter().map(near).sum::<usize>() >= 3 && one_at_a_time.iter().map(ended).sum::<usize>() >= 2,
        "vehicles 0 and 1 start near, vehicle 2 comes near others in flight and leaves them: {:?}",
        one_at_a_time
            .iter()
            .filter(|s| near(s) + ended(s) > 0)
            .collect::<Vec<_>>()
    );
    for threads in [1, 2] {
        let ahead = fly(true, threads);
        assert_eq!(ahead.len(), one_at_a_time.len());
        for (a, b) in ahead.iter().zip(&one_at_a_time) {
            assert_eq!(a, b, "stepped ahead on {threads} threads");
        }
    }
}
