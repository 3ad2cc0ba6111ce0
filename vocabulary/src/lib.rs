//! # marie-vocabulary
//!
//! The words every layer of marie speaks, and nothing that acts on them: the datamanagers
//! (`marie-dm`), the operations and the dispatcher (`marie-actors`), the node and the cluster
//! (`marie-cluster`), the robot and the monitor all say a run's facts in these types, so a
//! crate that only reads a run — the monitor, a tool over an events file — depends on this
//! one alone.
//!
//! - [`run`] — a run's vocabulary: how a run and an operation's part end, why a binding was
//!   lost, rebinds, choices, fault kinds, provenance;
//! - [`events`] — one typed event stream per node ([`events::EventBus`]), every fact of a run
//!   as an [`events::Event`];
//! - [`report`] — the run report, the fold of a run's events;
//! - [`property`] — the property interface: parameter declarations, values, and the
//!   requests any module can send an operation about itself;
//! - [`status`] — the 32-bit status word operations report;
//! - [`clock`] — time for operations and datamanagers: real, scaled or simulated;
//! - [`registry`] — the cluster-wide location table over ractor `pg`;
//! - [`replica`] — a replicated datamanager's replica roles: leader and follower;
//! - [`fence`] — fencing tokens: the epochs a receiver of commands admits;
//! - [`wire`] — the wire form of every message that may cross nodes (rmp-serde);
//! - [`diagnostic`] — `file:line:column` diagnostics and the TOML reader every file format
//!   (missions, worlds, node configs) shares.
//!
//! Its modules import one another without a cycle, in this order from the ground up:
//! `clock`, `status`, `replica`, `wire`, `registry`, `diagnostic`; `property`, `fence`; `run`;
//! `events`; `report`.
//!
//! ```
//! use marie_vocabulary::status::StatusFlags;
//! let status = StatusFlags(0b0110);
//! assert!(status.implies(StatusFlags(0b0100)));
//! ```

#![warn(missing_docs)]

pub mod clock;
pub mod diagnostic;
pub mod events;
pub mod fence;
pub mod property;
pub mod registry;
pub mod replica;
pub mod report;
pub mod run;
pub mod status;
pub mod wire;
