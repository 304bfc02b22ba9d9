//! Vehicle–vehicle proximity in one world: which pairs came closer than the
//! reporting distance `d` this step, and which touched.
//!
//! Two vehicles `a`, `b` at world positions `p_a`, `p_b` (NED, metres from
//! the world's origin) with body radii `r_a`, `r_b` are
//!
//! * **near** when `|p_a - p_b| < d`,
//! * **touching** (a collision) when `|p_a - p_b| < r_a + r_b`,
//!
//! and a pair's level (apart < near < touching) is reported each time it
//! rises: one [`ProximityEvent`] per rise, never again while the pair stays
//! there. A level falls only once the distance exceeds its threshold by
//! [`HYSTERESIS`] (10 %), so a pair hovering at the boundary does not chatter.
//!
//! The pairs are found by sweep and prune: the vehicles are kept sorted along
//! the horizontal axis (north or east) on which they spread most, by an
//! insertion sort that costs `O(n)` when they moved little since the last
//! step; each vehicle is compared only with those ahead of it within the
//! widest threshold along that axis. Pure and deterministic: pairs are
//! reported in the order of `(a, b)`, `a < b`.

use nalgebra::Vector3;

/// A level falls once the distance exceeds its threshold times this.
pub const HYSTERESIS: f64 = 1.1;

/// How close two vehicles came.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ProximityKind {
    /// Closer than the reporting distance.
    Near,
    /// Their bodies touch: closer than the sum of their radii.
    Collision,
}

impl ProximityKind {
    /// The name used in logs and summaries (`near`, `collision`).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Near => "near",
            Self::Collision => "collision",
        }
    }
}

/// A pair of vehicles whose level rose this step.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ProximityEvent {
    /// The lower vehicle index.
    pub a: usize,
    /// The higher vehicle index.
    pub b: usize,
    /// Their distance [m] after the step.
    pub distance_m: f64,
    /// What they reached.
    pub kind: ProximityKind,
}

/// The pairs' levels, carried from step to step.
#[derive(Clone, Debug)]
pub struct Proximity {
    distance_m: f64,
    /// Vehicle indices sorted along `axis`.
    order: Vec<usize>,
    /// 0 = north, 1 = east.
    axis: usize,
    /// The pairs above "apart", sorted by `(a, b)`, with their level.
    levels: Vec<(usize, usize, ProximityKind)>,
    /// This step's levels (kept to reuse its allocation).
    next: Vec<(usize, usize, ProximityKind)>,
}

impl Proximity {
    /// Report pairs closer than `distance_m` [m] (and touching ones).
    #[must_use]
    pub fn new(distance_m: f64) -> Self {
        Self {
            distance_m,
            order: Vec::new(),
            axis: 0,
            levels: Vec::new(),
            next: Vec::new(),
        }
    }

    /// The reporting distance [m].
    #[must_use]
    pub fn distance_m(&self) -> f64 {
        self.distance_m
    }

    /// The pairs now near or touching, `(a, b, level)` with `a < b`, sorted.
    #[must_use]
    pub fn levels(&self) -> &[(usize, usize, ProximityKind)] {
        &self.levels
    }

