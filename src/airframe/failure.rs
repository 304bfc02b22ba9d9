//! Hover feasibility with a rotor removed (`docs/model.md` section 3).
//!
//! Delete column `j` of `B`; check `rank B_f = 4`; then check that the hover
//! wrench `[m g, 0, 0, 0]` lies in the *interior* of the attainable set
//! `{B_f w : w_min <= w <= w_max}`. For each torque axis and direction the LP
//! `max +-tau_a  s.t.  u_T = m g, the other two torques = 0, bounds on w`
//! gives the margin; hover is interior when all six margins are positive.
//! Variables are rotor thrusts `T_i = c_T w_i` [N] for good conditioning.

use microlp::{ComparisonOp, OptimizationDirection, Problem};
use nalgebra::DMatrix;
use serde::Serialize;

use super::{Airframe, rank};
use crate::signals::GRAVITY;

/// Largest torque [N m] the rotors can add in each direction while holding hover thrust.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct TorqueMargins {
    /// Roll `[negative, positive]` magnitudes [N m].
    pub roll_n_m: [f64; 2],
    /// Pitch `[negative, positive]` magnitudes [N m].
    pub pitch_n_m: [f64; 2],
    /// Yaw `[negative, positive]` magnitudes [N m].
    pub yaw_n_m: [f64; 2],
}

impl TorqueMargins {
    /// The smallest of the six margins [N m].
    #[must_use]
    pub fn min(&self) -> f64 {
        [self.roll_n_m, self.pitch_n_m, self.yaw_n_m]
            .iter()
            .flatten()
            .copied()
            .fold(f64::INFINITY, f64::min)
    }
}

/// Whether the vehicle can still hover and hold attitude.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum HoverVerdict {
    /// Hover is in the interior of the attainable set: full control remains.
    Feasible,
    /// Hover is attainable but on the boundary: some torque direction has zero margin.
    Boundary,
    /// `B_f` has rank < 4: one virtual input (yaw) must be given up.
    RankDeficient,
    /// Hover thrust with zero torque cannot be produced within the speed limits.
    Infeasible,
}

/// The verdict for one failed rotor.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FailureAnalysis {
    /// Failed rotor label (1-based).
    pub rotor: usize,
    /// Rank of the remaining effectiveness matrix.
    pub rank: usize,
    /// Hover verdict.
    pub verdict: HoverVerdict,
    /// Torque margins at hover, when hover is attainable.
    pub margins: Option<TorqueMargins>,
}

/// Margin below which a direction counts as exhausted [N m].
const MARGIN_TOL: f64 = 1e-6;

/// Torque margins at hover for effectiveness `b` (4 x k), hover thrust
/// `thrust_n`, squared-speed bounds; `None` when hover cannot be attained.
#[must_use]
pub fn hover_margins(b: &DMatrix<f64>, thrust_n: f64, w_min: f64, w_max: f64) -> Option<TorqueMargins> {
    let k = b.ncols();
    let mut out = [[0.0; 2]; 3];
    for (axis, dirs) in out.iter_mut().enumerate() {
        for (d, sign) in [-1.0, 1.0].into_iter().enumerate() {
            let mut lp = Problem::new(OptimizationDirection::Maximize);
            let vars: Vec<_> = (0..k)
                .map(|i| {
                    let c_t = b[(0, i)];
                    // torque per newton of this rotor's thrust on the optimised axis
                    lp.add_var(sign * b[(axis + 1, i)] / c_t, (c_t * w_min, c_t * w_max))
                })
                .collect();
            lp.add_constraint(
                vars.iter().map(|v| (*v, 1.0)).collect::<Vec<_>>().as_slice(),
                ComparisonOp::Eq,
                thrust_n,
            );
            for other in (0..3).filter(|o| *o != axis) {
                let row: Vec<_> = vars
                    .iter()
                    .enumerate()
                    .map(|(i, v)| (*v, b[(other + 1, i)] / b[(0, i)]))
                    .collect();
                lp.add_constraint(row.as_slice(), ComparisonOp::Eq, 0.0);
            }
            let sol = lp.solve().ok()?.into_solution().ok()?;
            dirs[d] = sol.objective().max(0.0);
        }
    }
    Some(TorqueMargins {
        roll_n_m: out[0],
        pitch_n_m: out[1],
        yaw_n_m: out[2],
    })
}

