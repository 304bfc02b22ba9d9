//! Supervision, once per step: what happens without anyone asking — the
//! offboard setpoints stopped (`COM_OF_LOSS_T`, then `COM_OBL_RC_ACT`), the
//! pilot's sticks stopped (`COM_RC_LOSS_T`, then `NAV_RCL_ACT`), the
//! auto-disarm after a landing (`COM_DISARM_LAND`) or after arming without
//! taking off (`COM_DISARM_PRFLT`), and PX4's failsafes below. Every
//! failsafe acts through one runner ([`Autopilot::failsafe_action`]: one
//! [`FailsafeAction`] per parameter value, one announcement, a landing under
//! way never interrupted, a blind descent without a position, a failsafe
//! the pilot took over back in force while its cause lasts).
//!
//! [`Failsafe`] is the part that remembers and decides (the data link, the
//! battery level, the fence and its breach, the clamp announcement, the
//! client clock) and [`respond`] the runner's choice; the [`Autopilot`]
//! wires them to the commander and the navigator, which carry it out.
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
//! * The failsafe delay: a Return or Land the pilot may take over holds for
//!   `COM_FAIL_ACT_T` first (PX4's `FailsafeBase`), a client timer
//!   ([`ClientTimer::FailsafeDelay`]: it waits for the pilot to take over).
//!
//! # Which clock a timer runs on
//! A timer about the flight itself (landing, hold and loiter times, the
//! disarm after a landing) runs on simulated time, always. A timer that
//! waits for a client to act — the preflight auto-disarm (will the script
//! take off?), the offboard loss (is the setpoint stream still there?), the
//! data-link loss, the manual-control loss and the failsafe delay (will the
//! pilot take over?) — runs on simulated time headless and at speeds up to real time, and on
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
use super::geofence::{self, Breach, Fence};
use super::navigator::{DescendThen, Nav};
use super::position_checks::{PositionLoss, PositionValidity};
use super::rotor_monitor::RotorStatus;
use super::settings::{FailsafeAction, FailsafeSettings};
use super::status::{Announcements, Severity};
use super::{Autopilot, TIME_EPS};
use crate::geo::GeoPoint;
use crate::mission::{MissionType, Plan};
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
    /// A failsafe holding before its action: the action after
    /// `COM_FAIL_ACT_T`, unless the pilot took over.
    FailsafeDelay,
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

/// Offboard setpoints within the altitude limit this long [s] end an
/// excursion: the next clamp is announced again.
const CLAMP_REARM_S: f64 = 5.0;

/// The causes of the failsafes, as announced ("Failsafe: {cause}, triggering
/// {action}") and kept in [`super::FailsafeInForce`]; a lost position names
/// its own ([`super::position_checks::PositionLoss::cause`]).
pub(super) mod cause {
    /// No GCS HEARTBEAT for `COM_DL_LOSS_T` (`NAV_DLL_ACT`).
    pub(in crate::autopilot) const DATA_LINK: &str = "GCS connection lost";
    /// No MANUAL_CONTROL for `COM_RC_LOSS_T` in a manual mode (`NAV_RCL_ACT`).
    pub(in crate::autopilot) const MANUAL_CONTROL: &str = "manual control lost";
    /// No offboard setpoint for `COM_OF_LOSS_T` in Offboard (`COM_OBL_RC_ACT`).
    pub(in crate::autopilot) const OFFBOARD: &str = "offboard signal lost";
    /// The battery at its critical level (`COM_LOW_BAT_ACT`).
    pub(in crate::autopilot) const BATTERY_CRITICAL: &str = "battery critical";
    /// The battery at its emergency level (`COM_LOW_BAT_ACT`).
    pub(in crate::autopilot) const BATTERY_EMERGENCY: &str = "battery emergency";
    /// Outside the geofence (`GF_ACTION`).
    pub(in crate::autopilot) const GEOFENCE: &str = "geofence breach";
    /// A rotor lost with no hover left that holds the heading: land at once.
    pub(in crate::autopilot) const ROTOR_LOSS: &str = "rotor loss";
    /// A rotor failed or degraded, the vehicle still flyable (`COM_ACT_FAIL_ACT`).
    pub(in crate::autopilot) const ROTOR_FAILURE: &str = "rotor failure";
}

/// The failsafes' memory between steps and their decisions: the data link
/// (the latest GCS HEARTBEAT, declared lost), the battery warning level (and
/// the level at arming), the fence built from the plan and whether it is
/// breached, the announcement of a clamped offboard setpoint, and the clock
/// of the client timers.
#[derive(Clone, Debug, Default)]
pub(super) struct Failsafe {
    /// The clock of the timers that wait for a client.
    clock: ClientClock,
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
    /// A failsafe action held back while the vehicle holds (`COM_FAIL_ACT_T`).
    delayed: Option<Delayed>,
}

impl Failsafe {
    /// The clock of the client timers.
    pub(super) fn clock(&self) -> ClientClock {
        self.clock
    }

    /// Time client timers on `clock` from now on.
    pub(super) fn set_clock(&mut self, clock: ClientClock) {
        self.clock = clock;
    }

    /// A GCS HEARTBEAT at `now_s` [s]: the data link is alive; after a loss
    /// it is announced regained.
    pub(super) fn gcs_heartbeat(&mut self, now_s: f64, say: &mut Announcements) {
        self.gcs_heard_s = Some(now_s);
        if self.gcs_lost {
            self.gcs_lost = false;
            say.announce(Severity::Info, "Data link regained");
        }
    }

