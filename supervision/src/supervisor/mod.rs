//! The supervisor actor: starts its children in order, watches them through ractor's links,
//! restarts them by strategy and restart type within a restart intensity, and stops them in
//! reverse order. See [`Supervisor`] for how it works.

mod admin;
mod restarts;

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::sync::Arc;
use std::time::Duration;

use ractor::concurrency::JoinHandle;
use ractor::{
    Actor, ActorCell, ActorId, ActorProcessingErr, ActorRef, ActorStatus, RpcReplyPort,
    SupervisionEvent,
};
use tokio::sync::broadcast;
use tokio::time::Instant;

use crate::child::{ChildKind, ChildSpec, ChildStart, Restart, StartFn};
use crate::error::{StartError, SupervisorError};
use crate::events::{RestartCause, SupervisorEvent};
use crate::exit::{ExitReason, REACHED_MAX_RESTART_INTENSITY, SHUTDOWN};
use crate::handle::SupervisorRef;
use crate::info::{ChildCounts, ChildInfo, ChildState};
use crate::intensity::Intensity;
use crate::messages::{Internal, InternalKind, SupervisorMsg};
use crate::simple::{ChildTemplate, DynamicArg};
use crate::spec::SupervisorSpec;
use crate::start::run_start;
use crate::strategy::Strategy;
use crate::terminate::{shutdown_child, shutdown_together};
use crate::unwind::require_unwinding;
use crate::validate::validate_start;
use rand_xoshiro::Xoshiro256StarStar;

/// The supervisor actor (a ractor [`Actor`]). Start it with [`Supervisor::start`] or
/// [`Supervisor::start_linked`], or nest it with [`ChildSpec::supervisor`].
///
/// # How it works
///
/// * **Children** live in a map keyed by their position in the start order; a restart keeps
///   the key, so the order never changes (rest-for-one depends on it). Exits are matched by
///   the *current* incarnation's `ActorId` only: the exit of an incarnation the supervisor
///   stopped itself (say, a sibling in a one-for-all restart) finds no entry and is ignored,
///   so it never triggers a second restart.
/// * **Starts**: the initial children start in order inside the supervisor's own start
///   (`Supervisor::start` returns once all are up, or fails naming the child that did not
///   start, after stopping the others in reverse order). Later starts — restarts,
///   `start_child`, `restart_child` — run in a separate task, one at a time, in start order;
///   the result comes back as a message. The supervisor's mailbox therefore stays responsive
///   while a child starts slowly or hangs: `which_children`, `terminate_child` and `stop` are
///   served in between. A failed restart is retried by a message to itself (OTP's
///   `try_again_restart`), never by a loop inside one handler, and every attempt counts in
///   the restart intensity.
/// * **Stops** (sibling restarts, `terminate_child`, shutdown, giving up) run inside the
///   handler, in reverse start order, each by its shutdown spec — like OTP, the supervisor is
///   busy while it stops children.
/// * **Giving up**: when a restart would exceed the intensity, the supervisor stops all
///   children in reverse order and fails with [`REACHED_MAX_RESTART_INTENSITY`]; its parent
///   sees an abnormal exit (`ActorFailed`) and applies its own strategy.
/// * **Simple-one-for-one** instances are ordinary children built from the template and
///   their argument ([`ChildTemplate`]), keyed in start order like the others; only their
///   shutdown differs: all are asked to stop at once and waited for together.
/// * **Ignore**: a start answering [`ChildStart::Ignore`] leaves the child undefined (kept) or
///   forgets it (temporary children, simple-one-for-one instances); it is not a failure and
///   is never retried.
///
/// ractor specifics this relies on: a child exit arrives as `ActorTerminated` / `ActorFailed`
/// on the supervisor's supervision channel (which ractor serves before ordinary messages, so
/// an exit can overtake the result of the start that created the child — such early exits
/// are buffered until the start result arrives); a child's `pre_start` failure produces no
/// event, only the start function's error; when the supervisor itself terminates, ractor
/// kills whatever is still linked to it.
#[derive(Clone, Copy, Debug, Default)]
pub struct Supervisor;

/// The supervisor's start arguments: its own spec and its initial children, started in this
/// order.
#[derive(Clone, Debug)]
pub struct SupervisorArgs {
    /// Strategy, intensity, backoff.
    pub spec: SupervisorSpec,
    /// The initial children, in start order.
    pub children: Vec<ChildSpec>,
}

