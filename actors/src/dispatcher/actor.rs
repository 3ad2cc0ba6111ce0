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

use super::binding::{examine, Binding};
use super::mission::{EndMode, Mission};
use super::report::{ActionRecord, OpRecord, Outcome, RebindRecord, RunReport};
use crate::clock::{SharedClock, Timer};
use crate::eo::{EoError, EoReport, ParamOutcome};
use crate::flags::StatusFlags;
use crate::property::PropertyRequest;
use crate::registry::{self, Instance, ModuleKind, RegistryEvent};
use ractor::{Actor, ActorProcessingErr, ActorRef, RpcReplyPort, SpawnErr};
use std::collections::{BTreeMap, BTreeSet};
use std::time::Duration;
use tokio::sync::mpsc;

/// Registry id of the action dispatcher.
pub const DISPATCHER_ID: u32 = 1500;

/// How long suspended operations get to report before the dispatcher moves on.
const SUSPEND_GRACE: Duration = Duration::from_secs(5);

/// How often bound operations are asked whether they still answer.
const PROBE_PERIOD: Duration = Duration::from_millis(500);

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
    /// A bound operation's instance was lost; the dispatcher looks for a stand-in.
    Lost {
        /// Operation name.
        operation: String,
        /// What happened to it.
        cause: String,
    },
    /// A lost operation is bound again.
    Rebound(RebindRecord),
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
            /// Incarnation of the binding that was activated.
            incarnation: u64,
            /// Its report.
            report: Option<EoReport>,
        },
        /// An operation instance joined or left the registry.
        Registry {
            /// What happened.
            event: RegistryEvent,
        },
        /// Time to ask the bound operations whether they still answer.
        Probe {},
        /// A liveness probe of `name`'s incarnation `incarnation` ended.
        ProbeDone {
            /// Operation name.
            name: String,
            /// Incarnation probed.
            incarnation: u64,
            /// `None`: it answered.
            error: Option<EoError>,
        },
        /// The rebind deadline of `name`, lost as incarnation `incarnation`, passed.
        RebindDeadline {
            /// Operation name.
            name: String,
            /// Incarnation number after the loss.
            incarnation: u64,
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
        /// Stop the mission now (full stop) for `reason` — e.g. the node's operation
        /// supervisor gave up.
        Abort {
            /// Why.
            reason: String,
        },
    }
}

/// Start-up arguments of the dispatcher.
#[derive(Clone)]
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

/// How an activation is sent: for which action generation and binding incarnation, with
/// which epoch, and whether it takes over a lost instance's activation.
#[derive(Clone, Copy)]
struct Start {
    generation: u64,
    incarnation: u64,
    epoch: u64,
    resume: bool,
}

/// Timers of the whole run.
#[derive(Default)]
struct RunTimers {
    mission: Option<Timer>,
    probe: Option<Timer>,
}

struct Current {
    generation: u64,
    index: usize,
    start_ms: u64,
    running: BTreeSet<String>,
    enders_done: BTreeSet<String>,
    ending: bool,
    ops: BTreeMap<String, OpRecord>,
    /// The action's deadline, then its suspension grace; cancelled with the action.
    timer: Option<Timer>,
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
    rebinds: Vec<RebindRecord>,
    reply: Option<RpcReplyPort<RunReport>>,
    /// Dropping it ends the registry watch.
    _watch_guard: Option<tokio::sync::oneshot::Sender<()>>,
    /// The run's own timers, cancelled with the dispatcher.
    timers: RunTimers,
    ended: bool,
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
            let cand = examine(&inst, crate::eo::EoClient::DEFAULT_TIMEOUT)
                .await
                .map_err(|e| format!("operation `{key}`: {e}"))?;
            self.bindings.insert(key, Binding::new(cand));
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

    /// Start forwarding the registry's operation joins and leaves to the dispatcher, until
    /// the dispatcher's state is dropped.
    async fn watch_registry(&mut self, myself: &ActorRef<DispatcherMsg>) -> Result<(), String> {
        let mut watch = registry::watch(Some(ModuleKind::Operation))
            .await
            .map_err(|e| format!("cannot watch the registry: {e}"))?;
        let (guard, mut gone) = tokio::sync::oneshot::channel::<()>();
        self._watch_guard = Some(guard);
        let me = myself.clone();
        ractor::concurrency::spawn(async move {
            loop {
                tokio::select! {
                    _ = &mut gone => break,
                    event = watch.next() => {
                        let Some(event) = event else { break };
                        if me.cast(DispatcherMsg::Registry { event }).is_err() {
                            break;
                        }
                    }
                }
            }
        });
        Ok(())
    }

