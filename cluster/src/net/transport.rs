//! Starting and stopping a node's transport, and dialing its peers until they answer.

use super::config::{ClusterConfig, ClusterConfigError};
use super::dialed::{Dialed, OwnDial};
use super::events::NetEvent;
use super::heartbeat::{Heartbeat, HeartbeatArgs};
use super::listener;
use super::sessions::{Peer, Sessions};
use super::tls::{self, Tls, TlsError};
use marie_vocabulary::registry;
use ractor::{Actor, ActorRef};
use ractor_cluster::node::NodeConnectionMode;
use ractor_cluster::{IncomingEncryptionMode, NodeServer, NodeServerMessage};
use std::collections::BTreeSet;
use std::net::SocketAddr;
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::sync::{broadcast, mpsc, watch};
use tokio::task::JoinHandle;

/// First wait before dialing a peer again; doubled on each failure up to [`REDIAL_MAX`].
const REDIAL_MIN: Duration = Duration::from_millis(100);
/// Longest wait between two dials of an absent peer.
const REDIAL_MAX: Duration = Duration::from_secs(2);

/// Why the transport cannot start or did not see its peers.
#[derive(Debug, thiserror::Error)]
pub enum TransportError {
    /// The cluster settings cannot work.
    #[error("cluster config: {0}")]
    Config(#[from] ClusterConfigError),
    /// The node server did not start (e.g. the port is taken).
    #[error("cannot listen on {addr}: {reason}")]
    Listen {
        /// Where it tried.
        addr: SocketAddr,
        /// What failed.
        reason: String,
    },
    /// The TLS files cannot be used.
    #[error("TLS: {0}")]
    Tls(#[from] TlsError),
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
    /// The listener, the dialers of configured peers and the dialer of peers learned from
    /// heartbeats.
    tasks: Vec<JoinHandle<()>>,
    heartbeat: ActorRef<super::heartbeat::BeatMsg>,
    heartbeat_handle: JoinHandle<()>,
    /// The protocol versions its heartbeat claims.
    protocol: marie_vocabulary::wire::ProtocolRange,
}

impl std::fmt::Debug for Transport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Transport")
            .field("node", &self.node)
            .field("listen", &self.listen)
            .finish_non_exhaustive()
    }
}

impl ClusterConfig {
    /// Check what ractor_cluster would otherwise take silently or fail on later: the
    /// transport's first step, so its error is the transport's.
    pub fn validate(&self, node: &str) -> Result<(), TransportError> {
        Ok(self.check(node)?)
    }
}

impl Transport {
    /// Listen on `config.listen` as node `node`, name this process' node in the registry,
    /// and dial every configured peer (again and again, with backoff, while it is absent).
    pub async fn start(node: &str, config: &ClusterConfig) -> Result<Transport, TransportError> {
        config.validate(node)?;
        let tls = config.tls.as_ref().map(Tls::load).transpose()?;
        registry::set_local_node_name(node);
        let listen = config.listen;
        let listen_err = |reason: String| TransportError::Listen {
            addr: listen,
            reason,
        };
        // marie's listener takes the address peers dial (see `listener`): bound first, so
        // that a node on port 0 knows its port before it names itself to peers
        let listener = tokio::net::TcpListener::bind(listen)
            .await
            .map_err(|e| listen_err(e.to_string()))?;
        let advertised = listener.local_addr().unwrap_or(listen);
        // Isolated: marie dials the peers' peers itself (`Dialer::learn`), once each and
        // from one side only — ractor_cluster's transitive mode dials a peer once per member
        // that names it, and the duplicate sessions it then closes make peers flap — and
        // over TLS when on (its transitive dials are plain TCP). Its own listener takes a
        // port nobody is told; with TLS, it completes no handshake (marie's listener checks
        // what rustls does not, the name in a peer's certificate).
        let server = NodeServer::new(
            0,
            config.cookie.clone(),
            node.to_string(),
            listen.ip().to_string(),
            tls.as_ref()
                .map(|t| IncomingEncryptionMode::Tls(t.refusing_acceptor())),
            Some(NodeConnectionMode::Isolated),
        )
        .with_listen_addr(listen.ip());
        let (server, server_handle) = Actor::spawn(None, server, ())
            .await
            .map_err(|e| listen_err(e.to_string()))?;
        // peers are told the port marie listens on
        let _ = server.cast(NodeServerMessage::PortChanged {
            port: advertised.port(),
        });
        let sessions = Sessions::new(node);
        let _ = server.cast(NodeServerMessage::SubscribeToEvents {
            id: "marie-sessions".into(),
            subscription: Box::new(sessions.clone()),
        });
        let mut tasks = vec![tokio::spawn(listener::serve(
            listener,
            tls.clone(),
            server.clone(),
            sessions.clone(),
        ))];
        let dialer = Dialer {
            node: node.to_string(),
            listen: advertised,
            server: server.clone(),
            sessions: sessions.clone(),
            tls,
            timeout: config.dial_timeout,
            dialing: Arc::default(),
        };
        let (learned, heard) = mpsc::unbounded_channel();
        let started = Actor::spawn(
            None,
            Heartbeat,
            HeartbeatArgs {
                node: node.to_string(),
                config: config.heartbeat,
                sessions: sessions.clone(),
                protocol: config.protocol,
                learned,
            },
        )
        .await;
        let (heartbeat, heartbeat_handle) = match started {
            Ok(h) => h,
            Err(e) => {
                tasks.iter().for_each(JoinHandle::abort);
                server.stop(None);
                let _ = server_handle.await;
                return Err(listen_err(format!("the heartbeat did not start: {e}")));
            }
        };
        tracing::info!(node, %listen, peers = ?config.peers, tls = dialer.tls.is_some(), "node listening");
        for &addr in &config.peers {
            tasks.push(tokio::spawn(dialer.clone().keep(addr)));
        }
        tasks.push(tokio::spawn(dialer.learn(heard)));
        Ok(Transport {
            node: node.to_string(),
            listen: advertised,
            server,
            server_handle,
            sessions,
            tasks,
            heartbeat,
            heartbeat_handle,
            protocol: config.protocol,
        })
    }

