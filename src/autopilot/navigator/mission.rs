//! AUTO.MISSION: the stored mission flown item by item, as PX4's navigator
//! flies it.
//!
//! * **Items done at once** (no time passes): DO_CHANGE_SPEED (p2 > 0 the
//!   cruise speed, -2 back to MPC_XY_CRUISE), DO_JUMP (to item p1, p2
//!   more times; -1 forever; the counters restart with the mission),
//!   DO_SET_HOME (p1 = 1 here, else the item's position), and the camera,
//!   gimbal, servo, ROI and VTOL items (nothing to do in a simulator).
//! * **Positional items** (waypoint, the loiters, land, takeoff) are flown
//!   as a path: the reference chases a point `L` ahead of it along the
//!   polyline from where the leg began through the item's point and, when
//!   the item flies through (hold time 0 and a positional item follows),
//!   on along the next leg. `L = v / k1` is the distance at which the
//!   shaper's position loop asks for exactly the speed `v` (cruise), so the
//!   vehicle cruises along the legs, cuts corners within its acceleration
//!   limit instead of stopping, and slows only where it must stop.
//! * **Reached**: within the acceptance radius (p2, else NAV_ACC_RAD)
//!   horizontally and NAV_MC_ALT_RAD vertically, measured; a fly-through
//!   item also when the reference has passed it, within NAV_MC_ALT_RAD.
//!   Passed off its altitude (a home moved under a relative mission) the
//!   item is missed: the leg starts again where the vehicle is and turns
//!   back to the point, as PX4 re-anchors it. Then the hold time (p1,
//!   simulated time), the loiter time, the loiter turns (circles of radius
//!   |p3|) or the delay runs before the next item; LOITER_UNLIM never ends.
//! * **Takeoff**: NAV_TAKEOFF climbs where the vehicle is to the item's
//!   altitude (at least MIS_TAKEOFF_ALT), at MPC_TKO_SPEED below MPC_LAND_ALT1
//!   above home and MPC_Z_V_AUTO_UP above (as Takeoff); any other first item
//!   flown from the ground takes off the same way first (PX4's automatic
//!   takeoff) to the higher of MIS_TAKEOFF_ALT and the item's altitude.
//! * **Land** flies to the point at its altitude, then descends as Land
//!   does; the item is reached on touchdown. **RTL** hands over to Return
//!   (the mode clients see is RTL, as PX4's) and the mission is complete.
//! * Heading: the item's yaw (p4, degrees) when given, else along the leg
//!   (PX4's MPC_YAW_MODE 0); kept on short legs.
//!
//! The end: complete, holding at the last point (still AUTO.MISSION, as
//! PX4), or on the ground after a landing (disarmed by COM_DISARM_LAND).

use nalgebra::Vector3;

use super::{Nav, Navigator, Situation};
use crate::autopilot::control_loop::Demand;
use crate::autopilot::status::{Announcements, Severity};
use crate::control::{Reference, Setpoint, TranslationSetpoint, YawSetpoint};
use crate::geo::GeoPoint;
use crate::mission::{MissionItem, cmd};

/// Items done at once are at most this many per step (a DO_JUMP loop of DO items cannot hang the step).
const MAX_INSTANT_ITEMS: usize = 64;
/// A leg shorter than this [m] horizontally keeps the heading.
const YAW_MIN_LEG_M: f64 = 1.0;
/// A fly-through point where the path turns by more than this [rad] is flown to a stop.
const MAX_FLY_THROUGH_TURN_RAD: f64 = 2.0 * std::f64::consts::FRAC_PI_3;
/// A reference this much farther [m] from a point than its closest approach is leaving it.
const LEAVING_M: f64 = 0.05;
/// Circle radius [m] of LOITER_TURNS when the item gives none.
const DEFAULT_LOITER_RADIUS_M: f64 = 5.0;

/// Where the mission stands (MISSION_CURRENT's seq and, with the mode, its state).
#[derive(Clone, Debug, Default, PartialEq)]
pub(in crate::autopilot) struct MissionRun {
    /// The current item (MAVLink seq).
    current: usize,
    /// Flown since it was stored (or restarted).
    started: bool,
    /// The last item is done.
    complete: bool,
    /// DO_JUMP repeats left, by item (`None`: not met yet this run).
    jumps: Vec<Option<i32>>,
    /// The current item's progress.
    phase: Phase,
    /// Items reached or run since the autopilot last took them, oldest first.
    pub(super) done: Vec<ItemDone>,
    /// A DO_SET_HOME the autopilot must apply.
    pub(super) new_home: Option<SetHome>,
    /// The points and heading of the leg flown, already computed.
    memo: LegMemo,
}

