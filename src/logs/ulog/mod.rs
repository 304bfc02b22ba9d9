//! PX4's ULog file format, written (sans I/O: any [`std::io::Write`]).
//!
//! The layout (<https://docs.px4.io/main/en/dev_log/ulog_file_format.html>),
//! every integer little-endian:
//!
//! ```text
//! header   'U' 'L' 'o' 'g' 0x01 0x12 0x35 | version u8 (1) | timestamp u64 [us]
//! message  msg_size u16 (bytes after these 3) | msg_type u8 | payload
//!   'B' flag bits      compat_flags[8] | incompat_flags[8] | appended_offsets u64[3]
//!   'F' format         "name:type field;type[n] field;..."
//!   'I' info           key_len u8 | key "type name" | value
//!   'P' parameter      as 'I', type int32_t or float
//!   'A' add logged     multi_id u8 | msg_id u16 | format name
//!   'D' data           msg_id u16 | the fields as the format lays them out (packed)
//!   'L' logged string  log_level u8 ('0' emergency .. '7' debug) | timestamp u64 [us] | text
//! ```
//!
//! The definitions section (`B` first, then `F`, `I`, `P`) precedes the data
//! section (`A`, `D`, `L`, and `P` for a parameter changed in flight). Every
//! format's first field is `uint64_t timestamp` [us]. Fields are packed in
//! the order given (no padding), as pyulog and PX4's readers read them.
//!
//! [`flight`] fills PX4-named topics from the lockstep core; [`read`] reads a
//! file back (the report page of a ULog).

pub mod flight;
pub mod read;

use std::io::{self, Write};

/// The file magic and version 1.
pub const MAGIC: [u8; 8] = [b'U', b'L', b'o', b'g', 0x01, 0x12, 0x35, 0x01];

/// A field's C type, as ULog names it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FieldType {
    /// `uint8_t`
    U8,
    /// `uint16_t`
    U16,
    /// `uint32_t`
    U32,
    /// `int32_t`
    I32,
    /// `uint64_t`
    U64,
    /// `float` (IEEE 754 binary32)
    F32,
    /// `double` (IEEE 754 binary64)
    F64,
    /// `bool` (one byte, 0 or 1)
    Bool,
}

impl FieldType {
    /// Every type.
    pub const ALL: [FieldType; 8] = [
        FieldType::U8,
        FieldType::U16,
        FieldType::U32,
        FieldType::I32,
        FieldType::U64,
        FieldType::F32,
        FieldType::F64,
        FieldType::Bool,
    ];

    /// The type a format message names `name`, if any.
    #[must_use]
    pub fn from_c_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|t| t.c_name() == name)
    }

    /// The name in a format message.
    #[must_use]
    pub fn c_name(self) -> &'static str {
        match self {
            FieldType::U8 => "uint8_t",
            FieldType::U16 => "uint16_t",
            FieldType::U32 => "uint32_t",
            FieldType::I32 => "int32_t",
            FieldType::U64 => "uint64_t",
            FieldType::F32 => "float",
            FieldType::F64 => "double",
            FieldType::Bool => "bool",
        }
    }

    /// Size [bytes].
    #[must_use]
    pub fn size(self) -> usize {
        match self {
            FieldType::U8 | FieldType::Bool => 1,
            FieldType::U16 => 2,
            FieldType::U32 | FieldType::I32 | FieldType::F32 => 4,
            FieldType::U64 | FieldType::F64 => 8,
        }
    }
}

/// A message format: a topic's name and its fields as the 'F' message
/// spells them, each `type name;` or `type[n] name;` (an array), packed in
/// that order, the first `uint64_t timestamp;`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Format {
    /// Topic name.
    pub name: &'static str,
    /// The fields, as the 'F' message spells them (`uint64_t timestamp;float[3] xyz;`).
    pub fields: &'static str,
}

