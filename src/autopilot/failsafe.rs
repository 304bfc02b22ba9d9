//! Supervision, once per step: what happens without anyone asking — the
//! offboard setpoints stopped (`COM_OF_LOSS_T`, then `COM_OBL_RC_ACT`), the
//! pilot's sticks stopped (`COM_RC_LOSS_T`, then `NAV_RCL_ACT`), the
//! auto-disarm after a landing (`COM_DISARM_LAND`) or after arming without
//! taking off (`COM_DISARM_PRFLT`), and PX4's failsafes below. Every
//! failsafe acts through one runner ([`Autopilot::failsafe_action`]: one
//! [`FailsafeAction`] per parameter value, one announcement, a landing under
//! way never interrupted, a blind descent without a GPS fix).
//!
//! # PX4's failsafes
//! * Data-link loss: no GCS HEARTBEAT (MAV_TYPE_GCS, any link) for
//!   `COM_DL_LOSS_T`, armed or not, once a GCS was heard: announced, then
//!   `NAV_DLL_ACT` (disabled by default, ignored while landing); the next GCS
//!   HEARTBEAT is announced as the link regained. A client timer
//!   ([`ClientTimer::DataLinkLoss`]).
//! * Low battery: the monitor's remaining charge against `BAT_LOW_THR`,
//!   `BAT_CRIT_THR`, `BAT_EMERGEN_THR`; the level escalates only while armed,
//!   each new level announced, `COM_LOW_BAT_ACT` at critical and emergency.
//! * Geofence ([`super::geofence`]): the stored fence plan and
//!   `GF_MAX_HOR_DIST`/`GF_MAX_VER_DIST`, checked on the current position
//!   while armed in the air; `GF_ACTION` once per breach.
//!
//! # Which clock a timer runs on
//! A timer about the flight itself (landing, hold and loiter times, the
//! disarm after a landing) runs on simulated time, always. A timer that
//! waits for a client to act — the preflight auto-disarm (will the script
//! take off?), the offboard loss (is the setpoint stream still there?), the
//! data-link loss and the manual-control loss — runs on simulated time headless and at speeds up to real time, and on
//! the wall clock when the runtime runs faster ([`ClientClock::Wall`]): a
//! script that works at 1x keeps working at 20x without editing a
//! parameter. The core never reads a clock: it lists its pending client
//! timers ([`Autopilot::client_timers`]) and the runtime, which times them
//! on the wall clock, reports each expiry as an event at a simulated
//! instant ([`Autopilot::client_timeout`]), so the flight stays
//! deterministic given its inputs.

use serde::Serialize;

use nalgebra::Vector3;

use super::battery::BatteryWarning;
use super::geofence::{self, Fence};
use super::navigator::{DescendThen, Nav};
use super::settings::FailsafeAction;
use super::status::Severity;
use super::{Autopilot, TIME_EPS};
use crate::mission::MissionType;
use crate::signals::{Measurement, SensorReadings};

/// The clock of the timers that wait for a client.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, serde::Deserialize)]
pub enum ClientClock {
    /// Simulated time (headless, and daemons at up to real-time speed).
    #[default]
    Simulated,
    /// The runtime's wall clock: the core only acts on [`Autopilot::client_timeout`].
    Wall,
}

/// A timer that waits for a client to act.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, serde::Deserialize)]
pub enum ClientTimer {
    /// Armed and not taken off: disarm after `COM_DISARM_PRFLT`.
    PreflightDisarm,
    /// The offboard setpoint stream: lost after `COM_OF_LOSS_T` without a setpoint.
    OffboardLoss,
    /// The ground station: lost after `COM_DL_LOSS_T` without a GCS HEARTBEAT (once one was heard, armed or not).
    DataLinkLoss,
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
        // data-link loss (COM_DL_LOSS_T)
        if let Some(p) = self.data_link_timer() {
            out.push(p);
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
        self.client_timer_expired(timer, m);
        true
    }

    /// The one dispatcher of an expired client timer, on either clock.
    fn client_timer_expired(&mut self, timer: ClientTimer, m: &Measurement) {
        match timer {
            ClientTimer::PreflightDisarm => self.disarm_now("Disarmed by auto preflight disarming"),
            ClientTimer::OffboardLoss => {
                self.navigator.offboard_timed_out();
                if self.navigator.nav == Nav::Offboard {
                    self.offboard_lost(m);
                }
            }
            ClientTimer::DataLinkLoss => self.data_link_lost(m),
            ClientTimer::ManualControlLoss => self.manual_control_lost(m),
        }
    }

