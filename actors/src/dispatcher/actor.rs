//! The ActionDispatcher actor: runs a validated mission against live operations.
//!
//! It never does the work itself (thesis 3.2.4.1): for each action its mission's tree starts
//! — in a thesis mission, the next whose condition flags are implied by the status word —
//! it parameterizes and activates the action's operations, waits for the operations that
//! end the action, suspends the others, combines the flags they report, and tells the
//! tree how the action ended. In a thesis mission any failure is a full stop (thesis
//! 9.3.1); a mission's control keys add retries, fallbacks, timeouts, recoveries,
//! parallels and reactive conditions ([`super::tree`]).
//!
//! # Invariants
//! - Every wait has a deadline: an action's own, the suspension grace, the mission's; a stuck
//!   mission ends with a reason naming the operations it waited for.
//! - Events of an earlier action (by generation number) never touch the current one.
//! - Activations carry the binding's epoch, which starts above the epoch the operation had
//!   accepted before, so a dispatcher never has its commands ignored as stale — and a
//!   dispatcher that lost the operation to a newer one is told so.
//! - Parameters omitted by the mission are sent as the declared defaults, so values left by an
//!   earlier action or mission never leak into this one.
//!
//! # Self-healing
//! Operations are held through [`Binding`]s, never raw refs. The dispatcher notices a lost
//! instance three ways: the activation's reply port closes (the instance died mid-action), the
//! instance leaves the registry (it died at any time), or it does not answer a liveness probe
//! within its declared deadline (it hangs: the dispatcher kills it). It then adopts a live
//! instance that passes the same selection — the restarted one, or another — gives it the last
//! parameters, re-activates it if its action is running, and records the rebind in the report.
//! If none appears within the mission's `rebind_deadline`, the mission comes to a full stop
//! naming the operation.
//!
//! # Events and the report
//! Every step of the run is published on the bus given in [`DispatcherArgs`], and nothing
//! else carries it: the run's report is those events folded
//! ([`ReportBuilder`](marie_vocabulary::report::ReportBuilder)), by whoever runs the dispatcher. The
//! dispatcher answers its run request with its outcome only.
//!
//! # Layout
//! This file is the actor's shell: its arguments, state and message loop. What the state
//! does lives by concern: `running.rs` (actions) with `verdict.rs` (what a report means),
//! `healing.rs` (bindings), `assembly.rs` (events and the end of the run).

use super::binding::Binding;
use super::checkpoint::{Checkpoint, CheckpointArgs, Checkpointer};
use super::messages::DispatcherMsg;
use super::mission::Mission;
use super::tree::Tree;
use marie_vocabulary::clock::{SharedClock, Timer};
use marie_vocabulary::events::{EventBus, EventKind};
use marie_vocabulary::registry::{self, ModuleKind};
use marie_vocabulary::report::{ReportBuilder, RunReport};
use marie_vocabulary::run::{FaultKind, Outcome};
use marie_vocabulary::status::StatusFlags;
use ractor::{Actor, ActorProcessingErr, ActorRef, RpcReplyPort, SpawnErr};
use std::collections::{BTreeMap, BTreeSet};
use std::time::Duration;

/// Registry id of the action dispatcher.
pub const DISPATCHER_ID: u32 = 1500;

/// Start-up arguments of the dispatcher.
#[derive(Clone)]
pub struct DispatcherArgs {
    /// The validated mission.
    pub mission: Mission,
    /// The node's clock.
    pub clock: SharedClock,
    /// Where the run's events go (the node's bus); the report is folded from them.
    pub bus: EventBus,
    /// Record the run's progress in a run datamanager, under a term
    /// ([`super::checkpoint`]); `None`: the run is recorded nowhere and no standby can
    /// take it over.
    pub checkpoint: Option<CheckpointArgs>,
    /// Take over a lost dispatcher's run from its last checkpoint instead of starting
    /// one (with `checkpoint` of a higher term).
    pub take_over: Option<TakeOver>,
}

