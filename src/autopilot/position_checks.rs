//! Whether the horizontal navigation solution may be flown on, as PX4's
//! commander decides it from the estimator's own accuracy
//! (`EstimatorChecks::setModeRequirementFlags`), and what each mode needs
//! of it (PX4's `mode_requirements`, multirotor):
//!
//! | validity | PX4's flag | test | modes |
//! |---|---|---|---|
//! | `position` | `local_position_invalid` | `xy_valid`, `eph < COM_POS_FS_EPH` | Hold, Takeoff, Return, Mission, Orbit, Follow, Offboard position |
//! | `position_relaxed` | `local_position_invalid_relaxed` | `xy_valid` | Position, Land |
//! | `velocity` | `local_velocity_invalid` | `v_xy_valid`, `evh < COM_VEL_FS_EVH` | Offboard velocity |
//!
//! Each test has PX4's hysteresis in level and time
//! ([`Probation::update`]): once valid, the accuracy may grow to 2.5 times
//! its threshold before the solution is invalid; once invalid, it must pass
//! the threshold itself for a whole second before it is valid again. So a
//! GNSS loss is not a lost position at once: the filter dead-reckons, and
//! the position stays valid until the filter's own dead-reckoning limit
//! (`EKF2_NOAID_TOUT`, 5 s) or its growing `eph` ends it.
//!
//! On the ideal navigation solution (no filter) there is no accuracy to
//! read: the position is valid exactly while the GNSS receiver has a fix.
use super::health::HealthComponent;

/// What a mode steers by horizontally (see the module's table).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum PositionNeed {
    /// Nothing horizontal (Altitude, Stabilized, Descend, Offboard attitude).
    None,
    /// The horizontal velocity (Offboard with velocity setpoints).
    Velocity,
    /// A position, whatever its accuracy (Position, Land).
    Relaxed,
    /// A position within `COM_POS_FS_EPH` (the autonomous modes).
    Accurate,
}

/// Why the position was lost, for the texts that say so.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) enum PositionLoss {
    /// The GNSS receiver has no fix.
    #[default]
    NoFix,
    /// The fix is there, but the estimate is not valid (GNSS rejected, or too inaccurate).
    Estimate,
}

impl PositionLoss {
    /// The start of the text announcing the loss.
    pub(super) fn lost(self) -> &'static str {
        match self {
            Self::NoFix => "No GPS fix",
            Self::Estimate => "No valid position estimate",
        }
    }

    /// The start of the text announcing the position back.
    pub(super) fn regained(self) -> &'static str {
        match self {
            Self::NoFix => "GPS fix regained",
            Self::Estimate => "Position estimate valid again",
        }
    }

    /// The failsafe's cause, as the failsafe state names it.
    pub(super) const fn cause(self) -> &'static str {
        match self {
            Self::NoFix => "no GPS fix",
            Self::Estimate => "no valid position estimate",
        }
    }

    /// What the loss concerns, in a health report.
    pub(super) fn component(self) -> HealthComponent {
        match self {
            Self::NoFix => HealthComponent::Gps,
            Self::Estimate => HealthComponent::GlobalPositionEstimate,
        }
    }

    /// Whether a failsafe's `cause` is a lost position.
    pub(super) fn is_cause(cause: &str) -> bool {
        [Self::NoFix, Self::Estimate].iter().any(|l| l.cause() == cause)
    }
}

/// What the modes may rely on now (PX4's failsafe flags, negated).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct PositionValidity {
    /// A position accurate enough for the autonomous modes.
    pub(super) position: bool,
    /// A position, whatever its accuracy.
    pub(super) position_relaxed: bool,
    /// A horizontal velocity accurate enough.
    pub(super) velocity: bool,
    /// Why, when not everything is valid.
    pub(super) loss: PositionLoss,
}

