//! The parameters the flight stack uses, read once per
//! [`super::Autopilot::apply_params`] into plain typed fields (SI units). The
//! `SIM_*` parameters are the world's and are not read here.

use super::AutopilotError;
use crate::control::ControllerKind;
use crate::estimation::Polynomial;
use crate::params::{Param, ParamStore};

use super::failsafe::FailsafeAction;

/// What to do when the rotor monitor flags a failed or degraded rotor in
/// flight (`COM_ACT_FAIL_ACT`, PX4's values; PX4's 4, terminate, is outside its range).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum ActuatorFailureAction {
    /// 0: warn only, keep the mode (a mission goes on).
    Warn,
    /// 1: Hold.
    Hold,
    /// 2: Land.
    Land,
    /// 3: Return.
    Return,
}

impl ActuatorFailureAction {
    /// The one failsafe runner's action (`Warn` keeps the mode), for
    /// `rotors_changed` to route through [`super::Autopilot::failsafe_action`].
    #[must_use]
    pub(super) fn action(self) -> FailsafeAction {
        match self {
            Self::Warn => FailsafeAction::Warn,
            Self::Hold => FailsafeAction::Hold,
            Self::Land => FailsafeAction::Land,
            Self::Return => FailsafeAction::Return,
        }
    }
}

/// The manual-control parameters (sticks, RC loss), SI units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct ManualSettings {
    /// `COM_RC_LOSS_T` [s].
    pub(super) loss_s: f64,
    /// `NAV_RCL_ACT` (PX4's values, as `NAV_DLL_ACT`).
    pub(super) loss_action: FailsafeAction,
    /// `MPC_VEL_MANUAL` [m/s].
    pub(super) vel_max_m_s: f64,
    /// `MPC_MAN_Y_MAX` [rad/s].
    pub(super) yaw_rate_max_rad_s: f64,
    /// `MPC_HOLD_DZ` (stick units).
    pub(super) deadzone: f64,
    /// `MPC_MAN_TILT_MAX` [rad].
    pub(super) tilt_max_rad: f64,
    /// `MPC_MANTHR_MIN` (0..1 of the maximum thrust).
    pub(super) thrust_min: f64,
    /// `MC_ACRO_R_MAX`, `MC_ACRO_P_MAX`, `MC_ACRO_Y_MAX` [rad/s], body FRD.
    pub(super) acro_rate_max_rad_s: [f64; 3],
    /// `MC_ACRO_EXPO`, `MC_ACRO_EXPO_Y`.
    pub(super) acro_expo: [f64; 2],
    /// `MC_ACRO_SUPEXPO`, `MC_ACRO_SUPEXPOY`.
    pub(super) acro_superexpo: [f64; 2],
}

impl ManualSettings {
    fn from_store(p: &ParamStore) -> Self {
        let rad = |x: Param| p.real(x).to_radians();
        Self {
            loss_s: p.real(Param::COM_RC_LOSS_T),
            loss_action: FailsafeAction::from_nav_dll_act(i64::from(p.int(Param::NAV_RCL_ACT))),
            vel_max_m_s: p.real(Param::MPC_VEL_MANUAL),
            yaw_rate_max_rad_s: rad(Param::MPC_MAN_Y_MAX),
            deadzone: p.real(Param::MPC_HOLD_DZ),
            tilt_max_rad: rad(Param::MPC_MAN_TILT_MAX),
            thrust_min: p.real(Param::MPC_MANTHR_MIN),
            acro_rate_max_rad_s: [
                rad(Param::MC_ACRO_R_MAX),
                rad(Param::MC_ACRO_P_MAX),
                rad(Param::MC_ACRO_Y_MAX),
            ],
            acro_expo: [p.real(Param::MC_ACRO_EXPO), p.real(Param::MC_ACRO_EXPO_Y)],
            acro_superexpo: [p.real(Param::MC_ACRO_SUPEXPO), p.real(Param::MC_ACRO_SUPEXPOY)],
        }
    }
}

/// The flight stack's view of the parameter store.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Settings {
    pub(super) takeoff_alt_m: f64,
    /// The highest target altitude a command may ask for, AMSL [m] (`RP_ALT_MAX_AMSL`).
    pub(super) max_target_amsl_m: f64,
    pub(super) rtl_return_alt_m: f64,
    pub(super) rtl_descend_alt_m: f64,
    pub(super) acceptance_radius_m: f64,
    pub(super) mc_alt_radius_m: f64,
    pub(super) cruise_m_s: f64,
    pub(super) xy_vel_max_m_s: f64,
    pub(super) climb_m_s: f64,
    pub(super) descent_m_s: f64,
    pub(super) takeoff_speed_m_s: f64,
    pub(super) land_speed_m_s: f64,
    pub(super) land_alt1_m: f64,
    pub(super) offboard_loss_s: f64,
    pub(super) offboard_loss_action: FailsafeAction,
    pub(super) disarm_land_s: f64,
    pub(super) disarm_preflight_s: f64,
    pub(super) failure_injection: bool,
    pub(super) battery_cells: f64,
    pub(super) controller: ControllerKind,
    pub(super) position_scale: f64,
    pub(super) attitude_scale: f64,
    pub(super) estimator_order: usize,
    pub(super) estimator_polynomial: Polynomial,
    pub(super) estimator_cutoff_rad_s: f64,
    pub(super) feedback: bool,
    pub(super) model_mass_kg: f64,
    /// Data-link, battery and geofence failsafes.
    pub(super) failsafe: super::failsafe::FailsafeSettings,
    pub(super) actuator_failure_action: ActuatorFailureAction,
    /// Manual control and its loss.
    pub(super) manual: ManualSettings,
}

