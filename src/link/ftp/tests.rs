//! MAVLink FTP exchanges against a link serving an in-memory store.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use mavlink::dialects::common::{FILE_TRANSFER_PROTOCOL_DATA, MavMessage};

use super::param_pck;
use super::*;
use crate::link::testing::{FakeParams, MemFile, addr, link, snapshot};
use crate::link::wire::{self, Inbound};
use crate::params::ParamValue;

/// Files by path (no directories but `/` and `/log`), writable.
#[derive(Debug, Default)]
struct MemStore(BTreeMap<String, Vec<u8>>);

impl FileStore for MemStore {
    fn list(&self, path: &str) -> Result<Vec<DirEntry>, FsError> {
        match path.trim_matches('/') {
            "" => Ok(std::iter::once(DirEntry::Dir("log".into()))
                .chain(self.0.iter().map(|(k, v)| DirEntry::File(k.clone(), v.len() as u32)))
                .collect()),
            "log" => Ok(Vec::new()),
            _ => Err(FsError::NotFound),
        }
    }
    fn open(&self, path: &str) -> Result<Box<dyn ReadFile>, FsError> {
        let v = self.0.get(path.trim_start_matches('/')).ok_or(FsError::NotFound)?;
        Ok(Box::new(MemFile {
            bytes: v.clone(),
            fail_from: None,
        }))
    }
    fn create(&mut self, path: &str, truncate: bool) -> Result<u32, FsError> {
        if path.contains("..") {
            return Err(FsError::Protected);
        }
        let v = self.0.entry(path.trim_start_matches('/').into()).or_default();
        if truncate {
            v.clear();
        }
        Ok(v.len() as u32)
    }
    fn write_at(&mut self, path: &str, offset: u32, data: &[u8]) -> Result<usize, FsError> {
        let v = self.0.get_mut(path.trim_start_matches('/')).ok_or(FsError::NotFound)?;
        let end = offset as usize + data.len();
        if end > 1000 {
            return Err(FsError::Errno(errno::EFBIG));
        }
        if v.len() < end {
            v.resize(end, 0);
        }
        v[offset as usize..end].copy_from_slice(data);
        Ok(data.len())
    }
    fn remove_file(&mut self, path: &str) -> Result<(), FsError> {
        self.0
            .remove(path.trim_start_matches('/'))
            .map(|_| ())
            .ok_or(FsError::NotFound)
    }
    fn create_dir(&mut self, _: &str) -> Result<(), FsError> {
        Err(FsError::Protected)
    }
    fn remove_dir(&mut self, _: &str) -> Result<(), FsError> {
        Err(FsError::Protected)
    }
    fn rename(&mut self, from: &str, to: &str) -> Result<(), FsError> {
        let v = self.0.remove(from.trim_start_matches('/')).ok_or(FsError::NotFound)?;
        self.0.insert(to.trim_start_matches('/').into(), v);
        Ok(())
    }
    fn truncate(&mut self, path: &str, len: u32) -> Result<(), FsError> {
        let v = self.0.get_mut(path.trim_start_matches('/')).ok_or(FsError::NotFound)?;
        v.resize(len as usize, 0);
        Ok(())
    }
    fn logs(&self) -> Vec<LogFile> {
        self.0
            .iter()
            .filter(|(k, _)| k.ends_with(".ulg"))
            .map(|(k, v)| LogFile {
                path: format!("/{k}"),
                size: v.len() as u32,
                time_utc: 1_700_000_000,
            })
            .collect()
    }
    fn erase_logs(&mut self) {
        self.0.retain(|k, _| !k.ends_with(".ulg"));
    }
}

