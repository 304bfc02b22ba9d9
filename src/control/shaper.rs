//! Reference shaper: turns setpoints (position or velocity, yaw or yaw rate)
//! into smooth, dynamically feasible [`Reference`]s for the control laws.
//!
//! Translation: a critically damped fourth-order chain with saturations
//! (nested saturated loops, NED, per step of length `h`):
//! ```text
//! v_cmd = sat_v(k1 (p_sp - p))        or  sat_v(v_sp)       [m/s]
//! a_cmd = sat_a(k2 (v_cmd - v))                             [m/s^2]
//! j_cmd = sat_j(k3 (a_cmd - a))                             [m/s^3]
//! s     = k4 (j_cmd - j)                                    [m/s^4]   (snap, held over h)
//! p += v h + a h^2/2 + j h^3/6 + s h^4/24,  v += a h + j h^2/2 + s h^3/6,  a += j h + s h^2/2,  j += s h
//! ```
//! Unsaturated it is `(s + lambda)^4`: `k4 = 4 lambda`, `k3 = 1.5 lambda`,
//! `k2 = 2 lambda / 3`, `k1 = lambda / 4` (no overshoot). `lambda` is the largest
//! value for which the linear region itself respects the limits:
//! `lambda <= j_max / (1.5 a_max)` (the jerk loop) and `lambda <= 4 a_max / v_max`
//! (braking from cruise, `k1 v_max <= a_max`). A `Track` setpoint (a position
//! with its velocity and acceleration as feed-forward) may have a position
//! gain of its own, `k1'` (`ShaperLimits::track_gain_per_s`), followed by
//! the chain `(s + 4 k1')^4`. Velocity and acceleration
//! saturations keep the direction of the vector and bound the horizontal norm,
//! the climb and the descent separately; jerk is bounded in norm. Jerk is
//! continuous and snap bounded, so the geometric law's numerical `w_d_dot`
//! (doc section 5) stays smooth. The horizontal acceleration is also limited
//! to `g tan(max_tilt)`.
//!
//! Yaw: second order with rate and acceleration limits,
//! `r_cmd = sign(e) min(k_psi |e|, sqrt(a_max |e|), r_max)`, `e = wrap(psi_sp - psi)`,
//! `psi'' = sat(4 k_psi (r_cmd - psi'))`, `k_psi = a_max / r_max`.
//!
//! Pure: stepped by `dt`, no clock.

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use super::Reference;
use super::gains::GainProblem;
use crate::airframe::Airframe;
use crate::math::{euler_zyx, wrap_pi};
use crate::signals::GRAVITY;
use crate::signals::Measurement;

/// Kinematic limits of the shaped reference, per vehicle.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ShaperLimits {
    /// Horizontal speed [m/s].
    pub max_speed_xy_m_s: f64,
    /// Climb speed [m/s] (up, `-z` NED).
    pub max_climb_m_s: f64,
    /// Descent speed [m/s].
    pub max_descent_m_s: f64,
    /// Horizontal acceleration [m/s^2].
    pub max_accel_xy_m_s2: f64,
    /// Vertical acceleration, either way [m/s^2].
    pub max_accel_z_m_s2: f64,
    /// Jerk (norm) [m/s^3].
    pub max_jerk_m_s3: f64,
    /// Tilt the horizontal acceleration may ask for, `a_xy <= g tan(max_tilt)` [rad].
    pub max_tilt_rad: f64,
    /// Yaw rate [rad/s].
    pub max_yaw_rate_rad_s: f64,
    /// Yaw acceleration [rad/s^2].
    pub max_yaw_accel_rad_s2: f64,
    /// Position gain [1/s] of a [`TranslationSetpoint::Track`] setpoint (its
    /// chain's `lambda = 4 k1`); 0: the position loop's own `k1`.
    pub track_gain_per_s: f64,
}

