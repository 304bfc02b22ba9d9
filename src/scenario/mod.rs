//! Scenarios: a whole flight described in TOML and flown flat out in lockstep
//! by `rotorpilot simulate`.
//!
//! A scenario names an airframe, a controller and gain overrides, the initial
//! state, a disturbance schedule (external force in NED, torque in FRD, true
//! mass), either an analytic reference (`[reference]`) or timed setpoints
//! shaped into smooth references (`[[setpoint]]`), controller switches, the
//! estimator and whether it is fed back, sensor noise and its seed, failures
//! injected at given instants (`[[fault]]`, see [`fault`]), and the
//! duration. See `tools/scenarios/` for examples. Errors name the file, the
//! field and the problem. Headless fleets ([`fleet`]) fly several in one
//! world; [`placement`] is where a fleet file's vehicles spawn, read the same
//! way for the daemon's fleet files; [`shards`] closes a campaign's output
//! and merges the outputs of its shards.

pub mod campaign;
pub mod fault;
pub mod fleet;
mod mission;
pub mod placement;
mod run;
pub mod shards;
mod trajectory;

pub use fault::{AppliedFault, FaultType, FaultUnit, ScheduledFault};
pub use mission::{
    ItemResult, MissionFlight, MissionSummary, is_mission, mission_lockstep, mission_meta, run_mission,
    run_mission_with,
};
pub use run::{ScenarioPilot, Summary, lockstep, run, run_with, scenario_meta};
pub use trajectory::Trajectory;

use nalgebra::Vector3;
use serde::Deserialize;

use crate::airframe::{Airframe, AirframeError};
use crate::autopilot::{NavSource, nav_config};
use crate::control::{ControlGains, ControllerKind, GainError, GainOverrides, Setpoint};
use crate::estimation::nav::NavConfig;
use crate::estimation::{Discretization, EstimatorConfig, Polynomial};
use crate::params::ParamStore;
use crate::sim::{DisturbanceChange, Environment, SensorNoise, WindSettings};
use crate::tomlfile::{self, FileError};

/// Why a scenario could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    /// The file is unreadable, not valid TOML, or a value is wrong.
    #[error(transparent)]
    File(#[from] FileError),
    /// The airframe it names could not be loaded.
    #[error("{file}:{line}:{column}: airframe: {error}")]
    Airframe {
        /// Scenario path.
        file: String,
        /// 1-based line of the `airframe` value.
        line: usize,
        /// 1-based column of it.
        column: usize,
        /// The airframe's own error (in the message, not also its source:
        /// `{:#}` would print it twice).
        error: AirframeError,
    },
    /// The airframe's `[control]` table gives invalid gains.
    #[error("{file}: airframe {airframe}: {error}")]
    AirframeGains {
        /// Scenario path.
        file: String,
        /// Where the airframe came from.
        airframe: String,
        /// What is wrong (in the message only, as for `Airframe`).
        error: GainError,
    },
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    /// With its span, for an error at its line.
    airframe: toml::Spanned<String>,
    #[serde(default = "default_controller")]
    controller: ControllerKind,
    duration_s: f64,
    #[serde(default = "default_step")]
    step_s: f64,
    #[serde(default)]
    seed: u64,
    #[serde(default)]
    gains: GainOverrides,
    initial: Option<FileInitial>,
    #[serde(default)]
    noise: SensorNoise,
    #[serde(default)]
    world: Environment,
    #[serde(default)]
    wind: WindSettings,
    #[serde(default)]
    estimator: FileEstimator,
    reference: Option<Trajectory>,
    #[serde(default, rename = "setpoint")]
    setpoints: Vec<FileSetpoint>,
    #[serde(default, rename = "disturbance")]
    disturbances: Vec<FileDisturbance>,
    #[serde(default, rename = "switch")]
    switches: Vec<FileSwitch>,
    #[serde(default, rename = "fault")]
    faults: Vec<fault::FileFault>,
    #[serde(default)]
    navigation: FileNavigation,
}

/// A scenario's `[navigation]` table: the navigation solution flown on
/// (`source`, as `RP_NAV_SRC`) and the filter's height reference
/// (`height_ref`, as `EKF2_HGT_REF`). Absent: the ideal solution.
#[derive(Clone, Copy, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub(crate) struct FileNavigation {
    source: FileNavSource,
    height_ref: Option<FileHeightRef>,
}

