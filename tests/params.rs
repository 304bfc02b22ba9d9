//! The parameter table, store and files through the public API, as the
//! MAVLink layer uses them: PX4 names and defaults, bytewise INT32, refusals
//! that change nothing, and the persisted file.

mod common;

use common::scratch_dir;
use std::fs;

use rotorpilot::airframe::Airframe;
use rotorpilot::params::{PARAMS, ParamError, ParamStore, ParamType, ParamValue};

fn quad() -> Airframe {
    Airframe::load("quad").unwrap()
}

#[test]
fn px4_parameters_clients_read_have_px4_types_and_defaults() {
    let s = ParamStore::new(&quad());
    for (name, want) in [
        ("MIS_TAKEOFF_ALT", ParamValue::Real32(2.5)),
        ("RTL_RETURN_ALT", ParamValue::Real32(30.0)),
        ("RTL_DESCEND_ALT", ParamValue::Real32(10.0)),
        ("MPC_XY_CRUISE", ParamValue::Real32(5.0)),
        ("SYS_FAILURE_EN", ParamValue::Int32(0)),
        ("COM_OF_LOSS_T", ParamValue::Real32(1.0)),
        ("COM_OBL_RC_ACT", ParamValue::Int32(0)),
        ("COM_DISARM_LAND", ParamValue::Real32(2.0)),
        ("COM_DISARM_PRFLT", ParamValue::Real32(10.0)),
        ("MAV_SYS_ID", ParamValue::Int32(1)),
        ("MAV_COMP_ID", ParamValue::Int32(1)),
        ("NAV_ACC_RAD", ParamValue::Real32(2.0)),
        ("CTRL_TYPE", ParamValue::Int32(1)),
        ("EST_ORDER", ParamValue::Int32(3)),
        ("EST_POLY", ParamValue::Int32(0)),
        ("EST_CUTOFF", ParamValue::Real32(10.0)),
        ("EST_COMP", ParamValue::Int32(0)),
        ("SIM_MASS", ParamValue::Real32(2.0)),
        ("MDL_MASS", ParamValue::Real32(2.0)),
    ] {
        assert_eq!(s.get(name).map(|(_, v)| v), Some(want), "{name}");
    }
    // the ids are the instance's, not the file's: a set is refused, not deferred to a restart
    let spec = s.spec(s.index_of("MAV_SYS_ID").unwrap()).unwrap();
    assert!(!spec.reboot_required && spec.description.contains("refused"));
}

#[test]
fn indices_are_dense_and_names_fit_param_id() {
    let s = ParamStore::new(&quad());
    assert_eq!(s.len(), PARAMS.len());
    assert!(!s.is_empty());
    for i in 0..s.len() {
        let (spec, value) = s.by_index(i).unwrap();
        assert!(spec.name.len() <= 16);
        assert_eq!(s.index_of(spec.name), Some(i));
        assert_eq!(s.get(spec.name), Some((i, value)));
        assert_eq!(value.kind(), spec.kind);
        assert_eq!(s.default_value(i), Some(value));
        assert!(value.as_f64() >= spec.min && value.as_f64() <= spec.max);
    }
    assert!(s.by_index(s.len()).is_none());
}

#[test]
fn int32_values_travel_bytewise_and_decode_back() {
    let s = ParamStore::new(&quad());
    for (spec, value) in s.iter() {
        let wire = value.to_mavlink_float();
        let back = ParamValue::from_mavlink(spec.kind.mavlink_id(), wire).unwrap();
        assert_eq!(back, value, "{}", spec.name);
        if spec.kind == ParamType::Int32 {
            assert_eq!(wire.to_bits() as i32, value.as_f64() as i32);
        }
    }
    // PARAM_SET of INT32 1 as MAVSDK sends it (float bits 0x00000001)
    let v = ParamValue::from_mavlink(6, f32::from_bits(1)).unwrap();
    let mut s = s;
    assert_eq!(s.set("SYS_FAILURE_EN", v), Ok(ParamValue::Int32(1)));
    assert_eq!(s.get("SYS_FAILURE_EN").unwrap().1.to_mavlink_float().to_bits(), 1);
    assert_eq!(ParamValue::from_mavlink(1, 0.0), None, "only INT32 and REAL32, as PX4");
}

