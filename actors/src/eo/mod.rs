//! The eo-interface: elementary operations and the actor that hosts them.
//!
//! An author implements [`Operation`]; [`spawn_operation`] runs it in an [`EoHost`] that
//! speaks [`EoMsg`]: activation, suspension, atomic reparameterization and the property
//! interface, with [`EoClient`] as the typed way to send them. An application reads and sets
//! an operation through an [`OperationHandle`]: by name, typed, without epochs, following
//! the operation across restarts of its instances.
//!
//! The example declares parameters and flags by hand, by name and bit; [`crate::declare`]
//! declares them once as Rust types (`params!`, `flags!`), with one import from
//! [`crate::prelude`].
//!
//! ```
//! use marie_actors::eo::{self, Identity, Operation, OpContext, OpError, Step, EoClient};
//! use marie_vocabulary::status::{FlagDecl, StatusFlags};
//! use marie_vocabulary::property::{ParamDecl, ParamSchema, ParamMap};
//!
//! struct Countdown { left: i64 }
//! impl Operation for Countdown {
//!     fn identity(&self) -> Identity { Identity::new("countdown", 9001, "1.0.0", "counts to zero") }
//!     fn parameters(&self) -> ParamSchema { ParamSchema::new(vec![ParamDecl::int("from", 3).range(0.0, 100.0)]) }
//!     fn flags(&self) -> Vec<FlagDecl> { vec![FlagDecl::new("zero", "reached zero")] }
//!     async fn activate(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
//!         self.left = ctx.params().i64("from")?;
//!         Ok(Step::Continue)
//!     }
//!     async fn step(&mut self, _ctx: &mut OpContext) -> Result<Step, OpError> {
//!         self.left -= 1;
//!         Ok(if self.left <= 0 { Step::Finish(StatusFlags(1)) } else { Step::Continue })
//!     }
//! }
//! # #[tokio::main(flavor = "current_thread")] async fn main() {
//! let (actor, _) = eo::spawn_operation(Countdown { left: 0 }, Default::default()).await.unwrap();
//! let client = EoClient::new(actor.clone());
//! let report = client.activate(ParamMap::new(), 1).unwrap().await.unwrap();
//! assert!(matches!(report, eo::EoReport::Finished { flags: StatusFlags(1), .. }));
//! actor.stop(None);
//! # }
//! ```

mod absence;
mod client;
mod declaration;
mod factory;
mod handle;
mod handle_error;
mod host;
mod messages;
mod operation;

pub use client::{EoClient, EoError};
pub use declaration::{check_declaration, DeclarationError, Declared, MAX_FLAGS};
pub use factory::{OperationFactory, StartOperation};
pub use handle::OperationHandle;
pub use handle_error::{HandleError, SetError};
pub use host::{
    spawn_operation, spawn_operation_linked, EoHost, HostArgs, HostOptions, HostState, PINNED,
};
pub use messages::{EoMsg, EoReport, ParamOutcome};

/// How long an operation may take to answer a command unless it declares otherwise
/// ([`Operation::deadline`]).
pub const DEFAULT_DEADLINE: std::time::Duration =
    std::time::Duration::from_millis(marie_vocabulary::property::DEFAULT_DEADLINE_MS);
/// Time between an operation's steps unless it declares otherwise ([`Operation::period`]):
/// 100 ms of the node's clock.
pub const DEFAULT_PERIOD: std::time::Duration = std::time::Duration::from_millis(100);
/// How long an operation whose datamanager is gone (killed, crashed: no longer registered,
/// or its actor stopped) — or another module it needs ([`OpError::Unreachable`]: the cart,
/// whose node was lost or cut off from the operation's) — waits for the module's next
/// incarnation before it fails: its host holds its steps, answers every command meanwhile,
/// and steps again once the module is published again (by its supervisor, or by its node
/// coming back). Measured on the runtime's timer, not the node's
/// clock: real time on a node, and in a simulation's paused runtime virtual time that
/// stands still while anything (a restart) is being done — so it runs out only when nothing
/// is left that could bring the DM back.
pub const DATAMANAGER_RETURN: std::time::Duration = marie_dm::DmClient::DEFAULT_FOLLOW;
pub use operation::{Identity, OpContext, OpError, Operation, Params, Step};
