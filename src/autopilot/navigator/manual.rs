//! Manual control: the pilot's sticks (MANUAL_CONTROL, QGroundControl's
//! virtual joystick) and the modes flown with them, as PX4 flies them —
//! Position (`FlightTaskManualPosition`), Altitude (`FlightTaskManualAltitude`),
//! Stabilized and Manual (`mc_att_control`'s stick attitude) and Acro
//! (`mc_rate_control`'s stick rates) — and the loss of the sticks
//! (`COM_RC_LOSS_T`, then `NAV_RCL_ACT`).
//!
//! Sticks are PX4's `manual_control_setpoint`: roll, pitch, yaw and
//! throttle in `[-1, 1]`, throttle centred at 0. The latest sticks are kept
//! with their arrival time; the loss timer waits for a client and follows
//! the rule of [`crate::autopilot::failsafe`] (simulated time up to 1x, the
//! runtime's wall clock above).

use nalgebra::{Rotation2, UnitQuaternion, Vector2, Vector3};

use super::{Nav, Navigator, Situation};
use crate::autopilot::control_loop::Demand;
use crate::autopilot::settings::ManualSettings;
use crate::autopilot::status::Announcements;
use crate::autopilot::status::Severity;
use crate::autopilot::{ClientClock, FlightMode, TIME_EPS};
use crate::control::{Reference, Setpoint, ShaperLimits, TranslationSetpoint, YawSetpoint};
use crate::math::{euler_zyx, wrap_pi};
use crate::signals::{GRAVITY, Measurement};

/// Landed in Position or Altitude, a climb-rate demand above this [m/s]
/// takes off (below it the rotors idle), as offboard's takeoff trigger.
const TAKEOFF_CLIMB_M_S: f64 = 0.3;
/// PX4's arming checks: throttle above this is "above center" (modes that
/// hold the altitude) ...
const THROTTLE_ABOVE_CENTER: f64 = 0.2;
/// ... and below this "low" (modes where throttle is thrust).
const THROTTLE_LOW: f64 = -0.8;
/// The vertical reference of Altitude and Descend stays within this [m] of
/// the measured height (PX4 re-locks the altitude the same way).
const VERTICAL_LEASH_M: f64 = 1.0;

/// The pilot's sticks as PX4's `manual_control_setpoint` holds them.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ManualControl {
    /// Pitch stick in `[-1, 1]`: forward (nose down, fly forward) positive.
    pub pitch: f64,
    /// Roll stick in `[-1, 1]`: right (right side down) positive.
    pub roll: f64,
    /// Throttle in `[-1, 1]`: -1 low, 0 centred, 1 high.
    pub throttle: f64,
    /// Yaw stick in `[-1, 1]`: turn right (clockwise seen from above) positive.
    pub yaw: f64,
}

impl ManualControl {
    /// Every stick centred (throttle too: hold the altitude in Position and Altitude).
    pub const CENTRED: Self = Self {
        pitch: 0.0,
        roll: 0.0,
        throttle: 0.0,
        yaw: 0.0,
    };

    /// Every stick finite and within `[-1, 1]`.
    #[must_use]
    pub fn is_valid(&self) -> bool {
        [self.pitch, self.roll, self.throttle, self.yaw]
            .iter()
            .all(|x| x.is_finite() && x.abs() <= 1.0)
    }
}

/// The modes flown with the sticks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(in crate::autopilot) enum ManualMode {
    /// POSCTL.
    Position,
    /// ALTCTL.
    Altitude,
    /// STABILIZED.
    Stabilized,
    /// ACRO.
    Acro,
    /// MANUAL (flown as Stabilized on a multicopter).
    Manual,
}

impl ManualMode {
    /// The stick mode that `mode` is, if it is one.
    pub(in crate::autopilot) fn of(mode: FlightMode) -> Option<Self> {
        match mode {
            FlightMode::Position => Some(Self::Position),
            FlightMode::Altitude => Some(Self::Altitude),
            FlightMode::Stabilized => Some(Self::Stabilized),
            FlightMode::Acro => Some(Self::Acro),
            FlightMode::Manual => Some(Self::Manual),
            _ => None,
        }
    }

