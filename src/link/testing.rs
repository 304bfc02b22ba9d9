//! Test helpers: a link as the API link is set up, and a snapshot of a
//! vehicle on the ground at PX4's SITL home.

use std::net::SocketAddr;
use std::time::{Duration, Instant};

use nalgebra::{UnitQuaternion, Vector3};

use super::streams::{self, Identity};
use super::{Link, LinkConfig};

use crate::autopilot::{FlightMode, LandedState, MissionState, MissionStatus, Telemetry, VehicleType};
use crate::geo::GeoPoint;
use crate::lockstep::Snapshot;
use crate::mission::Plans;
use crate::signals::{GpsFix, WrenchEstimate};
use crate::sim::Truth;

/// A loopback address.
pub(crate) fn addr(port: u16) -> SocketAddr {
    SocketAddr::from(([127, 0, 0, 1], port))
}

/// Vehicle 1/1 with the API link's rates, sending to 14540 from `now`.
pub(crate) fn link(now: Instant) -> Link {
    Link::new(
        LinkConfig {
            name: "test".into(),
            identity: Identity {
                system_id: 1,
                component_id: 1,
            },
            default_remote: Some(addr(14540)),
            rates: streams::api_rates(),
            peer_timeout: Duration::from_secs(10),
        },
        now,
    )
}

/// A disarmed quad in Hold on the ground at home, 12.5 s after boot, with an
/// injected wrench and its estimate.
pub(crate) fn snapshot() -> Snapshot {
    let home = GeoPoint::PX4_SITL_HOME;
    Snapshot {
        telemetry: Telemetry {
            time_s: 12.5,
            vehicle_type: VehicleType::Quadrotor,
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
            gps_fix: GpsFix::Fix3d,
            gps_satellites: 12,
            battery_voltage_v: 16.2,
            battery_current_a: 0.5,
            battery_consumed_mah: 12.0,
            battery_remaining: 0.97,
            battery_warning: crate::autopilot::BatteryWarning::None,
            throttle: 0.0,
            estimate: WrenchEstimate {
                force_ned: Vector3::new(0.5, 0.5, 0.0),
                torque_rpy: Vector3::zeros(),
                torque_frd: Vector3::new(0.0, 0.0, 0.2),
                mass_kg: 1.8,
            },
            prearm_ok: true,
            mission: MissionStatus {
                seq: 0,
                total: 0,
                state: MissionState::NoMission,
                mission_id: 0,
                fence_id: 0,
                rally_id: 0,
            },
            failed_rotors: 0,
            degraded_rotors: 0,
        },
        truth: Truth {
            force_ned: Vector3::new(0.5, 0.5, 0.0),
            torque_frd: Vector3::new(0.0, 0.0, 0.2),
            true_mass_kg: 1.8,
        },
        plans: Plans::default(),
    }
}
