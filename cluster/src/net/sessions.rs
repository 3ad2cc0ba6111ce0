//! Who the node sees: ractor_cluster's session callbacks turned into a table of ready peers,
//! and the names behind session numbers recorded in the registry; and whom the node
//! refused, or was refused by, before a session (told once, at warn level, naming the
//! peer).

use super::auth::AuthWatch;
use super::dialed::Dialed;
use super::events::NetEvent;
use marie_vocabulary::registry;
use ractor::ActorRef;
use ractor_cluster::node::{NodeServerSessionInformation, NodeSessionMessage};
use ractor_cluster::NodeEventSubscription;
use std::collections::BTreeMap;
use std::net::SocketAddr;
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::sync::{broadcast, watch};

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

/// An open session: the peer's node name once authenticated, and the session's actor.
type OpenSession = (Option<String>, ActorRef<NodeSessionMessage>);

/// The ready sessions, by ractor's session number; `changed` ticks on every change.
#[derive(Clone)]
pub(crate) struct Sessions {
    ready: Arc<Mutex<BTreeMap<u64, Peer>>>,
    /// Every open session's actor, by session number: what closing a peer stops.
    actors: Arc<Mutex<BTreeMap<u64, OpenSession>>>,
    /// Which sessions end before they authenticate, telling a peer with another cookie.
    auth: Arc<Mutex<AuthWatch>>,
    changed: watch::Sender<u64>,
    /// What the transport tells ([`NetEvent`]): peers up and lost from here, the rest from
    /// the heartbeat.
    events: broadcast::Sender<NetEvent>,
    /// The sessions this node dialed, opened and ended: what ends a dial's wait for its
    /// session when the peer turns it away ([`Dialed`]).
    dialed: broadcast::Sender<Dialed>,
    node: String,
    /// Peers refused (another protocol version): a session with one is closed as soon as
    /// it is authenticated, before its modules reach the registry.
    refused: Arc<Mutex<std::collections::BTreeSet<String>>>,
    /// Why the peer at an address (`ip:port`) is refused before any session, by this node
    /// or by itself: what was last told of it, so that a redial refused again is not told
    /// again. Forgotten when a session with that address is ready.
    refusals: Arc<Mutex<BTreeMap<String, NetEvent>>>,
    /// The protocol version agreed with each peer (the highest both speak), by node name:
    /// what a frame for that peer is encoded at. Set by the heartbeat from each beat.
    agreed: Arc<Mutex<BTreeMap<String, u16>>>,
}

impl Sessions {
    pub(crate) fn new(node: &str) -> Self {
        Sessions {
            ready: Arc::default(),
            actors: Arc::default(),
            auth: Arc::default(),
            refused: Arc::default(),
            refusals: Arc::default(),
            agreed: Arc::default(),
            changed: watch::Sender::new(0),
            events: broadcast::Sender::new(256),
            dialed: broadcast::Sender::new(256),
            node: node.to_string(),
        }
    }

    /// The peers ready now, by name (one entry per peer, however many sessions).
    pub(crate) fn peers(&self) -> Vec<Peer> {
        peers_of(&self.table())
    }

    /// Tell `event` to whoever listens ([`Sessions::listen`]).
    pub(crate) fn tell(&self, event: NetEvent) {
        let _ = self.events.send(event);
    }

    /// Tell a refusal, this node's or a peer's — a connection refused, a dialed node
    /// refused, this node refused by a peer — at warn level (on a `marie` command's stderr
    /// by default) and to whoever listens.
    pub(crate) fn tell_refusal(&self, event: NetEvent) {
        tracing::warn!("node {} {event}", self.node);
        self.tell(event);
    }

    /// This node refused the node it dialed at `to` (its certificate): told unless the
    /// same was told last for that address.
    pub(crate) fn dial_refused(&self, to: SocketAddr, reason: String) {
        self.tell_refusal_once(&to.to_string(), NetEvent::DialRefused { to, reason });
    }

    /// Tell `event`, a refusal of the peer at `address`, and record it as that peer's —
    /// unless it is the one recorded already.
    fn tell_refusal_once(&self, address: &str, event: NetEvent) {
        {
            let mut refusals = self.refusals.lock().unwrap_or_else(|e| e.into_inner());
            if refusals.get(address) == Some(&event) {
                return;
            }
            refusals.insert(address.to_string(), event.clone());
        }
        self.tell_refusal(event);
    }