fn request(seq: u16, session: u8, opcode: u8, offset: u32, data: &[u8]) -> Vec<u8> {
    let mut payload = [0u8; 251];
    payload[0..2].copy_from_slice(&seq.to_le_bytes());
    payload[2] = session;
    payload[3] = opcode;
    payload[4] = data.len().min(255) as u8;
    payload[8..12].copy_from_slice(&offset.to_le_bytes());
    let n = data.len().min(239);
    payload[12..12 + n].copy_from_slice(&data[..n]);
    let mut enc = wire::Encoder::new(245, 190);
    enc.message(&MavMessage::FILE_TRANSFER_PROTOCOL(FILE_TRANSFER_PROTOCOL_DATA {
        target_network: 0,
        target_system: 1,
        target_component: 1,
        payload,
    }))
}

/// The FTP payloads sent.
fn replies(l: &mut Link) -> Vec<[u8; 251]> {
    l.drain()
        .iter()
        .flat_map(|o| {
            wire::frames(&o.bytes)
                .filter_map(|f| wire::decode(&f))
                .collect::<Vec<_>>()
        })
        .filter_map(|m| match m {
            Inbound::Other(m) => match *m {
                MavMessage::FILE_TRANSFER_PROTOCOL(f) => Some(f.payload),
                _ => None,
            },
            _ => None,
        })
        .collect()
}

struct Rig {
    l: Link,
    p: FakeParams,
    t: Instant,
    seq: u16,
}

impl Rig {
    fn new(files: MemStore) -> Self {
        let t = Instant::now();
        let mut l = link(t);
        l.set_files(Box::new(files));
        Self {
            l,
            p: FakeParams::standard(),
            t,
            seq: 0,
        }
    }

    /// One request; its effects and the replies.
    fn ask(&mut self, session: u8, opcode: u8, offset: u32, data: &[u8]) -> (Vec<Effect>, Vec<[u8; 251]>) {
        self.seq = self.seq.wrapping_add(2);
        let r = request(self.seq, session, opcode, offset, data);
        let e = self.l.on_datagram(self.t, addr(14540), &r, &snapshot(), &self.p);
        (e, replies(&mut self.l))
    }

    /// One request answered by one message: (opcode, data).
    fn one(&mut self, session: u8, opcode: u8, offset: u32, data: &[u8]) -> (u8, Vec<u8>) {
        let (_, r) = self.ask(session, opcode, offset, data);
        assert_eq!(r.len(), 1, "one answer to opcode {opcode}");
        let p = r[0];
        assert_eq!(u16::from_le_bytes([p[0], p[1]]), self.seq.wrapping_add(1), "seq + 1");
        assert_eq!(p[5], opcode, "req_opcode");
        (p[3], p[12..12 + usize::from(p[4])].to_vec())
    }

    /// Stream a burst to the end: the bytes and the closing NAK's error.
    fn burst(&mut self) -> (Vec<u8>, u8) {
        let (_, mut r) = self.ask(0, op::BURST_READ_FILE, 0, &[]);
        let mut bytes = Vec::new();
        for _ in 0..1000 {
            for p in r.drain(..) {
                assert_eq!(p[5], op::BURST_READ_FILE);
                if p[3] == op::NAK {
                    return (bytes, p[12]);
                }
                assert_eq!(u32::from_le_bytes([p[8], p[9], p[10], p[11]]) as usize, bytes.len());
                bytes.extend_from_slice(&p[12..12 + usize::from(p[4])]);
            }
            self.t += Duration::from_millis(5);
            self.l.poll(self.t, &snapshot(), 0);
            r = replies(&mut self.l);
        }
        panic!("the burst never ended");
    }
}

fn files() -> MemStore {
    let mut m = MemStore::default();
    m.0.insert("notes.txt".into(), (0..=255u8).cycle().take(1000).collect());
    m
}

#[test]
fn the_root_lists_the_log_directory_and_the_files_and_then_eof() {
    let mut r = Rig::new(files());
    let (opcode, data) = r.one(0, op::LIST_DIRECTORY, 0, b"/");
    assert_eq!(opcode, op::ACK);
    assert_eq!(data, b"S\0S\0Dlog\0Fnotes.txt\t1000\0");
    let (opcode, data) = r.one(0, op::LIST_DIRECTORY, 4, b"/");
    assert_eq!((opcode, data), (op::NAK, vec![err::EOF]));
    let (opcode, data) = r.one(0, op::LIST_DIRECTORY, 0, b"/nowhere");
    assert_eq!((opcode, data), (op::NAK, vec![err::FILE_NOT_FOUND]));
}

