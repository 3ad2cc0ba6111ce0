//! Running actions: the mission's tree ([`super::tree`]) says which actions start and which
//! are halted; this file activates their operations, collects their reports, ends each
//! action on its enders, suspends the rest, and tells the tree how each ended.
//!
//! The tree is ticked when an action completes, when the status word gains a flag (a
//! reactive condition may no longer hold) and when a backoff or a timeout is due
//! ([`DispatcherMsg::Wake`]). A thesis mission's tree is a schedule: the first action not
//! yet done whose flags hold runs next, and a failure fails the run.
//!
//! # Invariants
//! - Events of an earlier action (by generation number) never touch a later one; several
//!   actions live at once only under a parallel, and never share an operation.
//! - Parameters omitted by the mission are sent as the declared defaults, so values left by an
//!   earlier action or mission never leak into this one.
//! - An action ends when its enders say so (`any` or `all`), when nothing runs any more,
//!   when it fails, or when the tree halts it; what still runs is suspended and gets
//!   [`SUSPEND_GRACE`] to report.
//! - A halt completes before anything else starts: the actions a tick starts wait until
//!   every halted action's operations reported (or the grace passed). The run ends the
//!   same way: once the root is done, after the halted actions ended.

use super::actor::{ActionState, Current, DispatcherState, End, Start};
use super::effect::Effect;
use super::messages::DispatcherMsg;
use super::mission::EndMode;
use super::tree::{Command, Decision, Node, Status};
use crate::eo::{EoError, EoReport};
use marie_vocabulary::clock::Timer;
use marie_vocabulary::events::{ActionResult, EventKind, OpStarted};
use marie_vocabulary::run::LossCause;
use marie_vocabulary::run::{OpEnd, Outcome, ParamSource, ParamValue};
use marie_vocabulary::status::StatusFlags;
use ractor::ActorRef;
use std::collections::BTreeSet;
use std::time::Duration;

/// Tell `myself` the report `rx` brings (`None`: the instance died first) as `OpEnded` of
/// the operation written `key` in action `generation`, incarnation `incarnation`.
pub(super) fn forward_report(
    myself: &ActorRef<DispatcherMsg>,
    rx: ractor::concurrency::OneshotReceiver<EoReport>,
    generation: u64,
    key: &str,
    incarnation: u64,
) {
    let me = myself.clone();
    let key = key.to_string();
    ractor::concurrency::spawn(async move {
        let report = rx.await.ok();
        let _ = me.cast(DispatcherMsg::OpEnded {
            generation,
            key,
            incarnation,
            report,
        });
    });
}

/// Tell the fence keepers the epochs of the bindings an action's start moved to a newer
/// version (none: nothing to tell), as an adoption tells its raised epoch: before the
/// action's first command carries them. A keeper that does not answer learns them from
/// that command (each ask is bounded by the fence's own timeout).
async fn announce_moves(moved: &[marie_vocabulary::fence::Fence]) {
    if moved.is_empty() {
        return;
    }
    let announced = marie_vocabulary::fence::announce(moved).await;
    if announced.told < announced.keepers {
        tracing::warn!(
            "a move's epoch reached {} of {} fence keepers: the others learn it from the first command",
            announced.told,
            announced.keepers
        );
    }
}

/// How long suspended operations get to report before the dispatcher moves on.
pub(super) const SUSPEND_GRACE: Duration = Duration::from_secs(5);

impl DispatcherState {
    /// Send `Activate` (or `Resume`) to the binding's instance; its report comes back as
    /// `OpEnded`.
    pub(super) fn activate(
        &self,
        myself: &ActorRef<DispatcherMsg>,
        key: &str,
        start: Start,
        params: marie_vocabulary::property::ParamMap,
    ) -> Result<(), EoError> {
        let Some(b) = self.binding(key) else {
            return Err(EoError::Gone(key.to_string()));
        };
        let Start {
            generation,
            incarnation,
            epoch,
            resume,
        } = start;
        let rx = if resume {
            b.client.resume(params, epoch)?
        } else {
            b.client.activate(params, epoch)?
        };
        forward_report(myself, rx, generation, key, incarnation);
        Ok(())
    }

