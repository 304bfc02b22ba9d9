//! Speed of the full loop and of the estimator.
//!
//! * one lockstep step (reference + estimator + controller + allocation + RK4
//!   plant) per airframe and controller, flying a figure-eight;
//! * one estimator update for r = 5 (and r = 3, 20), trapezoidal.
//!
//! Run: `cargo bench --bench vehicle`. Figures go in the README.

use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::Vector3;
use rotorpilot::airframe::{Airframe, ControlWrench, GRAVITY};
use rotorpilot::control::{ControlGains, ControllerKind, feedforward_attitude};
use rotorpilot::estimation::{EstimatorConfig, MomentumEstimator, Polynomial};
use rotorpilot::model::{ExternalWrench, PlantConfig, RigidBodyState};
use rotorpilot::scenario::Trajectory;
use rotorpilot::vehicle::Vehicle;
use std::hint::black_box;

fn full_step(c: &mut Criterion) {
    let eight = Trajectory::FigureEight {
        half_width_m: 2.0,
        rate_rad_s: 0.5,
        altitude_m: 2.0,
    };
    let wind = ExternalWrench {
        force_ned: Vector3::new(0.5, 0.5, 0.0),
        torque_frd: Vector3::new(0.0, 0.0, 0.05),
    };
    for name in ["quad", "octo", "fsr-quad"] {
        let a = Airframe::load(name).unwrap();
        for kind in ControllerKind::ALL {
            let mut gains = ControlGains::for_airframe(&a);
            gains.apply(&a.control);
            let mut v = Vehicle::new(&a, PlantConfig::default(), kind, gains, EstimatorConfig::default()).unwrap();
            v.set_feedback(true);
            let r0 = eight.at(0.0);
            let start = RigidBodyState {
                position_ned: r0.position_ned,
                velocity_ned: r0.velocity_ned,
                attitude: feedforward_attitude(&r0.acceleration_ned, r0.yaw_rad),
                rate_frd: Vector3::zeros(),
            };
            let hover = ControlWrench::new(a.mass_kg * GRAVITY, Vector3::zeros());
            v.start_in_flight(start, hover);
            let mut k = 0u64;
            c.bench_function(&format!("full step {name} {}", kind.name()), |b| {
                b.iter(|| {
                    k += 1;
                    if k.is_multiple_of(60_000) {
                        v.start_in_flight(start, hover); // one minute of flight, then again
                    }
                    let t = v.plant().time_s();
                    let r = eight.at(t);
                    // by reference: the record is built, not copied again
                    black_box(&v.step(black_box(&r), &wind));
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

criterion_group!(benches, full_step, estimator_update);
criterion_main!(benches);
