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
//!   parameters an enum (see [`DeclaredParams`], [`ParamValue`]);
//! - [`flags!`](crate::flags!) — an enum of flags whose variant is both the declaration and the
//!   bit (see [`DeclaredFlags`]);
//! - [`Migrations`] — how a parameter of an older version maps onto this version's (a
//!   rename), for a binding that moves to a newer version mid-mission;
//! - [`DmName`] — datamanagers by constant ([`marie_dm::FEATURE`]);
//! - [`RecordKind<T>`](marie_dm::RecordKind) — a record's class, sub-classes and payload
//!   type (with the datamanagers, whose records it makes and selects).
//!
//! None of it replaces the string interfaces: the generated code calls them, and operations
//! declared by hand keep working. No proc-macro crate is involved; the macros are
//! `macro_rules!`, so the build stays as lean as it was.
//!
//! [`ParamSchema`]: marie_vocabulary::property::ParamSchema
//! [`ParamDecl`]: marie_vocabulary::property::ParamDecl
//!
//! ```
//! use marie_actors::prelude::*;
//!
//! marie_actors::params! {
//!     /// The countdown's parameters.
//!     pub struct CountdownParams {
//!         /// where to count down from
//!         pub from: i64 = 3, range(0, 100);
//!     }
//! }
//!
//! marie_actors::flags! {
//!     /// What the countdown reports.
//!     pub enum CountdownFlag {
//!         /// reached zero
//!         Zero = "zero",
//!     }
//! }
//!
//! #[derive(Default)]
//! struct Countdown { left: i64 }
//!
//! impl Operation for Countdown {
//!     fn identity(&self) -> Identity { Identity::new("countdown", 9002, "1.0.0", "counts to zero") }
//!     fn parameters(&self) -> ParamSchema { CountdownParams::schema() }
//!     fn flags(&self) -> Vec<FlagDecl> { CountdownFlag::decls() }
//!     async fn activate(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
//!         self.left = ctx.params().read::<CountdownParams>()?.from;
//!         Ok(Step::Continue)
//!     }
//!     async fn step(&mut self, _ctx: &mut OpContext) -> Result<Step, OpError> {
//!         self.left -= 1;
//!         Ok(if self.left <= 0 { Step::finish(CountdownFlag::Zero) } else { Step::Continue })
//!     }
//! }
//! # #[tokio::main(flavor = "current_thread")] async fn main() {
//! use marie_actors::eo::{self, EoClient, EoReport};
//! let (actor, _) = eo::spawn_operation(Countdown::default(), Default::default()).await.unwrap();
//! let client = EoClient::new(actor.clone());
//! let update = ParamMap::new().with(CountdownParams::from(), 5);
//! let report = client.activate(update, 1).unwrap().await.unwrap();
//! assert!(matches!(report, EoReport::Finished { flags, .. } if flags == CountdownFlag::Zero.into()));
//! actor.stop(None);
//! # }
//! ```

mod choice;
mod dm;
mod flags;
mod migration;
mod params;

pub use dm::DmName;
pub use flags::DeclaredFlags;
pub use migration::{Migrations, MigrationsError, Rename};
pub use params::{Bound, DeclaredParams, IntoParam, Param, ParamError, ParamMapExt, ParamValue};
