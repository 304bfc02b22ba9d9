//! Return's way round the geofence, as PX4's direct Return (RTL_TYPE 0)
//! plans it once at its start: a shortest path on the visibility graph of
//! the fence's zones grown by a margin. Pure geometry in local NED
//! (north, east) [m].
//!
//! * **Zones as rings.** Every zone becomes a closed ring of corners kept
//!   so that the side not to be flown lies to the left of each edge: an
//!   exclusion zone counter-clockwise (its inside is forbidden), an
//!   inclusion zone clockwise (its outside is). Each corner moves off the
//!   forbidden side so that every edge lies the margin `m` from the zone's
//!   own (a miter offset); `e` the unit edge directions, `n` their left
//!   normals:
//!   ```text
//!   b  = n_in + n_out,   |b| = 2 cos(turn / 2)
//!   v' = v - (b / |b|) 2 m / |b|
//!   ```
//!   A corner of the forbidden side that is convex and sharper than
//!   60 degrees (`|b| < 1`) is cut off instead, by two corners on the line
//!   perpendicular to `b` at `m` from `v`, one on each offset edge:
//!   `v - b^ m + p^ s` and `v - b^ m - p^ s`, `b^ = b / |b|`, `p^` = `b^`
//!   turned left, `s = m (1 - n_out . b^) / (e_out . b^)`.
//!   A circle (centre `c`, radius `r`) becomes the regular 8-gon with
//!   corners at the angles `(i + 1/2) 2 pi / 8` around `c`, of circumradius
//!   `r / cos(pi / 8) + m` for an exclusion (it holds the grown circle) and
//!   `r - m` for an inclusion (the shrunk circle holds it).
//! * **Exact tests.** Corners are rounded to the centimetre and every test
//!   is the sign of an integer cross product,
//!   `side(a, b, c) = sign((b - a) x (c - a))`, so sliding along a border,
//!   touching it and passing through a corner are decided exactly: a
//!   segment may run along a border, never into the forbidden side. A
//!   segment enters a ring's forbidden side when it crosses an edge, when
//!   it passes through a corner into the corner's forbidden cone, or when
//!   its midpoint (not on the border) lies on the forbidden side (winding
//!   number). Every inclusion zone is kept inside of, as PX4's planner
//!   does (the breach check needs only one).
//! * **Graph.** Nodes: the destination and the corners where the forbidden
//!   side is convex (no shortest path bends elsewhere). Two nodes are
//!   joined when the segment between them is tangent at both ends (neither
//!   it nor its mirror image leaves the corner into the forbidden cone) and
//!   enters no forbidden side; its cost is its length.
//! * **Search.** Dijkstra from the destination gives each node its
//!   distance `D` to it. From the start: the destination in sight is the
//!   straight line; else the node in sight with the least
//!   `|start - node| + D` begins the path, which follows the search's
//!   successors to the destination.
//!
//! No path (a fence PX4 does not plan on, a destination on the forbidden
//! side of the grown zones, nothing in sight from the start) is the straight
//! line, as PX4 falls back to it.

use nalgebra::Vector2;

use super::geofence::{Fence, Zone};

/// Corners of the polygon standing in for a circle.
const CIRCLE_CORNERS: usize = 8;
/// Nodes at most, the destination's included (PX4's default budget).
const MAX_NODES: usize = 100;
/// Zones at most.
const MAX_ZONES: usize = 16;
/// A circle of this radius [m] or less has no shape.
const MIN_CIRCLE_RADIUS_M: f64 = 0.1;
/// Coordinates stay below this magnitude [cm] (about 10,700 km).
const RANGE_CM: f64 = (1u64 << 30) as f64;
/// Edge lengths [m] and bisector norms below this are degenerate.
const TINY: f64 = f32::EPSILON as f64;

/// The way to the destination round the fence.
#[derive(Clone, Debug, PartialEq)]
pub(super) enum Route {
    /// The fence has no zone: nothing to avoid.
    NoFence,
    /// The destination is in sight: the straight line.
    Direct,
    /// Fly these points [m] (north, east) in order, then to the destination.
    Around(Vec<Vector2<f64>>),
    /// No way found: the straight line, the fence ignored.
    Straight(Unplanned),
}

