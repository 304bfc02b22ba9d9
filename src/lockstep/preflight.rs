//! The simulator's preflight check before arming (unforced): whether the
//! rotors can lift the vehicle's true mass. PX4 SITL's own sanity check, on
//! the world's truth (the flight stack never sees it).

use super::Lockstep;
use crate::airframe::{Actuation, Airframe};
use crate::autopilot::{Autopilot, AutopilotCommand, CommandOutcome, Severity, StatusText};
use crate::sim::RotorHealth;

/// The simulator's preflight check before arming (unforced): whether the
/// rotors can lift the vehicle's true mass, and if not the STATUSTEXT that
/// says so, as PX4 prints a failed preflight check:
///
/// ```text
/// lift [kg] = sum_i f_i c_T omega_max^2 / g    (f_i: 1 healthy, its thrust fraction degraded, 0 dead)
/// refused when m_true >= lift                  ("Preflight Fail: SIM_MASS 10.0 kg > lift 3.5 kg")
/// ```
///
/// `rotors` is the world's health of each rotor (from 0; missing: healthy).
/// An airframe with ideal actuation has no rotor limit: never refused.
#[must_use]
pub fn unliftable(airframe: &Airframe, true_mass_kg: f64, rotors: &[RotorHealth]) -> Option<String> {
    if airframe.actuation == Actuation::Ideal {
        return None;
    }
    let per_rotor_n = airframe.max_thrust_n() / airframe.rotor_count() as f64;
    let lift_n: f64 = (0..airframe.rotor_count())
        .map(|k| match rotors.get(k).copied().unwrap_or(RotorHealth::Healthy) {
            RotorHealth::Healthy => per_rotor_n,
            RotorHealth::Degraded { thrust_fraction } => per_rotor_n * thrust_fraction,
            RotorHealth::Off => 0.0,
        })
        .sum();
    let lift_kg = lift_n / crate::signals::GRAVITY;
    (true_mass_kg >= lift_kg).then(|| format!("Preflight Fail: SIM_MASS {true_mass_kg:.1} kg > lift {lift_kg:.1} kg"))
}

impl Lockstep<Autopilot> {
    /// The refusal of `command` for vehicle `i` when it is an unforced arm of
    /// a disarmed vehicle that cannot lift its true mass ([`unliftable`]); the
    /// STATUSTEXT that says so is announced. `None`: the autopilot judges it.
    pub(super) fn preflight(&mut self, i: usize, command: AutopilotCommand) -> Option<CommandOutcome> {
        if let AutopilotCommand::Arm { force: false } = command
            && !self.pilots[i].armed()
            && let Some(text) = unliftable(
                self.pilots[i].airframe(),
                self.world.plant(i).true_mass_kg(),
                &self.world.faults(i).rotors,
            )
        {
            // PX4 SITL's own sanity check, on the world's truth (the flight stack never sees it)
            let t = self.time_s();
            self.world_texts[i].push((
                t,
                StatusText {
                    severity: Severity::Critical,
                    text,
                },
            ));
            return Some(CommandOutcome::Denied(
                "vehicle cannot hover: true mass beyond the rotors' lift",
            ));
        }
        None
    }
}
