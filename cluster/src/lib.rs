//! # marie-cluster
//!
//! Running marie's actors on several nodes over ractor_cluster (DESIGN.md §6). It starts with
//! the versioned wire envelope every cross-node frame travels in; node bootstrap, the failure
//! detector and membership events build on it.
//!
//! ```
//! use marie_cluster::envelope::{Envelope, WIRE_VERSION};
//! let frame = Envelope::new("heartbeat", &42u64).unwrap().to_bytes().unwrap();
//! let back = Envelope::from_bytes(&frame).unwrap();
//! assert_eq!(back.version, WIRE_VERSION);
//! assert_eq!(back.payload::<u64>().unwrap(), 42);
//! ```

#![warn(missing_docs)]

pub mod envelope;
