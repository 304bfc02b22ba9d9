//! Flight control: three control laws behind one [`Controller`], and the
//! reference [`shaper`].
//!
//! | law | file | model | source |
//! |---|---|---|---|
//! | [`ControllerKind::Hierarchical`] | `hierarchical.rs` | ZYX Euler angles, partial feedback linearization | report section 2.2, doc section 4 |
//! | [`ControllerKind::Geometric`] | `geometric.rs` | SE(3), coordinate free | Lee, Leok, McClamroch 2010; report section 5, doc section 5 |
//! | [`ControllerKind::Passivity`] | `passivity.rs` | ZYX Euler angles, Slotine-Li reference signals | Ruggiero et al. 2015; report section 2.4, doc section 6 |
//!
//! "doc" is `docs/model.md`, "report" the origin homework report. Frames:
//! world NED, body FRD, thrust `u_T` along `-z_b`, `m p'' = m g e3 - u_T R e3 + f_e`.
//! Every law maps a [`Measurement`], a [`Reference`] and optionally a
//! [`WrenchEstimate`] (fed back as doc section 6: `mu -= f_hat / m` and
//! `tau -= Q^-T tau_hat_eta` for the RPY laws, `A -= f_hat` and `tau -= tau_hat^b`
//! for the geometric one) to a [`ControlWrench`] `(u_T, tau^b)`.
//!
//! Whatever comes in (upside down, huge rates, free-fall references, NaN),
//! what comes out is finite: non-finite inputs are replaced by a hold,
//! guards keep the thrust pointing up and the tilt bounded, the RPY laws hand
//! the attitude to the SO(3) loop before `theta` nears 90 deg, and the output
//! is clamped ([`ControlLimits`]).
//!
//! The pieces the laws share, one job a file: `law.rs` (what a law reads in a
//! step and what it returns), `sanitise.rs` (input checks and holds),
//! `rpy.rs` (the RPY laws' thrust/roll/pitch inversion, setpoint stage and
//! recovery), `euler.rs` (ZYX rate map in closed form), `derivative_filter.rs`
//! (`phi_d, theta_d` derivatives), `attitude.rs` (the SO(3) loop),
//! `saturation.rs` (output clamp) and `memo.rs`.
//!
//! Pure: no clock, no I/O, no global state; time enters only through `dt`.
//! Imports `math`, `signals` and `airframe` types, never the plant.

mod attitude;
mod derivative_filter;
mod euler;
mod gains;
mod geometric;
mod hierarchical;
mod law;
mod memo;
mod passivity;
mod relaxed_hover;
mod rpy;
mod sanitise;
mod saturation;
pub mod shaper;

pub use gains::{
    ControlGains, ControlLimits, GainError, GainOverrides, GainProblem, GeometricGains, GeometricOverrides,
    HierarchicalGains, HierarchicalOverrides, LimitsOverrides, PassivityGains, PassivityOverrides,
};
pub use geometric::JUMP_RATE_RAD_S;
pub use relaxed_hover::{
    Equilibrium, RelaxedHover, RelaxedHoverError, RelaxedHoverGains, RelaxedHoverPhase, UpSchedule,
};
pub use shaper::{Setpoint, Shaper, ShaperError, ShaperLimits, TranslationSetpoint, YawSetpoint};

use nalgebra::{Rotation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use crate::signals::{ControlWrench, GRAVITY};
use crate::signals::{Measurement, NominalModel, WrenchEstimate};
use attitude::{AttitudeTarget, so3_attitude};
use law::{LawInput, LawOutput};
use sanitise::{
    NO_ESTIMATE, all_finite, estimate_usable, finite_m3, finite_or_zero, finite3, measurement_ok, model_ok,
    sanitize_estimate, sanitize_reference,
};
use saturation::saturate;

/// `e3 = [0, 0, 1]`: NED down.
fn e3() -> Vector3<f64> {
    Vector3::new(0.0, 0.0, 1.0)
}

/// Which control law flies the vehicle (PX4-style parameter `CTRL_TYPE`: 0, 1, 2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ControllerKind {
    /// Two-loop RPY law with partial feedback linearization (`CTRL_TYPE` 0).
    Hierarchical,
    /// Geometric law on SE(3) (`CTRL_TYPE` 1).
    #[default]
    Geometric,
    /// Passivity-based RPY law (`CTRL_TYPE` 2).
    Passivity,
}