    /// The protocol versions agreed with its peers: what a frame for one is encoded at.
    pub fn agreement(&self) -> super::Agreement {
        super::Agreement::new(self.sessions.clone(), self.protocol)
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

    /// The refusal told last of the node at `addr`, if no session with it was ready since:
    /// this node refused its certificate ([`NetEvent::DialRefused`]), or it refused this
    /// node at authentication ([`NetEvent::RefusedBy`]). What a member that joins through
    /// that node tells instead of waiting in vain, also when it was told before the member
    /// listened to [`Transport::events`].
    pub fn refusal(&self, addr: SocketAddr) -> Option<NetEvent> {
        self.sessions.refusal(&addr.to_string())
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
        for t in &self.tasks {
            t.abort();
        }
        self.heartbeat.stop(None);
        let _ = self.heartbeat_handle.await;
        self.server.stop(Some("node stopping".into()));
        let _ = self.server_handle.await;
        tracing::info!(node = %self.node, "left the cluster");
    }
}

/// What became of a dialed session.
enum Fate {
    /// Its peer is ready (through it, or through a session the peer dialed).
    Ready,
    /// It ended before it was ready: turned away, or its handshake failed.
    Gone,
}

/// Dials peers: the configured ones while they are absent, and those other peers name in
/// their heartbeats (so that the cluster stays a full mesh, also with TLS and after a
/// partition heals).
#[derive(Clone)]
struct Dialer {
    node: String,
    listen: SocketAddr,
    server: ActorRef<NodeServerMessage>,
    sessions: Sessions,
    tls: Option<Tls>,
    /// Longest a connection, and then its session until ready, may take
    /// ([`ClusterConfig::dial_timeout`]).
    timeout: Duration,
    /// Addresses being dialed now (connecting, or their session not yet ready): never
    /// two dials to one address at once.
    dialing: Arc<Mutex<BTreeSet<SocketAddr>>>,
}

impl Dialer {
    /// Whether a ready peer listens at `addr`.
    fn present(&self, addr: SocketAddr) -> bool {
        let wanted = addr.to_string();
        self.sessions.peers().iter().any(|p| p.address == wanted)
    }

    /// One dial, with TLS if on, given up after the dial timeout; then wait, up to as long
    /// again, for its session to be ready — or to be gone: a session the peer turns away
    /// (a duplicate, a failed handshake) ends the wait at once, so the next dial comes
    /// after the redial backoff, not after the timeout. Nothing if `addr` is being dialed
    /// already.
    async fn dial(&self, addr: SocketAddr) {
        let lock = || self.dialing.lock().unwrap_or_else(|e| e.into_inner());
        if !lock().insert(addr) {
            return;
        }
        // both before the dial: its session's news comes after it
        let changes = self.sessions.subscribe();
        let news = self.sessions.dialed();
        let dialed = tokio::time::timeout(self.timeout, async {
            match &self.tls {
                None => ractor_cluster::client_connect(&self.server, addr).await,
                Some(tls) => tls.dial(&self.server, addr).await,
            }
        })
        .await;
        let node = &self.node;
        match dialed {
            Ok(Ok(())) => {
                tracing::debug!(%node, peer = %addr, "dialed");
                // the handshake and the state exchange follow
                match self.session_of(addr, changes, news).await {
                    Some(Fate::Ready) => {}
                    Some(Fate::Gone) => {
                        tracing::debug!(%node, peer = %addr, "the dialed session ended before it was ready")
                    }
                    None => {
                        tracing::debug!(%node, peer = %addr, "the dialed session not ready in time")
                    }
                }
            }
            Ok(Err(e)) => match tls::refused_certificate(&e) {
                // this node's own refusal, told (once) like an incoming one
                Some(reason) => self.sessions.dial_refused(addr, reason),
                None => tracing::debug!(%node, peer = %addr, error = %e, "dial failed"),
            },
            Err(_) => tracing::debug!(%node, peer = %addr, "dial timed out"),
        }
        lock().remove(&addr);
    }

