//! Unit tests of `link/command.rs`: the command protocol
//! (COMMAND_LONG/COMMAND_INT to autopilot commands and back to COMMAND_ACK).

use super::*;
use crate::autopilot::FlightMode;

fn long(command: u16, p: [f32; 7]) -> Command {
    Command::from(&CommandLong {
        params: p,
        command,
        target_system: 1,
        target_component: 1,
        confirmation: 0,
    })
}

const N: f32 = f32::NAN;

#[test]
fn arm_disarm_and_force() {
    let c = |p1, p2| classify(&long(400, [p1, p2, N, N, N, N, N]));
    assert_eq!(c(1.0, N), Action::Autopilot(AutopilotCommand::Arm { force: false }));
    assert_eq!(c(1.0, 0.0), Action::Autopilot(AutopilotCommand::Arm { force: false }));
    assert_eq!(
        c(1.0, 21196.0),
        Action::Autopilot(AutopilotCommand::Arm { force: true })
    );
    // MAVSDK arm_force() sends p1 = 0: a forced disarm
    assert_eq!(
        c(0.0, 21196.0),
        Action::Autopilot(AutopilotCommand::Disarm { force: true })
    );
    assert_eq!(
        c(0.0, 0.0),
        Action::Autopilot(AutopilotCommand::Disarm { force: false })
    );
    assert_eq!(c(3.0, 0.0), Action::Answer(result::UNSUPPORTED, None));
    assert_eq!(c(N, 0.0), Action::Answer(result::UNSUPPORTED, None));
}

#[test]
fn takeoff_at_an_impossible_place_is_denied_here() {
    for (lat, lon) in [(95.0, 8.5), (-90.5, 8.5), (47.4, 181.0)] {
        let a = classify(&long(22, [N, N, N, N, lat, lon, 500.0]));
        assert!(
            matches!(a, Action::Answer(result::DENIED, Some(_))),
            "{lat}, {lon}: {a:?}"
        );
    }
    let int = |x: i32| {
        Command::from(&CommandInt {
            params: [N; 4],
            x,
            y: 85_000_000,
            z: 500.0,
            command: 22,
            target_system: 1,
            target_component: 1,
            frame: 0,
            current: 0,
            autocontinue: 0,
        })
    };
    assert!(matches!(classify(&int(950_000_000)), Action::Answer(result::DENIED, _)));
    assert!(matches!(classify(&int(474_000_000)), Action::Autopilot(_)));
    // an unset position (NaN, 0/0) takes off where it stands
    assert!(matches!(classify(&long(22, [N; 7])), Action::Autopilot(_)));
    assert!(matches!(
        classify(&long(22, [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 10.0])),
        Action::Autopilot(_)
    ));
}

#[test]
fn takeoff_altitudes() {
    let a = classify(&long(22, [N; 7]));
    assert_eq!(
        a,
        Action::Autopilot(AutopilotCommand::Takeoff { altitude_amsl_m: None })
    );
    let a = classify(&long(22, [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 10.0]));
    assert_eq!(
        a,
        Action::Autopilot(AutopilotCommand::Takeoff {
            altitude_amsl_m: Some(10.0)
        })
    );
}

#[test]
fn reposition_from_mavsdk_3_and_4_and_pymavlink() {
    let mk = |frame| {
        Command::from(&CommandInt {
            params: [N, 1.0, N, 1.5],
            x: 473_977_420,
            y: 85_455_940,
            z: 508.0,
            command: 192,
            target_system: 1,
            target_component: 1,
            frame,
            current: 0,
            autocontinue: 0,
        })
    };
    for frame in [0, 5, 6] {
        let Action::Autopilot(AutopilotCommand::Reposition {
            lat_deg,
            lon_deg,
            alt_amsl_m,
            yaw_rad,
            speed_m_s,
        }) = classify(&mk(frame))
        else {
            panic!()
        };
        assert!((lat_deg.unwrap() - 47.397_742).abs() < 1e-9);
        assert!((lon_deg.unwrap() - 8.545_594).abs() < 1e-9);
        assert_eq!(alt_amsl_m, Some(508.0));
        assert_eq!(yaw_rad, Some(1.5));
        assert_eq!(speed_m_s, None);
    }
    // p2 = 0: PX4's commander answers UNSUPPORTED, its navigator still moves a Hold in force
    let a = classify(&long(192, [N, 0.0, N, N, 47.0, 8.0, 500.0]));
    assert_eq!(
        a,
        Action::Autopilot(AutopilotCommand::RepositionInHold {
            lat_deg: Some(47.0),
            lon_deg: Some(8.0),
            alt_amsl_m: Some(500.0),
            yaw_rad: None,
            speed_m_s: None
        })
    );
    // a bit other than CHANGE_MODE: UNSUPPORTED, nothing flown
    for p2 in [2.0, 3.0] {
        let a = classify(&long(192, [N, p2, N, N, 47.0, 8.0, 500.0]));
        assert!(matches!(a, Action::Answer(result::UNSUPPORTED, _)), "{a:?}");
    }
    // long form with NaN position keeps everything
    let a = classify(&long(192, [N, 1.0, N, N, N, N, N]));
    assert_eq!(
        a,
        Action::Autopilot(AutopilotCommand::Reposition {
            lat_deg: None,
            lon_deg: None,
            alt_amsl_m: None,
            yaw_rad: None,
            speed_m_s: None
        })
    );
}

