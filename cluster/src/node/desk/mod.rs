//! The dispatcher desk: a node that runs a cluster's missions for others, and takes a lost
//! dispatcher's run over.
//!
//! A node config with `dispatcher = "active"` or `"standby"` ([`DeskRole`]) runs a desk, a
//! permanent child of its root published in the registry as [`DESK_NAME`]. A member of the
//! cluster (`marie up --run`, [`RunOptions::dispatch_on`](super::RunOptions::dispatch_on))
//! asks a desk to [`DeskMsg::Start`] a run: the desk starts a dispatcher on its node that
//! records the run's progress in the run datamanager ([`RUN`], kept in replicas on other
//! nodes) at every transition ([`marie_actors::dispatcher::checkpoint`]). The member follows
//! the run through the cluster's relayed events.
//!
//! Every desk watches the cluster's dispatchers: when one leaves the registry (its process
//! died, its actor was killed) or its node is declared down (frozen, cut off), the desk
//! reads the run datamanager's newest checkpoint; if it belongs to a run that has not
//! ended and was written by the lost dispatcher (or, when a whole node is lost, on its
//! node), the desk takes the run over under a
//! higher term ([`TakeOver`]). A dispatcher that hangs — registered, its node up, but not
//! answering a desk's [`DispatcherMsg::Alive`] within [`ALIVE_DEADLINE`] — is lost too. A
//! standby's desk does so at once; an active node's desk
//! waits [`ACTIVE_STAGGER`] first and, should both take over, binds under a higher term
//! still, which fences the standby's off: two desks never carry one run on together.
//!
//! A desk in doubt weighs a loss only once the doubt is over, and only if the dispatcher
//! is still out of reach then: in doubt is a desk whose node hears fewer than a majority
//! of the nodes it ever heard (by their heartbeats: [`crate::net::heartbeat::reach`]) —
//! it is the one cut off, or it just woke from a freeze and sees every peer lost until
//! they redial it; it waits up to [`MINORITY_WAIT`] for a majority back. Otherwise it
//! would take over a run that was never lost: safe — the dispatcher it replaces is fenced
//! off — but a needless takeover.
//!
//! A desk whose own dispatcher was taken over from (its node frozen or cut off, then back)
//! may find the run lost again — the standby that took it over gone in turn: its dispatcher
//! is superseded, so the desk kills it and takes the run back.
//!
//! # Invariants
//! - A desk runs at most one dispatcher at a time.
//! - A takeover needs a checkpoint that has not ended and was written by the lost
//!   dispatcher (on the lost node).

mod refusal;
mod role;

pub use refusal::{DeskRefusal, NoRunDm};
pub use role::{DeskRole, UnknownDeskRole, ACTIVE_STAGGER};

use super::NodeError;
use marie_actors::dispatcher::checkpoint::{
    Checkpoint, CheckpointArgs, RunWatcher, CHECKPOINT_SOURCE,
};
use marie_actors::dispatcher::mission::Mission;
use marie_actors::dispatcher::{self, DispatcherArgs, DispatcherMsg, TakeOver};
use marie_dm::{AckSink, DmClient, RUN};
use marie_supervision::{ChildSpec, SupervisorRef};
use marie_vocabulary::clock::SharedClock;
use marie_vocabulary::events::{BusError, Event, EventBus, EventKind};
use marie_vocabulary::registry::{self, ModuleKind, RegistryEvent};
use ractor::{Actor, ActorProcessingErr, ActorRef};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::task::JoinHandle;

/// Registry name of a desk.
pub const DESK_NAME: &str = "dispatcher-desk";
/// Registry id of a desk.
pub const DESK_ID: u32 = 1501;
/// Child id of the desk under the node's root supervisor.
pub(crate) const DESK: &str = "dispatcher-desk";
/// How long a desk waits for the run datamanager (a replica being promoted).
const RUN_DM_WAIT: Duration = Duration::from_secs(10);
/// How long a desk waits for the requester's event watcher to reach its node.
const WATCHER_WAIT: Duration = Duration::from_secs(5);
/// How often a desk asks the other nodes' dispatchers whether they still answer.
const ALIVE_PERIOD: Duration = Duration::from_millis(500);
/// A dispatcher that has not answered for this long hangs: its run is taken over. Far
/// above the failure detector's deadline, and above the time a dispatcher may wait for a
/// checkpoint while the run datamanager fails over: a node frozen or cut off is declared
/// down long before, and a dispatcher that is only slow is left alone.
pub const ALIVE_DEADLINE: Duration = Duration::from_secs(5);
/// How long a desk that hears fewer than a majority of the nodes it ever heard (it is the
/// one cut off, or just woke from a freeze) waits for a majority back before it weighs a
/// loss.
pub const MINORITY_WAIT: Duration = Duration::from_secs(10);
/// Once a majority is back, how long the registry gets to hear their modules again.
const REJOIN_SETTLE: Duration = Duration::from_secs(1);

