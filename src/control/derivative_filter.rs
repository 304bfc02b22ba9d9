//! The derivative filter of the RPY laws' `phi_d, theta_d` (doc section 4):
//! critically damped, second order per channel,
//! ```text
//! x'' = w^2 (u - x) - 2 w x'
//! ```
//! discretized exactly for an input interpolated linearly between samples
//! (first-order hold). For the ramp `u_prev + r t` over a step `h` the
//! particular solution is `x_p = u - 2 r / w`, `x_p' = r`, and the error
//! `e = x - x_p` obeys the homogeneous equation:
//! ```text
//! c2 = e0' + w e0
//! e1 = (e0 + c2 h) exp(-w h),   e1' = (e0' - c2 w h) exp(-w h)
//! x1 = u - 2 r / w + e1,        x1' = r + e1',   x1'' = w^2 (u - x1) - 2 w x1'
//! ```

use nalgebra::Vector2;

use super::memo::Memo;
use super::sanitise::all_finite;

/// Critically damped second-order filter per channel,
/// `x'' = w^2 (u - x) - 2 w x'`, giving the derivatives `x', x''` of a kinked
/// signal (prototype: `phi_d, theta_d` with `w = 60 rad/s`, doc section 4).
/// Discretized exactly for an input interpolated linearly between samples
/// (first-order hold), so a ramp gives its slope and zero acceleration with
/// no sampling bias; the mean delay is `2 / w`.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct DerivativeFilter {
    x: Vector2<f64>,
    v: Vector2<f64>,
    u_prev: Vector2<f64>,
    initialized: bool,
    /// `exp(-w dt)` for the last `(w, dt)`.
    decay: Memo<(u64, u64), f64>,
}

impl DerivativeFilter {
    pub(super) fn reset(&mut self) {
        *self = Self::default();
    }

    /// Feed the sample `u` taken `dt` after the previous one; returns `(x', x'')`.
    /// The first sample after a reset initialises the filter in its steady
    /// state on a ramp through `u` of slope `v_init` (e.g. the measured rate, so
    /// that a law switched in starts without a rate-error or acceleration kick).
    #[inline]
    pub(super) fn update(
        &mut self,
        u: &Vector2<f64>,
        v_init: &Vector2<f64>,
        w: f64,
        dt: f64,
    ) -> (Vector2<f64>, Vector2<f64>) {
        let u_ok = all_finite(u.as_slice());
        if !self.initialized || !u_ok {
            // steady state on a ramp of slope v_init through u: x lags u by 2 v_init / w
            let u0 = if u_ok { *u } else { Vector2::zeros() };
            self.v = if all_finite(v_init.as_slice()) {
                *v_init
            } else {
                Vector2::zeros()
            };
            self.x = u0 - self.v * (2.0 / w);
            self.u_prev = u0;
            self.initialized = true;
            return (self.v, Vector2::zeros());
        }
        if dt > 0.0 {
            // particular solution for the ramp u_prev + r t: x_p = u - 2 r / w, x_p' = r;
            // the error e = x - x_p obeys the homogeneous equation.
            let r = (u - self.u_prev) / dt;
            let e0 = self.x - (self.u_prev - r * (2.0 / w));
            let ed0 = self.v - r;
            let decay = self.decay.get((w.to_bits(), dt.to_bits()), || (-w * dt).exp());
            let c2 = ed0 + e0 * w;
            let e1 = (e0 + c2 * dt) * decay;
            let ed1 = (ed0 - c2 * (w * dt)) * decay;
            self.x = u - r * (2.0 / w) + e1;
            self.v = r + ed1;
            self.u_prev = *u;
        }
        let acc = (u - self.x) * (w * w) - self.v * (2.0 * w);
        (self.v, acc)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// GIVEN ramps and a parabola WHEN filtered at w = 60 rad/s THEN the rate is
    /// the true one delayed by the filter's mean delay `2 / w` and the acceleration settles.
    #[test]
    fn derivative_filter_tracks_a_ramp() {
        let mut f = DerivativeFilter::default();
        let (mut v, mut a) = (Vector2::zeros(), Vector2::zeros());
        let mut t = 0.0;
        for k in 0..2000 {
            t = f64::from(k) * 1e-3;
            (v, a) = f.update(&Vector2::new(0.5 * t, -t * t), &Vector2::zeros(), 60.0, 1e-3);
        }
        assert!((v.x - 0.5).abs() < 1e-3, "{v}");
        assert!((v.y + 2.0 * (t - 2.0 / 60.0)).abs() < 2e-3, "{v}");
        assert!((a.y + 2.0).abs() < 1e-2, "{a}");
    }
}
