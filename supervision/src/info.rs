//! Introspection: what a supervisor reports about its children (OTP's `which_children` and
//! `count_children`).

use std::time::Duration;

use ractor::ActorCell;

use crate::child::{ChildKind, Restart, Shutdown};

/// The state of one child.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ChildState {
    /// Running as this incarnation.
    Running(ActorCell),
    /// A start is in progress.
    Starting,
    /// Waiting to be restarted: queued behind another start, waiting for a backoff delay, or
    /// about to retry after a failed start (OTP's `restarting`).
    Restarting,
    /// Not running and not going to be restarted: terminated by `terminate_child`, or a
    /// transient child that exited normally, a child whose start answered ignore (OTP's
    /// `undefined`). Simple-one-for-one instances are never undefined: they are removed.
    Undefined,
}

impl ChildState {
    /// The running incarnation, if any.
    pub fn actor(&self) -> Option<&ActorCell> {
        match self {
            ChildState::Running(cell) => Some(cell),
            _ => None,
        }
    }
}

/// One child as [`crate::SupervisorRef::which_children`] reports it, in start order.
#[derive(Clone, Debug)]
pub struct ChildInfo {
    /// The child's id.
    pub id: String,
    /// Running, starting, restarting or undefined.
    pub state: ChildState,
    /// Its restart type.
    pub restart: Restart,
    /// Its shutdown.
    pub shutdown: Shutdown,
    /// Worker or supervisor.
    pub kind: ChildKind,
    /// How many times it has been restarted.
    pub restarts: u32,
    /// Its start timeout, if any.
    pub start_timeout: Option<Duration>,
}

/// Child counts as [`crate::SupervisorRef::count_children`] reports them (OTP's
/// `count_children`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ChildCounts {
    /// All child specs, running or not.
    pub specs: usize,
    /// Children that are running.
    pub active: usize,
    /// Specs of kind supervisor, running or not.
    pub supervisors: usize,
    /// Specs of kind worker, running or not.
    pub workers: usize,
}
