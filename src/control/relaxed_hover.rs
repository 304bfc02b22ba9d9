//! Flying a quadrotor that has lost one rotor: give up yaw, let the body spin
//! and control the reduced attitude (the direction of the mean thrust) only,
//! descending slowly under position control; rotors cut at touchdown.
//! Mueller and D'Andrea, "Stability and control of a quadrocopter despite the
//! complete loss of one, two, or three propellers" (ICRA 2014) and "Relaxed
//! hover solutions for multicopters" (IJRR 2015); `docs/model.md`
//! section 3b.
//!
//! Frames: world NED, body FRD. Rotor `i` at `r_i = l_i [cos a_i, sin a_i, 0]`
//! gives thrust `f_i >= 0` along `-z_b` and drag torque `s_i kappa f_i` about
//! `+z_b` (`kappa = c_Q / c_T`); the body feels rotational drag `-gamma w`
//! (the airframe's `rotational_drag_n_m_s`, part of the nominal model) and the
//! rotors' gyroscopic torque `-w x H`, `H = -J_r sum_i s_i omega_i e3`.
//!
//! **(1) Equilibrium.** The body spins at the constant rate `w_bar` about a
//! body-fixed unit vector `n_bar` that points up in the world (`R n_bar = -e3`):
//!
//! ```text
//! tau(f) - gamma w_bar n_bar - w_bar^2 n_bar x I n_bar - w_bar n_bar x H(f) = 0   (torque, body)
//! sum_i f_i (-n_bar_z) = m g                                                     (mean thrust along up)
//! tau(f) = sum_i [ f_i l_i (-sin a_i, cos a_i, 0) + (0, 0, s_i kappa f_i) ]
//! ```
//!
//! Four equations, six unknowns (`f` of the three live rotors, `n_bar` on `S^2`,
//! `w_bar`). As in the paper, the two rotors next to the dead one carry equal
//! thrust `f_a` and the opposite rotor `rho f_a`; for each `rho` on a grid the
//! remaining unknowns `(f_a, n_x, n_y, w_bar)` come from Newton's method, and
//! the `rho` whose largest rotor thrust is smallest (most control margin) wins.
//! The thrust direction `-e3` is tilted from `n_bar`: the horizontal thrust
//! turns with the body and averages out over a revolution.
//!
//! **(2) Reduced attitude on `S^2`** (a geometric law in place of the paper's
//! LQR, doc section 3b). With `t` the desired up direction in the world (unit)
//! and `d = R^T t` in the body, `d' = d x w`. The rate command
//!
//! ```text
//! w_c = a n + k_n (n x d),      a = (w_z - k_n (n x d)_z) / n_z
//! ```
//!
//! makes `V = 1 - n . d` decay, `V' = -k_n |n x d|^2`, whatever the spin `a`
//! about `n` (left free: `a` follows the measured `w_z`). Only the body `x, y`
//! rates are tracked, with the two independent torques:
//!
//! ```text
//! tau_xy = [ w x I w + gamma w + w x H + I (k_w (w_c - w) + w_c') ]_xy,   w_c' ~ k_n n x (d x w)
//! ```
//!
//! `n` is `n_bar` once the body spins at `w_bar`; while it spins up from a
//! normal hover it is scheduled on the measured spin,
//! `n(s) = normalize((1 - s)(-e3) + s n_bar)`, `s = clamp(w . n_bar / w_bar, 0, 1)`,
//! so the thrust axis is not tilted before the spin that averages its
//! horizontal part out exists ([`UpSchedule`]; `k_n |n x d|` is capped at
//! `max_tilt_rate_rad_s`).
//!
//! **(3) Position and descent.** `a_des = -K_p (p - p_t)_xy - K_v v_xy` (bounded),
//! `a_des,z = -K_vz (v_z - v_descent)`; the wanted force `f_w = m (a_des - g e3)`
//! gives `t = f_w / |f_w|` and the total thrust `F = |f_w| / (-n_z)`.
//! `(F, tau_x, tau_y)` go to the three live rotors through the 3 x 3 map
//! `[1 1 1; -l_i sin a_i; l_i cos a_i] f = [F, tau_x, tau_y]` (yaw torque is
//! whatever results); attitude first: when a rotor would exceed `c_T omega_max^2`
//! the total thrust is lowered, and only below 60 % of the weight is the torque
//! scaled down instead.
//!
//! **(4) Touchdown.** Once the centre of mass is within 1 cm of its resting
//! height above the target (`target_z - gear_height`), every rotor is cut
//! (commanded 0) and stays cut.
//!
//! Pure: no clock, no I/O; time enters through `dt`. It sees the vehicle only
//! through a [`Measurement`] and its nominal model (the [`Airframe`] and
//! [`NominalModel`]), never the plant.