/// What a leg asks for every step and changes only with the leg, kept with
/// the exact bits of its inputs (the same values, computed once per change):
/// the last two item points converted from latitude and longitude (the
/// current and the next item's; each costs a cosine), keyed on the item, the
/// origin and home's altitude, and the leg's heading (an `atan2`).
#[derive(Clone, Debug, Default)]
struct LegMemo {
    points: [Option<PointEntry>; 2],
    /// The entry of `points` replaced next.
    next: usize,
    /// `(d_x, d_y)` bits and `atan2(d_y, d_x)`.
    heading: Option<(u64, u64, f64)>,
}

/// An item, the bits of the origin's latitude, longitude, altitude and of
/// home's altitude, and the item's point [m], NED.
type PointEntry = (MissionItem, [u64; 4], Vector3<f64>);

/// A memo holds no state of the mission: two runs are equal whatever it holds.
impl PartialEq for LegMemo {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl LegMemo {
    /// [`item_point_ned`] of `item`; an item without a point of its own
    /// (`here`'s position) is not kept.
    fn point(&mut self, item: &MissionItem, origin: &GeoPoint, home: &GeoPoint, here: &Vector3<f64>) -> Vector3<f64> {
        let key = [
            origin.lat_deg.to_bits(),
            origin.lon_deg.to_bits(),
            origin.alt_amsl_m.to_bits(),
            home.alt_amsl_m.to_bits(),
        ];
        let hit = self.points.iter().flatten().find(|(it, k, _)| it == item && *k == key);
        if let Some((_, _, p)) = hit {
            return *p;
        }
        let p = item_point_ned(item, origin, home, here);
        if item.geo_point(home.alt_amsl_m).is_some() {
            self.points[self.next] = Some((*item, key, p));
            self.next = 1 - self.next;
        }
        p
    }

    /// The heading [rad] of the horizontal direction `(d_x, d_y)`, `atan2(d_y, d_x)`.
    fn heading(&mut self, d_x: f64, d_y: f64) -> f64 {
        match self.heading {
            Some((x, y, psi)) if x == d_x.to_bits() && y == d_y.to_bits() => psi,
            _ => {
                let psi = d_y.atan2(d_x);
                self.heading = Some((d_x.to_bits(), d_y.to_bits(), psi));
                psi
            }
        }
    }
}

/// A mission item done, by MAVLink seq: a navigation item whose point (or
/// end: a landing, a return) was reached, as MISSION_ITEM_REACHED tells it,
/// or an item done at once (DO_CHANGE_SPEED, DO_JUMP, DO_SET_HOME, the no-ops)
/// that ran, which MISSION_ITEM_REACHED does not tell.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ItemDone {
    /// A navigation item reached.
    Reached(u16),
    /// An item done at once ran.
    Ran(u16),
}

/// What DO_SET_HOME asks for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(in crate::autopilot) enum SetHome {
    /// Where the vehicle is.
    Here,
    /// At this point.
    At(GeoPoint),
}

/// Progress through the current item.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
enum Phase {
    /// Not begun: the leg starts where the reference is when it does.
    #[default]
    Begin,
    /// Climbing from the ground to this NED z [m] before flying the item.
    TakeOff {
        /// Target [m], NED.
        target_ned: Vector3<f64>,
    },
    /// Flying the leg from `from` towards the item's point.
    Leg {
        /// Where the leg began [m], NED.
        from: Vector3<f64>,
        /// The reference's closest approach to the point so far [m].
        closest_m: f64,
    },
    /// At the point (or, for a delay, anywhere) until `until_s` [s] (`None`: forever).
    Wait {
        /// Where to hold [m], NED.
        at: Vector3<f64>,
        /// End of the wait, simulated time [s].
        until_s: Option<f64>,
    },
    /// Circling the point from `start_s` [s] until `until_s` [s].
    Circle {
        /// Centre [m], NED.
        centre: Vector3<f64>,
        /// Radius [m].
        radius_m: f64,
        /// Angular rate [rad/s], signed (positive clockwise seen from above).
        rate_rad_s: f64,
        /// Angle from north at `start_s` [rad].
        angle0_rad: f64,
        /// Start [s].
        start_s: f64,
        /// End [s].
        until_s: f64,
    },
    /// Descending to land at the point's horizontal position.
    Descend {
        /// Where [m], NED (z unused).
        at: Vector3<f64>,
    },
}

