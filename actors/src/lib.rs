//! # marie-actors
//!
//! Elementary operations and the action dispatcher that runs them, as [ractor] actors — the
//! acting part of marie, on the words of `marie-vocabulary` and the datamanagers of
//! `marie-dm`:
//!
//! - [`eo`] — elementary operations: the [`eo::Operation`] trait an author implements and the
//!   EO host actor that runs it (activate, suspend, atomic reparameterization, 32-bit status
//!   flags), and [`eo::OperationHandle`], an application's hold on one by name;
//! - [`declare`] — typed declarations of an operation's parameters ([`params!`]), flags
//!   ([`flags!`]), datamanagers and record kinds, so that a misspelt name is a compile error;
//!   [`prelude`] brings everything an operation author needs in one `use`;
//! - [`provision`] — asking the cluster for an operation no node runs yet (standbys);
//! - [`dispatcher`] — missions (task trees, behaviour trees) and the action dispatcher that
//!   runs them: selection, binding, healing, checkpoints and takeover.
//!
//! ```
//! use marie_actors::prelude::*;
//!
//! flags! {
//!     pub enum DoorFlag {
//!         /// the door is open
//!         Open = "open",
//!     }
//! }
//! assert_eq!(DoorFlag::Open.name(), "open");
//! ```

#![warn(missing_docs)]

pub mod declare;
pub mod dispatcher;
pub mod eo;
pub mod prelude;
pub mod provision;

/// What the declaration macros ([`params!`], [`flags!`], [`choice!`]) expand to names
/// through `$crate`, so that a crate using them needs no dependency of its own on the
/// vocabulary. Not a public path.
#[doc(hidden)]
pub mod __private {
    pub use marie_vocabulary::{property, status};
}
