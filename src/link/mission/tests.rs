//! Mission protocol tests through the link: datagrams in, frames and
//! effects out, the flight stack played by [`Plans::apply`] on the snapshot.

use std::net::SocketAddr;
use std::time::{Duration, Instant};

use mavlink::dialects::common::{
    MISSION_ACK_DATA, MISSION_CLEAR_ALL_DATA, MISSION_COUNT_DATA, MISSION_CURRENT_DATA, MISSION_REQUEST_DATA,
    MISSION_REQUEST_INT_DATA, MISSION_REQUEST_LIST_DATA, MISSION_SET_CURRENT_DATA, MavMessage, MavMissionResult,
    MavMissionType, MissionState as MavMissionState,
};
use proptest::prelude::*;

use super::{ItemMode, PlanOrigin, RETRY, TIMEOUT};
use crate::autopilot::{CommandOutcome, FlightMode, MissionState};
use crate::link::testing::{FakeParams, addr, link, snapshot};
use crate::link::wire::{self, Encoder, Inbound, ItemXy, MissionItemMsg};
use crate::link::{Effect, Link, Outgoing, To};
use crate::lockstep::Snapshot;
use crate::mission::{MissionType, PlanChange, Plans};

const MISSION: MavMissionType = MavMissionType::MAV_MISSION_TYPE_MISSION;

/// A client: its address and ids.
struct Client {
    addr: SocketAddr,
    enc: Encoder,
}

impl Client {
    fn new(port: u16, system: u8, component: u8) -> Self {
        Self {
            addr: addr(port),
            enc: Encoder::new(system, component),
        }
    }

    /// MAVSDK's ids.
    fn mavsdk() -> Self {
        Self::new(50_000, 245, 190)
    }

    fn msg(&mut self, m: &MavMessage) -> Vec<u8> {
        self.enc.message(m)
    }

    fn item(&mut self, m: &MissionItemMsg) -> Vec<u8> {
        self.enc.mission_item(m)
    }
}

/// A link, its clock, the vehicle's snapshot and parameters.
struct Bench {
    link: Link,
    now: Instant,
    t: Snapshot,
    params: FakeParams,
}

impl Bench {
    fn new() -> Self {
        let now = Instant::now();
        let mut link = link(now);
        let t = snapshot();
        // the streams due at boot, out of the way
        link.poll(now, &t, 0);
        link.drain();
        Self {
            link,
            now,
            t,
            params: FakeParams::standard(),
        }
    }

    fn send(&mut self, from: SocketAddr, bytes: &[u8]) -> Vec<Effect> {
        self.link.on_datagram(self.now, from, bytes, &self.t, &self.params)
    }

    fn msg(&mut self, c: &mut Client, m: &MavMessage) -> Vec<Effect> {
        let bytes = c.msg(m);
        self.send(c.addr, &bytes)
    }

    fn item(&mut self, c: &mut Client, m: &MissionItemMsg) -> Vec<Effect> {
        let bytes = c.item(m);
        self.send(c.addr, &bytes)
    }

    /// Move the clock on and run the link's timers.
    fn wait(&mut self, d: Duration) {
        self.now += d;
        self.link.poll(self.now, &self.t, 0);
    }

    /// The frames sent so far, decoded.
    fn sent(&mut self) -> Vec<(To, Inbound)> {
        decoded(&self.link.drain())
    }

    /// The flight stack applies a plan change (and publishes it), the link answers.
    fn apply(&mut self, e: Effect) {
        let Effect::Plans { ticket, change } = e else {
            panic!("not a plan change: {e:?}")
        };
        let outcome = self.t.plans.apply(change);
        self.sync_status();
        self.link.on_plans_changed(ticket, outcome);
    }

    /// MissionStatus as the autopilot fills it from the plans.
    fn sync_status(&mut self) {
        let p = &self.t.plans;
        let m = &mut self.t.telemetry.mission;
        let mission = p.get(MissionType::Mission);
        m.total = u16::try_from(mission.len()).unwrap_or(u16::MAX);
        m.state = if mission.is_empty() {
            MissionState::NoMission
        } else {
            MissionState::NotStarted
        };
        m.mission_id = mission.id();
        m.fence_id = p.get(MissionType::Fence).id();
        m.rally_id = p.get(MissionType::Rally).id();
    }
}

fn decoded(out: &[Outgoing]) -> Vec<(To, Inbound)> {
    out.iter()
        .flat_map(|o| {
            wire::frames(&o.bytes)
                .filter_map(|f| wire::decode(&f))
                .map(|m| (o.to, m))
                .collect::<Vec<_>>()
        })
        .collect()
}

/// The messages of the crate's types among `sent`, with their destinations.
fn messages(sent: &[(To, Inbound)]) -> Vec<(To, MavMessage)> {
    sent.iter()
        .filter_map(|(to, m)| match m {
            Inbound::Other(m) => Some((*to, (**m).clone())),
            _ => None,
        })
        .collect()
}

