//! The parameters the autopilot uses, read once per [`super::Autopilot::apply_params`]
//! into plain typed fields (SI units).

use nalgebra::Vector3;

use super::AutopilotError;
use crate::control::ControllerKind;
use crate::estimation::Polynomial;
use crate::params::{PARAMS, ParamStore};

/// Every parameter name the autopilot reads (a test checks each exists).
#[cfg(test)]
pub(super) const USED: &[&str] = &[
    "MIS_TAKEOFF_ALT",
    "RTL_RETURN_ALT",
    "RTL_DESCEND_ALT",
    "NAV_ACC_RAD",
    "MPC_XY_CRUISE",
    "MPC_XY_VEL_MAX",
    "MPC_Z_VEL_MAX_UP",
    "MPC_Z_VEL_MAX_DN",
    "MPC_TKO_SPEED",
    "MPC_LAND_SPEED",
    "MPC_LAND_ALT1",
    "COM_OF_LOSS_T",
    "COM_OBL_RC_ACT",
    "COM_DISARM_LAND",
    "COM_DISARM_PRFLT",
    "BAT1_N_CELLS",
    "BAT1_CAPACITY",
    "SIM_BAT_MIN_PCT",
    "CTRL_TYPE",
    "CTRL_POS_SCALE",
    "CTRL_ATT_SCALE",
    "EST_ORDER",
    "EST_POLY",
    "EST_CUTOFF",
    "EST_COMP",
    "SIM_FEXT_X",
    "SIM_FEXT_Y",
    "SIM_FEXT_Z",
    "SIM_TEXT_X",
    "SIM_TEXT_Y",
    "SIM_TEXT_Z",
    "SIM_MASS",
    "MDL_MASS",
    "SIM_GE_EN",
    "SIM_CE_EN",
    "SIM_CEIL_Z",
];

/// What to do when the offboard setpoints stop (`COM_OBL_RC_ACT`, without RC).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum OffboardLossAction {
    /// 0, 1, 2, 5 (and 6, 7: no termination or disarm in the air here).
    Hold,
    /// 3.
    Return,
    /// 4.
    Land,
}

/// The autopilot's view of the parameter store.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Settings {
    pub(super) takeoff_alt_m: f64,
    pub(super) rtl_return_alt_m: f64,
    pub(super) rtl_descend_alt_m: f64,
    pub(super) acceptance_radius_m: f64,
    pub(super) cruise_m_s: f64,
    pub(super) xy_vel_max_m_s: f64,
    pub(super) climb_m_s: f64,
    pub(super) descent_m_s: f64,
    pub(super) takeoff_speed_m_s: f64,
    pub(super) land_speed_m_s: f64,
    pub(super) land_alt1_m: f64,
    pub(super) offboard_loss_s: f64,
    pub(super) offboard_loss_action: OffboardLossAction,
    pub(super) disarm_land_s: f64,
    pub(super) disarm_preflight_s: f64,
    pub(super) battery_cells: f64,
    pub(super) battery_capacity_mah: f64,
    pub(super) battery_min_fraction: f64,
    pub(super) controller: ControllerKind,
    pub(super) position_scale: f64,
    pub(super) attitude_scale: f64,
    pub(super) estimator_order: usize,
    pub(super) estimator_polynomial: Polynomial,
    pub(super) estimator_cutoff_rad_s: f64,
    pub(super) feedback: bool,
    pub(super) force_ned: Vector3<f64>,
    pub(super) torque_frd: Vector3<f64>,
    pub(super) sim_mass_kg: f64,
    pub(super) model_mass_kg: f64,
    pub(super) ground_effect: bool,
    pub(super) ceiling_effect: bool,
    pub(super) ceiling_height_m: f64,
}

/// The value of `name`, or its declared default if the store lacks it.
fn value(store: &ParamStore, name: &str) -> f64 {
    store
        .value_f64(name)
        .or_else(|| PARAMS.iter().find(|p| p.name == name).map(|p| p.default))
        .unwrap_or(0.0)
}

