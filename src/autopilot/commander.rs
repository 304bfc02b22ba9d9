//! The commander: what each [`AutopilotCommand`] does and when it is refused
//! (PX4 behaviour, `docs/mavlink.md` sections 3, 5 and 8) — arming (its
//! prearm checks are `prearm`'s), the mode state machine, home, and the
//! gates of reboot and failure injection. Each command is judged at the instant it is
//! applied, against the sensor readings of that instant.
//!
//! [`Commander`] is the part that holds the arming state (armed, since
//! when, taken off, landed since when) and decides on its own: arming (on
//! the first failing prearm check) and disarming, the gate of a
//! command that needs the vehicle armed, the auto-disarm timers, reboot and
//! shutdown ([`PowerDecision`]) and failure injection. The [`Autopilot`]
//! gathers what the checks need from the other parts and carries out what
//! needs the navigator.

use nalgebra::Vector3;

use super::TIME_EPS;
use super::command::{AutopilotCommand, CommandOutcome, PowerAction};
use super::failsafe::{ClientTimer, PendingTimer};
use super::land_detector::LandEvent;
use super::navigator::{HoldTarget, ManualMode, Nav, OrbitChange};
use super::position_checks::PositionNeed;
use super::status::{Announcements, Severity};
use super::{Autopilot, FlightMode, ManualControl, OffboardSetpoint, TargetFix};
use crate::geo::GeoPoint;
use crate::signals::{Measurement, SensorReadings};

/// DO_CHANGE_SPEED's "back to the default speed" value.
const SPEED_DEFAULT: f64 = -2.0;
/// A target this little above `GF_MAX_VER_DIST` [m] is still at it (rounding of AMSL altitudes).
const ALTITUDE_TOLERANCE_M: f64 = 1e-3;

/// The commander's answer to MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN: the runtime
/// carries out an allowed one.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum PowerDecision {
    /// Disarmed: go ahead.
    Allowed(PowerAction),
    /// Armed: refused (DENIED), with the reason.
    Refused(&'static str),
}

impl PowerDecision {
    /// The answer to the command (mapped to MAV_RESULT by the link).
    pub(super) fn outcome(self) -> CommandOutcome {
        match self {
            Self::Allowed(_) => CommandOutcome::Accepted,
            Self::Refused(why) => CommandOutcome::Denied(why),
        }
    }
}

/// Announce `text` and answer `outcome`: how a command is refused.
pub(super) fn refuse(
    say: &mut Announcements,
    severity: Severity,
    text: &str,
    outcome: CommandOutcome,
) -> CommandOutcome {
    say.announce(severity, text);
    outcome
}

/// The arming state and the decisions that rest on it.
#[derive(Clone, Debug, Default)]
pub(super) struct Commander {
    armed: bool,
    /// When it was armed [s].
    armed_at_s: f64,
    /// Left the ground since arming.
    took_off: bool,
    /// When the land detector last said landed [s].
    landed_at_s: f64,
}

impl Commander {
    /// Armed.
    pub(super) fn armed(&self) -> bool {
        self.armed
    }

    /// Arm at `now_s` [s] unless a prearm check fails (`prearm`: the first
    /// failing one) and `force` does not skip them; announced either way.
    /// Already armed: accepted, nothing changes.
    pub(super) fn arm(
        &mut self,
        force: bool,
        prearm: Option<&'static str>,
        now_s: f64,
        landed: bool,
        say: &mut Announcements,
    ) -> CommandOutcome {
        if self.armed {
            return CommandOutcome::Accepted;
        }
        if !force && let Some(why) = prearm {
            return refuse(
                say,
                Severity::Critical,
                &format!("Arming denied: {why}"),
                CommandOutcome::TemporarilyRejected(why),
            );
        }
        self.armed = true;
        self.armed_at_s = now_s;
        self.took_off = !landed;
        say.announce(Severity::Info, "Armed by external command");
        CommandOutcome::Accepted
    }

    /// A disarm request: the answer when it does not disarm (already
    /// disarmed: accepted; in the air unless forced: refused, announced), or
    /// `None` when the vehicle is to be disarmed ([`Self::disarmed`]).
    pub(super) fn disarm_refusal(&self, force: bool, landed: bool, say: &mut Announcements) -> Option<CommandOutcome> {
        if !self.armed {
            return Some(CommandOutcome::Accepted);
        }
        if !force && !landed {
            return Some(refuse(
                say,
                Severity::Critical,
                "Disarming denied: not landed",
                CommandOutcome::TemporarilyRejected("vehicle in the air"),
            ));
        }
        None
    }

    /// Disarmed, announced with `text`.
    pub(super) fn disarmed(&mut self, text: &str, say: &mut Announcements) {
        self.armed = false;
        say.announce(Severity::Info, text);
    }

    /// `what` needs the vehicle armed: the refusal (announced), or `None` when armed.
    pub(super) fn refuse_unless_armed(&self, what: &str, say: &mut Announcements) -> Option<CommandOutcome> {
        (!self.armed).then(|| {
            refuse(
                say,
                Severity::Critical,
                &format!("{what} denied: vehicle not armed"),
                CommandOutcome::TemporarilyRejected("vehicle not armed"),
            )
        })
    }

