//! Errors of the supervisor's operations, of a child's start, and of a spec refused before
//! anything starts.

use std::time::Duration;

use ractor::SpawnErr;

use crate::exit::REACHED_MAX_RESTART_INTENSITY;
use crate::spec::MAX_EVENT_CAPACITY;
use crate::strategy::Strategy;

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
        /// How the start failed: refused by ractor, failed in the actor's start-up, panicked
        /// or timed out.
        reason: StartError,
    },
    /// The pending start of a child was abandoned because the child was terminated.
    #[error("child {0:?} was terminated before it started")]
    Terminated(String),
    /// The child's start answered [`crate::ChildStart::Ignore`] (OTP's `{ok, undefined}`): no
    /// actor runs. Not a failure of the supervisor: a static child's spec was kept, not
    /// running ([`crate::SupervisorRef::restart_child`] can try again later); a temporary
    /// child or a simple-one-for-one instance left nothing behind.
    #[error("child {0:?} ignored its start")]
    Ignored(String),
    /// A supervisor spec or child spec was refused before anything started (what was wrong
    /// is in the [`SpecError`]).
    #[error("invalid spec: {0}")]
    InvalidSpec(#[from] SpecError),
    /// The operation does not exist on a simple-one-for-one supervisor (OTP's
    /// `{error, simple_one_for_one}`): its children are instances of its template, started
    /// by [`crate::SupervisorRef::start_dynamic`] and stopped by
    /// [`crate::SupervisorRef::terminate_actor`]; they have no spec to restart or delete.
    #[error("not possible on a simple_one_for_one supervisor")]
    SimpleOneForOne,
    /// [`crate::SupervisorRef::start_dynamic`] on a supervisor that is not
    /// simple-one-for-one: it has no template to start an instance of.
    #[error("not a simple_one_for_one supervisor: no template to start an instance of")]
    NotSimpleOneForOne,
    /// [`crate::SupervisorRef::start_dynamic`] with an argument of another type than the
    /// template's start function takes; nothing was started.
    #[error("the template takes a {expected}, got a {got}")]
    WrongArgument {
        /// The template's argument type.
        expected: &'static str,
        /// The type given.
        got: &'static str,
    },
    /// The supervisor actor could not be spawned (e.g. its name is taken).
    #[error("cannot spawn the supervisor: {0}")]
    Spawn(StartError),
    /// The supervisor is not running (any more), so it cannot answer.
    #[error("the supervisor is not running")]
    NotRunning,
    /// The supervisor is shutting down.
    #[error("the supervisor is shutting down")]
    ShuttingDown,
    /// The supervisor exceeded its restart intensity and gave up.
    #[error("{}", REACHED_MAX_RESTART_INTENSITY)]
    ReachedMaxRestartIntensity,
    /// The program is built with `panic = "abort"`: a panicking child would end the process
    /// instead of reaching its supervisor, so no supervisor starts (see
    /// [`crate::require_unwinding`]).
    #[error(
        "supervisors need panics to unwind, but this program is built with `panic = \"abort\"`: \
         the first panic in an actor would end the whole process instead of reaching its \
         supervisor as a failure to restart from. Build with `panic = \"unwind\"` (Rust's \
         default): remove `panic = \"abort\"` from the profile in Cargo.toml (e.g. \
         `[profile.release]`) and `-C panic=abort` from RUSTFLAGS"
    )]
    PanicsAbort,
}

impl SupervisorError {
    /// The error of a failed supervisor spawn: the supervisor's own error when its start-up
    /// failed (a child failed to start, an invalid spec), otherwise ractor's.
    pub(crate) fn from_spawn(err: SpawnErr) -> Self {
        match err {
            SpawnErr::StartupFailed(inner) => match inner.downcast_ref::<SupervisorError>() {
                Some(own) => own.clone(),
                None => SupervisorError::Spawn(StartError::StartupFailed {
                    reason: inner.to_string(),
                }),
            },
            other => SupervisorError::Spawn(StartError::from(other)),
        }
    }
}

