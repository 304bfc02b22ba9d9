//! Unit tests of `link/convert.rs`: the conversions at the MAVLink edge (custom
//! mode, MAV_RESULT, landed state).

use super::*;

#[test]
fn custom_modes_match_px4_numbers() {
    assert_eq!(custom_mode(FlightMode::Hold), 50_593_792);
    assert_eq!(custom_mode(FlightMode::Takeoff), 33_816_576);
    assert_eq!(custom_mode(FlightMode::Mission), 67_371_008);
    assert_eq!(custom_mode(FlightMode::ReturnToLaunch), 84_148_224);
    assert_eq!(custom_mode(FlightMode::Land), 100_925_440);
    assert_eq!(custom_mode(FlightMode::Offboard), 393_216);
    assert_eq!(custom_mode(FlightMode::Position), 196_608);
    assert_eq!(custom_mode(FlightMode::Manual), 65_536);
    assert_eq!(custom_mode(FlightMode::Altitude), 131_072);
    assert_eq!(custom_mode(FlightMode::Acro), 327_680);
    assert_eq!(custom_mode(FlightMode::Stabilized), 458_752);
    // PX4's Descend is shown as AUTO.LAND
    assert_eq!(custom_mode(FlightMode::Descend), 100_925_440);
    // POSCTL.ORBIT: main 3, sub 1
    assert_eq!(custom_mode(FlightMode::Orbit), 16_973_824);
    // AUTO.FOLLOW_TARGET: main 4, sub 8
    assert_eq!(custom_mode(FlightMode::FollowTarget), 134_479_872);
}

#[test]
fn every_mode_round_trips() {
    for m in [
        FlightMode::Position,
        FlightMode::Hold,
        FlightMode::Takeoff,
        FlightMode::Land,
        FlightMode::ReturnToLaunch,
        FlightMode::Offboard,
        FlightMode::Mission,
        FlightMode::Altitude,
        FlightMode::Stabilized,
        FlightMode::Acro,
        FlightMode::Manual,
        FlightMode::Orbit,
        FlightMode::FollowTarget,
    ] {
        let (main, sub) = px4_mode(m);
        assert_eq!(mode_from_px4(main, sub), ModeRequest::Mode(m));
        assert_eq!(mode_from_set_mode(1, main, sub), ModeRequest::Mode(m));
        assert_eq!(base_mode(m, false) & 1, 1);
        assert_eq!(base_mode(m, true) & 128, 128);
    }
}

#[test]
fn set_mode_quirks() {
    // pymavlink sends 29 (custom + auto + guided + stabilize) for AUTO modes
    assert_eq!(mode_from_set_mode(29, 4, 3), ModeRequest::Mode(FlightMode::Hold));
    // MAVSDK sends 129 when armed: 128 is ignored
    assert_eq!(mode_from_set_mode(129, 6, 0), ModeRequest::Mode(FlightMode::Offboard));
    assert_eq!(mode_from_set_mode(81, 1, 0), ModeRequest::Mode(FlightMode::Manual));
    assert_eq!(mode_from_set_mode(1, 8, 0), ModeRequest::NotAvailable);
    // without CUSTOM_MODE_ENABLED, PX4 reads the manual flags
    assert_eq!(
        mode_from_set_mode(64 | 8, 0, 0),
        ModeRequest::Mode(FlightMode::Position)
    );
    assert_eq!(
        mode_from_set_mode(64 | 16, 0, 0),
        ModeRequest::Mode(FlightMode::Stabilized)
    );
    assert_eq!(mode_from_set_mode(64, 0, 0), ModeRequest::Mode(FlightMode::Manual));
    assert_eq!(mode_from_set_mode(16, 0, 0), ModeRequest::Unknown);
    assert_eq!(mode_from_set_mode(4, 0, 0), ModeRequest::Mode(FlightMode::Mission));
    assert_eq!(mode_from_px4(4, 0), ModeRequest::Mode(FlightMode::Mission));
    assert_eq!(mode_from_px4(42, 0), ModeRequest::Unknown);
}

#[test]
fn units() {
    assert_eq!(deg_e7(47.397_742), 473_977_420);
    assert!((from_deg_e7(85_455_940) - 8.545_594).abs() < 1e-12);
    assert_eq!(heading_cdeg(-0.5_f64.to_radians()), 35_950);
    assert_eq!(heading_cdeg(std::f64::consts::TAU), 0);
    assert_eq!(sat_i16(1e9), i16::MAX);
    assert_eq!(sat_i32(f64::NAN), 0);
    assert_eq!(finite(f32::NAN), None);
}

#[test]
fn available_modes_list_the_flown_modes_in_px4s_order() {
    let all = available_modes(0).unwrap();
    assert_eq!(all.len(), FlightMode::ALL.len());
    for (i, m) in all.iter().enumerate() {
        assert_eq!((m.mode_index, m.number_modes), (i as u8 + 1, all.len() as u8));
    }
    // by nav state: Manual (0) first, Orbit (21) last
    assert_eq!(all[0].custom_mode, custom_mode(FlightMode::Manual));
    assert_eq!(all[all.len() - 1].custom_mode, custom_mode(FlightMode::Orbit));
    let mission = all
        .iter()
        .find(|m| m.custom_mode == custom_mode(FlightMode::Mission))
        .unwrap();
    assert_eq!(mission.standard_mode, MavStandardMode::MAV_STANDARD_MODE_MISSION);
    assert_eq!(
        mission.mode_name.to_str().unwrap(),
        "",
        "a standard mode carries no name"
    );
    assert!(mission.properties.contains(MavModeProperty::MAV_MODE_PROPERTY_ADVANCED));
    let hold = all
        .iter()
        .find(|m| m.custom_mode == custom_mode(FlightMode::Hold))
        .unwrap();
    assert_eq!(hold.standard_mode, MavStandardMode::MAV_STANDARD_MODE_NON_STANDARD);
    assert_eq!(hold.mode_name.to_str().unwrap(), "Hold");
    let position = all
        .iter()
        .find(|m| m.custom_mode == custom_mode(FlightMode::Position))
        .unwrap();
    assert!(position.properties.is_empty(), "Position is not an advanced mode");
    // one by index; past the last, nothing
    assert_eq!(available_modes(3).unwrap(), vec![all[2].clone()]);
    assert!(available_modes(all.len() as u8 + 1).is_none());
}
