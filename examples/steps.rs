//! N full lockstep steps of the figure-eight at 2 m (estimate fed back, a
//! constant wind), exactly what `cargo bench --bench vehicle` times per
//! iteration, as one process: for instruction counts that do not move with
//! the machine's load.
//!
//! ```sh
//! cargo build --release --example steps
//! valgrind --tool=callgrind target/release/examples/steps quad geometric 12000
//! valgrind --tool=callgrind target/release/examples/steps quad geometric 2000
//! ```
//! The difference of the two totals over 10,000 is the count per step.
//!
//! Optional: `steps AIRFRAME LAW STEPS WIND_M_S [TURB_M_S]` flies in a mean
//! wind from the west (and Dryden turbulence of that `sigma_w`); give an
//! airframe file with an `[aero]` table for the cost of a step with wind and drag.

use nalgebra::Vector3;
use rotorpilot::control::ControllerKind;
use rotorpilot::scenario::{Scenario, lockstep};
use rotorpilot::sim::{DisturbanceSource, ExternalWrench, WindSettings};
use std::hint::black_box;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let (airframe, law, steps, air) = match &args[..] {
        [_, a, l, s] => (a, l, s, None),
        [_, a, l, s, w] => (a, l, s, Some((w.parse::<f64>()?, 0.0))),
        [_, a, l, s, w, t] => (a, l, s, Some((w.parse::<f64>()?, t.parse::<f64>()?))),
        _ => anyhow::bail!("usage: steps AIRFRAME LAW STEPS [WIND_M_S [TURB_M_S]] (e.g. steps quad geometric 12000)"),
    };
    let law: ControllerKind = law.parse()?;
    let steps: u64 = steps.parse()?;
    let text = format!(
        "airframe = \"{airframe}\"\ncontroller = \"{}\"\nduration_s = 86400.0\n\
         [reference]\nkind = \"figure_eight\"\nhalf_width_m = 2.0\nrate_rad_s = 0.5\naltitude_m = 2.0\n\
         [estimator]\nfeedback = true\n",
        law.name()
    );
    let scenario = Scenario::from_toml(&text, "steps", None)?;
    let mut core = lockstep(&scenario)?;
    let wind = ExternalWrench {
        force_ned: Vector3::new(0.5, 0.5, 0.0),
        torque_frd: Vector3::new(0.0, 0.0, 0.05),
    };
    core.world_mut().set_disturbance(0, DisturbanceSource::Constant(wind));
    if let Some((speed_m_s, turbulence_m_s)) = air {
        let air = WindSettings {
            speed_m_s,
            from_deg: 270.0,
            turbulence_m_s,
            ..WindSettings::default()
        };
        core.world_mut().set_wind(0, air);
    }
    for _ in 0..steps {
        core.step();
        black_box(core.last_step(0));
    }
    Ok(())
}