impl Settings {
    /// Read every used parameter.
    ///
    /// # Errors
    /// A value the autopilot cannot use (the store's ranges already exclude most).
    pub(super) fn from_store(store: &ParamStore) -> Result<Self, AutopilotError> {
        let v = |name: &str| value(store, name);
        let int = |name: &str| v(name) as i32;
        let controller =
            ControllerKind::try_from(int("CTRL_TYPE")).map_err(|e| AutopilotError::Param(e.to_string()))?;
        let estimator_polynomial = match int("EST_POLY") {
            0 => Polynomial::Butterworth,
            1 => Polynomial::Binomial,
            p => return Err(AutopilotError::Param(format!("EST_POLY {p} is not 0 or 1"))),
        };
        let order = int("EST_ORDER");
        let estimator_order =
            usize::try_from(order).map_err(|_| AutopilotError::Param(format!("EST_ORDER {order} is negative")))?;
        let offboard_loss_action = match int("COM_OBL_RC_ACT") {
            3 => OffboardLossAction::Return,
            4 => OffboardLossAction::Land,
            _ => OffboardLossAction::Hold,
        };
        let s = Self {
            takeoff_alt_m: v("MIS_TAKEOFF_ALT"),
            rtl_return_alt_m: v("RTL_RETURN_ALT"),
            rtl_descend_alt_m: v("RTL_DESCEND_ALT"),
            acceptance_radius_m: v("NAV_ACC_RAD"),
            cruise_m_s: v("MPC_XY_CRUISE"),
            xy_vel_max_m_s: v("MPC_XY_VEL_MAX"),
            climb_m_s: v("MPC_Z_VEL_MAX_UP"),
            descent_m_s: v("MPC_Z_VEL_MAX_DN"),
            takeoff_speed_m_s: v("MPC_TKO_SPEED"),
            land_speed_m_s: v("MPC_LAND_SPEED"),
            land_alt1_m: v("MPC_LAND_ALT1"),
            offboard_loss_s: v("COM_OF_LOSS_T"),
            offboard_loss_action,
            disarm_land_s: v("COM_DISARM_LAND"),
            disarm_preflight_s: v("COM_DISARM_PRFLT"),
            battery_cells: v("BAT1_N_CELLS"),
            battery_capacity_mah: v("BAT1_CAPACITY"),
            battery_min_fraction: v("SIM_BAT_MIN_PCT") / 100.0,
            controller,
            position_scale: v("CTRL_POS_SCALE"),
            attitude_scale: v("CTRL_ATT_SCALE"),
            estimator_order,
            estimator_polynomial,
            estimator_cutoff_rad_s: v("EST_CUTOFF"),
            feedback: int("EST_COMP") != 0,
            force_ned: Vector3::new(v("SIM_FEXT_X"), v("SIM_FEXT_Y"), v("SIM_FEXT_Z")),
            torque_frd: Vector3::new(v("SIM_TEXT_X"), v("SIM_TEXT_Y"), v("SIM_TEXT_Z")),
            sim_mass_kg: v("SIM_MASS"),
            model_mass_kg: v("MDL_MASS"),
            ground_effect: int("SIM_GE_EN") != 0,
            ceiling_effect: int("SIM_CE_EN") != 0,
            ceiling_height_m: v("SIM_CEIL_Z"),
        };
        let positive = [
            ("MPC_XY_CRUISE", s.cruise_m_s),
            ("MPC_XY_VEL_MAX", s.xy_vel_max_m_s),
            ("MPC_Z_VEL_MAX_UP", s.climb_m_s),
            ("MPC_Z_VEL_MAX_DN", s.descent_m_s),
            ("MPC_TKO_SPEED", s.takeoff_speed_m_s),
            ("MPC_LAND_SPEED", s.land_speed_m_s),
            ("SIM_MASS", s.sim_mass_kg),
            ("MDL_MASS", s.model_mass_kg),
            ("CTRL_POS_SCALE", s.position_scale),
            ("CTRL_ATT_SCALE", s.attitude_scale),
            ("EST_CUTOFF", s.estimator_cutoff_rad_s),
            ("BAT1_CAPACITY", s.battery_capacity_mah),
            ("BAT1_N_CELLS", s.battery_cells),
        ];
        for (name, x) in positive {
            if !(x.is_finite() && x > 0.0) {
                return Err(AutopilotError::Param(format!("{name} = {x} must be > 0")));
            }
        }
        Ok(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::airframe::Airframe;

    #[test]
    fn every_used_name_exists_and_defaults_read() {
        for name in USED {
            assert!(PARAMS.iter().any(|p| p.name == *name), "{name}");
        }
        let s = Settings::from_store(&ParamStore::new(&Airframe::load("quad").unwrap())).unwrap();
        assert_eq!(s.takeoff_alt_m, 2.5);
        assert_eq!(s.controller, ControllerKind::Geometric);
        assert_eq!(s.model_mass_kg, 2.0);
        assert_eq!(s.offboard_loss_action, OffboardLossAction::Hold);
        assert!(!s.feedback);
    }
}
