//! Follow target (AUTO.FOLLOW_TARGET): fly at a distance, height and angle
//! from a moving target whose positions a client sends (MAVLink
//! FOLLOW_TARGET), as PX4's follow-target flight task flies it.
//!
//! * The target: the latest fix (position, velocity when the client gives
//!   one, else the difference of the last two fixes), predicted to now at
//!   constant velocity, `p_t = p_fix + v_fix (t - t_fix)`. A fix older than
//!   [`TARGET_STALE_S`] (PX4's `GPS_MESSAGE_STALE_TIMEOUT_MS`) is lost: the
//!   vehicle holds where it is until fixes come again (PX4's task keeps the
//!   position then).
//! * PX4's second-order target filter (natural frequency
//!   [`FILTER_OMEGA_RAD_S`], damping [`FILTER_ZETA`], the prediction's
//!   velocity as rate feed-forward) smooths it:
//!   `x'' = w^2 (p_t - x) + 2 zeta w (v_t - x')`; it restarts at the target
//!   after a gap longer than [`FILTER_RESET_S`].
//! * The target's course is the direction of its filtered velocity, kept
//!   while it moves slower than [`COURSE_DEADZONE_M_S`]. The follow angle
//!   `FLW_TGT_FA` is measured from the course, clockwise (180 deg: behind);
//!   the orbit angle `theta` moves to `course + FLW_TGT_FA` at most at
//!   `FLW_TGT_MAX_VEL / FLW_TGT_DST` rad/s. On entry `theta` is where the
//!   vehicle already is, seen from the target, and the course the one that
//!   puts the follow angle there; a vehicle within [`YAW_MIN_DISTANCE_M`]
//!   of the target starts as PX4's task always does, both north (0).
//! * Desired position `p_d = x + FLW_TGT_DST [cos theta, sin theta, 0]`
//!   (NED), its height `FLW_TGT_HT` above home (`FLW_TGT_ALT_M` 0, and 1
//!   over this flat ground), never lower than where the mode started, or
//!   `FLW_TGT_HT` above the filtered target (`FLW_TGT_ALT_M` 2).
//! * More than [`ALT_ACCEPTANCE_M`] off that height the vehicle first climbs
//!   or descends where it is; within it, it flies `p_d` with the filtered
//!   target velocity and acceleration as feed-forward
//!   ([`TranslationSetpoint::Track`]), plus the velocity at which the
//!   sticks (below) move `p_d`, the nose to the target once more
//!   than [`YAW_MIN_DISTANCE_M`] away, horizontal speed under `MPC_XY_VEL_MAX`.
//! * The pilot's sticks (MANUAL_CONTROL) move the follow geometry, as in
//!   PX4's task: throttle the height at up to [`HEIGHT_ADJUST_M_S`], pitch
//!   the distance at up to [`DISTANCE_ADJUST_M_S`], roll the angle at up to
//!   `min(ANGLE_ADJUST_RAD_S, FLW_TGT_MAX_VEL / d)` (right: clockwise), each
//!   stick through PX4's expo and deadzone, `x' = s expo(deadzone(stick))`.
//!   Each moves only while the vehicle is within [`ADJUST_WINDOW_S`] of
//!   that speed of what it adjusts (the previous height setpoint, the
//!   distance, the orbit angle), so that the setpoint never runs away from
//!   it. A stick moves distance and height within `[1, 100]` m (a
//!   parameter set outside stays until a stick moves it back in), never
//!   the height above home below where the mode started. A parameter set
//!   meanwhile replaces what the sticks made of it. Sticks older than
//!   `COM_RC_LOSS_T` are centred, as PX4 zeroes lost sticks.
//! * Below [`MIN_SAFETY_ALTITUDE_M`] above the ground (`h = z_rest - z`, NED)
//!   it stops moving horizontally and climbs at [`EMERGENCY_ASCENT_M_S`]
//!   (PX4's emergency ascent): a follow height that asks for the ground (a
//!   target reported below it, `FLW_TGT_ALT_M` 2) keeps the vehicle about
//!   1 m up, in the mode, rather than landing it.
//!
//! Nothing here runs unless the mode is flown; a fix costs one conversion.