    /// Whether the offboard setpoints are fresh at `now` (on the client clock).
    pub(super) fn offboard_fresh(&self, now: f64) -> bool {
        self.navigator
            .offboard_fresh(now, self.settings.offboard_loss_s, self.client_clock)
    }

    /// The client timers on simulated time (one boundary rule for all:
    /// expired when `now - started >= duration - TIME_EPS`, dispatched as the
    /// runtime's wall-clock expiries are), the disarm after a landing and
    /// the geofence, at the instant of `m`.
    pub(super) fn supervise(&mut self, m: &Measurement) {
        let now = m.time_s;
        if self.client_clock == ClientClock::Simulated {
            for p in self.client_timers() {
                // an earlier expiry this step may have stopped or restarted it
                let running = self
                    .client_timers()
                    .iter()
                    .any(|q| q.timer == p.timer && q.started_s.to_bits() == p.started_s.to_bits());
                if running && now - p.started_s >= p.duration_s - TIME_EPS {
                    self.client_timer_expired(p.timer, m);
                }
            }
        }
        if self.armed
            && self.land.landed()
            && self.took_off
            && self.settings.disarm_land_s > 0.0
            && !matches!(self.navigator.nav, Nav::Takeoff { .. })
            && now - self.landed_at_s >= self.settings.disarm_land_s - TIME_EPS
        {
            self.disarm_now("Disarmed by landing");
        }
        self.supervise_geofence(m);
    }

    /// Offboard setpoints lost while in Offboard: announced, then `COM_OBL_RC_ACT`.
    fn offboard_lost(&mut self, m: &Measurement) {
        self.say.announce(Severity::Warning, "Offboard signal lost");
        if !self.armed {
            // no failsafe on the ground: Offboard without setpoints is no
            // mode to stay in, so fall back to Hold as before arming
            self.navigator.enter_hold();
            return;
        }
        let action = self.settings.offboard_loss_action;
        self.failsafe_action("offboard signal lost", action, m);
    }
}

// ----- PX4's failsafes: data-link loss, low battery, geofence ----------------------------------

/// Offboard setpoints within the altitude limit this long [s] end an
/// excursion: the next clamp is announced again.
const CLAMP_REARM_S: f64 = 5.0;

/// What the failsafes remember between steps.
#[derive(Clone, Debug, Default)]
pub(super) struct FailsafeState {
    /// When the latest GCS HEARTBEAT arrived [s] (`None`: never).
    gcs_heard_s: Option<f64>,
    /// The data link was declared lost (until the next GCS HEARTBEAT).
    gcs_lost: bool,
    /// The battery warning level in force (escalates only while armed).
    battery_warning: BatteryWarning,
    /// The level when it was armed: a failsafe acts only on worse (PX4).
    battery_warning_at_arming: BatteryWarning,
    /// The fence, built from the plan with this id and length.
    fence: Option<(u32, usize, Fence)>,
    /// Breached, and its action taken (re-armed once back inside).
    breached: bool,
    /// A clamped offboard setpoint was announced (re-armed after
    /// [`CLAMP_REARM_S`] of setpoints within the limit).
    clamp_announced: bool,
    /// Since when the offboard setpoints are within the altitude limit [s].
    clamp_clear_since_s: Option<f64>,
}

impl Autopilot {
    /// A GCS HEARTBEAT (MAV_TYPE_GCS, from any link) arrived at the instant of
    /// `readings`: the data link is alive; after a loss it is announced regained.
    pub fn gcs_heartbeat(&mut self, readings: &SensorReadings) {
        self.now_s = readings.measurement.time_s;
        self.failsafes.gcs_heard_s = Some(self.now_s);
        if self.failsafes.gcs_lost {
            self.failsafes.gcs_lost = false;
            self.say.announce(Severity::Info, "Data link regained");
        }
    }

    /// The battery warning level in force (BATTERY_STATUS `charge_state`).
    #[must_use]
    pub fn battery_warning(&self) -> BatteryWarning {
        self.failsafes.battery_warning
    }