#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
enum FileNavSource {
    #[default]
    Ideal,
    Filter,
}

#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
enum FileHeightRef {
    Baro,
    Gnss,
}

impl FileNavigation {
    /// Sets `RP_NAV_SRC` and `EKF2_HGT_REF` in `params` as the table says:
    /// the ideal solution when it names no source (unlike the daemon, which
    /// boots on the filter), `EKF2_HGT_REF` untouched when it names none.
    pub(crate) fn apply(self, params: &mut ParamStore) {
        use crate::params::ParamValue::Int32;
        let _ = params.set("RP_NAV_SRC", Int32(i32::from(self.source == FileNavSource::Filter)));
        if let Some(h) = self.height_ref {
            let _ = params.set("EKF2_HGT_REF", Int32(i32::from(h == FileHeightRef::Gnss)));
        }
    }
}

fn default_controller() -> ControllerKind {
    ControllerKind::Geometric
}

fn default_step() -> f64 {
    crate::signals::DEFAULT_STEP_S
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileInitial {
    position_ned: [f64; 3],
    #[serde(default)]
    velocity_ned: [f64; 3],
    #[serde(default)]
    euler_deg: [f64; 3],
    #[serde(default)]
    rate_frd_deg_s: [f64; 3],
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields, default)]
struct FileEstimator {
    order: usize,
    polynomial: Polynomial,
    cutoff_rad_s: f64,
    discretization: Discretization,
    feedback: bool,
}

