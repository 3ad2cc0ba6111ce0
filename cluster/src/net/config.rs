//! Where a node listens, whom it joins, and the cookie it proves itself with.

use super::detector::HeartbeatConfig;
use super::tls::TlsFiles;
use super::TransportError;
use marie_actors::wire::PROTOCOL_VERSION;
use std::net::SocketAddr;

/// Longest cookie accepted (ractor_cluster hashes it; a longer one gains nothing).
pub const MAX_COOKIE_LEN: usize = 256;

/// Whether `cookie` can be a cluster's cookie: not empty, at most [`MAX_COOKIE_LEN`] bytes.
pub fn check_cookie(cookie: &str) -> Result<(), String> {
    if cookie.is_empty() {
        return Err("the cookie must not be empty".into());
    }
    if cookie.len() > MAX_COOKIE_LEN {
        return Err(format!("the cookie is longer than {MAX_COOKIE_LEN} bytes"));
    }
    Ok(())
}

/// The `[cluster]` part of a node config.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ClusterConfig {
    /// The address the node listens on for its peers (an explicit port: peers dial it).
    pub listen: SocketAddr,
    /// Nodes to join; any one reachable member is enough.
    pub peers: Vec<SocketAddr>,
    /// Shared secret of the cluster: a peer with another cookie is refused.
    pub cookie: String,
    /// The failure detector's heartbeat period and deadline.
    pub heartbeat: HeartbeatConfig,
    /// The protocol version the node claims in its heartbeats: [`PROTOCOL_VERSION`]; another
    /// value only to see a cluster refuse it (`marie node --protocol-version`, hidden).
    pub protocol: u16,
    /// Mutual TLS for every session; `None`: plain TCP (the cookie still authenticates).
    pub tls: Option<TlsFiles>,
}

impl ClusterConfig {
    /// Listen on `listen`, join nobody yet.
    pub fn new(listen: SocketAddr, cookie: impl Into<String>) -> Self {
        ClusterConfig {
            listen,
            peers: Vec::new(),
            cookie: cookie.into(),
            heartbeat: HeartbeatConfig::default(),
            protocol: PROTOCOL_VERSION,
            tls: None,
        }
    }

    /// Also join the node at `addr`.
    pub fn with_peer(mut self, addr: SocketAddr) -> Self {
        self.peers.push(addr);
        self
    }

    /// The failure detector's heartbeat period and deadline (default:
    /// [`DEFAULT_DEADLINE`](super::detector::DEFAULT_DEADLINE), 1.2 s of silence, with
    /// a heartbeat every 240 ms — a frozen or cut-off peer is declared down within about
    /// 1.5 s). Every node of a cluster should use the same.
    pub fn with_heartbeat(mut self, heartbeat: HeartbeatConfig) -> Self {
        self.heartbeat = heartbeat;
        self
    }

    /// Encrypt every session with mutual TLS from these files.
    pub fn with_tls(mut self, files: TlsFiles) -> Self {
        self.tls = Some(files);
        self
    }

    /// Check what ractor_cluster would otherwise take silently or fail on later.
    pub fn validate(&self, node: &str) -> Result<(), TransportError> {
        if node.is_empty() || node.contains('@') || node.chars().any(char::is_whitespace) {
            return Err(TransportError::Config(format!(
                "node name {node:?} cannot join a cluster: it must be non-empty, without '@' or spaces"
            )));
        }
        check_cookie(&self.cookie).map_err(TransportError::Config)?;
        self.heartbeat.validate().map_err(TransportError::Config)?;
        if let Some(p) = self.peers.iter().find(|p| p.port() == 0) {
            return Err(TransportError::Config(format!("peer {p} has no port")));
        }
        Ok(())
    }
}