impl ControllerKind {
    /// All laws, in `CTRL_TYPE` order.
    pub const ALL: [ControllerKind; 3] = [
        ControllerKind::Hierarchical,
        ControllerKind::Geometric,
        ControllerKind::Passivity,
    ];

    /// Lower-case name, as in files and on the command line.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            ControllerKind::Hierarchical => "hierarchical",
            ControllerKind::Geometric => "geometric",
            ControllerKind::Passivity => "passivity",
        }
    }

    /// The `CTRL_TYPE` parameter value.
    #[must_use]
    pub fn param_value(self) -> i32 {
        match self {
            ControllerKind::Hierarchical => 0,
            ControllerKind::Geometric => 1,
            ControllerKind::Passivity => 2,
        }
    }
}

impl std::fmt::Display for ControllerKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A `CTRL_TYPE` value or controller name that names no law.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum UnknownControllerKind {
    /// Parameter value outside 0..=2.
    #[error("CTRL_TYPE {0} is not a controller (0 hierarchical, 1 geometric, 2 passivity)")]
    Value(i32),
    /// Unknown name.
    #[error("unknown controller `{0}` (hierarchical, geometric, passivity)")]
    Name(String),
}

impl TryFrom<i32> for ControllerKind {
    type Error = UnknownControllerKind;

    fn try_from(v: i32) -> Result<Self, Self::Error> {
        match v {
            0 => Ok(ControllerKind::Hierarchical),
            1 => Ok(ControllerKind::Geometric),
            2 => Ok(ControllerKind::Passivity),
            _ => Err(UnknownControllerKind::Value(v)),
        }
    }
}

impl std::str::FromStr for ControllerKind {
    type Err = UnknownControllerKind;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        ControllerKind::ALL
            .into_iter()
            .find(|k| k.name().eq_ignore_ascii_case(s))
            .ok_or_else(|| UnknownControllerKind::Name(s.to_string()))
    }
}

/// The desired trajectory at one instant: a flat output (position and yaw)
/// with its derivatives. Laws use position to acceleration and yaw to yaw
/// acceleration; jerk and snap are carried for feedforward and logging.
#[derive(Clone, Copy, Debug, PartialEq, Default, Serialize, Deserialize)]
pub struct Reference {
    /// `p_d` [m], NED.
    pub position_ned: Vector3<f64>,
    /// `p_d'` [m/s], NED.
    pub velocity_ned: Vector3<f64>,
    /// `p_d''` [m/s^2], NED.
    pub acceleration_ned: Vector3<f64>,
    /// `p_d'''` [m/s^3], NED.
    pub jerk_ned: Vector3<f64>,
    /// `p_d''''` [m/s^4], NED.
    pub snap_ned: Vector3<f64>,
    /// `psi_d` [rad] (ZYX yaw, from North towards East).
    pub yaw_rad: f64,
    /// `psi_d'` [rad/s].
    pub yaw_rate_rad_s: f64,
    /// `psi_d''` [rad/s^2].
    pub yaw_accel_rad_s2: f64,
}

impl Reference {
    /// Hover at `position_ned` [m] with heading `yaw_rad` [rad]; all derivatives zero.
    #[must_use]
    pub fn hold(position_ned: Vector3<f64>, yaw_rad: f64) -> Self {
        Self {
            position_ned,
            yaw_rad,
            ..Self::default()
        }
    }

    /// Whether every field is finite.
    #[must_use]
    pub fn is_finite(&self) -> bool {
        let [p, v, a, j, s] = [
            &self.position_ned,
            &self.velocity_ned,
            &self.acceleration_ned,
            &self.jerk_ned,
            &self.snap_ned,
        ];
        all_finite(&[
            p.x,
            p.y,
            p.z,
            v.x,
            v.y,
            v.z,
            a.x,
            a.y,
            a.z,
            j.x,
            j.y,
            j.z,
            s.x,
            s.y,
            s.z,
            self.yaw_rad,
            self.yaw_rate_rad_s,
            self.yaw_accel_rad_s2,
        ])
    }
}