impl Format {
    /// Bytes of one sample: the sum of the fields' sizes; `None` when a
    /// field is not `type name;` or `type[n] name;` of a [`FieldType`].
    #[must_use]
    pub fn size(&self) -> Option<usize> {
        if !self.fields.ends_with(';') {
            return None;
        }
        self.fields
            .split_terminator(';')
            .map(|field| {
                let (ty, _name) = field.split_once(' ')?;
                let (ty, len) = match ty.split_once('[') {
                    Some((ty, n)) => (ty, n.strip_suffix(']')?.parse::<usize>().ok()?),
                    None => (ty, 1),
                };
                Some(FieldType::from_c_name(ty)?.size() * len)
            })
            .sum()
    }

    /// The 'F' message text: `name:type field;type[n] field;...`.
    #[must_use]
    pub fn text(&self) -> String {
        format!("{}:{}", self.name, self.fields)
    }
}

/// A parameter or info value of a fixed-size type.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Value {
    /// `int32_t`
    I32(i32),
    /// `float`
    F32(f32),
}

/// The level of a logged string ('L'), the Linux kernel's (and PX4's).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LogLevel {
    /// '0'
    Emergency,
    /// '1'
    Alert,
    /// '2'
    Critical,
    /// '3'
    Error,
    /// '4'
    Warning,
    /// '5'
    Notice,
    /// '6'
    Info,
    /// '7'
    Debug,
}

impl LogLevel {
    /// The byte written: ASCII '0' + level.
    #[must_use]
    pub fn byte(self) -> u8 {
        b'0' + self as u8
    }
}

/// A sample's bytes, packed field by field in a format's order (little-endian).
#[derive(Clone, Debug, Default)]
pub struct Sample {
    bytes: Vec<u8>,
}

impl Sample {
    /// A sample starting with its `timestamp` [us].
    #[must_use]
    pub fn new(timestamp_us: u64) -> Self {
        let mut bytes = Vec::with_capacity(128);
        bytes.extend_from_slice(&timestamp_us.to_le_bytes());
        Self { bytes }
    }

    /// Append a `uint64_t`.
    #[must_use]
    pub fn u64(mut self, v: u64) -> Self {
        self.bytes.extend_from_slice(&v.to_le_bytes());
        self
    }

    /// Append a `uint32_t`.
    #[must_use]
    pub fn u32(mut self, v: u32) -> Self {
        self.bytes.extend_from_slice(&v.to_le_bytes());
        self
    }

    /// Append an `int32_t`.
    #[must_use]
    pub fn i32(mut self, v: i32) -> Self {
        self.bytes.extend_from_slice(&v.to_le_bytes());
        self
    }

    /// Append a `uint16_t`.
    #[must_use]
    pub fn u16(mut self, v: u16) -> Self {
        self.bytes.extend_from_slice(&v.to_le_bytes());
        self
    }

    /// Append a `uint8_t`.
    #[must_use]
    pub fn u8(mut self, v: u8) -> Self {
        self.bytes.push(v);
        self
    }

    /// Append a `bool`.
    #[must_use]
    pub fn bool(self, v: bool) -> Self {
        self.u8(u8::from(v))
    }

    /// Append a `float` (rounded from f64).
    #[must_use]
    pub fn f32(mut self, v: f64) -> Self {
        self.bytes.extend_from_slice(&(v as f32).to_le_bytes());
        self
    }

    /// Append a `float[n]`.
    #[must_use]
    pub fn f32s(mut self, v: &[f64]) -> Self {
        for x in v {
            self.bytes.extend_from_slice(&(*x as f32).to_le_bytes());
        }
        self
    }

    /// Append a `double`.
    #[must_use]
    pub fn f64(mut self, v: f64) -> Self {
        self.bytes.extend_from_slice(&v.to_le_bytes());
        self
    }

    /// The packed bytes.
    #[must_use]
    pub fn bytes(&self) -> &[u8] {
        &self.bytes
    }
}

