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

use std::marker::PhantomData;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use tokio::sync::{Notify, broadcast, watch};
use tracing::{debug, info, warn};

use super::messages::{Event, lock};
use crate::autopilot::{Severity, StatusText, status_text_lines};
use crate::lockstep::Snapshot;
use crate::mission::Plans;
use crate::mission::file::{MissionFileError, save_plans};
use crate::params::ParamFileError;
use crate::params::ParamStore;

/// A vehicle's parameter file at start ([`ParamStore::load_keeping_bad`]):
/// a file with lines that do not read, or an empty one, is renamed aside to
/// `params.bad-<unix time>` (the warning names it) and the store holds its
/// valid lines; the start's save then writes a clean file.
pub(super) fn load_params(
    airframe: &crate::airframe::Airframe,
    path: &Path,
) -> Result<(ParamStore, Vec<String>), ParamFileError> {
    let unix_s = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    let loaded = ParamStore::load_keeping_bad(airframe, path, unix_s)?;
    if let Some(aside) = &loaded.set_aside {
        warn!(path = %path.display(), kept = %aside.display(), "parameter file set aside");
    }
    Ok((loaded.store, loaded.warnings))
}

/// The warnings of [`load_params`] told to the clients at start
/// (STATUSTEXT critical): the one saying where a damaged file went.
pub(super) fn announce_params_warnings(warnings: &[String], events: &broadcast::Sender<Event>) {
    for w in warnings.iter().filter(|w| w.contains(".bad-")) {
        announce(events, Severity::Critical, &format!("Parameter file set aside: {w}"));
    }
}

/// The first wait before a failed save is tried again; each further failure
/// doubles it, up to [`RETRY_MAX`].
pub(super) const RETRY_FIRST: Duration = Duration::from_secs(1);
/// The longest wait between two tries of a failed save.
pub(super) const RETRY_MAX: Duration = Duration::from_secs(30);

/// The wait after `failures` failed tries in a row (>= 1): `RETRY_FIRST *
/// 2^(failures - 1)`, at most [`RETRY_MAX`].
pub(super) fn backoff(failures: u32) -> Duration {
    let doublings = failures.saturating_sub(1).min(16);
    (RETRY_FIRST * 2u32.pow(doublings)).min(RETRY_MAX)
}

/// Tell every link's clients `text` (split into STATUSTEXT lines).
pub(super) fn announce(events: &broadcast::Sender<Event>, severity: Severity, text: &str) {
    for line in status_text_lines(text) {
        let _ = events.send(Event::StatusText(StatusText {
            severity,
            text: line.to_string(),
        }));
    }
}

/// Keep one state file saved: write it with `write` (blocking: on the
/// blocking pool) whenever notified, coalescing bursts, until `stop`
/// changes. A failed write is reported to every client (STATUSTEXT
/// critical, and the log) and tried again after [`backoff`] until it
/// succeeds (a new notification tries at once); the success after failures
/// is announced. Reports: the first failure, then every tenth.
pub(super) async fn keep_saved<F>(
    what: &'static str,
    write: F,
    save: Arc<Notify>,
    events: broadcast::Sender<Event>,
    mut stop: watch::Receiver<bool>,
) where
    F: Fn() -> Result<(), String> + Clone + Send + 'static,
{
    let mut failures: u32 = 0;
    loop {
        let retry = if failures == 0 { None } else { Some(backoff(failures)) };
        tokio::select! {
            () = save.notified() => {}
            () = async {
                match retry {
                    Some(d) => tokio::time::sleep(d).await,
                    None => std::future::pending().await,
                }
            } => {}
            _ = stop.changed() => return,
        }
        let w = write.clone();
        let result = match tokio::task::spawn_blocking(w).await {
            Ok(r) => r,
            Err(e) => Err(format!("the writer failed: {e}")),
        };
        match result {
            Ok(()) => {
                if failures > 0 {
                    info!(what, failures, "saved after failed tries");
                    announce(
                        &events,
                        Severity::Info,
                        &format!("{what} saved after {failures} failed tries"),
                    );
                }
                debug!(what, "saved");
                failures = 0;
            }
            Err(e) => {
                failures += 1;
                warn!(what, error = %e, failures, retry_s = backoff(failures).as_secs_f64(), "cannot save; will retry");
                if failures == 1 || failures.is_multiple_of(10) {
                    announce(
                        &events,
                        Severity::Critical,
                        &format!("{what} not saved (retrying): {e}"),
                    );
                }
            }
        }
    }
}

