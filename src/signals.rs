//! Values that flow between the blocks of the loop (plant -> sensors ->
//! estimator -> controller -> allocation): what flight software may know about
//! the vehicle. Controllers and estimators import these, never `model`.

use nalgebra::{Matrix3, UnitQuaternion, Vector3};
use serde::Serialize;

/// A measurement of the vehicle state at one instant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Measurement {
    /// Simulated time [s].
    pub time_s: f64,
    /// Position [m], NED.
    pub position_ned: Vector3<f64>,
    /// Velocity [m/s], NED.
    pub velocity_ned: Vector3<f64>,
    /// Attitude, body FRD to NED.
    pub attitude: UnitQuaternion<f64>,
    /// Angular velocity [rad/s], body FRD.
    pub rate_frd: Vector3<f64>,
}

/// The model that controllers and estimators assume (never the plant's truth).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct NominalModel {
    /// Nominal mass `m` [kg].
    pub mass_kg: f64,
    /// Nominal inertia `I_b` [kg m^2], body FRD.
    pub inertia_kg_m2: Matrix3<f64>,
}

/// An estimate of the external wrench and of the real mass.
#[derive(Clone, Copy, Debug, PartialEq, Default, Serialize)]
pub struct WrenchEstimate {
    /// Estimated external force `f_e` [N], world NED.
    pub force_ned: Vector3<f64>,
    /// Estimated external torque as a generalized force on the ZYX Euler
    /// angles, `tau_e = Q^T tau_e^b` [N m] (the report's coordinates).
    pub torque_rpy: Vector3<f64>,
    /// Estimated external torque `tau_e^b` [N m], body FRD.
    pub torque_frd: Vector3<f64>,
    /// Real mass `m + f_e,z / g` [kg].
    pub mass_kg: f64,
}
