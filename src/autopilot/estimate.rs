//! The wrench estimate the controller is given (`EST_COMP`): nothing is
//! learned while the vehicle rests on the ground (the ground's reaction is not
//! a disturbance; the estimator restarts every such step), and after the
//! estimator is rebuilt in flight (a new `EST_ORDER`, `EST_POLY` or
//! `EST_CUTOFF`) the fed-back estimate cross-fades from the old one to the
//! new one over `8 r / omega_c` seconds (0.5 to 30 s):
//!
//! ```text
//! f_fb(t) = (1 - w) f_old + w f_new,   w = clamp((t - t_0) / T, 0, 1)
//! ```

use crate::signals::WrenchEstimate;

/// A cross-fade in progress.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Fade {
    from: WrenchEstimate,
    start_s: f64,
    duration_s: f64,
}

impl Fade {
    fn weight(&self, now: f64) -> f64 {
        ((now - self.start_s) / self.duration_s).clamp(0.0, 1.0)
    }
}

fn blend(a: &WrenchEstimate, b: &WrenchEstimate, w: f64) -> WrenchEstimate {
    WrenchEstimate {
        force_ned: a.force_ned * (1.0 - w) + b.force_ned * w,
        torque_rpy: a.torque_rpy * (1.0 - w) + b.torque_rpy * w,
        torque_frd: a.torque_frd * (1.0 - w) + b.torque_frd * w,
        mass_kg: a.mass_kg * (1.0 - w) + b.mass_kg * w,
    }
}

/// The fed-back estimate's state.
#[derive(Clone, Debug, Default, PartialEq)]
pub(super) struct EstimateFeedback {
    fade: Option<Fade>,
}

impl EstimateFeedback {
    /// The duration [s] of the cross-fade after a rebuild to order `r` and cutoff `omega_c` [rad/s].
    pub(super) fn fade_duration_s(order: usize, cutoff_rad_s: f64) -> f64 {
        (8.0 * order as f64 / cutoff_rad_s).clamp(0.5, 30.0)
    }

    /// On the ground: nothing to fade.
    pub(super) fn cancel_fade(&mut self) {
        self.fade = None;
    }

    /// Fade from `from` (what was fed back) to the rebuilt estimator's output over `duration_s`.
    pub(super) fn start_fade(&mut self, from: WrenchEstimate, now: f64, duration_s: f64) {
        self.fade = Some(Fade {
            from,
            start_s: now,
            duration_s,
        });
    }

    /// The estimate to feed back at `now` given the estimator's `estimate`.
    pub(super) fn feed_back(&mut self, estimate: &WrenchEstimate, now: f64) -> WrenchEstimate {
        match self.fade {
            Some(f) => {
                let w = f.weight(now);
                if w >= 1.0 {
                    self.fade = None;
                    *estimate
                } else {
                    blend(&f.from, estimate, w)
                }
            }
            None => *estimate,
        }
    }

    /// What is fed back right now (the start of a new cross-fade): the fade
    /// in progress, the estimate when feedback is on, else nothing (zero
    /// wrench, the nominal mass).
    pub(super) fn current(
        &self,
        estimate: &WrenchEstimate,
        now: f64,
        feedback: bool,
        nominal_mass_kg: f64,
    ) -> WrenchEstimate {
        match self.fade {
            Some(f) => blend(&f.from, estimate, f.weight(now)),
            None if feedback => *estimate,
            None => WrenchEstimate {
                mass_kg: nominal_mass_kg,
                ..WrenchEstimate::default()
            },
        }
    }
}
