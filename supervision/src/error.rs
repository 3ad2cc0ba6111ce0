//! Errors of the supervisor's operations.

use ractor::SpawnErr;

use crate::exit::REACHED_MAX_RESTART_INTENSITY;

/// Why a supervisor operation failed.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum SupervisorError {
    /// `start_child` with the id of a running child.
    #[error("child {0:?} is already started")]
    AlreadyStarted(String),
    /// `start_child` with the id of a child that is present but not running (delete it first).
    #[error("child {0:?} is already present")]
    AlreadyPresent(String),
    /// No child has this id.
    #[error("no child {0:?}")]
    NotFound(String),
    /// The operation needs a stopped child, but it runs.
    #[error("child {0:?} is running")]
    Running(String),
    /// The operation needs a stopped child, but it is being (re)started.
    #[error("child {0:?} is restarting")]
    Restarting(String),
    /// A child's start function failed.
    #[error("child {id:?} failed to start: {reason}")]
    StartFailed {
        /// The child's id.
        id: String,
        /// The start function's error.
        reason: String,
    },
    /// The pending start of a child was abandoned because the child was terminated.
    #[error("child {0:?} was terminated before it started")]
    Terminated(String),
    /// Two child specs share an id.
    #[error("duplicate child id {0:?}")]
    DuplicateChildId(String),
    /// The supervisor actor could not be spawned (e.g. its name is taken).
    #[error("cannot spawn the supervisor: {0}")]
    Spawn(String),
    /// The supervisor is not running (any more), so it cannot answer.
    #[error("the supervisor is not running")]
    NotRunning,
    /// The supervisor is shutting down.
    #[error("the supervisor is shutting down")]
    ShuttingDown,
    /// The supervisor exceeded its restart intensity and gave up.
    #[error("{}", REACHED_MAX_RESTART_INTENSITY)]
    ReachedMaxRestartIntensity,
}

impl SupervisorError {
    /// The error of a failed supervisor spawn: the supervisor's own error when its start-up
    /// failed (a child failed to start, duplicate ids), otherwise ractor's.
    pub(crate) fn from_spawn(err: SpawnErr) -> Self {
        match err {
            SpawnErr::StartupFailed(inner) => match inner.downcast_ref::<SupervisorError>() {
                Some(own) => own.clone(),
                None => SupervisorError::Spawn(inner.to_string()),
            },
            other => SupervisorError::Spawn(other.to_string()),
        }
    }
}
