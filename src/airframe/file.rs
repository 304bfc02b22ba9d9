//! The airframe TOML schema and its validation.
//!
//! Every key carries its unit in its name; unknown keys are refused. Errors
//! name the file, the field (`body.mass_kg`, `rotors[3].angle_deg`, rotors
//! counted from 1 as they are labelled) and the problem; a value the file
//! spells out is also located by its line and column:
//!
//! ```text
//! quad.toml:19:27: rotor.radius_m: must be a finite number > 0, got 0
//! ```

use super::{
    Actuation, AeroCoefficients, Airframe, CeilingEffectParams, GroundEffectParams, RotorGeometry, RotorParams, Spin,
};
use crate::signals::{GRAVITY, MAX_ROTORS};
use nalgebra::Matrix3;

use crate::tomlfile::{self, FileError};
use serde::Deserialize;

/// Why an airframe could not be loaded.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum AirframeError {
    /// The file is unreadable, not valid TOML, or a value is wrong.
    #[error(transparent)]
    File(#[from] FileError),
    /// Neither a file nor a built-in airframe.
    #[error("unknown airframe `{name}`: not a file and not a built-in airframe ({builtin})")]
    Unknown {
        /// What was asked for.
        name: String,
        /// Built-in names.
        builtin: String,
    },
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileAirframe {
    name: String,
    #[serde(default)]
    description: String,
    actuation: FileActuation,
    body: FileBody,
    rotor: FileRotor,
    rotors: Vec<FileRotorGeometry>,
    ground_effect: FileGroundEffect,
    ceiling_effect: FileCeilingEffect,
    /// Optional aerodynamic coefficients (all 0 when absent).
    #[serde(default)]
    aero: FileAero,
    /// Optional controller gain overrides for this vehicle (checked by `control`).
    #[serde(default)]
    control: toml::Table,
}

#[derive(Deserialize, Clone, Copy)]
#[serde(rename_all = "lowercase")]
enum FileActuation {
    Rotors,
    Ideal,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileBody {
    mass_kg: f64,
    inertia_diag_kg_m2: [f64; 3],
    gear_height_m: f64,
    /// Rotational drag `gamma` [N m s] (`tau_d = -gamma omega`); absent: 0.
    #[serde(default)]
    rotational_drag_n_m_s: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileRotor {
    thrust_coefficient_n_s2: f64,
    torque_coefficient_n_m_s2: f64,
    radius_m: f64,
    time_constant_s: f64,
    speed_min_rad_s: f64,
    speed_max_rad_s: f64,
    #[serde(default)]
    inertia_kg_m2: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileRotorGeometry {
    angle_deg: f64,
    arm_m: f64,
    spin: Spin,
    #[serde(default)]
    motor: Option<usize>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileGroundEffect {
    body_coefficient: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileCeilingEffect {
    k1: f64,
    k2_m: f64,
}

/// The `[aero]` table: RotorPy's `Multirotor(aero=True)` coefficients, each 0 when absent.
#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
struct FileAero {
    c_dx: f64,
    c_dy: f64,
    c_dz: f64,
    k_d: f64,
    k_z: f64,
    k_h: f64,
    k_flap: f64,
}

pub(super) fn parse(text: &str, file: &str) -> Result<Airframe, AirframeError> {
    let raw: FileAirframe = tomlfile::parse(text, file)?;
    Ok(validate(raw, file).map_err(|e| at_its_line(e, text))?)
}

/// A value found wrong after parsing, moved to its line in `text` when the
/// file spells the field out (`file:line:column: field: problem`); as it
/// was otherwise (a default, or a problem of the whole file).
fn at_its_line(e: FileError, text: &str) -> FileError {
    if let FileError::Invalid { file, field, problem } = &e
        && let Some(at) = field_offset(text, field)
    {
        return tomlfile::error_at(text, file, at, format!("{field}: {problem}"));
    }
    e
}

/// Byte offset in `text` of the value a field name points at:
/// `body.mass_kg`, `rotors[2].arm_m` (rotors counted from 1) or
/// `body.inertia_diag_kg_m2 (x)` (the words after the path ignored).
fn field_offset(text: &str, field: &str) -> Option<usize> {
    use toml::de::{DeTable, DeValue};
    let path = field.split(' ').next()?;
    let doc = DeTable::parse(text).ok()?;
    let mut table = doc.get_ref();
    let mut segments = path.split('.').peekable();
    while let Some(segment) = segments.next() {
        let (key, label) = match segment.split_once('[') {
            Some((k, rest)) => (k, Some(rest.strip_suffix(']')?.parse::<usize>().ok()?)),
            None => (segment, None),
        };
        let mut value = table.get(key)?;
        if let Some(n) = label {
            let DeValue::Array(items) = value.get_ref() else {
                return None;
            };
            value = items.get(n.checked_sub(1)?)?;
        }
        if segments.peek().is_none() {
            return Some(value.span().start);
        }
        let DeValue::Table(t) = value.get_ref() else {
            return None;
        };
        table = t;
    }
    None
}

struct Checker<'a> {
    file: &'a str,
}

impl Checker<'_> {
    fn fail(&self, field: impl Into<String>, problem: impl Into<String>) -> FileError {
        FileError::invalid(self.file, field, problem)
    }

    /// `value` must be finite and strictly positive.
    fn positive(&self, field: &str, value: f64) -> Result<f64, FileError> {
        if value.is_finite() && value > 0.0 {
            Ok(value)
        } else {
            Err(self.fail(field, format!("must be a finite number > 0, got {value}")))
        }
    }

    /// `value` must be finite and not negative.
    fn non_negative(&self, field: &str, value: f64) -> Result<f64, FileError> {
        if value.is_finite() && value >= 0.0 {
            Ok(value)
        } else {
            Err(self.fail(field, format!("must be a finite number >= 0, got {value}")))
        }
    }
}

#[allow(clippy::too_many_lines)]
fn validate(raw: FileAirframe, file: &str) -> Result<Airframe, FileError> {
    let c = Checker { file };
    if raw.name.trim().is_empty() {
        return Err(c.fail("name", "must not be empty"));
    }
    let mass_kg = c.positive("body.mass_kg", raw.body.mass_kg)?;
    let [ixx, iyy, izz] = raw.body.inertia_diag_kg_m2;
    for (axis, v) in ["x", "y", "z"].iter().zip([ixx, iyy, izz]) {
        c.positive(&format!("body.inertia_diag_kg_m2 ({axis})"), v)?;
    }
    // Principal moments of a real body obey the triangle inequality.
    let slack = 1e-12 * (ixx + iyy + izz);
    if ixx + iyy + slack < izz || iyy + izz + slack < ixx || izz + ixx + slack < iyy {
        return Err(c.fail(
            "body.inertia_diag_kg_m2",
            format!("[{ixx}, {iyy}, {izz}] violates the triangle inequality of a rigid body (each moment <= sum of the other two)"),
        ));
    }
    let gear_height_m = c.non_negative("body.gear_height_m", raw.body.gear_height_m)?;
    let rotational_drag_n_m_s = c.non_negative("body.rotational_drag_n_m_s", raw.body.rotational_drag_n_m_s)?;

    let r = &raw.rotor;
    let rotor = RotorParams {
        c_t: c.positive("rotor.thrust_coefficient_n_s2", r.thrust_coefficient_n_s2)?,
        c_q: c.positive("rotor.torque_coefficient_n_m_s2", r.torque_coefficient_n_m_s2)?,
        radius_m: c.positive("rotor.radius_m", r.radius_m)?,
        time_constant_s: c.positive("rotor.time_constant_s", r.time_constant_s)?,
        speed_min_rad_s: c.non_negative("rotor.speed_min_rad_s", r.speed_min_rad_s)?,
        speed_max_rad_s: c.positive("rotor.speed_max_rad_s", r.speed_max_rad_s)?,
        inertia_kg_m2: c.non_negative("rotor.inertia_kg_m2", r.inertia_kg_m2)?,
    };
    if rotor.speed_max_rad_s <= rotor.speed_min_rad_s {
        return Err(c.fail(
            "rotor.speed_max_rad_s",
            format!(
                "must exceed rotor.speed_min_rad_s ({} <= {})",
                rotor.speed_max_rad_s, rotor.speed_min_rad_s
            ),
        ));
    }

    let n = raw.rotors.len();
    if !(3..=MAX_ROTORS).contains(&n) {
        return Err(c.fail(
            "rotors",
            format!("a flat multirotor needs 3 to {MAX_ROTORS} rotors, found {n}"),
        ));
    }
    let mut rotors = Vec::with_capacity(n);
    for (i, g) in raw.rotors.iter().enumerate() {
        let label = i + 1;
        if !g.angle_deg.is_finite() {
            return Err(c.fail(
                format!("rotors[{label}].angle_deg"),
                format!("must be finite, got {}", g.angle_deg),
            ));
        }
        let arm_m = c.positive(&format!("rotors[{label}].arm_m"), g.arm_m)?;
        let wrapped = g.angle_deg.rem_euclid(360.0);
        for (j, prev) in raw.rotors[..i].iter().enumerate() {
            let d = (prev.angle_deg.rem_euclid(360.0) - wrapped).abs();
            if d < 1e-6 || (360.0 - d) < 1e-6 {
                return Err(c.fail(
                    format!("rotors[{label}].angle_deg"),
                    format!("duplicate rotor angle {} deg (same as rotors[{}])", g.angle_deg, j + 1),
                ));
            }
        }
        rotors.push(RotorGeometry {
            angle_rad: g.angle_deg.to_radians(),
            arm_m,
            spin: g.spin,
            motor: motor_number(&c, &raw.rotors, i)?,
        });
    }
    for i in 0..n {
        for j in i + 1..n {
            let d = (rotors[i].position_frd() - rotors[j].position_frd()).norm();
            if d < 2.0 * rotor.radius_m {
                return Err(c.fail(
                    "rotor.radius_m",
                    format!(
                        "rotor disks of rotors[{}] and rotors[{}] overlap: hubs {d:.4} m apart, 2 x radius = {:.4} m",
                        i + 1,
                        j + 1,
                        2.0 * rotor.radius_m
                    ),
                ));
            }
        }
    }

    let ground_effect = GroundEffectParams {
        body_coefficient: c.non_negative("ground_effect.body_coefficient", raw.ground_effect.body_coefficient)?,
    };
    let ceiling_effect = CeilingEffectParams {
        k1: c.positive("ceiling_effect.k1", raw.ceiling_effect.k1)?,
        k2_m: c.positive("ceiling_effect.k2_m", raw.ceiling_effect.k2_m)?,
    };
    // Finite gain at contact needs k1 k2^2 > rho^2 (doc section 8).
    if ceiling_effect.k1 * ceiling_effect.k2_m.powi(2) <= rotor.radius_m.powi(2) {
        return Err(c.fail(
            "ceiling_effect.k2_m",
            format!(
                "k1 * k2_m^2 = {:.4e} must exceed rotor.radius_m^2 = {:.4e}, or the ceiling gain is infinite at contact",
                ceiling_effect.k1 * ceiling_effect.k2_m.powi(2),
                rotor.radius_m.powi(2)
            ),
        ));
    }

    let a = &raw.aero;
    let aero = AeroCoefficients {
        c_dx: c.non_negative("aero.c_dx", a.c_dx)?,
        c_dy: c.non_negative("aero.c_dy", a.c_dy)?,
        c_dz: c.non_negative("aero.c_dz", a.c_dz)?,
        k_d: c.non_negative("aero.k_d", a.k_d)?,
        k_z: c.non_negative("aero.k_z", a.k_z)?,
        k_h: c.non_negative("aero.k_h", a.k_h)?,
        k_flap: c.non_negative("aero.k_flap", a.k_flap)?,
    };

    let airframe = Airframe {
        name: raw.name.trim().to_string(),
        description: raw.description,
        source: file.to_string(),
        actuation: match raw.actuation {
            FileActuation::Rotors => Actuation::Rotors,
            FileActuation::Ideal => Actuation::Ideal,
        },
        mass_kg,
        inertia_kg_m2: Matrix3::from_diagonal(&nalgebra::Vector3::new(ixx, iyy, izz)),
        gear_height_m,
        rotational_drag_n_m_s,
        rotor,
        rotors,
        ground_effect,
        ceiling_effect,
        aero,
        control: raw.control,
    };
    let b = airframe.effectiveness();
    let rank = super::rank(&b);
    if rank < 4 {
        return Err(c.fail(
            "rotors",
            format!("the allocation matrix has rank {rank} < 4: this layout cannot command thrust, roll, pitch and yaw independently (check spins and angles)"),
        ));
    }
    if airframe.actuation == Actuation::Rotors {
        let max_thrust = airframe.max_thrust_n();
        if max_thrust <= mass_kg * GRAVITY {
            return Err(c.fail(
                "body.mass_kg",
                format!(
                    "{mass_kg} kg weighs {:.2} N but all rotors at rotor.speed_max_rad_s give only {max_thrust:.2} N: the vehicle cannot hover",
                    mass_kg * GRAVITY
                ),
            ));
        }
    }
    Ok(airframe)
}

/// The motor number of `rotors[i]` (from 0): its `motor`, which every rotor
/// gives or none does (then its place, from 1), each of 1 to n once.
fn motor_number(c: &Checker<'_>, rotors: &[FileRotorGeometry], i: usize) -> Result<usize, FileError> {
    let n = rotors.len();
    let field = format!("rotors[{}].motor", i + 1);
    let Some(m) = rotors[i].motor else {
        return match rotors.iter().position(|r| r.motor.is_some()) {
            Some(j) => Err(c.fail(
                field,
                format!("missing: rotors[{}] gives its motor number, so every rotor must", j + 1),
            )),
            None => Ok(i + 1),
        };
    };
    if !(1..=n).contains(&m) {
        return Err(c.fail(field, format!("must be a motor number from 1 to {n}, got {m}")));
    }
    if let Some(j) = rotors[..i].iter().position(|r| r.motor == Some(m)) {
        return Err(c.fail(field, format!("motor {m} is rotors[{}] already", j + 1)));
    }
    Ok(m)
}