    /// The land detector's change at `now_s` [s]: a takeoff armed is
    /// remembered and announced, a landing timed (and announced armed).
    pub(super) fn land_event(&mut self, event: Option<LandEvent>, now_s: f64, say: &mut Announcements) {
        match event {
            Some(LandEvent::TookOff) if self.armed => {
                self.took_off = true;
                say.announce(Severity::Info, "Takeoff detected");
            }
            Some(LandEvent::Landed) => {
                self.landed_at_s = now_s;
                if self.armed {
                    say.announce(Severity::Info, "Landing detected");
                }
            }
            Some(LandEvent::TookOff) | None => {}
        }
    }

    /// The preflight auto-disarm (`COM_DISARM_PRFLT` = `duration_s`, 0 off):
    /// armed, landed and not taken off since arming, it runs from arming.
    pub(super) fn preflight_disarm_timer(&self, landed: bool, duration_s: f64) -> Option<PendingTimer> {
        (self.armed && landed && !self.took_off && duration_s > 0.0).then_some(PendingTimer {
            timer: ClientTimer::PreflightDisarm,
            started_s: self.armed_at_s,
            duration_s,
        })
    }

    /// Whether the disarm after a landing (`COM_DISARM_LAND` = `after_s`,
    /// 0 off) is due at `now_s` [s]: armed, landed after a takeoff for
    /// `after_s`, and no takeoff under way.
    pub(super) fn landing_disarm_due(&self, now_s: f64, landed: bool, taking_off: bool, after_s: f64) -> bool {
        self.armed
            && landed
            && self.took_off
            && after_s > 0.0
            && !taking_off
            && now_s - self.landed_at_s >= after_s - TIME_EPS
    }

    /// Reboot or shutdown: allowed disarmed, refused (announced) armed.
    pub(super) fn power(&self, action: PowerAction, say: &mut Announcements) -> PowerDecision {
        if !self.armed {
            return PowerDecision::Allowed(action);
        }
        let (text, why) = match action {
            PowerAction::Reboot => ("Reboot denied: disarm first", "disarm before reboot"),
            PowerAction::Shutdown => ("Shutdown denied: disarm first", "disarm before shutdown"),
        };
        say.announce(Severity::Critical, text);
        PowerDecision::Refused(why)
    }

    /// MAV_CMD_INJECT_FAILURE: accepted with `SYS_FAILURE_EN` (`enabled`),
    /// else denied (announced); the world carries it out.
    pub(super) fn failure_injection(enabled: bool, say: &mut Announcements) -> CommandOutcome {
        if enabled {
            CommandOutcome::Accepted
        } else {
            refuse(
                say,
                Severity::Warning,
                "Failure injection disabled (SYS_FAILURE_EN)",
                CommandOutcome::Denied("failure injection disabled (SYS_FAILURE_EN)"),
            )
        }
    }
}

