//! Wind and aerodynamics in the plant and the world (`docs/model.md` section
//! 9): the drag opposes the airspeed, a west wind pushes east, the terms are
//! RotorPy's in FRD, zero coefficients leave the plant untouched, and
//! turbulence is seeded, deterministic and on its own stream.

use nalgebra::{Matrix3, UnitQuaternion, Vector3};
use rotorpilot::airframe::Airframe;
use rotorpilot::signals::{ActuatorCommand, ControlWrench, GRAVITY, RotorVector};
use rotorpilot::sim::{
    Environment, ExternalWrench, Plant, PlantConfig, RigidBodyState, SensorConfig, SensorNoise, WindSettings, World,
};

/// RotorPy's hummingbird coefficients (rotorpy/vehicles/hummingbird_params.py).
const HUMMINGBIRD: &str =
    "\n[aero]\nc_dx = 0.005\nc_dy = 0.005\nc_dz = 0.01\nk_d = 1.19e-4\nk_z = 2.32e-4\nk_h = 3.39e-3\n";
/// The same with a flapping moment (RotorPy ships `k_flap = 0` everywhere;
/// its sign tilts the rotor plane towards the airspeed, see the model doc).
const AERO: &str =
    "\n[aero]\nc_dx = 0.005\nc_dy = 0.005\nc_dz = 0.01\nk_d = 1.19e-4\nk_z = 2.32e-4\nk_h = 3.39e-3\nk_flap = 2.0e-5\n";

/// The shipped quad without any `[aero]` table it may have, and with `extra` appended.
fn quad_with(extra: &str) -> Airframe {
    let text = Airframe::load_text("quad").unwrap().0;
    let plain = match text.find("\n[aero]") {
        Some(at) => {
            let rest = &text[at + 1..];
            let end = rest.find("\n[").map_or(text.len(), |e| at + 1 + e + 1);
            format!("{}{}", &text[..at + 1], &text[end..])
        }
        None => text,
    };
    Airframe::from_toml(&format!("{plain}{extra}"), "quad-with-aero.toml").unwrap()
}

fn config() -> PlantConfig {
    PlantConfig {
        environment: Environment {
            ground_effect: false,
            ceiling_effect: false,
            ..Environment::default()
        },
        ..PlantConfig::default()
    }
}

fn hover(a: &Airframe) -> RotorVector {
    a.allocator()
        .allocate(&ControlWrench::new(a.mass_kg * GRAVITY, Vector3::zeros()))
        .speed_cmd_rad_s
}

/// A plant at 50 m, level, moving at `velocity_ned`, rotors at hover speed.
fn flying(a: &Airframe, velocity_ned: Vector3<f64>) -> (Plant, ActuatorCommand) {
    let mut p = Plant::new(a, config());
    let mut s = RigidBodyState::at_rest(Vector3::new(0.0, 0.0, -50.0));
    s.velocity_ned = velocity_ned;
    p.set_state(s);
    let w = hover(a);
    p.set_rotor_speeds(&w);
    (p, ActuatorCommand::RotorSpeeds(w))
}

const NONE: ExternalWrench = ExternalWrench {
    force_ned: Vector3::new(0.0, 0.0, 0.0),
    torque_frd: Vector3::new(0.0, 0.0, 0.0),
};

