//! The momentum-based estimator of external force, external torque and real
//! mass (`docs/model.md` sections 2, 6 and 7; Ruggiero, Cacace,
//! Sadeghian, Lippiello, Robotics and Autonomous Systems 72, 2015; the origin
//! report, exercise 4).

use nalgebra::{UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use super::EstimatorError;
use super::chain::{ChainFilter, Discretization};
use super::gains::{Polynomial, forward_euler_bound, forward_euler_stable, gains_for, polynomial_coefficients};
use crate::math::{euler_zyx, rate_map};
use crate::signals::{ControlWrench, GRAVITY};
use crate::signals::{Measurement, NominalModel, WrenchEstimate};

/// Below this `|cos theta|` (|pitch| above about 89.94 deg) the RPY torque
/// channels stop using the measurements and coast (see [`MomentumEstimator`]).
pub const RPY_MIN_COS_PITCH: f64 = 1e-3;

/// Estimator settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EstimatorConfig {
    /// Order r of `G(s)`, `1..=20`.
    pub order: usize,
    /// Denominator polynomial of `G(s)`.
    pub polynomial: Polynomial,
    /// Cutoff `omega_c` [rad/s] (Butterworth, binomial; unused by a custom polynomial).
    pub cutoff_rad_s: f64,
    /// Discretization rule.
    pub discretization: Discretization,
    /// Sample time `h` [s]: the estimator runs at a fixed rate.
    pub sample_time_s: f64,
}

impl Default for EstimatorConfig {
    /// Butterworth r = 3, `omega_c` = 10 rad/s, trapezoidal, h = 1 ms (doc section 10's suggestion).
    fn default() -> Self {
        Self {
            order: 3,
            polynomial: Polynomial::Butterworth,
            cutoff_rad_s: 10.0,
            discretization: Discretization::Trapezoidal,
            sample_time_s: crate::signals::DEFAULT_STEP_S,
        }
    }
}

impl EstimatorConfig {
    /// Validate and return the chain gains `K_1..K_r` [1/s].
    ///
    /// # Errors
    /// Order outside `1..=20`; cutoff or sample time not finite and > 0; a
    /// custom list of the wrong length, with a coefficient not > 0, or not
    /// Hurwitz; forward Euler unstable at this sample time.
    pub fn gains(&self) -> Result<Vec<f64>, EstimatorError> {
        let h = self.sample_time_s;
        if !(h.is_finite() && h > 0.0) {
            return Err(EstimatorError::SampleTime(h));
        }
        let gains = gains_for(&self.polynomial, self.order, self.cutoff_rad_s)?;
        if self.discretization == Discretization::ForwardEuler {
            let stable = match forward_euler_bound(&self.polynomial, self.order) {
                Some(bound) => self.cutoff_rad_s * h < bound,
                None => forward_euler_stable(
                    &polynomial_coefficients(&self.polynomial, self.order, self.cutoff_rad_s)?,
                    h,
                ),
            };
            if !stable {
                return Err(EstimatorError::EulerUnstable { h });
            }
        }
        Ok(gains)
    }
}

/// One estimator sample: the state `x_k` at `t_k` and the command `u_{k-1}`
/// that was held over `[t_{k-1}, t_k)` (doc section 2 timing: the estimator at
/// `t_k` uses `x_{k-1}`, `x_k` and `u_{k-1}`, so it never waits for the
/// controller's output at `t_k`). The report's log provides exactly these.
///
/// `eta_dot` and `rate_frd` describe the same motion (`rate_frd = Q(eta) eta_dot`):
/// the RPY channels use `eta_dot`, the body-frame channels `rate_frd`. Build
/// inputs with [`EstimatorInput::from_euler_rates`] or [`input_from`].
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct EstimatorInput {
    /// Time `t_k` [s] (recorded; the update uses the configured sample time).
    pub time_s: f64,
    /// Velocity `p_dot` [m/s], world NED.
    pub velocity_ned: Vector3<f64>,
    /// ZYX Euler angles `eta = [roll, pitch, yaw]` [rad].
    pub eta: Vector3<f64>,
    /// Euler angle rates `eta_dot` [rad/s].
    pub eta_dot: Vector3<f64>,
    /// Angular velocity `omega` [rad/s], body FRD.
    pub rate_frd: Vector3<f64>,
    /// Total thrust `u_T` [N] along `-z_b` held over `[t_{k-1}, t_k)` (ignored at the first sample).
    pub thrust_n: f64,
    /// Body torque `tau^b` [N m], FRD, held over `[t_{k-1}, t_k)` (ignored at the first sample).
    pub torque_frd: Vector3<f64>,
}

impl EstimatorInput {
    /// From the report's signals: velocity (NED), Euler angles and their rates,
    /// and the command held over the interval ending at `time_s`;
    /// `rate_frd = Q(eta) eta_dot`.
    #[must_use]
    pub fn from_euler_rates(
        time_s: f64,
        velocity_ned: Vector3<f64>,
        eta: Vector3<f64>,
        eta_dot: Vector3<f64>,
        applied: &ControlWrench,
    ) -> Self {
        Self {
            time_s,
            velocity_ned,
            eta,
            eta_dot,
            rate_frd: rate_map(&eta) * eta_dot,
            thrust_n: applied.thrust_n,
            torque_frd: applied.torque_frd,
        }
    }
}

