//! Flying without a position: the reaction to losing it, as PX4 reacts
//! (`COM_POSCTL_NAVL` 0 with a pilot, the Descend failsafe without).
//!
//! Whether the position may be flown on is the commander's verdict
//! ([`crate::autopilot::position_checks`]: the GNSS fix on the ideal
//! solution, the filter's own accuracy on the filter). Without it, in a mode
//! that needs it ([`PositionNeed`]: Hold, Takeoff, Land, Return, Mission,
//! Orbit, Follow, Offboard with position or velocity setpoints) the vehicle
//! **descends** (PX4's Descend, shown as AUTO.LAND): level, with no
//! horizontal feedback at all, its height and heading held by the same
//! blind reference as Altitude mode, sinking at `MPC_LAND_SPEED` until it
//! lands. In Position mode the pilot keeps flying in **Altitude** mode.
//! When the position returns before touchdown, Descend gives way to what
//! was intended ([`DescendThen`]: a landing keeps landing, with the
//! position; a return returns; a mission flies on from the item it stood
//! at, as PX4 gives the mode back; anything else holds where the vehicle is),
//! and the Altitude fallback to Position; both announced (a failsafe the
//! pilot took over, in force again with the position loss, sets what Descend
//! gives way to: [`Navigator::set_descend_then`]). The supervision
//! runs every step, not only on the change: a mode entered meanwhile that
//! needs a position is corrected at once.
//! Modes and commands that need a position are refused meanwhile.

use nalgebra::Vector2;

use super::manual::ManualMode;
use super::offboard::{LocalSetpoint, Targets};
use super::{DescendThen, Nav, Navigator, RtlPhase, Situation};
use crate::autopilot::FlightMode;
use crate::autopilot::control_loop::Demand;
use crate::autopilot::position_checks::{PositionLoss, PositionNeed, PositionValidity};
use crate::autopilot::status::{Announcements, Severity};

impl Navigator {
    /// Descend without a position (level, heading held), then `then` if the fix returns.
    pub(in crate::autopilot) fn enter_descend(&mut self, then: DescendThen) {
        self.nav = Nav::Descend { then };
        self.restart_references();
    }

    /// In Descend: give way to `then` when the position returns (a failsafe
    /// in force again decides it, not the mode Descend replaced). Nothing otherwise.
    pub(in crate::autopilot) fn set_descend_then(&mut self, then: DescendThen) {
        if let Nav::Descend { then: t } = &mut self.nav {
            *t = then;
        }
    }

    /// What Descend gives way to when the position returns (`None`: not in Descend).
    pub(in crate::autopilot) fn descending_then(&self) -> Option<DescendThen> {
        match self.nav {
            Nav::Descend { then } => Some(then),
            _ => None,
        }
    }

    /// What the active mode meant to do, for Descend to resume when the
    /// fix returns: a landing lands, a return returns, a mission flies on,
    /// the rest holds.
    fn descend_then(&self) -> DescendThen {
        match self.nav {
            Nav::Descend { then } => then,
            Nav::Rtl {
                phase: RtlPhase::Land, ..
            } => DescendThen::Land,
            Nav::Rtl { .. } => DescendThen::Return,
            _ if self.landing() => DescendThen::Land,
            Nav::Mission => DescendThen::Mission,
            _ => DescendThen::Hold,
        }
    }

    /// What the active mode steers by horizontally (PX4's mode requirements).
    pub(in crate::autopilot) fn position_need(&self) -> PositionNeed {
        self.position_need_of(self.mode())
    }

    /// What `mode` steers by horizontally, were it flown now (PX4's mode
    /// requirements; Offboard by its latest setpoint).
    pub(in crate::autopilot) fn position_need_of(&self, mode: FlightMode) -> PositionNeed {
        match mode {
            FlightMode::Hold
            | FlightMode::Takeoff
            | FlightMode::ReturnToLaunch
            | FlightMode::Mission
            | FlightMode::Orbit
            | FlightMode::FollowTarget => PositionNeed::Accurate,
            FlightMode::Land | FlightMode::Position => PositionNeed::Relaxed,
            FlightMode::Altitude
            | FlightMode::Stabilized
            | FlightMode::Acro
            | FlightMode::Manual
            | FlightMode::Descend => PositionNeed::None,
            FlightMode::Offboard => self.offboard_need(),
        }
    }

    /// What Offboard steers by, entered now: the latest setpoint's kind
    /// (PX4's offboard check: a position setpoint needs the position, a
    /// velocity or acceleration one the velocity, an attitude one neither).
    pub(in crate::autopilot) fn offboard_need(&self) -> PositionNeed {
        match self.offboard {
            Some((LocalSetpoint::Attitude(_), _)) => PositionNeed::None,
            Some((LocalSetpoint::Local(Targets { position: Some(_), .. }), _)) => PositionNeed::Accurate,
            _ => PositionNeed::Velocity,
        }
    }