    /// The current action's key for operation `name`, if it is among the running ones.
    fn running_key(&self, name: &str) -> Option<String> {
        let cur = self.current.as_ref()?;
        let action = &self.mission.actions[cur.index];
        action
            .ops
            .iter()
            .find(|o| o.name == name && cur.running.contains(&o.key))
            .map(|o| o.key.clone())
    }

    /// The instance of `name` is gone (or hung and killed): let it go and look for a
    /// stand-in. Nothing happens if the binding is already lost.
    async fn lose(&mut self, myself: &ActorRef<DispatcherMsg>, name: &str, cause: String) {
        let now = self.clock.now();
        let Some(b) = self.bindings.get_mut(name) else {
            return;
        };
        if b.lost.is_some() || self.ended {
            return;
        }
        b.lose(cause.clone(), now);
        let incarnation = b.incarnation;
        tracing::warn!(op = %name, %cause, "operation lost; rebinding");
        self.emit(DispatchEvent::Lost {
            operation: name.to_string(),
            cause,
        });
        // A lost operation of an action that is ending has nothing left to do in it.
        if let Some(key) = self.running_key(name) {
            let ending = self.current.as_ref().is_some_and(|c| c.ending);
            if ending && self.give_up_on(myself, &[key]) {
                return;
            }
        }
        let timer = Timer::cast_after(
            &self.clock,
            self.mission.rebind_deadline,
            myself,
            DispatcherMsg::RebindDeadline {
                name: name.to_string(),
                incarnation,
            },
        );
        if let Some(b) = self.bindings.get_mut(name) {
            b.deadline_timer = Some(timer);
        }
        let found = registry::lookup(ModuleKind::Operation, name);
        for inst in found {
            if self.try_adopt(myself, name, &inst).await {
                break;
            }
        }
    }

    /// Adopt `inst` for the lost binding `name` if it passes the binding's selection; then
    /// restore its parameters and, if its action runs, re-activate it. True if adopted.
    async fn try_adopt(
        &mut self,
        myself: &ActorRef<DispatcherMsg>,
        name: &str,
        inst: &Instance,
    ) -> bool {
        let Some(b) = self.bindings.get(name) else {
            return false;
        };
        let Some(lost) = &b.lost else {
            return false;
        };
        if inst.actor.get_id() == lost.dead {
            return false;
        }
        let cand = match examine(inst, b.deadline).await {
            Ok(c) => c,
            Err(e) => {
                tracing::debug!(op = %name, actor = %inst.actor.get_id(), error = %e, "stand-in does not answer");
                return false;
            }
        };
        let now = self.clock.now();
        let b = self.bindings.get_mut(name).expect("checked above");
        if b.lost.is_none() {
            return false; // adopted another while this one was examined
        }
        if let Err(why) = b.accepts(&cand) {
            tracing::info!(op = %name, actor = %inst.actor.get_id(), %why, "instance cannot stand in");
            return false;
        }
        let Some((lost, downtime)) = b.adopt(cand, now) else {
            return false;
        };
        let record = RebindRecord {
            operation: name.to_string(),
            cause: lost.cause,
            from: lost.from,
            to: b.address(),
            downtime_ms: downtime.as_millis() as u64,
        };
        tracing::info!(op = %name, from = %record.from, to = %record.to, downtime_ms = record.downtime_ms, "operation rebound");
        let (client, epoch, params, incarnation) =
            (b.client.clone(), b.epoch, b.params.clone(), b.incarnation);
        self.rebinds.push(record.clone());
        self.emit(DispatchEvent::Rebound(record));
        match self.running_key(name) {
            Some(key) => {
                let cur = self.current.as_mut().expect("running_key found it");
                if let Some(rec) = cur.ops.get_mut(&key) {
                    rec.address = client.actor().get_id().to_string();
                }
                let generation = cur.generation;
                let start = Start {
                    generation,
                    incarnation,
                    epoch,
                    resume: true,
                };
                if let Err(e) = self.activate(myself, &key, start, params) {
                    self.report_gone(myself, name, incarnation, e);
                }
            }
            None if !params.is_empty() => match client.parameterize(params, epoch).await {
                Ok(ParamOutcome::Applied) => {}
                Ok(other) => {
                    tracing::warn!(op = %name, ?other, "last parameters not restored")
                }
                Err(e) => self.report_gone(myself, name, incarnation, e),
            },
            None => {}
        }
        true
    }

