//! Everything an operation author needs, in one import: `use marie_actors::prelude::*;`.
//!
//! An operation touches five modules — [`eo`](crate::eo) for the trait and its context,
//! [`property`](marie_vocabulary::property) for parameters, [`flags`](marie_vocabulary::status) for its status
//! word, [`dm`](marie_dm) for the datamanagers, [`declare`](crate::declare) for the typed
//! declarations — and an author should not have to learn that layout before writing the
//! first one. The prelude re-exports the items of those modules that appear in an
//! operation's code, and the macros. Hosting, missions and the dispatcher are not an
//! operation's business and stay in their modules.
//!
//! ```
//! use marie_actors::prelude::*;
//!
//! marie_actors::params! {
//!     /// How long to wait.
//!     pub struct WaitParams {
//!         /// seconds to wait
//!         pub seconds: f64 = 1.0, range(0.0, 60.0), unit("s");
//!     }
//! }
//!
//! marie_actors::flags! {
//!     /// What waiting reports.
//!     pub enum WaitFlag {
//!         /// the time is up
//!         Elapsed = "elapsed",
//!     }
//! }
//!
//! const WAITS: RecordKind<f64> = RecordKind::new("wait").with_sub1("started");
//!
//! #[derive(Default)]
//! struct Wait { until: std::time::Duration }
//!
//! impl Operation for Wait {
//!     fn identity(&self) -> Identity { Identity::new("wait", 9003, "1.0.0", "waits") }
//!     fn parameters(&self) -> ParamSchema { WaitParams::schema() }
//!     fn flags(&self) -> Vec<FlagDecl> { WaitFlag::decls() }
//!     async fn activate(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
//!         let p: WaitParams = ctx.params().read()?;
//!         self.until = ctx.now() + std::time::Duration::from_secs_f64(p.seconds);
//!         ctx.dm(PARAMETER)?.put_kind(WAITS, &p.seconds)?;
//!         Ok(Step::Continue)
//!     }
//!     async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
//!         Ok(if ctx.now() >= self.until { Step::finish(WaitFlag::Elapsed) } else { Step::Continue })
//!     }
//! }
//! # let _ = Wait::default();
//! ```

pub use crate::declare::{
    DeclaredFlags, DeclaredParams, DmName, IntoParam, Param, ParamError, ParamMapExt, ParamValue,
};
pub use crate::eo::{Identity, OpContext, OpError, Operation, Params, Step};
pub use crate::{choice, flags, params};
pub use marie_dm::{
    DmClient, DmError, DmSpec, NewRecord, Query, Record, RecordHeader, RecordKind, FEATURE,
    PARAMETER, WORLD,
};
pub use marie_vocabulary::property::{FromValue, ParamDecl, ParamMap, ParamSchema, Value};
pub use marie_vocabulary::status::{FlagDecl, StatusFlags};