marie_vocabulary::remote_message! {
    /// Messages of a dispatcher desk.
    pub enum DeskMsg {
        /// Start run `run` of `mission` (a checked [`Mission`] as MessagePack), recorded
        /// in the run datamanager; the answer comes once the dispatcher runs (or why not).
        /// `watcher` is the requester's event watcher (its node and actor number): the
        /// desk waits until it can reach it, so the run's first events reach it too.
        Start {
            /// The run's id.
            run: String,
            /// The mission, checked, as MessagePack.
            mission: Vec<u8>,
            /// The requester's node name.
            watcher_node: String,
            /// Its watcher's actor number there.
            watcher_pid: u64,
        } -> Result<(), DeskRefusal>,
    }
    local {
        /// The dispatcher on `node` is gone, noticed at `noticed`.
        Lost {
            /// Its node.
            node: String,
            /// When it was noticed.
            noticed: Instant,
            /// It hangs (still registered, its node up), rather than gone.
            hung: bool,
            /// Its actor number on its node; `None`: every dispatcher of the node is lost
            /// (the node declared down or its sessions ended).
            pid: Option<u64>,
        },
        /// The run whose newest checkpoint is `from` was written on this node and has not
        /// ended: this desk (just started) takes it over unless it runs a dispatcher.
        Resume {
            /// The checkpoint.
            from: Box<Checkpoint>,
        },
        /// Take over the run whose last checkpoint is `from`.
        TakeOver {
            /// The checkpoint.
            from: Box<Checkpoint>,
            /// When the loss was noticed.
            noticed: Instant,
        },
    }
}

/// What a desk starts dispatchers with.
#[derive(Clone)]
pub(crate) struct DeskArgs {
    pub(crate) node: String,
    pub(crate) role: DeskRole,
    pub(crate) clock: SharedClock,
    pub(crate) bus: EventBus,
    pub(crate) root: SupervisorRef,
}

/// The desk as a permanent child of the node's root.
pub(crate) fn child_spec(args: DeskArgs) -> ChildSpec {
    ChildSpec::worker(DESK, move |sup| {
        let args = args.clone();
        async move {
            let (actor, _) = Actor::spawn_linked(None, Desk, args, sup).await?;
            Ok(actor.get_cell())
        }
    })
}

struct Desk;

struct DeskState {
    args: DeskArgs,
    /// The dispatcher this desk runs, if any.
    running: Option<ActorRef<DispatcherMsg>>,
    /// The run and term this desk took over last: a second word of the same loss (its
    /// registry leave, then its node declared down) takes nothing over again.
    took: Option<(String, u64)>,
    /// Numbers the dispatchers' child ids.
    runs: Arc<AtomicU64>,
    /// The watches of the other dispatchers (their leaves and losses, their hangs).
    watching: [JoinHandle<()>; 2],
}

impl Drop for DeskState {
    fn drop(&mut self) {
        for task in &self.watching {
            task.abort();
        }
    }
}

impl Actor for Desk {
    type Msg = DeskMsg;
    type State = DeskState;
    type Arguments = DeskArgs;

    async fn pre_start(
        &self,
        myself: ActorRef<DeskMsg>,
        args: DeskArgs,
    ) -> Result<DeskState, ActorProcessingErr> {
        let watching = [
            watch_dispatchers(&args, myself.clone()).await?,
            watch_hangs(args.node.clone(), myself.clone()),
        ];
        registry::publish(
            ModuleKind::Dispatcher,
            DESK_ID,
            DESK_NAME,
            myself.get_cell(),
        )?;
        tracing::info!(node = %args.node, role = args.role.label(), "dispatcher desk ready");
        resume_orphan(args.node.clone(), myself.clone());
        Ok(DeskState {
            args,
            running: None,
            took: None,
            runs: Arc::default(),
            watching,
        })
    }