use nalgebra::{Matrix3, Matrix4, Vector3, Vector4};

use crate::airframe::Airframe;
use crate::signals::{GRAVITY, Measurement, NominalModel, RotorVector};

/// Why no relaxed-hover controller can be built for this vehicle.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum RelaxedHoverError {
    /// Relaxed hover here is for a quadrotor with one dead rotor.
    #[error("relaxed hover needs a quadrotor, this airframe has {0} rotors")]
    NotAQuad(usize),
    /// The dead rotor does not exist.
    #[error("rotor {} does not exist: the vehicle has {count}", rotor + 1)]
    NoSuchRotor {
        /// The rotor asked for, from 0.
        rotor: usize,
        /// How many rotors there are.
        count: usize,
    },
    /// Without rotational drag the spin has no equilibrium (it grows without bound).
    #[error("the airframe has no rotational drag (body.rotational_drag_n_m_s = 0): the spin has no equilibrium")]
    NoRotationalDrag,
    /// The three live rotors cannot hold the vehicle up (or the layout is degenerate).
    #[error("no relaxed-hover equilibrium within the rotor limits: {0}")]
    NoEquilibrium(String),
    /// The nominal model is not usable (mass, inertia not finite and positive).
    #[error("nominal model unusable: {0}")]
    BadModel(String),
}

/// The relaxed-hover equilibrium (1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Equilibrium {
    /// `n_bar`: the body vector (unit, FRD) that points up in the world.
    pub up_frd: Vector3<f64>,
    /// `w_bar` [rad/s]: the spin rate about `n_bar` (sign: right hand about `n_bar`).
    pub spin_rad_s: f64,
    /// The rotor thrusts `f_bar_i` [N] (0 for the dead rotor).
    pub thrust_n: RotorVector,
    /// The rotor speeds `sqrt(f_bar_i / c_T)` [rad/s].
    pub speed_rad_s: RotorVector,
    /// `rho`: thrust of the rotor opposite the dead one over that of its neighbours.
    pub opposite_ratio: f64,
    /// Angle between the thrust axis `-z_b` and the world vertical [rad]: `acos(-n_bar_z)`.
    pub tilt_rad: f64,
}

/// Gains of the relaxed-hover controller.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RelaxedHoverGains {
    /// Horizontal position gain `K_p` [1/s^2].
    pub position: f64,
    /// Horizontal velocity gain `K_v` [1/s].
    pub velocity: f64,
    /// Vertical velocity gain `K_vz` [1/s].
    pub vertical_velocity: f64,
    /// Largest horizontal acceleration asked for [m/s^2].
    pub max_horizontal_accel_m_s2: f64,
    /// Largest vertical acceleration asked for, either way [m/s^2].
    pub max_vertical_accel_m_s2: f64,
    /// Reduced-attitude gain `k_n` [1/s].
    pub attitude: f64,
    /// Body-rate gain `k_w` [1/s].
    pub rate: f64,
    /// Largest reduced-attitude rate `k_n |n x d|` asked for [rad/s].
    pub max_tilt_rate_rad_s: f64,
    /// Which up vector `n` the reduced attitude steers to.
    pub up: UpSchedule,
}

