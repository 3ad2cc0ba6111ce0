//! Child specifications: how a supervisor starts one child, when it restarts it, and how it
//! stops it (OTP's child spec: id, start, restart, shutdown, type).

use std::fmt;
use std::future::Future;
use std::pin::Pin;
use std::sync::Arc;
use std::time::Duration;

use ractor::{Actor, ActorCell, SpawnErr};
use serde::{Deserialize, Serialize};

use crate::exit::ExitReason;

/// What a successful start function produced: OTP's `{ok, Pid}` or `ignore`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ChildStart {
    /// The child runs as this actor, linked to the supervisor.
    Started(ActorCell),
    /// The child chose not to run now (OTP's `ignore`) — say, an operation whose device is
    /// absent on this robot. That is not a failure: nothing counts toward the restart
    /// intensity. A static child keeps its spec, not running
    /// ([`crate::ChildState::Undefined`]), so [`crate::SupervisorRef::restart_child`] can
    /// start it later; a temporary child, and any instance of a simple-one-for-one
    /// supervisor, leaves nothing behind.
    Ignore,
}

impl ChildStart {
    /// The started actor, if the child did not ignore its start.
    pub fn actor(&self) -> Option<&ActorCell> {
        match self {
            ChildStart::Started(cell) => Some(cell),
            ChildStart::Ignore => None,
        }
    }
}

impl From<ActorCell> for ChildStart {
    fn from(cell: ActorCell) -> Self {
        ChildStart::Started(cell)
    }
}

/// The future a start function returns: the new child (or [`ChildStart::Ignore`]), or why it
/// could not start.
pub type StartFuture = Pin<Box<dyn Future<Output = Result<ChildStart, SpawnErr>> + Send>>;

/// A start function. It is given the supervisor's cell and **must spawn the child linked to
/// it** (`Actor::spawn_linked(.., supervisor)`), since the supervisor learns of the child's
/// exits only through ractor's link. It is called again for every restart, so it must be able
/// to build fresh arguments each time. Spawning should be its last step: a start that is
/// abandoned (timeout, supervisor shutdown) is dropped at whatever `.await` it is in.
pub type StartFn = Arc<dyn Fn(ActorCell) -> StartFuture + Send + Sync>;

/// When a stopped child is restarted (OTP's restart type).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Restart {
    /// Always restarted, whatever the exit reason: a service that must be there.
    Permanent,
    /// Restarted only after an abnormal exit: a job that may finish, but not crash.
    Transient,
    /// Never restarted, and forgotten once it stops: a one-off task.
    Temporary,
}

impl Restart {
    /// Whether a child of this type is restarted after an exit for `reason`.
    pub fn restarts_after(self, reason: &ExitReason) -> bool {
        match self {
            Restart::Permanent => true,
            Restart::Transient => reason.is_abnormal(),
            Restart::Temporary => false,
        }
    }
}

/// How a supervisor stops a child (OTP's shutdown).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Shutdown {
    /// Kill at once: the child's `post_stop` does not run. (A kill takes effect at the
    /// child's next `.await`; an actor stuck in blocking code cannot be killed by anyone, and
    /// the supervisor gives up waiting for it after a few seconds.)
    BrutalKill,
    /// Ask it to stop (reason [`crate::SHUTDOWN`], so `post_stop` runs), wait up to this
    /// long, then kill it.
    Timeout(Duration),
    /// Ask it to stop and wait as long as it takes: for child supervisors, which need the
    /// time to stop their own children in order.
    Infinity,
}

/// Whether a child is a worker or a supervisor itself (OTP's child type). Reported by
/// introspection; the default shutdown differs (workers 5 s, supervisors infinity).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ChildKind {
    /// An ordinary actor.
    Worker,
    /// A supervisor of its own children.
    Supervisor,
}

/// Everything a supervisor needs to run one child. Cheap to clone (the start function is
/// shared), so a spec can be handed to several supervisors or kept for later restarts.
#[derive(Clone)]
pub struct ChildSpec {
    /// Unique name of the child within its supervisor; dynamic operations address it by id.
    pub id: String,
    /// Spawns a new incarnation linked to the given supervisor cell (see [`StartFn`]).
    pub start: StartFn,
    /// When the child is restarted.
    pub restart: Restart,
    /// How the child is stopped.
    pub shutdown: Shutdown,
    /// Worker or supervisor.
    pub kind: ChildKind,
    /// Give up on a start that takes longer than this (the attempt counts as a failed start).
    /// `None` (the default, as in OTP) waits as long as the start takes. A hanging restart
    /// never blocks the supervisor's mailbox, only the starts queued after it; a hanging
    /// *initial* start blocks `Supervisor::start`, as in OTP.
    pub start_timeout: Option<Duration>,
}

/// OTP's default shutdown for workers.
const WORKER_SHUTDOWN: Duration = Duration::from_secs(5);

impl ChildSpec {
    /// A spec from its parts: permanent, with the default shutdown of its kind.
    pub fn new(id: impl Into<String>, kind: ChildKind, start: StartFn) -> Self {
        let shutdown = match kind {
            ChildKind::Worker => Shutdown::Timeout(WORKER_SHUTDOWN),
            ChildKind::Supervisor => Shutdown::Infinity,
        };
        ChildSpec {
            id: id.into(),
            start,
            restart: Restart::Permanent,
            shutdown,
            kind,
            start_timeout: None,
        }
    }

