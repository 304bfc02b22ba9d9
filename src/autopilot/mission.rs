//! The mission as the commander sees it: starting it, setting the current
//! item, what a new upload does to a mission in progress, and the progress
//! clients are told (MISSION_CURRENT). The flying is the navigator's
//! (`navigator/mission`).

use super::telemetry::{MissionState, MissionStatus};
use super::{Autopilot, CommandOutcome, Severity};
use crate::mission::MissionType;
use crate::signals::Measurement;

impl Autopilot {
    /// MISSION_CURRENT's content now.
    pub(super) fn mission_status(&self) -> MissionStatus {
        let mission = self.plans.get(MissionType::Mission);
        MissionStatus {
            seq: 0,
            total: u16::try_from(mission.len()).unwrap_or(u16::MAX),
            state: if mission.is_empty() {
                MissionState::NoMission
            } else {
                MissionState::NotStarted
            },
            mission_id: mission.id(),
            fence_id: self.plans.get(MissionType::Fence).id(),
            rally_id: self.plans.get(MissionType::Rally).id(),
        }
    }

    /// A new mission was stored, or the mission cleared.
    pub(super) fn mission_replaced(&mut self) {}

    /// MISSION_START: AUTO.MISSION from `first` (or where it stands).
    pub(super) fn start_mission(&mut self, _first: Option<u16>, _m: &Measurement) -> CommandOutcome {
        self.refuse(
            Severity::Critical,
            "Mission start denied: no mission",
            CommandOutcome::TemporarilyRejected("no mission"),
        )
    }

    /// MISSION_SET_CURRENT / DO_SET_MISSION_CURRENT.
    pub(super) fn set_mission_current(&mut self, _seq: u16) -> CommandOutcome {
        CommandOutcome::Denied("no mission")
    }
}
