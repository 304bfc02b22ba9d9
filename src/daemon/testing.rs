//! Helpers of the daemon's unit tests: a fresh scratch directory and a lone
//! quad's lockstep core at PX4's SITL home.

use std::path::PathBuf;

use crate::airframe::Airframe;
use crate::autopilot::Autopilot;
use crate::geo::GeoPoint;
use crate::lockstep::Lockstep;
use crate::params::ParamStore;
use crate::sim::SensorConfig;

/// `rotorpilot-NAME-PID` under the system temp dir, emptied and created.
pub(super) fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("rotorpilot-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A quad's default parameters and its one-vehicle core at PX4's SITL home.
pub(super) fn quad() -> (ParamStore, Lockstep<Autopilot>) {
    let airframe = Airframe::load("quad").unwrap();
    let params = ParamStore::new(&airframe);
    let core = Lockstep::one_vehicle(&airframe, GeoPoint::PX4_SITL_HOME, &params, SensorConfig::default()).unwrap();
    (params, core)
}