#[test]
fn set_mode_and_refusals() {
    let a = classify(&long(176, [1.0, 4.0, 3.0, N, N, N, N]));
    assert_eq!(a, Action::Autopilot(AutopilotCommand::SetMode(FlightMode::Hold)));
    let a = classify(&long(176, [129.0, 6.0, 0.0, N, N, N, N]));
    assert_eq!(a, Action::Autopilot(AutopilotCommand::SetMode(FlightMode::Offboard)));
    // manual modes go to the autopilot, which refuses them without manual control
    let a = classify(&long(176, [81.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0]));
    assert_eq!(a, Action::Autopilot(AutopilotCommand::SetMode(FlightMode::Manual)));
    // AUTO.FOLLOW_TARGET goes to the autopilot; AUTO.PRECLAND exists in PX4 but is not flown here
    let a = classify(&long(176, [1.0, 4.0, 8.0, 0.0, 0.0, 0.0, 0.0]));
    assert_eq!(
        a,
        Action::Autopilot(AutopilotCommand::SetMode(FlightMode::FollowTarget))
    );
    let a = classify(&long(176, [1.0, 4.0, 9.0, 0.0, 0.0, 0.0, 0.0]));
    assert!(matches!(a, Action::Answer(result::TEMPORARILY_REJECTED, _)));
    // Mission goes to the autopilot, which refuses it without a mission
    let a = classify(&long(176, [1.0, 4.0, 4.0, N, N, N, N]));
    assert_eq!(a, Action::Autopilot(AutopilotCommand::SetMode(FlightMode::Mission)));
    assert_eq!(
        classify(&long(31_000, [N; 7])),
        Action::Answer(result::UNSUPPORTED, None)
    );
    // the autopilot decides: no mission yet, SYS_FAILURE_EN
    assert_eq!(
        classify(&long(300, [0.0; 7])),
        Action::Autopilot(AutopilotCommand::StartMission { first: Some(0) })
    );
    assert_eq!(
        classify(&long(300, [3.0, N, N, N, N, N, N])),
        Action::Autopilot(AutopilotCommand::StartMission { first: Some(3) })
    );
    for p1 in [N, -1.0] {
        assert_eq!(
            classify(&long(300, [p1, N, N, N, N, N, N])),
            Action::Autopilot(AutopilotCommand::StartMission { first: None })
        );
    }
    assert_eq!(
        classify(&long(224, [2.0, N, N, N, N, N, N])),
        Action::Autopilot(AutopilotCommand::SetMissionCurrent { seq: 2 })
    );
    assert_eq!(
        classify(&long(224, [1e9, N, N, N, N, N, N])),
        Action::Autopilot(AutopilotCommand::SetMissionCurrent { seq: u16::MAX })
    );
    assert!(matches!(
        classify(&long(224, [N; 7])),
        Action::Answer(result::DENIED, _)
    ));
    assert_eq!(
        classify(&long(420, [1.0, 1.0, 3.0, N, N, N, N])),
        Action::Autopilot(AutopilotCommand::InjectFailure {
            unit: 1,
            kind: 1,
            instance: 3
        })
    );
    // SYS_FAILURE_EN is the autopilot's to check, whatever the numbers
    assert_eq!(
        classify(&long(420, [N, 1.0, 0.0, N, N, N, N])),
        Action::Autopilot(AutopilotCommand::InjectFailure {
            unit: 255,
            kind: 1,
            instance: 0
        })
    );
    // DO_CHANGE_SPEED: NaN is "no change" (-1), -2 is "back to the default"
    assert_eq!(
        classify(&long(178, [1.0, N, -1.0, N, N, N, N])),
        Action::Autopilot(AutopilotCommand::ChangeSpeed { speed_m_s: -1.0 })
    );
    assert_eq!(
        classify(&long(178, [1.0, 3.5, -1.0, N, N, N, N])),
        Action::Autopilot(AutopilotCommand::ChangeSpeed { speed_m_s: 3.5 })
    );
}