    /// What became of the session a dial to `addr` opened, heard on `changes` and `news`
    /// (both subscribed before the dial): ready, gone, or — `None` — neither within the
    /// dial timeout.
    async fn session_of(
        &self,
        addr: SocketAddr,
        mut changes: watch::Receiver<u64>,
        mut news: broadcast::Receiver<Dialed>,
    ) -> Option<Fate> {
        let mut own = OwnDial::new(addr.to_string());
        let wait = async {
            loop {
                if self.present(addr) {
                    return Fate::Ready;
                }
                tokio::select! {
                    changed = changes.changed() => if changed.is_err() {
                        // the sessions are gone: the transport is stopping
                        return Fate::Gone;
                    },
                    heard = news.recv() => match heard {
                        Ok(heard) if own.ended(&heard) => return Fate::Gone,
                        Ok(_) => {}
                        // news missed (256 behind): the timeout still ends the wait
                        Err(broadcast::error::RecvError::Lagged(_)) => {}
                        Err(broadcast::error::RecvError::Closed) => return Fate::Gone,
                    },
                }
            }
        };
        tokio::time::timeout(self.timeout, wait).await.ok()
    }

    /// Keep a session with the peer at `addr`: dial it whenever no ready peer listens
    /// there, backing off while it does not answer.
    async fn keep(self, addr: SocketAddr) {
        let mut changes = self.sessions.subscribe();
        let mut backoff = REDIAL_MIN;
        loop {
            if self.present(addr) {
                backoff = REDIAL_MIN;
                // sleep until something changes (a peer lost, perhaps this one)
                if changes.changed().await.is_err() {
                    return;
                }
                continue;
            }
            self.dial(addr).await;
            // back off; wake early on any session change
            let _ = tokio::time::timeout(backoff, changes.changed()).await;
            backoff = (backoff * 2).min(REDIAL_MAX);
        }
    }

    /// Dial, each time it is heard of, a peer another peer sees and this node does not —
    /// when this node's address is the lower of the two: both hear of each other from
    /// their common peers, and one session between them is what both want. (Another peer
    /// keeps naming it while it lives, which is the retry.)
    async fn learn(self, mut heard: mpsc::UnboundedReceiver<SocketAddr>) {
        while let Some(addr) = heard.recv().await {
            if addr <= self.listen || self.present(addr) {
                continue;
            }
            let this = self.clone();
            tokio::spawn(async move {
                tracing::debug!(node = %this.node, peer = %addr, "dialing a peer learned from a heartbeat");
                this.dial(addr).await;
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::net::config::CookieError;
    use crate::net::detector::{HeartbeatConfig, HeartbeatError};

    #[test]
    fn cluster_settings_that_cannot_work_are_matched_by_their_kind() {
        let listen: SocketAddr = "127.0.0.1:7100".parse().unwrap();
        let config = |cookie: &str| ClusterConfig::new(listen, cookie);
        let Err(TransportError::Config(ClusterConfigError::NodeName { name })) =
            config("c").validate("a@b")
        else {
            panic!("a node name with '@' was accepted");
        };
        assert_eq!(name, "a@b");
        let err = config("").validate("a").unwrap_err();
        assert!(
            matches!(
                err,
                TransportError::Config(ClusterConfigError::Cookie(CookieError::Empty))
            ),
            "{err:?}"
        );
        assert_eq!(
            err.to_string(),
            "cluster config: the cookie must not be empty"
        );
        let slow = config("c").with_heartbeat(HeartbeatConfig {
            period: Duration::from_millis(800),
            deadline: Duration::from_millis(1500),
        });
        assert!(matches!(
            slow.validate("a"),
            Err(TransportError::Config(ClusterConfigError::Heartbeat(
                HeartbeatError::PeriodTooLong { .. }
            )))
        ));
        let portless: SocketAddr = "127.0.0.1:0".parse().unwrap();
        let err = config("c").with_peer(portless).validate("a").unwrap_err();
        assert!(
            matches!(
                err,
                TransportError::Config(ClusterConfigError::PeerWithoutPort { peer }) if peer == portless
            ),
            "{err:?}"
        );
        assert_eq!(
            err.to_string(),
            "cluster config: peer 127.0.0.1:0 has no port"
        );
    }
}
