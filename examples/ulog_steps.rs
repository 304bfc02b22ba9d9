//! The cost of the ULog per step: a quad takes off (5 s) and hovers for N
//! steps of the lockstep core, with or without `FlightUlog::on_step` after
//! each step (writing into `io::sink()`: the formatting and decimation, not
//! the disk). For instruction counts that do not move with the machine's load:
//!
//! ```sh
//! cargo build --release --example ulog_steps
//! for log in off on; do for n in 2000 12000; do
//!   valgrind --tool=callgrind --callgrind-out-file=/dev/null target/release/examples/ulog_steps $log $n 2>&1 | grep refs
//! done; done
//! ```
//! The difference of the two totals over 10,000 is the count per step.

use rotorpilot::airframe::Airframe;
use rotorpilot::autopilot::AutopilotCommand;
use rotorpilot::geo::GeoPoint;
use rotorpilot::lockstep::Lockstep;
use rotorpilot::logs::ulog::flight::FlightUlog;
use rotorpilot::params::ParamStore;
use rotorpilot::sim::SensorConfig;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let [_, log, steps] = &args[..] else {
        anyhow::bail!("usage: ulog_steps on|off STEPS");
    };
    let steps: u64 = steps.parse()?;
    let airframe = Airframe::load("quad")?;
    let params = ParamStore::new(&airframe);
    let mut core = Lockstep::one_vehicle(&airframe, GeoPoint::PX4_SITL_HOME, &params, SensorConfig::default())?;
    let mut ulog = match log.as_str() {
        "on" => Some(FlightUlog::new(std::io::sink(), &params, &core, 0)?),
        "off" => None,
        _ => anyhow::bail!("on or off, not {log}"),
    };
    for _ in 0..1000 {
        core.step();
    }
    core.command(0, AutopilotCommand::Arm { force: false });
    core.command(0, AutopilotCommand::Takeoff { altitude_amsl_m: None });
    for _ in 0..(5000 + steps) {
        core.step();
        if let Some(u) = &mut ulog {
            u.on_step(&mut core, 0)?;
        }
    }
    let z = core.last_step(0).measurement.position_ned.z;
    println!("altitude {:.2} m after {steps} hover steps", -z);
    Ok(())
}