    /// The refusal of the peer at `address` told last ([`NetEvent::DialRefused`],
    /// [`NetEvent::RefusedBy`]), if no session with it was ready since.
    pub(crate) fn refusal(&self, address: &str) -> Option<NetEvent> {
        self.refusals
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .get(address)
            .cloned()
    }

    /// The peers ready now and the transport's news from then on: peers are told up and
    /// lost under the table's lock, so none is missed or told twice.
    pub(crate) fn listen(&self) -> (Vec<Peer>, broadcast::Receiver<NetEvent>) {
        let table = self.table();
        (peers_of(&table), self.events.subscribe())
    }

    /// The sessions this node dials from now on, opened and ended. A receiver that falls
    /// 256 behind loses the oldest.
    pub(crate) fn dialed(&self) -> broadcast::Receiver<Dialed> {
        self.dialed.subscribe()
    }

    /// A receiver that sees every change of the table.
    pub(crate) fn subscribe(&self) -> watch::Receiver<u64> {
        self.changed.subscribe()
    }

    /// Refuse `peer` from now on: its later sessions are closed at once, the open ones after
    /// `grace` (time for this node's own heartbeat to reach it, so that it learns why too).
    /// False if it already was refused.
    pub(crate) fn refuse(&self, peer: &str, reason: &'static str, grace: Duration) -> bool {
        let new = self
            .refused
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .insert(peer.to_string());
        if new {
            let (this, peer) = (self.clone(), peer.to_string());
            tokio::spawn(async move {
                tokio::time::sleep(grace).await;
                this.close(&peer, reason);
            });
        }
        new
    }

    /// The protocol version agreed with `peer`; `None` before its first beat.
    pub(crate) fn agreed(&self, peer: &str) -> Option<u16> {
        self.agreed
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .get(peer)
            .copied()
    }

    /// Note the version agreed with `peer` (`None`: none, it is refused).
    pub(crate) fn set_agreed(&self, peer: &str, version: Option<u16>) {
        let mut agreed = self.agreed.lock().unwrap_or_else(|e| e.into_inner());
        match version {
            Some(v) => agreed.insert(peer.to_string(), v),
            None => agreed.remove(peer),
        };
    }

    /// The node name behind ractor's session number `session`, once authenticated.
    pub(crate) fn name_of(&self, session: u64) -> Option<String> {
        self.open().get(&session).and_then(|(name, _)| name.clone())
    }

    fn is_refused(&self, peer: &str) -> bool {
        self.refused
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .contains(peer)
    }

    /// Close every session with the peer named `peer` (its modules leave the registry with
    /// them); the transport redials it with backoff.
    pub(crate) fn close(&self, peer: &str, reason: &str) {
        let actors = self.open();
        for (name, actor) in actors.values() {
            if name.as_deref() == Some(peer) {
                tracing::info!(node = %self.node, %peer, reason, "closing the session");
                actor.stop(Some(reason.to_string()));
            }
        }
    }

    fn open(&self) -> std::sync::MutexGuard<'_, BTreeMap<u64, OpenSession>> {
        self.actors.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn auth(&self) -> std::sync::MutexGuard<'_, AuthWatch> {
        self.auth.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn table(&self) -> std::sync::MutexGuard<'_, BTreeMap<u64, Peer>> {
        self.ready.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn bump(&self) {
        self.changed.send_modify(|n| *n += 1);
    }
}

/// The peers of a session table, by name, one entry per peer.
fn peers_of(table: &BTreeMap<u64, Peer>) -> Vec<Peer> {
    let mut peers: Vec<Peer> = table.values().cloned().collect();
    peers.sort_by(|a, b| a.name.cmp(&b.name));
    peers.dedup_by(|a, b| a.name == b.name);
    peers
}

/// `name@host` → `name` (marie's node names have no `@`).
fn node_name(full: &str) -> &str {
    full.split_once('@').map_or(full, |(name, _)| name)
}