impl Phase {
    /// A leg beginning at `from`.
    fn leg(from: Vector3<f64>) -> Self {
        Phase::Leg {
            from,
            closest_m: f64::INFINITY,
        }
    }
}

impl MissionRun {
    /// The current item (MAVLink seq).
    pub(in crate::autopilot) fn current(&self) -> usize {
        self.current
    }

    /// Flown since it was stored (or restarted).
    pub(in crate::autopilot) fn started(&self) -> bool {
        self.started
    }

    /// The last item is done.
    pub(in crate::autopilot) fn complete(&self) -> bool {
        self.complete
    }

    /// A new or cleared mission: from the first item, not started, counters reset.
    pub(in crate::autopilot) fn reset(&mut self) {
        *self = MissionRun {
            done: std::mem::take(&mut self.done),
            new_home: self.new_home.take(),
            ..MissionRun::default()
        };
    }

    /// Make `seq` current (its leg begins where the vehicle is); a completed mission is open again.
    pub(in crate::autopilot) fn set_current(&mut self, seq: usize) {
        self.current = seq;
        self.complete = false;
        self.phase = Phase::Begin;
    }

    /// Resume (or start) flying: the current item's leg begins where the vehicle is;
    /// a completed mission starts over.
    pub(in crate::autopilot) fn resume(&mut self) {
        if self.complete {
            self.reset();
        }
        self.started = true;
        self.phase = Phase::Begin;
    }

    fn reach(&mut self, seq: usize) {
        self.done
            .push(ItemDone::Reached(u16::try_from(seq).unwrap_or(u16::MAX)));
    }

    /// Item `seq`, done at once (DO_*), ran.
    fn ran(&mut self, seq: usize) {
        self.done.push(ItemDone::Ran(u16::try_from(seq).unwrap_or(u16::MAX)));
    }

    fn next(&mut self) {
        self.current += 1;
        self.phase = Phase::Begin;
    }
}

/// An item's point [m], NED: its latitude, longitude and altitude in its
/// frame (relative frames from home's altitude; terrain is flat, so above
/// home too); NaN latitude and longitude mean `here`'s horizontal position.
pub(in crate::autopilot) fn item_point_ned(
    item: &MissionItem,
    origin: &GeoPoint,
    home: &GeoPoint,
    here: &Vector3<f64>,
) -> Vector3<f64> {
    match item.geo_point(home.alt_amsl_m) {
        Some(g) => g.ned_from(origin),
        None => Vector3::new(here.x, here.y, origin.alt_amsl_m - item.alt_amsl(home.alt_amsl_m)),
    }
}

/// The point `lookahead` [m] along `path` ahead of the projection of `p` on
/// its first segment (clamped to the last point).
fn carrot(path: &[Vector3<f64>], p: &Vector3<f64>, lookahead: f64) -> Vector3<f64> {
    let (a, b) = (path[0], path[1]);
    let seg = b - a;
    let len = seg.norm();
    let along = if len > 1e-9 {
        ((p - a).dot(&seg) / len).clamp(0.0, len)
    } else {
        len
    };
    let mut left = lookahead;
    let mut from = if len > 1e-9 { a + seg * (along / len) } else { b };
    for w in path.windows(2).map(|w| w[1]) {
        let d = (w - from).norm();
        if d >= left && d > 1e-9 {
            return from + (w - from) * (left / d);
        }
        left -= d;
        from = w;
    }
    from
}

/// Whether the path `a -> b -> c` turns by more than [`MAX_FLY_THROUGH_TURN_RAD`] at `b`.
fn sharp_turn(a: &Vector3<f64>, b: &Vector3<f64>, c: &Vector3<f64>) -> bool {
    match ((b - a).try_normalize(1e-6), (c - b).try_normalize(1e-6)) {
        (Some(u1), Some(u2)) => u1.dot(&u2) < MAX_FLY_THROUGH_TURN_RAD.cos(),
        _ => false,
    }
}