fn acks(sent: &[(To, Inbound)]) -> Vec<MISSION_ACK_DATA> {
    messages(sent)
        .into_iter()
        .filter_map(|(_, m)| match m {
            MavMessage::MISSION_ACK(a) => Some(a),
            _ => None,
        })
        .collect()
}

fn texts(sent: &[(To, Inbound)]) -> Vec<String> {
    messages(sent)
        .into_iter()
        .filter_map(|(_, m)| match m {
            MavMessage::STATUSTEXT(s) => Some(s.text.to_str().unwrap_or("").to_string()),
            _ => None,
        })
        .collect()
}

fn items(sent: &[(To, Inbound)]) -> Vec<(To, MissionItemMsg)> {
    sent.iter()
        .filter_map(|(to, m)| match m {
            Inbound::MissionItem(i) => Some((*to, *i)),
            _ => None,
        })
        .collect()
}

fn currents(sent: &[(To, Inbound)]) -> Vec<MISSION_CURRENT_DATA> {
    messages(sent)
        .into_iter()
        .filter_map(|(to, m)| match m {
            MavMessage::MISSION_CURRENT(c) => {
                assert_eq!(to, To::All);
                Some(c)
            }
            _ => None,
        })
        .collect()
}

/// A MISSION_REQUEST(_INT) the vehicle sent.
#[derive(Debug, PartialEq)]
struct Request {
    seq: u16,
    mode: ItemMode,
    mission_type: MavMissionType,
    to: To,
    target: (u8, u8),
}

/// The requests among `sent`.
fn requests(sent: &[(To, Inbound)]) -> Vec<Request> {
    messages(sent)
        .into_iter()
        .filter_map(|(to, m)| {
            let (seq, mode, mission_type, target) = match m {
                MavMessage::MISSION_REQUEST(r) => (
                    r.seq,
                    ItemMode::Float,
                    r.mission_type,
                    (r.target_system, r.target_component),
                ),
                MavMessage::MISSION_REQUEST_INT(r) => (
                    r.seq,
                    ItemMode::Int,
                    r.mission_type,
                    (r.target_system, r.target_component),
                ),
                _ => return None,
            };
            Some(Request {
                seq,
                mode,
                mission_type,
                to,
                target,
            })
        })
        .collect()
}

/// A request for `seq` in `mode` from the vehicle to `c`.
fn req(seq: u16, mode: ItemMode, c: &Client, target: (u8, u8)) -> Request {
    Request {
        seq,
        mode,
        mission_type: MISSION,
        to: To::Peer(c.addr),
        target,
    }
}

fn count(n: u16, mission_type: MavMissionType) -> MavMessage {
    MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
        count: n,
        target_system: 1,
        target_component: 1,
        mission_type,
        opaque_id: 0,
    })
}

fn client_ack(result: MavMissionResult) -> MavMessage {
    MavMessage::MISSION_ACK(MISSION_ACK_DATA {
        target_system: 1,
        target_component: 1,
        mavtype: result,
        mission_type: MISSION,
        opaque_id: 0,
    })
}

/// A MAVSDK-like waypoint, relative altitude, degE7.
fn waypoint_int(seq: u16) -> MissionItemMsg {
    MissionItemMsg {
        params: [0.0, 1.0, 0.0, f32::NAN],
        xy: ItemXy::Int {
            x: 473_977_420 + i32::from(seq) * 1000,
            y: 85_455_940 - i32::from(seq) * 777,
        },
        z: 10.0 + f32::from(seq),
        seq,
        command: 16,
        target_system: 1,
        target_component: 1,
        frame: 6,
        current: u8::from(seq == 0),
        autocontinue: 1,
        mission_type: 0,
    }
}

/// A pymavlink MAVWPLoader waypoint: floats, targets 0.
fn waypoint_float(seq: u16) -> MissionItemMsg {
    MissionItemMsg {
        params: [0.5, 2.0, 0.0, f32::NAN],
        xy: ItemXy::Float {
            x: 47.397_742 + f32::from(seq) * 1e-4,
            y: 8.545_594 - f32::from(seq) * 3e-5,
        },
        z: 12.5,
        seq,
        command: 16,
        target_system: 0,
        target_component: 0,
        frame: 3,
        current: 0,
        autocontinue: 1,
        mission_type: 0,
    }
}

/// Upload `msgs` from `c` as a well-behaved client does; the effect of the last item.
fn upload(b: &mut Bench, c: &mut Client, kind: MavMissionType, msgs: &[MissionItemMsg]) -> Effect {
    let n = u16::try_from(msgs.len()).unwrap();
    assert!(b.msg(c, &count(n, kind)).is_empty());
    let mut last = Vec::new();
    for m in msgs {
        let r = requests(&b.sent());
        assert_eq!(r.len(), 1, "one request per item");
        assert_eq!(r[0].seq, m.seq);
        last = b.item(c, m);
    }
    assert_eq!(last.len(), 1);
    last.pop().unwrap()
}