    /// Tick the mission's tree: tell its decisions, halt what it halts, start what it
    /// starts (once every halted action ended), arm its next wake, and end the run once
    /// its root is done.
    pub(super) fn tick(&mut self, myself: &ActorRef<DispatcherMsg>) {
        if self.ended || self.due.is_some() {
            return;
        }
        let now = Duration::from_millis(self.elapsed_ms());
        let tick = self.tree.tick(self.status.0, now);
        for decision in tick.decisions {
            self.tell_decision(decision);
        }
        let mut halted = Vec::new();
        for command in &tick.commands {
            match *command {
                Command::Halt(index) => {
                    let found = self
                        .live
                        .values_mut()
                        .find(|c| c.index == index && c.end != End::Halted);
                    if let Some(cur) = found {
                        cur.end = End::Halted;
                        cur.state = ActionState::Ending;
                        halted.push(cur.generation);
                    } else {
                        // not started yet: it waited for an earlier halt
                        self.pending.retain(|p| *p != index);
                    }
                }
                Command::Start(index) => self.pending.push(index),
            }
        }
        self.wake = tick.wake.map(|at| {
            Timer::cast_after(
                &self.clock,
                at.saturating_sub(now),
                myself,
                DispatcherMsg::Wake {},
            )
        });
        let outcome = match tick.status {
            Status::Running => None,
            Status::Succeeded if self.status.implies(self.mission.success) => {
                Some((Outcome::Succeeded, String::new()))
            }
            Status::Succeeded => {
                let missing = self
                    .mission
                    .flags_to_names(self.mission.success & !self.status);
                let reason = format!(
                    "every action ran but success flags are missing: {}",
                    missing.join(", ")
                );
                Some((Outcome::Failed, reason))
            }
            Status::Failed => {
                let reason = self.failure.take().unwrap_or_else(|| self.stuck());
                Some((Outcome::Failed, reason))
            }
        };
        for generation in halted {
            self.end_action(myself, generation);
        }
        match outcome {
            // the run ends once the halted actions' operations reported (within the grace)
            Some(outcome) => self.conclude_when_halted(myself, outcome),
            None => self.start_pending(myself),
        }
    }

    /// End the run with `outcome` once no action is live; until then, each one that
    /// completes brings it closer ([`Self::complete_action`]).
    fn conclude_when_halted(
        &mut self,
        myself: &ActorRef<DispatcherMsg>,
        outcome: (Outcome, String),
    ) {
        self.pending.clear();
        if self.live.is_empty() {
            self.due = None;
            self.finish(myself, outcome.0, outcome.1);
        } else {
            self.due = Some(outcome);
        }
    }

    /// Start the actions the tree started, unless a halted action is still ending.
    fn start_pending(&mut self, myself: &ActorRef<DispatcherMsg>) {
        if self.ended || self.live.values().any(|c| c.end == End::Halted) {
            return;
        }
        for index in std::mem::take(&mut self.pending) {
            self.start_action(myself, index);
            if self.ended {
                return;
            }
        }
    }

    /// Why nothing can run: what each waiting item of the root schedule waits for.
    fn stuck(&self) -> String {
        let waiting: Vec<String> = self
            .tree
            .waiting()
            .into_iter()
            .map(|(id, when)| {
                let missing = self
                    .mission
                    .flags_to_names(StatusFlags(when) & !self.status);
                format!(
                    "`{}` waits for {}",
                    self.mission.control.label(id),
                    missing.join(", ")
                )
            })
            .collect();
        format!("no action can run: {}", waiting.join("; "))
    }