impl Supervisor {
    /// Spawn a supervisor (registered under `name`, if given) and start `children` in order.
    /// Returns once all started; if one fails to start, the ones already started are stopped
    /// in reverse order and the error names the child. In a build whose panics abort, nothing
    /// starts: [`SupervisorError::PanicsAbort`].
    pub async fn start(
        name: Option<String>,
        spec: SupervisorSpec,
        children: Vec<ChildSpec>,
    ) -> Result<(SupervisorRef, JoinHandle<()>), SupervisorError> {
        require_unwinding()?;
        validate_start(&spec, &children)?;
        let (actor, handle) = Actor::spawn(name, Supervisor, SupervisorArgs { spec, children })
            .await
            .map_err(SupervisorError::from_spawn)?;
        Ok((actor.into(), handle))
    }

    /// Like [`Supervisor::start`], linked to `parent`: the parent gets the supervisor's exit
    /// as a supervision event — `ActorFailed` with [`REACHED_MAX_RESTART_INTENSITY`] when it
    /// gives up.
    pub async fn start_linked(
        name: Option<String>,
        spec: SupervisorSpec,
        children: Vec<ChildSpec>,
        parent: ActorCell,
    ) -> Result<(SupervisorRef, JoinHandle<()>), SupervisorError> {
        require_unwinding()?;
        validate_start(&spec, &children)?;
        let (actor, handle) =
            Actor::spawn_linked(name, Supervisor, SupervisorArgs { spec, children }, parent)
                .await
                .map_err(SupervisorError::from_spawn)?;
        Ok((actor.into(), handle))
    }
}

/// The start function a temporary child keeps once it started: it will never be restarted, so
/// its start parameters are dropped (OTP's "do not save start parameters for temporary
/// children" — they can be large, and a long-running supervisor may start many).
fn forgotten_start() -> StartFn {
    Arc::new(|_| {
        Box::pin(async {
            Err(ractor::SpawnErr::StartupFailed(
                "the start parameters of a temporary child are not kept".into(),
            ))
        })
    })
}

/// The supervisor's state; opaque (inspect it through [`SupervisorRef`]).
pub struct SupervisorState {
    spec: SupervisorSpec,
    intensity: Intensity,
    epoch: Instant,
    /// Children by start-order key.
    children: BTreeMap<u64, Child>,
    by_id: HashMap<String, u64>,
    /// Current incarnations only.
    by_actor: HashMap<ActorId, u64>,
    /// Children waiting for their start, served in key order.
    pending: BTreeSet<u64>,
    next_key: u64,
    next_token: u64,
    next_generation: u64,
    /// The token of the start task whose result is awaited; other tasks were abandoned.
    in_flight: Option<u64>,
    /// Start tasks not yet reported back, by token.
    tasks: HashMap<u64, JoinHandle<()>>,
    /// Exits of unknown actors seen while a start was in flight: they may belong to the
    /// incarnation whose start result has not arrived yet.
    early_exits: HashMap<ActorId, ExitReason>,
    /// Backoff timers.
    timers: Vec<JoinHandle<()>>,
    /// The template of a simple-one-for-one supervisor.
    template: Option<ChildTemplate>,
    /// The number of the next simple-one-for-one instance.
    next_instance: u64,
    rng: Xoshiro256StarStar,
    events: Option<broadcast::Sender<SupervisorEvent>>,
}

impl std::fmt::Debug for SupervisorState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SupervisorState")
            .field("spec", &self.spec)
            .field("children", &self.children.len())
            .finish_non_exhaustive()
    }
}

struct Child {
    spec: ChildSpec,
    status: Status,
    /// Bumped whenever a child's restart plan changes, so stale retries and timers are
    /// recognized.
    generation: u64,
    restarts: u32,
    /// Restart attempts since the child last ran stably (backoff attempt number).
    consecutive: u32,
    started_at: Instant,
    /// Why the next start is a restart; `None` for a first start.
    cause: Option<RestartCause>,
    /// The last incarnation, for `ChildRestarted::old`.
    old: Option<ActorId>,
    /// A `start_child` / `restart_child` caller waiting for this child's start.
    waiter: Option<RpcReplyPort<Result<ActorCell, SupervisorError>>>,
}

enum Status {
    Running(ActorCell),
    /// Queued in `pending`.
    Pending,
    /// Its start task (this token) runs.
    Starting(u64),
    /// Waiting for a retry or a backoff timer.
    Restarting,
    /// Not running, not to be restarted.
    Undefined,
}

/// The restart intensity was exceeded: the supervisor must give up.
struct Escalation;

