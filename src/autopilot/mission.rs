//! The mission as the commander sees it: starting it (MISSION_START and the
//! switch to AUTO.MISSION), setting the current item, what a new upload
//! does to a mission in progress, and the progress clients are told
//! (MISSION_CURRENT). The flying is the navigator's (`navigator/mission`).
//!
//! PX4's answers: MISSION_START without a mission, or with a first item
//! beyond it, is DENIED; it switches to AUTO.MISSION and arms (prearm checks
//! apply: TEMPORARILY_REJECTED when they fail). AUTO.MISSION without a
//! mission is TEMPORARILY_REJECTED. Setting the current item beyond the
//! mission is DENIED. A new mission, or a cleared one, starts over from its
//! first item; one cleared while it is flown gives way to Hold.

use nalgebra::Vector3;

use super::command::CommandOutcome;
use super::navigator::{self, Nav, SetHome};
use super::status::Severity;
use super::telemetry::{MissionState, MissionStatus};
use super::{Autopilot, FlightMode};
use crate::mission::MissionType;
use crate::signals::Measurement;

impl Autopilot {
    /// MISSION_CURRENT's content now.
    pub(super) fn mission_status(&self) -> MissionStatus {
        let mission = self.plans.get(MissionType::Mission);
        let run = self.navigator.mission();
        let state = if mission.is_empty() {
            MissionState::NoMission
        } else if run.complete() {
            MissionState::Complete
        } else if self.commander.armed() && self.navigator.nav() == Nav::Mission {
            MissionState::Active
        } else if run.started() {
            MissionState::Paused
        } else {
            MissionState::NotStarted
        };
        MissionStatus {
            seq: u16::try_from(run.current().min(mission.len().saturating_sub(1))).unwrap_or(u16::MAX),
            total: u16::try_from(mission.len()).unwrap_or(u16::MAX),
            state,
            mission_id: mission.id(),
            fence_id: self.plans.get(MissionType::Fence).id(),
            rally_id: self.plans.get(MissionType::Rally).id(),
        }
    }

    /// A new mission was stored, or the mission cleared: from the first item;
    /// a cleared mission being flown gives way to Hold.
    pub(super) fn mission_replaced(&mut self) {
        self.navigator.mission_mut().reset();
        if self.navigator.nav() == Nav::Mission {
            if self.plans.get(MissionType::Mission).is_empty() {
                self.navigator.enter_hold();
                self.say.announce(Severity::Warning, "Mission cleared: holding");
            } else {
                self.navigator.enter_mission();
            }
        }
    }

    /// AUTO.MISSION: TemporarilyRejected without a mission.
    pub(super) fn enter_mission(&mut self) -> CommandOutcome {
        if self.plans.get(MissionType::Mission).is_empty() {
            return self.refuse(
                Severity::Critical,
                "Switching to Mission denied: no mission",
                CommandOutcome::TemporarilyRejected("no mission"),
            );
        }
        self.navigator.enter_mission();
        CommandOutcome::Accepted
    }

    /// Refuse the mission when one of its points lies outside the geofence
    /// (zones, `GF_MAX_HOR_DIST`, `GF_MAX_VER_DIST`), as a Reposition there
    /// is refused (PX4's mission feasibility check).
    fn refuse_mission_outside_geofence(&mut self, m: &Measurement) -> Option<CommandOutcome> {
        let here = m.position_ned;
        let points: Vec<(usize, Vector3<f64>)> = self
            .plans
            .get(MissionType::Mission)
            .items()
            .iter()
            .enumerate()
            .filter(|(_, it)| it.has_position())
            .map(|(i, it)| (i, navigator::item_point_ned(it, &self.origin, &self.home, &here)))
            .collect();
        let outside = points.into_iter().find(|(_, p)| self.outside_geofence(p))?;
        let text = format!("Mission start denied: item {} outside geofence", outside.0);
        Some(self.refuse(
            Severity::Critical,
            &text,
            CommandOutcome::Denied("mission outside the geofence"),
        ))
    }

    /// MISSION_START: AUTO.MISSION from `first` (or where it stands), and arm.
    pub(super) fn start_mission(&mut self, first: Option<u16>, m: &Measurement) -> CommandOutcome {
        let total = self.plans.get(MissionType::Mission).len();
        if total == 0 {
            return self.refuse(
                Severity::Critical,
                "Mission start denied! No valid mission",
                CommandOutcome::Denied("no mission"),
            );
        }
        if first.is_some_and(|f| usize::from(f) >= total) {
            return CommandOutcome::Denied("first item beyond the mission");
        }
        if let Some(refused) = self.refuse_without_position("Mission start") {
            return refused;
        }
        if let Some(refused) = self.refuse_mission_outside_geofence(m) {
            return refused;
        }
        let was = self.navigator.saved();
        if let Some(f) = first {
            self.navigator.mission_mut().set_current(usize::from(f));
        }
        if self.navigator.mode() != FlightMode::Mission {
            self.navigator.enter_mission();
        } else if first.is_some() {
            self.navigator.mission_mut().resume();
        }
        if !self.commander.armed() {
            let outcome = self.arm(false, m);
            if outcome != CommandOutcome::Accepted {
                self.navigator.restore(was);
                return outcome;
            }
        }
        CommandOutcome::Accepted
    }

    /// MISSION_SET_CURRENT / DO_SET_MISSION_CURRENT: Denied beyond the mission.
    pub(super) fn set_mission_current(&mut self, seq: u16) -> CommandOutcome {
        if usize::from(seq) >= self.plans.get(MissionType::Mission).len() {
            return CommandOutcome::Denied("no such mission item");
        }
        self.navigator.mission_mut().set_current(usize::from(seq));
        CommandOutcome::Accepted
    }

    /// DO_SET_HOME from the mission.
    pub(super) fn mission_set_home(&mut self, h: SetHome, m: &Measurement) {
        let point = match h {
            SetHome::Here => None,
            SetHome::At(p) => Some(p),
        };
        if self.set_home_to(point, m) == CommandOutcome::Accepted {
            self.say.announce(Severity::Info, "Home position set by the mission");
        }
    }
}