/// Writes one ULog file: [`UlogWriter::new`] writes the header and flag
/// bits; then the definitions (`format`, `info_*`, `parameter`), then
/// the data (`add_logged`, `data`, `logged_string`, `parameter`).
#[derive(Debug)]
pub struct UlogWriter<W: Write> {
    w: W,
    next_msg_id: u16,
    /// The size of each subscribed message id's format (checked at `data`).
    sizes: Vec<usize>,
    buf: Vec<u8>,
}

impl<W: Write> UlogWriter<W> {
    /// Write the file header (magic, version 1, `timestamp_us` [us]: the
    /// log's start on the logging clock) and the flag bits (none set).
    ///
    /// # Errors
    /// Writing fails.
    pub fn new(mut w: W, timestamp_us: u64) -> io::Result<Self> {
        let mut head = Vec::with_capacity(16 + 3 + 40);
        head.extend_from_slice(&MAGIC);
        head.extend_from_slice(&timestamp_us.to_le_bytes());
        w.write_all(&head)?;
        let mut me = Self {
            w,
            next_msg_id: 0,
            sizes: Vec::new(),
            buf: Vec::with_capacity(256),
        };
        // compat_flags[8], incompat_flags[8] (no appended data), appended_offsets[3]
        me.message(b'B', &[0u8; 40])?;
        Ok(me)
    }

    fn message(&mut self, kind: u8, payload: &[u8]) -> io::Result<()> {
        let size = u16::try_from(payload.len())
            .map_err(|_| io::Error::new(io::ErrorKind::InvalidInput, "ULog message over 65535 bytes"))?;
        self.buf.clear();
        self.buf.extend_from_slice(&size.to_le_bytes());
        self.buf.push(kind);
        self.buf.extend_from_slice(payload);
        self.w.write_all(&self.buf)
    }

    /// 'F': define a format.
    ///
    /// # Errors
    /// Writing fails.
    pub fn format(&mut self, f: &Format) -> io::Result<()> {
        self.message(b'F', f.text().as_bytes())
    }

    fn key_value(&mut self, kind: u8, key: &str, value: &[u8]) -> io::Result<()> {
        let key_len = u8::try_from(key.len())
            .map_err(|_| io::Error::new(io::ErrorKind::InvalidInput, "ULog key over 255 bytes"))?;
        let mut p = Vec::with_capacity(1 + key.len() + value.len());
        p.push(key_len);
        p.extend_from_slice(key.as_bytes());
        p.extend_from_slice(value);
        self.message(kind, &p)
    }

    /// 'I': a string info (`char[len] name`).
    ///
    /// # Errors
    /// Writing fails.
    pub fn info_str(&mut self, name: &str, value: &str) -> io::Result<()> {
        self.key_value(b'I', &format!("char[{}] {name}", value.len()), value.as_bytes())
    }

    /// 'I': an `int32_t` or `float` info.
    ///
    /// # Errors
    /// Writing fails.
    pub fn info(&mut self, name: &str, value: Value) -> io::Result<()> {
        let (key, bytes) = typed(name, value);
        self.key_value(b'I', &key, &bytes)
    }

    /// 'P': a parameter (`int32_t` or `float`), at start or when it changes.
    ///
    /// # Errors
    /// Writing fails.
    pub fn parameter(&mut self, name: &str, value: Value) -> io::Result<()> {
        let (key, bytes) = typed(name, value);
        self.key_value(b'P', &key, &bytes)
    }