/// Estimator input from a measurement at `t_k` and the wrench `applied` over
/// `[t_{k-1}, t_k)` (the command sent in the previous step):
/// `eta = euler_zyx(attitude)`, `eta_dot = Q(eta)^-1 omega`. At
/// `|pitch| = 90 deg` `eta_dot` is not finite; only the RPY torque channels
/// use it.
#[must_use]
pub fn input_from(meas: &Measurement, applied: &ControlWrench) -> EstimatorInput {
    let eta = euler_zyx(&meas.attitude);
    let eta_dot = rate_map(&eta)
        .try_inverse()
        .map_or(Vector3::repeat(f64::NAN), |q_inv| q_inv * meas.rate_frd);
    EstimatorInput {
        time_s: meas.time_s,
        velocity_ned: meas.velocity_ned,
        eta,
        eta_dot,
        rate_frd: meas.rate_frd,
        thrust_n: applied.thrust_n,
        torque_frd: applied.torque_frd,
    }
}

/// Channel groups: linear (force), RPY angular, body angular.
const GROUPS: usize = 3;
/// Chain channels: `[f_e (NED, 3); tau_e (RPY, 3); tau_e^b (FRD, 3)]`.
const CHANNELS: usize = 9;

/// Roll and pitch sines and cosines and the thrust axis of one attitude:
/// all the estimator needs of it.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Attitude {
    sp: f64,
    cp: f64,
    st: f64,
    ct: f64,
    /// `1 / cos theta` (infinite at `cos theta = 0`), for `Q^-1`.
    sec_t: f64,
    /// `R e3` (NED): the thrust acts as `-u_T R e3`.
    thrust_axis: Vector3<f64>,
}

impl Attitude {
    /// From ZYX Euler angles: one `sin_cos` per angle,
    /// `R e3 = [c_psi s_th c_ph + s_psi s_ph, s_psi s_th c_ph - c_psi s_ph, c_th c_ph]`.
    fn from_euler(eta: &Vector3<f64>) -> Self {
        let (sp, cp) = eta.x.sin_cos();
        let (st, ct) = eta.y.sin_cos();
        let (sy, cy) = eta.z.sin_cos();
        Self {
            sp,
            cp,
            st,
            ct,
            sec_t: 1.0 / ct,
            thrust_axis: Vector3::new(cy * st * cp + sy * sp, sy * st * cp - cy * sp, ct * cp),
        }
    }

    /// From the quaternion without trigonometric functions: `R e3` is the
    /// third column of `R`; for the angles of `math::euler_zyx`,
    /// `sin theta = -r31`, `cos theta = sqrt(r32^2 + r33^2)`,
    /// `sin phi = r32 / cos theta`, `cos phi = r33 / cos theta` (roll set to 0
    /// at `cos theta = 0`, where it is undefined).
    fn from_quaternion(q: &UnitQuaternion<f64>) -> Self {
        let (w, x, y, z) = (q.w, q.i, q.j, q.k);
        let r13 = 2.0 * (x * z + w * y);
        let r23 = 2.0 * (y * z - w * x);
        let r31 = 2.0 * (x * z - w * y);
        let r32 = 2.0 * (y * z + w * x);
        let r33 = 1.0 - 2.0 * (x * x + y * y);
        let ct = (r32 * r32 + r33 * r33).sqrt();
        let sec_t = 1.0 / ct;
        let (sp, cp) = if ct > 0.0 {
            (r32 * sec_t, r33 * sec_t)
        } else {
            (0.0, 1.0)
        };
        Self {
            sp,
            cp,
            st: -r31,
            ct,
            sec_t,
            thrust_axis: Vector3::new(r13, r23, r33),
        }
    }

    /// `Q x` with `Q = [[1, 0, -s_th], [0, c_ph, c_th s_ph], [0, -s_ph, c_th c_ph]]`.
    fn q(&self, x: &Vector3<f64>) -> Vector3<f64> {
        let (sp, cp, st, ct) = (self.sp, self.cp, self.st, self.ct);
        Vector3::new(x.x - st * x.z, cp * x.y + ct * sp * x.z, -sp * x.y + ct * cp * x.z)
    }

    /// `Q^T x`.
    fn qt(&self, x: &Vector3<f64>) -> Vector3<f64> {
        let (sp, cp, st, ct) = (self.sp, self.cp, self.st, self.ct);
        Vector3::new(x.x, cp * x.y - sp * x.z, -st * x.x + ct * (sp * x.y + cp * x.z))
    }