/// GIVEN a level quad flying north at 5 m/s in still air THEN the air pushes
/// it south with `|v| c_dx v + k_d sum omega_i v`, lifts it by `k_h 4 v^2`,
/// pitches it by the flapping moment `-k_flap sum omega_i v` about y, and it
/// slows down, where the same quad without coefficients keeps its speed.
#[test]
fn a_body_moving_north_in_still_air_feels_a_force_south() {
    let a = quad_with(AERO);
    let (mut p, cmd) = flying(&a, Vector3::new(5.0, 0.0, 0.0));
    let om = *p.rotor_speeds();
    p.step(&cmd, &NONE).unwrap();
    let f = p.last_aero_wrench();
    let sum_om: f64 = om.iter().take(4).sum();
    let south = -(5.0 * 0.005 * 5.0 + 1.19e-4 * sum_om * 5.0);
    assert!((f.force_ned.x - south).abs() < 1e-12, "{} vs {south}", f.force_ned.x);
    assert!(f.force_ned.y.abs() < 1e-12);
    assert!(
        (f.force_ned.z + 4.0 * 3.39e-3 * 25.0).abs() < 1e-12,
        "lift up: {}",
        f.force_ned.z
    );
    let t = f.torque_frd;
    assert!((t.y + 2.0e-5 * sum_om * 5.0).abs() < 1e-12, "flapping: {t}");
    assert!(t.x.abs() < 1e-12 && t.z.abs() < 1e-12, "{t}");
    assert!(p.state().velocity_ned.x < 5.0 - 1e-4, "{}", p.state().velocity_ned.x);

    let bare = quad_with("");
    let (mut q, cmd) = flying(&bare, Vector3::new(5.0, 0.0, 0.0));
    q.step(&cmd, &NONE).unwrap();
    assert_eq!(q.last_aero_wrench(), ExternalWrench::default());
    assert_eq!(q.state().velocity_ned.x, 5.0);
}

/// GIVEN a quad hovering still in a 5 m/s wind from the west THEN the air
/// pushes it east, and after 1 s it drifts east; calm air or zero
/// coefficients leave it in place.
#[test]
fn a_wind_from_the_west_pushes_east() {
    let a = quad_with(HUMMINGBIRD);
    let west = WindSettings {
        speed_m_s: 5.0,
        from_deg: 270.0,
        ..WindSettings::default()
    };
    let (mut p, cmd) = flying(&a, Vector3::zeros());
    p.set_wind_ned(west.mean_ned());
    p.step(&cmd, &NONE).unwrap();
    let f = p.last_aero_wrench().force_ned;
    assert!(f.y > 0.1 && f.x.abs() < 1e-12, "{f}");
    for _ in 0..999 {
        p.step(&cmd, &NONE).unwrap();
    }
    assert!(p.state().position_ned.y > 0.05, "{}", p.state().position_ned);
    assert!(p.state().velocity_ned.y > 0.1, "{}", p.state().velocity_ned);

    // zero coefficients: the wind changes nothing, bit for bit
    let bare = quad_with("");
    let run = |wind: Option<Vector3<f64>>| {
        let (mut p, cmd) = flying(&bare, Vector3::new(1.0, -2.0, 0.5));
        if let Some(w) = wind {
            p.set_wind_ned(w);
        }
        for _ in 0..500 {
            p.step(&cmd, &NONE).unwrap();
        }
        *p.state()
    };
    assert_eq!(run(None), run(Some(west.mean_ned())));
}

/// RotorPy's `compute_body_wrench` aero terms transcribed literally in its
/// z-up body frame (FLU), for rotor hubs `r` (FLU), body airspeed `v` (FLU),
/// body rates `w` (FLU) and rotor speeds.
fn rotorpy_aero_flu(
    r: &[Vector3<f64>],
    v: Vector3<f64>,
    w: Vector3<f64>,
    speeds: &[f64],
    c: [f64; 7],
) -> (Vector3<f64>, Vector3<f64>) {
    let [c_dx, c_dy, c_dz, k_d, k_z, k_h, k_flap] = c;
    let drag = Matrix3::from_diagonal(&Vector3::new(c_dx, c_dy, c_dz));
    let rotor_drag = Matrix3::from_diagonal(&Vector3::new(k_d, k_d, k_z));
    let d = -v.norm() * drag * v;
    let mut f = d;
    let mut m = Vector3::zeros();
    for (ri, &om) in r.iter().zip(speeds) {
        let vi = v + w.cross(ri);
        let h = -om * rotor_drag * vi;
        let m_flap = -k_flap * om * vi.cross(&Vector3::z());
        let t = Vector3::new(0.0, 0.0, k_h * (vi.x * vi.x + vi.y * vi.y));
        f += t + h;
        m += ri.cross(&(t + h)) + m_flap;
    }
    (f, m)
}

