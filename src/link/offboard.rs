//! Offboard setpoints: SET_POSITION_TARGET_LOCAL_NED (84),
//! SET_POSITION_TARGET_GLOBAL_INT (86) and SET_ATTITUDE_TARGET (82) into
//! [`OffboardSetpoint`]s in NED/FRD SI units.
//!
//! The type masks are decoded bit by bit (MAVSDK uses 2552, 2503, 1479, 2496,
//! 2048 and 3135, but any combination is read). A vector whose three
//! components are all ignored becomes `None`; a partly ignored vector keeps
//! NaN in the ignored components, PX4's "unset" (for example, position x/y
//! with velocity z). The autopilot does not fly such mixed setpoints yet: it
//! refuses them (and a SET_ATTITUDE_TARGET without thrust), which the daemon
//! logs; setpoints have no ACK.
//!
//! Frames: LOCAL_NED (1) as is; LOCAL_OFFSET_NED (7) position relative to the
//! current position; BODY_NED (8), BODY_OFFSET_NED (9) and BODY_FRD (12)
//! rotate velocity and acceleration by the current heading (PX4 turns a body
//! velocity into NED so that "forward" stays horizontal) and take position as
//! an offset from the current position, also rotated. Global: GLOBAL_INT (5)
//! and GLOBAL (0) altitude AMSL, RELATIVE_ALT (6, 3) above home, TERRAIN_ALT
//! (11, 10) above the flat ground at the NED origin's altitude. Other frames
//! are ignored, as PX4 ignores them.

use mavlink::dialects::common::{
    SET_ATTITUDE_TARGET_DATA, SET_POSITION_TARGET_GLOBAL_INT_DATA, SET_POSITION_TARGET_LOCAL_NED_DATA,
};
use nalgebra::{Quaternion, Rotation3, UnitQuaternion, Vector3};

use crate::autopilot::{OffboardSetpoint, Telemetry};
use crate::geo::GeoPoint;

/// Position-target mask bits.
mod bit {
    pub(super) const X: u16 = 1;
    pub(super) const VX: u16 = 8;
    pub(super) const AX: u16 = 64;
    pub(super) const YAW: u16 = 1024;
    pub(super) const YAW_RATE: u16 = 2048;
}

/// Three components, each NaN where `mask` (three bits from `first`) says
/// ignore; `None` when nothing is left.
fn masked(v: [f32; 3], mask: u16, first: u16) -> Option<Vector3<f64>> {
    let mut out = Vector3::zeros();
    let mut any = false;
    for (i, x) in v.iter().enumerate() {
        let ignored = mask & (first << i) != 0;
        out[i] = if ignored || !x.is_finite() {
            f64::NAN
        } else {
            any = true;
            f64::from(*x)
        };
    }
    any.then_some(out)
}

fn scalar(v: f32, mask: u16, b: u16) -> Option<f64> {
    (mask & b == 0 && v.is_finite()).then_some(f64::from(v))
}

fn yaw_of(t: &Telemetry) -> f64 {
    t.attitude.euler_angles().2
}

/// How a local frame is read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum LocalFrame {
    Ned,
    OffsetNed,
    Body,
}

fn local_frame(frame: u8) -> Option<LocalFrame> {
    match frame {
        1 => Some(LocalFrame::Ned),
        7 => Some(LocalFrame::OffsetNed),
        8 | 9 | 12 => Some(LocalFrame::Body),
        _ => None,
    }
}

/// SET_POSITION_TARGET_LOCAL_NED to a setpoint; `None` for an unsupported
/// frame or a message that sets nothing.
#[must_use]
pub fn local_ned(m: &SET_POSITION_TARGET_LOCAL_NED_DATA, t: &Telemetry) -> Option<OffboardSetpoint> {
    let frame = local_frame(m.coordinate_frame as u8)?;
    let mask = m.type_mask.bits();
    let mut position = masked([m.x, m.y, m.z], mask, bit::X);
    let mut velocity = masked([m.vx, m.vy, m.vz], mask, bit::VX);
    let mut acceleration = masked([m.afx, m.afy, m.afz], mask, bit::AX);
    match frame {
        LocalFrame::Ned => {}
        LocalFrame::OffsetNed => position = position.map(|p| offset(p, &t.position_ned)),
        LocalFrame::Body => {
            let r = Rotation3::from_axis_angle(&Vector3::z_axis(), yaw_of(t));
            let rot = |v: Vector3<f64>| rotate_keep_nan(&r, v);
            position = position.map(|p| offset(rot(p), &t.position_ned));
            velocity = velocity.map(rot);
            acceleration = acceleration.map(rot);
        }
    }
    let sp = OffboardSetpoint::Local {
        position_ned: position,
        velocity_ned: velocity,
        acceleration_ned: acceleration,
        yaw_rad: scalar(m.yaw, mask, bit::YAW),
        yaw_rate_rad_s: scalar(m.yaw_rate, mask, bit::YAW_RATE),
    };
    sets_something(&sp).then_some(sp)
}

