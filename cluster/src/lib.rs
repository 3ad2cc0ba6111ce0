//! # marie-cluster
//!
//! The node — what joins a cluster: its config ([`node::NodeConfig`]: what it hosts), its
//! supervision tree, the plug a robot fits into ([`node::Robot`]), and fault injection
//! ([`fault`]); the transport that makes nodes a cluster over ractor_cluster ([`net`]:
//! joining, a full mesh, heartbeats and the failure detector, TLS), a cluster file of
//! several nodes ([`layout`]), and every node's events for whoever watches the cluster
//! ([`relay`]). Every cross-node frame travels in the versioned wire envelope, which lives
//! with the rest of the wire code in [`marie_vocabulary::wire`] and is re-exported here as
//! [`envelope`].
//!
//! ```
//! use marie_cluster::envelope::{Envelope, PROTOCOL_VERSION};
//! let frame = Envelope::new("heartbeat", &42u64).unwrap().to_bytes().unwrap();
//! let back = Envelope::from_bytes(&frame).unwrap();
//! assert_eq!(back.version, PROTOCOL_VERSION);
//! assert_eq!(back.payload::<u64>().unwrap(), 42);
//! ```

#![warn(missing_docs)]

pub use marie_vocabulary::wire::envelope;

pub mod fault;
pub mod layout;
pub mod net;
pub mod node;
pub mod relay;
pub mod replicas;
