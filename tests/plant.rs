//! The plant: free fall, hover, yaw direction, integrator invariants, ground
//! contact, ground and ceiling effect (`docs/model.md` sections 2, 8, 9),
//! and determinism.

use nalgebra::{Matrix3, UnitQuaternion, Vector3};
use rotorpilot::airframe::Airframe;
use rotorpilot::signals::{ActuatorCommand, Measurement};
use rotorpilot::signals::{ControlWrench, GRAVITY, RotorVector};
use rotorpilot::sim::aero::{AeroEffects, ceiling_ratio, cheeseman_bennett, multirotor_ground_effect};

/// The shipped airframe without its `[aero]` table: these oracles are the
/// rigid body's and the control laws' in still air, without drag.
fn drag_free(name: &str) -> Airframe {
    let mut af = Airframe::load(name).unwrap();
    af.aero = rotorpilot::airframe::AeroCoefficients::default();
    af
}
use rotorpilot::sim::{
    Contact, Environment, ExternalWrench, Plant, PlantConfig, RigidBodyState, SensorNoise, Sensors, SimFault, StepEvent,
};

fn no_surfaces() -> PlantConfig {
    PlantConfig {
        environment: Environment {
            ground_effect: false,
            ceiling_effect: false,
            ..Environment::default()
        },
        ..PlantConfig::default()
    }
}

fn airborne(name: &str, altitude_m: f64, config: PlantConfig) -> (Airframe, Plant) {
    let a = drag_free(name);
    let mut p = Plant::new(&a, config);
    p.set_state(RigidBodyState::at_rest(Vector3::new(0.0, 0.0, -altitude_m)));
    (a, p)
}

fn hover_speeds(a: &Airframe) -> RotorVector {
    a.allocator()
        .allocate(&ControlWrench::new(a.mass_kg * GRAVITY, Vector3::zeros()))
        .speed_cmd_rad_s
}

const NONE: ExternalWrench = ExternalWrench {
    force_ned: Vector3::new(0.0, 0.0, 0.0),
    torque_frd: Vector3::new(0.0, 0.0, 0.0),
};

/// GIVEN a stopped vehicle at 100 m WHEN it falls for 2 s THEN z = z0 + g t^2 / 2.
#[test]
fn free_fall_matches_g_t_squared_over_two() {
    let (_, mut p) = airborne("quad", 100.0, no_surfaces());
    for _ in 0..2000 {
        p.step(&ActuatorCommand::Stop, &NONE).unwrap();
    }
    let t = p.time_s();
    assert!((t - 2.0).abs() < 1e-12);
    let z = p.state().position_ned.z;
    assert!((z - (-100.0 + 0.5 * GRAVITY * t * t)).abs() < 1e-9, "z = {z}");
    assert!((p.state().velocity_ned.z - GRAVITY * t).abs() < 1e-9);
}

/// GIVEN rotors spinning at the computed hover speed WHEN held for 10 s THEN the vehicle does not move.
#[test]
fn hover_at_computed_speeds_holds_still() {
    for name in ["quad", "hexa", "octo"] {
        let (a, mut p) = airborne(name, 20.0, no_surfaces());
        let w = hover_speeds(&a);
        p.set_rotor_speeds(&w);
        for _ in 0..10_000 {
            p.step(&ActuatorCommand::RotorSpeeds(w), &NONE).unwrap();
        }
        let s = p.state();
        assert!(
            (s.position_ned - Vector3::new(0.0, 0.0, -20.0)).norm() < 1e-9,
            "{name}: {:?}",
            s.position_ned
        );
        assert!(s.rate_frd.norm() < 1e-12 && s.velocity_ned.norm() < 1e-10, "{name}");
    }
    // ideal actuation: the commanded wrench acts directly
    let (a, mut p) = airborne("fsr-quad", 20.0, no_surfaces());
    let hover = ActuatorCommand::Wrench(ControlWrench::new(a.mass_kg * GRAVITY, Vector3::zeros()));
    for _ in 0..5000 {
        p.step(&hover, &NONE).unwrap();
    }
    assert!((p.state().position_ned.z + 20.0).abs() < 1e-12);
}