impl Autopilot {
    /// Carry out a command at the instant of `readings`. Accepted commands
    /// take effect from the next [`Self::step`]; refusals leave everything as
    /// it was and, for arming, takeoff, mode changes, reboot and failure
    /// injection, queue a STATUSTEXT saying why.
    ///
    /// | command | refused |
    /// |---|---|
    /// | `Arm` | TemporarilyRejected when a prearm check fails (not landed, estimator not initialised, home invalid, mode not armable: Offboard without fresh setpoints); `force` skips the checks |
    /// | `Disarm` | TemporarilyRejected in the air unless forced (forced: rotors stop, the vehicle falls) |
    /// | `Takeoff` | Denied for a non-finite altitude, one above `GF_MAX_VER_DIST` or an AMSL altitude above `RP_ALT_MAX_AMSL`; TemporarilyRejected when disarmed |
    /// | `Land`, `ReturnToLaunch` | TemporarilyRejected when disarmed |
    /// | `SetMode` | Takeoff, Land, RTL as above; Offboard TemporarilyRejected without a fresh setpoint (COM_OF_LOSS_T, on the client clock); Mission TemporarilyRejected without a mission |
    /// | `StartMission` | Denied without a mission or with a first item beyond it; TemporarilyRejected when arming is (it arms) |
    /// | `SetMissionCurrent` | Denied beyond the mission |
    /// | `Reposition` | Denied for non-finite parts, lat/lon out of range, or an AMSL altitude above `RP_ALT_MAX_AMSL`; TemporarilyRejected when disarmed; a target outside the geofence (zones, `GF_MAX_HOR_DIST`, `GF_MAX_VER_DIST`) is Accepted, announced ("Reposition is outside geofence") and ignored, the vehicle holding where it is (PX4) |
    /// | `Orbit` | Denied for non-finite parts, lat/lon out of range, an AMSL altitude above `RP_ALT_MAX_AMSL`, or a radius outside `[1, 1000]` m ("Orbit radius limit exceeded", PX4's `MC_ORBIT_RAD_MAX`); TemporarilyRejected without a valid position. Accepted disarmed too (the mode is selected; it cannot be armed in) |
    /// | `ChangeSpeed` | Denied when not finite |
    /// | `SetHome` | Denied for an invalid point |
    /// | `Offboard` | Denied when a given part is not finite, or nothing is given; a position above `GF_MAX_VER_DIST` is clamped to it (announced once) |
    /// | `ManualControl` | Denied when a stick is not finite or beyond `[-1, 1]` |
    /// | `FollowTarget` | Denied when not finite or off the globe; kept in any mode |
    /// | `SetMode` FollowTarget | TemporarilyRejected without a valid position; accepted disarmed (not armable) |
    /// | `SetMode` to a manual mode | TemporarilyRejected without fresh sticks (`COM_RC_LOSS_T`, client clock), Position also without a valid position |
    /// | anything that needs a position (Hold, Takeoff, RTL, Mission, Reposition) | TemporarilyRejected without a valid position; Land then descends without position |
    /// | `Power` | Denied when armed |
    /// | `InjectFailure` | Denied while `SYS_FAILURE_EN` = 0 |
    ///
    /// Disarmed, Hold is accepted with a valid position. Selecting the active
    /// mode again is accepted and changes nothing.
    ///
    /// A mode the pilot selects ends the failsafe in force (PX4's user
    /// takeover: a Hold, Return, Land or Descend failsafe allows a mode
    /// switch), unless the command itself started a failsafe (Land without
    /// a fix). While the cause of the failsafe taken over lasts, it is
    /// remembered: the next failsafe, a lost position's Descend included,
    /// ends the takeover and the more severe action is in force (PX4's
    /// `FailsafeBase::checkFailsafe` and `getSelectedAction`). A failsafe
    /// holding before its Return or Land (`COM_FAIL_ACT_T`) is taken over
    /// the same way, also by selecting Hold or by a reposition that changes
    /// the mode: its action is not carried out.
    pub fn command(&mut self, cmd: AutopilotCommand, readings: &SensorReadings) -> CommandOutcome {
        let mode = self.navigator.mode();
        // while a failsafe holds before it acts, selecting a mode takes over
        // even when it is Hold, the mode flown, and so does a reposition
        // (PX4: the user's intended mode changed)
        let takes_over_the_delay = self.failsafe_delayed()
            && matches!(cmd, AutopilotCommand::SetMode(_) | AutopilotCommand::Reposition { .. });
        let held = self.in_failsafe.take();
        let outcome = self.dispatch(cmd, readings);
        let took_over = outcome == CommandOutcome::Accepted && (self.navigator.mode() != mode || takes_over_the_delay);
        if took_over {
            self.end_failsafe_delay();
            if let Some(f) = held
                && f.action.is_some()
                && self.failsafe_cause_lasts(&f.cause)
            {
                self.taken_over = Some(f);
            }
        } else if self.in_failsafe.is_none() {
            self.in_failsafe = held;
        }
        outcome
    }

    fn dispatch(&mut self, cmd: AutopilotCommand, readings: &SensorReadings) -> CommandOutcome {
        let readings = self.navigated(readings);
        let readings = &*readings;
        let m = &readings.measurement;
        self.now_s = m.time_s;
        match cmd {
            AutopilotCommand::Arm { force } => self.arm(force, m),
            AutopilotCommand::Disarm { force } => self.disarm(force),
            AutopilotCommand::RunPrearmChecks => self.run_prearm_checks(m),
            AutopilotCommand::Takeoff { altitude_amsl_m } => self.takeoff(altitude_amsl_m, m),
            AutopilotCommand::Land => self.land(m),
            AutopilotCommand::ReturnToLaunch => self.return_to_launch(m),
            AutopilotCommand::SetMode(mode) => self.set_mode(mode, m),
            AutopilotCommand::StartMission { first } => self.start_mission(first, m),
            AutopilotCommand::SetMissionCurrent { seq } => self.set_mission_current(seq),
            AutopilotCommand::Reposition {
                lat_deg,
                lon_deg,
                alt_amsl_m,
                yaw_rad,
                speed_m_s,
            } => self.reposition([lat_deg, lon_deg, alt_amsl_m], yaw_rad, speed_m_s, m),
            AutopilotCommand::RepositionInHold {
                lat_deg,
                lon_deg,
                alt_amsl_m,
                yaw_rad,
                speed_m_s,
            } => {
                if !self.land.landed() && matches!(self.navigator.nav(), Nav::Hold { .. }) {
                    // the navigator's answer is the flight; the command's is PX4's commander's
                    let _ = self.reposition([lat_deg, lon_deg, alt_amsl_m], yaw_rad, speed_m_s, m);
                }
                CommandOutcome::Unsupported
            }
            AutopilotCommand::Orbit {
                radius_m,
                velocity_m_s,
                yaw,
                lat_deg,
                lon_deg,
                alt_amsl_m,
            } => self.orbit(radius_m, velocity_m_s, yaw, [lat_deg, lon_deg, alt_amsl_m], m),
            AutopilotCommand::ChangeSpeed { speed_m_s } => self.change_speed(speed_m_s),
            AutopilotCommand::SetHome(point) => self.set_home_to(point, m),
            AutopilotCommand::Offboard(sp) => self.offboard_setpoint(&sp, m),
            AutopilotCommand::ManualControl(sticks) => self.manual_control(sticks, m),
            AutopilotCommand::FollowTarget(fix) => self.follow_target(&fix, m),
            AutopilotCommand::Power(action) => self.commander.power(action, &mut self.say).outcome(),
            AutopilotCommand::InjectFailure { .. } => {
                Commander::failure_injection(self.settings.failure_injection, &mut self.say)
            }
        }
    }

