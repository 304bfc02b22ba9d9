//! The parameters the flight stack uses, read once per
//! [`super::Autopilot::apply_params`] into plain typed fields (SI units). The
//! `SIM_*` parameters are the world's and are not read here. A leaf of the
//! flight stack: the failsafe actions each failsafe parameter names
//! ([`FailsafeAction`]) live here, so the failsafes, the navigator and the
//! commander all read them from one place.

use super::battery::{BatteryThresholds, BatteryWarning};
use super::error::AutopilotError;
use super::geofence::DistanceLimits;
use crate::control::ControllerKind;
use crate::estimation::Polynomial;
use crate::params::{Param, ParamStore};

/// What a failsafe does (PX4's `FailsafeBase::Action`, the ones a multirotor
/// uses): every failsafe parameter (`NAV_DLL_ACT`, `NAV_RCL_ACT`,
/// `COM_OBL_RC_ACT`, `COM_LOW_BAT_ACT`, `GF_ACTION`, `COM_ACT_FAIL_ACT`) maps
/// to one, and [`super::Autopilot::failsafe_action`] carries it out.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum FailsafeAction {
    /// Nothing (not even a message).
    None,
    /// A warning only.
    Warn,
    /// Hold (AUTO.LOITER) where it is.
    Hold,
    /// Return to launch (AUTO.RTL).
    Return,
    /// Land where it is (AUTO.LAND).
    Land,
    /// Flight termination: the rotors stop (a multirotor falls).
    Terminate,
    /// Disarm (PX4's lockdown): the rotors stop.
    Disarm,
    /// Descend without a position (what Hold, Return and Land become while
    /// the GNSS fix is lost; no parameter names it).
    Descend,
}

impl FailsafeAction {
    /// `NAV_DLL_ACT` and `NAV_RCL_ACT`: 0 disabled, 1 Hold, 2 Return, 3 Land,
    /// 5 Terminate, 6 Disarm (4: none, as PX4's default branch).
    pub(super) fn from_nav_dll_act(v: i64) -> Self {
        match v {
            1 => Self::Hold,
            2 => Self::Return,
            3 => Self::Land,
            5 => Self::Terminate,
            6 => Self::Disarm,
            _ => Self::None,
        }
    }

    /// `COM_OBL_RC_ACT`: 3 Return, 4 Land, 6 Terminate, 7 Disarm; 5 Hold, and
    /// 0-2 (Position, Altitude, Manual: they need RC, which is absent here) Hold.
    pub(super) fn from_com_obl_rc_act(v: i64) -> Self {
        match v {
            3 => Self::Return,
            4 => Self::Land,
            6 => Self::Terminate,
            7 => Self::Disarm,
            _ => Self::Hold,
        }
    }

    /// `COM_ACT_FAIL_ACT`: 0 warn only (the mode is kept: a mission goes
    /// on), 1 Hold, 2 Land, 3 Return, 4 Terminate (PX4's failsafe maps 4 to
    /// flight termination, though its metadata bounds the parameter at 3).
    fn from_com_act_fail_act(v: i64) -> Self {
        match v {
            1 => Self::Hold,
            2 => Self::Land,
            3 => Self::Return,
            4 => Self::Terminate,
            _ => Self::Warn,
        }
    }

    /// `GF_ACTION`: 0 none, 1 warning, 2 Hold, 3 Return, 4 Terminate, 5 Land.
    fn from_gf_action(v: i64) -> Self {
        match v {
            0 => Self::None,
            2 => Self::Hold,
            3 => Self::Return,
            4 => Self::Terminate,
            5 => Self::Land,
            _ => Self::Warn,
        }
    }

    /// The mode or reaction as the STATUSTEXT names it.
    pub(super) const fn name(self) -> &'static str {
        match self {
            Self::None | Self::Warn => "warning",
            Self::Hold => "Hold",
            Self::Return => "Return",
            Self::Land => "Land",
            Self::Terminate => "flight termination",
            Self::Disarm => "Disarm",
            Self::Descend => "Descend",
        }
    }
}

/// `COM_LOW_BAT_ACT` (PX4's `LowBatteryAction`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum LowBatteryAction {
    /// 0: warnings only.
    Warning,
    /// 1 (PX4's legacy value): Return at critical and emergency.
    Return,
    /// 2: Land at critical and emergency.
    Land,
    /// 3: Return at critical, Land at emergency.
    ReturnOrLand,
}

