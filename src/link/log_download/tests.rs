//! Log download exchanges against a link serving an in-memory store.

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use mavlink::dialects::common::{
    LOG_ERASE_DATA, LOG_REQUEST_DATA_DATA, LOG_REQUEST_END_DATA, LOG_REQUEST_LIST_DATA, MavMessage,
};

use crate::link::ftp::{DirEntry, FileStore, FsError, LogFile, ReadFile};
use crate::link::testing::{FakeParams, MemFile, addr, link, snapshot};
use crate::link::wire::{self, Inbound};
use crate::link::{Link, Outgoing};

/// Logs by name (shared: a test adds one while the link holds the store).
#[derive(Debug, Default, Clone)]
struct Logs(Arc<Mutex<Vec<Named>>>);

/// A log's path and bytes.
type Named = (String, Vec<u8>);

impl Logs {
    fn of(logs: Vec<Named>) -> Self {
        Self(Arc::new(Mutex::new(logs)))
    }
}

impl FileStore for Logs {
    fn list(&self, _: &str) -> Result<Vec<DirEntry>, FsError> {
        Err(FsError::NotFound)
    }
    fn open(&self, path: &str) -> Result<Box<dyn ReadFile>, FsError> {
        let all = self.0.lock().unwrap();
        let v = &all.iter().find(|l| l.0 == path).ok_or(FsError::NotFound)?.1;
        // a log named `bad` fails to be read from byte 100 on
        Ok(Box::new(MemFile {
            bytes: v.clone(),
            fail_from: path.contains("bad").then_some(100),
        }))
    }
    fn create(&mut self, _: &str, _: bool) -> Result<u32, FsError> {
        Err(FsError::Protected)
    }
    fn write_at(&mut self, _: &str, _: u32, _: &[u8]) -> Result<usize, FsError> {
        Err(FsError::Protected)
    }
    fn remove_file(&mut self, _: &str) -> Result<(), FsError> {
        Err(FsError::Protected)
    }
    fn create_dir(&mut self, _: &str) -> Result<(), FsError> {
        Err(FsError::Protected)
    }
    fn remove_dir(&mut self, _: &str) -> Result<(), FsError> {
        Err(FsError::Protected)
    }
    fn rename(&mut self, _: &str, _: &str) -> Result<(), FsError> {
        Err(FsError::Protected)
    }
    fn truncate(&mut self, _: &str, _: u32) -> Result<(), FsError> {
        Err(FsError::Protected)
    }
    fn logs(&self) -> Vec<LogFile> {
        self.0
            .lock()
            .unwrap()
            .iter()
            .map(|(p, v)| LogFile {
                path: p.clone(),
                size: v.len() as u32,
                time_utc: 1_700_000_000,
            })
            .collect()
    }
    fn erase_logs(&mut self) {
        self.0.lock().unwrap().clear();
    }
}

fn send(l: &mut Link, t: Instant, m: &MavMessage) {
    let mut enc = wire::Encoder::new(245, 190);
    let p = FakeParams::standard();
    let e = l.on_datagram(t, addr(14540), &enc.message(m), &snapshot(), &p);
    assert!(e.is_empty());
}

fn messages(out: &[Outgoing]) -> Vec<MavMessage> {
    out.iter()
        .flat_map(|o| {
            wire::frames(&o.bytes)
                .filter_map(|f| wire::decode(&f))
                .collect::<Vec<_>>()
        })
        .filter_map(|m| match m {
            Inbound::Other(m) => Some(*m),
            _ => None,
        })
        .filter(|m| matches!(m, MavMessage::LOG_ENTRY(_) | MavMessage::LOG_DATA(_)))
        .collect()
}

/// Everything the link sends until it falls silent.
fn run(l: &mut Link, mut t: Instant) -> Vec<MavMessage> {
    let mut all = messages(&l.drain());
    for _ in 0..2000 {
        t += Duration::from_millis(5);
        l.poll(t, &snapshot(), 0);
        let m = messages(&l.drain());
        if m.is_empty() && l.logs.transfer.is_none() {
            break;
        }
        all.extend(m);
    }
    all
}

