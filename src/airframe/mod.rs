//! Vehicle description: mass, inertia, rotor geometry and coefficients, read
//! from a TOML file (`params/airframes/*.toml`, or any file given by path).
//!
//! A flat multirotor's rotor `i` sits at `r_i = l_i [cos a_i, sin a_i, 0]` in
//! FRD, with the arm angle `a_i` measured from `x_b` towards `y_b` (clockwise
//! seen from above) and spin sign `s_i = +1` for counter-clockwise seen from
//! above (`docs/model.md` sections 2-3). Thrust `T_i = c_T w_i^2`
//! along `-z_b`, drag torque `s_i c_Q w_i^2` about `+z_b`.
//!
//! The mass and inertia here are the *nominal* ones that controllers and
//! estimators see; the plant ([`crate::sim::Plant`]) starts from them and may
//! be given a different true mass and inertia.

mod allocation;
mod failure;
mod file;
mod report;

pub use allocation::{Allocation, Allocator, YawPriority, effectiveness, rank, wrench_map};
pub use failure::{
    FailureAnalysis, HoverVerdict, TorqueMargins, analyse_failures, degraded_verdict, hover_margins, intact_verdict,
};
pub use file::AirframeError;
pub use report::AirframeReport;

use nalgebra::{Matrix3, Vector3};
use serde::Serialize;

/// How commands reach the rigid body.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Actuation {
    /// Rotor speeds go through first-order motor lag and speed limits; the
    /// wrench is `B w` with `w = omega^2`.
    Rotors,
    /// The commanded total thrust and body torque act directly (the origin
    /// report's Simulink model); rotor geometry is used only for ground and
    /// ceiling effect.
    Ideal,
}

/// Rotor spin direction seen from above.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Spin {
    /// Clockwise seen from above: `s = -1` (yaws the body counter-clockwise).
    Cw,
    /// Counter-clockwise seen from above: `s = +1` (yaws the body clockwise, positive FRD yaw).
    Ccw,
}

impl Spin {
    /// The sign `s_i` of the drag reaction `s_i c_Q w_i^2` about `+z_b`.
    #[must_use]
    pub fn sign(self) -> f64 {
        match self {
            Spin::Cw => -1.0,
            Spin::Ccw => 1.0,
        }
    }
}

/// Where one rotor sits, which way it spins, and the number a client calls it by.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct RotorGeometry {
    /// Arm angle `a_i` [rad] from `x_b` towards `y_b`.
    pub angle_rad: f64,
    /// Arm length `l_i` [m] from the centre of mass.
    pub arm_m: f64,
    /// Spin direction.
    pub spin: Spin,
    /// Its motor number, from 1: the number PX4 gives the motor in this
    /// place on its airframe of the same layout (output function Motor N,
    /// `CA_ROTOR{N-1}`), which MAV_CMD_INJECT_FAILURE's instance, the
    /// channels of ACTUATOR_OUTPUT_STATUS and the motor STATUSTEXTs count
    /// by. By default the rotor's place in the airframe file.
    pub motor: usize,
}

impl RotorGeometry {
    /// Rotor hub position `r_i = l_i [cos a_i, sin a_i, 0]` [m], body FRD.
    #[must_use]
    pub fn position_frd(&self) -> Vector3<f64> {
        Vector3::new(
            self.arm_m * self.angle_rad.cos(),
            self.arm_m * self.angle_rad.sin(),
            0.0,
        )
    }
}

/// Properties shared by all rotors of a vehicle.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct RotorParams {
    /// Thrust coefficient `c_T` [N s^2]: `T = c_T omega^2`.
    pub c_t: f64,
    /// Drag-torque coefficient `c_Q` [N m s^2]: `Q = c_Q omega^2`.
    pub c_q: f64,
    /// Rotor radius `rho` [m] (ground and ceiling effect).
    pub radius_m: f64,
    /// Motor first-order time constant `tau_m` [s].
    pub time_constant_s: f64,
    /// Lowest commandable speed (idle) [rad/s].
    pub speed_min_rad_s: f64,
    /// Highest speed [rad/s].
    pub speed_max_rad_s: f64,
    /// Rotor + motor-bell inertia about the spin axis `J_r` [kg m^2] (gyroscopic torque).
    pub inertia_kg_m2: f64,
}

/// Ground-effect model constants (doc section 8).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct GroundEffectParams {
    /// Empirical body-lift coefficient `K_b` (0 = pure rotor-image model).
    pub body_coefficient: f64,
}

/// Ceiling-effect model constants: `T/T_oce = 1 / (1 - (rho/(z + k2))^2 / k1)` (doc section 8).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct CeilingEffectParams {
    /// `k1` (dimensionless, > 0).
    pub k1: f64,
    /// `k2` [m] (> 0).
    pub k2_m: f64,
}

