//! Missions and the action dispatcher.
//!
//! A [`mission::Mission`] is a task tree loaded from TOML and checked against the operations
//! that are actually running ([`RegistryCatalog`]); [`run_mission`] runs it with an
//! [`ActionDispatcher`] and returns a [`RunReport`].

mod actor;
mod assembly;
mod binding;
mod catalog;
mod healing;
mod loss;
mod messages;
pub mod mission;
mod report;
mod running;

pub use actor::{
    request_run, run_mission, spawn_dispatcher, ActionDispatcher, DispatchError, DispatcherArgs,
    DispatcherState, DISPATCHER_ID,
};
pub use catalog::{describe, RegistryCatalog};
pub use loss::LossCause;
pub use messages::{DispatchEvent, DispatcherMsg};
pub use report::{
    ActionRecord, FaultRecord, OpEnd, OpRecord, Outcome, RebindRecord, RunReport, REPORT_KEEPS,
};