impl Default for ShaperLimits {
    /// Conservative values for a small multirotor (PX4-like speeds).
    fn default() -> Self {
        Self {
            max_speed_xy_m_s: 5.0,
            max_climb_m_s: 3.0,
            max_descent_m_s: 1.5,
            max_accel_xy_m_s2: 3.0,
            max_accel_z_m_s2: 2.0,
            max_jerk_m_s3: 8.0,
            max_tilt_rad: 30f64.to_radians(),
            max_yaw_rate_rad_s: 1.0,
            max_yaw_accel_rad_s2: 1.5,
            track_gain_per_s: 0.0,
        }
    }
}

/// An invalid shaper limit: field, value, problem.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("shaper limit {field} = {value} {problem}")]
pub struct ShaperError {
    /// Field name.
    pub field: &'static str,
    /// The offending value.
    pub value: f64,
    /// What is wrong.
    pub problem: GainProblem,
}

impl ShaperLimits {
    /// Limits from the airframe's thrust and yaw authority: keep 25 % of the
    /// maximum thrust `n c_T w_max^2` for attitude control, tilt at most
    /// `acos(m g / 0.75 T_max)` (and 35 deg), horizontal acceleration 60 % of
    /// `g tan(tilt)` (at most 4), vertical half the spare thrust acceleration
    /// (at most 3), jerk `3 a_xy` (at most 12); yaw acceleration 30 % of the yaw
    /// torque available at hover over `I_zz` (at most 3), yaw rate at most 1 rad/s.
    #[must_use]
    pub fn for_airframe(airframe: &Airframe) -> Self {
        let d = Self::default();
        let n = airframe.rotor_count() as f64;
        let m = airframe.mass_kg;
        let weight = m * GRAVITY;
        let c_t = airframe.rotor.c_t;
        let (w_min, w_max) = airframe.speed_sq_bounds();
        // 75 % of the rotors' maximum `n c_T w_max^2` (Airframe::max_thrust_n), multiplied in
        // this order: the golden logs (tests/golden.rs) pin the shaped references to the bit
        let usable = 0.75 * n * c_t * w_max;
        if !(usable > weight && m > 0.0) {
            return d;
        }
        let tilt = (weight / usable).acos().clamp(5f64.to_radians(), 35f64.to_radians());
        let a_xy = (0.6 * GRAVITY * tilt.tan()).min(4.0);
        let a_z = (0.5 * (usable / m - GRAVITY)).clamp(0.5, 3.0);
        let w_hover = weight / (n * c_t);
        let spare = (w_max - w_hover).min(w_hover - w_min).max(0.0);
        let yaw_torque = n * airframe.rotor.c_q * spare;
        let i_zz = airframe.inertia_kg_m2[(2, 2)];
        let yaw_acc = if i_zz > 0.0 {
            (0.3 * yaw_torque / i_zz).clamp(0.2, 3.0)
        } else {
            d.max_yaw_accel_rad_s2
        };
        Self {
            max_tilt_rad: tilt,
            max_accel_xy_m_s2: a_xy,
            max_accel_z_m_s2: a_z,
            max_jerk_m_s3: (3.0 * a_xy).min(12.0),
            max_yaw_accel_rad_s2: yaw_acc,
            max_yaw_rate_rad_s: yaw_acc.min(1.0),
            ..d
        }
    }

    /// Every limit finite and positive; tilt below 80 deg.
    ///
    /// # Errors
    /// The first offending field.
    pub fn validate(&self) -> Result<(), ShaperError> {
        let fields = [
            ("max_speed_xy_m_s", self.max_speed_xy_m_s),
            ("max_climb_m_s", self.max_climb_m_s),
            ("max_descent_m_s", self.max_descent_m_s),
            ("max_accel_xy_m_s2", self.max_accel_xy_m_s2),
            ("max_accel_z_m_s2", self.max_accel_z_m_s2),
            ("max_jerk_m_s3", self.max_jerk_m_s3),
            ("max_tilt_rad", self.max_tilt_rad),
            ("max_yaw_rate_rad_s", self.max_yaw_rate_rad_s),
            ("max_yaw_accel_rad_s2", self.max_yaw_accel_rad_s2),
        ];
        for (field, value) in fields {
            let problem = if !value.is_finite() {
                GainProblem::NotFinite
            } else if value <= 0.0 {
                GainProblem::NotPositive
            } else {
                continue;
            };
            return Err(ShaperError { field, value, problem });
        }
        if self.max_tilt_rad >= 80f64.to_radians() {
            return Err(ShaperError {
                field: "max_tilt_rad",
                value: self.max_tilt_rad,
                problem: GainProblem::OutOfRange("below 80 deg"),
            });
        }
        if !(self.track_gain_per_s.is_finite() && self.track_gain_per_s >= 0.0) {
            return Err(ShaperError {
                field: "track_gain_per_s",
                value: self.track_gain_per_s,
                problem: GainProblem::OutOfRange("0 (the position loop's) or a positive gain"),
            });
        }
        Ok(())
    }
}