/// Whether `p` is past the corner `b` of the path `a -> b -> c`: beyond the
/// plane through `b` that bisects the turn, normal `u_ab + u_bc`
/// (perpendicular to the path when it runs straight on). A reversal has no
/// such plane: never.
fn past_corner(a: &Vector3<f64>, b: &Vector3<f64>, c: &Vector3<f64>, p: &Vector3<f64>) -> bool {
    let (u1, u2) = ((b - a).try_normalize(1e-9), (c - b).try_normalize(1e-9));
    let n = match (u1, u2) {
        (Some(u1), Some(u2)) => u1 + u2,
        (None, Some(u)) | (Some(u), None) => u,
        (None, None) => return true,
    };
    n.norm() > 1e-6 && (p - b).dot(&n) >= 0.0
}

/// A waypoint's hold time [s] (p1; NaN or negative: none).
fn hold_s(it: &MissionItem) -> f64 {
    let p1 = f64::from(it.params[0]);
    if p1 > 0.0 { p1 } else { 0.0 }
}

fn deg_or_none(v: f32) -> Option<f64> {
    v.is_finite().then(|| f64::from(v).to_radians())
}

impl Navigator {
    /// Fly the mission: the demand for this step (may advance items, complete
    /// the mission, or hand over to Return).
    #[allow(clippy::too_many_lines)]
    pub(super) fn mission_demand(&mut self, cx: &Situation<'_>, say: &mut Announcements) -> Demand {
        let items = cx.mission;
        let now = cx.meas.time_s;
        // items done at once
        let mut guard = 0;
        while self.mission.current < items.len() && guard < MAX_INSTANT_ITEMS {
            guard += 1;
            let seq = self.mission.current;
            let it = items[seq];
            match it.command {
                cmd::DO_CHANGE_SPEED => {
                    let v = f64::from(it.params[1]);
                    if v > 0.0 {
                        self.set_cruise(Some(v.min(cx.settings.xy_vel_max_m_s)));
                    } else if v == -2.0 {
                        self.set_cruise(None);
                    }
                    self.mission.ran(seq);
                    self.mission.next();
                }
                cmd::DO_JUMP => {
                    let target = f64::from(it.params[0]) as usize;
                    let repeat = f64::from(it.params[1]) as i32;
                    if self.mission.jumps.len() < items.len() {
                        self.mission.jumps.resize(items.len(), None);
                    }
                    self.mission.ran(seq);
                    let left = self.mission.jumps[seq].get_or_insert(repeat);
                    if target < items.len() && (*left == -1 || *left > 0) {
                        if *left > 0 {
                            *left -= 1;
                        }
                        self.mission.set_current(target);
                    } else {
                        self.mission.next();
                    }
                }
                cmd::DO_SET_HOME => {
                    self.mission.new_home = Some(if it.params[0] == 1.0 || it.x.is_nan() {
                        SetHome::Here
                    } else {
                        SetHome::At(GeoPoint {
                            lat_deg: it.x,
                            lon_deg: it.y,
                            alt_amsl_m: it.alt_amsl(cx.home.alt_amsl_m),
                        })
                    });
                    self.mission.ran(seq);
                    self.mission.next();
                }
                c if cmd::NO_OPS.contains(&c) => {
                    self.mission.ran(seq);
                    self.mission.next();
                }
                _ => break,
            }
        }
        if self.mission.current >= items.len() {
            return self.mission_end(cx, say);
        }
        let seq = self.mission.current;
        let it = items[seq];
        if it.command == cmd::NAV_RETURN_TO_LAUNCH {
            self.mission.reach(seq);
            self.mission.complete = true;
            self.enter_rtl(cx, say);
            return self.mode_demand(cx, say);
        }
        let here_ref = self.current_position(cx.meas);
        let point = self.mission.memo.point(&it, cx.origin, cx.home, &here_ref);
        if it.command == cmd::NAV_DELAY && self.mission.phase == Phase::Begin {
            let until = now + f64::from(it.params[0]).max(0.0);
            self.mission.phase = Phase::Wait {
                at: here_ref,
                until_s: Some(until),
            };
        }
        // begin: from the ground, take off first
        if self.mission.phase == Phase::Begin {
            let z_min = cx.home_ned.z - cx.settings.takeoff_alt_m;
            if it.command == cmd::NAV_TAKEOFF {
                let z = point.z.min(z_min).min(here_ref.z);
                self.mission.phase = Phase::TakeOff {
                    target_ned: Vector3::new(here_ref.x, here_ref.y, z),
                };
                say.announce(
                    Severity::Info,
                    format!("Mission takeoff to {:.1} m above home", cx.home_ned.z - z),
                );
            } else if cx.resting && it.command != cmd::NAV_LAND {
                let z = point.z.min(z_min);
                self.mission.phase = Phase::TakeOff {
                    target_ned: Vector3::new(here_ref.x, here_ref.y, z),
                };
                say.announce(Severity::Info, "Mission: taking off first");
            } else {
                self.mission.phase = Phase::leg(here_ref);
            }
        }
        let s = cx.settings;
        let cruise = self.cruise_m_s(s);
        let normal = self.limits(cruise, s.auto_climb_m_s, s.auto_descent_m_s);
        let hold_yaw = YawSetpoint::Hold;
        let item_yaw = deg_or_none(it.params[3]);
        match self.mission.phase {
            // replaced above
            Phase::Begin => Demand::Idle,
            Phase::TakeOff { target_ned } => {
                let height_m = cx.home_ned.z - cx.meas.position_ned.z;
                let limits = self.limits(cruise, s.takeoff_climb_m_s(height_m), s.auto_descent_m_s);
                let r = self.go_to(cx.meas, target_ned, hold_yaw, limits, cx.dt);
                if super::arrived(&r, &target_ned) && (cx.meas.position_ned.z - target_ned.z).abs() < s.mc_alt_radius_m
                {
                    if it.command == cmd::NAV_TAKEOFF {
                        self.mission.reach(seq);
                        self.mission.next();
                    } else {
                        self.mission.phase = Phase::leg(target_ned);
                    }
                }
                Demand::Track(r)
            }
            Phase::Leg { from, closest_m } => {
                let fly_through = it.command == cmd::NAV_WAYPOINT && hold_s(&it) == 0.0;
                // flown through unless the path turns back sharply there (then it stops, as PX4 slows to a stop)
                let next = fly_through
                    .then(|| self.next_point(cx, seq + 1, &point))
                    .flatten()
                    .filter(|n| !sharp_turn(&from, &point, n));
                let mut target = point;
                if it.command == cmd::NAV_LAND {
                    // fly there at the altitude the leg began, then descend
                    target.z = from.z;
                }
                let through = [from, target, next.unwrap_or(target)];
                let path = if next.is_some() { &through[..] } else { &through[..2] };
                let heading = if (target.xy() - from.xy()).norm() > YAW_MIN_LEG_M {
                    let d = target - from;
                    Some(self.mission.memo.heading(d.x, d.y))
                } else {
                    None
                };
                let yaw = item_yaw.or(heading).map_or(YawSetpoint::Hold, YawSetpoint::Angle);
                let r = self.follow(cx, path, yaw, normal);
                // past a fly-through point: beyond the corner's bisector and
                // moving away from the point (never at the start of a leg
                // that doubles back on itself, as a DO_JUMP loop does)
                let d = (r.position_ned - target).norm();
                let leaving = d > closest_m + LEAVING_M;
                let passed = leaving && next.is_some_and(|n| past_corner(&from, &target, &n, &r.position_ned));
                if let Phase::Leg { closest_m, .. } = &mut self.mission.phase {
                    *closest_m = closest_m.min(d);
                }
                let acc = if it.params[1] > 0.0 && it.command == cmd::NAV_WAYPOINT {
                    f64::from(it.params[1])
                } else {
                    s.acceptance_radius_m
                };
                let off = cx.meas.position_ned - target;
                let at_altitude = off.z.abs() <= s.mc_alt_radius_m;
                if at_altitude && (passed || off.xy().norm() <= acc) {
                    self.item_reached(cx, seq, &it, target, say);
                } else if passed {
                    // missed: past the point, off its altitude; the leg starts
                    // again where the vehicle is, so it turns back to the point
                    self.mission.phase = Phase::leg(cx.meas.position_ned);
                }
                Demand::Track(r)
            }
            Phase::Wait { at, until_s } => {
                let done = until_s.is_some_and(|u| now >= u - crate::autopilot::TIME_EPS);
                if done {
                    if it.command == cmd::NAV_DELAY {
                        self.mission.reach(seq);
                    }
                    self.mission.next();
                }
                if cx.resting {
                    return Demand::Idle;
                }
                let yaw = item_yaw.map_or(hold_yaw, YawSetpoint::Angle);
                Demand::Track(self.go_to(cx.meas, at, yaw, normal, cx.dt))
            }
            Phase::Circle {
                centre,
                radius_m,
                rate_rad_s,
                angle0_rad,
                start_s,
                until_s,
            } => {
                let a = angle0_rad + rate_rad_s * (now - start_s);
                let p = centre + Vector3::new(radius_m * a.cos(), radius_m * a.sin(), 0.0);
                let r = self.go_to(cx.meas, p, hold_yaw, normal, cx.dt);
                if now >= until_s - crate::autopilot::TIME_EPS {
                    self.mission.next();
                }
                Demand::Track(r)
            }
            Phase::Descend { at } => {
                if cx.landed {
                    self.mission.reach(seq);
                    self.mission.next();
                    if self.mission.current >= items.len() {
                        return self.mission_end(cx, say);
                    }
                    return Demand::Idle;
                }
                if cx.resting {
                    return Demand::Idle;
                }
                Demand::Track(self.descend(cx, at.xy()))
            }
        }
    }

