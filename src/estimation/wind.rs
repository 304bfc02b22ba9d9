//! The wind the vehicle feels: the air-relative velocity that the airframe's
//! nominal drag model needs to explain the external force the momentum-based
//! estimator sees, and the wind as ground velocity minus that airspeed
//! (`docs/estimator.md`, "The wind the vehicle feels").
//!
//! The drag model is RotorPy's (`Multirotor(aero=True)`), restricted to the
//! body-horizontal axes, with `v` the airspeed of the centre of mass in body
//! FRD, `omega_i` the rotor speeds and `S = sum_i omega_i`:
//!
//! ```text
//! F_x = -(c_dx |v| + k_d S) v_x        F_y = -(c_dy |v| + k_d S) v_y        [N], body FRD
//! ```
//!
//! Solved for `v`, as PX4's EKF2 does with its multirotor drag fusion
//! (`EKF2_BCOEF_X/Y`, `EKF2_MCOEF`): only the body `x` and `y` force
//! components are used (the `z` one also carries the thrust model's and the
//! nominal mass's errors) and the wind is taken horizontal in NED (`w_d = 0`,
//! PX4's wind states are horizontal too), which closes the system: with `R`
//! the attitude (FRD to NED) and `s = |v|`,
//!
//! ```text
//! v_x(s) = -F_x / (c_dx s + k_d S)      v_y(s) = -F_y / (c_dy s + k_d S)
//! v_z(s) = (v_g,d - R_31 v_x - R_32 v_y) / R_33        (the air moves with the ground vertically)
//! |v(s)| = s                                            (one scalar equation, solved by Newton's method)
//! w_ned  = v_g,ned - R v(s)                             (w_d = 0 by construction)
//! ```
//!
//! with `F = R^T f_e` the estimated external force in body FRD and `v_g` the
//! measured ground velocity (NED). `|v(s)| - s` is positive at `s = 0` and
//! negative for large `s`, so a root exists whenever the force is one the
//! drag can produce below [`MAX_AIRSPEED_M_S`].
//!
//! What it assumes: every external force in the body plane is this drag (an
//! injected force, a wall or a tether reads as wind); the nominal drag
//! coefficients are the vehicle's; the body rates are small (the hubs'
//! airspeed `omega x r_i` is left out); the wind has no vertical component.
//! Without a drag term on an axis (both `c_d` and `k_d S` zero: zero
//! coefficients, or stopped rotors without parasitic drag) no airspeed
//! explains a force on it and there is no estimate ([`None`]), never a
//! division by zero. With parasitic drag only, the slope of the drag at zero
//! airspeed is zero: near still air the estimate is noisy, and the variance
//! [`WindFilter`] reports says so.

use nalgebra::{UnitQuaternion, Vector2, Vector3};
use serde::Serialize;

use crate::signals::WindEstimate;

/// The largest airspeed [m/s] the solver looks for; a force that needs more
/// is not drag (no estimate).
pub const MAX_AIRSPEED_M_S: f64 = 200.0;

/// Tilt beyond which there is no estimate: `R_33 = cos(tilt)` below this
/// (60 deg) makes the vertical closure ill-conditioned.
pub const MIN_COS_TILT: f64 = 0.5;

/// The solver stops when an iterate moves the airspeed by less than this
/// [m/s], far below any noise.
const TOLERANCE_M_S: f64 = 1e-12;

/// Iterations at most: enough for bisection alone to narrow
/// `[0, MAX_AIRSPEED_M_S]` to [`TOLERANCE_M_S`] (48), where Newton's method
/// takes about six.
const MAX_ITERATIONS: usize = 64;

/// The nominal drag model the wind estimate inverts (the body-horizontal
/// terms of the airframe's aerodynamic coefficients).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct DragModel {
    /// Parasitic drag along body `x_b` [N/(m/s)^2] (`c_dx`).
    pub c_dx: f64,
    /// Parasitic drag along body `y_b` [N/(m/s)^2] (`c_dy`).
    pub c_dy: f64,
    /// Rotor drag in the rotor plane [N/(rad/s)/(m/s)] (`k_d`), per rotor.
    pub k_d: f64,
}

impl DragModel {
    /// Whether some airspeed could be told from a force: a body-horizontal
    /// drag coefficient is not zero.
    #[must_use]
    pub fn can_explain_a_force(&self) -> bool {
        self.c_dx > 0.0 || self.c_dy > 0.0 || self.k_d > 0.0
    }
}