/// Why no way round was planned.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Unplanned {
    /// More zones or corners than the planner holds.
    Budget,
    /// A point lies too far from the origin.
    OutOfRange,
    /// A zone has no usable shape: a polygon crossing itself, folding back
    /// or with a zero-length edge, a circle of 0.1 m or less, an inclusion
    /// circle no wider than the margin.
    Degenerate,
    /// The destination lies on the forbidden side of the grown zones.
    DestinationOutside,
    /// No node and not the destination is in sight from the start, or none
    /// in sight leads to the destination.
    NoPath,
}

impl Unplanned {
    /// PX4's status code of a fence it cannot plan on (said in its warning), if this is one.
    pub(super) fn fence_code(self) -> Option<u8> {
        match self {
            Unplanned::Budget => Some(5),
            Unplanned::OutOfRange => Some(6),
            Unplanned::Degenerate => Some(7),
            Unplanned::DestinationOutside | Unplanned::NoPath => None,
        }
    }
}

/// The way from `start` to `dest` [m] (north, east) round `fence`'s zones
/// grown by `margin_m` [m].
pub(super) fn plan(fence: &Fence, margin_m: f64, start: Vector2<f64>, dest: Vector2<f64>) -> Route {
    if fence.inclusion.is_empty() && fence.exclusion.is_empty() {
        return Route::NoFence;
    }
    let graph = match Graph::build(fence, margin_m) {
        Ok(g) => g,
        Err(why) => return Route::Straight(why),
    };
    let (Some(start), Some(dest)) = (Cm::from_m(start), Cm::from_m(dest)) else {
        return Route::Straight(Unplanned::OutOfRange);
    };
    graph.route(start, dest)
}

/// A point on the centimetre grid (north, east) [cm].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Cm {
    n: i64,
    e: i64,
}

impl Cm {
    /// `p` [m] rounded to the centimetre, if within range.
    fn from_m(p: Vector2<f64>) -> Option<Self> {
        let (n, e) = ((p.x * 100.0).round(), (p.y * 100.0).round());
        (n.abs() < RANGE_CM && e.abs() < RANGE_CM).then_some(Cm {
            n: n as i64,
            e: e as i64,
        })
    }

    /// Back to metres.
    fn to_m(self) -> Vector2<f64> {
        Vector2::new(self.n as f64 / 100.0, self.e as f64 / 100.0)
    }

    fn plus(self, o: Cm) -> Cm {
        Cm {
            n: self.n + o.n,
            e: self.e + o.e,
        }
    }

    fn twice(self) -> Cm {
        self.plus(self)
    }
}

/// Where `c` lies seen along `a -> b`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Side {
    Left,
    On,
    Right,
}

/// `sign((b - a) x (c - a))`, exact.
fn side(a: Cm, b: Cm, c: Cm) -> Side {
    let cross = i128::from(b.n - a.n) * i128::from(c.e - a.e) - i128::from(b.e - a.e) * i128::from(c.n - a.n);
    match cross.signum() {
        1 => Side::Left,
        -1 => Side::Right,
        _ => Side::On,
    }
}

/// Whether `c`, on the line through `a` and `b`, lies strictly between them.
fn strictly_between(a: Cm, b: Cm, c: Cm) -> bool {
    let inside = |lo: i64, hi: i64, x: i64| (lo < x && x < hi) || (hi < x && x < lo);
    if (a.n - b.n).abs() >= (a.e - b.e).abs() {
        inside(a.n, b.n, c.n)
    } else {
        inside(a.e, b.e, c.e)
    }
}

/// How segment `pq` meets segment `ab`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Meet {
    /// Not at all, or only at a shared end.
    Apart,
    /// Each crosses the other's interior at a single point.
    Cross,
    /// Both lie on one line.
    Collinear,
    /// `b` lies strictly inside `pq`.
    EndInside,
    /// `a` lies strictly inside `pq`, or `p` or `q` strictly inside `ab`.
    Touch,
}

fn meet(p: Cm, q: Cm, a: Cm, b: Cm) -> Meet {
    let (sa, sb) = (side(p, q, a), side(p, q, b));
    if sa != Side::On && sa == sb {
        return Meet::Apart;
    }
    let (sp, sq) = (side(a, b, p), side(a, b, q));
    if sp != Side::On && sp == sq {
        return Meet::Apart;
    }
    let ons = [sa, sb, sp, sq].iter().filter(|s| **s == Side::On).count();
    if ons == 0 {
        Meet::Cross
    } else if ons == 4 {
        Meet::Collinear
    } else if sb == Side::On && strictly_between(p, q, b) {
        Meet::EndInside
    } else if (sa == Side::On && strictly_between(p, q, a))
        || (sp == Side::On && strictly_between(a, b, p))
        || (sq == Side::On && strictly_between(a, b, q))
    {
        Meet::Touch
    } else {
        Meet::Apart
    }
}

