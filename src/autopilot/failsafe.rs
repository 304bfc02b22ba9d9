//! Supervision, once per step: what happens without anyone asking — the
//! offboard setpoints stopped (`COM_OF_LOSS_T`, then `COM_OBL_RC_ACT`), and
//! the auto-disarm after a landing (`COM_DISARM_LAND`) or after arming
//! without taking off (`COM_DISARM_PRFLT`). The failsafes of later issues
//! (data link, battery, geofence) join here.
//!
//! # Which clock a timer runs on
//! A timer about the flight itself (landing, hold and loiter times, the
//! disarm after a landing) runs on simulated time, always. A timer that
//! waits for a client to act — the preflight auto-disarm (will the script
//! take off?) and the offboard loss (is the setpoint stream still there?)
//! — runs on simulated time headless and at speeds up to real time, and on
//! the wall clock when the runtime runs faster ([`ClientClock::Wall`]): a
//! script that works at 1x keeps working at 20x without editing a
//! parameter. The core never reads a clock: it lists its pending client
//! timers ([`Autopilot::client_timers`]) and the runtime, which times them
//! on the wall clock, reports each expiry as an event at a simulated
//! instant ([`Autopilot::client_timeout`]), so the flight stays
//! deterministic given its inputs.

use serde::Serialize;

use super::navigator::Nav;
use super::settings::OffboardLossAction;
use super::{Autopilot, Severity, TIME_EPS};
use crate::signals::{Measurement, SensorReadings};

/// The clock of the timers that wait for a client.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub enum ClientClock {
    /// Simulated time (headless, and daemons at up to real-time speed).
    #[default]
    Simulated,
    /// The runtime's wall clock: the core only acts on [`Autopilot::client_timeout`].
    Wall,
}

/// A timer that waits for a client to act.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub enum ClientTimer {
    /// Armed and not taken off: disarm after `COM_DISARM_PRFLT`.
    PreflightDisarm,
    /// The offboard setpoint stream: lost after `COM_OF_LOSS_T` without a setpoint.
    OffboardLoss,
    /// The pilot's sticks (MANUAL_CONTROL) in a manual mode: lost after
    /// `COM_RC_LOSS_T` without them, then `NAV_RCL_ACT`.
    ManualControlLoss,
}

/// A client timer running now.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct PendingTimer {
    /// Which.
    pub timer: ClientTimer,
    /// The simulated instant it started [s]: its identity (a new start is a new timer).
    pub started_s: f64,
    /// How long it runs [s] (on the client clock).
    pub duration_s: f64,
}

impl Autopilot {
    /// Time client timers on `clock` from now on.
    pub fn set_client_clock(&mut self, clock: ClientClock) {
        self.client_clock = clock;
    }

    /// The clock of the client timers.
    #[must_use]
    pub fn client_clock(&self) -> ClientClock {
        self.client_clock
    }

    /// The client timers running now (for the runtime to time on the wall clock).
    #[must_use]
    pub fn client_timers(&self) -> Vec<PendingTimer> {
        let mut out = Vec::new();
        let s = &self.settings;
        if self.armed && self.land.landed() && !self.took_off && s.disarm_preflight_s > 0.0 {
            out.push(PendingTimer {
                timer: ClientTimer::PreflightDisarm,
                started_s: self.armed_at_s,
                duration_s: s.disarm_preflight_s,
            });
        }
        if let Some(t) = self.navigator.offboard_arrival() {
            out.push(PendingTimer {
                timer: ClientTimer::OffboardLoss,
                started_s: t,
                duration_s: s.offboard_loss_s,
            });
        }
        if let Some(t) = self.navigator.manual_loss_timer_start() {
            out.push(PendingTimer {
                timer: ClientTimer::ManualControlLoss,
                started_s: t,
                duration_s: s.manual.loss_s,
            });
        }
        out
    }

    /// The runtime's wall clock says the client timer `timer` that started at
    /// `started_s` has run out: act on it at the instant of `readings` if it
    /// is still running (a timer since restarted or stopped is ignored).
    /// True when it was acted on.
    pub fn client_timeout(&mut self, timer: ClientTimer, started_s: f64, readings: &SensorReadings) -> bool {
        let m = &readings.measurement;
        self.now_s = m.time_s;
        let running = self
            .client_timers()
            .iter()
            .any(|p| p.timer == timer && p.started_s.to_bits() == started_s.to_bits());
        if !running {
            return false;
        }
        match timer {
            ClientTimer::PreflightDisarm => self.disarm_now("Disarmed by auto preflight disarming"),
            ClientTimer::OffboardLoss => {
                self.navigator.offboard_timed_out();
                if self.navigator.nav == Nav::Offboard {
                    self.offboard_lost(m);
                }
            }
            ClientTimer::ManualControlLoss => self.manual_control_lost(m),
        }
        true
    }

    /// Whether the offboard setpoints are fresh at `now` (on the client clock).
    pub(super) fn offboard_fresh(&self, now: f64) -> bool {
        self.navigator
            .offboard_fresh(now, self.settings.offboard_loss_s, self.client_clock)
    }

    /// Offboard loss and auto-disarm at the instant of `m`.
    pub(super) fn supervise(&mut self, m: &Measurement) {
        let now = m.time_s;
        let simulated = self.client_clock == ClientClock::Simulated;
        if simulated && self.navigator.nav == Nav::Offboard && !self.offboard_fresh(now) {
            self.offboard_lost(m);
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
            } else if simulated
                && s.disarm_preflight_s > 0.0
                && now - self.armed_at_s >= s.disarm_preflight_s - TIME_EPS
            {
                self.disarm_now("Disarmed by auto preflight disarming");
            }
        }
    }

    /// Offboard setpoints lost while in Offboard: `COM_OBL_RC_ACT`.
    fn offboard_lost(&mut self, m: &Measurement) {
        match self.settings.offboard_loss_action {
            OffboardLossAction::Hold => {
                self.navigator.enter_hold();
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
}