    /// 'A': subscribe to a format (instance `multi_id`); the message id its
    /// data messages carry. Ids count from 0 in subscription order.
    ///
    /// # Errors
    /// Writing fails, a format whose fields do not parse, or 65536
    /// subscriptions already.
    pub fn add_logged(&mut self, f: &Format, multi_id: u8) -> io::Result<u16> {
        let size = f.size().ok_or_else(|| {
            io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("ULog format {}: fields not `type name;` or `type[n] name;`", f.name),
            )
        })?;
        let id = self.next_msg_id;
        let mut p = Vec::with_capacity(3 + f.name.len());
        p.push(multi_id);
        p.extend_from_slice(&id.to_le_bytes());
        p.extend_from_slice(f.name.as_bytes());
        self.message(b'A', &p)?;
        self.next_msg_id = id
            .checked_add(1)
            .ok_or_else(|| io::Error::new(io::ErrorKind::InvalidInput, "too many ULog subscriptions"))?;
        self.sizes.push(size);
        Ok(id)
    }

    /// 'D': one sample of subscription `msg_id`.
    ///
    /// # Errors
    /// Writing fails, or the sample's size is not its format's (a bug).
    pub fn data(&mut self, msg_id: u16, sample: &Sample) -> io::Result<()> {
        let want = self.sizes.get(usize::from(msg_id)).copied();
        if want != Some(sample.bytes().len()) {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!(
                    "ULog sample of {} bytes for message id {msg_id} (format: {want:?})",
                    sample.bytes().len()
                ),
            ));
        }
        let mut p = Vec::with_capacity(2 + sample.bytes().len());
        p.extend_from_slice(&msg_id.to_le_bytes());
        p.extend_from_slice(sample.bytes());
        self.message(b'D', &p)
    }

    /// 'L': a logged string at `timestamp_us` [us].
    ///
    /// # Errors
    /// Writing fails.
    pub fn logged_string(&mut self, level: LogLevel, timestamp_us: u64, text: &str) -> io::Result<()> {
        let mut p = Vec::with_capacity(9 + text.len());
        p.push(level.byte());
        p.extend_from_slice(&timestamp_us.to_le_bytes());
        p.extend_from_slice(text.as_bytes());
        self.message(b'L', &p)
    }

    /// Flush the underlying writer.
    ///
    /// # Errors
    /// Flushing fails.
    pub fn flush(&mut self) -> io::Result<()> {
        self.w.flush()
    }

    /// The underlying writer.
    pub fn into_inner(self) -> W {
        self.w
    }
}

/// `("int32_t name" | "float name", little-endian bytes)`.
fn typed(name: &str, value: Value) -> (String, Vec<u8>) {
    match value {
        Value::I32(v) => (format!("int32_t {name}"), v.to_le_bytes().to_vec()),
        Value::F32(v) => (format!("float {name}"), v.to_le_bytes().to_vec()),
    }
}