/// What the translation should do.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TranslationSetpoint {
    /// Go to and stay at this position [m], NED.
    Position(Vector3<f64>),
    /// Fly at this velocity [m/s], NED (saturated to the limits).
    Velocity(Vector3<f64>),
    /// Follow a moving point: a position [m] with its velocity [m/s] and
    /// acceleration [m/s^2] as feed-forward, NED, as PX4's trajectory
    /// setpoint: `v_cmd = v_ff + k1 (p_sp - p)`, `a_cmd = a_ff + k2 (v_cmd - v)`
    /// (then saturated as any command), so that a path moving at `v_ff` is
    /// tracked without the lag `v_ff / k1` a bare position gives. A
    /// non-finite feed-forward component counts as zero.
    Track {
        /// Position [m], NED.
        position: Vector3<f64>,
        /// Velocity feed-forward [m/s], NED.
        velocity: Vector3<f64>,
        /// Acceleration feed-forward [m/s^2], NED.
        acceleration: Vector3<f64>,
    },
    /// Brake to a stop and stay wherever that is.
    Hold,
}

/// What the heading should do.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum YawSetpoint {
    /// Turn to this yaw [rad] the short way.
    Angle(f64),
    /// Turn at this rate [rad/s] (saturated).
    Rate(f64),
    /// Stop turning.
    Hold,
}

/// A setpoint for the shaper. Non-finite parts are treated as `Hold`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Setpoint {
    /// Translation.
    pub translation: TranslationSetpoint,
    /// Heading.
    pub yaw: YawSetpoint,
}

impl Setpoint {
    /// Go to `position_ned` [m] and turn to `yaw_rad` [rad].
    #[must_use]
    pub fn position(position_ned: Vector3<f64>, yaw_rad: f64) -> Self {
        Self {
            translation: TranslationSetpoint::Position(position_ned),
            yaw: YawSetpoint::Angle(yaw_rad),
        }
    }

    /// Fly at `velocity_ned` [m/s] and turn to `yaw_rad` [rad].
    #[must_use]
    pub fn velocity(velocity_ned: Vector3<f64>, yaw_rad: f64) -> Self {
        Self {
            translation: TranslationSetpoint::Velocity(velocity_ned),
            yaw: YawSetpoint::Angle(yaw_rad),
        }
    }
}

/// The shaper state (module doc). Start it with [`Shaper::reset`] or
/// [`Shaper::reset_to`] at the vehicle's state; otherwise it starts at rest at
/// the origin, heading north.
#[derive(Clone, Debug)]
pub struct Shaper {
    limits: ShaperLimits,
    k: [f64; 4],
    /// The gains a [`TranslationSetpoint::Track`] setpoint is followed with.
    k_track: [f64; 4],
    k_yaw: f64,
    /// Horizontal acceleration limit `min(a_xy, g tan(max_tilt))` [m/s^2],
    /// set with the gains when the limits change (no `tan` per step).
    a_xy_max: f64,
    /// The last step `dt` (its bits) and its split into `n` substeps of `h`
    /// [s] (below): `dt` rarely changes, so neither does the split.
    substeps: Option<(u64, u32, f64)>,
    p: Vector3<f64>,
    v: Vector3<f64>,
    a: Vector3<f64>,
    j: Vector3<f64>,
    s: Vector3<f64>,
    yaw: f64,
    yaw_rate: f64,
    yaw_acc: f64,
}