impl Actor for Supervisor {
    type Msg = SupervisorMsg;
    type State = SupervisorState;
    type Arguments = SupervisorArgs;

    async fn pre_start(
        &self,
        myself: ActorRef<SupervisorMsg>,
        args: SupervisorArgs,
    ) -> Result<SupervisorState, ActorProcessingErr> {
        require_unwinding()?;
        validate_start(&args.spec, &args.children).map_err(SupervisorError::from)?;
        let mut state = SupervisorState::new(args.spec);
        for spec in args.children {
            match run_start(&spec.start, myself.get_cell(), spec.start_timeout).await {
                Ok(ChildStart::Started(cell)) => state.add_started(&myself, spec, cell),
                Ok(ChildStart::Ignore) => state.add_ignored(&myself, spec),
                Err(reason) => {
                    tracing::error!(
                        supervisor = %myself.get_id(), child = %spec.id, %reason,
                        "child failed to start; stopping the supervisor"
                    );
                    state.shutdown_all().await;
                    return Err(Box::new(SupervisorError::StartFailed {
                        id: spec.id,
                        reason,
                    }));
                }
            }
        }
        Ok(state)
    }

    async fn post_stop(
        &self,
        myself: ActorRef<SupervisorMsg>,
        state: &mut SupervisorState,
    ) -> Result<(), ActorProcessingErr> {
        tracing::debug!(supervisor = %myself.get_id(), "supervisor stopping its children");
        state.shutdown_all().await;
        state.emit(SupervisorEvent::Stopped {
            reason: SHUTDOWN.to_string(),
        });
        state.events = None;
        Ok(())
    }

    async fn handle(
        &self,
        myself: ActorRef<SupervisorMsg>,
        message: SupervisorMsg,
        state: &mut SupervisorState,
    ) -> Result<(), ActorProcessingErr> {
        match state.handle(&myself, message).await {
            Ok(()) => Ok(()),
            Err(Escalation) => state.give_up(&myself).await,
        }
    }

    async fn handle_supervisor_evt(
        &self,
        myself: ActorRef<SupervisorMsg>,
        event: SupervisionEvent,
        state: &mut SupervisorState,
    ) -> Result<(), ActorProcessingErr> {
        match state.on_supervision_event(&myself, event).await {
            Ok(()) => Ok(()),
            Err(Escalation) => state.give_up(&myself).await,
        }
    }
}

impl SupervisorState {
    fn new(spec: SupervisorSpec) -> Self {
        let (events, _) = broadcast::channel(spec.event_capacity.max(1));
        let rng = match &spec.backoff {
            Some(b) => b.rng(),
            None => rand_core::SeedableRng::seed_from_u64(0),
        };
        SupervisorState {
            intensity: Intensity::new(spec.max_restarts, spec.period),
            epoch: Instant::now(),
            children: BTreeMap::new(),
            by_id: HashMap::new(),
            by_actor: HashMap::new(),
            pending: BTreeSet::new(),
            next_key: 0,
            next_token: 0,
            next_generation: 0,
            in_flight: None,
            tasks: HashMap::new(),
            early_exits: HashMap::new(),
            timers: Vec::new(),
            rng,
            events: Some(events),
            template: spec.template.clone(),
            next_instance: 0,
            spec,
        }
    }

    fn emit(&self, event: SupervisorEvent) {
        if let Some(tx) = &self.events {
            // no subscribers is fine
            let _ = tx.send(event);
        }
    }

    fn generation(&mut self) -> u64 {
        self.next_generation += 1;
        self.next_generation
    }

    fn new_child(spec: ChildSpec, status: Status) -> Child {
        Child {
            spec,
            status,
            generation: 0,
            restarts: 0,
            consecutive: 0,
            started_at: Instant::now(),
            cause: None,
            old: None,
            waiter: None,
        }
    }

    fn is_simple(&self) -> bool {
        self.spec.strategy == Strategy::SimpleOneForOne
    }

    /// Record an initial child that started.
    fn add_started(
        &mut self,
        myself: &ActorRef<SupervisorMsg>,
        mut spec: ChildSpec,
        cell: ActorCell,
    ) {
        let key = self.next_key;
        self.next_key += 1;
        let id = spec.id.clone();
        if spec.restart == Restart::Temporary {
            spec.start = forgotten_start();
        }
        ensure_linked(myself, &id, &cell);
        self.by_id.insert(id.clone(), key);
        self.by_actor.insert(cell.get_id(), key);
        self.children
            .insert(key, Self::new_child(spec, Status::Running(cell.clone())));
        tracing::debug!(supervisor = %myself.get_id(), child = %id, actor = %cell.get_id(), "child started");
        self.emit(SupervisorEvent::ChildStarted { id, actor: cell });
    }