    /// `Q^-1 w`: `[w_x + (s_ph w_y + c_ph w_z) t_th, c_ph w_y - s_ph w_z, (s_ph w_y + c_ph w_z) / c_th]`.
    fn q_inv(&self, w: &Vector3<f64>) -> Vector3<f64> {
        let a = (self.sp * w.y + self.cp * w.z) * self.sec_t;
        Vector3::new(w.x + a * self.st, self.cp * w.y - self.sp * w.z, a)
    }

    /// `Q_dot(eta, eta_dot)^T x` (`Q_dot` as `math::rate_map_dot`; its first column is zero):
    /// `[0, -phi_dot A, -theta_dot (c_th x_x + s_th A) + phi_dot c_th B]` with
    /// `A = s_ph x_y + c_ph x_z`, `B = c_ph x_y - s_ph x_z` (also the terms of `Q^T x`).
    fn q_dot_t(&self, eta_dot: &Vector3<f64>, x: &Vector3<f64>) -> Vector3<f64> {
        let (sp, cp, st, ct) = (self.sp, self.cp, self.st, self.ct);
        let (pd, td) = (eta_dot.x, eta_dot.y);
        let a = sp * x.y + cp * x.z;
        let b = cp * x.y - sp * x.z;
        Vector3::new(0.0, -pd * a, -td * (ct * x.x + st * a) + pd * ct * b)
    }
}

/// The kinematic part of one sample (independent of the nominal model).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Kinematics {
    attitude: Attitude,
    /// `p_dot` [m/s], NED.
    velocity: Vector3<f64>,
    /// `eta_dot` [rad/s].
    eta_dot: Vector3<f64>,
    /// `Q eta_dot` [rad/s]: the angular velocity the RPY channels see.
    rate_rpy: Vector3<f64>,
    /// `omega` [rad/s], FRD: the angular velocity the body channels see.
    rate_frd: Vector3<f64>,
    /// `rate_rpy` is `rate_frd` itself (from a measurement), so the RPY and
    /// body channels share `I_b omega` and its cross product.
    rates_equal: bool,
    /// Per group (linear, RPY, body): the data are usable.
    valid: [bool; GROUPS],
    /// Every group is usable (`valid == [true; 3]`, one test on the hot path).
    all_valid: bool,
}

/// Every group of a sample is usable.
const ALL_VALID: [bool; GROUPS] = [true; GROUPS];

impl Kinematics {
    #[inline(always)]
    fn from_input(x: &EstimatorInput) -> Self {
        let attitude = Attitude::from_euler(&x.eta);
        let mut kin = Self {
            attitude,
            velocity: x.velocity_ned,
            eta_dot: x.eta_dot,
            rate_rpy: attitude.q(&x.eta_dot),
            rate_frd: x.rate_frd,
            rates_equal: false,
            valid: ALL_VALID,
            all_valid: true,
        };
        // one test on the usual path: a sum is finite only if every term is
        let sum = (x.eta + x.velocity_ned + x.eta_dot + x.rate_frd).sum();
        if !(sum.is_finite() && attitude.ct.abs() >= RPY_MIN_COS_PITCH) {
            let eta_ok = finite(&x.eta);
            kin.valid = [
                eta_ok && finite(&x.velocity_ned),
                eta_ok && finite(&x.eta_dot) && attitude.ct.abs() >= RPY_MIN_COS_PITCH,
                finite(&x.rate_frd),
            ];
            kin.all_valid = kin.valid == ALL_VALID;
        }
        kin
    }

    #[inline(always)]
    fn from_measurement(meas: &Measurement) -> Self {
        let attitude = Attitude::from_quaternion(&meas.attitude);
        let w = meas.rate_frd;
        let mut kin = Self {
            attitude,
            velocity: meas.velocity_ned,
            eta_dot: attitude.q_inv(&w),
            rate_rpy: w,
            rate_frd: w,
            rates_equal: true,
            valid: ALL_VALID,
            all_valid: true,
        };
        // one test on the usual path: a sum is finite only if every term is
        let sum = meas.attitude.coords.sum() + (meas.velocity_ned + w).sum();
        if !(sum.is_finite() && attitude.ct.abs() >= RPY_MIN_COS_PITCH) {
            let att_ok = meas.attitude.coords.iter().all(|c| c.is_finite());
            let rate_ok = finite(&w);
            kin.valid = [
                att_ok && finite(&meas.velocity_ned),
                att_ok && rate_ok && attitude.ct.abs() >= RPY_MIN_COS_PITCH,
                rate_ok,
            ];
            kin.all_valid = kin.valid == ALL_VALID;
        }
        kin
    }
}

fn finite(v: &Vector3<f64>) -> bool {
    v.x.is_finite() && v.y.is_finite() && v.z.is_finite()
}

/// Everything the update needs from one state sample, with the nominal model.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Sample {
    kin: Kinematics,
    /// `[m p_dot; M(eta) eta_dot; I_b omega]`.
    momentum: [f64; CHANNELS],
    /// The command-free part of `d`: `[m g e3; C^T(eta, eta_dot) eta_dot; -omega x I_b omega]`.
    drift: [f64; CHANNELS],
}

