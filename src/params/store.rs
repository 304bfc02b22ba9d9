//! The typed parameter store: one value per [`PARAMS`] entry, in table order.

use super::{PARAMS, Param, ParamSpec, ParamType, ParamValue};
use crate::airframe::Airframe;

/// Why a parameter value was refused. The store is unchanged after any of these.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ParamError {
    /// No parameter has this name.
    #[error("unknown parameter {name}{}", super::did_you_mean(name))]
    Unknown {
        /// The name asked for.
        name: String,
    },
    /// The value has the wrong type (PX4 never converts).
    #[error("{name} is {expected}, got a {got} value {value}")]
    WrongType {
        /// Parameter name.
        name: &'static str,
        /// Its type.
        expected: ParamType,
        /// The type given.
        got: ParamType,
        /// The value given.
        value: ParamValue,
    },
    /// NaN or infinite.
    #[error("{name} = {value} is not a finite number")]
    NotFinite {
        /// Parameter name.
        name: &'static str,
        /// The value given.
        value: f64,
    },
    /// Outside the declared range.
    #[error("{name} = {value} is outside [{min}, {max}] {unit}")]
    OutOfRange {
        /// Parameter name.
        name: &'static str,
        /// The value given.
        value: f64,
        /// Smallest allowed value.
        min: f64,
        /// Largest allowed value.
        max: f64,
        /// Unit.
        unit: &'static str,
    },
}

/// Current values of every parameter in [`PARAMS`], with defaults that may
/// depend on the airframe (`SIM_MASS` and `MDL_MASS` default to its nominal mass).
#[derive(Clone, Debug, PartialEq)]
pub struct ParamStore {
    values: Vec<ParamValue>,
    defaults: Vec<ParamValue>,
    generation: u64,
}

impl ParamStore {
    /// Every parameter at its default for `airframe`.
    #[must_use]
    pub fn new(airframe: &Airframe) -> Self {
        let defaults: Vec<ParamValue> = PARAMS
            .iter()
            .enumerate()
            .map(|(i, spec)| match Param::ALL.get(i) {
                Some(Param::SIM_MASS | Param::MDL_MASS) => Self::airframe_mass(spec, airframe.mass_kg),
                _ => spec.default_value(),
            })
            .collect();
        Self {
            values: defaults.clone(),
            defaults,
            generation: 0,
        }
    }

    /// The airframe's mass as the default of a mass parameter, clamped into its range.
    fn airframe_mass(spec: &ParamSpec, mass_kg: f64) -> ParamValue {
        let m = mass_kg as f32;
        if m.is_finite() {
            ParamValue::Real32(m.clamp(spec.min as f32, spec.max as f32))
        } else {
            spec.default_value()
        }
    }

    /// Number of parameters (MAVLink `param_count`).
    #[must_use]
    pub fn len(&self) -> usize {
        self.values.len()
    }

