//! Speed of the full loop and of the estimator.
//!
//! * one lockstep step (reference + estimator + controller + allocation + RK4
//!   plant) per airframe and controller, flying a figure-eight;
//! * one estimator update for r = 5 (and r = 3, 20), trapezoidal;
//! * a whole mission flown headless (`rotorpilot simulate` on a mission).
//!
//! Run: `cargo bench --bench vehicle`. Figures go in docs/performance.md.

use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::Vector3;
use rotorpilot::airframe::Airframe;
use rotorpilot::control::ControllerKind;
use rotorpilot::estimation::{EstimatorConfig, MomentumEstimator, Polynomial};
use rotorpilot::scenario::{MissionFlight, Scenario, lockstep, run_mission};
use rotorpilot::signals::ControlWrench;
use rotorpilot::sim::{DisturbanceSource, ExternalWrench};
use std::hint::black_box;

/// The figure-eight at 2 m (inside the quad's ground effect), estimate fed
/// back, through the lockstep core as `rotorpilot simulate` flies it.
fn figure_eight(airframe: &str, kind: ControllerKind) -> Scenario {
    let text = format!(
        "airframe = \"{airframe}\"\ncontroller = \"{}\"\nduration_s = 60.0\n\
         [reference]\nkind = \"figure_eight\"\nhalf_width_m = 2.0\nrate_rad_s = 0.5\naltitude_m = 2.0\n\
         [estimator]\nfeedback = true\n",
        kind.name()
    );
    Scenario::from_toml(&text, "bench", None).unwrap()
}

fn full_step(c: &mut Criterion) {
    let wind = ExternalWrench {
        force_ned: Vector3::new(0.5, 0.5, 0.0),
        torque_frd: Vector3::new(0.0, 0.0, 0.05),
    };
    for name in ["quad", "octo", "fsr-quad"] {
        for kind in ControllerKind::ALL {
            let scenario = figure_eight(name, kind);
            let start = || {
                let mut core = lockstep(&scenario).unwrap();
                core.world_mut().set_disturbance(0, DisturbanceSource::Constant(wind));
                core
            };
            let mut core = start();
            let mut k = 0u64;
            c.bench_function(&format!("full step {name} {}", kind.name()), |b| {
                b.iter(|| {
                    k += 1;
                    if k.is_multiple_of(60_000) {
                        core = start(); // one minute of flight, then again
                    }
                    core.step();
                    black_box(core.last_step(0));
                });
            });
        }
    }
}

fn estimator_update(c: &mut Criterion) {
    let a = Airframe::load("fsr-quad").unwrap();
    for (order, poly) in [
        (3, Polynomial::Butterworth),
        (5, Polynomial::Butterworth),
        (20, Polynomial::Binomial),
    ] {
        let config = EstimatorConfig {
            order,
            polynomial: poly,
            ..EstimatorConfig::default()
        };
        let mut est = MomentumEstimator::new(config, a.nominal()).unwrap();
        // a short recorded flight (a slow wobble), read in a loop: the
        // estimator reads each measurement from memory, as in the vehicle
        let flight: Vec<_> = (0..256)
            .map(|j| {
                let phase = std::f64::consts::TAU * f64::from(j) / 256.0;
                rotorpilot::signals::Measurement {
                    time_s: f64::from(j) * 1e-3,
                    position_ned: Vector3::new(0.0, 0.0, -1.0),
                    velocity_ned: Vector3::new(0.1 * phase.sin(), -0.2, 0.05 * phase.cos()),
                    attitude: rotorpilot::math::from_euler_zyx(&Vector3::new(0.05 + 0.02 * phase.sin(), -0.03, 0.4)),
                    rate_frd: Vector3::new(0.02 * phase.cos(), 0.02, -0.03),
                }
            })
            .collect();
        let u = ControlWrench::new(12.3, Vector3::new(0.01, 0.0, -0.2));
        let mut k = 0usize;
        c.bench_function(&format!("estimator update r={order}"), |b| {
            b.iter(|| {
                k += 1;
                // the path the vehicle uses: straight from the measurement (no Euler angles)
                black_box(est.update_measured(black_box(&flight[k % 256]), &u));
            });
        });
    }
}

/// A whole mission flown headless, as `rotorpilot simulate` flies it: five
/// waypoints around home (automatic takeoff, four fly-through corners, a
/// stop), and the shipped square (takeoff, RTL and landing included).
fn mission_flight(c: &mut Criterion) {
    let five = "duration_s = 300\n[params]\nMPC_XY_CRUISE = 8.0\n[mission]\n\
        [[mission.item]]\ncommand = 16\nparams = [0.0, 3.0, 0.0, nan]\nx = 47.3981917\ny = 8.545594\nz = 10.0\n\
        [[mission.item]]\ncommand = 16\nparams = [0.0, 3.0, 0.0, nan]\nx = 47.3981917\ny = 8.5462583\nz = 15.0\n\
        [[mission.item]]\ncommand = 16\nparams = [0.0, 3.0, 0.0, nan]\nx = 47.397742\ny = 8.5462583\nz = 15.0\n\
        [[mission.item]]\ncommand = 16\nparams = [0.0, 3.0, 0.0, nan]\nx = 47.3973\ny = 8.5459\nz = 12.0\n\
        [[mission.item]]\ncommand = 16\nparams = [0.5, 1.0, 0.0, nan]\nx = 47.397742\ny = 8.545594\nz = 10.0\n";
    let square = std::fs::read_to_string("tools/scenarios/mission-square.toml").unwrap();
    let mut g = c.benchmark_group("mission headless");
    g.sample_size(10);
    for (name, text) in [("5 waypoints", five), ("square with RTL", square.as_str())] {
        let flight = MissionFlight::from_toml(text, name, None).unwrap();
        let s = run_mission(&flight, None).unwrap();
        assert_eq!(s.verdict, "pass", "{name}: {:?}", s.reasons);
        println!("{name}: {:.1} s of simulated flight per run", s.sim_time_s);
        g.bench_function(name, |b| b.iter(|| black_box(run_mission(&flight, None).unwrap())));
    }
    g.finish();
}

criterion_group!(benches, full_step, estimator_update, mission_flight);
criterion_main!(benches);
