//! Exact-float JSON: the one codec by which rotorpilot's own JSON files
//! (the flight record, the stored plans `missions.json`) keep every number
//! bit for bit.
//!
//! Written: an f64 in its shortest round-trip form (serde_json's
//! `float_roundtrip` parses it exactly); an f32 in its shortest form when
//! that reads back through a double to the same f32 (nearly always), else as
//! the double it is. JSON has no number for NaN and the infinities, so they
//! are strings: `"nan"` (the usual quiet NaN: `0x7ff8000000000000` as f64,
//! `0x7fc00000` as f32), `"nan:0x…"` (a NaN of other bits, in hexadecimal, 16
//! digits for an f64 and 8 for an f32), `"inf"` and `"-inf"`.
//!
//! Read: all of that, and also `"+inf"` and `null` for the quiet NaN where a
//! float (not an optional one) is expected, as `missions.json` was written
//! before this codec. A `"nan:0x…"` whose bits are no NaN of the width
//! asked for, and a number too large for an f32, are refused.
//!
//! [`to_value`] and [`from_value`] carry whole serde types through these
//! rules; [`f64_value`], [`f32_value`], [`f64_from`] and [`f32_from`] are the
//! rules for one number.

use serde::Deserializer;
use serde::de::value::{MapAccessDeserializer, MapDeserializer, SeqDeserializer};
use serde::de::{self, IntoDeserializer, Visitor};
use serde::ser::{self, Serialize};
use serde_json::{Map, Value};

/// `v` as a JSON value whose numbers read back bit for bit (module doc).
///
/// # Errors
/// A map key that is not a string or number.
pub fn to_value<T: Serialize + ?Sized>(v: &T) -> Result<Value, serde_json::Error> {
    v.serialize(ExactSer)
}

/// Read back what [`to_value`] wrote.
///
/// # Errors
/// `v` does not hold a `T`.
pub fn from_value<T: de::DeserializeOwned>(v: Value) -> Result<T, de::value::Error> {
    T::deserialize(Exact(v))
}

/// The JSON of a non-finite float: `"nan"`, `"nan:0x<bits>"`, `"inf"`, `"-inf"`.
fn nan_or_inf(is_nan: bool, positive: bool, canonical: bool, bits: String) -> Value {
    Value::String(match (is_nan, canonical) {
        (true, true) => "nan".into(),
        (true, false) => format!("nan:0x{bits}"),
        (false, _) => if positive { "inf" } else { "-inf" }.into(),
    })
}

/// The JSON of an f64 that reads back to the same bits (module doc).
#[must_use]
pub fn f64_value(v: f64) -> Value {
    if v.is_finite() {
        Value::from(v)
    } else {
        nan_or_inf(
            v.is_nan(),
            v > 0.0,
            v.to_bits() == f64::NAN.to_bits(),
            format!("{:016x}", v.to_bits()),
        )
    }
}

/// The JSON of an f32 that reads back to the same bits (module doc).
#[must_use]
pub fn f32_value(v: f32) -> Value {
    if v.is_finite() {
        let short = format!("{v:?}");
        match short.parse::<f64>() {
            // through a double, as serde_json reads it
            Ok(d) if (d as f32).to_bits() == v.to_bits() => Value::from(d),
            _ => Value::from(f64::from(v)),
        }
    } else {
        nan_or_inf(
            v.is_nan(),
            v > 0.0,
            v.to_bits() == f32::NAN.to_bits(),
            format!("{:08x}", v.to_bits()),
        )
    }
}

/// Why a JSON value is no float of the width asked for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FloatError {
    /// Neither a number, nor `null`, nor a string.
    NotAFloat,
    /// A string that names no NaN or infinity of the width.
    NotSpecial,
    /// A number too large for an f32 (the number).
    TooLarge(f64),
}

impl FloatError {
    /// What is wrong with `v`, in words.
    #[must_use]
    pub fn describe(self, v: &Value) -> String {
        match self {
            FloatError::NotAFloat | FloatError::NotSpecial => format!("expected a number, found {v}"),
            FloatError::TooLarge(d) => format!("{d} does not fit a 32-bit float"),
        }
    }
}