    /// The action or group node `id` decorates (through retries, timeouts, recoveries and
    /// a reactive wrapper of one child), or `id` itself: what a decision names as the
    /// item it turns to (`fallback to \`back-along-wall\``, not to its retry).
    fn item_of(&self, mut id: usize) -> usize {
        let nodes = self.tree.preorder();
        loop {
            let decorated = match nodes[id] {
                Node::Retry { .. } | Node::Timeout { .. } | Node::Recover { .. } => true,
                Node::Reactive { children, .. } => children.len() == 1,
                _ => false,
            };
            match self.tree.child_ids(id).first() {
                Some(child) if decorated => id = *child,
                _ => return id,
            }
        }
    }

    /// Publish a control decision of the tree, its nodes named.
    fn tell_decision(&mut self, decision: Decision) {
        let control = &self.mission.control;
        let (node, what) = match decision {
            Decision::Retry { node, attempt, of } => (node, format!("retry {attempt} of {of}")),
            Decision::GaveUp { node, of } => (node, format!("gave up after {of} attempts")),
            Decision::Fallback { node, to } => {
                let to = self.item_of(to);
                (node, format!("fallback to `{}`", control.label(to)))
            }
            Decision::Timeout { node, limit_ms } => (
                node,
                format!("timeout after {:.1} s", limit_ms as f64 / 1000.0),
            ),
            Decision::ConditionLost { node } => (node, "condition no longer holds".to_string()),
            Decision::Recovery { node } => {
                let recovery = self.tree.child_ids(node).get(1).copied().unwrap_or(node);
                let recovery = self.item_of(recovery);
                (node, format!("recovery `{}`", control.label(recovery)))
            }
            Decision::Decided { node, succeeded } => (
                node,
                match succeeded {
                    true => "parallel succeeded".to_string(),
                    false => "parallel failed".to_string(),
                },
            ),
        };
        let label = control.label(node).to_string();
        tracing::info!(node = %label, decision = %what, "control");
        self.emit(EventKind::Control {
            item: label,
            decision: what,
            run_ms: self.elapsed_ms(),
        });
    }

    /// Start action `index`: its operations' parameters set, the action recorded — and,
    /// for a recorded run, once that checkpoint is stored, launched ([`Self::launch`]): a
    /// standby never carries on from an action older than the one whose commands went out.
    pub(super) fn start_action(&mut self, myself: &ActorRef<DispatcherMsg>, index: usize) {
        self.generation += 1;
        let generation = self.generation;
        let action = self.mission.actions[index].clone();
        let mut current = Current {
            generation,
            index,
            started_ms: self.elapsed_ms(),
            running: BTreeSet::new(),
            enders_done: BTreeSet::new(),
            state: ActionState::Running,
            end: End::Done,
            timer: None,
            launched: false,
        };
        tracing::info!(action = %action.name, "action started");
        let mut moved = Vec::new();
        for op in &action.ops {
            moved.extend(self.upgrade_at_start(&op.name, &action.name, generation));
            let Some(b) = self.bindings.get_mut(&op.name) else {
                let reason = format!("operation `{}` is not bound", op.key);
                self.finish(myself, Outcome::Failed, reason);
                return;
            };
            b.params = b.supplied(&op.params);
            current.running.insert(op.key.clone());
        }
        self.live.insert(generation, current);
        let me = myself.clone();
        match self.record(None) {
            Some(stored) => {
                ractor::concurrency::spawn(async move {
                    // refused: the writer told the dispatcher it is fenced
                    if let Ok(Ok(())) = stored.await {
                        announce_moves(&moved).await;
                        let _ = me.cast(DispatcherMsg::Launch { generation });
                    }
                });
            }
            None if moved.is_empty() => self.launch(myself, generation),
            None => {
                ractor::concurrency::spawn(async move {
                    announce_moves(&moved).await;
                    let _ = me.cast(DispatcherMsg::Launch { generation });
                });
            }
        }
    }

