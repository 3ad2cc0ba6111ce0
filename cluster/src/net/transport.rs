//! Starting and stopping a node's transport, and dialing its peers until they answer.

use super::config::ClusterConfig;
use super::events::NetEvent;
use super::heartbeat::{Heartbeat, HeartbeatArgs};
use super::sessions::Sessions;
use marie_actors::registry;
use ractor::{Actor, ActorRef};
use ractor_cluster::node::NodeConnectionMode;
use ractor_cluster::{NodeServer, NodeServerMessage};
use std::net::SocketAddr;
use std::time::Duration;
use tokio::task::JoinHandle;

/// First wait before dialing a peer again; doubled on each failure up to [`REDIAL_MAX`].
const REDIAL_MIN: Duration = Duration::from_millis(100);
/// Longest wait between two dials of an absent peer.
const REDIAL_MAX: Duration = Duration::from_secs(2);
/// Longest a dial may take: a peer behind a partition drops our SYNs silently, and the
/// kernel would retry them for minutes — long after the partition healed.
const DIAL_TIMEOUT: Duration = Duration::from_secs(2);

/// A peer node the transport has a ready session with.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Peer {
    /// Its node name.
    pub name: String,
    /// The address it listens on (`host:port`).
    pub address: String,
    /// ractor's number for the session (changes on every reconnect).
    pub session: u64,
}

/// Why the transport cannot start or did not see its peers.
#[derive(Debug, thiserror::Error)]
pub enum TransportError {
    /// The cluster settings cannot work.
    #[error("cluster config: {0}")]
    Config(String),
    /// The node server did not start (e.g. the port is taken).
    #[error("cannot listen on {addr}: {reason}")]
    Listen {
        /// Where it tried.
        addr: SocketAddr,
        /// What failed.
        reason: String,
    },
    /// Fewer peers than awaited answered in time.
    #[error("saw {seen} of {wanted} peer(s) within {waited:?}: {}", if .names.is_empty() { "none".to_string() } else { .names.join(", ") })]
    PeersMissing {
        /// How many were awaited.
        wanted: usize,
        /// How many were there.
        seen: usize,
        /// Their names.
        names: Vec<String>,
        /// How long it waited.
        waited: Duration,
    },
}

/// A node's place in the cluster: its server, its sessions, its dialers.
pub struct Transport {
    node: String,
    listen: SocketAddr,
    server: ActorRef<NodeServerMessage>,
    server_handle: JoinHandle<()>,
    sessions: Sessions,
    dialers: Vec<JoinHandle<()>>,
    heartbeat: ActorRef<super::heartbeat::BeatMsg>,
    heartbeat_handle: JoinHandle<()>,
}

impl Transport {
    /// Listen on `config.listen` as node `node`, name this process' node in the registry,
    /// and dial every configured peer (again and again, with backoff, while it is absent).
    pub async fn start(node: &str, config: &ClusterConfig) -> Result<Transport, TransportError> {
        config.validate(node)?;
        registry::set_local_node_name(node);
        let listen = config.listen;
        let server = NodeServer::new(
            listen.port(),
            config.cookie.clone(),
            node.to_string(),
            listen.ip().to_string(),
            None,
            // a node that joins one member dials that member's peers: a full mesh
            Some(NodeConnectionMode::Transitive),
        )
        .with_listen_addr(listen.ip());
        let (server, server_handle) =
            Actor::spawn(None, server, ())
                .await
                .map_err(|e| TransportError::Listen {
                    addr: listen,
                    reason: e.to_string(),
                })?;
        let sessions = Sessions::new(node);
        server
            .cast(NodeServerMessage::SubscribeToEvents {
                id: "marie-sessions".into(),
                subscription: Box::new(sessions.clone()),
            })
            .map_err(|e| TransportError::Listen {
                addr: listen,
                reason: e.to_string(),
            })?;
        let (heartbeat, heartbeat_handle) = Actor::spawn(
            None,
            Heartbeat,
            HeartbeatArgs {
                node: node.to_string(),
                config: config.heartbeat,
                sessions: sessions.clone(),
                protocol: config.protocol,
            },
        )
        .await
        .map_err(|e| TransportError::Listen {
            addr: listen,
            reason: format!("the heartbeat did not start: {e}"),
        })?;
        tracing::info!(node, %listen, peers = ?config.peers, "node listening");
        let dialers = config
            .peers
            .iter()
            .map(|&addr| {
                tokio::spawn(dial_while_absent(
                    node.to_string(),
                    server.clone(),
                    sessions.clone(),
                    addr,
                ))
            })
            .collect();
        Ok(Transport {
            node: node.to_string(),
            listen,
            server,
            server_handle,
            sessions,
            dialers,
            heartbeat,
            heartbeat_handle,
        })
    }