fn list(start: u16, end: u16) -> MavMessage {
    MavMessage::LOG_REQUEST_LIST(LOG_REQUEST_LIST_DATA {
        start,
        end,
        target_system: 1,
        target_component: 1,
    })
}

#[test]
fn with_no_logs_the_list_is_one_entry_saying_none() {
    let t = Instant::now();
    let mut l = link(t);
    send(&mut l, t, &list(0, u16::MAX));
    let out = run(&mut l, t);
    assert_eq!(out.len(), 1);
    let MavMessage::LOG_ENTRY(e) = &out[0] else { panic!() };
    assert_eq!((e.id, e.num_logs, e.last_log_num, e.size, e.time_utc), (0, 0, 0, 0, 0));
}

#[test]
fn logs_are_listed_then_sent_in_90_byte_chunks_then_erased() {
    let t = Instant::now();
    let mut l = link(t);
    let big: Vec<u8> = (0..1000u32).map(|i| (i * 7) as u8).collect();
    l.set_files(Box::new(Logs::of(vec![
        ("/log/a.ulg".into(), vec![1; 5]),
        ("/log/b.ulg".into(), big.clone()),
    ])));
    send(&mut l, t, &list(0, u16::MAX));
    let out = run(&mut l, t);
    let entries: Vec<_> = out
        .iter()
        .map(|m| match m {
            MavMessage::LOG_ENTRY(e) => (e.id, e.num_logs, e.last_log_num, e.size),
            other => panic!("{other:?}"),
        })
        .collect();
    assert_eq!(entries, vec![(0, 2, 1, 5), (1, 2, 1, 1000)]);
    send(
        &mut l,
        t,
        &MavMessage::LOG_REQUEST_DATA(LOG_REQUEST_DATA_DATA {
            ofs: 0,
            count: u32::MAX,
            id: 1,
            target_system: 1,
            target_component: 1,
        }),
    );
    let mut got = Vec::new();
    for m in run(&mut l, t) {
        let MavMessage::LOG_DATA(d) = m else { panic!() };
        assert_eq!((d.id, d.ofs as usize), (1, got.len()));
        got.extend_from_slice(&d.data[..usize::from(d.count)]);
    }
    assert_eq!(got, big);
    // a part: 100 bytes from 950 is 50 bytes, one short message
    send(
        &mut l,
        t,
        &MavMessage::LOG_REQUEST_DATA(LOG_REQUEST_DATA_DATA {
            ofs: 950,
            count: 100,
            id: 1,
            target_system: 1,
            target_component: 1,
        }),
    );
    let out = run(&mut l, t);
    assert_eq!(out.len(), 1);
    // a log that was not listed gets nothing, as PX4
    send(
        &mut l,
        t,
        &MavMessage::LOG_REQUEST_DATA(LOG_REQUEST_DATA_DATA {
            ofs: 0,
            count: 90,
            id: 7,
            target_system: 1,
            target_component: 1,
        }),
    );
    assert!(run(&mut l, t).is_empty());
    send(
        &mut l,
        t,
        &MavMessage::LOG_REQUEST_END(LOG_REQUEST_END_DATA {
            target_system: 1,
            target_component: 1,
        }),
    );
    send(
        &mut l,
        t,
        &MavMessage::LOG_ERASE(LOG_ERASE_DATA {
            target_system: 1,
            target_component: 1,
        }),
    );
    send(&mut l, t, &list(0, u16::MAX));
    let out = run(&mut l, t);
    let MavMessage::LOG_ENTRY(e) = &out[0] else { panic!() };
    assert_eq!(e.num_logs, 0);
}

