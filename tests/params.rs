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
        ("RTL_RETURN_ALT", ParamValue::Real32(60.0)),
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
        ("MIS_TAKEOFF_ALT", ParamValue::Real32(81.0)),
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
    s.set("RTL_RETURN_ALT", ParamValue::Real32(30.0)).unwrap();
    s.save(&path).unwrap();
    let (back, _) = ParamStore::load(&quad(), &path).unwrap();
    assert_eq!(back.get("RTL_RETURN_ALT").unwrap().1, ParamValue::Real32(30.0));
    assert_eq!(fs::read_dir(&dir).unwrap().count(), 1, "no temporary file left");
    let (missing, w) = ParamStore::load_or_default(&quad(), &dir.join("none.toml")).unwrap();
    assert_eq!(missing, ParamStore::new(&quad()));
    assert!(w.is_empty());
    fs::remove_dir_all(&dir).unwrap();
}