    /// The mode as clients see it.
    pub(in crate::autopilot) fn flight_mode(self) -> FlightMode {
        match self {
            Self::Position => FlightMode::Position,
            Self::Altitude => FlightMode::Altitude,
            Self::Stabilized => FlightMode::Stabilized,
            Self::Acro => FlightMode::Acro,
            Self::Manual => FlightMode::Manual,
        }
    }

    /// Whether the throttle stick asks for a climb rate (else it is thrust).
    fn throttle_is_climb_rate(self) -> bool {
        matches!(self, Self::Position | Self::Altitude)
    }

    pub(in crate::autopilot) fn name(self) -> &'static str {
        match self {
            Self::Position => "Position",
            Self::Altitude => "Altitude",
            Self::Stabilized => "Stabilized",
            Self::Acro => "Acro",
            Self::Manual => "Manual",
        }
    }
}

/// PX4's `math::deadzone`: `0` within `|x| <= dz`, else `(x - sign(x) dz) / (1 - dz)`.
fn deadzone(x: f64, dz: f64) -> f64 {
    if x.abs() <= dz || dz >= 1.0 {
        0.0
    } else {
        (x - x.signum() * dz) / (1.0 - dz)
    }
}

/// PX4's `math::expo`: `(1 - e) x + e x^3` (`x` clamped to `[-1, 1]`).
fn expo(x: f64, e: f64) -> f64 {
    let x = x.clamp(-1.0, 1.0);
    (1.0 - e) * x + e * x * x * x
}

/// PX4's `math::expo_deadzone`: `expo(deadzone(x, dz), e)`.
pub(super) fn expo_deadzone(x: f64, e: f64, dz: f64) -> f64 {
    expo(deadzone(x, dz), e)
}

/// PX4's `math::superexpo`: `expo(x, e) (1 - g) / (1 - |x| g)`.
fn superexpo(x: f64, e: f64, g: f64) -> f64 {
    let x = x.clamp(-1.0, 1.0);
    expo(x, e) * (1.0 - g) / (1.0 - x.abs() * g)
}

/// Climb stick to a vertical velocity [m/s], NED (down positive):
/// `v_z = -t v_up` for `t > 0`, `-t v_down` below, `t` after the deadzone.
fn climb_rate_ned(throttle: f64, dz: f64, up: f64, down: f64) -> f64 {
    let t = deadzone(throttle, dz);
    if t > 0.0 { -t * up } else { -t * down }
}

/// PX4's `throttle_curve` (MPC_THR_CURVE 0, "rescale to hover"): throttle
/// `t` in `[-1, 1]` to collective thrust in `[0, 1]` of the maximum,
/// piecewise linear through `(-1, t_min)`, `(0, t_hover)`, `(1, 1)`.
fn throttle_curve(t: f64, t_min: f64, t_hover: f64) -> f64 {
    let t = t.clamp(-1.0, 1.0);
    if t <= 0.0 {
        t_min + (t + 1.0) * (t_hover - t_min)
    } else {
        t_hover + t * (1.0 - t_hover)
    }
}

/// Stick tilt (PX4's `mc_att_control`): `v = (roll, -pitch) theta_max`,
/// its norm capped at `theta_max`, is the axis-angle of the tilt in the
/// heading frame (FRD turned by yaw only).
fn stick_tilt(sticks: &ManualControl, tilt_max_rad: f64) -> Vector2<f64> {
    let v = Vector2::new(sticks.roll, -sticks.pitch) * tilt_max_rad;
    let n = v.norm();
    if n > tilt_max_rad { v * (tilt_max_rad / n) } else { v }
}

