//! Join and leave events of the location table.

use super::{node_name_of, parse_entry, Instance, ModuleKind, SCOPE};
use ractor::pg::{self, GroupChangeMessage};
use ractor::{Actor, ActorProcessingErr, ActorRef, SupervisionEvent};
use tokio::sync::mpsc;

/// A change in the location table.
#[derive(Clone, Debug)]
pub enum RegistryEvent {
    /// An instance published itself.
    Joined(Instance),
    /// An instance left (it died, or withdrew).
    Left(Instance),
}

impl RegistryEvent {
    /// The instance concerned.
    pub fn instance(&self) -> &Instance {
        match self {
            RegistryEvent::Joined(i) | RegistryEvent::Left(i) => i,
        }
    }
}

/// A stream of registry events; dropping it stops the watch.
pub struct Watch {
    rx: mpsc::UnboundedReceiver<RegistryEvent>,
    watcher: ActorRef<WatcherMsg>,
}

impl std::fmt::Debug for Watch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Watch")
            .field("waiting", &self.rx.len())
            .finish_non_exhaustive()
    }
}

impl Watch {
    /// The next event, or `None` if the watcher stopped.
    pub async fn next(&mut self) -> Option<RegistryEvent> {
        self.rx.recv().await
    }

    /// The next event if one is already there (to take a burst of joins at once).
    pub fn try_next(&mut self) -> Option<RegistryEvent> {
        self.rx.try_recv().ok()
    }
}

impl Drop for Watch {
    fn drop(&mut self) {
        self.watcher.stop(None);
    }
}

/// The watcher actor takes no messages; it only receives `pg` events.
pub(crate) enum WatcherMsg {}
impl ractor::Message for WatcherMsg {}

struct Watcher;

struct WatcherArgs {
    kind: Option<ModuleKind>,
    tx: mpsc::UnboundedSender<RegistryEvent>,
}

impl Actor for Watcher {
    type Msg = WatcherMsg;
    type State = WatcherArgs;
    type Arguments = WatcherArgs;

    async fn pre_start(
        &self,
        myself: ActorRef<Self::Msg>,
        args: WatcherArgs,
    ) -> Result<WatcherArgs, ActorProcessingErr> {
        pg::monitor_scope(SCOPE.to_string(), myself.get_cell());
        Ok(args)
    }

    async fn post_stop(
        &self,
        myself: ActorRef<Self::Msg>,
        _state: &mut WatcherArgs,
    ) -> Result<(), ActorProcessingErr> {
        pg::demonitor_scope(SCOPE.to_string(), myself.get_id());
        Ok(())
    }

    async fn handle_supervisor_evt(
        &self,
        myself: ActorRef<Self::Msg>,
        evt: SupervisionEvent,
        state: &mut WatcherArgs,
    ) -> Result<(), ActorProcessingErr> {
        let SupervisionEvent::ProcessGroupChanged(change) = evt else {
            return Ok(());
        };
        let (joined, group, actors) = match change {
            GroupChangeMessage::Join(_, g, a) => (true, g, a),
            GroupChangeMessage::Leave(_, g, a) => (false, g, a),
        };
        let Some((kind, id, name)) = parse_entry(&group) else {
            return Ok(());
        };
        if state.kind.is_some_and(|k| k != kind) {
            return Ok(());
        }
        for actor in actors {
            let inst = Instance {
                kind,
                id,
                name: name.to_string(),
                node: node_name_of(&actor.get_id()),
                actor,
            };
            let evt = if joined {
                RegistryEvent::Joined(inst)
            } else {
                RegistryEvent::Left(inst)
            };
            if state.tx.send(evt).is_err() {
                myself.stop(None);
                break;
            }
        }
        Ok(())
    }
}

/// Watch the table for joins and leaves of one kind (or all, with `None`). Events that happen
/// after this call returns are delivered in order.
pub async fn watch(kind: Option<ModuleKind>) -> Result<Watch, ractor::SpawnErr> {
    let (tx, rx) = mpsc::unbounded_channel();
    let (watcher, _) = Actor::spawn(None, Watcher, WatcherArgs { kind, tx }).await?;
    Ok(Watch { rx, watcher })
}
