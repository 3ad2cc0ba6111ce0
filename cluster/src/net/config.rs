//! Where a node listens, whom it joins, and the cookie it proves itself with.

use super::detector::{HeartbeatConfig, HeartbeatError};
use super::tls::TlsFiles;
use marie_vocabulary::wire::ProtocolRange;
use std::net::SocketAddr;
use std::time::Duration;

/// How long a dial may take by default ([`ClusterConfig::dial_timeout`]).
pub const DEFAULT_DIAL_TIMEOUT: Duration = Duration::from_secs(2);

/// Longest cookie accepted (ractor_cluster hashes it; a longer one gains nothing).
pub const MAX_COOKIE_LEN: usize = 256;

/// Whether `cookie` can be a cluster's cookie: not empty, at most [`MAX_COOKIE_LEN`] bytes.
pub fn check_cookie(cookie: &str) -> Result<(), CookieError> {
    if cookie.is_empty() {
        return Err(CookieError::Empty);
    }
    if cookie.len() > MAX_COOKIE_LEN {
        return Err(CookieError::TooLong {
            len: cookie.len(),
            max: MAX_COOKIE_LEN,
        });
    }
    Ok(())
}

/// Why a string cannot be a cluster's cookie ([`check_cookie`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum CookieError {
    /// The cookie is empty: it would authenticate nothing.
    #[error("the cookie must not be empty")]
    Empty,
    /// The cookie is longer than [`MAX_COOKIE_LEN`] bytes.
    #[error("the cookie is longer than {max} bytes")]
    TooLong {
        /// Its length in bytes.
        len: usize,
        /// The longest accepted ([`MAX_COOKIE_LEN`]).
        max: usize,
    },
}

/// Cluster settings that cannot work ([`ClusterConfig::validate`]): what ractor_cluster
/// would otherwise take silently or fail on later.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ClusterConfigError {
    /// The node's name is empty or holds `@` or whitespace: ractor names nodes `name@host`.
    #[error(
        "node name {name:?} cannot join a cluster: it must be non-empty, without '@' or spaces"
    )]
    NodeName {
        /// The name given.
        name: String,
    },
    /// The cookie cannot be a cluster's cookie.
    #[error(transparent)]
    Cookie(#[from] CookieError),
    /// The heartbeat period and deadline cannot work together.
    #[error(transparent)]
    Heartbeat(#[from] HeartbeatError),
    /// The dial timeout is zero: no dial could ever succeed.
    #[error("the dial timeout must be longer than zero")]
    DialTimeoutZero,
    /// A peer's address has port 0: nobody listens there.
    #[error("peer {peer} has no port")]
    PeerWithoutPort {
        /// The peer's address.
        peer: SocketAddr,
    },
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
    /// The protocol versions the node claims to speak in its heartbeats: this build's
    /// ([`ProtocolRange::this_build`]); another range only to see a cluster agree with a
    /// node of another build or refuse it (`marie node --protocol-range`, hidden).
    pub protocol: ProtocolRange,
    /// Mutual TLS for every session; `None`: plain TCP (the cookie still authenticates).
    pub tls: Option<TlsFiles>,
    /// Longest a dial may take — the connection, then its session until ready or turned
    /// away, each — before the peer is dialed again: a peer behind a partition drops the
    /// connection's SYNs silently, and the kernel would retry them for minutes, long after
    /// the partition healed. Default [`DEFAULT_DIAL_TIMEOUT`].
    pub dial_timeout: Duration,
}

impl ClusterConfig {
    /// Listen on `listen`, join nobody yet.
    pub fn new(listen: SocketAddr, cookie: impl Into<String>) -> Self {
        ClusterConfig {
            listen,
            peers: Vec::new(),
            cookie: cookie.into(),
            heartbeat: HeartbeatConfig::default(),
            protocol: ProtocolRange::this_build(),
            tls: None,
            dial_timeout: DEFAULT_DIAL_TIMEOUT,
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

    /// Give up a dial after `timeout` (default [`DEFAULT_DIAL_TIMEOUT`]): its connection, and
    /// then its session until ready. A session the peer turns away ends the wait at once,
    /// whatever the timeout; a longer one only lets a slow connection or handshake finish.
    pub fn with_dial_timeout(mut self, timeout: Duration) -> Self {
        self.dial_timeout = timeout;
        self
    }

    /// What ractor_cluster would otherwise take silently or fail on later. The public check
    /// is [`ClusterConfig::validate`], beside the transport whose error it answers.
    pub(crate) fn check(&self, node: &str) -> Result<(), ClusterConfigError> {
        if node.is_empty() || node.contains('@') || node.chars().any(char::is_whitespace) {
            return Err(ClusterConfigError::NodeName {
                name: node.to_string(),
            });
        }
        check_cookie(&self.cookie)?;
        self.heartbeat.validate()?;
        if self.dial_timeout.is_zero() {
            return Err(ClusterConfigError::DialTimeoutZero);
        }
        if let Some(&peer) = self.peers.iter().find(|p| p.port() == 0) {
            return Err(ClusterConfigError::PeerWithoutPort { peer });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_bad_cookie_is_matched_by_its_kind_and_keeps_its_text() {
        assert_eq!(check_cookie("thesis"), Ok(()));
        assert_eq!(check_cookie(""), Err(CookieError::Empty));
        assert_eq!(
            CookieError::Empty.to_string(),
            "the cookie must not be empty"
        );
        let long = "x".repeat(MAX_COOKIE_LEN + 1);
        let err = check_cookie(&long).unwrap_err();
        assert_eq!(
            err,
            CookieError::TooLong {
                len: MAX_COOKIE_LEN + 1,
                max: MAX_COOKIE_LEN
            }
        );
        assert_eq!(err.to_string(), "the cookie is longer than 256 bytes");
    }
}