#[test]
fn a_file_is_read_by_offset_and_by_burst_and_its_crc_is_px4s() {
    let mut r = Rig::new(files());
    let (opcode, data) = r.one(0, op::OPEN_FILE_RO, 0, b"/notes.txt");
    assert_eq!((opcode, data), (op::ACK, 1000u32.to_le_bytes().to_vec()));
    // one session per link, as PX4
    let (opcode, data) = r.one(0, op::OPEN_FILE_RO, 0, b"/notes.txt");
    assert_eq!((opcode, data), (op::NAK, vec![err::NO_SESSIONS_AVAILABLE]));
    let (_, data) = r.one(0, op::READ_FILE, 239, &[]);
    assert_eq!(data, (239..478).map(|i| (i % 256) as u8).collect::<Vec<_>>());
    let (opcode, data) = r.one(0, op::READ_FILE, 1000, &[]);
    assert_eq!((opcode, data), (op::NAK, vec![err::EOF]));
    let (opcode, data) = r.one(3, op::READ_FILE, 0, &[]);
    assert_eq!((opcode, data), (op::NAK, vec![err::INVALID_SESSION]));
    let (bytes, end) = r.burst();
    assert_eq!(end, err::EOF);
    assert_eq!(bytes, files().0["notes.txt"]);
    let (_, data) = r.one(0, op::CALC_FILE_CRC32, 0, b"/notes.txt");
    // zlib's CRC-32 complements in and out; PX4's crc32part does neither
    let zlib_of_complemented = {
        let mut c = 0xFFFF_FFFFu32 ^ 0xFFFF_FFFF;
        c = crate::mission::crc::crc32part(&bytes, c);
        c
    };
    assert_eq!(data, zlib_of_complemented.to_le_bytes().to_vec());
    assert_eq!(
        crate::mission::crc::crc32part(b"123456789", 0xFFFF_FFFF) ^ 0xFFFF_FFFF,
        0xCBF4_3926,
        "the CRC-32 check value"
    );
    let (opcode, _) = r.one(0, op::TERMINATE_SESSION, 0, &[]);
    assert_eq!(opcode, op::ACK);
    let (opcode, data) = r.one(0, op::TERMINATE_SESSION, 0, &[]);
    assert_eq!((opcode, data), (op::NAK, vec![err::INVALID_SESSION]));
}

#[test]
fn bad_requests_get_px4s_naks_and_answers_get_nothing() {
    let mut r = Rig::new(files());
    assert_eq!(r.one(0, 99, 0, &[]), (op::NAK, vec![err::UNKNOWN_COMMAND]));
    assert_eq!(r.one(0, op::NONE, 0, &[]).0, op::ACK);
    assert_eq!(
        r.one(0, op::BURST_READ_FILE, 0, &[]),
        (op::NAK, vec![err::INVALID_SESSION])
    );
    assert_eq!(r.one(0, op::WRITE_FILE, 0, b"x"), (op::NAK, vec![err::INVALID_SESSION]));
    // size over 239
    let mut raw = request(40, 0, op::READ_FILE, 0, &[]);
    let mut payload = [0u8; 251];
    payload[0] = 40;
    payload[3] = op::READ_FILE;
    payload[4] = 240;
    raw = {
        let _ = raw;
        let mut enc = wire::Encoder::new(245, 190);
        enc.message(&MavMessage::FILE_TRANSFER_PROTOCOL(FILE_TRANSFER_PROTOCOL_DATA {
            target_network: 0,
            target_system: 1,
            target_component: 1,
            payload,
        }))
    };
    r.l.on_datagram(r.t, addr(14540), &raw, &snapshot(), &r.p);
    let out = replies(&mut r.l);
    assert_eq!((out[0][3], out[0][12]), (op::NAK, err::INVALID_DATA_SIZE));
    for answer in [op::ACK, op::NAK] {
        let (_, out) = r.ask(0, answer, 0, &[]);
        assert!(out.is_empty(), "no answer to an answer");
    }
}