#[test]
fn refused_values_leave_the_store_unchanged() {
    let mut s = ParamStore::new(&quad());
    s.set("MIS_TAKEOFF_ALT", ParamValue::Real32(4.0)).unwrap();
    let before = s.clone();
    let refusals: [(&str, ParamValue); 8] = [
        ("NOT_A_PARAM", ParamValue::Real32(1.0)),
        ("MIS_TAKEOFF_ALT", ParamValue::Real32(f32::NAN)),
        ("MIS_TAKEOFF_ALT", ParamValue::Real32(f32::INFINITY)),
        ("MIS_TAKEOFF_ALT", ParamValue::Real32(-0.5)),
        ("MIS_TAKEOFF_ALT", ParamValue::Int32(3)),
        ("CTRL_TYPE", ParamValue::Real32(2.0)),
        ("CTRL_TYPE", ParamValue::Int32(-1)),
        ("SIM_MASS", ParamValue::Real32(-1.0)),
    ];
    for (name, value) in refusals {
        let e = s.set(name, value).unwrap_err();
        assert!(e.to_string().contains(name), "{e}");
        assert_eq!(s, before, "{name} = {value:?}");
    }
    assert!(matches!(
        s.set("EST_ORDER", ParamValue::Int32(25)),
        Err(ParamError::OutOfRange { name: "EST_ORDER", .. })
    ));
    // a refused MAVLink PARAM_SET with the wrong type: REAL32 bits for an INT32 parameter
    let wrong = ParamValue::from_mavlink(9, 1.0).unwrap();
    assert!(matches!(s.set("EST_COMP", wrong), Err(ParamError::WrongType { .. })));
    assert_eq!(s, before);
}

#[test]
fn save_load_round_trip_keeps_every_value_and_airframe_defaults() {
    let dir = scratch_dir("round-trip");
    let path = dir.join("params.toml");
    let mut s = ParamStore::new(&quad());
    s.set("RTL_RETURN_ALT", ParamValue::Real32(25.5)).unwrap();
    s.set("CTRL_TYPE", ParamValue::Int32(2)).unwrap();
    s.set("EST_CUTOFF", ParamValue::Real32(12.345_678)).unwrap();
    s.set("SIM_TEXT_Z", ParamValue::Real32(-0.2)).unwrap();
    s.save(&path).unwrap();
    let (back, warnings) = ParamStore::load(&quad(), &path).unwrap();
    assert!(warnings.is_empty(), "{warnings:?}");
    assert_eq!(back.iter().collect::<Vec<_>>(), s.iter().collect::<Vec<_>>());
    // the same file on another airframe: changed values kept, mass defaults from that airframe
    let fsr = Airframe::load("fsr-quad").unwrap();
    let (other, _) = ParamStore::load(&fsr, &path).unwrap();
    assert_eq!(other.get("RTL_RETURN_ALT").unwrap().1, ParamValue::Real32(25.5));
    assert_eq!(other.get("SIM_MASS").unwrap().1, ParamValue::Real32(1.5));
    // saving again over the old file
    s.set("RTL_RETURN_ALT", ParamValue::Real32(45.0)).unwrap();
    s.save(&path).unwrap();
    let (back, _) = ParamStore::load(&quad(), &path).unwrap();
    assert_eq!(back.get("RTL_RETURN_ALT").unwrap().1, ParamValue::Real32(45.0));
    assert_eq!(fs::read_dir(&dir).unwrap().count(), 1, "no temporary file left");
    let (missing, w) = ParamStore::load_or_default(&quad(), &dir.join("none.toml")).unwrap();
    assert_eq!(missing, ParamStore::new(&quad()));
    assert!(w.is_empty());
    fs::remove_dir_all(&dir).unwrap();
}