/// What the controller did in its last step (telemetry, logs, tests).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ControlStatus {
    /// Law that produced the output.
    pub kind: ControllerKind,
    /// Time stamp of the measurement used [s].
    pub time_s: f64,
    /// Desired attitude (FRD to NED).
    pub attitude_sp: UnitQuaternion<f64>,
    /// Desired body rate [rad/s], desired body frame.
    pub rate_sp_frd: Vector3<f64>,
    /// Thrust the law asked for before the output clamp [N].
    pub thrust_request_n: f64,
    /// `e_p = p - p_d` [m], NED.
    pub position_error_ned: Vector3<f64>,
    /// `e_v = v - v_d` [m/s], NED.
    pub velocity_error_ned: Vector3<f64>,
    /// Attitude error [rad]: `e_R` (FRD) for the SO(3) loop, `eta - eta_d` for the RPY loops.
    pub attitude_error_rad: Vector3<f64>,
    /// A guard changed the request (tilt, vertical acceleration).
    pub guard_active: bool,
    /// The output clamp changed the wrench.
    pub output_saturated: bool,
    /// An RPY law handed its attitude to the SO(3) loop.
    pub recovery: bool,
    /// The desired attitude jumped and its derivatives were restarted.
    pub reference_jump: bool,
    /// Some input (measurement, reference, estimate, model, `dt`) was not usable and was replaced.
    pub input_replaced: bool,
    /// The output came from [`Controller::update_attitude`].
    pub attitude_mode: bool,
}

impl Default for ControlStatus {
    fn default() -> Self {
        Self {
            kind: ControllerKind::default(),
            time_s: 0.0,
            attitude_sp: UnitQuaternion::identity(),
            rate_sp_frd: Vector3::zeros(),
            thrust_request_n: 0.0,
            position_error_ned: Vector3::zeros(),
            velocity_error_ned: Vector3::zeros(),
            attitude_error_rad: Vector3::zeros(),
            guard_active: false,
            output_saturated: false,
            recovery: false,
            reference_jump: false,
            input_replaced: false,
            attitude_mode: false,
        }
    }
}

/// The flight controller: one active law, switchable at run time.
///
/// ```
/// use nalgebra::{UnitQuaternion, Vector3};
/// use rotorpilot::airframe::Airframe;
/// use rotorpilot::control::{ControlGains, Controller, ControllerKind, Reference};
/// use rotorpilot::signals::Measurement;
///
/// let airframe = Airframe::load("quad").unwrap();
/// let model = airframe.nominal();
/// let mut ctl = Controller::new(ControllerKind::Geometric, ControlGains::for_vehicle(&model)).unwrap();
/// let on_the_ground = Measurement {
///     time_s: 0.0,
///     position_ned: Vector3::new(0.0, 0.0, -0.24),
///     velocity_ned: Vector3::zeros(),
///     attitude: UnitQuaternion::identity(),
///     rate_frd: Vector3::zeros(),
/// };
/// let reference = Reference::hold(Vector3::new(0.0, 0.0, -2.0), 0.0);
/// let wrench = ctl.update(&model, &on_the_ground, &reference, None, 0.001);
/// assert!(wrench.thrust_n > 0.0);
/// ```
#[derive(Clone, Debug)]
pub struct Controller {
    kind: ControllerKind,
    gains: ControlGains,
    hierarchical: hierarchical::Hierarchical,
    geometric: geometric::Geometric,
    passivity: passivity::Passivity,
    status: ControlStatus,
    last: Option<ControlWrench>,
    /// The last call was `update_attitude`: the position laws restart on the next `update`.
    attitude_mode: bool,
}

impl Controller {
    /// A controller running `kind` with `gains`.
    ///
    /// # Errors
    /// The first invalid gain ([`ControlGains::validate`]).
    pub fn new(kind: ControllerKind, gains: ControlGains) -> Result<Self, GainError> {
        gains.validate()?;
        Ok(Self {
            kind,
            gains,
            hierarchical: hierarchical::Hierarchical::default(),
            geometric: geometric::Geometric::default(),
            passivity: passivity::Passivity::default(),
            status: ControlStatus {
                kind,
                ..ControlStatus::default()
            },
            last: None,
            attitude_mode: false,
        })
    }

    /// The active law.
    #[must_use]
    pub fn kind(&self) -> ControllerKind {
        self.kind
    }

    /// The gains in use.
    #[must_use]
    pub fn gains(&self) -> &ControlGains {
        &self.gains
    }

