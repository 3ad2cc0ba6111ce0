//! A run dispatched on another node's desk ([`super::desk`]) and followed from this one:
//! what [`RunOptions::dispatch_on`](super::RunOptions::dispatch_on) does.
//!
//! The node asks the desk to start the run and then follows it through the cluster's
//! relayed events ([`crate::relay`]): every event the run's dispatcher publishes — on the
//! desk's node, then on each standby's that takes the run over — is republished on this
//! node's bus ([`EventBus::republish`]), so the run's report, its fault injector, its
//! lines, events file and page see one continuous run, wherever it is dispatched. The run
//! ends with the `run_ended` of its current dispatcher. Should that dispatcher's node be
//! lost, or the dispatcher be fenced off, and no standby tell its takeover within
//! [`TAKEOVER_WAIT`], the run fails, saying so.
//!
//! # Invariants
//! - The watch of the relayed events starts before the run does, and the desk waits until
//!   it reaches it: no event of the run is missed.
//! - Only the current dispatcher ends the run: the node of the desk, then the `to` of each
//!   `takeover`.

use super::desk::{DeskMsg, DESK_NAME};
use super::{Node, NodeError};
use marie_actors::dispatcher::mission::Mission;
use marie_vocabulary::events::{BusError, DispatcherVoice, Event, EventKind};
use marie_vocabulary::registry::{self, ModuleKind};
use marie_vocabulary::run::Outcome;
use ractor::rpc::CallResult;
use ractor::ActorRef;
use std::time::Duration;

/// How long a run waits for a standby to take it over once its dispatcher's node is lost.
pub const TAKEOVER_WAIT: Duration = Duration::from_secs(20);
/// How long a desk may take to start a run.
const START_TIMEOUT: Duration = Duration::from_secs(20);
/// How many relayed events the follower holds before it takes them (it takes them as they
/// come; a run's events arrive far slower).
const FOLLOW_CAPACITY: usize = 1 << 16;
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

