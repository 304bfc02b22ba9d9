//! Test helpers: a telemetry snapshot of a vehicle on the ground at PX4's
//! SITL home.

use nalgebra::{UnitQuaternion, Vector3};

use crate::autopilot::{FlightMode, LandedState, Telemetry};
use crate::geo::GeoPoint;
use crate::signals::WrenchEstimate;

/// A disarmed vehicle in Hold on the ground at home, 12.5 s after boot.
pub(crate) fn telemetry() -> Telemetry {
    let home = GeoPoint::PX4_SITL_HOME;
    Telemetry {
        time_s: 12.5,
        armed: false,
        mode: FlightMode::Hold,
        landed: LandedState::OnGround,
        position_ned: Vector3::zeros(),
        velocity_ned: Vector3::zeros(),
        acceleration_ned: Vector3::zeros(),
        attitude: UnitQuaternion::identity(),
        rate_frd: Vector3::zeros(),
        global: home,
        origin: home,
        home,
        home_ned: Vector3::zeros(),
        battery_voltage_v: 16.2,
        battery_current_a: 0.5,
        battery_consumed_mah: 12.0,
        battery_remaining: 0.97,
        throttle: 0.0,
        estimate: WrenchEstimate {
            force_ned: Vector3::new(0.5, 0.5, 0.0),
            torque_rpy: Vector3::zeros(),
            torque_frd: Vector3::new(0.0, 0.0, 0.2),
            mass_kg: 1.8,
        },
        injected_force_ned: Vector3::new(0.5, 0.5, 0.0),
        injected_torque_frd: Vector3::new(0.0, 0.0, 0.2),
        true_mass_kg: 1.8,
        prearm_ok: true,
    }
}
