//! The plant: a multirotor as a 6-DoF rigid body in NED/FRD, stepped by
//! simulated time only (`docs/model.md` section 2).
//!
//! ```text
//! p' = v
//! m v' = m g e3 - u_T R e3 + f_e                  (f_e world NED)
//! q'  = 1/2 q (x) [0, w]                           (R = R(q): FRD -> NED)
//! I w' = -w x I w + tau + tau_e - w x sum_i h_i - gamma w
//!                                                  (tau_e body FRD, h_i = -s_i J_r omega_i e3,
//!                                                   -gamma w: rotational drag, doc section 3b)
//! [u_T, tau] = B (r (x) omega^2)                   (r: ground/ceiling ratio per rotor, yaw row unscaled)
//! omega_i' = (h_i clamp(omega_cmd_i, omega_min, omega_max) - omega_i) / tau_m   (h_i: 1 healthy, 0 dead motor)
//! ```
//!
//! Aerodynamics (RotorPy's `Multirotor(aero=True)` terms in FRD, doc section
//! 8b; [`Plant::aero_wrench_frd`]): with the wind `w` (NED, held over the
//! step) the body airspeed is `v_a = R^T (v - w)` and hub `i`'s
//! `v_i = v_a + w x r_i`; then, in body FRD,
//!
//! ```text
//! f_a = -|v_a| C_D v_a + sum_i (H_i - k_h (v_i,x^2 + v_i,y^2) e3)     C_D = diag(c_dx, c_dy, c_dz)
//! H_i = -omega_i diag(k_d, k_d, k_z) v_i
//! tau_a = sum_i r_i x (H_i - k_h (v_i,x^2 + v_i,y^2) e3) + k_flap omega_i [v_i,y, -v_i,x, 0]
//! m v' += R f_a,   I w' += tau_a
//! ```
//!
//! evaluated once a step, at its start state and start rotor speeds, and
//! held over the step with the external wrench (`Drag`, `sim/drag.rs`, writes the rotor
//! sum in closed form).
//! With every coefficient 0 the terms are skipped, bit for bit.
//!
//! Integration: fixed-step RK4 (1 ms by default) with the command held over the
//! step; the motor lag is integrated exactly (`omega(t) = w_bar + (omega_0 - w_bar) e^{-t/tau_m}`)
//! and evaluated at the RK4 stage times, as is the external wrench. The
//! quaternion is renormalised after every step. Ground and ceiling ratios are
//! evaluated once per step, at its start.
//!
//! Ground contact: flat ground at `environment.ground_z_ned`. When a step ends with
//! the centre of mass at or below its resting height (`gear_height_m` above the
//! ground) the vehicle rests: height clamped, velocity and angular velocity
//! zeroed, roll and pitch levelled, yaw kept. A resting vehicle therefore stays
//! exactly put (no sinking, bouncing or drift) until its thrust exceeds its
//! weight. The step reports touchdown and liftoff.

use nalgebra::{Matrix3, Quaternion, SMatrix, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use super::aero::AeroEffects;
use super::drag::Drag;
use crate::airframe::{Actuation, AeroCoefficients, Airframe, Allocator};
use crate::signals::{ActuatorCommand, ControlWrench, DEFAULT_STEP_S, GRAVITY, MAX_ROTORS, Measurement, RotorVector};

/// External wrench acting on the body.
#[derive(Clone, Copy, Debug, PartialEq, Default, Serialize, Deserialize)]
pub struct ExternalWrench {
    /// Force [N], world NED.
    pub force_ned: Vector3<f64>,
    /// Torque [N m], body FRD.
    pub torque_frd: Vector3<f64>,
}

/// An external wrench that may change with simulated time; evaluated at the RK4 stage times.
pub trait Disturbance {
    /// The wrench at simulated time `t_s` [s].
    fn wrench_at(&self, t_s: f64) -> ExternalWrench;
}

impl Disturbance for ExternalWrench {
    fn wrench_at(&self, _t_s: f64) -> ExternalWrench {
        *self
    }
}

impl<F: Fn(f64) -> ExternalWrench> Disturbance for F {
    fn wrench_at(&self, t_s: f64) -> ExternalWrench {
        self(t_s)
    }
}

/// The environment every vehicle of the world shares: flat ground, an
/// optional flat ceiling, and whether their aerodynamic effects are simulated.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Environment {
    /// NED z of the flat ground surface [m] (0: the home altitude).
    pub ground_z_ned: f64,
    /// NED z of a flat ceiling [m], if any (must be above the vehicle: smaller z).
    pub ceiling_z_ned: Option<f64>,
    /// Apply ground effect.
    pub ground_effect: bool,
    /// Apply ceiling effect (when a ceiling exists).
    pub ceiling_effect: bool,
}

impl Default for Environment {
    fn default() -> Self {
        Self {
            ground_z_ned: 0.0,
            ceiling_z_ned: None,
            ground_effect: true,
            ceiling_effect: true,
        }
    }
}

/// Rigid-body state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RigidBodyState {
    /// Position of the centre of mass [m], NED.
    pub position_ned: Vector3<f64>,
    /// Velocity [m/s], NED.
    pub velocity_ned: Vector3<f64>,
    /// Attitude, body FRD to NED.
    pub attitude: UnitQuaternion<f64>,
    /// Angular velocity [rad/s], body FRD.
    pub rate_frd: Vector3<f64>,
}

