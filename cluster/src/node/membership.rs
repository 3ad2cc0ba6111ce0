//! A node's place in a cluster, when its config has one ([`NodeConfig::cluster`]):
//! the transport [`Node::start`](super::Node::start) starts for it, the node's side of
//! what the transport tells, and leaving at [`Node::shutdown`](super::Node::shutdown).
//!
//! Joined, a node
//! - listens, dials its peers and keeps the cluster a full mesh ([`Transport`]);
//! - publishes the cluster's news on its bus (nodes up, lost, declared down, refused,
//!   this node frozen: [`crate::net::publish_on`]), beside its other events;
//! - forwards its events to whoever watches the cluster ([`crate::relay::forward`]);
//! - restarts its operations as a new incarnation when it was itself frozen past its
//!   peers' deadline (they declared it down and replaced its operations, so whatever its
//!   instances were doing is stale), telling each time as a [`Reincarnation`].

use super::config::NodeConfig;
use super::tree;
use crate::net::{ClusterConfig, NetEvent, Transport, TransportError};
use marie_supervision::SupervisorRef;
use marie_vocabulary::events::EventBus;
use std::time::Duration;
use tokio::sync::broadcast;
use tokio::task::JoinHandle;

/// How many reincarnations a slow receiver of [`Node::reincarnations`](super::Node::reincarnations)
/// may fall behind before it loses the oldest (a node is frozen rarely).
const REINCARNATIONS_KEPT: usize = 16;

/// A frozen node's restart of its operations as a new incarnation.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Reincarnation {
    /// How long the node had been frozen (past its failure detector's deadline).
    pub frozen: Duration,
    /// How many operation instances it restarted.
    pub restarted: usize,
}

/// The transport of a node that joined a cluster, and the node's tasks that follow it.
pub(super) struct Membership {
    transport: Transport,
    /// The bus publisher, the relay forwarder, the reincarnation watcher.
    tasks: Vec<JoinHandle<()>>,
    reincarnations: broadcast::Sender<Reincarnation>,
}

impl Membership {
    /// Start the transport of node `config.name` as `cluster` says, and the node's tasks
    /// that follow it (its news on `bus`, `bus` forwarded, reincarnation through `root`).
    pub(super) async fn join(
        config: &NodeConfig,
        cluster: &ClusterConfig,
        bus: &EventBus,
        root: SupervisorRef,
    ) -> Result<Membership, TransportError> {
        let transport = Transport::start(&config.name, cluster).await?;
        let (reincarnations, _) = broadcast::channel(REINCARNATIONS_KEPT);
        let tasks = vec![
            crate::net::publish_on(&transport, bus.clone()),
            crate::relay::forward(bus.clone(), transport.agreement()),
            tokio::spawn(reincarnate_when_frozen(
                transport.events().1,
                root,
                config.clone(),
                reincarnations.clone(),
            )),
        ];
        Ok(Membership {
            transport,
            tasks,
            reincarnations,
        })
    }

    /// The transport.
    pub(super) fn transport(&self) -> &Transport {
        &self.transport
    }

    /// The reincarnations from now on.
    pub(super) fn reincarnations(&self) -> broadcast::Receiver<Reincarnation> {
        self.reincarnations.subscribe()
    }

    /// Leave the cluster: stop following the transport, then close every session and stop
    /// listening (the peers see this node's modules leave at once).
    pub(super) async fn leave(self) {
        for task in &self.tasks {
            task.abort();
        }
        self.transport.stop().await;
    }
}

/// On every [`NetEvent::Frozen`], restart the node's operations as a new incarnation
/// ([`tree::reincarnate`]) and tell it.
async fn reincarnate_when_frozen(
    mut news: broadcast::Receiver<NetEvent>,
    root: SupervisorRef,
    config: NodeConfig,
    told: broadcast::Sender<Reincarnation>,
) {
    loop {
        let frozen = match news.recv().await {
            Ok(NetEvent::Frozen { silent }) => silent,
            Ok(_) => continue,
            Err(broadcast::error::RecvError::Lagged(n)) => {
                tracing::warn!(node = %config.name, "{n} transport event(s) unseen by the reincarnation watcher");
                continue;
            }
            Err(broadcast::error::RecvError::Closed) => return,
        };
        match tree::reincarnate(&root, &config).await {
            Ok(restarted) => {
                let _ = told.send(Reincarnation { frozen, restarted });
            }
            Err(e) => {
                tracing::error!(node = %config.name, "could not restart its operations after a freeze: {e}")
            }
        }
    }
}
