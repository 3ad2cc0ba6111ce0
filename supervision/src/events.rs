//! What a supervisor reports as it works, so tests and embedders can wait for it instead of
//! sleeping, and a node can log or count restarts.

use std::time::Duration;

use ractor::{ActorCell, ActorId};

use crate::error::StartError;
use crate::exit::ExitReason;

/// Why a child is being restarted.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum RestartCause {
    /// The child itself stopped, for this reason.
    Exited(ExitReason),
    /// It was restarted together with the child of this id (one-for-all, rest-for-one).
    Sibling(String),
    /// Someone called [`crate::SupervisorRef::restart_child`].
    Manual,
}

/// One step of a supervisor's work, broadcast to every subscriber
/// ([`crate::SupervisorRef::subscribe`]).
#[derive(Clone, Debug)]
pub enum SupervisorEvent {
    /// A child started for the first time (at supervisor start or by `start_child`).
    ChildStarted {
        /// The child's id.
        id: String,
        /// The new incarnation.
        actor: ActorCell,
    },
    /// A child stopped by itself (crash, normal stop, killed by someone else). The supervisor
    /// decides next whether to restart it.
    ChildExited {
        /// The child's id.
        id: String,
        /// The incarnation that stopped.
        actor: ActorId,
        /// Why it stopped.
        reason: ExitReason,
    },
    /// The supervisor stopped a child itself (sibling restart, `terminate_child`, shutdown).
    ChildShutdown {
        /// The child's id.
        id: String,
        /// The incarnation that was stopped.
        actor: ActorId,
        /// It had to be killed (brutal kill, or it outlived its shutdown timeout).
        killed: bool,
    },
    /// A restart waits for a backoff delay before its start attempt.
    RestartScheduled {
        /// The child whose exit (or failed start) triggered the restart.
        id: String,
        /// How long the supervisor waits.
        delay: Duration,
        /// 0 for the first attempt since the child last ran stably.
        attempt: u32,
    },
    /// A child was started again.
    ChildRestarted {
        /// The child's id.
        id: String,
        /// Its previous incarnation, if it had one.
        old: Option<ActorId>,
        /// The new incarnation.
        new: ActorCell,
        /// Why it was restarted.
        cause: RestartCause,
        /// How many times this child has been restarted, this time included.
        restarts: u32,
    },
    /// A restart attempt failed (the start function returned an error, panicked or timed
    /// out). The supervisor tries again, counting the attempt in its restart intensity.
    RestartFailed {
        /// The child's id.
        id: String,
        /// Why the start failed.
        error: StartError,
    },
    /// A child's start answered [`crate::ChildStart::Ignore`]: it does not run. A static
    /// child stays, not running ([`crate::ChildState::Undefined`]); a temporary child or a
    /// simple-one-for-one instance is dropped. Not a failure: no restart, no intensity.
    ChildIgnored {
        /// The child's id.
        id: String,
    },
    /// A child was removed from the supervisor (a temporary child stopped, or
    /// `delete_child`).
    ChildDeleted {
        /// The child's id.
        id: String,
    },
    /// More than `max_restarts` restarts within `period`: the supervisor stops its children
    /// and fails with [`crate::REACHED_MAX_RESTART_INTENSITY`].
    IntensityExceeded {
        /// The configured limit.
        max_restarts: usize,
        /// The configured window.
        period: Duration,
    },
    /// The supervisor has stopped all its children and is terminating; the last event.
    Stopped {
        /// [`crate::SHUTDOWN`] or [`crate::REACHED_MAX_RESTART_INTENSITY`].
        reason: String,
    },
}

impl SupervisorEvent {
    /// The id of the child the event is about, if it is about one.
    pub fn child_id(&self) -> Option<&str> {
        match self {
            SupervisorEvent::ChildStarted { id, .. }
            | SupervisorEvent::ChildExited { id, .. }
            | SupervisorEvent::ChildShutdown { id, .. }
            | SupervisorEvent::RestartScheduled { id, .. }
            | SupervisorEvent::ChildRestarted { id, .. }
            | SupervisorEvent::RestartFailed { id, .. }
            | SupervisorEvent::ChildIgnored { id }
            | SupervisorEvent::ChildDeleted { id } => Some(id),
            SupervisorEvent::IntensityExceeded { .. } | SupervisorEvent::Stopped { .. } => None,
        }
    }
}