/// Payloads compared without the fields the vehicle sets itself (targets, current).
fn content(m: &MissionItemMsg) -> [u8; MissionItemMsg::LEN] {
    MissionItemMsg {
        target_system: 0,
        target_component: 0,
        current: 0,
        ..*m
    }
    .encode()
}

#[test]
fn float_mode_first_then_int_on_unsupported_and_the_mode_sticks() {
    let mut b = Bench::new();
    let mut c = Client::mavsdk();
    assert_eq!(b.link.missions().mode(), ItemMode::Float);
    assert!(b.msg(&mut c, &count(2, MISSION)).is_empty());
    let r = requests(&b.sent());
    assert_eq!(r, vec![req(0, ItemMode::Float, &c, (245, 190))]);
    // MAVSDK refuses MISSION_REQUEST: the same item again, as MISSION_REQUEST_INT
    b.msg(&mut c, &client_ack(MavMissionResult::MAV_MISSION_UNSUPPORTED));
    let sent = b.sent();
    assert!(acks(&sent).is_empty());
    assert_eq!(requests(&sent), vec![req(0, ItemMode::Int, &c, (245, 190))]);
    assert_eq!(b.link.missions().mode(), ItemMode::Int);
    b.item(&mut c, &waypoint_int(0));
    assert_eq!(requests(&b.sent())[0].mode, ItemMode::Int);
    let e = b.item(&mut c, &waypoint_int(1));
    assert!(b.sent().is_empty(), "nothing before the flight stack answers");
    b.apply(e.into_iter().next().unwrap());
    // the next upload on this link starts in int mode
    b.msg(&mut c, &count(1, MISSION));
    let sent = b.sent();
    assert_eq!(acks(&sent).len(), 1);
    assert_eq!(requests(&sent)[0].mode, ItemMode::Int);
}

#[test]
fn a_mission_item_sets_float_mode() {
    let mut b = Bench::new();
    let mut c = Client::new(50_001, 255, 0);
    b.msg(&mut c, &count(3, MISSION));
    b.msg(&mut c, &client_ack(MavMissionResult::MAV_MISSION_UNSUPPORTED));
    assert_eq!(requests(&b.sent()).last().unwrap().mode, ItemMode::Int);
    b.item(&mut c, &waypoint_float(0));
    assert_eq!(b.link.missions().mode(), ItemMode::Float);
    assert_eq!(requests(&b.sent()), vec![req(1, ItemMode::Float, &c, (255, 0))]);
    // and MISSION_ITEM_INT int mode again
    b.item(&mut c, &waypoint_int(1));
    assert_eq!(requests(&b.sent())[0].mode, ItemMode::Int);
}

#[test]
fn accepted_only_after_the_stored_plan_and_again_for_a_repeated_last_item() {
    let mut b = Bench::new();
    let mut c = Client::mavsdk();
    let msgs: Vec<_> = (0..4).map(waypoint_int).collect();
    b.msg(&mut c, &count(4, MISSION));
    let mut effect = Vec::new();
    for m in &msgs {
        assert!(acks(&b.sent()).is_empty(), "no ACK during the upload");
        effect = b.item(&mut c, m);
    }
    assert!(acks(&b.sent()).is_empty());
    let [Effect::Plans { ticket, change }] = effect.as_slice() else {
        panic!("{effect:?}")
    };
    let PlanChange::Store { kind, items, base_id } = change else {
        panic!("{change:?}")
    };
    assert_eq!((*kind, items.len(), *base_id), (MissionType::Mission, 4, Some(0)));
    assert!(matches!(ticket.origin, PlanOrigin::Upload { last_seq: 3, .. }));
    assert!(b.link.missions().busy());
    b.apply(effect.pop().unwrap());
    assert!(!b.link.missions().busy());
    let id = b.t.plans.get(MissionType::Mission).id();
    assert_ne!(id, 0);
    let sent = b.sent();
    let a = acks(&sent);
    assert_eq!(a.len(), 1);
    assert_eq!(
        (
            a[0].mavtype,
            a[0].mission_type,
            a[0].opaque_id,
            a[0].target_system,
            a[0].target_component
        ),
        (MavMissionResult::MAV_MISSION_ACCEPTED, MISSION, id, 245, 190)
    );
    assert!(texts(&sent).is_empty());
    // the ACK was lost: the last item again gets it again, and changes nothing
    assert!(b.item(&mut c, &msgs[3]).is_empty());
    let a = acks(&b.sent());
    assert_eq!(
        (a.len(), a[0].mavtype, a[0].opaque_id),
        (1, MavMissionResult::MAV_MISSION_ACCEPTED, id)
    );
    // an earlier item, or another client's, gets nothing
    b.item(&mut c, &msgs[2]);
    b.item(&mut Client::new(50_002, 245, 190), &msgs[3]);
    assert!(b.sent().is_empty());
    // nor, once a new upload began, the old last item
    b.msg(&mut c, &count(4, MISSION));
    b.sent();
    b.msg(&mut c, &client_ack(MavMissionResult::MAV_MISSION_OPERATION_CANCELLED));
    b.sent();
    b.item(&mut c, &msgs[3]);
    assert!(acks(&b.sent()).is_empty());
}