/// Scale `x` so that its horizontal norm is at most `h`, its up part (`-z`)
/// at most `up` and its down part at most `down` (direction kept).
fn sat_box(x: &Vector3<f64>, h: f64, up: f64, down: f64) -> Vector3<f64> {
    let mut f: f64 = 1.0;
    let n = x.xy().norm();
    if n > h {
        f = f.min(h / n);
    }
    if x.z < -up {
        f = f.min(up / -x.z);
    }
    if x.z > down {
        f = f.min(down / x.z);
    }
    x * f
}

fn sat_norm(x: &Vector3<f64>, max: f64) -> Vector3<f64> {
    let n = x.norm();
    if n > max { x * (max / n) } else { *x }
}

impl Shaper {
    /// A shaper with `limits`, at rest at the origin.
    ///
    /// # Errors
    /// An invalid limit ([`ShaperLimits::validate`]).
    pub fn new(limits: ShaperLimits) -> Result<Self, ShaperError> {
        limits.validate()?;
        let mut s = Self {
            limits,
            k: [0.0; 4],
            k_track: [0.0; 4],
            k_yaw: 0.0,
            a_xy_max: 0.0,
            substeps: None,
            p: Vector3::zeros(),
            v: Vector3::zeros(),
            a: Vector3::zeros(),
            j: Vector3::zeros(),
            s: Vector3::zeros(),
            yaw: 0.0,
            yaw_rate: 0.0,
            yaw_acc: 0.0,
        };
        s.set_gains();
        Ok(s)
    }

    /// Gains and the horizontal acceleration limit for the limits in force.
    fn set_gains(&mut self) {
        let l = &self.limits;
        let a_xy = l.max_accel_xy_m_s2.min(GRAVITY * l.max_tilt_rad.tan());
        self.a_xy_max = a_xy;
        self.substeps = None;
        let a_z = l.max_accel_z_m_s2;
        let v_z = l.max_climb_m_s.max(l.max_descent_m_s);
        let lambda = (l.max_jerk_m_s3 / (1.5 * a_xy.max(a_z)))
            .min(4.0 * a_xy / l.max_speed_xy_m_s)
            .min(4.0 * a_z / v_z)
            .clamp(0.05, 50.0);
        let gains = |lambda: f64| [lambda / 4.0, 2.0 * lambda / 3.0, 1.5 * lambda, 4.0 * lambda];
        self.k = gains(lambda);
        self.k_track = if l.track_gain_per_s > 0.0 {
            gains(4.0 * l.track_gain_per_s)
        } else {
            self.k
        };
        self.k_yaw = l.max_yaw_accel_rad_s2 / l.max_yaw_rate_rad_s;
    }

    /// The position loop's gain `k1` [1/s]: a target `d` [m] away asks for
    /// the speed `k1 d` (saturated at the speed limit).
    #[must_use]
    pub fn position_gain(&self) -> f64 {
        self.k[0]
    }

    /// The limits in force.
    #[must_use]
    pub fn limits(&self) -> &ShaperLimits {
        &self.limits
    }

    /// Change the limits; the state is kept.
    ///
    /// # Errors
    /// An invalid limit; the old limits stay.
    pub fn set_limits(&mut self, limits: ShaperLimits) -> Result<(), ShaperError> {
        limits.validate()?;
        self.limits = limits;
        self.set_gains();
        Ok(())
    }

    /// Restart at `position_ned` [m] moving at `velocity_ned` [m/s] with
    /// heading `yaw_rad` [rad]; acceleration, jerk and yaw rate zero.
    /// Non-finite inputs become zero.
    pub fn reset(&mut self, position_ned: Vector3<f64>, velocity_ned: Vector3<f64>, yaw_rad: f64) {
        let fin = |v: Vector3<f64>| {
            if v.iter().all(|x| x.is_finite()) {
                v
            } else {
                Vector3::zeros()
            }
        };
        self.p = fin(position_ned);
        self.v = fin(velocity_ned);
        self.a = Vector3::zeros();
        self.j = Vector3::zeros();
        self.s = Vector3::zeros();
        self.yaw = if yaw_rad.is_finite() { wrap_pi(yaw_rad) } else { 0.0 };
        self.yaw_rate = 0.0;
        self.yaw_acc = 0.0;
    }

