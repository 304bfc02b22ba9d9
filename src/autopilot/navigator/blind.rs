//! Flying without a position: the reaction to losing the GNSS fix, as PX4
//! reacts (`COM_POSCTL_NAVL` 0 with a pilot, the Descend failsafe without).
//!
//! The flight stack sees only the receiver's status
//! ([`crate::signals::GpsReading`]); without a fix the horizontal position
//! and velocity of the navigation solution are not to be trusted (the
//! world lets them drift). In a mode that needs them — Hold, Takeoff, Land,
//! Return, Mission, Offboard with position or velocity setpoints — the
//! vehicle **descends** (PX4's Descend, shown as AUTO.LAND): level, with no
//! horizontal feedback at all, its height and heading held by the same
//! blind reference as Altitude mode, sinking at `MPC_LAND_SPEED` until it
//! lands. In Position mode the pilot keeps flying in **Altitude** mode.
//! When the fix returns before touchdown, Descend gives way to what was
//! intended ([`DescendThen`]: a landing keeps landing, with the position; a
//! return returns; anything else holds where the vehicle is), and the
//! Altitude fallback to Position; both announced. The supervision runs every
//! step, not only on the change: a mode entered meanwhile that needs a
//! position is corrected at once.
//! Modes and commands that need a position are refused meanwhile.

use nalgebra::Vector2;

use super::manual::ManualMode;
use super::offboard::LocalSetpoint;
use super::{DescendThen, Nav, Navigator, RtlPhase, Situation};
use crate::autopilot::control_loop::Demand;
use crate::autopilot::status::{Announcements, Severity};

impl Navigator {
    /// Descend without a position (level, heading held), then `then` if the fix returns.
    pub(in crate::autopilot) fn enter_descend(&mut self, then: DescendThen) {
        self.nav = Nav::Descend { then };
        self.restart_references();
    }

    /// What the active mode meant to do, for Descend to resume when the
    /// fix returns: a landing lands, a return returns, the rest holds.
    fn descend_then(&self) -> DescendThen {
        match self.nav {
            Nav::Descend { then } => then,
            Nav::Rtl {
                phase: RtlPhase::Land, ..
            } => DescendThen::Land,
            Nav::Rtl { .. } => DescendThen::Return,
            _ if self.landing() => DescendThen::Land,
            _ => DescendThen::Hold,
        }
    }

    /// Whether the active mode steers by the horizontal position or velocity.
    pub(in crate::autopilot) fn needs_position(&self) -> bool {
        match self.nav {
            Nav::Hold { .. }
            | Nav::Takeoff { .. }
            | Nav::Land { .. }
            | Nav::Rtl { .. }
            | Nav::Mission
            | Nav::Orbit(_)
            | Nav::Follow(_) => true,
            Nav::Manual(mode) => mode == ManualMode::Position,
            Nav::Offboard => !matches!(self.offboard, Some((LocalSetpoint::Attitude(_), _))),
            Nav::Descend { .. } => false,
        }
    }

    /// Whether Offboard, entered now, would steer by the position or
    /// velocity (the latest setpoint is not an attitude one).
    pub(in crate::autopilot) fn offboard_needs_position(&self) -> bool {
        !matches!(self.offboard, Some((LocalSetpoint::Attitude(_), _)))
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

    /// The GNSS fix (`lost`: none) at the instant of `cx`, every step: while
    /// it is lost, armed, a mode that needs a position is replaced (the
    /// reaction of the module doc); on its return, Descend and the Altitude
    /// fallback give way.
    pub(in crate::autopilot) fn supervise_gps(
        &mut self,
        lost: bool,
        armed: bool,
        cx: &Situation<'_>,
        say: &mut Announcements,
    ) {
        let changed = lost != self.gps_lost;
        self.gps_lost = lost;
        if !armed {
            return;
        }
        if lost {
            if self.manual_mode() == Some(ManualMode::Position) {
                self.enter_manual(ManualMode::Altitude);
                self.gps_fallback = true;
                say.announce(Severity::Critical, "No GPS fix: Position falls back to Altitude");
            } else if self.needs_position() {
                self.descend_without_position("No GPS fix: descending without position", say);
            }
            return;
        }
        if !changed {
            return;
        }
        match self.nav {
            Nav::Descend { then } if !cx.landed => self.resume_after_descend(then, cx, say),
            Nav::Manual(ManualMode::Altitude) if self.gps_fallback => {
                self.enter_manual(ManualMode::Position);
                say.announce(Severity::Warning, "GPS fix regained: back to Position");
            }
            _ => {}
        }
    }

    /// The fix is back during Descend: carry on with what was intended, announced.
    fn resume_after_descend(&mut self, then: DescendThen, cx: &Situation<'_>, say: &mut Announcements) {
        match then {
            DescendThen::Hold => {
                self.enter_hold();
                say.announce(Severity::Warning, "GPS fix regained: holding position");
            }
            DescendThen::Land => {
                say.announce(Severity::Warning, "GPS fix regained: landing");
                self.enter_land(cx.meas, false, say);
            }
            DescendThen::Return => {
                say.announce(Severity::Warning, "GPS fix regained: returning");
                self.enter_rtl(cx, say);
            }
        }
    }
}