impl Sample {
    /// The sample of `kin` for the nominal model ([`Self::refresh`]).
    fn new(nominal: &NominalModel, kin: Kinematics) -> Self {
        let mut s = Self {
            kin,
            momentum: [0.0; CHANNELS],
            drift: [0.0; CHANNELS],
        };
        s.refresh(nominal);
        s
    }

    /// Momentum and drift of `self.kin` for the nominal model, with `w = Q eta_dot`:
    /// `M eta_dot = Q^T I_b w` and `C^T eta_dot = Q_dot^T I_b w + Q^T ((I_b w) x w)`,
    /// the transpose of `math::rpy_coriolis` applied to `eta_dot` (checked in the tests).
    /// Inlined, so that the update uses the new values straight from registers.
    #[inline(always)]
    fn refresh(&mut self, nominal: &NominalModel) {
        let m = nominal.mass_kg;
        let ib = &nominal.inertia_kg_m2;
        let kin = &self.kin;
        let att = &kin.attitude;
        let w = kin.rate_frd;
        let iw = ib * w;
        let gyro = iw.cross(&w);
        // from a measurement both channels see the same rate: reuse I_b w and its cross product
        let (iw_eta, iw_eta_x_w_eta) = if kin.rates_equal {
            (iw, gyro)
        } else {
            let w_eta = kin.rate_rpy;
            let iw_eta = ib * w_eta;
            (iw_eta, iw_eta.cross(&w_eta))
        };
        let p_eta = att.qt(&iw_eta);
        let c_t_eta_dot = att.q_dot_t(&kin.eta_dot, &iw_eta) + att.qt(&iw_eta_x_w_eta);
        let v = kin.velocity;
        self.momentum = [m * v.x, m * v.y, m * v.z, p_eta.x, p_eta.y, p_eta.z, iw.x, iw.y, iw.z];
        self.drift = [
            0.0,
            0.0,
            m * GRAVITY,
            c_t_eta_dot.x,
            c_t_eta_dot.y,
            c_t_eta_dot.z,
            gyro.x,
            gyro.y,
            gyro.z,
        ];
    }
}

/// Check a nominal model: mass finite > 0, inertia finite, symmetric, positive definite.
fn check_nominal(nominal: &NominalModel) -> Result<(), EstimatorError> {
    let m = nominal.mass_kg;
    if !(m.is_finite() && m > 0.0) {
        return Err(EstimatorError::NominalMass(m));
    }
    let i = &nominal.inertia_kg_m2;
    let scale = i.amax();
    if !i.iter().all(|x| x.is_finite())
        || (i - i.transpose()).amax() > 1e-9 * scale
        || i.symmetric_part().cholesky().is_none()
    {
        return Err(EstimatorError::NominalInertia);
    }
    Ok(())
}

/// Momentum-based estimator of the external wrench and of the real mass.
///
/// # Channels
/// Nine identical chains `G(s) = c_0 / (s^r + ... + c_0)` (see
/// [`super::gains`], [`super::chain`]) on the generalized momentum, with the
/// *nominal* mass `m` and inertia `I_b` ([`NominalModel`]):
///
/// ```text
/// linear  (world NED)    q_f = m p_dot            q_f'   = m g e3 - u_T R(eta) e3            + f_e
/// RPY     (eta coords)   q_e = M(eta) eta_dot     q_e'   = C^T(eta, eta_dot) eta_dot + Q^T tau^b + tau_e,  tau_e = Q^T tau_e^b
/// body    (FRD)          q_b = I_b omega          q_b'   = -omega x I_b omega + tau^b         + tau_e^b
/// ```
///
/// `M = Q^T I_b Q` and `C` are those of `crate::math` (`M_dot - 2C` skew; the
/// often quoted `C'` would bias `tau_e` by `Q^T (omega x I_b omega)`). The
/// first two rows are the report's estimator (Ruggiero et al. 2015); the body
/// rows are its variant without the `Q` singularity. Output
/// ([`WrenchEstimate`]): `force_ned` [N] from the linear channels,
/// `torque_rpy` [N m] from the RPY channels, `torque_frd` [N m] from the body
/// channels, `mass_kg = m + f_z / g`.
///
/// With a wrong nominal mass the force channels converge to
/// `f_e + (m - m_r)(p_ddot - g e3)`, which at hover is `f_e - (m - m_r) g e3`:
/// hence the real mass `m_r = m + f_z / g` (doc section 7).
///
/// # Which torque to feed the controllers
/// `torque_frd` (the body variant). It needs no `Q^-1`, so it stays valid at
/// pitch +-90 deg where `eta_dot = Q^-1 omega` and the RPY channels break down,
/// and the geometric controller works in body axes (`tau^b -= tau_e^b`
/// directly). The hierarchical and passivity-based controllers, written in
/// `eta` coordinates, map it with `tau_e = Q^T tau_e^b`; away from the
/// singularity that equals `torque_rpy` up to the filter's lag (the RPY
/// channels filter `Q^T tau_e^b`, which varies with the attitude).
/// `torque_rpy` is kept for comparison with the report.
///
/// # Sampling
/// Call [`update`](Self::update) every `h` seconds with `x_k` and `u_{k-1}`
/// ([`EstimatorInput`], e.g. from the report's log), or in the flight loop
/// [`update_measured`](Self::update_measured) with the measurement and the
/// wrench applied since the previous sample (same result, no Euler angles, no
/// trigonometry). The timing follows doc section 2: the estimate at `t_k`
/// never needs `u_k`, so feeding it to the controller at `t_k` makes no
/// algebraic loop. The first sample sets `q_0 = q(x_0)` (the vehicle need
/// not start at rest) and returns a zero estimate. Each later sample integrates
/// `d` over `[t_{k-1}, t_k)` with `u_{k-1}` held (trapezoidal: `d(x_{k-1}, u_{k-1})`
/// and `d(x_k, u_{k-1})`; forward Euler: `d(x_{k-1}, u_{k-1})`) and advances the
/// chains. Nothing is allocated per update.
///
/// # Unusable data
/// A group of channels (linear, RPY, body) whose inputs at `t_{k-1}` or `t_k`
/// are not finite (or, for RPY, `|cos theta| < RPY_MIN_COS_PITCH`) *coasts*:
/// its chains are fed the increment of a wrench equal to the current estimate
/// (no NaN gets in), and the momentum difference is taken up again from the
/// next sample with usable data.
#[derive(Clone, Debug)]
pub struct MomentumEstimator {
    config: EstimatorConfig,
    nominal: NominalModel,
    chain: ChainFilter<CHANNELS>,
    /// Two sample slots: `x_{k-1}` (with the current nominal model) in
    /// `slots[prev]`; the next sample is written into the other slot, so
    /// the roles swap without copying.
    slots: [Sample; 2],
    /// Slot of `x_{k-1}` in `slots`.
    prev: usize,
    /// `t_{k-1}` [s].
    prev_time_s: f64,
    initialized: bool,
    samples: u64,
}

