//! The plant alone, open loop: one airframe, an initial state and a schedule
//! of held rotor-speed commands, read from a JSON case file; the state after
//! each segment of the schedule printed as JSON on stdout. No flight stack,
//! no sensors, no ground (the case must start above it), ground and ceiling
//! effect off; the airframe file's `[aero]` coefficients and a constant wind. For cross-checks against other simulators
//! (`tests/rotorpy/test_rotorpy_crosscheck.py` drives it beside RotorPy).
//!
//! ```sh
//! cargo build --release --example plant_open_loop
//! target/release/examples/plant_open_loop case.json > states.json
//! ```
//!
//! The case (every vector NED world or FRD body, SI units):
//!
//! ```text
//! {"airframe": "quad",                    // built-in name or file path
//!  "dt_s": 0.001,                          // the plant's RK4 step
//!  "position_ned": [0, 0, -50], "velocity_ned": [0, 0, 0],
//!  "attitude_wxyz": [1, 0, 0, 0],          // FRD -> NED, Hamilton
//!  "rate_frd": [0, 0, 0],
//!  "rotor_speeds_rad_s": [500, 500, 500, 500],
//!  "wind_ned_m_s": [0, 5, 0],              // optional, constant (here from the west)
//!  "segments": [{"steps": 10, "rotor_speeds_rad_s": [510, 490, 510, 490]}, ...]}
//! ```
//!
//! Each segment holds its command for `steps` plant steps. The output has one
//! sample at the start and one after each segment:
//! `{"samples": [{"t_s", "position_ned", "velocity_ned", "attitude_wxyz",
//! "rate_frd", "rotor_speeds_rad_s"}, ...]}`.

use anyhow::{Context, bail};
use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use rotorpilot::airframe::Airframe;
use rotorpilot::signals::{ActuatorCommand, RotorVector};
use rotorpilot::sim::{Contact, Environment, ExternalWrench, Plant, PlantConfig, RigidBodyState};
use serde::{Deserialize, Serialize};

/// One held command.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Segment {
    /// Plant steps the command is held for.
    steps: u64,
    /// Commanded rotor speeds [rad/s], in the airframe's rotor order.
    rotor_speeds_rad_s: Vec<f64>,
}

/// The case file.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Case {
    airframe: String,
    dt_s: f64,
    position_ned: [f64; 3],
    velocity_ned: [f64; 3],
    attitude_wxyz: [f64; 4],
    rate_frd: [f64; 3],
    rotor_speeds_rad_s: Vec<f64>,
    /// Constant wind [m/s], NED (the air's velocity; absent: still air).
    #[serde(default)]
    wind_ned_m_s: [f64; 3],
    segments: Vec<Segment>,
}

/// The state at one instant.
#[derive(Serialize)]
struct Sample {
    t_s: f64,
    position_ned: [f64; 3],
    velocity_ned: [f64; 3],
    attitude_wxyz: [f64; 4],
    rate_frd: [f64; 3],
    rotor_speeds_rad_s: Vec<f64>,
}

fn sample(plant: &Plant) -> Sample {
    let s = plant.state();
    let q = s.attitude.quaternion();
    Sample {
        t_s: plant.time_s(),
        position_ned: s.position_ned.into(),
        velocity_ned: s.velocity_ned.into(),
        attitude_wxyz: [q.w, q.i, q.j, q.k],
        rate_frd: s.rate_frd.into(),
        rotor_speeds_rad_s: plant.rotor_speeds().as_slice()[..plant.rotor_count()].to_vec(),
    }
}

/// The rotor vector of `speeds`, which must have one finite entry per rotor.
fn rotor_vector(speeds: &[f64], n: usize, what: &str) -> anyhow::Result<RotorVector> {
    if speeds.len() != n || !speeds.iter().all(|x| x.is_finite()) {
        bail!("{what}: {} speeds for {n} rotors, or not all finite", speeds.len());
    }
    let mut v = RotorVector::zeros();
    v.as_mut_slice()[..n].copy_from_slice(speeds);
    Ok(v)
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let [_, path] = &args[..] else {
        bail!("usage: plant_open_loop CASE.json (the case format: the doc comment of examples/plant_open_loop.rs)");
    };
    let text = std::fs::read_to_string(path).with_context(|| format!("reading {path}"))?;
    let case: Case = serde_json::from_str(&text).with_context(|| format!("{path}: not a valid case"))?;
    let airframe = Airframe::load(&case.airframe)?;
    if !(case.dt_s.is_finite() && case.dt_s > 0.0) {
        bail!("{path}: dt_s must be > 0 (got {})", case.dt_s);
    }
    let config = PlantConfig {
        dt_s: case.dt_s,
        environment: Environment {
            ground_effect: false,
            ceiling_effect: false,
            ..Environment::default()
        },
    };
    let mut plant = Plant::new(&airframe, config);
    let [w, x, y, z] = case.attitude_wxyz;
    plant.set_state(RigidBodyState {
        position_ned: case.position_ned.into(),
        velocity_ned: case.velocity_ned.into(),
        attitude: UnitQuaternion::from_quaternion(Quaternion::new(w, x, y, z)),
        rate_frd: Vector3::from(case.rate_frd),
    });
    if plant.contact() != Contact::Airborne {
        bail!("{path}: the case must start in the air (position_ned z above the resting height)");
    }
    let n = plant.rotor_count();
    plant.set_rotor_speeds(&rotor_vector(&case.rotor_speeds_rad_s, n, "rotor_speeds_rad_s")?);
    if !case.wind_ned_m_s.iter().all(|x| x.is_finite()) {
        bail!("{path}: wind_ned_m_s must be finite");
    }
    plant.set_wind_ned(case.wind_ned_m_s.into());
    let no_wrench = ExternalWrench::default();
    let mut samples = vec![sample(&plant)];
    for (k, seg) in case.segments.iter().enumerate() {
        let cmd = ActuatorCommand::RotorSpeeds(rotor_vector(&seg.rotor_speeds_rad_s, n, &format!("segment {k}"))?);
        for _ in 0..seg.steps {
            plant
                .step(&cmd, &no_wrench)
                .with_context(|| format!("segment {k} at t = {} s", plant.time_s()))?;
        }
        if plant.contact() != Contact::Airborne {
            bail!("segment {k}: the vehicle reached the ground; start higher");
        }
        samples.push(sample(&plant));
    }
    println!("{}", serde_json::json!({ "samples": samples }));
    Ok(())
}