    async fn handle(
        &self,
        myself: ActorRef<DeskMsg>,
        msg: DeskMsg,
        state: &mut DeskState,
    ) -> Result<(), ActorProcessingErr> {
        match msg {
            DeskMsg::Start {
                run,
                mission,
                watcher_node,
                watcher_pid,
                reply,
            } => {
                let answer = state.start(run, &mission, &watcher_node, watcher_pid).await;
                let _ = reply.send(answer);
            }
            DeskMsg::Lost {
                node,
                noticed,
                hung,
                pid,
            } => {
                // (busy or not: a dispatcher of this desk that another node's took over
                // from is superseded, and the run may be this desk's again)
                if node == state.args.node {
                    return Ok(());
                }
                let (stagger, _) = state.args.role.rank();
                let me = myself.clone();
                tokio::spawn(async move {
                    tokio::time::sleep(stagger).await;
                    if majority_back().await {
                        tokio::time::sleep(REJOIN_SETTLE).await;
                    }
                    // gone, unless another dispatcher of that node answers for it (this
                    // node was frozen or cut off, not that one; or the one that left was
                    // superseded there)
                    if !hung && dispatcher_in_reach(&node) {
                        tracing::info!(%node, "a dispatcher there is in reach: nothing to take over");
                        return;
                    }
                    let Ok(dm) = run_dm().await else {
                        return; // no run recorded in this cluster
                    };
                    match Checkpoint::newest(&dm).await {
                        Ok(Some(from)) if from.ended.is_none() && from.written_by(&node, pid) => {
                            let _ = me.cast(DeskMsg::TakeOver {
                                from: Box::new(from),
                                noticed,
                            });
                        }
                        Ok(Some(from)) if from.ended.is_none() && from.node == node => {
                            tracing::info!(%node, ?pid, writer = ?from.writer, term = from.term, "the dispatcher lost there did not write the run's newest checkpoint: nothing to take over");
                        }
                        Ok(_) => {}
                        Err(e) => {
                            tracing::warn!(%node, error = %e, "cannot read the run's checkpoints")
                        }
                    }
                });
            }
            DeskMsg::Resume { from } => {
                // a dispatcher of this desk may have started the run since it looked (a run
                // asked for as the cluster came up): then it is the writer, alive
                if state.busy() {
                    return Ok(());
                }
                tracing::warn!(run = %from.run, term = from.term, "a run of this node's previous process, without a dispatcher and followed still: taking it over");
                let _ = myself.cast(DeskMsg::TakeOver {
                    from,
                    noticed: Instant::now(),
                });
            }
            DeskMsg::TakeOver { from, noticed } => {
                let term = from.term + state.args.role.rank().1;
                if state
                    .took
                    .as_ref()
                    .is_some_and(|(run, t)| *run == from.run && *t >= term)
                {
                    return Ok(());
                }
                if let Some(stale) = state.running.clone().filter(|_| state.busy()) {
                    // the run's newest checkpoint is another node's: the dispatcher this
                    // desk runs was taken over from (its next checkpoint would be refused
                    // for the newer term; it may write none for long) — stopped, so that
                    // this desk can take the run back
                    tracing::warn!(run = %from.run, term = from.term, "this desk's dispatcher was superseded: killed to take the run back");
                    // killed, not stopped: it may hang (what the standby took over from)
                    let _ = stale.kill_and_wait(Some(Duration::from_secs(5))).await;
                }
                state.took = Some((from.run.clone(), term));
                if let Err(e) = state.take_over(*from, noticed).await {
                    tracing::error!(error = %e, "cannot take the run over");
                }
            }
        }
        Ok(())
    }
}

impl DeskState {
    /// True while a dispatcher of this desk runs.
    fn busy(&self) -> bool {
        self.running.as_ref().is_some_and(|d| {
            !matches!(
                d.get_status(),
                ractor::ActorStatus::Stopping | ractor::ActorStatus::Stopped
            )
        })
    }

    async fn start(
        &mut self,
        run: String,
        mission: &[u8],
        watcher_node: &str,
        watcher_pid: u64,
    ) -> Result<(), DeskRefusal> {
        if self.busy() {
            return Err(DeskRefusal::Busy {
                node: self.args.node.clone(),
            });
        }
        let mission: Mission =
            rmp_serde::from_slice(mission).map_err(|e| DeskRefusal::Garbled {
                reason: e.to_string(),
            })?;
        if !crate::relay::reaches(watcher_node, watcher_pid, WATCHER_WAIT).await {
            tracing::warn!(%watcher_node, "the requester's event watcher is not in reach yet: it may miss the run's first events");
        }
        let dm = run_dm().await?;
        // the checkpoints are acknowledged records too: the check at the run's end looks
        // them up
        let dm = dm.with_acks(AckSink::publishing_on(self.args.bus.clone()));
        let watcher = Some(RunWatcher {
            node: watcher_node.to_string(),
            pid: watcher_pid,
        });
        let checkpoint = CheckpointArgs {
            run,
            term: 1,
            dm,
            watcher,
        };
        self.spawn(DispatcherArgs {
            checkpoint: Some(checkpoint),
            ..DispatcherArgs::new(mission, self.args.clock.clone(), self.args.bus.clone())
        })
        .await
        .map_err(|e| DeskRefusal::NotStarted {
            reason: e.to_string(),
        })
    }

