//! # marie-cluster
//!
//! The node — what joins a cluster: its config ([`node::NodeConfig`]: what it hosts), its
//! supervision tree, the plug a robot fits into ([`node::Robot`]), and fault injection
//! ([`fault`]). Running marie's actors on several nodes over ractor_cluster (DESIGN.md §6)
//! builds on it: every cross-node frame travels in the versioned wire envelope, which lives
//! with the rest of the wire code in [`marie_actors::wire`] and is re-exported here as
//! [`envelope`]; joining, the failure detector and membership events come next.
//!
//! ```
//! use marie_cluster::envelope::{Envelope, PROTOCOL_VERSION};
//! let frame = Envelope::new("heartbeat", &42u64).unwrap().to_bytes().unwrap();
//! let back = Envelope::from_bytes(&frame).unwrap();
//! assert_eq!(back.version, PROTOCOL_VERSION);
//! assert_eq!(back.payload::<u64>().unwrap(), 42);
//! ```

#![warn(missing_docs)]

pub use marie_actors::wire::envelope;

pub mod fault;
pub mod layout;
pub mod net;
pub mod node;
