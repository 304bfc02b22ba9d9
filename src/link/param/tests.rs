//! Unit tests of `link/param.rs`: the parameter protocol
//! (PARAM_REQUEST_LIST/READ, PARAM_SET, PARAM_VALUE).

use super::*;
use crate::link::testing::FakeParams;

fn pv(m: &MavMessage) -> &PARAM_VALUE_DATA {
    match m {
        MavMessage::PARAM_VALUE(p) => p,
        other => panic!("not PARAM_VALUE: {other:?}"),
    }
}

#[test]
fn int32_is_bytewise() {
    let (f, t) = to_wire(ParamValue::Int32(1));
    assert_eq!(f.to_bits(), 1);
    assert_eq!(t, MavParamType::MAV_PARAM_TYPE_INT32);
    assert_eq!(from_wire(t, f), Some(ParamValue::Int32(1)));
    assert_eq!(
        from_wire(
            MavParamType::MAV_PARAM_TYPE_INT32,
            f32::from_bits((-7i32).cast_unsigned())
        ),
        Some(ParamValue::Int32(-7))
    );
    assert_eq!(from_wire(MavParamType::MAV_PARAM_TYPE_UINT8, 1.0), None);
}

#[test]
fn list_is_consistent() {
    let p = FakeParams::standard();
    let l = list(&p);
    assert_eq!(l.len(), 5);
    for (i, m) in l.iter().enumerate() {
        assert_eq!(usize::from(pv(m).param_index), i);
        assert_eq!(pv(m).param_count, 5);
    }
    // a 16-character name has no terminating null
    assert_eq!(name_of(&pv(&l[4]).param_id), "SIXTEEN_CHARS_XX");
}

#[test]
fn read_by_name_and_index() {
    let p = FakeParams::standard();
    let m = read(&p, "CTRL_TYPE", -1, (255, 0));
    assert_eq!(pv(&m).param_index, 1);
    let m = read(&p, "ignored", 2, (255, 0));
    assert_eq!(name_of(&pv(&m).param_id), "MIS_TAKEOFF_ALT");
    let m = read(&p, "NOPE", -1, (255, 0));
    assert!(matches!(m, MavMessage::PARAM_ERROR(ref e) if e.error == MavParamError::MAV_PARAM_ERROR_DOES_NOT_EXIST));
    let m = read(&p, "", 99, (255, 0));
    assert!(matches!(m, MavMessage::PARAM_ERROR(ref e) if e.param_index == 99));
}

#[test]
fn set_accepts_echoes_and_refuses_unchanged() {
    let mut p = FakeParams::standard();
    let int1 = f32::from_bits(1);
    let r = set(
        &mut p,
        "CTRL_TYPE",
        MavParamType::MAV_PARAM_TYPE_INT32,
        int1,
        (245, 190),
    );
    assert_eq!(r.replies.len(), 1);
    assert_eq!(pv(&r.replies[0]).param_value.to_bits(), 1);
    assert_eq!(r.changed.as_ref().map(|c| c.0), Some(1));
    // out of range: PARAM_ERROR, then the unchanged value
    let r = set(
        &mut p,
        "CTRL_TYPE",
        MavParamType::MAV_PARAM_TYPE_INT32,
        f32::from_bits(7),
        (245, 190),
    );
    assert!(r.changed.is_none());
    assert!(matches!(r.replies[0], MavMessage::PARAM_ERROR(_)));
    assert_eq!(pv(&r.replies[1]).param_value.to_bits(), 1);
    // wrong type: REAL32 1.0 into an INT32
    let r = set(
        &mut p,
        "CTRL_TYPE",
        MavParamType::MAV_PARAM_TYPE_REAL32,
        2.0,
        (245, 190),
    );
    assert!(r.changed.is_none());
    assert_eq!(pv(&r.replies[1]).param_value.to_bits(), 1);
    // NaN
    let r = set(
        &mut p,
        "MIS_TAKEOFF_ALT",
        MavParamType::MAV_PARAM_TYPE_REAL32,
        f32::NAN,
        (245, 190),
    );
    assert_eq!(pv(&r.replies[1]).param_value, 2.5);
    // unknown name: only PARAM_ERROR
    let r = set(&mut p, "NO_SUCH", MavParamType::MAV_PARAM_TYPE_REAL32, 1.0, (245, 190));
    assert_eq!(r.replies.len(), 1);
    assert!(matches!(r.replies[0], MavMessage::PARAM_ERROR(ref e) if e.target_system == 245));
}