    /// Replace the gains (internal state kept, so the change is bumpless up to the gains).
    ///
    /// # Errors
    /// The first invalid gain; the old gains stay in force.
    pub fn set_gains(&mut self, gains: ControlGains) -> Result<(), GainError> {
        gains.validate()?;
        self.gains = gains;
        Ok(())
    }

    /// What the last step did.
    #[must_use]
    pub fn status(&self) -> &ControlStatus {
        &self.status
    }

    /// Switch to `kind`, bumplessly: the new law's internal state (derivative
    /// filters, previous `R_d`) is cleared and re-initialised from the first
    /// measurement it sees, so its derivative terms start at zero instead of
    /// kicking. Switching to the active law does nothing.
    pub fn switch_to(&mut self, kind: ControllerKind) {
        if kind != self.kind {
            self.reset_law(kind);
            self.kind = kind;
        }
    }

    /// Clear all internal state (after disarm, a reference reset or a long pause).
    pub fn reset(&mut self) {
        for k in ControllerKind::ALL {
            self.reset_law(k);
        }
        self.last = None;
        self.attitude_mode = false;
        self.status = ControlStatus {
            kind: self.kind,
            ..ControlStatus::default()
        };
    }

    fn reset_law(&mut self, kind: ControllerKind) {
        match kind {
            ControllerKind::Hierarchical => self.hierarchical.reset(),
            ControllerKind::Geometric => self.geometric.reset(),
            ControllerKind::Passivity => self.passivity.reset(),
        }
    }

    /// Hold output when the inputs are unusable: the last thrust (or hover), no torque.
    fn hold(&mut self, model: &NominalModel, time_s: f64) -> ControlWrench {
        let thrust = self.last.map_or(model.mass_kg * GRAVITY, |w| w.thrust_n);
        let out = if model_ok(model) {
            saturate(thrust, &Vector3::zeros(), model, &self.gains.limits).0
        } else {
            ControlWrench::default()
        };
        self.status = ControlStatus {
            kind: self.kind,
            time_s: if time_s.is_finite() { time_s } else { self.status.time_s },
            thrust_request_n: out.thrust_n,
            input_replaced: true,
            ..ControlStatus::default()
        };
        out
    }

    /// One control step: total thrust `u_T` [N] and body torque `tau^b` [N m, FRD]
    /// for the measurement `meas` and reference `reference`, with the optional
    /// external-wrench `estimate` fed back, `dt` [s] after the previous step
    /// (used for the laws' numerical derivatives; `<= 0` or non-finite means
    /// "same instant": no derivative update). Always finite.
    pub fn update(
        &mut self,
        model: &NominalModel,
        meas: &Measurement,
        reference: &Reference,
        estimate: Option<&WrenchEstimate>,
        dt: f64,
    ) -> ControlWrench {
        update_controller(self, model, meas, reference, estimate, dt)
    }

    /// The body of [`Self::update`], inlined into both versions of
    /// [`update_controller`].
    #[inline(always)]
    fn update_inner(
        &mut self,
        model: &NominalModel,
        meas: &Measurement,
        reference: &Reference,
        estimate: Option<&WrenchEstimate>,
        dt: f64,
    ) -> ControlWrench {
        if !model_ok(model) || !measurement_ok(meas) {
            for k in ControllerKind::ALL {
                self.reset_law(k);
            }
            return self.hold(model, meas.time_s);
        }
        if self.attitude_mode {
            self.reset_law(self.kind);
            self.attitude_mode = false;
        }
        let dt_ok = dt.is_finite() && dt >= 0.0;
        let dt = if dt_ok { dt } else { 0.0 };
        // one finiteness test on the hot path; the part-by-part repair only when it fails
        let ref_replaced = !reference.is_finite();
        let held;
        let reference = if ref_replaced {
            held = sanitize_reference(reference, meas);
            &held
        } else {
            reference
        };
        let capped;
        let (est, est_replaced) = match estimate {
            None => (&NO_ESTIMATE, false),
            Some(e) if estimate_usable(e, model, &self.gains.limits) => (e, false),
            Some(e) => {
                capped = sanitize_estimate(e, model, &self.gains.limits);
                (&capped.0, capped.1)
            }
        };
        let g = &self.gains;
        let input = LawInput {
            model,
            measurement: meas,
            reference,
            estimate: est,
            limits: &g.limits,
            dt,
        };
        let out: LawOutput = match self.kind {
            ControllerKind::Hierarchical => self.hierarchical.update(&g.hierarchical, &input),
            ControllerKind::Geometric => self.geometric.update(&g.geometric, &input),
            ControllerKind::Passivity => self.passivity.update(&g.passivity, &input),
        };
        let (wrench, saturated) = saturate(out.thrust_n, &out.torque_frd, model, &g.limits);
        self.status = ControlStatus {
            kind: self.kind,
            time_s: meas.time_s,
            attitude_sp: attitude_of(&out.attitude_sp),
            rate_sp_frd: finite_or_zero(&out.rate_sp_frd),
            thrust_request_n: if out.thrust_n.is_finite() {
                out.thrust_n
            } else {
                wrench.thrust_n
            },
            position_error_ned: input.position_error(),
            velocity_error_ned: input.velocity_error(),
            attitude_error_rad: finite_or_zero(&out.attitude_error),
            guard_active: out.limited,
            output_saturated: saturated,
            recovery: out.recovery,
            reference_jump: out.reference_jump,
            input_replaced: ref_replaced || est_replaced || !dt_ok,
            attitude_mode: false,
        };
        self.last = Some(wrench);
        wrench
    }

