//! Supervision, once per step: what happens without anyone asking — the
//! offboard setpoints stopped (`COM_OF_LOSS_T`, then `COM_OBL_RC_ACT`), and
//! the auto-disarm after a landing (`COM_DISARM_LAND`) or after arming
//! without taking off (`COM_DISARM_PRFLT`). The failsafes of later issues
//! (data link, battery, geofence) join here.

use super::navigator::Nav;
use super::settings::OffboardLossAction;
use super::{Autopilot, Severity, TIME_EPS};
use crate::signals::Measurement;

impl Autopilot {
    /// Offboard loss and auto-disarm at the instant of `m`.
    pub(super) fn supervise(&mut self, m: &Measurement) {
        let now = m.time_s;
        if self.navigator.nav == Nav::Offboard && !self.navigator.offboard_fresh(now, self.settings.offboard_loss_s) {
            match self.settings.offboard_loss_action {
                OffboardLossAction::Hold => {
                    self.navigator.enter_hold(false);
                    self.say
                        .announce(Severity::Warning, "Offboard signal lost: switching to Hold");
                }
                OffboardLossAction::Return => {
                    self.say.announce(Severity::Warning, "Offboard signal lost: returning");
                    let cx = situation!(self, m);
                    self.navigator.enter_rtl(&cx, &mut self.say);
                }
                OffboardLossAction::Land => {
                    self.say.announce(Severity::Warning, "Offboard signal lost: landing");
                    let landed = self.land.landed();
                    self.navigator.enter_land(m, landed, &mut self.say);
                }
            }
        }
        if self.armed && self.land.landed() {
            let s = &self.settings;
            if self.took_off {
                if s.disarm_land_s > 0.0
                    && !matches!(self.navigator.nav, Nav::Takeoff { .. })
                    && now - self.landed_at_s >= s.disarm_land_s - TIME_EPS
                {
                    self.disarm_now("Disarmed by landing");
                }
            } else if s.disarm_preflight_s > 0.0 && now - self.armed_at_s >= s.disarm_preflight_s - TIME_EPS {
                self.disarm_now("Disarmed by auto preflight disarming");
            }
        }
    }
}