    /// Refuse a command: announce `text`, answer `outcome`.
    pub(super) fn refuse(&mut self, severity: Severity, text: &str, outcome: CommandOutcome) -> CommandOutcome {
        refuse(&mut self.say, severity, text, outcome)
    }

    /// A takeoff to `z` [m, NED] above `GF_MAX_VER_DIST` is refused (DENIED,
    /// announced), never flown: the refusal, or `None` when it may go.
    fn refuse_takeoff_above_fence(&mut self, z: f64) -> Option<CommandOutcome> {
        let z_max = self.max_altitude_z()?;
        (z < z_max - ALTITUDE_TOLERANCE_M).then(|| {
            self.refuse(
                Severity::Critical,
                "Takeoff denied: above geofence max altitude",
                CommandOutcome::Denied("takeoff altitude above GF_MAX_VER_DIST"),
            )
        })
    }

    /// A target altitude AMSL [m] above `RP_ALT_MAX_AMSL` is refused
    /// (DENIED, announced): the refusal, or `None` when it may go.
    fn refuse_above_ceiling(&mut self, what: &str, altitude_amsl_m: Option<f64>) -> Option<CommandOutcome> {
        let max = self.settings.max_target_amsl_m;
        altitude_amsl_m.filter(|a| *a > max).map(|a| {
            self.refuse(
                Severity::Critical,
                &format!("{what} denied: {a:.0} m above RP_ALT_MAX_AMSL"),
                CommandOutcome::Denied("altitude above RP_ALT_MAX_AMSL"),
            )
        })
    }

    /// The gates of a command that flies to a point (`what`: Takeoff,
    /// Reposition), in order: an AMSL altitude above `RP_ALT_MAX_AMSL`
    /// (Denied), disarmed, no valid position (TemporarilyRejected); each announced.
    /// The refusal, or `None` when it may go.
    fn refuse_flight(&mut self, what: &str, altitude_amsl_m: Option<f64>) -> Option<CommandOutcome> {
        if let Some(refused) = self.refuse_above_ceiling(what, altitude_amsl_m) {
            return Some(refused);
        }
        if let Some(refused) = self.commander.refuse_unless_armed(what, &mut self.say) {
            return Some(refused);
        }
        self.refuse_without_position(what)
    }

