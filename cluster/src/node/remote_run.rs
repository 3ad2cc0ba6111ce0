//! A run dispatched on another node's desk ([`super::desk`]) and watched from this one:
//! what [`RunOptions::dispatch_on`](super::RunOptions::dispatch_on) does.
//!
//! The node asks the desk to start the run and then watches it through the cluster's
//! relayed events ([`crate::relay`]): every event the run's dispatcher publishes — on the
//! desk's node, then on each standby's that takes the run over — is republished on this
//! node's bus ([`EventBus::republish`]), so the run's report, its fault injector, its
//! lines, events file and page see one continuous run, wherever it is dispatched. The run
//! ends with the `run_ended` of its current dispatcher. Should that dispatcher's node be
//! lost (and not come back with it: a node restarted is a new process), or the dispatcher
//! be fenced off, and no standby tell its takeover within [`TAKEOVER_WAIT`], the run fails,
//! saying so.
//!
//! # Invariants
//! - The watch of the relayed events starts before the run does, and the desk waits until
//!   it reaches it: no event of the run is missed.
//! - Only the current dispatcher ends the run: the node of the desk, then the `to` of each
//!   `takeover`.

use super::desk::{DeskMsg, DESK_NAME};
use super::{Node, NodeError};
use crate::relay::Watch;
use marie_actors::dispatcher::mission::Mission;
use marie_vocabulary::events::{
    BusError, DispatcherVoice, Event, EventBus, EventKind, EventSubscription,
};
use marie_vocabulary::registry::{self, ModuleKind};
use marie_vocabulary::run::Outcome;
use ractor::rpc::CallResult;
use ractor::ActorRef;
use std::time::Duration;
use tokio::time::Instant;

/// How long a run waits for a standby to take it over once its dispatcher's node is lost.
pub const TAKEOVER_WAIT: Duration = Duration::from_secs(20);
/// How often a run whose dispatcher was lost with its node looks whether the node is back
/// with it.
const LOOK_AGAIN: Duration = Duration::from_millis(500);
/// How long a desk may take to start a run.
const START_TIMEOUT: Duration = Duration::from_secs(20);
/// How many relayed events the watch holds before it takes them (it takes them as they
/// come; a run's events arrive far slower).
const RELAY_CAPACITY: usize = 1 << 16;
/// Why a run waits for a takeover.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Orphaned {
    /// Its dispatcher's node was lost (it may come back).
    WithNode,
    /// Its dispatcher was fenced off by a standby's term.
    Fenced,
}

impl Orphaned {
    fn why(self) -> &'static str {
        match self {
            Orphaned::WithNode => "was lost with its node",
            Orphaned::Fenced => "was fenced off",
        }
    }
}

/// What the run knows of the run while it watches it.
struct RemoteRun {
    /// The dispatcher speaking for the run (its run_ended ends it): on the desk's node,
    /// until a takeover.
    voice: DispatcherVoice,
    /// The run's time as its dispatcher last told it, and when.
    told: (u64, Instant),
    /// Since when the run has no dispatcher, and why.
    lost_since: Option<(Instant, Orphaned)>,
    /// When to look next whether a lost dispatcher's node is back with it.
    look_at: Instant,
}

impl RemoteRun {
    fn new() -> Self {
        RemoteRun {
            voice: DispatcherVoice::default(),
            told: (0, Instant::now()),
            lost_since: None,
            look_at: Instant::now(),
        }
    }