impl RigidBodyState {
    /// At rest at `position_ned`, level, heading north.
    #[must_use]
    pub fn at_rest(position_ned: Vector3<f64>) -> Self {
        Self {
            position_ned,
            velocity_ned: Vector3::zeros(),
            attitude: UnitQuaternion::identity(),
            rate_frd: Vector3::zeros(),
        }
    }
}

/// Whether the vehicle rests on the ground.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Contact {
    /// Flying.
    Airborne,
    /// Resting on the ground.
    OnGround,
}

/// What happened during a step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StepEvent {
    /// Nothing noteworthy.
    None,
    /// The vehicle came down on the ground with this downward speed [m/s].
    Touchdown {
        /// Vertical speed at contact [m/s], positive down.
        speed_m_s: f64,
    },
    /// The vehicle left the ground.
    Liftoff,
}

/// Why a step was refused; the state is left unchanged.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum SimFault {
    /// A command held NaN or infinity.
    #[error("actuator command is not finite")]
    NonFiniteCommand,
    /// Integration produced NaN or infinity (the state was kept).
    #[error("state became non-finite during integration")]
    NonFiniteState,
}

/// Plant options beyond the airframe.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlantConfig {
    /// Integration step [s].
    pub dt_s: f64,
    /// Environment.
    pub environment: Environment,
}

impl Default for PlantConfig {
    fn default() -> Self {
        Self {
            dt_s: DEFAULT_STEP_S,
            environment: Environment::default(),
        }
    }
}

/// The simulated vehicle.
#[derive(Clone, Debug)]
pub struct Plant {
    actuation: Actuation,
    n: usize,
    /// `B`, zero-padded.
    b: SMatrix<f64, 4, MAX_ROTORS>,
    /// The columns of `B` as plain arrays (the rotor loops visit only the first `n`).
    b_cols: [[f64; 4]; MAX_ROTORS],
    allocator: Allocator,
    rotor_positions_frd: [Vector3<f64>; MAX_ROTORS],
    spin: RotorVector,
    rotor_inertia: f64,
    speed_min: f64,
    speed_max: f64,
    gear_height_m: f64,
    /// Rotational drag `gamma` [N m s]: body torque `-gamma w` (0: none, and
    /// the derivative skips the term, so a drag-free plant is bit-for-bit the
    /// plant without it).
    rotational_drag: f64,
    /// Longest arm [m] (bounds how far a rotor can be from the centre vertically).
    max_arm_m: f64,
    aero: AeroEffects,
    environment: Environment,
    dt: f64,
    /// `e^{-h/(2 tau_m)}`, `e^{-h/tau_m}`.
    decay: (f64, f64),
    mass: f64,
    /// `1 / mass` [1/kg].
    inv_mass: f64,
    inertia: Matrix3<f64>,
    /// `inertia` as the derivative applies it.
    body_inertia: BodyInertia,
    state: RigidBodyState,
    rotor_speed: RotorVector,
    contact: Contact,
    steps: u64,
    /// Per-rotor speed factor of a faulty motor (`None`: all healthy).
    rotor_health: Option<RotorVector>,
    last_wrench: ControlWrench,
    last_external: ExternalWrench,
    /// The drag model of body and rotors.
    drag: Drag,
    /// Whether any of its coefficients is not 0 (else the aerodynamic terms are skipped).
    aero_on: bool,
    /// The air's velocity at the vehicle [m/s], NED, held over a step.
    wind_ned: Vector3<f64>,
    /// The aerodynamic wrench at the start of the last step (force NED, torque FRD).
    last_aero: ExternalWrench,
}

/// `1 / sqrt(n)`, by its series `1 - e/2 + 3 e^2/8` (`e = n - 1`, remainder
/// below `0.32 |e|^3 < 1e-16`) when `|e| < 1e-6`, as for the squared norm
/// of a quaternion after one RK4 step: no square root and no division on
/// the step's critical path.
fn inv_sqrt_near_one(n: f64) -> f64 {
    let e = n - 1.0;
    if e.abs() < 1e-6 {
        1.0 - e * (0.5 - 0.375 * e)
    } else {
        1.0 / n.sqrt()
    }
}

/// The true body inertia as the derivative uses it, `I w` and `I^-1 x`,
/// with a cheaper diagonal case (airframe files give principal inertias).
#[derive(Clone, Copy, Debug)]
enum BodyInertia {
    /// `diag(i)`, `diag(inv)` [kg m^2], [1/(kg m^2)].
    Diagonal { i: Vector3<f64>, inv: Vector3<f64> },
    /// Any invertible inertia [kg m^2] and its inverse.
    Full { i: Matrix3<f64>, inv: Matrix3<f64> },
}

impl BodyInertia {
    /// `None` when `i` is not invertible.
    fn new(i: &Matrix3<f64>) -> Option<Self> {
        let inv = i.try_inverse()?;
        let diagonal = |m: &Matrix3<f64>| (0..3).all(|r| (0..3).all(|c| r == c || m[(r, c)] == 0.0));
        Some(if diagonal(i) && diagonal(&inv) {
            // the same values as the full products (the zeros add exactly nothing)
            Self::Diagonal {
                i: i.diagonal(),
                inv: inv.diagonal(),
            }
        } else {
            Self::Full { i: *i, inv }
        })
    }

    /// `I w`.
    #[inline]
    fn apply(&self, w: &Vector3<f64>) -> Vector3<f64> {
        match self {
            Self::Diagonal { i, .. } => i.component_mul(w),
            Self::Full { i, .. } => i * w,
        }
    }

