//! Unit tests of `link/offboard.rs`: offboard setpoints: typemasks, frames and
//! targets.

use super::*;
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
    let f = MavFrame::MAV_FRAME_LOCAL_NED;
    // 2552: position + yaw
    let Some(OffboardSetpoint::Local(t)) = local_ned(&local(2552, f)) else {
        panic!()
    };
    assert_eq!(t.position, Some(Vector3::new(1.0, 2.0, -3.0)));
    assert!(t.velocity.is_none() && t.acceleration.is_none() && t.yaw_rate_rad_s.is_none());
    assert!((t.yaw_rad.unwrap() - 0.7).abs() < 1e-6);
    // 2503: velocity + yaw
    let Some(OffboardSetpoint::Local(t)) = local_ned(&local(2503, f)) else {
        panic!()
    };
    assert!(t.position.is_none());
    assert!((t.velocity.unwrap() - Vector3::new(0.5, 0.0, -0.2)).norm() < 1e-6);
    // 3135: acceleration only
    let Some(OffboardSetpoint::Local(t)) = local_ned(&local(3135, f)) else {
        panic!()
    };
    assert_eq!(t.acceleration, Some(Vector3::zeros()));
    assert!(t.yaw_rad.is_none());
    // 4: position x/y only; partial masks keep NaN
    let Some(OffboardSetpoint::Local(t)) = local_ned(&local(4, f)) else {
        panic!()
    };
    let p = t.position.unwrap();
    assert_eq!((p.x, p.y), (1.0, 2.0));
    assert!(p.z.is_nan());
    // unsupported frame
    assert!(local_ned(&local(2552, MavFrame::MAV_FRAME_GLOBAL)).is_none());
}

#[test]
fn relative_frames_are_left_to_the_autopilot() {
    // 1479: velocity + yaw rate, BODY_NED: resolved against the heading when applied
    let Some(OffboardSetpoint::Relative(frame, t)) = local_ned(&local(1479, MavFrame::MAV_FRAME_BODY_NED)) else {
        panic!()
    };
    assert_eq!(frame, RelativeFrame::Body);
    assert!(t.position.is_none());
    assert!((t.velocity.unwrap() - Vector3::new(0.5, 0.0, -0.2)).norm() < 1e-6);
    assert!((t.yaw_rate_rad_s.unwrap() - 0.1).abs() < 1e-6);
    let Some(OffboardSetpoint::Relative(frame, _)) = local_ned(&local(2552, MavFrame::MAV_FRAME_LOCAL_OFFSET_NED))
    else {
        panic!()
    };
    assert_eq!(frame, RelativeFrame::OffsetNed);
}

#[test]
fn global_frames() {
    let home = crate::geo::GeoPoint::PX4_SITL_HOME;
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
    let Some(OffboardSetpoint::Global(altitude, t)) = global_int(&m) else {
        panic!()
    };
    let p = t.position.unwrap();
    assert_eq!(altitude, AltitudeReference::Home);
    assert!((p.lat_deg - home.lat_deg).abs() < 1e-7 && p.alt_m == 10.0);
    m.coordinate_frame = MavFrame::MAV_FRAME_GLOBAL_INT;
    // altitude ignored: unset, the rest kept
    m.type_mask = PositionTargetTypemask::from_bits_retain(2552 | 4);
    let Some(OffboardSetpoint::Global(altitude, t)) = global_int(&m) else {
        panic!()
    };
    assert_eq!(altitude, AltitudeReference::Amsl);
    assert!(t.position.unwrap().alt_m.is_nan());
    m.coordinate_frame = MavFrame::MAV_FRAME_LOCAL_NED;
    assert!(global_int(&m).is_none());
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
        thrust_body: [0.0; 3],
    };
    let Some(OffboardSetpoint::Attitude(AttitudeTarget {
        attitude,
        rate_frd,
        thrust_normalised,
    })) = attitude(&m)
    else {
        panic!()
    };
    assert_eq!(attitude, Some(UnitQuaternion::identity()));
    assert!(rate_frd.is_none());
    assert!((thrust_normalised - 0.6).abs() < 1e-6);
    m.type_mask = AttitudeTargetTypemask::from_bits_retain(128);
    let Some(OffboardSetpoint::Attitude(AttitudeTarget {
        attitude: a, rate_frd, ..
    })) = super::attitude(&m)
    else {
        panic!()
    };
    assert!(a.is_none());
    assert!((rate_frd.unwrap().z - 0.3).abs() < 1e-6);
    m.q = [0.0; 4];
    m.type_mask = AttitudeTargetTypemask::from_bits_retain(7);
    assert!(super::attitude(&m).is_none());
}