impl MomentumEstimator {
    /// A new estimator, waiting for its first sample.
    ///
    /// # Errors
    /// An invalid configuration (see [`EstimatorConfig::gains`]) or nominal
    /// model (mass not finite > 0, inertia not finite, symmetric and positive definite).
    pub fn new(config: EstimatorConfig, nominal: NominalModel) -> Result<Self, EstimatorError> {
        check_nominal(&nominal)?;
        let gains = config.gains()?;
        let chain = ChainFilter::new(&gains, config.discretization, config.sample_time_s)?;
        Ok(Self {
            slots: [Sample::new(&nominal, Kinematics::from_input(&EstimatorInput::default())); 2],
            prev: 0,
            prev_time_s: 0.0,
            config,
            nominal,
            chain,
            initialized: false,
            samples: 0,
        })
    }

    /// The configuration.
    #[must_use]
    pub fn config(&self) -> &EstimatorConfig {
        &self.config
    }

    /// The nominal model in use.
    #[must_use]
    pub fn nominal(&self) -> &NominalModel {
        &self.nominal
    }

    /// Chain gains `K_1..K_r` [1/s].
    #[must_use]
    pub fn gains(&self) -> &[f64] {
        self.chain.gains()
    }

    /// The latest estimate (zero force and torque, nominal mass before the second sample).
    #[must_use]
    pub fn estimate(&self) -> WrenchEstimate {
        self.output(&self.chain.output())
    }

    /// The estimate from the chain outputs `[f (3); tau_rpy (3); tau_frd (3)]`.
    fn output(&self, y: &[f64; CHANNELS]) -> WrenchEstimate {
        WrenchEstimate {
            force_ned: Vector3::new(y[0], y[1], y[2]),
            torque_rpy: Vector3::new(y[3], y[4], y[5]),
            torque_frd: Vector3::new(y[6], y[7], y[8]),
            mass_kg: self.nominal.mass_kg + y[2] / GRAVITY,
        }
    }

    /// Whether the first sample has been taken.
    #[must_use]
    pub fn is_initialized(&self) -> bool {
        self.initialized
    }

    /// Samples taken since construction or [`reset`](Self::reset).
    #[must_use]
    pub fn samples(&self) -> u64 {
        self.samples
    }

    /// Time of the latest sample [s], if any.
    #[must_use]
    pub fn last_time_s(&self) -> Option<f64> {
        self.initialized.then_some(self.prev_time_s)
    }

    /// Forget everything: zero chains; the next sample sets `q_0` again.
    pub fn reset(&mut self) {
        self.chain.reset();
        self.initialized = false;
        self.samples = 0;
    }

    /// Change the nominal model in flight (e.g. after the mass was
    /// re-estimated). The momentum integral restarts from the latest sample
    /// with the new model (`q_0 := q_new(x_{k-1}) - gamma_1 / K_1`) while the
    /// chains keep their state as their initial state, so the wrench estimate
    /// does not jump and then converges to its meaning under the new model.
    /// `mass_kg` uses the new `m` at once (`m_new + f_z / g`: it moves by
    /// `m_new - m_old` and returns as `f_z` settles).
    ///
    /// # Errors
    /// An invalid nominal model; the estimator is then unchanged.
    pub fn set_nominal(&mut self, nominal: NominalModel) -> Result<(), EstimatorError> {
        check_nominal(&nominal)?;
        self.nominal = nominal;
        self.slots[self.prev].refresh(&self.nominal);
        Ok(())
    }