    /// `I^-1 x`.
    #[inline]
    fn solve(&self, x: &Vector3<f64>) -> Vector3<f64> {
        match self {
            Self::Diagonal { inv, .. } => inv.component_mul(x),
            Self::Full { inv, .. } => inv * x,
        }
    }
}

/// `R(q)` (FRD to NED) of the state's unit quaternion (a step-start state:
/// renormalised by the step before).
fn rotation_matrix(s: &RigidBodyState) -> Matrix3<f64> {
    let q = s.attitude.quaternion();
    let (w, x, y, z) = (q.w, q.i, q.j, q.k);
    let (x2, y2, z2) = (x + x, y + y, z + z);
    let (xx, yy, zz) = (x * x2, y * y2, z * z2);
    let (xy, xz, yz) = (x * y2, x * z2, y * z2);
    let (wx, wy, wz) = (w * x2, w * y2, w * z2);
    Matrix3::new(
        1.0 - (yy + zz),
        xy - wz,
        xz + wy,
        xy + wz,
        1.0 - (xx + zz),
        yz - wx,
        xz - wy,
        yz + wx,
        1.0 - (xx + yy),
    )
}

/// Time derivative of the rigid-body part.
struct Deriv {
    p: Vector3<f64>,
    v: Vector3<f64>,
    q: Quaternion<f64>,
    w: Vector3<f64>,
}

impl Plant {
    /// A plant for `airframe`, resting on the ground at the NED origin, rotors stopped.
    /// True mass and inertia start at the airframe's nominal values.
    #[must_use]
    pub fn new(airframe: &Airframe, config: PlantConfig) -> Self {
        let n = airframe.rotor_count();
        let mut positions = [Vector3::zeros(); MAX_ROTORS];
        let mut spin = RotorVector::zeros();
        for (i, r) in airframe.rotors.iter().enumerate() {
            positions[i] = r.position_frd();
            spin[i] = r.spin.sign();
        }
        let allocator = airframe.allocator();
        let tau_m = airframe.rotor.time_constant_s;
        let dt = config.dt_s;
        let rest = Vector3::new(0.0, 0.0, config.environment.ground_z_ned - airframe.gear_height_m);
        let inertia = airframe.inertia_kg_m2;
        Self {
            actuation: airframe.actuation,
            n,
            b: *allocator.b(),
            b_cols: std::array::from_fn(|j| std::array::from_fn(|i| allocator.b()[(i, j)])),
            allocator,
            rotor_positions_frd: positions,
            spin,
            rotor_inertia: airframe.rotor.inertia_kg_m2,
            speed_min: airframe.rotor.speed_min_rad_s,
            speed_max: airframe.rotor.speed_max_rad_s,
            gear_height_m: airframe.gear_height_m,
            rotational_drag: airframe.rotational_drag_n_m_s,
            max_arm_m: airframe.rotors.iter().fold(0.0, |m, r| r.arm_m.max(m)),
            aero: AeroEffects::new(airframe),
            environment: config.environment,
            dt,
            decay: ((-0.5 * dt / tau_m).exp(), (-dt / tau_m).exp()),
            mass: airframe.mass_kg,
            inv_mass: 1.0 / airframe.mass_kg,
            inertia,
            body_inertia: BodyInertia::new(&inertia).unwrap_or(BodyInertia::Full {
                i: inertia,
                inv: Matrix3::zeros(),
            }),
            state: RigidBodyState::at_rest(rest),
            rotor_speed: RotorVector::zeros(),
            contact: Contact::OnGround,
            steps: 0,
            rotor_health: None,
            last_wrench: ControlWrench::default(),
            last_external: ExternalWrench::default(),
            drag: Drag::new(airframe),
            aero_on: !airframe.aero.is_zero(),
            wind_ned: Vector3::zeros(),
            last_aero: ExternalWrench::default(),
        }
    }

    /// Set the air's velocity at the vehicle [m/s], NED, for the next steps
    /// (held constant over each step, as RotorPy holds it).
    pub fn set_wind_ned(&mut self, wind_ned: Vector3<f64>) {
        self.wind_ned = wind_ned;
    }

    /// The air's velocity at the vehicle [m/s], NED.
    #[must_use]
    pub fn wind_ned(&self) -> Vector3<f64> {
        self.wind_ned
    }

    /// The aerodynamic coefficients the plant flies with.
    #[must_use]
    pub fn aero_coefficients(&self) -> &AeroCoefficients {
        self.drag.coefficients()
    }

    /// The aerodynamic wrench at the start of the last step: force [N] world
    /// NED, torque [N m] body FRD (zero when every coefficient is 0).
    #[must_use]
    pub fn last_aero_wrench(&self) -> ExternalWrench {
        self.last_aero
    }

    /// The aerodynamic force and torque on the body, both body FRD [N], [N m],
    /// at `state` (its quaternion of unit norm) with rotor speeds `speeds`
    /// [rad/s] in the wind set by [`Self::set_wind_ned`] (the terms of the
    /// module doc, the closed form of `Drag` in `sim/drag.rs`).
    #[must_use]
    pub fn aero_wrench_frd(&self, state: &RigidBodyState, speeds: &RotorVector) -> (Vector3<f64>, Vector3<f64>) {
        let r = rotation_matrix(state);
        self.drag.wrench_frd(
            &r.tr_mul(&(state.velocity_ned - self.wind_ned)),
            &state.rate_frd,
            speeds,
        )
    }

