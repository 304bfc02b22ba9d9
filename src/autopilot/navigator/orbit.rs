//! Orbit: circle a centre at a radius and a tangential speed, as PX4's
//! Orbit flight task flies it (MAV_CMD_DO_ORBIT, mode POSCTL.ORBIT).
//!
//! * Entered as a mode, the orbit is PX4's placeholder: radius 1 m, 1 m/s
//!   clockwise, around a centre 1 m south of where the vehicle is
//!   (`centre = p - r e_north`), so that the vehicle already stands on it.
//! * DO_ORBIT sets what it gives: radius `|p1|` (its sign is the direction:
//!   positive clockwise seen from above), speed `p2`, the yaw behaviour
//!   `p3`, the centre `p5`/`p6` (latitude/longitude) and the altitude AMSL
//!   `p7`; a missing part keeps the current value. The speed is clamped to
//!   `MPC_XY_VEL_MAX`, then lowered until the centripetal acceleration
//!   `v^2 / r` stays below [`ACCEL_MAX_M_S2`].
//! * Away from the circle (more than [`ON_CIRCLE_M`] off the radius or
//!   `NAV_MC_ALT_RAD` off the altitude) the vehicle first flies straight to
//!   the closest point of the circle at the cruise speed, its nose already
//!   where the yaw behaviour will hold it there; on it, the reference runs
//!   around the circle:
//!
//!   `p = c + r [cos phi, sin phi, 0]`, `phi' = v_t / r`,
//!   `v = v_t [-sin phi, cos phi, 0]`,
//!   `a = a_t [-sin phi, cos phi, 0] - (v_t^2 / r) [cos phi, sin phi, 0]`,
//!
//!   `phi` measured from north towards east (NED), the tangential speed
//!   `v_t` reaching the commanded speed at `MPC_ACC_HOR` (`a_t`), as PX4
//!   slews it, so that the entry has no step in velocity.

use nalgebra::Vector3;

use super::{Nav, Navigator, Situation};
use crate::autopilot::control_loop::Demand;
use crate::control::{Reference, Setpoint, TranslationSetpoint, YawSetpoint};
use crate::math::{euler_zyx, wrap_pi};

/// The smallest radius [m] (PX4's `_radius_min`).
const RADIUS_MIN_M: f64 = 1.0;
/// The largest radius [m] (PX4's `MC_ORBIT_RAD_MAX` default).
const RADIUS_MAX_M: f64 = 1000.0;
/// The centripetal acceleration an orbit may ask for [m/s^2] (PX4's default).
const ACCEL_MAX_M_S2: f64 = 2.0;
/// Within this distance [m] of the radius the vehicle is on the circle (PX4's
/// `_horizontal_acceptance_radius`).
const ON_CIRCLE_M: f64 = 2.0;

/// Where the nose points while orbiting (MAVLink `ORBIT_YAW_BEHAVIOUR`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum OrbitYaw {
    /// 0: the front to the centre (PX4's default).
    FrontToCentre,
    /// 1: the heading the command found.
    InitialHeading,
    /// 2: not controlled (held as it is).
    Uncontrolled,
    /// 3: the front along the circle, in the direction of flight.
    FrontTangent,
    /// 4: by the pilot's yaw stick (held as it is without sticks).
    RcControlled,
}

impl OrbitYaw {
    /// From MAVLink's number; `None` for a number MAVLink does not define
    /// (5, ORBIT_YAW_BEHAVIOUR_UNCHANGED, is read by the caller as "keep").
    #[must_use]
    pub fn from_mavlink(value: u8) -> Option<Self> {
        Some(match value {
            0 => Self::FrontToCentre,
            1 => Self::InitialHeading,
            2 => Self::Uncontrolled,
            3 => Self::FrontTangent,
            4 => Self::RcControlled,
            _ => return None,
        })
    }

    /// MAVLink's number.
    #[must_use]
    pub fn to_mavlink(self) -> u8 {
        match self {
            Self::FrontToCentre => 0,
            Self::InitialHeading => 1,
            Self::Uncontrolled => 2,
            Self::FrontTangent => 3,
            Self::RcControlled => 4,
        }
    }
}