/// The non-finite float a string names, as f64 bits or f32 bits (module
/// doc); bits that are not a NaN of that width are refused: `None`.
fn special_bits(s: &str, f32_bits: bool) -> Option<u64> {
    match s {
        "nan" if f32_bits => Some(u64::from(f32::NAN.to_bits())),
        "nan" => Some(f64::NAN.to_bits()),
        "inf" | "+inf" if f32_bits => Some(u64::from(f32::INFINITY.to_bits())),
        "inf" | "+inf" => Some(f64::INFINITY.to_bits()),
        "-inf" if f32_bits => Some(u64::from(f32::NEG_INFINITY.to_bits())),
        "-inf" => Some(f64::NEG_INFINITY.to_bits()),
        _ => {
            let bits = u64::from_str_radix(s.strip_prefix("nan:0x")?, 16).ok()?;
            let is_nan = if f32_bits {
                f32::from_bits(u32::try_from(bits).ok()?).is_nan()
            } else {
                f64::from_bits(bits).is_nan()
            };
            is_nan.then_some(bits)
        }
    }
}

/// Read an f64 as [`f64_value`] writes it (and `null`, `"+inf"`: module doc).
///
/// # Errors
/// `v` is no f64.
pub fn f64_from(v: &Value) -> Result<f64, FloatError> {
    match v {
        Value::Null => Ok(f64::NAN),
        Value::Number(n) => Ok(n.as_f64().unwrap_or(f64::NAN)),
        Value::String(s) => special_bits(s, false).map(f64::from_bits).ok_or(FloatError::NotSpecial),
        _ => Err(FloatError::NotAFloat),
    }
}

/// Read an f32 as [`f32_value`] writes it (and `null`, `"+inf"`: module
/// doc); a plain number is rounded to f32.
///
/// # Errors
/// `v` is no f32.
pub fn f32_from(v: &Value) -> Result<f32, FloatError> {
    match v {
        Value::Null => Ok(f32::NAN),
        Value::Number(n) => {
            let d = n.as_f64().unwrap_or(f64::NAN);
            let f = d as f32;
            if f.is_finite() {
                Ok(f)
            } else {
                Err(FloatError::TooLarge(d))
            }
        }
        Value::String(s) => special_bits(s, true)
            .and_then(|b| u32::try_from(b).ok())
            .map(f32::from_bits)
            .ok_or(FloatError::NotSpecial),
        _ => Err(FloatError::NotAFloat),
    }
}

/// `fn $name(self, v: $ty) -> SerResult` for each integer: a JSON number.
macro_rules! serialize_as_number {
    ($($name:ident: $ty:ty),* $(,)?) => {
        $(fn $name(self, v: $ty) -> SerResult {
            Ok(Value::from(v))
        })*
    };
}

/// Serializes into a [`Value`] with [`f64_value`] / [`f32_value`] numbers.
struct ExactSer;