#[test]
fn a_resent_request_gets_the_same_answer_without_doing_it_twice() {
    let mut r = Rig::new(files());
    let raw = request(10, 0, op::OPEN_FILE_RO, 0, b"/notes.txt");
    r.l.on_datagram(r.t, addr(14540), &raw, &snapshot(), &r.p);
    let first = replies(&mut r.l);
    r.l.on_datagram(r.t, addr(14540), &raw, &snapshot(), &r.p);
    let again = replies(&mut r.l);
    assert_eq!(first, again, "not NoSessionsAvailable: the ACK resent");
}

#[test]
fn a_file_is_written_within_the_stores_cap_and_removed() {
    let mut r = Rig::new(files());
    assert_eq!(r.one(0, op::CREATE_FILE, 0, b"/new.bin").0, op::ACK);
    let (opcode, data) = r.one(0, op::WRITE_FILE, 0, b"hello");
    assert_eq!((opcode, data), (op::ACK, 5u32.to_le_bytes().to_vec()));
    let (opcode, data) = r.one(0, op::WRITE_FILE, 998, b"toolong");
    assert_eq!((opcode, data), (op::NAK, vec![err::FAIL_ERRNO, errno::EFBIG]));
    assert_eq!(r.one(0, op::TERMINATE_SESSION, 0, &[]).0, op::ACK);
    assert_eq!(r.one(0, op::RENAME, 0, b"/new.bin\0/b.bin").0, op::ACK);
    assert_eq!(r.one(0, op::TRUNCATE_FILE, 2, b"/b.bin").0, op::ACK);
    assert_eq!(r.one(0, op::OPEN_FILE_RO, 0, b"/b.bin").1, 2u32.to_le_bytes().to_vec());
    assert_eq!(r.one(0, op::RESET_SESSIONS, 0, &[]).0, op::ACK);
    assert_eq!(r.one(0, op::REMOVE_FILE, 0, b"/b.bin").0, op::ACK);
    assert_eq!(
        r.one(0, op::REMOVE_FILE, 0, b"/b.bin"),
        (op::NAK, vec![err::FILE_NOT_FOUND])
    );
    assert_eq!(
        r.one(0, op::CREATE_FILE, 0, b"/../x"),
        (op::NAK, vec![err::FILE_PROTECTED])
    );
    assert_eq!(
        r.one(0, op::RENAME, 0, b"/only-one"),
        (op::NAK, vec![err::FAIL_ERRNO, errno::EINVAL])
    );
}

#[test]
fn an_idle_session_is_closed_after_ten_seconds() {
    let mut r = Rig::new(files());
    assert_eq!(r.one(0, op::OPEN_FILE_RO, 0, b"/notes.txt").0, op::ACK);
    r.t += Duration::from_secs(11);
    r.l.poll(r.t, &snapshot(), 0);
    let _ = replies(&mut r.l);
    assert_eq!(r.one(0, op::OPEN_FILE_RO, 0, b"/notes.txt").0, op::ACK);
}

/// Decode a param.pck download: (magic, num, total, entries).
type Decoded = (u16, u16, u16, Vec<(String, u8, u32, Option<u32>)>);

fn decode(f: &[u8]) -> Decoded {
    let u16_at = |i: usize| u16::from_le_bytes([f[i], f[i + 1]]);
    let mut i = 6;
    let mut prev = String::new();
    let mut out = Vec::new();
    while i < f.len() {
        if f[i] == 0 {
            i += 1;
            continue;
        }
        let kind = f[i] & 0x0F;
        let has_default = f[i] & 0x10 != 0;
        let common = usize::from(f[i + 1] & 0x0F);
        let len = usize::from(f[i + 1] >> 4) + 1;
        let name = format!(
            "{}{}",
            &prev[..common],
            std::str::from_utf8(&f[i + 2..i + 2 + len]).unwrap()
        );
        i += 2 + len;
        let value = u32::from_le_bytes(f[i..i + 4].try_into().unwrap());
        i += 4;
        let default = has_default.then(|| {
            i += 4;
            u32::from_le_bytes(f[i - 4..i].try_into().unwrap())
        });
        out.push((name.clone(), kind, value, default));
        prev = name;
    }
    (u16_at(0), u16_at(2), u16_at(4), out)
}

