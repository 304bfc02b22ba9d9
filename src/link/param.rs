//! The parameter protocol as PX4 speaks it: PARAM_REQUEST_LIST,
//! PARAM_REQUEST_READ (by name with index -1, else by index), PARAM_SET with
//! INT32 values carried bytewise in the float field, PARAM_VALUE answers, and
//! PARAM_ERROR for names that do not exist and for refused values (`docs/mavlink.md`
//! section 6).

use mavlink::dialects::common::{MavMessage, MavParamError, MavParamType, PARAM_ERROR_DATA, PARAM_VALUE_DATA};

use crate::params::ParamValue;

/// What the link needs of a parameter table. Implemented by
/// [`crate::params::ParamStore`]; tests use small fakes.
pub trait ParamAccess {
    /// Number of parameters (PARAM_VALUE `param_count`).
    fn count(&self) -> usize;
    /// Name and value of parameter `index` (0-based, table order).
    fn by_index(&self, index: usize) -> Option<(&str, ParamValue)>;
    /// Index and value of a parameter by name (exact, case-sensitive).
    fn by_name(&self, name: &str) -> Option<(usize, ParamValue)>;
    /// Set a parameter; the value actually stored, or why it was refused
    /// (and then nothing changed).
    ///
    /// # Errors
    /// Unknown name, wrong type, out of range or not finite.
    fn set(&mut self, name: &str, value: ParamValue) -> Result<ParamValue, String>;
    /// The default of parameter `index` (`None`: not known; PX4's
    /// `param.pck?withdefaults=1` then names none).
    fn default_of(&self, index: usize) -> Option<ParamValue>;
}

impl ParamAccess for crate::params::ParamStore {
    fn count(&self) -> usize {
        self.len()
    }

    fn by_index(&self, index: usize) -> Option<(&str, ParamValue)> {
        crate::params::ParamStore::by_index(self, index).map(|(spec, v)| (spec.name, v))
    }

    fn by_name(&self, name: &str) -> Option<(usize, ParamValue)> {
        self.get(name)
    }

    fn set(&mut self, name: &str, value: ParamValue) -> Result<ParamValue, String> {
        crate::params::ParamStore::set(self, name, value).map_err(|e| e.to_string())
    }

    fn default_of(&self, index: usize) -> Option<ParamValue> {
        self.default_value(index)
    }
}

/// A value as PX4 puts it on the wire: REAL32 as is, INT32 bytewise.
#[must_use]
pub fn to_wire(v: ParamValue) -> (f32, MavParamType) {
    match v {
        ParamValue::Int32(i) => (f32::from_bits(i.cast_unsigned()), MavParamType::MAV_PARAM_TYPE_INT32),
        ParamValue::Real32(f) => (f, MavParamType::MAV_PARAM_TYPE_REAL32),
    }
}

/// Read a PARAM_SET value: INT32 bytewise, REAL32 as is; other types are
/// not used by PX4 (`None`).
#[must_use]
pub fn from_wire(kind: MavParamType, value: f32) -> Option<ParamValue> {
    match kind {
        MavParamType::MAV_PARAM_TYPE_INT32 => Some(ParamValue::Int32(value.to_bits().cast_signed())),
        MavParamType::MAV_PARAM_TYPE_REAL32 => Some(ParamValue::Real32(value)),
        _ => None,
    }
}

/// Whether two values have the same type.
#[must_use]
pub fn same_type(a: ParamValue, b: ParamValue) -> bool {
    matches!(
        (a, b),
        (ParamValue::Int32(_), ParamValue::Int32(_)) | (ParamValue::Real32(_), ParamValue::Real32(_))
    )
}

/// A PARAM_VALUE message.
#[must_use]
pub fn param_value(name: &str, value: ParamValue, index: usize, count: usize) -> MavMessage {
    let (param_value, param_type) = to_wire(value);
    MavMessage::PARAM_VALUE(PARAM_VALUE_DATA {
        param_value,
        param_count: u16::try_from(count).unwrap_or(u16::MAX),
        param_index: u16::try_from(index).unwrap_or(u16::MAX),
        param_id: name.into(),
        param_type,
    })
}

/// A PARAM_ERROR message to a requester.
#[must_use]
pub fn param_error(name: &str, index: i16, error: MavParamError, to: (u8, u8)) -> MavMessage {
    MavMessage::PARAM_ERROR(PARAM_ERROR_DATA {
        param_index: index,
        target_system: to.0,
        target_component: to.1,
        param_id: name.into(),
        error,
    })
}

/// A param name from a 16-byte, null-padded `param_id` (no null when 16 long).
#[must_use]
pub fn name_of(id: &[u8; 16]) -> String {
    let end = id.iter().position(|b| *b == 0).unwrap_or(16);
    String::from_utf8_lossy(&id[..end]).into_owned()
}

/// Every parameter as PARAM_VALUE, in index order (so the last index is
/// last, which scripts stop on).
#[must_use]
pub fn list<P: ParamAccess + ?Sized>(params: &P) -> Vec<MavMessage> {
    let n = params.count();
    (0..n)
        .filter_map(|i| params.by_index(i).map(|(name, v)| param_value(name, v, i, n)))
        .collect()
}

