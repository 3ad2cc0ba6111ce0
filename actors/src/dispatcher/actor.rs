//! The ActionDispatcher actor: runs a validated mission against live operations.
//!
//! It never does the work itself (thesis 3.2.4.1): for each action whose condition flags are
//! implied by the status word it parameterizes and activates the action's operations, waits
//! for the operations that end the action, suspends the others, combines the flags they
//! report, and picks the next action. Any failure is a full stop (thesis 9.3.1).
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

use super::catalog::describe;
use super::mission::{EndMode, Mission};
use super::report::{ActionRecord, OpRecord, Outcome, RunReport};
use crate::clock::{cast_after, SharedClock};
use crate::eo::{EoClient, EoReport};
use crate::flags::StatusFlags;
use crate::property::{General, Group, ParamMap, PropertyReply, PropertyRequest};
use crate::registry::{self, ModuleKind};
use ractor::{Actor, ActorProcessingErr, ActorRef, RpcReplyPort, SpawnErr};
use std::collections::{BTreeMap, BTreeSet};
use std::time::Duration;
use tokio::sync::mpsc;

/// Registry id of the action dispatcher.
pub const DISPATCHER_ID: u32 = 1500;

/// How long suspended operations get to report before the dispatcher moves on.
const SUSPEND_GRACE: Duration = Duration::from_secs(5);

/// Progress of a run, for live output.
#[derive(Clone, Debug, PartialEq)]
pub enum DispatchEvent {
    /// All operations were found and bound.
    Bound {
        /// `(operation, version, node)` for each binding.
        operations: Vec<(String, String, String)>,
    },
    /// An action started.
    ActionStarted {
        /// Action name.
        action: String,
        /// Its operations.
        operations: Vec<String>,
    },
    /// An action ended.
    ActionEnded {
        /// Action name.
        action: String,
        /// Status word after it, as names.
        flags: Vec<String>,
        /// Status word after it.
        status: StatusFlags,
    },
    /// The mission ended.
    Ended {
        /// Outcome.
        outcome: Outcome,
        /// Reason of a failure.
        reason: String,
    },
}

crate::remote_message! {
    /// Messages of the action dispatcher.
    pub enum DispatcherMsg {
        /// Run the mission; the answer comes when it has ended.
        Run {} -> RunReport,
    }
    local {
        /// An activation ended (`None`: its operation died before reporting).
        OpEnded {
            /// Generation of the action that activated it.
            generation: u64,
            /// The operation's key in that action.
            key: String,
            /// Its report.
            report: Option<EoReport>,
        },
        /// The deadline of action generation `generation` passed.
        ActionDeadline {
            /// Generation of the action.
            generation: u64,
        },
        /// Suspended operations of generation `generation` had their time to report.
        SuspendGrace {
            /// Generation of the action.
            generation: u64,
        },
        /// The whole mission's deadline passed.
        MissionDeadline {},
    }
}

/// Start-up arguments of the dispatcher.
pub struct DispatcherArgs {
    /// The validated mission.
    pub mission: Mission,
    /// The node's clock.
    pub clock: SharedClock,
    /// Where progress events go.
    pub events: Option<mpsc::UnboundedSender<DispatchEvent>>,
}

/// The ActionDispatcher actor.
pub struct ActionDispatcher;

struct Binding {
    client: EoClient,
    name: String,
    id: u32,
    version: String,
    node: String,
    address: String,
    epoch: u64,
    defaults: ParamMap,
    flag_names: Vec<String>,
    params: ParamMap,
}

struct Current {
    generation: u64,
    index: usize,
    start_ms: u64,
    running: BTreeSet<String>,
    enders_done: BTreeSet<String>,
    ending: bool,
    ops: BTreeMap<String, OpRecord>,
}

/// State of the dispatcher.
pub struct DispatcherState {
    mission: Mission,
    clock: SharedClock,
    events: Option<mpsc::UnboundedSender<DispatchEvent>>,
    bindings: BTreeMap<String, Binding>,
    status: StatusFlags,
    done: Vec<bool>,
    generation: u64,
    current: Option<Current>,
    started: Duration,
    actions: Vec<ActionRecord>,
    reply: Option<RpcReplyPort<RunReport>>,
}

impl DispatcherState {
    fn emit(&self, evt: DispatchEvent) {
        if let Some(tx) = &self.events {
            let _ = tx.send(evt);
        }
    }