/// Which side of a ring's border may be flown.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Keep {
    /// An inclusion zone.
    Inside,
    /// An exclusion zone.
    Outside,
}

/// A node's part in shortest paths.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Bend {
    /// The destination, or a corner where the forbidden side is convex.
    May,
    /// A corner where the forbidden side is reflex or straight.
    Never,
}

/// A grown zone: `len` nodes from `first`, the forbidden side on the left.
#[derive(Clone, Copy, Debug)]
struct Ring {
    first: usize,
    len: usize,
    keep: Keep,
    /// Bounding box.
    lo: Cm,
    hi: Cm,
}

/// The visibility graph: node 0 the destination, then each ring's corners.
#[derive(Debug)]
struct Graph {
    nodes: Vec<Cm>,
    bends: Vec<Bend>,
    /// The ring of each node (`None`: the destination).
    owner: Vec<Option<usize>>,
    rings: Vec<Ring>,
}

/// Most corners a simple polygon of `n` vertices grows to: a corner sharper
/// than 60 degrees is split in two, and with the interior angles summing to
/// `(n - 2) 180` and each below 360, `k` such corners need
/// `(n - 2) 180 < 60 k + 360 (n - k)`, so `k <= floor((180 n + 359) / 300)`.
fn most_corners(n: usize) -> usize {
    if n < 3 { 0 } else { n + (180 * n + 359) / 300 }
}

/// Twice the signed area of the polygon `v` (shoelace): positive counter-clockwise.
fn twice_area(v: &[Vector2<f64>]) -> f64 {
    let n = v.len();
    (0..n).map(|i| v[i].perp(&v[(i + 1) % n])).sum()
}

/// Whether two edges of the polygon `v` that do not follow each other meet.
fn crosses_itself(v: &[Cm]) -> bool {
    let n = v.len();
    (0..n).any(|i| {
        (i + 2..n)
            .filter(|&j| !(i == 0 && j == n - 1))
            .any(|j| meet(v[i], v[(i + 1) % n], v[j], v[(j + 1) % n]) != Meet::Apart)
    })
}

/// The left normal of the unit vector `u`.
fn left(u: Vector2<f64>) -> Vector2<f64> {
    Vector2::new(-u.y, u.x)
}

/// The polygon `v` grown by `m` [m] off its forbidden side, with that side on
/// the left (module doc: miter offset, sharp convex corners cut off).
fn grown_polygon(v: &[Vector2<f64>], keep: Keep, m: f64) -> Result<Vec<Vector2<f64>>, Unplanned> {
    let n = v.len();
    if n < 3 {
        return Err(Unplanned::Degenerate);
    }
    let grid: Option<Vec<Cm>> = v.iter().map(|p| Cm::from_m(*p)).collect();
    let grid = grid.ok_or(Unplanned::OutOfRange)?;
    if crosses_itself(&grid) {
        return Err(Unplanned::Degenerate);
    }
    let counter_clockwise = twice_area(v) > 0.0;
    let reverse = counter_clockwise == (keep == Keep::Inside);
    let at = |i: usize| v[if reverse { n - 1 - i } else { i }];
    let mut out = Vec::with_capacity(most_corners(n));
    for i in 0..n {
        let (prev, here, next) = (at((i + n - 1) % n), at(i), at((i + 1) % n));
        let (d_in, d_out) = (here - prev, next - here);
        if d_in.norm() < TINY || d_out.norm() < TINY {
            return Err(Unplanned::Degenerate);
        }
        let (e_in, e_out) = (d_in.normalize(), d_out.normalize());
        let n_out = left(e_out);
        let b = left(e_in) + n_out;
        let b_len = b.norm();
        if b_len < TINY {
            return Err(Unplanned::Degenerate);
        }
        let b_hat = b / b_len;
        let convex = e_in.perp(&e_out) > 0.0;
        if convex && b_len < 1.0 && m > TINY {
            let base = here - b_hat * m;
            let s = m * (1.0 - n_out.dot(&b_hat)) / e_out.dot(&b_hat);
            out.push(base + left(b_hat) * s);
            out.push(base - left(b_hat) * s);
        } else {
            out.push(here - b_hat * (2.0 * m / b_len));
        }
    }
    Ok(out)
}