    /// Why arming would be refused at the instant of `m`, if it would ([`Prearm::failure`]).
    pub(super) fn prearm_failure(&self, m: &Measurement) -> Option<&'static str> {
        self.prearm_in(self.navigator.mode(), m.time_s).failure()
    }

    /// Arm (prearm checks unless `force`), at the instant of `m`.
    pub(super) fn arm(&mut self, force: bool, m: &Measurement) -> CommandOutcome {
        let prearm = if self.commander.armed() {
            None
        } else {
            self.prearm_failure(m)
        };
        let landed = self.land.landed();
        self.commander.arm(force, prearm, m.time_s, landed, &mut self.say)
    }

    /// Run the arming checks now, as PX4's commander does on
    /// MAV_CMD_RUN_PREARM_CHECKS (a forced health report): the first that
    /// fails is said ("Preflight Fail: ..."), armed or not; accepted.
    fn run_prearm_checks(&mut self, m: &Measurement) -> CommandOutcome {
        if !self.commander.armed()
            && let Some(reason) = self.prearm_failure(m)
        {
            self.say
                .announce(Severity::Critical, format!("Preflight Fail: {reason}"));
        }
        CommandOutcome::Accepted
    }

    fn disarm(&mut self, force: bool) -> CommandOutcome {
        if let Some(answer) = self.commander.disarm_refusal(force, self.land.landed(), &mut self.say) {
            return answer;
        }
        self.disarm_now("Disarmed by external command");
        CommandOutcome::Accepted
    }

    /// Disarm: rotors stop, Hold (Position kept), the controller starts over.
    pub(super) fn disarm_now(&mut self, text: &str) {
        self.end_failsafe_delay();
        self.commander.disarmed(text, &mut self.say);
        self.navigator.disarmed();
        self.reset_controller();
    }

    /// Take off to `altitude_amsl_m` (None: home + MIS_TAKEOFF_ALT; lower
    /// targets raised to that; a vehicle already higher keeps its altitude).
    fn takeoff(&mut self, altitude_amsl_m: Option<f64>, m: &Measurement) -> CommandOutcome {
        if altitude_amsl_m.is_some_and(|a| !a.is_finite()) {
            return CommandOutcome::Denied("invalid takeoff altitude");
        }
        if let Some(refused) = self.refuse_flight("Takeoff", altitude_amsl_m) {
            return refused;
        }
        let home = self.home_ned();
        let min_alt = self.settings.takeoff_alt_m;
        let mut z = home.z - min_alt;
        if let Some(a) = altitude_amsl_m {
            let z_asked = self.origin.alt_amsl_m - a;
            if z_asked > z {
                self.say.announce(
                    Severity::Info,
                    format!("Using minimum takeoff altitude: {min_alt:.2} m"),
                );
            } else {
                z = z_asked;
            }
        }
        let here = self.navigator.current_position(m);
        self.start_takeoff(&here, z.min(here.z), home.z, None)
    }

    /// Climb from `here` [m, NED] to NED z `z` [m] (home at NED z `home_z`),
    /// then hold (at `then`, a reposition given on the ground); refused
    /// above `GF_MAX_VER_DIST`, else announced.
    fn start_takeoff(&mut self, here: &Vector3<f64>, z: f64, home_z: f64, then: Option<HoldTarget>) -> CommandOutcome {
        if let Some(refused) = self.refuse_takeoff_above_fence(z) {
            return refused;
        }
        self.navigator.enter_takeoff(Vector3::new(here.x, here.y, z), then);
        self.say
            .announce(Severity::Info, format!("Takeoff to {:.1} m above home", home_z - z));
        CommandOutcome::Accepted
    }

    fn land(&mut self, m: &Measurement) -> CommandOutcome {
        if let Some(refused) = self.commander.refuse_unless_armed("Land", &mut self.say) {
            return refused;
        }
        let position = self.navigator.position();
        if !position.serves(PositionNeed::Relaxed) {
            if !matches!(self.navigator.nav(), Nav::Descend { .. }) {
                // a landing asked for: the position back keeps landing
                self.navigator.enter_descend(super::navigator::DescendThen::Land);
                self.enter_blind_failsafe();
                self.say.announce(
                    Severity::Critical,
                    format!("{}: descending without position", position.loss.lost()),
                );
            }
            return CommandOutcome::Accepted;
        }
        if !matches!(self.navigator.nav(), Nav::Land { .. }) {
            let landed = self.land.landed();
            self.navigator.enter_land(m, landed, &mut self.say);
        }
        CommandOutcome::Accepted
    }

    fn return_to_launch(&mut self, m: &Measurement) -> CommandOutcome {
        if let Some(refused) = self.commander.refuse_unless_armed("Return", &mut self.say) {
            return refused;
        }
        if let Some(refused) = self.refuse_without_position("Return") {
            return refused;
        }
        if !matches!(self.navigator.nav(), Nav::Rtl { .. }) {
            let cx = situation!(self, m);
            self.navigator.enter_rtl(&cx, &mut self.say);
        }
        CommandOutcome::Accepted
    }

    fn set_mode(&mut self, mode: FlightMode, m: &Measurement) -> CommandOutcome {
        if mode == self.navigator.mode() {
            return CommandOutcome::Accepted;
        }
        match mode {
            FlightMode::Hold | FlightMode::Mission => {
                if let Some(refused) = self.refuse_without_position(&format!("Switching to {mode:?}")) {
                    return refused;
                }
                if mode == FlightMode::Mission {
                    return self.enter_mission();
                }
                self.navigator.enter_hold();
                CommandOutcome::Accepted
            }
            FlightMode::Descend => self.land(m),
            FlightMode::Orbit => {
                if let Some(refused) = self.refuse_without_position("Switching to Orbit") {
                    return refused;
                }
                let cx = situation!(self, m);
                self.navigator.enter_orbit(&cx);
                CommandOutcome::Accepted
            }
            FlightMode::FollowTarget => {
                if let Some(refused) = self.refuse_without_position("Switching to Follow Target") {
                    return refused;
                }
                let cx = situation!(self, m);
                self.navigator.enter_follow(&cx);
                CommandOutcome::Accepted
            }
            FlightMode::Position => self.enter_manual_mode(ManualMode::Position, m),
            FlightMode::Altitude => self.enter_manual_mode(ManualMode::Altitude, m),
            FlightMode::Stabilized => self.enter_manual_mode(ManualMode::Stabilized, m),
            FlightMode::Acro => self.enter_manual_mode(ManualMode::Acro, m),
            FlightMode::Manual => self.enter_manual_mode(ManualMode::Manual, m),
            FlightMode::Takeoff => self.takeoff(None, m),
            FlightMode::Land => self.land(m),
            FlightMode::ReturnToLaunch => self.return_to_launch(m),
            FlightMode::Offboard => {
                if self.offboard_fresh(m.time_s) {
                    if let Some(refused) = self.refuse_without(self.navigator.offboard_need(), "Switching to Offboard")
                    {
                        return refused;
                    }
                    self.navigator.enter_offboard();
                    CommandOutcome::Accepted
                } else {
                    self.refuse(
                        Severity::Critical,
                        "Switching to Offboard denied: no offboard signal",
                        CommandOutcome::TemporarilyRejected("no offboard signal"),
                    )
                }
            }
        }
    }

    /// DO_REPOSITION: fly to `[lat, lon, alt AMSL]` in Hold; `None` parts keep
    /// the current value. On the ground (armed) it takes off first, to at
    /// least MIS_TAKEOFF_ALT, as PX4 does.
    fn reposition(
        &mut self,
        [lat_deg, lon_deg, alt_amsl_m]: [Option<f64>; 3],
        yaw_rad: Option<f64>,
        speed_m_s: Option<f64>,
        m: &Measurement,
    ) -> CommandOutcome {
        let parts = [lat_deg, lon_deg, alt_amsl_m, yaw_rad, speed_m_s];
        if parts.iter().flatten().any(|x| !x.is_finite()) {
            return CommandOutcome::Denied("invalid reposition value");
        }
        if lat_deg.is_some_and(|l| l.abs() > 90.0) || lon_deg.is_some_and(|l| l.abs() > 180.0) {
            return self.refuse(
                Severity::Critical,
                "Reposition denied: latitude/longitude out of range",
                CommandOutcome::Denied("invalid reposition position"),
            );
        }
        if let Some(refused) = self.refuse_flight("Reposition", alt_amsl_m) {
            return refused;
        }
        let here = self.navigator.current_position(m);
        let here_geo = self.origin.offset(&here);
        let point = GeoPoint {
            lat_deg: lat_deg.unwrap_or(here_geo.lat_deg),
            lon_deg: lon_deg.unwrap_or(here_geo.lon_deg),
            alt_amsl_m: alt_amsl_m.unwrap_or(here_geo.alt_amsl_m),
        };
        let mut target = point.ned_from(&self.origin);
        // keep the unchanged parts exact (no round trip through degrees)
        if lat_deg.is_none() && lon_deg.is_none() {
            target.x = here.x;
            target.y = here.y;
        }
        if alt_amsl_m.is_none() {
            target.z = here.z;
        }
        if self.outside_geofence(&target) {
            // PX4: the commander accepts DO_REPOSITION and switches to Hold;
            // the navigator ignores a target outside the fence
            // (navigator_main.cpp), so the vehicle stays where it is.
            self.say.announce(Severity::Critical, "Reposition is outside geofence");
            if !self.land.landed() && !matches!(self.navigator.nav(), Nav::Hold { .. }) {
                self.navigator.enter_hold();
            }
            return CommandOutcome::Accepted;
        }
        let hold = HoldTarget {
            position_ned: target,
            yaw_rad,
            speed_m_s: speed_m_s
                .filter(|s| *s > 0.0)
                .map(|s| s.min(self.settings.xy_vel_max_m_s)),
        };
        if self.land.landed() {
            let home = self.home_ned();
            let z = target.z.min(home.z - self.settings.takeoff_alt_m).min(here.z);
            return self.start_takeoff(&here, z, home.z, Some(hold));
        }
        self.navigator.enter_hold_at(hold);
        CommandOutcome::Accepted
    }

    /// DO_ORBIT: switch to Orbit and circle as asked (`None` parts keep the
    /// orbit's current value; PX4's placeholder when another mode flew).
    fn orbit(
        &mut self,
        radius_m: Option<f64>,
        velocity_m_s: Option<f64>,
        yaw: Option<super::OrbitYaw>,
        [lat_deg, lon_deg, alt_amsl_m]: [Option<f64>; 3],
        m: &Measurement,
    ) -> CommandOutcome {
        let parts = [radius_m, velocity_m_s, lat_deg, lon_deg, alt_amsl_m];
        if parts.iter().flatten().any(|x| !x.is_finite()) {
            return CommandOutcome::Denied("invalid orbit value");
        }
        if lat_deg.is_some_and(|l| l.abs() > 90.0) || lon_deg.is_some_and(|l| l.abs() > 180.0) {
            return self.refuse(
                Severity::Critical,
                "Orbit denied: latitude/longitude out of range",
                CommandOutcome::Denied("invalid orbit centre"),
            );
        }
        if let Some(refused) = self.refuse_above_ceiling("Orbit", alt_amsl_m) {
            return refused;
        }
        if let Some(refused) = self.refuse_without_position("Orbit") {
            return refused;
        }
        let centre_xy = lat_deg.zip(lon_deg).map(|(lat_deg, lon_deg)| {
            let c = GeoPoint {
                lat_deg,
                lon_deg,
                alt_amsl_m: self.origin.alt_amsl_m,
            }
            .ned_from(&self.origin);
            [c.x, c.y]
        });
        let change = OrbitChange {
            radius_m,
            velocity_m_s,
            yaw,
            centre_xy,
            z: alt_amsl_m.map(|a| self.origin.alt_amsl_m - a),
        };
        let cx = situation!(self, m);
        if self.navigator.command_orbit(&cx, &change) {
            CommandOutcome::Accepted
        } else {
            self.refuse(
                Severity::Critical,
                "Orbit radius limit exceeded",
                CommandOutcome::Denied("orbit radius out of range"),
            )
        }
    }

    /// DO_CHANGE_SPEED: a positive speed becomes the cruise speed (capped at
    /// MPC_XY_VEL_MAX), -2 restores MPC_XY_CRUISE, other values change nothing.
    fn change_speed(&mut self, speed_m_s: f64) -> CommandOutcome {
        if !speed_m_s.is_finite() {
            return CommandOutcome::Denied("invalid speed");
        }
        if speed_m_s == SPEED_DEFAULT {
            self.navigator.set_cruise(None);
        } else if speed_m_s > 0.0 {
            self.navigator
                .set_cruise(Some(speed_m_s.min(self.settings.xy_vel_max_m_s)));
        }
        CommandOutcome::Accepted
    }

    /// Home here (on the ground: the ground under the vehicle) or at `point`.
    pub(super) fn set_home_to(&mut self, point: Option<GeoPoint>, m: &Measurement) -> CommandOutcome {
        let home = match point {
            Some(p) if p.is_valid() => p,
            Some(_) => return CommandOutcome::Denied("invalid home position"),
            None => {
                // on the ground: where the vehicle rests (relative altitude 0), as PX4
                let mut p = m.position_ned;
                if self.land.landed() {
                    p.z = self.land.rest_z(m);
                }
                self.origin.offset(&p)
            }
        };
        self.set_home(home);
        CommandOutcome::Accepted
    }

    fn offboard_setpoint(&mut self, sp: &OffboardSetpoint, m: &Measurement) -> CommandOutcome {
        let mut local = sp.resolve(m, &self.origin, &self.home);
        if !sp.position_in_range() || !local.is_valid() {
            return CommandOutcome::Denied("invalid offboard setpoint");
        }
        // AMSL = origin altitude - NED z; a stream of setpoints gets no text
        if local
            .position_z()
            .is_some_and(|z| self.origin.alt_amsl_m - z > self.settings.max_target_amsl_m)
        {
            return CommandOutcome::Denied("offboard setpoint above RP_ALT_MAX_AMSL");
        }
        if let Some(z_max) = self.max_altitude_z() {
            let clamped = local.clamp_position_z(z_max);
            self.offboard_clamped(clamped);
        }
        self.navigator.set_offboard(local, m.time_s);
        CommandOutcome::Accepted
    }

    /// A FOLLOW_TARGET fix at the instant of `m`, resolved to NED.
    fn follow_target(&mut self, fix: &TargetFix, m: &Measurement) -> CommandOutcome {
        if !fix.is_valid() {
            return CommandOutcome::Denied("invalid follow target");
        }
        let point = GeoPoint {
            lat_deg: fix.lat_deg,
            lon_deg: fix.lon_deg,
            alt_amsl_m: fix.alt_amsl_m,
        };
        let ned = point.ned_from(&self.origin);
        self.navigator.set_follow_target(ned, fix.velocity_ned, m.time_s);
        CommandOutcome::Accepted
    }

    /// New sticks at the instant of `m`.
    pub(super) fn manual_control(&mut self, sticks: ManualControl, m: &Measurement) -> CommandOutcome {
        if !sticks.is_valid() {
            return CommandOutcome::Denied("invalid manual control");
        }
        self.navigator.set_manual(sticks, m.time_s);
        CommandOutcome::Accepted
    }

    /// Switch to a manual mode: refused without fresh sticks (PX4: "No
    /// manual control input"), and Position without a valid position.
    pub(super) fn enter_manual_mode(&mut self, mode: ManualMode, m: &Measurement) -> CommandOutcome {
        let fresh = self
            .navigator
            .manual_fresh(m.time_s, self.settings.manual.loss_s, self.failsafe.clock());
        if !fresh {
            let text = format!("Switching to {} denied: no manual control", mode.name());
            return self.refuse(
                Severity::Critical,
                &text,
                CommandOutcome::TemporarilyRejected("no manual control input"),
            );
        }
        if mode == ManualMode::Position
            && let Some(refused) = self.refuse_without(PositionNeed::Relaxed, "Switching to Position")
        {
            return refused;
        }
        self.navigator.enter_manual(mode);
        CommandOutcome::Accepted
    }

    /// Refuse `what` (an autonomous mode) while the position is lost.
    pub(super) fn refuse_without_position(&mut self, what: &str) -> Option<CommandOutcome> {
        self.refuse_without(PositionNeed::Accurate, what)
    }

    /// Refuse `what`, which needs `need` of the position, while that is not valid.
    fn refuse_without(&mut self, need: PositionNeed, what: &str) -> Option<CommandOutcome> {
        let position = self.navigator.position();
        (!position.serves(need)).then(|| {
            self.refuse(
                Severity::Critical,
                &format!("{what} denied: {}", position.loss.cause()),
                CommandOutcome::TemporarilyRejected("no position estimate"),
            )
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn texts(say: &mut Announcements) -> Vec<String> {
        say.drain().into_iter().map(|s| s.text).collect()
    }

    #[test]
    fn arming_is_denied_with_the_reason_unless_forced() {
        let mut c = Commander::default();
        let mut say = Announcements::default();
        let out = c.arm(false, Some("no GPS fix"), 1.0, true, &mut say);
        assert_eq!(out, CommandOutcome::TemporarilyRejected("no GPS fix"));
        assert!(!c.armed());
        assert_eq!(texts(&mut say), ["Arming denied: no GPS fix"]);
        assert_eq!(
            c.arm(true, Some("no GPS fix"), 1.0, true, &mut say),
            CommandOutcome::Accepted
        );
        assert!(c.armed());
        assert_eq!(texts(&mut say), ["Armed by external command"]);
        // armed again: accepted, nothing said
        assert_eq!(
            c.arm(false, Some("vehicle not landed"), 2.0, true, &mut say),
            CommandOutcome::Accepted
        );
        assert!(texts(&mut say).is_empty());
    }

    #[test]
    fn disarming_is_refused_in_the_air_unless_forced() {
        let mut c = Commander::default();
        let mut say = Announcements::default();
        assert_eq!(c.disarm_refusal(false, false, &mut say), Some(CommandOutcome::Accepted));
        c.arm(false, None, 0.0, true, &mut say);
        say.drain();
        assert_eq!(
            c.disarm_refusal(false, false, &mut say),
            Some(CommandOutcome::TemporarilyRejected("vehicle in the air"))
        );
        assert_eq!(texts(&mut say), ["Disarming denied: not landed"]);
        assert_eq!(c.disarm_refusal(true, false, &mut say), None);
        assert_eq!(c.disarm_refusal(false, true, &mut say), None);
        c.disarmed("Disarmed by external command", &mut say);
        assert!(!c.armed());
        assert_eq!(texts(&mut say), ["Disarmed by external command"]);
    }

    #[test]
    fn takeoff_land_and_return_need_the_vehicle_armed() {
        let mut c = Commander::default();
        let mut say = Announcements::default();
        assert_eq!(
            c.refuse_unless_armed("Takeoff", &mut say),
            Some(CommandOutcome::TemporarilyRejected("vehicle not armed"))
        );
        assert_eq!(texts(&mut say), ["Takeoff denied: vehicle not armed"]);
        c.arm(false, None, 0.0, true, &mut say);
        assert_eq!(c.refuse_unless_armed("Return", &mut say), None);
    }

    #[test]
    fn reboot_and_shutdown_only_disarmed() {
        let mut c = Commander::default();
        let mut say = Announcements::default();
        let d = c.power(PowerAction::Reboot, &mut say);
        assert_eq!(d, PowerDecision::Allowed(PowerAction::Reboot));
        assert_eq!(d.outcome(), CommandOutcome::Accepted);
        assert!(texts(&mut say).is_empty());
        c.arm(false, None, 0.0, true, &mut say);
        say.drain();
        let d = c.power(PowerAction::Shutdown, &mut say);
        assert_eq!(d, PowerDecision::Refused("disarm before shutdown"));
        assert_eq!(d.outcome(), CommandOutcome::Denied("disarm before shutdown"));
        assert_eq!(texts(&mut say), ["Shutdown denied: disarm first"]);
    }

    #[test]
    fn failure_injection_needs_sys_failure_en() {
        let mut say = Announcements::default();
        assert_eq!(Commander::failure_injection(true, &mut say), CommandOutcome::Accepted);
        assert!(matches!(
            Commander::failure_injection(false, &mut say),
            CommandOutcome::Denied(_)
        ));
        assert_eq!(texts(&mut say), ["Failure injection disabled (SYS_FAILURE_EN)"]);
    }

    #[test]
    fn auto_disarm_before_takeoff_and_after_landing() {
        let mut c = Commander::default();
        let mut say = Announcements::default();
        assert_eq!(c.preflight_disarm_timer(true, 10.0), None);
        c.arm(false, None, 2.0, true, &mut say);
        let t = c.preflight_disarm_timer(true, 10.0).expect("armed on the ground");
        assert_eq!(
            (t.timer, t.started_s, t.duration_s),
            (ClientTimer::PreflightDisarm, 2.0, 10.0)
        );
        assert_eq!(c.preflight_disarm_timer(true, 0.0), None, "0 disables it");
        say.drain();
        c.land_event(Some(LandEvent::TookOff), 3.0, &mut say);
        assert_eq!(texts(&mut say), ["Takeoff detected"]);
        assert_eq!(c.preflight_disarm_timer(true, 10.0), None, "taken off");
        assert!(!c.landing_disarm_due(30.0, false, false, 2.0), "in the air");
        c.land_event(Some(LandEvent::Landed), 20.0, &mut say);
        assert_eq!(texts(&mut say), ["Landing detected"]);
        assert!(!c.landing_disarm_due(21.9, true, false, 2.0));
        assert!(c.landing_disarm_due(22.0, true, false, 2.0));
        assert!(!c.landing_disarm_due(22.0, true, true, 2.0), "a takeoff under way");
        assert!(!c.landing_disarm_due(22.0, true, false, 0.0), "0 disables it");
    }

    #[test]
    fn a_takeoff_disarmed_is_not_remembered() {
        let mut c = Commander::default();
        let mut say = Announcements::default();
        c.land_event(Some(LandEvent::TookOff), 1.0, &mut say);
        c.land_event(Some(LandEvent::Landed), 2.0, &mut say);
        assert!(texts(&mut say).is_empty());
        // armed in the air: taken off at arming
        c.arm(true, None, 3.0, false, &mut say);
        assert_eq!(c.preflight_disarm_timer(true, 10.0), None);
    }
}