    /// A relayed event of the run, republished on `bus`; `current` is the node of the
    /// dispatcher speaking for the run. The outcome once that dispatcher ended the run.
    fn relayed(&mut self, bus: &EventBus, event: Event, current: &str) -> Option<Outcome> {
        if !event.kind.is_dispatch() {
            return None;
        }
        let heard = self.voice.hears(&event);
        let Event { node, kind, .. } = event;
        if let EventKind::ActionStarted { run_ms, .. } | EventKind::ActionEnded { run_ms, .. } =
            &kind
        {
            self.told = (*run_ms, Instant::now());
        }
        match &kind {
            EventKind::Takeover { .. } => self.lost_since = None,
            // the dispatcher speaking for the run was fenced off: a standby stored a newer
            // term, and its `takeover` is on its way — or it never comes (the standby was
            // lost right after), and the run fails
            EventKind::DispatcherFenced { .. } if node == current && self.lost_since.is_none() => {
                tracing::warn!(node = %current, "the run's dispatcher was fenced off: waiting for the standby's takeover");
                self.lost_since = Some((Instant::now(), Orphaned::Fenced));
            }
            _ => {}
        }
        let ended = match &kind {
            EventKind::RunEnded { outcome, .. } if heard => Some(*outcome),
            _ => None,
        };
        bus.republish(&node, kind);
        ended
    }

    /// News of this node's own bus: the node of the run's dispatcher (`current`) lost, or
    /// back. `Err` when the bus closed.
    fn own(&mut self, news: Result<Event, BusError>, current: &str) -> Result<(), NodeError> {
        match news {
            Ok(Event {
                kind: EventKind::NodeDown { peer, .. } | EventKind::NodeLost { peer, .. },
                ..
            }) if peer == current && self.lost_since.is_none() => {
                tracing::warn!(node = %current, "the run's dispatcher node is lost: waiting for a standby to take the run over");
                self.lost_since = Some((Instant::now(), Orphaned::WithNode));
                self.look_at = Instant::now() + LOOK_AGAIN;
            }
            // its node back: whether its dispatcher goes on is told by the registry
            // ([`RemoteRun::look_again`]) — a node frozen or cut off comes back with it, one
            // restarted (a new process) without it
            Ok(_) | Err(BusError::Lagged { .. }) => {}
            Err(BusError::Closed) => return Err(NodeError::Desk("the node's bus closed".into())),
        }
        Ok(())
    }

    /// While the run's dispatcher is lost with its node (`current`): if the node is up
    /// again and a dispatcher of it is in the registry, that one goes on — the node was
    /// frozen or cut off, not restarted (a restarted node's new process runs no dispatcher
    /// of the run: a run watched on was left without one, for ever, when no standby was
    /// left to take it over).
    fn look_again(&mut self, current: &str) {
        let orphaned = self
            .lost_since
            .is_some_and(|(_, why)| why == Orphaned::WithNode);
        if orphaned && dispatcher_of(current) {
            tracing::info!(node = %current, "the run's dispatcher node is back with its dispatcher");
            self.lost_since = None;
        }
        self.look_at = Instant::now() + LOOK_AGAIN;
    }

    /// When to look again whether the run's dispatcher is back ([`RemoteRun::look_again`]).
    fn look_again_at(&self) -> Option<Instant> {
        self.lost_since
            .filter(|(_, why)| *why == Orphaned::WithNode)
            .map(|_| self.look_at)
    }

    /// When the run fails for want of a takeover, if it has no dispatcher now.
    fn no_takeover_after(&self) -> Option<Instant> {
        self.lost_since.map(|(since, _)| since + TAKEOVER_WAIT)
    }

    /// No standby took the run over in time: the run fails, told as the lost dispatcher's
    /// end on `bus` (the run's report folds its dispatcher's events only).
    fn no_takeover(&self, bus: &EventBus, current: &str) -> Outcome {
        let why = self.lost_since.map_or("was lost", |(_, why)| why.why());
        let reason = format!(
            "the dispatcher on `{current}` {why} and no standby took the run over \
             within {:.0} s",
            TAKEOVER_WAIT.as_secs_f64()
        );
        bus.republish(
            current,
            EventKind::RunEnded {
                outcome: Outcome::Failed,
                reason,
                run_ms: self.told.0 + self.told.1.elapsed().as_millis() as u64,
                status: 0,
                flags: Vec::new(),
            },
        );
        Outcome::Failed
    }
}

/// Wait until `deadline`, or for ever without one.
async fn until(deadline: Option<Instant>) {
    match deadline {
        Some(at) => tokio::time::sleep_until(at).await,
        None => std::future::pending().await,
    }
}