/// Which body vector the reduced-attitude loop turns up.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UpSchedule {
    /// Always the equilibrium's `n_bar`.
    Equilibrium,
    /// `n(s)`, from `-e3` (level) at no spin to `n_bar` at the equilibrium spin.
    SpinScheduled,
}

impl Default for RelaxedHoverGains {
    fn default() -> Self {
        Self {
            position: 0.8,
            velocity: 1.6,
            vertical_velocity: 2.0,
            max_horizontal_accel_m_s2: 2.5,
            max_vertical_accel_m_s2: 3.0,
            attitude: 8.0,
            rate: 30.0,
            max_tilt_rate_rad_s: 10.0,
            up: UpSchedule::SpinScheduled,
        }
    }
}

/// Where the landing stands.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RelaxedHoverPhase {
    /// Spinning, descending towards the target.
    Descending,
    /// Down: rotors cut.
    Landed,
}

/// Attitude before thrust, but not below this fraction of the weight [-].
const MIN_THRUST_FRACTION: f64 = 0.6;

/// Margin above the resting height at which the rotors are cut [m].
const TOUCHDOWN_MARGIN_M: f64 = 0.01;

/// The controller for a quadrotor with rotor `dead` gone.
#[derive(Clone, Debug)]
pub struct RelaxedHover {
    dead: usize,
    /// The live rotors, in label order.
    live: [usize; 3],
    positions_frd: [Vector3<f64>; 3],
    /// The dead rotor's hub [m], FRD.
    dead_position_frd: Vector3<f64>,
    spin_sign: [f64; 3],
    /// `[1 1 1; -l sin a; l cos a]^-1`: `(F, tau_x, tau_y)` to live-rotor thrusts.
    alloc_inv: Matrix3<f64>,
    c_t: f64,
    /// `kappa = c_Q / c_T` [m].
    kappa: f64,
    rotor_inertia: f64,
    thrust_min: f64,
    thrust_max: f64,
    gear_height_m: f64,
    gamma: f64,
    mass: f64,
    inertia: Matrix3<f64>,
    equilibrium: Equilibrium,
    gains: RelaxedHoverGains,
    phase: RelaxedHoverPhase,
    /// Last commanded live-rotor speeds [rad/s] (gyroscopic feedforward).
    last_speed: [f64; 3],
}

/// The torque residual and the thrust balance of (1) at `x = (f_a, n_x, n_y, w)`.
struct EquilibriumProblem<'a> {
    hover: &'a RelaxedHover,
    rho: f64,
    /// Index (into `live`) of the rotor opposite the dead one.
    opposite: usize,
}

impl EquilibriumProblem<'_> {
    fn thrusts(&self, fa: f64) -> [f64; 3] {
        std::array::from_fn(|k| if k == self.opposite { self.rho * fa } else { fa })
    }

    fn up(nx: f64, ny: f64) -> Vector3<f64> {
        Vector3::new(nx, ny, -(1.0 - nx * nx - ny * ny).max(1e-9).sqrt())
    }

    fn residual(&self, x: &Vector4<f64>) -> Vector4<f64> {
        let h = self.hover;
        let f = self.thrusts(x[0]);
        let n = Self::up(x[1], x[2]);
        let w = x[3];
        let speeds = f.map(|fi| (fi.max(0.0) / h.c_t).sqrt());
        let tau = h.rotor_torque(&f);
        let big_h = h.spin_momentum(&speeds);
        let r = tau - n * (h.gamma * w) - n.cross(&(h.inertia * n)) * (w * w) - n.cross(&big_h) * w;
        let total: f64 = f.iter().sum();
        Vector4::new(r.x, r.y, r.z, total * (-n.z) - h.mass * GRAVITY)
    }

    /// Newton's method with a forward-difference Jacobian from `x0`.
    fn solve(&self, x0: Vector4<f64>) -> Option<Vector4<f64>> {
        let mut x = x0;
        for _ in 0..60 {
            let r = self.residual(&x);
            if r.amax() < 1e-10 {
                return Some(x);
            }
            let mut j = Matrix4::zeros();
            for k in 0..4 {
                let step = 1e-7 * x[k].abs().max(1e-3);
                let mut xk = x;
                xk[k] += step;
                j.set_column(k, &((self.residual(&xk) - r) / step));
            }
            let dx = j.lu().solve(&r)?;
            x -= dx;
            if !x.iter().all(|v| v.is_finite()) || x[1] * x[1] + x[2] * x[2] >= 1.0 {
                return None;
            }
        }
        (self.residual(&x).amax() < 1e-8).then_some(x)
    }
}

