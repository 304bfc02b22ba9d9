//! Offboard: external setpoints (SET_POSITION_TARGET_*, SET_ATTITUDE_TARGET)
//! followed while they keep coming. A setpoint in a relative or global frame
//! is resolved to local NED against the measurement at the instant it
//! arrives, as PX4 does: LOCAL_OFFSET_NED adds the current position; the body
//! frames (BODY_NED, BODY_OFFSET_NED, BODY_FRD) turn velocity and
//! acceleration by the current heading (so "forward" stays horizontal) and
//! take position as a turned offset; global targets are converted around the
//! NED origin, their altitude AMSL, above home, or above the ground at the
//! origin. A NaN component is PX4's "unset" and stays NaN.

use nalgebra::{Rotation3, UnitQuaternion, Vector3};

use super::{Nav, Navigator, Situation};
use crate::autopilot::TIME_EPS;
use crate::autopilot::control_loop::Demand;
use crate::control::{Reference, Setpoint, ShaperLimits, TranslationSetpoint, YawSetpoint};
use crate::geo::GeoPoint;
use crate::math::euler_zyx;
use crate::signals::Measurement;

/// Landed in offboard, a position setpoint this far [m] above the vehicle starts the flight (PX4's takeoff trigger)...
const TAKEOFF_TRIGGER_M: f64 = 0.2;
/// ... as does a climb-rate setpoint above this [m/s], or an upward acceleration setpoint above this [m/s^2].
const TAKEOFF_TRIGGER_M_S: f64 = 0.3;
const TAKEOFF_TRIGGER_M_S2: f64 = 0.5;

/// A frame measured from where the vehicle is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RelativeFrame {
    /// LOCAL_OFFSET_NED (7): position is an offset from the current position, in NED.
    OffsetNed,
    /// BODY_NED (8), BODY_OFFSET_NED (9), BODY_FRD (12): forward-right-down
    /// turned by the current heading only; position is an offset from the
    /// current position.
    Body,
}

/// What a global target's altitude is measured from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AltitudeReference {
    /// GLOBAL (0), GLOBAL_INT (5): AMSL.
    Amsl,
    /// GLOBAL_RELATIVE_ALT (3, 6): above home.
    Home,
    /// GLOBAL_TERRAIN_ALT (10, 11): above the (flat) ground at the NED origin.
    Terrain,
}

/// A global position target: a NaN component is unset.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GlobalTarget {
    /// Latitude [deg].
    pub lat_deg: f64,
    /// Longitude [deg].
    pub lon_deg: f64,
    /// Altitude [m] above the [`AltitudeReference`].
    pub alt_m: f64,
}

/// An offboard setpoint as it arrives, in SI units; `None` = ignored by the
/// mask, a NaN component = unset.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum OffboardSetpoint {
    /// LOCAL_NED: position / velocity / acceleration in local NED.
    Local {
        /// Position [m], NED.
        position_ned: Option<Vector3<f64>>,
        /// Velocity [m/s], NED.
        velocity_ned: Option<Vector3<f64>>,
        /// Acceleration [m/s^2], NED.
        acceleration_ned: Option<Vector3<f64>>,
        /// Yaw [rad].
        yaw_rad: Option<f64>,
        /// Yaw rate [rad/s].
        yaw_rate_rad_s: Option<f64>,
    },
    /// Measured from the vehicle's position and heading when it arrives.
    Relative {
        /// How to read the vectors.
        frame: RelativeFrame,
        /// Position offset [m].
        position: Option<Vector3<f64>>,
        /// Velocity [m/s].
        velocity: Option<Vector3<f64>>,
        /// Acceleration [m/s^2].
        acceleration: Option<Vector3<f64>>,
        /// Yaw [rad].
        yaw_rad: Option<f64>,
        /// Yaw rate [rad/s].
        yaw_rate_rad_s: Option<f64>,
    },
    /// SET_POSITION_TARGET_GLOBAL_INT: a global position, NED velocity and acceleration.
    Global {
        /// Position.
        position: Option<GlobalTarget>,
        /// What the altitude is measured from.
        altitude: AltitudeReference,
        /// Velocity [m/s], NED.
        velocity_ned: Option<Vector3<f64>>,
        /// Acceleration [m/s^2], NED.
        acceleration_ned: Option<Vector3<f64>>,
        /// Yaw [rad].
        yaw_rad: Option<f64>,
        /// Yaw rate [rad/s].
        yaw_rate_rad_s: Option<f64>,
    },
    /// Attitude (or body rates) and normalised thrust.
    Attitude {
        /// Attitude, FRD to NED; `None` = rates only.
        attitude: Option<UnitQuaternion<f64>>,
        /// Body rates [rad/s], FRD; `None` = ignored.
        rate_frd: Option<Vector3<f64>>,
        /// Collective thrust, 0..1 of the maximum.
        thrust_normalised: f64,
    },
}

