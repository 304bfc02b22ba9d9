//! The aerodynamic wrench of body and rotors (RotorPy's `Multirotor(aero=True)`
//! terms, `docs/model.md` section 8b), in body FRD, with the rotor sum in
//! closed form: the hubs of every airframe lie in the body's x-y plane, so
//! the sum over rotors needs only the speed-weighted moments of the hub
//! positions, six sums a step.
//!
//! With the body airspeed `v_a = (a, b, c)`, the body rates `(p, q, r)`, hub
//! `i` at `(x_i, y_i, 0)` turning at `omega_i`, its airspeed is
//! `v_i = (a - r y_i, b + r x_i, c + p y_i - q x_i)` and
//!
//! ```text
//! f = -|v_a| diag(c_dx, c_dy, c_dz) v_a + sum_i F_i
//! F_i = (-k_d omega_i v_i,x, -k_d omega_i v_i,y, -k_z omega_i v_i,z - k_h Q_i),  Q_i = v_i,x^2 + v_i,y^2
//! tau = sum_i r_i x F_i + k_flap omega_i (v_i,y, -v_i,x, 0)
//! ```
//!
//! written with `S_0 = sum omega_i`, `S_x = sum omega_i x_i`, `S_y`, `S_xx`,
//! `S_yy`, `S_xy` (per step) and the same sums unweighted, `G_*` (per
//! airframe; `G_xrr = sum x_i (x_i^2 + y_i^2)`, `G_yrr`, `G_rr`, `n`):
//!
//! ```text
//! f_x = -k_d (a S_0 - r S_y)            f_y = -k_d (b S_0 + r S_x)
//! f_z = -k_z (c S_0 + p S_y - q S_x) - k_h (n (a^2 + b^2) + 2 r (b G_x - a G_y) + r^2 G_rr)
//! tau_x = -k_z (c S_y + p S_yy - q S_xy) - k_h (G_y (a^2 + b^2) + 2 r (b G_xy - a G_yy) + r^2 G_yrr)
//!         + k_flap (b S_0 + r S_x)
//! tau_y =  k_z (c S_x + p S_xy - q S_xx) + k_h (G_x (a^2 + b^2) + 2 r (b G_xx - a G_xy) + r^2 G_xrr)
//!         - k_flap (a S_0 - r S_y)
//! tau_z = -k_d (b S_x - a S_y + r (S_xx + S_yy))
//! ```

use nalgebra::Vector3;

use crate::airframe::{AeroCoefficients, Airframe};
use crate::signals::{MAX_ROTORS, RotorVector};

/// An airframe's drag model: its coefficients and the moments of its hub
/// positions (body FRD, in the x-y plane).
#[derive(Clone, Debug)]
pub(super) struct Drag {
    c: AeroCoefficients,
    /// Hub coordinates `x_i`, `y_i` [m], body FRD; unused slots 0.
    hub_x: [f64; MAX_ROTORS],
    hub_y: [f64; MAX_ROTORS],
    n: usize,
    /// `n`, `G_x`, `G_y`, `G_xx`, `G_yy`, `G_xy`, `G_rr`, `G_xrr`, `G_yrr`.
    g: [f64; 9],
}

impl Drag {
    /// The drag model of `airframe` (its `[aero]` table and rotor hubs).
    pub(super) fn new(airframe: &Airframe) -> Self {
        let mut hub_x = [0.0; MAX_ROTORS];
        let mut hub_y = [0.0; MAX_ROTORS];
        let mut g = [0.0; 9];
        for (i, r) in airframe.rotors.iter().take(MAX_ROTORS).enumerate() {
            let p = r.position_frd();
            let (x, y) = (p.x, p.y);
            hub_x[i] = x;
            hub_y[i] = y;
            let rr = x * x + y * y;
            for (gk, v) in g.iter_mut().zip([1.0, x, y, x * x, y * y, x * y, rr, x * rr, y * rr]) {
                *gk += v;
            }
        }
        Self {
            c: airframe.aero,
            hub_x,
            hub_y,
            n: airframe.rotors.len().min(MAX_ROTORS),
            g,
        }
    }

    /// The coefficients.
    pub(super) fn coefficients(&self) -> &AeroCoefficients {
        &self.c
    }

    /// Aerodynamic force [N] and torque [N m], both body FRD, at body
    /// airspeed `va` [m/s] and body rates `rate` [rad/s] (FRD) with rotor
    /// speeds `speeds` [rad/s] (the module doc's closed form).
    #[inline(always)]
    pub(super) fn wrench_frd(
        &self,
        va: &Vector3<f64>,
        rate: &Vector3<f64>,
        speeds: &RotorVector,
    ) -> (Vector3<f64>, Vector3<f64>) {
        let c = &self.c;
        let (mut s0, mut sx, mut sy, mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        for i in 0..self.n {
            let (w, x, y) = (speeds[i], self.hub_x[i], self.hub_y[i]);
            let (wx, wy) = (w * x, w * y);
            s0 += w;
            sx += wx;
            sy += wy;
            sxx += wx * x;
            syy += wy * y;
            sxy += wx * y;
        }
        let [n, gx, gy, gxx, gyy, gxy, grr, gxrr, gyrr] = self.g;
        let (a, b, cz) = (va.x, va.y, va.z);
        let (p, q, r) = (rate.x, rate.y, rate.z);
        let speed = va.norm();
        let ab = a * a + b * b;
        let r2 = r * r;
        // sum_i omega_i v_i,x and sum_i omega_i v_i,y
        let wvx = a * s0 - r * sy;
        let wvy = b * s0 + r * sx;
        let force = Vector3::new(
            -speed * c.c_dx * a - c.k_d * wvx,
            -speed * c.c_dy * b - c.k_d * wvy,
            -speed * c.c_dz * cz
                - c.k_z * (cz * s0 + p * sy - q * sx)
                - c.k_h * (n * ab + 2.0 * r * (b * gx - a * gy) + r2 * grr),
        );
        let mut torque = Vector3::new(
            -c.k_z * (cz * sy + p * syy - q * sxy) - c.k_h * (gy * ab + 2.0 * r * (b * gxy - a * gyy) + r2 * gyrr),
            c.k_z * (cz * sx + p * sxy - q * sxx) + c.k_h * (gx * ab + 2.0 * r * (b * gxx - a * gxy) + r2 * gxrr),
            -c.k_d * (b * sx - a * sy + r * (sxx + syy)),
        );
        if c.k_flap != 0.0 {
            torque.x += c.k_flap * wvy;
            torque.y -= c.k_flap * wvx;
        }
        (force, torque)
    }
}