/// The 8-gon standing in for the circle (`centre`, `radius_m`) grown by
/// `m` [m] off its forbidden side, with that side on the left.
fn grown_circle(centre: Vector2<f64>, radius_m: f64, keep: Keep, m: f64) -> Result<Vec<Vector2<f64>>, Unplanned> {
    if radius_m.is_nan() || radius_m <= MIN_CIRCLE_RADIUS_M {
        return Err(Unplanned::Degenerate);
    }
    let k = CIRCLE_CORNERS as f64;
    let (radius, turn) = match keep {
        Keep::Outside => (radius_m / (std::f64::consts::PI / k).cos() + m, 1.0),
        Keep::Inside => (radius_m - m, -1.0),
    };
    if radius <= TINY {
        return Err(Unplanned::Degenerate);
    }
    let step = turn * 2.0 * std::f64::consts::PI / k;
    Ok((0..CIRCLE_CORNERS)
        .map(|i| {
            let angle = (i as f64 + 0.5) * step;
            centre + Vector2::new(angle.cos(), angle.sin()) * radius
        })
        .collect())
}

impl Graph {
    /// The rings of `fence` grown by `margin_m` [m], the destination's node
    /// still to be set.
    fn build(fence: &Fence, margin_m: f64) -> Result<Graph, Unplanned> {
        let zones: Vec<(&Zone, Keep)> = (fence.inclusion.iter().map(|z| (z, Keep::Inside)))
            .chain(fence.exclusion.iter().map(|z| (z, Keep::Outside)))
            .collect();
        let corners: usize = zones
            .iter()
            .map(|(z, _)| match z {
                Zone::Polygon(v) => most_corners(v.len()),
                Zone::Circle { .. } => CIRCLE_CORNERS,
            })
            .sum();
        if zones.len() > MAX_ZONES || corners > MAX_NODES - 1 {
            return Err(Unplanned::Budget);
        }
        if margin_m.is_nan() || margin_m < 0.0 {
            return Err(Unplanned::Degenerate);
        }
        let mut g = Graph {
            nodes: vec![Cm { n: 0, e: 0 }],
            bends: vec![Bend::May],
            owner: vec![None],
            rings: Vec::with_capacity(zones.len()),
        };
        for (zone, keep) in zones {
            let corners = match zone {
                Zone::Polygon(v) => grown_polygon(v, keep, margin_m)?,
                Zone::Circle { centre, radius_m } => grown_circle(*centre, *radius_m, keep, margin_m)?,
            };
            g.add_ring(&corners, keep)?;
        }
        Ok(g)
    }

    /// Append a ring of `corners` [m] (forbidden side on the left).
    fn add_ring(&mut self, corners: &[Vector2<f64>], keep: Keep) -> Result<(), Unplanned> {
        let grid: Option<Vec<Cm>> = corners.iter().map(|p| Cm::from_m(*p)).collect();
        let grid = grid.ok_or(Unplanned::OutOfRange)?;
        let ring = Ring {
            first: self.nodes.len(),
            len: grid.len(),
            keep,
            lo: Cm {
                n: grid.iter().map(|c| c.n).min().unwrap_or(0),
                e: grid.iter().map(|c| c.e).min().unwrap_or(0),
            },
            hi: Cm {
                n: grid.iter().map(|c| c.n).max().unwrap_or(0),
                e: grid.iter().map(|c| c.e).max().unwrap_or(0),
            },
        };
        let index = self.rings.len();
        let n = grid.len();
        for i in 0..n {
            let turn = side(grid[(i + n - 1) % n], grid[i], grid[(i + 1) % n]);
            self.bends
                .push(if turn == Side::Left { Bend::May } else { Bend::Never });
            self.owner.push(Some(index));
        }
        self.nodes.extend(grid);
        self.rings.push(ring);
        Ok(())
    }

    /// Corner `i` of `ring` (indices wrap).
    fn corner(&self, ring: &Ring, i: usize) -> Cm {
        self.nodes[ring.first + i % ring.len]
    }