impl Sessions {
    /// Session `ses` ended: when it ended before it authenticated, after its peer named
    /// itself, and nothing else explains the end, one more failed authentication in a row
    /// with that peer ([`AuthWatch`]), told as a refusal once there are enough.
    fn ended(&self, ses: &NodeServerSessionInformation) {
        let name = ses.peer_name.as_ref();
        let peer = name.map(|n| node_name(&n.name));
        // every end reaches the watch: it forgets the session there
        let Some(attempts) = self.auth().ended(ses.node_id, peer) else {
            return;
        };
        let (Some(name), Some(peer)) = (name, peer) else {
            return;
        };
        // a peer this node refused (another protocol version) has its sessions closed in
        // the handshake by both sides: that explains the end, not a cookie. (Told wrongly
        // since a turned-away dial is redialled at once: two such ends came within the
        // e2e test's watch, `failure_detector::a_node_of_another_protocol_version_…`.)
        if self.is_refused(peer) {
            return;
        }
        let address = &name.connection_string;
        if ses.is_server {
            // this node checked the peer's answer to its challenge, and closed
            let from = ses
                .peer_addr
                .parse()
                .unwrap_or_else(|_| SocketAddr::from(([0, 0, 0, 0], 0)));
            self.tell_refusal(NetEvent::ConnectionRefused {
                from,
                reason: format!(
                    "{peer} (listening on {address}) failed authentication on {attempts} \
                     connections in a row: it has another cookie"
                ),
            });
        } else {
            // the peer closed after this node answered its challenge
            let reason = format!(
                "authentication failed on {attempts} connections in a row: it has another \
                 cookie"
            );
            self.tell_refusal_once(
                address,
                NetEvent::RefusedBy {
                    peer: peer.to_string(),
                    address: address.clone(),
                    reason,
                },
            );
        }
    }
}

impl NodeEventSubscription for Sessions {
    fn node_session_opened(&self, ses: NodeServerSessionInformation) {
        self.open().insert(ses.node_id, (None, ses.actor.clone()));
        self.auth().opened(ses.node_id);
        if !ses.is_server {
            let _ = self.dialed.send(Dialed::Opened {
                session: ses.node_id,
                to: ses.peer_addr.clone(),
            });
        }
        tracing::debug!(node = %self.node, peer_addr = %ses.peer_addr, incoming = ses.is_server, "session opened");
    }

    fn node_session_authenticated(&self, ses: NodeServerSessionInformation) {
        if let Some(peer) = &ses.peer_name {
            let name = node_name(&peer.name);
            // authenticated, whether or not it is refused below: its cookie is right
            self.auth().authenticated(ses.node_id, name);
            if self.is_refused(name) {
                tracing::debug!(node = %self.node, peer = %peer.name, "a refused peer is back: closed");
                ses.actor
                    .stop(Some("refused: another protocol version".into()));
                return;
            }
            // before the state exchange, so the peer's modules arrive already named
            registry::set_peer_node_name(ses.node_id, name);
            self.open()
                .insert(ses.node_id, (Some(name.to_string()), ses.actor.clone()));
        }
    }

    fn node_session_ready(&self, ses: NodeServerSessionInformation) {
        let Some(name) = &ses.peer_name else {
            return;
        };
        // refused after this session was authenticated (its first beat came before the
        // session was ready): never news. The refusal's grace closes it, once this node's
        // own beats have told the peer why
        if self.is_refused(node_name(&name.name)) {
            return;
        }
        let peer = Peer {
            name: node_name(&name.name).to_string(),
            address: name.connection_string.clone(),
            session: ses.node_id,
        };
        // whatever refused it before is over
        self.refusals
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .remove(&peer.address);
        tracing::info!(node = %self.node, peer = %peer.name, address = %peer.address, "sees peer");
        registry::declare_up(&peer.name);
        {
            let mut table = self.table();
            // a second session with the same peer (both dialed at once) is no news
            if !table.values().any(|p| p.name == peer.name) {
                self.tell(NetEvent::PeerUp {
                    peer: peer.name.clone(),
                    address: peer.address.clone(),
                });
            }
            table.insert(ses.node_id, peer);
        }
        self.bump();
    }

    fn node_session_disconnected(&self, ses: NodeServerSessionInformation) {
        self.open().remove(&ses.node_id);
        self.ended(&ses);
        let gone = {
            let mut table = self.table();
            let gone = table.remove(&ses.node_id);
            if let Some(peer) = &gone {
                if !table.values().any(|p| p.name == peer.name) {
                    self.tell(NetEvent::PeerLost {
                        peer: peer.name.clone(),
                        address: peer.address.clone(),
                    });
                }
            }
            gone
        };
        if let Some(peer) = gone {
            tracing::info!(node = %self.node, peer = %peer.name, address = %peer.address, "lost peer");
            self.bump();
        } else {
            tracing::debug!(node = %self.node, peer_addr = %ses.peer_addr, "session closed before it was ready");
        }
        // told last: a dialer that hears it finds the table as the session left it
        if !ses.is_server {
            let _ = self.dialed.send(Dialed::Ended {
                session: ses.node_id,
            });
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