/// Classify hover for effectiveness `b` at `thrust_n`.
fn verdict(b: &DMatrix<f64>, thrust_n: f64, w_min: f64, w_max: f64) -> (usize, HoverVerdict, Option<TorqueMargins>) {
    let r = rank(b);
    if r < 4 {
        return (r, HoverVerdict::RankDeficient, None);
    }
    match hover_margins(b, thrust_n, w_min, w_max) {
        None => (r, HoverVerdict::Infeasible, None),
        Some(m) if m.min() > MARGIN_TOL => (r, HoverVerdict::Feasible, Some(m)),
        Some(m) => (r, HoverVerdict::Boundary, Some(m)),
    }
}

/// Hover verdict of the intact vehicle at its nominal mass.
#[must_use]
pub fn intact_verdict(airframe: &Airframe) -> (HoverVerdict, Option<TorqueMargins>) {
    let (lo, hi) = airframe.speed_sq_bounds();
    let (_, v, m) = verdict(&airframe.effectiveness(), airframe.mass_kg * GRAVITY, lo, hi);
    (v, m)
}

/// For each single rotor failure, rank and hover verdict at the nominal mass.
#[must_use]
pub fn analyse_failures(airframe: &Airframe) -> Vec<FailureAnalysis> {
    let b = airframe.effectiveness();
    let (lo, hi) = airframe.speed_sq_bounds();
    let thrust = airframe.mass_kg * GRAVITY;
    (0..b.ncols())
        .map(|j| {
            let bf = b.clone().remove_column(j);
            let (rank, verdict, margins) = verdict(&bf, thrust, lo, hi);
            FailureAnalysis {
                rotor: j + 1,
                rank,
                verdict,
                margins,
            }
        })
        .collect()
}

/// Hover verdict of `airframe` at mass `mass_kg` after rotor faults: column
/// `i` of `B` scaled by the thrust fraction `gains[i]` the rotor still gives,
/// deleted when `gains[i] <= 0` (failed). All gains 1 is [`intact_verdict`]
/// at that mass; one gain 0 is that rotor's row of [`analyse_failures`].
#[must_use]
pub fn degraded_verdict(airframe: &Airframe, gains: &[f64], mass_kg: f64) -> FailureAnalysis {
    let b = airframe.effectiveness();
    let (lo, hi) = airframe.speed_sq_bounds();
    let kept: Vec<usize> = (0..b.ncols())
        .filter(|i| gains.get(*i).copied().unwrap_or(1.0) > 0.0)
        .collect();
    let bf = DMatrix::from_fn(4, kept.len(), |r, j| {
        b[(r, kept[j])] * gains.get(kept[j]).copied().unwrap_or(1.0)
    });
    let (rank, verdict, margins) = verdict(&bf, mass_kg * GRAVITY, lo, hi);
    FailureAnalysis {
        rotor: (0..b.ncols()).find(|i| !kept.contains(i)).map_or(0, |i| i + 1),
        rank,
        verdict,
        margins,
    }
}

#[cfg(test)]
mod degraded_tests {
    use super::*;

    /// Found by the fuzzer (tests/fuzz.rs): a client that fails every rotor
    /// left no column, and the rank's SVD of an empty matrix panicked.
    #[test]
    fn every_rotor_failed_is_a_verdict_not_a_panic() {
        let af = Airframe::load("quad").unwrap();
        let v = degraded_verdict(&af, &[0.0; 4], af.mass_kg);
        assert_eq!(v.rank, 0);
        assert_eq!(v.rotor, 1);
        assert_eq!(v.verdict, HoverVerdict::RankDeficient, "{v:?}");
    }

    #[test]
    fn one_failed_rotor_matches_the_failure_table() {
        let af = Airframe::load("octo").unwrap();
        let table = analyse_failures(&af);
        for j in 0..8 {
            let mut g = vec![1.0; 8];
            g[j] = 0.0;
            assert_eq!(degraded_verdict(&af, &g, af.mass_kg), table[j]);
        }
        let q = Airframe::load("quad").unwrap();
        let v = degraded_verdict(&q, &[0.0, 1.0, 1.0, 1.0], q.mass_kg);
        assert_eq!(v.verdict, HoverVerdict::RankDeficient);
        let h = degraded_verdict(&af, &[0.5, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0], af.mass_kg);
        assert_eq!(h.verdict, HoverVerdict::Feasible);
    }
}
