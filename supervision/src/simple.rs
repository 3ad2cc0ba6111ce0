//! Simple-one-for-one supervision: one child template, any number of instances started at run
//! time with an argument each (OTP's `simple_one_for_one`).
//!
//! (See [`ChildTemplate`] for the semantics and the design.)

use std::any::{Any, TypeId};
use std::fmt;
use std::future::Future;
use std::sync::Arc;
use std::time::Duration;

use ractor::{Actor, ActorCell, SpawnErr};

use crate::child::{ChildKind, ChildSpec, ChildStart, Restart, Shutdown, StartFn, StartFuture};

/// The start argument of one instance, type-erased (see [`ChildTemplate`] for why).
/// [`crate::SupervisorRef::start_dynamic`] builds it; build one yourself only to send
/// [`crate::SupervisorMsg::StartDynamic`] directly.
#[derive(Clone)]
pub struct DynamicArg {
    value: Arc<dyn Any + Send + Sync>,
    type_id: TypeId,
    type_name: &'static str,
}

impl DynamicArg {
    /// Wrap `value`.
    pub fn new<A: Any + Send + Sync>(value: A) -> Self {
        DynamicArg {
            value: Arc::new(value),
            type_id: TypeId::of::<A>(),
            type_name: std::any::type_name::<A>(),
        }
    }

    /// The name of the wrapped value's type.
    pub fn type_name(&self) -> &'static str {
        self.type_name
    }
}

impl fmt::Debug for DynamicArg {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_tuple("DynamicArg").field(&self.type_name).finish()
    }
}

type TemplateStartFn =
    Arc<dyn Fn(ActorCell, &(dyn Any + Send + Sync)) -> StartFuture + Send + Sync>;

/// How a simple-one-for-one supervisor starts each instance: like a [`ChildSpec`], but its
/// start function takes an argument of type `A` besides the supervisor's cell. Cheap to clone.
///
/// A node's failover needs to say "start another instance of operation X, with these
/// parameters" without writing a child spec per instance: the operation's supervisor is a
/// simple-one-for-one supervisor whose [`ChildTemplate`] knows how to start one instance of X
/// from an argument, and [`crate::SupervisorRef::start_dynamic`] starts one.
///
/// # Why the argument is a type-erased `Any`
///
/// The argument's type is fixed by the template (`ChildTemplate::worker::<A, ..>`), but the
/// supervisor does not carry it in its own type: [`crate::Supervisor`] is one actor type with
/// one message type, [`crate::SupervisorMsg`]. That is what lets supervisors of any kind nest
/// in one tree, and lets a [`crate::SupervisorRef`] be recovered from any child supervisor's
/// cell ([`crate::SupervisorRef::from_cell`]) — a `Supervisor<A>` would need its argument type
/// named wherever a supervisor is handled, and a child supervisor found at run time could not
/// be addressed at all. So the argument travels as an `Arc<dyn Any + Send + Sync>`
/// ([`DynamicArg`]), tagged with its type; the supervisor compares the tag with the template's
/// before it starts anything, and a mismatch is a typed error
/// ([`crate::SupervisorError::WrongArgument`]) naming both types, never a panic. No serde:
/// the argument never leaves the process, it is handed to the start function as it is.
///
/// # Semantics (as OTP)
///
/// * Instances get generated ids, `"{template id}#{n}"` (OTP's are `undefined`); they are
///   addressed by their actor ([`crate::SupervisorRef::terminate_actor`]).
/// * Each instance restarts by the template's restart type, with the argument it was started
///   with; restarting one never touches the others. The supervisor's restart intensity counts
///   the restarts of all instances together.
/// * An instance that is not restarted — temporary, or transient after a normal exit or a
///   shutdown — is removed, not kept undefined: there is no spec of its own to restart. A
///   temporary instance's argument is dropped as soon as it started; an instance whose start
///   answers [`crate::ChildStart::Ignore`] leaves nothing behind.
/// * On shutdown all instances are asked to stop at once and waited for together (OTP stops
///   them asynchronously too): there is no order among instances.
#[derive(Clone)]
pub struct ChildTemplate {
    /// The template's id; instances are named `"{id}#{n}"`.
    pub id: String,
    start: TemplateStartFn,
    arg_type: TypeId,
    arg_type_name: &'static str,
    /// When an instance is restarted (each instance on its own).
    pub restart: Restart,
    /// How an instance is stopped.
    pub shutdown: Shutdown,
    /// Whether the instances are workers or supervisors.
    pub kind: ChildKind,
    /// Give up on an instance's start that takes longer than this.
    pub start_timeout: Option<Duration>,
}