/// An orbit being flown.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(in crate::autopilot) struct Orbit {
    /// Centre [m], NED; its z is the altitude flown.
    pub(in crate::autopilot) centre_ned: Vector3<f64>,
    /// Radius [m], in `[RADIUS_MIN_M, RADIUS_MAX_M]`.
    pub(in crate::autopilot) radius_m: f64,
    /// Tangential speed [m/s]: positive clockwise seen from above.
    pub(in crate::autopilot) velocity_m_s: f64,
    /// Where the nose points.
    pub(in crate::autopilot) yaw: OrbitYaw,
    /// The heading when the orbit was commanded [rad].
    initial_yaw_rad: f64,
    /// Flying to the circle, or around it.
    phase: OrbitPhase,
}

/// Where an orbit stands.
#[derive(Clone, Copy, Debug, PartialEq)]
enum OrbitPhase {
    /// Flying to the closest point of the circle.
    Approach,
    /// On the circle at angle `phi` [rad] (from north towards east) with
    /// tangential speed `speed` [m/s] (signed like the orbit's velocity).
    Circle { phi: f64, speed: f64 },
}

/// What DO_ORBIT asks; `None` keeps the current value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(in crate::autopilot) struct OrbitChange {
    /// Signed radius [m] (sign: direction, positive clockwise).
    pub(in crate::autopilot) radius_m: Option<f64>,
    /// Speed [m/s] (its magnitude; the direction comes from the radius).
    pub(in crate::autopilot) velocity_m_s: Option<f64>,
    /// Yaw behaviour.
    pub(in crate::autopilot) yaw: Option<OrbitYaw>,
    /// Centre [m], NED horizontal.
    pub(in crate::autopilot) centre_xy: Option<[f64; 2]>,
    /// Altitude [m], NED z.
    pub(in crate::autopilot) z: Option<f64>,
}

/// `v` clamped to `+-v_max`, then lowered until `v^2 / r < ACCEL_MAX_M_S2`
/// (PX4's `_sanitizeParams`: a small radius beats a high speed).
fn sanitised_velocity(radius_m: f64, v: f64, v_max: f64) -> f64 {
    let v = v.clamp(-v_max, v_max);
    if v * v >= ACCEL_MAX_M_S2 * radius_m {
        v.signum() * (ACCEL_MAX_M_S2 * radius_m).sqrt()
    } else {
        v
    }
}

impl Orbit {
    /// PX4's placeholder orbit when the mode is entered: radius 1 m, 1 m/s
    /// clockwise, the vehicle at `p` [m, NED] on the circle, nose to the
    /// centre, heading `yaw` [rad] kept as the initial one.
    fn placeholder(p: &Vector3<f64>, yaw: f64, v_max: f64) -> Self {
        let radius_m = RADIUS_MIN_M;
        Self {
            centre_ned: Vector3::new(p.x - radius_m, p.y, p.z),
            radius_m,
            velocity_m_s: sanitised_velocity(radius_m, 1.0, v_max),
            yaw: OrbitYaw::FrontToCentre,
            initial_yaw_rad: yaw,
            phase: OrbitPhase::Approach,
        }
    }

    /// The orbit with `change` applied at heading `yaw` [rad]: `Err` (and no
    /// change) when the radius is outside `[RADIUS_MIN_M, RADIUS_MAX_M]`.
    fn changed(&self, change: &OrbitChange, yaw: f64, v_max: f64) -> Result<Self, ()> {
        let mut o = *self;
        let mut clockwise = o.velocity_m_s >= 0.0;
        let mut radius = o.radius_m;
        if let Some(r) = change.radius_m {
            if !(RADIUS_MIN_M..=RADIUS_MAX_M).contains(&r.abs()) {
                return Err(());
            }
            clockwise = r > 0.0;
            radius = r.abs();
        }
        let speed = change.velocity_m_s.map_or(o.velocity_m_s.abs(), f64::abs);
        o.radius_m = radius;
        o.velocity_m_s = sanitised_velocity(radius, if clockwise { speed } else { -speed }, v_max);
        if let Some(y) = change.yaw {
            o.yaw = y;
        }
        if let Some([x, y]) = change.centre_xy {
            o.centre_ned.x = x;
            o.centre_ned.y = y;
        }
        if let Some(z) = change.z {
            o.centre_ned.z = z;
        }
        o.initial_yaw_rad = yaw;
        o.phase = OrbitPhase::Approach;
        Ok(o)
    }

    /// Whether `p` [m, NED] is on the circle (within [`ON_CIRCLE_M`] of the
    /// radius and `alt_radius_m` of the altitude).
    fn on_circle(&self, p: &Vector3<f64>, alt_radius_m: f64) -> bool {
        let d = (p.xy() - self.centre_ned.xy()).norm();
        (d - self.radius_m).abs() < ON_CIRCLE_M && (p.z - self.centre_ned.z).abs() < alt_radius_m
    }