    /// The adopted instance failed at once: handle it like a failed probe (by message, so
    /// losing and adopting never recurse).
    fn report_gone(
        &self,
        myself: &ActorRef<DispatcherMsg>,
        name: &str,
        incarnation: u64,
        error: EoError,
    ) {
        let _ = myself.cast(DispatcherMsg::ProbeDone {
            name: name.to_string(),
            incarnation,
            error: Some(error),
        });
    }

    /// Send `Activate` (or `Resume`) to the binding's instance; its report comes back as
    /// `OpEnded`.
    fn activate(
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
        Ok(())
    }

    /// Ask every bound instance whether it still answers, within its declared deadline.
    fn probe(&mut self, myself: &ActorRef<DispatcherMsg>) {
        for b in self.bindings.values_mut() {
            if b.lost.is_some() || b.probing {
                continue;
            }
            b.probing = true;
            let client = b.client.clone().with_timeout(b.deadline);
            let (name, incarnation) = (b.name.clone(), b.incarnation);
            let me = myself.clone();
            ractor::concurrency::spawn(async move {
                let error = client
                    .property(PropertyRequest::Get("epoch".to_string()))
                    .await
                    .err();
                let _ = me.cast(DispatcherMsg::ProbeDone {
                    name,
                    incarnation,
                    error,
                });
            });
        }
        self.timers.probe = Some(Timer::cast_after(
            &self.clock,
            PROBE_PERIOD,
            myself,
            DispatcherMsg::Probe {},
        ));
    }

    async fn on_probe_done(
        &mut self,
        myself: &ActorRef<DispatcherMsg>,
        name: String,
        incarnation: u64,
        error: Option<EoError>,
    ) {
        let Some(b) = self.bindings.get_mut(&name) else {
            return;
        };
        if b.incarnation != incarnation || b.lost.is_some() {
            return;
        }
        b.probing = false;
        match error {
            None => {}
            Some(EoError::Timeout(_, deadline)) => {
                b.client.actor().kill();
                let cause = format!(
                    "hung: no answer within its deadline of {} ms; killed",
                    deadline.as_millis()
                );
                self.lose(myself, &name, cause).await;
            }
            Some(EoError::Gone(_)) => {
                self.lose(myself, &name, "died: its actor is gone".to_string())
                    .await;
            }
        }
    }

    async fn on_registry(&mut self, myself: &ActorRef<DispatcherMsg>, event: RegistryEvent) {
        match event {
            RegistryEvent::Left(inst) => {
                let id = inst.actor.get_id();
                let name = self
                    .bindings
                    .values()
                    .find(|b| b.lost.is_none() && b.actor_id() == id)
                    .map(|b| b.name.clone());
                if let Some(name) = name {
                    self.lose(myself, &name, "died: it left the registry".to_string())
                        .await;
                }
            }
            RegistryEvent::Joined(inst) => {
                let lost = self
                    .bindings
                    .get(&inst.name)
                    .is_some_and(|b| b.lost.is_some());
                if lost {
                    let name = inst.name.clone();
                    self.try_adopt(myself, &name, &inst).await;
                }
            }
        }
    }

    fn on_rebind_deadline(
        &mut self,
        myself: &ActorRef<DispatcherMsg>,
        name: String,
        incarnation: u64,
    ) {
        let Some(b) = self.bindings.get(&name) else {
            return;
        };
        let Some(lost) = &b.lost else {
            return;
        };
        if b.incarnation != incarnation {
            return;
        }
        let reason = format!(
            "operation `{name}` was lost ({}) and no compatible instance appeared within {:.1}s",
            lost.cause,
            self.mission.rebind_deadline.as_secs_f64()
        );
        self.finish(myself, Outcome::Failed, reason);
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
            timer: None,
        };
        tracing::info!(action = %action.name, "action started");
        self.emit(DispatchEvent::ActionStarted {
            action: action.name.clone(),
            operations: action.ops.iter().map(|o| o.key.clone()).collect(),
        });
        let mut unreachable = None;
        let mut activations = Vec::new();
        for op in &action.ops {
            let Some(b) = self.bindings.get_mut(&op.name) else {
                unreachable = Some(format!("operation `{}` is not bound", op.key));
                break;
            };
            let mut params = b.defaults.clone();
            params.extend(op.params.clone());
            b.params = params.clone();
            let (epoch, incarnation, lost) = (b.epoch, b.incarnation, b.lost.is_some());
            current.ops.insert(
                op.key.clone(),
                OpRecord {
                    name: b.name.clone(),
                    id: b.id,
                    version: b.version.clone(),
                    node: b.node.clone(),
                    address: b.address(),
                    ended: "running".to_string(),
                    flags: Vec::new(),
                },
            );
            // A lost operation is activated when a stand-in is adopted.
            current.running.insert(op.key.clone());
            activations.push((
                op.key.clone(),
                op.name.clone(),
                incarnation,
                params,
                epoch,
                lost,
            ));
        }
        self.current = Some(current);
        for (key, name, incarnation, params, epoch, lost) in activations {
            if lost || unreachable.is_some() {
                continue;
            }
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
        if let Some(reason) = unreachable {
            self.finish(myself, Outcome::Failed, reason);
            return;
        }
        let timer = Timer::cast_after(
            &self.clock,
            action.deadline,
            myself,
            DispatcherMsg::ActionDeadline { generation },
        );
        if let Some(cur) = self.current.as_mut() {
            cur.timer = Some(timer);
        }
    }