/// Why a child's start failed, by kind, so a caller can tell a name clash (fix the spec)
/// from a failing start-up (the child's own fault) from a start function that panicked or
/// hung. Plain data (the start's error as text), so [`SupervisorError`] stays `Clone` and
/// comparable; the texts are those of ractor's `SpawnErr` and of the supervisor's own
/// checks.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum StartError {
    /// ractor refused the spawn: another actor is registered under the child's name.
    #[error("Actor '{name}' is already registered in the actor registry")]
    NameTaken {
        /// The name the child asked for.
        name: String,
    },
    /// ractor refused the spawn: the actor had been started already.
    #[error("Actor cannot be re-started more than once")]
    AlreadyStarted,
    /// The actor's start-up (its `pre_start`) returned an error or panicked.
    #[error("Actor panicked during startup '{reason}'")]
    StartupFailed {
        /// The start-up's error, as text.
        reason: String,
    },
    /// The start function itself panicked, when called or while its future ran.
    #[error("start function panicked: {message}")]
    Panicked {
        /// The panic's message (`unknown panic` when it was neither a `String` nor a `&str`).
        message: String,
    },
    /// The start did not finish within the child's start timeout; it was abandoned.
    #[error("start timed out after {limit:?}")]
    TimedOut {
        /// The child's start timeout.
        limit: Duration,
    },
}

impl From<SpawnErr> for StartError {
    fn from(err: SpawnErr) -> Self {
        match err {
            SpawnErr::ActorAlreadyRegistered(name) => StartError::NameTaken { name },
            SpawnErr::ActorAlreadyStarted => StartError::AlreadyStarted,
            SpawnErr::StartupFailed(inner) => StartError::StartupFailed {
                reason: inner.to_string(),
            },
        }
    }
}

/// Why a supervisor spec or a child spec was refused.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum SpecError {
    /// The restart intensity's period is zero: no window to count restarts in (OTP's
    /// `invalid_period`).
    #[error("invalid period: the restart intensity's period must be longer than zero")]
    ZeroPeriod,
    /// The event channel capacity is 0 or above [`MAX_EVENT_CAPACITY`].
    #[error("invalid event capacity {0}: it must be within 1..={MAX_EVENT_CAPACITY}")]
    EventCapacity(usize),
    /// The backoff cannot work (the text says why).
    #[error("invalid backoff: {0}")]
    Backoff(String),
    /// A child spec's id is empty (or only blanks): it could not be addressed (OTP's
    /// `missing_id`).
    #[error("invalid child spec: the id is empty")]
    EmptyId,
    /// Two child specs share an id (OTP's `duplicate_child_name`).
    #[error("duplicate child id {0:?}")]
    DuplicateChildId(String),
    /// A shutdown timeout of zero: the child would be killed before it could stop (OTP's
    /// `invalid_shutdown`; say
    /// [`Shutdown::BrutalKill`](crate::Shutdown::BrutalKill) if that is meant).
    #[error("invalid shutdown of child {0:?}: a timeout of zero (use BrutalKill to kill at once)")]
    ZeroShutdownTimeout(String),
    /// A start timeout of zero: every start would fail.
    #[error("invalid start timeout of child {0:?}: zero would fail every start")]
    ZeroStartTimeout(String),
    /// A simple-one-for-one supervisor without a child template.
    #[error("a simple_one_for_one supervisor needs exactly one child template, it has none")]
    MissingTemplate,
    /// A child template given to a supervisor of another strategy.
    #[error("a child template is only for simple_one_for_one supervisors, not {0:?}")]
    TemplateWithoutSimpleOneForOne(Strategy),
    /// A simple-one-for-one supervisor given static children besides its template: its only
    /// child spec is the template, and every child is an instance of it (OTP's
    /// `bad_start_spec`).
    #[error(
        "a simple_one_for_one supervisor has exactly one child spec, its template; {0} static children given"
    )]
    SimpleOneForOneChildren(usize),
}
