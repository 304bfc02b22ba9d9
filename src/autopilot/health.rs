//! The health and arming report: every arming check that fails now, for
//! every mode at once, as PX4's commander reports it to ground stations
//! (its health and arming checks: each failing check names the modes it
//! keeps from arming and the component it concerns; a summary says, per
//! mode, whether arming in it, or switching to it while armed, is
//! possible). The report's types; `prearm` runs the checks.

use super::FlightMode;

/// Every text a failing check can give ([`FailedCheck::text`]), in PX4's
/// order: what a ground station's event metadata must know.
pub const CHECK_TEXTS: [&str; 14] = [
    "vehicle not landed",
    "no valid position estimate",
    "estimator not initialised",
    "home position invalid",
    "no GPS fix",
    "ESC failure",
    "battery critical",
    "no ground station connection",
    "no manual control input",
    "throttle above center",
    "high throttle",
    "no offboard signal",
    "no valid mission",
    "flight mode not armable",
];

/// What a check concerns (PX4's health components, the ones rotorpilot's checks speak of).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HealthComponent {
    /// No component in particular (the vehicle, the mode).
    None,
    /// The GNSS receiver.
    Gps,
    /// Manual control (RC or joystick).
    RemoteControl,
    /// Motors and ESCs.
    MotorsEscs,
    /// The battery.
    Battery,
    /// The data link to the ground station.
    CommunicationLinks,
    /// The mission.
    Mission,
    /// The attitude estimate.
    AttitudeEstimate,
    /// The local position estimate.
    LocalPositionEstimate,
    /// The global position estimate (and home).
    GlobalPositionEstimate,
}

impl HealthComponent {
    /// Whether a failure of it is a fault of the vehicle (not the sticks or
    /// the mission a mode lacks, nor no component at all).
    #[must_use]
    pub fn is_health(self) -> bool {
        !matches!(self, Self::None | Self::RemoteControl | Self::Mission)
    }
}

/// A set of [`FlightMode`]s (one bit each, by [`FlightMode::ALL`] index).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ModeSet(u16);

impl ModeSet {
    /// Every mode.
    pub const ALL: Self = Self((1 << FlightMode::ALL.len()) - 1);

    /// Just `mode`.
    #[must_use]
    pub fn of(mode: FlightMode) -> Self {
        Self(1 << mode.index())
    }

    /// Whether `mode` is in the set.
    #[must_use]
    pub fn contains(self, mode: FlightMode) -> bool {
        self.0 & Self::of(mode).0 != 0
    }

    /// The set with `mode` added.
    #[must_use]
    pub fn with(self, mode: FlightMode) -> Self {
        Self(self.0 | Self::of(mode).0)
    }

    /// The modes in the set, in [`FlightMode::ALL`] order.
    pub fn iter(self) -> impl Iterator<Item = FlightMode> {
        FlightMode::ALL.into_iter().filter(move |m| self.contains(*m))
    }
}

/// One check that fails.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FailedCheck {
    /// Why, in the words arming is denied with ("no GPS fix", "battery critical", ...).
    pub text: &'static str,
    /// What it concerns.
    pub component: HealthComponent,
    /// The modes it keeps from arming.
    pub modes: ModeSet,
}

/// The health and arming report at one instant.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct HealthReport {
    /// Every failing check, in PX4's order (a check failing several modes once).
    pub checks: Vec<FailedCheck>,
    /// The modes arming is possible in.
    pub can_arm: ModeSet,
    /// The modes that can be switched to while armed.
    pub can_run: ModeSet,
}

impl HealthReport {
    /// The parts of the vehicle whose health fails (a sensor, the motors,
    /// the battery, the data link, an estimate), each once: not the sticks
    /// or the mission a mode lacks.
    pub fn health_errors(&self) -> impl Iterator<Item = HealthComponent> + '_ {
        let mut seen = Vec::new();
        self.checks.iter().map(|c| c.component).filter(move |c| {
            let new = c.is_health() && !seen.contains(c);
            seen.push(*c);
            new
        })
    }

    /// Add `mode` to the modes the check `text` fails (the check added the first time).
    pub(super) fn fail(&mut self, text: &'static str, component: HealthComponent, mode: FlightMode) {
        match self.checks.iter_mut().find(|c| c.text == text) {
            Some(c) => c.modes = c.modes.with(mode),
            None => self.checks.push(FailedCheck {
                text,
                component,
                modes: ModeSet::of(mode),
            }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_mode_set_holds_what_was_added() {
        let s = ModeSet::default().with(FlightMode::Mission).with(FlightMode::Hold);
        assert!(s.contains(FlightMode::Mission) && s.contains(FlightMode::Hold));
        assert!(!s.contains(FlightMode::Offboard));
        assert_eq!(s.iter().collect::<Vec<_>>(), [FlightMode::Hold, FlightMode::Mission]);
        assert!(FlightMode::ALL.iter().all(|m| ModeSet::ALL.contains(*m)));
    }

    #[test]
    fn a_check_failing_several_modes_is_listed_once() {
        let mut r = HealthReport::default();
        r.fail("no GPS fix", HealthComponent::Gps, FlightMode::Hold);
        r.fail("battery critical", HealthComponent::Battery, FlightMode::Hold);
        r.fail("no GPS fix", HealthComponent::Gps, FlightMode::Mission);
        assert_eq!(r.checks.len(), 2);
        assert_eq!(
            r.checks[0].modes,
            ModeSet::of(FlightMode::Hold).with(FlightMode::Mission)
        );
        let errors: Vec<_> = r.health_errors().collect();
        assert_eq!(errors, [HealthComponent::Gps, HealthComponent::Battery]);
        r.fail("no valid mission", HealthComponent::Mission, FlightMode::Mission);
        assert_eq!(
            r.health_errors().count(),
            2,
            "a mode's mission is no fault of the vehicle"
        );
    }
}