/// At a tilted, turning, climbing state in a gusty 3-D wind the plant's aero
/// wrench equals RotorPy's computed in its z-up frame and turned into FRD by
/// the rotation `P = diag(1, -1, -1)` (FLU <-> FRD): every sign matches.
#[test]
fn aero_terms_are_rotorpys_in_frd() {
    let a = quad_with(AERO);
    let mut p = Plant::new(&a, config());
    let s = RigidBodyState {
        position_ned: Vector3::new(3.0, -4.0, -20.0),
        velocity_ned: Vector3::new(4.0, -2.5, -1.2),
        attitude: UnitQuaternion::from_euler_angles(0.2, -0.15, 1.1),
        rate_frd: Vector3::new(0.8, -0.5, 0.3),
    };
    p.set_state(s);
    let wind = Vector3::new(-1.0, 3.5, 0.7);
    p.set_wind_ned(wind);
    let speeds = RotorVector::from_fn(|i, _| [610.0, 720.0, 805.0, 690.0, 0.0, 0.0, 0.0, 0.0][i.min(7)]);
    let (f, m) = p.aero_wrench_frd(&s, &speeds);

    let flu = Matrix3::from_diagonal(&Vector3::new(1.0, -1.0, -1.0));
    let v_frd = s.attitude.inverse() * (s.velocity_ned - wind);
    let hubs: Vec<_> = a.rotors.iter().map(|r| flu * r.position_frd()).collect();
    let sp: Vec<f64> = speeds.iter().take(4).copied().collect();
    let (f_flu, m_flu) = rotorpy_aero_flu(
        &hubs,
        flu * v_frd,
        flu * s.rate_frd,
        &sp,
        [0.005, 0.005, 0.01, 1.19e-4, 2.32e-4, 3.39e-3, 2.0e-5],
    );
    assert!((f - flu * f_flu).norm() < 1e-12, "{f} vs {}", flu * f_flu);
    assert!((m - flu * m_flu).norm() < 1e-12, "{m} vs {}", flu * m_flu);
    assert!(f.norm() > 0.1 && m.norm() > 1e-3);
}

fn windy_world(seed: u64, wind: WindSettings, noise: SensorNoise) -> World {
    let a = quad_with(HUMMINGBIRD);
    let mut w = World::new(0.001, Environment::default());
    w.add_vehicle(&a, SensorConfig { noise, seed });
    w.start_in_flight(
        0,
        RigidBodyState::at_rest(Vector3::new(0.0, 0.0, -10.0)),
        &ControlWrench::new(a.mass_kg * GRAVITY, Vector3::zeros()),
    );
    w.set_wind(0, wind);
    w
}

fn fly(w: &mut World, steps: usize) -> Vec<(RigidBodyState, Vector3<f64>, Vector3<f64>)> {
    let hover = hover(&quad_with(HUMMINGBIRD));
    let cmd = ActuatorCommand::RotorSpeeds(hover);
    (0..steps)
        .map(|_| {
            let noise = w.sense(0).measurement.position_ned - w.plant(0).state().position_ned;
            let r = w.step(|_| &cmd)[0];
            (r.truth, r.wind_ned, noise)
        })
        .collect()
}