/// Aerodynamic coefficients of body and rotors: exactly the terms of
/// RotorPy 3.0.0's `Multirotor(aero=True)` (`docs/model.md` section 8b), read
/// from the airframe file's optional `[aero]` table. Every coefficient is
/// `>= 0` and 0 when absent; all 0 means no aerodynamic force at all.
///
/// With `v` the body-FRD airspeed of the centre of mass and `v_i = v + omega x r_i`
/// the airspeed of hub `i`:
/// * parasitic drag at the centre of mass: `D = -|v| diag(c_dx, c_dy, c_dz) v`;
/// * rotor drag at hub `i`: `H_i = -omega_i diag(k_d, k_d, k_z) v_i`;
/// * translational lift: thrust `T_i += k_h (v_i,x^2 + v_i,y^2)` along `-z_b`;
/// * flapping moment: `M_i = -k_flap omega_i (e_z x v_i)` (FRD, see the model doc).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct AeroCoefficients {
    /// Parasitic drag along body `x_b` [N/(m/s)^2] (RotorPy `c_Dx`).
    pub c_dx: f64,
    /// Parasitic drag along body `y_b` [N/(m/s)^2] (RotorPy `c_Dy`).
    pub c_dy: f64,
    /// Parasitic drag along body `z_b` [N/(m/s)^2] (RotorPy `c_Dz`).
    pub c_dz: f64,
    /// Rotor drag in the rotor plane [N/(rad/s)/(m/s)] (RotorPy `k_d`).
    pub k_d: f64,
    /// Induced-inflow drag along the rotor axis [N/(rad/s)/(m/s)] (RotorPy `k_z`).
    pub k_z: f64,
    /// Translational lift [N/(m/s)^2] (RotorPy `k_h`).
    pub k_h: f64,
    /// Blade-flapping moment [N m/(rad/s)/(m/s)] (RotorPy `k_flap`).
    pub k_flap: f64,
}

impl AeroCoefficients {
    /// Whether every coefficient is 0 (the body feels no air at all).
    #[must_use]
    pub fn is_zero(&self) -> bool {
        *self == Self::default()
    }
}

/// A validated vehicle description.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Airframe {
    /// Short name (`quad`, `octo`, ...).
    pub name: String,
    /// One-line description.
    pub description: String,
    /// Where it was read from (a path, or `built-in NAME`).
    pub source: String,
    /// How commands act on the body.
    pub actuation: Actuation,
    /// Nominal mass [kg].
    pub mass_kg: f64,
    /// Nominal inertia about the centre of mass [kg m^2], body FRD.
    #[serde(serialize_with = "serialize_matrix3")]
    pub inertia_kg_m2: Matrix3<f64>,
    /// Height of the centre of mass above flat ground when resting on it [m].
    pub gear_height_m: f64,
    /// Rotational (aerodynamic) drag coefficient `gamma` [N m s]: the body
    /// torque `tau_d = -gamma omega` (FRD, `omega` the body rates; Mueller and
    /// D'Andrea's relaxed-hover model, doc section 3b). 0 (no drag) unless the
    /// file's `body.rotational_drag_n_m_s` says otherwise.
    pub rotational_drag_n_m_s: f64,
    /// Rotor coefficients and limits.
    pub rotor: RotorParams,
    /// Rotor layout, in label order (rotor 1 first).
    pub rotors: Vec<RotorGeometry>,
    /// Ground-effect constants.
    pub ground_effect: GroundEffectParams,
    /// Ceiling-effect constants.
    pub ceiling_effect: CeilingEffectParams,
    /// Aerodynamic drag, lift and flapping coefficients (all 0 unless the file has an `[aero]` table).
    pub aero: AeroCoefficients,
    /// The file's `[control]` table as written: controller gain overrides that
    /// `control::ControlGains::for_airframe` reads, applies and checks (the
    /// airframe does not know the control laws).
    pub control: toml::Table,
}

fn serialize_matrix3<S: serde::Serializer>(m: &Matrix3<f64>, s: S) -> Result<S::Ok, S::Error> {
    let rows: [[f64; 3]; 3] = [
        [m[(0, 0)], m[(0, 1)], m[(0, 2)]],
        [m[(1, 0)], m[(1, 1)], m[(1, 2)]],
        [m[(2, 0)], m[(2, 1)], m[(2, 2)]],
    ];
    rows.serialize(s)
}

/// The airframes shipped with rotorpilot, embedded in the binary: `(name, TOML text)`.
pub const BUILTIN: &[(&str, &str)] = &[
    ("quad", include_str!("../../params/airframes/quad.toml")),
    ("hexa", include_str!("../../params/airframes/hexa.toml")),
    ("octo", include_str!("../../params/airframes/octo.toml")),
    ("fsr-quad", include_str!("../../params/airframes/fsr-quad.toml")),
    ("hexa-ppnnpn", include_str!("../../params/airframes/hexa-ppnnpn.toml")),
];