/// The messages of a ULog file after its 16-byte header, in file order:
/// each message's type and payload (for tests that read a file back).
///
/// # Panics
/// The messages do not end at the file's end.
#[cfg(test)]
pub(crate) fn messages(file: &[u8]) -> Vec<(u8, &[u8])> {
    let mut out = Vec::new();
    let mut i = 16;
    while i + 3 <= file.len() {
        let size = usize::from(u16::from_le_bytes([file[i], file[i + 1]]));
        out.push((file[i + 2], &file[i + 3..i + 3 + size]));
        i += 3 + size;
    }
    assert_eq!(i, file.len(), "messages end at the file's end");
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    const TOPIC: Format = Format {
        name: "t",
        fields: "uint64_t timestamp;float[2] xy;bool ok;",
    };

    #[test]
    fn format_sizes_are_the_packed_fields() {
        assert_eq!(TOPIC.size(), Some(8 + 2 * 4 + 1));
        for bad in [
            "uint64_t timestamp",
            "int timestamp;",
            "float[x] a;",
            "float[2 a;",
            "bool;",
        ] {
            let f = Format { name: "t", fields: bad };
            assert_eq!(f.size(), None, "{bad}");
        }
        let mut w = UlogWriter::new(Vec::new(), 0).unwrap();
        let bad = Format {
            name: "t",
            fields: "int t;",
        };
        assert!(w.add_logged(&bad, 0).is_err());
    }

    #[test]
    fn header_and_flag_bits_are_the_spec_bytes() {
        let w = UlogWriter::new(Vec::new(), 0x0102_0304_0506_0708).unwrap();
        let b = w.into_inner();
        assert_eq!(&b[..7], b"ULog\x01\x12\x35");
        assert_eq!(b[7], 1, "file version 1");
        assert_eq!(&b[8..16], &[8, 7, 6, 5, 4, 3, 2, 1], "timestamp u64 little-endian");
        // 'B': size 40, type 'B', 40 zero bytes
        assert_eq!(&b[16..19], &[40, 0, b'B']);
        assert_eq!(b.len(), 16 + 3 + 40);
        assert!(b[19..].iter().all(|x| *x == 0));
    }

    #[test]
    fn format_subscription_and_data_messages() {
        let mut w = UlogWriter::new(Vec::new(), 0).unwrap();
        w.format(&TOPIC).unwrap();
        let id = w.add_logged(&TOPIC, 0).unwrap();
        assert_eq!(id, 0);
        w.data(id, &Sample::new(1000).f32s(&[1.5, -2.0]).bool(true)).unwrap();
        let b = w.into_inner();
        let b = &b[59..];
        let text = b"t:uint64_t timestamp;float[2] xy;bool ok;";
        assert_eq!(&b[..3], &[u8::try_from(text.len()).unwrap(), 0, b'F']);
        assert_eq!(&b[3..3 + text.len()], text);
        let b = &b[3 + text.len()..];
        // 'A': multi_id 0, msg_id 0, name "t"
        assert_eq!(&b[..7], &[4, 0, b'A', 0, 0, 0, b't']);
        let b = &b[7..];
        // 'D': msg_id u16 + 8 + 4 + 4 + 1 bytes
        assert_eq!(&b[..5], &[19, 0, b'D', 0, 0]);
        assert_eq!(&b[5..13], &1000u64.to_le_bytes());
        assert_eq!(&b[13..17], &1.5f32.to_le_bytes());
        assert_eq!(&b[17..21], &(-2.0f32).to_le_bytes());
        assert_eq!(b[21], 1);
        assert_eq!(b.len(), 22);
    }

    #[test]
    fn a_sample_of_the_wrong_size_is_refused() {
        let mut w = UlogWriter::new(Vec::new(), 0).unwrap();
        w.format(&TOPIC).unwrap();
        let id = w.add_logged(&TOPIC, 0).unwrap();
        assert!(w.data(id, &Sample::new(0).f32(1.0)).is_err());
        assert!(w.data(id + 1, &Sample::new(0).f32s(&[1.0, 2.0]).bool(false)).is_err());
    }

    #[test]
    fn info_parameter_and_logged_string_messages() {
        let mut w = UlogWriter::new(Vec::new(), 0).unwrap();
        w.info_str("sys_name", "rp").unwrap();
        w.parameter("MPC_XY_P", Value::F32(0.95)).unwrap();
        w.parameter("COM_ARM", Value::I32(-3)).unwrap();
        w.logged_string(LogLevel::Warning, 7, "hi").unwrap();
        let b = w.into_inner();
        let b = &b[59..];
        let key = b"char[2] sys_name";
        assert_eq!(
            &b[..4],
            &[
                u8::try_from(1 + key.len() + 2).unwrap(),
                0,
                b'I',
                u8::try_from(key.len()).unwrap()
            ]
        );
        assert_eq!(&b[4..4 + key.len()], key);
        assert_eq!(&b[4 + key.len()..6 + key.len()], b"rp");
        let b = &b[6 + key.len()..];
        let key = b"float MPC_XY_P";
        assert_eq!(b[2], b'P');
        assert_eq!(&b[4..4 + key.len()], key);
        assert_eq!(&b[4 + key.len()..8 + key.len()], &0.95f32.to_le_bytes());
        let b = &b[8 + key.len()..];
        let key = b"int32_t COM_ARM";
        assert_eq!(&b[4..4 + key.len()], key);
        assert_eq!(&b[4 + key.len()..8 + key.len()], &(-3i32).to_le_bytes());
        let b = &b[8 + key.len()..];
        assert_eq!(&b[..4], &[11, 0, b'L', b'4']);
        assert_eq!(&b[4..12], &7u64.to_le_bytes());
        assert_eq!(&b[12..], b"hi");
    }
}