impl LowBatteryAction {
    fn from_param(v: i64) -> Self {
        match v {
            1 => Self::Return,
            2 => Self::Land,
            3 => Self::ReturnOrLand,
            _ => Self::Warning,
        }
    }

    /// PX4's `fromBatteryWarningActParam`: the action at warning level `w`.
    pub(super) fn action(self, w: BatteryWarning) -> FailsafeAction {
        match (w, self) {
            (BatteryWarning::None, _) => FailsafeAction::None,
            (BatteryWarning::Low, _) | (_, Self::Warning) => FailsafeAction::Warn,
            (BatteryWarning::Critical, Self::Return | Self::ReturnOrLand)
            | (BatteryWarning::Emergency, Self::Return) => FailsafeAction::Return,
            (BatteryWarning::Critical | BatteryWarning::Emergency, _) => FailsafeAction::Land,
        }
    }
}

/// The failsafe parameters as typed values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct FailsafeSettings {
    /// `COM_DL_LOSS_T` [s].
    pub(super) data_link_loss_s: f64,
    /// `NAV_DLL_ACT`.
    pub(super) data_link_loss_action: FailsafeAction,
    /// `BAT_LOW_THR`, `BAT_CRIT_THR`, `BAT_EMERGEN_THR`.
    pub(super) battery: BatteryThresholds,
    /// `COM_LOW_BAT_ACT`.
    pub(super) low_battery_action: LowBatteryAction,
    /// `GF_ACTION`.
    pub(super) geofence_action: FailsafeAction,
    /// `GF_MAX_HOR_DIST`, `GF_MAX_VER_DIST`.
    pub(super) geofence_limits: DistanceLimits,
    /// `COM_FAIL_ACT_T` [s]: how long a delayed failsafe holds first (0: not delayed).
    pub(super) action_delay_s: f64,
    /// `COM_POS_FS_EPH` [m] (negative: no limit).
    pub(super) position_eph_max_m: f64,
    /// `COM_VEL_FS_EVH` [m/s].
    pub(super) velocity_evh_max_m_s: f64,
}

impl FailsafeSettings {
    /// Read from the store (its ranges already hold each value in PX4's range).
    pub(super) fn from_store(p: &ParamStore) -> Self {
        Self {
            data_link_loss_s: f64::from(p.int(Param::COM_DL_LOSS_T)),
            data_link_loss_action: FailsafeAction::from_nav_dll_act(i64::from(p.int(Param::NAV_DLL_ACT))),
            battery: BatteryThresholds {
                low: p.real(Param::BAT_LOW_THR),
                critical: p.real(Param::BAT_CRIT_THR),
                emergency: p.real(Param::BAT_EMERGEN_THR),
            },
            low_battery_action: LowBatteryAction::from_param(i64::from(p.int(Param::COM_LOW_BAT_ACT))),
            geofence_action: FailsafeAction::from_gf_action(i64::from(p.int(Param::GF_ACTION))),
            geofence_limits: DistanceLimits {
                max_horizontal_m: p.real(Param::GF_MAX_HOR_DIST),
                max_vertical_m: p.real(Param::GF_MAX_VER_DIST),
            },
            // PX4 delays only above 0.1 s (`FailsafeBase::checkFailsafe`)
            action_delay_s: Some(p.real(Param::COM_FAIL_ACT_T)).filter(|t| *t > 0.1).unwrap_or(0.0),
            position_eph_max_m: p.real(Param::COM_POS_FS_EPH),
            velocity_evh_max_m_s: p.real(Param::COM_VEL_FS_EVH),
        }
    }