impl Node {
    /// Run `mission` on the desk of node `on` and follow it to its end (see the module
    /// docs): the outcome its current dispatcher ends it with.
    pub(super) async fn dispatch_on(
        &self,
        mission: Mission,
        on: &str,
    ) -> Result<Outcome, NodeError> {
        let desk = registry::lookup(ModuleKind::Dispatcher, DESK_NAME)
            .into_iter()
            .find(|i| i.node == on)
            .ok_or_else(|| {
                NodeError::Desk(format!(
                    "node `{on}` runs no dispatcher desk (a node config runs one with \
                     `dispatcher = \"active\"` or `\"standby\"` in its `[node]`)"
                ))
            })?;
        let desk: ActorRef<DeskMsg> = desk.actor.into();
        let mut watch = crate::relay::watch(FOLLOW_CAPACITY)
            .await
            .map_err(|e| NodeError::Desk(format!("cannot follow the run's events: {e}")))?;
        let run = format!(
            "{}-{}",
            self.config.name,
            marie_actors::dispatcher::checkpoint::unix_ms()
        );
        let bytes = rmp_serde::to_vec(&mission)
            .map_err(|e| NodeError::Desk(format!("cannot send the mission: {e}")))?;
        let (watcher_node, watcher_pid) = (self.config.name.clone(), watch.pid());
        // subscribed before the run starts: a loss of its dispatcher is not missed
        let mut own = self.bus.subscribe();
        let answer = desk
            .call(
                |reply| DeskMsg::Start {
                    run: run.clone(),
                    mission: bytes,
                    watcher_node,
                    watcher_pid,
                    reply,
                },
                Some(START_TIMEOUT),
            )
            .await;
        match answer {
            Ok(CallResult::Success(Ok(()))) => {}
            Ok(CallResult::Success(Err(why))) => {
                return Err(NodeError::Desk(format!(
                    "node `{on}` did not start the run: {why}"
                )))
            }
            _ => {
                return Err(NodeError::Desk(format!(
                    "node `{on}`'s dispatcher desk did not answer within {START_TIMEOUT:?}"
                )))
            }
        }
        tracing::info!(%run, node = %on, "run dispatched; following it");
        // the dispatcher speaking for the run (its run_ended ends it): on `on`, until a
        // takeover
        let mut voice = DispatcherVoice::default();
        // the run's time as its dispatcher last told it, and when
        let mut told = (0u64, tokio::time::Instant::now());
        // since when the run has no dispatcher, and why
        let mut lost_since: Option<(tokio::time::Instant, Orphaned)> = None;
        loop {
            let no_takeover = async {
                match lost_since {
                    Some((since, _)) => tokio::time::sleep_until(since + TAKEOVER_WAIT).await,
                    None => std::future::pending().await,
                }
            };
            let current = voice.node().unwrap_or(on).to_string();
            tokio::select! {
                event = watch.recv() => {
                    let Some(event) = event else {
                        return Err(NodeError::Desk("the run's events stopped coming".into()));
                    };
                    if !event.kind.is_dispatch() {
                        continue;
                    }
                    let heard = voice.hears(&event);
                    let Event { node, kind, .. } = event;
                    if let EventKind::ActionStarted { run_ms, .. } | EventKind::ActionEnded { run_ms, .. } = &kind {
                        told = (*run_ms, tokio::time::Instant::now());
                    }
                    match &kind {
                        EventKind::Takeover { .. } => lost_since = None,
                        // the dispatcher speaking for the run was fenced off: a standby
                        // stored a newer term, and its `takeover` is on its way — or it
                        // never comes (the standby was lost right after), and the run fails
                        EventKind::DispatcherFenced { .. }
                            if node == current && lost_since.is_none() =>
                        {
                            tracing::warn!(node = %current, "the run's dispatcher was fenced off: waiting for the standby's takeover");
                            lost_since = Some((tokio::time::Instant::now(), Orphaned::Fenced));
                        }
                        _ => {}
                    }
                    let ended = match &kind {
                        EventKind::RunEnded { outcome, .. } if heard => Some(*outcome),
                        _ => None,
                    };
                    self.bus.republish(&node, kind);
                    if let Some(outcome) = ended {
                        return Ok(outcome);
                    }
                }
                news = own.recv() => match news {
                    Ok(Event { kind: EventKind::NodeDown { peer, .. } | EventKind::NodeLost { peer, .. }, .. })
                        if peer == current && lost_since.is_none() =>
                    {
                        tracing::warn!(node = %current, "the run's dispatcher node is lost: waiting for a standby to take the run over");
                        lost_since = Some((tokio::time::Instant::now(), Orphaned::WithNode));
                    }
                    // its node back: the dispatcher goes on (unless it was fenced off)
                    Ok(Event { kind: EventKind::NodeUp { peer, .. }, .. })
                        if peer == current && lost_since.is_some_and(|(_, why)| why == Orphaned::WithNode) =>
                    {
                        lost_since = None;
                    }
                    Ok(_) | Err(BusError::Lagged { .. }) => {}
                    Err(BusError::Closed) => return Err(NodeError::Desk("the node's bus closed".into())),
                },
                () = no_takeover => {
                    let why = lost_since.map_or("was lost", |(_, why)| why.why());
                    let reason = format!(
                        "the dispatcher on `{current}` {why} and no standby took the run over \
                         within {:.0} s",
                        TAKEOVER_WAIT.as_secs_f64()
                    );
                    // told as the lost dispatcher's end: the run's report folds its
                    // dispatcher's events only
                    self.bus.republish(&current, EventKind::RunEnded {
                        outcome: Outcome::Failed,
                        reason,
                        run_ms: told.0 + told.1.elapsed().as_millis() as u64,
                        status: 0,
                        flags: Vec::new(),
                    });
                    return Ok(Outcome::Failed);
                }
            }
        }
    }
}