#[test]
fn the_later_of_two_uploads_over_two_links_is_denied() {
    let mut b = Bench::new();
    let mut other = link(b.now);
    let (mut c1, mut c2) = (Client::mavsdk(), Client::new(50_010, 255, 190));
    let e1 = upload(&mut b, &mut c1, MISSION, &[waypoint_int(0)]);
    // the second upload begins on the other link before the first is stored
    let n = c2.msg(&count(1, MISSION));
    other.on_datagram(b.now, c2.addr, &n, &b.t, &b.params);
    b.apply(e1);
    other.drain();
    let it = c2.item(&waypoint_float(0));
    let e2 = other.on_datagram(b.now, c2.addr, &it, &b.t, &b.params);
    let [Effect::Plans { ticket, change }] = e2.as_slice() else {
        panic!("{e2:?}")
    };
    let outcome = b.t.plans.apply(change.clone());
    other.on_plans_changed(*ticket, outcome);
    let sent = decoded(&other.drain());
    assert_eq!(acks(&sent)[0].mavtype, MavMissionResult::MAV_MISSION_DENIED);
    assert_eq!(texts(&sent), vec!["Mission upload refused: changed by another client"]);
    // the first plan stays
    assert_eq!(b.t.plans.get(MissionType::Mission).items()[0].frame, 6);
}

#[test]
fn request_again_after_250_ms_and_drop_after_5_s() {
    let mut b = Bench::new();
    let mut c = Client::mavsdk();
    b.msg(&mut c, &count(2, MISSION));
    b.sent();
    assert_eq!(b.link.next_deadline().map(|d| d <= b.now + RETRY), Some(true));
    b.wait(RETRY - Duration::from_millis(10));
    assert!(requests(&b.sent()).is_empty());
    b.wait(Duration::from_millis(20));
    assert_eq!(requests(&b.sent()).iter().map(|r| r.seq).collect::<Vec<_>>(), vec![0]);
    b.item(&mut c, &waypoint_int(0));
    b.sent();
    // silence: the request for item 1 every 250 ms, then the transfer is dropped
    let mut asked = 0;
    let mut dropped = Vec::new();
    for _ in 0..110 {
        b.wait(Duration::from_millis(50));
        let sent = b.sent();
        asked += requests(&sent).len();
        dropped.extend(texts(&sent));
        assert!(acks(&sent).is_empty(), "PX4 sends no ACK on a timeout");
    }
    assert!((18..=20).contains(&asked), "{asked} requests in 5 s");
    assert_eq!(dropped, vec!["Mission upload timed out"]);
    assert!(!b.link.missions().busy());
    // a late item is ignored, the plan unchanged
    assert!(b.item(&mut c, &waypoint_int(1)).is_empty());
    assert!(b.sent().is_empty());
    assert!(b.t.plans.get(MissionType::Mission).is_empty());
}

#[test]
fn a_second_uploader_is_refused_busy_while_the_first_goes_on() {
    let mut b = Bench::new();
    let (mut first, mut second) = (Client::mavsdk(), Client::new(50_003, 255, 0));
    b.msg(&mut first, &count(2, MISSION));
    b.item(&mut first, &waypoint_int(0));
    b.sent();
    assert!(b.msg(&mut second, &count(5, MISSION)).is_empty());
    let sent = b.sent();
    let a = acks(&sent);
    assert_eq!(a.len(), 1);
    assert_eq!(
        (a[0].mavtype, a[0].target_system),
        (MavMissionResult::MAV_MISSION_ERROR, 255)
    );
    assert_eq!(texts(&sent), vec!["Mission upload busy"]);
    assert!(sent.iter().all(|(to, _)| *to == To::Peer(second.addr)));
    // the same ids from another port are another client
    let mut moved = Client::new(50_004, 245, 190);
    b.msg(&mut moved, &count(1, MISSION));
    assert_eq!(acks(&b.sent())[0].mavtype, MavMissionResult::MAV_MISSION_ERROR);
    // the first upload is undisturbed
    let e = b.item(&mut first, &waypoint_int(1));
    assert!(matches!(e.as_slice(), [Effect::Plans { .. }]));
}