/// The horizontal acceleration [m/s^2], NED, that tilts the vehicle as the
/// sticks ask at heading `yaw_rad`: `a = g tan(theta) d`, `theta` the stick
/// tilt and `d` its direction (forward for pitch, right for roll) turned
/// by the heading.
fn tilt_acceleration_ned(sticks: &ManualControl, tilt_max_rad: f64, yaw_rad: f64) -> Vector2<f64> {
    let v = stick_tilt(sticks, tilt_max_rad);
    let theta = v.norm();
    if theta < 1e-9 {
        return Vector2::zeros();
    }
    // axis (x: roll, y: pitch) to the direction of travel (forward, right)
    let dir = Vector2::new(-v.y, v.x) / theta;
    Rotation2::new(yaw_rad) * dir * (GRAVITY * theta.min(1.5).tan())
}

/// A vertical reference followed at a bounded acceleration: height `z` [m]
/// and vertical velocity `vz` [m/s], NED.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Vertical {
    z: f64,
    vz: f64,
}

impl Navigator {
    /// Keep `sticks` (valid) as the latest, arrived at `now` [s].
    pub(in crate::autopilot) fn set_manual(&mut self, sticks: ManualControl, now: f64) {
        self.manual = Some((sticks, now));
        self.manual_lost = false;
    }

    /// Whether sticks arrived within `loss_s` [s] of `now` (simulated time),
    /// or, timed on the wall clock, whether sticks exist that the runtime has
    /// not declared lost.
    pub(in crate::autopilot) fn manual_fresh(&self, now: f64, loss_s: f64, clock: ClientClock) -> bool {
        match clock {
            ClientClock::Simulated => {
                !self.manual_lost && self.manual.is_some_and(|(_, t)| now - t < loss_s - TIME_EPS)
            }
            ClientClock::Wall => self.manual.is_some() && !self.manual_lost,
        }
    }

    /// The latest sticks (centred when none came, or once declared lost:
    /// PX4 zeroes timed-out sticks).
    pub(in crate::autopilot) fn sticks(&self) -> ManualControl {
        match self.manual {
            Some((s, _)) if !self.manual_lost => s,
            _ => ManualControl::CENTRED,
        }
    }

    /// The sticks as PX4's flight tasks read them: the latest while fresh
    /// ([`Navigator::manual_fresh`]: within `loss_s` [s] on the simulated
    /// clock, until the loss timer runs out on the wall clock), else centred
    /// (PX4 zeroes the sticks when their signal is lost).
    pub(in crate::autopilot) fn fresh_sticks(&self, now: f64, loss_s: f64, clock: ClientClock) -> ManualControl {
        if self.manual_fresh(now, loss_s, clock) {
            self.sticks()
        } else {
            ManualControl::CENTRED
        }
    }

    /// The active manual mode, if one is.
    pub(in crate::autopilot) fn manual_mode(&self) -> Option<ManualMode> {
        match self.nav {
            Nav::Manual(mode) => Some(mode),
            _ => None,
        }
    }

    /// When the sticks the loss timer waits after arrived [s]: in a manual
    /// mode or in Follow target (whose sticks move what it follows from),
    /// with sticks not yet declared lost.
    pub(in crate::autopilot) fn manual_loss_timer_start(&self) -> Option<f64> {
        if !matches!(self.nav, Nav::Manual(_) | Nav::Follow(_)) {
            return None;
        }
        self.manual.filter(|_| !self.manual_lost).map(|(_, t)| t)
    }