/// SET_POSITION_TARGET_GLOBAL_INT to a setpoint in local NED.
#[must_use]
pub fn global_int(m: &SET_POSITION_TARGET_GLOBAL_INT_DATA, t: &Telemetry) -> Option<OffboardSetpoint> {
    let alt_base = match m.coordinate_frame as u8 {
        0 | 5 => 0.0,
        3 | 6 => t.home.alt_amsl_m,
        10 | 11 => t.origin.alt_amsl_m,
        _ => return None,
    };
    let mask = m.type_mask.bits();
    let point = GeoPoint {
        lat_deg: f64::from(m.lat_int) * 1e-7,
        lon_deg: f64::from(m.lon_int) * 1e-7,
        alt_amsl_m: f64::from(m.alt) + alt_base,
    };
    let ned = point.ned_from(&t.origin);
    let position = masked([ned.x as f32, ned.y as f32, ned.z as f32], mask, bit::X).map(|mut p| {
        // keep f64 precision where the component is used
        for i in 0..3 {
            if p[i].is_finite() {
                p[i] = ned[i];
            }
        }
        p
    });
    let sp = OffboardSetpoint::Local {
        position_ned: position,
        velocity_ned: masked([m.vx, m.vy, m.vz], mask, bit::VX),
        acceleration_ned: masked([m.afx, m.afy, m.afz], mask, bit::AX),
        yaw_rad: scalar(m.yaw, mask, bit::YAW),
        yaw_rate_rad_s: scalar(m.yaw_rate, mask, bit::YAW_RATE),
    };
    sets_something(&sp).then_some(sp)
}

/// SET_ATTITUDE_TARGET to a setpoint. Mask bits 1, 2, 4 ignore the body
/// rates, 64 the thrust (NaN then), 128 the attitude.
#[must_use]
pub fn attitude(m: &SET_ATTITUDE_TARGET_DATA) -> Option<OffboardSetpoint> {
    let mask = u16::from(m.type_mask.bits());
    let attitude = if mask & 128 == 0 {
        let q = Quaternion::new(
            f64::from(m.q[0]),
            f64::from(m.q[1]),
            f64::from(m.q[2]),
            f64::from(m.q[3]),
        );
        let n = q.norm();
        if !n.is_finite() || n < 0.5 {
            return None;
        }
        Some(UnitQuaternion::from_quaternion(q))
    } else {
        None
    };
    let rate_frd = masked([m.body_roll_rate, m.body_pitch_rate, m.body_yaw_rate], mask, 1);
    if attitude.is_none() && rate_frd.is_none() {
        return None;
    }
    let thrust = if mask & 64 == 0 && m.thrust.is_finite() {
        f64::from(m.thrust).clamp(0.0, 1.0)
    } else {
        f64::NAN
    };
    Some(OffboardSetpoint::Attitude {
        attitude,
        rate_frd,
        thrust_normalised: thrust,
    })
}

fn offset(p: Vector3<f64>, current: &Vector3<f64>) -> Vector3<f64> {
    p + current
}

fn rotate_keep_nan(r: &Rotation3<f64>, v: Vector3<f64>) -> Vector3<f64> {
    // Rotate the finite part; a NaN component stays unset.
    let nan = v.map(f64::is_nan);
    let rotated = r * v.map(|x| if x.is_nan() { 0.0 } else { x });
    Vector3::from_fn(|i, _| if nan[i] { f64::NAN } else { rotated[i] })
}