    async fn take_over(&mut self, from: Checkpoint, noticed: Instant) -> Result<(), NodeError> {
        let (_, raise) = self.args.role.rank();
        let dm = run_dm().await?;
        let dm = dm.with_acks(AckSink::publishing_on(self.args.bus.clone()));
        let checkpoint = CheckpointArgs {
            run: from.run.clone(),
            term: from.term + raise,
            dm,
            watcher: from.watcher.clone(),
        };
        let mission = from.mission.clone();
        self.spawn(DispatcherArgs {
            checkpoint: Some(checkpoint),
            take_over: Some(TakeOver { from, noticed }),
            ..DispatcherArgs::new(mission, self.args.clock.clone(), self.args.bus.clone())
        })
        .await
    }

    /// Start a dispatcher with `args` as a temporary child of the node's root and ask it
    /// to run (it answers when the run is over; the run's events tell everything).
    async fn spawn(&mut self, args: DispatcherArgs) -> Result<(), NodeError> {
        let n = self.runs.fetch_add(1, Ordering::Relaxed);
        let spec = super::run::dispatcher_child(format!("desk-dispatcher-{n}"), args);
        let dispatcher: ActorRef<DispatcherMsg> = self.args.root.start_child(spec).await?.into();
        self.running = Some(dispatcher.clone());
        tokio::spawn(async move {
            let outcome = dispatcher::request_run(&dispatcher).await;
            tracing::info!(?outcome, "dispatched run over");
        });
        Ok(())
    }
}

/// A desk that starts — its node restarted, a new process — looks once for a run left
/// without a dispatcher: the run datamanager's newest checkpoint has not ended, was written
/// on this node (by a dispatcher of its previous process: dead, unless this desk started
/// the run since — [`DeskMsg::Resume`] asks), and whoever follows the run still listens
/// ([`Checkpoint::watcher`]). Then it takes the run over. Without this, a run whose active
/// dispatcher's node was killed while no standby was left (given up after too many
/// restarts, or none declared) had no dispatcher for ever, though its node was back within
/// a second. A run nobody follows any more (a cluster started again on old data
/// directories) is left alone; so is one written on another node — the desks that watch
/// that node take it over when its dispatcher is lost (a desk starting as a run starts
/// elsewhere took it over needlessly, before its dispatcher was in the registry).
fn resume_orphan(me: String, desk: ActorRef<DeskMsg>) {
    tokio::spawn(async move {
        // the cluster heard first: a majority of the nodes, and their modules
        majority_back().await;
        tokio::time::sleep(REJOIN_SETTLE).await;
        let Ok(dm) = run_dm().await else {
            return; // no run recorded in this cluster
        };
        let from = match Checkpoint::newest(&dm).await {
            Ok(Some(from)) if from.ended.is_none() => from,
            Ok(_) => return,
            Err(e) => {
                tracing::warn!(error = %e, "cannot read the run's checkpoints");
                return;
            }
        };
        let Some(watcher) = from.watcher.clone().filter(|_| from.node == me) else {
            return;
        };
        if !crate::relay::reaches(&watcher.node, watcher.pid, WATCHER_WAIT).await {
            tracing::info!(run = %from.run, watcher = %watcher.node, "a run without a dispatcher, but nobody follows it: left alone");
            return;
        }
        let _ = desk.cast(DeskMsg::Resume {
            from: Box::new(from),
        });
    });
}