    /// The aerodynamic wrench as the step adds it: force [N] world NED
    /// (`R f_a`), torque [N m] body FRD.
    #[inline(always)]
    fn aero_ned(&self, state: &RigidBodyState, speeds: &RotorVector) -> ExternalWrench {
        let r = rotation_matrix(state);
        let (f, torque_frd) = self.drag.wrench_frd(
            &r.tr_mul(&(state.velocity_ned - self.wind_ned)),
            &state.rate_frd,
            speeds,
        );
        ExternalWrench {
            force_ned: r * f,
            torque_frd,
        }
    }

    /// Simulated time [s] (`steps x dt`).
    #[must_use]
    pub fn time_s(&self) -> f64 {
        self.steps as f64 * self.dt
    }

    /// Integration step [s].
    #[must_use]
    pub fn dt_s(&self) -> f64 {
        self.dt
    }

    /// True state.
    #[must_use]
    pub fn state(&self) -> &RigidBodyState {
        &self.state
    }

    /// Replace the true state (initial conditions). The contact flag follows the new height.
    pub fn set_state(&mut self, state: RigidBodyState) {
        self.state = state;
        self.contact = if state.position_ned.z >= self.rest_z() - 1e-12 {
            Contact::OnGround
        } else {
            Contact::Airborne
        };
    }

    /// Rotor speeds [rad/s].
    #[must_use]
    pub fn rotor_speeds(&self) -> &RotorVector {
        &self.rotor_speed
    }

    /// Set rotor speeds [rad/s] (initial conditions, e.g. spinning at hover).
    pub fn set_rotor_speeds(&mut self, speeds: &RotorVector) {
        self.rotor_speed = *speeds;
    }

    /// Number of rotors.
    #[must_use]
    pub fn rotor_count(&self) -> usize {
        self.n
    }

    /// Ground contact.
    #[must_use]
    pub fn contact(&self) -> Contact {
        self.contact
    }

    /// True mass [kg].
    #[must_use]
    pub fn true_mass_kg(&self) -> f64 {
        self.mass
    }

    /// Change the true mass [kg] (payload drop, wrong nominal mass). Ignored unless finite and > 0.
    pub fn set_true_mass(&mut self, mass_kg: f64) {
        if mass_kg.is_finite() && mass_kg > 0.0 {
            self.mass = mass_kg;
            self.inv_mass = 1.0 / mass_kg;
        }
    }

    /// Rotational drag coefficient `gamma` [N m s] (body torque `-gamma w`).
    #[must_use]
    pub fn rotational_drag_n_m_s(&self) -> f64 {
        self.rotational_drag
    }

    /// True inertia [kg m^2], FRD.
    #[must_use]
    pub fn true_inertia(&self) -> &Matrix3<f64> {
        &self.inertia
    }

    /// Change the true inertia. Ignored unless invertible and finite.
    pub fn set_true_inertia(&mut self, inertia: Matrix3<f64>) {
        if inertia.iter().all(|x| x.is_finite())
            && let Some(body) = BodyInertia::new(&inertia)
        {
            self.inertia = inertia;
            self.body_inertia = body;
        }
    }

    /// Environment.
    #[must_use]
    pub fn environment(&self) -> &Environment {
        &self.environment
    }

    /// Set the step count (the clock of a world the plant joins late).
    pub fn set_steps(&mut self, steps: u64) {
        self.steps = steps;
    }

    /// The true acceleration at the current state [m/s^2], NED:
    /// `a = g e3 + (-u_T R e3 + f_e) / m` with the thrust and external force
    /// of the last step and the true mass; zero resting on the ground.
    #[must_use]
    pub fn acceleration_ned(&self) -> Vector3<f64> {
        if self.contact == Contact::OnGround {
            return Vector3::zeros();
        }
        let q = self.state.attitude.quaternion();
        let (w, x, y, z) = (q.w, q.i, q.j, q.k);
        let r_e3 = Vector3::new(
            2.0 * (x * z + w * y),
            2.0 * (y * z - w * x),
            w * w - x * x - y * y + z * z,
        );
        let mut f = self.last_external.force_ned - r_e3 * self.last_wrench.thrust_n;
        if self.aero_on {
            f += self.last_aero.force_ned;
        }
        f * self.inv_mass + Vector3::new(0.0, 0.0, GRAVITY)
    }

    /// How commands reach the body.
    #[must_use]
    pub fn actuation(&self) -> Actuation {
        self.actuation
    }

    /// The rotor speed commands [rad/s] that give `wrench` (the airframe's
    /// allocator, with desaturation).
    #[must_use]
    pub fn allocate(&self, wrench: &ControlWrench) -> RotorVector {
        self.allocator.allocate(wrench).speed_cmd_rad_s
    }

    /// Run rotor `i` (from 0) at `factor` times its commanded speed: 1 healthy,
    /// 0 a dead motor (it spins down with its lag), between them a motor that
    /// cannot reach its command. A factor outside `[0, 1]` or a rotor beyond
    /// the count changes nothing.
    pub fn set_rotor_health(&mut self, i: usize, factor: f64) {
        if i >= self.n || !(0.0..=1.0).contains(&factor) {
            return;
        }
        let mut h = self.rotor_health.unwrap_or_else(|| {
            let mut ones = RotorVector::zeros();
            ones.rows_mut(0, self.n).fill(1.0);
            ones
        });
        h[i] = factor;
        // all healthy again: back to the path without a multiplication
        self.rotor_health = (h.rows(0, self.n).iter().any(|f| *f != 1.0)).then_some(h);
    }