/// Every parameter rotorpilot implements that PX4 SITL's multicopter also
/// has: this list is exact, so a parameter newly shared is a deliberate step.
const SHARED_WITH_PX4: &[&str] = &[
    "MIS_TAKEOFF_ALT",
    "RTL_RETURN_ALT",
    "RTL_DESCEND_ALT",
    "NAV_ACC_RAD",
    "NAV_MC_ALT_RAD",
    "MPC_XY_CRUISE",
    "MPC_XY_VEL_MAX",
    "MPC_Z_VEL_MAX_UP",
    "MPC_Z_VEL_MAX_DN",
    "MPC_Z_V_AUTO_UP",
    "MPC_Z_V_AUTO_DN",
    "MPC_TKO_SPEED",
    "MPC_LAND_SPEED",
    "MPC_LAND_ALT1",
    "MPC_LAND_ALT2",
    "COM_OF_LOSS_T",
    "COM_OBL_RC_ACT",
    "COM_DISARM_LAND",
    "COM_FAIL_ACT_T",
    "COM_DISARM_PRFLT",
    "COM_ACT_FAIL_ACT",
    "COM_RC_LOSS_T",
    "NAV_RCL_ACT",
    "MPC_VEL_MANUAL",
    "MPC_MAN_Y_MAX",
    "MPC_HOLD_DZ",
    "MPC_MAN_TILT_MAX",
    "MPC_MANTHR_MIN",
    "MC_ACRO_R_MAX",
    "MC_ACRO_P_MAX",
    "MC_ACRO_Y_MAX",
    "MC_ACRO_EXPO",
    "MC_ACRO_EXPO_Y",
    "MC_ACRO_SUPEXPO",
    "MC_ACRO_SUPEXPOY",
    "FLW_TGT_HT",
    "FLW_TGT_DST",
    "FLW_TGT_FA",
    "FLW_TGT_ALT_M",
    "FLW_TGT_MAX_VEL",
    "SYS_FAILURE_EN",
    "MAV_SYS_ID",
    "MAV_COMP_ID",
    "MAV_HB_FORW_EN",
    "BAT1_N_CELLS",
    "BAT1_CAPACITY",
    "SIM_BAT_MIN_PCT",
    "COM_POS_FS_EPH",
    "COM_VEL_FS_EVH",
    "COM_DL_LOSS_T",
    "NAV_DLL_ACT",
    "BAT_LOW_THR",
    "BAT_CRIT_THR",
    "BAT_EMERGEN_THR",
    "COM_LOW_BAT_ACT",
    "GF_ACTION",
    "GF_MAX_HOR_DIST",
    "GF_MAX_VER_DIST",
    "EKF2_HGT_REF",
    "EKF2_BARO_CTRL",
    "EKF2_GPS_CTRL",
    "EKF2_REQ_GPS_H",
    "EKF2_BARO_NOISE",
    "EKF2_BARO_GATE",
    "EKF2_GPS_P_NOISE",
    "EKF2_GPS_V_NOISE",
    "EKF2_NOAID_TOUT",
];