#[test]
fn the_uploader_counting_again_restarts() {
    let mut b = Bench::new();
    let mut c = Client::mavsdk();
    b.msg(&mut c, &count(3, MISSION));
    b.item(&mut c, &waypoint_int(0));
    b.item(&mut c, &waypoint_int(1));
    b.sent();
    b.msg(&mut c, &count(2, MISSION));
    assert_eq!(requests(&b.sent())[0].seq, 0);
    b.item(&mut c, &waypoint_int(0));
    let e = b.item(&mut c, &waypoint_int(1));
    b.apply(e.into_iter().next().unwrap());
    assert_eq!(b.t.plans.get(MissionType::Mission).len(), 2);
}

#[test]
fn out_of_sequence_items_are_ignored_and_an_error_ack_abandons() {
    let mut b = Bench::new();
    let mut c = Client::mavsdk();
    b.msg(&mut c, &count(3, MISSION));
    b.item(&mut c, &waypoint_int(0));
    b.sent();
    for seq in [0, 2, 7] {
        assert!(b.item(&mut c, &waypoint_int(seq)).is_empty());
    }
    assert!(b.sent().is_empty());
    b.msg(&mut c, &client_ack(MavMissionResult::MAV_MISSION_OPERATION_CANCELLED));
    assert!(!b.link.missions().busy());
    let sent = b.sent();
    assert!(acks(&sent).is_empty());
    assert_eq!(texts(&sent).len(), 1);
    assert!(b.item(&mut c, &waypoint_int(1)).is_empty());
    assert!(b.sent().is_empty());
}

#[test]
fn an_invalid_latitude_is_refused_with_param5_and_nothing_stored() {
    let mut b = Bench::new();
    let mut c = Client::mavsdk();
    b.msg(&mut c, &count(2, MISSION));
    b.item(&mut c, &waypoint_int(0));
    b.sent();
    let bad = MissionItemMsg {
        xy: ItemXy::Int {
            x: 950_000_000,
            y: 85_455_940,
        },
        ..waypoint_int(1)
    };
    assert!(b.item(&mut c, &bad).is_empty(), "no plan change");
    let sent = b.sent();
    let a = acks(&sent);
    assert_eq!(
        (a.len(), a[0].mavtype),
        (1, MavMissionResult::MAV_MISSION_INVALID_PARAM5_X)
    );
    assert_eq!(texts(&sent), vec!["Mission item 1 refused: invalid latitude / x"]);
    assert!(!b.link.missions().busy());
    // an unknown command (the crate could not even decode it) is UNSUPPORTED
    b.msg(&mut c, &count(1, MISSION));
    b.sent();
    b.item(
        &mut c,
        &MissionItemMsg {
            command: 31_337,
            ..waypoint_int(0)
        },
    );
    assert_eq!(acks(&b.sent())[0].mavtype, MavMissionResult::MAV_MISSION_UNSUPPORTED);
}

#[test]
fn too_many_items_no_space_and_count_zero_clears() {
    let mut b = Bench::new();
    let mut c = Client::mavsdk();
    assert!(b.msg(&mut c, &count(20_001, MISSION)).is_empty());
    let sent = b.sent();
    assert_eq!(acks(&sent)[0].mavtype, MavMissionResult::MAV_MISSION_NO_SPACE);
    assert!(requests(&sent).is_empty());
    assert!(!b.link.missions().busy());
    // a rally point, then MISSION_COUNT 0 of type rally: PX4 clears
    let rally = MissionItemMsg {
        command: 5100,
        frame: 3,
        mission_type: 2,
        ..waypoint_int(0)
    };
    let e = upload(&mut b, &mut c, MavMissionType::MAV_MISSION_TYPE_RALLY, &[rally]);
    b.apply(e);
    b.sent();
    assert_eq!(b.t.plans.get(MissionType::Rally).len(), 1);
    let mut e = b.msg(&mut c, &count(0, MavMissionType::MAV_MISSION_TYPE_RALLY));
    assert!(matches!(
        e.as_slice(),
        [Effect::Plans {
            change: PlanChange::Clear(Some(MissionType::Rally)),
            ..
        }]
    ));
    b.apply(e.pop().unwrap());
    let a = acks(&b.sent());
    assert_eq!(
        (a[0].mavtype, a[0].mission_type, a[0].opaque_id),
        (
            MavMissionResult::MAV_MISSION_ACCEPTED,
            MavMissionType::MAV_MISSION_TYPE_RALLY,
            0
        )
    );
    assert!(b.t.plans.get(MissionType::Rally).is_empty());
    // ALL is no type to upload
    b.msg(&mut c, &count(2, MavMissionType::MAV_MISSION_TYPE_ALL));
    assert_eq!(acks(&b.sent())[0].mavtype, MavMissionResult::MAV_MISSION_UNSUPPORTED);
}