    /// Whether the active mode stands in for one lost with the position
    /// (Descend, or Altitude in place of Position).
    pub(in crate::autopilot) fn flying_blind(&self) -> bool {
        match self.nav {
            Nav::Descend { .. } => true,
            Nav::Manual(ManualMode::Altitude) => self.position_fallback,
            _ => false,
        }
    }

    /// Descend: `MPC_LAND_SPEED` down, no horizontal acceleration, heading held.
    pub(super) fn descend_demand(&mut self, cx: &Situation<'_>) -> Demand {
        if cx.resting {
            return Demand::Idle;
        }
        let (meas, dt) = (cx.meas, cx.dt);
        let (v, az) = self.vertical_step(meas, cx.settings.land_speed_m_s, self.base_limits.max_accel_z_m_s2, dt);
        let yaw = self.yaw_step(meas, 0.0, dt);
        Demand::Track(Self::blind_reference(meas, v, az, Vector2::zeros(), yaw, 0.0))
    }
}

impl Navigator {
    /// Enter Descend, announced (Critical) with `text`; the fix back resumes
    /// what the active mode meant to do.
    fn descend_without_position(&mut self, text: &str, say: &mut Announcements) {
        let then = self.descend_then();
        self.enter_descend(then);
        say.announce(Severity::Critical, text);
    }

    /// The commander's verdict on the position (`validity`) at the instant
    /// of `cx`, every step: while armed, a mode that needs more than is
    /// valid is replaced (the reaction of the module doc); when what Descend
    /// or the Altitude fallback gave way for is valid again, it comes back.
    pub(in crate::autopilot) fn supervise_position(
        &mut self,
        validity: PositionValidity,
        armed: bool,
        cx: &Situation<'_>,
        say: &mut Announcements,
    ) {
        let before = std::mem::replace(&mut self.position, validity);
        if !armed {
            return;
        }
        let lost = validity.loss.lost();
        if self.manual_mode() == Some(ManualMode::Position) && !validity.serves(PositionNeed::Relaxed) {
            self.enter_manual(ManualMode::Altitude);
            self.position_fallback = true;
            say.announce(Severity::Critical, format!("{lost}: Position falls back to Altitude"));
            return;
        }
        if !validity.serves(self.position_need()) {
            self.descend_without_position(&format!("{lost}: descending without position"), say);
            return;
        }
        let regained = |need| validity.serves(need) && !before.serves(need);
        match self.nav {
            Nav::Descend { then } if !cx.landed && regained(then.need()) => {
                self.resume_after_descend(then, before.loss, cx, say);
            }
            Nav::Manual(ManualMode::Altitude) if self.position_fallback && regained(PositionNeed::Relaxed) => {
                self.enter_manual(ManualMode::Position);
                say.announce(
                    Severity::Warning,
                    format!("{}: back to Position", before.loss.regained()),
                );
            }
            _ => {}
        }
    }

    /// The position is back during Descend (it was lost for `loss`): carry
    /// on with what was intended, announced.
    fn resume_after_descend(
        &mut self,
        then: DescendThen,
        loss: PositionLoss,
        cx: &Situation<'_>,
        say: &mut Announcements,
    ) {
        let regained = loss.regained();
        match then {
            DescendThen::Mission => {
                self.enter_mission();
                say.announce(Severity::Warning, format!("{regained}: resuming mission"));
            }
            DescendThen::Hold => {
                self.enter_hold();
                say.announce(Severity::Warning, format!("{regained}: holding position"));
            }
            DescendThen::Land => {
                say.announce(Severity::Warning, format!("{regained}: landing"));
                self.enter_land(cx.meas, false, say);
            }
            DescendThen::Return => {
                say.announce(Severity::Warning, format!("{regained}: returning"));
                self.enter_rtl(cx, say);
            }
        }
    }
}

impl DescendThen {
    /// The more severe of `self` and `other` (PX4's order of failsafe
    /// actions: Hold, Return, Land; the mission, no failsafe action, below
    /// them): what the failsafe framework selects when both are in force.
    pub(in crate::autopilot) fn most_severe(self, other: Self) -> Self {
        let rank = |t: Self| match t {
            Self::Mission => 0,
            Self::Hold => 1,
            Self::Return => 2,
            Self::Land => 3,
        };
        if rank(other) > rank(self) { other } else { self }
    }

    /// What the mode Descend gives way to needs of the position.
    pub(in crate::autopilot) fn need(self) -> PositionNeed {
        match self {
            Self::Land => PositionNeed::Relaxed,
            Self::Mission | Self::Hold | Self::Return => PositionNeed::Accurate,
        }
    }
}