/// A world with turbulence: the same seed gives the same flight bit for bit,
/// another seed another; the wind and the aero wrench reach the step report
/// and the truth; the sensors' noise stream is the same with or without
/// turbulence (the wind draws from its own).
#[test]
fn turbulence_is_deterministic_and_on_its_own_stream() {
    let gusty = WindSettings {
        speed_m_s: 5.0,
        from_deg: 270.0,
        turbulence_m_s: 1.5,
        ..WindSettings::default()
    };
    let noise = SensorNoise {
        position_m: 0.1,
        ..SensorNoise::default()
    };
    let mut w1 = windy_world(11, gusty, noise);
    let a = fly(&mut w1, 2000);
    let b = fly(&mut windy_world(11, gusty, noise), 2000);
    assert_eq!(a, b);
    let c = fly(&mut windy_world(12, gusty, noise), 2000);
    assert_ne!(
        a.iter().map(|x| x.1).collect::<Vec<_>>(),
        c.iter().map(|x| x.1).collect::<Vec<_>>()
    );
    // the wind varies about its mean
    let dev = a.iter().map(|x| (x.1 - gusty.mean_ned()).norm()).fold(0.0, f64::max);
    assert!(dev > 0.05, "{dev}");
    let truth = w1.truth(0);
    assert_eq!(truth.wind_ned, w1.last_report(0).wind_ned);
    assert_eq!(truth.aero_force_ned, w1.last_report(0).aero.force_ned);
    assert!(truth.aero_force_ned.y > 0.0, "{}", truth.aero_force_ned);
    assert_eq!(truth.external_force_ned(), truth.force_ned + truth.aero_force_ned);
    // the sensors' noise does not depend on the turbulence
    let calm = fly(&mut windy_world(11, WindSettings::default(), noise), 2000);
    for (x, y) in a.iter().zip(&calm) {
        assert!((x.2 - y.2).norm() < 1e-9, "{} vs {}", x.2, y.2);
    }
}

/// The largest gap [m/s^2] over `steps` steps between the acceleration the
/// accelerometer is fed (`Plant::acceleration_ned`, NED) and the finite
/// difference of the true velocity over the same step, `(v_{k+1} - v_k) / h`,
/// for `a` flying at `velocity_ned` with an injected `external` force (NED)
/// at hover rotor speeds.
fn accelerometer_gap(a: &Airframe, velocity_ned: Vector3<f64>, external: &ExternalWrench, steps: usize) -> f64 {
    let (mut p, cmd) = flying(a, velocity_ned);
    let h = p.dt_s();
    let mut gap: f64 = 0.0;
    for _ in 0..steps {
        let v0 = p.state().velocity_ned;
        p.step(&cmd, external).unwrap();
        let fd = (p.state().velocity_ned - v0) / h;
        gap = gap.max((p.acceleration_ned() - fd).norm());
    }
    gap
}

/// GIVEN the shipped quad (its `[aero]` table) flying at 3 m/s north, 1 m/s
/// east and 2 m/s up in still air, with and without an injected force
/// WHEN it is stepped 200 times at hover rotor speeds
/// THEN the acceleration the accelerometer is fed matches the finite
/// difference of the true velocity as closely as without drag (the
/// aerodynamic force counted once: the plant's external wrench of the step
/// is the injected one, the aerodynamic one is added beside it), while the
/// drag itself is far larger than that gap.
#[test]
fn the_accelerometer_feels_the_drag_the_body_integrates_once() {
    let shipped = Airframe::load("quad").unwrap();
    assert!(!shipped.aero.is_zero());
    let bare = quad_with("");
    let v = Vector3::new(3.0, 1.0, -2.0);
    let pushed = ExternalWrench {
        force_ned: Vector3::new(0.5, -0.3, 0.2),
        torque_frd: Vector3::zeros(),
    };
    let (mut p, cmd) = flying(&shipped, v);
    p.step(&cmd, &pushed).unwrap();
    let drag = p.last_aero_wrench().force_ned.norm() / shipped.mass_kg;
    assert_eq!(p.last_external_wrench(), pushed, "the injected wrench alone");
    for external in [NONE, pushed] {
        let with = accelerometer_gap(&shipped, v, &external, 200);
        let without = accelerometer_gap(&bare, v, &external, 200);
        println!(
            "accelerometer vs finite difference: {with:.3e} m/s^2 with drag ({drag:.3} m/s^2), {without:.3e} without"
        );
        assert!(with < 1e-2 && without < 1e-2, "{with} {without}");
        assert!(drag > 10.0 * with, "{drag} {with}");
    }
}