impl DispatcherArgs {
    /// A dispatcher of `mission` on `clock`, telling its run on `bus`, recording nothing.
    pub fn new(mission: Mission, clock: SharedClock, bus: EventBus) -> DispatcherArgs {
        DispatcherArgs {
            mission,
            clock,
            bus,
            checkpoint: None,
            take_over: None,
        }
    }
}

/// A lost dispatcher's run to carry on ([`DispatcherArgs::take_over`]).
#[derive(Clone, Debug)]
pub struct TakeOver {
    /// The lost dispatcher's last checkpoint.
    pub from: Checkpoint,
    /// When the loss was noticed (the takeover's gap counts from here).
    pub noticed: std::time::Instant,
}

impl std::fmt::Debug for DispatcherArgs {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("DispatcherArgs")
            .field("mission", &self.mission.name)
            .field("bus", &self.bus)
            .finish_non_exhaustive()
    }
}

/// The ActionDispatcher actor.
#[derive(Debug)]
pub struct ActionDispatcher;

/// How an activation is sent: for which action generation and binding incarnation, with
/// which epoch, and whether it takes over a lost instance's activation.
#[derive(Clone, Copy)]
pub(super) struct Start {
    pub(super) generation: u64,
    pub(super) incarnation: u64,
    pub(super) epoch: u64,
    pub(super) resume: bool,
}

/// Timers of the whole run.
#[derive(Default)]
pub(super) struct RunTimers {
    pub(super) mission: Option<Timer>,
    pub(super) probe: Option<Timer>,
}

/// Where the current action is in its life.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum ActionState {
    /// Its operations run; it waits for its enders.
    Running,
    /// It ended: what still ran was suspended, and the action completes when they have
    /// reported (or the suspension grace passes).
    Ending,
}

/// How an action that is ending ends, for the tree.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(super) enum End {
    /// Its enders finished (or nothing ran any more): succeeded.
    Done,
    /// It failed, for this reason.
    Failed(String),
    /// The tree halted it: its end is not the tree's news.
    Halted,
}

/// An action that runs now (several under a parallel).
pub(super) struct Current {
    pub(super) generation: u64,
    pub(super) index: usize,
    /// When it started, ms since the run began.
    pub(super) started_ms: u64,
    pub(super) running: BTreeSet<String>,
    pub(super) enders_done: BTreeSet<String>,
    /// Running, or ending (its others suspended, waiting for their reports).
    pub(super) state: ActionState,
    /// Once ending: how it ends.
    pub(super) end: End,
    /// The action's deadline, then its suspension grace; cancelled with the action.
    pub(super) timer: Option<Timer>,
    /// Its operations were activated (a recorded run's action waits for its checkpoint).
    pub(super) launched: bool,
}

/// State of the dispatcher.
pub struct DispatcherState {
    pub(super) mission: Mission,
    pub(super) clock: SharedClock,
    pub(super) bus: EventBus,
    pub(super) bindings: BTreeMap<String, Binding>,
    pub(super) status: StatusFlags,
    pub(super) done: Vec<bool>,
    pub(super) generation: u64,
    /// The actions that run or end now, by generation.
    pub(super) live: BTreeMap<u64, Current>,
    /// The mission's behaviour tree and its state.
    pub(super) tree: Tree,
    /// Actions the tree started that wait for halted actions to end first (a halt ends
    /// before anything else starts).
    pub(super) pending: Vec<usize>,
    /// Why the latest action failed: the run's reason if the tree fails.
    pub(super) failure: Option<String>,
    /// When the tree must be ticked again (a backoff, a timeout).
    pub(super) wake: Option<Timer>,
    /// The run's outcome once the tree's root is done, while halted actions still end.
    pub(super) due: Option<(Outcome, String)>,
    pub(super) started: Duration,
    pub(super) reply: Option<RpcReplyPort<Outcome>>,
    /// Dropping it ends the registry watch.
    pub(super) _watch_guard: Option<tokio::sync::oneshot::Sender<()>>,