    /// The data-link timer: a GCS heard once and not yet declared lost,
    /// armed or not (PX4 tracks the link either way, so arming long after
    /// the last HEARTBEAT finds it lost on both clocks alike); it started at
    /// the latest GCS HEARTBEAT.
    fn data_link_timer(&self) -> Option<PendingTimer> {
        if self.failsafes.gcs_lost {
            return None;
        }
        Some(PendingTimer {
            timer: ClientTimer::DataLinkLoss,
            started_s: self.failsafes.gcs_heard_s?,
            duration_s: self.settings.failsafe.data_link_loss_s,
        })
    }

    /// Whether the data link is lost (no GCS HEARTBEAT for `COM_DL_LOSS_T`, none since).
    pub(super) fn data_link_is_lost(&self) -> bool {
        self.failsafes.gcs_lost
    }

    /// No GCS HEARTBEAT for `COM_DL_LOSS_T`: announce it and, armed, take
    /// `NAV_DLL_ACT` (PX4 ignores the loss while landing: the runner's rule).
    fn data_link_lost(&mut self, m: &Measurement) {
        self.failsafes.gcs_lost = true;
        self.say
            .announce(Severity::Critical, "Connection to ground station lost");
        let action = self.settings.failsafe.data_link_loss_action;
        self.failsafe_action("GCS connection lost", action, m);
    }

    /// The battery monitor's warning level at the instant of `readings`: it
    /// follows the charge while disarmed and only escalates while armed
    /// (PX4's hysteresis: a sagging voltage that recovers does not clear it);
    /// each new level is announced and acted on (`COM_LOW_BAT_ACT`) when worse
    /// than at arming.
    pub(super) fn supervise_battery(&mut self, readings: &SensorReadings) {
        let remaining = self.battery.remaining(&readings.battery);
        let level = self.settings.failsafe.battery.level(remaining);
        let f = &mut self.failsafes;
        if !self.armed {
            f.battery_warning = level;
            f.battery_warning_at_arming = level;
            return;
        }
        if level <= f.battery_warning {
            return;
        }
        f.battery_warning = level;
        let worse_than_at_arming = level > f.battery_warning_at_arming;
        let (severity, text, cause) = match level {
            BatteryWarning::None => return,
            BatteryWarning::Low => (Severity::Warning, "Low battery level, return advised", "battery low"),
            BatteryWarning::Critical => (
                Severity::Critical,
                "Critical battery level, land now",
                "battery critical",
            ),
            BatteryWarning::Emergency => (
                Severity::Emergency,
                "Emergency battery level, land immediately",
                "battery emergency",
            ),
        };
        self.say.announce(severity, text);
        let action = if worse_than_at_arming {
            self.settings.failsafe.low_battery_action.action(level)
        } else {
            FailsafeAction::Warn
        };
        if action != FailsafeAction::Warn {
            self.failsafe_action(cause, action, &readings.measurement);
        }
    }

    /// The fence of the stored plan (rebuilt when the plan changed).
    fn fence(&mut self) -> &Fence {
        let plan = self.plans.get(MissionType::Fence);
        let key = (plan.id(), plan.len());
        let stale = self.failsafes.fence.as_ref().is_none_or(|(id, n, _)| (*id, *n) != key);
        if stale {
            let fence = Fence::from_items(plan.items(), &self.origin);
            self.failsafes.fence = Some((key.0, key.1, fence));
        }
        &self.failsafes.fence.as_ref().expect("just built").2
    }

    /// The geofence on the current position, armed and in the air: a breach
    /// is announced and `GF_ACTION` taken once; back inside re-arms it.
    /// Not checked while the GNSS fix is lost (PX4 checks the fence only
    /// with a valid global position; the drifting solution would breach it).
    fn supervise_geofence(&mut self, m: &Measurement) {
        if !self.armed || self.land.landed() {
            self.failsafes.breached = false;
            return;
        }
        if self.navigator.gps_lost {
            return;
        }
        let home = self.home_ned();
        let limits = self.settings.failsafe.geofence_limits;
        let breach = geofence::check(self.fence(), &limits, &m.position_ned, &home);
        match (breach, self.failsafes.breached) {
            (Some(b), false) => {
                self.failsafes.breached = true;
                let action = self.settings.failsafe.geofence_action;
                if action != FailsafeAction::None {
                    self.say
                        .announce(Severity::Critical, format!("Geofence breached: {}", b.describe()));
                }
                self.failsafe_action("geofence breach", action, m);
            }
            (None, true) => self.failsafes.breached = false,
            _ => {}
        }
    }

