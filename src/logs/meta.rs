//! The sidecar `<csv>.meta.json` of a flight CSV: what produced it
//! (airframe, nominal model, step, estimator settings), written next to the
//! CSV by every producer, so the CSV itself carries no header comment and
//! the shipped logs stay byte for byte.

use serde::{Deserialize, Serialize};

use crate::autopilot::Autopilot;
use crate::estimation::EstimatorConfig;
use crate::signals::NominalModel;

/// What produced a flight CSV: its sidecar `<csv>.meta.json`
/// ([`meta_path`]), one JSON object written next to the CSV by every
/// producer (`simulate --csv`, the daemon's `--log-csv`, `replay --csv`):
///
/// ```text
/// { "format": "rotorpilot-flight-csv-meta", "version": 1,
///   "producer": "rotorpilot 0.1.0 simulate", "source": "tools/scenarios/quad-step-10m.toml",
///   "airframe": "quad", "nominal_mass_kg": 2.0,
///   "nominal_inertia_kg_m2": [[Ixx, Ixy, Ixz], [Iyx, Iyy, Iyz], [Izx, Izy, Izz]],   (body FRD)
///   "step_s": 0.001,
///   "estimator": { "order": 3, "polynomial": "butterworth", "cutoff_rad_s": 10.0,
///                  "discretization": "trapezoidal", "sample_time_s": 0.001 } }
/// ```
///
/// The nominal model is the one the flight's estimator used (`MDL_MASS` for
/// the daemon), at the start of the flight.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LogMeta {
    /// Always [`META_FORMAT`].
    pub format: String,
    /// [`META_VERSION`].
    pub version: u32,
    /// The program and command that wrote the CSV (`rotorpilot 0.1.0 simulate`).
    pub producer: String,
    /// What was flown: the scenario or mission file, or the daemon's run.
    pub source: String,
    /// The airframe's name (`quad`, ...; a file's own name for a TOML airframe).
    pub airframe: String,
    /// The estimator's nominal mass [kg].
    pub nominal_mass_kg: f64,
    /// The estimator's nominal inertia [kg m^2], body FRD, rows.
    pub nominal_inertia_kg_m2: [[f64; 3]; 3],
    /// The simulation step [s] (the interval between rows).
    pub step_s: f64,
    /// The flight's own estimator settings.
    pub estimator: EstimatorConfig,
}

/// [`LogMeta::format`].
pub const META_FORMAT: &str = "rotorpilot-flight-csv-meta";
/// [`LogMeta::version`].
pub const META_VERSION: u32 = 1;

impl LogMeta {
    /// The sidecar of a log written by `producer` (e.g. `simulate`) from `source`.
    #[must_use]
    pub fn new(
        producer: &str,
        source: &str,
        airframe: &str,
        nominal: &NominalModel,
        estimator: &EstimatorConfig,
        step_s: f64,
    ) -> Self {
        let i = &nominal.inertia_kg_m2;
        Self {
            format: META_FORMAT.into(),
            version: META_VERSION,
            producer: format!("rotorpilot {} {producer}", env!("CARGO_PKG_VERSION")),
            source: source.into(),
            airframe: airframe.into(),
            nominal_mass_kg: nominal.mass_kg,
            nominal_inertia_kg_m2: std::array::from_fn(|r| std::array::from_fn(|c| i[(r, c)])),
            step_s,
            estimator: estimator.clone(),
        }
    }

    /// The nominal model it records.
    #[must_use]
    pub fn nominal(&self) -> NominalModel {
        let i = &self.nominal_inertia_kg_m2;
        NominalModel {
            mass_kg: self.nominal_mass_kg,
            inertia_kg_m2: nalgebra::Matrix3::from_fn(|r, c| i[r][c]),
        }
    }

    /// Write it as the sidecar of the CSV at `csv` ([`meta_path`]).
    ///
    /// # Errors
    /// A file that cannot be written (the message names it).
    pub fn write_beside(&self, csv: &std::path::Path) -> Result<(), String> {
        let path = meta_path(csv);
        let text = serde_json::to_string_pretty(self).map_err(|e| e.to_string())? + "\n";
        std::fs::write(&path, text).map_err(|e| format!("cannot write {}: {e}", path.display()))
    }

    /// Read the sidecar of the CSV at `csv`: `Ok(None)` when there is none.
    ///
    /// # Errors
    /// A sidecar that cannot be read or is not a valid [`LogMeta`] (the
    /// message names the file, the line and the field).
    pub fn read_beside(csv: &std::path::Path) -> Result<Option<Self>, String> {
        let path = meta_path(csv);
        let text = match std::fs::read_to_string(&path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(format!("{}: cannot read: {e}", path.display())),
        };
        let meta: Self = serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))?;
        if meta.format != META_FORMAT || meta.version != META_VERSION {
            return Err(format!(
                "{}: format `{}` version {}, this rotorpilot reads `{META_FORMAT}` version {META_VERSION}",
                path.display(),
                meta.format,
                meta.version
            ));
        }
        crate::estimation::MomentumEstimator::new(meta.estimator.clone(), meta.nominal())
            .map_err(|e| format!("{}: {e}", path.display()))?;
        Ok(Some(meta))
    }
}

/// The sidecar's path: the CSV's path with `.meta.json` appended
/// (`flight.csv` -> `flight.csv.meta.json`).
#[must_use]
pub fn meta_path(csv: &std::path::Path) -> std::path::PathBuf {
    let mut name = csv.as_os_str().to_owned();
    name.push(".meta.json");
    std::path::PathBuf::from(name)
}

/// The sidecar ([`LogMeta`]) of the flight CSV of `ap`'s vehicle, as it
/// flies now, written by `producer` from `source`.
#[must_use]
pub fn autopilot_meta(ap: &Autopilot, producer: &str, source: &str) -> LogMeta {
    let est = ap.estimator();
    LogMeta::new(
        producer,
        source,
        &ap.airframe().name,
        est.nominal(),
        est.config(),
        ap.dt_s(),
    )
}
