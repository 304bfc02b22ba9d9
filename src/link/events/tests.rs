use super::*;

fn report(checks: &[(&'static str, HealthComponent, ModeSet)], can_arm: ModeSet) -> HealthReport {
    HealthReport {
        checks: checks
            .iter()
            .map(|(text, component, modes)| crate::autopilot::FailedCheck {
                text,
                component: *component,
                modes: *modes,
            })
            .collect(),
        can_arm,
        can_run: can_arm,
    }
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(b[at..at + 4].try_into().unwrap())
}

#[test]
fn event_ids_are_px4s_fnv1a_of_the_name_with_the_autopilot_component() {
    // FNV-1a 32 test vectors: "a" 0xe40c292c, "foobar" 0xbf9cf968
    assert_eq!(event_id("a"), 0x010c_292c);
    assert_eq!(event_id("foobar"), 0x019c_f968);
}

#[test]
fn a_report_is_the_arming_summary_each_check_and_the_health_summary() {
    let hold_mission = ModeSet::of(FlightMode::Hold).with(FlightMode::Mission);
    let r = report(
        &[
            ("ESC failure", HealthComponent::MotorsEscs, ModeSet::ALL),
            (
                "no valid mission",
                HealthComponent::Mission,
                ModeSet::of(FlightMode::Mission),
            ),
        ],
        ModeSet::default(),
    );
    let e = health_events(&r);
    assert_eq!(e.len(), 4);
    assert_eq!(e[0].id, event_id("commander_arming_check_summary"));
    assert_eq!(e[0].log_levels, 0x88);
    assert_eq!(e[0].arguments[0], 0, "chunk 0");
    assert_eq!(
        u32_at(&e[0].arguments, 1),
        256 | 262_144,
        "arming errors: motors_escs, mission"
    );
    assert_eq!(u32_at(&e[0].arguments, 13), 0, "can run nothing");
    assert_eq!(e[1].id, event_id("check_esc_failure"));
    assert_eq!(e[1].log_levels, 0x33);
    assert_eq!(u32_at(&e[1].arguments, 0), group_mask(ModeSet::ALL));
    assert_eq!(e[1].arguments[4], 8, "motors_escs is bit 8");
    assert_eq!(e[2].id, event_id("check_no_valid_mission"));
    assert_eq!(u32_at(&e[2].arguments, 0), 1 << 3, "Mission is navigation state 3");
    assert_eq!(e[3].id, event_id("commander_health_summary"));
    assert_eq!(
        u32_at(&e[3].arguments, 5),
        256,
        "health error: the motors, not the mission"
    );
    assert!(u32_at(&e[3].arguments, 1) & 256 != 0, "the motors are present");
    assert_eq!(group_mask(hold_mission), 1 << 4 | 1 << 3);
}

#[test]
fn reports_go_out_when_forced_or_changed_at_most_every_two_seconds() {
    let ready = report(&[], ModeSet::ALL);
    let failed = report(
        &[("ESC failure", HealthComponent::MotorsEscs, ModeSet::ALL)],
        ModeSet::default(),
    );
    let mut r = Reporter::default();
    assert!(r.due(0.0));
    let first = r.update(0.0, ready.clone(), false);
    assert_eq!(first.iter().map(|e| e.sequence).collect::<Vec<_>>(), [0, 1]);
    assert!(!r.due(0.05) && r.due(0.1));
    assert!(r.update(0.1, ready.clone(), false).is_empty(), "unchanged");
    assert!(
        r.update(1.0, failed.clone(), false).is_empty(),
        "changed, but 1 s after the last"
    );
    let changed = r.update(2.0, failed.clone(), false);
    assert_eq!(changed.iter().map(|e| e.sequence).collect::<Vec<_>>(), [2, 3, 4]);
    assert_eq!(changed[0].event_time_boot_ms, 2000);
    let forced = r.update(2.1, failed, true);
    assert_eq!(forced.len(), 3, "forced: sent again at once");
    assert_eq!(forced[0].sequence, 5);
}

#[test]
fn a_link_answers_requests_from_its_log_and_says_the_current_sequence() {
    let now = Instant::now();
    let mut log = EventLog::new(now);
    let Some(MavMessage::CURRENT_EVENT_SEQUENCE(c)) = log.current_sequence(now) else {
        panic!("due at once")
    };
    assert_eq!((c.sequence, c.flags.bits()), (u16::MAX, 1), "none yet: reset");
    assert!(log.current_sequence(now + Duration::from_secs(1)).is_none());
    let mut r = Reporter::default();
    for e in r.update(0.0, report(&[], ModeSet::ALL), true) {
        log.keep(&e);
    }
    let Some(MavMessage::CURRENT_EVENT_SEQUENCE(c)) = log.current_sequence(now + CURRENT_SEQUENCE_PERIOD) else {
        panic!("due again after 3 s")
    };
    assert_eq!((c.sequence, c.flags.bits()), (1, 0));
    let again = log.request(1, 1, (255, 190));
    assert!(matches!(&again[..], [MavMessage::EVENT(e)] if e.sequence == 1));
    let gone = log.request(7, 7, (255, 190));
    let [MavMessage::RESPONSE_EVENT_ERROR(err)] = &gone[..] else {
        panic!("{gone:?}")
    };
    assert_eq!((err.sequence, err.target_system, err.target_component), (7, 255, 190));
    assert_eq!(
        err.sequence_oldest_available, 0,
        "the next kept after 7 (wrapping) is 0"
    );
    let many = log.request(0, 999, (255, 190));
    assert_eq!(
        many.len(),
        LOG_CAPACITY + 1,
        "one error for the part the log cannot hold"
    );
}

#[test]
fn a_log_keeps_the_last_twenty() {
    // 11 reports of 2 events: 0 and 1 are gone, 2..=21 kept
    let mut log = EventLog::new(Instant::now());
    let mut r = Reporter::default();
    for i in 0..11 {
        for e in r.update(f64::from(i), report(&[], ModeSet::ALL), true) {
            log.keep(&e);
        }
    }
    assert!(matches!(
        &log.request(0, 0, (1, 1))[..],
        [MavMessage::RESPONSE_EVENT_ERROR(_)]
    ));
    assert!(matches!(&log.request(21, 21, (1, 1))[..], [MavMessage::EVENT(_)]));
}

#[test]
fn the_metadata_decodes_every_event_a_report_sends() {
    let meta: Value = serde_json::from_slice(events_json()).unwrap();
    let px4 = &meta["components"]["1"];
    assert_eq!(px4["namespace"], "px4");
    assert_eq!(px4["supported_protocols"][0], "health_and_arming_check");
    let mission = convert::custom_mode(FlightMode::Mission);
    assert_eq!(px4["navigation_mode_groups"]["groups"]["3"][0], mission);
    let arming = &px4["event_groups"]["arming_check"]["events"];
    for text in CHECK_TEXTS {
        let sub = (event_id(&check_name(text)) & 0xFF_FFFF).to_string();
        assert_eq!(arming[&sub]["message"], check_message(text), "{text}");
    }
    let summary = (event_id("commander_arming_check_summary") & 0xFF_FFFF).to_string();
    assert_eq!(arming[&summary]["type"], "summary");
    assert_eq!(
        px4["enums"]["health_component_t"]["entries"]["256"]["name"],
        "motors_escs"
    );
    let general: Value = serde_json::from_slice(general_json()).unwrap();
    assert_eq!(general["version"], 1);
    assert_eq!(general["metadataTypes"][0]["type"], 4);
    assert_eq!(general["metadataTypes"][0]["uri"], "mftp://etc/extras/all_events.json");
    assert_eq!(general["metadataTypes"][0]["fileCrc"], crc(events_json()));
    assert_eq!(metadata_file("/etc/extras/all_events.json"), Some(events_json()));
    assert_eq!(metadata_file("etc/extras/component_general.json"), Some(general_json()));
    assert_eq!(metadata_file("etc/extras/other.json"), None);
}

#[test]
fn a_failsafe_is_an_event_in_the_words_of_its_status_text() {
    let e = failsafe_event("battery critical", "Land");
    assert_eq!(e.id, event_id("commander_failsafe_activated"));
    assert_eq!(e.log_levels, 0x22, "critical");
    let cause = usize::from(e.arguments[0]);
    let action = usize::from(e.arguments[1]);
    assert_eq!(
        (FAILSAFE_CAUSES[cause - 1], FAILSAFE_ACTIONS[action - 1]),
        ("battery critical", "Land")
    );
    assert_eq!(failsafe_event("a cause nobody listed", "Land").arguments[0], 0, "other");
    let meta: Value = serde_json::from_slice(events_json()).unwrap();
    let px4 = &meta["components"]["1"];
    let sub = (event_id("commander_failsafe_activated") & 0xFF_FFFF).to_string();
    assert_eq!(
        px4["event_groups"]["default"]["events"][&sub]["message"],
        "Failsafe: {1}, triggering {2}"
    );
    let causes = &px4["enums"]["failsafe_cause_t"]["entries"];
    assert_eq!(causes[cause.to_string()]["description"], "battery critical");
    assert_eq!(
        px4["enums"]["failsafe_action_t"]["entries"][action.to_string()]["description"],
        "Land"
    );
}

#[test]
fn a_failsafe_is_said_once_for_each_cause_and_action() {
    let mut r = Reporter::default();
    assert!(r.failsafe(0.0, None).is_none(), "none in force");
    let first = r
        .failsafe(1.0, Some(("battery critical", "Return")))
        .expect("a new failsafe");
    assert_eq!((first.sequence, first.event_time_boot_ms), (0, 1000));
    assert!(
        r.failsafe(1.1, Some(("battery critical", "Return"))).is_none(),
        "said already"
    );
    let again = r
        .failsafe(2.0, Some(("battery critical", "Descend")))
        .expect("a new action for it");
    assert_eq!(again.arguments, failsafe_event("battery critical", "Descend").arguments);
    assert!(r.failsafe(3.0, None).is_none(), "an ended failsafe says nothing");
    assert_eq!(
        r.failsafe(4.0, Some(("battery critical", "Descend")))
            .map(|e| e.sequence),
        Some(2),
        "a new one"
    );
}