struct SeqSer(Vec<Value>);
struct VariantSeqSer(&'static str, Vec<Value>);
struct MapSer(Map<String, Value>, Option<String>);
struct VariantMapSer(&'static str, Map<String, Value>);

fn variant(name: &str, v: Value) -> Value {
    Value::Object(Map::from_iter([(name.to_string(), v)]))
}

type SerResult = Result<Value, serde_json::Error>;

impl ser::Serializer for ExactSer {
    type Ok = Value;
    type Error = serde_json::Error;
    type SerializeSeq = SeqSer;
    type SerializeTuple = SeqSer;
    type SerializeTupleStruct = SeqSer;
    type SerializeTupleVariant = VariantSeqSer;
    type SerializeMap = MapSer;
    type SerializeStruct = MapSer;
    type SerializeStructVariant = VariantMapSer;

    fn serialize_bool(self, v: bool) -> SerResult {
        Ok(Value::Bool(v))
    }
    serialize_as_number!(serialize_i8: i8, serialize_i16: i16, serialize_i32: i32, serialize_i64: i64,
        serialize_u8: u8, serialize_u16: u16, serialize_u32: u32, serialize_u64: u64);
    fn serialize_f32(self, v: f32) -> SerResult {
        Ok(f32_value(v))
    }
    fn serialize_f64(self, v: f64) -> SerResult {
        Ok(f64_value(v))
    }
    fn serialize_char(self, v: char) -> SerResult {
        Ok(Value::String(v.to_string()))
    }
    fn serialize_str(self, v: &str) -> SerResult {
        Ok(Value::String(v.to_string()))
    }
    fn serialize_bytes(self, v: &[u8]) -> SerResult {
        Ok(Value::Array(v.iter().map(|&b| Value::from(b)).collect()))
    }
    fn serialize_none(self) -> SerResult {
        Ok(Value::Null)
    }
    fn serialize_some<T: Serialize + ?Sized>(self, v: &T) -> SerResult {
        v.serialize(self)
    }
    fn serialize_unit(self) -> SerResult {
        Ok(Value::Null)
    }
    fn serialize_unit_struct(self, _: &'static str) -> SerResult {
        Ok(Value::Null)
    }
    fn serialize_unit_variant(self, _: &'static str, _: u32, name: &'static str) -> SerResult {
        Ok(Value::String(name.into()))
    }
    fn serialize_newtype_struct<T: Serialize + ?Sized>(self, _: &'static str, v: &T) -> SerResult {
        v.serialize(self)
    }
    fn serialize_newtype_variant<T: Serialize + ?Sized>(
        self,
        _: &'static str,
        _: u32,
        name: &'static str,
        v: &T,
    ) -> SerResult {
        Ok(variant(name, v.serialize(self)?))
    }
    fn serialize_seq(self, len: Option<usize>) -> Result<SeqSer, serde_json::Error> {
        Ok(SeqSer(Vec::with_capacity(len.unwrap_or(0))))
    }
    fn serialize_tuple(self, len: usize) -> Result<SeqSer, serde_json::Error> {
        self.serialize_seq(Some(len))
    }
    fn serialize_tuple_struct(self, _: &'static str, len: usize) -> Result<SeqSer, serde_json::Error> {
        self.serialize_seq(Some(len))
    }
    fn serialize_tuple_variant(
        self,
        _: &'static str,
        _: u32,
        name: &'static str,
        _: usize,
    ) -> Result<VariantSeqSer, serde_json::Error> {
        Ok(VariantSeqSer(name, Vec::new()))
    }
    fn serialize_map(self, _: Option<usize>) -> Result<MapSer, serde_json::Error> {
        Ok(MapSer(Map::new(), None))
    }
    fn serialize_struct(self, _: &'static str, _: usize) -> Result<MapSer, serde_json::Error> {
        self.serialize_map(None)
    }
    fn serialize_struct_variant(
        self,
        _: &'static str,
        _: u32,
        name: &'static str,
        _: usize,
    ) -> Result<VariantMapSer, serde_json::Error> {
        Ok(VariantMapSer(name, Map::new()))
    }
}

impl ser::SerializeSeq for SeqSer {
    type Ok = Value;
    type Error = serde_json::Error;
    fn serialize_element<T: Serialize + ?Sized>(&mut self, v: &T) -> Result<(), serde_json::Error> {
        self.0.push(v.serialize(ExactSer)?);
        Ok(())
    }
    fn end(self) -> SerResult {
        Ok(Value::Array(self.0))
    }
}

/// A tuple and a tuple struct serialize as a sequence: `impl ser::$trait
/// for SeqSer` whose `$method` is [`ser::SerializeSeq::serialize_element`].
macro_rules! like_a_seq {
    ($($trait:ident::$method:ident),*) => {
        $(impl ser::$trait for SeqSer {
            type Ok = Value;
            type Error = serde_json::Error;
            fn $method<T: Serialize + ?Sized>(&mut self, v: &T) -> Result<(), serde_json::Error> {
                ser::SerializeSeq::serialize_element(self, v)
            }
            fn end(self) -> SerResult {
                ser::SerializeSeq::end(self)
            }
        })*
    };
}

like_a_seq!(SerializeTuple::serialize_element, SerializeTupleStruct::serialize_field);

impl ser::SerializeTupleVariant for VariantSeqSer {
    type Ok = Value;
    type Error = serde_json::Error;
    fn serialize_field<T: Serialize + ?Sized>(&mut self, v: &T) -> Result<(), serde_json::Error> {
        self.1.push(v.serialize(ExactSer)?);
        Ok(())
    }
    fn end(self) -> SerResult {
        Ok(variant(self.0, Value::Array(self.1)))
    }
}

impl ser::SerializeMap for MapSer {
    type Ok = Value;
    type Error = serde_json::Error;
    fn serialize_key<T: Serialize + ?Sized>(&mut self, k: &T) -> Result<(), serde_json::Error> {
        self.1 = Some(match k.serialize(ExactSer)? {
            Value::String(s) => s,
            Value::Number(n) => n.to_string(),
            other => return Err(ser::Error::custom(format!("a map key must be a string, got {other}"))),
        });
        Ok(())
    }
    fn serialize_value<T: Serialize + ?Sized>(&mut self, v: &T) -> Result<(), serde_json::Error> {
        let k = self
            .1
            .take()
            .ok_or_else(|| ser::Error::custom("a map value without a key"))?;
        self.0.insert(k, v.serialize(ExactSer)?);
        Ok(())
    }
    fn end(self) -> SerResult {
        Ok(Value::Object(self.0))
    }
}

impl ser::SerializeStruct for MapSer {
    type Ok = Value;
    type Error = serde_json::Error;
    fn serialize_field<T: Serialize + ?Sized>(&mut self, k: &'static str, v: &T) -> Result<(), serde_json::Error> {
        self.0.insert(k.into(), v.serialize(ExactSer)?);
        Ok(())
    }
    fn end(self) -> SerResult {
        Ok(Value::Object(self.0))
    }
}

impl ser::SerializeStructVariant for VariantMapSer {
    type Ok = Value;
    type Error = serde_json::Error;
    fn serialize_field<T: Serialize + ?Sized>(&mut self, k: &'static str, v: &T) -> Result<(), serde_json::Error> {
        self.1.insert(k.into(), v.serialize(ExactSer)?);
        Ok(())
    }
    fn end(self) -> SerResult {
        Ok(variant(self.0, Value::Object(self.1)))
    }
}

/// Deserializes what [`ExactSer`] wrote: the spellings of [`f64_from`] and
/// [`f32_from`] where a float is expected.
struct Exact(Value);

type DeError = de::value::Error;

impl<'de> IntoDeserializer<'de, DeError> for Exact {
    type Deserializer = Self;
    fn into_deserializer(self) -> Self {
        self
    }
}

impl<'de> Deserializer<'de> for Exact {
    type Error = DeError;

    fn deserialize_any<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, DeError> {
        match self.0 {
            Value::Null => visitor.visit_unit(),
            Value::Bool(b) => visitor.visit_bool(b),
            Value::Number(n) => {
                if let Some(u) = n.as_u64() {
                    visitor.visit_u64(u)
                } else if let Some(i) = n.as_i64() {
                    visitor.visit_i64(i)
                } else {
                    visitor.visit_f64(n.as_f64().unwrap_or(f64::NAN))
                }
            }
            Value::String(s) => visitor.visit_string(s),
            Value::Array(a) => {
                let mut seq = SeqDeserializer::new(a.into_iter().map(Exact));
                let v = visitor.visit_seq(&mut seq)?;
                seq.end()?;
                Ok(v)
            }
            Value::Object(m) => {
                let mut map = MapDeserializer::new(m.into_iter().map(|(k, v)| (k, Exact(v))));
                let v = visitor.visit_map(&mut map)?;
                map.end()?;
                Ok(v)
            }
        }
    }

    fn deserialize_f64<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, DeError> {
        match f64_from(&self.0) {
            Ok(v) => visitor.visit_f64(v),
            Err(FloatError::NotAFloat) => self.deserialize_any(visitor),
            Err(e) => Err(de::Error::custom(e.describe(&self.0))),
        }
    }

    fn deserialize_f32<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, DeError> {
        match f32_from(&self.0) {
            Ok(v) => visitor.visit_f32(v),
            Err(FloatError::NotAFloat) => self.deserialize_any(visitor),
            Err(e) => Err(de::Error::custom(e.describe(&self.0))),
        }
    }

    fn deserialize_option<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, DeError> {
        match self.0 {
            Value::Null => visitor.visit_none(),
            v => visitor.visit_some(Exact(v)),
        }
    }

    fn deserialize_newtype_struct<V: Visitor<'de>>(self, _: &'static str, visitor: V) -> Result<V::Value, DeError> {
        visitor.visit_newtype_struct(self)
    }

    fn deserialize_enum<V: Visitor<'de>>(
        self,
        _: &'static str,
        _: &'static [&'static str],
        visitor: V,
    ) -> Result<V::Value, DeError> {
        match self.0 {
            Value::String(s) => visitor.visit_enum(s.into_deserializer()),
            Value::Object(m) if m.len() == 1 => visitor.visit_enum(MapAccessDeserializer::new(MapDeserializer::new(
                m.into_iter().map(|(k, v)| (k, Exact(v))),
            ))),
            other => Err(de::Error::custom(format!(
                "expected a variant name or {{\"Variant\": ...}}, found {other}"
            ))),
        }
    }

    serde::forward_to_deserialize_any! {
        bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 char str string bytes byte_buf unit unit_struct seq tuple
        tuple_struct map struct identifier ignored_any
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floats_read_back_bit_for_bit() {
        let specials = [
            f64::NAN,
            -f64::NAN,
            f64::from_bits(0x7ff8_0000_0000_0001),
            f64::INFINITY,
            f64::NEG_INFINITY,
            0.1,
            -0.0,
            f64::MIN_POSITIVE,
            5e-324,
            f64::MAX,
        ];
        let mut x: u64 = 0x9e37_79b9_7f4a_7c15;
        let mut values: Vec<f64> = specials.to_vec();
        for _ in 0..20_000 {
            // xorshift: arbitrary bit patterns
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            values.push(f64::from_bits(x));
        }
        for v in values {
            let back: f64 = from_value(serde_json::from_str(&f64_value(v).to_string()).unwrap()).unwrap();
            assert_eq!(back.to_bits(), v.to_bits(), "{v:?}");
            let f = f32::from_bits(x as u32 ^ v.to_bits() as u32);
            let back: f32 = from_value(serde_json::from_str(&f32_value(f).to_string()).unwrap()).unwrap();
            assert_eq!(back.to_bits(), f.to_bits(), "{f:?}");
        }
        for f in [
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::from_bits(0x7fc0_0001),
            0.1,
            16_777_217.0,
        ] {
            let back: f32 = from_value(serde_json::from_str(&f32_value(f).to_string()).unwrap()).unwrap();
            assert_eq!(back.to_bits(), f.to_bits(), "{f:?}");
        }
    }

    #[test]
    fn nan_bits_that_are_no_nan_are_refused() {
        let read64 = |s: &str| from_value::<f64>(Value::String(s.into())).map(f64::to_bits);
        let read32 = |s: &str| from_value::<f32>(Value::String(s.into())).map(f32::to_bits);
        assert_eq!(read64("nan:0x7ff8000000000001").unwrap(), 0x7ff8_0000_0000_0001);
        assert_eq!(read32("nan:0x7fc00001").unwrap(), 0x7fc0_0001);
        // 1.0, an infinity, zero: bit patterns that are no NaN
        for s in ["nan:0x3ff0000000000000", "nan:0x7ff0000000000000", "nan:0x0"] {
            let e = read64(s).unwrap_err().to_string();
            assert!(e.contains("expected a number"), "{s}: {e}");
        }
        for s in ["nan:0x3f800000", "nan:0x7f800000", "nan:0x7ff8000000000001"] {
            let e = read32(s).unwrap_err().to_string();
            assert!(e.contains("expected a number"), "{s}: {e}");
        }
    }

    #[test]
    fn older_spellings_read_too() {
        let v: Vec<f64> = from_value(serde_json::json!([null, "+inf", "nan"])).unwrap();
        assert_eq!(v[0].to_bits(), f64::NAN.to_bits());
        assert_eq!(v[1], f64::INFINITY);
        assert_eq!(v[2].to_bits(), f64::NAN.to_bits());
        assert_eq!(f32_from(&Value::Null).map(f32::to_bits), Ok(f32::NAN.to_bits()));
        // `null` stays "not given" where a value is optional
        let o: Option<f64> = from_value(Value::Null).unwrap();
        assert_eq!(o, None);
        assert_eq!(f32_from(&serde_json::json!(1e39)), Err(FloatError::TooLarge(1e39)));
    }
}