use nalgebra::{Vector2, Vector3};

use super::manual::{ManualControl, expo_deadzone};
use super::{Nav, Navigator, Situation};
use crate::autopilot::control_loop::Demand;
use crate::autopilot::settings::FollowSettings;
use crate::control::{Setpoint, TranslationSetpoint, YawSetpoint};
use crate::math::wrap_pi;

/// A fix older than this is lost [s] (PX4's `GPS_MESSAGE_STALE_TIMEOUT_MS`).
pub const TARGET_STALE_S: f64 = 3.0;
/// Natural frequency of the target filter [rad/s] (PX4's `TARGET_POSE_FILTER_NATURAL_FREQUENCY`).
const FILTER_OMEGA_RAD_S: f64 = 1.0;
/// Damping of the target filter (PX4's `TARGET_POSE_FILTER_DAMPING_RATIO`,
/// written as PX4 writes it).
#[allow(clippy::approx_constant)]
const FILTER_ZETA: f64 = 0.7071;
/// After a gap this long the target filter restarts at the target [s] (PX4's `TARGET_ESTIMATOR_TIMEOUT_US`).
const FILTER_RESET_S: f64 = 1.5;
/// Below this speed the target's course is kept [m/s] (PX4's deadzone).
const COURSE_DEADZONE_M_S: f64 = 1.0;
/// Further than this off the follow height, climb first [m] (PX4's `ALT_ACCEPTANCE_THRESHOLD`).
const ALT_ACCEPTANCE_M: f64 = 3.0;
/// Closer than this the heading is kept [m] (PX4's `MINIMUM_DISTANCE_TO_TARGET_FOR_YAW_CONTROL`).
const YAW_MIN_DISTANCE_M: f64 = 1.0;
/// Below this height above the ground the vehicle climbs [m] (PX4's `MINIMUM_SAFETY_ALTITUDE`).
const MIN_SAFETY_ALTITUDE_M: f64 = 1.0;
/// The climb rate of that ascent [m/s] (PX4's `EMERGENCY_ASCENT_SPEED`).
const EMERGENCY_ASCENT_M_S: f64 = 0.5;
/// Full pitch stick moves the follow distance this fast [m/s] (PX4's `FOLLOW_DISTANCE_USER_ADJUST_SPEED`).
const DISTANCE_ADJUST_M_S: f64 = 2.0;
/// Full throttle moves the follow height this fast [m/s] (PX4's `FOLLOW_HEIGHT_USER_ADJUST_SPEED`).
const HEIGHT_ADJUST_M_S: f64 = 1.5;
/// Full roll stick moves the follow angle at most this fast [rad/s] (PX4's `FOLLOW_ANGLE_USER_ADJUST_SPEED`).
const ANGLE_ADJUST_RAD_S: f64 = 1.5;
/// The sticks set the distance and the height up to this [m] (PX4's `FOLLOW_DISTANCE_MAX`, `FOLLOW_HEIGHT_MAX`).
const ADJUST_MAX_M: f64 = 100.0;
/// A stick adjusts only while the vehicle is within this many seconds of
/// its adjustment speed of the setpoint [s] (PX4's `USER_ADJUSTMENT_ERROR_TIME_WINDOW`).
const ADJUST_WINDOW_S: f64 = 0.5;
/// The expo of the sticks (PX4's `Sticks`, 0.6).
const STICK_EXPO: f64 = 0.6;

/// One FOLLOW_TARGET report, as the client sends it.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TargetFix {
    /// Latitude [deg].
    pub lat_deg: f64,
    /// Longitude [deg].
    pub lon_deg: f64,
    /// Altitude AMSL [m].
    pub alt_amsl_m: f64,
    /// Velocity [m/s], NED, when the client gives one.
    pub velocity_ned: Option<Vector3<f64>>,
}

