//! Offboard: external setpoints (SET_POSITION_TARGET_*, SET_ATTITUDE_TARGET)
//! followed while they keep coming. A setpoint in a relative or global frame
//! is resolved to local NED against the measurement at the instant it
//! arrives, as PX4 does: LOCAL_OFFSET_NED adds the current position; the body
//! frames (BODY_NED, BODY_OFFSET_NED, BODY_FRD) turn velocity and
//! acceleration by the current heading (so "forward" stays horizontal) and
//! take position as a turned offset; global targets are converted around the
//! NED origin, their altitude AMSL, above home, or above the ground at the
//! origin. A NaN component is PX4's "unset" and stays NaN.
//!
//! A position given with a velocity or an acceleration is PX4's trajectory
//! setpoint: the velocity and acceleration are feed-forward to the position
//! (`v_cmd = v_sp + k1 (p_sp - p)`, the shaper's `Track`, with `k1` PX4's
//! position gain [`TRACK_GAIN_PER_S`] and the shaper's chain `(s + 4 k1)^4`
//! around it), horizontal speed up to `MPC_XY_VEL_MAX`, so a time-stamped
//! path is flown in time, and a constant feed-forward against a fixed
//! position settles `v_sp / k1` past it, as on PX4. A
//! position alone is flown to at up to `MPC_XY_VEL_MAX` too: in Offboard no
//! flight task of PX4's sets a cruise speed, and its position controller
//! limits the horizontal speed to `MPC_XY_VEL_MAX` (`MulticopterPositionControl`).

use nalgebra::{Rotation3, UnitQuaternion, Vector3};

use super::{Nav, Navigator, Situation};
use crate::autopilot::ClientClock;
use crate::autopilot::TIME_EPS;
use crate::autopilot::control_loop::Demand;
use crate::control::{Reference, Setpoint, ShaperLimits, TranslationSetpoint, YawSetpoint};
use crate::geo::GeoPoint;
use crate::math::euler_zyx;
use crate::signals::Measurement;

/// PX4's `MPC_XY_P` default [1/s]: its position controller's gain on the
/// position error of a trajectory setpoint, `v = v_sp + MPC_XY_P (p_sp - p)`.
const TRACK_GAIN_PER_S: f64 = 0.95;

/// Landed in offboard, a position setpoint this far [m] above the vehicle starts the flight (PX4's takeoff trigger)...
const TAKEOFF_TRIGGER_M: f64 = 0.2;
/// ... as does a climb-rate setpoint above this [m/s], or an upward acceleration setpoint above this [m/s^2].
const TAKEOFF_TRIGGER_M_S: f64 = 0.3;
const TAKEOFF_TRIGGER_M_S2: f64 = 0.5;

/// A frame measured from where the vehicle is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum RelativeFrame {
    /// LOCAL_OFFSET_NED (7): position is an offset from the current position, in NED.
    OffsetNed,
    /// BODY_NED (8), BODY_OFFSET_NED (9), BODY_FRD (12): forward-right-down
    /// turned by the current heading only; position is an offset from the
    /// current position.
    Body,
}

/// What a global target's altitude is measured from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum AltitudeReference {
    /// GLOBAL (0), GLOBAL_INT (5): AMSL.
    Amsl,
    /// GLOBAL_RELATIVE_ALT (3, 6): above home.
    Home,
    /// GLOBAL_TERRAIN_ALT (10, 11): above the (flat) ground at the NED origin.
    Terrain,
}

/// A global position target: a NaN component is unset.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct GlobalTarget {
    /// Latitude [deg].
    pub lat_deg: f64,
    /// Longitude [deg].
    pub lon_deg: f64,
    /// Altitude [m] above the [`AltitudeReference`].
    pub alt_m: f64,
}

/// Position, velocity and acceleration targets with yaw, as a setpoint
/// message carries them (SI units): `None` = ignored by the type mask, a NaN
/// component = unset (which the autopilot refuses).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Targets<P> {
    /// Position, in the setpoint's frame.
    pub position: Option<P>,
    /// Velocity [m/s].
    pub velocity: Option<Vector3<f64>>,
    /// Acceleration [m/s^2].
    pub acceleration: Option<Vector3<f64>>,
    /// Yaw [rad].
    pub yaw_rad: Option<f64>,
    /// Yaw rate [rad/s].
    pub yaw_rate_rad_s: Option<f64>,
}