    /// Whether `p` lies strictly inside the forbidden cone of corner `i` of
    /// `ring`: a convex corner's cone is where both edges have `p` on their
    /// left, a reflex corner's where either has.
    fn in_cone(&self, ring: &Ring, i: usize, p: Cm) -> bool {
        let (prev, here, next) = (
            self.corner(ring, i + ring.len - 1),
            self.corner(ring, i),
            self.corner(ring, i + 1),
        );
        let (after_in, after_out) = (side(prev, here, p) == Side::Left, side(here, next, p) == Side::Left);
        if side(prev, here, next) == Side::Left {
            after_in && after_out
        } else {
            after_in || after_out
        }
    }

    /// Whether the segment from node `k` towards `p` is tangent at `k`:
    /// neither it nor its mirror image about `k` leaves into the forbidden cone.
    fn tangent(&self, k: usize, p: Cm) -> bool {
        let Some(r) = self.owner[k] else {
            return true;
        };
        let ring = &self.rings[r];
        let here = self.nodes[k];
        let mirror = here.twice().plus(Cm { n: -p.n, e: -p.e });
        let i = k - ring.first;
        !self.in_cone(ring, i, p) && !self.in_cone(ring, i, mirror)
    }

    /// Whether the segment `s`-`e` enters the forbidden side of `ring`.
    fn ring_blocks(&self, ring: &Ring, s: Cm, e: Cm) -> bool {
        let apart = s.n.max(e.n) < ring.lo.n
            || s.n.min(e.n) > ring.hi.n
            || s.e.max(e.e) < ring.lo.e
            || s.e.min(e.e) > ring.hi.e;
        if apart {
            return ring.keep == Keep::Inside;
        }
        // the midpoint, doubled to stay on the grid, against the doubled ring
        let mid = s.plus(e);
        let mut winding = 0i32;
        let mut mid_on_border = false;
        for i in 0..ring.len {
            let (a, b) = (self.corner(ring, i + ring.len - 1), self.corner(ring, i));
            match meet(s, e, a, b) {
                Meet::Cross => return true,
                Meet::EndInside if self.in_cone(ring, i, s) || self.in_cone(ring, i, e) => return true,
                _ => {}
            }
            let (a2, b2) = (a.twice(), b.twice());
            match side(a2, b2, mid) {
                Side::On => mid_on_border |= strictly_between(a2, b2, mid) || b2 == mid,
                Side::Left if a2.e <= mid.e && b2.e > mid.e => winding += 1,
                Side::Right if a2.e > mid.e && b2.e <= mid.e => winding -= 1,
                _ => {}
            }
        }
        if mid_on_border {
            return false;
        }
        let inside = winding != 0;
        inside != (ring.keep == Keep::Inside)
    }

    /// Whether the segment `s`-`e` enters any forbidden side.
    fn blocked(&self, s: Cm, e: Cm) -> bool {
        self.rings.iter().any(|r| self.ring_blocks(r, s, e))
    }

    /// Whether nodes `i` and `j` are joined.
    fn joined(&self, i: usize, j: usize) -> bool {
        let (a, b) = (self.nodes[i], self.nodes[j]);
        i != j
            && self.bends[i] == Bend::May
            && self.bends[j] == Bend::May
            && self.tangent(i, b)
            && self.tangent(j, a)
            && !self.blocked(a, b)
    }

    /// Whether node `k` is in sight from the point `p`.
    fn sees(&self, p: Cm, k: usize) -> bool {
        self.bends[k] == Bend::May && self.tangent(k, p) && !self.blocked(p, self.nodes[k])
    }

    /// Length [m] between two grid points.
    fn length(a: Cm, b: Cm) -> f64 {
        (a.to_m() - b.to_m()).norm()
    }

    /// Dijkstra from node 0: each node's distance [m] to it and its next node on the way.
    fn towards_destination(&self) -> (Vec<f64>, Vec<Option<usize>>) {
        let n = self.nodes.len();
        let mut cost = vec![f64::INFINITY; n * n];
        for i in 0..n {
            for j in i + 1..n {
                if self.joined(i, j) {
                    let c = Self::length(self.nodes[i], self.nodes[j]);
                    cost[i * n + j] = c;
                    cost[j * n + i] = c;
                }
            }
        }
        let mut dist = vec![f64::INFINITY; n];
        let mut next = vec![None; n];
        let mut settled = vec![false; n];
        dist[0] = 0.0;
        while let Some(u) = (0..n)
            .filter(|&k| !settled[k] && dist[k].is_finite())
            .min_by(|&a, &b| dist[a].total_cmp(&dist[b]))
        {
            settled[u] = true;
            for v in 0..n {
                let d = dist[u] + cost[u * n + v];
                if !settled[v] && d < dist[v] {
                    dist[v] = d;
                    next[v] = Some(u);
                }
            }
        }
        (dist, next)
    }