/// A setpoint resolved to local NED (what offboard guidance follows).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(in crate::autopilot) enum LocalSetpoint {
    /// Targets in local NED.
    Local {
        position_ned: Option<Vector3<f64>>,
        velocity_ned: Option<Vector3<f64>>,
        acceleration_ned: Option<Vector3<f64>>,
        yaw_rad: Option<f64>,
        yaw_rate_rad_s: Option<f64>,
    },
    /// Attitude or rates and thrust.
    Attitude {
        attitude: Option<UnitQuaternion<f64>>,
        rate_frd: Option<Vector3<f64>>,
        thrust_normalised: f64,
    },
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
            OffboardSetpoint::Global { position: Some(g), .. } => !(g.lat_deg.abs() > 90.0 || g.lon_deg.abs() > 180.0),
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
            OffboardSetpoint::Local {
                position_ned,
                velocity_ned,
                acceleration_ned,
                yaw_rad,
                yaw_rate_rad_s,
            } => LocalSetpoint::Local {
                position_ned,
                velocity_ned,
                acceleration_ned,
                yaw_rad,
                yaw_rate_rad_s,
            },
            OffboardSetpoint::Relative {
                frame,
                position,
                velocity,
                acceleration,
                yaw_rad,
                yaw_rate_rad_s,
            } => {
                let here = meas.position_ned;
                let (position_ned, velocity_ned, acceleration_ned) = match frame {
                    RelativeFrame::OffsetNed => (position.map(|p| p + here), velocity, acceleration),
                    RelativeFrame::Body => {
                        let r = Rotation3::from_axis_angle(&Vector3::z_axis(), euler_zyx(&meas.attitude).z);
                        let turn = |v: Vector3<f64>| rotate_keep_nan(&r, v);
                        (
                            position.map(|p| turn(p) + here),
                            velocity.map(turn),
                            acceleration.map(turn),
                        )
                    }
                };
                LocalSetpoint::Local {
                    position_ned,
                    velocity_ned,
                    acceleration_ned,
                    yaw_rad,
                    yaw_rate_rad_s,
                }
            }
            OffboardSetpoint::Global {
                position,
                altitude,
                velocity_ned,
                acceleration_ned,
                yaw_rad,
                yaw_rate_rad_s,
            } => {
                let base = match altitude {
                    AltitudeReference::Amsl => 0.0,
                    AltitudeReference::Home => home.alt_amsl_m,
                    AltitudeReference::Terrain => origin.alt_amsl_m,
                };
                let position_ned = position.map(|g| {
                    GeoPoint {
                        lat_deg: g.lat_deg,
                        lon_deg: g.lon_deg,
                        alt_amsl_m: g.alt_m + base,
                    }
                    .ned_from(origin)
                });
                LocalSetpoint::Local {
                    position_ned,
                    velocity_ned,
                    acceleration_ned,
                    yaw_rad,
                    yaw_rate_rad_s,
                }
            }
            OffboardSetpoint::Attitude {
                attitude,
                rate_frd,
                thrust_normalised,
            } => LocalSetpoint::Attitude {
                attitude,
                rate_frd,
                thrust_normalised,
            },
        }
    }
}

impl LocalSetpoint {
    /// Whether it can be followed: every given part finite, something given.
    pub(in crate::autopilot) fn is_valid(&self) -> bool {
        match self {
            LocalSetpoint::Local {
                position_ned,
                velocity_ned,
                acceleration_ned,
                yaw_rad,
                yaw_rate_rad_s,
            } => {
                let parts = [position_ned, velocity_ned, acceleration_ned];
                parts.iter().any(|p| p.is_some())
                    && parts.iter().all(|p| p.is_none_or(|v| finite3(&v)))
                    && yaw_rad.is_none_or(f64::is_finite)
                    && yaw_rate_rad_s.is_none_or(f64::is_finite)
            }
            LocalSetpoint::Attitude {
                attitude,
                rate_frd,
                thrust_normalised,
            } => {
                thrust_normalised.is_finite()
                    && attitude.is_none_or(|q| q.coords.iter().all(|x| x.is_finite()))
                    && rate_frd.is_none_or(|w| finite3(&w))
            }
        }
    }

