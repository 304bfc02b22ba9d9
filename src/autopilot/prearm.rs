//! The prearm checks, in PX4's order, for any mode: what arming in the
//! selected mode is refused with (the first that fails) and the health and
//! arming report ([`HealthReport`]: all of them, for every mode at once).
//!
//! The global checks (landed, position estimate, estimator, home, rotors,
//! battery, data link) fail every mode; the position check fails the modes
//! whose [`PositionNeed`](super::position_checks::PositionNeed) the
//! position does not serve; the mode's own check (sticks, offboard signal,
//! a mission, an armable mode) fails that mode. Queries: they change nothing.

use super::health::{HealthComponent, HealthReport};
use super::navigator::ManualMode;
use super::settings::FailsafeAction;
use super::{Autopilot, BatteryWarning, FlightMode, RotorStatus};

/// What the prearm checks look at, gathered by the [`Autopilot`] at one instant.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Prearm {
    /// The land detector says landed.
    pub(super) landed: bool,
    /// The navigation solution may be flown on (always with the ideal
    /// source; the filter aligned with its position valid).
    pub(super) position_valid: bool,
    /// The estimator has had its first sample.
    pub(super) estimator_initialised: bool,
    /// Home is a valid point.
    pub(super) home_valid: bool,
    /// The mode steers by a position that is lost: why (`no GPS fix`, ...)
    /// and what it concerns.
    pub(super) mode_without_position: Option<(&'static str, HealthComponent)>,
    /// Every rotor is healthy (the rotor monitor).
    pub(super) rotors_healthy: bool,
    /// The battery warning level in force.
    pub(super) battery: BatteryWarning,
    /// The data link is lost and `NAV_DLL_ACT` would act on it.
    pub(super) data_link_lost_with_action: bool,
    /// Why the selected mode cannot be armed in, if it cannot (no sticks,
    /// no offboard signal, no mission, an automatic mode that is not
    /// armable), and what it concerns.
    pub(super) mode: Option<(&'static str, HealthComponent)>,
}

impl Prearm {
    /// Every failing check, in PX4's order, with the component it concerns.
    pub(super) fn failures(&self) -> impl Iterator<Item = (&'static str, HealthComponent)> {
        use HealthComponent as C;
        [
            (!self.landed).then_some(("vehicle not landed", C::None)),
            (!self.position_valid).then_some(("no valid position estimate", C::LocalPositionEstimate)),
            (!self.estimator_initialised).then_some(("estimator not initialised", C::AttitudeEstimate)),
            (!self.home_valid).then_some(("home position invalid", C::GlobalPositionEstimate)),
            self.mode_without_position,
            (!self.rotors_healthy).then_some(("ESC failure", C::MotorsEscs)),
            (self.battery >= BatteryWarning::Critical).then_some(("battery critical", C::Battery)),
            self.data_link_lost_with_action
                .then_some(("no ground station connection", C::CommunicationLinks)),
            self.mode,
        ]
        .into_iter()
        .flatten()
    }

    /// The first failing check, in PX4's order, as the reason arming is denied.
    pub(super) fn failure(&self) -> Option<&'static str> {
        self.failures().next().map(|(why, _)| why)
    }
}

impl Autopilot {
    /// The health and arming report at simulated time `now_s` [s] (the
    /// instant of the latest step).
    #[must_use]
    pub fn health_report(&self, now_s: f64) -> HealthReport {
        let mut report = HealthReport::default();
        for mode in FlightMode::ALL {
            let prearm = self.prearm_in(mode, now_s);
            let mut failures = prearm.failures().peekable();
            if failures.peek().is_none() {
                report.can_arm = report.can_arm.with(mode);
            }
            for (text, component) in failures {
                report.fail(text, component, mode);
            }
            if prearm.mode_without_position.is_none() && self.mode_runnable(mode, now_s) {
                report.can_run = report.can_run.with(mode);
            }
        }
        report
    }

    /// What the prearm checks see at `now_s` [s] for arming in `mode`.
    pub(super) fn prearm_in(&self, mode: FlightMode, now_s: f64) -> Prearm {
        let position = self.navigator.position();
        Prearm {
            landed: self.land.landed(),
            position_valid: self.navigation().is_none_or(super::navigation::FilterNavigation::ready),
            estimator_initialised: self.control_initialised(),
            home_valid: self.home.is_valid(),
            mode_without_position: (!position.serves(self.navigator.position_need_of(mode)))
                .then(|| (position.loss.cause(), position.loss.component())),
            rotors_healthy: self.rotor_status().iter().all(|r| *r == RotorStatus::Healthy),
            battery: self.battery_warning(),
            data_link_lost_with_action: self.failsafe.data_link_is_lost()
                && self.settings.failsafe.data_link_loss_action != FailsafeAction::None,
            mode: self.mode_prearm_failure(mode, now_s),
        }
    }