    /// The way from `start` to `dest`.
    fn route(mut self, start: Cm, dest: Cm) -> Route {
        self.nodes[0] = dest;
        if self.blocked(dest, dest) {
            return Route::Straight(Unplanned::DestinationOutside);
        }
        let (dist, next) = self.towards_destination();
        let mut first: Option<(f64, usize)> = None;
        for (k, to_dest) in dist.iter().enumerate() {
            if !self.sees(start, k) {
                continue;
            }
            if k == 0 {
                return Route::Direct;
            }
            let c = Self::length(start, self.nodes[k]) + to_dest;
            if c < first.map_or(f64::INFINITY, |(best, _)| best) {
                first = Some((c, k));
            }
        }
        let Some((_, mut k)) = first else {
            return Route::Straight(Unplanned::NoPath);
        };
        let mut path = Vec::new();
        for _ in 0..self.nodes.len() {
            path.push(self.nodes[k].to_m());
            match next[k] {
                Some(j) if j != 0 => k = j,
                _ => break,
            }
        }
        Route::Around(path)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// PX4's margin for a multicopter with NAV_ACC_RAD 2 m.
    const M: f64 = 4.0;

    fn v(n: f64, e: f64) -> Vector2<f64> {
        Vector2::new(n, e)
    }

    fn rect(n0: f64, e0: f64, n1: f64, e1: f64) -> Zone {
        Zone::Polygon(vec![v(n0, e0), v(n1, e0), v(n1, e1), v(n0, e1)])
    }

    fn fence(inclusion: Vec<Zone>, exclusion: Vec<Zone>) -> Fence {
        Fence { inclusion, exclusion }
    }

    fn around(r: Route) -> Vec<Vector2<f64>> {
        match r {
            Route::Around(p) => p,
            other => panic!("expected a path round the fence, got {other:?}"),
        }
    }

    /// Least distance [m] from `p` to the segment `a`-`b`.
    fn to_segment(p: Vector2<f64>, a: Vector2<f64>, b: Vector2<f64>) -> f64 {
        let d = b - a;
        let t = ((p - a).dot(&d) / d.norm_squared()).clamp(0.0, 1.0);
        (a + d * t - p).norm()
    }

    /// Least distance [m] from the polyline `start`, `path`..., `dest` to `p`.
    fn clearance(start: Vector2<f64>, path: &[Vector2<f64>], dest: Vector2<f64>, p: Vector2<f64>) -> f64 {
        let pts: Vec<_> = std::iter::once(start)
            .chain(path.iter().copied())
            .chain([dest])
            .collect();
        pts.windows(2)
            .map(|w| to_segment(p, w[0], w[1]))
            .fold(f64::INFINITY, f64::min)
    }

    /// Whether the polyline enters the axis-aligned box (n0..n1, e0..e1), sampled every 1 cm.
    fn enters_box(pts: &[Vector2<f64>], n0: f64, e0: f64, n1: f64, e1: f64) -> bool {
        pts.windows(2).any(|w| {
            let steps = ((w[1] - w[0]).norm() * 100.0).ceil() as usize;
            (0..=steps).any(|i| {
                let p = w[0] + (w[1] - w[0]) * (i as f64 / steps.max(1) as f64);
                p.x > n0 && p.x < n1 && p.y > e0 && p.y < e1
            })
        })
    }

    #[test]
    fn a_square_exclusion_in_the_way_is_flown_round_one_side_at_the_margin() {
        // home at the origin, the start 100 m north, a 20 m square between
        let f = fence(vec![], vec![rect(40.0, -10.0, 60.0, 10.0)]);
        let (start, home) = (v(100.0, 0.0), v(0.0, 0.0));
        let path = around(plan(&f, M, start, home));
        assert_eq!(path.len(), 2, "{path:?}");
        // the grown square's corners: each corner pushed out by the margin on both edges
        let side = path[0].y.signum();
        assert!((path[0] - v(64.0, 14.0 * side)).norm() < 1e-9, "{path:?}");
        assert!((path[1] - v(36.0, 14.0 * side)).norm() < 1e-9, "{path:?}");
        let pts = [start, path[0], path[1], home];
        assert!(!enters_box(&pts, 40.0, -10.0, 60.0, 10.0));
        // the corners of the zone stay at least the margin away
        for corner in [v(40.0, -10.0), v(40.0, 10.0), v(60.0, -10.0), v(60.0, 10.0)] {
            assert!(clearance(start, &path, home, corner) >= M - 1e-9);
        }
    }

    #[test]
    fn no_fence_or_nothing_in_the_way_is_the_straight_line() {
        let (start, home) = (v(100.0, 0.0), v(0.0, 0.0));
        assert_eq!(plan(&Fence::default(), M, start, home), Route::NoFence);
        let aside = fence(
            vec![rect(-200.0, -200.0, 200.0, 200.0)],
            vec![rect(40.0, 30.0, 60.0, 50.0)],
        );
        assert_eq!(plan(&aside, M, start, home), Route::Direct);
        assert_eq!(plan(&aside, M, home, home), Route::Direct, "start at the destination");
    }

    #[test]
    fn a_destination_on_the_forbidden_side_or_walled_off_is_the_straight_line() {
        let start = v(100.0, 0.0);
        // home inside an exclusion zone, or within the margin of one
        let on_home = fence(vec![], vec![rect(-10.0, -10.0, 10.0, 10.0)]);
        assert_eq!(
            plan(&on_home, M, start, v(0.0, 0.0)),
            Route::Straight(Unplanned::DestinationOutside)
        );
        let near_home = fence(vec![], vec![rect(2.0, -10.0, 20.0, 10.0)]);
        assert_eq!(
            plan(&near_home, M, start, v(0.0, 0.0)),
            Route::Straight(Unplanned::DestinationOutside)
        );
        // a wall across the whole inclusion zone between start and home
        let wall = fence(
            vec![rect(-100.0, -100.0, 100.0, 100.0)],
            vec![rect(40.0, -200.0, 60.0, 200.0)],
        );
        assert_eq!(
            plan(&wall, M, v(90.0, 0.0), v(0.0, 0.0)),
            Route::Straight(Unplanned::NoPath)
        );
        // the start inside the grown exclusion zone sees nothing
        let square = fence(vec![], vec![rect(40.0, -10.0, 60.0, 10.0)]);
        assert_eq!(
            plan(&square, M, v(50.0, 0.0), v(0.0, 0.0)),
            Route::Straight(Unplanned::NoPath)
        );
    }

    #[test]
    fn an_exclusion_circle_is_flown_round_on_its_grown_octagon() {
        let (centre, r) = (v(50.0, 0.0), 10.0);
        let f = fence(vec![], vec![Zone::Circle { centre, radius_m: r }]);
        let (start, home) = (v(100.0, 0.0), v(0.0, 0.0));
        let path = around(plan(&f, M, start, home));
        assert!(!path.is_empty());
        let corner_radius = r / (std::f64::consts::PI / 8.0).cos() + M;
        for p in &path {
            assert!(((p - centre).norm() - corner_radius).abs() < 0.01, "{p:?}");
        }
        // the octagon's edges keep the circle the margin times cos(pi/8) away
        let clear = clearance(start, &path, home, centre);
        assert!(clear >= r + M * (std::f64::consts::PI / 8.0).cos() - 0.01, "{clear}");
        assert!(path.windows(2).all(|w| (w[0] - home).norm() > (w[1] - home).norm()));
    }

    #[test]
    fn an_inclusion_is_kept_inside_of_and_its_bends_lie_the_margin_inside() {
        // an L: the straight line from one arm to the other cuts the notch
        let l = Zone::Polygon(vec![
            v(0.0, 0.0),
            v(100.0, 0.0),
            v(100.0, 40.0),
            v(40.0, 40.0),
            v(40.0, 100.0),
            v(0.0, 100.0),
        ]);
        let f = fence(vec![l], vec![]);
        let path = around(plan(&f, M, v(90.0, 20.0), v(20.0, 90.0)));
        assert_eq!(path, vec![v(36.0, 36.0)]);
        // an inclusion circle: its corners are never bends, an exclusion inside is flown round
        let f = fence(
            vec![Zone::Circle {
                centre: v(0.0, 0.0),
                radius_m: 200.0,
            }],
            vec![Zone::Circle {
                centre: v(50.0, 0.0),
                radius_m: 10.0,
            }],
        );
        let path = around(plan(&f, M, v(100.0, 0.0), v(0.0, 0.0)));
        assert!(path.iter().all(|p| p.norm() < 100.0), "{path:?}");
    }

    #[test]
    fn a_fence_px4_does_not_plan_on_is_the_straight_line() {
        let (start, home) = (v(100.0, 0.0), v(0.0, 0.0));
        let bow_tie = Zone::Polygon(vec![v(40.0, -10.0), v(60.0, 10.0), v(60.0, -10.0), v(40.0, 10.0)]);
        assert_eq!(
            plan(&fence(vec![], vec![bow_tie]), M, start, home),
            Route::Straight(Unplanned::Degenerate)
        );
        // MAVSDK's example: a zero-radius inclusion circle beside the polygon
        let dot = Zone::Circle {
            centre: v(0.0, 0.0),
            radius_m: 0.0,
        };
        let with_dot = fence(vec![rect(-200.0, -200.0, 200.0, 200.0), dot], vec![]);
        assert_eq!(plan(&with_dot, M, start, home), Route::Straight(Unplanned::Degenerate));
        let narrow = Zone::Circle {
            centre: v(0.0, 0.0),
            radius_m: M,
        };
        assert_eq!(
            plan(&fence(vec![narrow], vec![]), M, start, home),
            Route::Straight(Unplanned::Degenerate)
        );
        let many: Vec<Zone> = (0..17)
            .map(|i| rect(1000.0 + 30.0 * f64::from(i), 0.0, 1010.0 + 30.0 * f64::from(i), 10.0))
            .collect();
        assert_eq!(
            plan(&fence(vec![], many), M, start, home),
            Route::Straight(Unplanned::Budget)
        );
        assert_eq!(Unplanned::Degenerate.fence_code(), Some(7));
        assert_eq!(Unplanned::NoPath.fence_code(), None);
    }

    #[test]
    fn a_sharp_corner_is_cut_off_at_the_margin() {
        // a thin triangle, its tip (20 degrees) pointing north
        let tip = v(100.0, 0.0);
        let tri = vec![v(0.0, -10.0), tip, v(0.0, 10.0)];
        let grown = grown_polygon(&tri, Keep::Outside, M).expect("a simple polygon");
        assert_eq!(grown.len(), 4, "the tip split in two: {grown:?}");
        let cut: Vec<_> = grown.iter().filter(|p| p.x > 100.0).collect();
        assert_eq!(cut.len(), 2, "{grown:?}");
        assert!(((cut[0] + cut[1]) / 2.0 - v(100.0 + M, 0.0)).norm() < 1e-9);
        // every grown corner lies the margin off the edges it was offset from, none nearer
        for p in &grown {
            let d = (0..3)
                .map(|i| to_segment(*p, tri[i], tri[(i + 1) % 3]))
                .fold(f64::INFINITY, f64::min);
            assert!(d >= M - 1e-9, "{p:?} {d}");
        }
        assert_eq!(most_corners(3), 5, "two of a triangle's corners can be sharp");
        assert_eq!(most_corners(4), 7);
    }

    #[test]
    fn touching_and_sliding_along_a_border_is_allowed_crossing_is_not() {
        let g = Graph::build(&fence(vec![], vec![rect(0.0, 0.0, 10.0, 10.0)]), 0.0).expect("a square");
        let c = |n: i64, e: i64| Cm { n: n * 100, e: e * 100 };
        assert!(!g.blocked(c(-5, 0), c(15, 0)), "along an edge");
        assert!(!g.blocked(c(-5, -5), c(0, 0)), "to a corner");
        assert!(!g.blocked(c(-5, 5), c(5, 15)), "through a corner, outside");
        assert!(g.blocked(c(-5, -5), c(15, 15)), "through two corners, across");
        assert!(g.blocked(c(-5, 5), c(15, 5)), "across");
        assert!(g.blocked(c(5, 5), c(5, 5)), "a point inside");
        assert!(!g.blocked(c(10, 5), c(10, 5)), "a point on the border");
    }
}
