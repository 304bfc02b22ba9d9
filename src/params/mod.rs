//! Parameters declared once as data (PX4 style): name (<= 16 characters),
//! type, default, range, unit and description in one table; MAVLink's
//! PARAM_* protocol, the persisted file and the README table derive from it.
//!
//! (Types below are the contract with `link` and `autopilot`; the table,
//! store and persistence are being written.)

use serde::Serialize;

/// MAVLink parameter types rotorpilot uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum ParamType {
    /// MAV_PARAM_TYPE_INT32 (6), sent bytewise in the float field as PX4 does.
    Int32,
    /// MAV_PARAM_TYPE_REAL32 (9).
    Real32,
}

/// A typed parameter value.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub enum ParamValue {
    /// An integer.
    Int32(i32),
    /// A float.
    Real32(f32),
}

/// One declared parameter.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ParamSpec {
    /// MAVLink name, upper case, at most 16 characters.
    pub name: &'static str,
    /// Type.
    pub kind: ParamType,
    /// Default value.
    pub default: f64,
    /// Smallest allowed value.
    pub min: f64,
    /// Largest allowed value.
    pub max: f64,
    /// Unit (`m`, `m/s`, `N`, `kg`, `rad/s`, `s`, or empty).
    pub unit: &'static str,
    /// One-line description.
    pub description: &'static str,
}