    /// Tell the action of `generation` started and activate its operations (a lost one is
    /// activated when a stand-in is adopted).
    pub(super) fn launch(&mut self, myself: &ActorRef<DispatcherMsg>, generation: u64) {
        let Some(cur) = self.live.get_mut(&generation) else {
            return;
        };
        if cur.launched || cur.ending() || self.ended {
            return;
        }
        cur.launched = true;
        let (index, started_ms) = (cur.index, cur.started_ms);
        let action = self.mission.actions[index].clone();
        let mut started = Vec::new();
        let mut activations = Vec::new();
        for op in &action.ops {
            let Some(b) = self.bindings.get(&op.name) else {
                continue;
            };
            let supplied = b.info.migrated(&op.params);
            started.push(OpStarted {
                key: op.key.clone(),
                name: b.name.clone(),
                id: b.id,
                version: b.version.clone(),
                node: b.node.clone(),
                address: b.address(),
                params: b
                    .params
                    .iter()
                    .map(|(name, value)| ParamValue {
                        name: name.clone(),
                        value: value.clone(),
                        source: match supplied.contains_key(name) {
                            true => ParamSource::Mission,
                            false => ParamSource::Default,
                        },
                    })
                    .collect(),
            });
            if b.lost.is_none() {
                activations.push((
                    op.key.clone(),
                    op.name.clone(),
                    b.incarnation,
                    b.params.clone(),
                    b.epoch,
                ));
            }
        }
        self.emit(EventKind::ActionStarted {
            action: action.name.clone(),
            run_ms: started_ms,
            operations: started,
        });
        // launched: a standby attaches to these activations rather than starting them anew
        self.checkpoint();
        for (key, name, incarnation, params, epoch) in activations {
            let start = Start {
                generation,
                incarnation,
                epoch,
                resume: false,
            };
            if let Err(e) = self.activate(myself, &key, start, params) {
                // the instance died since it was bound: a loss like any other
                self.report_gone(myself, &name, incarnation, e);
            }
        }
        let ran = Duration::from_millis(self.elapsed_ms().saturating_sub(started_ms));
        let timer = Timer::cast_after(
            &self.clock,
            action.deadline.saturating_sub(ran),
            myself,
            DispatcherMsg::ActionDeadline { generation },
        );
        if let Some(cur) = self.live.get_mut(&generation) {
            cur.timer = Some(timer);
        }
    }

    pub(super) async fn on_op_ended(
        &mut self,
        myself: &ActorRef<DispatcherMsg>,
        generation: u64,
        key: String,
        incarnation: u64,
        report: Option<EoReport>,
    ) {
        let Some(cur) = self.live.get(&generation) else {
            return;
        };
        if !cur.running.contains(&key) {
            return;
        }
        let Some(b) = self.binding(&key) else {
            return;
        };
        if b.incarnation != incarnation || b.lost.is_some() {
            return; // about an instance already let go
        }
        let name = b.name.clone();
        let reported_ms = self.elapsed_ms();
        if let Some(b) = self.bindings.get_mut(&name) {
            b.last_report_ms = Some(reported_ms);
        }
        if matches!(report, Some(EoReport::Idle { .. })) {
            // attached after a takeover, and nothing ran: it carries on resumed
            self.resume_idle(myself, &key, generation, incarnation);
            return;
        }
        if let Some(EoReport::Stale { current, .. }) = &report {
            if self.checkpoint_now(myself).await.is_err() {
                return; // a newer dispatcher bound it: this one is fenced
            }
            let reason =
                format!("operation `{key}` is now bound by another dispatcher (epoch {current})");
            self.finish(myself, Outcome::Failed, reason);
            return;
        }
        if let Some(reason) = self.first_activation_failed(&name, generation, report.as_ref()) {
            // an upgrade's new instance replied with an error: back to the old one
            if self.roll_back(myself, &name, reason).await {
                return;
            }
        }
        let Some(cur) = self.live.get(&generation) else {
            return;
        };
        if report.is_none() && !cur.ending() {
            // The instance died mid-action: rebind and carry on.
            let action = self.mission.actions[cur.index].name.clone();
            self.lose(myself, &name, LossCause::DiedInAction { action })
                .await;
            return;
        }
        let Some(cur) = self.live.get_mut(&generation) else {
            return;
        };
        cur.running.remove(&key);
        let action = &self.mission.actions[cur.index];
        let action_name = action.name.clone();
        let ending = cur.ending();
        let Effect {
            ended,
            flags,
            failure,
        } = Effect::of(report, ending, &key, &action_name);
        let global = self.translate(&key, flags);
        let news = global & !self.status;
        self.status |= global;
        let names = self.mission.flags_to_names(global);
        self.emit(EventKind::OpEnded {
            action: action_name,
            key: key.clone(),
            ended,
            flags: names,
        });
        self.checkpoint();
        tracing::debug!(op = %key, %ended, flags = %global, "operation report");
        if let Some(reason) = failure {
            // say what the action still waited for: often the real news (a dock not found)
            let waiting = self.awaited_enders(generation, &key);
            let reason = match waiting.is_empty() {
                true => reason,
                false => format!("{reason} (while waiting for {})", waiting.join(", ")),
            };
            self.fail_action(myself, generation, reason);
            return;
        }
        let cur = self.live.get_mut(&generation).expect("checked above");
        if ending {
            if cur.running.is_empty() {
                self.complete_action(myself, generation);
            }
            return;
        }
        let action = &self.mission.actions[cur.index];
        let mut end = cur.running.is_empty();
        if ended == OpEnd::Finished && action.ends_on(&key) {
            cur.enders_done.insert(key);
            end |= match action.end_mode {
                EndMode::Any => true,
                EndMode::All => action.ends_on.iter().all(|k| cur.enders_done.contains(k)),
            };
        }
        if end {
            // its enders finished — or every operation finished but the enders' condition
            // cannot hold any more
            self.end_action(myself, generation);
        } else if !news.is_empty() {
            // a reactive condition may no longer hold
            self.tick(myself);
        }
    }