    /// An altitude above home [m] capped so that it stays inside
    /// `GF_MAX_VER_DIST` (PX4 caps the return altitude the same way).
    pub(super) fn cap_height(&self, height_m: f64) -> f64 {
        let max = self.geofence_limits.max_vertical_m;
        if max > 0.0 { height_m.min(max) } else { height_m }
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

/// The follow-target parameters (`FLW_TGT_*`), SI units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct FollowSettings {
    /// `FLW_TGT_HT` [m].
    pub(super) height_m: f64,
    /// `FLW_TGT_DST` [m].
    pub(super) distance_m: f64,
    /// `FLW_TGT_FA` [rad], clockwise from the target's course.
    pub(super) angle_rad: f64,
    /// `FLW_TGT_ALT_M` = 2: track the target's altitude (else a height above home).
    pub(super) track_altitude: bool,
    /// `FLW_TGT_MAX_VEL` [m/s].
    pub(super) max_tangential_m_s: f64,
}

impl FollowSettings {
    fn from_store(p: &ParamStore) -> Self {
        Self {
            height_m: p.real(Param::FLW_TGT_HT),
            distance_m: p.real(Param::FLW_TGT_DST),
            angle_rad: p.real(Param::FLW_TGT_FA).to_radians(),
            track_altitude: p.int(Param::FLW_TGT_ALT_M) == 2,
            max_tangential_m_s: p.real(Param::FLW_TGT_MAX_VEL),
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
    /// `MPC_Z_VEL_MAX_UP` [m/s]: the manual modes, offboard, orbit and follow.
    pub(super) climb_m_s: f64,
    /// `MPC_Z_VEL_MAX_DN` [m/s]: as `climb_m_s`, and a landing above `MPC_LAND_ALT1` ([`Self::land_descent_m_s`]).
    pub(super) descent_m_s: f64,
    /// `MPC_Z_V_AUTO_UP` [m/s], at most `MPC_Z_VEL_MAX_UP`: the automatic modes.
    pub(super) auto_climb_m_s: f64,
    /// `MPC_Z_V_AUTO_DN` [m/s], at most `MPC_Z_VEL_MAX_DN`: the automatic modes (not landing).
    pub(super) auto_descent_m_s: f64,
    /// `MPC_TKO_SPEED` [m/s], at most `MPC_Z_VEL_MAX_UP` ([`Self::takeoff_climb_m_s`]).
    pub(super) takeoff_speed_m_s: f64,
    /// `MPC_LAND_SPEED` [m/s], at most `MPC_Z_VEL_MAX_DN`.
    pub(super) land_speed_m_s: f64,
    /// `MPC_LAND_ALT1` [m] above home, at least `MPC_LAND_ALT2`.
    pub(super) land_alt1_m: f64,
    /// `MPC_LAND_ALT2` [m] above home.
    pub(super) land_alt2_m: f64,
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
    pub(super) failsafe: FailsafeSettings,
    /// `COM_ACT_FAIL_ACT`.
    pub(super) actuator_failure_action: FailsafeAction,
    /// Manual control and its loss.
    pub(super) manual: ManualSettings,
    /// Follow target.
    pub(super) follow: FollowSettings,
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
        let actuator_failure_action = FailsafeAction::from_com_act_fail_act(i64::from(p.int(Param::COM_ACT_FAIL_ACT)));
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
            auto_climb_m_s: p.real(Param::MPC_Z_V_AUTO_UP),
            auto_descent_m_s: p.real(Param::MPC_Z_V_AUTO_DN),
            takeoff_speed_m_s: p.real(Param::MPC_TKO_SPEED),
            land_speed_m_s: p.real(Param::MPC_LAND_SPEED),
            land_alt1_m: p.real(Param::MPC_LAND_ALT1),
            land_alt2_m: p.real(Param::MPC_LAND_ALT2),
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
            failsafe: FailsafeSettings::from_store(p),
            actuator_failure_action,
            manual: ManualSettings::from_store(p),
            follow: FollowSettings::from_store(p),
        };
        // the automatic modes' speeds stay within the largest ones, as PX4's
        // MulticopterPositionControl::parameters_update constrains them
        s.auto_climb_m_s = s.auto_climb_m_s.min(s.climb_m_s);
        s.auto_descent_m_s = s.auto_descent_m_s.min(s.descent_m_s);
        s.takeoff_speed_m_s = s.takeoff_speed_m_s.min(s.climb_m_s);
        s.land_speed_m_s = s.land_speed_m_s.min(s.descent_m_s);
        // the first step of a slow landing is no lower than the second (PX4's
        // FlightTaskAuto::updateParams)
        s.land_alt1_m = s.land_alt1_m.max(s.land_alt2_m);
        // the return altitude stays inside GF_MAX_VER_DIST (PX4's RTL)
        s.rtl_return_alt_m = s.failsafe.cap_height(s.rtl_return_alt_m);
        let positive = [
            ("MPC_XY_CRUISE", s.cruise_m_s),
            ("MPC_XY_VEL_MAX", s.xy_vel_max_m_s),
            ("MPC_Z_VEL_MAX_UP", s.climb_m_s),
            ("MPC_Z_VEL_MAX_DN", s.descent_m_s),
            ("MPC_Z_V_AUTO_UP", s.auto_climb_m_s),
            ("MPC_Z_V_AUTO_DN", s.auto_descent_m_s),
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

    /// The descent speed limit of a landing [m/s] at `height_m` [m] above
    /// home, PX4's (FlightTaskAuto::_prepareLandSetpoints, `math::gradual`):
    /// ```text
    /// v_down(h) = MPC_LAND_SPEED                                   if h <= ALT2
    ///             MPC_LAND_SPEED + (h - ALT2) / (ALT1 - ALT2)
    ///                              (MPC_Z_VEL_MAX_DN - MPC_LAND_SPEED)  if ALT2 < h < ALT1
    ///             MPC_Z_VEL_MAX_DN                                 if h >= ALT1
    /// ```
    /// (`ALT1`, `ALT2` being `MPC_LAND_ALT1`, `MPC_LAND_ALT2`). With PX4's
    /// defaults: 1.5 m/s above 10 m, 0.7 m/s below 5 m, linear between.
    pub(super) fn land_descent_m_s(&self, height_m: f64) -> f64 {
        let (lo, hi) = (self.land_alt2_m, self.land_alt1_m);
        if height_m <= lo {
            self.land_speed_m_s
        } else if height_m >= hi {
            self.descent_m_s
        } else {
            self.land_speed_m_s + (height_m - lo) / (hi - lo) * (self.descent_m_s - self.land_speed_m_s)
        }
    }

    /// The climb speed limit of a takeoff [m/s] at `height_m` [m] above home,
    /// PX4's (FlightTaskAuto::_updateTrajConstraints for a takeoff setpoint,
    /// the height its `_dist_to_ground`):
    /// ```text
    /// v_up(h) = MPC_TKO_SPEED    if h < MPC_LAND_ALT1
    ///           MPC_Z_V_AUTO_UP  otherwise
    /// ```
    /// both at most `MPC_Z_VEL_MAX_UP`. With PX4's defaults: 1.5 m/s up to
    /// 10 m, 3 m/s above.
    pub(super) fn takeoff_climb_m_s(&self, height_m: f64) -> f64 {
        if height_m < self.land_alt1_m {
            self.takeoff_speed_m_s
        } else {
            self.auto_climb_m_s
        }
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

    #[test]
    fn takeoff_climbs_at_mpc_tko_speed_below_mpc_land_alt1_and_auto_speeds_stay_within_the_largest() {
        let mut p = ParamStore::new(&Airframe::load("quad").unwrap());
        let s = Settings::from_store(&p).unwrap();
        assert_eq!((s.auto_climb_m_s, s.auto_descent_m_s), (3.0, 1.5));
        assert_eq!(s.takeoff_climb_m_s(0.0), 1.5);
        assert_eq!(s.takeoff_climb_m_s(9.99), 1.5);
        assert_eq!(s.takeoff_climb_m_s(10.0), 3.0);
        assert_eq!(s.takeoff_climb_m_s(100.0), 3.0);
        for (name, x) in [
            ("MPC_Z_VEL_MAX_UP", 2.0),
            ("MPC_Z_V_AUTO_UP", 5.0),
            ("MPC_TKO_SPEED", 2.5),
            ("MPC_Z_VEL_MAX_DN", 1.0),
            ("MPC_Z_V_AUTO_DN", 3.0),
            ("MPC_LAND_SPEED", 1.2),
        ] {
            p.set(name, crate::params::ParamValue::Real32(x)).unwrap();
        }
        let s = Settings::from_store(&p).unwrap();
        assert_eq!((s.auto_climb_m_s, s.auto_descent_m_s), (2.0, 1.0));
        assert_eq!((s.takeoff_speed_m_s, s.land_speed_m_s), (2.0, 1.0));
    }
}
