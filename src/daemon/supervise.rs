//! The link tasks, watched: a link task that ends while the daemon runs
//! (a panic, or a return it should not make) is a fault the daemon must not
//! hide — [`LinkTasks::ended`] names the link and how it ended, and the
//! daemon stops with that message (exit status non-zero) rather than run on
//! deaf on that link. (Restarting it is not done: its socket and protocol
//! state went with it.)

use std::collections::HashMap;
use std::future::Future;

use tokio::task::{Id, JoinError, JoinSet};

/// The running link tasks, by name.
#[derive(Debug, Default)]
pub(super) struct LinkTasks {
    set: JoinSet<()>,
    names: HashMap<Id, String>,
}

impl LinkTasks {
    /// Start `task`, named `name` in messages ("gcs link", "vehicle instance 2: api link").
    pub(super) fn spawn(&mut self, name: String, task: impl Future<Output = ()> + Send + 'static) {
        let handle = self.set.spawn(task);
        self.names.insert(handle.id(), name);
    }

    /// Waits for the first link task to end and says which and how
    /// ("gcs link task panicked: ..."); never resolves while none has.
    pub(super) async fn ended(&mut self) -> String {
        match self.set.join_next_with_id().await {
            Some(Ok((id, ()))) => format!("{} task stopped unexpectedly", self.name(id)),
            Some(Err(e)) => self.failure(&e),
            None => std::future::pending().await,
        }
    }

    fn name(&self, id: Id) -> &str {
        self.names.get(&id).map_or("a link", String::as_str)
    }

    fn failure(&self, e: &JoinError) -> String {
        let name = self.name(e.id());
        if e.is_panic() {
            format!("{name} task panicked: {e}")
        } else {
            format!("{name} task was cancelled")
        }
    }

    /// Wait for every link task to end (they were told to stop).
    pub(super) async fn join_all(mut self) {
        while self.set.join_next().await.is_some() {}
    }
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use super::*;

    #[tokio::test]
    async fn a_link_task_that_panics_is_named_and_the_others_keep_running() {
        let mut links = LinkTasks::default();
        let (tx, rx) = tokio::sync::oneshot::channel::<()>();
        links.spawn("gcs link".into(), async move {
            let _ = rx.await;
        });
        links.spawn("vehicle instance 2: api link".into(), async {
            tokio::time::sleep(Duration::from_millis(20)).await;
            panic!("injected");
        });
        let why = tokio::time::timeout(Duration::from_secs(2), links.ended())
            .await
            .expect("noticed");
        assert!(why.starts_with("vehicle instance 2: api link task panicked"), "{why}");
        // none else has ended: no second report
        assert!(
            tokio::time::timeout(Duration::from_millis(50), links.ended())
                .await
                .is_err()
        );
        let _ = tx.send(());
        let why = links.ended().await;
        assert_eq!(why, "gcs link task stopped unexpectedly");
        tokio::time::timeout(Duration::from_secs(1), links.join_all())
            .await
            .unwrap();
    }
}