impl<P> Targets<P> {
    /// Whether anything is set.
    #[must_use]
    pub fn sets_something(&self) -> bool {
        self.position.is_some()
            || self.velocity.is_some()
            || self.acceleration.is_some()
            || self.yaw_rad.is_some()
            || self.yaw_rate_rad_s.is_some()
    }

    /// The same targets with the position `f` makes of this one.
    fn map_position<Q>(self, f: impl FnOnce(P) -> Q) -> Targets<Q> {
        Targets {
            position: self.position.map(f),
            velocity: self.velocity,
            acceleration: self.acceleration,
            yaw_rad: self.yaw_rad,
            yaw_rate_rad_s: self.yaw_rate_rad_s,
        }
    }
}

/// An attitude (or body-rate) target with its thrust (SET_ATTITUDE_TARGET).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AttitudeTarget {
    /// Attitude, FRD to NED; `None` = rates only.
    pub attitude: Option<UnitQuaternion<f64>>,
    /// Body rates [rad/s], FRD; `None` = ignored.
    pub rate_frd: Option<Vector3<f64>>,
    /// Collective thrust, 0..1 of the maximum.
    pub thrust_normalised: f64,
}

/// An offboard setpoint as it arrives.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum OffboardSetpoint {
    /// LOCAL_NED: position [m], velocity and acceleration in local NED.
    Local(Targets<Vector3<f64>>),
    /// Measured from the vehicle's position and heading when it arrives.
    Relative(RelativeFrame, Targets<Vector3<f64>>),
    /// SET_POSITION_TARGET_GLOBAL_INT: a global position with its altitude
    /// reference, velocity and acceleration in NED.
    Global(AltitudeReference, Targets<GlobalTarget>),
    /// SET_ATTITUDE_TARGET.
    Attitude(AttitudeTarget),
}

/// A setpoint resolved to local NED (what offboard guidance follows).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(in crate::autopilot) enum LocalSetpoint {
    /// Targets in local NED.
    Local(Targets<Vector3<f64>>),
    /// Attitude or rates and thrust.
    Attitude(AttitudeTarget),
}

fn finite3(v: &Vector3<f64>) -> bool {
    v.iter().all(|x| x.is_finite())
}

/// Turn by `r` what is set; a NaN component stays unset.
fn rotate_keep_nan(r: &Rotation3<f64>, v: Vector3<f64>) -> Vector3<f64> {
    let nan = v.map(f64::is_nan);
    let rotated = r * v.map(|x| if x.is_nan() { 0.0 } else { x });
    Vector3::from_fn(|i, _| if nan[i] { f64::NAN } else { rotated[i] })
}

impl OffboardSetpoint {
    /// Whether a global target lies on the globe (latitude within ±90°,
    /// longitude within ±180°; an unset component is fine).
    pub(in crate::autopilot) fn position_in_range(&self) -> bool {
        match self {
            OffboardSetpoint::Global(_, Targets { position: Some(g), .. }) => {
                !(g.lat_deg.abs() > 90.0 || g.lon_deg.abs() > 180.0)
            }
            _ => true,
        }
    }

    /// Resolved to local NED against the measurement `meas`, the NED origin
    /// and home at the instant it arrives.
    pub(in crate::autopilot) fn resolve(
        &self,
        meas: &Measurement,
        origin: &GeoPoint,
        home: &GeoPoint,
    ) -> LocalSetpoint {
        match *self {
            OffboardSetpoint::Local(t) => LocalSetpoint::Local(t),
            OffboardSetpoint::Relative(RelativeFrame::OffsetNed, t) => {
                LocalSetpoint::Local(t.map_position(|p| p + meas.position_ned))
            }
            OffboardSetpoint::Relative(RelativeFrame::Body, t) => {
                let r = Rotation3::from_axis_angle(&Vector3::z_axis(), euler_zyx(&meas.attitude).z);
                let turn = |v: Vector3<f64>| rotate_keep_nan(&r, v);
                LocalSetpoint::Local(Targets {
                    velocity: t.velocity.map(turn),
                    acceleration: t.acceleration.map(turn),
                    ..t.map_position(|p| turn(p) + meas.position_ned)
                })
            }
            OffboardSetpoint::Global(altitude, t) => {
                let base = match altitude {
                    AltitudeReference::Amsl => 0.0,
                    AltitudeReference::Home => home.alt_amsl_m,
                    AltitudeReference::Terrain => origin.alt_amsl_m,
                };
                LocalSetpoint::Local(t.map_position(|g| {
                    GeoPoint {
                        lat_deg: g.lat_deg,
                        lon_deg: g.lon_deg,
                        alt_amsl_m: g.alt_m + base,
                    }
                    .ned_from(origin)
                }))
            }
            OffboardSetpoint::Attitude(a) => LocalSetpoint::Attitude(a),
        }
    }
}

