//! # marie-cluster
//!
//! Running marie's actors on several nodes over ractor_cluster (DESIGN.md §6). Every
//! cross-node frame travels in the versioned wire envelope, which lives with the rest of the
//! wire code in [`marie_actors::wire`] and is re-exported here as [`envelope`]; node
//! bootstrap, the failure detector and membership events build on it.
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