impl RelaxedHover {
    /// The controller for `airframe` (a quadrotor with rotational drag) with
    /// rotor `dead_rotor` (from 0) gone, using the nominal mass and inertia.
    ///
    /// # Errors
    /// [`RelaxedHoverError`]: not a quad, no such rotor, no drag, a degenerate
    /// layout or no equilibrium within the rotor limits.
    pub fn new(airframe: &Airframe, nominal: &NominalModel, dead_rotor: usize) -> Result<Self, RelaxedHoverError> {
        let count = airframe.rotor_count();
        if count != 4 {
            return Err(RelaxedHoverError::NotAQuad(count));
        }
        if dead_rotor >= count {
            return Err(RelaxedHoverError::NoSuchRotor {
                rotor: dead_rotor,
                count,
            });
        }
        let gamma = airframe.rotational_drag_n_m_s;
        if !(gamma.is_finite() && gamma > 0.0) {
            return Err(RelaxedHoverError::NoRotationalDrag);
        }
        let mass = nominal.mass_kg;
        if !(mass.is_finite() && mass > 0.0) {
            return Err(RelaxedHoverError::BadModel(format!("mass {mass} kg")));
        }
        let inertia = nominal.inertia_kg_m2;
        if !inertia.iter().all(|x| x.is_finite()) || inertia.try_inverse().is_none() {
            return Err(RelaxedHoverError::BadModel("inertia not invertible".into()));
        }
        let live: [usize; 3] = {
            let mut it = (0..4).filter(|&i| i != dead_rotor);
            std::array::from_fn(|_| it.next().unwrap_or(0))
        };
        let positions_frd = live.map(|i| airframe.rotors[i].position_frd());
        let spin_sign = live.map(|i| airframe.rotors[i].spin.sign());
        let alloc = Matrix3::from_fn(|r, k| {
            let p = positions_frd[k];
            match r {
                0 => 1.0,
                // r x (-f e3) = f (-p_y, p_x, 0)
                1 => -p.y,
                _ => p.x,
            }
        });
        let alloc_inv = alloc.try_inverse().ok_or_else(|| {
            RelaxedHoverError::NoEquilibrium("the three live rotors are collinear: no roll/pitch authority".into())
        })?;
        let rotor = &airframe.rotor;
        let mut hover = Self {
            dead: dead_rotor,
            live,
            positions_frd,
            dead_position_frd: airframe.rotors[dead_rotor].position_frd(),
            spin_sign,
            alloc_inv,
            c_t: rotor.c_t,
            kappa: rotor.c_q / rotor.c_t,
            rotor_inertia: rotor.inertia_kg_m2,
            thrust_min: rotor.c_t * rotor.speed_min_rad_s.powi(2),
            thrust_max: rotor.c_t * rotor.speed_max_rad_s.powi(2),
            gear_height_m: airframe.gear_height_m,
            gamma,
            mass,
            inertia,
            equilibrium: Equilibrium {
                up_frd: -Vector3::z(),
                spin_rad_s: 0.0,
                thrust_n: RotorVector::zeros(),
                speed_rad_s: RotorVector::zeros(),
                opposite_ratio: 0.0,
                tilt_rad: 0.0,
            },
            gains: RelaxedHoverGains::default(),
            phase: RelaxedHoverPhase::Descending,
            last_speed: [0.0; 3],
        };
        hover.equilibrium = hover.solve_equilibrium()?;
        hover.last_speed = live.map(|i| hover.equilibrium.speed_rad_s[i]);
        Ok(hover)
    }