    /// Look at the vehicles at `positions_ned` [m, world NED] with body
    /// `radii_m`; append the pairs whose level rose to `events`.
    ///
    /// # Panics
    /// When the two slices differ in length.
    pub fn check(&mut self, positions_ned: &[Vector3<f64>], radii_m: &[f64], events: &mut Vec<ProximityEvent>) {
        assert_eq!(positions_ned.len(), radii_m.len(), "one radius per vehicle");
        let n = positions_ned.len();
        let first = events.len();
        if self.order.len() != n {
            self.order = (0..n).collect();
        }
        if n < 2 {
            return;
        }
        // the axis along which the vehicles spread most
        let spread = |k: usize| {
            let (lo, hi) = positions_ned
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                    (lo.min(p[k]), hi.max(p[k]))
                });
            hi - lo
        };
        let axis = usize::from(spread(1) > spread(0));
        self.axis = axis;
        let key = |i: usize| positions_ned[i][axis];
        // insertion sort: O(n) when nearly sorted (NaN positions sort to an end)
        for j in 1..n {
            let mut k = j;
            while k > 0 && key(self.order[k - 1]).total_cmp(&key(self.order[k])).is_gt() {
                self.order.swap(k - 1, k);
                k -= 1;
            }
        }
        let max_radius = radii_m.iter().copied().fold(0.0, f64::max);
        // the widest threshold a level may still hold at
        let window = self.distance_m.max(2.0 * max_radius) * HYSTERESIS;
        self.next.clear();
        for (s, &i) in self.order.iter().enumerate() {
            let pi = positions_ned[i];
            for &j in &self.order[s + 1..] {
                let pj = positions_ned[j];
                let gap = pj[axis] - pi[axis];
                if gap.is_nan() || gap > window {
                    break;
                }
                let (a, b) = if i < j { (i, j) } else { (j, i) };
                let touch = radii_m[a] + radii_m[b];
                let d = (pj - pi).norm();
                let was = self
                    .levels
                    .binary_search_by(|&(x, y, _)| (x, y).cmp(&(a, b)))
                    .ok()
                    .map(|k| self.levels[k].2);
                let level = if d < touch {
                    Some(ProximityKind::Collision)
                } else if d < self.distance_m {
                    Some(ProximityKind::Near)
                } else {
                    None
                };
                // held by hysteresis: a level falls only beyond its threshold x 1.1
                let held = match was {
                    Some(ProximityKind::Collision) if d <= touch * HYSTERESIS => Some(ProximityKind::Collision),
                    Some(_) if d <= self.distance_m * HYSTERESIS => Some(ProximityKind::Near),
                    _ => None,
                };
                let now = level.max(held);
                if let Some(kind) = now {
                    if was.is_none_or(|w| kind > w) {
                        events.push(ProximityEvent {
                            a,
                            b,
                            distance_m: d,
                            kind,
                        });
                    }
                    self.next.push((a, b, kind));
                }
            }
        }
        self.next.sort_unstable_by_key(|&(a, b, _)| (a, b));
        std::mem::swap(&mut self.levels, &mut self.next);
        events[first..].sort_by_key(|e| (e.a, e.b));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(p: &mut Proximity, pos: &[[f64; 3]], radii: &[f64]) -> Vec<ProximityEvent> {
        let pos: Vec<_> = pos.iter().map(|v| Vector3::new(v[0], v[1], v[2])).collect();
        let mut ev = Vec::new();
        p.check(&pos, radii, &mut ev);
        ev
    }

    #[test]
    fn a_pair_is_reported_once_per_rise_with_hysteresis() {
        let mut p = Proximity::new(2.0);
        let r = [0.3, 0.3];
        assert!(run(&mut p, &[[0.0, 0.0, 0.0], [3.0, 0.0, 0.0]], &r).is_empty());
        let e = run(&mut p, &[[0.0, 0.0, 0.0], [1.9, 0.0, 0.0]], &r);
        assert_eq!(e.len(), 1);
        assert_eq!((e[0].a, e[0].b, e[0].kind), (0, 1, ProximityKind::Near));
        assert!((e[0].distance_m - 1.9).abs() < 1e-12);
        // stays near: nothing new; 2.1 m is within the hysteresis (2.2 m)
        assert!(run(&mut p, &[[0.0, 0.0, 0.0], [1.5, 0.0, 0.0]], &r).is_empty());
        assert!(run(&mut p, &[[0.0, 0.0, 0.0], [2.1, 0.0, 0.0]], &r).is_empty());
        assert!(run(&mut p, &[[0.0, 0.0, 0.0], [1.9, 0.0, 0.0]], &r).is_empty());
        // touching: a collision (0.5 m < 0.6 m)
        let e = run(&mut p, &[[0.0, 0.0, 0.0], [0.0, 0.0, 0.5]], &r);
        assert_eq!(e.len(), 1);
        assert_eq!(e[0].kind, ProximityKind::Collision);
        // apart beyond 2.2 m, then near again: reported again
        assert!(run(&mut p, &[[0.0, 0.0, 0.0], [2.3, 0.0, 0.0]], &r).is_empty());
        assert!(p.levels().is_empty());
        let e = run(&mut p, &[[0.0, 0.0, 0.0], [0.0, 1.0, 0.0]], &r);
        assert_eq!(e.len(), 1);
        assert_eq!(e[0].kind, ProximityKind::Near);
    }

    #[test]
    fn the_sweep_finds_what_every_pair_compared_finds() {
        // a deterministic scatter of 60 vehicles moving over 50 steps;
        // compare with the brute force over every pair
        let n = 60;
        let radii: Vec<f64> = (0..n).map(|i| 0.2 + 0.01 * (i % 7) as f64).collect();
        let mut p = Proximity::new(2.0);
        let mut brute: Vec<Option<ProximityKind>> = vec![None; n * n];
        for step in 0..50 {
            let pos: Vec<Vector3<f64>> = (0..n)
                .map(|i| {
                    let s = f64::from(step) * 0.05;
                    let fi = i as f64;
                    Vector3::new(
                        (fi * 1.7).sin() * 12.0 + s * (fi * 0.3).cos(),
                        (fi * 2.3).cos() * 4.0 + s * (fi * 0.7).sin(),
                        -1.0 - (fi * 0.9).sin(),
                    )
                })
                .collect();
            let mut ev = Vec::new();
            p.check(&pos, &radii, &mut ev);
            let mut expect = Vec::new();
            for a in 0..n {
                for b in a + 1..n {
                    let d = (pos[a] - pos[b]).norm();
                    let touch = radii[a] + radii[b];
                    let was = brute[a * n + b];
                    let level = if d < touch {
                        Some(ProximityKind::Collision)
                    } else if d < 2.0 {
                        Some(ProximityKind::Near)
                    } else {
                        None
                    };
                    let held = match was {
                        Some(ProximityKind::Collision) if d <= touch * HYSTERESIS => Some(ProximityKind::Collision),
                        Some(_) if d <= 2.0 * HYSTERESIS => Some(ProximityKind::Near),
                        _ => None,
                    };
                    let now = level.max(held);
                    if let Some(k) = now
                        && was.is_none_or(|w| k > w)
                    {
                        expect.push((a, b, k));
                    }
                    brute[a * n + b] = now;
                }
            }
            let got: Vec<_> = ev.iter().map(|e| (e.a, e.b, e.kind)).collect();
            assert_eq!(got, expect, "step {step}");
        }
    }
}
