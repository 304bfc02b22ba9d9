//! Unit tests of `link/manual.rs`: MANUAL_CONTROL to stick inputs.

use super::*;

fn msg(x: i16, y: i16, z: i16, r: i16) -> MANUAL_CONTROL_DATA {
    MANUAL_CONTROL_DATA {
        x,
        y,
        z,
        r,
        ..MANUAL_CONTROL_DATA::default()
    }
}

#[test]
fn axes_scale_as_px4() {
    let s = sticks(&msg(1000, -500, 500, 250));
    assert_eq!(
        s,
        ManualControl {
            pitch: 1.0,
            roll: -0.5,
            throttle: 0.0,
            yaw: 0.25
        }
    );
    assert_eq!(sticks(&msg(0, 0, 0, 0)).throttle, -1.0);
    assert_eq!(sticks(&msg(0, 0, 1000, 0)).throttle, 1.0);
    // out of range (INT16_MAX marks an invalid axis): left at 0
    let s = sticks(&msg(i16::MAX, -1001, -1, i16::MAX));
    assert_eq!(s, ManualControl::CENTRED);
    assert!(s.is_valid());
}