impl Settings {
    /// Read every parameter the flight stack uses.
    ///
    /// # Errors
    /// A value the flight stack cannot use (the store's ranges already exclude most).
    pub(super) fn from_store(p: &ParamStore) -> Result<Self, AutopilotError> {
        let controller =
            ControllerKind::try_from(p.int(Param::CTRL_TYPE)).map_err(|e| AutopilotError::Param(e.to_string()))?;
        let estimator_polynomial = match p.int(Param::EST_POLY) {
            0 => Polynomial::Butterworth,
            1 => Polynomial::Binomial,
            x => return Err(AutopilotError::Param(format!("EST_POLY {x} is not 0 or 1"))),
        };
        let order = p.int(Param::EST_ORDER);
        let estimator_order =
            usize::try_from(order).map_err(|_| AutopilotError::Param(format!("EST_ORDER {order} is negative")))?;
        let offboard_loss_action = FailsafeAction::from_com_obl_rc_act(i64::from(p.int(Param::COM_OBL_RC_ACT)));
        let actuator_failure_action = match p.int(Param::COM_ACT_FAIL_ACT) {
            1 => ActuatorFailureAction::Hold,
            2 => ActuatorFailureAction::Land,
            3 => ActuatorFailureAction::Return,
            _ => ActuatorFailureAction::Warn,
        };
        let mut s = Self {
            takeoff_alt_m: p.real(Param::MIS_TAKEOFF_ALT),
            max_target_amsl_m: p.real(Param::RP_ALT_MAX_AMSL),
            rtl_return_alt_m: p.real(Param::RTL_RETURN_ALT),
            rtl_descend_alt_m: p.real(Param::RTL_DESCEND_ALT),
            acceptance_radius_m: p.real(Param::NAV_ACC_RAD),
            mc_alt_radius_m: p.real(Param::NAV_MC_ALT_RAD),
            cruise_m_s: p.real(Param::MPC_XY_CRUISE),
            xy_vel_max_m_s: p.real(Param::MPC_XY_VEL_MAX),
            climb_m_s: p.real(Param::MPC_Z_VEL_MAX_UP),
            descent_m_s: p.real(Param::MPC_Z_VEL_MAX_DN),
            takeoff_speed_m_s: p.real(Param::MPC_TKO_SPEED),
            land_speed_m_s: p.real(Param::MPC_LAND_SPEED),
            land_alt1_m: p.real(Param::MPC_LAND_ALT1),
            offboard_loss_s: p.real(Param::COM_OF_LOSS_T),
            offboard_loss_action,
            disarm_land_s: p.real(Param::COM_DISARM_LAND),
            disarm_preflight_s: p.real(Param::COM_DISARM_PRFLT),
            failure_injection: p.int(Param::SYS_FAILURE_EN) != 0,
            battery_cells: p.real(Param::BAT1_N_CELLS),
            controller,
            position_scale: p.real(Param::CTRL_POS_SCALE),
            attitude_scale: p.real(Param::CTRL_ATT_SCALE),
            estimator_order,
            estimator_polynomial,
            estimator_cutoff_rad_s: p.real(Param::EST_CUTOFF),
            feedback: p.int(Param::EST_COMP) != 0,
            model_mass_kg: p.real(Param::MDL_MASS),
            failsafe: super::failsafe::FailsafeSettings::from_store(p),
            actuator_failure_action,
            manual: ManualSettings::from_store(p),
        };
        // the return altitude stays inside GF_MAX_VER_DIST (PX4's RTL)
        s.rtl_return_alt_m = s.failsafe.cap_height(s.rtl_return_alt_m);
        let positive = [
            ("MPC_XY_CRUISE", s.cruise_m_s),
            ("MPC_XY_VEL_MAX", s.xy_vel_max_m_s),
            ("MPC_Z_VEL_MAX_UP", s.climb_m_s),
            ("MPC_Z_VEL_MAX_DN", s.descent_m_s),
            ("MPC_TKO_SPEED", s.takeoff_speed_m_s),
            ("MPC_LAND_SPEED", s.land_speed_m_s),
            ("MDL_MASS", s.model_mass_kg),
            ("CTRL_POS_SCALE", s.position_scale),
            ("CTRL_ATT_SCALE", s.attitude_scale),
            ("EST_CUTOFF", s.estimator_cutoff_rad_s),
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
    fn defaults_read() {
        let s = Settings::from_store(&ParamStore::new(&Airframe::load("quad").unwrap())).unwrap();
        assert_eq!(s.takeoff_alt_m, 2.5);
        assert_eq!(s.controller, ControllerKind::Geometric);
        assert_eq!(s.model_mass_kg, 2.0);
        assert_eq!(s.offboard_loss_action, FailsafeAction::Hold);
        assert!(!s.feedback && !s.failure_injection);
    }
}