    /// Why `mode` itself cannot be armed in at `now_s` [s], if it cannot:
    /// the sticks of a manual mode, the offboard signal, a mission, or a
    /// mode that is not armable.
    fn mode_prearm_failure(&self, mode: FlightMode, now_s: f64) -> Option<(&'static str, HealthComponent)> {
        if let Some(manual) = ManualMode::of(mode) {
            let clock = self.failsafe.clock();
            return self
                .navigator
                .manual_prearm_failure(manual, now_s, self.settings.manual.loss_s, clock)
                .map(|why| (why, HealthComponent::RemoteControl));
        }
        match mode {
            FlightMode::Offboard if !self.offboard_fresh(now_s) => Some(("no offboard signal", HealthComponent::None)),
            FlightMode::Mission if self.plans.get(crate::mission::MissionType::Mission).is_empty() => {
                Some(("no valid mission", HealthComponent::Mission))
            }
            FlightMode::Hold | FlightMode::Offboard | FlightMode::Mission => None,
            _ => Some(("flight mode not armable", HealthComponent::None)),
        }
    }

    /// Whether `mode` (its position served) could be switched to while
    /// armed at `now_s` [s]: a manual mode needs its sticks, Offboard its
    /// signal, Mission a mission.
    fn mode_runnable(&self, mode: FlightMode, now_s: f64) -> bool {
        if ManualMode::of(mode).is_some() {
            let clock = self.failsafe.clock();
            return self.navigator.manual_fresh(now_s, self.settings.manual.loss_s, clock);
        }
        match mode {
            FlightMode::Offboard => self.offboard_fresh(now_s),
            FlightMode::Mission => !self.plans.get(crate::mission::MissionType::Mission).is_empty(),
            _ => true,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ready() -> Prearm {
        Prearm {
            landed: true,
            position_valid: true,
            estimator_initialised: true,
            home_valid: true,
            mode_without_position: None,
            rotors_healthy: true,
            battery: BatteryWarning::None,
            data_link_lost_with_action: false,
            mode: None,
        }
    }

    #[test]
    fn prearm_checks_name_the_first_failure_in_px4_order() {
        assert_eq!(ready().failure(), None);
        let all_bad = Prearm {
            landed: false,
            position_valid: false,
            estimator_initialised: false,
            home_valid: false,
            mode_without_position: Some(("no GPS fix", HealthComponent::Gps)),
            rotors_healthy: false,
            battery: BatteryWarning::Emergency,
            data_link_lost_with_action: true,
            mode: Some(("no offboard signal", HealthComponent::None)),
        };
        assert_eq!(all_bad.failure(), Some("vehicle not landed"));
        let cases = [
            (
                Prearm {
                    position_valid: false,
                    ..ready()
                },
                "no valid position estimate",
            ),
            (
                Prearm {
                    estimator_initialised: false,
                    ..ready()
                },
                "estimator not initialised",
            ),
            (
                Prearm {
                    home_valid: false,
                    ..ready()
                },
                "home position invalid",
            ),
            (
                Prearm {
                    mode_without_position: Some(("no GPS fix", HealthComponent::Gps)),
                    ..ready()
                },
                "no GPS fix",
            ),
            (
                Prearm {
                    rotors_healthy: false,
                    ..ready()
                },
                "ESC failure",
            ),
            (
                Prearm {
                    battery: BatteryWarning::Critical,
                    ..ready()
                },
                "battery critical",
            ),
            (
                Prearm {
                    data_link_lost_with_action: true,
                    ..ready()
                },
                "no ground station connection",
            ),
            (
                Prearm {
                    mode: Some(("no valid mission", HealthComponent::None)),
                    ..ready()
                },
                "no valid mission",
            ),
        ];
        for (p, why) in cases {
            assert_eq!(p.failure(), Some(why));
        }
        // a low battery does not stop arming
        assert_eq!(
            Prearm {
                battery: BatteryWarning::Low,
                ..ready()
            }
            .failure(),
            None
        );
        // the mode is judged last
        let p = Prearm {
            home_valid: false,
            mode: Some(("no manual control input", HealthComponent::None)),
            ..ready()
        };
        assert_eq!(p.failure(), Some("home position invalid"));
    }
}