impl PositionValidity {
    /// Everything valid, or nothing (the ideal solution: the GNSS fix decides).
    pub(super) const fn all(valid: bool) -> Self {
        Self {
            position: valid,
            position_relaxed: valid,
            velocity: valid,
            loss: PositionLoss::NoFix,
        }
    }

    /// Whether a mode needing `need` can be flown.
    pub(super) fn serves(self, need: PositionNeed) -> bool {
        match need {
            PositionNeed::None => true,
            PositionNeed::Velocity => self.velocity,
            PositionNeed::Relaxed => self.position_relaxed,
            PositionNeed::Accurate => self.position,
        }
    }
}

impl Default for PositionValidity {
    fn default() -> Self {
        Self::all(true)
    }
}

/// What the navigation filter says of its horizontal solution (PX4's
/// `vehicle_local_position` fields the commander reads).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct HorizontalAccuracy {
    /// Horizontal position and velocity valid (`xy_valid`, `v_xy_valid`:
    /// aligned, and aided within `EKF2_NOAID_TOUT`).
    pub(super) valid: bool,
    /// Horizontal position accuracy `eph` [m].
    pub(super) eph_m: f64,
    /// Horizontal velocity accuracy `evh` [m/s].
    pub(super) evh_m_s: f64,
    /// The GNSS receiver has a fix (only to say why the position was lost).
    pub(super) fix: bool,
}

/// One validity with PX4's hysteresis (`checkPosVelValidity`).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Probation {
    valid: bool,
    /// The latest instant the level check failed [s].
    last_fail_s: f64,
}

/// How long the level check must pass before an invalid solution is valid again [s].
const PROBATION_S: f64 = 1.0;
/// How far past its threshold the accuracy of a valid solution may grow.
const VALID_MARGIN: f64 = 2.5;

impl Probation {
    /// Invalid since boot (PX4 starts every check failed).
    const fn new() -> Self {
        Self {
            valid: false,
            last_fail_s: 0.0,
        }
    }

    /// The validity at `now_s` for data `data_valid` of accuracy `accuracy`
    /// against the threshold `required` (infinite: no accuracy needed):
    ///
    /// ```text
    /// pass   = data_valid && accuracy < (valid ? 2.5 required : required)
    /// !pass : valid <- false, last_fail <- now
    /// pass && !valid && now > last_fail + 1 s : valid <- true
    /// ```
    fn update(&mut self, now_s: f64, data_valid: bool, accuracy: f64, required: f64) -> bool {
        let threshold = if self.valid { required * VALID_MARGIN } else { required };
        if data_valid && accuracy < threshold {
            if !self.valid && now_s > self.last_fail_s + PROBATION_S {
                self.valid = true;
            }
        } else {
            self.valid = false;
            self.last_fail_s = now_s;
        }
        self.valid
    }
}

/// The commander's checks of the filter's horizontal solution, run every step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct PositionChecks {
    position: Probation,
    position_relaxed: Probation,
    velocity: Probation,
    /// Why the solution was lost, kept until all of it is valid again.
    loss: PositionLoss,
}

impl Default for PositionChecks {
    fn default() -> Self {
        Self {
            position: Probation::new(),
            position_relaxed: Probation::new(),
            velocity: Probation::new(),
            loss: PositionLoss::NoFix,
        }
    }
}