    /// The data-link timer: a GCS heard once and not yet declared lost,
    /// armed or not (PX4 tracks the link either way, so arming long after
    /// the last HEARTBEAT finds it lost on both clocks alike); it started at
    /// the latest GCS HEARTBEAT and runs `COM_DL_LOSS_T`.
    pub(super) fn data_link_timer(&self, s: &FailsafeSettings) -> Option<PendingTimer> {
        if self.gcs_lost {
            return None;
        }
        Some(PendingTimer {
            timer: ClientTimer::DataLinkLoss,
            started_s: self.gcs_heard_s?,
            duration_s: s.data_link_loss_s,
        })
    }

    /// Whether the data link is lost (no GCS HEARTBEAT for `COM_DL_LOSS_T`, none since).
    pub(super) fn data_link_is_lost(&self) -> bool {
        self.gcs_lost
    }

    /// No GCS HEARTBEAT for `COM_DL_LOSS_T`: declared lost and announced;
    /// the action to take (`NAV_DLL_ACT`).
    pub(super) fn data_link_lost(&mut self, s: &FailsafeSettings, say: &mut Announcements) -> FailsafeAction {
        self.gcs_lost = true;
        say.announce(Severity::Critical, "Connection to ground station lost");
        s.data_link_loss_action
    }

    /// The battery warning level in force (BATTERY_STATUS `charge_state`).
    pub(super) fn battery_warning(&self) -> BatteryWarning {
        self.battery_warning
    }

    /// The battery monitor's warning `level` now: it follows the charge
    /// while disarmed and only escalates while armed (PX4's hysteresis: a
    /// sagging voltage that recovers does not clear it); each new level is
    /// announced, and when worse than at arming the cause and action of
    /// `COM_LOW_BAT_ACT` are returned for the runner (none for a warning).
    pub(super) fn battery(
        &mut self,
        level: BatteryWarning,
        armed: bool,
        s: &FailsafeSettings,
        say: &mut Announcements,
    ) -> Option<(&'static str, FailsafeAction)> {
        if !armed {
            self.battery_warning = level;
            self.battery_warning_at_arming = level;
            return None;
        }
        if level <= self.battery_warning {
            return None;
        }
        self.battery_warning = level;
        let worse_than_at_arming = level > self.battery_warning_at_arming;
        let (severity, text, cause) = match level {
            BatteryWarning::None => return None,
            BatteryWarning::Low => (Severity::Warning, "Low battery level, return advised", "battery low"),
            BatteryWarning::Critical => (
                Severity::Critical,
                "Critical battery level, land now",
                cause::BATTERY_CRITICAL,
            ),
            BatteryWarning::Emergency => (
                Severity::Emergency,
                "Emergency battery level, land immediately",
                cause::BATTERY_EMERGENCY,
            ),
        };
        say.announce(severity, text);
        let action = if worse_than_at_arming {
            s.low_battery_action.action(level)
        } else {
            FailsafeAction::Warn
        };
        (action != FailsafeAction::Warn).then_some((cause, action))
    }

    /// The fence of `plan` (the stored fence plan, rebuilt when it changed)
    /// around `origin`.
    pub(super) fn fence(&mut self, plan: &Plan, origin: &GeoPoint) -> &Fence {
        let key = (plan.id(), plan.len());
        let stale = self.fence.as_ref().is_none_or(|(id, n, _)| (*id, *n) != key);
        if stale {
            let fence = Fence::from_items(plan.items(), origin);
            self.fence = Some((key.0, key.1, fence));
        }
        &self.fence.as_ref().expect("just built").2
    }

    /// Disarmed or landed: the fence is not watched, a breach is forgotten.
    pub(super) fn geofence_at_rest(&mut self) {
        self.breached = false;
    }

    /// The geofence's verdict on the current position (armed, in the air):
    /// a new breach is announced (unless `GF_ACTION` is none) and its action
    /// returned for the runner, once; back inside re-arms it.
    pub(super) fn geofence(
        &mut self,
        breach: Option<Breach>,
        s: &FailsafeSettings,
        say: &mut Announcements,
    ) -> Option<FailsafeAction> {
        match (breach, self.breached) {
            (Some(b), false) => {
                self.breached = true;
                let action = s.geofence_action;
                if action != FailsafeAction::None {
                    say.announce(Severity::Critical, format!("Geofence breached: {}", b.describe()));
                }
                Some(action)
            }
            (None, true) => {
                self.breached = false;
                None
            }
            _ => None,
        }
    }

    /// An offboard position setpoint at `now_s` [s] was clamped to the
    /// altitude limit (`clamped`) or was within it: announce a clamp once
    /// per excursion (a stream at the limit, in and out of range by noise,
    /// is announced once; [`CLAMP_REARM_S`] within the limit ends the excursion).
    pub(super) fn offboard_clamped(&mut self, clamped: bool, now_s: f64, say: &mut Announcements) {
        if clamped {
            self.clamp_clear_since_s = None;
            if !self.clamp_announced {
                self.clamp_announced = true;
                say.announce(Severity::Warning, "Offboard setpoint clamped to max altitude");
            }
            return;
        }
        let since = *self.clamp_clear_since_s.get_or_insert(now_s);
        if now_s - since >= CLAMP_REARM_S - TIME_EPS {
            self.clamp_announced = false;
        }
    }
}

