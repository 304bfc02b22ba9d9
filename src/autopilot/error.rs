//! Why an [`super::Autopilot`] could not be built or parameters applied: a
//! leaf, so the settings, the control loop and the stack all name it.

use super::control_loop::ControlLoopError;
use crate::control::{GainError, ShaperError};
use crate::estimation::EstimatorError;

/// Why an autopilot could not be built or parameters applied.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum AutopilotError {
    /// The home position is not a valid point.
    #[error("home {lat_deg}, {lon_deg}, {alt_amsl_m} m is not a valid position")]
    InvalidHome {
        /// Latitude [deg].
        lat_deg: f64,
        /// Longitude [deg].
        lon_deg: f64,
        /// Altitude AMSL [m].
        alt_amsl_m: f64,
    },
    /// A parameter value the autopilot cannot use.
    #[error("parameter: {0}")]
    Param(String),
    /// The control gains derived from the parameters are invalid.
    #[error(transparent)]
    Gains(#[from] GainError),
    /// The estimator settings are invalid.
    #[error("estimator: {0}")]
    Estimator(#[from] EstimatorError),
    /// The reference shaper limits are invalid.
    #[error(transparent)]
    Shaper(#[from] ShaperError),
}

impl From<ControlLoopError> for AutopilotError {
    fn from(e: ControlLoopError) -> Self {
        match e {
            ControlLoopError::Gains(e) => AutopilotError::Gains(e),
            ControlLoopError::Estimator(e) => AutopilotError::Estimator(e),
        }
    }
}