    fn elapsed_ms(&self) -> u64 {
        self.clock.now().saturating_sub(self.started).as_millis() as u64
    }

    /// Translate an operation's own flag bits to the mission's status word.
    fn translate(&self, key: &str, flags: StatusFlags) -> StatusFlags {
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

    /// The binding of the operation written as `key` in the current action. Bindings are
    /// per operation (canonical name), so an operation named by name in one action and by id
    /// in another is one binding with one epoch.
    fn binding(&self, key: &str) -> Option<&Binding> {
        let cur = self.current.as_ref()?;
        let op = self.mission.actions[cur.index].op(key)?;
        self.bindings.get(&op.name)
    }

    async fn bind(&mut self) -> Result<(), String> {
        let names: Vec<String> = self
            .mission
            .operation_names()
            .into_iter()
            .map(str::to_string)
            .collect();
        for key in names {
            let Some(inst) = registry::lookup(ModuleKind::Operation, &key)
                .into_iter()
                .next()
            else {
                return Err(format!("operation `{key}` has no live instance"));
            };
            let client = EoClient::from_cell(inst.actor.clone());
            let info = describe(client.clone())
                .await
                .map_err(|e| format!("operation `{key}`: {e}"))?;
            let epoch = match client
                .property(PropertyRequest::Group(Group::General))
                .await
                .map_err(|e| format!("operation `{key}`: {e}"))?
            {
                PropertyReply::General(General { epoch, .. }) => epoch + 1,
                other => return Err(format!("operation `{key}` answered {other:?}")),
            };
            self.bindings.insert(
                key,
                Binding {
                    client,
                    name: info.name,
                    id: info.id,
                    version: info.version,
                    node: inst.node,
                    address: inst.actor.get_id().to_string(),
                    epoch,
                    defaults: info.schema.defaults(),
                    flag_names: info.flags.into_iter().map(|f| f.name).collect(),
                    params: ParamMap::new(),
                },
            );
        }
        self.emit(DispatchEvent::Bound {
            operations: self
                .bindings
                .values()
                .map(|b| (b.name.clone(), b.version.clone(), b.node.clone()))
                .collect(),
        });
        Ok(())
    }

    fn next_action(&mut self, myself: &ActorRef<DispatcherMsg>) {
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

    fn start_action(&mut self, myself: &ActorRef<DispatcherMsg>, index: usize) {
        self.generation += 1;
        let generation = self.generation;
        let action = self.mission.actions[index].clone();
        let mut current = Current {
            generation,
            index,
            start_ms: self.elapsed_ms(),
            running: BTreeSet::new(),
            enders_done: BTreeSet::new(),
            ending: false,
            ops: BTreeMap::new(),
        };
        tracing::info!(action = %action.name, "action started");
        self.emit(DispatchEvent::ActionStarted {
            action: action.name.clone(),
            operations: action.ops.iter().map(|o| o.key.clone()).collect(),
        });
        let mut unreachable = None;
        for op in &action.ops {
            let Some(b) = self.bindings.get_mut(&op.name) else {
                unreachable = Some(format!("operation `{}` is not bound", op.key));
                break;
            };
            let mut params = b.defaults.clone();
            params.extend(op.params.clone());
            b.params = params.clone();
            current.ops.insert(
                op.key.clone(),
                OpRecord {
                    name: b.name.clone(),
                    id: b.id,
                    version: b.version.clone(),
                    node: b.node.clone(),
                    address: b.address.clone(),
                    ended: "running".to_string(),
                    flags: Vec::new(),
                },
            );
            match b.client.activate(params, b.epoch) {
                Ok(rx) => {
                    current.running.insert(op.key.clone());
                    let me = myself.clone();
                    let key = op.key.clone();
                    ractor::concurrency::spawn(async move {
                        let report = rx.await.ok();
                        let _ = me.cast(DispatcherMsg::OpEnded {
                            generation,
                            key,
                            report,
                        });
                    });
                }
                Err(e) => {
                    unreachable = Some(format!("operation `{}`: {e}", op.key));
                    break;
                }
            }
        }
        self.current = Some(current);
        if let Some(reason) = unreachable {
            self.finish(myself, Outcome::Failed, reason);
            return;
        }
        cast_after(
            &self.clock,
            action.deadline,
            myself,
            DispatcherMsg::ActionDeadline { generation },
        );
    }

    fn on_op_ended(
        &mut self,
        myself: &ActorRef<DispatcherMsg>,
        generation: u64,
        key: String,
        report: Option<EoReport>,
    ) {
        let Some(cur) = self.current.as_mut() else {
            return;
        };
        if cur.generation != generation || !cur.running.remove(&key) {
            return;
        }
        let action = &self.mission.actions[cur.index];
        let action_name = action.name.clone();
        let ending = cur.ending;
        let (ended, flags, failure) = match report {
            Some(EoReport::Finished { flags, .. }) => ("finished", flags, None),
            Some(EoReport::Suspended { flags, .. }) if ending => ("suspended", flags, None),
            Some(EoReport::Suspended { flags, .. }) => (
                "suspended",
                flags,
                Some(format!(
                    "operation `{key}` was suspended by another party during action `{action_name}`"
                )),
            ),
            Some(EoReport::Failed { reason, flags, .. }) => (
                "failed",
                flags,
                Some(format!(
                    "operation `{key}` failed in action `{action_name}`: {reason}"
                )),
            ),
            Some(EoReport::Rejected { rejections, .. }) => (
                "failed",
                StatusFlags::EMPTY,
                Some(format!(
                    "operation `{key}` refused its parameters in action `{action_name}`: {}",
                    rejections
                        .iter()
                        .map(|r| r.to_string())
                        .collect::<Vec<_>>()
                        .join("; ")
                )),
            ),
            Some(EoReport::Stale { current, .. }) => (
                "failed",
                StatusFlags::EMPTY,
                Some(format!(
                    "operation `{key}` is now bound by another dispatcher (epoch {current})"
                )),
            ),
            None if ending => ("lost", StatusFlags::EMPTY, None),
            None => (
                "lost",
                StatusFlags::EMPTY,
                Some(format!(
                    "operation `{key}` died during action `{action_name}`"
                )),
            ),
        };
        let global = self.translate(&key, flags);
        self.status |= global;
        let names = self.mission.flags_to_names(global);
        let cur = self.current.as_mut().expect("checked above");
        if let Some(rec) = cur.ops.get_mut(&key) {
            rec.ended = ended.to_string();
            rec.flags = names;
        }
        tracing::debug!(op = %key, ended, flags = %global, "operation report");
        if let Some(reason) = failure {
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
        if ended == "finished" && action.ends_on(&key) {
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
    fn end_action(&mut self, myself: &ActorRef<DispatcherMsg>) {
        let Some(cur) = self.current.as_mut() else {
            return;
        };
        cur.ending = true;
        if cur.running.is_empty() {
            self.complete_action(myself);
            return;
        }
        let generation = cur.generation;
        let running: Vec<String> = cur.running.iter().cloned().collect();
        for key in &running {
            if let Some(b) = self.binding(key) {
                let _ = b.client.suspend(b.epoch);
            }
        }
        cast_after(
            &self.clock,
            SUSPEND_GRACE,
            myself,
            DispatcherMsg::SuspendGrace { generation },
        );
    }

    fn record_current(&mut self) {
        let Some(cur) = self.current.take() else {
            return;
        };
        let end_ms = self.elapsed_ms();
        let action = &self.mission.actions[cur.index];
        self.done[cur.index] = true;
        self.actions.push(ActionRecord {
            name: action.name.clone(),
            start_ms: cur.start_ms,
            end_ms,
            flags: self.mission.flags_to_names(self.status),
            status: self.status.0,
            operations: action
                .ops
                .iter()
                .filter_map(|o| cur.ops.get(&o.key).cloned())
                .collect(),
        });
    }

    fn complete_action(&mut self, myself: &ActorRef<DispatcherMsg>) {
        let name = self
            .current
            .as_ref()
            .map(|c| self.mission.actions[c.index].name.clone())
            .unwrap_or_default();
        self.record_current();
        tracing::info!(action = %name, status = %self.status, "action ended");
        self.emit(DispatchEvent::ActionEnded {
            action: name,
            flags: self.mission.flags_to_names(self.status),
            status: self.status,
        });
        self.next_action(myself);
    }

    fn finish(&mut self, myself: &ActorRef<DispatcherMsg>, outcome: Outcome, reason: String) {
        if let Some(cur) = &self.current {
            for key in &cur.running {
                if let Some(b) = self.binding(key) {
                    let _ = b.client.suspend(b.epoch);
                }
            }
        }
        self.record_current();
        match outcome {
            Outcome::Succeeded => tracing::info!(mission = %self.mission.name, "mission succeeded"),
            Outcome::Failed => {
                tracing::warn!(mission = %self.mission.name, %reason, "mission failed: full stop")
            }
        }
        let report = RunReport {
            mission: self.mission.name.clone(),
            outcome,
            reason: reason.clone(),
            status: self.status.0,
            flags: self.mission.flags_to_names(self.status),
            actions: std::mem::take(&mut self.actions),
            rebinds: Vec::new(),
            duration_ms: self.elapsed_ms(),
            final_pose: None,
            collisions: None,
            seed: None,
            inside_goal: None,
            judgement: None,
        };
        self.emit(DispatchEvent::Ended { outcome, reason });
        if let Some(reply) = self.reply.take() {
            let _ = reply.send(report);
        }
        myself.stop(Some("mission ended".to_string()));
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
        Ok(DispatcherState {
            status: args.mission.initial,
            started: args.clock.now(),
            mission: args.mission,
            clock: args.clock,
            events: args.events,
            bindings: BTreeMap::new(),
            done: vec![false; n],
            generation: 0,
            current: None,
            actions: Vec::new(),
            reply: None,
        })
    }

    async fn handle(
        &self,
        myself: ActorRef<DispatcherMsg>,
        msg: DispatcherMsg,
        state: &mut DispatcherState,
    ) -> Result<(), ActorProcessingErr> {
        match msg {
            DispatcherMsg::Run { reply } => {
                if state.reply.is_some() || state.generation > 0 {
                    tracing::warn!("a dispatcher runs its mission once; request ignored");
                    return Ok(());
                }
                state.reply = Some(reply);
                state.started = state.clock.now();
                if let Err(reason) = state.bind().await {
                    state.finish(&myself, Outcome::Failed, reason);
                    return Ok(());
                }
                if let Some(deadline) = state.mission.deadline {
                    cast_after(
                        &state.clock,
                        deadline,
                        &myself,
                        DispatcherMsg::MissionDeadline {},
                    );
                }
                state.next_action(&myself);
            }
            DispatcherMsg::OpEnded {
                generation,
                key,
                report,
            } => state.on_op_ended(&myself, generation, key, report),
            DispatcherMsg::ActionDeadline { generation } => {
                let Some(cur) = &state.current else {
                    return Ok(());
                };
                if cur.generation != generation || cur.ending {
                    return Ok(());
                }
                let action = &state.mission.actions[cur.index];
                let waiting: Vec<String> = action
                    .ends_on
                    .iter()
                    .filter(|k| !cur.enders_done.contains(*k))
                    .map(|k| format!("`{k}`"))
                    .collect();
                let reason = format!(
                    "action `{}` missed its deadline of {:.1}s waiting for {}",
                    action.name,
                    action.deadline.as_secs_f64(),
                    waiting.join(", ")
                );
                state.finish(&myself, Outcome::Failed, reason);
            }
            DispatcherMsg::SuspendGrace { generation } => {
                let Some(cur) = &mut state.current else {
                    return Ok(());
                };
                if cur.generation != generation || !cur.ending {
                    return Ok(());
                }
                for key in std::mem::take(&mut cur.running) {
                    tracing::warn!(op = %key, "no report after suspension");
                    if let Some(rec) = cur.ops.get_mut(&key) {
                        rec.ended = "unresponsive".to_string();
                    }
                }
                state.complete_action(&myself);
            }
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
    /// The dispatcher stopped without a report.
    #[error("dispatcher stopped without a report")]
    NoReport,
}

/// Run `mission` with a new dispatcher and wait for its report.
pub async fn run_mission(
    mission: Mission,
    clock: SharedClock,
    events: Option<mpsc::UnboundedSender<DispatchEvent>>,
) -> Result<RunReport, DispatchError> {
    let (actor, handle) = Actor::spawn(
        None,
        ActionDispatcher,
        DispatcherArgs {
            mission,
            clock,
            events,
        },
    )
    .await?;
    let (tx, rx) = ractor::concurrency::oneshot();
    actor
        .cast(DispatcherMsg::Run { reply: tx.into() })
        .map_err(|_| DispatchError::NoReport)?;
    let report = rx.await.map_err(|_| DispatchError::NoReport);
    let _ = handle.await;
    report
}