impl Node {
    /// Run `mission` on the desk of node `on` and watch it to its end (see the module
    /// docs): the outcome its current dispatcher ends it with.
    pub(super) async fn dispatch_on(
        &self,
        mission: Mission,
        on: &str,
    ) -> Result<Outcome, NodeError> {
        let desk = desk_on(on)?;
        let watch = crate::relay::watch(RELAY_CAPACITY)
            .await
            .map_err(|e| NodeError::Desk(format!("cannot watch the run's events: {e}")))?;
        let run = format!(
            "{}-{}",
            self.config.name,
            marie_actors::dispatcher::checkpoint::unix_ms()
        );
        let bytes = rmp_serde::to_vec(&mission)
            .map_err(|e| NodeError::Desk(format!("cannot send the mission: {e}")))?;
        // subscribed before the run starts: a loss of its dispatcher is not missed
        let own = self.bus.subscribe();
        self.start_on(&desk, on, &run, bytes, &watch).await?;
        tracing::info!(%run, node = %on, "run dispatched; watching it");
        self.watch_run(on, watch, own).await
    }

    /// Ask the desk of node `on` to start `run` (the mission as `bytes`), its events
    /// relayed to `watch`.
    async fn start_on(
        &self,
        desk: &ActorRef<DeskMsg>,
        on: &str,
        run: &str,
        bytes: Vec<u8>,
        watch: &Watch,
    ) -> Result<(), NodeError> {
        let (watcher_node, watcher_pid) = (self.config.name.clone(), watch.pid());
        let answer = desk
            .call(
                |reply| DeskMsg::Start {
                    run: run.to_string(),
                    mission: bytes,
                    watcher_node,
                    watcher_pid,
                    reply,
                },
                Some(START_TIMEOUT),
            )
            .await;
        match answer {
            Ok(CallResult::Success(Ok(()))) => Ok(()),
            Ok(CallResult::Success(Err(why))) => Err(NodeError::Desk(format!(
                "node `{on}` did not start the run: {why}"
            ))),
            _ => Err(NodeError::Desk(format!(
                "node `{on}`'s dispatcher desk did not answer within {START_TIMEOUT:?}"
            ))),
        }
    }

    /// Watch the run dispatched on `on` to its end: its relayed events from `watch`, the
    /// news of the nodes from this node's bus (`own`), and the wait for a takeover.
    async fn watch_run(
        &self,
        on: &str,
        mut watch: Watch,
        mut own: EventSubscription,
    ) -> Result<Outcome, NodeError> {
        let mut run = RemoteRun::new();
        loop {
            let current = run.voice.node().unwrap_or(on).to_string();
            tokio::select! {
                event = watch.recv() => {
                    let Some(event) = event else {
                        return Err(NodeError::Desk("the run's events stopped coming".into()));
                    };
                    if let Some(outcome) = run.relayed(&self.bus, event, &current) {
                        return Ok(outcome);
                    }
                }
                news = own.recv() => run.own(news, &current)?,
                () = until(run.look_again_at()) => run.look_again(&current),
                () = until(run.no_takeover_after()) => {
                    return Ok(run.no_takeover(&self.bus, &current));
                }
            }
        }
    }
}

/// True if node `node` is up and a run's dispatcher of it is in the registry.
fn dispatcher_of(node: &str) -> bool {
    !registry::is_declared_down(node)
        && registry::list_of(ModuleKind::Dispatcher)
            .iter()
            .any(|i| i.id == marie_actors::dispatcher::DISPATCHER_ID && i.node == node)
}

/// The dispatcher desk of node `on`.
fn desk_on(on: &str) -> Result<ActorRef<DeskMsg>, NodeError> {
    let desk = registry::lookup(ModuleKind::Dispatcher, DESK_NAME)
        .into_iter()
        .find(|i| i.node == on)
        .ok_or_else(|| {
            NodeError::Desk(format!(
                "node `{on}` runs no dispatcher desk (a node config runs one with \
                 `dispatcher = \"active\"` or `\"standby\"` in its `[node]`)"
            ))
        })?;
    Ok(desk.actor.into())
}