/// One solution of the drag model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WindSolution {
    /// The wind [m/s], NED (the air's velocity over the ground; `z` = 0).
    pub wind_ned: Vector3<f64>,
    /// The airspeed of the centre of mass [m/s], body FRD (ground velocity minus wind).
    pub airspeed_frd: Vector3<f64>,
}

/// The wind that explains the external force `force_ned` [N] (NED, the
/// estimator's `f_e`) at ground velocity `velocity_ned` [m/s], attitude
/// `attitude` (FRD to NED) and rotor speeds summing to `rotor_speed_sum`
/// [rad/s] (the equations in the module doc). [`None`] when the model cannot
/// explain the force: no drag on a body-horizontal axis, a force that needs
/// more than [`MAX_AIRSPEED_M_S`], a tilt beyond 60 deg, or an input not finite.
#[must_use]
pub fn wind_from_force(
    model: &DragModel,
    force_ned: &Vector3<f64>,
    velocity_ned: &Vector3<f64>,
    attitude: &UnitQuaternion<f64>,
    rotor_speed_sum: f64,
) -> Option<WindSolution> {
    let finite = force_ned.iter().chain(velocity_ned.iter()).all(|x| x.is_finite())
        && rotor_speed_sum.is_finite()
        && attitude.coords.iter().all(|x| x.is_finite());
    if !finite {
        return None;
    }
    let linear = model.k_d * rotor_speed_sum.max(0.0);
    let drag_on_both_axes = linear > 0.0 || (model.c_dx > 0.0 && model.c_dy > 0.0);
    if !drag_on_both_axes {
        return None;
    }
    let r = attitude.to_rotation_matrix();
    let r = r.matrix();
    let r33 = r[(2, 2)];
    if r33 < MIN_COS_TILT {
        return None;
    }
    let f = r.transpose() * force_ned;
    // v(s) and its slope dv/ds: d v_x/ds = -v_x c_dx / (c_dx s + k_d S),
    // likewise v_y, and d v_z/ds = -(R_31 v_x' + R_32 v_y') / R_33
    let airspeed = |s: f64| {
        let (dx, dy) = (model.c_dx * s + linear, model.c_dy * s + linear);
        let (vx, vy) = (-f.x / dx, -f.y / dy);
        let vz = (velocity_ned.z - r[(2, 0)] * vx - r[(2, 1)] * vy) / r33;
        let (sx, sy) = (-vx * model.c_dx / dx, -vy * model.c_dy / dy);
        let sz = -(r[(2, 0)] * sx + r[(2, 1)] * sy) / r33;
        (Vector3::new(vx, vy, vz), Vector3::new(sx, sy, sz))
    };
    // g(s) = |v(s)| - s: >= 0 at s = 0 (infinite there without rotor drag),
    // < 0 beyond the root. Newton's method on g, s <- s - g / g' with
    // g' = v . v' / |v| - 1, kept inside the bracket [lo, hi] of the root
    // (a step that leaves it, or no slope, bisects instead)
    let (v_max, _) = airspeed(MAX_AIRSPEED_M_S);
    if v_max.norm() - MAX_AIRSPEED_M_S >= 0.0 {
        return None;
    }
    let (mut lo, mut hi) = (0.0, MAX_AIRSPEED_M_S);
    let mut s = MAX_AIRSPEED_M_S;
    let mut airspeed_frd = v_max;
    for _ in 0..MAX_ITERATIONS {
        let (v, slope) = airspeed(s);
        airspeed_frd = v;
        let norm = v.norm();
        let g = norm - s;
        if g >= 0.0 {
            lo = s;
        } else {
            hi = s;
        }
        let newton = s - g / (v.dot(&slope) / norm - 1.0);
        let next = if newton > lo && newton < hi {
            newton
        } else {
            0.5 * (lo + hi)
        };
        if g == 0.0 || (next - s).abs() <= TOLERANCE_M_S {
            break;
        }
        s = next;
    }
    let mut wind_ned = velocity_ned - r * airspeed_frd;
    wind_ned.z = 0.0;
    wind_ned
        .iter()
        .all(|x| x.is_finite())
        .then_some(WindSolution { wind_ned, airspeed_frd })
}

/// The reported wind: a first-order low-pass of the solutions and the
/// running variance of the solutions about it, per horizontal axis, both
/// with time constant `tau`:
///
/// ```text
/// a = 1 - exp(-dt / tau)
/// w_mean += a (w - w_mean)
/// var    += a ((w - w_mean)^2 - var)           per axis, north and east
/// ```
///
/// (MAVLink's `WIND_COV.var_horiz` is "the variability of a 1 Hz low-passed
/// wind estimate"; PX4 puts `variance_north + variance_east` there.) The
/// first sample starts the mean; it is reported [`Self::settled`] once it
/// has filtered for `settle_s`.
#[derive(Clone, Debug, PartialEq)]
pub struct WindFilter {
    tau_s: f64,
    settle_s: f64,
    state: Option<FilterState>,
}

