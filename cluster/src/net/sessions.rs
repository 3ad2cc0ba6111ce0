//! Who the node sees: ractor_cluster's session callbacks turned into a table of ready peers,
//! and the names behind session numbers recorded in the registry.

use super::transport::Peer;
use marie_actors::registry;
use ractor_cluster::node::NodeServerSessionInformation;
use ractor_cluster::NodeEventSubscription;
use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};
use tokio::sync::watch;

/// The ready sessions, by ractor's session number; `changed` ticks on every change.
#[derive(Clone)]
pub(crate) struct Sessions {
    ready: Arc<Mutex<BTreeMap<u64, Peer>>>,
    changed: watch::Sender<u64>,
    node: String,
}

impl Sessions {
    pub(crate) fn new(node: &str) -> Self {
        Sessions {
            ready: Arc::default(),
            changed: watch::Sender::new(0),
            node: node.to_string(),
        }
    }

    /// The peers ready now, by name.
    pub(crate) fn peers(&self) -> Vec<Peer> {
        let mut peers: Vec<Peer> = self.table().values().cloned().collect();
        peers.sort_by(|a, b| a.name.cmp(&b.name));
        peers
    }

    /// A receiver that sees every change of the table.
    pub(crate) fn subscribe(&self) -> watch::Receiver<u64> {
        self.changed.subscribe()
    }

    fn table(&self) -> std::sync::MutexGuard<'_, BTreeMap<u64, Peer>> {
        self.ready.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn bump(&self) {
        self.changed.send_modify(|n| *n += 1);
    }
}

/// `name@host` → `name` (marie's node names have no `@`).
fn node_name(full: &str) -> &str {
    full.split_once('@').map_or(full, |(name, _)| name)
}

impl NodeEventSubscription for Sessions {
    fn node_session_opened(&self, ses: NodeServerSessionInformation) {
        tracing::debug!(node = %self.node, peer_addr = %ses.peer_addr, incoming = ses.is_server, "session opened");
    }

    fn node_session_authenticated(&self, ses: NodeServerSessionInformation) {
        if let Some(peer) = &ses.peer_name {
            // before the state exchange, so the peer's modules arrive already named
            registry::set_peer_node_name(ses.node_id, node_name(&peer.name));
        }
    }

    fn node_session_ready(&self, ses: NodeServerSessionInformation) {
        let Some(name) = &ses.peer_name else {
            return;
        };
        let peer = Peer {
            name: node_name(&name.name).to_string(),
            address: name.connection_string.clone(),
            session: ses.node_id,
        };
        registry::set_peer_node_name(ses.node_id, &peer.name);
        tracing::info!(node = %self.node, peer = %peer.name, address = %peer.address, "sees peer");
        self.table().insert(ses.node_id, peer);
        self.bump();
    }

    fn node_session_disconnected(&self, ses: NodeServerSessionInformation) {
        let gone = self.table().remove(&ses.node_id);
        if let Some(peer) = gone {
            tracing::info!(node = %self.node, peer = %peer.name, address = %peer.address, "lost peer");
            self.bump();
        } else {
            tracing::debug!(node = %self.node, peer_addr = %ses.peer_addr, "session closed before it was ready");
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn node_names_drop_the_host() {
        assert_eq!(node_name("alpha@127.0.0.1"), "alpha");
        assert_eq!(node_name("alpha"), "alpha");
    }
}