    /// The run's own timers, cancelled with the dispatcher.
    pub(super) timers: RunTimers,
    pub(super) ended: bool,
    /// The newer term this dispatcher was fenced off by, once it was
    /// ([`DispatcherState::fenced`]).
    pub(super) fenced_by: Option<u64>,
    /// Records the run's progress, if it is recorded.
    pub(super) checkpoints: Option<Checkpointer>,
    /// What to record it with, until the run starts.
    pub(super) checkpoint_args: Option<CheckpointArgs>,
    /// The run to take over, until the run starts.
    pub(super) take_over: Option<TakeOver>,
}

impl std::fmt::Debug for DispatcherState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("DispatcherState")
            .field("mission", &self.mission.name)
            .field("status", &self.status)
            .field("generation", &self.generation)
            .field("bindings", &self.bindings.keys().collect::<Vec<_>>())
            .field("ended", &self.ended)
            .finish_non_exhaustive()
    }
}

impl Current {
    /// True once the action ended and only waits for suspended operations.
    pub(super) fn ending(&self) -> bool {
        self.state == ActionState::Ending
    }
}

impl DispatcherState {
    /// Run the mission, once: start its checkpoints, carry a lost dispatcher's run on when
    /// this one takes over, else tell the run and its tree, watch the registry, bind every
    /// operation, record the first epochs, and tick the tree.
    async fn on_run(&mut self, myself: &ActorRef<DispatcherMsg>, reply: RpcReplyPort<Outcome>) {
        if self.reply.is_some() || self.generation > 0 {
            tracing::warn!("a dispatcher runs its mission once; request ignored");
            return;
        }
        self.reply = Some(reply);
        self.started = self.clock.now();
        if let Some(args) = self.checkpoint_args.take() {
            self.checkpoints = Some(Checkpointer::start(args, myself.clone()));
        }
        if let Some(take_over) = self.take_over.take() {
            self.carry_on(myself, take_over).await;
            return;
        }
        self.emit(EventKind::RunStarted {
            mission: self.mission.name.clone(),
            actions: self.mission.plan(),
            success: self.mission.flags_to_names(self.mission.success),
        });
        self.emit(EventKind::ControlPlan {
            items: super::plan::control_plan(&self.mission),
        });
        if let Err(e) = self.watch_registry(myself).await {
            self.finish(myself, Outcome::Failed, e.to_string());
            return;
        }
        if let Err(e) = self.bind().await {
            self.finish(myself, Outcome::Failed, e.to_string());
            return;
        }
        // the run's first epochs are recorded before any command carries them
        if self.checkpoint_now(myself).await.is_err() {
            return; // fenced off
        }
        self.announce(None).await;
        self.emit_bound();
        self.probe(myself);
        if let Some(deadline) = self.mission.deadline {
            self.timers.mission = Some(Timer::cast_after(
                &self.clock,
                deadline,
                myself,
                DispatcherMsg::MissionDeadline {},
            ));
        }
        self.tick(myself);
    }

    /// Translate an operation's own flag bits to the mission's status word.
    pub(super) fn translate(&self, key: &str, flags: StatusFlags) -> StatusFlags {
        let Some(binding) = self.binding(key) else {
            return StatusFlags::EMPTY;
        };
        let mut out = StatusFlags::EMPTY;
        for bit in flags.bits() {
            let Some(name) = binding.flag_names.get(bit as usize) else {
                continue;
            };
            if let Some(global) = self.mission.flags.get(name).copied() {
                out |= StatusFlags::bit(global).unwrap_or_default();
            }
        }
        out
    }

    /// The binding of the operation written as `key` (a name or an id: one operation
    /// wherever it is written). Bindings are per operation (canonical name), so an
    /// operation named by name in one action and by id in another is one binding with one
    /// epoch.
    pub(super) fn binding(&self, key: &str) -> Option<&Binding> {
        let op = self.mission.actions.iter().find_map(|a| a.op(key))?;
        self.bindings.get(&op.name)
    }