impl Default for FileEstimator {
    fn default() -> Self {
        let c = EstimatorConfig::default();
        Self {
            order: c.order,
            polynomial: c.polynomial,
            cutoff_rad_s: c.cutoff_rad_s,
            discretization: c.discretization,
            feedback: false,
        }
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileSetpoint {
    at_s: f64,
    position_ned: Option<[f64; 3]>,
    velocity_ned: Option<[f64; 3]>,
    #[serde(default)]
    yaw_deg: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileDisturbance {
    at_s: f64,
    force_ned: Option<[f64; 3]>,
    torque_frd: Option<[f64; 3]>,
    true_mass_kg: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileSwitch {
    at_s: f64,
    controller: ControllerKind,
}

/// Where the reference comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum ReferencePlan {
    /// An analytic curve.
    Trajectory(Trajectory),
    /// Timed setpoints `(from time [s], setpoint)`, shaped.
    Setpoints(Vec<(f64, Setpoint)>),
}

/// Initial state given explicitly.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InitialState {
    /// Position [m], NED.
    pub position_ned: Vector3<f64>,
    /// Velocity [m/s], NED.
    pub velocity_ned: Vector3<f64>,
    /// ZYX Euler angles [rad].
    pub euler_rad: Vector3<f64>,
    /// Angular velocity [rad/s], FRD.
    pub rate_frd: Vector3<f64>,
}

/// A validated scenario.
#[derive(Clone, Debug)]
pub struct Scenario {
    /// The file it came from.
    pub source: String,
    /// The vehicle.
    pub airframe: Airframe,
    /// The initial law.
    pub controller: ControllerKind,
    /// Gains after the airframe's defaults and the scenario's overrides.
    pub gains: ControlGains,
    /// Duration [s].
    pub duration_s: f64,
    /// Integration step [s].
    pub step_s: f64,
    /// Noise seed.
    pub seed: u64,
    /// Sensor noise.
    pub noise: SensorNoise,
    /// Environment.
    pub world: Environment,
    /// The air (`[wind]`: mean wind, turbulence, gusts; calm by default).
    pub wind: WindSettings,
    /// Estimator.
    pub estimator: EstimatorConfig,
    /// Feed the estimate back.
    pub feedback: bool,
    /// Initial state; `None` = on the reference at t = 0 with its feedforward attitude.
    pub initial: Option<InitialState>,
    /// The reference.
    pub reference: ReferencePlan,
    /// Disturbance schedule, sorted by time.
    pub disturbances: Vec<DisturbanceChange>,
    /// Controller switches `(time [s], law)`, sorted.
    pub switches: Vec<(f64, ControllerKind)>,
    /// Failures injected, sorted by time.
    pub faults: Vec<ScheduledFault>,
    /// The navigation filter's settings when the control law flies on it
    /// (`[navigation] source = "filter"`); `None`: the ideal solution.
    pub navigation: Option<NavConfig>,
}

impl Scenario {
    /// Read and validate a scenario file; a relative airframe path is resolved
    /// against the scenario's directory.
    ///
    /// # Errors
    /// [`ScenarioError`] naming the file, the field and the problem.
    pub fn from_file(path: &std::path::Path) -> Result<Self, ScenarioError> {
        let text = tomlfile::read(path)?;
        Self::from_toml(&text, &path.display().to_string(), path.parent())
    }

    /// Parse and validate scenario TOML (`file` labels errors; `dir` resolves a relative airframe path).
    ///
    /// # Errors
    /// [`ScenarioError`] naming the file, the field and the problem.
    #[allow(clippy::too_many_lines)]
    pub fn from_toml(text: &str, file: &str, dir: Option<&std::path::Path>) -> Result<Self, ScenarioError> {
        let raw: File = tomlfile::parse(text, file)?;
        let fail = |field: &str, problem: String| ScenarioError::File(FileError::invalid(file, field, problem));
        let name = raw.airframe.get_ref();
        let airframe_spec = match dir {
            Some(d) if name.ends_with(".toml") && !std::path::Path::new(name).is_absolute() => {
                d.join(name).display().to_string()
            }
            _ => name.clone(),
        };
        let airframe = Airframe::load(&airframe_spec).map_err(|error| {
            let (line, column) = tomlfile::line_column(text, raw.airframe.span().start);
            ScenarioError::Airframe {
                file: file.to_string(),
                line,
                column,
                error,
            }
        })?;
        if !(raw.duration_s.is_finite() && raw.duration_s > 0.0 && raw.duration_s <= 86_400.0) {
            return Err(fail(
                "duration_s",
                format!("must be in (0, 86400] s, got {}", raw.duration_s),
            ));
        }
        if !(raw.step_s.is_finite() && raw.step_s >= 1e-5 && raw.step_s <= 0.01) {
            return Err(fail("step_s", format!("must be in [1e-5, 0.01] s, got {}", raw.step_s)));
        }
        let mut gains =
            ControlGains::for_airframe(&airframe, airframe.mass_kg).map_err(|error| ScenarioError::AirframeGains {
                file: file.to_string(),
                airframe: airframe.source.clone(),
                error,
            })?;
        gains.apply(&raw.gains);
        gains
            .validate()
            .map_err(|e| fail(&format!("gains.{}", e.field), format!("{} {}", e.value, e.problem)))?;
        let estimator = EstimatorConfig {
            order: raw.estimator.order,
            polynomial: raw.estimator.polynomial,
            cutoff_rad_s: raw.estimator.cutoff_rad_s,
            discretization: raw.estimator.discretization,
            sample_time_s: raw.step_s,
        };
        estimator.gains().map_err(|e| fail("estimator", e.to_string()))?;
        for (name, v) in [
            ("noise.position_m", raw.noise.position_m),
            ("noise.velocity_m_s", raw.noise.velocity_m_s),
            ("noise.attitude_rad", raw.noise.attitude_rad),
            ("noise.rate_rad_s", raw.noise.rate_rad_s),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(fail(name, format!("must be finite and >= 0, got {v}")));
            }
        }
        raw.wind.validate().map_err(|(f, p)| fail(&format!("wind.{f}"), p))?;
        if let Some(zc) = raw.world.ceiling_z_ned
            && !(zc.is_finite() && zc < raw.world.ground_z_ned)
        {
            return Err(fail(
                "world.ceiling_z_ned",
                format!("must be above the ground (smaller NED z), got {zc}"),
            ));
        }
        let finite3 = |field: &str, v: [f64; 3]| {
            if v.iter().all(|x| x.is_finite()) {
                Ok(Vector3::from(v))
            } else {
                Err(fail(field, format!("must be finite, got {v:?}")))
            }
        };
        let initial = match raw.initial {
            None => None,
            Some(i) => Some(InitialState {
                position_ned: finite3("initial.position_ned", i.position_ned)?,
                velocity_ned: finite3("initial.velocity_ned", i.velocity_ned)?,
                euler_rad: finite3("initial.euler_deg", i.euler_deg)?.map(f64::to_radians),
                rate_frd: finite3("initial.rate_frd_deg_s", i.rate_frd_deg_s)?.map(f64::to_radians),
            }),
        };
        let reference = match (raw.reference, raw.setpoints.is_empty()) {
            (Some(_), false) => {
                return Err(fail(
                    "reference",
                    "give either [reference] or [[setpoint]], not both".into(),
                ));
            }
            (None, true) => {
                return Err(fail(
                    "reference",
                    "missing: give [reference] or at least one [[setpoint]]".into(),
                ));
            }
            (Some(t), true) => {
                t.validate().map_err(|(f, p)| fail(&format!("reference.{f}"), p))?;
                ReferencePlan::Trajectory(t)
            }
            (None, false) => {
                let mut list = Vec::new();
                for (i, s) in raw.setpoints.iter().enumerate() {
                    let at = |f: &str| format!("setpoint[{}].{f}", i + 1);
                    check_time(&at("at_s"), s.at_s, raw.duration_s).map_err(|p| fail(&at("at_s"), p))?;
                    if !s.yaw_deg.is_finite() {
                        return Err(fail(&at("yaw_deg"), format!("must be finite, got {}", s.yaw_deg)));
                    }
                    let yaw = s.yaw_deg.to_radians();
                    let sp = match (s.position_ned, s.velocity_ned) {
                        (Some(p), None) => Setpoint::position(finite3(&at("position_ned"), p)?, yaw),
                        (None, Some(v)) => Setpoint::velocity(finite3(&at("velocity_ned"), v)?, yaw),
                        _ => {
                            return Err(fail(
                                &at("position_ned"),
                                "give exactly one of position_ned, velocity_ned".into(),
                            ));
                        }
                    };
                    list.push((s.at_s, sp));
                }
                list.sort_by(|a, b| a.0.total_cmp(&b.0));
                ReferencePlan::Setpoints(list)
            }
        };
        let mut disturbances = Vec::new();
        for (i, d) in raw.disturbances.iter().enumerate() {
            let at = |f: &str| format!("disturbance[{}].{f}", i + 1);
            check_time(&at("at_s"), d.at_s, raw.duration_s).map_err(|p| fail(&at("at_s"), p))?;
            if let Some(m) = d.true_mass_kg
                && !(m.is_finite() && m > 0.0)
            {
                return Err(fail(&at("true_mass_kg"), format!("must be finite and > 0, got {m}")));
            }
            disturbances.push(DisturbanceChange {
                at_s: d.at_s,
                force_ned: d.force_ned.map(|v| finite3(&at("force_ned"), v)).transpose()?,
                torque_frd: d.torque_frd.map(|v| finite3(&at("torque_frd"), v)).transpose()?,
                true_mass_kg: d.true_mass_kg,
            });
        }
        disturbances.sort_by(|a, b| a.at_s.total_cmp(&b.at_s));
        let mut switches = Vec::new();
        for (i, s) in raw.switches.iter().enumerate() {
            let field = format!("switch[{}].at_s", i + 1);
            check_time(&field, s.at_s, raw.duration_s).map_err(|p| fail(&field, p))?;
            switches.push((s.at_s, s.controller));
        }
        switches.sort_by(|a, b| a.0.total_cmp(&b.0));
        let faults = fault::validate(&raw.faults, raw.duration_s, &airframe).map_err(|(f, p)| fail(&f, p))?;
        let mut params = ParamStore::new(&airframe);
        raw.navigation.apply(&mut params);
        let navigation = (NavSource::from_params(&params) == NavSource::Filter).then(|| nav_config(&params));
        Ok(Self {
            source: file.to_string(),
            airframe,
            controller: raw.controller,
            gains,
            duration_s: raw.duration_s,
            step_s: raw.step_s,
            seed: raw.seed,
            noise: raw.noise,
            world: raw.world,
            wind: raw.wind,
            estimator,
            feedback: raw.estimator.feedback,
            initial,
            reference,
            disturbances,
            switches,
            faults,
            navigation,
        })
    }
}

fn check_time(_field: &str, t: f64, duration: f64) -> Result<(), String> {
    if t.is_finite() && t >= 0.0 && t <= duration {
        Ok(())
    } else {
        Err(format!("must be within [0, duration_s = {duration}] s, got {t}"))
    }
}