    /// The point of the next positional item after `from_seq` (skipping items
    /// done at once), if the path continues through it.
    fn next_point(&mut self, cx: &Situation<'_>, from_seq: usize, here: &Vector3<f64>) -> Option<Vector3<f64>> {
        let items = cx.mission;
        let mut k = from_seq;
        while k < items.len() {
            let it = &items[k];
            match it.command {
                cmd::NAV_WAYPOINT
                | cmd::NAV_LOITER_TIME
                | cmd::NAV_LOITER_UNLIM
                | cmd::NAV_LOITER_TURNS
                | cmd::NAV_LOITER_TO_ALT => {
                    if it.x.is_nan() {
                        return None;
                    }
                    return Some(self.mission.memo.point(it, cx.origin, cx.home, here));
                }
                cmd::DO_CHANGE_SPEED | cmd::DO_SET_HOME => k += 1,
                c if cmd::NO_OPS.contains(&c) => k += 1,
                _ => return None,
            }
        }
        None
    }

    /// The reference following `path` at the cruise speed (a point `L = v / k1` ahead).
    fn follow(
        &mut self,
        cx: &Situation<'_>,
        path: &[Vector3<f64>],
        yaw: YawSetpoint,
        limits: crate::control::ShaperLimits,
    ) -> Reference {
        if *self.shaper.limits() != limits {
            let _ = self.shaper.set_limits(limits);
        }
        let k1 = self.shaper.position_gain();
        let lookahead = if k1 > 0.0 { limits.max_speed_xy_m_s / k1 } else { 0.0 };
        let p = self.current_position(cx.meas);
        let c = carrot(path, &p, lookahead);
        self.shape(
            cx.meas,
            Setpoint {
                translation: TranslationSetpoint::Position(c),
                yaw,
            },
            limits,
            cx.dt,
        )
    }