    /// Whether it asks a landed vehicle to take off: a position more than
    /// `TAKEOFF_TRIGGER_M` above it, a climb or upward acceleration, or any
    /// attitude setpoint (its thrust decides).
    fn wants_to_climb(&self, meas: &Measurement) -> bool {
        match self {
            LocalSetpoint::Local {
                position_ned,
                velocity_ned,
                acceleration_ned,
                ..
            } => {
                if let Some(p) = position_ned {
                    p.z < meas.position_ned.z - TAKEOFF_TRIGGER_M
                } else if let Some(v) = velocity_ned {
                    v.z < -TAKEOFF_TRIGGER_M_S
                } else {
                    acceleration_ned.is_some_and(|a| a.z < -TAKEOFF_TRIGGER_M_S2)
                }
            }
            LocalSetpoint::Attitude { .. } => true,
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
        if !matches!(sp, LocalSetpoint::Attitude { attitude: None, .. }) {
            self.rate_target = None;
        }
        self.offboard = Some((sp, now));
    }

    /// Whether a setpoint arrived within `loss_s` [s] of `now`.
    pub(in crate::autopilot) fn offboard_fresh(&self, now: f64, loss_s: f64) -> bool {
        self.offboard.is_some_and(|(_, t)| now - t <= loss_s + TIME_EPS)
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
            LocalSetpoint::Local {
                position_ned,
                velocity_ned,
                acceleration_ned,
                yaw_rad,
                yaw_rate_rad_s,
            } => {
                let yaw = yaw_setpoint(yaw_rad, yaw_rate_rad_s);
                if let Some(p) = position_ned {
                    Demand::Track(self.go_to(meas, p, yaw, normal, dt))
                } else if let Some(v) = velocity_ned {
                    let limits = ShaperLimits {
                        max_speed_xy_m_s: s.xy_vel_max_m_s,
                        ..normal
                    };
                    let sp = Setpoint {
                        translation: TranslationSetpoint::Velocity(v),
                        yaw,
                    };
                    Demand::Track(self.shape(meas, sp, limits, dt))
                } else if let Some(a) = acceleration_ned {
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
            LocalSetpoint::Attitude {
                attitude,
                rate_frd,
                thrust_normalised,
            } => {
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

    #[test]
    fn relative_frames_resolve_against_the_state_when_applied() {
        let home = GeoPoint::PX4_SITL_HOME;
        let m = facing_east_at(Vector3::new(1.0, 2.0, -3.0));
        // BODY_NED velocity: forward 0.5 becomes east when facing east; a NaN stays unset
        let body = OffboardSetpoint::Relative {
            frame: RelativeFrame::Body,
            position: Some(Vector3::new(2.0, 0.0, f64::NAN)),
            velocity: Some(Vector3::new(0.5, 0.0, -0.2)),
            acceleration: None,
            yaw_rad: None,
            yaw_rate_rad_s: Some(0.1),
        };
        let LocalSetpoint::Local {
            position_ned,
            velocity_ned,
            ..
        } = body.resolve(&m, &home, &home)
        else {
            panic!()
        };
        assert!((velocity_ned.unwrap() - Vector3::new(0.0, 0.5, -0.2)).norm() < 1e-9);
        let p = position_ned.unwrap();
        assert!((p.xy() - Vector3::new(1.0, 4.0, 0.0).xy()).norm() < 1e-9, "{p}");
        assert!(p.z.is_nan());
        let offset = OffboardSetpoint::Relative {
            frame: RelativeFrame::OffsetNed,
            position: Some(Vector3::new(1.0, 0.0, 0.0)),
            velocity: None,
            acceleration: None,
            yaw_rad: None,
            yaw_rate_rad_s: None,
        };
        let LocalSetpoint::Local { position_ned, .. } = offset.resolve(&m, &home, &home) else {
            panic!()
        };
        assert_eq!(position_ned, Some(Vector3::new(2.0, 2.0, -3.0)));
    }

    #[test]
    fn global_altitudes_from_their_reference() {
        let origin = GeoPoint::PX4_SITL_HOME;
        let home = GeoPoint {
            alt_amsl_m: origin.alt_amsl_m + 2.0,
            ..origin
        };
        let m = facing_east_at(Vector3::zeros());
        let at = |altitude, alt_m| {
            let sp = OffboardSetpoint::Global {
                position: Some(GlobalTarget {
                    lat_deg: origin.lat_deg,
                    lon_deg: origin.lon_deg,
                    alt_m,
                }),
                altitude,
                velocity_ned: None,
                acceleration_ned: None,
                yaw_rad: None,
                yaw_rate_rad_s: None,
            };
            let LocalSetpoint::Local { position_ned, .. } = sp.resolve(&m, &origin, &home) else {
                panic!()
            };
            position_ned.unwrap()
        };
        assert!((at(AltitudeReference::Home, 10.0) - Vector3::new(0.0, 0.0, -12.0)).norm() < 1e-9);
        assert!((at(AltitudeReference::Terrain, 10.0).z + 10.0).abs() < 1e-9);
        assert!((at(AltitudeReference::Amsl, origin.alt_amsl_m + 5.0).z + 5.0).abs() < 1e-9);
        // off the globe: out of range; an unset latitude is fine
        let far = |lat_deg| OffboardSetpoint::Global {
            position: Some(GlobalTarget {
                lat_deg,
                lon_deg: 8.5,
                alt_m: 10.0,
            }),
            altitude: AltitudeReference::Home,
            velocity_ned: None,
            acceleration_ned: None,
            yaw_rad: None,
            yaw_rate_rad_s: None,
        };
        assert!(!far(200.0).position_in_range());
        assert!(far(f64::NAN).position_in_range() && far(47.0).position_in_range());
    }
}