impl ChildTemplate {
    /// A template of permanent workers with a 5 s shutdown. `start` gets the supervisor's cell
    /// and the instance's argument, and **must spawn the actor linked to that cell** (as a
    /// [`ChildSpec`]'s start function); it is called again with a clone of the same argument
    /// for every restart of the instance.
    ///
    /// ```
    /// # use marie_supervision::ChildTemplate;
    /// # use ractor::{Actor, ActorProcessingErr, ActorRef};
    /// # struct Wall;
    /// # impl Actor for Wall {
    /// #     type Msg = (); type State = (); type Arguments = f64;
    /// #     async fn pre_start(&self, _: ActorRef<()>, _: f64) -> Result<(), ActorProcessingErr> { Ok(()) }
    /// # }
    /// // one wall follower per requested distance
    /// let template = ChildTemplate::worker("wall-follower", |sup, distance: f64| async move {
    ///     let (actor, _) = Actor::spawn_linked(None, Wall, distance, sup).await?;
    ///     Ok(actor.get_cell())
    /// });
    /// assert!(template.arg_type_name().contains("f64"));
    /// ```
    pub fn worker<A, F, Fut, T>(id: impl Into<String>, start: F) -> Self
    where
        A: Clone + Send + Sync + 'static,
        F: Fn(ActorCell, A) -> Fut + Send + Sync + 'static,
        Fut: Future<Output = Result<T, SpawnErr>> + Send + 'static,
        T: Into<ChildStart> + 'static,
    {
        let start: TemplateStartFn = Arc::new(move |sup, arg| match arg.downcast_ref::<A>() {
            Some(arg) => {
                let started = start(sup, arg.clone());
                Box::pin(async move { started.await.map(Into::into) })
            }
            // the supervisor checks the type before it starts; this is a safety net
            None => Box::pin(async {
                Err(SpawnErr::StartupFailed(
                    format!("argument is not a {}", std::any::type_name::<A>()).into(),
                ))
            }),
        });
        ChildTemplate {
            id: id.into(),
            start,
            arg_type: TypeId::of::<A>(),
            arg_type_name: std::any::type_name::<A>(),
            restart: Restart::Permanent,
            shutdown: Shutdown::Timeout(Duration::from_secs(5)),
            kind: ChildKind::Worker,
            start_timeout: None,
        }
    }

    /// A template of workers running actor `Act`, unnamed; `make` builds the handler and its
    /// arguments from the instance's argument, afresh for every (re)start.
    pub fn actor<A, Act, F>(id: impl Into<String>, make: F) -> Self
    where
        A: Clone + Send + Sync + 'static,
        Act: Actor,
        F: Fn(A) -> (Act, Act::Arguments) + Send + Sync + 'static,
    {
        Self::worker(id, move |sup, arg: A| {
            let (handler, args) = make(arg);
            async move {
                let (actor, _) = Act::spawn_linked(None, handler, args, sup).await?;
                Ok(ChildStart::Started(actor.get_cell()))
            }
        })
    }

    /// The same template with another restart type.
    pub fn with_restart(mut self, restart: Restart) -> Self {
        self.restart = restart;
        self
    }

    /// The same template with another shutdown.
    pub fn with_shutdown(mut self, shutdown: Shutdown) -> Self {
        self.shutdown = shutdown;
        self
    }

    /// The same template with another kind.
    pub fn with_kind(mut self, kind: ChildKind) -> Self {
        self.kind = kind;
        self
    }

    /// The same template with a bound on how long one start may take.
    pub fn with_start_timeout(mut self, timeout: Duration) -> Self {
        self.start_timeout = Some(timeout);
        self
    }

    /// The name of the argument type the template's start function takes.
    pub fn arg_type_name(&self) -> &'static str {
        self.arg_type_name
    }

    /// Whether `arg` has the type the start function takes.
    pub(crate) fn accepts(&self, arg: &DynamicArg) -> bool {
        arg.type_id == self.arg_type
    }

    /// The child spec of instance `id` started with `arg`: an ordinary child spec whose start
    /// function holds the argument, so restarts reuse it.
    pub(crate) fn instance(&self, id: String, arg: DynamicArg) -> ChildSpec {
        let start = self.start.clone();
        let value = arg.value;
        let start: StartFn = Arc::new(move |sup| start(sup, &*value));
        let mut spec = ChildSpec::new(id, self.kind, start);
        spec.restart = self.restart;
        spec.shutdown = self.shutdown;
        spec.start_timeout = self.start_timeout;
        spec
    }
}

impl PartialEq for ChildTemplate {
    /// Two templates are equal when they are clones of one another (the same start function)
    /// with the same settings.
    fn eq(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.start, &other.start)
            && self.id == other.id
            && self.arg_type == other.arg_type
            && self.restart == other.restart
            && self.shutdown == other.shutdown
            && self.kind == other.kind
            && self.start_timeout == other.start_timeout
    }
}

impl fmt::Debug for ChildTemplate {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("ChildTemplate")
            .field("id", &self.id)
            .field("arg", &self.arg_type_name)
            .field("restart", &self.restart)
            .field("shutdown", &self.shutdown)
            .field("kind", &self.kind)
            .field("start_timeout", &self.start_timeout)
            .finish_non_exhaustive()
    }
}