    /// Record an initial child whose start answered ignore: kept, not running, unless it is
    /// temporary (OTP's `sup_start_ignore_child` / `sup_start_ignore_temporary_child`).
    fn add_ignored(&mut self, myself: &ActorRef<SupervisorMsg>, spec: ChildSpec) {
        let id = spec.id.clone();
        tracing::info!(supervisor = %myself.get_id(), child = %id, "child ignored its start");
        if spec.restart != Restart::Temporary {
            let key = self.next_key;
            self.next_key += 1;
            self.by_id.insert(id.clone(), key);
            self.children
                .insert(key, Self::new_child(spec, Status::Undefined));
        }
        self.emit(SupervisorEvent::ChildIgnored { id });
    }

    async fn handle(
        &mut self,
        myself: &ActorRef<SupervisorMsg>,
        message: SupervisorMsg,
    ) -> Result<(), Escalation> {
        match message {
            SupervisorMsg::StartChild(spec, reply) => self.start_child(myself, spec, reply),
            SupervisorMsg::StartDynamic(arg, reply) => self.start_dynamic(myself, arg, reply),
            SupervisorMsg::TerminateActor(actor, reply) => {
                let result = self.terminate_actor(myself, actor).await;
                let _ = reply.send(result);
            }
            SupervisorMsg::TerminateChild(id, reply) => {
                let result = if self.is_simple() {
                    Err(SupervisorError::SimpleOneForOne)
                } else {
                    self.terminate_child(myself, &id).await
                };
                let _ = reply.send(result);
            }
            SupervisorMsg::RestartChild(id, reply) => {
                if self.is_simple() {
                    let _ = reply.send(Err(SupervisorError::SimpleOneForOne));
                } else {
                    self.restart_child(myself, &id, reply)
                }
            }
            SupervisorMsg::DeleteChild(id, reply) => {
                let _ = reply.send(if self.is_simple() {
                    Err(SupervisorError::SimpleOneForOne)
                } else {
                    self.delete_child(&id)
                });
            }
            SupervisorMsg::GetChildSpec(id, reply) => {
                let spec = self
                    .by_id
                    .get(&id)
                    .and_then(|key| self.children.get(key))
                    .map(|c| c.spec.clone())
                    .ok_or(SupervisorError::NotFound(id));
                let _ = reply.send(spec);
            }
            SupervisorMsg::WhichChildren(reply) => {
                let _ = reply.send(self.which_children());
            }
            SupervisorMsg::CountChildren(reply) => {
                let _ = reply.send(self.count_children());
            }
            SupervisorMsg::Subscribe(reply) => {
                if let Some(tx) = &self.events {
                    let _ = reply.send(tx.subscribe());
                }
            }
            SupervisorMsg::Internal(Internal(kind)) => match kind {
                InternalKind::StartDone { token, key, result } => {
                    return self.start_done(myself, token, key, result).await;
                }
                InternalKind::Retry { key, generation } => {
                    if let Some(child) = self.children.get(&key) {
                        if child.generation == generation
                            && matches!(child.status, Status::Restarting)
                        {
                            let cause = child.cause.clone().unwrap_or(RestartCause::Manual);
                            return self.restart(myself, key, cause).await;
                        }
                    }
                }
                InternalKind::BackoffDone { key, generation } => {
                    if let Some(child) = self.children.get(&key) {
                        if child.generation == generation
                            && matches!(child.status, Status::Restarting)
                        {
                            self.release(myself, key);
                        }
                    }
                }
            },
        }
        Ok(())
    }
}

/// Warn about (and, if it has no supervisor at all, repair) a child its start function did not
/// link to the supervisor: without the link its exits would go unnoticed.
fn ensure_linked(myself: &ActorRef<SupervisorMsg>, id: &str, cell: &ActorCell) {
    if cell.get_status() >= ActorStatus::Stopping {
        return;
    }
    match cell.try_get_supervisor() {
        Some(sup) if sup.get_id() == myself.get_id() => {}
        Some(other) => tracing::warn!(
            supervisor = %myself.get_id(), child = %id, other = %other.get_id(),
            "start function linked the child to another actor; its exits will not be seen"
        ),
        None => {
            tracing::warn!(
                supervisor = %myself.get_id(), child = %id,
                "start function did not link the child to the supervisor; linking it"
            );
            cell.link(myself.get_cell());
        }
    }
}
