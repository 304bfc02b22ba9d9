//! The fixtures every test of the link shares: a link as the API link is set
//! up, a snapshot of a vehicle on the ground at PX4's SITL home, and a small
//! parameter table.

use std::net::SocketAddr;
use std::time::{Duration, Instant};

use nalgebra::{UnitQuaternion, Vector3};

use super::param::ParamAccess;
use super::streams::{self, Identity};
use super::wire::CommandLong;
use super::{Link, LinkConfig};

use crate::autopilot::{
    FlightMode, ImuVibration, InnovationRatios, LandedState, MissionState, MissionStatus, NavVariances,
    NavigationReport, RotorOutputs, SolutionStatus, Telemetry, VehicleType,
};
use crate::geo::GeoPoint;
use crate::lockstep::Snapshot;
use crate::mission::Plans;
use crate::params::ParamValue;
use crate::signals::{AxesSample, BaroSample, GnssSample, GpsFix, RawSensorReadings, WrenchEstimate};

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

/// COMMAND_LONG arm (MAV_CMD_COMPONENT_ARM_DISARM, 400) for vehicle 1/1.
pub(crate) fn arm() -> CommandLong {
    CommandLong {
        params: [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        command: 400,
        target_system: 1,
        target_component: 1,
        confirmation: 0,
    }
}

/// A disarmed quad in Hold on the ground at home, 12.5 s after boot, with an
/// injected wrench and its estimate.
pub(crate) fn snapshot() -> Snapshot {
    let home = GeoPoint::PX4_SITL_HOME;
    let mut snapshot = Snapshot {
        telemetry: Telemetry {
            time_s: 12.5,
            vehicle_type: VehicleType::Quadrotor,
            armed: false,
            mode: FlightMode::Hold,
            failsafe: false,
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
            wind: None,
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
            orbit: None,
            // a filter's healthy solution at rest, with its covariance
            navigation: NavigationReport {
                solution: SolutionStatus::good(true),
                ratios: InnovationRatios {
                    vel: Some(0.1),
                    pos_horiz: Some(0.2),
                    pos_vert: Some(0.3),
                    mag: Some(0.4),
                },
                pos_horiz_accuracy_m: 0.5,
                pos_vert_accuracy_m: 0.7,
                variances: Some(NavVariances {
                    position_ned_m2: Vector3::new(0.125, 0.125, 0.49),
                    velocity_ned_m2_s2: Vector3::new(0.01, 0.01, 0.02),
                    attitude_frd_rad2: Vector3::new(1e-4, 1e-4, 4e-4),
                }),
                reset_count: 1,
            },
            vibration: Some(ImuVibration {
                time_s: 12.496,
                accel_m_s2: 0.05,
                gyro_rad_s: 0.004,
                coning_rad2_s2: 1e-6,
            }),
            // a quadrotor at rest, disarmed: its rotors stopped
            rotor_outputs: RotorOutputs {
                count: 4,
                ..RotorOutputs::default()
            },
        },
        truth: Default::default(),
        ground_truth: Default::default(),
        plans: Plans::default(),
        raw: resting_raw(&home, 12.5),
    };
    // the injected wrench the estimate above has found (the world's truth
    // reaches a link only inside a snapshot)
    snapshot.truth.force_ned = Vector3::new(0.5, 0.5, 0.0);
    snapshot.truth.torque_frd = Vector3::new(0.0, 0.0, 0.2);
    snapshot.truth.true_mass_kg = 1.8;
    snapshot
}

/// Noise-free raw samples of a level vehicle at rest at `home` at `t` [s]
/// (the link sees the world only in a snapshot).
pub(crate) fn resting_raw(home: &GeoPoint, t: f64) -> RawSensorReadings {
    RawSensorReadings {
        accel: Some(AxesSample {
            time_s: t,
            frd: Vector3::new(0.0, 0.0, -9.81),
        }),
        gyro: Some(AxesSample {
            time_s: t,
            frd: Vector3::zeros(),
        }),
        mag: Some(AxesSample {
            time_s: t,
            frd: Vector3::new(0.2, -0.05, 0.44),
        }),
        baro: Some(BaroSample {
            time_s: t,
            pressure_pa: 95_460.0,
            temperature_c: 11.7,
        }),
        gnss: Some(GnssSample {
            time_s: t - 0.125,
            delivered_s: t,
            lat_deg: home.lat_deg,
            lon_deg: home.lon_deg,
            alt_amsl_m: home.alt_amsl_m,
            velocity_ned: Vector3::zeros(),
            eph_m: 0.9,
            epv_m: 1.78,
            speed_accuracy_m_s: 0.4,
            hdop: 0.7,
            vdop: 1.1,
            fix: GpsFix::Fix3d,
            satellites: 12,
        }),
    }
}

/// A small parameter table: name, value, min, max per entry.
#[derive(Debug, Clone)]
pub(crate) struct FakeParams(pub(crate) Vec<(&'static str, ParamValue, f64, f64)>);

impl FakeParams {
    pub(crate) fn standard() -> Self {
        Self(vec![
            ("COM_OF_LOSS_T", ParamValue::Real32(1.0), 0.0, 60.0),
            ("CTRL_TYPE", ParamValue::Int32(0), 0.0, 2.0),
            ("MIS_TAKEOFF_ALT", ParamValue::Real32(2.5), 0.0, 100.0),
            ("SYS_FAILURE_EN", ParamValue::Int32(0), 0.0, 1.0),
            ("SIXTEEN_CHARS_XX", ParamValue::Real32(0.0), -1.0, 1.0),
        ])
    }
}

impl ParamAccess for FakeParams {
    fn count(&self) -> usize {
        self.0.len()
    }
    fn by_index(&self, index: usize) -> Option<(&str, ParamValue)> {
        self.0.get(index).map(|(n, v, _, _)| (*n, *v))
    }
    fn by_name(&self, name: &str) -> Option<(usize, ParamValue)> {
        self.0.iter().position(|p| p.0 == name).map(|i| (i, self.0[i].1))
    }
    fn set(&mut self, name: &str, value: ParamValue) -> Result<ParamValue, String> {
        let p = self.0.iter_mut().find(|p| p.0 == name).ok_or("unknown")?;
        let x = match value {
            ParamValue::Int32(i) => f64::from(i),
            ParamValue::Real32(f) => f64::from(f),
        };
        if !x.is_finite() || x < p.2 || x > p.3 {
            return Err(format!("{name} = {x} outside [{}, {}]", p.2, p.3));
        }
        p.1 = value;
        Ok(value)
    }
    /// The fixture keeps no defaults beside its values.
    fn default_of(&self, _index: usize) -> Option<ParamValue> {
        None
    }
}

/// A file's bytes as a store's [`super::ftp::FileStore::open`] hands them
/// out; `fail_from`: reads at or past this offset fail (a disk error).
#[derive(Debug, Default)]
pub(crate) struct MemFile {
    pub(crate) bytes: Vec<u8>,
    pub(crate) fail_from: Option<u64>,
}

impl super::ftp::ReadFile for MemFile {
    fn size(&self) -> Result<u64, super::ftp::FsError> {
        Ok(self.bytes.len() as u64)
    }
    fn read_at(&self, offset: u64, buf: &mut [u8]) -> Result<usize, super::ftp::FsError> {
        if self.fail_from.is_some_and(|f| offset >= f) {
            return Err(super::ftp::FsError::Errno(super::ftp::errno::EIO));
        }
        let s = usize::try_from(offset).unwrap_or(usize::MAX).min(self.bytes.len());
        let n = buf.len().min(self.bytes.len() - s);
        buf[..n].copy_from_slice(&self.bytes[s..s + n]);
        Ok(n)
    }
}