impl TargetFix {
    /// Whether it can be used: finite, latitude and longitude in range.
    #[must_use]
    pub fn is_valid(&self) -> bool {
        self.lat_deg.is_finite()
            && self.lon_deg.is_finite()
            && self.alt_amsl_m.is_finite()
            && self.lat_deg.abs() <= 90.0
            && self.lon_deg.abs() <= 180.0
            && self.velocity_ned.is_none_or(|v| v.iter().all(|x| x.is_finite()))
    }
}

/// The latest fix, resolved to NED, and its arrival time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Target {
    position_ned: Vector3<f64>,
    velocity_ned: Vector3<f64>,
    time_s: f64,
}

impl Target {
    /// A fix at `position_ned` [m] arriving at `time_s`, after `previous`:
    /// its own velocity, else the difference of the two positions.
    pub(super) fn new(
        position_ned: Vector3<f64>,
        velocity_ned: Option<Vector3<f64>>,
        time_s: f64,
        previous: Option<&Target>,
    ) -> Self {
        let velocity_ned = velocity_ned.unwrap_or_else(|| match previous {
            Some(p) if time_s - p.time_s > 1e-3 && time_s - p.time_s < TARGET_STALE_S => {
                (position_ned - p.position_ned) / (time_s - p.time_s)
            }
            _ => Vector3::zeros(),
        });
        Self {
            position_ned,
            velocity_ned,
            time_s,
        }
    }

    /// Predicted position and velocity at `t` [s], or `None` when stale.
    fn at(&self, t: f64) -> Option<(Vector3<f64>, Vector3<f64>)> {
        let age = t - self.time_s;
        (age <= TARGET_STALE_S).then(|| (self.position_ned + self.velocity_ned * age.max(0.0), self.velocity_ned))
    }
}

/// Where the vehicle follows from: distance [m], height [m] and angle
/// [rad, clockwise from the target's course].
#[derive(Clone, Copy, Debug, PartialEq)]
struct Geometry {
    distance_m: f64,
    height_m: f64,
    angle_rad: f64,
}

impl Geometry {
    fn of(fs: &FollowSettings) -> Self {
        Self {
            distance_m: fs.distance_m,
            height_m: fs.height_m,
            angle_rad: fs.angle_rad,
        }
    }
}

/// What Follow remembers between steps.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(in crate::autopilot) struct Follow {
    /// The filtered target: position [m], velocity [m/s], acceleration [m/s^2], NED; `None` until a fix.
    filter: Option<(Vector3<f64>, Vector3<f64>, Vector3<f64>)>,
    /// When the filter was last fed [s].
    fed_s: f64,
    /// The target's course [rad] (from north, clockwise).
    course_rad: f64,
    /// The orbit angle `theta` [rad]; `None` until the first fix places it.
    theta_rad: Option<f64>,
    /// The follow height's NED z floor: where the mode started [m].
    start_z: f64,
    /// The geometry flown: the parameters', moved by the sticks.
    geometry: Geometry,
    /// The parameters' geometry when last read (a change replaces the flown one).
    params: Geometry,
    /// The NED z of the last position setpoint [m] (where the mode started, at first).
    setpoint_z: f64,
}

/// One step of the second-order target filter (module doc), `dt` [s].
fn filter_step(
    (x, v, _): (Vector3<f64>, Vector3<f64>, Vector3<f64>),
    target: &Vector3<f64>,
    target_v: &Vector3<f64>,
    dt: f64,
) -> (Vector3<f64>, Vector3<f64>, Vector3<f64>) {
    let w = FILTER_OMEGA_RAD_S;
    let a = (target - x) * (w * w) + (target_v - v) * (2.0 * FILTER_ZETA * w);
    let v_next = v + a * dt;
    (x + (v + v_next) * (0.5 * dt), v_next, a)
}

/// `x + dx`, kept within `[lo, hi]` by a move towards it, never taken out
/// of it by one, and never snapped into it from outside.
fn step_within(x: f64, dx: f64, lo: f64, hi: f64) -> f64 {
    if dx > 0.0 {
        (x + dx).min(hi.max(x))
    } else {
        (x + dx).max(lo.min(x))
    }
}