    /// Rotor torque `tau(f) = sum_i [f_i (-p_y, p_x, 0) + (0, 0, s_i kappa f_i)]`
    /// [N m], body FRD, of the live rotors' thrusts `f` [N].
    fn rotor_torque(&self, f: &[f64; 3]) -> Vector3<f64> {
        let mut tau = Vector3::zeros();
        for ((p, s), fk) in self.positions_frd.iter().zip(&self.spin_sign).zip(f) {
            tau += Vector3::new(-p.y * fk, p.x * fk, s * self.kappa * fk);
        }
        tau
    }

    /// Rotor spin momentum `H = -J_r sum_i s_i omega_i e3` [N m s], body FRD.
    fn spin_momentum(&self, speeds: &[f64; 3]) -> Vector3<f64> {
        let s: f64 = (0..3).map(|k| self.spin_sign[k] * speeds[k]).sum();
        Vector3::new(0.0, 0.0, -self.rotor_inertia * s)
    }
}

/// `n(s) = normalize((1 - s)(-e3) + s n_bar)`: the up vector scheduled on the spin fraction `s` in `[0, 1]`.
fn scheduled_up(n_bar: &Vector3<f64>, s: f64) -> Vector3<f64> {
    let v = -Vector3::z() * (1.0 - s) + n_bar * s;
    let norm = v.norm();
    if norm > 1e-9 { v / norm } else { *n_bar }
}

/// `v` shortened to at most `max` in length.
fn clamp_norm(v: Vector3<f64>, max: f64) -> Vector3<f64> {
    let n = v.norm();
    if n > max { v * (max / n) } else { v }
}

impl RelaxedHover {
    /// (1): scan `rho` (opposite rotor over neighbours), solve the rest by
    /// Newton, keep the solution with the smallest largest rotor thrust.
    fn solve_equilibrium(&self) -> Result<Equilibrium, RelaxedHoverError> {
        // the live rotor opposite the dead one is the one farthest from it
        let opposite = (0..3)
            .max_by(|&a, &b| {
                let da = (self.positions_frd[a] - self.dead_position_frd).norm();
                let db = (self.positions_frd[b] - self.dead_position_frd).norm();
                da.total_cmp(&db)
            })
            .unwrap_or(0);
        let weight = self.mass * GRAVITY;
        let mut best: Option<(f64, f64, Vector4<f64>)> = None;
        let mut last_problem = String::from("Newton's method did not converge for any thrust ratio");
        for step in 1..=30 {
            let rho = f64::from(step) * 0.05;
            let problem = EquilibriumProblem {
                hover: self,
                rho,
                opposite,
            };
            let fa = weight / (2.0 + rho);
            let f = problem.thrusts(fa);
            let yaw = self.rotor_torque(&f).z;
            // drag balances the yaw torque: gamma w (-1) ~ yaw for n ~ -e3
            let w0 = -yaw / self.gamma;
            let Some(x) = problem.solve(Vector4::new(fa, 0.0, 0.0, w0)) else {
                continue;
            };
            let f = problem.thrusts(x[0]);
            let f_max = f.iter().copied().fold(0.0, f64::max);
            if f.iter().any(|&fi| fi < self.thrust_min) || f_max > self.thrust_max {
                last_problem = format!(
                    "the largest rotor thrust {f_max:.3} N exceeds c_T omega_max^2 = {:.3} N (thrust ratio {rho:.2})",
                    self.thrust_max
                );
                continue;
            }
            if best.is_none_or(|(m, _, _)| f_max < m) {
                best = Some((f_max, rho, x));
            }
        }
        let (_, rho, x) = best.ok_or(RelaxedHoverError::NoEquilibrium(last_problem))?;
        let problem = EquilibriumProblem {
            hover: self,
            rho,
            opposite,
        };
        let f = problem.thrusts(x[0]);
        let up = EquilibriumProblem::up(x[1], x[2]);
        let mut thrust = RotorVector::zeros();
        let mut speed = RotorVector::zeros();
        for (&i, &fk) in self.live.iter().zip(&f) {
            thrust[i] = fk;
            speed[i] = (fk / self.c_t).sqrt();
        }
        Ok(Equilibrium {
            up_frd: up,
            spin_rad_s: x[3],
            thrust_n: thrust,
            speed_rad_s: speed,
            opposite_ratio: rho,
            tilt_rad: (-up.z).clamp(-1.0, 1.0).acos(),
        })
    }

