//! MANUAL_CONTROL (QGroundControl's virtual joystick, a script's sticks) to
//! the autopilot's [`ManualControl`], read as PX4's `mavlink_receiver` does:
//! `x` is pitch, `y` roll, `r` yaw, each `[-1000, 1000]` to `[-1, 1]`; `z`
//! is throttle `[0, 1000]` to `[-1, 1]` (`z / 500 - 1`, 500 centred). An
//! axis outside its range (INT16_MAX: "invalid") is left at 0, as PX4
//! leaves it.

use mavlink::dialects::common::MANUAL_CONTROL_DATA;

use crate::autopilot::ManualControl;

/// One axis in `[-1000, 1000]` to `[-1, 1]`, 0 when out of range.
fn axis(v: i16) -> f64 {
    if (-1000..=1000).contains(&v) {
        f64::from(v) / 1000.0
    } else {
        0.0
    }
}

/// The sticks a MANUAL_CONTROL carries.
#[must_use]
pub fn sticks(m: &MANUAL_CONTROL_DATA) -> ManualControl {
    ManualControl {
        pitch: axis(m.x),
        roll: axis(m.y),
        throttle: if (0..=1000).contains(&m.z) {
            f64::from(m.z) / 500.0 - 1.0
        } else {
            0.0
        },
        yaw: axis(m.r),
    }
}

#[cfg(test)]
mod tests;
