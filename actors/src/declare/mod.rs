//! Typed declarations: an operation's parameters, flags, datamanagers and record kinds
//! declared once, in Rust, so that a misspelt name is a compile error.
//!
//! # Why
//! The interfaces name everything by string — parameters (`ctx.params().i64("start")`),
//! flags (by position: `StatusFlags(1)` is "the first declared flag"), datamanagers
//! (`ctx.dm("feature")`), record classes (`Query::class("wall")`). That is right on the wire
//! and in mission files, which are written by people and checked when they are loaded; in an
//! operation's own code it means each name is written twice, once where it is declared and
//! once where it is used, and a typo between the two shows only when the operation runs.
//! The declarations here generate both sides from one:
//!
//! - [`params!`](crate::params) — a struct of parameters: its [`ParamSchema`] (exactly the
//!   [`ParamDecl`]s written by hand), its defaults, a typed read (`ctx.params().read()`) and
//!   a typed key per parameter ([`Param<T>`]); [`choice!`](crate::choice) gives choice
//!   parameters an enum ([`params`], [`choice`]);
//! - [`flags!`](crate::flags!) — an enum of flags whose variant is both the declaration and the
//!   bit ([`flags`]);
//! - [`DmName`] — datamanagers by constant ([`crate::dm::FEATURE`]) ([`dm`]);
//! - [`RecordKind<T>`] — a record's class, sub-classes and payload type ([`records`]).
//!
//! None of it replaces the string interfaces: the generated code calls them, and operations
//! declared by hand keep working. No proc-macro crate is involved; the macros are
//! `macro_rules!`, so the build stays as lean as it was.
//!
//! [`ParamSchema`]: crate::property::ParamSchema
//! [`ParamDecl`]: crate::property::ParamDecl
//!
//! ```
//! use marie_actors::declare::{DeclaredParams, ParamMapExt};
//! use marie_actors::property::ParamMap;
//!
//! marie_actors::params! {
//!     /// The countdown's parameters.
//!     pub struct CountdownParams {
//!         /// where to count down from
//!         pub from: i64 = 3, range(0, 100);
//!     }
//! }
//! assert_eq!(CountdownParams::schema().get("from").map(|d| d.max), Some(Some(100.0)));
//! let update = ParamMap::new().with(CountdownParams::from(), 5);
//! assert_eq!(CountdownParams::from_map(&update), Ok(CountdownParams { from: 5 }));
//! ```

pub mod choice;
pub mod dm;
pub mod flags;
pub mod params;
pub mod records;

pub use dm::DmName;
pub use flags::DeclaredFlags;
pub use params::{Bound, DeclaredParams, IntoParam, Param, ParamError, ParamMapExt, ParamValue};
pub use records::RecordKind;
