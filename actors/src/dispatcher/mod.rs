//! Missions and the action dispatcher.
//!
//! A [`mission::Mission`] is a task tree loaded from TOML and checked against the operations
//! that are actually running ([`RegistryCatalog`]); [`run_mission`] runs it with an
//! [`ActionDispatcher`] and returns a [`RunReport`].

mod actor;
mod binding;
mod catalog;
pub mod mission;
mod report;

pub use actor::{
    request_run, run_mission, spawn_dispatcher, ActionDispatcher, DispatchError, DispatchEvent,
    DispatcherArgs, DispatcherMsg, DispatcherState, DISPATCHER_ID,
};
pub use catalog::{describe, RegistryCatalog};
pub use report::{ActionRecord, FaultRecord, OpRecord, Outcome, RebindRecord, RunReport};