#[test]
fn param_pck_holds_every_parameter_and_no_value_straddles_a_block() {
    let mut r = Rig::new(files());
    let (opcode, size) = r.one(0, op::OPEN_FILE_RO, 0, b"@PARAM/param.pck");
    assert_eq!(opcode, op::ACK);
    let (f, end) = r.burst();
    assert_eq!((f.len() as u32).to_le_bytes().to_vec(), size);
    assert_eq!(end, err::EOF);
    let (magic, num, total, entries) = decode(&f);
    assert_eq!((magic, num, total), (param_pck::MAGIC, 5, 5));
    let names: Vec<_> = entries.iter().map(|e| e.0.as_str()).collect();
    assert_eq!(
        names,
        [
            "COM_OF_LOSS_T",
            "CTRL_TYPE",
            "MIS_TAKEOFF_ALT",
            "SYS_FAILURE_EN",
            "SIXTEEN_CHARS_XX"
        ]
    );
    assert_eq!(entries[0].2, 1.0f32.to_bits());
    assert_eq!((entries[1].1, entries[1].2), (3, 0));
    // a block of 16 bytes puts padding in; every value stays inside one block
    let small = param_pck::download("@PARAM/param.pck", &r.p, 16).unwrap();
    assert_eq!(decode(&small).3, entries);
    let mut i = 6;
    while i < small.len() {
        if small[i] == 0 {
            i += 1;
            continue;
        }
        let v = i + 2 + usize::from(small[i + 1] >> 4) + 1;
        assert_eq!(v / 16, (v + 3) / 16, "value at {v} straddles a block");
        i = v + 4;
    }
    let part = param_pck::download("@PARAM/param.pck?start=1&count=2", &r.p, 239).unwrap();
    let (_, num, total, entries) = decode(&part);
    assert_eq!((num, total, entries[0].0.as_str()), (2, 5, "CTRL_TYPE"));
    for bad in [
        "@PARAM/param.pck?withdefaults=2",
        "@PARAM/param.pck?start=5",
        "@PARAM/param.pck?count=65535",
    ] {
        assert!(param_pck::download(bad, &r.p, 239).is_err(), "{bad}");
    }
    assert!(!param_pck::is_param_path("@PARAM/param.pckx"));
}

/// A param.pck upload of `entries` (name, type, raw value).
fn upload_file(entries: &[(&str, u8, [u8; 4])]) -> Vec<u8> {
    let mut f = vec![0u8; 6];
    let mut prev = "";
    for (name, kind, raw) in entries {
        let common = name
            .bytes()
            .zip(prev.bytes())
            .take_while(|(a, b)| a == b)
            .count()
            .min(15);
        let rest = &name[common..];
        f.push(*kind);
        f.push(common as u8 | (((rest.len() - 1) as u8) << 4));
        f.extend_from_slice(rest.as_bytes());
        f.extend_from_slice(raw);
        prev = name;
    }
    let len = f.len() as u16;
    f[0..2].copy_from_slice(&param_pck::MAGIC.to_le_bytes());
    f[2..4].copy_from_slice(&(entries.len() as u16).to_le_bytes());
    f[4..6].copy_from_slice(&len.to_le_bytes());
    f
}

