//! Reading a ULog file back (the report page's ULog input): the formats
//! ('F'), the subscriptions ('A'), the data ('D'), the info strings ('I')
//! and the logged strings ('L'), as pyulog reads them. Fields of the basic
//! types and arrays of them are read; a nested type is skipped over by its
//! size (its fields are not offered), as are padding fields (`_padding`).
//! Appended data and tagged strings ('C') are left out.

use std::collections::HashMap;

use super::MAGIC;

/// A basic field type as a reader meets it (PX4's logs use more types than
/// rotorpilot writes).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum FieldType {
    U8,
    I8,
    U16,
    I16,
    U32,
    I32,
    U64,
    I64,
    F32,
    F64,
    Bool,
    Char,
}

impl FieldType {
    fn from_c_name(name: &str) -> Option<Self> {
        Some(match name {
            "uint8_t" => Self::U8,
            "int8_t" => Self::I8,
            "uint16_t" => Self::U16,
            "int16_t" => Self::I16,
            "uint32_t" => Self::U32,
            "int32_t" => Self::I32,
            "uint64_t" => Self::U64,
            "int64_t" => Self::I64,
            "float" => Self::F32,
            "double" => Self::F64,
            "bool" => Self::Bool,
            "char" => Self::Char,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Self::U8 | Self::I8 | Self::Bool | Self::Char => 1,
            Self::U16 | Self::I16 => 2,
            Self::U32 | Self::I32 | Self::F32 => 4,
            Self::U64 | Self::I64 | Self::F64 => 8,
        }
    }
}

/// One field of a format, flattened: `name` or `name[k]` for array entries.
#[derive(Clone, Debug)]
struct Field {
    name: String,
    kind: FieldType,
    offset: usize,
}

/// A format: its size and its readable fields.
#[derive(Clone, Debug, Default)]
struct Layout {
    size: usize,
    fields: Vec<Field>,
}

/// A topic's samples: `timestamp` [us] and each field by name.
#[derive(Clone, Debug, Default)]
pub struct Topic {
    /// `timestamp` of each sample [us].
    pub timestamp_us: Vec<u64>,
    /// Each field's values (`name` or `name[k]`), as `f64`.
    pub fields: HashMap<String, Vec<f64>>,
}

impl Topic {
    /// Field `name`'s values (`None`: no such field).
    #[must_use]
    pub fn field(&self, name: &str) -> Option<&[f64]> {
        self.fields.get(name).map(Vec::as_slice)
    }
}

/// A ULog file read back.
#[derive(Clone, Debug, Default)]
pub struct UlogFile {
    /// Topics by name (multi-instance topics: instance 0 only).
    pub topics: HashMap<String, Topic>,
    /// Info strings ('I' of type `char[n]`) by key.
    pub info: HashMap<String, String>,
    /// Logged strings: (timestamp [us], level '0'..'7' as 0..7, text).
    pub logged: Vec<(u64, u8, String)>,
}

impl UlogFile {
    /// The topic `name`, if the log has samples of it.
    #[must_use]
    pub fn topic(&self, name: &str) -> Option<&Topic> {
        self.topics.get(name).filter(|t| !t.timestamp_us.is_empty())
    }
}

fn read_value(kind: FieldType, b: &[u8]) -> f64 {
    let a = |n: usize| -> [u8; 8] {
        let mut x = [0u8; 8];
        x[..n].copy_from_slice(&b[..n]);
        x
    };
    match kind {
        FieldType::U8 | FieldType::Bool | FieldType::Char => f64::from(b[0]),
        FieldType::I8 => f64::from(b[0] as i8),
        FieldType::U16 => f64::from(u16::from_le_bytes([b[0], b[1]])),
        FieldType::I16 => f64::from(i16::from_le_bytes([b[0], b[1]])),
        FieldType::U32 => f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
        FieldType::I32 => f64::from(i32::from_le_bytes([b[0], b[1], b[2], b[3]])),
        FieldType::U64 => u64::from_le_bytes(a(8)) as f64,
        FieldType::I64 => i64::from_le_bytes(a(8)) as f64,
        FieldType::F32 => f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
        FieldType::F64 => f64::from_le_bytes(a(8)),
    }
}

/// The layout of format `name` (nested formats resolved from `texts`).
fn layout(
    name: &str,
    texts: &HashMap<String, String>,
    cache: &mut HashMap<String, Layout>,
    depth: u8,
) -> Result<Layout, String> {
    if let Some(l) = cache.get(name) {
        return Ok(l.clone());
    }
    if depth > 8 {
        return Err(format!("format {name}: nested too deep"));
    }
    let text = texts
        .get(name)
        .ok_or_else(|| format!("format {name} is used but never defined"))?;
    let mut l = Layout::default();
    for decl in text.split(';').filter(|d| !d.trim().is_empty()) {
        let (ty, field) = decl
            .trim()
            .split_once(' ')
            .ok_or_else(|| format!("format {name}: bad field {decl:?}"))?;
        let (base, count) = match ty.split_once('[') {
            Some((b, n)) => (
                b,
                n.trim_end_matches(']')
                    .parse::<usize>()
                    .map_err(|_| format!("format {name}: bad array {ty:?}"))?,
            ),
            None => (ty, 1),
        };
        if let Some(kind) = FieldType::from_c_name(base) {
            if !field.starts_with("_padding") {
                for k in 0..count {
                    let n = if ty.contains('[') {
                        format!("{field}[{k}]")
                    } else {
                        field.to_string()
                    };
                    l.fields.push(Field {
                        name: n,
                        kind,
                        offset: l.size + k * kind.size(),
                    });
                }
            }
            l.size += count * kind.size();
        } else {
            let inner = layout(base, texts, cache, depth + 1)?;
            l.size += count * inner.size;
        }
    }
    cache.insert(name.to_string(), l.clone());
    Ok(l)
}

/// Read a ULog file; `file` labels the errors.
///
/// # Errors
/// Not a ULog (its magic), a message cut short, a format that cannot be laid out.
pub fn read_ulog(bytes: &[u8], file: &str) -> Result<UlogFile, String> {
    if bytes.len() < 16 || bytes[..7] != MAGIC[..7] {
        return Err(format!("{file}: not a ULog file (no ULog magic at its start)"));
    }
    let mut texts: HashMap<String, String> = HashMap::new();
    let mut cache: HashMap<String, Layout> = HashMap::new();
    // msg_id -> (topic name, layout), instance 0 only
    let mut subs: HashMap<u16, (String, Layout)> = HashMap::new();
    let mut out = UlogFile::default();
    let mut i = 16;
    while i + 3 <= bytes.len() {
        let size = usize::from(u16::from_le_bytes([bytes[i], bytes[i + 1]]));
        let kind = bytes[i + 2];
        let Some(body) = bytes.get(i + 3..i + 3 + size) else {
            // a log cut short by a killed writer: read what is whole
            break;
        };
        i += 3 + size;
        match kind {
            b'F' => {
                let s = String::from_utf8_lossy(body);
                if let Some((name, fields)) = s.split_once(':') {
                    texts.insert(name.to_string(), fields.to_string());
                }
            }
            b'I' if !body.is_empty() => {
                let klen = usize::from(body[0]);
                if let Some(key) = body.get(1..1 + klen) {
                    let key = String::from_utf8_lossy(key);
                    if let Some((ty, name)) = key.split_once(' ')
                        && ty.starts_with("char[")
                    {
                        let v = String::from_utf8_lossy(&body[1 + klen..]).to_string();
                        out.info.insert(name.to_string(), v);
                    }
                }
            }
            b'A' if body.len() >= 3 => {
                let multi = body[0];
                let id = u16::from_le_bytes([body[1], body[2]]);
                let name = String::from_utf8_lossy(&body[3..]).to_string();
                if multi == 0 {
                    let l = layout(&name, &texts, &mut cache, 0).map_err(|e| format!("{file}: {e}"))?;
                    out.topics.entry(name.clone()).or_default();
                    subs.insert(id, (name, l));
                }
            }
            b'D' if body.len() >= 2 => {
                let id = u16::from_le_bytes([body[0], body[1]]);
                let Some((name, l)) = subs.get(&id) else { continue };
                let d = &body[2..];
                if d.len() < l.size || l.size < 8 {
                    continue;
                }
                let topic = out.topics.entry(name.clone()).or_default();
                topic
                    .timestamp_us
                    .push(u64::from_le_bytes(d[..8].try_into().unwrap_or([0; 8])));
                for f in &l.fields {
                    topic
                        .fields
                        .entry(f.name.clone())
                        .or_default()
                        .push(read_value(f.kind, &d[f.offset..]));
                }
            }
            b'L' if body.len() >= 9 => {
                let level = body[0].saturating_sub(b'0');
                let t = u64::from_le_bytes(body[1..9].try_into().unwrap_or([0; 8]));
                out.logged
                    .push((t, level, String::from_utf8_lossy(&body[9..]).to_string()));
            }
            _ => {}
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::super::{Format, LogLevel, Sample, UlogWriter};
    use super::*;

    #[test]
    fn what_the_writer_wrote_reads_back() {
        let f = Format {
            name: "t",
            fields: "uint64_t timestamp;float[2] xy;bool ok;uint8_t[3] _padding0;",
        };
        let mut w = UlogWriter::new(Vec::new(), 0).unwrap();
        w.format(&f).unwrap();
        w.info_str("sys_name", "rotorpilot").unwrap();
        let id = w.add_logged(&f, 0).unwrap();
        for k in 0..3u8 {
            let s = Sample::new(u64::from(k) * 1000)
                .f32s(&[f64::from(k), -1.5])
                .bool(k == 1)
                .u8(0)
                .u8(0)
                .u8(0);
            w.data(id, &s).unwrap();
        }
        w.logged_string(LogLevel::Warning, 2500, "Failsafe: test").unwrap();
        let bytes = w.into_inner();
        let u = read_ulog(&bytes, "x.ulg").unwrap();
        let t = u.topic("t").unwrap();
        assert_eq!(t.timestamp_us, vec![0, 1000, 2000]);
        assert_eq!(t.field("xy[0]").unwrap(), &[0.0, 1.0, 2.0]);
        assert_eq!(t.field("xy[1]").unwrap(), &[-1.5; 3]);
        assert_eq!(t.field("ok").unwrap(), &[0.0, 1.0, 0.0]);
        assert!(t.field("_padding0[0]").is_none());
        assert_eq!(u.info["sys_name"], "rotorpilot");
        assert_eq!(u.logged, vec![(2500, 4, "Failsafe: test".to_string())]);
        assert!(read_ulog(b"{\"header\":1}\n", "x").unwrap_err().contains("not a ULog"));
    }
}