/// One step `dt` [s] of the sticks' adjustments of `g` (module doc), each
/// stick `s = expo(deadzone(stick))`:
/// `h += 1.5 s_throttle dt` while `|z_sp - z| < 1.5 * 0.5`,
/// `d += 2 s_pitch dt` while `| |p - x|_xy - d | < 2 * 0.5`,
/// `a += min(1.5, v_max / d) s_roll dt` while `|wrap(atan2(p - x) - theta)| < 1.5 * 0.5`.
/// `p` the vehicle [m], `x` the filtered target [m], NED; `theta` the orbit
/// angle setpoint [rad] and `setpoint_z` (`z_sp`) the height setpoint [m]
/// of the step before. A centred stick changes nothing.
fn adjust(
    mut g: Geometry,
    sticks: &ManualControl,
    (p, x): (&Vector3<f64>, &Vector3<f64>),
    (theta, setpoint_z): (Option<f64>, f64),
    (deadzone, max_tangential_m_s, dt): (f64, f64, f64),
) -> Geometry {
    let rate = |stick: f64| expo_deadzone(stick, STICK_EXPO, deadzone);
    let up = rate(sticks.throttle);
    if up != 0.0 && (setpoint_z - p.z).abs() < HEIGHT_ADJUST_M_S * ADJUST_WINDOW_S {
        g.height_m = step_within(
            g.height_m,
            HEIGHT_ADJUST_M_S * up * dt,
            MIN_SAFETY_ALTITUDE_M,
            ADJUST_MAX_M,
        );
    }
    let out = p.xy() - x.xy();
    let away = rate(sticks.pitch);
    if away != 0.0 && (out.norm() - g.distance_m).abs() < DISTANCE_ADJUST_M_S * ADJUST_WINDOW_S {
        g.distance_m = step_within(
            g.distance_m,
            DISTANCE_ADJUST_M_S * away * dt,
            YAW_MIN_DISTANCE_M,
            ADJUST_MAX_M,
        );
    }
    let round = rate(sticks.roll);
    if let Some(theta) = theta.filter(|_| round != 0.0) {
        let measured = out.y.atan2(out.x);
        if wrap_pi(measured - theta).abs() < ANGLE_ADJUST_RAD_S * ADJUST_WINDOW_S {
            let most = ANGLE_ADJUST_RAD_S.min(max_tangential_m_s / g.distance_m);
            g.angle_rad = wrap_pi(g.angle_rad + most * round * dt);
        }
    }
    g
}

/// Move `theta` towards `goal` [rad] by at most `max_step` [rad], the short way.
fn orbit_step(theta: f64, goal: f64, max_step: f64) -> f64 {
    let e = wrap_pi(goal - theta);
    if e.abs() <= max_step {
        wrap_pi(goal)
    } else {
        wrap_pi(theta + e.signum() * max_step)
    }
}

/// `flown` with each parameter that changed since `seen` put in its place
/// (PX4's task on a parameter update); `seen` becomes `now`.
fn refreshed(mut flown: Geometry, seen: &mut Geometry, now: &Geometry) -> Geometry {
    if now.distance_m != seen.distance_m {
        flown.distance_m = now.distance_m;
    }
    if now.height_m != seen.height_m {
        flown.height_m = now.height_m;
    }
    if now.angle_rad != seen.angle_rad {
        flown.angle_rad = now.angle_rad;
    }
    *seen = *now;
    flown
}

impl Navigator {
    /// A FOLLOW_TARGET fix resolved to NED at `now` [s]: kept whatever the mode.
    pub(in crate::autopilot) fn set_follow_target(
        &mut self,
        position_ned: Vector3<f64>,
        velocity_ned: Option<Vector3<f64>>,
        now: f64,
    ) {
        self.follow_target = Some(Target::new(
            position_ned,
            velocity_ned,
            now,
            self.follow_target.as_ref(),
        ));
    }