    /// Why arming in `mode` at `now` would be refused (PX4's checks): no
    /// sticks fresh within `loss_s` on `clock`; throttle above centre where
    /// it is a climb rate; throttle not low where it is thrust.
    pub(in crate::autopilot) fn manual_prearm_failure(
        &self,
        mode: ManualMode,
        now: f64,
        loss_s: f64,
        clock: ClientClock,
    ) -> Option<&'static str> {
        if !self.manual_fresh(now, loss_s, clock) {
            return Some("no manual control input");
        }
        let t = self.sticks().throttle;
        if mode.throttle_is_climb_rate() {
            (t > THROTTLE_ABOVE_CENTER).then_some("throttle above center")
        } else {
            (t >= THROTTLE_LOW).then_some("high throttle")
        }
    }

    /// The sticks are lost (their timer, a client timer, ran out): from now
    /// on they read centred (PX4 zeroes timed-out sticks). In a manual mode
    /// it is announced (PX4's words, Critical) and true: `NAV_RCL_ACT` is to
    /// be carried out by the one failsafe runner.
    pub(in crate::autopilot) fn manual_control_lost(&mut self, say: &mut Announcements) -> bool {
        self.manual_lost = true;
        if self.manual_mode().is_none() {
            return false;
        }
        say.announce(Severity::Critical, "Manual control lost");
        true
    }

    /// Fly `mode` with the sticks from the vehicle's current state.
    pub(in crate::autopilot) fn enter_manual(&mut self, mode: ManualMode) {
        self.nav = Nav::Manual(mode);
        self.restart_references();
    }

    /// Forget the references of the manual and blind modes (they restart
    /// from the measurement).
    pub(super) fn restart_references(&mut self) {
        self.shaper_live = false;
        self.vertical = None;
        self.yaw_sp = None;
        self.rate_target = None;
        self.position_fallback = false;
    }

    /// Advance the vertical reference towards the vertical velocity
    /// `vz_cmd` [m/s], NED, at most `a_max` [m/s^2]:
    /// `vz+ = vz + sat(vz_cmd - vz, a_max dt)`, `z+ = z + vz+ dt`, kept
    /// within [`VERTICAL_LEASH_M`] of the measured height. Returns the
    /// reference and its acceleration.
    pub(super) fn vertical_step(&mut self, meas: &Measurement, vz_cmd: f64, a_max: f64, dt: f64) -> (Vertical, f64) {
        let mut v = self.vertical.unwrap_or(Vertical {
            z: meas.position_ned.z,
            vz: meas.velocity_ned.z,
        });
        let dv = (vz_cmd - v.vz).clamp(-a_max * dt, a_max * dt);
        v.vz += dv;
        v.z = (v.z + v.vz * dt).clamp(
            meas.position_ned.z - VERTICAL_LEASH_M,
            meas.position_ned.z + VERTICAL_LEASH_M,
        );
        self.vertical = Some(v);
        (v, if dt > 0.0 { dv / dt } else { 0.0 })
    }

    /// The heading setpoint turned at `rate` [rad/s] over `dt`: `psi+ = psi + r dt`.
    pub(super) fn yaw_step(&mut self, meas: &Measurement, rate: f64, dt: f64) -> f64 {
        let psi = wrap_pi(self.yaw_sp.unwrap_or_else(|| euler_zyx(&meas.attitude).z) + rate * dt);
        self.yaw_sp = Some(psi);
        psi
    }

    /// A reference that holds height and heading with the vertical reference
    /// `v` (acceleration `az`) and asks for the horizontal acceleration
    /// `a_xy` [m/s^2], NED, as feedforward only: the horizontal position and
    /// velocity are the measured ones, so their errors are zero and no
    /// horizontal measurement steers the vehicle (PX4's Altitude and Descend).
    pub(super) fn blind_reference(
        meas: &Measurement,
        v: Vertical,
        az: f64,
        a_xy: Vector2<f64>,
        yaw: f64,
        yaw_rate: f64,
    ) -> Reference {
        let (p, u) = (meas.position_ned, meas.velocity_ned);
        Reference {
            position_ned: Vector3::new(p.x, p.y, v.z),
            velocity_ned: Vector3::new(u.x, u.y, v.vz),
            acceleration_ned: Vector3::new(a_xy.x, a_xy.y, az),
            yaw_rad: yaw,
            yaw_rate_rad_s: yaw_rate,
            ..Reference::default()
        }
    }

    /// The demand of a manual mode from the latest sticks.
    pub(super) fn manual_demand(&mut self, cx: &Situation<'_>, mode: ManualMode) -> Demand {
        let s = cx.settings;
        let man = &s.manual;
        let sticks = self.sticks();
        match mode {
            ManualMode::Position | ManualMode::Altitude => {
                let vz = climb_rate_ned(sticks.throttle, man.deadzone, s.climb_m_s, s.descent_m_s);
                if cx.resting && vz > -TAKEOFF_CLIMB_M_S {
                    return Demand::Idle;
                }
                let yaw_rate = deadzone(sticks.yaw, man.deadzone) * man.yaw_rate_max_rad_s;
                if mode == ManualMode::Position {
                    Demand::Track(self.position_reference(cx, &sticks, vz, yaw_rate))
                } else {
                    let (meas, dt) = (cx.meas, cx.dt);
                    let (v, az) = self.vertical_step(meas, vz, self.base_limits.max_accel_z_m_s2, dt);
                    let yaw = self.yaw_step(meas, yaw_rate, dt);
                    let a_xy = tilt_acceleration_ned(&sticks, man.tilt_max_rad, euler_zyx(&meas.attitude).z);
                    Demand::Track(Self::blind_reference(meas, v, az, a_xy, yaw, yaw_rate))
                }
            }
            ManualMode::Stabilized | ManualMode::Manual => {
                let hover = hover_thrust(cx);
                let t_min = if cx.landed { 0.0 } else { man.thrust_min };
                let thrust_n = throttle_curve(sticks.throttle, t_min, hover) * cx.max_thrust_n;
                if cx.resting && thrust_n <= hover * cx.max_thrust_n {
                    return Demand::Idle;
                }
                let yaw_rate = sticks.yaw * man.yaw_rate_max_rad_s;
                let yaw = self.yaw_step(cx.meas, yaw_rate, cx.dt);
                let v = stick_tilt(&sticks, man.tilt_max_rad);
                let attitude = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw)
                    * UnitQuaternion::from_scaled_axis(Vector3::new(v.x, v.y, 0.0));
                Demand::Attitude {
                    attitude,
                    rate_frd: Vector3::new(0.0, 0.0, yaw_rate),
                    thrust_n,
                }
            }
            ManualMode::Acro => {
                let thrust_n = (sticks.throttle + 1.0) * 0.5 * cx.max_thrust_n;
                if cx.resting && thrust_n <= hover_thrust(cx) * cx.max_thrust_n {
                    return Demand::Idle;
                }
                let rate = acro_rates(&sticks, man);
                let q0 = self.rate_target.unwrap_or(cx.meas.attitude);
                let q1 = q0 * UnitQuaternion::from_scaled_axis(rate * cx.dt);
                self.rate_target = Some(q1);
                Demand::Attitude {
                    attitude: q1,
                    rate_frd: rate,
                    thrust_n,
                }
            }
        }
    }

    /// Position mode: the horizontal sticks after the deadzone, their norm
    /// capped at 1, turned by the heading, times MPC_VEL_MANUAL are the
    /// velocity setpoint [m/s], NED, `vz` the vertical one; the shaper
    /// brings the reference there (centred sticks: it stops and holds).
    fn position_reference(&mut self, cx: &Situation<'_>, sticks: &ManualControl, vz: f64, yaw_rate: f64) -> Reference {
        let (s, man) = (cx.settings, &cx.settings.manual);
        let mut st = Vector2::new(
            deadzone(sticks.pitch, man.deadzone),
            deadzone(sticks.roll, man.deadzone),
        );
        if st.norm() > 1.0 {
            st /= st.norm();
        }
        let heading = if self.shaper_live {
            self.shaper.reference().yaw_rad
        } else {
            euler_zyx(&cx.meas.attitude).z
        };
        let v_xy = Rotation2::new(heading) * st * man.vel_max_m_s;
        let limits = ShaperLimits {
            max_yaw_rate_rad_s: self.base_limits.max_yaw_rate_rad_s.max(man.yaw_rate_max_rad_s),
            ..self.limits(man.vel_max_m_s, s.climb_m_s, s.descent_m_s)
        };
        let sp = Setpoint {
            translation: TranslationSetpoint::Velocity(Vector3::new(v_xy.x, v_xy.y, vz)),
            yaw: YawSetpoint::Rate(yaw_rate),
        };
        self.shape(cx.meas, sp, limits, cx.dt)
    }
}