/// A positive FRD yaw torque (about +z down) turns the nose clockwise seen from above (yaw grows);
/// at rotor level that is what speeding up the counter-clockwise rotors does.
#[test]
fn pure_yaw_torque_spins_the_body_the_right_way() {
    let (a, mut p) = airborne("fsr-quad", 20.0, no_surfaces());
    let cmd = ActuatorCommand::Wrench(ControlWrench::new(a.mass_kg * GRAVITY, Vector3::new(0.0, 0.0, 0.5)));
    for _ in 0..1000 {
        p.step(&cmd, &NONE).unwrap();
    }
    let yaw = rotorpilot::math::euler_zyx(&p.state().attitude).z;
    // psi = tau t^2 / (2 Izz) = 0.5 / (2 * 2.4832) at t = 1 s
    assert!((yaw - 0.5 / (2.0 * 2.4832)).abs() < 1e-9, "yaw {yaw}");
    assert!(p.state().rate_frd.z > 0.0);

    let (a, mut p) = airborne("quad", 20.0, no_surfaces());
    let mut w = hover_speeds(&a);
    for (i, r) in a.rotors.iter().enumerate() {
        w[i] += if r.spin.sign() > 0.0 { 20.0 } else { -20.0 };
    }
    p.set_rotor_speeds(&w);
    for _ in 0..500 {
        p.step(&ActuatorCommand::RotorSpeeds(w), &NONE).unwrap();
    }
    assert!(
        p.state().rate_frd.z > 0.1,
        "CCW rotors faster must yaw positive: {}",
        p.state().rate_frd.z
    );
    assert!(p.state().rate_frd.xy().norm() < 1e-9);
}

/// Torque-free asymmetric body spinning about an unstable-free mix of axes:
/// the quaternion stays unit, energy is not created and angular momentum (world) is kept.
#[test]
fn integrator_keeps_unit_quaternion_and_does_not_create_energy() {
    // torque-free: the quad without its rotational drag (body.rotational_drag_n_m_s)
    let mut a = drag_free("quad");
    a.rotational_drag_n_m_s = 0.0;
    let mut p = Plant::new(&a, no_surfaces());
    p.set_state(RigidBodyState::at_rest(Vector3::new(0.0, 0.0, -5000.0))); // falls ~2 km in 20 s, never lands
    let inertia = Matrix3::from_diagonal(&Vector3::new(0.02, 0.03, 0.05));
    p.set_true_inertia(inertia);
    let w0 = Vector3::new(3.0, -1.0, 5.0);
    p.set_state(RigidBodyState {
        rate_frd: w0,
        ..*p.state()
    });
    let energy = |w: &Vector3<f64>| 0.5 * w.dot(&(inertia * w));
    let momentum = |p: &Plant| p.state().attitude * (inertia * p.state().rate_frd);
    let (e0, h0) = (energy(&w0), momentum(&p));
    let mut e_max: f64 = e0;
    for _ in 0..20_000 {
        p.step(&ActuatorCommand::Stop, &NONE).unwrap();
        assert!((p.state().attitude.norm() - 1.0).abs() < 1e-14);
        e_max = e_max.max(energy(&p.state().rate_frd));
    }
    assert!(e_max <= e0 * (1.0 + 1e-10), "energy created: {e0} -> {e_max}");
    assert!((energy(&p.state().rate_frd) - e0).abs() / e0 < 1e-10);
    assert!((momentum(&p) - h0).norm() / h0.norm() < 1e-9);
}

/// A vehicle resting on the ground stays exactly put, idle rotors or not.
#[test]
fn resting_vehicle_stays_put() {
    let a = drag_free("quad");
    let mut p = Plant::new(&a, PlantConfig::default());
    let start = *p.state();
    assert_eq!(p.contact(), Contact::OnGround);
    assert!((start.position_ned.z + a.gear_height_m).abs() < 1e-15);
    // idle rotors and a sideways push smaller than friction can hold
    let idle = ActuatorCommand::RotorSpeeds(RotorVector::from_element(100.0));
    let push = ExternalWrench {
        force_ned: Vector3::new(1.0, 0.5, 0.0),
        torque_frd: Vector3::zeros(),
    };
    for k in 0..5000 {
        let ev = p
            .step(if k % 2 == 0 { &idle } else { &ActuatorCommand::Stop }, &push)
            .unwrap();
        assert_eq!(ev, StepEvent::None);
    }
    assert_eq!(*p.state(), start, "no sinking, bouncing or drift");
}

/// Dropped from 1 m: touchdown is reported once with the impact speed, then the vehicle rests.
#[test]
fn touchdown_and_liftoff_are_detected() {
    let a = drag_free("quad");
    let mut p = Plant::new(&a, no_surfaces());
    let rest_z = -a.gear_height_m;
    p.set_state(RigidBodyState::at_rest(Vector3::new(0.0, 0.0, rest_z - 1.0)));
    assert_eq!(p.contact(), Contact::Airborne);
    let mut touchdowns = vec![];
    for _ in 0..2000 {
        if let StepEvent::Touchdown { speed_m_s } = p.step(&ActuatorCommand::Stop, &NONE).unwrap() {
            touchdowns.push(speed_m_s);
        }
    }
    assert_eq!(touchdowns.len(), 1);
    assert!(
        (touchdowns[0] - (2.0 * GRAVITY * 1.0f64).sqrt()).abs() < 0.02,
        "{touchdowns:?}"
    );
    assert_eq!(p.contact(), Contact::OnGround);
    assert_eq!(p.state().position_ned.z, rest_z);
    // full throttle lifts off
    let full = ActuatorCommand::RotorSpeeds(RotorVector::from_element(1000.0));
    let mut lifted = false;
    for _ in 0..500 {
        lifted |= p.step(&full, &NONE).unwrap() == StepEvent::Liftoff;
    }
    assert!(lifted && p.contact() == Contact::Airborne && p.state().position_ned.z < rest_z - 0.1);
}