    /// Change the environment (effects on/off, ceiling height).
    pub fn set_environment(&mut self, environment: Environment) {
        self.environment = environment;
    }

    /// The thrust and body torque the rotors applied at the start of the last step.
    #[must_use]
    pub fn last_wrench(&self) -> ControlWrench {
        self.last_wrench
    }

    /// The injected external wrench at the start of the last step (the
    /// aerodynamic one, which the step adds to it, is [`Self::last_aero_wrench`]).
    #[must_use]
    pub fn last_external_wrench(&self) -> ExternalWrench {
        self.last_external
    }

    /// The true state as a noiseless measurement.
    #[must_use]
    pub fn truth(&self) -> Measurement {
        Measurement {
            time_s: self.time_s(),
            position_ned: self.state.position_ned,
            velocity_ned: self.state.velocity_ned,
            attitude: self.state.attitude,
            rate_frd: self.state.rate_frd,
        }
    }

    fn rest_z(&self) -> f64 {
        self.environment.ground_z_ned - self.gear_height_m
    }

    /// Per-rotor thrust ratio from ground and ceiling effect at the current state.
    #[inline(always)]
    fn thrust_ratios(&self) -> Option<RotorVector> {
        let ground = self.environment.ground_effect;
        let ceiling = self.environment.ceiling_effect && self.environment.ceiling_z_ned.is_some();
        if !ground && !ceiling {
            return None;
        }
        // Cheap reject before any per-rotor transform: no rotor is nearer a
        // surface than the centre's distance minus the longest arm.
        let z = self.state.position_ned.z;
        let ground_far = !ground || self.environment.ground_z_ned - z - self.max_arm_m > self.aero.ground_cutoff_m();
        let ceiling_far = !ceiling
            || self
                .environment
                .ceiling_z_ned
                .is_none_or(|zc| z - zc - self.max_arm_m > self.aero.ceiling_cutoff_m());
        if ground_far && ceiling_far {
            return None;
        }
        // only the third row of R(q) is needed: (R p_i).z, with the rounding of
        // `to_rotation_matrix` and of the matrix-vector product
        let q = &self.state.attitude;
        let (w, i, j, k) = (q.w, q.i, q.j, q.k);
        let r31 = i * k * 2.0 - w * j * 2.0;
        let r32 = w * i * 2.0 + j * k * 2.0;
        let r33 = w * w - i * i - j * j + k * k;
        let n = self.n;
        let mut rotor_z = [0.0; MAX_ROTORS];
        for (z, p) in rotor_z[..n].iter_mut().zip(&self.rotor_positions_frd) {
            *z = self.state.position_ned.z + (r31 * p.x + r32 * p.y + r33 * p.z);
        }
        let mut ratio: Option<RotorVector> = None;
        if ground {
            let mut heights = [0.0; MAX_ROTORS];
            for (h, z) in heights[..n].iter_mut().zip(&rotor_z) {
                *h = self.environment.ground_z_ned - z;
            }
            ratio = self.aero.ground_ratios_if_near(&heights);
        }
        if ceiling && let Some(zc) = self.environment.ceiling_z_ned {
            let mut gaps = [0.0; MAX_ROTORS];
            for (g, z) in gaps[..n].iter_mut().zip(&rotor_z) {
                *g = z - zc;
            }
            if let Some(c) = self.aero.ceiling_ratios_if_near(&gaps) {
                ratio = Some(ratio.map_or(c, |g| g.component_mul(&c)));
            }
        }
        ratio
    }

    /// Rotor wrench `B (r (x) w)` with the yaw row on unscaled `w`.
    /// Only the `n` used columns of the padded `B` are visited.
    fn rotor_wrench(&self, speed_sq: &RotorVector, ratio: &RotorVector) -> ControlWrench {
        let n = self.n;
        let mut acc = [0.0; 4];
        for ((col, &x), &rj) in self.b_cols[..n]
            .iter()
            .zip(&speed_sq.as_slice()[..n])
            .zip(&ratio.as_slice()[..n])
        {
            let xs = x * rj;
            acc[0] += col[0] * xs;
            acc[1] += col[1] * xs;
            acc[2] += col[2] * xs;
            // yaw row on the unscaled speeds
            acc[3] += col[3] * x;
        }
        ControlWrench::new(acc[0], Vector3::new(acc[1], acc[2], acc[3]))
    }

    /// The exact first-order motor lag towards `target` evaluated at the
    /// stage times `t, t + h/2, t + h`,
    /// `omega(t + s) = w_bar + (omega(t) - w_bar) e^{-s/tau_m}`, and at each of
    /// them the rotor wrench `B (r (x) omega^2)` (yaw row on unscaled
    /// `omega^2`) and the rotors' spin momentum `-J_r sum_i s_i omega_i`.
    /// One pass over the `n` rotors; also returns the speeds at `t + h`.
    #[inline(always)]
    fn lagged_rotor_wrenches(
        &self,
        target: &RotorVector,
        ratio: Option<&RotorVector>,
    ) -> ([ControlWrench; 3], [f64; 3], RotorVector) {
        let (decay_half, decay_full) = self.decay;
        let mut acc = [[0.0; 4]; 3];
        let mut spin = [0.0; 3];
        let mut end = RotorVector::zeros();
        // n <= MAX_ROTORS, said to the compiler: no bounds checks in the loop
        for i in 0..self.n.min(MAX_ROTORS) {
            let (bar, om0) = (target[i], self.rotor_speed[i]);
            let speeds = [om0, bar + (om0 - bar) * decay_half, bar + (om0 - bar) * decay_full];
            end[i] = speeds[2];
            let (col, r, s) = (&self.b_cols[i], ratio.map_or(1.0, |r| r[i]), self.spin[i]);
            for ((a, sp), om) in acc.iter_mut().zip(&mut spin).zip(speeds) {
                let x = om * om;
                let xs = x * r;
                a[0] += col[0] * xs;
                a[1] += col[1] * xs;
                a[2] += col[2] * xs;
                a[3] += col[3] * x;
                *sp += s * om;
            }
        }
        let j = -self.rotor_inertia;
        (
            acc.map(|a| ControlWrench::new(a[0], Vector3::new(a[1], a[2], a[3]))),
            spin.map(|x| j * x),
            end,
        )
    }