    /// Action `generation` failed for `reason`: it ends (what still runs suspended) and the
    /// tree hears of its failure.
    pub(super) fn fail_action(
        &mut self,
        myself: &ActorRef<DispatcherMsg>,
        generation: u64,
        reason: String,
    ) {
        let Some(cur) = self.live.get_mut(&generation) else {
            return;
        };
        if cur.end != End::Halted {
            cur.end = End::Failed(reason);
        }
        cur.state = ActionState::Ending;
        self.end_action(myself, generation);
    }

    /// Suspend what still runs of action `generation`; it completes when they have
    /// reported.
    pub(super) fn end_action(&mut self, myself: &ActorRef<DispatcherMsg>, generation: u64) {
        let Some(cur) = self.live.get_mut(&generation) else {
            return;
        };
        cur.state = ActionState::Ending;
        if !cur.launched {
            // ended while its start's checkpoint was being stored: nothing was activated,
            // nothing is suspended (its launch, when stored, finds it gone)
            cur.running.clear();
        }
        if cur.running.is_empty() {
            self.complete_action(myself, generation);
            return;
        }
        let running: Vec<String> = cur.running.iter().cloned().collect();
        self.checkpoint();
        let mut lost = Vec::new();
        for key in &running {
            match self.binding(key) {
                Some(b) if b.lost.is_none() => {
                    let _ = b.client.suspend(b.epoch);
                }
                _ => lost.push(key.clone()),
            }
        }
        // An operation still without a stand-in has nothing to suspend.
        if self.give_up_on(myself, generation, &lost) {
            return;
        }
        let Some(cur) = self.live.get_mut(&generation) else {
            return;
        };
        // replaces (cancels) the action's deadline
        cur.timer = Some(Timer::cast_after(
            &self.clock,
            SUSPEND_GRACE,
            myself,
            DispatcherMsg::SuspendGrace { generation },
        ));
    }

    /// Action `generation`'s enders that have not finished (other than `except`), quoted.
    pub(super) fn awaited_enders(&self, generation: u64, except: &str) -> Vec<String> {
        let Some(cur) = self.live.get(&generation) else {
            return Vec::new();
        };
        self.mission.actions[cur.index]
            .ends_on
            .iter()
            .filter(|k| k.as_str() != except && !cur.enders_done.contains(*k))
            .map(|k| format!("`{k}`"))
            .collect()
    }