#[test]
fn an_item_of_another_type_ends_the_upload() {
    let mut b = Bench::new();
    let mut c = Client::mavsdk();
    b.msg(&mut c, &count(2, MavMissionType::MAV_MISSION_TYPE_FENCE));
    assert_eq!(
        requests(&b.sent())[0].mission_type,
        MavMissionType::MAV_MISSION_TYPE_FENCE
    );
    assert!(b.item(&mut c, &waypoint_int(0)).is_empty());
    let a = acks(&b.sent());
    assert_eq!(
        (a[0].mavtype, a[0].mission_type),
        (
            MavMissionResult::MAV_MISSION_ERROR,
            MavMissionType::MAV_MISSION_TYPE_FENCE
        )
    );
    assert!(!b.link.missions().busy());
}

fn request_int(seq: u16, mission_type: MavMissionType) -> MavMessage {
    MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
        seq,
        target_system: 1,
        target_component: 0,
        mission_type,
    })
}

fn request_float(seq: u16) -> MavMessage {
    MavMessage::MISSION_REQUEST(MISSION_REQUEST_DATA {
        seq,
        target_system: 1,
        target_component: 0,
        mission_type: MISSION,
    })
}

fn request_list(mission_type: MavMissionType) -> MavMessage {
    MavMessage::MISSION_REQUEST_LIST(MISSION_REQUEST_LIST_DATA {
        target_system: 1,
        target_component: 0,
        mission_type,
    })
}

#[test]
fn float_upload_downloads_float_bit_for_bit() {
    let mut b = Bench::new();
    let mut c = Client::new(50_005, 255, 0);
    let up: Vec<_> = (0..3)
        .map(|s| MissionItemMsg {
            current: u8::from(s == 0),
            ..waypoint_float(s)
        })
        .collect();
    let e = upload(&mut b, &mut c, MISSION, &up);
    b.apply(e);
    b.sent();
    for m in &up {
        b.msg(&mut c, &request_float(m.seq));
        let got = items(&b.sent());
        assert_eq!(got.len(), 1);
        let (to, down) = got[0];
        assert_eq!(to, To::Peer(c.addr));
        assert_eq!(down.message_id(), 39);
        assert_eq!(content(&down), content(m), "seq {}", m.seq);
        assert_eq!((down.target_system, down.target_component), (255, 0));
        assert_eq!(down.current, u8::from(m.seq == 0), "seq 0 is the current item");
    }
}

#[test]
fn int_upload_downloads_int_identically_and_mission_item_current_follows_the_vehicle() {
    let mut b = Bench::new();
    let mut c = Client::mavsdk();
    let mut up: Vec<_> = (0..3).map(waypoint_int).collect();
    // an item without a position: x, y are plain numbers
    up.push(MissionItemMsg {
        params: [1.0, 7.5, -1.0, 0.0],
        xy: ItemXy::Int { x: 0, y: 0 },
        z: f32::NAN,
        command: 178,
        frame: 2,
        ..waypoint_int(3)
    });
    let e = upload(&mut b, &mut c, MISSION, &up);
    b.apply(e);
    b.sent();
    b.t.telemetry.mission.seq = 2;
    for m in &up {
        b.msg(&mut c, &request_int(m.seq, MISSION));
        let (_, down) = items(&b.sent())[0];
        assert_eq!(down.message_id(), 73);
        assert_eq!(content(&down), content(m), "seq {}", m.seq);
        assert_eq!(down.current, u8::from(m.seq == 2));
    }
    // and the float form of an int upload is the nearest float
    b.msg(&mut c, &request_float(1));
    let (_, down) = items(&b.sent())[0];
    let ItemXy::Float { x, .. } = down.xy else { panic!() };
    assert_eq!(x, (473_978_420.0_f64 / 1e7) as f32);
}

#[test]
fn pipelined_download_with_repeats_and_the_end() {
    let mut b = Bench::new();
    let mut c = Client::new(50_006, 255, 230);
    let up: Vec<_> = (0..7).map(waypoint_int).collect();
    let e = upload(&mut b, &mut c, MISSION, &up);
    b.apply(e);
    b.sent();
    b.msg(&mut c, &request_list(MISSION));
    let m = messages(&b.sent());
    let MavMessage::MISSION_COUNT(n) = &m[0].1 else {
        panic!("{m:?}")
    };
    assert_eq!(
        (
            n.count,
            n.mission_type,
            n.opaque_id,
            n.target_system,
            n.target_component
        ),
        (7, MISSION, b.t.plans.get(MissionType::Mission).id(), 255, 230)
    );
    // MAVProxy: five requests in flight, then the rest, one asked again
    let mut dgram = Vec::new();
    for s in 0..5 {
        dgram.extend(c.msg(&request_int(s, MISSION)));
    }
    b.send(c.addr, &dgram);
    assert_eq!(
        items(&b.sent()).iter().map(|(_, i)| i.seq).collect::<Vec<_>>(),
        vec![0, 1, 2, 3, 4]
    );
    for s in [5, 3, 6] {
        b.msg(&mut c, &request_int(s, MISSION));
    }
    assert_eq!(
        items(&b.sent()).iter().map(|(_, i)| i.seq).collect::<Vec<_>>(),
        vec![5, 3, 6]
    );
    b.msg(&mut c, &request_int(7, MISSION));
    let a = acks(&b.sent());
    assert_eq!(a[0].mavtype, MavMissionResult::MAV_MISSION_INVALID_SEQUENCE);
    // the client's closing ACK needs nothing
    b.msg(&mut c, &client_ack(MavMissionResult::MAV_MISSION_ACCEPTED));
    assert!(b.sent().is_empty());
    // an empty type: count 0; ALL: count 0 as in PX4
    for t in [
        MavMissionType::MAV_MISSION_TYPE_FENCE,
        MavMissionType::MAV_MISSION_TYPE_ALL,
    ] {
        b.msg(&mut c, &request_list(t));
        let m = messages(&b.sent());
        assert!(matches!(&m[0].1, MavMessage::MISSION_COUNT(n) if n.count == 0 && n.mission_type == t));
    }
}

