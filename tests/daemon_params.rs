//! The parameter protocol against the running daemon: the list, reads by name
//! and index, INT32 bytewise, the echo and the rebroadcast, every refusal
//! (unknown name, out of range, wrong type, NaN: nothing changes), and
//! persistence across restarts and `--reset-params`.
#![allow(deprecated)]

mod common;

use std::time::Duration;

use common::daemon::{Client, NAN, Vehicle, config};
use mavlink::dialects::common::*;

const S3: Duration = Duration::from_secs(3);

fn name(p: &PARAM_VALUE_DATA) -> String {
    p.param_id.to_str().unwrap().to_string()
}

async fn read(c: &mut Client, to: std::net::SocketAddr, id: &str, index: i16) -> Option<MavMessage> {
    c.drain().await;
    c.send(
        to,
        &MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
            param_index: index,
            target_system: 1,
            target_component: 1,
            param_id: id.into(),
        }),
    )
    .await;
    c.wait_for(S3, |r| match &r.msg {
        Some(m @ (MavMessage::PARAM_VALUE(_) | MavMessage::PARAM_ERROR(_))) => Some(m.clone()),
        _ => None,
    })
    .await
}

/// The PARAM_VALUEs and PARAM_ERRORs for `id` within `wait`.
async fn answers(c: &mut Client, id: &str, wait: Duration) -> Vec<MavMessage> {
    let mut out = Vec::new();
    let t0 = tokio::time::Instant::now();
    while let Some(r) = c.recv(wait.saturating_sub(t0.elapsed())).await {
        match &r.msg {
            Some(MavMessage::PARAM_VALUE(p)) if name(p) == id => out.push(r.msg.clone().unwrap()),
            Some(MavMessage::PARAM_ERROR(e)) if e.param_id.to_str().unwrap() == id => out.push(r.msg.clone().unwrap()),
            _ => {}
        }
    }
    out
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn list_is_complete_ordered_and_consistent() {
    let mut c = Client::with_ids(255, 0).await;
    let v = Vehicle::start(config(Some(c.addr()), None, 1.0)).await;
    c.send(
        v.gcs,
        &MavMessage::PARAM_REQUEST_LIST(PARAM_REQUEST_LIST_DATA {
            target_system: 1,
            target_component: 0,
        }),
    )
    .await;
    let mut got: Vec<PARAM_VALUE_DATA> = Vec::new();
    let t0 = tokio::time::Instant::now();
    while t0.elapsed() < S3 {
        let Some(r) = c.recv(Duration::from_millis(500)).await else {
            break;
        };
        if let Some(MavMessage::PARAM_VALUE(p)) = r.msg {
            let last = p.param_index + 1 == p.param_count;
            got.push(p);
            if last {
                break;
            }
        }
    }
    let n = got[0].param_count;
    // the whole table: rotorpilot's and every other PX4 SITL multicopter parameter
    assert_eq!(usize::from(n), rotorpilot::params::PARAMS.len(), "{n} parameters");
    assert!(n > 1000, "{n} parameters");
    assert_eq!(got.len(), usize::from(n));
    for (i, p) in got.iter().enumerate() {
        assert_eq!(usize::from(p.param_index), i, "index order");
        assert_eq!(p.param_count, n, "constant count");
        assert!(matches!(
            p.param_type,
            MavParamType::MAV_PARAM_TYPE_INT32 | MavParamType::MAV_PARAM_TYPE_REAL32
        ));
    }
    let names: Vec<String> = got.iter().map(name).collect();
    for must in [
        "MIS_TAKEOFF_ALT",
        "RTL_RETURN_ALT",
        "MPC_XY_CRUISE",
        "SYS_FAILURE_EN",
        "COM_OF_LOSS_T",
        "COM_DISARM_LAND",
        "COM_DISARM_PRFLT",
        "SIM_FEXT_X",
        "SIM_MASS",
        "CTRL_TYPE",
    ] {
        assert!(names.iter().any(|x| x == must), "{must}");
    }
    let mut sorted = names.clone();
    sorted.sort();
    sorted.dedup();
    assert_eq!(sorted.len(), names.len(), "no duplicates");
    // MAV_SYS_ID shows the instance's system id, INT32 bytewise
    let sys = got.iter().find(|p| name(p) == "MAV_SYS_ID").unwrap();
    assert_eq!(sys.param_value.to_bits(), 1);
    v.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn read_by_name_by_index_and_unknown() {
    let mut c = Client::new().await;
    let v = Vehicle::start(config(Some(c.addr()), None, 1.0)).await;
    let Some(MavMessage::PARAM_VALUE(p)) = read(&mut c, v.gcs, "CTRL_TYPE", -1).await else {
        panic!("by name")
    };
    assert_eq!(p.param_type, MavParamType::MAV_PARAM_TYPE_INT32);
    let idx = p.param_index;
    // by index: the name is ignored
    let Some(MavMessage::PARAM_VALUE(q)) = read(&mut c, v.gcs, "WHATEVER", idx.cast_signed()).await else {
        panic!("by index")
    };
    assert_eq!(name(&q), "CTRL_TYPE");
    // unknown name and index out of range: PARAM_ERROR DOES_NOT_EXIST
    let Some(MavMessage::PARAM_ERROR(e)) = read(&mut c, v.gcs, "NO_SUCH_PARAM", -1).await else {
        panic!("error")
    };
    assert_eq!(e.error, MavParamError::MAV_PARAM_ERROR_DOES_NOT_EXIST);
    assert_eq!((e.target_system, e.target_component), (245, 190));
    let Some(MavMessage::PARAM_ERROR(_)) = read(&mut c, v.gcs, "", 30_000).await else {
        panic!("index error")
    };
    v.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn int32_set_is_bytewise_echoed_rebroadcast_applied_and_saved() {
    let mut gcs = Client::new().await;
    let mut api = Client::new().await;
    let v = Vehicle::start(config(Some(gcs.addr()), Some(api.addr()), 1.0)).await;
    api.drain().await;
    // before the set: failure injection is DENIED
    let a = gcs.command(v.gcs, 420, [4.0, 1.0, 0.0, NAN, NAN, NAN, NAN]).await;
    assert_eq!(a.result, 2, "failure injection with SYS_FAILURE_EN = 0");
    gcs.drain().await;
    gcs.param_set(
        v.gcs,
        "SYS_FAILURE_EN",
        f32::from_bits(1),
        MavParamType::MAV_PARAM_TYPE_INT32,
    )
    .await;
    let got = answers(&mut gcs, "SYS_FAILURE_EN", Duration::from_millis(500)).await;
    // the echo, then the rebroadcast
    assert_eq!(got.len(), 2, "{got:?}");
    for m in &got {
        let MavMessage::PARAM_VALUE(p) = m else { panic!("{m:?}") };
        assert_eq!(p.param_type, MavParamType::MAV_PARAM_TYPE_INT32);
        assert_eq!(p.param_value.to_bits(), 1);
    }
    // the other link hears the change once
    let other = answers(&mut api, "SYS_FAILURE_EN", Duration::from_millis(200)).await;
    assert_eq!(other.len(), 1);
    // it applies at once: the next command, sent as soon as the set is
    // answered, injects the failure (GPS off: ACCEPTED, was DENIED above)
    let a = gcs.command(v.gcs, 420, [4.0, 1.0, 0.0, NAN, NAN, NAN, NAN]).await;
    assert_eq!(a.result, 0, "failure injection right after SYS_FAILURE_EN = 1");
    // and persists
    tokio::time::sleep(Duration::from_millis(300)).await;
    let text = std::fs::read_to_string(v.state_dir.join("params.toml")).unwrap();
    assert!(text.lines().any(|l| l.trim() == "SYS_FAILURE_EN = 1"), "{text}");
    v.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn refused_sets_answer_the_unchanged_value() {
    let mut c = Client::new().await;
    let v = Vehicle::start(config(Some(c.addr()), None, 1.0)).await;
    let real = MavParamType::MAV_PARAM_TYPE_REAL32;
    for (id, value, kind) in [
        ("MIS_TAKEOFF_ALT", -1.0, real),     // out of range
        ("MIS_TAKEOFF_ALT", f32::NAN, real), // NaN
        ("MIS_TAKEOFF_ALT", f32::from_bits(5), MavParamType::MAV_PARAM_TYPE_INT32), // wrong type
        ("MIS_TAKEOFF_ALT", 5.0, MavParamType::MAV_PARAM_TYPE_UINT8), // unsupported type
    ] {
        c.param_set(v.gcs, id, value, kind).await;
        let got = answers(&mut c, id, Duration::from_millis(400)).await;
        assert!(matches!(got.first(), Some(MavMessage::PARAM_ERROR(_))), "{got:?}");
        let values: Vec<f32> = got
            .iter()
            .filter_map(|m| match m {
                MavMessage::PARAM_VALUE(p) => Some(p.param_value),
                _ => None,
            })
            .collect();
        assert_eq!(
            values,
            vec![2.5],
            "{id} = {value} ({kind:?}) must answer the unchanged value once"
        );
    }
    // CTRL_TYPE: REAL32 for an INT32 parameter is refused (PX4 never converts)
    let Some(MavMessage::PARAM_VALUE(before)) = read(&mut c, v.gcs, "CTRL_TYPE", -1).await else {
        panic!()
    };
    c.param_set(v.gcs, "CTRL_TYPE", 2.0, real).await;
    let got = answers(&mut c, "CTRL_TYPE", Duration::from_millis(400)).await;
    let Some(MavMessage::PARAM_VALUE(p)) = got.last() else {
        panic!("{got:?}")
    };
    assert_eq!(p.param_value.to_bits(), before.param_value.to_bits());
    // unknown name: PARAM_ERROR only
    c.param_set(v.gcs, "NO_SUCH_PARAM", 1.0, real).await;
    let got = answers(&mut c, "NO_SUCH_PARAM", Duration::from_millis(400)).await;
    assert_eq!(got.len(), 1);
    let MavMessage::PARAM_ERROR(e) = &got[0] else { panic!() };
    assert_eq!(e.error, MavParamError::MAV_PARAM_ERROR_DOES_NOT_EXIST);
    // nothing changed
    let Some(MavMessage::PARAM_VALUE(p)) = read(&mut c, v.gcs, "MIS_TAKEOFF_ALT", -1).await else {
        panic!()
    };
    assert_eq!(p.param_value, 2.5);
    v.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn parameters_persist_across_restarts_unless_reset() {
    let mut c = Client::new().await;
    let cfg = config(Some(c.addr()), None, 1.0);
    let dir = cfg.state_dir.clone();
    let v = Vehicle::start(cfg.clone()).await;
    c.param_set(v.gcs, "MPC_XY_CRUISE", 7.5, MavParamType::MAV_PARAM_TYPE_REAL32)
        .await;
    assert!(
        !answers(&mut c, "MPC_XY_CRUISE", Duration::from_millis(300))
            .await
            .is_empty()
    );
    let took = v.stop_keep_state().await;
    assert!(
        took < Duration::from_secs(1),
        "clean shutdown within a second: {took:?}"
    );
    // restart on the same state dir: the value is back
    let v = Vehicle::start(cfg.clone()).await;
    let Some(MavMessage::PARAM_VALUE(p)) = read(&mut c, v.gcs, "MPC_XY_CRUISE", -1).await else {
        panic!()
    };
    assert_eq!(p.param_value, 7.5);
    v.stop_keep_state().await;
    // --reset-params: defaults
    let mut reset = cfg;
    reset.reset_params = true;
    reset.state_dir = dir;
    let v = Vehicle::start(reset).await;
    let Some(MavMessage::PARAM_VALUE(p)) = read(&mut c, v.gcs, "MPC_XY_CRUISE", -1).await else {
        panic!()
    };
    assert_eq!(p.param_value, 5.0);
    v.stop().await;
}

/// The rollback: a value in the table's range that the autopilot refuses in
/// combination with the airframe (CTRL_POS_SCALE = 3 scales a 1e308 N/m
/// passivity stiffness past f64::MAX) gets PARAM_ERROR, the unchanged value
/// once, and a STATUSTEXT naming the gain, read off the wire; a read and the
/// saved file still show the old value; a value the autopilot takes is then
/// accepted as usual.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_set_the_autopilot_rejects_is_rolled_back_and_explained() {
    let mut c = Client::new().await;
    let mut cfg = config(Some(c.addr()), None, 1.0);
    cfg.airframe = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/fixtures/airframes/quad-huge-passivity-gain.toml"
    )
    .to_string();
    let v = Vehicle::start(cfg).await;
    let real = MavParamType::MAV_PARAM_TYPE_REAL32;
    c.drain().await;
    c.param_set(v.gcs, "CTRL_POS_SCALE", 3.0, real).await;
    let mut got = Vec::new();
    let mut texts = Vec::new();
    let t0 = tokio::time::Instant::now();
    while let Some(r) = c.recv(Duration::from_millis(500).saturating_sub(t0.elapsed())).await {
        match r.msg {
            Some(MavMessage::PARAM_VALUE(p)) if name(&p) == "CTRL_POS_SCALE" => got.push(("value", p.param_value)),
            Some(MavMessage::PARAM_ERROR(e)) if e.param_id.to_str().unwrap() == "CTRL_POS_SCALE" => {
                assert_eq!(e.error, MavParamError::MAV_PARAM_ERROR_VALUE_OUT_OF_RANGE);
                got.push(("error", f32::NAN));
            }
            Some(MavMessage::STATUSTEXT(s)) => texts.push(s.text.to_str().unwrap().to_string()),
            _ => {}
        }
    }
    assert_eq!(got.len(), 2, "PARAM_ERROR then the unchanged value: {got:?}");
    assert_eq!(got[0].0, "error", "{got:?}");
    assert_eq!(got[1], ("value", 1.0), "{got:?}");
    assert!(
        texts
            .iter()
            .any(|t| t.starts_with("param: ") && t.contains("passivity.kp_n_per_m")),
        "{texts:?}"
    );
    let Some(MavMessage::PARAM_VALUE(p)) = read(&mut c, v.gcs, "CTRL_POS_SCALE", -1).await else {
        panic!("read")
    };
    assert_eq!(p.param_value, 1.0, "read back after the refusal");
    // a scale the autopilot takes (1.25^2 x 1e308 is finite): accepted
    c.param_set(v.gcs, "CTRL_POS_SCALE", 1.25, real).await;
    let got = answers(&mut c, "CTRL_POS_SCALE", Duration::from_millis(400)).await;
    assert!(
        matches!(got.first(), Some(MavMessage::PARAM_VALUE(p)) if p.param_value == 1.25),
        "{got:?}"
    );
    let dir = v.state_dir.clone();
    v.stop_keep_state().await;
    let text = std::fs::read_to_string(dir.join("params.toml")).unwrap();
    assert!(text.lines().any(|l| l.trim() == "CTRL_POS_SCALE = 1.25"), "{text}");
    let _ = std::fs::remove_dir_all(&dir);
}
