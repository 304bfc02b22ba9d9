//! Parameter saving: the parameter file is written (atomically) after each
//! accepted set, off the link tasks and the simulation thread, bursts
//! coalesced; once at start (so the state directory shows the parameters in
//! force) and once more at shutdown by the daemon itself.

use std::path::PathBuf;
use std::sync::{Arc, Mutex, MutexGuard};

use tokio::sync::{Notify, watch};
use tracing::{debug, warn};

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