/// Doc section 9 ground-effect oracles (rho = 0.1, quad l = 0.25, d = 0.35355, b = 0.25).
#[test]
fn ground_effect_ratios_match_doc_section_9() {
    let d = 0.25 * 2f64.sqrt();
    let cases = [
        (0.2, 1.01587, 1.03368, 1.12209),
        (0.1, 1.06667, 1.08769, 1.25394),
        (0.05, 1.33333, 1.35495, 1.57336),
    ];
    for (z, cb, kb0, kb2) in cases {
        assert!((cheeseman_bennett(0.1, z) - cb).abs() < 1e-5, "CB at {z}");
        assert!(
            (multirotor_ground_effect(0.1, z, d, 0.25, 0.0) - kb0).abs() < 1e-5,
            "K_b=0 at {z}"
        );
        assert!(
            (multirotor_ground_effect(0.1, z, d, 0.25, 2.0) - kb2).abs() < 1e-5,
            "K_b=2 at {z}"
        );
    }
    assert!(
        (cheeseman_bennett(0.1, 0.2) - 1.0159).abs() < 1e-4 && (cheeseman_bennett(0.1, 0.05) - 4.0 / 3.0).abs() < 1e-12
    );

    // per-rotor formula at equal heights equals the closed form
    let a = ge_quad(2.0);
    let ge = AeroEffects::new(&a);
    let r = ge.ground_ratios(&[0.2; 12]);
    for i in 0..4 {
        assert!((r[i] - 1.12209).abs() < 1e-5, "{}", r[i]);
    }
}

/// A quad-X with the doc's ground-effect geometry and body coefficient `k_b`.
fn ge_quad(k_b: f64) -> Airframe {
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/params/airframes/fsr-quad.toml"))
        .unwrap()
        .replace("body_coefficient = 0.0", &format!("body_coefficient = {k_b}"))
        .replace("actuation = \"ideal\"", "actuation = \"rotors\"")
        .replace(
            "inertia_diag_kg_m2 = [1.2416, 1.2416, 2.4832]",
            "inertia_diag_kg_m2 = [0.03, 0.03, 0.05]",
        );
    Airframe::from_toml(&text, "ge-quad").unwrap()
}

/// Roll +10 deg at centre height 0.2 m (K_b = 2): right rotors lower, more thrust, negative (restoring) roll moment.
#[test]
fn tilted_vehicle_near_ground_feels_a_restoring_moment() {
    let a = ge_quad(2.0);
    let mut p = Plant::new(&a, PlantConfig::default());
    let roll = 10f64.to_radians();
    p.set_state(RigidBodyState {
        position_ned: Vector3::new(0.0, 0.0, -0.2),
        attitude: UnitQuaternion::from_euler_angles(roll, 0.0, 0.0),
        ..RigidBodyState::at_rest(Vector3::zeros())
    });
    // T_OGE = 1.25 g / 4 per rotor
    let w = RotorVector::from_fn(|i, _| {
        if i < 4 {
            (1.25 * GRAVITY / 4.0 / a.rotor.c_t).sqrt()
        } else {
            0.0
        }
    });
    p.set_rotor_speeds(&w);
    p.step(&ActuatorCommand::RotorSpeeds(w), &NONE).unwrap();
    let tau_x = p.last_wrench().torque_frd.x;
    assert!((tau_x + 0.0527).abs() < 2e-4, "extra roll moment {tau_x}");
    // per-rotor heights and ratios of the doc
    let ge = AeroEffects::new(&a);
    let heights: Vec<f64> = a
        .rotors
        .iter()
        .map(|r| 0.2 - (UnitQuaternion::from_euler_angles(roll, 0.0, 0.0) * r.position_frd()).z)
        .collect();
    let mut h = [0.0; 12];
    h[..4].copy_from_slice(&heights);
    let ratios = ge.ground_ratios(&h);
    for i in 0..4 {
        let expect = if heights[i] < 0.2 {
            (0.1693, 1.14972)
        } else {
            (0.2307, 1.10114)
        };
        assert!(
            (heights[i] - expect.0).abs() < 1e-4 && (ratios[i] - expect.1).abs() < 1e-4,
            "{heights:?} {ratios}"
        );
    }
}