/// What the one failsafe runner has the vehicle do.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Response {
    /// Hold where it is.
    Hold,
    /// Return to launch.
    Return,
    /// Land where it is.
    Land,
    /// Descend without a position, then what was meant when the fix returns.
    Descend(DescendThen),
    /// Stop the rotors (flight termination, PX4's lockdown).
    Disarm,
}

impl Response {
    /// The action taken, as announced: `asked` unless it became another.
    fn taken(self, asked: FailsafeAction) -> FailsafeAction {
        match self {
            Self::Hold => FailsafeAction::Hold,
            Self::Return => FailsafeAction::Return,
            Self::Land => FailsafeAction::Land,
            Self::Descend(_) => FailsafeAction::Descend,
            Self::Disarm => asked,
        }
    }

    /// What the vehicle is to do once it has a position (a Descend gives
    /// way to it); `None` for a disarm.
    fn then(self) -> Option<DescendThen> {
        match self {
            Self::Hold => Some(DescendThen::Hold),
            Self::Return => Some(DescendThen::Return),
            Self::Land => Some(DescendThen::Land),
            Self::Descend(then) => Some(then),
            Self::Disarm => None,
        }
    }
}

/// What a Hold, Return or Land failsafe has the vehicle do once it has a
/// position (`None` for any other action).
fn then_of(action: FailsafeAction) -> Option<DescendThen> {
    match action {
        FailsafeAction::Hold => Some(DescendThen::Hold),
        FailsafeAction::Return => Some(DescendThen::Return),
        FailsafeAction::Land => Some(DescendThen::Land),
        _ => None,
    }
}

/// The failsafe action that has the vehicle do `then` (the mission, which
/// no failsafe action flies, is never the more severe: Hold stands for it).
fn action_of(then: DescendThen) -> FailsafeAction {
    match then {
        DescendThen::Mission | DescendThen::Hold => FailsafeAction::Hold,
        DescendThen::Return => FailsafeAction::Return,
        DescendThen::Land => FailsafeAction::Land,
    }
}

/// The action a lost position in Position mode takes: Altitude mode (PX4's
/// `COM_POSCTL_NAVL` 0).
pub(super) const ALTITUDE_FALLBACK: &str = "Altitude";

/// Every cause a failsafe acts for ([`crate::autopilot::FailsafeInForce::cause`]):
/// the [`cause`]s and a lost position's.
pub const FAILSAFE_CAUSES: [&str; 10] = [
    cause::DATA_LINK,
    cause::MANUAL_CONTROL,
    cause::OFFBOARD,
    cause::BATTERY_CRITICAL,
    cause::BATTERY_EMERGENCY,
    cause::GEOFENCE,
    cause::ROTOR_LOSS,
    cause::ROTOR_FAILURE,
    PositionLoss::NoFix.cause(),
    PositionLoss::Estimate.cause(),
];

/// Every action a failsafe takes, as announced ([`crate::autopilot::FailsafeInForce::action`]).
pub const FAILSAFE_ACTIONS: [&str; 7] = [
    FailsafeAction::Hold.name(),
    FailsafeAction::Return.name(),
    FailsafeAction::Land.name(),
    FailsafeAction::Descend.name(),
    ALTITUDE_FALLBACK,
    FailsafeAction::Terminate.name(),
    FailsafeAction::Disarm.name(),
];

/// The runner's choice for failsafe `action` caused by `cause`, announced
/// as PX4 does ("Failsafe activated due to {cause}, triggering {action}",
/// shortened to fit a STATUSTEXT: "Failsafe: {cause}, triggering
/// {action}"); `None` when nothing is to be done ([`decide`]); a warning is
/// only said.
pub(super) fn respond(
    cause: &str,
    action: FailsafeAction,
    armed: bool,
    position: PositionValidity,
    nav: Nav,
    landing: bool,
    say: &mut Announcements,
) -> Option<Response> {
    if action == FailsafeAction::Warn && armed {
        say.announce(Severity::Warning, format!("Failsafe warning: {cause}"));
    }
    let response = decide(action, armed, position, nav, landing)?;
    let severity = if response == Response::Disarm {
        Severity::Emergency
    } else {
        Severity::Critical
    };
    say.announce(
        severity,
        format!("Failsafe: {cause}, triggering {}", response.taken(action).name()),
    );
    Some(response)
}

/// What failsafe `action` has the vehicle do, unsaid; `None` when nothing is
/// to be done. Disarmed, nothing happens, and a warning acts on nothing.
/// While the position does not serve Hold, Return or Land (`position`),
/// each becomes Descend (remembering which, for when the position
/// returns). A mode already in force (`nav`) is not entered again, and a
/// landing (`landing`: Land, Descend, a return's or a mission's landing) is
/// not interrupted by Hold, Return or Land (PX4).
fn decide(
    action: FailsafeAction,
    armed: bool,
    position: PositionValidity,
    nav: Nav,
    landing: bool,
) -> Option<Response> {
    if matches!(action, FailsafeAction::None | FailsafeAction::Warn) || !armed {
        return None;
    }
    let then = then_of(action);
    let action = match then {
        Some(then) if !position.serves(then.need()) => FailsafeAction::Descend,
        _ => action,
    };
    let already = match action {
        FailsafeAction::Hold => landing || matches!(nav, Nav::Hold { target: None, .. }),
        FailsafeAction::Return => landing || matches!(nav, Nav::Rtl { .. }),
        FailsafeAction::Land | FailsafeAction::Descend => landing,
        _ => false,
    };
    if already {
        return None;
    }
    match action {
        FailsafeAction::Hold => Some(Response::Hold),
        FailsafeAction::Return => Some(Response::Return),
        FailsafeAction::Land => Some(Response::Land),
        FailsafeAction::Descend => Some(Response::Descend(then.unwrap_or(DescendThen::Hold))),
        FailsafeAction::Terminate | FailsafeAction::Disarm => Some(Response::Disarm),
        FailsafeAction::None | FailsafeAction::Warn => None,
    }
}

