//! Mission files: QGroundControl `.plan`, QGC WPL 110 text, and the
//! state-dir file the vehicle keeps its plans in. (Filled by the mission-files work.)