    /// The live action running operation `name` and the key it writes it as: at most one
    /// (a parallel's children never share an operation, and an action starts only once
    /// the halted ones ended).
    pub(super) fn running_key(&self, name: &str) -> Option<(u64, String)> {
        self.live.values().find_map(|cur| {
            self.mission.actions[cur.index]
                .ops
                .iter()
                .find(|o| o.name == name && cur.running.contains(&o.key))
                .map(|o| (cur.generation, o.key.clone()))
        })
    }
}

impl Actor for ActionDispatcher {
    type Msg = DispatcherMsg;
    type State = DispatcherState;
    type Arguments = DispatcherArgs;

    async fn pre_start(
        &self,
        myself: ActorRef<DispatcherMsg>,
        args: DispatcherArgs,
    ) -> Result<DispatcherState, ActorProcessingErr> {
        registry::publish(
            ModuleKind::Dispatcher,
            DISPATCHER_ID,
            "dispatcher",
            myself.get_cell(),
        )?;
        let n = args.mission.actions.len();
        let tree = Tree::new(args.mission.control.root.clone());
        Ok(DispatcherState {
            status: args.mission.initial,
            started: args.clock.now(),
            mission: args.mission,
            clock: args.clock,
            bus: args.bus,
            bindings: BTreeMap::new(),
            done: vec![false; n],
            generation: 0,
            live: BTreeMap::new(),
            tree,
            pending: Vec::new(),
            failure: None,
            wake: None,
            due: None,
            reply: None,
            _watch_guard: None,

            timers: RunTimers::default(),
            ended: false,
            fenced_by: None,
            checkpoints: None,
            checkpoint_args: args.checkpoint,
            take_over: args.take_over,
        })
    }

    // The dispatcher's shell: one arm per message, each handing it to its `on_*` (or to a
    // one-line step); its length is the length of the message list.
    async fn handle(
        &self,
        myself: ActorRef<DispatcherMsg>,
        msg: DispatcherMsg,
        state: &mut DispatcherState,
    ) -> Result<(), ActorProcessingErr> {
        // a newer term refused a checkpoint: whatever this message says, the run is the
        // successor's (see `Checkpointer::superseded`)
        if let Some(superseded) = state.superseded() {
            state.fenced(&myself, superseded.newer);
            return Ok(());
        }
        match msg {
            DispatcherMsg::Run { reply } => state.on_run(&myself, reply).await,
            DispatcherMsg::OpEnded {
                generation,
                key,
                incarnation,
                report,
            } => {
                state
                    .on_op_ended(&myself, generation, key, incarnation, report)
                    .await
            }
            DispatcherMsg::Registry { event } => state.on_registry(&myself, event).await,
            DispatcherMsg::NodeDown { node } => state.on_node_down(&myself, node).await,
            DispatcherMsg::NodeUp { node } => state.on_node_up(&myself, node).await,
            DispatcherMsg::Probe {} => {
                if !state.ended {
                    state.probe(&myself);
                }
            }
            DispatcherMsg::ProbeDone {
                name,
                incarnation,
                error,
            } => state.on_probe_done(&myself, name, incarnation, error).await,
            DispatcherMsg::ProvisionDue { name, incarnation } => {
                state.on_provision_due(name, incarnation)
            }
            DispatcherMsg::RebindDeadline { name, incarnation } => {
                state.on_rebind_deadline(&myself, name, incarnation).await
            }
            DispatcherMsg::ActionDeadline { generation } => {
                state.on_action_deadline(&myself, generation)
            }
            DispatcherMsg::SuspendGrace { generation } => {
                state.on_suspend_grace(&myself, generation)
            }
            DispatcherMsg::Abort { reason } => state.finish(&myself, Outcome::Failed, reason),
            DispatcherMsg::Fenced { newer } => state.fenced(&myself, newer),
            DispatcherMsg::NoMajority { reason } => state.no_majority(&myself, reason),
            DispatcherMsg::Launch { generation } => state.launch(&myself, generation),
            DispatcherMsg::Wake {} => state.tick(&myself),
            DispatcherMsg::Alive { reply } => {
                let _ = reply.send(state.elapsed_ms());
            }
            DispatcherMsg::Inject { fault } => {
                tracing::warn!(actor = %myself.get_id(), %fault, "injected fault into the dispatcher");
                match fault {
                    FaultKind::Panic => panic!("injected fault: the dispatcher panics"),
                    // only a kill ends this (ractor's kill signal interrupts a handler)
                    FaultKind::Hang => std::future::pending::<()>().await,
                    FaultKind::Kill => myself.kill(),
                    // the injector refuses the others (`FaultKind::hits_datamanager`)
                    _ => tracing::warn!(%fault, "not a dispatcher's fault: ignored"),
                }
            }
            DispatcherMsg::Conclude { outcome, reason } => state.conclude(&myself, outcome, reason),
            DispatcherMsg::MissionDeadline {} => {
                let deadline = state.mission.deadline.unwrap_or_default();
                state.finish(
                    &myself,
                    Outcome::Failed,
                    format!(
                        "mission `{}` missed its deadline of {:.1}s",
                        state.mission.name,
                        deadline.as_secs_f64()
                    ),
                );
            }
        }
        Ok(())
    }
}

