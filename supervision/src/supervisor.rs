//! The supervisor actor: starts its children in order, watches them through ractor's links,
//! restarts them by strategy and restart type within a restart intensity, and stops them in
//! reverse order. See [`Supervisor`] for how it works.

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
use crate::error::SupervisorError;
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
    /// in reverse order and the error names the child.
    pub async fn start(
        name: Option<String>,
        spec: SupervisorSpec,
        children: Vec<ChildSpec>,
    ) -> Result<(SupervisorRef, JoinHandle<()>), SupervisorError> {
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

    async fn on_supervision_event(
        &mut self,
        myself: &ActorRef<SupervisorMsg>,
        event: SupervisionEvent,
    ) -> Result<(), Escalation> {
        let Some((cell, reason)) = ExitReason::from_supervision_event(&event) else {
            return Ok(());
        };
        // release the child's final state now rather than at the end of the handler
        drop(event);
        let actor = cell.get_id();
        match self.by_actor.remove(&actor) {
            Some(key) => self.child_exited(myself, key, actor, reason).await,
            None => {
                if self.in_flight.is_some() {
                    self.early_exits.insert(actor, reason);
                } else {
                    tracing::trace!(supervisor = %myself.get_id(), %actor, "exit of a former child ignored");
                }
                Ok(())
            }
        }
    }

    /// The current incarnation of child `key` stopped by itself.
    async fn child_exited(
        &mut self,
        myself: &ActorRef<SupervisorMsg>,
        key: u64,
        actor: ActorId,
        reason: ExitReason,
    ) -> Result<(), Escalation> {
        let Some(child) = self.children.get_mut(&key) else {
            return Ok(());
        };
        child.status = Status::Undefined;
        child.old = Some(actor);
        if let Some(backoff) = &self.spec.backoff {
            if child.started_at.elapsed() >= backoff.reset_after {
                child.consecutive = 0;
            }
        }
        let id = child.spec.id.clone();
        let restart = child.spec.restart;
        if reason.is_abnormal() {
            tracing::warn!(supervisor = %myself.get_id(), child = %id, %actor, %reason, "child exited abnormally");
        } else {
            tracing::info!(supervisor = %myself.get_id(), child = %id, %actor, %reason, "child exited");
        }
        self.emit(SupervisorEvent::ChildExited {
            id,
            actor,
            reason: reason.clone(),
        });
        if restart == Restart::Temporary {
            self.remove_child(key);
            return Ok(());
        }
        if !restart.restarts_after(&reason) {
            if self.is_simple() {
                // an instance that is not restarted has nothing left to keep (as in OTP):
                // a transient instance that finished is gone, not undefined
                self.remove_child(key);
            }
            return Ok(());
        }
        self.restart(myself, key, RestartCause::Exited(reason))
            .await
    }

    /// One restart round for child `key` (OTP's `restart/2`): count it, stop the siblings the
    /// strategy restarts with it (reverse order), then start them all in order — at once, or
    /// after the backoff delay.
    async fn restart(
        &mut self,
        myself: &ActorRef<SupervisorMsg>,
        key: u64,
        cause: RestartCause,
    ) -> Result<(), Escalation> {
        if !self.intensity.record(self.epoch.elapsed()) {
            return Err(Escalation);
        }
        let Some(trigger) = self.children.get(&key).map(|c| c.spec.id.clone()) else {
            return Ok(());
        };
        let scope = self.spec.strategy.scope(&self.children, key);
        for &k in scope.iter().rev() {
            if k == key {
                continue;
            }
            self.stop_child(k).await;
            if self
                .children
                .get(&k)
                .is_some_and(|c| c.spec.restart == Restart::Temporary)
            {
                // a temporary sibling is stopped, not restarted
                self.remove_child(k);
            }
        }
        for &k in &scope {
            let generation = self.generation();
            let Some(child) = self.children.get_mut(&k) else {
                continue;
            };
            if k == key {
                if let Status::Pending = child.status {
                    self.pending.remove(&k);
                }
                child.cause = Some(cause.clone());
            } else {
                child.cause = Some(RestartCause::Sibling(trigger.clone()));
            }
            child.generation = generation;
            child.status = Status::Restarting;
        }

        let Some(child) = self.children.get_mut(&key) else {
            return Ok(());
        };
        let attempt = child.consecutive;
        child.consecutive = attempt.saturating_add(1);
        let generation = child.generation;
        let delay = match &self.spec.backoff {
            Some(backoff) => backoff.delay(attempt, &mut self.rng),
            None => Duration::ZERO,
        };
        if delay.is_zero() {
            self.release(myself, key);
        } else {
            tracing::debug!(supervisor = %myself.get_id(), child = %trigger, ?delay, attempt, "restart scheduled");
            self.emit(SupervisorEvent::RestartScheduled {
                id: trigger,
                delay,
                attempt,
            });
            let me = myself.clone();
            self.timers.retain(|t| !t.is_finished());
            self.timers.push(tokio::spawn(async move {
                tokio::time::sleep(delay).await;
                let _ = me.cast(SupervisorMsg::Internal(Internal(
                    InternalKind::BackoffDone { key, generation },
                )));
            }));
        }
        Ok(())
    }

    /// Queue the children of `key`'s restart round that wait for it, and start the queue.
    fn release(&mut self, myself: &ActorRef<SupervisorMsg>, key: u64) {
        for k in self.spec.strategy.scope(&self.children, key) {
            if let Some(child) = self.children.get_mut(&k) {
                if let Status::Restarting = child.status {
                    child.status = Status::Pending;
                    self.pending.insert(k);
                }
            }
        }
        self.pump(myself);
    }

    /// Start the first queued child, unless a start is already running.
    fn pump(&mut self, myself: &ActorRef<SupervisorMsg>) {
        if self.in_flight.is_some() {
            return;
        }
        let Some(key) = self.pending.pop_first() else {
            return;
        };
        let Some(child) = self.children.get_mut(&key) else {
            return;
        };
        let token = self.next_token;
        self.next_token += 1;
        child.status = Status::Starting(token);
        self.in_flight = Some(token);
        let start = child.spec.start.clone();
        let timeout = child.spec.start_timeout;
        let me = myself.clone();
        let task = tokio::spawn(async move {
            let result = run_start(&start, me.get_cell(), timeout).await;
            // drop the start function (and the start parameters it holds) before reporting,
            // so that a temporary child's parameters are gone once its start is answered
            drop(start);
            let started = result.as_ref().ok().and_then(|s| s.actor().cloned());
            let done =
                SupervisorMsg::Internal(Internal(InternalKind::StartDone { token, key, result }));
            if me.cast(done).is_err() {
                // the supervisor is gone; do not leave its child behind
                if let Some(cell) = started {
                    cell.kill();
                }
            }
        });
        self.tasks.insert(token, task);
    }

    async fn start_done(
        &mut self,
        myself: &ActorRef<SupervisorMsg>,
        token: u64,
        key: u64,
        result: Result<ChildStart, String>,
    ) -> Result<(), Escalation> {
        self.tasks.remove(&token);
        let outcome = if self.in_flight == Some(token) {
            self.in_flight = None;
            let outcome = self.started(myself, key, result).await;
            // early exits can only belong to the start just reported
            self.early_exits.clear();
            outcome
        } else {
            if let Ok(ChildStart::Started(cell)) = result {
                tracing::debug!(supervisor = %myself.get_id(), actor = %cell.get_id(), "abandoned start finished; killing its actor");
                cell.kill();
            }
            Ok(())
        };
        if outcome.is_ok() {
            self.pump(myself);
        }
        outcome
    }

    /// The start of child `key` (the one awaited) finished.
    async fn started(
        &mut self,
        myself: &ActorRef<SupervisorMsg>,
        key: u64,
        result: Result<ChildStart, String>,
    ) -> Result<(), Escalation> {
        let simple = self.is_simple();
        let Some(child) = self.children.get_mut(&key) else {
            if let Ok(ChildStart::Started(cell)) = result {
                cell.kill();
            }
            return Ok(());
        };
        let id = child.spec.id.clone();
        match result {
            Ok(ChildStart::Ignore) => {
                tracing::info!(supervisor = %myself.get_id(), child = %id, "child ignored its start");
                child.status = Status::Undefined;
                let first = child.cause.take().is_none();
                let waiter = child.waiter.take();
                let drop_it = simple || child.spec.restart == Restart::Temporary;
                self.emit(SupervisorEvent::ChildIgnored { id: id.clone() });
                if drop_it {
                    if first {
                        // a first start leaves no trace
                        self.forget_child(key);
                    } else {
                        self.remove_child(key);
                    }
                }
                if let Some(waiter) = waiter {
                    let _ = waiter.send(Err(SupervisorError::Ignored(id)));
                }
                Ok(())
            }
            Ok(ChildStart::Started(cell)) => {
                let actor = cell.get_id();
                child.status = Status::Running(cell.clone());
                child.started_at = Instant::now();
                if child.spec.restart == Restart::Temporary {
                    child.spec.start = forgotten_start();
                }
                let event = match child.cause.take() {
                    Some(cause) => {
                        child.restarts = child.restarts.saturating_add(1);
                        tracing::info!(supervisor = %myself.get_id(), child = %id, %actor, ?cause, "child restarted");
                        SupervisorEvent::ChildRestarted {
                            id: id.clone(),
                            old: child.old.take(),
                            new: cell.clone(),
                            cause,
                            restarts: child.restarts,
                        }
                    }
                    None => {
                        tracing::debug!(supervisor = %myself.get_id(), child = %id, %actor, "child started");
                        SupervisorEvent::ChildStarted {
                            id: id.clone(),
                            actor: cell.clone(),
                        }
                    }
                };
                if let Some(waiter) = child.waiter.take() {
                    let _ = waiter.send(Ok(cell.clone()));
                }
                self.by_actor.insert(actor, key);
                self.emit(event);
                if let Some(reason) = self.early_exits.remove(&actor) {
                    self.by_actor.remove(&actor);
                    return self.child_exited(myself, key, actor, reason).await;
                }
                ensure_linked(myself, &id, &cell);
                Ok(())
            }
            Err(reason) => {
                match child.cause.clone() {
                    None => {
                        // the first start of a dynamic child: it leaves no spec behind
                        let waiter = child.waiter.take();
                        self.forget_child(key);
                        if let Some(waiter) = waiter {
                            let _ = waiter.send(Err(SupervisorError::StartFailed { id, reason }));
                        }
                    }
                    Some(RestartCause::Manual) => {
                        child.status = Status::Undefined;
                        child.cause = None;
                        if let Some(waiter) = child.waiter.take() {
                            let _ = waiter.send(Err(SupervisorError::StartFailed { id, reason }));
                        }
                    }
                    Some(_) => {
                        tracing::warn!(supervisor = %myself.get_id(), child = %id, %reason, "restart failed; trying again");
                        child.status = Status::Restarting;
                        let generation = child.generation;
                        self.emit(SupervisorEvent::RestartFailed { id, error: reason });
                        // children queued behind it in the same round wait for its retry
                        let behind: Vec<u64> = match self.spec.strategy {
                            Strategy::OneForOne | Strategy::SimpleOneForOne => Vec::new(),
                            Strategy::RestForOne => self.pending.range(key..).copied().collect(),
                            Strategy::OneForAll => self.pending.iter().copied().collect(),
                        };
                        for k in behind {
                            self.pending.remove(&k);
                            if let Some(c) = self.children.get_mut(&k) {
                                c.status = Status::Restarting;
                            }
                        }
                        let _ =
                            myself.cast(SupervisorMsg::Internal(Internal(InternalKind::Retry {
                                key,
                                generation,
                            })));
                    }
                }
                Ok(())
            }
        }
    }

    /// Stop child `key` by its shutdown spec if it runs, abandon its start if one is queued
    /// or running, and leave it undefined.
    async fn stop_child(&mut self, key: u64) {
        let generation = self.generation();
        let Some(child) = self.children.get_mut(&key) else {
            return;
        };
        child.generation = generation;
        let cell = match std::mem::replace(&mut child.status, Status::Undefined) {
            Status::Running(cell) => cell,
            Status::Starting(token) => {
                if self.in_flight == Some(token) {
                    self.in_flight = None;
                }
                return;
            }
            Status::Pending => {
                self.pending.remove(&key);
                return;
            }
            Status::Restarting | Status::Undefined => return,
        };
        let actor = cell.get_id();
        child.old = Some(actor);
        let shutdown = child.spec.shutdown;
        let id = child.spec.id.clone();
        self.by_actor.remove(&actor);
        let killed = shutdown_child(&cell, shutdown).await;
        tracing::debug!(child = %id, %actor, killed, "child shut down");
        self.emit(SupervisorEvent::ChildShutdown { id, actor, killed });
    }

    /// Remove child `key` without a trace (no event, no reply).
    fn forget_child(&mut self, key: u64) -> Option<Child> {
        let child = self.children.remove(&key)?;
        self.by_id.remove(&child.spec.id);
        self.pending.remove(&key);
        match &child.status {
            Status::Running(cell) => {
                self.by_actor.remove(&cell.get_id());
            }
            Status::Starting(token) if self.in_flight == Some(*token) => self.in_flight = None,
            _ => {}
        }
        Some(child)
    }

    /// Remove child `key`, telling a waiting caller and the subscribers.
    fn remove_child(&mut self, key: u64) {
        if let Some(child) = self.forget_child(key) {
            let id = child.spec.id;
            if let Some(waiter) = child.waiter {
                let _ = waiter.send(Err(SupervisorError::Terminated(id.clone())));
            }
            self.emit(SupervisorEvent::ChildDeleted { id });
        }
    }

    fn start_child(
        &mut self,
        myself: &ActorRef<SupervisorMsg>,
        spec: ChildSpec,
        reply: RpcReplyPort<Result<ActorCell, SupervisorError>>,
    ) {
        if self.is_simple() {
            let _ = reply.send(Err(SupervisorError::SimpleOneForOne));
            return;
        }
        if let Err(e) = spec.validate() {
            let _ = reply.send(Err(e.into()));
            return;
        }
        if let Some(key) = self.by_id.get(&spec.id) {
            let err = match self.children[key].status {
                Status::Running(_) => SupervisorError::AlreadyStarted(spec.id),
                _ => SupervisorError::AlreadyPresent(spec.id),
            };
            let _ = reply.send(Err(err));
            return;
        }
        self.add_pending(myself, spec, reply);
    }

    /// Add `spec` at the end of the start order and queue its first start.
    fn add_pending(
        &mut self,
        myself: &ActorRef<SupervisorMsg>,
        spec: ChildSpec,
        reply: RpcReplyPort<Result<ActorCell, SupervisorError>>,
    ) {
        let key = self.next_key;
        self.next_key += 1;
        self.by_id.insert(spec.id.clone(), key);
        let mut child = Self::new_child(spec, Status::Pending);
        child.waiter = Some(reply);
        self.children.insert(key, child);
        self.pending.insert(key);
        self.pump(myself);
    }

    /// Start one more instance of the template with `arg` (simple-one-for-one only).
    fn start_dynamic(
        &mut self,
        myself: &ActorRef<SupervisorMsg>,
        arg: DynamicArg,
        reply: RpcReplyPort<Result<ActorCell, SupervisorError>>,
    ) {
        let Some(template) = self.template.as_ref().filter(|_| self.is_simple()) else {
            let _ = reply.send(Err(SupervisorError::NotSimpleOneForOne));
            return;
        };
        if !template.accepts(&arg) {
            let _ = reply.send(Err(SupervisorError::WrongArgument {
                expected: template.arg_type_name(),
                got: arg.type_name(),
            }));
            return;
        }
        self.next_instance += 1;
        let id = format!("{}#{}", template.id, self.next_instance);
        let spec = template.instance(id, arg);
        self.add_pending(myself, spec, reply);
    }

    /// Stop instance `actor` of a simple-one-for-one supervisor and forget it.
    async fn terminate_actor(
        &mut self,
        myself: &ActorRef<SupervisorMsg>,
        actor: ActorId,
    ) -> Result<(), SupervisorError> {
        if !self.is_simple() {
            return Err(SupervisorError::NotFound(actor.to_string()));
        }
        let key = match self.by_actor.get(&actor) {
            Some(&key) => Some(key),
            // an instance restarting after this incarnation's exit
            None => self
                .children
                .iter()
                .find(|(_, c)| !matches!(c.status, Status::Running(_)) && c.old == Some(actor))
                .map(|(&k, _)| k),
        };
        let Some(key) = key else {
            // OTP: terminating an instance that has already gone is fine; a live actor that
            // is not an instance is not
            return match ractor::registry::where_is_pid(actor) {
                Some(_) => Err(SupervisorError::NotFound(actor.to_string())),
                None => Ok(()),
            };
        };
        self.stop_child(key).await;
        if let Some(waiter) = self.children.get_mut(&key).and_then(|c| c.waiter.take()) {
            let _ = waiter.send(Err(SupervisorError::Terminated(actor.to_string())));
        }
        self.remove_child(key);
        self.pump(myself);
        Ok(())
    }

    async fn terminate_child(
        &mut self,
        myself: &ActorRef<SupervisorMsg>,
        id: &str,
    ) -> Result<(), SupervisorError> {
        let Some(&key) = self.by_id.get(id) else {
            return Err(SupervisorError::NotFound(id.to_string()));
        };
        let was_restarting = matches!(self.children[&key].status, Status::Restarting);
        self.stop_child(key).await;
        if was_restarting {
            // siblings whose restart waited for this child's retry or backoff would wait
            // forever: start them now, without it
            self.release(myself, key);
        }
        if let Some(child) = self.children.get_mut(&key) {
            child.cause = None;
            if let Some(waiter) = child.waiter.take() {
                let _ = waiter.send(Err(SupervisorError::Terminated(id.to_string())));
            }
            if child.spec.restart == Restart::Temporary {
                self.remove_child(key);
            }
        }
        self.pump(myself);
        Ok(())
    }

    fn restart_child(
        &mut self,
        myself: &ActorRef<SupervisorMsg>,
        id: &str,
        reply: RpcReplyPort<Result<ActorCell, SupervisorError>>,
    ) {
        let Some(&key) = self.by_id.get(id) else {
            let _ = reply.send(Err(SupervisorError::NotFound(id.to_string())));
            return;
        };
        let Some(child) = self.children.get_mut(&key) else {
            return;
        };
        match child.status {
            Status::Running(_) => {
                let _ = reply.send(Err(SupervisorError::Running(id.to_string())));
            }
            Status::Pending | Status::Starting(_) | Status::Restarting => {
                let _ = reply.send(Err(SupervisorError::Restarting(id.to_string())));
            }
            Status::Undefined => {
                child.cause = Some(RestartCause::Manual);
                child.waiter = Some(reply);
                child.status = Status::Pending;
                self.pending.insert(key);
                self.pump(myself);
            }
        }
    }

    fn delete_child(&mut self, id: &str) -> Result<(), SupervisorError> {
        let Some(&key) = self.by_id.get(id) else {
            return Err(SupervisorError::NotFound(id.to_string()));
        };
        match self.children[&key].status {
            Status::Running(_) => Err(SupervisorError::Running(id.to_string())),
            Status::Pending | Status::Starting(_) | Status::Restarting => {
                Err(SupervisorError::Restarting(id.to_string()))
            }
            Status::Undefined => {
                self.remove_child(key);
                Ok(())
            }
        }
    }

    fn which_children(&self) -> Vec<ChildInfo> {
        self.children
            .values()
            .map(|c| ChildInfo {
                id: c.spec.id.clone(),
                state: match &c.status {
                    Status::Running(cell) => ChildState::Running(cell.clone()),
                    Status::Pending | Status::Starting(_) if c.cause.is_none() => {
                        ChildState::Starting
                    }
                    Status::Pending | Status::Starting(_) | Status::Restarting => {
                        ChildState::Restarting
                    }
                    Status::Undefined => ChildState::Undefined,
                },
                restart: c.spec.restart,
                shutdown: c.spec.shutdown,
                kind: c.spec.kind,
                restarts: c.restarts,
                start_timeout: c.spec.start_timeout,
            })
            .collect()
    }

    fn count_children(&self) -> ChildCounts {
        let mut counts = ChildCounts {
            // a simple-one-for-one supervisor has one spec, its template (as OTP counts)
            specs: if self.is_simple() {
                1
            } else {
                self.children.len()
            },
            ..ChildCounts::default()
        };
        for c in self.children.values() {
            if let Status::Running(_) = c.status {
                counts.active += 1;
            }
            match c.spec.kind {
                ChildKind::Worker => counts.workers += 1,
                ChildKind::Supervisor => counts.supervisors += 1,
            }
        }
        counts
    }

    /// Stop every child in reverse start order and abandon all pending starts.
    async fn shutdown_all(&mut self) {
        for (_, task) in self.tasks.drain() {
            task.abort();
        }
        for timer in self.timers.drain(..) {
            timer.abort();
        }
        self.in_flight = None;
        self.early_exits.clear();
        if self.is_simple() {
            self.shutdown_instances().await;
        }
        let keys: Vec<u64> = self.children.keys().rev().copied().collect();
        for key in keys {
            self.stop_child(key).await;
            if let Some(waiter) = self.children.get_mut(&key).and_then(|c| c.waiter.take()) {
                let _ = waiter.send(Err(SupervisorError::ShuttingDown));
            }
        }
        self.pending.clear();
    }

    /// Stop every running instance of a simple-one-for-one supervisor at once and wait for
    /// them together (OTP stops them asynchronously too; there is no order among instances).
    async fn shutdown_instances(&mut self) {
        let mut stopping = Vec::new();
        for child in self.children.values_mut() {
            if let Status::Running(cell) = &child.status {
                let cell = cell.clone();
                child.status = Status::Undefined;
                child.old = Some(cell.get_id());
                self.by_actor.remove(&cell.get_id());
                stopping.push((child.spec.id.clone(), cell, child.spec.shutdown));
            }
        }
        let cells: Vec<_> = stopping.iter().map(|(_, c, s)| (c.clone(), *s)).collect();
        let killed = shutdown_together(&cells).await;
        for ((id, cell, _), killed) in stopping.into_iter().zip(killed) {
            self.emit(SupervisorEvent::ChildShutdown {
                id,
                actor: cell.get_id(),
                killed,
            });
        }
    }

    /// The restart intensity was exceeded: stop everything and fail, escalating to the parent.
    async fn give_up(
        &mut self,
        myself: &ActorRef<SupervisorMsg>,
    ) -> Result<(), ActorProcessingErr> {
        tracing::error!(
            supervisor = %myself.get_id(),
            max_restarts = self.spec.max_restarts,
            period = ?self.spec.period,
            "reached max restart intensity; stopping all children and giving up"
        );
        self.emit(SupervisorEvent::IntensityExceeded {
            max_restarts: self.spec.max_restarts,
            period: self.spec.period,
        });
        self.shutdown_all().await;
        self.emit(SupervisorEvent::Stopped {
            reason: REACHED_MAX_RESTART_INTENSITY.to_string(),
        });
        self.events = None;
        Err(Box::new(SupervisorError::ReachedMaxRestartIntensity))
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
