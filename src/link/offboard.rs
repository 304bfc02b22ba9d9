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
//! Frames are passed on as the autopilot must read them: LOCAL_NED (1) as is;
//! LOCAL_OFFSET_NED (7) and the body frames BODY_NED (8), BODY_OFFSET_NED (9),
//! BODY_FRD (12) as [`OffboardSetpoint::Relative`], resolved by the
//! autopilot against the state at the instant the setpoint arrives; global
//! targets with their altitude reference: GLOBAL_INT (5) and GLOBAL (0) AMSL,
//! RELATIVE_ALT (6, 3) above home, TERRAIN_ALT (11, 10) above the ground.
//! Other frames are ignored, as PX4 ignores them.
//!
//! FOLLOW_TARGET (144), the target of follow-me, is read here too: its
//! position (latitude, longitude, altitude AMSL) and, when its
//! `est_capabilities` has the velocity bit, its NED velocity.

use mavlink::dialects::common::{
    FOLLOW_TARGET_DATA, SET_ATTITUDE_TARGET_DATA, SET_POSITION_TARGET_GLOBAL_INT_DATA,
    SET_POSITION_TARGET_LOCAL_NED_DATA,
};
use nalgebra::{Quaternion, UnitQuaternion, Vector3};

use crate::autopilot::{
    AltitudeReference, AttitudeTarget, GlobalTarget, OffboardSetpoint, RelativeFrame, TargetFix, Targets,
};

/// Position-target mask bits.
mod bit {
    pub(super) const X: u16 = 1;
    pub(super) const Y: u16 = 2;
    pub(super) const Z: u16 = 4;
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

/// The targets of a position-target message with `position` (already
/// masked, in the message's frame); `None` when it sets nothing.
fn targets<P>(position: Option<P>, mask: u16, v: [f32; 3], a: [f32; 3], yaw: f32, yaw_rate: f32) -> Option<Targets<P>> {
    let t = Targets {
        position,
        velocity: masked(v, mask, bit::VX),
        acceleration: masked(a, mask, bit::AX),
        yaw_rad: scalar(yaw, mask, bit::YAW),
        yaw_rate_rad_s: scalar(yaw_rate, mask, bit::YAW_RATE),
    };
    t.sets_something().then_some(t)
}

/// SET_POSITION_TARGET_LOCAL_NED to a setpoint; `None` for an unsupported
/// frame or a message that sets nothing.
#[must_use]
pub fn local_ned(m: &SET_POSITION_TARGET_LOCAL_NED_DATA) -> Option<OffboardSetpoint> {
    let frame = match m.coordinate_frame as u8 {
        1 => None,
        7 => Some(RelativeFrame::OffsetNed),
        8 | 9 | 12 => Some(RelativeFrame::Body),
        _ => return None,
    };
    let mask = m.type_mask.bits();
    let position = masked([m.x, m.y, m.z], mask, bit::X);
    let t = targets(
        position,
        mask,
        [m.vx, m.vy, m.vz],
        [m.afx, m.afy, m.afz],
        m.yaw,
        m.yaw_rate,
    )?;
    Some(match frame {
        None => OffboardSetpoint::Local(t),
        Some(frame) => OffboardSetpoint::Relative(frame, t),
    })
}

/// SET_POSITION_TARGET_GLOBAL_INT to a setpoint (latitude and longitude in
/// degrees, the altitude with its reference).
#[must_use]
pub fn global_int(m: &SET_POSITION_TARGET_GLOBAL_INT_DATA) -> Option<OffboardSetpoint> {
    let altitude = match m.coordinate_frame as u8 {
        0 | 5 => AltitudeReference::Amsl,
        3 | 6 => AltitudeReference::Home,
        10 | 11 => AltitudeReference::Terrain,
        _ => return None,
    };
    let mask = m.type_mask.bits();
    let used = |b: u16| mask & b == 0;
    let alt_used = used(bit::Z) && m.alt.is_finite();
    let position = (used(bit::X) || used(bit::Y) || alt_used).then(|| GlobalTarget {
        lat_deg: if used(bit::X) {
            f64::from(m.lat_int) * 1e-7
        } else {
            f64::NAN
        },
        lon_deg: if used(bit::Y) {
            f64::from(m.lon_int) * 1e-7
        } else {
            f64::NAN
        },
        alt_m: if alt_used { f64::from(m.alt) } else { f64::NAN },
    });
    let t = targets(
        position,
        mask,
        [m.vx, m.vy, m.vz],
        [m.afx, m.afy, m.afz],
        m.yaw,
        m.yaw_rate,
    )?;
    Some(OffboardSetpoint::Global(altitude, t))
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
    Some(OffboardSetpoint::Attitude(AttitudeTarget {
        attitude,
        rate_frd,
        thrust_normalised: thrust,
    }))
}

/// FOLLOW_TARGET's `est_capabilities` bit: the velocity is given.
const FOLLOW_VEL: u8 = 2;

/// FOLLOW_TARGET to a target fix (the autopilot refuses one that is not
/// finite or off the globe).
#[must_use]
pub fn follow_target(m: &FOLLOW_TARGET_DATA) -> TargetFix {
    let v = Vector3::new(f64::from(m.vel[0]), f64::from(m.vel[1]), f64::from(m.vel[2]));
    TargetFix {
        lat_deg: f64::from(m.lat) * 1e-7,
        lon_deg: f64::from(m.lon) * 1e-7,
        alt_amsl_m: f64::from(m.alt),
        velocity_ned: (m.est_capabilities & FOLLOW_VEL != 0 && v.iter().all(|x| x.is_finite())).then_some(v),
    }
}

#[cfg(test)]
mod tests;
