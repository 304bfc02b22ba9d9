//! Gains of the three control laws and the limits they share.
//!
//! Defaults come from pole placement ([`ControlGains::for_vehicle`]): each
//! loop is a second-order system `s^2 + 2 zeta w s + w^2`, with the gains
//! written per unit mass/inertia for the hierarchical law and multiplied by
//! the nominal mass and inertia for the geometric and passivity-based laws.
//!
//! Files (airframe, scenario) override single gains through [`GainOverrides`]:
//! every field there is optional and unknown fields are rejected, and the
//! overrides are applied on top of the vehicle's defaults, so a file need not
//! (and should not) repeat gains it does not change:
//! ```toml
//! [geometric]
//! kp_n_per_m = [355.0, 355.0, 565.0]
//! [limits]
//! max_tilt_rad = 0.6
//! ```

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use crate::signals::NominalModel;

/// Defines a gains struct (all fields required) and its override twin (all
/// fields optional), with `apply` copying the overrides that are set.
macro_rules! gains_with_overrides {
    (
        $(#[$meta:meta])*
        $name:ident, $over:ident {
            $( $(#[$fmeta:meta])* $field:ident : $ty:ty ),* $(,)?
        }
    ) => {
        $(#[$meta])*
        #[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
        #[serde(deny_unknown_fields)]
        pub struct $name {
            $( $(#[$fmeta])* pub $field: $ty, )*
        }

        #[doc = concat!("Optional overrides of [`", stringify!($name), "`]: unset fields keep their value.")]
        #[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
        #[serde(deny_unknown_fields, default)]
        pub struct $over {
            $( $(#[$fmeta])* #[serde(skip_serializing_if = "Option::is_none")] pub $field: Option<$ty>, )*
        }

        impl $name {
            #[doc = concat!("Copy every field set in `overrides` into `self`.")]
            pub fn apply(&mut self, overrides: &$over) {
                $( if let Some(v) = overrides.$field { self.$field = v; } )*
            }
        }
    };
}

gains_with_overrides! {
    /// Hierarchical (two-loop RPY) law, `docs/model.md` section 4.
    /// Gains are per unit mass (outer) and per unit inertia (inner), so they
    /// place poles directly: `s^2 + K_D s + K_P` per axis.
    HierarchicalGains, HierarchicalOverrides {
        /// Outer `K_P` [1/s^2] per NED axis.
        kp_pos_per_s2: Vector3<f64>,
        /// Outer `K_D` [1/s] per NED axis.
        kd_pos_per_s: Vector3<f64>,
        /// Inner `K_P,eta` [1/s^2] for roll, pitch, yaw.
        kp_att_per_s2: Vector3<f64>,
        /// Inner `K_D,eta` [1/s] for roll, pitch, yaw.
        kd_att_per_s: Vector3<f64>,
        /// Natural frequency [rad/s] of the critically damped filter giving
        /// `phi_d, theta_d` derivatives (prototype: 60).
        eta_filter_rad_s: f64,
    }
}

gains_with_overrides! {
    /// Geometric law on SE(3) (Lee, Leok, McClamroch 2010), doc section 5.
    GeometricGains, GeometricOverrides {
        /// `K_p` [N/m] per NED axis.
        kp_n_per_m: Vector3<f64>,
        /// `K_v` [N s/m] per NED axis.
        kv_n_s_per_m: Vector3<f64>,
        /// `K_R` [N m/rad] per FRD axis.
        kr_n_m_per_rad: Vector3<f64>,
        /// `K_omega` [N m s/rad] per FRD axis.
        komega_n_m_s_per_rad: Vector3<f64>,
        /// Cutoff [Hz] of the first-order low-pass on `w_d_dot` (0: none,
        /// the report's raw second difference; `geometric.rs`).
        omega_dot_d_cutoff_hz: f64,
    }
}

gains_with_overrides! {
    /// Passivity-based law (Ruggiero, Cacace, Sadeghian, Lippiello 2015), doc
    /// section 6. Linearized per axis: `m e'' + (m sigma_p + D_p) e' + (D_p sigma_p + K_p) e = f`
    /// and the same with `I_b, sigma, D_o, K_o` for the angles.
    PassivityGains, PassivityOverrides {
        /// Linear coupling gain `sigma_p` [1/s].
        sigma_p_per_s: f64,
        /// Linear damping `D_p` [N s/m] per NED axis.
        dp_n_s_per_m: Vector3<f64>,
        /// Linear stiffness `K_p` [N/m] per NED axis.
        kp_n_per_m: Vector3<f64>,
        /// Angular coupling gain `sigma` [1/s].
        sigma_per_s: f64,
        /// Angular damping `D_o` [N m s/rad] for roll, pitch, yaw.
        do_n_m_s_per_rad: Vector3<f64>,
        /// Angular stiffness `K_o` [N m/rad] for roll, pitch, yaw.
        ko_n_m_per_rad: Vector3<f64>,
        /// Natural frequency [rad/s] of the `phi_d, theta_d` derivative filter.
        eta_filter_rad_s: f64,
    }
}

gains_with_overrides! {
    /// Guards and output limits shared by the three laws.
    ControlLimits, LimitsOverrides {
        /// Largest commanded tilt of the thrust axis from vertical [rad] (all laws).
        max_tilt_rad: f64,
        /// Largest commanded downward acceleration as a fraction of `g`
        /// (`mu_z <= 0.9 g`, doc section 4; geometric: `A_z <= -(1 - 0.9) m g`).
        max_down_accel_g: f64,
        /// Smallest thrust command as a fraction of the nominal weight `m g`
        /// (keeps torque authority through the allocator).
        min_thrust_g: f64,
        /// Largest thrust command as a fraction of the nominal weight `m g`
        /// (default 2; [`ControlGains::for_airframe`] lowers it to the rotors'
        /// maximum). Keep it below about 1.4 times the rotors' maximum thrust:
        /// beyond that the allocator's 30 % collective shift cannot bring the
        /// request into range and no roll/pitch torque is left.
        max_thrust_g: f64,
        /// Torque clamp per FRD axis, `|tau_i| <= I_ii * this` [rad/s^2].
        max_angular_accel_rad_s2: f64,
        /// Tilt [rad] above which the RPY laws (hierarchical, passivity) hand
        /// the attitude to the SO(3) loop until the tilt is back below
        /// `(max_tilt_rad + recovery_tilt_rad) / 2`; must be below 85 deg.
        recovery_tilt_rad: f64,
    }
}

/// Gains of all three laws and the shared limits.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ControlGains {
    /// Hierarchical law.
    pub hierarchical: HierarchicalGains,
    /// Geometric law (also the attitude loop of [`super::Controller::update_attitude`]).
    pub geometric: GeometricGains,
    /// Passivity-based law.
    pub passivity: PassivityGains,
    /// Guards and output limits.
    pub limits: ControlLimits,
}

/// Optional overrides of [`ControlGains`], as read from an airframe or scenario file.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GainOverrides {
    /// Hierarchical law.
    pub hierarchical: HierarchicalOverrides,
    /// Geometric law.
    pub geometric: GeometricOverrides,
    /// Passivity-based law.
    pub passivity: PassivityOverrides,
    /// Guards and output limits.
    pub limits: LimitsOverrides,
}

/// What is wrong with a gain.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum GainProblem {
    /// A table of overrides that does not read as gains (an unknown key, a
    /// wrong type): the reader's message.
    Unreadable(String),
    /// NaN or infinite.
    NotFinite,
    /// Zero or negative where a positive value is required.
    NotPositive,
    /// Outside its allowed range (the message says which).
    OutOfRange(&'static str),
}

impl std::fmt::Display for GainProblem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            GainProblem::Unreadable(why) => f.write_str(why),
            GainProblem::NotFinite => f.write_str("is not finite"),
            GainProblem::NotPositive => f.write_str("must be > 0"),
            GainProblem::OutOfRange(why) => write!(f, "is out of range: {why}"),
        }
    }
}

/// A rejected gain: which field (`law.field[axis]`), its value and the problem.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{}", self.describe())]
pub struct GainError {
    /// Dotted field name, e.g. `geometric.kr_n_m_per_rad[2]`.
    pub field: String,
    /// The offending value.
    pub value: f64,
    /// What is wrong.
    pub problem: GainProblem,
}

impl GainError {
    fn describe(&self) -> String {
        match &self.problem {
            GainProblem::Unreadable(why) => format!("control gains {}: {why}", self.field),
            p => format!("control gain {} = {} {p}", self.field, self.value),
        }
    }
}

impl GainOverrides {
    /// Read overrides from a TOML table such as an airframe file's `[control]`
    /// (`[control.geometric]`, ...); unknown keys and wrong types are refused.
    ///
    /// # Errors
    /// [`GainProblem::Unreadable`] with the reader's message.
    pub fn from_table(table: &toml::Table) -> Result<Self, GainError> {
        toml::Value::Table(table.clone())
            .try_into()
            .map_err(|e: toml::de::Error| GainError {
                field: "[control]".into(),
                value: f64::NAN,
                problem: GainProblem::Unreadable(e.message().trim().to_string()),
            })
    }
}

/// Pole-placement design of the defaults: natural frequency [rad/s] and damping ratio.
#[derive(Clone, Copy, Debug)]
struct Pole {
    w: f64,
    zeta: f64,
}

impl Pole {
    fn stiffness(self) -> f64 {
        self.w * self.w
    }
    fn damping(self) -> f64 {
        2.0 * self.zeta * self.w
    }
}

/// Position loop (all axes): slow enough for tilt limits and 20 ms motor lag.
const POSITION: Pole = Pole { w: 2.5, zeta: 0.9 };
/// Roll/pitch loop: 6 times the position loop (doc section 4 suggests about 5);
/// with a 20 ms motor lag the closed-loop damping stays about 0.6.
const ROLL_PITCH: Pole = Pole { w: 15.0, zeta: 0.9 };
/// Yaw loop: yaw authority of a multirotor is small (drag torque only).
const YAW: Pole = Pole { w: 5.0, zeta: 0.9 };
/// Coupling gains of the passivity-based law as fractions of the natural frequency.
const SIGMA_FRACTION: f64 = 0.25;

impl Default for ControlLimits {
    fn default() -> Self {
        Self {
            max_tilt_rad: 40f64.to_radians(),
            max_down_accel_g: 0.9,
            min_thrust_g: 0.1,
            max_thrust_g: 2.0,
            max_angular_accel_rad_s2: 1000.0,
            recovery_tilt_rad: 70f64.to_radians(),
        }
    }
}

impl ControlGains {
    /// Defaults for a vehicle by pole placement, scaled with its nominal mass
    /// and inertia: position `w = 2.5 rad/s`, roll/pitch `w = 15 rad/s`, yaw
    /// `w = 5 rad/s`, all `zeta = 0.9`. The passivity law is matched to the
    /// same linearized poles (doc section 10) with `sigma = w / 4`.
    #[must_use]
    pub fn for_vehicle(model: &NominalModel) -> Self {
        let m = model.mass_kg;
        let i = model.inertia_kg_m2.diagonal();
        let att = |p_rp: Pole, p_y: Pole| Vector3::new(p_rp.w, p_rp.w, p_y.w);
        let stiff = |pp: Pole, py: Pole| Vector3::new(pp.stiffness(), pp.stiffness(), py.stiffness());
        let damp = |pp: Pole, py: Pole| Vector3::new(pp.damping(), pp.damping(), py.damping());
        let hierarchical = HierarchicalGains {
            kp_pos_per_s2: Vector3::repeat(POSITION.stiffness()),
            kd_pos_per_s: Vector3::repeat(POSITION.damping()),
            kp_att_per_s2: stiff(ROLL_PITCH, YAW),
            kd_att_per_s: damp(ROLL_PITCH, YAW),
            eta_filter_rad_s: 60.0,
        };
        let geometric = GeometricGains {
            kp_n_per_m: Vector3::repeat(m * POSITION.stiffness()),
            kv_n_s_per_m: Vector3::repeat(m * POSITION.damping()),
            kr_n_m_per_rad: i.component_mul(&stiff(ROLL_PITCH, YAW)),
            komega_n_m_s_per_rad: i.component_mul(&damp(ROLL_PITCH, YAW)),
            omega_dot_d_cutoff_hz: 0.0,
        };
        // sigma below 2 zeta w (positive damping) and w^2 > (2 zeta w - sigma) sigma (positive stiffness).
        let sigma_p = SIGMA_FRACTION * POSITION.w;
        let dp = m * (POSITION.damping() - sigma_p);
        let kp = m * POSITION.stiffness() - dp * sigma_p;
        // one sigma for all three angles: the smaller, from the yaw pole
        let sigma = SIGMA_FRACTION * att(ROLL_PITCH, YAW).min();
        let d_o = i.component_mul(&(damp(ROLL_PITCH, YAW) - Vector3::repeat(sigma)));
        let k_o = i.component_mul(&stiff(ROLL_PITCH, YAW)) - d_o * sigma;
        let passivity = PassivityGains {
            sigma_p_per_s: sigma_p,
            dp_n_s_per_m: Vector3::repeat(dp),
            kp_n_per_m: Vector3::repeat(kp),
            sigma_per_s: sigma,
            do_n_m_s_per_rad: d_o,
            ko_n_m_per_rad: k_o,
            eta_filter_rad_s: 60.0,
        };
        Self {
            hierarchical,
            geometric,
            passivity,
            limits: ControlLimits::default(),
        }
    }

    /// The gains `airframe` flies with when the controller assumes the mass
    /// `mass_kg` (its nominal mass, or `MDL_MASS`): [`Self::for_vehicle`] for
    /// that mass and the airframe's inertia, the thrust cap set to what its
    /// rotors can deliver, `n c_T w_max^2` (at most the default 2 `m g`), then
    /// the airframe file's `[control]` overrides; checked.
    /// A request above the rotors' maximum leaves the allocator no collective
    /// room for roll and pitch torque (its thrust shift is limited to 30 %), so
    /// the cap matters at rotor level.
    ///
    /// # Errors
    /// An unreadable `[control]` table or a gain it makes invalid.
    pub fn for_airframe(airframe: &crate::airframe::Airframe, mass_kg: f64) -> Result<Self, GainError> {
        let model = NominalModel {
            mass_kg,
            inertia_kg_m2: airframe.inertia_kg_m2,
        };
        let mut g = Self::for_vehicle(&model);
        let ratio = airframe.max_thrust_n() / (model.mass_kg * crate::signals::GRAVITY);
        if ratio.is_finite() && ratio > 1.0 {
            g.limits.max_thrust_g = ratio.min(g.limits.max_thrust_g);
        }
        g.apply(&GainOverrides::from_table(&airframe.control)?);
        g.validate()?;
        Ok(g)
    }

    /// The origin report's gains for its vehicle `fsr-quad` (1.5 kg,
    /// `I_b = diag(1.2416, 1.2416, 2.4832)`): geometric `K_p = diag(355, 355, 565)`,
    /// `K_v = diag(27, 27, 15)`, `K_R = diag(300, 300, 500)`, `K_omega = diag(25, 25, 20)`
    /// (report section 5.2); hierarchical and passivity-based as in doc section 10
    /// (`K_P = 16`, `K_D = 7.2`, `K_P,eta = 400`, `K_D,eta = 36`; `sigma_p = 1`,
    /// `D_p = 9.3`, `K_p = 14.7`, `sigma = 5`, `D_o = diag(38.49, 38.49, 76.98)`,
    /// `K_o = diag(304.2, 304.2, 608.4)`).
    #[must_use]
    pub fn report() -> Self {
        Self {
            hierarchical: HierarchicalGains {
                kp_pos_per_s2: Vector3::repeat(16.0),
                kd_pos_per_s: Vector3::repeat(7.2),
                kp_att_per_s2: Vector3::repeat(400.0),
                kd_att_per_s: Vector3::repeat(36.0),
                eta_filter_rad_s: 60.0,
            },
            geometric: GeometricGains {
                kp_n_per_m: Vector3::new(355.0, 355.0, 565.0),
                kv_n_s_per_m: Vector3::new(27.0, 27.0, 15.0),
                kr_n_m_per_rad: Vector3::new(300.0, 300.0, 500.0),
                komega_n_m_s_per_rad: Vector3::new(25.0, 25.0, 20.0),
                omega_dot_d_cutoff_hz: 0.0,
            },
            passivity: PassivityGains {
                sigma_p_per_s: 1.0,
                dp_n_s_per_m: Vector3::repeat(9.3),
                kp_n_per_m: Vector3::repeat(14.7),
                sigma_per_s: 5.0,
                do_n_m_s_per_rad: Vector3::new(38.49, 38.49, 76.98),
                ko_n_m_per_rad: Vector3::new(304.2, 304.2, 608.4),
                eta_filter_rad_s: 60.0,
            },
            limits: ControlLimits::default(),
        }
    }

    /// Apply every override that is set.
    pub fn apply(&mut self, overrides: &GainOverrides) {
        self.hierarchical.apply(&overrides.hierarchical);
        self.geometric.apply(&overrides.geometric);
        self.passivity.apply(&overrides.passivity);
        self.limits.apply(&overrides.limits);
    }

    /// `self` with `overrides` applied.
    #[must_use]
    pub fn with(mut self, overrides: &GainOverrides) -> Self {
        self.apply(overrides);
        self
    }

    /// Check every gain: finite and positive; the limits also in their ranges.
    ///
    /// # Errors
    /// The first offending field, its value and the problem.
    pub fn validate(&self) -> Result<(), GainError> {
        let h = &self.hierarchical;
        positive3("hierarchical.kp_pos_per_s2", &h.kp_pos_per_s2)?;
        positive3("hierarchical.kd_pos_per_s", &h.kd_pos_per_s)?;
        positive3("hierarchical.kp_att_per_s2", &h.kp_att_per_s2)?;
        positive3("hierarchical.kd_att_per_s", &h.kd_att_per_s)?;
        positive("hierarchical.eta_filter_rad_s", h.eta_filter_rad_s)?;
        let g = &self.geometric;
        positive3("geometric.kp_n_per_m", &g.kp_n_per_m)?;
        positive3("geometric.kv_n_s_per_m", &g.kv_n_s_per_m)?;
        positive3("geometric.kr_n_m_per_rad", &g.kr_n_m_per_rad)?;
        positive3("geometric.komega_n_m_s_per_rad", &g.komega_n_m_s_per_rad)?;
        if !(g.omega_dot_d_cutoff_hz.is_finite() && g.omega_dot_d_cutoff_hz >= 0.0) {
            return Err(GainError {
                field: "geometric.omega_dot_d_cutoff_hz".into(),
                value: g.omega_dot_d_cutoff_hz,
                problem: GainProblem::OutOfRange("0 (no low-pass) or a positive frequency"),
            });
        }
        let p = &self.passivity;
        positive("passivity.sigma_p_per_s", p.sigma_p_per_s)?;
        positive3("passivity.dp_n_s_per_m", &p.dp_n_s_per_m)?;
        positive3("passivity.kp_n_per_m", &p.kp_n_per_m)?;
        positive("passivity.sigma_per_s", p.sigma_per_s)?;
        positive3("passivity.do_n_m_s_per_rad", &p.do_n_m_s_per_rad)?;
        positive3("passivity.ko_n_m_per_rad", &p.ko_n_m_per_rad)?;
        positive("passivity.eta_filter_rad_s", p.eta_filter_rad_s)?;
        let l = &self.limits;
        positive("limits.max_tilt_rad", l.max_tilt_rad)?;
        range(
            "limits.max_tilt_rad",
            l.max_tilt_rad,
            0.0,
            80f64.to_radians(),
            "at most 80 deg",
        )?;
        positive("limits.max_down_accel_g", l.max_down_accel_g)?;
        range(
            "limits.max_down_accel_g",
            l.max_down_accel_g,
            0.0,
            0.99,
            "below 0.99 (thrust must point up)",
        )?;
        positive("limits.min_thrust_g", l.min_thrust_g)?;
        positive("limits.max_thrust_g", l.max_thrust_g)?;
        if l.max_thrust_g <= l.min_thrust_g.max(1.0) {
            return Err(GainError {
                field: "limits.max_thrust_g".into(),
                value: l.max_thrust_g,
                problem: GainProblem::OutOfRange("above 1 (hover) and above min_thrust_g"),
            });
        }
        positive("limits.max_angular_accel_rad_s2", l.max_angular_accel_rad_s2)?;
        positive("limits.recovery_tilt_rad", l.recovery_tilt_rad)?;
        if l.recovery_tilt_rad <= l.max_tilt_rad || l.recovery_tilt_rad > 85f64.to_radians() {
            return Err(GainError {
                field: "limits.recovery_tilt_rad".into(),
                value: l.recovery_tilt_rad,
                problem: GainProblem::OutOfRange("above max_tilt_rad and at most 85 deg"),
            });
        }
        Ok(())
    }
}

fn positive(field: &str, value: f64) -> Result<(), GainError> {
    let problem = if !value.is_finite() {
        GainProblem::NotFinite
    } else if value <= 0.0 {
        GainProblem::NotPositive
    } else {
        return Ok(());
    };
    Err(GainError {
        field: field.to_string(),
        value,
        problem,
    })
}

fn positive3(field: &str, v: &Vector3<f64>) -> Result<(), GainError> {
    for (k, x) in v.iter().enumerate() {
        positive(&format!("{field}[{k}]"), *x)?;
    }
    Ok(())
}

fn range(field: &str, value: f64, lo: f64, hi: f64, why: &'static str) -> Result<(), GainError> {
    if value > lo && value <= hi {
        Ok(())
    } else {
        Err(GainError {
            field: field.to_string(),
            value,
            problem: GainProblem::OutOfRange(why),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Matrix3;

    fn model(m: f64, i: [f64; 3]) -> NominalModel {
        NominalModel {
            mass_kg: m,
            inertia_kg_m2: Matrix3::from_diagonal(&Vector3::from(i)),
        }
    }

    #[test]
    fn defaults_are_valid_and_scale_with_mass_and_inertia() {
        let quad = ControlGains::for_vehicle(&model(2.0, [0.0217, 0.0217, 0.04]));
        let octo = ControlGains::for_vehicle(&model(1.5, [0.03, 0.03, 0.05]));
        quad.validate().unwrap();
        octo.validate().unwrap();
        ControlGains::report().validate().unwrap();
        for name in ["quad", "octo", "hexa", "fsr-quad"] {
            let a = crate::airframe::Airframe::load(name).unwrap();
            let g = ControlGains::for_airframe(&a, a.mass_kg).unwrap();
            assert!(g.limits.max_thrust_g > 1.5 && g.limits.max_thrust_g <= 2.0, "{name}");
        }
        assert!((quad.geometric.kp_n_per_m.x / octo.geometric.kp_n_per_m.x - 2.0 / 1.5).abs() < 1e-12);
        assert!((quad.geometric.kr_n_m_per_rad.x / octo.geometric.kr_n_m_per_rad.x - 0.0217 / 0.03).abs() < 1e-12);
        assert_eq!(quad.hierarchical, octo.hierarchical);
    }

    /// GIVEN the doc's section-10 vehicle WHEN the passivity gains are matched to the
    /// hierarchical poles (w = 4, zeta = 0.9, sigma_p = 1; w = 20, sigma = 5) THEN they are the doc's numbers.
    #[test]
    fn passivity_matching_reproduces_doc_section_10() {
        let r = ControlGains::report();
        let (m, i) = (1.5, 1.2416);
        let lin = (m * r.passivity.sigma_p_per_s + r.passivity.dp_n_s_per_m.x) / m;
        let stiff = (r.passivity.dp_n_s_per_m.x * r.passivity.sigma_p_per_s + r.passivity.kp_n_per_m.x) / m;
        assert!((lin - 7.2).abs() < 1e-9 && (stiff - 16.0).abs() < 1e-9);
        let ang = (i * r.passivity.sigma_per_s + r.passivity.do_n_m_s_per_rad.x) / i;
        let ang_k = (r.passivity.do_n_m_s_per_rad.x * r.passivity.sigma_per_s + r.passivity.ko_n_m_per_rad.x) / i;
        assert!((ang - 36.0).abs() < 0.01 && (ang_k - 400.0).abs() < 0.01);
    }

    #[test]
    fn passivity_defaults_match_hierarchical_poles() {
        let md = model(1.5, [0.03, 0.03, 0.05]);
        let g = ControlGains::for_vehicle(&md);
        let p = &g.passivity;
        let h = &g.hierarchical;
        let m = md.mass_kg;
        assert!(((m * p.sigma_p_per_s + p.dp_n_s_per_m.x) / m - h.kd_pos_per_s.x).abs() < 1e-12);
        assert!(((p.dp_n_s_per_m.x * p.sigma_p_per_s + p.kp_n_per_m.x) / m - h.kp_pos_per_s2.x).abs() < 1e-12);
        for k in 0..3 {
            let i = md.inertia_kg_m2[(k, k)];
            assert!(((i * p.sigma_per_s + p.do_n_m_s_per_rad[k]) / i - h.kd_att_per_s[k]).abs() < 1e-9);
            assert!(
                ((p.do_n_m_s_per_rad[k] * p.sigma_per_s + p.ko_n_m_per_rad[k]) / i - h.kp_att_per_s2[k]).abs() < 1e-9
            );
        }
    }

    #[test]
    fn overrides_from_toml_change_single_gains_and_reject_unknown_fields() {
        let text = "[geometric]\nkp_n_per_m = [355.0, 355.0, 565.0]\n[limits]\nmax_tilt_rad = 0.5\n";
        let o: GainOverrides = toml::from_str(text).unwrap();
        let base = ControlGains::for_vehicle(&model(2.0, [0.0217, 0.0217, 0.04]));
        let g = base.with(&o);
        assert_eq!(g.geometric.kp_n_per_m, Vector3::new(355.0, 355.0, 565.0));
        assert_eq!(g.geometric.kv_n_s_per_m, base.geometric.kv_n_s_per_m);
        assert_eq!(g.limits.max_tilt_rad, 0.5);
        assert_eq!(g.hierarchical, base.hierarchical);
        assert!(toml::from_str::<GainOverrides>("[geometric]\nkp = [1.0, 1.0, 1.0]\n").is_err());
        assert!(toml::from_str::<GainOverrides>("[geometrc]\n").is_err());
    }

    #[test]
    fn validate_names_field_and_problem() {
        let mut g = ControlGains::report();
        g.geometric.kr_n_m_per_rad.z = f64::NAN;
        let e = g.validate().unwrap_err();
        assert_eq!(e.field, "geometric.kr_n_m_per_rad[2]");
        assert_eq!(e.problem, GainProblem::NotFinite);
        let mut g = ControlGains::report();
        g.passivity.sigma_per_s = 0.0;
        let e = g.validate().unwrap_err();
        assert_eq!(e.field, "passivity.sigma_per_s");
        assert_eq!(e.problem, GainProblem::NotPositive);
        assert!(e.to_string().contains("passivity.sigma_per_s"));
        let mut g = ControlGains::report();
        g.limits.recovery_tilt_rad = g.limits.max_tilt_rad;
        assert_eq!(g.validate().unwrap_err().field, "limits.recovery_tilt_rad");
        for bad in [-1.0, f64::NAN, f64::INFINITY] {
            let mut g = ControlGains::report();
            g.geometric.omega_dot_d_cutoff_hz = bad;
            assert_eq!(g.validate().unwrap_err().field, "geometric.omega_dot_d_cutoff_hz");
        }
        let mut g = ControlGains::report();
        g.geometric.omega_dot_d_cutoff_hz = 30.0;
        assert!(g.validate().is_ok());
    }
}
