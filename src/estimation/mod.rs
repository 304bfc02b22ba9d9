//! Momentum-based external-wrench estimator of order r, and the real mass
//! (`docs/model.md` section 7; Ruggiero, Cacace, Sadeghian,
//! Lippiello, "Passivity-based control of VToL UAVs with a momentum-based
//! estimator of external wrench and unmodeled dynamics", Robotics and
//! Autonomous Systems 72, 2015; the origin report, exercise 4).
//!
//! ```text
//! q  = [m p_dot ; M(eta) eta_dot]                         generalized momentum, nominal m, I_b
//! q' = d + [f_e ; tau_e],  d = [m g e3 - u_T R e3 ; C^T(eta, eta_dot) eta_dot + Q^T tau^b]
//! gamma_1 = K_1 (q - q(0) - int (d + gamma_r)),  gamma_i = K_i int (gamma_{i-1} - gamma_r)
//! gamma_r / w = G(s) = c_0 / (s^r + c_{r-1} s^{r-1} + ... + c_0)   per channel, G(0) = 1
//! m_real = m + f_e,z / g                                   (NED: f_e,z < 0 when lighter than assumed)
//! ```
//!
//! * [`gains`]: Butterworth / binomial / custom polynomials, chain gains, validation.
//! * [`chain`]: the discrete chain (trapezoidal or forward Euler), shared by all channels.
//! * [`momentum`]: the estimator proper ([`MomentumEstimator`]): RPY channels
//!   as in the report plus a body-frame angular variant.
//! * [`metrics`]: 2 % settling time, overshoot and RMS error of a time series.
//! * [`wind`]: the wind that explains the estimated force through the nominal drag model.
//! * [`nav`]: the navigation filter, an error-state EKF after PX4's EKF2 (`docs/navigation.md`).
//!
//! Pure and deterministic: no clock, no I/O, no allocation per update.

pub mod chain;
pub mod gains;
pub mod metrics;
pub mod momentum;
pub mod nav;
pub mod sweep;
pub mod wind;

pub use chain::{ChainFilter, Discretization, step_response};
pub use gains::{MAX_ORDER, Polynomial};
pub use metrics::{MetricsError, StepMetrics, step_metrics};
pub use momentum::{EstimatorConfig, EstimatorInput, MomentumEstimator, RPY_MIN_COS_PITCH, input_from};

/// Why an estimator (or a filter polynomial) was refused.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum EstimatorError {
    /// The order is outside `1..=MAX_ORDER`.
    #[error("estimator order r must be between 1 and {max}, got {0}", max = gains::MAX_ORDER)]
    Order(usize),
    /// The cutoff is not finite and > 0.
    #[error("cutoff frequency must be finite and > 0 rad/s, got {0}")]
    Cutoff(f64),
    /// The sample time is not finite and > 0.
    #[error("sample time must be finite and > 0 s, got {0}")]
    SampleTime(f64),
    /// A custom polynomial list has the wrong length.
    #[error(
        "custom polynomial of order {order} needs {order} coefficients c_0..c_{{r-1}} (the leading 1 left out), got {got}"
    )]
    CustomLength {
        /// The configured order r.
        order: usize,
        /// The list length given.
        got: usize,
    },
    /// A polynomial coefficient is not finite and > 0.
    #[error("polynomial coefficient c_{index} = {value} must be finite and > 0")]
    Coefficient {
        /// Index j of `c_j`.
        index: usize,
        /// The value given.
        value: f64,
    },
    /// The custom polynomial has a root with real part >= 0.
    #[error(
        "custom polynomial is not Hurwitz (Routh array first column not positive at row {row}): the estimator would be unstable"
    )]
    NotHurwitz {
        /// First Routh row whose leading entry is not > 0.
        row: usize,
    },
    /// A chain gain is not finite and > 0.
    #[error("chain gain K_{index} = {value} must be finite and > 0")]
    Gain {
        /// Index i of `K_i` (1-based).
        index: usize,
        /// The value given.
        value: f64,
    },
    /// Forward Euler would be unstable at this sample time.
    #[error(
        "forward Euler is unstable for this filter at h = {h} s (a pole p has |1 + h p| >= 1): lower the cutoff or the sample time, or use the trapezoidal rule"
    )]
    EulerUnstable {
        /// The sample time [s].
        h: f64,
    },
    /// The trapezoidal system matrix could not be inverted.
    #[error("the trapezoidal chain matrix is singular")]
    SingularSystem,
    /// The nominal mass is not finite and > 0.
    #[error("nominal mass must be finite and > 0 kg, got {0}")]
    NominalMass(f64),
    /// The nominal inertia is not usable.
    #[error("nominal inertia must be finite, symmetric and positive definite")]
    NominalInertia,
}