    /// Take sample `k`: the state `x_k` and the command `u_{k-1}` held over
    /// `[t_{k-1}, t_k)` ([`EstimatorInput`]); returns the estimate at `t_k`.
    pub fn update(&mut self, x: &EstimatorInput) -> WrenchEstimate {
        input_update(self, x)
    }

    /// [`Self::update`] with the sample's own step `h` = `t_k - t_{k-1}` [s]
    /// instead of the configured one: `d` is integrated over `[t_{k-1}, t_k)`
    /// and the chains advance by the rule for that `h`
    /// ([`ChainFilter::set_sample_time`]), for logs whose step varies. With
    /// `h` equal to the configured sample time the result is that of
    /// [`Self::update`], bit for bit; the step set stays until another is given.
    ///
    /// # Errors
    /// `h` not finite and > 0, or forward Euler unstable at `h`; the
    /// estimator is then unchanged.
    pub fn update_with_step(&mut self, x: &EstimatorInput, h: f64) -> Result<WrenchEstimate, EstimatorError> {
        if h.to_bits() != self.chain.sample_time_s().to_bits() {
            if self.config.discretization == Discretization::ForwardEuler {
                EstimatorConfig {
                    sample_time_s: h,
                    ..self.config.clone()
                }
                .gains()?;
            }
            self.chain.set_sample_time(h)?;
        }
        Ok(input_update(self, x))
    }

    /// The same as `update(&input_from(meas, applied))` (equal up to
    /// rounding) but straight from the quaternion: no Euler angles and no
    /// trigonometric functions, so it is the faster path in the flight loop,
    /// and the thrust axis `R e3` stays exact at any attitude. `applied` is
    /// the wrench held over `[t_{k-1}, t_k)`.
    pub fn update_measured(&mut self, meas: &Measurement, applied: &ControlWrench) -> WrenchEstimate {
        measured_update(self, meas, applied)
    }

    /// Take the sample `x_k` whose kinematics were just written into the free
    /// slot (the roles of the slots then swap, nothing is copied). Inlined
    /// into both updates, so that the kinematics need not go through memory.
    #[inline(always)]
    fn step(&mut self, time_s: f64, thrust: f64, tau: &Vector3<f64>) -> WrenchEstimate {
        let next = 1 - self.prev;
        self.slots[next].refresh(&self.nominal);
        self.samples += 1;
        if !self.initialized {
            self.prev = next;
            self.prev_time_s = time_s;
            self.initialized = true;
            return self.estimate();
        }
        let prev = &self.slots[self.prev];
        let cur = &self.slots[next];
        let (pa, ca) = (&prev.kin.attitude, &cur.kin.attitude);
        let h = self.chain.sample_time_s();
        // u_k = q_k - q_{k-1} - (integral of d over the interval): the drift part
        // h/2 (d_{k-1} + d_k) (trapezoidal) or h d_{k-1}, and the command part h_cmd
        let h_tau = h * tau;
        let mut increment = [0.0; CHANNELS];
        match self.chain.discretization() {
            Discretization::Trapezoidal => {
                let hh = 0.5 * h;
                let f = -hh * thrust * (pa.thrust_axis + ca.thrust_axis);
                let t = hh * (pa.qt(tau) + ca.qt(tau));
                let h_cmd = [f.x, f.y, f.z, t.x, t.y, t.z, h_tau.x, h_tau.y, h_tau.z];
                for c in 0..CHANNELS {
                    let drift = hh * (prev.drift[c] + cur.drift[c]);
                    increment[c] = cur.momentum[c] - prev.momentum[c] - drift - h_cmd[c];
                }
            }
            Discretization::ForwardEuler => {
                let f = -h * thrust * pa.thrust_axis;
                let t = h * pa.qt(tau);
                let h_cmd = [f.x, f.y, f.z, t.x, t.y, t.z, h_tau.x, h_tau.y, h_tau.z];
                for c in 0..CHANNELS {
                    increment[c] = cur.momentum[c] - prev.momentum[c] - h * prev.drift[c] - h_cmd[c];
                }
            }
        }
        // one test on the usual path: a sum is finite only if every term is
        let cmd_ok = (thrust + tau.sum()).is_finite();
        if !(cmd_ok && prev.kin.all_valid && cur.kin.all_valid) {
            let tau_ok = finite(tau);
            let usable: [bool; GROUPS] = std::array::from_fn(|g| {
                prev.kin.valid[g] && cur.kin.valid[g] && [thrust.is_finite(), tau_ok, tau_ok][g]
            });
            coast(&mut increment, usable, &self.chain.output(), h);
        }
        let y = self.chain.advance(&increment);
        self.prev = next;
        self.prev_time_s = time_s;
        self.output(&y)
    }
}