    /// Item `seq` reached at its point: announce, then hold, loiter, descend or go on.
    fn item_reached(
        &mut self,
        cx: &Situation<'_>,
        seq: usize,
        it: &MissionItem,
        point: Vector3<f64>,
        say: &mut Announcements,
    ) {
        let now = cx.meas.time_s;
        let p1 = f64::from(it.params[0]);
        match it.command {
            cmd::NAV_LAND => {
                self.mission.phase = Phase::Descend { at: point };
                say.announce(Severity::Info, "Mission: landing");
                return;
            }
            cmd::NAV_LOITER_UNLIM => {
                self.mission.phase = Phase::Wait {
                    at: point,
                    until_s: None,
                };
            }
            cmd::NAV_LOITER_TIME => {
                self.mission.phase = Phase::Wait {
                    at: point,
                    until_s: Some(now + p1.max(0.0)),
                };
            }
            cmd::NAV_LOITER_TURNS => {
                let p3 = f64::from(it.params[2]);
                let radius = if p3.is_finite() && p3.abs() > 0.1 {
                    p3.abs()
                } else {
                    DEFAULT_LOITER_RADIUS_M
                };
                let speed = self.cruise_m_s(cx.settings);
                let rate = speed / radius * if p3 < 0.0 { -1.0 } else { 1.0 };
                let turns = p1.max(0.0);
                // the circle passes through the point (entered heading east when clockwise)
                self.mission.phase = Phase::Circle {
                    centre: point - Vector3::new(radius, 0.0, 0.0),
                    radius_m: radius,
                    rate_rad_s: rate,
                    angle0_rad: 0.0,
                    start_s: now,
                    until_s: now + turns * std::f64::consts::TAU / rate.abs(),
                };
            }
            _ => {
                let hold = if it.command == cmd::NAV_WAYPOINT && p1 > 0.0 {
                    p1
                } else {
                    0.0
                };
                if hold > 0.0 {
                    self.mission.phase = Phase::Wait {
                        at: point,
                        until_s: Some(now + hold),
                    };
                } else {
                    // nothing to wait for: the next leg starts at this point, flown through
                    self.mission.reach(seq);
                    self.mission.next();
                    if self.mission.current < cx.mission.len() {
                        self.mission.phase = Phase::leg(point);
                    }
                    return;
                }
            }
        }
        self.mission.reach(seq);
    }

