//! Missions and the action dispatcher.
//!
//! A [`mission::Mission`] is a task tree loaded from TOML and checked against the operations
//! that are actually running ([`RegistryCatalog`]), carrying the instances that check chose
//! ([`CheckedChoices`]). An [`ActionDispatcher`] runs it, binding those choices unless an
//! instance changed since: every step is an event on the node's
//! [`EventBus`](marie_vocabulary::events::EventBus), and the run's report is those events folded
//! ([`marie_vocabulary::report`]).
//!
//! This is the low layer. An application runs missions on a node
//! (`marie_cluster::node::Node::run`), which adds what a run needs around the dispatcher:
//! the node's supervision, faults, a robot's judgement, and the report folded from the
//! node's one bus. [`run_mission`] runs a dispatcher alone (a test, a tool), folding its
//! own events into the report.

mod actor;
mod assembly;
mod binding;
mod candidates;
mod catalog;
mod checked;
pub mod checkpoint;
mod effect;
mod healing;
mod messages;
pub mod mission;
pub mod plan;
mod rollback;
mod running;
pub mod selection;
pub mod survey;
mod takeover;
pub mod tree;
pub mod upgrade;
pub mod upgrade_check;
mod upgrading;

pub use actor::{
    request_run, run_mission, spawn_dispatcher, ActionDispatcher, DispatchError, DispatcherArgs,
    DispatcherState, TakeOver, DISPATCHER_ID,
};
pub use candidates::describe;
pub use catalog::RegistryCatalog;
pub use checked::CheckedChoices;
pub use messages::DispatcherMsg;
pub use survey::{survey, Survey};