    /// Restart at a measured state (position, velocity, yaw).
    pub fn reset_to(&mut self, meas: &Measurement) {
        self.reset(meas.position_ned, meas.velocity_ned, euler_zyx(&meas.attitude).z);
    }

    /// The current reference (without stepping).
    #[must_use]
    pub fn reference(&self) -> Reference {
        Reference {
            position_ned: self.p,
            velocity_ned: self.v,
            acceleration_ned: self.a,
            jerk_ned: self.j,
            snap_ned: self.s,
            yaw_rad: self.yaw,
            yaw_rate_rad_s: self.yaw_rate,
            yaw_accel_rad_s2: self.yaw_acc,
        }
    }

    /// Advance by `dt` [s] towards `setpoint` and return the new reference.
    /// Long steps are split so that the fastest loop stays well resolved.
    pub fn update(&mut self, setpoint: &Setpoint, dt: f64) -> Reference {
        update_shaper(self, setpoint, dt)
    }

    /// The body of [`Self::update`], inlined into both versions of
    /// [`update_shaper`].
    #[inline(always)]
    fn update_inner(&mut self, setpoint: &Setpoint, dt: f64) -> Reference {
        if !(dt.is_finite() && dt > 0.0) {
            return self.reference();
        }
        let (n, h) = match self.substeps {
            Some((bits, n, h)) if bits == dt.to_bits() => (n, h),
            _ => {
                let h_max = 0.25 / self.k[3].max(self.k_track[3]);
                let n = (dt / h_max).ceil().clamp(1.0, 10_000.0);
                let h = dt / n;
                self.substeps = Some((dt.to_bits(), n as u32, h));
                (n as u32, h)
            }
        };
        for _ in 0..n {
            self.step(setpoint, h);
        }
        self.reference()
    }

    #[inline(always)]
    fn step(&mut self, setpoint: &Setpoint, h: f64) {
        let l = &self.limits;
        let fin = |v: &Vector3<f64>| v.iter().all(|x| x.is_finite());
        let [k1, k2, k3, k4] = match setpoint.translation {
            TranslationSetpoint::Track { .. } => self.k_track,
            _ => self.k,
        };
        let or_zero = |v: &Vector3<f64>| v.map(|x| if x.is_finite() { x } else { 0.0 });
        let (v_cmd, a_ff) = match setpoint.translation {
            TranslationSetpoint::Position(p) if fin(&p) => ((p - self.p) * k1, None),
            TranslationSetpoint::Velocity(v) if fin(&v) => (v, None),
            TranslationSetpoint::Track {
                position,
                velocity,
                acceleration,
            } if fin(&position) => (
                or_zero(&velocity) + (position - self.p) * k1,
                Some(or_zero(&acceleration)),
            ),
            _ => (Vector3::zeros(), None),
        };
        let v_cmd = sat_box(&v_cmd, l.max_speed_xy_m_s, l.max_climb_m_s, l.max_descent_m_s);
        let a_z = l.max_accel_z_m_s2;
        let a_want = match a_ff {
            None => (v_cmd - self.v) * k2,
            Some(a) => a + (v_cmd - self.v) * k2,
        };
        let a_cmd = sat_box(&a_want, self.a_xy_max, a_z, a_z);
        let j_cmd = sat_norm(&((a_cmd - self.a) * k3), l.max_jerk_m_s3);
        let s = (j_cmd - self.j) * k4;
        let (h2, h3, h4) = (h * h, h * h * h, h * h * h * h);
        self.p += self.v * h + self.a * (h2 / 2.0) + self.j * (h3 / 6.0) + s * (h4 / 24.0);
        self.v += self.a * h + self.j * (h2 / 2.0) + s * (h3 / 6.0);
        self.a += self.j * h + s * (h2 / 2.0);
        self.j += s * h;
        self.s = s;

        let r_max = l.max_yaw_rate_rad_s;
        let acc_max = l.max_yaw_accel_rad_s2;
        let rate_cmd = match setpoint.yaw {
            YawSetpoint::Angle(psi) if psi.is_finite() => {
                let e = wrap_pi(psi - self.yaw);
                e.signum() * (self.k_yaw * e.abs()).min((acc_max * e.abs()).sqrt()).min(r_max)
            }
            YawSetpoint::Rate(r) if r.is_finite() => r.clamp(-r_max, r_max),
            _ => 0.0,
        };
        let acc = (4.0 * self.k_yaw * (rate_cmd - self.yaw_rate)).clamp(-acc_max, acc_max);
        self.yaw = wrap_pi(self.yaw + self.yaw_rate * h + acc * (h2 / 2.0));
        self.yaw_rate += acc * h;
        self.yaw_acc = acc;
    }
}

