//! Saving the state directory off the link tasks and the simulation thread,
//! bursts coalesced (a [`Notify`] holds one permit however often it is
//! notified while a write runs):
//!
//! - the parameter file after each accepted set;
//! - the stored plans (`missions.json`) after each accepted plan change,
//!   from the latest [`Snapshot`] the simulation thread published (it
//!   publishes before it notifies, so the change is in it).
//!
//! Both are written once at start (so the state directory shows what is in
//! force, and a `--reset-*` run replaces the old file) and once more at
//! shutdown by the daemon itself. Writes are atomic (`crate::statefile`).

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, MutexGuard};

use tokio::sync::{Notify, watch};
use tracing::{debug, warn};

use crate::lockstep::Snapshot;
use crate::mission::Plans;
use crate::mission::file::{MissionFileError, save_plans};
use crate::params::ParamStore;

/// The parameter store, locked (never across an `.await`).
pub(super) fn lock(p: &Mutex<ParamStore>) -> MutexGuard<'_, ParamStore> {
    // A panic while holding the lock leaves the store consistent (every
    // mutation is a single checked set), so a poisoned lock is still usable.
    p.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Writes the parameter file whenever notified (coalescing bursts) until `stop` changes.
pub(super) async fn saver(
    params: Arc<Mutex<ParamStore>>,
    path: PathBuf,
    save: Arc<Notify>,
    mut stop: watch::Receiver<bool>,
) {
    loop {
        tokio::select! {
            () = save.notified() => {}
            _ = stop.changed() => return,
        }
        let snapshot = lock(&params).clone();
        let p = path.clone();
        match tokio::task::spawn_blocking(move || snapshot.save(&p)).await {
            Ok(Ok(())) => debug!(path = %path.display(), "parameters saved"),
            Ok(Err(e)) => warn!(error = %e, "cannot save parameters"),
            Err(e) => warn!(error = %e, "parameter saver failed"),
        }
    }
}

/// The plans file, and the lock that keeps two writes of it (the saver's and
/// the one at shutdown) from sharing its temporary file; it also remembers
/// that the final write was made, so a saver write that was late (a task
/// that did not stop in time) cannot put older plans over it.
#[derive(Clone, Debug)]
pub(super) struct PlansFile {
    path: PathBuf,
    /// Held while writing; true once the final write is done.
    finished: Arc<Mutex<bool>>,
}

impl PlansFile {
    pub(super) fn new(path: PathBuf) -> Self {
        Self {
            path,
            finished: Arc::new(Mutex::new(false)),
        }
    }

    pub(super) fn path(&self) -> &Path {
        &self.path
    }

    /// Write `plans` (blocking: the file system), unless the final write was made.
    pub(super) fn save(&self, plans: &Plans) -> Result<(), MissionFileError> {
        let finished = self.finished.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        if *finished {
            return Ok(());
        }
        save_plans(&self.path, plans)
    }

    /// The last write, at shutdown; later [`Self::save`] calls do nothing.
    pub(super) fn save_final(&self, plans: &Plans) -> Result<(), MissionFileError> {
        let mut finished = self.finished.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        *finished = true;
        save_plans(&self.path, plans)
    }
}

/// Writes the plans file whenever notified (coalescing bursts), from the
/// latest snapshot, until `stop` changes.
pub(super) async fn plan_saver(
    tel: watch::Receiver<Snapshot>,
    file: PlansFile,
    changed: Arc<Notify>,
    mut stop: watch::Receiver<bool>,
) {
    loop {
        tokio::select! {
            () = changed.notified() => {}
            _ = stop.changed() => return,
        }
        // shared items: a cheap clone, the lock of the watch released at once
        let plans = tel.borrow().plans.clone();
        let f = file.clone();
        match tokio::task::spawn_blocking(move || f.save(&plans)).await {
            Ok(Ok(())) => debug!(path = %file.path().display(), "plans saved"),
            Ok(Err(e)) => warn!(error = %e, "cannot save the plans"),
            Err(e) => warn!(error = %e, "plan saver failed"),
        }
    }
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use super::*;
    use crate::airframe::Airframe;
    use crate::geo::GeoPoint;
    use crate::lockstep::Lockstep;
    use crate::mission::file::load_plans;
    use crate::mission::{MissionItem, MissionType, PlanChange, cmd};
    use crate::sim::SensorConfig;

    fn waypoint(z: f32) -> MissionItem {
        MissionItem {
            frame: 3,
            command: cmd::NAV_WAYPOINT,
            autocontinue: true,
            params: [0.0, 1.0, 0.0, f32::NAN],
            x: 47.398,
            y: 8.5456,
            z,
        }
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_burst_of_plan_changes_ends_with_the_last_plans_on_disk() {
        let dir = std::env::temp_dir().join(format!("rotorpilot-plan-saver-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let file = PlansFile::new(dir.join("missions.json"));
        let airframe = Airframe::load("quad").unwrap();
        let params = ParamStore::new(&airframe);
        let mut core =
            Lockstep::one_vehicle(&airframe, GeoPoint::PX4_SITL_HOME, &params, SensorConfig::default()).unwrap();
        let (tel_tx, tel_rx) = watch::channel(core.snapshot(0));
        let (stop_tx, stop_rx) = watch::channel(false);
        let changed = Arc::new(Notify::new());
        let task = tokio::spawn(plan_saver(tel_rx, file.clone(), changed.clone(), stop_rx));
        // as the simulation thread does it: change, publish, notify
        for k in 0..20 {
            let items = (0..=k).map(|i| waypoint(10.0 + i as f32)).collect();
            core.change_plans(
                0,
                PlanChange::Store {
                    kind: MissionType::Mission,
                    items,
                    base_id: None,
                },
            )
            .unwrap();
            tel_tx.send_replace(core.snapshot(0));
            changed.notify_one();
        }
        let want = core.pilot(0).plans().get(MissionType::Mission).id();
        let mut on_disk = 0;
        for _ in 0..200 {
            tokio::time::sleep(Duration::from_millis(10)).await;
            on_disk = load_plans(file.path()).map_or(0, |p| p.get(MissionType::Mission).id());
            if on_disk == want {
                break;
            }
        }
        assert_eq!(on_disk, want, "the latest mission is saved");
        assert_eq!(load_plans(file.path()).unwrap().get(MissionType::Mission).len(), 20);
        let _ = stop_tx.send(true);
        tokio::time::timeout(Duration::from_secs(2), task)
            .await
            .unwrap()
            .unwrap();
        // after the final write, a late save changes nothing
        file.save_final(&Plans::default()).unwrap();
        file.save(core.pilot(0).plans()).unwrap();
        assert_eq!(load_plans(file.path()).unwrap(), Plans::default());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
