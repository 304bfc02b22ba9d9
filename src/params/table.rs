//! The parameter table: every parameter once, as data, in MAVLink index order.
//! First the parameters rotorpilot implements (PX4 names first, then
//! rotorpilot's own), declared here with a [`Param`] each; then every other
//! parameter PX4 SITL's multicopter boots with, from `params/px4-multicopter.tsv`
//! (`px4.rs`), stored but without effect. `rotorpilot params` prints it
//! (`--markdown` is `docs/parameters.md`).

use std::sync::LazyLock;

use super::px4::px4_params;
use super::{Effect, ParamSpec, ParamType};

/// A REAL32 parameter.
const fn real(
    name: &'static str,
    default: f64,
    min: f64,
    max: f64,
    unit: &'static str,
    description: &'static str,
) -> ParamSpec {
    ParamSpec {
        name,
        kind: ParamType::Real32,
        default,
        min,
        max,
        unit,
        description,
        values: &[],
        reboot_required: false,
        effect: Effect::Acts,
    }
}

/// An INT32 parameter.
const fn int(name: &'static str, default: i32, min: i32, max: i32, description: &'static str) -> ParamSpec {
    ParamSpec {
        name,
        kind: ParamType::Int32,
        default: default as f64,
        min: min as f64,
        max: max as f64,
        unit: "",
        description,
        values: &[],
        reboot_required: false,
        effect: Effect::Acts,
    }
}

/// An INT32 parameter that selects one of a few meanings: `values` lists
/// each value with its meaning (PX4's `values:`; a value in the range but not
/// listed acts as the description says).
const fn choice(
    name: &'static str,
    default: i32,
    min: i32,
    max: i32,
    description: &'static str,
    values: &'static [(i32, &'static str)],
) -> ParamSpec {
    ParamSpec {
        values,
        ..int(name, default, min, max, description)
    }
}

/// An INT32 switch (PX4's `boolean`): 0 disabled, 1 enabled.
const fn switch(name: &'static str, default: i32, description: &'static str) -> ParamSpec {
    choice(name, default, 0, 1, description, &[(0, "disabled"), (1, "enabled")])
}

/// `spec`, used only from the next start (PX4's `reboot_required`).
const fn at_boot(spec: ParamSpec) -> ParamSpec {
    ParamSpec {
        reboot_required: true,
        ..spec
    }
}

/// A REAL32 parameter read at boot.
const fn boot_real(
    name: &'static str,
    default: f64,
    min: f64,
    max: f64,
    unit: &'static str,
    description: &'static str,
) -> ParamSpec {
    at_boot(real(name, default, min, max, unit, description))
}

/// An INT32 parameter read at boot.
const fn boot_int(name: &'static str, default: i32, min: i32, max: i32, description: &'static str) -> ParamSpec {
    at_boot(int(name, default, min, max, description))
}

/// A choice read at boot.
const fn boot_choice(
    name: &'static str,
    default: i32,
    min: i32,
    max: i32,
    description: &'static str,
    values: &'static [(i32, &'static str)],
) -> ParamSpec {
    at_boot(choice(name, default, min, max, description, values))
}

/// A switch read at boot.
const fn boot_switch(name: &'static str, default: i32, description: &'static str) -> ParamSpec {
    at_boot(switch(name, default, description))
}