#[derive(Clone, Copy, Debug, PartialEq)]
struct FilterState {
    start_s: f64,
    last_s: f64,
    mean_ne: Vector2<f64>,
    variance_ne: Vector2<f64>,
}

impl WindFilter {
    /// A filter with time constant `tau_s` [s] that reports after `settle_s` [s].
    #[must_use]
    pub fn new(tau_s: f64, settle_s: f64) -> Self {
        Self {
            tau_s,
            settle_s,
            state: None,
        }
    }

    /// Forget everything (on the ground).
    pub fn reset(&mut self) {
        self.state = None;
    }

    /// Take the solution `wind_ned` at time `time_s` [s].
    pub fn update(&mut self, time_s: f64, wind_ned: &Vector3<f64>) {
        let w = wind_ned.xy();
        match &mut self.state {
            None => {
                self.state = Some(FilterState {
                    start_s: time_s,
                    last_s: time_s,
                    mean_ne: w,
                    variance_ne: Vector2::zeros(),
                });
            }
            Some(s) => {
                let a = 1.0 - (-(time_s - s.last_s).max(0.0) / self.tau_s).exp();
                s.mean_ne += a * (w - s.mean_ne);
                let d = w - s.mean_ne;
                s.variance_ne += a * (d.component_mul(&d) - s.variance_ne);
                s.last_s = time_s;
            }
        }
    }

