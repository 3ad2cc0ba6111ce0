//! The transport: a node's ractor_cluster `NodeServer`, the peers it dials, and whom it sees.
//!
//! A node that joins a cluster listens on its [`ClusterConfig::listen`] address and dials
//! every configured peer (any one is enough: a node also dials every peer its peers see,
//! so the cluster becomes a full mesh, which `pg` needs — membership is pushed only to
//! directly connected nodes). A peer that goes away is redialled with backoff for as long
//! as the transport runs. Each peer is known by its configured node name: ractor names
//! nodes `name@host` and numbers sessions afresh on every reconnect, so the transport records
//! the name behind each session number in the registry, which then shows every remote
//! module with its node. With [`ClusterConfig::tls`], every session is mutual TLS ([`tls`]).
//!
//! ractor_cluster has no failure detector: [`heartbeat`] adds one (default: a silent peer
//! is declared down within 1.5 s), and refuses peers of another protocol version.
//!
//! A node joins a cluster through its config: [`NodeBuilder::cluster`] or
//! [`NodeConfig::with_cluster`] — [`Node::start`] then starts its transport, puts the
//! cluster's news on its bus, and [`Node::shutdown`] leaves. Starting a [`Transport`] by
//! hand, as below, is the low road, for a member that runs no node of its own (the CLI's
//! `ls --join`, `kill --join`).
//!
//! [`NodeBuilder::cluster`]: crate::node::NodeBuilder::cluster
//! [`NodeConfig::with_cluster`]: crate::node::NodeConfig::with_cluster
//! [`Node::start`]: crate::node::Node::start
//! [`Node::shutdown`]: crate::node::Node::shutdown
//!
//! ```no_run
//! # async fn demo() -> Result<(), marie_cluster::net::TransportError> {
//! use marie_cluster::net::{ClusterConfig, Transport};
//! use std::time::Duration;
//! let config = ClusterConfig::new("127.0.0.1:7101".parse().unwrap(), "secret")
//!     .with_peer("127.0.0.1:7100".parse().unwrap());
//! let transport = Transport::start("beta", &config).await?;
//! let peers = transport.wait_for_peers(1, Duration::from_secs(10)).await?;
//! println!("beta sees {}", peers[0].name);
//! transport.stop().await;
//! # Ok(()) }
//! ```

mod agreement;
mod auth;
mod config;
pub mod detector;
mod dialed;
mod events;
pub mod heartbeat;
pub mod listener;
mod publish;
mod sessions;
pub mod tls;
mod transport;

pub use agreement::Agreement;
pub use config::{
    check_cookie, ClusterConfig, ClusterConfigError, CookieError, DEFAULT_DIAL_TIMEOUT,
    MAX_COOKIE_LEN,
};
pub use detector::{HeartbeatConfig, HeartbeatError};
pub use events::{NetEvent, UPGRADE_ADVICE};
pub use publish::publish_on;
pub use sessions::Peer;
pub use tls::{TlsError, TlsFile, TlsFiles};
pub use transport::{Transport, TransportError};