/// With constant rotor speeds, the closer the ceiling the larger the upward pull.
#[test]
fn ceiling_effect_pulls_the_vehicle_up_as_the_gap_closes() {
    let a = drag_free("quad");
    let w = hover_speeds(&a);
    let mut previous_up = 0.0;
    for gap in [1.0, 0.5, 0.3, 0.15, 0.05] {
        let config = PlantConfig {
            environment: Environment {
                ceiling_z_ned: Some(-10.0),
                ..Environment::default()
            },
            ..PlantConfig::default()
        };
        let mut p = Plant::new(&a, config);
        p.set_state(RigidBodyState::at_rest(Vector3::new(0.0, 0.0, -10.0 + gap)));
        p.set_rotor_speeds(&w);
        p.step(&ActuatorCommand::RotorSpeeds(w), &NONE).unwrap();
        let up = -p.state().velocity_ned.z; // starts at rest: upward velocity after one step
        assert!(up > previous_up, "gap {gap}: upward {up} not above {previous_up}");
        previous_up = up;
    }
    let k2 = a.ceiling_effect.k2_m;
    let rho = a.rotor.radius_m;
    assert!((ceiling_ratio(rho, 2.5, k2, 0.0) - 1.0 / (1.0 - (1.0f64 / 1.1).powi(2) / 2.5)).abs() < 1e-9);
    assert!(ceiling_ratio(rho, 2.5, k2, 2.0 * rho) < ceiling_ratio(rho, 2.5, k2, rho));
}

fn noisy_run(seed: u64) -> (Vec<RigidBodyState>, Vec<Measurement>) {
    let a = drag_free("octo");
    let noise = SensorNoise {
        position_m: 0.01,
        velocity_m_s: 0.02,
        attitude_rad: 0.002,
        rate_rad_s: 0.01,
    };
    let mut sensors = Sensors::new(noise, seed);
    let mut p = Plant::new(&a, PlantConfig::default());
    let gust = |t: f64| ExternalWrench {
        force_ned: Vector3::new(0.5 * (3.0 * t).sin(), 0.5, -0.2 * t),
        torque_frd: Vector3::new(0.0, 0.01 * t.cos(), 0.2),
    };
    let mut states = vec![];
    let mut meas = vec![];
    for k in 0..3000 {
        let w = RotorVector::from_fn(|i, _| {
            if i < 8 {
                470.0 + 30.0 * ((k + i) as f64 * 0.01).sin()
            } else {
                0.0
            }
        });
        p.step(&ActuatorCommand::RotorSpeeds(w), &gust).unwrap();
        states.push(*p.state());
        meas.push(sensors.measure(&p.truth()));
    }
    (states, meas)
}

/// Same inputs and seed: bit-identical trajectory and measurements.
#[test]
fn runs_are_bit_identical_for_the_same_seed() {
    let (s1, m1) = noisy_run(7);
    let (s2, m2) = noisy_run(7);
    assert_eq!(s1, s2);
    assert_eq!(m1, m2);
    let (s3, m3) = noisy_run(8);
    assert_eq!(s1, s3, "noise is on the measurement, not the plant");
    assert_ne!(m1, m3);
    assert!(s1.last().unwrap().position_ned.z < -0.5, "the run actually flew");
}

/// Non-finite commands are refused and leave the state alone.
#[test]
fn non_finite_commands_are_refused() {
    let (_, mut p) = airborne("quad", 10.0, PlantConfig::default());
    let before = *p.state();
    let nan = ActuatorCommand::Wrench(ControlWrench::new(f64::NAN, Vector3::zeros()));
    assert_eq!(p.step(&nan, &NONE), Err(SimFault::NonFiniteCommand));
    let inf = ActuatorCommand::RotorSpeeds(RotorVector::from_element(f64::INFINITY));
    assert_eq!(p.step(&inf, &NONE), Err(SimFault::NonFiniteCommand));
    assert_eq!(*p.state(), before);
    assert_eq!(p.time_s(), 0.0);
}

/// True mass differs from nominal: the same hover command now climbs.
#[test]
fn true_mass_differs_from_nominal() {
    let (a, mut p) = airborne("fsr-quad", 10.0, no_surfaces());
    p.set_true_mass(1.25);
    let hover_nominal = ActuatorCommand::Wrench(ControlWrench::new(a.mass_kg * GRAVITY, Vector3::zeros()));
    for _ in 0..1000 {
        p.step(&hover_nominal, &NONE).unwrap();
    }
    // a = g (1 - 1.5/1.25) = -0.2 g upward over 1 s
    assert!((p.state().velocity_ned.z - (GRAVITY * (1.0 - 1.5 / 1.25))).abs() < 1e-9);
}