/// The answer to PARAM_REQUEST_READ.
#[must_use]
pub fn read<P: ParamAccess + ?Sized>(params: &P, name: &str, index: i16, to: (u8, u8)) -> MavMessage {
    let n = params.count();
    let found = if index < 0 {
        params.by_name(name).map(|(i, v)| (i, name.to_string(), v))
    } else {
        params
            .by_index(index.cast_unsigned().into())
            .map(|(nm, v)| (index.cast_unsigned().into(), nm.to_string(), v))
    };
    match found {
        Some((i, nm, v)) => param_value(&nm, v, i, n),
        None => param_error(name, index, MavParamError::MAV_PARAM_ERROR_DOES_NOT_EXIST, to),
    }
}

/// The answer to a PARAM_SET.
#[derive(Clone, Debug, PartialEq)]
pub struct SetReply {
    /// Messages for the requester, in order.
    pub replies: Vec<MavMessage>,
    /// The parameter changed: its index and the PARAM_VALUE to rebroadcast.
    pub changed: Option<(usize, Box<MavMessage>)>,
    /// Why the set was refused (for STATUSTEXT).
    pub refused: Option<String>,
}

/// First half of a PARAM_SET: the name must exist and the value have the
/// parameter's type. `Ok((index, value))` to apply, or the refusal to send.
///
/// # Errors
/// The refusal: an unknown name gets only PARAM_ERROR (DOES_NOT_EXIST);
/// a wrong or unsupported type gets PARAM_ERROR and then PARAM_VALUE with
/// the unchanged value.
pub fn check_set<P: ParamAccess + ?Sized>(
    params: &P,
    name: &str,
    kind: MavParamType,
    raw: f32,
    to: (u8, u8),
) -> Result<(usize, ParamValue), SetReply> {
    let Some((index, current)) = params.by_name(name) else {
        return Err(SetReply {
            replies: vec![param_error(name, -1, MavParamError::MAV_PARAM_ERROR_DOES_NOT_EXIST, to)],
            changed: None,
            refused: Some(format!("unknown parameter {name}")),
        });
    };
    let Some(value) = from_wire(kind, raw) else {
        return Err(refusal(
            params,
            name,
            index,
            MavParamError::MAV_PARAM_ERROR_TYPE_UNSUPPORTED,
            format!("{name}: type {kind:?} not supported"),
            to,
        ));
    };
    if !same_type(value, current) {
        return Err(refusal(
            params,
            name,
            index,
            MavParamError::MAV_PARAM_ERROR_TYPE_MISMATCH,
            format!("{name} is {}, got a {} value", type_name(current), type_name(value)),
            to,
        ));
    }
    Ok((index, value))
}

/// Second half of a PARAM_SET, once the value was applied (`Ok`: the value
/// stored) or refused (`Err`: why; the table is unchanged): the echo and the
/// change to rebroadcast, or PARAM_ERROR and the unchanged PARAM_VALUE.
#[must_use]
pub fn finish_set<P: ParamAccess + ?Sized>(
    params: &P,
    name: &str,
    index: usize,
    outcome: Result<ParamValue, String>,
    to: (u8, u8),
) -> SetReply {
    match outcome {
        Ok(stored) => {
            let msg = param_value(name, stored, index, params.count());
            SetReply {
                replies: vec![msg.clone()],
                changed: Some((index, Box::new(msg))),
                refused: None,
            }
        }
        Err(why) => refusal(
            params,
            name,
            index,
            MavParamError::MAV_PARAM_ERROR_VALUE_OUT_OF_RANGE,
            why,
            to,
        ),
    }
}

fn refusal<P: ParamAccess + ?Sized>(
    params: &P,
    name: &str,
    index: usize,
    error: MavParamError,
    why: String,
    to: (u8, u8),
) -> SetReply {
    let mut replies = vec![param_error(name, i16::try_from(index).unwrap_or(-1), error, to)];
    if let Some((_, current)) = params.by_name(name) {
        replies.push(param_value(name, current, index, params.count()));
    }
    SetReply {
        replies,
        changed: None,
        refused: Some(why),
    }
}

/// A whole PARAM_SET on a table the caller owns: [`check_set`], then
/// [`ParamAccess::set`], then [`finish_set`].
pub fn set<P: ParamAccess + ?Sized>(
    params: &mut P,
    name: &str,
    kind: MavParamType,
    raw: f32,
    to: (u8, u8),
) -> SetReply {
    match check_set(params, name, kind, raw, to) {
        Err(reply) => reply,
        Ok((index, value)) => {
            let outcome = params.set(name, value);
            finish_set(params, name, index, outcome, to)
        }
    }
}

fn type_name(v: ParamValue) -> &'static str {
    match v {
        ParamValue::Int32(_) => "INT32",
        ParamValue::Real32(_) => "REAL32",
    }
}

#[cfg(test)]
mod tests;