impl PositionChecks {
    /// The validity at `now_s` of a solution of accuracy `a`, against
    /// `COM_POS_FS_EPH` (`eph_max_m`, negative: no limit) and
    /// `COM_VEL_FS_EVH` (`evh_max_m_s`).
    pub(super) fn update(
        &mut self,
        now_s: f64,
        a: &HorizontalAccuracy,
        eph_max_m: f64,
        evh_max_m_s: f64,
    ) -> PositionValidity {
        let eph_max_m = if eph_max_m < 0.0 { f64::INFINITY } else { eph_max_m };
        let was_valid = self.position.valid && self.position_relaxed.valid && self.velocity.valid;
        let v = PositionValidity {
            position: self.position.update(now_s, a.valid, a.eph_m, eph_max_m),
            position_relaxed: self.position_relaxed.update(now_s, a.valid, a.eph_m, f64::INFINITY),
            velocity: self.velocity.update(now_s, a.valid, a.evh_m_s, evh_max_m_s),
            loss: self.loss,
        };
        // the fix lost says why; else a solution valid until now lost its accuracy
        if !a.fix {
            self.loss = PositionLoss::NoFix;
        } else if was_valid && !(v.position && v.position_relaxed && v.velocity) {
            self.loss = PositionLoss::Estimate;
        }
        PositionValidity { loss: self.loss, ..v }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn accuracy(valid: bool, eph_m: f64) -> HorizontalAccuracy {
        HorizontalAccuracy {
            valid,
            eph_m,
            evh_m_s: 0.1,
            fix: true,
        }
    }

    #[test]
    fn a_valid_solution_is_trusted_after_a_second_of_passing() {
        let mut c = PositionChecks::default();
        assert!(!c.update(0.5, &accuracy(false, 0.5), 5.0, 1.0).position);
        assert!(!c.update(1.0, &accuracy(true, 0.5), 5.0, 1.0).position);
        assert!(!c.update(1.5, &accuracy(true, 0.5), 5.0, 1.0).position);
        assert!(c.update(1.501, &accuracy(true, 0.5), 5.0, 1.0).position);
    }

    #[test]
    fn once_valid_the_accuracy_may_grow_to_two_and_a_half_times_the_threshold() {
        let mut c = PositionChecks::default();
        c.update(2.0, &accuracy(true, 0.5), 5.0, 1.0);
        let v = c.update(3.0, &accuracy(true, 12.4), 5.0, 1.0);
        assert!(v.position && v.position_relaxed);
        let v = c.update(3.1, &accuracy(true, 12.6), 5.0, 1.0);
        assert!(!v.position, "past 2.5 x COM_POS_FS_EPH");
        assert!(v.position_relaxed, "the relaxed check needs no accuracy");
        assert!(v.velocity);
        // invalid now: back under 12.5 m is not enough, under 5 m for a second is
        assert!(!c.update(3.2, &accuracy(true, 6.0), 5.0, 1.0).position);
        assert!(!c.update(3.3, &accuracy(true, 4.0), 5.0, 1.0).position);
        assert!(c.update(4.3, &accuracy(true, 4.0), 5.0, 1.0).position);
    }

    #[test]
    fn a_lost_solution_is_lost_at_once_and_says_why() {
        let mut c = PositionChecks::default();
        c.update(2.0, &accuracy(true, 0.5), 5.0, 1.0);
        let lost = HorizontalAccuracy {
            fix: false,
            ..accuracy(false, 0.5)
        };
        let v = c.update(2.001, &lost, 5.0, 1.0);
        assert_eq!((v.position, v.position_relaxed, v.velocity), (false, false, false));
        assert_eq!(v.loss, PositionLoss::NoFix);
        assert!(v.serves(PositionNeed::None) && !v.serves(PositionNeed::Relaxed));
        // the fix back: still the fix's loss while the solution proves itself
        let v = c.update(2.5, &accuracy(true, 0.5), 5.0, 1.0);
        assert_eq!((v.position, v.loss), (false, PositionLoss::NoFix));
        assert!(c.update(3.01, &accuracy(true, 0.5), 5.0, 1.0).position);
        // lost with the fix there: the estimate's fault
        let v = c.update(3.5, &accuracy(false, 0.5), 5.0, 1.0);
        assert_eq!((v.position, v.loss), (false, PositionLoss::Estimate));
    }

    #[test]
    fn a_negative_eph_threshold_checks_no_accuracy() {
        let mut c = PositionChecks::default();
        c.update(2.0, &accuracy(true, 500.0), -1.0, 1.0);
        assert!(c.update(3.5, &accuracy(true, 500.0), -1.0, 1.0).position);
    }
}
