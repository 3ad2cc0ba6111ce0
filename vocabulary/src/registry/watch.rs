//! Join and leave events of the location table.
//!
//! An instance is in three groups (its name's, its id's and its entry `KIND/ID/NAME`), and
//! [`lookup`](super::lookup) finds it only once it is in all three. A local publication
//! joins the entry group last, but a peer's memberships arrive in the order of its `pg`
//! table — arbitrary (ractor_cluster sends them as it iterates a hash map when a session
//! opens) — so the entry group may come before the name's. `Joined` is therefore said
//! when the last of the three arrives, whichever it is: whoever is told of an instance can
//! look it up by name at once (an operation that waited for its cart stepped again, found
//! no cart in the gap, waited for a `Joined` that had already been said, and failed).

use super::{entry_group, key_group, node_name_of, parse_entry, Instance, ModuleKind, SCOPE};
use ractor::pg::{self, GroupChangeMessage};
use ractor::{Actor, ActorCell, ActorId, ActorProcessingErr, ActorRef, SupervisionEvent};
use std::collections::HashMap;
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

struct WatcherState {
    kind: Option<ModuleKind>,
    tx: mpsc::UnboundedSender<RegistryEvent>,
    /// Instances in their entry group whose name's or id's group has not come yet: said
    /// joined when it does.
    pending: HashMap<ActorId, Instance>,
}

/// A group of the table: an instance's entry, or one of its keys (its name or its id).
enum Group<'a> {
    Entry(ModuleKind, u32, &'a str),
    Key(ModuleKind),
}

fn parse_group(group: &str) -> Option<Group<'_>> {
    if let Some((kind, id, name)) = parse_entry(group) {
        return Some(Group::Entry(kind, id, name));
    }
    let (prefix, key) = group.split_once('/')?;
    if key.contains('/') {
        return None;
    }
    Some(Group::Key(ModuleKind::from_prefix(prefix)?))
}

/// Whether a lookup by name or by id finds `inst` (all three of its groups hold it).
fn complete(inst: &Instance) -> bool {
    let (scope, actor) = (SCOPE.to_string(), inst.actor.get_id());
    [
        key_group(inst.kind, &inst.name),
        key_group(inst.kind, &inst.id.to_string()),
        entry_group(inst.kind, inst.id, &inst.name),
    ]
    .iter()
    .all(|group| {
        pg::get_scoped_members(&scope, group)
            .iter()
            .any(|a| a.get_id() == actor)
    })
}

impl WatcherState {
    fn wanted(&self, kind: ModuleKind) -> bool {
        self.kind.is_none_or(|k| k == kind)
    }

    /// What joining `group` makes known: entries now complete, told at once; the rest wait
    /// for their keys.
    fn joined(&mut self, group: &str, actors: Vec<ActorCell>) -> Vec<Instance> {
        match parse_group(group) {
            Some(Group::Entry(kind, id, name)) if self.wanted(kind) => {
                let mut ready = Vec::new();
                for actor in actors {
                    let inst = instance(kind, id, name, actor);
                    if complete(&inst) {
                        ready.push(inst);
                    } else {
                        self.pending.insert(inst.actor.get_id(), inst);
                    }
                }
                ready
            }
            Some(Group::Key(kind)) if self.wanted(kind) && !self.pending.is_empty() => actors
                .iter()
                .filter_map(|a| {
                    let id = a.get_id();
                    let done = self.pending.get(&id).is_some_and(complete);
                    done.then(|| self.pending.remove(&id)).flatten()
                })
                .collect(),
            _ => Vec::new(),
        }
    }

    /// What leaving `group` makes known: an instance leaving its entry group has left.
    fn left(&mut self, group: &str, actors: Vec<ActorCell>) -> Vec<Instance> {
        match parse_group(group) {
            Some(Group::Entry(kind, id, name)) if self.wanted(kind) => actors
                .into_iter()
                .map(|actor| {
                    self.pending.remove(&actor.get_id());
                    instance(kind, id, name, actor)
                })
                .collect(),
            _ => Vec::new(),
        }
    }
}

fn instance(kind: ModuleKind, id: u32, name: &str, actor: ActorCell) -> Instance {
    Instance {
        kind,
        id,
        name: name.to_string(),
        node: node_name_of(&actor.get_id()),
        actor,
    }
}