/// Declares the table once: the [`Param`] enum (one variant per parameter,
/// named as the parameter, in index order) and [`PARAMS`], each entry built
/// by `real`, `int`, `choice` or `switch` with the name filled in from the variant.
macro_rules! parameters {
    ($( $(#[$meta:meta])* $name:ident : $ctor:ident ( $($arg:expr),* $(,)? ) ),* $(,)?) => {
        /// Every parameter, by its (PX4) name; `Param::X as usize` is its index.
        #[allow(non_camel_case_types)]
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        pub enum Param {
            $( #[doc = concat!("`", stringify!($name), "`")] $name, )*
        }

        impl Param {
            /// Every parameter in index order.
            pub const ALL: &'static [Param] = &[$(Param::$name),*];
        }

        /// The parameters rotorpilot implements, in index order (the first of [`PARAMS`]).
        static IMPLEMENTED: &[ParamSpec] = &[
            $( $(#[$meta])* $ctor(stringify!($name), $($arg),*), )*
        ];
    };
}

/// Every parameter, in MAVLink index order: the implemented ones (index =
/// `Param::X as usize`), then PX4's others in name order, each once.
pub static PARAMS: LazyLock<Vec<ParamSpec>> = LazyLock::new(|| {
    let mut all = IMPLEMENTED.to_vec();
    all.extend(
        px4_params()
            .iter()
            .filter(|p| IMPLEMENTED.iter().all(|q| q.name != p.name))
            .map(|p| p.stored_only()),
    );
    all
});

/// Index of every parameter by name.
static INDEX: LazyLock<std::collections::HashMap<&'static str, usize>> =
    LazyLock::new(|| PARAMS.iter().enumerate().map(|(i, p)| (p.name, i)).collect());

/// The index of parameter `name` (exact, case-sensitive, as PX4).
pub(super) fn index_of(name: &str) -> Option<usize> {
    INDEX.get(name).copied()
}

impl Param {
    /// Its declaration.
    #[must_use]
    pub fn spec(self) -> &'static ParamSpec {
        &PARAMS[self as usize]
    }

    /// Its name (at most 16 characters, as MAVLink carries it).
    #[must_use]
    pub fn name(self) -> &'static str {
        self.spec().name
    }
}

parameters! {
    // --- PX4: mission, return, navigation -------------------------------------------------------
    // PX4 declares no maximum (src/modules/navigator/mission_params.yaml; older PX4 had 80 m)
    MIS_TAKEOFF_ALT: real(2.5, 0.0, f32::MAX as f64, "m", "Takeoff altitude above home (a lower takeoff target is raised to it)"),
    RTL_RETURN_ALT: real(30.0, 0.0, 150.0, "m", "RTL: climb to at least this altitude above home before returning"),
    RTL_DESCEND_ALT: real(10.0, 0.0, 100.0, "m", "RTL: above home, descend to this altitude before landing"),
    NAV_ACC_RAD: real(2.0, 0.05, 200.0, "m", "Horizontal acceptance radius of a target (mission items without their own, RTL arrival over home)"),
    NAV_MC_ALT_RAD: real(0.8, 0.05, 200.0, "m", "Vertical acceptance radius of a mission item"),
    // --- PX4: multicopter position control --------------------------------------------------------
    MPC_XY_CRUISE: real(
        5.0, 0.5, 20.0, "m/s",
        "Cruise ground speed of reposition, missions and RTL",
    ),
    MPC_XY_VEL_MAX: real(
        12.0, 0.5, 20.0, "m/s",
        "Largest horizontal speed (caps cruise and reposition; the limit of offboard setpoints)",
    ),
    MPC_Z_VEL_MAX_UP: real(3.0, 0.5, 8.0, "m/s", "Largest climb speed"),
    MPC_Z_VEL_MAX_DN: real(1.5, 0.5, 4.0, "m/s", "Largest descent speed (also a landing above MPC_LAND_ALT1)"),
    MPC_Z_V_AUTO_UP: real(
        3.0, 0.5, 8.0, "m/s",
        "Climb speed in the automatic modes (at most MPC_Z_VEL_MAX_UP; a takeoff above MPC_LAND_ALT1)",
    ),
    MPC_Z_V_AUTO_DN: real(
        1.5, 0.5, 4.0, "m/s",
        "Descent speed in the automatic modes, landing aside (at most MPC_Z_VEL_MAX_DN)",
    ),
    MPC_TKO_SPEED: real(
        1.5, 0.5, 5.0, "m/s",
        "Climb speed of a takeoff below MPC_LAND_ALT1 above home (at most MPC_Z_VEL_MAX_UP)",
    ),
    MPC_LAND_SPEED: real(0.7, 0.2, 2.0, "m/s", "Landing descent speed below MPC_LAND_ALT2"),
    MPC_LAND_ALT1: real(
        10.0, 0.0, 122.0, "m",
        "Height above home: a landing descends at MPC_Z_VEL_MAX_DN above it, slowing linearly to MPC_LAND_SPEED at MPC_LAND_ALT2; a takeoff climbs at MPC_TKO_SPEED below it",
    ),
    MPC_LAND_ALT2: real(
        5.0, 0.0, 122.0, "m",
        "Height above home below which a landing descends at MPC_LAND_SPEED (MPC_LAND_ALT1 is at least this)",
    ),
    // --- PX4: commander ------------------------------------------------------------------------
    COM_OF_LOSS_T: real(1.0, 0.0, 60.0, "s", "Offboard: setpoints older than this are lost (OFFBOARD refused or left)"),
    COM_OBL_RC_ACT: choice(
        0, 0, 7,
        "Offboard loss action (PX4's RC modes 0-2 need RC, absent here: they Hold)",
        &[
            (0, "Hold (PX4: Position)"),
            (1, "Hold (PX4: Altitude)"),
            (2, "Hold (PX4: Manual)"),
            (3, "Return"),
            (4, "Land"),
            (5, "Hold"),
            (6, "Terminate"),
            (7, "Disarm"),
        ],
    ),
    COM_DISARM_LAND: real(2.0, -1.0, 20.0, "s", "Disarm this long after a landing (<= 0: never)"),
    COM_FAIL_ACT_T: real(
        5.0, 0.0, 25.0, "s",
        "Failsafe delay: Hold this long before a Return or Land failsafe acts, for the pilot to take over (<= 0.1: none)",
    ),
    COM_DISARM_PRFLT: real(
        10.0, -1.0, 20.0, "s",
        "Disarm this long after arming if the vehicle has not taken off (<= 0: never)",
    ),
    // --- PX4: commander, actuator failure (rotor monitor) --------------------------------------
    // PX4's metadata bounds it at 3 but documents 4, Terminate, and its failsafe acts on it
    COM_ACT_FAIL_ACT: choice(
        0, 0, 4,
        "Action when a rotor fails or degrades in flight (ESC speed vs command)",
        &[(0, "warning, fly on"), (1, "Hold"), (2, "Land"), (3, "Return"), (4, "Terminate")],
    ),
    // --- PX4: manual control (MANUAL_CONTROL sticks), RC loss ---------------------------------
    COM_RC_LOSS_T: real(0.5, 0.0, 35.0, "s", "Manual control (MANUAL_CONTROL) older than this is lost"),
    NAV_RCL_ACT: choice(
        2, 0, 6,
        "Manual control loss action in a manual mode (4: none)",
        &[(0, "disabled"), (1, "Hold"), (2, "Return"), (3, "Land"), (5, "Terminate"), (6, "Disarm")],
    ),
    MPC_VEL_MANUAL: real(10.0, 3.0, 20.0, "m/s", "Position mode: horizontal speed at full stick"),
    MPC_MAN_Y_MAX: real(150.0, 0.0, 400.0, "deg/s", "Position, Altitude, Stabilized: yaw rate at full stick"),
    MPC_HOLD_DZ: real(0.1, 0.0, 1.0, "", "Stick deadzone of Position and Altitude: centred sticks hold"),
    MPC_MAN_TILT_MAX: real(35.0, 0.0, 90.0, "deg", "Altitude, Stabilized: tilt at full stick"),
    MPC_MANTHR_MIN: real(0.08, 0.0, 1.0, "", "Stabilized: collective thrust at zero throttle in the air"),
    MC_ACRO_R_MAX: real(720.0, 0.0, 1800.0, "deg/s", "Acro: roll rate at full stick"),
    MC_ACRO_P_MAX: real(720.0, 0.0, 1800.0, "deg/s", "Acro: pitch rate at full stick"),
    MC_ACRO_Y_MAX: real(540.0, 0.0, 1800.0, "deg/s", "Acro: yaw rate at full stick"),
    MC_ACRO_EXPO: real(0.69, 0.0, 1.0, "", "Acro: roll and pitch expo (0 linear, 1 cubic)"),
    MC_ACRO_EXPO_Y: real(0.69, 0.0, 1.0, "", "Acro: yaw expo (0 linear, 1 cubic)"),
    MC_ACRO_SUPEXPO: real(0.7, 0.0, 0.95, "", "Acro: roll and pitch super-expo"),
    MC_ACRO_SUPEXPOY: real(0.7, 0.0, 0.95, "", "Acro: yaw super-expo"),
    // --- PX4: follow target (AUTO.FOLLOW_TARGET, FOLLOW_TARGET messages) -----------------------
    FLW_TGT_HT: real(8.0, 8.0, f32::MAX as f64, "m", "Follow target: height above home (above the target with FLW_TGT_ALT_M 2)"),
    FLW_TGT_DST: real(8.0, 1.0, f32::MAX as f64, "m", "Follow target: horizontal distance to the target"),
    FLW_TGT_FA: real(
        180.0, -180.0, 180.0, "deg",
        "Follow target: angle from the target's course, clockwise (0 in front, 90 right, 180 behind)",
    ),
    FLW_TGT_ALT_M: choice(
        0, i32::MIN, i32::MAX,
        "Follow target: altitude mode (PX4 bounds it not; another value is 0)",
        &[(0, "2D: constant height above home"), (1, "2D + terrain (flat ground here: as 0)"), (2, "3D: track the target's altitude")],
    ),
    FLW_TGT_MAX_VEL: real(
        5.0, 0.0, 20.0, "m/s",
        "Follow target: largest tangential speed when the follow angle moves round the target",
    ),
    // --- PX4: system, MAVLink, battery ---------------------------------------------------------
    SYS_FAILURE_EN: switch(0, "Allow failure injection (MAV_CMD_INJECT_FAILURE)"),
    MAV_SYS_ID: int(1, 1, 250, "MAVLink system id: --instance + 1, as PX4 SITL sets it at every start (a set to another value is refused)"),
    MAV_COMP_ID: int(1, 1, 250, "MAVLink component id: 1, the autopilot's (a set to another value is refused)"),
    MAV_HB_FORW_EN: switch(1, "Forward clients' HEARTBEATs between the vehicle's links, as its other messages are (PX4: 1)"),
    BAT1_N_CELLS: int(4, 1, 14, "Battery cells in series (the monitor reads them; the simulated pack has them)"),
    BAT1_CAPACITY: real(5000.0, 100.0, 100_000.0, "mAh", "Battery capacity (of the simulated pack)"),
    SIM_BAT_MIN_PCT: real(50.0, 0.0, 100.0, "%", "Simulated battery: charge never drops below this (PX4 SITL's floor)"),
    // --- rotorpilot: control -------------------------------------------------------------------
    CTRL_TYPE: choice(
        1, 0, 2,
        "Control law (switched bumplessly in flight)",
        &[(0, "hierarchical"), (1, "geometric"), (2, "passivity")],
    ),
    CTRL_POS_SCALE: real(
        1.0, 0.2, 3.0, "",
        "Position loop frequency scale s: stiffness gains x s^2, damping gains x s (all laws)",
    ),
    CTRL_ATT_SCALE: real(
        1.0, 0.2, 3.0, "",
        "Attitude loop frequency scale s: stiffness gains x s^2, damping gains x s (all laws)",
    ),
    // --- rotorpilot: estimator -----------------------------------------------------------------
    EST_ORDER: int(3, 1, 20, "Wrench estimator order r"),
    EST_POLY: choice(0, 0, 1, "Estimator filter polynomial", &[(0, "Butterworth"), (1, "binomial")]),
    EST_CUTOFF: real(10.0, 0.1, 100.0, "rad/s", "Estimator cutoff frequency"),
    EST_COMP: switch(0, "Feed the wrench estimate back to the controller"),
    // --- rotorpilot: simulation ----------------------------------------------------------------
    SIM_FEXT_X: real(0.0, -50.0, 50.0, "N", "Injected external force, north (world NED)"),
    SIM_FEXT_Y: real(0.0, -50.0, 50.0, "N", "Injected external force, east (world NED)"),
    SIM_FEXT_Z: real(0.0, -50.0, 50.0, "N", "Injected external force, down (world NED)"),
    SIM_TEXT_X: real(0.0, -10.0, 10.0, "N m", "Injected external torque, body x forward (FRD)"),
    SIM_TEXT_Y: real(0.0, -10.0, 10.0, "N m", "Injected external torque, body y right (FRD)"),
    SIM_TEXT_Z: real(0.0, -10.0, 10.0, "N m", "Injected external torque, body z down (FRD)"),
    SIM_MASS: real(2.0, 0.05, 100.0, "kg", "True mass of the simulated vehicle (default: the airframe's nominal mass)"),
    MDL_MASS: real(
        2.0, 0.05, 100.0, "kg",
        "Nominal mass the controller and estimator assume (default: the airframe's)",
    ),
    SIM_GE_EN: switch(1, "Simulate ground effect"),
    SIM_CE_EN: switch(1, "Simulate ceiling effect (needs SIM_CEIL_Z > 0)"),
    SIM_CEIL_Z: real(0.0, 0.0, 100.0, "m", "Height of a flat ceiling above the home ground (0: no ceiling)"),
    // --- simulation: the air (ArduPilot SITL's SIM_WIND_* names and meanings; gusts our own) ---
    SIM_WIND_SPD: real(0.0, 0.0, 50.0, "m/s", "Simulated mean wind speed (as ArduPilot SITL)"),
    SIM_WIND_DIR: real(
        180.0, 0.0, 360.0, "deg",
        "Direction the simulated wind comes from, true (0 north, 90 east; as ArduPilot SITL)",
    ),
    SIM_WIND_DIR_Z: real(
        0.0, -90.0, 90.0, "deg",
        "Vertical angle of the simulated wind: 0 horizontal, 90 pure updraft (as ArduPilot SITL)",
    ),
    SIM_WIND_TURB: real(
        0.0, 0.0, 10.0, "m/s",
        "Turbulence: Dryden (MIL-F-8785C low altitude) vertical RMS sigma_w, horizontal from height; 0 off (light 0.77, moderate 1.54, severe 2.31)",
    ),
    SIM_GUST_SPD: real(0.0, 0.0, 30.0, "m/s", "1-cosine gust: peak speed (0: no gust)"),
    SIM_GUST_DIR: real(180.0, 0.0, 360.0, "deg", "1-cosine gust: direction it comes from, true"),
    SIM_GUST_T0: real(0.0, 0.0, 1_000_000.0, "s", "1-cosine gust: simulated time the first gust starts"),
    SIM_GUST_DUR: real(2.0, 0.1, 60.0, "s", "1-cosine gust: duration of one gust"),
    SIM_GUST_PER: real(0.0, 0.0, 3600.0, "s", "1-cosine gust: repeat period (0: a single gust)"),
    // --- PX4: failsafes (data link, battery, geofence) -------------------------------------------
    COM_POS_FS_EPH: real(
        5.0, -1.0, 400.0, "m",
        "Horizontal position error threshold: a larger eph (2.5 times it once valid) is no position for the autonomous modes; -1: none",
    ),
    COM_VEL_FS_EVH: real(
        1.0, 0.0, 1000.0, "m/s",
        "Horizontal velocity error threshold: a larger evh (2.5 times it once valid) is no velocity for Offboard",
    ),
    COM_DL_LOSS_T: int(10, 5, 300, "GCS connection loss: no GCS HEARTBEAT for this long [s] while armed"),
    NAV_DLL_ACT: choice(
        0, 0, 6,
        "GCS connection loss action (4: none)",
        &[(0, "disabled"), (1, "Hold"), (2, "Return"), (3, "Land"), (5, "Terminate"), (6, "Disarm")],
    ),
    BAT_LOW_THR: real(0.15, 0.12, 0.5, "norm", "Battery low below this remaining charge (warning)"),
    BAT_CRIT_THR: real(0.07, 0.05, 0.5, "norm", "Battery critical below this remaining charge (COM_LOW_BAT_ACT)"),
    BAT_EMERGEN_THR: real(0.05, 0.03, 0.5, "norm", "Battery emergency below this remaining charge (COM_LOW_BAT_ACT)"),
    COM_LOW_BAT_ACT: choice(
        0, 0, 3,
        "Low battery action",
        &[
            (0, "warning"),
            (1, "Return at critical and emergency (PX4's legacy value)"),
            (2, "Land at critical and emergency"),
            (3, "Return at critical, Land at emergency"),
        ],
    ),
    GF_ACTION: choice(
        2, 0, 5,
        "Geofence breach action",
        &[(0, "none"), (1, "warning"), (2, "Hold"), (3, "Return"), (4, "Terminate"), (5, "Land")],
    ),
    GF_MAX_HOR_DIST: real(0.0, 0.0, 10_000.0, "m", "Geofence: largest horizontal distance from home (0: no limit)"),
    GF_MAX_VER_DIST: real(0.0, 0.0, 10_000.0, "m", "Geofence: largest height above home, also for targets (0: no limit)"),
    // --- rotorpilot: failure injection (MAV_CMD_INJECT_FAILURE, FAILURE_TYPE_WRONG) ------------
    SIM_MOT_WRONG_FR: real(0.5, 0.0, 1.0, "", "Injected MOTOR WRONG: the motor gives this fraction of its thrust"),
    SIM_GPS_WRONG_M: real(
        10.0, 0.0, 1000.0, "m",
        "Injected GPS WRONG: the position reported is this far north (world NED) of the truth",
    ),
    // --- rotorpilot: bounds on what a client may ask -----------------------------------
    RP_ALT_MAX_AMSL: real(
        9_000.0, 0.0, 20_000.0, "m",
        "Highest altitude AMSL a takeoff or reposition may ask for; higher is refused (DENIED)",
    ),
    // --- rotorpilot: navigation source (read at boot) -------------------------------------------
    RP_NAV_SRC: boot_choice(
        1, 0, 1,
        "Navigation solution the flight stack flies on (the daemon boots on the filter, as a PX4 vehicle flies on EKF2; a scenario or mission file flies the ideal solution unless its [navigation] table names the filter)",
        &[
            (0, "ideal: the world's solution (true state plus seeded noise)"),
            (1, "filter: the EKF fed by the raw IMU, barometer, magnetometer and GNSS"),
        ],
    ),
    // --- PX4: the navigation filter (EKF2; read at boot, used with RP_NAV_SRC = 1) ---------------
    EKF2_HGT_REF: boot_choice(
        1, 0, 1,
        "Height reference of the navigation filter (PX4's 2 range and 3 vision are not modelled)",
        &[(0, "barometric pressure"), (1, "GNSS")],
    ),
    EKF2_BARO_CTRL: boot_switch(1, "Barometric height aiding"),
    EKF2_GPS_CTRL: boot_int(7, 0, 15, "GNSS aiding bitmask: 1 position, 2 altitude, 4 3D velocity (8 heading: not modelled)"),
    EKF2_REQ_GPS_H: boot_real(0.5, 0.1, 100.0, "s", "GNSS checks must pass this long before GNSS is fused (PX4 SITL's 0.5 s)"),
    EKF2_BARO_NOISE: boot_real(3.5, 0.01, 15.0, "m", "Measurement noise for barometric altitude"),
    EKF2_BARO_GATE: boot_real(5.0, 1.0, 100.0, "SD", "Gate size for barometric and GNSS height fusion"),
    EKF2_GPS_P_NOISE: boot_real(0.5, 0.01, 10.0, "m", "Minimum GNSS position measurement noise"),
    EKF2_GPS_V_NOISE: boot_real(0.3, 0.01, 5.0, "m/s", "Minimum GNSS velocity measurement noise"),
    EKF2_NOAID_TOUT: boot_int(
        5_000_000, 500_000, 10_000_000,
        "Maximum inertial dead-reckoning time [us]: the horizontal position is invalid after it",
    ),
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_unique_short_upper_case_and_defaults_in_range() {
        for (i, p) in PARAMS.iter().enumerate() {
            assert!(!p.name.is_empty() && p.name.len() <= 16, "{}", p.name);
            assert!(
                p.name
                    .bytes()
                    .all(|b| b.is_ascii_uppercase() || b.is_ascii_digit() || b == b'_'),
                "{}",
                p.name
            );
            assert!(PARAMS[..i].iter().all(|q| q.name != p.name), "duplicate {}", p.name);
            assert!(p.min <= p.default && p.default <= p.max, "{}", p.name);
            assert!(p.min.is_finite() && p.max.is_finite());
            assert!(!p.description.is_empty());
            if p.kind == ParamType::Int32 {
                for x in [p.default, p.min, p.max] {
                    assert_eq!(x.fract(), 0.0, "{}", p.name);
                    assert!(x.abs() <= f64::from(i32::MAX) + 1.0);
                }
            } else {
                // the f32 default must itself pass the f32 range check
                let d = p.default as f32;
                assert!(d >= p.min as f32 && d <= p.max as f32, "{}", p.name);
            }
        }
    }

    #[test]
    fn every_param_names_its_own_entry() {
        assert_eq!(Param::ALL.len(), IMPLEMENTED.len());
        assert_eq!(&PARAMS[..IMPLEMENTED.len()], IMPLEMENTED);
        assert!(
            PARAMS[IMPLEMENTED.len()..]
                .iter()
                .all(|p| p.effect == Effect::StoredOnly)
        );
        assert!(IMPLEMENTED.iter().all(|p| p.effect == Effect::Acts));
        for (i, p) in Param::ALL.iter().enumerate() {
            assert_eq!(*p as usize, i);
            assert_eq!(p.spec().name, format!("{p:?}"));
        }
    }

    #[test]
    fn listed_values_ascend_in_range_and_name_the_default() {
        let mut listed = 0;
        for p in PARAMS.iter() {
            if p.values.is_empty() {
                continue;
            }
            listed += 1;
            assert_eq!(p.kind, ParamType::Int32, "{}", p.name);
            assert!(p.values.windows(2).all(|w| w[0].0 < w[1].0), "{}", p.name);
            for (v, meaning) in p.values {
                assert!(p.min <= f64::from(*v) && f64::from(*v) <= p.max, "{} {v}", p.name);
                assert!(!meaning.is_empty(), "{} {v}", p.name);
            }
            assert!(p.values.iter().any(|(v, _)| f64::from(*v) == p.default), "{}", p.name);
        }
        // the actions, the law, the polynomial and the switches
        assert!(listed >= 12, "{listed}");
        assert_eq!(Param::CTRL_TYPE.spec().values[2], (2, "passivity"));
    }

    #[test]
    fn the_parameters_clients_read_exist() {
        for name in [
            "MIS_TAKEOFF_ALT",
            "RTL_RETURN_ALT",
            "MPC_XY_CRUISE",
            "SYS_FAILURE_EN",
            "COM_OF_LOSS_T",
            "COM_OBL_RC_ACT",
            "COM_DISARM_LAND",
            "COM_DISARM_PRFLT",
            "MAV_SYS_ID",
            "MAV_COMP_ID",
            "NAV_ACC_RAD",
        ] {
            assert!(PARAMS.iter().any(|p| p.name == name), "{name}");
        }
    }
}