#[test]
fn a_full_range_request_lists_afresh_as_px4_does() {
    let t = Instant::now();
    let mut l = link(t);
    let store = Logs::of(vec![("/log/a.ulg".into(), vec![1; 5])]);
    l.set_files(Box::new(store.clone()));
    send(&mut l, t, &list(0, u16::MAX));
    assert_eq!(run(&mut l, t).len(), 1);
    // a new flight's log appears: MAVSDK's next list (0..0xFFFF) sees it
    store.0.lock().unwrap().push(("/log/b.ulg".into(), vec![2; 7]));
    send(&mut l, t, &list(0, u16::MAX));
    let out = run(&mut l, t);
    let sizes: Vec<_> = out
        .iter()
        .map(|m| match m {
            MavMessage::LOG_ENTRY(e) => (e.id, e.num_logs, e.size),
            other => panic!("{other:?}"),
        })
        .collect();
    assert_eq!(sizes, vec![(0, 2, 5), (1, 2, 7)]);
    // a narrow re-request (lost entries) keeps the list it has
    store.0.lock().unwrap().push(("/log/c.ulg".into(), vec![3; 9]));
    send(&mut l, t, &list(1, 1));
    let out = run(&mut l, t);
    let MavMessage::LOG_ENTRY(e) = &out[0] else { panic!() };
    assert_eq!((out.len(), e.id, e.num_logs), (1, 1, 2));
}

fn data(id: u16, ofs: u32, count: u32) -> MavMessage {
    MavMessage::LOG_REQUEST_DATA(LOG_REQUEST_DATA_DATA {
        ofs,
        count,
        id,
        target_system: 1,
        target_component: 1,
    })
}

#[test]
fn a_list_starting_past_the_last_log_gets_no_entry_as_px4() {
    let t = Instant::now();
    let mut l = link(t);
    l.set_files(Box::new(Logs::of(vec![
        ("/log/a.ulg".into(), vec![1; 5]),
        ("/log/b.ulg".into(), vec![2; 7]),
    ])));
    send(&mut l, t, &list(5, 5));
    assert!(run(&mut l, t).is_empty(), "not log 1 for a request of log 5");
    send(&mut l, t, &list(1, 9));
    let ids: Vec<_> = run(&mut l, t)
        .iter()
        .map(|m| match m {
            MavMessage::LOG_ENTRY(e) => (e.id, e.num_logs, e.last_log_num),
            other => panic!("{other:?}"),
        })
        .collect();
    assert_eq!(ids, vec![(1, 2, 1)]);
}

#[test]
fn a_read_error_stops_the_transfer_instead_of_ending_the_log_short() {
    let t = Instant::now();
    let mut l = link(t);
    l.set_files(Box::new(Logs::of(vec![("/log/bad.ulg".into(), vec![7; 1000])])));
    send(&mut l, t, &list(0, u16::MAX));
    assert_eq!(run(&mut l, t).len(), 1);
    send(&mut l, t, &data(0, 0, u32::MAX));
    let sent: Vec<_> = run(&mut l, t)
        .iter()
        .map(|m| match m {
            MavMessage::LOG_DATA(d) => (d.ofs, d.count),
            other => panic!("{other:?}"),
        })
        .collect();
    // bytes 0..90 and 90..180 read; the read at 180 fails: nothing more, no
    // short LOG_DATA that a client takes for the end of the log
    assert_eq!(sent, vec![(0, 90), (90, 90)]);
    assert!(l.logs.transfer.is_none());
}

#[test]
fn a_transfer_held_back_by_the_budget_loses_no_chunk() {
    let t = Instant::now();
    let mut l = link(t);
    let big: Vec<u8> = (0..20_000u32).map(|i| (i * 13) as u8).collect();
    l.set_files(Box::new(Logs::of(vec![("/log/a.ulg".into(), big.clone())])));
    send(&mut l, t, &list(0, u16::MAX));
    run(&mut l, t);
    send(&mut l, t, &data(0, 0, u32::MAX));
    let mut got = Vec::new();
    for m in run(&mut l, t) {
        let MavMessage::LOG_DATA(d) = m else { panic!() };
        assert_eq!(d.ofs as usize, got.len(), "no gap");
        got.extend_from_slice(&d.data[..usize::from(d.count)]);
    }
    assert_eq!(got, big);
}