#[test]
fn clear_all_types_and_acked_with_255() {
    let mut b = Bench::new();
    let mut c = Client::mavsdk();
    let e = upload(&mut b, &mut c, MISSION, &[waypoint_int(0)]);
    b.apply(e);
    b.sent();
    let clear = MavMessage::MISSION_CLEAR_ALL(MISSION_CLEAR_ALL_DATA {
        target_system: 1,
        target_component: 0,
        mission_type: MavMissionType::MAV_MISSION_TYPE_ALL,
    });
    let mut e = b.msg(&mut c, &clear);
    assert!(matches!(
        e.as_slice(),
        [Effect::Plans {
            change: PlanChange::Clear(None),
            ..
        }]
    ));
    assert!(b.sent().is_empty(), "the ACK waits for the flight stack");
    b.apply(e.pop().unwrap());
    let a = acks(&b.sent());
    assert_eq!(
        (a[0].mavtype, a[0].mission_type),
        (
            MavMissionResult::MAV_MISSION_ACCEPTED,
            MavMissionType::MAV_MISSION_TYPE_ALL
        )
    );
    assert_eq!(b.t.plans, Plans::default());
    // ignored while an upload runs on the link (PX4)
    b.msg(&mut c, &count(2, MISSION));
    b.sent();
    // (a client that heartbeats, as every GCS does: an unproven one gets
    // three times the bytes it sent, too few for this text)
    let mut other = Client::new(50_007, 255, 0);
    b.msg(&mut other, &MavMessage::HEARTBEAT(Default::default()));
    assert!(b.msg(&mut other, &clear).is_empty());
    let sent = b.sent();
    assert!(acks(&sent).is_empty());
    assert_eq!(texts(&sent), vec!["Clear ignored: upload in progress"]);
}

fn set_current(seq: u16) -> MavMessage {
    MavMessage::MISSION_SET_CURRENT(MISSION_SET_CURRENT_DATA {
        seq,
        target_system: 1,
        target_component: 1,
    })
}

#[test]
fn set_current_is_answered_with_mission_current_of_that_seq() {
    let mut b = Bench::new();
    let mut c = Client::mavsdk();
    let e = upload(
        &mut b,
        &mut c,
        MISSION,
        &[waypoint_int(0), waypoint_int(1), waypoint_int(2)],
    );
    b.apply(e);
    b.wait(Duration::from_millis(1));
    b.sent();
    let e = b.msg(&mut c, &set_current(2));
    assert_eq!(e, vec![Effect::SetMissionCurrent { seq: 2 }]);
    // the autopilot took it (its snapshot may lag one step): MISSION_CURRENT 2 at once
    b.link.on_mission_current_set(2, &CommandOutcome::Accepted, &b.t);
    let cur = currents(&b.sent());
    assert_eq!(cur.len(), 1);
    assert_eq!((cur[0].seq, cur[0].total), (2, 3));
    // a refusal the autopilot announces itself
    b.link.on_mission_current_set(1, &CommandOutcome::Denied("no"), &b.t);
    assert!(b.sent().is_empty());
    // past the end, or while an upload runs: ignored with a text (PX4)
    assert!(b.msg(&mut c, &set_current(3)).is_empty());
    assert_eq!(texts(&b.sent()).len(), 1);
    b.msg(&mut c, &count(1, MISSION));
    b.sent();
    assert!(b.msg(&mut c, &set_current(0)).is_empty());
    assert_eq!(texts(&b.sent()), vec!["Set current ignored: upload in progress"]);
}