    /// The equilibrium the controller flies about.
    #[must_use]
    pub fn equilibrium(&self) -> &Equilibrium {
        &self.equilibrium
    }

    /// The dead rotor (from 0).
    #[must_use]
    pub fn dead_rotor(&self) -> usize {
        self.dead
    }

    /// Descending or landed.
    #[must_use]
    pub fn phase(&self) -> RelaxedHoverPhase {
        self.phase
    }

    /// The gains in use.
    #[must_use]
    pub fn gains(&self) -> &RelaxedHoverGains {
        &self.gains
    }

    /// Replace the gains.
    pub fn set_gains(&mut self, gains: RelaxedHoverGains) {
        self.gains = gains;
    }

    /// One control step: from the measurement at `t_k` to rotor speed
    /// commands [rad/s] held over `[t_k, t_k + dt)` (the dead rotor and, once
    /// landed, every rotor commanded 0). `target_position_ned` [m, NED]: hold
    /// its `x, y` and land on the ground at its `z`; `descent_speed_m_s` [m/s]
    /// (positive down). Non-finite inputs hold the equilibrium command. Once
    /// [`RelaxedHoverPhase::Landed`] it returns zeros: send
    /// `ActuatorCommand::Stop` then (a zero speed command is clamped to idle).
    pub fn update(
        &mut self,
        m: &Measurement,
        target_position_ned: Vector3<f64>,
        descent_speed_m_s: f64,
        dt: f64,
    ) -> RotorVector {
        // the law is static (no integrator, no filter): `dt` is part of the
        // interface every control step has, unused here
        let _ = dt;
        if self.phase == RelaxedHoverPhase::Landed {
            return RotorVector::zeros();
        }
        let finite = |v: &Vector3<f64>| v.iter().all(|x| x.is_finite());
        let q = m.attitude.coords;
        if !(finite(&m.position_ned)
            && finite(&m.velocity_ned)
            && finite(&m.rate_frd)
            && q.iter().all(|x| x.is_finite())
            && finite(&target_position_ned)
            && descent_speed_m_s.is_finite())
        {
            return self.equilibrium.speed_rad_s;
        }
        // (4) touchdown: within the margin of the resting height
        if m.position_ned.z >= target_position_ned.z - self.gear_height_m - TOUCHDOWN_MARGIN_M {
            self.phase = RelaxedHoverPhase::Landed;
            return RotorVector::zeros();
        }
        let g = &self.gains;
        let eq = &self.equilibrium;
        let w = m.rate_frd;

        // scheduled up vector n(s)
        let n = match g.up {
            UpSchedule::Equilibrium => eq.up_frd,
            UpSchedule::SpinScheduled => {
                let s = (w.dot(&eq.up_frd) / eq.spin_rad_s).clamp(0.0, 1.0);
                scheduled_up(&eq.up_frd, s)
            }
        };

        // (3) outer loop: wanted acceleration, force, up direction, thrust
        let e = m.position_ned - target_position_ned;
        let a_xy = clamp_norm(
            Vector3::new(
                -g.position * e.x - g.velocity * m.velocity_ned.x,
                -g.position * e.y - g.velocity * m.velocity_ned.y,
                0.0,
            ),
            g.max_horizontal_accel_m_s2,
        );
        let a_z = (-g.vertical_velocity * (m.velocity_ned.z - descent_speed_m_s))
            .clamp(-g.max_vertical_accel_m_s2, g.max_vertical_accel_m_s2);
        let f_w = (a_xy + Vector3::new(0.0, 0.0, a_z - GRAVITY)) * self.mass;
        let f_norm = f_w.norm().max(1e-6);
        let t_w = f_w / f_norm;
        let thrust = f_norm / (-n.z).max(0.2);

        // (2) reduced attitude on S^2 and the x, y rate loop
        let r = m.attitude.to_rotation_matrix();
        let d = r.inverse() * t_w;
        let e_n = clamp_norm(n.cross(&d) * g.attitude, g.max_tilt_rate_rad_s) / g.attitude;
        let a = (w.z - g.attitude * e_n.z) / n.z;
        let w_c = n * a + e_n * g.attitude;
        let w_c_dot = n.cross(&d.cross(&w)) * g.attitude;
        let speeds = self.last_speed;
        let big_h = self.spin_momentum(&speeds);
        let mut alpha = (w_c - w) * g.rate + w_c_dot;
        alpha.z = 0.0;
        let tau = w.cross(&(self.inertia * w)) + w * self.gamma + w.cross(&big_h) + self.inertia * alpha;

        let f = self.allocate(thrust, tau.x, tau.y);
        let mut out = RotorVector::zeros();
        for ((&i, &fk), last) in self.live.iter().zip(&f).zip(&mut self.last_speed) {
            let speed = (fk / self.c_t).sqrt();
            *last = speed;
            out[i] = speed;
        }
        out
    }