    async fn on_op_ended(
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
        if report.is_none() && !cur.ending {
            // The instance died mid-action: rebind and carry on.
            let name = b.name.clone();
            let action = self.mission.actions[cur.index].name.clone();
            self.lose(myself, &name, format!("died during action `{action}`"))
                .await;
            return;
        }
        let cur = self.current.as_mut().expect("checked above");
        cur.running.remove(&key);
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
            None => ("lost", StatusFlags::EMPTY, None),
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
    fn awaited_enders(&self, except: &str) -> Vec<String> {
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
    fn give_up_on(&mut self, myself: &ActorRef<DispatcherMsg>, keys: &[String]) -> bool {
        let Some(cur) = self.current.as_mut() else {
            return false;
        };
        for key in keys {
            cur.running.remove(key);
            if let Some(rec) = cur.ops.get_mut(key) {
                rec.ended = "lost".to_string();
            }
        }
        if cur.running.is_empty() {
            self.complete_action(myself);
            return true;
        }
        false
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
        if self.ended {
            return;
        }
        self.ended = true;
        if let Some(cur) = &self.current {
            for key in &cur.running {
                if let Some(b) = self.binding(key).filter(|b| b.lost.is_none()) {
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
            rebinds: std::mem::take(&mut self.rebinds),
            duration_ms: self.elapsed_ms(),
            final_pose: None,
            collisions: None,
            seed: None,
            inside_goal: None,
            judgement: None,
            faults: Vec::new(),
        };
        self.emit(DispatchEvent::Ended { outcome, reason });
        if let Some(reply) = self.reply.take() {
            let _ = reply.send(report);
        }
        myself.stop(None); // a normal exit: its work is done
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
            rebinds: Vec::new(),
            reply: None,
            _watch_guard: None,
            timers: RunTimers::default(),
            ended: false,
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
                if let Err(reason) = state.watch_registry(&myself).await {
                    state.finish(&myself, Outcome::Failed, reason);
                    return Ok(());
                }
                if let Err(reason) = state.bind().await {
                    state.finish(&myself, Outcome::Failed, reason);
                    return Ok(());
                }
                state.probe(&myself);
                if let Some(deadline) = state.mission.deadline {
                    state.timers.mission = Some(Timer::cast_after(
                        &state.clock,
                        deadline,
                        &myself,
                        DispatcherMsg::MissionDeadline {},
                    ));
                }
                state.next_action(&myself);
            }
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
            DispatcherMsg::RebindDeadline { name, incarnation } => {
                state.on_rebind_deadline(&myself, name, incarnation)
            }
            DispatcherMsg::ActionDeadline { generation } => {
                let Some(cur) = &state.current else {
                    return Ok(());
                };
                if cur.generation != generation || cur.ending {
                    return Ok(());
                }
                let action = &state.mission.actions[cur.index];
                let waiting = state.awaited_enders("");
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
            DispatcherMsg::Abort { reason } => state.finish(&myself, Outcome::Failed, reason),
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

/// Ask `dispatcher` to run its mission and wait for the report (a dispatcher runs once).
pub async fn request_run(dispatcher: &ActorRef<DispatcherMsg>) -> Result<RunReport, DispatchError> {
    let (tx, rx) = ractor::concurrency::oneshot();
    dispatcher
        .cast(DispatcherMsg::Run { reply: tx.into() })
        .map_err(|_| DispatchError::NoReport)?;
    rx.await.map_err(|_| DispatchError::NoReport)
}

/// Run `mission` with a new, unsupervised dispatcher and wait for its report.
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
    let report = request_run(&actor).await;
    // the dispatcher stops by itself once it has reported
    let _ = handle.await;
    report
}