impl LocalSetpoint {
    /// A position target above the altitude limit (NED z below `min_z` [m])
    /// is lowered to it; true when it was.
    pub(in crate::autopilot) fn clamp_position_z(&mut self, min_z: f64) -> bool {
        match self {
            LocalSetpoint::Local(Targets { position: Some(p), .. }) if p.z < min_z => {
                p.z = min_z;
                true
            }
            _ => false,
        }
    }

    /// The position target's NED z [m], if it has one.
    pub(in crate::autopilot) fn position_z(&self) -> Option<f64> {
        match self {
            LocalSetpoint::Local(Targets { position: Some(p), .. }) => Some(p.z),
            _ => None,
        }
    }

    /// Whether it can be followed: every given part finite, something given.
    pub(in crate::autopilot) fn is_valid(&self) -> bool {
        match self {
            LocalSetpoint::Local(t) => {
                let parts = [&t.position, &t.velocity, &t.acceleration];
                parts.iter().any(|p| p.is_some())
                    && parts.iter().all(|p| p.is_none_or(|v| finite3(&v)))
                    && t.yaw_rad.is_none_or(f64::is_finite)
                    && t.yaw_rate_rad_s.is_none_or(f64::is_finite)
            }
            LocalSetpoint::Attitude(a) => {
                a.thrust_normalised.is_finite()
                    && a.attitude.is_none_or(|q| q.coords.iter().all(|x| x.is_finite()))
                    && a.rate_frd.is_none_or(|w| finite3(&w))
            }
        }
    }

    /// Whether it asks a landed vehicle to take off: a position more than
    /// `TAKEOFF_TRIGGER_M` above it, a climb or upward acceleration, or any
    /// attitude setpoint (its thrust decides).
    fn wants_to_climb(&self, meas: &Measurement) -> bool {
        match self {
            LocalSetpoint::Local(t) => {
                if let Some(p) = t.position {
                    p.z < meas.position_ned.z - TAKEOFF_TRIGGER_M
                } else if let Some(v) = t.velocity {
                    v.z < -TAKEOFF_TRIGGER_M_S
                } else {
                    t.acceleration.is_some_and(|a| a.z < -TAKEOFF_TRIGGER_M_S2)
                }
            }
            LocalSetpoint::Attitude(_) => true,
        }
    }
}

fn yaw_setpoint(yaw_rad: Option<f64>, yaw_rate_rad_s: Option<f64>) -> YawSetpoint {
    match (yaw_rad, yaw_rate_rad_s) {
        (Some(y), _) => YawSetpoint::Angle(y),
        (None, Some(r)) => YawSetpoint::Rate(r),
        (None, None) => YawSetpoint::Hold,
    }
}

impl Navigator {
    /// Keep `sp` (valid, resolved) as the latest setpoint, arrived at `now` [s].
    pub(in crate::autopilot) fn set_offboard(&mut self, sp: LocalSetpoint, now: f64) {
        if !matches!(sp, LocalSetpoint::Attitude(AttitudeTarget { attitude: None, .. })) {
            self.rate_target = None;
        }
        self.offboard = Some((sp, now));
        self.offboard_lost = false;
    }

