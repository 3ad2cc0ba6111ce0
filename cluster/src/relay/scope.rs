//! The watchers coming and going, as a wake-up for the forwarder: a watcher joining (its
//! node's membership reaching this node) or leaving (its session closing) is looked at as
//! it happens. Were it looked at only when this node publishes, a node that publishes
//! nothing for a while would meet a watcher for the first time after a freeze — and take it
//! for a newcomer, not due what it missed.

use super::{GROUP, SCOPE};
use ractor::pg::{self, GroupChangeMessage};
use ractor::{Actor, ActorProcessingErr, ActorRef, SpawnErr, SupervisionEvent};
use tokio::sync::mpsc;

/// Changes of the watchers' group, coalesced: one wake-up stands for every change since the
/// last was taken. Dropping it stops the watch.
pub(super) struct Changes {
    rx: mpsc::Receiver<()>,
    actor: ActorRef<ChangesMsg>,
}

impl Changes {
    /// Watch the group from now on.
    pub(super) async fn watch() -> Result<Changes, SpawnErr> {
        let (tx, rx) = mpsc::channel(1);
        let (actor, _) = Actor::spawn(None, Watcher, tx).await?;
        Ok(Changes { rx, actor })
    }

    /// The next change (pending forever once the watch is gone).
    pub(super) async fn next(&mut self) {
        if self.rx.recv().await.is_none() {
            std::future::pending::<()>().await;
        }
    }
}

impl Drop for Changes {
    fn drop(&mut self) {
        self.actor.stop(None);
    }
}

/// The watch takes no messages; it only receives `pg` events.
pub(super) enum ChangesMsg {}
impl ractor::Message for ChangesMsg {}

struct Watcher;

impl Actor for Watcher {
    type Msg = ChangesMsg;
    type State = mpsc::Sender<()>;
    type Arguments = mpsc::Sender<()>;

    async fn pre_start(
        &self,
        myself: ActorRef<ChangesMsg>,
        tx: mpsc::Sender<()>,
    ) -> Result<mpsc::Sender<()>, ActorProcessingErr> {
        pg::monitor_scope(SCOPE.to_string(), myself.get_cell());
        Ok(tx)
    }

    async fn post_stop(
        &self,
        myself: ActorRef<ChangesMsg>,
        _tx: &mut mpsc::Sender<()>,
    ) -> Result<(), ActorProcessingErr> {
        pg::demonitor_scope(SCOPE.to_string(), myself.get_id());
        Ok(())
    }

    async fn handle_supervisor_evt(
        &self,
        myself: ActorRef<ChangesMsg>,
        evt: SupervisionEvent,
        tx: &mut mpsc::Sender<()>,
    ) -> Result<(), ActorProcessingErr> {
        let SupervisionEvent::ProcessGroupChanged(change) = evt else {
            return Ok(());
        };
        let group = match &change {
            GroupChangeMessage::Join(_, group, _) | GroupChangeMessage::Leave(_, group, _) => group,
        };
        if group != GROUP {
            return Ok(());
        }
        match tx.try_send(()) {
            // full: a wake-up is already waiting, and it stands for this change too
            Ok(()) | Err(mpsc::error::TrySendError::Full(())) => {}
            Err(mpsc::error::TrySendError::Closed(())) => myself.stop(None),
        }
        Ok(())
    }
}