    #[inline(always)]
    fn deriv(&self, s: &RigidBodyState, w: &ControlWrench, ext: &ExternalWrench, gyro_h: f64) -> Deriv {
        // thrust along -z_b in NED: -u_T R e3, with R e3 the third column of
        // R(q) = [2(xz + wy), 2(yz - wx), w^2 - x^2 - y^2 + z^2] / |q|^2 (RK4
        // stages carry unnormalised quaternions); one division per evaluation
        let q = s.attitude.quaternion();
        let (qw, qx, qy, qz) = (q.w, q.i, q.j, q.k);
        let inv_m = self.inv_mass;
        let thrust_per_m = -w.thrust_n * inv_m / q.norm_squared();
        let acc = Vector3::new(
            thrust_per_m * (2.0 * (qx * qz + qw * qy)) + ext.force_ned.x * inv_m,
            thrust_per_m * (2.0 * (qy * qz - qw * qx)) + ext.force_ned.y * inv_m,
            thrust_per_m * (qw * qw - qx * qx - qy * qy + qz * qz) + ext.force_ned.z * inv_m + GRAVITY,
        );
        let om = s.rate_frd;
        // rotor gyroscopics: -w x sum h_i with sum h_i = [0, 0, gyro_h]
        let gyro = Vector3::new(-om.y * gyro_h, om.x * gyro_h, 0.0);
        let mut torque = w.torque_frd + ext.torque_frd + gyro - om.cross(&self.body_inertia.apply(&om));
        if self.rotational_drag != 0.0 {
            // rotational drag tau_d = -gamma w (body FRD)
            torque -= om * self.rotational_drag;
        }
        let alpha = self.body_inertia.solve(&torque);
        // q' = 1/2 q (x) [0, w], written out (the product with a pure quaternion)
        let (hx, hy, hz) = (0.5 * om.x, 0.5 * om.y, 0.5 * om.z);
        let qd = Quaternion::new(
            -qx * hx - qy * hy - qz * hz,
            qw * hx + qy * hz - qz * hy,
            qw * hy + qz * hx - qx * hz,
            qw * hz + qx * hy - qy * hx,
        );
        Deriv {
            p: s.velocity_ned,
            v: acc,
            q: qd,
            w: alpha,
        }
    }

    #[inline(always)]
    fn advance(s: &RigidBodyState, d: &Deriv, h: f64) -> RigidBodyState {
        RigidBodyState {
            position_ned: s.position_ned + d.p * h,
            velocity_ned: s.velocity_ned + d.v * h,
            // intermediate stages use the unnormalised sum (RK4 on R^4), renormalised at the end
            attitude: UnitQuaternion::new_unchecked(s.attitude.quaternion() + d.q * h),
            rate_frd: s.rate_frd + d.w * h,
        }
    }

    /// `s + h/6 (k1 + 2 k2 + 2 k3 + k4)`, the quaternion renormalised.
    #[inline(always)]
    fn rk4_combine(s: &RigidBodyState, k1: &Deriv, k2: &Deriv, k3: &Deriv, k4: &Deriv, h: f64) -> RigidBodyState {
        let sixth = h / 6.0;
        let q = s.attitude.quaternion() + (k1.q + (k2.q + k3.q) * 2.0 + k4.q) * sixth;
        RigidBodyState {
            position_ned: s.position_ned + (k1.p + (k2.p + k3.p) * 2.0 + k4.p) * sixth,
            velocity_ned: s.velocity_ned + (k1.v + (k2.v + k3.v) * 2.0 + k4.v) * sixth,
            attitude: UnitQuaternion::new_unchecked(q * inv_sqrt_near_one(q.norm_squared())),
            rate_frd: s.rate_frd + (k1.w + (k2.w + k3.w) * 2.0 + k4.w) * sixth,
        }
    }

    /// The aerodynamic wrench of the step (force [N] NED, torque [N m] FRD),
    /// held over it: the terms at the step's start state and start rotor
    /// speeds (the motor lag's `omega_0`, or with ideal actuation and no
    /// target the speeds that give the applied wrench `direct`,
    /// `sqrt(max(B^+ [u_T, tau], 0))`). Inlined into both versions of the
    /// step, so that it runs the AVX2 code too.
    #[inline(always)]
    fn aero_held(&self, s: &RigidBodyState, target: Option<&RotorVector>, direct: &ControlWrench) -> ExternalWrench {
        match target {
            Some(_) => self.aero_ned(s, &self.rotor_speed),
            None => {
                let w = self.allocator.inverse(direct).map(|x| x.max(0.0).sqrt());
                self.aero_ned(s, &w)
            }
        }
    }