    /// Whether the target `p` [m], NED, lies outside the geofence (zones or limits).
    pub(super) fn outside_geofence(&mut self, p: &Vector3<f64>) -> bool {
        let home = self.home_ned();
        let limits = self.settings.failsafe.geofence_limits;
        geofence::check(self.fence(), &limits, p, &home).is_some()
    }

    /// The lowest NED z [m] a target may have (`GF_MAX_VER_DIST` above home), if limited.
    pub(super) fn max_altitude_z(&self) -> Option<f64> {
        self.settings.failsafe.geofence_limits.min_z_ned(&self.home_ned())
    }

    /// An offboard position setpoint was clamped to the altitude limit
    /// (`clamped`) or was within it: announce a clamp once per excursion (a
    /// stream at the limit, in and out of range by noise, is announced once;
    /// [`CLAMP_REARM_S`] within the limit ends the excursion).
    pub(super) fn offboard_clamped(&mut self, clamped: bool) {
        let now = self.now_s;
        let f = &mut self.failsafes;
        if clamped {
            f.clamp_clear_since_s = None;
            if !f.clamp_announced {
                f.clamp_announced = true;
                self.say
                    .announce(Severity::Warning, "Offboard setpoint clamped to max altitude");
            }
            return;
        }
        let since = *f.clamp_clear_since_s.get_or_insert(now);
        if now - since >= CLAMP_REARM_S - TIME_EPS {
            f.clamp_announced = false;
        }
    }

    /// Take a failsafe action for `cause` (the one runner of every
    /// failsafe), announced as PX4 does ("Failsafe activated due to {cause},
    /// triggering {action}", shortened to fit a STATUSTEXT: "Failsafe:
    /// {cause}, triggering {action}"). Disarmed, nothing happens. While the GNSS fix is lost, Hold, Return and Land become
    /// Descend (remembering which, for when the fix returns). A mode already
    /// in force is not entered again, and a landing (Land, Descend, a
    /// return's or a mission's landing) is not interrupted by Hold, Return or
    /// Land (PX4).
    pub(in crate::autopilot) fn failsafe_action(&mut self, cause: &str, action: FailsafeAction, m: &Measurement) {
        if action == FailsafeAction::None {
            return;
        }
        if !self.armed {
            return;
        }
        if action == FailsafeAction::Warn {
            self.say
                .announce(Severity::Warning, format!("Failsafe warning: {cause}"));
            return;
        }
        let then = match action {
            FailsafeAction::Land => Some(DescendThen::Land),
            FailsafeAction::Return => Some(DescendThen::Return),
            FailsafeAction::Hold => Some(DescendThen::Hold),
            _ => None,
        };
        let action = match then {
            Some(_) if self.navigator.gps_lost => FailsafeAction::Descend,
            _ => action,
        };
        let nav = self.navigator.nav;
        let landing = self.navigator.landing();
        let already = match action {
            FailsafeAction::Hold => landing || matches!(nav, Nav::Hold { target: None, .. }),
            FailsafeAction::Return => landing || matches!(nav, Nav::Rtl { .. }),
            FailsafeAction::Land | FailsafeAction::Descend => landing,
            _ => false,
        };
        if already {
            return;
        }
        let severity = if matches!(action, FailsafeAction::Terminate | FailsafeAction::Disarm) {
            Severity::Emergency
        } else {
            Severity::Critical
        };
        self.say
            .announce(severity, format!("Failsafe: {cause}, triggering {}", action.name()));
        match action {
            FailsafeAction::Hold => self.navigator.enter_hold(),
            FailsafeAction::Return => {
                let cx = situation!(self, m);
                self.navigator.enter_rtl(&cx, &mut self.say);
            }
            FailsafeAction::Land => {
                let landed = self.land.landed();
                self.navigator.enter_land(m, landed, &mut self.say);
            }
            FailsafeAction::Descend => self.navigator.enter_descend(then.unwrap_or(DescendThen::Hold)),
            FailsafeAction::Terminate | FailsafeAction::Disarm => self.disarm_now("Disarmed by failsafe"),
            FailsafeAction::None | FailsafeAction::Warn => {}
        }
    }
}