    /// After the last item: complete; hold at the last point, or rest on the ground.
    fn mission_end(&mut self, cx: &Situation<'_>, say: &mut Announcements) -> Demand {
        if !self.mission.complete {
            self.mission.complete = true;
            say.announce(Severity::Info, "Mission finished");
        }
        if cx.resting {
            return Demand::Idle;
        }
        let r = self.shape(
            cx.meas,
            Setpoint {
                translation: TranslationSetpoint::Hold,
                yaw: YawSetpoint::Hold,
            },
            self.limits(
                self.cruise_m_s(cx.settings),
                cx.settings.auto_climb_m_s,
                cx.settings.auto_descent_m_s,
            ),
            cx.dt,
        );
        Demand::Track(r)
    }

    /// Whether the mission is landing (for the landed state).
    pub(in crate::autopilot) fn mission_landing(&self) -> bool {
        matches!(self.mission.phase, Phase::Descend { .. })
    }

    /// Whether the mission is taking off (for the landed state).
    pub(in crate::autopilot) fn mission_taking_off(&self) -> bool {
        matches!(self.mission.phase, Phase::TakeOff { .. })
    }

    /// Enter AUTO.MISSION (resuming where it stands).
    pub(in crate::autopilot) fn enter_mission(&mut self) {
        self.mission.resume();
        self.nav = Nav::Mission;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_carrot_walks_on_along_the_next_leg() {
        let path = [
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(10.0, 0.0, 0.0),
            Vector3::new(10.0, 10.0, 0.0),
        ];
        let c = carrot(&path, &Vector3::new(2.0, 1.0, 0.0), 3.0);
        assert!((c - Vector3::new(5.0, 0.0, 0.0)).norm() < 1e-12);
        let c = carrot(&path, &Vector3::new(8.0, 0.0, 0.0), 5.0);
        assert!((c - Vector3::new(10.0, 3.0, 0.0)).norm() < 1e-12);
        let c = carrot(&path, &Vector3::new(12.0, 0.0, 0.0), 50.0);
        assert!((c - path[2]).norm() < 1e-12);
    }

    #[test]
    fn a_corner_is_passed_beyond_its_bisector() {
        let (a, b, c) = (
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(10.0, 0.0, 0.0),
            Vector3::new(10.0, 10.0, 0.0),
        );
        assert!(!past_corner(&a, &b, &c, &Vector3::new(8.0, 1.0, 0.0)));
        assert!(past_corner(&a, &b, &c, &Vector3::new(9.0, 1.5, 0.0)));
        // straight on: the perpendicular plane
        let d = Vector3::new(20.0, 0.0, 0.0);
        assert!(!past_corner(&a, &b, &d, &Vector3::new(9.99, 3.0, 0.0)));
        assert!(past_corner(&a, &b, &d, &Vector3::new(10.01, 3.0, 0.0)));
        // a reversal: never by the plane
        assert!(!past_corner(&a, &b, &a, &Vector3::new(10.0, 0.0, 0.0)));
    }
}
