//! `@PARAM/param.pck`: the parameter table as one packed file, PX4's
//! `ParamPckFile` (ArduPilot's `AP_Filesystem_Param` wire format):
//!
//! ```text
//! header: u16 magic (0x671B; 0x671C with defaults), u16 num_params (entries here),
//!         u16 total_params (download: all parameters; upload: the file's length in bytes)
//! entry:  u8 type:4 | flags:4   (3 int32, 4 float; upload also 1 int8, 2 int16; flag 1: default follows)
//!         u8 common_len:4 | (name_len - 1):4   (name bytes shared with the previous entry)
//!         name[name_len], value[4], default[4] when flagged
//! ```
//!
//! Zero bytes before an entry pad it so that its value (and default) never
//! straddles a read block of 239 bytes. The path takes a query
//! `?start=N&count=N&withdefaults=0|1` (count 0: all from start). A download
//! is the table as it was at open. An upload (CreateFile, WriteFile,
//! TerminateSession) takes magic 0x671B only, without defaults; its chunks
//! may come in any order (at most 65,535 bytes, the length the header can
//! name); unknown names are skipped, int8/int16 widened, and values
//! converted to the parameter's type as PX4 does. Unlike PX4, which sets
//! each entry as it completes, the parameters are set only once the whole
//! file has arrived well formed, so a broken upload changes nothing.

use crate::link::param::ParamAccess;
use crate::params::ParamValue;

const PATH: &str = "@PARAM/param.pck";
/// Header bytes.
pub const HEADER_LEN: usize = 6;
/// Magic of a file without defaults.
pub const MAGIC: u16 = 0x671B;
/// Magic of a file with defaults.
pub const MAGIC_WITH_DEFAULTS: u16 = 0x671C;
const TYPE_INT8: u8 = 1;
const TYPE_INT16: u8 = 2;
const TYPE_INT32: u8 = 3;
const TYPE_FLOAT: u8 = 4;

/// A file PX4 would not open, or an upload it would refuse.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Refused;

/// Whether `path` names the packed parameter file (with or without a query).
#[must_use]
pub fn is_param_path(path: &str) -> bool {
    path.strip_prefix(PATH)
        .is_some_and(|rest| rest.is_empty() || rest.starts_with('?'))
}

/// The query's `start`, `count` and `withdefaults` (PX4 reads them with
/// `strtoul`: digits up to the first non-digit, 0 for none).
fn query(path: &str) -> (u64, u64, u64) {
    let (mut start, mut count, mut with_defaults) = (0, 0, 0);
    let Some((_, q)) = path.split_once('?') else {
        return (0, 0, 0);
    };
    let num = |s: &str| -> u64 {
        let digits: String = s.chars().take_while(char::is_ascii_digit).take(19).collect();
        digits.parse().unwrap_or(0)
    };
    for part in q.split('&') {
        if let Some(v) = part.strip_prefix("start=") {
            start = num(v);
        } else if let Some(v) = part.strip_prefix("count=") {
            count = num(v);
        } else if let Some(v) = part.strip_prefix("withdefaults=") {
            with_defaults = num(v);
        }
    }
    (start, count, with_defaults)
}

fn bits(v: ParamValue) -> (u8, [u8; 4]) {
    match v {
        ParamValue::Int32(i) => (TYPE_INT32, i.to_le_bytes()),
        ParamValue::Real32(f) => (TYPE_FLOAT, f.to_le_bytes()),
    }
}

/// The file for `path` with every read of `block` bytes holding whole
/// values; `Err` for what PX4 refuses to open (a bad query, an empty range).
///
/// # Errors
/// `withdefaults` over 1, `count` of 65,535 or more, `start` past the last parameter.
pub fn download<P: ParamAccess + ?Sized>(path: &str, params: &P, block: usize) -> Result<Vec<u8>, Refused> {
    let (start, count, with_defaults) = query(path);
    let total = params.count();
    if start >= total as u64 || count >= u64::from(u16::MAX) || with_defaults > 1 || block == 0 || total > 4096 {
        return Err(Refused);
    }
    let start = start as usize;
    let mut num = total - start;
    if count > 0 && (count as usize) < num {
        num = count as usize;
    }
    let with_defaults = with_defaults == 1;
    let magic = if with_defaults { MAGIC_WITH_DEFAULTS } else { MAGIC };
    let mut out = Vec::new();
    out.extend_from_slice(&magic.to_le_bytes());
    out.extend_from_slice(&(num as u16).to_le_bytes());
    out.extend_from_slice(&(total as u16).to_le_bytes());
    let mut prev = String::new();
    for i in start..start + num {
        let Some((name, value)) = params.by_index(i) else {
            return Err(Refused);
        };
        let default = params
            .default_of(i)
            .filter(|d| with_defaults && bits(*d).1 != bits(value).1);
        let common = name.bytes().zip(prev.bytes()).take_while(|(a, b)| a == b).count();
        let (mut common, mut name_len) = (common, name.len() - common);
        if name_len == 0 {
            // the encoding cannot say an empty suffix
            name_len = 1;
            common -= 1;
        }
        if common + name_len > 16 || common > 15 {
            return Err(Refused);
        }
        let (kind, value_bytes) = bits(value);
        let data_len = 4 + if default.is_some() { 4 } else { 0 };
        let packed = 2 + name_len + data_len;
        let end_mod = (out.len() + packed) % block;
        if end_mod > 0 && end_mod < data_len {
            out.resize(out.len() + data_len - end_mod, 0);
        }
        out.push(kind | if default.is_some() { 0x10 } else { 0 });
        out.push(common as u8 | (((name_len - 1) as u8) << 4));
        out.extend_from_slice(&name.as_bytes()[common..]);
        out.extend_from_slice(&value_bytes);
        if let Some(d) = default {
            out.extend_from_slice(&bits(d).1);
        }
        prev = name.to_string();
    }
    Ok(out)
}