    /// Attitude and thrust setpoint (offboard `SET_ATTITUDE_TARGET`): the
    /// geometric attitude loop (doc section 5) with the geometric gains,
    /// `R_d` = `attitude_sp` (FRD to NED), `omega_d` = `body_rate_ff_frd` [rad/s]
    /// in the desired body frame, `omega_d' = 0`, and `thrust_n` [N] passed
    /// through the output clamp. Non-finite setpoints hold the current attitude
    /// and hover thrust. The position laws restart on the next [`Self::update`].
    /// `dt` [s] is accepted for symmetry with `update`; this mode keeps no
    /// derivatives (a finite difference of offboard rate setpoints arriving at
    /// 50 Hz would only add torque spikes).
    pub fn update_attitude(
        &mut self,
        model: &NominalModel,
        meas: &Measurement,
        attitude_sp: &UnitQuaternion<f64>,
        body_rate_ff_frd: &Vector3<f64>,
        thrust_n: f64,
        dt: f64,
    ) -> ControlWrench {
        let _ = dt;
        if !model_ok(model) || !measurement_ok(meas) {
            return self.hold(model, meas.time_s);
        }
        self.attitude_mode = true;
        let r = *meas.attitude.to_rotation_matrix().matrix();
        let sp_ok = attitude_sp.coords.iter().all(|x| x.is_finite()) && attitude_sp.coords.norm() > 0.5;
        let r_d = if sp_ok {
            *UnitQuaternion::new_normalize(*attitude_sp.quaternion())
                .to_rotation_matrix()
                .matrix()
        } else {
            r
        };
        let w_d = finite_or_zero(body_rate_ff_frd);
        let thrust = if thrust_n.is_finite() {
            thrust_n
        } else {
            model.mass_kg * GRAVITY
        };
        let target = AttitudeTarget {
            r_d: &r_d,
            omega_d: &w_d,
            omega_dot_d: &Vector3::zeros(),
        };
        let out = so3_attitude(
            &model.inertia_kg_m2,
            &r,
            &meas.rate_frd,
            &target,
            &self.gains.geometric.so3(),
        );
        let (wrench, saturated) = saturate(thrust, &out.torque, model, &self.gains.limits);
        self.status = ControlStatus {
            kind: self.kind,
            time_s: meas.time_s,
            attitude_sp: attitude_of(&r_d),
            rate_sp_frd: w_d,
            thrust_request_n: thrust,
            attitude_error_rad: finite_or_zero(&out.e_r),
            output_saturated: saturated,
            input_replaced: !sp_ok || !finite3(body_rate_ff_frd) || !thrust_n.is_finite(),
            attitude_mode: true,
            ..ControlStatus::default()
        };
        self.last = Some(wrench);
        wrench
    }
}

// Compiled for the x86-64 baseline and for AVX2, the CPU picking one at the
// first call: the same bits, fewer instructions (why: the comment above
// `step_plant` in sim/plant.rs). The laws, the input checks and the output
// clamp are inlined into it.

/// [`Controller::update`].
#[multiversion::multiversion(targets("x86_64+avx2"))]
fn update_controller(
    ctrl: &mut Controller,
    model: &NominalModel,
    meas: &Measurement,
    reference: &Reference,
    estimate: Option<&WrenchEstimate>,
    dt: f64,
) -> ControlWrench {
    ctrl.update_inner(model, meas, reference, estimate, dt)
}

