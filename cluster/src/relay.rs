//! Events across nodes: every node forwards the events of its own bus to the cluster's
//! watchers — a `run --join` writing its events file, a monitor — so that a restart on one
//! node, a peer declared down by another, reach whoever watches the whole cluster.
//!
//! A watcher is an actor in `pg` (scope [`SCOPE`], group [`GROUP`]); each node's forwarder
//! subscribes to its bus and casts each event — a versioned [`Envelope`] of kind `event`,
//! encoded once — to every remote watcher. A node with no watcher only reads its bus. A
//! module's joining and leaving is told by its own node only, not echoed by every node
//! whose registry it reaches.
//!
//! Bounded on both sides: the forwarder reads the bus like any subscriber (falling behind
//! loses the oldest events, counted), and a watcher keeps at most its capacity of events
//! not yet taken, counting the rest as lost ([`Watch::lost`]); a frame that does not decode
//! is dropped with a warning.
//!
//! ```no_run
//! # async fn demo(bus: marie_actors::events::EventBus) {
//! use marie_cluster::relay;
//! let forwarder = relay::forward(bus); // on every node
//! let mut watch = relay::watch(1024).await.unwrap(); // on the watcher
//! while let Some(event) = watch.recv().await {
//!     println!("{} on {}: {:?}", event.at_ms, event.node, event.kind);
//! }
//! # forwarder.abort();
//! # }
//! ```

use marie_actors::events::{BusError, Event, EventBus, EventKind};
use marie_actors::wire::Envelope;
use ractor::{pg, Actor, ActorProcessingErr, ActorRef, SpawnErr};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use tokio::sync::mpsc;
use tokio::task::JoinHandle;

/// `pg` scope of the event watchers.
pub const SCOPE: &str = "marie-events";
/// `pg` group of the event watchers.
pub const GROUP: &str = "watchers";
/// The envelope kind of a forwarded event.
const KIND: &str = "event";

marie_actors::remote_message! {
    /// Messages of an event watcher.
    pub enum WatcherMsg {
        /// An event of another node: an [`Envelope`] of kind `event`.
        Event {
            /// The encoded envelope.
            frame: Vec<u8>,
        },
    }
}

/// Forward every event `bus` publishes to the remote watchers, until the bus closes or the
/// task is aborted.
pub fn forward(bus: EventBus) -> JoinHandle<()> {
    let mut sub = bus.subscribe();
    tokio::spawn(async move {
        let (scope, group) = (SCOPE.to_string(), GROUP.to_string());
        loop {
            let event = match sub.recv().await {
                Ok(e) => e,
                Err(BusError::Lagged { missed }) => {
                    tracing::warn!(missed, "the event forwarder fell behind its bus");
                    continue;
                }
                Err(BusError::Closed) => return,
            };
            if echo_of_another_node(&event, bus.node()) {
                continue;
            }
            let watchers: Vec<ActorRef<WatcherMsg>> = pg::get_scoped_members(&scope, &group)
                .into_iter()
                .filter(|c| !c.get_id().is_local())
                .map(Into::into)
                .collect();
            if watchers.is_empty() {
                continue;
            }
            match Envelope::new(KIND, &event).and_then(|e| e.to_bytes()) {
                Ok(frame) => {
                    for w in watchers {
                        let _ = w.cast(WatcherMsg::Event {
                            frame: frame.clone(),
                        });
                    }
                }
                Err(e) => tracing::error!(error = %e, "cannot encode an event to forward"),
            }
        }
    })
}

/// Whether `event` only echoes news of another node: a module of another node joining or
/// leaving this node's registry (that node tells it itself).
fn echo_of_another_node(event: &Event, here: &str) -> bool {
    matches!(&event.kind, EventKind::Joined(m) | EventKind::Left(m) if m.node != here)
}

/// The events of the other nodes, as they arrive.
pub struct Watch {
    events: mpsc::Receiver<Event>,
    lost: Arc<AtomicU64>,
    actor: ActorRef<WatcherMsg>,
}

impl std::fmt::Debug for Watch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Watch")
            .field("lost", &self.lost())
            .finish_non_exhaustive()
    }
}