/// An upload being received: the bytes so far and which have arrived.
#[derive(Clone, Debug, Default)]
pub struct Upload {
    bytes: Vec<u8>,
    received: Vec<bool>,
    failed: bool,
}

/// The largest upload (the header names its length in a `u16`).
const MAX_UPLOAD: usize = u16::MAX as usize;

/// One entry of an upload: name, wire type and its raw value bytes.
pub type Entry = (String, u8, [u8; 4]);

impl Upload {
    /// WriteFile of `data` at `offset`.
    ///
    /// # Errors
    /// Past the largest file; then the upload has failed for good.
    pub fn write(&mut self, offset: u32, data: &[u8]) -> Result<(), Refused> {
        let end = offset as usize + data.len();
        if self.failed || end > MAX_UPLOAD {
            self.failed = true;
            return Err(Refused);
        }
        if end > self.bytes.len() {
            self.bytes.resize(end, 0);
            self.received.resize(end, false);
        }
        self.bytes[offset as usize..end].copy_from_slice(data);
        self.received[offset as usize..end].fill(true);
        Ok(())
    }

    /// The entries of a complete, well-formed file.
    ///
    /// # Errors
    /// A failed write, a gap, a wrong magic or length, a malformed entry,
    /// or fewer or more entries than the header says.
    pub fn finish(&self) -> Result<Vec<Entry>, Refused> {
        let b = &self.bytes;
        if self.failed || b.len() < HEADER_LEN || self.received.iter().any(|r| !r) {
            return Err(Refused);
        }
        let magic = u16::from_le_bytes([b[0], b[1]]);
        let num = usize::from(u16::from_le_bytes([b[2], b[3]]));
        let len = usize::from(u16::from_le_bytes([b[4], b[5]]));
        if magic != MAGIC || len != b.len() {
            return Err(Refused);
        }
        let mut entries = Vec::new();
        let mut prev = String::new();
        let mut i = HEADER_LEN;
        while i < b.len() {
            if b[i] == 0 {
                i += 1;
                continue;
            }
            let kind = b[i] & 0x0F;
            let flags = b[i] >> 4;
            let Some(&lens) = b.get(i + 1) else { return Err(Refused) };
            let common = usize::from(lens & 0x0F);
            let name_len = usize::from(lens >> 4) + 1;
            let vlen = match kind {
                TYPE_INT8 => 1,
                TYPE_INT16 => 2,
                TYPE_INT32 | TYPE_FLOAT => 4,
                _ => return Err(Refused),
            };
            if flags != 0 || common + name_len > 16 || common > prev.len() {
                return Err(Refused);
            }
            let name_start = i + 2;
            let value_start = name_start + name_len;
            let Some(raw) = b.get(value_start..value_start + vlen) else {
                return Err(Refused);
            };
            let suffix = std::str::from_utf8(&b[name_start..value_start]).map_err(|_| Refused)?;
            let name = format!("{}{suffix}", prev.get(..common).ok_or(Refused)?);
            let mut value = [0u8; 4];
            value[..vlen].copy_from_slice(raw);
            entries.push((name.clone(), kind, value));
            prev = name;
            i = value_start + vlen;
        }
        if entries.len() != num {
            return Err(Refused);
        }
        Ok(entries)
    }
}

/// An entry's value in the type of the parameter it sets (PX4
/// `apply_entry`: integers widened, a float to an INT32 parameter truncated
/// toward zero, an integer to a FLOAT parameter converted).
fn convert(kind: u8, raw: [u8; 4], to: ParamValue) -> Option<ParamValue> {
    let (as_int, as_float) = match kind {
        TYPE_INT8 => {
            let v = i32::from(raw[0].cast_signed());
            (v, v as f32)
        }
        TYPE_INT16 => {
            let v = i32::from(i16::from_le_bytes([raw[0], raw[1]]));
            (v, v as f32)
        }
        TYPE_INT32 => {
            let v = i32::from_le_bytes(raw);
            (v, v as f32)
        }
        TYPE_FLOAT => {
            let f = f32::from_le_bytes(raw);
            (f as i32, f)
        }
        _ => return None,
    };
    Some(match to {
        ParamValue::Int32(_) => ParamValue::Int32(as_int),
        ParamValue::Real32(_) => ParamValue::Real32(as_float),
    })
}

/// The sets an upload asks for: each known parameter whose value it
/// changes (bit for bit), in file order; unknown names are skipped.
#[must_use]
pub fn changes<P: ParamAccess + ?Sized>(entries: &[Entry], params: &P) -> Vec<(String, ParamValue)> {
    entries
        .iter()
        .filter_map(|(name, kind, raw)| {
            let (_, current) = params.by_name(name)?;
            let value = convert(*kind, *raw, current)?;
            (bits(value).1 != bits(current).1).then(|| (name.clone(), value))
        })
        .collect()
}