    /// A permanent worker with a 5 s shutdown, started by `start`, which must spawn the actor
    /// linked to the supervisor cell it is given. The start answers the actor's cell, or a
    /// [`ChildStart`] when it may also decline to run ([`ChildStart::Ignore`]):
    ///
    /// ```
    /// # use marie_supervision::ChildSpec;
    /// # use ractor::{Actor, ActorProcessingErr, ActorRef};
    /// # struct Sensor;
    /// # impl Actor for Sensor {
    /// #     type Msg = (); type State = (); type Arguments = u32;
    /// #     async fn pre_start(&self, _: ActorRef<()>, _: u32) -> Result<(), ActorProcessingErr> { Ok(()) }
    /// # }
    /// let spec = ChildSpec::worker("sonar", |sup| async move {
    ///     let (actor, _) = Actor::spawn_linked(Some("sonar".into()), Sensor, 1203, sup).await?;
    ///     Ok(actor.get_cell())
    /// });
    /// assert_eq!(spec.id, "sonar");
    ///
    /// // a child that may decline to run (OTP's `ignore`)
    /// # use marie_supervision::ChildStart;
    /// # let fitted = false;
    /// let spec = ChildSpec::worker("laser", move |sup| async move {
    ///     if !fitted {
    ///         return Ok(ChildStart::Ignore);
    ///     }
    ///     let (actor, _) = Actor::spawn_linked(None, Sensor, 1, sup).await?;
    ///     Ok(ChildStart::Started(actor.get_cell()))
    /// });
    /// ```
    pub fn worker<F, Fut, T>(id: impl Into<String>, start: F) -> Self
    where
        F: Fn(ActorCell) -> Fut + Send + Sync + 'static,
        Fut: Future<Output = Result<T, SpawnErr>> + Send + 'static,
        T: Into<ChildStart> + 'static,
    {
        Self::new(
            id,
            ChildKind::Worker,
            Arc::new(move |sup| {
                let started = start(sup);
                Box::pin(async move { started.await.map(Into::into) })
            }),
        )
    }

    /// A permanent worker running actor `A`, unnamed; `make` builds the handler and its
    /// arguments afresh for every (re)start.
    pub fn actor<A, F>(id: impl Into<String>, make: F) -> Self
    where
        A: Actor,
        F: Fn() -> (A, A::Arguments) + Send + Sync + 'static,
    {
        Self::worker(id, move |sup| {
            let (handler, args) = make();
            async move {
                let (actor, _) = A::spawn_linked(None, handler, args, sup).await?;
                Ok(ChildStart::Started(actor.get_cell()))
            }
        })
    }

    /// The same spec with another restart type.
    pub fn with_restart(mut self, restart: Restart) -> Self {
        self.restart = restart;
        self
    }

    /// The same spec with another shutdown.
    pub fn with_shutdown(mut self, shutdown: Shutdown) -> Self {
        self.shutdown = shutdown;
        self
    }

    /// The same spec with another kind (e.g. a hand-written start function that starts a
    /// supervisor).
    pub fn with_kind(mut self, kind: ChildKind) -> Self {
        self.kind = kind;
        self
    }

    /// The same spec with a bound on how long one start may take.
    pub fn with_start_timeout(mut self, timeout: Duration) -> Self {
        self.start_timeout = Some(timeout);
        self
    }
}

impl fmt::Debug for ChildSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("ChildSpec")
            .field("id", &self.id)
            .field("restart", &self.restart)
            .field("shutdown", &self.shutdown)
            .field("kind", &self.kind)
            .field("start_timeout", &self.start_timeout)
            .finish_non_exhaustive()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn restart_types_follow_otp() {
        let normal = ExitReason::Normal;
        let shutdown = ExitReason::Shutdown(None);
        let crash = ExitReason::Failed("boom".into());
        let killed = ExitReason::Killed;
        for r in [&normal, &shutdown, &crash, &killed] {
            assert!(Restart::Permanent.restarts_after(r));
            assert!(!Restart::Temporary.restarts_after(r));
        }
        assert!(!Restart::Transient.restarts_after(&normal));
        assert!(!Restart::Transient.restarts_after(&shutdown));
        assert!(Restart::Transient.restarts_after(&crash));
        assert!(Restart::Transient.restarts_after(&killed));
    }

    #[test]
    fn default_shutdown_depends_on_kind() {
        let start: StartFn = Arc::new(|_| Box::pin(async { Err(SpawnErr::ActorAlreadyStarted) }));
        let w = ChildSpec::new("w", ChildKind::Worker, start.clone());
        let s = ChildSpec::new("s", ChildKind::Supervisor, start);
        assert_eq!(w.shutdown, Shutdown::Timeout(Duration::from_secs(5)));
        assert_eq!(s.shutdown, Shutdown::Infinity);
        assert_eq!(w.restart, Restart::Permanent);
    }
}