/// One state file and its single writer: every write (the savers', a link's
/// write-through, the one at shutdown) holds the lock while it takes its
/// snapshot and writes it, so writes never share the temporary file, the
/// last write holds the latest state, and once the final write at shutdown
/// is made no late write can put older state over it. `K` says which file
/// ([`ParamsFile`], [`PlansFile`]) and so what it saves.
#[derive(Clone, Debug)]
pub(super) struct StateFile<K> {
    path: PathBuf,
    /// Held while writing; true once the final write is done.
    finished: Arc<Mutex<bool>>,
    kind: PhantomData<K>,
}

/// The parameter file's kind ([`ParamsFile`]).
#[derive(Clone, Copy, Debug)]
pub(super) struct Parameters;

/// The plans file's kind ([`PlansFile`]).
#[derive(Clone, Copy, Debug)]
pub(super) struct StoredPlans;

/// The parameter file (`params.toml`).
pub(super) type ParamsFile = StateFile<Parameters>;

/// The plans file (`missions.json`).
pub(super) type PlansFile = StateFile<StoredPlans>;

impl<K> StateFile<K> {
    pub(super) fn new(path: PathBuf) -> Self {
        Self {
            path,
            finished: Arc::new(Mutex::new(false)),
            kind: PhantomData,
        }
    }

    pub(super) fn path(&self) -> &Path {
        &self.path
    }

    /// Run `write` (blocking: the file system) under the lock, unless the
    /// final write was made (then nothing is written).
    fn write<E>(&self, write: impl FnOnce(&Path) -> Result<(), E>) -> Result<(), E> {
        let finished = self.finished.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        if *finished {
            return Ok(());
        }
        write(&self.path)
    }

    /// The last write, at shutdown; later writes do nothing.
    fn write_final<E>(&self, write: impl FnOnce(&Path) -> Result<(), E>) -> Result<(), E> {
        let mut finished = self.finished.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        *finished = true;
        write(&self.path)
    }
}

impl ParamsFile {
    /// Write the parameters in force (blocking), the snapshot taken under the file's lock.
    pub(super) fn save(&self, params: &Mutex<ParamStore>) -> Result<(), ParamFileError> {
        self.write(|p| lock(params).clone().save(p))
    }

    /// The last write, at shutdown.
    pub(super) fn save_final(&self, params: &Mutex<ParamStore>) -> Result<(), ParamFileError> {
        self.write_final(|p| lock(params).clone().save(p))
    }
}

impl PlansFile {
    /// Write `plans` (blocking: the file system), unless the final write was made.
    #[cfg(test)]
    pub(super) fn save(&self, plans: &Plans) -> Result<(), MissionFileError> {
        self.write(|p| save_plans(p, plans))
    }

    /// Write the plans of the latest snapshot, taken under the file's lock.
    pub(super) fn save_latest(&self, tel: &watch::Receiver<Snapshot>) -> Result<(), MissionFileError> {
        self.write(|p| {
            // shared items: a cheap clone, the lock of the watch released at once
            let plans = tel.borrow().plans.clone();
            save_plans(p, &plans)
        })
    }

    /// The last write, at shutdown; later [`Self::save`] calls do nothing.
    pub(super) fn save_final(&self, plans: &Plans) -> Result<(), MissionFileError> {
        self.write_final(|p| save_plans(p, plans))
    }
}