    /// Clamp the vehicle's rotor commands to `[omega_min, omega_max]`; unused slots stay 0.
    #[inline(always)]
    fn clamp_speeds(&self, w: &RotorVector) -> RotorVector {
        let mut out = RotorVector::zeros();
        for i in 0..self.n.min(MAX_ROTORS) {
            out[i] = w[i].clamp(self.speed_min, self.speed_max);
        }
        out
    }

    /// Advance one step of `dt` under `cmd` and `disturbance`.
    ///
    /// # Errors
    /// [`SimFault`] when the command or the result is not finite; the state is then unchanged.
    pub fn step<D: Disturbance + ?Sized>(
        &mut self,
        cmd: &ActuatorCommand,
        disturbance: &D,
    ) -> Result<StepEvent, SimFault> {
        step_plant(self, cmd, disturbance)
    }

    /// The body of [`Self::step`], inlined into both versions of [`step_plant`].
    #[inline(always)]
    fn advance_step<D: Disturbance + ?Sized>(
        &mut self,
        cmd: &ActuatorCommand,
        disturbance: &D,
    ) -> Result<StepEvent, SimFault> {
        let h = self.dt;
        let t = self.time_s();
        let ratio = self.thrust_ratios();

        // Rotor speed targets, or a directly acting wrench.
        let target: Option<RotorVector> = match (self.actuation, cmd) {
            (Actuation::Ideal, _) => None,
            (Actuation::Rotors, ActuatorCommand::Stop) => Some(RotorVector::zeros()),
            (Actuation::Rotors, ActuatorCommand::RotorSpeeds(w)) => {
                if !w.as_slice().iter().all(|x| x.is_finite()) {
                    return Err(SimFault::NonFiniteCommand);
                }
                Some(self.clamp_speeds(w))
            }
            (Actuation::Rotors, ActuatorCommand::Wrench(wr)) => {
                if !(wr.thrust_n.is_finite() && wr.torque_frd.as_slice().iter().all(|x| x.is_finite())) {
                    return Err(SimFault::NonFiniteCommand);
                }
                Some(self.allocator.allocate(wr).speed_cmd_rad_s)
            }
        };

        let mut target = target;
        if let (Some(t), Some(h)) = (&mut target, &self.rotor_health) {
            t.component_mul_assign(h);
        }
        let (w0, wmid, w1, spin_mom, rotor_speed_next) = if let Some(bar) = target {
            // exact first-order lag at the stage times t, t + h/2, t + h
            let (w, spin_mom, om1) = self.lagged_rotor_wrenches(&bar, ratio.as_ref());
            (w[0], w[1], w[2], spin_mom, om1)
        } else {
            let direct = match cmd {
                ActuatorCommand::Stop => ControlWrench::default(),
                ActuatorCommand::RotorSpeeds(w) => ControlWrench::from_vector(&(self.b * w.component_mul(w))),
                ActuatorCommand::Wrench(wr) => *wr,
            };
            if !direct.to_vector().iter().all(|x| x.is_finite()) {
                return Err(SimFault::NonFiniteCommand);
            }
            let direct = match ratio {
                // ideal actuation near a surface: spread over the rotors, scale, recombine
                Some(r) => self.rotor_wrench(&self.allocator.inverse(&direct), &r),
                None => direct,
            };
            (direct, direct, direct, [0.0; 3], self.rotor_speed)
        };

        let mut e0 = disturbance.wrench_at(t);
        let mut emid = disturbance.wrench_at(t + 0.5 * h);
        let mut e1 = disturbance.wrench_at(t + h);

        let s = self.state;
        // the injected wrench alone is the step's external wrench; the
        // aerodynamic one is reported beside it (`last_aero`), so that
        // `acceleration_ned` adds it once
        let injected = e0;
        if self.aero_on {
            // the aerodynamic wrench, held over the step, joins the external one
            let a = self.aero_held(&s, target.as_ref(), &w0);
            for e in [&mut e0, &mut emid, &mut e1] {
                e.force_ned += a.force_ned;
                e.torque_frd += a.torque_frd;
            }
            self.last_aero = a;
        }
        let k1 = self.deriv(&s, &w0, &e0, spin_mom[0]);
        let s2 = Self::advance(&s, &k1, 0.5 * h);
        let k2 = self.deriv(&s2, &wmid, &emid, spin_mom[1]);
        let s3 = Self::advance(&s, &k2, 0.5 * h);
        let k3 = self.deriv(&s3, &wmid, &emid, spin_mom[1]);
        let s4 = Self::advance(&s, &k3, h);
        let k4 = self.deriv(&s4, &w1, &e1, spin_mom[2]);
        let mut next = Self::rk4_combine(&s, &k1, &k2, &k3, &k4, h);
        let finite3 = |v: &Vector3<f64>| v.x.is_finite() && v.y.is_finite() && v.z.is_finite();
        let c = &next.attitude.coords;
        let finite = finite3(&next.position_ned)
            && finite3(&next.velocity_ned)
            && finite3(&next.rate_frd)
            && c.x.is_finite()
            && c.y.is_finite()
            && c.z.is_finite()
            && c.w.is_finite();
        if !finite {
            return Err(SimFault::NonFiniteState);
        }

        // Ground contact.
        let rest_z = self.rest_z();
        let mut event = StepEvent::None;
        if next.position_ned.z >= rest_z {
            // Resting: a vehicle already on the ground keeps its exact pose (no
            // drift, no creep); one touching down keeps where it arrived, levelled.
            let (x, y, attitude) = match self.contact {
                Contact::OnGround => (s.position_ned.x, s.position_ned.y, s.attitude),
                Contact::Airborne => {
                    event = StepEvent::Touchdown {
                        speed_m_s: next.velocity_ned.z.max(0.0),
                    };
                    let yaw = crate::math::euler_zyx(&next.attitude).z;
                    (
                        next.position_ned.x,
                        next.position_ned.y,
                        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw),
                    )
                }
            };
            next = RigidBodyState {
                position_ned: Vector3::new(x, y, rest_z),
                velocity_ned: Vector3::zeros(),
                attitude,
                rate_frd: Vector3::zeros(),
            };
            self.contact = Contact::OnGround;
        } else if self.contact == Contact::OnGround {
            event = StepEvent::Liftoff;
            self.contact = Contact::Airborne;
        }

