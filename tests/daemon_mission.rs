//! The mission protocol through the daemon on loopback: an upload stored
//! by the flight stack and acknowledged with its id, the download of it,
//! MISSION_CURRENT reporting it, the clear, and two uploads over two links
//! of which the later finisher is refused. Every test starts its own vehicle.
#![allow(deprecated)]

mod common;

use std::net::SocketAddr;
use std::time::Duration;

use common::daemon::{Client, Vehicle, config};
use mavlink::dialects::common::*;
use rotorpilot::link::wire::MissionItemMsg;

const S3: Duration = Duration::from_secs(3);
const MISSION: MavMissionType = MavMissionType::MAV_MISSION_TYPE_MISSION;

/// MAVSDK's waypoint `seq`: relative altitude, degE7.
fn waypoint(seq: u16) -> MavMessage {
    MavMessage::MISSION_ITEM_INT(MISSION_ITEM_INT_DATA {
        param1: 0.0,
        param2: 1.0,
        param3: 0.0,
        param4: f32::NAN,
        x: 473_977_420 + i32::from(seq) * 1000,
        y: 85_455_940,
        z: 10.0,
        seq,
        command: MavCmd::MAV_CMD_NAV_WAYPOINT,
        target_system: 1,
        target_component: 1,
        frame: MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT,
        current: u8::from(seq == 0),
        autocontinue: 1,
        mission_type: MISSION,
    })
}

/// The next MISSION_ACK.
async fn mission_ack(c: &mut Client) -> MISSION_ACK_DATA {
    c.wait_for(S3, |r| match &r.msg {
        Some(MavMessage::MISSION_ACK(a)) => Some(a.clone()),
        _ => None,
    })
    .await
    .expect("MISSION_ACK")
}

/// The next request for an item: (seq, int mode).
async fn item_request(c: &mut Client) -> (u16, bool) {
    c.wait_for(S3, |r| match &r.msg {
        Some(MavMessage::MISSION_REQUEST(q)) => Some((q.seq, false)),
        Some(MavMessage::MISSION_REQUEST_INT(q)) => Some((q.seq, true)),
        _ => None,
    })
    .await
    .expect("a request")
}

/// Upload `n` waypoints to `to` as MAVSDK does (refusing MISSION_REQUEST);
/// the final MISSION_ACK.
async fn upload(c: &mut Client, to: SocketAddr, n: u16) -> MISSION_ACK_DATA {
    let count = MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
        count: n,
        target_system: 1,
        target_component: 1,
        mission_type: MISSION,
        opaque_id: 0,
    });
    c.send(to, &count).await;
    let mut sent = 0;
    while sent < n {
        match item_request(c).await {
            (_, false) => {
                let no = MavMessage::MISSION_ACK(MISSION_ACK_DATA {
                    target_system: 1,
                    target_component: 1,
                    mavtype: MavMissionResult::MAV_MISSION_UNSUPPORTED,
                    mission_type: MISSION,
                    opaque_id: 0,
                });
                c.send(to, &no).await;
            }
            (seq, true) => {
                assert_eq!(seq, sent);
                c.send(to, &waypoint(seq)).await;
                sent += 1;
            }
        }
    }
    mission_ack(c).await
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn upload_download_report_and_clear() {
    let mut c = Client::new().await;
    let v = Vehicle::start(config(None, None, 1.0)).await;
    let ack = upload(&mut c, v.api, 3).await;
    assert_eq!(ack.mavtype, MavMissionResult::MAV_MISSION_ACCEPTED);
    assert_ne!(ack.opaque_id, 0, "the plan's id");
    assert_eq!((ack.target_system, ack.target_component), (245, 190));
    // MISSION_CURRENT reports the stored mission
    let cur = c
        .wait_for(S3, |r| match &r.msg {
            Some(MavMessage::MISSION_CURRENT(m)) if m.total == 3 => Some(m.clone()),
            _ => None,
        })
        .await
        .expect("MISSION_CURRENT with the mission");
    assert_eq!(cur.mission_id, ack.opaque_id);
    assert_eq!(cur.mission_state, MissionState::MISSION_STATE_NOT_STARTED);
    // the download gives back what went up
    let list = MavMessage::MISSION_REQUEST_LIST(MISSION_REQUEST_LIST_DATA {
        target_system: 1,
        target_component: 1,
        mission_type: MISSION,
    });
    c.send(v.api, &list).await;
    let n = c
        .wait_for(S3, |r| match &r.msg {
            Some(MavMessage::MISSION_COUNT(n)) => Some(n.clone()),
            _ => None,
        })
        .await
        .expect("MISSION_COUNT");
    assert_eq!((n.count, n.opaque_id), (3, ack.opaque_id));
    for seq in 0..3 {
        let req = MavMessage::MISSION_REQUEST_INT(MISSION_REQUEST_INT_DATA {
            seq,
            target_system: 1,
            target_component: 1,
            mission_type: MISSION,
        });
        c.send(v.api, &req).await;
        let item = c
            .wait_for(S3, |r| {
                (r.msgid == 73).then(|| MissionItemMsg::decode(true, &r.payload))
            })
            .await
            .expect("MISSION_ITEM_INT");
        let MavMessage::MISSION_ITEM_INT(up) = waypoint(seq) else {
            unreachable!()
        };
        assert_eq!(item.seq, seq);
        assert_eq!((item.command, item.frame, item.z), (16, 3, 10.0));
        assert_eq!(item.xy, rotorpilot::link::wire::ItemXy::Int { x: up.x, y: up.y });
    }
    // clear all
    let clear = MavMessage::MISSION_CLEAR_ALL(MISSION_CLEAR_ALL_DATA {
        target_system: 1,
        target_component: 1,
        mission_type: MavMissionType::MAV_MISSION_TYPE_ALL,
    });
    c.send(v.api, &clear).await;
    let ack = mission_ack(&mut c).await;
    assert_eq!(
        (ack.mavtype, ack.mission_type),
        (
            MavMissionResult::MAV_MISSION_ACCEPTED,
            MavMissionType::MAV_MISSION_TYPE_ALL
        )
    );
    c.wait_for(S3, |r| match &r.msg {
        Some(MavMessage::MISSION_CURRENT(m)) if m.total == u16::MAX => Some(()),
        _ => None,
    })
    .await
    .expect("MISSION_CURRENT without a mission");
    v.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn of_two_uploads_over_two_links_the_later_finisher_is_denied() {
    let (mut a, mut b) = (Client::new().await, Client::with_ids(255, 190).await);
    let v = Vehicle::start(config(None, None, 1.0)).await;
    // b begins on the GCS link, a uploads whole on the API link meanwhile
    let count = MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
        count: 1,
        target_system: 1,
        target_component: 0,
        mission_type: MISSION,
        opaque_id: 0,
    });
    b.send(v.gcs, &count).await;
    assert_eq!(item_request(&mut b).await, (0, false));
    let first = upload(&mut a, v.api, 2).await;
    assert_eq!(first.mavtype, MavMissionResult::MAV_MISSION_ACCEPTED);
    b.send(v.gcs, &waypoint(0)).await;
    let second = mission_ack(&mut b).await;
    assert_eq!(second.mavtype, MavMissionResult::MAV_MISSION_DENIED);
    let text = b
        .wait_for(S3, |r| match &r.msg {
            Some(MavMessage::STATUSTEXT(s)) => Some(s.text.to_str().unwrap_or("").to_string()),
            _ => None,
        })
        .await
        .expect("why");
    assert_eq!(text, "Mission upload refused: changed by another client");
    v.stop().await;
}