// The two updates are compiled twice, for the x86-64 baseline and with AVX2
// (wider vectors over the nine channels, three-operand instructions), and the
// first call picks the version this CPU runs. Both give the same bits: the
// additions, products, divisions and roots are IEEE operations rounded the
// same at any vector width, and Rust neither fuses `a * b + c` nor reorders
// sums. Everything on the usual path is inlined into them (hence the
// `inline(always)` on the kinematics), so all of it gets the wider code.

/// [`MomentumEstimator::update`].
#[multiversion::multiversion(targets("x86_64+avx2"))]
fn input_update(est: &mut MomentumEstimator, x: &EstimatorInput) -> WrenchEstimate {
    est.slots[1 - est.prev].kin = Kinematics::from_input(x);
    est.step(x.time_s, x.thrust_n, &x.torque_frd)
}

/// [`MomentumEstimator::update_measured`].
#[multiversion::multiversion(targets("x86_64+avx2"))]
fn measured_update(est: &mut MomentumEstimator, meas: &Measurement, applied: &ControlWrench) -> WrenchEstimate {
    est.slots[1 - est.prev].kin = Kinematics::from_measurement(meas);
    est.step(meas.time_s, applied.thrust_n, &applied.torque_frd)
}

/// Replace the increments of the groups that are not `usable` by those of a
/// wrench equal to the current estimate `held`: those chains coast.
fn coast(increment: &mut [f64; CHANNELS], usable: [bool; GROUPS], held: &[f64; CHANNELS], h: f64) {
    for (g, ok) in usable.iter().enumerate() {
        if !ok {
            let group = 3 * g..3 * g + 3;
            for (inc, est) in increment[group.clone()].iter_mut().zip(&held[group]) {
                *inc = h * est;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{from_euler_zyx, rpy_coriolis, rpy_inertia};
    use nalgebra::Matrix3;

    fn seed_nominal() -> NominalModel {
        NominalModel {
            mass_kg: 1.5,
            inertia_kg_m2: Matrix3::from_diagonal(&Vector3::new(1.2416, 1.2416, 2.4832)),
        }
    }

    /// The fused momentum / Coriolis terms equal `crate::math`'s definitions.
    #[test]
    fn sample_matches_math_definitions() {
        let mut nominal = seed_nominal();
        nominal.inertia_kg_m2 = Matrix3::new(0.03, 0.001, -0.002, 0.001, 0.04, 0.0005, -0.002, 0.0005, 0.05);
        for (eta, eta_dot) in [
            (Vector3::new(0.1, -0.2, 0.3), Vector3::new(0.4, -0.5, 0.6)),
            (Vector3::new(-1.0, 1.2, -2.9), Vector3::new(2.0, 0.3, -1.5)),
        ] {
            let x = EstimatorInput::from_euler_rates(
                0.0,
                Vector3::new(1.0, 2.0, 3.0),
                eta,
                eta_dot,
                &ControlWrench::default(),
            );
            let s = Sample::new(&nominal, Kinematics::from_input(&x));
            let ib = &nominal.inertia_kg_m2;
            let p = rpy_inertia(ib, &eta) * eta_dot;
            let ct = rpy_coriolis(ib, &eta, &eta_dot).transpose() * eta_dot;
            let r = from_euler_zyx(&eta).to_rotation_matrix();
            let re3 = r * Vector3::z();
            for i in 0..3 {
                assert!((s.momentum[3 + i] - p[i]).abs() < 1e-14);
                assert!((s.drift[3 + i] - ct[i]).abs() < 1e-14);
                assert!((s.kin.attitude.thrust_axis[i] - re3[i]).abs() < 1e-14);
                assert!((s.momentum[i] - 1.5 * x.velocity_ned[i]).abs() < 1e-15);
            }
            let q = rate_map(&eta);
            let v = Vector3::new(0.3, -0.7, 1.1);
            assert!((s.kin.attitude.q(&v) - q * v).amax() < 1e-15);
            assert!((s.kin.attitude.qt(&v) - q.transpose() * v).amax() < 1e-15);
            assert!((s.kin.attitude.q_inv(&(q * v)) - v).amax() < 1e-14);
            assert!((s.kin.rate_rpy - q * eta_dot).amax() < 1e-15);
            // the same from the quaternion, without trigonometry
            let meas = Measurement {
                time_s: 0.0,
                position_ned: Vector3::zeros(),
                velocity_ned: x.velocity_ned,
                attitude: from_euler_zyx(&eta),
                rate_frd: x.rate_frd,
            };
            let sq = Sample::new(&nominal, Kinematics::from_measurement(&meas));
            for i in 0..CHANNELS {
                assert!((sq.momentum[i] - s.momentum[i]).abs() < 1e-13, "momentum {i}");
                assert!((sq.drift[i] - s.drift[i]).abs() < 1e-13, "drift {i}");
            }
            assert!((sq.kin.attitude.thrust_axis - re3).amax() < 1e-15);
            assert!((sq.kin.eta_dot - eta_dot).amax() < 1e-13);
            assert_eq!(sq.kin.valid, [true; 3]);
            // doc section 9 oracle for the seed inertia
            if eta.x == 0.1 {
                let s9 = Sample::new(&seed_nominal(), Kinematics::from_input(&x));
                assert!((s9.drift[3] - 0.345964).abs() < 1e-6 && (s9.drift[4] + 0.198530).abs() < 1e-6);
                assert!(s9.drift[5].abs() < 1e-12);
            }
        }
    }

    fn bits(e: &WrenchEstimate) -> Vec<u64> {
        let v = [e.force_ned, e.torque_rpy, e.torque_frd];
        v.iter()
            .flat_map(|x| x.iter().map(|c| c.to_bits()))
            .chain([e.mass_kg.to_bits()])
            .collect()
    }

    /// The dispatched updates (the AVX2 build on a CPU that has it) give the
    /// same bits as the same steps compiled here for the x86-64 baseline.
    #[test]
    fn dispatched_updates_give_the_baseline_bits() {
        let mut nominal = seed_nominal();
        nominal.inertia_kg_m2 = Matrix3::new(0.03, 0.001, -0.002, 0.001, 0.04, 0.0005, -0.002, 0.0005, 0.05);
        for (order, polynomial) in [(5, Polynomial::Butterworth), (20, Polynomial::Binomial)] {
            let config = EstimatorConfig {
                order,
                polynomial,
                ..EstimatorConfig::default()
            };
            let mut dispatched = MomentumEstimator::new(config.clone(), nominal).unwrap();
            let mut baseline = dispatched.clone();
            let (mut dispatched_x, mut baseline_x) = (dispatched.clone(), dispatched.clone());
            for k in 0..500 {
                let t = k as f64 * 1e-3;
                let eta = Vector3::new(0.3 * (2.0 * t).sin(), -0.2 * (3.0 * t).cos(), 1.0 + t);
                let meas = Measurement {
                    time_s: t,
                    position_ned: Vector3::zeros(),
                    velocity_ned: Vector3::new((5.0 * t).sin(), t, -0.5),
                    attitude: from_euler_zyx(&eta),
                    rate_frd: Vector3::new(0.4 * (7.0 * t).cos(), 0.1, -0.3 * t),
                };
                let applied = ControlWrench::new(14.0 + (11.0 * t).sin(), Vector3::new(0.1, -0.05 * t, -0.2));
                let a = dispatched.update_measured(&meas, &applied);
                baseline.slots[1 - baseline.prev].kin = Kinematics::from_measurement(&meas);
                let b = baseline.step(t, applied.thrust_n, &applied.torque_frd);
                assert_eq!(bits(&a), bits(&b), "update_measured, r = {order}, sample {k}");
                let x = input_from(&meas, &applied);
                let a = dispatched_x.update(&x);
                baseline_x.slots[1 - baseline_x.prev].kin = Kinematics::from_input(&x);
                let b = baseline_x.step(t, x.thrust_n, &x.torque_frd);
                assert_eq!(bits(&a), bits(&b), "update, r = {order}, sample {k}");
            }
        }
    }

    #[test]
    fn input_from_measurement() {
        let eta = Vector3::new(0.2, -0.3, 1.0);
        let eta_dot = Vector3::new(0.1, 0.2, -0.3);
        let meas = Measurement {
            time_s: 1.5,
            position_ned: Vector3::zeros(),
            velocity_ned: Vector3::new(1.0, 0.0, -0.5),
            attitude: from_euler_zyx(&eta),
            rate_frd: rate_map(&eta) * eta_dot,
        };
        let w = ControlWrench::new(14.0, Vector3::new(0.1, 0.0, -0.2));
        let x = input_from(&meas, &w);
        assert!((x.eta - eta).norm() < 1e-12 && (x.eta_dot - eta_dot).norm() < 1e-12);
        assert_eq!(x.rate_frd, meas.rate_frd);
        assert_eq!((x.thrust_n, x.torque_frd, x.time_s), (14.0, w.torque_frd, 1.5));
    }

    #[test]
    fn refuses_bad_nominal() {
        let c = EstimatorConfig::default();
        let mut n = seed_nominal();
        n.mass_kg = 0.0;
        assert!(matches!(
            MomentumEstimator::new(c.clone(), n),
            Err(EstimatorError::NominalMass(_))
        ));
        let mut n = seed_nominal();
        n.inertia_kg_m2[(0, 0)] = -1.0;
        assert!(matches!(
            MomentumEstimator::new(c.clone(), n),
            Err(EstimatorError::NominalInertia)
        ));
        let mut n = seed_nominal();
        n.inertia_kg_m2[(0, 1)] = 0.1;
        assert!(MomentumEstimator::new(c.clone(), n).is_err());
        let mut est = MomentumEstimator::new(c, seed_nominal()).unwrap();
        n.inertia_kg_m2[(0, 1)] = f64::NAN;
        assert!(est.set_nominal(n).is_err());
        assert_eq!(est.nominal(), &seed_nominal());
    }
}