    /// The heading [rad] and its rate [rad/s] the yaw behaviour asks for at
    /// angle `phi` with tangential speed `speed`; `hold` is the heading now.
    fn yaw_at(&self, phi: f64, speed: f64, hold: f64) -> (f64, f64) {
        let rate = speed / self.radius_m;
        match self.yaw {
            OrbitYaw::FrontToCentre => (wrap_pi(phi + std::f64::consts::PI), rate),
            OrbitYaw::FrontTangent => (
                wrap_pi(phi + self.velocity_m_s.signum() * std::f64::consts::FRAC_PI_2),
                rate,
            ),
            OrbitYaw::InitialHeading => (self.initial_yaw_rad, 0.0),
            OrbitYaw::Uncontrolled | OrbitYaw::RcControlled => (hold, 0.0),
        }
    }

    /// The angle [rad] of `p` around the centre (from north towards east).
    fn angle_of(&self, p: &Vector3<f64>) -> f64 {
        let d = p - self.centre_ned;
        if d.xy().norm() > 1e-9 { d.y.atan2(d.x) } else { 0.0 }
    }
}

impl Navigator {
    /// Orbit mode entered (no command): PX4's placeholder around where the
    /// vehicle is meant to be.
    pub(in crate::autopilot) fn enter_orbit(&mut self, cx: &Situation<'_>) {
        let p = self.current_position(cx.meas);
        let yaw = euler_zyx(&cx.meas.attitude).z;
        self.nav = Nav::Orbit(Orbit::placeholder(&p, yaw, cx.settings.xy_vel_max_m_s));
    }

    /// DO_ORBIT: switch to Orbit (from the placeholder when another mode
    /// flies) and apply `change`. `false`, and nothing changed, when the
    /// radius is out of range.
    pub(in crate::autopilot) fn command_orbit(&mut self, cx: &Situation<'_>, change: &OrbitChange) -> bool {
        let p = self.current_position(cx.meas);
        let yaw = euler_zyx(&cx.meas.attitude).z;
        let v_max = cx.settings.xy_vel_max_m_s;
        let base = match self.nav {
            Nav::Orbit(o) => o,
            _ => Orbit::placeholder(&p, yaw, v_max),
        };
        match base.changed(change, yaw, v_max) {
            Ok(o) => {
                self.nav = Nav::Orbit(o);
                true
            }
            Err(()) => false,
        }
    }

    /// The orbit flown, if Orbit is the mode.
    pub(in crate::autopilot) fn orbit(&self) -> Option<&Orbit> {
        match &self.nav {
            Nav::Orbit(o) => Some(o),
            _ => None,
        }
    }