#[test]
fn standard_modes_and_prearm_checks() {
    let c = |p1| classify(&long(262, [p1, N, N, N, N, N, N]));
    for (standard, mode) in [
        (1.0, FlightMode::Position),
        (2.0, FlightMode::Orbit),
        (4.0, FlightMode::Altitude),
        (5.0, FlightMode::ReturnToLaunch),
        (6.0, FlightMode::Mission),
        (7.0, FlightMode::Land),
        (8.0, FlightMode::Takeoff),
    ] {
        assert_eq!(c(standard), Action::Autopilot(AutopilotCommand::SetMode(mode)));
        assert_eq!(convert::standard_mode(mode) as u8 as f32, standard);
    }
    // non-standard, cruise (fixed-wing), unknown, not a number: FAILED (PX4)
    for p1 in [0.0, 3.0, 9.0, -1.0, 300.0, N] {
        assert_eq!(c(p1), Action::Answer(result::FAILED, None), "{p1}");
    }
    assert_eq!(
        classify(&long(401, [N; 7])),
        Action::Autopilot(AutopilotCommand::RunPrearmChecks)
    );
}

#[test]
fn requests_and_reboot() {
    assert_eq!(
        classify(&long(512, [148.0, N, N, N, N, N, N])),
        Action::SendMessage(148, None)
    );
    // param2, rounded, is a message's index (AVAILABLE_MODES' mode)
    assert_eq!(
        classify(&long(512, [435.0, 2.4, N, N, N, N, N])),
        Action::SendMessage(435, Some(2))
    );
    assert_eq!(
        classify(&long(512, [435.0, -1.0, N, N, N, N, N])),
        Action::SendMessage(435, None)
    );
    assert_eq!(
        classify(&long(520, [1.0, N, N, N, N, N, N])),
        Action::SendMessage(148, None)
    );
    assert_eq!(classify(&long(410, [0.0; 7])), Action::SendMessage(242, None));
    assert_eq!(
        classify(&long(511, [245.0, 1e6, N, N, N, N, N])),
        Action::SetInterval(245, Interval::Every(Duration::from_secs(1)))
    );
    // the autopilot refuses while armed
    assert_eq!(
        classify(&long(246, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])),
        Action::Autopilot(AutopilotCommand::Power(PowerAction::Reboot))
    );
    assert_eq!(
        classify(&long(246, [2.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])),
        Action::Autopilot(AutopilotCommand::Power(PowerAction::Shutdown))
    );
    assert_eq!(classify(&long(246, [0.0; 7])), Action::Answer(result::ACCEPTED, None));
}

#[test]
fn set_home() {
    assert_eq!(
        classify(&long(179, [1.0, N, N, N, N, N, N])),
        Action::Autopilot(AutopilotCommand::SetHome(None))
    );
    let a = classify(&long(179, [0.0, N, N, N, 47.4, 8.5, 500.0]));
    assert!(matches!(a, Action::Autopilot(AutopilotCommand::SetHome(Some(p))) if p.alt_amsl_m == 500.0));
    // an invalid point goes to the autopilot, which refuses it
    assert!(matches!(
        classify(&long(179, [0.0, N, N, N, 147.4, 8.5, 500.0])),
        Action::Autopilot(AutopilotCommand::SetHome(Some(p))) if !p.is_valid()
    ));
}

#[test]
fn orbit_as_mavsdk_sends_it_and_nan_keeps() {
    // MAVSDK's do_orbit: COMMAND_INT, global frame, lat/lon in degE7
    let c = Command::from(&CommandInt {
        params: [-10.0, 2.0, 3.0, N],
        x: 473_977_420,
        y: 85_455_940,
        z: 498.0,
        command: id::DO_ORBIT,
        frame: 0,
        current: 0,
        autocontinue: 0,
        target_system: 1,
        target_component: 1,
    });
    let Action::Autopilot(AutopilotCommand::Orbit {
        radius_m,
        velocity_m_s,
        yaw,
        lat_deg,
        lon_deg,
        alt_amsl_m,
    }) = classify(&c)
    else {
        panic!("{:?}", classify(&c))
    };
    assert_eq!(
        (radius_m, velocity_m_s, yaw),
        (Some(-10.0), Some(2.0), Some(OrbitYaw::FrontTangent))
    );
    assert!((lat_deg.unwrap() - 47.397742).abs() < 1e-9 && (lon_deg.unwrap() - 8.545594).abs() < 1e-9);
    assert_eq!(alt_amsl_m, Some(498.0));
    // NaN keeps; 5 (ORBIT_YAW_BEHAVIOUR_UNCHANGED) keeps; an undefined number is PX4's default
    let keep = |p3: f32| classify(&long(id::DO_ORBIT, [N, N, p3, N, N, N, N]));
    assert_eq!(
        keep(N),
        Action::Autopilot(AutopilotCommand::Orbit {
            radius_m: None,
            velocity_m_s: None,
            yaw: None,
            lat_deg: None,
            lon_deg: None,
            alt_amsl_m: None,
        })
    );
    assert!(matches!(
        keep(5.0),
        Action::Autopilot(AutopilotCommand::Orbit { yaw: None, .. })
    ));
    assert!(matches!(
        keep(42.0),
        Action::Autopilot(AutopilotCommand::Orbit {
            yaw: Some(OrbitYaw::FrontToCentre),
            ..
        })
    ));
}