/// Writes the parameter file whenever notified ([`keep_saved`]) until `stop` changes.
pub(super) async fn saver(
    params: Arc<Mutex<ParamStore>>,
    file: ParamsFile,
    save: Arc<Notify>,
    events: broadcast::Sender<Event>,
    stop: watch::Receiver<bool>,
) {
    let write = move || file.save(&params).map_err(|e| e.to_string());
    keep_saved("Parameters", write, save, events, stop).await;
}

/// Writes the plans file whenever notified ([`keep_saved`]), from the
/// latest snapshot, until `stop` changes.
pub(super) async fn plan_saver(
    tel: watch::Receiver<Snapshot>,
    file: PlansFile,
    changed: Arc<Notify>,
    events: broadcast::Sender<Event>,
    stop: watch::Receiver<bool>,
) {
    let write = move || file.save_latest(&tel).map_err(|e| e.to_string());
    keep_saved("Mission/fence/rally", write, changed, events, stop).await;
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use super::*;
    use crate::lockstep::test_quad;
    use crate::mission::file::load_plans;
    use crate::mission::{MissionItem, MissionType, PlanChange, cmd};
    use crate::statefile::scratch_dir as scratch;

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
        let dir = scratch("plan-saver");
        let file = PlansFile::new(dir.join("missions.json"));
        let (mut core, _) = test_quad();
        let (tel_tx, tel_rx) = watch::channel(core.snapshot(0));
        let (stop_tx, stop_rx) = watch::channel(false);
        let changed = Arc::new(Notify::new());
        let (ev_tx, _) = broadcast::channel(16);
        let task = tokio::spawn(plan_saver(tel_rx, file.clone(), changed.clone(), ev_tx, stop_rx));
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

    #[test]
    fn the_backoff_doubles_from_one_second_to_thirty() {
        let s: Vec<u64> = (1..=7).map(|f| backoff(f).as_secs()).collect();
        assert_eq!(s, vec![1, 2, 4, 8, 16, 30, 30]);
        assert_eq!(backoff(u32::MAX), RETRY_MAX);
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_failing_save_is_reported_retried_and_its_success_announced() {
        use std::sync::atomic::{AtomicU32, Ordering};
        let tries = Arc::new(AtomicU32::new(0));
        let t = tries.clone();
        // fails twice, then works
        let write = move || {
            if t.fetch_add(1, Ordering::SeqCst) < 2 {
                Err("/state/params.toml: No space left on device (os error 28)".to_string())
            } else {
                Ok(())
            }
        };
        let (ev_tx, mut ev_rx) = broadcast::channel(64);
        let (stop_tx, stop_rx) = watch::channel(false);
        let save = Arc::new(Notify::new());
        save.notify_one();
        let task = tokio::spawn(keep_saved("Parameters", write, save, ev_tx, stop_rx));
        let mut said = Vec::new();
        let deadline = tokio::time::Instant::now() + Duration::from_secs(6);
        while !said.iter().any(|(_, t): &(Severity, String)| t.contains("saved after")) {
            match tokio::time::timeout_at(deadline, ev_rx.recv()).await {
                Ok(Ok(Event::StatusText(s))) => said.push((s.severity, s.text)),
                Ok(_) => {}
                Err(_) => panic!("no success announced: {said:?}"),
            }
        }
        assert_eq!(tries.load(Ordering::SeqCst), 3, "the first try and two retries");
        assert_eq!(said[0].0, Severity::Critical);
        assert!(said[0].1.starts_with("Parameters not saved"), "{said:?}");
        assert!(said.iter().any(|(_, t)| t.contains("No space left")), "{said:?}");
        // the first failure is reported, not the second (every tenth is)
        assert_eq!(
            said.iter()
                .filter(|(_, t)| t.starts_with("Parameters not saved"))
                .count(),
            1
        );
        assert_eq!(
            said.last().unwrap(),
            &(Severity::Info, "Parameters saved after 2 failed tries".to_string())
        );
        let _ = stop_tx.send(true);
        tokio::time::timeout(Duration::from_secs(2), task)
            .await
            .unwrap()
            .unwrap();
    }
}