    /// Stop waiting for `keys` in action `generation`, recording them as lost; completes
    /// the action (and returns true) when nothing else runs.
    pub(super) fn give_up_on(
        &mut self,
        myself: &ActorRef<DispatcherMsg>,
        generation: u64,
        keys: &[String],
    ) -> bool {
        let Some(cur) = self.live.get_mut(&generation) else {
            return false;
        };
        let action = self.mission.actions[cur.index].name.clone();
        let mut gone = Vec::new();
        for key in keys {
            if cur.running.remove(key) {
                gone.push(key.clone());
            }
        }
        let nothing_runs = cur.running.is_empty();
        self.ended_without_report(&action, gone, OpEnd::Lost);
        if nothing_runs {
            self.complete_action(myself, generation);
            return true;
        }
        false
    }

    /// Action `generation` is over: tell it, let the tree hear how it ended (unless the
    /// tree halted it), and tick.
    pub(super) fn complete_action(&mut self, myself: &ActorRef<DispatcherMsg>, generation: u64) {
        let Some(cur) = self.live.remove(&generation) else {
            return;
        };
        let name = self.mission.actions[cur.index].name.clone();
        match &cur.end {
            End::Done => {
                self.done[cur.index] = true;
                self.tree.leaf_ended(cur.index, true);
            }
            End::Failed(reason) => {
                self.failure = Some(reason.clone());
                self.tree.leaf_ended(cur.index, false);
            }
            End::Halted => {}
        }
        tracing::info!(action = %name, status = %self.status, "action ended");
        let (status, flags) = self.status_now();
        let result = match cur.end {
            End::Done => ActionResult::Succeeded,
            End::Failed(_) => ActionResult::Failed,
            End::Halted => ActionResult::Halted,
        };
        self.emit(EventKind::ActionEnded {
            action: name,
            run_ms: self.elapsed_ms(),
            flags,
            status,
            result: Some(result),
        });
        self.checkpoint();
        if let Some(outcome) = self.due.take() {
            return self.conclude_when_halted(myself, outcome);
        }
        match cur.end {
            End::Halted => self.start_pending(myself),
            _ => self.tick(myself),
        }
    }

    /// The deadline of action `generation` passed: it fails, naming what it waited for.
    pub(super) fn on_action_deadline(&mut self, myself: &ActorRef<DispatcherMsg>, generation: u64) {
        let Some(cur) = self.live.get(&generation) else {
            return;
        };
        if cur.ending() {
            return;
        }
        let action = &self.mission.actions[cur.index];
        let waiting = self.awaited_enders(generation, "");
        let reason = format!(
            "action `{}` missed its deadline of {:.1}s waiting for {}",
            action.name,
            action.deadline.as_secs_f64(),
            waiting.join(", ")
        );
        self.fail_action(myself, generation, reason);
    }

    /// The suspended operations of action `generation` had their time: whatever has not
    /// reported is recorded as unresponsive and the action completes.
    pub(super) fn on_suspend_grace(&mut self, myself: &ActorRef<DispatcherMsg>, generation: u64) {
        let Some(cur) = self.live.get_mut(&generation) else {
            return;
        };
        if !cur.ending() {
            return;
        }
        let action = self.mission.actions[cur.index].name.clone();
        let silent: Vec<String> = std::mem::take(&mut cur.running).into_iter().collect();
        for key in &silent {
            tracing::warn!(op = %key, "no report after suspension");
        }
        self.ended_without_report(&action, silent, OpEnd::Unresponsive);
        self.complete_action(myself, generation);
    }

    /// Record that `keys` of action `action` ended as `ended` without a report of theirs.
    fn ended_without_report(&mut self, action: &str, keys: Vec<String>, ended: OpEnd) {
        for key in keys {
            self.emit(EventKind::OpEnded {
                action: action.to_string(),
                key,
                ended,
                flags: Vec::new(),
            });
        }
    }
}