    /// The estimate, once the filter has run for its settling time.
    #[must_use]
    pub fn settled(&self) -> Option<WindEstimate> {
        let s = self.state?;
        (s.last_s - s.start_s >= self.settle_s).then(|| WindEstimate {
            time_s: s.last_s,
            wind_ned: Vector3::new(s.mean_ne.x, s.mean_ne.y, 0.0),
            variance_ne: s.variance_ne,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// RotorPy's body drag force (FRD) at body airspeed `v`, all three axes.
    fn drag_frd(m: &DragModel, c_dz: f64, k_z: f64, s: f64, v: &Vector3<f64>) -> Vector3<f64> {
        let n = v.norm();
        Vector3::new(
            -(m.c_dx * n + m.k_d * s) * v.x,
            -(m.c_dy * n + m.k_d * s) * v.y,
            -(c_dz * n + k_z * s) * v.z,
        )
    }

    fn model() -> DragModel {
        DragModel {
            c_dx: 0.01,
            c_dy: 0.012,
            k_d: 2e-5,
        }
    }

    /// The force the estimator sees in a given wind (NED), and the solution.
    fn round_trip(
        m: &DragModel,
        wind: Vector3<f64>,
        v_g: Vector3<f64>,
        q: UnitQuaternion<f64>,
        s: f64,
    ) -> Option<WindSolution> {
        let v_b = q.inverse() * (v_g - wind);
        let f_ned = q * drag_frd(m, 0.03, 4e-5, s, &v_b);
        wind_from_force(m, &f_ned, &v_g, &q, s)
    }

    #[test]
    fn the_wind_that_made_the_force_is_found_again() {
        let m = model();
        let cases = [
            // hovering level in 5 m/s from the west (blowing east)
            (
                Vector3::new(0.0, 5.0, 0.0),
                Vector3::zeros(),
                UnitQuaternion::identity(),
            ),
            // tilted into it, yawed, drifting and climbing
            (
                Vector3::new(-3.0, 4.0, 0.0),
                Vector3::new(0.4, -0.2, -0.5),
                UnitQuaternion::from_euler_angles(0.1, -0.15, 2.0),
            ),
            // flying fast downwind
            (
                Vector3::new(6.0, 1.0, 0.0),
                Vector3::new(10.0, 2.0, 0.3),
                UnitQuaternion::from_euler_angles(-0.05, -0.3, 0.2),
            ),
        ];
        for (wind, v_g, q) in cases {
            let sol = round_trip(&m, wind, v_g, q, 4.0 * 900.0).expect("explained");
            assert!((sol.wind_ned - wind).norm() < 1e-9, "{wind} -> {}", sol.wind_ned);
            assert!((sol.airspeed_frd - q.inverse() * (v_g - wind)).norm() < 1e-9);
        }
    }

    #[test]
    fn rotor_drag_alone_is_linear_and_parasitic_drag_alone_quadratic() {
        let level = UnitQuaternion::identity();
        let rotor = DragModel {
            k_d: 2e-5,
            ..DragModel::default()
        };
        // F = -k_d S v: 0.36 N against the airspeed at S = 3600 rad/s is 5 m/s
        let f = Vector3::new(0.0, 2e-5 * 3600.0 * 5.0, 0.0);
        let sol = wind_from_force(&rotor, &f, &Vector3::zeros(), &level, 3600.0).unwrap();
        assert!(
            (sol.wind_ned - Vector3::new(0.0, 5.0, 0.0)).norm() < 1e-9,
            "{}",
            sol.wind_ned
        );
        let parasitic = DragModel {
            c_dx: 0.01,
            c_dy: 0.01,
            k_d: 0.0,
        };
        // F = -c |v| v: 0.25 N at c = 0.01 is 5 m/s, rotors stopped or not
        let f = Vector3::new(0.25, 0.0, 0.0);
        for s in [0.0, 3600.0] {
            let sol = wind_from_force(&parasitic, &f, &Vector3::zeros(), &level, s).unwrap();
            assert!(
                (sol.wind_ned - Vector3::new(5.0, 0.0, 0.0)).norm() < 1e-9,
                "{}",
                sol.wind_ned
            );
        }
        // no force in still air: no wind, also where the drag has no slope
        let sol = wind_from_force(&parasitic, &Vector3::zeros(), &Vector3::zeros(), &level, 0.0).unwrap();
        assert_eq!(sol.wind_ned, Vector3::zeros());
    }

    #[test]
    fn without_drag_there_is_no_estimate_not_a_division_by_zero() {
        let level = UnitQuaternion::identity();
        let f = Vector3::new(0.3, -0.2, -1.0);
        // zero coefficients, hovering
        assert_eq!(
            wind_from_force(&DragModel::default(), &f, &Vector3::zeros(), &level, 3600.0),
            None
        );
        assert!(!DragModel::default().can_explain_a_force());
        // rotor drag only, rotors stopped
        let rotor = DragModel {
            k_d: 2e-5,
            ..DragModel::default()
        };
        assert_eq!(wind_from_force(&rotor, &f, &Vector3::zeros(), &level, 0.0), None);
        // parasitic drag along x only: the y force is not drag
        let x_only = DragModel {
            c_dx: 0.01,
            ..DragModel::default()
        };
        assert_eq!(wind_from_force(&x_only, &f, &Vector3::zeros(), &level, 0.0), None);
    }

    #[test]
    fn forces_drag_cannot_make_and_bad_input_give_no_estimate() {
        let m = model();
        let level = UnitQuaternion::identity();
        // 1 kN of drag needs more than 200 m/s
        let huge = Vector3::new(1e3, 0.0, 0.0);
        assert_eq!(wind_from_force(&m, &huge, &Vector3::zeros(), &level, 3600.0), None);
        // tilted 70 deg
        let tilted = UnitQuaternion::from_euler_angles(1.22, 0.0, 0.0);
        let f = Vector3::new(0.1, 0.0, 0.0);
        assert_eq!(wind_from_force(&m, &f, &Vector3::zeros(), &tilted, 3600.0), None);
        let nan = Vector3::new(f64::NAN, 0.0, 0.0);
        assert_eq!(wind_from_force(&m, &nan, &Vector3::zeros(), &level, 3600.0), None);
        assert_eq!(wind_from_force(&m, &f, &nan, &level, 3600.0), None);
        assert_eq!(wind_from_force(&m, &f, &Vector3::zeros(), &level, f64::INFINITY), None);
    }

    #[test]
    fn the_filter_settles_on_the_mean_and_reports_the_spread() {
        let mut filter = WindFilter::new(1.0, 3.0);
        assert_eq!(filter.settled(), None);
        // +-1 m/s about (0, 5) every 20 ms for 20 s
        for k in 0..1000 {
            let t = f64::from(k) * 0.02;
            let e = if k % 2 == 0 { 1.0 } else { -1.0 };
            filter.update(t, &Vector3::new(e, 5.0, 0.0));
            if t < 3.0 {
                assert_eq!(filter.settled(), None, "{t}");
            }
        }
        let w = filter.settled().unwrap();
        assert!(
            (w.wind_ned - Vector3::new(0.0, 5.0, 0.0)).norm() < 0.02,
            "{}",
            w.wind_ned
        );
        assert!((w.variance_ne.x - 1.0).abs() < 0.05, "{}", w.variance_ne);
        assert!(w.variance_ne.y < 1e-12);
        assert_eq!(w.time_s, 19.98);
        filter.reset();
        assert_eq!(filter.settled(), None);
    }
}
