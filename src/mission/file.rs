//! Mission files: QGroundControl `.plan`, QGC WPL 110 text, and the
//! state-dir file the vehicle keeps its plans in. (Placeholder until the
//! mission-files work lands: only the shape.)

use std::path::Path;

use super::MissionItem;

/// The three plans a mission file holds, as a client would upload them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PlanFile {
    /// Mission items.
    pub mission: Vec<MissionItem>,
    /// Geofence items.
    pub fence: Vec<MissionItem>,
    /// Rally points.
    pub rally: Vec<MissionItem>,
}

/// Load a `.plan` or WPL file.
///
/// # Errors
/// Not yet readable.
pub fn load_mission_file(path: &Path) -> anyhow::Result<PlanFile> {
    anyhow::bail!("{}: mission files are not readable yet", path.display())
}