fn sets_something(sp: &OffboardSetpoint) -> bool {
    match sp {
        OffboardSetpoint::Local {
            position_ned,
            velocity_ned,
            acceleration_ned,
            yaw_rad,
            yaw_rate_rad_s,
        } => {
            position_ned.is_some()
                || velocity_ned.is_some()
                || acceleration_ned.is_some()
                || yaw_rad.is_some()
                || yaw_rate_rad_s.is_some()
        }
        OffboardSetpoint::Attitude { .. } => true,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::testing::telemetry;
    use mavlink::dialects::common::{AttitudeTargetTypemask, MavFrame, PositionTargetTypemask};

    fn local(mask: u16, frame: MavFrame) -> SET_POSITION_TARGET_LOCAL_NED_DATA {
        SET_POSITION_TARGET_LOCAL_NED_DATA {
            time_boot_ms: 0,
            x: 1.0,
            y: 2.0,
            z: -3.0,
            vx: 0.5,
            vy: 0.0,
            vz: -0.2,
            afx: 0.0,
            afy: 0.0,
            afz: 0.0,
            yaw: 0.7,
            yaw_rate: 0.1,
            type_mask: PositionTargetTypemask::from_bits_retain(mask),
            target_system: 1,
            target_component: 1,
            coordinate_frame: frame,
        }
    }

    #[test]
    fn mavsdk_masks() {
        let t = telemetry();
        let f = MavFrame::MAV_FRAME_LOCAL_NED;
        // 2552: position + yaw
        let Some(OffboardSetpoint::Local {
            position_ned,
            velocity_ned,
            acceleration_ned,
            yaw_rad,
            yaw_rate_rad_s,
        }) = local_ned(&local(2552, f), &t)
        else {
            panic!()
        };
        assert_eq!(position_ned, Some(Vector3::new(1.0, 2.0, -3.0)));
        assert!(velocity_ned.is_none() && acceleration_ned.is_none() && yaw_rate_rad_s.is_none());
        assert!((yaw_rad.unwrap() - 0.7).abs() < 1e-6);
        // 2503: velocity + yaw
        let Some(OffboardSetpoint::Local {
            position_ned,
            velocity_ned,
            ..
        }) = local_ned(&local(2503, f), &t)
        else {
            panic!()
        };
        assert!(position_ned.is_none());
        assert!((velocity_ned.unwrap() - Vector3::new(0.5, 0.0, -0.2)).norm() < 1e-6);
        // 3135: acceleration only
        let Some(OffboardSetpoint::Local {
            acceleration_ned,
            yaw_rad,
            ..
        }) = local_ned(&local(3135, f), &t)
        else {
            panic!()
        };
        assert_eq!(acceleration_ned, Some(Vector3::zeros()));
        assert!(yaw_rad.is_none());
        // 4: position x/y only; partial masks keep NaN
        let Some(OffboardSetpoint::Local { position_ned, .. }) = local_ned(&local(4, f), &t) else {
            panic!()
        };
        let p = position_ned.unwrap();
        assert_eq!((p.x, p.y), (1.0, 2.0));
        assert!(p.z.is_nan());
        // unsupported frame
        assert!(local_ned(&local(2552, MavFrame::MAV_FRAME_GLOBAL), &t).is_none());
    }

    #[test]
    fn body_velocity_turns_with_heading() {
        let mut t = telemetry();
        t.attitude = UnitQuaternion::from_euler_angles(0.0, 0.0, std::f64::consts::FRAC_PI_2);
        // 1479: velocity + yaw rate, BODY_NED: forward 0.5 becomes east when facing east
        let Some(OffboardSetpoint::Local {
            velocity_ned,
            yaw_rate_rad_s,
            ..
        }) = local_ned(&local(1479, MavFrame::MAV_FRAME_BODY_NED), &t)
        else {
            panic!()
        };
        let v = velocity_ned.unwrap();
        assert!((v - Vector3::new(0.0, 0.5, -0.2)).norm() < 1e-6, "{v}");
        assert!((yaw_rate_rad_s.unwrap() - 0.1).abs() < 1e-6);
    }

    #[test]
    fn global_frames() {
        let t = telemetry();
        let home = t.home;
        let mut m = SET_POSITION_TARGET_GLOBAL_INT_DATA {
            time_boot_ms: 0,
            lat_int: crate::link::convert::deg_e7(home.lat_deg),
            lon_int: crate::link::convert::deg_e7(home.lon_deg),
            alt: 10.0,
            vx: 0.0,
            vy: 0.0,
            vz: 0.0,
            afx: 0.0,
            afy: 0.0,
            afz: 0.0,
            yaw: 0.0,
            yaw_rate: 0.0,
            type_mask: PositionTargetTypemask::from_bits_retain(2552),
            target_system: 1,
            target_component: 1,
            coordinate_frame: MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
        };
        let Some(OffboardSetpoint::Local { position_ned, .. }) = global_int(&m, &t) else {
            panic!()
        };
        assert!((position_ned.unwrap() - Vector3::new(0.0, 0.0, -10.0)).norm() < 0.01);
        m.coordinate_frame = MavFrame::MAV_FRAME_GLOBAL_INT;
        m.alt = (home.alt_amsl_m + 5.0) as f32;
        let Some(OffboardSetpoint::Local { position_ned, .. }) = global_int(&m, &t) else {
            panic!()
        };
        assert!((position_ned.unwrap().z + 5.0).abs() < 0.01);
    }

    #[test]
    fn attitude_masks() {
        let mut m = SET_ATTITUDE_TARGET_DATA {
            time_boot_ms: 0,
            q: [1.0, 0.0, 0.0, 0.0],
            body_roll_rate: 0.0,
            body_pitch_rate: 0.0,
            body_yaw_rate: 0.3,
            thrust: 0.6,
            target_system: 1,
            target_component: 1,
            type_mask: AttitudeTargetTypemask::from_bits_retain(7),
        };
        let Some(OffboardSetpoint::Attitude {
            attitude,
            rate_frd,
            thrust_normalised,
        }) = attitude(&m)
        else {
            panic!()
        };
        assert_eq!(attitude, Some(UnitQuaternion::identity()));
        assert!(rate_frd.is_none());
        assert!((thrust_normalised - 0.6).abs() < 1e-6);
        m.type_mask = AttitudeTargetTypemask::from_bits_retain(128);
        let Some(OffboardSetpoint::Attitude {
            attitude: a, rate_frd, ..
        }) = super::attitude(&m)
        else {
            panic!()
        };
        assert!(a.is_none());
        assert!((rate_frd.unwrap().z - 0.3).abs() < 1e-6);
        m.q = [0.0; 4];
        m.type_mask = AttitudeTargetTypemask::from_bits_retain(7);
        assert!(super::attitude(&m).is_none());
    }
}
