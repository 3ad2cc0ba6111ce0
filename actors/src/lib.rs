//! # marie-actors
//!
//! The three interfaces of the MARIE control architecture as [ractor] actors, plus the
//! location table and the action dispatcher:
//!
//! - [`eo`] — elementary operations: the [`eo::Operation`] trait an author implements and the
//!   EO host actor that runs it (activate, suspend, atomic reparameterization, 32-bit status
//!   flags);
//! - [`property`] — the property interface: parameter declarations, values, and the requests
//!   any module can send an operation about itself;
//! - [`dm`] — datamanagers: records stored, selected (also by waiting), deleted by query;
//! - [`registry`] — the cluster-wide location table over ractor `pg`;
//! - [`dispatcher`] — missions (task trees) and the action dispatcher that runs them;
//! - [`run`] — a run's vocabulary (outcomes, loss causes, rebinds, choices, fault kinds),
//!   below both the events and the dispatcher; [`report`] — the run report, the fold of a
//!   run's events;
//! - [`diagnostic`] — `file:line:column` diagnostics and the TOML reader every file format
//!   (missions, worlds, node configs) shares.
//! - [`events`] — one typed event stream per node: the [`events::EventBus`].
//! - [`declare`] — typed declarations of an operation's parameters ([`params!`]), flags
//!   ([`flags!`]), datamanagers and record kinds, so that a misspelt name is a compile error;
//!   [`prelude`] brings everything an operation author needs in one `use`.
//!
//! Every message that may cross nodes is serializable with rmp-serde ([`wire`]).
//!
//! ```
//! use marie_actors::status::StatusFlags;
//! let status = StatusFlags(0b0110);
//! assert!(status.implies(StatusFlags(0b0100)));
//! ```

#![warn(missing_docs)]

pub mod clock;
pub mod declare;
pub mod diagnostic;
pub mod dispatcher;
pub mod dm;
pub mod eo;
pub mod events;
pub mod fence;
pub mod prelude;
pub mod property;
pub mod provision;
pub mod registry;
pub mod report;
pub mod run;
pub mod status;
pub mod wire;