#[test]
fn mission_current_at_1_hz_and_at_once_on_change() {
    let now = Instant::now();
    let mut l = link(now);
    let mut t = snapshot();
    l.poll(now, &t, 0);
    let cur = currents(&decoded(&l.drain()));
    assert_eq!(cur.len(), 1, "the stream's, not a second for the change");
    assert_eq!(
        (cur[0].seq, cur[0].total, cur[0].mission_state, cur[0].mission_mode),
        (0, u16::MAX, MavMissionState::MISSION_STATE_NO_MISSION, 2)
    );
    let mut sent_at = Vec::new();
    for i in 1..=250 {
        let at = now + Duration::from_millis(10 * i);
        if i == 130 {
            t.telemetry.mission = crate::autopilot::MissionStatus {
                seq: 4,
                total: 9,
                state: MissionState::Active,
                mission_id: 7,
                fence_id: 8,
                rally_id: 9,
            };
            t.telemetry.mode = FlightMode::Mission;
        }
        l.poll(at, &t, 0);
        for c in currents(&decoded(&l.drain())) {
            sent_at.push((i, c));
        }
    }
    let times: Vec<_> = sent_at.iter().map(|(i, _)| *i).collect();
    assert_eq!(times, vec![100, 130, 200], "1 Hz, and at once on the change");
    let c = &sent_at[1].1;
    assert_eq!(
        (
            c.seq,
            c.total,
            c.mission_state,
            c.mission_mode,
            c.mission_id,
            c.fence_id,
            c.rally_points_id
        ),
        (4, 9, MavMissionState::MISSION_STATE_ACTIVE, 1, 7, 8, 9)
    );
    // SET_MESSAGE_INTERVAL and REQUEST_MESSAGE know it as message 42
    assert_eq!(
        crate::link::streams::Stream::from_message_id(42),
        Some(crate::link::streams::Stream::MissionCurrent)
    );
}

#[test]
fn item_reached_at_once_then_ten_repeats_a_second_apart() {
    let mut b = Bench::new();
    b.t.telemetry.mission.total = 5;
    b.link.on_mission_item_reached(b.now, 3);
    let reached = |sent: &[(To, Inbound)]| {
        messages(sent)
            .into_iter()
            .filter_map(|(to, m)| match m {
                MavMessage::MISSION_ITEM_REACHED(r) => Some((to, r.seq)),
                _ => None,
            })
            .collect::<Vec<_>>()
    };
    assert_eq!(reached(&b.sent()), vec![(To::All, 3)]);
    let mut repeats = 0;
    for _ in 0..150 {
        let before = b.now;
        b.wait(Duration::from_millis(100));
        let r = reached(&b.sent());
        if !r.is_empty() {
            assert_eq!(r, vec![(To::All, 3)]);
            assert!(b.now.duration_since(before) <= Duration::from_millis(100));
            repeats += 1;
        }
    }
    assert_eq!(repeats, 10);
    assert_eq!(b.link.missions().next_deadline(), None);
}

#[test]
fn mission_messages_for_the_mission_planner_or_another_vehicle() {
    let mut b = Bench::new();
    let mut c = Client::mavsdk();
    let to = |system, component| {
        MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
            count: 1,
            target_system: system,
            target_component: component,
            mission_type: MISSION,
            opaque_id: 0,
        })
    };
    b.msg(&mut c, &to(2, 1));
    assert!(b.sent().is_empty());
    b.msg(&mut c, &to(1, 190));
    assert_eq!(requests(&b.sent()).len(), 1);
    // an item for another vehicle is not this upload's
    let other = MissionItemMsg {
        target_system: 2,
        ..waypoint_int(0)
    };
    assert!(b.item(&mut c, &other).is_empty());
    assert!(b.link.missions().busy());
    let mine = MissionItemMsg {
        target_system: 1,
        target_component: 190,
        ..waypoint_int(0)
    };
    assert_eq!(b.item(&mut c, &mine).len(), 1);
}

#[test]
fn a_plan_change_never_answered_frees_the_link() {
    let mut b = Bench::new();
    let mut c = Client::mavsdk();
    let _lost = upload(&mut b, &mut c, MISSION, &[waypoint_int(0)]);
    assert!(b.link.missions().busy());
    b.wait(TIMEOUT + Duration::from_millis(1));
    assert!(!b.link.missions().busy());
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    /// Any payload of any mission message, in any state: no panic.
    #[test]
    fn hostile_mission_frames_do_not_panic(
        frames in proptest::collection::vec(
            (prop::sample::select(vec![39u32, 73, 44, 47, 40, 51, 43, 45, 41]), proptest::collection::vec(any::<u8>(), 0..40)),
            1..30,
        ),
    ) {
        let mut b = Bench::new();
        let mut c = Client::mavsdk();
        b.msg(&mut c, &count(3, MISSION));
        for (id, payload) in frames {
            let bytes = c.enc.raw(id, &payload);
            for e in b.send(c.addr, &bytes) {
                if matches!(e, Effect::Plans { .. }) {
                    b.apply(e);
                }
            }
            b.wait(Duration::from_millis(100));
            b.sent();
        }
    }
}