    /// The demand of Orbit (module doc).
    pub(super) fn orbit_demand(&mut self, cx: &Situation<'_>, mut orbit: Orbit) -> Demand {
        if cx.resting {
            return Demand::Idle;
        }
        let (meas, s, dt) = (cx.meas, cx.settings, cx.dt);
        let p = meas.position_ned;
        if orbit.phase == OrbitPhase::Approach && orbit.on_circle(&p, s.mc_alt_radius_m) {
            orbit.phase = OrbitPhase::Circle {
                phi: orbit.angle_of(&p),
                speed: 0.0,
            };
        }
        let reference = match orbit.phase {
            OrbitPhase::Approach => {
                let c = orbit.centre_ned;
                let out = p.xy() - c.xy();
                let dir = if out.norm() > 1e-9 {
                    out / out.norm()
                } else {
                    nalgebra::Vector2::new(1.0, 0.0)
                };
                let entry = c.xy() + dir * orbit.radius_m;
                let target = Vector3::new(entry.x, entry.y, c.z);
                let hold = euler_zyx(&meas.attitude).z;
                let (yaw, _) = orbit.yaw_at(dir.y.atan2(dir.x), 0.0, hold);
                let limits = self.limits(self.cruise_m_s(s), s.climb_m_s, s.descent_m_s);
                self.shape(
                    meas,
                    Setpoint {
                        translation: TranslationSetpoint::Position(target),
                        yaw: YawSetpoint::Angle(yaw),
                    },
                    limits,
                    dt,
                )
            }
            OrbitPhase::Circle { phi, speed } => {
                let accel = self.base_limits.max_accel_xy_m_s2;
                let dv = (orbit.velocity_m_s - speed).clamp(-accel * dt, accel * dt);
                let speed_next = speed + dv;
                let a_t = dv / dt;
                let phi_next = wrap_pi(phi + 0.5 * (speed + speed_next) / orbit.radius_m * dt);
                let hold = self.shaper.reference().yaw_rad;
                let (yaw, yaw_rate) = orbit.yaw_at(phi_next, speed_next, hold);
                orbit.phase = OrbitPhase::Circle {
                    phi: phi_next,
                    speed: speed_next,
                };
                let (sin, cos) = phi_next.sin_cos();
                let radial = Vector3::new(cos, sin, 0.0);
                let tangent = Vector3::new(-sin, cos, 0.0);
                let r = Reference {
                    position_ned: orbit.centre_ned + radial * orbit.radius_m,
                    velocity_ned: tangent * speed_next,
                    acceleration_ned: tangent * a_t - radial * (speed_next * speed_next / orbit.radius_m),
                    yaw_rad: yaw,
                    yaw_rate_rad_s: yaw_rate,
                    ..Reference::hold(orbit.centre_ned, yaw)
                };
                // the shaper continues from the circle when another mode takes over
                self.shaper.reset(r.position_ned, r.velocity_ned, r.yaw_rad);
                self.shaper_live = true;
                r
            }
        };
        self.nav = Nav::Orbit(orbit);
        Demand::Track(reference)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn velocity_is_clamped_then_kept_under_the_centripetal_limit() {
        assert_eq!(sanitised_velocity(10.0, 2.0, 12.0), 2.0);
        assert_eq!(sanitised_velocity(10.0, -30.0, 12.0), -(20f64.sqrt()));
        assert_eq!(sanitised_velocity(100.0, 15.0, 12.0), 12.0);
    }

    #[test]
    fn a_command_changes_only_what_it_gives_and_refuses_a_radius_out_of_range() {
        let o = Orbit::placeholder(&Vector3::new(5.0, 5.0, -10.0), 0.3, 12.0);
        assert_eq!((o.radius_m, o.velocity_m_s), (1.0, 1.0));
        assert_eq!(o.centre_ned, Vector3::new(4.0, 5.0, -10.0));
        let change = OrbitChange {
            radius_m: Some(-10.0),
            velocity_m_s: Some(2.0),
            yaw: None,
            centre_xy: Some([20.0, 30.0]),
            z: None,
        };
        let c = o.changed(&change, 0.5, 12.0).unwrap();
        assert_eq!((c.radius_m, c.velocity_m_s), (10.0, -2.0));
        assert_eq!(c.centre_ned, Vector3::new(20.0, 30.0, -10.0));
        assert_eq!((c.yaw, c.initial_yaw_rad), (OrbitYaw::FrontToCentre, 0.5));
        let speed_only = OrbitChange {
            radius_m: None,
            velocity_m_s: Some(3.0),
            yaw: Some(OrbitYaw::FrontTangent),
            centre_xy: None,
            z: Some(-20.0),
        };
        let d = c.changed(&speed_only, 0.5, 12.0).unwrap();
        assert_eq!(
            (d.radius_m, d.velocity_m_s, d.yaw),
            (10.0, -3.0, OrbitYaw::FrontTangent)
        );
        assert_eq!(d.centre_ned.z, -20.0);
        for r in [0.5, -1500.0] {
            let bad = OrbitChange {
                radius_m: Some(r),
                ..speed_only
            };
            assert!(c.changed(&bad, 0.0, 12.0).is_err());
        }
    }

    #[test]
    fn yaw_behaviours() {
        let mut o = Orbit::placeholder(&Vector3::zeros(), 0.25, 12.0);
        o.radius_m = 10.0;
        o.velocity_m_s = 2.0;
        let east = std::f64::consts::FRAC_PI_2;
        // at the circle's east point the centre is to the west
        let (y, rate) = o.yaw_at(east, 2.0, 0.0);
        assert!((y + east).abs() < 1e-12, "{y}");
        assert_eq!(rate, 0.2);
        o.yaw = OrbitYaw::FrontTangent;
        // clockwise at the east point flies south
        assert!((o.yaw_at(east, 2.0, 0.0).0 - std::f64::consts::PI).abs() < 1e-12);
        o.yaw = OrbitYaw::InitialHeading;
        assert_eq!(o.yaw_at(east, 2.0, 0.0), (0.25, 0.0));
        o.yaw = OrbitYaw::Uncontrolled;
        assert_eq!(o.yaw_at(east, 2.0, 1.5), (1.5, 0.0));
    }
}