    /// `(F, tau_x, tau_y)` to the live rotors' thrusts [N] within
    /// `[c_T omega_min^2, c_T omega_max^2]`, attitude first (doc section 3):
    /// `f = F' a + lambda b` with `a = M^-1 [1, 0, 0]`, `b = M^-1 [0, tau_x, tau_y]`,
    /// `F' <= F` the largest total that fits with the whole torque (`lambda = 1`);
    /// the torque is scaled down (`lambda < 1`) only when that leaves less than
    /// [`MIN_THRUST_FRACTION`] of the weight.
    fn allocate(&self, thrust: f64, tau_x: f64, tau_y: f64) -> [f64; 3] {
        let a = self.alloc_inv.column(0).into_owned();
        let b = self.alloc_inv * Vector3::new(0.0, tau_x, tau_y);
        let floor = (MIN_THRUST_FRACTION * self.mass * GRAVITY).min(thrust);
        let fit = |lambda: f64| {
            let mut f_total = thrust;
            for (ak, bk) in a.iter().zip(b.iter()) {
                if *ak > 1e-12 {
                    f_total = f_total.min((self.thrust_max - lambda * bk) / ak);
                }
            }
            f_total
        };
        let mut lambda = 1.0;
        if fit(1.0) < floor {
            // bisection on lambda: fit is non-increasing in lambda
            let (mut lo, mut hi) = (0.0, 1.0);
            for _ in 0..30 {
                let mid = 0.5 * (lo + hi);
                if fit(mid) >= floor { lo = mid } else { hi = mid }
            }
            lambda = lo;
        }
        let f_total = fit(lambda).max(0.0);
        std::array::from_fn(|k| (f_total * a[k] + lambda * b[k]).clamp(self.thrust_min, self.thrust_max))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad(gamma: f64) -> Airframe {
        let mut af = Airframe::load("quad").unwrap();
        af.rotational_drag_n_m_s = gamma;
        af
    }

    /// The equilibrium satisfies the torque and thrust balance it states, for every dead rotor.
    #[test]
    fn equilibrium_balances_torque_and_weight() {
        let af = quad(0.013);
        let nominal = af.nominal();
        for dead in 0..4 {
            let h = RelaxedHover::new(&af, &nominal, dead).unwrap();
            let eq = *h.equilibrium();
            assert_eq!(eq.thrust_n[dead], 0.0);
            let f: [f64; 3] = h.live.map(|i| eq.thrust_n[i]);
            let speeds = h.live.map(|i| eq.speed_rad_s[i]);
            let n = eq.up_frd;
            let w = eq.spin_rad_s;
            let residual = h.rotor_torque(&f)
                - n * (h.gamma * w)
                - n.cross(&(h.inertia * n)) * (w * w)
                - n.cross(&h.spin_momentum(&speeds)) * w;
            assert!(residual.amax() < 1e-8, "dead {dead}: torque residual {residual}");
            let up_thrust: f64 = f.iter().sum::<f64>() * (-n.z);
            assert!((up_thrust - nominal.mass_kg * GRAVITY).abs() < 1e-8);
            assert!((n.norm() - 1.0).abs() < 1e-12);
            assert!(f.iter().all(|&x| x <= h.thrust_max && x >= h.thrust_min));
            // a CCW rotor (s = +1) dead leaves the CW rotors' reaction: the body yaws negative
            let s_dead = af.rotors[dead].spin.sign();
            assert!(w * n.z * s_dead < 0.0, "dead {dead}: spin {w} about {n}");
        }
    }

    /// At the equilibrium (n_bar up, spinning at w_bar about it, descending at
    /// the commanded speed above the target) the law commands the equilibrium
    /// rotor speeds: the controller's fixed point is the relaxed hover of (1).
    /// Near the ground it cuts every rotor and stays cut; non-finite input holds.
    #[test]
    fn equilibrium_is_the_fixed_point_and_touchdown_cuts() {
        let af = quad(0.013);
        for dead in 0..4 {
            let mut h = RelaxedHover::new(&af, &af.nominal(), dead).unwrap();
            let eq = *h.equilibrium();
            let attitude = nalgebra::UnitQuaternion::rotation_between(&eq.up_frd, &(-Vector3::z())).unwrap();
            let m = Measurement {
                time_s: 1.0,
                position_ned: Vector3::new(3.0, -2.0, -5.0),
                velocity_ned: Vector3::new(0.0, 0.0, 0.7),
                attitude,
                rate_frd: eq.up_frd * eq.spin_rad_s,
            };
            let target = Vector3::new(3.0, -2.0, 0.0);
            let out = h.update(&m, target, 0.7, 1e-3);
            for i in 0..4 {
                assert!(
                    (out[i] - eq.speed_rad_s[i]).abs() < 1e-6,
                    "dead {dead}, rotor {i}: {} vs {}",
                    out[i],
                    eq.speed_rad_s[i]
                );
            }
            let mut bad = m;
            bad.rate_frd.x = f64::NAN;
            assert_eq!(h.update(&bad, target, 0.7, 1e-3), eq.speed_rad_s);
            assert_eq!(h.phase(), RelaxedHoverPhase::Descending);
            let mut down = m;
            down.position_ned.z = -af.gear_height_m - 0.005;
            assert_eq!(h.update(&down, target, 0.7, 1e-3), RotorVector::zeros());
            assert_eq!(h.phase(), RelaxedHoverPhase::Landed);
            // stays cut even if it bounces up
            assert_eq!(h.update(&m, target, 0.7, 1e-3), RotorVector::zeros());
        }
    }

    #[test]
    fn refuses_what_it_cannot_fly() {
        let af = quad(0.0);
        assert_eq!(
            RelaxedHover::new(&af, &af.nominal(), 0).unwrap_err(),
            RelaxedHoverError::NoRotationalDrag
        );
        let af = quad(0.013);
        assert!(matches!(
            RelaxedHover::new(&af, &af.nominal(), 4),
            Err(RelaxedHoverError::NoSuchRotor { rotor: 4, count: 4 })
        ));
        let octo = Airframe::load("octo").unwrap();
        assert_eq!(
            RelaxedHover::new(&octo, &octo.nominal(), 0).unwrap_err(),
            RelaxedHoverError::NotAQuad(8)
        );
        let mut heavy = af.nominal();
        heavy.mass_kg = 3.0;
        assert!(matches!(
            RelaxedHover::new(&af, &heavy, 0),
            Err(RelaxedHoverError::NoEquilibrium(_))
        ));
    }
}