/// Whether failsafe `action` for `cause` starts or joins the failsafe
/// delay (`COM_FAIL_ACT_T`): the actions PX4 lets the user take over
/// "automatically" (`UserTakeoverAllowed::Auto`, the default of
/// `FailsafeBase::ActionOptions`, in `failsafe.cpp`) — the data link, the
/// sticks, the battery, a failed rotor, and the geofence's Return and Land
/// (its Hold is `AlwaysModeSwitchOnly`). Not the offboard signal and a lost
/// position (PX4's mode fallbacks, which act at once), nor a rotor loss that
/// leaves no heading (rotorpilot's own, an emergency).
fn may_wait(cause: &str, action: FailsafeAction) -> bool {
    match cause {
        cause::DATA_LINK
        | cause::MANUAL_CONTROL
        | cause::BATTERY_CRITICAL
        | cause::BATTERY_EMERGENCY
        | cause::ROTOR_FAILURE => true,
        cause::GEOFENCE => action != FailsafeAction::Hold,
        _ => false,
    }
}

/// Announce that failsafe `action` for `cause` follows in `seconds` [s],
/// rounded to whole seconds. PX4 says "Failsafe activated, entering Hold
/// for 5 seconds" (and in its event the cause and the action); the cause,
/// the action and the time fit one STATUSTEXT: "Failsafe: {cause}, {action} in 5 s".
fn announce_delay(say: &mut Announcements, cause: &str, action: FailsafeAction, seconds: f64) {
    say.announce(
        Severity::Critical,
        format!("Failsafe: {cause}, {} in {} s", action.name(), (seconds + 0.5).floor()),
    );
}

/// The failsafe delay (PX4's `_current_delay`, `COM_FAIL_ACT_T`): the
/// vehicle holds, and `action` follows when it runs out, unless the pilot
/// selects a mode, the vehicle disarms, the position stops serving Hold, or
/// a Return, Land or worse that cannot wait acts first. One delay for all:
/// a failsafe that may wait joins it, and the more severe action is carried
/// out when it runs out. A Hold failsafe starts it too (it holds at once,
/// and a Return or Land that joins it acts when it runs out).
#[derive(Clone, Debug, PartialEq)]
struct Delayed {
    /// Why (the cause of the most severe action).
    cause: String,
    /// What follows: Hold, Return or Land.
    action: FailsafeAction,
    /// When it started [s].
    started_s: f64,
    /// How long it runs [s] (`COM_FAIL_ACT_T` then).
    duration_s: f64,
}

// ----- the wiring: the failsafes' decisions carried out by the flight stack ---------------------

impl Autopilot {
    /// Time client timers on `clock` from now on.
    pub fn set_client_clock(&mut self, clock: ClientClock) {
        self.failsafe.set_clock(clock);
    }

    /// The clock of the client timers.
    #[must_use]
    pub fn client_clock(&self) -> ClientClock {
        self.failsafe.clock()
    }

    /// The client timers running now (for the runtime to time on the wall clock).
    #[must_use]
    pub fn client_timers(&self) -> Vec<PendingTimer> {
        let mut out = Vec::new();
        let s = &self.settings;
        if let Some(p) = self
            .commander
            .preflight_disarm_timer(self.land.landed(), s.disarm_preflight_s)
        {
            out.push(p);
        }
        if let Some(t) = self.navigator.offboard_arrival() {
            out.push(PendingTimer {
                timer: ClientTimer::OffboardLoss,
                started_s: t,
                duration_s: s.offboard_loss_s,
            });
        }
        // data-link loss (COM_DL_LOSS_T)
        if let Some(p) = self.failsafe.data_link_timer(&s.failsafe) {
            out.push(p);
        }
        if let Some(t) = self.navigator.manual_loss_timer_start() {
            out.push(PendingTimer {
                timer: ClientTimer::ManualControlLoss,
                started_s: t,
                duration_s: s.manual.loss_s,
            });
        }
        if let Some(d) = &self.failsafe.delayed {
            out.push(PendingTimer {
                timer: ClientTimer::FailsafeDelay,
                started_s: d.started_s,
                duration_s: d.duration_s,
            });
        }
        out
    }