    /// Whether there are no parameters (never: the table is not empty).
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.values.is_empty()
    }

    /// The declaration of parameter `index` (MAVLink `param_index`).
    #[must_use]
    pub fn spec(&self, index: usize) -> Option<&'static ParamSpec> {
        PARAMS.get(index)
    }

    /// Index of `name` (exact, case-sensitive, as PX4).
    #[must_use]
    pub fn index_of(&self, name: &str) -> Option<usize> {
        super::table::index_of(name)
    }

    /// Index and value of `name`.
    #[must_use]
    pub fn get(&self, name: &str) -> Option<(usize, ParamValue)> {
        let i = self.index_of(name)?;
        Some((i, self.values[i]))
    }

    /// The value of `p`.
    #[must_use]
    pub fn value(&self, p: Param) -> ParamValue {
        self.values[p as usize]
    }

    /// The value of `p` as `f64` (a REAL32 widened, an INT32 converted).
    #[must_use]
    pub fn real(&self, p: Param) -> f64 {
        self.value(p).as_f64()
    }

    /// The value of the INT32 parameter `p` (a REAL32 truncated towards zero).
    #[must_use]
    pub fn int(&self, p: Param) -> i32 {
        match self.value(p) {
            ParamValue::Int32(i) => i,
            ParamValue::Real32(f) => f as i32,
        }
    }

    /// Declaration and value of parameter `index`.
    #[must_use]
    pub fn by_index(&self, index: usize) -> Option<(&'static ParamSpec, ParamValue)> {
        Some((PARAMS.get(index)?, *self.values.get(index)?))
    }

    /// The value of `name` as `f64`, `None` if unknown.
    #[must_use]
    pub fn value_f64(&self, name: &str) -> Option<f64> {
        self.get(name).map(|(_, v)| v.as_f64())
    }

    /// The default in force for parameter `index` (airframe-dependent for the masses).
    #[must_use]
    pub fn default_value(&self, index: usize) -> Option<ParamValue> {
        self.defaults.get(index).copied()
    }

    /// Every parameter with its value, in index order.
    pub fn iter(&self) -> impl Iterator<Item = (&'static ParamSpec, ParamValue)> + '_ {
        PARAMS.iter().zip(self.values.iter().copied())
    }

    /// How many successful `set`s changed a value since construction (lets a
    /// caller notice that parameters must be applied again).
    #[must_use]
    pub fn generation(&self) -> u64 {
        self.generation
    }

    /// Check `value` for `spec` without storing it.
    ///
    /// # Errors
    /// Wrong type, not finite, out of range.
    pub fn check(spec: &'static ParamSpec, value: ParamValue) -> Result<(), ParamError> {
        if value.kind() != spec.kind {
            return Err(ParamError::WrongType {
                name: spec.name,
                expected: spec.kind,
                got: value.kind(),
                value,
            });
        }
        let in_range = match value {
            ParamValue::Int32(i) => {
                let x = f64::from(i);
                x >= spec.min && x <= spec.max
            }
            ParamValue::Real32(x) => {
                if !x.is_finite() {
                    return Err(ParamError::NotFinite {
                        name: spec.name,
                        value: f64::from(x),
                    });
                }
                // compare in f32: the f32 nearest to a bound (0.7 -> 0.69999998) must pass
                x >= spec.min as f32 && x <= spec.max as f32
            }
        };
        if in_range {
            Ok(())
        } else {
            Err(ParamError::OutOfRange {
                name: spec.name,
                value: value.as_f64(),
                min: spec.min,
                max: spec.max,
                unit: spec.unit,
            })
        }
    }

    /// Set `name` to `value` and return the value now stored (exactly the one
    /// given: nothing is clamped or converted, so PARAM_VALUE can echo it).
    ///
    /// # Errors
    /// Unknown name, wrong type, NaN or infinity, out of range; the store is
    /// then unchanged.
    pub fn set(&mut self, name: &str, value: ParamValue) -> Result<ParamValue, ParamError> {
        let index = self
            .index_of(name)
            .ok_or_else(|| ParamError::Unknown { name: name.to_string() })?;
        Self::check(&PARAMS[index], value)?;
        if self.values[index] != value {
            self.values[index] = value;
            self.generation += 1;
        }
        Ok(value)
    }

    /// Put every parameter back to its default.
    pub fn reset_to_defaults(&mut self) {
        if self.values != self.defaults {
            self.values.clone_from(&self.defaults);
            self.generation += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn store() -> ParamStore {
        ParamStore::new(&Airframe::load("quad").unwrap())
    }

    #[test]
    fn defaults_follow_the_table_and_the_airframe() {
        let s = store();
        assert_eq!(s.len(), PARAMS.len());
        assert_eq!(s.get("MIS_TAKEOFF_ALT"), Some((0, ParamValue::Real32(2.5))));
        assert_eq!(s.get("CTRL_TYPE").unwrap().1, ParamValue::Int32(1));
        let fsr = ParamStore::new(&Airframe::load("fsr-quad").unwrap());
        assert_eq!(fsr.get("SIM_MASS").unwrap().1, ParamValue::Real32(1.5));
        assert_eq!(fsr.get("MDL_MASS").unwrap().1, ParamValue::Real32(1.5));
        let (spec, v) = s.by_index(0).unwrap();
        assert_eq!(spec.name, "MIS_TAKEOFF_ALT");
        assert_eq!(v, ParamValue::Real32(2.5));
        assert!(s.by_index(s.len()).is_none());
        assert!(s.spec(s.len()).is_none());
        assert_eq!(s.iter().count(), s.len());
    }

    #[test]
    fn every_refusal_leaves_the_store_unchanged() {
        let mut s = store();
        let before = s.clone();
        let e = s.set("NO_SUCH_PARAM", ParamValue::Real32(1.0)).unwrap_err();
        assert!(matches!(e, ParamError::Unknown { .. }));
        assert!(e.to_string().contains("NO_SUCH_PARAM"));
        // case-sensitive, as PX4
        assert!(matches!(
            s.set("mis_takeoff_alt", ParamValue::Real32(3.0)),
            Err(ParamError::Unknown { .. })
        ));
        let e = s.set("CTRL_TYPE", ParamValue::Real32(1.0)).unwrap_err();
        assert!(matches!(
            e,
            ParamError::WrongType {
                name: "CTRL_TYPE",
                expected: ParamType::Int32,
                got: ParamType::Real32,
                ..
            }
        ));
        assert!(matches!(
            s.set("MIS_TAKEOFF_ALT", ParamValue::Int32(3)),
            Err(ParamError::WrongType { .. })
        ));
        for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            let e = s.set("MIS_TAKEOFF_ALT", ParamValue::Real32(bad)).unwrap_err();
            assert!(
                matches!(
                    e,
                    ParamError::NotFinite {
                        name: "MIS_TAKEOFF_ALT",
                        ..
                    }
                ),
                "{e}"
            );
        }
        let e = s.set("CTRL_TYPE", ParamValue::Int32(3)).unwrap_err();
        assert_eq!(
            e,
            ParamError::OutOfRange {
                name: "CTRL_TYPE",
                value: 3.0,
                min: 0.0,
                max: 2.0,
                unit: ""
            }
        );
        let e = s.set("MIS_TAKEOFF_ALT", ParamValue::Real32(-1.0)).unwrap_err();
        let msg = e.to_string();
        assert!(
            msg.contains("MIS_TAKEOFF_ALT") && msg.contains("-1") && msg.contains("outside [0, "),
            "{msg}"
        );
        assert!(s.set("EST_ORDER", ParamValue::Int32(0)).is_err());
        assert!(s.set("EST_ORDER", ParamValue::Int32(21)).is_err());
        assert!(s.set("SIM_MASS", ParamValue::Real32(0.0)).is_err());
        assert_eq!(s, before);
        assert_eq!(s.generation(), 0);
    }

    #[test]
    fn accepted_values_are_stored_exactly_including_bounds() {
        let mut s = store();
        assert_eq!(
            s.set("MPC_LAND_SPEED", ParamValue::Real32(0.2)),
            Ok(ParamValue::Real32(0.2))
        );
        assert_eq!(s.get("MPC_LAND_SPEED").unwrap().1, ParamValue::Real32(0.2));
        assert!(s.set("MPC_LAND_SPEED", ParamValue::Real32(2.0)).is_ok());
        assert!(s.set("EST_ORDER", ParamValue::Int32(20)).is_ok());
        assert!(s.set("COM_DISARM_LAND", ParamValue::Real32(-1.0)).is_ok());
        assert_eq!(s.generation(), 4);
        // setting the same value again is accepted and changes nothing
        assert!(s.set("EST_ORDER", ParamValue::Int32(20)).is_ok());
        assert_eq!(s.generation(), 4);
        s.reset_to_defaults();
        assert_eq!(s.get("EST_ORDER").unwrap().1, ParamValue::Int32(3));
        assert_eq!(s.generation(), 5);
    }
}
