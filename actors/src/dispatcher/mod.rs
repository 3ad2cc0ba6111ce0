//! Missions and the action dispatcher.
//!
//! A [`mission::Mission`] is a task tree loaded from TOML and checked against the operations
//! that are actually running ([`RegistryCatalog`]); [`run_mission`] runs it with an
//! [`ActionDispatcher`] and returns a [`RunReport`]. Its progress is published on an
//! [`EventBus`](crate::events::EventBus); the report is rebuilt from those events by
//! [`RunReport::from_events`] (bounded: see [`REPORT_KEEPS`]), and [`DispatchEvent`] is the
//! live-line view of them.

mod actor;
mod assembly;
mod binding;
mod builder;
mod candidates;
mod catalog;
mod healing;
mod loss;
mod messages;
pub mod mission;
mod progress;
mod report;
mod running;
pub mod selection;
pub mod survey;
mod verdict;

pub use actor::{
    request_run, run_mission, spawn_dispatcher, ActionDispatcher, DispatchError, DispatcherArgs,
    DispatcherState, DISPATCHER_ID,
};
pub use builder::ReportBuilder;
pub use candidates::describe;
pub use catalog::RegistryCatalog;
pub use loss::LossCause;
pub use messages::DispatcherMsg;
pub use progress::{DispatchEvent, ProgressRelay};
pub use report::{
    ActionRecord, FaultRecord, OpEnd, OpRecord, Outcome, RebindRecord, RunReport, REPORT_KEEPS,
};
pub use survey::{survey, Survey};