    /// Whether a setpoint arrived within `loss_s` [s] of `now` (simulated
    /// time), or, when the runtime times the link on the wall clock, whether
    /// a setpoint exists that the runtime has not declared lost.
    pub(in crate::autopilot) fn offboard_fresh(&self, now: f64, loss_s: f64, clock: ClientClock) -> bool {
        match clock {
            ClientClock::Simulated => self.offboard.is_some_and(|(_, t)| now - t < loss_s - TIME_EPS),
            ClientClock::Wall => self.offboard.is_some() && !self.offboard_lost,
        }
    }

    /// When the latest setpoint arrived [s], unless declared lost.
    pub(in crate::autopilot) fn offboard_arrival(&self) -> Option<f64> {
        self.offboard.filter(|_| !self.offboard_lost).map(|(_, t)| t)
    }

    /// The runtime declared the setpoint stream lost (wall clock).
    pub(in crate::autopilot) fn offboard_timed_out(&mut self) {
        self.offboard_lost = true;
    }

    /// Follow the setpoints.
    pub(in crate::autopilot) fn enter_offboard(&mut self) {
        self.nav = Nav::Offboard;
        self.rate_target = None;
    }

    /// The demand in Offboard.
    pub(super) fn offboard_demand(&mut self, cx: &Situation<'_>) -> Demand {
        let (meas, dt) = (cx.meas, cx.dt);
        let s = cx.settings;
        let normal = self.limits(self.cruise_m_s(s), s.climb_m_s, s.descent_m_s);
        // every setpoint that moves the vehicle: PX4's position controller's limit
        let offboard = ShaperLimits {
            max_speed_xy_m_s: s.xy_vel_max_m_s,
            track_gain_per_s: TRACK_GAIN_PER_S,
            ..normal
        };
        let hold = Setpoint {
            translation: TranslationSetpoint::Hold,
            yaw: YawSetpoint::Hold,
        };
        let Some((sp, _)) = self.offboard else {
            return Demand::Track(self.shape(meas, hold, normal, dt));
        };
        if cx.resting && !sp.wants_to_climb(meas) {
            // PX4's takeoff handling: a vehicle on the ground idles until the setpoint asks it up
            return Demand::Idle;
        }
        match sp {
            LocalSetpoint::Local(Targets {
                position,
                velocity,
                acceleration,
                yaw_rad,
                yaw_rate_rad_s,
            }) => {
                let yaw = yaw_setpoint(yaw_rad, yaw_rate_rad_s);
                let feed_forward = velocity.is_some() || acceleration.is_some();
                if let Some(p) = position.filter(|p| feed_forward && finite3(p)) {
                    // PX4's trajectory setpoint: the velocity and acceleration
                    // given with the position are its feed-forward
                    let nan = Vector3::repeat(f64::NAN);
                    let sp = Setpoint {
                        translation: TranslationSetpoint::Track {
                            position: p,
                            velocity: velocity.unwrap_or(nan),
                            acceleration: acceleration.unwrap_or(nan),
                        },
                        yaw,
                    };
                    Demand::Track(self.shape(meas, sp, offboard, dt))
                } else if let Some(p) = position {
                    Demand::Track(self.go_to(meas, p, yaw, offboard, dt))
                } else if let Some(v) = velocity {
                    let sp = Setpoint {
                        translation: TranslationSetpoint::Velocity(v),
                        yaw,
                    };
                    Demand::Track(self.shape(meas, sp, offboard, dt))
                } else if let Some(a) = acceleration {
                    // Pure acceleration: feedforward from the measured state (drifts, as in PX4).
                    self.shaper_live = false;
                    let heading = euler_zyx(&meas.attitude).z;
                    Demand::Track(Reference {
                        position_ned: meas.position_ned,
                        velocity_ned: meas.velocity_ned,
                        acceleration_ned: a,
                        yaw_rad: yaw_rad.unwrap_or(heading),
                        yaw_rate_rad_s: if yaw_rad.is_some() {
                            0.0
                        } else {
                            yaw_rate_rad_s.unwrap_or(0.0)
                        },
                        ..Reference::default()
                    })
                } else {
                    Demand::Track(self.shape(meas, hold, normal, dt))
                }
            }
            LocalSetpoint::Attitude(AttitudeTarget {
                attitude,
                rate_frd,
                thrust_normalised,
            }) => {
                self.shaper_live = false;
                let rate = rate_frd.unwrap_or_else(Vector3::zeros);
                let q = match attitude {
                    Some(q) => {
                        self.rate_target = None;
                        q
                    }
                    None => {
                        let q0 = self.rate_target.unwrap_or(meas.attitude);
                        let q1 = q0 * UnitQuaternion::from_scaled_axis(rate * dt);
                        self.rate_target = Some(q1);
                        q1
                    }
                };
                Demand::Attitude {
                    attitude: q,
                    rate_frd: rate,
                    thrust_n: thrust_normalised.clamp(0.0, 1.0) * cx.max_thrust_n,
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn facing_east_at(p: Vector3<f64>) -> Measurement {
        Measurement {
            time_s: 1.0,
            position_ned: p,
            velocity_ned: Vector3::zeros(),
            attitude: UnitQuaternion::from_euler_angles(0.0, 0.0, std::f64::consts::FRAC_PI_2),
            rate_frd: Vector3::zeros(),
        }
    }

    fn position<P>(position: P) -> Targets<P> {
        Targets {
            position: Some(position),
            velocity: None,
            acceleration: None,
            yaw_rad: None,
            yaw_rate_rad_s: None,
        }
    }

    fn local(sp: LocalSetpoint) -> Targets<Vector3<f64>> {
        match sp {
            LocalSetpoint::Local(t) => t,
            LocalSetpoint::Attitude(_) => panic!("{sp:?}"),
        }
    }

    #[test]
    fn relative_frames_resolve_against_the_state_when_applied() {
        let home = GeoPoint::PX4_SITL_HOME;
        let m = facing_east_at(Vector3::new(1.0, 2.0, -3.0));
        // BODY_NED velocity: forward 0.5 becomes east when facing east; a NaN stays unset
        let body = OffboardSetpoint::Relative(
            RelativeFrame::Body,
            Targets {
                velocity: Some(Vector3::new(0.5, 0.0, -0.2)),
                yaw_rate_rad_s: Some(0.1),
                ..position(Vector3::new(2.0, 0.0, f64::NAN))
            },
        );
        let t = local(body.resolve(&m, &home, &home));
        assert!((t.velocity.unwrap() - Vector3::new(0.0, 0.5, -0.2)).norm() < 1e-9);
        assert_eq!(t.yaw_rate_rad_s, Some(0.1));
        let p = t.position.unwrap();
        assert!((p.xy() - Vector3::new(1.0, 4.0, 0.0).xy()).norm() < 1e-9, "{p}");
        assert!(p.z.is_nan());
        let offset = OffboardSetpoint::Relative(RelativeFrame::OffsetNed, position(Vector3::new(1.0, 0.0, 0.0)));
        assert_eq!(
            local(offset.resolve(&m, &home, &home)).position,
            Some(Vector3::new(2.0, 2.0, -3.0))
        );
    }

    #[test]
    fn global_altitudes_from_their_reference() {
        let origin = GeoPoint::PX4_SITL_HOME;
        let home = GeoPoint {
            alt_amsl_m: origin.alt_amsl_m + 2.0,
            ..origin
        };
        let m = facing_east_at(Vector3::zeros());
        let global = |altitude, lat_deg, alt_m| {
            OffboardSetpoint::Global(
                altitude,
                position(GlobalTarget {
                    lat_deg,
                    lon_deg: origin.lon_deg,
                    alt_m,
                }),
            )
        };
        let at = |altitude, alt_m| {
            local(global(altitude, origin.lat_deg, alt_m).resolve(&m, &origin, &home))
                .position
                .unwrap()
        };
        assert!((at(AltitudeReference::Home, 10.0) - Vector3::new(0.0, 0.0, -12.0)).norm() < 1e-9);
        assert!((at(AltitudeReference::Terrain, 10.0).z + 10.0).abs() < 1e-9);
        assert!((at(AltitudeReference::Amsl, origin.alt_amsl_m + 5.0).z + 5.0).abs() < 1e-9);
        // off the globe: out of range; an unset latitude is fine
        let far = |lat_deg| global(AltitudeReference::Home, lat_deg, 10.0);
        assert!(!far(200.0).position_in_range());
        assert!(far(f64::NAN).position_in_range() && far(47.0).position_in_range());
    }
}