// Compiled for the x86-64 baseline and for AVX2, the CPU picking one at the
// first call: the same bits, fewer instructions (why: the comment above
// `step_plant` in sim/plant.rs).

/// [`Shaper::update`].
#[multiversion::multiversion(targets("x86_64+avx2"))]
fn update_shaper(shaper: &mut Shaper, setpoint: &Setpoint, dt: f64) -> Reference {
    shaper.update_inner(setpoint, dt)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(shaper: &mut Shaper, sp: &Setpoint, seconds: f64, dt: f64) -> Vec<Reference> {
        let n = (seconds / dt).round() as usize;
        (0..n).map(|_| shaper.update(sp, dt)).collect()
    }

    /// GIVEN a 10 m diagonal step WHEN shaped THEN every limit holds (within 2 %),
    /// the reference arrives without measurable overshoot and stops.
    #[test]
    fn position_step_respects_limits_and_settles() {
        let l = ShaperLimits::default();
        let mut s = Shaper::new(l).unwrap();
        s.reset(Vector3::new(0.0, 0.0, -2.0), Vector3::zeros(), 0.0);
        let goal = Vector3::new(8.0, -6.0, -4.0);
        let refs = run(&mut s, &Setpoint::position(goal, 1.0), 20.0, 1e-3);
        let a_xy = l.max_accel_xy_m_s2.min(GRAVITY * l.max_tilt_rad.tan());
        for r in &refs {
            assert!(r.velocity_ned.xy().norm() <= l.max_speed_xy_m_s * 1.02);
            assert!(-r.velocity_ned.z <= l.max_climb_m_s * 1.02 && r.velocity_ned.z <= l.max_descent_m_s * 1.02);
            assert!(r.acceleration_ned.xy().norm() <= a_xy * 1.02, "{}", r.acceleration_ned);
            assert!(r.acceleration_ned.z.abs() <= l.max_accel_z_m_s2 * 1.02);
            assert!(r.jerk_ned.norm() <= l.max_jerk_m_s3 * 1.0001);
            assert!(r.yaw_rate_rad_s.abs() <= l.max_yaw_rate_rad_s * 1.0001);
            assert!(r.yaw_accel_rad_s2.abs() <= l.max_yaw_accel_rad_s2 * 1.0001);
        }
        let last = refs.last().unwrap();
        assert!((last.position_ned - goal).norm() < 1e-3, "{}", last.position_ned);
        assert!(last.velocity_ned.norm() < 1e-3);
        assert!((last.yaw_rad - 1.0).abs() < 1e-3);
        // overshoot along the path direction
        let dir = (goal - Vector3::new(0.0, 0.0, -2.0)).normalize();
        let max_along = refs
            .iter()
            .map(|r| (r.position_ned - goal).dot(&dir))
            .fold(f64::NEG_INFINITY, f64::max);
        assert!(max_along < 0.02, "overshoot {max_along}");
    }

    #[test]
    fn velocity_setpoint_is_saturated_and_smooth() {
        let l = ShaperLimits::default();
        let mut s = Shaper::new(l).unwrap();
        let refs = run(
            &mut s,
            &Setpoint::velocity(Vector3::new(20.0, 0.0, -10.0), 0.0),
            10.0,
            1e-3,
        );
        let last = refs.last().unwrap();
        // direction kept, climb the binding limit (3 m/s up => 6 m/s north would exceed 5, so horizontal binds)
        assert!((last.velocity_ned.x - 5.0).abs() < 1e-3 && (last.velocity_ned.z + 2.5).abs() < 1e-3);
        for w in refs.windows(2) {
            // jerk continuous: snap bounded
            assert!((w[1].jerk_ned - w[0].jerk_ned).norm() < 1e-3 * 4.0 * 50.0 * l.max_jerk_m_s3);
        }
    }

    #[test]
    fn yaw_turns_the_short_way_and_yaw_rate_setpoint_is_clamped() {
        let mut s = Shaper::new(ShaperLimits::default()).unwrap();
        s.reset(Vector3::zeros(), Vector3::zeros(), 3.0);
        let refs = run(
            &mut s,
            &Setpoint {
                translation: TranslationSetpoint::Hold,
                yaw: YawSetpoint::Angle(-3.0),
            },
            8.0,
            1e-3,
        );
        assert!(refs[100].yaw_rate_rad_s > 0.0, "short way across +-pi");
        assert!((refs.last().unwrap().yaw_rad + 3.0).abs() < 1e-3);
        let refs = run(
            &mut s,
            &Setpoint {
                translation: TranslationSetpoint::Hold,
                yaw: YawSetpoint::Rate(-10.0),
            },
            4.0,
            1e-3,
        );
        assert!((refs.last().unwrap().yaw_rate_rad_s + 1.0).abs() < 1e-9);
    }

    /// GIVEN a point moving north-east at 2 m/s
    /// WHEN it is shaped as a bare position, and as a position with its
    /// velocity as feed-forward (`Track`)
    /// THEN the bare position trails it by `v / k1`, the tracked one by
    /// under a centimetre once settled.
    #[test]
    fn velocity_feed_forward_removes_the_lag_of_a_moving_point() {
        let v = Vector3::new(1.6, 1.2, 0.0);
        let p = |t: f64| Vector3::new(0.0, 0.0, -5.0) + v * t;
        let lag = |track: bool| {
            let mut s = Shaper::new(ShaperLimits::default()).unwrap();
            s.reset(p(0.0), v, 0.0);
            let dt = 1e-3;
            let mut r = s.reference();
            for k in 1..=20_000 {
                let target = p(k as f64 * dt);
                let translation = if track {
                    TranslationSetpoint::Track {
                        position: target,
                        velocity: v,
                        acceleration: Vector3::new(f64::NAN, 0.0, 0.0),
                    }
                } else {
                    TranslationSetpoint::Position(target)
                };
                let sp = Setpoint {
                    translation,
                    yaw: YawSetpoint::Hold,
                };
                r = s.update(&sp, dt);
            }
            (p(20.0) - r.position_ned).norm()
        };
        let k1 = Shaper::new(ShaperLimits::default()).unwrap().position_gain();
        assert!(
            (lag(false) - v.norm() / k1).abs() < 0.05,
            "{} vs {}",
            lag(false),
            v.norm() / k1
        );
        assert!(lag(true) < 0.01, "{}", lag(true));
    }

    #[test]
    fn long_steps_and_bad_inputs_stay_finite() {
        let mut s = Shaper::new(ShaperLimits::default()).unwrap();
        let sp = Setpoint::position(Vector3::new(f64::NAN, 1.0, 2.0), f64::INFINITY);
        let r = s.update(&sp, 0.5);
        assert!(r.is_finite());
        let r = s.update(&Setpoint::position(Vector3::new(100.0, 0.0, 0.0), 0.0), 1.0);
        assert!(r.is_finite() && r.velocity_ned.norm() <= 5.0 * 1.02);
        assert!(
            Shaper::new(ShaperLimits {
                max_jerk_m_s3: 0.0,
                ..ShaperLimits::default()
            })
            .is_err()
        );
    }

    #[test]
    fn airframe_limits_are_valid() {
        for name in ["quad", "octo", "hexa", "fsr-quad"] {
            let af = Airframe::load(name).unwrap();
            let l = ShaperLimits::for_airframe(&af);
            l.validate().unwrap();
            assert!(l.max_tilt_rad <= 35f64.to_radians() + 1e-12, "{name}");
        }
    }
}