/// The default vehicle.
pub const DEFAULT_AIRFRAME: &str = "quad";

impl Airframe {
    /// Load a built-in airframe by name, or a file by path.
    ///
    /// # Errors
    /// [`AirframeError`] naming the file, the field and the problem.
    pub fn load(name_or_path: &str) -> Result<Self, AirframeError> {
        let (text, label) = Self::load_text(name_or_path)?;
        Self::from_toml(&text, &label)
    }

    /// The TOML text [`Self::load`] parses for a built-in name or a file
    /// path, with the label its messages name (a flight record keeps both,
    /// so that a replay rebuilds the airframe without the file).
    ///
    /// # Errors
    /// As [`Self::load`]: unknown name, unreadable file.
    pub fn load_text(name_or_path: &str) -> Result<(String, String), AirframeError> {
        let path = std::path::Path::new(name_or_path);
        if path.is_file() {
            return Ok((crate::tomlfile::read(path)?, path.display().to_string()));
        }
        if let Some((name, text)) = BUILTIN.iter().find(|(n, _)| *n == name_or_path) {
            return Ok((
                (*text).to_string(),
                format!("built-in {name} (params/airframes/{name}.toml)"),
            ));
        }
        if name_or_path.contains('/') || name_or_path.ends_with(".toml") {
            return Err(crate::tomlfile::FileError::Io {
                file: name_or_path.to_string(),
                message: "no such file".into(),
            }
            .into());
        }
        Err(AirframeError::Unknown {
            name: name_or_path.to_string(),
            builtin: BUILTIN.iter().map(|(n, _)| *n).collect::<Vec<_>>().join(", "),
        })
    }

    /// Read and validate an airframe file.
    ///
    /// # Errors
    /// [`AirframeError`] naming the file, the field and the problem.
    pub fn from_file(path: &std::path::Path) -> Result<Self, AirframeError> {
        let text = crate::tomlfile::read(path)?;
        Self::from_toml(&text, &path.display().to_string())
    }

    /// Parse and validate airframe TOML; `file` labels error messages.
    ///
    /// # Errors
    /// [`AirframeError`] naming the file, the field and the problem.
    pub fn from_toml(text: &str, file: &str) -> Result<Self, AirframeError> {
        file::parse(text, file)
    }

    /// The nominal model controllers and estimators see.
    #[must_use]
    pub fn nominal(&self) -> crate::signals::NominalModel {
        crate::signals::NominalModel {
            mass_kg: self.mass_kg,
            inertia_kg_m2: self.inertia_kg_m2,
        }
    }

    /// Number of rotors.
    #[must_use]
    pub fn rotor_count(&self) -> usize {
        self.rotors.len()
    }

    /// The rotor (from 0) whose motor number is `motor` ([`RotorGeometry::motor`]), if any.
    #[must_use]
    pub fn rotor_of_motor(&self, motor: usize) -> Option<usize> {
        self.rotors.iter().position(|r| r.motor == motor)
    }

    /// The motor number of rotor `i` (from 0; [`RotorGeometry::motor`]), or `i + 1` past the rotors.
    #[must_use]
    pub fn motor_of_rotor(&self, i: usize) -> usize {
        self.rotors.get(i).map_or(i + 1, |r| r.motor)
    }

    /// The 4 x n effectiveness matrix `B` of this airframe (doc section 3).
    #[must_use]
    pub fn effectiveness(&self) -> nalgebra::DMatrix<f64> {
        effectiveness(&self.rotors, self.rotor.c_t, self.rotor.c_q)
    }

    /// Bounds on the squared rotor speed `w = omega^2` [rad^2/s^2].
    #[must_use]
    pub fn speed_sq_bounds(&self) -> (f64, f64) {
        (self.rotor.speed_min_rad_s.powi(2), self.rotor.speed_max_rad_s.powi(2))
    }

    /// The largest collective thrust of all rotors at full speed, `n c_T omega_max^2` [N].
    #[must_use]
    pub fn max_thrust_n(&self) -> f64 {
        let (_, w_max) = self.speed_sq_bounds();
        self.rotor_count() as f64 * self.rotor.c_t * w_max
    }

    /// The allocator (minimum-norm inverse with desaturation) for all rotors.
    ///
    /// # Panics
    /// Never for a validated airframe (validation checks rank 4).
    #[must_use]
    pub fn allocator(&self) -> Allocator {
        let (lo, hi) = self.speed_sq_bounds();
        Allocator::new(&self.effectiveness(), lo, hi).expect("validated airframe has rank 4")
    }
}