        self.state = next;
        self.rotor_speed = rotor_speed_next;
        self.last_wrench = w0;
        self.last_external = injected;
        self.steps += 1;
        Ok(event)
    }
}

// The step is compiled twice, for the x86-64 baseline and with AVX2 (three-
// operand instructions, wider vectors), and the first call picks the version
// this CPU runs. Both give the same bits: additions, products, divisions and
// roots are IEEE operations rounded the same at any vector width, and Rust
// neither fuses `a * b + c` nor reorders sums. The work of the step (ground
// effect, motor lag, drag, RK4) is inlined into it, so all of it gets the
// wider code. The control law, allocation and the shaper are compiled the
// same way, as the estimator's update is.

/// [`Plant::step`].
#[multiversion::multiversion(targets("x86_64+avx2"))]
fn step_plant<D: Disturbance + ?Sized>(
    plant: &mut Plant,
    cmd: &ActuatorCommand,
    disturbance: &D,
) -> Result<StepEvent, SimFault> {
    plant.advance_step(cmd, disturbance)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The series agrees with `1 / sqrt(n)` to rounding where it is used,
    /// and the exact form takes over beyond.
    #[test]
    fn inverse_square_root_near_one() {
        for e in [0.0_f64, 1e-16, -3e-12, 5e-9, -9.9e-7, 9.9e-7, 1.1e-6, -0.5, 3.0] {
            let n = 1.0 + e;
            let exact = 1.0 / n.sqrt();
            assert!(
                (inv_sqrt_near_one(n) - exact).abs() <= 2.0 * f64::EPSILON * exact,
                "{e}"
            );
        }
    }

    /// Rotational drag alone on a spinning body with stopped rotors decays the
    /// yaw rate as `r(t) = r0 e^{-gamma t / I_zz}`; without drag the rate stays.
    #[test]
    fn rotational_drag_decays_the_spin_exponentially() {
        let with = Airframe::load("quad").unwrap();
        assert_eq!(with.rotational_drag_n_m_s, 0.013);
        let text = include_str!("../../params/airframes/quad.toml")
            .replace("rotational_drag_n_m_s = 0.013", "rotational_drag_n_m_s = 0.0");
        let without = Airframe::from_toml(&text, "quad without drag").unwrap();
        assert_eq!(without.rotational_drag_n_m_s, 0.0);
        for (af, gamma) in [(with, 0.013), (without, 0.0)] {
            let mut plant = Plant::new(&af, PlantConfig::default());
            let mut s = RigidBodyState::at_rest(Vector3::new(0.0, 0.0, -100.0));
            s.rate_frd = Vector3::new(0.0, 0.0, 10.0);
            plant.set_state(s);
            for _ in 0..1000 {
                plant.step(&ActuatorCommand::Stop, &ExternalWrench::default()).unwrap();
            }
            let expected = 10.0 * (-gamma * plant.time_s() / af.inertia_kg_m2[(2, 2)]).exp();
            let r = plant.state().rate_frd.z;
            assert!((r - expected).abs() < 1e-9, "gamma {gamma}: {r} vs {expected}");
            assert_eq!(plant.rotational_drag_n_m_s(), gamma);
        }
        let bad = include_str!("../../params/airframes/quad.toml")
            .replace("rotational_drag_n_m_s = 0.013", "rotational_drag_n_m_s = -0.01");
        let e = Airframe::from_toml(&bad, "bad.toml").unwrap_err().to_string();
        assert!(
            e.contains("bad.toml") && e.contains("body.rotational_drag_n_m_s"),
            "{e}"
        );
    }

    /// The diagonal fast path of the inertia equals the full products.
    #[test]
    fn diagonal_inertia_equals_full_products() {
        let i = Matrix3::from_diagonal(&Vector3::new(0.0217, 0.0219, 0.04));
        let body = BodyInertia::new(&i).unwrap();
        assert!(matches!(body, BodyInertia::Diagonal { .. }));
        let full = BodyInertia::Full {
            i,
            inv: i.try_inverse().unwrap(),
        };
        let w = Vector3::new(0.3, -1.7, 2.9);
        assert_eq!(body.apply(&w), full.apply(&w));
        assert_eq!(body.solve(&w), full.solve(&w));
        let skew = Matrix3::new(0.03, 0.001, 0.0, 0.001, 0.04, 0.0, 0.0, 0.0, 0.05);
        assert!(matches!(BodyInertia::new(&skew), Some(BodyInertia::Full { .. })));
        assert!(BodyInertia::new(&Matrix3::zeros()).is_none());
    }
}