/// Wait up to [`MINORITY_WAIT`] until this node hears a majority ([`in_majority`]); true if
/// it did not at first (it was in doubt: whatever comes back needs [`REJOIN_SETTLE`] to be
/// heard again).
async fn majority_back() -> bool {
    if in_majority().await {
        return false;
    }
    let until = Instant::now() + MINORITY_WAIT;
    while !in_majority().await && Instant::now() < until {
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
    true
}

/// True if this node hears a majority of the nodes it ever heard, or has no heartbeat to
/// tell (no cluster: nothing to doubt). The heartbeats, not the sessions or the registry:
/// a node cut off declares its peers down one by one, a tick or so apart, and the first
/// loss it sees must not find the others still "in reach"; a node woken from a freeze has
/// heard nobody lately.
async fn in_majority() -> bool {
    crate::net::heartbeat::reach()
        .await
        .is_none_or(|reach| reach.majority())
}

/// True if a dispatcher of node `node` is in the registry and its node not declared down.
fn dispatcher_in_reach(node: &str) -> bool {
    !registry::is_declared_down(node) && dispatchers().any(|i| i.node == node)
}

/// The runs' dispatchers in the registry (not the desks).
fn dispatchers() -> impl Iterator<Item = registry::Instance> {
    registry::list_of(ModuleKind::Dispatcher)
        .into_iter()
        .filter(|i| i.id == dispatcher::DISPATCHER_ID)
}

/// The run datamanager, waiting for one (a replica being promoted).
async fn run_dm() -> Result<DmClient, NoRunDm> {
    DmClient::lookup_within(RUN.name, CHECKPOINT_SOURCE, RUN_DM_WAIT)
        .await
        .map(|dm| dm.with_follow(RUN_DM_WAIT))
        .map_err(|_| NoRunDm)
}

/// Tell the desk `desk` whenever a dispatcher on another node leaves the registry or its
/// node is lost (declared down, or its sessions ended).
async fn watch_dispatchers(
    args: &DeskArgs,
    desk: ActorRef<DeskMsg>,
) -> Result<JoinHandle<()>, ractor::SpawnErr> {
    let mut leaves = registry::watch(Some(ModuleKind::Dispatcher)).await?;
    let mut bus = args.bus.subscribe();
    let me = args.node.clone();
    Ok(tokio::spawn(async move {
        loop {
            let (node, pid) = tokio::select! {
                event = leaves.next() => match event {
                    Some(RegistryEvent::Left(inst)) if inst.name == "dispatcher" => {
                        let pid = inst.actor_id().pid();
                        (inst.node, Some(pid))
                    }
                    Some(_) => continue,
                    None => return,
                },
                event = bus.recv() => match event {
                    Ok(Event { kind: EventKind::NodeDown { peer, .. } | EventKind::NodeLost { peer, .. }, .. }) => (peer, None),
                    Ok(_) | Err(BusError::Lagged { .. }) => continue,
                    Err(BusError::Closed) => return,
                },
            };
            if node == me {
                continue;
            }
            let noticed = Instant::now();
            if desk
                .cast(DeskMsg::Lost {
                    node,
                    noticed,
                    hung: false,
                    pid,
                })
                .is_err()
            {
                return;
            }
        }
    }))
}

/// Ask every other node's dispatcher every [`ALIVE_PERIOD`] whether it answers; tell the
/// desk of one that has not for [`ALIVE_DEADLINE`] (a dispatcher that hangs).
fn watch_hangs(me: String, desk: ActorRef<DeskMsg>) -> JoinHandle<()> {
    tokio::spawn(async move {
        let mut ticks = tokio::time::interval(ALIVE_PERIOD);
        ticks.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        loop {
            ticks.tick().await;
            let others = dispatchers().filter(|i| i.node != me);
            for inst in others {
                let actor: ActorRef<DispatcherMsg> = inst.actor.clone().into();
                let asked = Instant::now();
                // the deadline is kept here, not by the call: a remote call's own timeout
                // was seen to take 30 s instead of 5 under CI's load
                let answer = tokio::time::timeout(
                    ALIVE_DEADLINE,
                    actor.call(|reply| DispatcherMsg::Alive { reply }, None),
                )
                .await;
                // a deadline noticed far too late: this node itself stood still (frozen),
                // not the dispatcher; asked again at the next tick
                let stood_still = asked.elapsed() > ALIVE_DEADLINE + 2 * ALIVE_PERIOD;
                if answer.is_err() && !stood_still {
                    tracing::warn!(node = %inst.node, "the dispatcher there does not answer: it hangs");
                    if desk
                        .cast(DeskMsg::Lost {
                            node: inst.node.clone(),
                            noticed: asked + ALIVE_DEADLINE,
                            hung: true,
                            pid: Some(inst.actor_id().pid()),
                        })
                        .is_err()
                    {
                        return;
                    }
                }
            }
        }
    })
}
