//! What the parameters say about the simulated world: the `SIM_*` truth (an
//! injected wrench, the true mass, ground and ceiling effect, the battery's
//! floor, the wind) and the battery pack fitted (the one `BAT1_*` describes, as PX4
//! SITL's battery simulator does). The flight stack never reads these.

use nalgebra::Vector3;

use super::plant::ExternalWrench;
use super::wind::{Gust, WindSettings};
use crate::params::{Param, ParamStore};

/// One vehicle's world configuration, read from its parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WorldSettings {
    /// The injected external wrench (`SIM_FEXT_*` world NED, `SIM_TEXT_*` body FRD).
    pub external: ExternalWrench,
    /// The true mass [kg] (`SIM_MASS`).
    pub true_mass_kg: f64,
    /// Ground effect on (`SIM_GE_EN`).
    pub ground_effect: bool,
    /// Ceiling effect on (`SIM_CE_EN`).
    pub ceiling_effect: bool,
    /// Height of a flat ceiling above the ground [m], `None` for no ceiling (`SIM_CEIL_Z` = 0).
    pub ceiling_height_m: Option<f64>,
    /// Cells in series of the pack (`BAT1_N_CELLS`).
    pub battery_cells: f64,
    /// Capacity of the pack [mAh] (`BAT1_CAPACITY`).
    pub battery_capacity_mah: f64,
    /// The charge never drops below this fraction (`SIM_BAT_MIN_PCT` / 100).
    pub battery_min_fraction: f64,
    /// What injected WRONG faults do.
    pub faults: FaultSettings,
    /// The air: mean wind, turbulence and gusts (`SIM_WIND_*`, `SIM_GUST_*`).
    pub wind: WindSettings,
}

/// What an injected FAILURE_TYPE_WRONG does, per unit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FaultSettings {
    /// A WRONG motor gives this fraction of its commanded thrust, `T = f T_cmd`
    /// (`SIM_MOT_WRONG_FR`, 0..1).
    pub motor_thrust_fraction: f64,
    /// A WRONG GNSS receiver puts the vehicle this far north of where it is
    /// [m] (`SIM_GPS_WRONG_M`): `p~ = p + (d, 0, 0)` NED.
    pub gps_offset_north_m: f64,
}

impl Default for FaultSettings {
    /// The parameters' defaults: half the thrust, 10 m north.
    fn default() -> Self {
        Self {
            motor_thrust_fraction: 0.5,
            gps_offset_north_m: 10.0,
        }
    }
}

impl WorldSettings {
    /// Read every world parameter (the store's ranges make each one usable).
    #[must_use]
    pub fn from_store(p: &ParamStore) -> Self {
        let ceiling = p.real(Param::SIM_CEIL_Z);
        Self {
            external: ExternalWrench {
                force_ned: Vector3::new(
                    p.real(Param::SIM_FEXT_X),
                    p.real(Param::SIM_FEXT_Y),
                    p.real(Param::SIM_FEXT_Z),
                ),
                torque_frd: Vector3::new(
                    p.real(Param::SIM_TEXT_X),
                    p.real(Param::SIM_TEXT_Y),
                    p.real(Param::SIM_TEXT_Z),
                ),
            },
            true_mass_kg: p.real(Param::SIM_MASS),
            ground_effect: p.int(Param::SIM_GE_EN) != 0,
            ceiling_effect: p.int(Param::SIM_CE_EN) != 0,
            ceiling_height_m: (ceiling > 0.0).then_some(ceiling),
            battery_cells: p.real(Param::BAT1_N_CELLS),
            battery_capacity_mah: p.real(Param::BAT1_CAPACITY),
            battery_min_fraction: p.real(Param::SIM_BAT_MIN_PCT) / 100.0,
            faults: FaultSettings {
                motor_thrust_fraction: p.real(Param::SIM_MOT_WRONG_FR),
                gps_offset_north_m: p.real(Param::SIM_GPS_WRONG_M),
            },
            wind: WindSettings {
                speed_m_s: p.real(Param::SIM_WIND_SPD),
                from_deg: p.real(Param::SIM_WIND_DIR),
                dir_z_deg: p.real(Param::SIM_WIND_DIR_Z),
                turbulence_m_s: p.real(Param::SIM_WIND_TURB),
                gust: Gust {
                    speed_m_s: p.real(Param::SIM_GUST_SPD),
                    from_deg: p.real(Param::SIM_GUST_DIR),
                    start_s: p.real(Param::SIM_GUST_T0),
                    duration_s: p.real(Param::SIM_GUST_DUR),
                    period_s: p.real(Param::SIM_GUST_PER),
                },
            },
        }
    }
}