/// Shared parameters whose default here differs from PX4 SITL's boot value,
/// each with PX4's value and why: (name, rotorpilot, PX4 SITL, reason).
const DEVIATIONS: &[(&str, f64, f64, &str)] = &[
    (
        "MC_ACRO_R_MAX",
        720.0,
        100.0,
        "PX4 v1.14's acro rates; later PX4 made them beginner-friendly",
    ),
    ("MC_ACRO_P_MAX", 720.0, 100.0, "as MC_ACRO_R_MAX"),
    ("MC_ACRO_Y_MAX", 540.0, 100.0, "as MC_ACRO_R_MAX"),
    ("MC_ACRO_EXPO", 0.69, 0.0, "as MC_ACRO_R_MAX"),
    ("MC_ACRO_EXPO_Y", 0.69, 0.0, "as MC_ACRO_R_MAX"),
    ("MC_ACRO_SUPEXPO", 0.7, 0.0, "as MC_ACRO_R_MAX"),
    ("MC_ACRO_SUPEXPOY", 0.7, 0.0, "as MC_ACRO_R_MAX"),
    (
        "SYS_FAILURE_EN",
        0.0,
        1.0,
        "PX4 SITL's rcS enables failure injection; here it must be asked for",
    ),
    (
        "BAT1_CAPACITY",
        5000.0,
        -1.0,
        "the simulated pack's capacity; PX4's -1 is 'unknown'",
    ),
    (
        "NAV_DLL_ACT",
        0.0,
        2.0,
        "the x500 airframe sets Return on data-link loss; here none by default",
    ),
    (
        "COM_LOW_BAT_ACT",
        0.0,
        3.0,
        "PX4 SITL's rcS sets Return/Land; here a warning by default",
    ),
];

#[test]
fn shared_defaults_are_px4_sitl_boot_defaults() {
    use rotorpilot::params::{Effect, px4_params};
    let px4 = px4_params();
    let s = ParamStore::new(&quad());
    let shared: Vec<&str> = PARAMS
        .iter()
        .filter(|p| p.effect == Effect::Acts && px4.iter().any(|q| q.name == p.name))
        .map(|p| p.name)
        .collect();
    assert_eq!(shared, SHARED_WITH_PX4, "the parameters shared with PX4");
    for name in SHARED_WITH_PX4 {
        let theirs = px4.iter().find(|q| q.name == *name).unwrap();
        let (i, ours) = s.get(name).unwrap();
        assert_eq!(s.spec(i).unwrap().kind, theirs.kind, "{name}: PX4's type");
        let px4_default = match theirs.kind {
            ParamType::Int32 => ParamValue::Int32(theirs.default as i32),
            ParamType::Real32 => ParamValue::Real32(theirs.default as f32),
        };
        match DEVIATIONS.iter().find(|d| d.0 == *name) {
            None => assert_eq!(ours, px4_default, "{name}: PX4 SITL boots with {px4_default}"),
            Some(&(_, here, there, why)) => {
                assert_eq!(
                    ours.as_f64() as f32,
                    here as f32,
                    "{name}: the listed deviation ({why})"
                );
                assert_eq!(theirs.default as f32, there as f32, "{name}: PX4's value moved");
                assert_ne!(ours, px4_default, "{name} now matches PX4: drop it from DEVIATIONS");
            }
        }
    }
}

/// Shared parameters whose range here does not reach a bound PX4 declares,
/// each with why: (name, reason).
const RANGE_DEVIATIONS: &[(&str, &str)] = &[
    (
        "MPC_XY_VEL_MAX",
        "PX4 declares 0; the speeds it caps (cruise, reposition, offboard) must stay > 0 here",
    ),
    (
        "BAT1_CAPACITY",
        "PX4's -1 is 'unknown'; the simulated pack needs a capacity",
    ),
];