/// The collective thrust that holds the nominal weight, as a fraction of
/// the maximum (what PX4's hover-thrust estimator finds for MPC_THR_HOVER).
fn hover_thrust(cx: &Situation<'_>) -> f64 {
    if cx.max_thrust_n > 0.0 {
        (cx.settings.model_mass_kg * GRAVITY / cx.max_thrust_n).clamp(0.05, 0.95)
    } else {
        0.5
    }
}

/// Acro: body rates [rad/s], FRD, `w = superexpo(stick) w_max` per axis
/// (`-pitch`: a forward stick pitches the nose down).
fn acro_rates(sticks: &ManualControl, man: &ManualSettings) -> Vector3<f64> {
    let [e, ey] = man.acro_expo;
    let [g, gy] = man.acro_superexpo;
    let [r, p, y] = man.acro_rate_max_rad_s;
    Vector3::new(
        superexpo(sticks.roll, e, g) * r,
        superexpo(-sticks.pitch, e, g) * p,
        superexpo(sticks.yaw, ey, gy) * y,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stick_shaping_matches_px4() {
        assert_eq!(deadzone(0.05, 0.1), 0.0);
        assert!((deadzone(0.55, 0.1) - 0.5).abs() < 1e-12);
        assert!((deadzone(-1.0, 0.1) + 1.0).abs() < 1e-12);
        // superexpo: ends fixed, centre flattened
        assert!((superexpo(1.0, 0.69, 0.7) - 1.0).abs() < 1e-12);
        assert!((superexpo(-1.0, 0.69, 0.7) + 1.0).abs() < 1e-12);
        let half = superexpo(0.5, 0.69, 0.7);
        assert!(half > 0.0 && half < 0.3, "{half}");
        // throttle curve through (-1, min), (0, hover), (1, 1)
        assert!((throttle_curve(-1.0, 0.08, 0.4) - 0.08).abs() < 1e-12);
        assert!((throttle_curve(0.0, 0.08, 0.4) - 0.4).abs() < 1e-12);
        assert!((throttle_curve(1.0, 0.08, 0.4) - 1.0).abs() < 1e-12);
        // climb: up at full throttle, down at zero, none centred
        assert!((climb_rate_ned(1.0, 0.1, 3.0, 1.5) + 3.0).abs() < 1e-12);
        assert!((climb_rate_ned(-1.0, 0.1, 3.0, 1.5) - 1.5).abs() < 1e-12);
        assert_eq!(climb_rate_ned(0.05, 0.1, 3.0, 1.5), 0.0);
    }

    #[test]
    fn forward_stick_accelerates_along_the_heading() {
        let fwd = ManualControl {
            pitch: 1.0,
            ..ManualControl::CENTRED
        };
        let tilt = 35f64.to_radians();
        let a = tilt_acceleration_ned(&fwd, tilt, 0.0);
        assert!((a - Vector2::new(GRAVITY * tilt.tan(), 0.0)).norm() < 1e-9, "{a}");
        // facing east, forward is east; a right stick while facing north is east too
        let a = tilt_acceleration_ned(&fwd, tilt, std::f64::consts::FRAC_PI_2);
        assert!(a.x.abs() < 1e-9 && a.y > 0.0, "{a}");
        let right = ManualControl {
            roll: 0.5,
            ..ManualControl::CENTRED
        };
        let a = tilt_acceleration_ned(&right, tilt, 0.0);
        assert!(a.x.abs() < 1e-9 && a.y > 0.0, "{a}");
        // the stick tilt quaternion pitches the nose down for a forward stick
        let v = stick_tilt(&fwd, tilt);
        let q = UnitQuaternion::from_scaled_axis(Vector3::new(v.x, v.y, 0.0));
        assert!((euler_zyx(&q).y + tilt).abs() < 1e-9);
    }
}
