//! Running actions: choosing the next action by flag implication, activating its operations,
//! collecting their reports, ending the action on its enders, suspending the rest.
//!
//! # Invariants
//! - Events of an earlier action (by generation number) never touch the current one.
//! - Parameters omitted by the mission are sent as the declared defaults, so values left by an
//!   earlier action or mission never leak into this one.
//! - An action ends when its enders say so (`any` or `all`), or when nothing runs any more;
//!   what still runs is suspended and gets [`SUSPEND_GRACE`] to report.

use super::actor::{ActionState, Current, DispatcherState, Start};
use super::effect::Effect;
use super::messages::DispatcherMsg;
use super::mission::EndMode;
use crate::clock::Timer;
use crate::eo::{EoError, EoReport};
use crate::events::{EventKind, OpStarted};
use crate::run::LossCause;
use crate::run::{OpEnd, Outcome};
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
        params: crate::property::ParamMap,
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

    pub(super) fn next_action(&mut self, myself: &ActorRef<DispatcherMsg>) {
        let next = self
            .mission
            .actions
            .iter()
            .enumerate()
            .find(|(i, a)| !self.done[*i] && self.status.implies(a.when))
            .map(|(i, _)| i);
        match next {
            Some(i) => self.start_action(myself, i),
            None if self.done.iter().all(|d| *d) => {
                if self.status.implies(self.mission.success) {
                    self.finish(myself, Outcome::Succeeded, String::new());
                } else {
                    let missing = self
                        .mission
                        .flags_to_names(self.mission.success & !self.status);
                    self.finish(
                        myself,
                        Outcome::Failed,
                        format!(
                            "every action ran but success flags are missing: {}",
                            missing.join(", ")
                        ),
                    );
                }
            }
            None => {
                let waiting: Vec<String> = self
                    .mission
                    .actions
                    .iter()
                    .enumerate()
                    .filter(|(i, _)| !self.done[*i])
                    .map(|(_, a)| {
                        let missing = self.mission.flags_to_names(a.when & !self.status);
                        format!("`{}` waits for {}", a.name, missing.join(", "))
                    })
                    .collect();
                self.finish(
                    myself,
                    Outcome::Failed,
                    format!("no action can run: {}", waiting.join("; ")),
                );
            }
        }
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
            timer: None,
            launched: false,
        };
        tracing::info!(action = %action.name, "action started");
        for op in &action.ops {
            let Some(b) = self.bindings.get_mut(&op.name) else {
                let reason = format!("operation `{}` is not bound", op.key);
                self.finish(myself, Outcome::Failed, reason);
                return;
            };
            let mut params = b.defaults.clone();
            params.extend(op.params.clone());
            b.params = params;
            current.running.insert(op.key.clone());
        }
        self.current = Some(current);
        match self.record(None) {
            Some(stored) => {
                let me = myself.clone();
                ractor::concurrency::spawn(async move {
                    // refused: the writer told the dispatcher it is fenced
                    if let Ok(Ok(())) = stored.await {
                        let _ = me.cast(DispatcherMsg::Launch { generation });
                    }
                });
            }
            None => self.launch(myself, generation),
        }
    }

    /// Tell the action of `generation` started and activate its operations (a lost one is
    /// activated when a stand-in is adopted).
    pub(super) fn launch(&mut self, myself: &ActorRef<DispatcherMsg>, generation: u64) {
        let Some(cur) = self.current.as_mut() else {
            return;
        };
        if cur.generation != generation || cur.launched || self.ended {
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
            started.push(OpStarted {
                key: op.key.clone(),
                name: b.name.clone(),
                id: b.id,
                version: b.version.clone(),
                node: b.node.clone(),
                address: b.address(),
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
        if let Some(cur) = self.current.as_mut() {
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
        let Some(cur) = self.current.as_ref() else {
            return;
        };
        if cur.generation != generation || !cur.running.contains(&key) {
            return;
        }
        let Some(b) = self.binding(&key) else {
            return;
        };
        if b.incarnation != incarnation || b.lost.is_some() {
            return; // about an instance already let go
        }
        let name = b.name.clone();
        if matches!(report, Some(EoReport::Idle { .. })) {
            // attached after a takeover, and nothing ran: it carries on resumed
            self.resume_idle(myself, &key, generation, incarnation);
            return;
        }
        if matches!(report, Some(EoReport::Stale { .. })) && self.checkpoint_now().await.is_err() {
            return; // a newer dispatcher bound it: this one is fenced
        }
        let cur = self.current.as_ref().expect("checked above");
        if report.is_none() && !cur.ending() {
            // The instance died mid-action: rebind and carry on.
            let action = self.mission.actions[cur.index].name.clone();
            self.lose(myself, &name, LossCause::DiedInAction { action })
                .await;
            return;
        }
        let cur = self.current.as_mut().expect("checked above");
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
        self.status |= global;
        let names = self.mission.flags_to_names(global);
        self.emit(EventKind::OpEnded {
            action: action_name,
            key: key.clone(),
            ended,
            flags: names,
        });
        self.checkpoint();
        let cur = self.current.as_mut().expect("checked above");
        tracing::debug!(op = %key, %ended, flags = %global, "operation report");
        if let Some(reason) = failure {
            // say what the action still waited for: often the real news (a dock not found)
            let waiting = self.awaited_enders(&key);
            let reason = match waiting.is_empty() {
                true => reason,
                false => format!("{reason} (while waiting for {})", waiting.join(", ")),
            };
            self.finish(myself, Outcome::Failed, reason);
            return;
        }
        if ending {
            if cur.running.is_empty() {
                self.complete_action(myself);
            }
            return;
        }
        let action = &self.mission.actions[cur.index];
        if ended == OpEnd::Finished && action.ends_on(&key) {
            cur.enders_done.insert(key);
            let end = match action.end_mode {
                EndMode::Any => true,
                EndMode::All => action.ends_on.iter().all(|k| cur.enders_done.contains(k)),
            };
            if end {
                self.end_action(myself);
                return;
            }
        }
        if cur.running.is_empty() {
            // Every operation finished but the enders' condition cannot hold any more.
            self.end_action(myself);
        }
    }

    /// Suspend what still runs; the action completes when they have reported.
    pub(super) fn end_action(&mut self, myself: &ActorRef<DispatcherMsg>) {
        let Some(cur) = self.current.as_mut() else {
            return;
        };
        cur.state = ActionState::Ending;
        if cur.running.is_empty() {
            self.complete_action(myself);
            return;
        }
        let generation = cur.generation;
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
        if self.give_up_on(myself, &lost) {
            return;
        }
        let cur = self.current.as_mut().expect("checked above");
        // replaces (cancels) the action's deadline
        cur.timer = Some(Timer::cast_after(
            &self.clock,
            SUSPEND_GRACE,
            myself,
            DispatcherMsg::SuspendGrace { generation },
        ));
    }

    /// The current action's enders that have not finished (other than `except`), quoted.
    pub(super) fn awaited_enders(&self, except: &str) -> Vec<String> {
        let Some(cur) = &self.current else {
            return Vec::new();
        };
        self.mission.actions[cur.index]
            .ends_on
            .iter()
            .filter(|k| k.as_str() != except && !cur.enders_done.contains(*k))
            .map(|k| format!("`{k}`"))
            .collect()
    }

    /// Stop waiting for `keys` in the current action, recording them as lost; completes the
    /// action (and returns true) when nothing else runs.
    pub(super) fn give_up_on(&mut self, myself: &ActorRef<DispatcherMsg>, keys: &[String]) -> bool {
        let Some(cur) = self.current.as_mut() else {
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
            self.complete_action(myself);
            return true;
        }
        false
    }

    pub(super) fn complete_action(&mut self, myself: &ActorRef<DispatcherMsg>) {
        let name = self
            .current
            .as_ref()
            .map(|c| self.mission.actions[c.index].name.clone())
            .unwrap_or_default();
        self.record_current();
        tracing::info!(action = %name, status = %self.status, "action ended");
        let (status, flags) = self.status_now();
        self.emit(EventKind::ActionEnded {
            action: name,
            run_ms: self.elapsed_ms(),
            flags,
            status,
        });
        self.next_action(myself);
    }

    /// The deadline of action `generation` passed: a full stop naming what it waited for.
    pub(super) fn on_action_deadline(&mut self, myself: &ActorRef<DispatcherMsg>, generation: u64) {
        let Some(cur) = &self.current else {
            return;
        };
        if cur.generation != generation || cur.ending() {
            return;
        }
        let action = &self.mission.actions[cur.index];
        let waiting = self.awaited_enders("");
        let reason = format!(
            "action `{}` missed its deadline of {:.1}s waiting for {}",
            action.name,
            action.deadline.as_secs_f64(),
            waiting.join(", ")
        );
        self.finish(myself, Outcome::Failed, reason);
    }

    /// The suspended operations of action `generation` had their time: whatever has not
    /// reported is recorded as unresponsive and the action completes.
    pub(super) fn on_suspend_grace(&mut self, myself: &ActorRef<DispatcherMsg>, generation: u64) {
        let Some(cur) = &mut self.current else {
            return;
        };
        if cur.generation != generation || !cur.ending() {
            return;
        }
        let action = self.mission.actions[cur.index].name.clone();
        let silent: Vec<String> = std::mem::take(&mut cur.running).into_iter().collect();
        for key in &silent {
            tracing::warn!(op = %key, "no report after suspension");
        }
        self.ended_without_report(&action, silent, OpEnd::Unresponsive);
        self.complete_action(myself);
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