#[test]
fn a_param_pck_upload_sets_the_parameters_it_changes() {
    let mut r = Rig::new(files());
    let f = upload_file(&[
        ("COM_OF_LOSS_T", 4, 5.0f32.to_le_bytes()),
        ("CTRL_TYPE", 3, 0i32.to_le_bytes()),        // unchanged: no set
        ("NOT_A_PARAM", 3, 1i32.to_le_bytes()),      // unknown: skipped
        ("SYS_FAILURE_EN", 4, 1.0f32.to_le_bytes()), // float to an INT32 parameter
    ]);
    assert_eq!(r.one(0, op::CREATE_FILE, 0, b"@PARAM/param.pck").0, op::ACK);
    // the second chunk first: the order does not matter
    assert_eq!(r.one(0, op::WRITE_FILE, 10, &f[10..]).0, op::ACK);
    assert_eq!(r.one(0, op::WRITE_FILE, 0, &f[..10]).0, op::ACK);
    let (effects, out) = r.ask(0, op::TERMINATE_SESSION, 0, &[]);
    assert_eq!(out[0][3], op::ACK);
    let sets: Vec<_> = effects
        .iter()
        .map(|e| match e {
            Effect::SetParam { ticket, value } => (ticket.name.clone(), *value),
            other => panic!("{other:?}"),
        })
        .collect();
    assert_eq!(
        sets,
        vec![
            ("COM_OF_LOSS_T".to_string(), ParamValue::Real32(5.0)),
            ("SYS_FAILURE_EN".to_string(), ParamValue::Int32(1)),
        ]
    );
}

#[test]
fn a_broken_param_pck_upload_sets_nothing_and_is_nakked() {
    let good = upload_file(&[("COM_OF_LOSS_T", 4, 5.0f32.to_le_bytes())]);
    let mut wrong_count = good.clone();
    wrong_count[2] = 2;
    let mut bad_type = good.clone();
    bad_type[6] = 9;
    for (what, chunks) in [
        ("a gap", vec![(0u32, good[..4].to_vec()), (6, good[6..].to_vec())]),
        ("a wrong count", vec![(0, wrong_count)]),
        ("a bad type", vec![(0, bad_type)]),
        ("too long", vec![(0, good.clone()), (good.len() as u32, vec![1])]),
    ] {
        let mut r = Rig::new(files());
        assert_eq!(r.one(0, op::CREATE_FILE, 0, b"@PARAM/param.pck").0, op::ACK);
        for (ofs, c) in chunks {
            r.one(0, op::WRITE_FILE, ofs, &c);
        }
        let (effects, out) = r.ask(0, op::TERMINATE_SESSION, 0, &[]);
        assert_eq!((out[0][3], out[0][12]), (op::NAK, err::FAIL), "{what}");
        assert!(effects.is_empty(), "{what}");
    }
    let mut r = Rig::new(files());
    assert_eq!(r.one(0, op::CREATE_FILE, 0, b"@PARAM/param.pck").0, op::ACK);
    assert_eq!(
        r.one(0, op::WRITE_FILE, 65_530, b"0123456789"),
        (op::NAK, vec![err::FAIL])
    );
}

#[test]
fn a_request_reusing_the_last_seq_with_another_opcode_is_answered_anew() {
    let mut r = Rig::new(files());
    let open = request(10, 0, op::OPEN_FILE_RO, 0, b"/notes.txt");
    r.l.on_datagram(r.t, addr(14540), &open, &snapshot(), &r.p);
    assert_eq!(replies(&mut r.l)[0][5], op::OPEN_FILE_RO);
    // same seq, another opcode: a new request (a restarted client), not a resend
    let list = request(10, 0, op::LIST_DIRECTORY, 0, b"/");
    r.l.on_datagram(r.t, addr(14540), &list, &snapshot(), &r.p);
    let out = replies(&mut r.l);
    assert_eq!((out[0][3], out[0][5]), (op::ACK, op::LIST_DIRECTORY));
}