impl Watch {
    /// The next event of another node; `None` once the watch stopped.
    pub async fn recv(&mut self) -> Option<Event> {
        self.events.recv().await
    }

    /// The next event if one is waiting.
    pub fn try_recv(&mut self) -> Option<Event> {
        self.events.try_recv().ok()
    }

    /// Events dropped because the watch was full or their frame did not decode.
    pub fn lost(&self) -> u64 {
        self.lost.load(Ordering::Relaxed)
    }
}

impl Drop for Watch {
    fn drop(&mut self) {
        self.actor.stop(None);
    }
}

/// Watch every other node's events, keeping at most `capacity` not yet taken. The
/// watcher is in `pg` when this returns: nodes forward to it from their next event on
/// (once the membership has reached them).
pub async fn watch(capacity: usize) -> Result<Watch, SpawnErr> {
    let (tx, events) = mpsc::channel(capacity.max(1));
    let lost = Arc::new(AtomicU64::new(0));
    let (actor, _) = Actor::spawn(
        None,
        Watcher,
        WatcherState {
            tx,
            lost: lost.clone(),
        },
    )
    .await?;
    Ok(Watch {
        events,
        lost,
        actor,
    })
}

struct Watcher;

struct WatcherState {
    tx: mpsc::Sender<Event>,
    lost: Arc<AtomicU64>,
}

impl Actor for Watcher {
    type Msg = WatcherMsg;
    type State = WatcherState;
    type Arguments = WatcherState;

    async fn pre_start(
        &self,
        myself: ActorRef<WatcherMsg>,
        state: WatcherState,
    ) -> Result<WatcherState, ActorProcessingErr> {
        pg::join_scoped(SCOPE.into(), GROUP.into(), vec![myself.get_cell()]);
        Ok(state)
    }

    async fn handle(
        &self,
        _myself: ActorRef<WatcherMsg>,
        msg: WatcherMsg,
        state: &mut WatcherState,
    ) -> Result<(), ActorProcessingErr> {
        let WatcherMsg::Event { frame } = msg;
        let event = Envelope::from_bytes(&frame)
            .map_err(|e| e.to_string())
            .and_then(|env| {
                if env.kind != KIND {
                    return Err(format!("a frame of kind {:?}", env.kind));
                }
                env.payload::<Event>().map_err(|e| e.to_string())
            });
        match event {
            Ok(event) => {
                if state.tx.try_send(event).is_err() {
                    state.lost.fetch_add(1, Ordering::Relaxed);
                }
            }
            Err(e) => {
                state.lost.fetch_add(1, Ordering::Relaxed);
                tracing::warn!(error = %e, "a forwarded event that does not decode: dropped");
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use marie_actors::events::ModuleInfo;
    use marie_actors::registry::ModuleKind;

    fn event(kind: EventKind) -> Event {
        Event {
            at_ms: 7,
            node: "alpha".into(),
            kind,
        }
    }

    fn joined(node: &str) -> EventKind {
        EventKind::Joined(ModuleInfo {
            module: ModuleKind::Operation,
            name: "sampler".into(),
            id: 1,
            node: node.into(),
            address: "0.1".into(),
        })
    }

    #[test]
    fn a_module_is_told_by_its_own_node_only() {
        assert!(!echo_of_another_node(&event(joined("alpha")), "alpha"));
        assert!(echo_of_another_node(&event(joined("beta")), "alpha"));
        let frozen = event(EventKind::NodeFrozen { silent_ms: 1 });
        assert!(!echo_of_another_node(&frozen, "alpha"));
    }

    #[tokio::test]
    async fn a_watcher_drops_what_does_not_decode_and_counts_it() {
        let mut watch = watch(8).await.unwrap();
        let first = event(joined("alpha"));
        for frame in [
            b"garbage".to_vec(),
            Envelope::new("heartbeat", &1u64)
                .unwrap()
                .to_bytes()
                .unwrap(),
            Envelope::new(KIND, &first).unwrap().to_bytes().unwrap(),
        ] {
            watch.actor.cast(WatcherMsg::Event { frame }).unwrap();
        }
        // the actor handles its messages in order: the two bad frames came first
        assert_eq!(watch.recv().await, Some(first));
        assert_eq!(watch.lost(), 2);
    }
}
