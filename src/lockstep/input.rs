//! The one way an input reaches the lockstep core: [`Input`] (plain data,
//! as the [`Lockstep`] method that takes it) and [`apply`]. The daemon's
//! simulation thread applies every client input through it (and records
//! it), and a replay applies every recorded line through it, so the two
//! cannot differ.

use serde::{Deserialize, Serialize};

use super::Lockstep;
use crate::autopilot::{Autopilot, AutopilotCommand, AutopilotError, ClientTimer, CommandOutcome};
use crate::mission::{MissionResult, PlanChange};
use crate::params::{ParamStore, ParamValue};

/// One input to the core (plain data), as the `Lockstep` method that takes it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Input {
    /// [`Lockstep::command`]: a command, an offboard setpoint, manual control, a failure injection.
    Command(AutopilotCommand),
    /// [`Lockstep::set_param`] (refused ones too).
    SetParam {
        /// Parameter name.
        name: String,
        /// The value asked for.
        value: ParamValue,
    },
    /// [`Lockstep::change_plans`]: a mission, geofence or rally upload or clear.
    ChangePlans(PlanChange),
    /// [`Lockstep::gcs_heartbeat`].
    GcsHeartbeat,
    /// [`Lockstep::client_timeout`]: a client timer ran out on the wall clock.
    ClientTimeout {
        /// Which timer.
        timer: ClientTimer,
        /// When it started [s, simulated].
        started_s: f64,
    },
    /// [`Lockstep::reboot`] from the parameters in force.
    Reboot,
    /// Another vehicle of the fleet came near (or touched): the text
    /// [`super::proximity_text`] announced ([`Lockstep::announce`]).
    /// The live fleet's core raised it itself (it sees every vehicle); the
    /// record keeps it so that a replay of this one vehicle tells it alike.
    Proximity {
        /// The other vehicle's label (`system 3`).
        other: String,
        /// Near or touching.
        kind: crate::sim::ProximityKind,
        /// Their distance [m].
        distance_m: f64,
    },
    /// An encounter with another vehicle of the fleet is over (the pair
    /// apart again, or the flight ended): the text
    /// [`super::encounter_text`] announced ([`Lockstep::announce`]). As
    /// [`Input::Proximity`], the live fleet followed it itself and the
    /// record keeps it for a replay of this one vehicle.
    EncounterEnded {
        /// The other vehicle's label (`system 3`).
        other: String,
        /// The encounter's closest approach [m], centre to centre.
        closest_m: f64,
        /// When it came [s, simulated].
        closest_s: f64,
    },
}

/// What the core answered to an [`Input`].
#[derive(Debug)]
pub enum Applied {
    /// To a command.
    Command(CommandOutcome),
    /// To a parameter set: the stored value or why it was refused.
    SetParam(Result<ParamValue, String>),
    /// To a plan change: the new plan's id or why nothing changed.
    Plans(Result<u32, MissionResult>),
    /// To a heartbeat (nothing to answer).
    GcsHeartbeat,
    /// To a client timeout: whether the timer still ran.
    ClientTimeout(bool),
    /// To a reboot.
    Reboot(Result<(), AutopilotError>),
    /// To a proximity event or an encounter's end (announced).
    Announced,
}

impl Applied {
    /// The outcome as the record keeps it (replay compares it).
    #[must_use]
    pub fn text(&self) -> String {
        match self {
            Applied::Command(o) => format!("{o:?}"),
            Applied::SetParam(r) => format!("{r:?}"),
            Applied::Plans(r) => format!("{r:?}"),
            Applied::GcsHeartbeat => "done".into(),
            Applied::ClientTimeout(b) => b.to_string(),
            Applied::Reboot(r) => match r {
                Ok(()) => "Ok".into(),
                Err(e) => format!("Err({e})"),
            },
            Applied::Announced => "announced".into(),
        }
    }
}

/// Apply `input` to vehicle `i` of `core` at the current instant;
/// `params` is the vehicle's parameter store (set_param changes it, reboot
/// reads it).
pub fn apply(core: &mut Lockstep<Autopilot>, i: usize, params: &mut ParamStore, input: &Input) -> Applied {
    match input {
        Input::Command(c) => Applied::Command(core.command(i, *c)),
        Input::SetParam { name, value } => Applied::SetParam(core.set_param(i, params, name, *value)),
        Input::ChangePlans(change) => Applied::Plans(core.change_plans(i, change.clone())),
        Input::GcsHeartbeat => {
            core.gcs_heartbeat(i);
            Applied::GcsHeartbeat
        }
        Input::ClientTimeout { timer, started_s } => Applied::ClientTimeout(core.client_timeout(i, *timer, *started_s)),
        Input::Reboot => Applied::Reboot(core.reboot(i, params)),
        Input::Proximity {
            other,
            kind,
            distance_m,
        } => {
            core.announce(i, super::proximity_text(*kind, other, *distance_m));
            Applied::Announced
        }
        Input::EncounterEnded { other, closest_m, .. } => {
            core.announce(i, super::encounter_text(other, *closest_m));
            Applied::Announced
        }
    }
}