/// PX4 checks no range on PARAM_SET, but QGroundControl offers what PX4
/// declares and scripts set values within it: every value PX4 declares
/// valid for a parameter we share is accepted here too (where PX4 declares
/// no bound, the bound here is our own). Each shared parameter's range
/// reaches PX4's declared bounds, or is listed in RANGE_DEVIATIONS; the
/// bounds themselves are set and read back.
#[test]
fn shared_ranges_reach_the_bounds_px4_declares() {
    use rotorpilot::params::px4_params;
    let mut s = ParamStore::new(&quad());
    let value = |kind: ParamType, x: f64| match kind {
        ParamType::Int32 => ParamValue::Int32(x as i32),
        ParamType::Real32 => ParamValue::Real32(x as f32),
    };
    let px4 = px4_params();
    let mut short = Vec::new();
    for name in SHARED_WITH_PX4 {
        let theirs = px4.iter().find(|q| q.name == *name).unwrap();
        let (i, _) = s.get(name).unwrap();
        let ours = *s.spec(i).unwrap();
        let (lo, hi) = theirs.kind.limits();
        // PX4's declared bounds (an undeclared one is the type's limit)
        let declared: Vec<f64> = [theirs.min, theirs.max]
            .into_iter()
            .filter(|b| *b != lo && *b != hi)
            .collect();
        let unreached: Vec<f64> = declared
            .iter()
            .copied()
            .filter(|b| *b < ours.min || *b > ours.max)
            .collect();
        let listed = RANGE_DEVIATIONS.iter().any(|d| d.0 == *name);
        if unreached.is_empty() {
            assert!(
                !listed,
                "{name} now reaches PX4's bounds: drop it from RANGE_DEVIATIONS"
            );
            for b in declared {
                let v = value(theirs.kind, b);
                assert_eq!(s.set(name, v), Ok(v), "{name} = {b}, a value PX4 declares valid");
            }
        } else if !listed {
            let bound = |b: f64| {
                if b == lo || b == hi {
                    "none".to_string()
                } else {
                    b.to_string()
                }
            };
            short.push(format!(
                "{name}: here {}..{}, PX4 declares {}..{}",
                ours.min,
                ours.max,
                bound(theirs.min),
                bound(theirs.max)
            ));
        }
    }
    assert!(short.is_empty(), "ranges short of PX4's declared bounds: {short:#?}");
}

#[test]
fn px4_parameters_rotorpilot_does_not_use_are_stored_checked_and_saved() {
    use rotorpilot::params::{Effect, px4_params};
    let mut s = ParamStore::new(&quad());
    // every PX4 parameter exists here, with PX4's type and boot default
    for q in px4_params() {
        let (i, v) = s.get(q.name).unwrap_or_else(|| panic!("{} missing", q.name));
        assert_eq!(s.spec(i).unwrap().kind, q.kind, "{}", q.name);
        if s.spec(i).unwrap().effect == Effect::StoredOnly {
            assert_eq!(v.as_f64() as f32, q.default as f32, "{}", q.name);
        }
    }
    // the ones PX4's own integration tests set
    assert_eq!(
        s.set("MPC_Z_V_AUTO_DN", ParamValue::Real32(2.5)),
        Ok(ParamValue::Real32(2.5))
    );
    assert_eq!(s.set("RTL_TYPE", ParamValue::Int32(1)), Ok(ParamValue::Int32(1)));
    assert_eq!(s.set("RTL_APPR_FORCE", ParamValue::Int32(1)), Ok(ParamValue::Int32(1)));
    assert_eq!(s.set("EKF2_HGT_REF", ParamValue::Int32(0)), Ok(ParamValue::Int32(0)));
    // PX4's range: MPC_Z_V_AUTO_DN is 0.5 .. 4 m/s
    assert!(matches!(
        s.set("MPC_Z_V_AUTO_DN", ParamValue::Real32(9.0)),
        Err(ParamError::OutOfRange { .. })
    ));
    assert!(matches!(
        s.set("RTL_TYPE", ParamValue::Real32(1.0)),
        Err(ParamError::WrongType { .. })
    ));
    let mut back = ParamStore::new(&quad());
    let warnings = back.apply_file_text(&s.to_file_text(), "params.toml");
    assert!(warnings.is_empty(), "{warnings:?}");
    for name in ["MPC_Z_V_AUTO_DN", "RTL_TYPE", "RTL_APPR_FORCE", "EKF2_HGT_REF"] {
        assert_eq!(back.get(name), s.get(name), "{name} saved and read back");
    }
}