#[test]
fn a_long_crc32_is_summed_over_turns_and_a_resend_does_not_restart_it() {
    let mut store = MemStore::default();
    let big: Vec<u8> = (0..3_500_000u32).map(|i| (i * 31 + i / 7) as u8).collect();
    store.0.insert("big.bin".into(), big.clone());
    let mut r = Rig::new(store);
    let raw = request(20, 0, op::CALC_FILE_CRC32, 0, b"/big.bin");
    r.l.on_datagram(r.t, addr(14540), &raw, &snapshot(), &r.p);
    assert!(replies(&mut r.l).is_empty(), "not all of it in one turn");
    let mut answer = None;
    for turn in 1..10 {
        // the client resends while the vehicle sums: ignored, not restarted
        r.l.on_datagram(r.t, addr(14540), &raw, &snapshot(), &r.p);
        r.t += Duration::from_millis(2);
        r.l.poll(r.t, &snapshot(), 0);
        if let Some(p) = replies(&mut r.l).pop() {
            answer = Some((turn, p));
            break;
        }
    }
    let (turns, p) = answer.expect("answered");
    assert_eq!(turns, 3, "1 MiB a turn: 3.5 MB in four turns, the first at the request");
    assert_eq!(
        (p[3], p[5], u16::from_le_bytes([p[0], p[1]])),
        (op::ACK, op::CALC_FILE_CRC32, 21)
    );
    let want = crate::mission::crc::crc32part(&big, 0);
    assert_eq!(p[12..16], want.to_le_bytes());
    // a resend after the answer gets the answer kept
    r.l.on_datagram(r.t, addr(14540), &raw, &snapshot(), &r.p);
    assert_eq!(replies(&mut r.l), vec![p]);
}

/// A file of `size` bytes whose byte at `i` is `i as u8`.
#[derive(Debug)]
struct Pattern {
    size: u64,
}

impl ReadFile for Pattern {
    fn size(&self) -> Result<u64, FsError> {
        Ok(self.size)
    }
    fn read_at(&self, offset: u64, buf: &mut [u8]) -> Result<usize, FsError> {
        let n = usize::try_from(self.size.saturating_sub(offset))
            .unwrap_or(usize::MAX)
            .min(buf.len());
        for (k, b) in buf[..n].iter_mut().enumerate() {
            *b = (offset + k as u64) as u8;
        }
        Ok(n)
    }
}

#[test]
fn a_crc32_goes_on_past_four_gib() {
    // the sum started just below 2^32 (as after 4 GiB of turns) ends at the
    // file's end past 2^32 instead of wrapping round for ever
    let start = u64::from(u32::MAX) - 10;
    let size = u64::from(u32::MAX) + 100;
    let mut c = Crc {
        to: addr(14540),
        requester: (245, 190),
        req: header(&[0u8; 251]),
        file: Box::new(Pattern { size }),
        offset: start,
        crc: 0,
        due: Instant::now(),
    };
    let tail: Vec<u8> = (start..size).map(|i| i as u8).collect();
    assert_eq!(c.step(CRC_PER_TURN), Some(Ok(crate::mission::crc::crc32part(&tail, 0))));
    assert_eq!(c.offset, size);
}

#[test]
fn the_component_metadata_files_are_served_from_memory() {
    let mut r = Rig::new(files());
    for (path, want) in [
        (
            &b"/etc/extras/component_general.json"[..],
            crate::link::events::general_json(),
        ),
        (&b"etc/extras/all_events.json"[..], crate::link::events::events_json()),
    ] {
        let (opcode, size) = r.one(0, op::OPEN_FILE_RO, 0, path);
        assert_eq!(opcode, op::ACK);
        assert_eq!(size, (want.len() as u32).to_le_bytes().to_vec());
        let (f, end) = r.burst();
        assert_eq!((f.as_slice(), end), (want, err::EOF));
        assert_eq!(r.one(0, op::TERMINATE_SESSION, 0, &[]).0, op::ACK);
    }
    let (opcode, _) = r.one(0, op::CREATE_FILE, 0, b"/etc/extras/all_events.json");
    assert_eq!(opcode, op::ACK, "writing goes to the store, never to the metadata");
    assert_eq!(r.one(0, op::TERMINATE_SESSION, 0, &[]).0, op::ACK);
}