    /// The runtime's wall clock says the client timer `timer` that started at
    /// `started_s` has run out: act on it at the instant of `readings` if it
    /// is still running (a timer since restarted or stopped is ignored).
    /// True when it was acted on.
    pub fn client_timeout(&mut self, timer: ClientTimer, started_s: f64, readings: &SensorReadings) -> bool {
        let readings = self.navigated(readings);
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
                if self.navigator.nav() == Nav::Offboard {
                    self.offboard_lost(m);
                }
            }
            ClientTimer::DataLinkLoss => {
                // PX4 ignores the loss while landing: the runner's rule
                let action = self.failsafe.data_link_lost(&self.settings.failsafe, &mut self.say);
                self.failsafe_action(cause::DATA_LINK, action, m);
            }
            ClientTimer::ManualControlLoss => {
                // in a manual mode NAV_RCL_ACT, descending instead of Hold,
                // Return or Land without a position (the runner's rule)
                if self.navigator.manual_control_lost(&mut self.say) {
                    let action = self.settings.manual.loss_action;
                    self.failsafe_action(cause::MANUAL_CONTROL, action, m);
                }
            }
            ClientTimer::FailsafeDelay => {
                // a Hold was flown from the start: nothing follows
                let d = self.failsafe.delayed.take().expect("a running timer");
                if d.action != FailsafeAction::Hold {
                    self.act_on_failsafe(&d.cause, d.action, m);
                }
            }
        }
    }

    /// Whether the offboard setpoints are fresh at `now` (on the client clock).
    pub(super) fn offboard_fresh(&self, now: f64) -> bool {
        self.navigator
            .offboard_fresh(now, self.settings.offboard_loss_s, self.failsafe.clock())
    }

    /// The client timers on simulated time (one boundary rule for all:
    /// expired when `now - started >= duration - TIME_EPS`, dispatched as the
    /// runtime's wall-clock expiries are), the disarm after a landing and
    /// the geofence, at the instant of `m`.
    pub(super) fn supervise(&mut self, m: &Measurement) {
        let now = m.time_s;
        if self.failsafe.clock() == ClientClock::Simulated {
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
        let taking_off = matches!(self.navigator.nav(), Nav::Takeoff { .. });
        if self
            .commander
            .landing_disarm_due(now, self.land.landed(), taking_off, self.settings.disarm_land_s)
        {
            self.disarm_now("Disarmed by landing");
        }
        self.supervise_geofence(m);
        self.supervise_failsafe_delay();
    }

    /// Offboard setpoints lost while in Offboard: announced, then `COM_OBL_RC_ACT`.
    fn offboard_lost(&mut self, m: &Measurement) {
        self.say.announce(Severity::Warning, "Offboard signal lost");
        if !self.commander.armed() {
            // no failsafe on the ground: Offboard without setpoints is no
            // mode to stay in, so fall back to Hold as before arming
            self.navigator.enter_hold();
            return;
        }
        let action = self.settings.offboard_loss_action;
        self.failsafe_action(cause::OFFBOARD, action, m);
    }

    /// A GCS HEARTBEAT (MAV_TYPE_GCS, from any link) arrived at the instant of
    /// `readings`: the data link is alive; after a loss it is announced regained.
    pub fn gcs_heartbeat(&mut self, readings: &SensorReadings) {
        self.now_s = readings.measurement.time_s;
        self.failsafe.gcs_heartbeat(self.now_s, &mut self.say);
    }

    /// The battery warning level in force (BATTERY_STATUS `charge_state`).
    #[must_use]
    pub fn battery_warning(&self) -> BatteryWarning {
        self.failsafe.battery_warning()
    }

    /// The battery monitor's warning level at the instant of `readings`,
    /// judged by [`Failsafe::battery`], its action taken.
    pub(super) fn supervise_battery(&mut self, readings: &SensorReadings) {
        let remaining = self.battery.remaining(&readings.battery);
        let level = self.settings.failsafe.battery.level(remaining);
        let armed = self.commander.armed();
        if let Some((cause, action)) = self
            .failsafe
            .battery(level, armed, &self.settings.failsafe, &mut self.say)
        {
            self.failsafe_action(cause, action, &readings.measurement);
        }
    }

    /// The geofence on the current position, armed and in the air
    /// ([`Failsafe::geofence`]). Not checked while the position is lost (PX4
    /// checks the fence only with a valid global position; the drifting
    /// solution would breach it).
    fn supervise_geofence(&mut self, m: &Measurement) {
        if !self.commander.armed() || self.land.landed() {
            self.failsafe.geofence_at_rest();
            return;
        }
        if self.navigator.position_lost() {
            return;
        }
        let breach = self.geofence_breach(&m.position_ned);
        if let Some(action) = self.failsafe.geofence(breach, &self.settings.failsafe, &mut self.say) {
            self.failsafe_action(cause::GEOFENCE, action, m);
        }
    }

    /// The geofence's verdict (zones or limits) on `p` [m], NED.
    fn geofence_breach(&mut self, p: &Vector3<f64>) -> Option<Breach> {
        let home = self.home_ned();
        let limits = self.settings.failsafe.geofence_limits;
        let fence = self.failsafe.fence(self.plans.get(MissionType::Fence), &self.origin);
        geofence::check(fence, &limits, p, &home)
    }

    /// Whether the target `p` [m], NED, lies outside the geofence (zones or limits).
    pub(super) fn outside_geofence(&mut self, p: &Vector3<f64>) -> bool {
        self.geofence_breach(p).is_some()
    }

    /// The lowest NED z [m] a target may have (`GF_MAX_VER_DIST` above home), if limited.
    pub(super) fn max_altitude_z(&self) -> Option<f64> {
        self.settings.failsafe.geofence_limits.min_z_ned(&self.home_ned())
    }

    /// An offboard position setpoint was clamped to the altitude limit
    /// (`clamped`) or was within it ([`Failsafe::offboard_clamped`]).
    pub(super) fn offboard_clamped(&mut self, clamped: bool) {
        self.failsafe.offboard_clamped(clamped, self.now_s, &mut self.say);
    }

    /// Whether the cause of a failsafe (`cause`) is still there (PX4's
    /// `state_failure` of an action in the failsafe framework's list): a
    /// rotor flagged, the data link lost, the battery at its critical level
    /// or worse (it never recovers armed), outside the geofence, the sticks
    /// lost. The offboard signal and a lost position only stand in for the
    /// mode the pilot chose (PX4's mode fallback): a mode chosen since ends them.
    pub(in crate::autopilot) fn failsafe_cause_lasts(&self, cause: &str) -> bool {
        match cause {
            cause::ROTOR_LOSS | cause::ROTOR_FAILURE => self.rotor_status().iter().any(|r| *r != RotorStatus::Healthy),
            cause::DATA_LINK => self.failsafe.data_link_is_lost(),
            cause::BATTERY_CRITICAL | cause::BATTERY_EMERGENCY => {
                self.failsafe.battery_warning() >= BatteryWarning::Critical
            }
            cause::GEOFENCE => self.failsafe.breached,
            cause::MANUAL_CONTROL => {
                !self
                    .navigator
                    .manual_fresh(self.now_s, self.settings.manual.loss_s, self.failsafe.clock())
            }
            _ => false,
        }
    }

    /// Take a failsafe action for `cause` (the one runner of every
    /// failsafe). A Hold, Return or Land ends a takeover (PX4: a new action
    /// of Hold or worse clears it), and the failsafe taken over comes back
    /// instead when its action is the more severe.
    ///
    /// The failsafe delay ([`Delayed`], `COM_FAIL_ACT_T`): a Return or Land
    /// that may wait ([`may_wait`], judged on this failsafe's own cause and
    /// on that of one taken over that comes back) holds first (PX4's
    /// `FailsafeBase`: "Failsafe activated, entering Hold for 5 seconds";
    /// here "Failsafe: {cause}, {action} in 5 s"), unless
    /// the position does not serve Hold or a failsafe other than Hold is in
    /// force already; a Hold that may wait holds at once and starts the
    /// delay too. A delay running takes such a failsafe in.
    pub(in crate::autopilot) fn failsafe_action(&mut self, cause: &str, action: FailsafeAction, m: &Measurement) {
        let mut can_wait = may_wait(cause, action);
        let mut cause = cause.to_owned();
        let mut action = action;
        if matches!(
            action,
            FailsafeAction::Hold
                | FailsafeAction::Return
                | FailsafeAction::Land
                | FailsafeAction::Terminate
                | FailsafeAction::Disarm
        ) && self.commander.armed()
            && let Some(f) = self.taken_over.take()
            // the failsafe taken over is the more severe: it comes back
            && let (Some(then), Some(before)) = (then_of(action), f.action)
            && before.most_severe(then) != then
        {
            action = action_of(before);
            // it waits only if it may itself (a rotor loss's landing never does)
            can_wait &= may_wait(&f.cause, action);
            cause = f.cause;
        }
        if !(can_wait && self.failsafe_waits(action)) {
            self.act_on_failsafe(&cause, action, m);
            return;
        }
        let then = then_of(action).expect("a Hold, Return or Land");
        if let Some(d) = self.failsafe.delayed.as_mut() {
            // the delay running: the more severe action follows when it runs
            // out, announced with the time left
            let before = then_of(d.action).expect("a Hold, Return or Land");
            if before.most_severe(then) != before {
                d.action = action;
                d.cause.clone_from(&cause);
                let left_s = (d.started_s + d.duration_s - m.time_s).max(0.0);
                announce_delay(&mut self.say, &cause, action, left_s);
                self.enter_failsafe(&cause, Some(then), FailsafeAction::Hold.name());
            }
            return;
        }
        let delay_s = self.settings.failsafe.action_delay_s;
        if action == FailsafeAction::Hold {
            self.act_on_failsafe(&cause, action, m);
        } else {
            announce_delay(&mut self.say, &cause, action, delay_s);
            if !matches!(self.navigator.nav(), Nav::Hold { target: None, .. }) {
                self.navigator.enter_hold();
            }
            self.enter_failsafe(&cause, Some(then), FailsafeAction::Hold.name());
        }
        self.failsafe.delayed = Some(Delayed {
            cause,
            action,
            started_s: m.time_s,
            duration_s: delay_s,
        });
    }

    /// Whether failsafe `action` holds first (or joins the delay): the delay
    /// is not 0, it is a Hold, Return or Land the runner would carry out
    /// now, Hold can be flown (the position serves it), and no failsafe
    /// other than Hold is in force (PX4's `clearDelayIfNeeded`).
    fn failsafe_waits(&self, action: FailsafeAction) -> bool {
        let position = self.navigator.position();
        self.settings.failsafe.action_delay_s > 0.0
            && matches!(
                decide(
                    action,
                    self.commander.armed(),
                    position,
                    self.navigator.nav(),
                    self.navigator.landing(),
                ),
                Some(Response::Hold | Response::Return | Response::Land)
            )
            && position.serves(DescendThen::Hold.need())
            && self
                .in_failsafe
                .as_ref()
                .is_none_or(|f| f.triggered == FailsafeAction::Hold.name())
    }

    /// Carry out failsafe `action` for `cause` now: [`respond`] chooses, the
    /// navigator or the commander carries it out. A Return, Land or worse
    /// ends the failsafe delay; a Hold leaves it running, and its failsafe in force.
    fn act_on_failsafe(&mut self, cause: &str, action: FailsafeAction, m: &Measurement) {
        let response = respond(
            cause,
            action,
            self.commander.armed(),
            self.navigator.position(),
            self.navigator.nav(),
            self.navigator.landing(),
            &mut self.say,
        );
        if let Some(r) = response
            && !(r == Response::Hold && self.failsafe.delayed.is_some())
        {
            self.failsafe.delayed = None;
            self.enter_failsafe(cause, r.then(), r.taken(action).name());
        }
        match response {
            Some(Response::Hold) => self.navigator.enter_hold(),
            Some(Response::Return) => {
                let cx = situation!(self, m);
                self.navigator.enter_rtl(&cx, &mut self.say);
            }
            Some(Response::Land) => {
                let landed = self.land.landed();
                self.navigator.enter_land(m, landed, &mut self.say);
            }
            Some(Response::Descend(then)) => self.navigator.enter_descend(then),
            Some(Response::Disarm) => self.disarm_now("Disarmed by failsafe"),
            None => {}
        }
    }

    /// The failsafe delay ends without its action when the position no
    /// longer serves Hold (the lost position's Descend gives way to the
    /// action instead); it runs out as a client timer.
    fn supervise_failsafe_delay(&mut self) {
        if self.failsafe.delayed.is_some() && !self.navigator.position().serves(DescendThen::Hold.need()) {
            self.failsafe.delayed = None;
        }
    }

    /// The pilot selected a mode (PX4's user takeover) or the vehicle
    /// disarmed: the failsafe delay ends without its action.
    pub(in crate::autopilot) fn end_failsafe_delay(&mut self) {
        self.failsafe.delayed = None;
    }

    /// Whether the failsafe delay runs (`COM_FAIL_ACT_T`).
    pub(in crate::autopilot) fn failsafe_delayed(&self) -> bool {
        self.failsafe.delayed.is_some()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::airframe::Airframe;
    use crate::autopilot::settings::LowBatteryAction;
    use crate::params::ParamStore;

    fn settings() -> FailsafeSettings {
        FailsafeSettings::from_store(&ParamStore::new(&Airframe::load("quad").unwrap()))
    }

    fn texts(say: &mut Announcements) -> Vec<String> {
        say.drain().into_iter().map(|s| s.text).collect()
    }

    #[test]
    fn a_critical_battery_in_flight_triggers_com_low_bat_act_once() {
        let s = FailsafeSettings {
            low_battery_action: LowBatteryAction::ReturnOrLand,
            ..settings()
        };
        let mut f = Failsafe::default();
        let mut say = Announcements::default();
        // disarmed: the level follows the charge, nothing is said
        assert_eq!(f.battery(BatteryWarning::Low, false, &s, &mut say), None);
        assert_eq!(f.battery(BatteryWarning::None, false, &s, &mut say), None);
        assert_eq!(f.battery_warning(), BatteryWarning::None);
        assert!(texts(&mut say).is_empty());
        // armed: low is a warning only
        assert_eq!(f.battery(BatteryWarning::Low, true, &s, &mut say), None);
        assert_eq!(texts(&mut say), ["Low battery level, return advised"]);
        let got = f.battery(BatteryWarning::Critical, true, &s, &mut say);
        assert_eq!(got, Some(("battery critical", FailsafeAction::Return)));
        assert_eq!(texts(&mut say), ["Critical battery level, land now"]);
        // no repeat, no recovery while armed
        assert_eq!(f.battery(BatteryWarning::Critical, true, &s, &mut say), None);
        assert_eq!(f.battery(BatteryWarning::None, true, &s, &mut say), None);
        assert_eq!(f.battery_warning(), BatteryWarning::Critical);
        let got = f.battery(BatteryWarning::Emergency, true, &s, &mut say);
        assert_eq!(got, Some(("battery emergency", FailsafeAction::Land)));
    }

    #[test]
    fn a_battery_level_held_at_arming_is_only_announced() {
        let s = FailsafeSettings {
            low_battery_action: LowBatteryAction::Land,
            ..settings()
        };
        let mut f = Failsafe::default();
        let mut say = Announcements::default();
        f.battery(BatteryWarning::Critical, false, &s, &mut say);
        // armed at critical: the warning level restarts from the charge
        assert_eq!(f.battery(BatteryWarning::Critical, true, &s, &mut say), None);
        assert_eq!(
            f.battery(BatteryWarning::Emergency, true, &s, &mut say),
            Some(("battery emergency", FailsafeAction::Land))
        );
        let warn_only = FailsafeSettings {
            low_battery_action: LowBatteryAction::Warning,
            ..settings()
        };
        let mut f = Failsafe::default();
        assert_eq!(f.battery(BatteryWarning::Emergency, true, &warn_only, &mut say), None);
    }

    #[test]
    fn the_data_link_is_timed_from_the_latest_gcs_heartbeat() {
        let s = FailsafeSettings {
            data_link_loss_action: FailsafeAction::Return,
            ..settings()
        };
        let mut f = Failsafe::default();
        let mut say = Announcements::default();
        assert_eq!(f.data_link_timer(&s), None, "no GCS heard yet");
        f.gcs_heartbeat(3.0, &mut say);
        let t = f.data_link_timer(&s).unwrap();
        assert_eq!(
            (t.timer, t.started_s, t.duration_s),
            (ClientTimer::DataLinkLoss, 3.0, s.data_link_loss_s)
        );
        assert_eq!(f.data_link_lost(&s, &mut say), FailsafeAction::Return);
        assert!(f.data_link_is_lost());
        assert_eq!(f.data_link_timer(&s), None);
        assert_eq!(texts(&mut say), ["Connection to ground station lost"]);
        f.gcs_heartbeat(9.0, &mut say);
        assert!(!f.data_link_is_lost());
        assert_eq!(texts(&mut say), ["Data link regained"]);
        assert_eq!(f.data_link_timer(&s).unwrap().started_s, 9.0);
    }

    #[test]
    fn every_action_taken_is_one_the_event_metadata_knows() {
        use FailsafeAction as A;
        for a in [A::Hold, A::Return, A::Land, A::Terminate, A::Disarm, A::Descend] {
            assert!(FAILSAFE_ACTIONS.contains(&a.name()), "{a:?}");
        }
    }

    #[test]
    fn the_runner_chooses_the_response() {
        let mut say = Announcements::default();
        let hold = Nav::Hold { target: None };
        let run = |action, armed, lost: bool, nav, landing, say: &mut Announcements| {
            let position = PositionValidity::all(!lost);
            respond("GCS connection lost", action, armed, position, nav, landing, say)
        };
        // disarmed or none: nothing, not even a message
        assert_eq!(run(FailsafeAction::Return, false, false, hold, false, &mut say), None);
        assert_eq!(run(FailsafeAction::None, true, false, hold, false, &mut say), None);
        assert!(texts(&mut say).is_empty());
        assert_eq!(run(FailsafeAction::Warn, true, false, hold, false, &mut say), None);
        assert_eq!(texts(&mut say), ["Failsafe warning: GCS connection lost"]);
        assert_eq!(
            run(FailsafeAction::Return, true, false, hold, false, &mut say),
            Some(Response::Return)
        );
        assert_eq!(texts(&mut say), ["Failsafe: GCS connection lost, triggering Return"]);
        // without a fix: a blind descent that remembers the intent
        assert_eq!(
            run(FailsafeAction::Return, true, true, hold, false, &mut say),
            Some(Response::Descend(DescendThen::Return))
        );
        assert_eq!(
            run(FailsafeAction::Land, true, true, Nav::Offboard, false, &mut say),
            Some(Response::Descend(DescendThen::Land))
        );
        say.drain();
        // a landing goes on; a mode in force is not entered again
        assert_eq!(
            run(FailsafeAction::Hold, true, false, Nav::Offboard, true, &mut say),
            None
        );
        assert_eq!(
            run(FailsafeAction::Land, true, false, Nav::Offboard, true, &mut say),
            None
        );
        assert_eq!(run(FailsafeAction::Hold, true, false, hold, false, &mut say), None);
        assert!(texts(&mut say).is_empty());
        // termination stops the rotors, even while landing
        assert_eq!(
            run(FailsafeAction::Terminate, true, false, hold, true, &mut say),
            Some(Response::Disarm)
        );
        let said = say.drain();
        assert_eq!(said[0].severity, Severity::Emergency);
        assert_eq!(said[0].text, "Failsafe: GCS connection lost, triggering flight t");
    }

    #[test]
    fn a_geofence_breach_acts_once_until_back_inside() {
        let s = FailsafeSettings {
            geofence_action: FailsafeAction::Land,
            ..settings()
        };
        let mut f = Failsafe::default();
        let mut say = Announcements::default();
        assert_eq!(f.geofence(None, &s, &mut say), None);
        assert_eq!(
            f.geofence(Some(Breach::MaxAltitude), &s, &mut say),
            Some(FailsafeAction::Land)
        );
        assert_eq!(texts(&mut say), ["Geofence breached: max altitude exceeded"]);
        assert_eq!(f.geofence(Some(Breach::MaxAltitude), &s, &mut say), None);
        assert_eq!(f.geofence(None, &s, &mut say), None);
        assert_eq!(
            f.geofence(Some(Breach::OutsideInclusion), &s, &mut say),
            Some(FailsafeAction::Land)
        );
        f.geofence_at_rest();
        assert_eq!(
            f.geofence(Some(Breach::OutsideInclusion), &s, &mut say),
            Some(FailsafeAction::Land)
        );
        // GF_ACTION none: nothing said, and the runner does nothing with it
        let quiet = FailsafeSettings {
            geofence_action: FailsafeAction::None,
            ..settings()
        };
        let mut f = Failsafe::default();
        say.drain();
        assert_eq!(
            f.geofence(Some(Breach::MaxAltitude), &quiet, &mut say),
            Some(FailsafeAction::None)
        );
        assert!(texts(&mut say).is_empty());
    }

    #[test]
    fn a_clamped_setpoint_is_announced_once_per_excursion() {
        let mut f = Failsafe::default();
        let mut say = Announcements::default();
        f.offboard_clamped(true, 1.0, &mut say);
        f.offboard_clamped(true, 1.1, &mut say);
        f.offboard_clamped(false, 1.2, &mut say);
        f.offboard_clamped(true, 2.0, &mut say);
        assert_eq!(texts(&mut say), ["Offboard setpoint clamped to max altitude"]);
        f.offboard_clamped(false, 3.0, &mut say);
        f.offboard_clamped(false, 8.0, &mut say);
        f.offboard_clamped(true, 8.1, &mut say);
        assert_eq!(texts(&mut say), ["Offboard setpoint clamped to max altitude"]);
    }
}