/// Unit quaternion of a rotation matrix (identity if not finite).
#[inline(always)]
fn attitude_of(r: &nalgebra::Matrix3<f64>) -> UnitQuaternion<f64> {
    if finite_m3(r) {
        UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(*r))
    } else {
        UnitQuaternion::identity()
    }
}

/// The attitude whose thrust gives the acceleration `acceleration_ned` [m/s^2]
/// (any mass) with heading `yaw_rad`: the geometric law's `R_d` with zero
/// feedback (doc section 5), `z_d = (g e3 - a) / |g e3 - a|`,
/// `y_d = (z_d x x_c) / |z_d x x_c|`, `x_d = y_d x z_d`. Useful to start a simulation
/// on a reference. Level with the heading when undefined (free fall, non-finite input).
#[must_use]
pub fn feedforward_attitude(acceleration_ned: &Vector3<f64>, yaw_rad: f64) -> UnitQuaternion<f64> {
    let z_d = (e3() * GRAVITY - acceleration_ned).normalize();
    let (s, c) = yaw_rad.sin_cos();
    let y_d = z_d.cross(&Vector3::new(c, s, 0.0)).normalize();
    let r = nalgebra::Matrix3::from_columns(&[y_d.cross(&z_d), y_d, z_d]);
    if finite_m3(&r) {
        attitude_of(&r)
    } else if yaw_rad.is_finite() {
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw_rad)
    } else {
        UnitQuaternion::identity()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn controller_kind_names_and_parameter_values() {
        for (k, name, v) in [
            (ControllerKind::Hierarchical, "\"hierarchical\"", 0),
            (ControllerKind::Geometric, "\"geometric\"", 1),
            (ControllerKind::Passivity, "\"passivity\"", 2),
        ] {
            assert_eq!(serde_json::to_string(&k).unwrap(), name);
            assert_eq!(serde_json::from_str::<ControllerKind>(name).unwrap(), k);
            assert_eq!(ControllerKind::try_from(v).unwrap(), k);
            assert_eq!(k.param_value(), v);
            assert_eq!(k.name().parse::<ControllerKind>().unwrap(), k);
        }
        assert_eq!(
            ControllerKind::try_from(3).unwrap_err(),
            UnknownControllerKind::Value(3)
        );
        assert!("pid".parse::<ControllerKind>().is_err());
        assert!(serde_json::from_str::<ControllerKind>("\"Geometric\"").is_err());
    }

    #[test]
    fn feedforward_attitude_tilts_thrust_into_the_acceleration() {
        let a = Vector3::new(2.0, -1.0, -0.5);
        let q = feedforward_attitude(&a, 0.4);
        // thrust along -z_b must give g e3 - (u/m) z_b = a
        let z_b = q * Vector3::z();
        let u_over_m = (e3() * GRAVITY - a).norm();
        assert!((e3() * GRAVITY - z_b * u_over_m - a).norm() < 1e-12);
        // heading: y_d is normal to x_c = [cos psi, sin psi, 0] (Lee et al.), so x_d lies in its vertical plane
        assert!(
            (q * Vector3::y())
                .dot(&Vector3::new(0.4f64.cos(), 0.4f64.sin(), 0.0))
                .abs()
                < 1e-12
        );
        let level = feedforward_attitude(&Vector3::new(0.0, 0.0, GRAVITY), 0.4);
        assert!(level.coords.iter().all(|x| x.is_finite()));
    }

    #[test]
    fn new_rejects_invalid_gains_and_switching_is_idempotent() {
        let mut g = ControlGains::report();
        g.limits.max_tilt_rad = f64::NAN;
        assert!(Controller::new(ControllerKind::Geometric, g).is_err());
        let mut c = Controller::new(ControllerKind::Geometric, ControlGains::report()).unwrap();
        c.switch_to(ControllerKind::Geometric);
        assert_eq!(c.kind(), ControllerKind::Geometric);
        c.switch_to(ControllerKind::Passivity);
        assert_eq!(c.kind(), ControllerKind::Passivity);
        assert!(c.set_gains(g).is_err());
        assert_eq!(c.gains(), &ControlGains::report());
    }
}