impl Actor for Watcher {
    type Msg = WatcherMsg;
    type State = WatcherState;
    type Arguments = WatcherState;

    async fn pre_start(
        &self,
        myself: ActorRef<Self::Msg>,
        state: WatcherState,
    ) -> Result<WatcherState, ActorProcessingErr> {
        pg::monitor_scope(SCOPE.to_string(), myself.get_cell());
        Ok(state)
    }

    async fn post_stop(
        &self,
        myself: ActorRef<Self::Msg>,
        _state: &mut WatcherState,
    ) -> Result<(), ActorProcessingErr> {
        pg::demonitor_scope(SCOPE.to_string(), myself.get_id());
        Ok(())
    }

    async fn handle_supervisor_evt(
        &self,
        myself: ActorRef<Self::Msg>,
        evt: SupervisionEvent,
        state: &mut WatcherState,
    ) -> Result<(), ActorProcessingErr> {
        let SupervisionEvent::ProcessGroupChanged(change) = evt else {
            return Ok(());
        };
        let events: Vec<RegistryEvent> = match change {
            GroupChangeMessage::Join(_, g, a) => state
                .joined(&g, a)
                .into_iter()
                .map(RegistryEvent::Joined)
                .collect(),
            GroupChangeMessage::Leave(_, g, a) => state
                .left(&g, a)
                .into_iter()
                .map(RegistryEvent::Left)
                .collect(),
        };
        for evt in events {
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
    let state = WatcherState {
        kind,
        tx,
        pending: HashMap::new(),
    };
    let (watcher, _) = Actor::spawn(None, Watcher, state).await?;
    Ok(Watch { rx, watcher })
}

#[cfg(test)]
mod tests {
    use super::super::{lookup, publish};
    use super::*;
    use std::time::Duration;

    struct Idle;
    impl Actor for Idle {
        type Msg = ();
        type State = ();
        type Arguments = ();
        async fn pre_start(&self, _: ActorRef<()>, _: ()) -> Result<(), ActorProcessingErr> {
            Ok(())
        }
    }

    async fn next(watch: &mut Watch) -> RegistryEvent {
        tokio::time::timeout(Duration::from_secs(30), watch.next())
            .await
            .expect("an event within 30 s")
            .expect("the watcher runs")
    }

    /// A peer's memberships arrive in any order: joined is said when the instance can be
    /// looked up by name and id, not when its entry group comes first.
    #[tokio::test]
    async fn an_instance_whose_entry_comes_before_its_keys_is_joined_when_the_last_key_comes() {
        let kind = ModuleKind::Hardware;
        let mut watch = watch(Some(kind)).await.unwrap();
        let (late, _h1) = Actor::spawn(None, Idle, ()).await.unwrap();
        let (sentinel, _h2) = Actor::spawn(None, Idle, ()).await.unwrap();
        let join = |group: String, actor: &ActorRef<()>| {
            pg::join_scoped(SCOPE.to_string(), group, vec![actor.get_cell()]);
        };
        // as a session's sync may bring them: the entry, the name, (later) the id
        join(entry_group(kind, 9101, "late-cart"), &late);
        join(key_group(kind, "late-cart"), &late);
        // a whole publication in between: its joined comes first, the late one is not
        // said while a lookup by its id finds nothing
        publish(kind, 9102, "sentinel-cart", sentinel.get_cell()).unwrap();
        let first = next(&mut watch).await;
        assert!(
            matches!(&first, RegistryEvent::Joined(i) if i.name == "sentinel-cart"),
            "{first:?}"
        );
        assert!(lookup(kind, "9101").is_empty());
        join(key_group(kind, "9101"), &late);
        let RegistryEvent::Joined(inst) = next(&mut watch).await else {
            panic!("the late instance was not said joined");
        };
        assert_eq!((inst.id, inst.name.as_str()), (9101, "late-cart"));
        assert_eq!(lookup(kind, "late-cart").len(), 1);
        assert_eq!(lookup(kind, "9101").len(), 1);
        // leaving its entry group, it has left
        pg::leave_scoped(
            SCOPE.to_string(),
            entry_group(kind, 9101, "late-cart"),
            vec![late.get_cell()],
        );
        let left = next(&mut watch).await;
        assert!(
            matches!(&left, RegistryEvent::Left(i) if i.id == 9101),
            "{left:?}"
        );
    }
}