    /// The peers ready now, and what happens from then on: peers up, lost, declared down,
    /// refused — and this node frozen — none missed or told twice. A receiver that falls
    /// 256 events behind loses the oldest.
    pub fn events(&self) -> (Vec<Peer>, tokio::sync::broadcast::Receiver<NetEvent>) {
        self.sessions.listen()
    }

    /// This node's name.
    pub fn node(&self) -> &str {
        &self.node
    }

    /// The address it listens on.
    pub fn listen(&self) -> SocketAddr {
        self.listen
    }

    /// The peers it has a ready session with now, by name.
    pub fn peers(&self) -> Vec<Peer> {
        self.sessions.peers()
    }

    /// Wait until at least `n` peers are ready (their modules are then in the registry:
    /// ractor_cluster marks a session ready once the process groups are exchanged).
    pub async fn wait_for_peers(
        &self,
        n: usize,
        timeout: Duration,
    ) -> Result<Vec<Peer>, TransportError> {
        let mut changes = self.sessions.subscribe();
        let wait = async {
            loop {
                let peers = self.sessions.peers();
                if peers.len() >= n {
                    return peers;
                }
                if changes.changed().await.is_err() {
                    return peers;
                }
            }
        };
        match tokio::time::timeout(timeout, wait).await {
            Ok(peers) if peers.len() >= n => Ok(peers),
            _ => {
                let peers = self.sessions.peers();
                Err(TransportError::PeersMissing {
                    wanted: n,
                    seen: peers.len(),
                    names: peers.into_iter().map(|p| p.name).collect(),
                    waited: timeout,
                })
            }
        }
    }

    /// Wait until the set of peers has not changed for `quiet` (a joining node learns of
    /// the members behind its first peer a moment after it), at most `timeout` in all.
    pub async fn settle(&self, quiet: Duration, timeout: Duration) -> Vec<Peer> {
        let mut changes = self.sessions.subscribe();
        let _ = tokio::time::timeout(timeout, async {
            while let Ok(Ok(())) = tokio::time::timeout(quiet, changes.changed()).await {}
        })
        .await;
        self.sessions.peers()
    }

    /// Stop dialing, close every session and stop listening.
    pub async fn stop(self) {
        for d in &self.dialers {
            d.abort();
        }
        self.heartbeat.stop(None);
        let _ = self.heartbeat_handle.await;
        self.server.stop(Some("node stopping".into()));
        let _ = self.server_handle.await;
        tracing::info!(node = %self.node, "left the cluster");
    }
}

/// Keep a session with the peer at `addr`: dial it whenever no ready peer listens there,
/// backing off while it does not answer.
async fn dial_while_absent(
    node: String,
    server: ActorRef<NodeServerMessage>,
    sessions: Sessions,
    addr: SocketAddr,
) {
    let mut changes = sessions.subscribe();
    let mut backoff = REDIAL_MIN;
    let wanted = addr.to_string();
    loop {
        let present = sessions.peers().iter().any(|p| p.address == wanted);
        if present {
            backoff = REDIAL_MIN;
            // sleep until something changes (a peer lost, perhaps this one)
            if changes.changed().await.is_err() {
                return;
            }
            continue;
        }
        match tokio::time::timeout(DIAL_TIMEOUT, ractor_cluster::client_connect(&server, addr))
            .await
        {
            Ok(Ok(())) => tracing::debug!(%node, peer = %addr, "dialed"),
            Ok(Err(e)) => tracing::debug!(%node, peer = %addr, error = %e, "dial failed"),
            Err(_) => tracing::debug!(%node, peer = %addr, "dial timed out"),
        }
        // give the handshake its time, or back off; wake early on any session change
        let _ = tokio::time::timeout(backoff, changes.changed()).await;
        backoff = (backoff * 2).min(REDIAL_MAX);
    }
}