/// Why a mission could not be run at all.
#[derive(Debug, thiserror::Error)]
pub enum DispatchError {
    /// The dispatcher actor did not start.
    #[error("dispatcher did not start: {0}")]
    Spawn(#[from] SpawnErr),
    /// The dispatcher stopped without ending its run.
    #[error("dispatcher stopped without ending its run")]
    NoReport,
}

/// Spawn a dispatcher for `args`, linked to `supervisor` if given. It does nothing until
/// asked to [`run`](request_run).
pub async fn spawn_dispatcher(
    args: DispatcherArgs,
    supervisor: Option<ractor::ActorCell>,
) -> Result<ActorRef<DispatcherMsg>, SpawnErr> {
    Ok(match supervisor {
        Some(sup) => {
            Actor::spawn_linked(None, ActionDispatcher, args, sup)
                .await?
                .0
        }
        None => Actor::spawn(None, ActionDispatcher, args).await?.0,
    })
}

/// Ask `dispatcher` to run its mission and wait for its end: the dispatcher's outcome (a
/// dispatcher runs once; the run's events are on the bus it was given).
pub async fn request_run(dispatcher: &ActorRef<DispatcherMsg>) -> Result<Outcome, DispatchError> {
    let (tx, rx) = ractor::concurrency::oneshot();
    dispatcher
        .cast(DispatcherMsg::Run { reply: tx.into() })
        .map_err(|_| DispatchError::NoReport)?;
    rx.await.map_err(|_| DispatchError::NoReport)
}

/// Run `mission` with a new, unsupervised dispatcher and give the report of its events.
///
/// The low layer, for tests and tools: no supervision, no faults, no robot's judgement —
/// an application runs missions on a node (`marie_cluster::node::Node::run`). Its events go
/// to `bus` (subscribe before calling), else to a bus of its own; the report is those
/// events folded, as a node folds its own.
pub async fn run_mission(
    mission: Mission,
    clock: SharedClock,
    bus: Option<EventBus>,
) -> Result<RunReport, DispatchError> {
    let bus = bus.unwrap_or_else(|| EventBus::new(registry::local_node_name(), clock.clone()));
    let report = ReportBuilder::attach(&bus);
    let (actor, handle) = Actor::spawn(
        None,
        ActionDispatcher,
        DispatcherArgs::new(mission, clock, bus),
    )
    .await?;
    let outcome = request_run(&actor).await;
    // the dispatcher stops by itself once it has answered
    let _ = handle.await;
    outcome.map(|_| report.finish())
}