    /// Follow entered: no filter yet, the height floor where the vehicle is meant to be.
    pub(in crate::autopilot) fn enter_follow(&mut self, cx: &Situation<'_>) {
        let p = self.current_position(cx.meas);
        let geometry = Geometry::of(&cx.settings.follow);
        self.nav = Nav::Follow(Follow {
            filter: None,
            fed_s: f64::NEG_INFINITY,
            course_rad: 0.0,
            theta_rad: None,
            start_z: p.z,
            geometry,
            params: geometry,
            setpoint_z: p.z,
        });
    }

    /// The demand of Follow (module doc).
    pub(super) fn follow_demand(&mut self, cx: &Situation<'_>, mut f: Follow) -> Demand {
        if cx.resting {
            return Demand::Idle;
        }
        let (meas, s, dt) = (cx.meas, cx.settings, cx.dt);
        let fs = &s.follow;
        let t = meas.time_s;
        let p = meas.position_ned;
        let limits = self.limits(s.xy_vel_max_m_s, s.climb_m_s, s.descent_m_s);
        let Some((target_p, target_v)) = self.follow_target.and_then(|tg| tg.at(t)) else {
            // no target (never, or lost): hold where it is
            self.nav = Nav::Follow(f);
            let hold = Setpoint {
                translation: TranslationSetpoint::Hold,
                yaw: YawSetpoint::Hold,
            };
            return Demand::Track(self.shape(meas, hold, limits, dt));
        };
        let filter = match f.filter {
            Some(state) if t - f.fed_s <= FILTER_RESET_S => filter_step(state, &target_p, &target_v, dt),
            _ => (target_p, target_v, Vector3::zeros()),
        };
        f.filter = Some(filter);
        f.fed_s = t;
        let (x, v, a) = filter;
        let before = refreshed(f.geometry, &mut f.params, &Geometry::of(fs));
        let mut g = adjust(
            before,
            &self.fresh_sticks(t, s.manual.loss_s, cx.clock),
            (&p, &x),
            (f.theta_rad, f.setpoint_z),
            (s.manual.deadzone, fs.max_tangential_m_s, dt),
        );
        // the height above home never goes below where the mode started:
        // the sticks do not wind it down past that floor
        let height_z = |h: f64| {
            if fs.track_altitude {
                x.z - h
            } else {
                f.start_z.min(cx.home_ned.z - h)
            }
        };
        if !fs.track_altitude {
            let floor_m = cx.home_ned.z - f.start_z;
            g.height_m = g.height_m.max(before.height_m.min(floor_m));
        }
        f.geometry = g;
        let speed_xy = v.xy().norm();
        let theta = match f.theta_rad {
            None => {
                // start where the vehicle is, seen from the target; over the
                // target, where no side is nearer, as PX4 starts: the orbit
                // angle and the course north
                let out = p.xy() - x.xy();
                if out.norm() > YAW_MIN_DISTANCE_M {
                    let theta = out.y.atan2(out.x);
                    f.course_rad = wrap_pi(theta - g.angle_rad);
                    theta
                } else {
                    f.course_rad = 0.0;
                    0.0
                }
            }
            Some(theta) => theta,
        };
        if speed_xy >= COURSE_DEADZONE_M_S {
            f.course_rad = v.y.atan2(v.x);
        }
        let max_step = fs.max_tangential_m_s / g.distance_m * dt;
        let goal = f.course_rad + g.angle_rad;
        let theta_before = theta;
        let theta = orbit_step(theta, goal, max_step);
        f.theta_rad = Some(theta);
        let radial = Vector2::new(theta.cos(), theta.sin());
        let xy = x.xy() + radial * g.distance_m;
        let z = height_z(g.height_m);
        // what the sticks move, fed forward: out along the radial, round
        // along the tangent (clockwise seen from above) while the stick
        // turns the angle and the orbit angle keeps up with it, up or down
        // as the flown height moves
        let out_m_s = (g.distance_m - before.distance_m) / dt;
        let turning = g.angle_rad != before.angle_rad && theta == wrap_pi(goal);
        let round_m_s = if turning {
            wrap_pi(theta - theta_before) / dt * g.distance_m
        } else {
            0.0
        };
        let moving = Vector3::new(
            radial.x * out_m_s - radial.y * round_m_s,
            radial.y * out_m_s + radial.x * round_m_s,
            (z - height_z(before.height_m)) / dt,
        );
        let to_target = x.xy() - p.xy();
        let yaw = if to_target.norm() > YAW_MIN_DISTANCE_M {
            YawSetpoint::Angle(to_target.y.atan2(to_target.x))
        } else {
            YawSetpoint::Hold
        };
        let emergency = cx.rest_z - p.z < MIN_SAFETY_ALTITUDE_M;
        f.setpoint_z = if emergency { p.z } else { z };
        let translation = if emergency {
            // too close to the ground: no horizontal motion, climb slowly
            TranslationSetpoint::Velocity(Vector3::new(0.0, 0.0, -EMERGENCY_ASCENT_M_S))
        } else if (z - p.z).abs() < ALT_ACCEPTANCE_M {
            let vertical = if fs.track_altitude { 1.0 } else { 0.0 };
            TranslationSetpoint::Track {
                position: Vector3::new(xy.x, xy.y, z),
                velocity: Vector3::new(v.x, v.y, v.z * vertical) + moving,
                acceleration: Vector3::new(a.x, a.y, a.z * vertical),
            }
        } else {
            // the height first, where the reference is
            let here = self.current_position(meas);
            TranslationSetpoint::Position(Vector3::new(here.x, here.y, z))
        };
        self.nav = Nav::Follow(f);
        Demand::Track(self.shape(meas, Setpoint { translation, yaw }, limits, dt))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_fix_without_velocity_takes_the_difference_and_goes_stale() {
        let a = Target::new(Vector3::new(0.0, 0.0, 0.0), None, 10.0, None);
        assert_eq!(a.velocity_ned, Vector3::zeros());
        let b = Target::new(Vector3::new(2.0, 1.0, 0.0), None, 11.0, Some(&a));
        assert_eq!(b.velocity_ned, Vector3::new(2.0, 1.0, 0.0));
        let (p, _) = b.at(12.5).unwrap();
        assert!((p - Vector3::new(5.0, 2.5, 0.0)).norm() < 1e-12);
        assert!(b.at(11.0 + TARGET_STALE_S + 0.01).is_none());
        let given = Target::new(Vector3::zeros(), Some(Vector3::new(0.0, -1.0, 0.0)), 12.0, Some(&b));
        assert_eq!(given.velocity_ned, Vector3::new(0.0, -1.0, 0.0));
    }

    #[test]
    fn the_filter_follows_a_ramp_without_lag_and_the_orbit_angle_is_rate_limited() {
        let v = Vector3::new(3.0, 0.0, 0.0);
        let mut s = (Vector3::zeros(), v, Vector3::zeros());
        let dt = 1e-3;
        for k in 1..=10_000 {
            let t = k as f64 * dt;
            s = filter_step(s, &(v * t), &v, dt);
        }
        // no lag (a bare second-order filter would trail by 2 zeta v / w = 4.2 m): one step's v dt at most
        assert!((s.0 - v * 10.0).norm() < 1e-2, "{}", s.0);
        // a quarter turn at 0.5 rad/s takes pi/2 / 0.5 s
        let mut theta = 0.0;
        let mut steps = 0;
        while (theta - std::f64::consts::FRAC_PI_2).abs() > 1e-12 {
            theta = orbit_step(theta, std::f64::consts::FRAC_PI_2, 0.5 * dt);
            steps += 1;
        }
        assert!((steps as f64 * dt - std::f64::consts::PI).abs() < 2e-3, "{steps}");
        // the short way across +-pi
        assert!(orbit_step(3.0, -3.0, 0.01) > 3.0 - 1e-12 || orbit_step(3.0, -3.0, 0.01) < -3.0);
    }

    #[test]
    fn a_stick_moves_what_it_moves_inside_its_window_and_within_bounds() {
        let g = Geometry {
            distance_m: 10.0,
            height_m: 10.0,
            angle_rad: 0.0,
        };
        let (dt, dz, max_vel) = (1e-3, 0.1, 5.0);
        // the vehicle 10 m north of the target, at its height setpoint
        let (p, x) = (Vector3::new(10.0, 0.0, -10.0), Vector3::zeros());
        let stick = |pitch, roll, throttle| ManualControl {
            pitch,
            roll,
            throttle,
            yaw: 0.0,
        };
        let at = |sticks: ManualControl, theta: Option<f64>, setpoint_z: f64| {
            adjust(g, &sticks, (&p, &x), (theta, setpoint_z), (dz, max_vel, dt))
        };
        // centred, or within the deadzone: nothing moves
        assert_eq!(at(ManualControl::CENTRED, Some(0.0), -10.0), g);
        assert_eq!(at(stick(0.05, -0.1, 0.1), Some(0.0), -10.0), g);
        // full sticks: 1.5 m/s up, 2 m/s out, min(1.5, 5 / d) rad/s clockwise
        // (d as the pitch has just moved it, as PX4 orders them)
        let moved = at(stick(1.0, 1.0, 1.0), Some(0.0), -10.0);
        assert!((moved.height_m - (10.0 + 1.5 * dt)).abs() < 1e-12);
        assert!((moved.distance_m - (10.0 + 2.0 * dt)).abs() < 1e-12);
        assert!((moved.angle_rad - 5.0 / moved.distance_m * dt).abs() < 1e-12);
        // outside each window: the setpoint 0.75 m from the vehicle, the
        // vehicle 1 m off the distance, 0.75 rad off the orbit angle (or none yet)
        assert_eq!(at(stick(0.0, 0.0, 1.0), Some(0.0), -10.75).height_m, 10.0);
        let off = adjust(
            g,
            &stick(1.0, 0.0, 0.0),
            (&Vector3::new(11.0, 0.0, -10.0), &x),
            (Some(0.0), -10.0),
            (dz, max_vel, dt),
        );
        assert_eq!(off.distance_m, 10.0);
        assert_eq!(at(stick(0.0, 1.0, 0.0), Some(-0.75), -10.0).angle_rad, 0.0);
        assert_eq!(at(stick(0.0, 1.0, 0.0), None, -10.0).angle_rad, 0.0);
        // bounds: a move never takes a value out of [lo, hi], nor snaps one in from outside
        assert_eq!(step_within(99.9995, 0.001, 1.0, 100.0), 100.0);
        assert_eq!(step_within(1.0004, -0.001, 1.0, 100.0), 1.0);
        assert_eq!(step_within(150.0, 0.001, 1.0, 100.0), 150.0);
        assert_eq!(step_within(150.0, -0.001, 1.0, 100.0), 150.0 - 0.001);
    }

    #[test]
    fn a_parameter_set_replaces_what_the_sticks_made_of_it_and_only_that() {
        let params = Geometry {
            distance_m: 10.0,
            height_m: 10.0,
            angle_rad: 0.0,
        };
        let flown = Geometry {
            distance_m: 14.0,
            height_m: 12.0,
            angle_rad: 0.5,
        };
        let mut seen = params;
        assert_eq!(refreshed(flown, &mut seen, &params), flown);
        let now = Geometry {
            height_m: 8.0,
            ..params
        };
        assert_eq!(refreshed(flown, &mut seen, &now), Geometry { height_m: 8.0, ..flown });
        assert_eq!(seen, now);
    }

    #[test]
    fn a_fix_must_be_finite_and_on_the_globe() {
        let ok = TargetFix {
            lat_deg: 47.0,
            lon_deg: 8.0,
            alt_amsl_m: 500.0,
            velocity_ned: None,
        };
        assert!(ok.is_valid());
        assert!(!TargetFix { lat_deg: 91.0, ..ok }.is_valid());
        assert!(
            !TargetFix {
                alt_amsl_m: f64::NAN,
                ..ok
            }
            .is_valid()
        );
        assert!(
            !TargetFix {
                velocity_ned: Some(Vector3::new(f64::INFINITY, 0.0, 0.0)),
                ..ok
            }
            .is_valid()
        );
    }
}
