//! Speed of one plant step (RK4, 1 ms) at rotor level.
//!
//! Run: `cargo bench --bench plant`. Figures go in docs/performance.md.

use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::Vector3;
use rotorpilot::airframe::Airframe;
use rotorpilot::signals::ActuatorCommand;
use rotorpilot::signals::{ControlWrench, GRAVITY};
use rotorpilot::sim::{ExternalWrench, Plant, PlantConfig, RigidBodyState};
use std::hint::black_box;

fn plant_step(c: &mut Criterion) {
    let wind = ExternalWrench {
        force_ned: Vector3::new(0.5, 0.5, 0.0),
        torque_frd: Vector3::new(0.0, 0.0, 0.2),
    };
    for (name, altitude, label) in [
        ("quad", 20.0, "quad rotor-level, free air"),
        ("octo", 20.0, "octo rotor-level, free air"),
        ("quad", 0.5, "quad rotor-level, in ground effect"),
        ("octo", 0.5, "octo rotor-level, in ground effect"),
        ("fsr-quad", 20.0, "fsr-quad ideal actuation"),
    ] {
        let a = Airframe::load(name).unwrap();
        let mut p = Plant::new(&a, PlantConfig::default());
        p.set_state(RigidBodyState::at_rest(Vector3::new(0.0, 0.0, -altitude)));
        let hover = a
            .allocator()
            .allocate(&ControlWrench::new(a.mass_kg * GRAVITY, Vector3::zeros()));
        p.set_rotor_speeds(&hover.speed_cmd_rad_s);
        let cmd = match a.actuation {
            rotorpilot::airframe::Actuation::Rotors => ActuatorCommand::RotorSpeeds(hover.speed_cmd_rad_s),
            rotorpilot::airframe::Actuation::Ideal => ActuatorCommand::Wrench(hover.achieved),
        };
        let start = *p.state();
        let mut k = 0u32;
        c.bench_function(label, |b| {
            b.iter(|| {
                // keep the vehicle where the case says (drift under the disturbance is slow)
                k += 1;
                if k.is_multiple_of(4096) {
                    p.set_state(start);
                }
                black_box(p.step(black_box(&cmd), &wind)).ok();
            });
        });
    }
}

criterion_group!(benches, plant_step);
criterion_main!(benches);
