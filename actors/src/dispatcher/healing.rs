//! Healing bindings: noticing that a bound instance is lost, finding a stand-in, restoring it.
//!
//! The dispatcher notices a lost instance three ways: the activation's reply port closes (the
//! instance died mid-action, see `running.rs`), the instance leaves the registry (it died at
//! any time), or it does not answer a liveness probe within its declared deadline (it hangs:
//! the dispatcher kills it). It then adopts a live instance that passes the binding's
//! selection — the restarted one, or another — gives it the last parameters, re-activates it
//! (as `Resume`) if its action is running, and records the rebind. Stand-ins are looked for
//! when the loss is noticed, whenever an instance of the operation joins the registry, and
//! when a node is up again (what it hosts joined the registry while it was still declared
//! down, and was ruled out then: a node frozen past the deadline that restarts its
//! operations as it wakes). If none appears within the mission's `rebind_deadline`, the
//! mission comes to a full stop naming the operation.
//!
//! # Invariants
//! - Losing and adopting never recurse: an adopted instance that fails at once is reported
//!   back to the actor as a failed probe.
//! - A binding is lost at most once per incarnation; probe results and deadlines of an older
//!   incarnation are ignored.

use super::actor::{DispatcherState, Start};
use super::binding::Binding;
use super::candidates::{examine, examine_all, select, Prospect};
use super::messages::DispatcherMsg;
use crate::eo::{EoError, ParamOutcome};
use crate::provision::GRACE as PROVISION_GRACE;
use marie_vocabulary::clock::Timer;
use marie_vocabulary::events::{BoundOp, BusError, Event, EventKind};
use marie_vocabulary::fence::{self, Fence};
use marie_vocabulary::property::PropertyRequest;
use marie_vocabulary::registry::{self, Instance, ModuleKind, RegistryEvent};
use marie_vocabulary::run::{Choice, LossCause, Outcome, RebindRecord, Verdict};
use ractor::ActorRef;
use std::time::Duration;

/// How often bound operations are asked whether they still answer.
const PROBE_PERIOD: Duration = Duration::from_millis(500);

/// Why a run could not start: the run's reason (`run_ended`) says it in these words.
#[derive(Debug, thiserror::Error)]
pub(crate) enum StartError {
    /// The registry's joins and leaves cannot be watched, so lost instances would go
    /// unnoticed.
    #[error("cannot watch the registry: {0}")]
    Watch(#[source] ractor::SpawnErr),
    /// No live instance of an operation fits the mission: the choice says why for each.
    #[error("{}", .choice.why_none())]
    NoInstance {
        /// The choice that found nothing, every candidate with its reason.
        choice: Choice,
    },
}

impl DispatcherState {
    /// The lowest epoch this run binds under: its start in clock ms × 1000. A later run —
    /// of this dispatcher or of another on a synchronized clock — binds above every epoch an
    /// earlier one used (up to a thousand rebinds per ms of run), so the receivers' fences
    /// ([`marie_vocabulary::fence`]) admit a new run's commands and keep refusing a replaced
    /// incarnation's.
    fn epoch_base(&self) -> u64 {
        (self.started.as_millis() as u64).saturating_mul(1000)
    }

    /// Bind every operation of the mission, in order of first use, and tell each choice
    /// (`selected`) and the bindings (`bound`) on the bus. An operation the mission's check
    /// chose an instance for is bound to it as it is now, unless an instance changed since
    /// ([`super::checked`]); the others — and those — are selected among every live
    /// instance, as the check would have.
    pub(super) async fn bind(&mut self) -> Result<(), StartError> {
        let names: Vec<String> = self
            .mission
            .operation_names()
            .into_iter()
            .map(str::to_string)
            .collect();
        // used once: a mission's run binds what its check chose, never a later run's
        let checked = std::mem::take(&mut self.mission.checked);
        for key in names {
            let need = self.mission.need(&key);
            let held = match checked.get(&key) {
                None => None,
                Some(choice) => match choice.confirm(&need).await {
                    Ok(cand) => Some((cand, choice.choice().clone())),
                    Err(changed) => {
                        tracing::info!(op = %key, %changed, "the check's choice no longer holds; selecting again");
                        None
                    }
                },
            };
            let (cand, choice) = match held {
                Some(held) => held,
                None => {
                    let (found, choice) = select(&need, crate::eo::EoClient::DEFAULT_TIMEOUT).await;
                    let Some(index) = choice.chosen_index() else {
                        self.emit(EventKind::Selected {
                            choice: choice.clone(),
                        });
                        return Err(StartError::NoInstance { choice });
                    };
                    (
                        found
                            .found
                            .into_iter()
                            .nth(index)
                            .expect("chosen among found"),
                        choice,
                    )
                }
            };
            self.emit(EventKind::Selected { choice });
            self.bindings
                .insert(key, Binding::new(cand, self.epoch_base(), need));
        }
        Ok(())
    }

    /// Announce the epochs of the bindings of operation `only` (of every binding with
    /// `None`) to the receivers' fence keepers ([`marie_vocabulary::fence::announce`]): after the
    /// epochs are recorded, before a command carries them and before they are told on the
    /// bus — so from the `bound` or `rebound` event on, the receivers in reach refuse the
    /// epochs they replace.
    pub(super) async fn announce(&self, only: Option<&str>) {
        let fences: Vec<Fence> = self
            .bindings
            .values()
            .filter(|b| only.is_none_or(|name| b.name == name))
            .map(|b| Fence::new(b.name.clone(), b.epoch))
            .collect();
        let announced = fence::announce(&fences).await;
        if announced.told < announced.keepers {
            tracing::warn!(
                "new epochs reached {} of {} fence keepers: the others learn them from the first commands",
                announced.told,
                announced.keepers
            );
        }
    }

    /// Tell every binding's instance and epoch (`bound`): at the run's start, and after a
    /// takeover — once the epochs are recorded and announced.
    pub(super) fn emit_bound(&mut self) {
        let operations = self
            .bindings
            .values()
            .map(|b| BoundOp {
                name: b.name.clone(),
                version: b.version.clone(),
                node: b.node.clone(),
                epoch: b.epoch,
                address: b.actor_id().to_string(),
            })
            .collect();
        self.emit(EventKind::Bound { operations });
    }

    /// Start forwarding the registry's operation joins and leaves, the failure detector's
    /// verdicts on nodes and the nodes seen again (from the bus), to the dispatcher, until
    /// the dispatcher's state is dropped.
    pub(super) async fn watch_registry(
        &mut self,
        myself: &ActorRef<DispatcherMsg>,
    ) -> Result<(), StartError> {
        let mut watch = registry::watch(Some(ModuleKind::Operation))
            .await
            .map_err(StartError::Watch)?;
        let (guard, mut gone) = tokio::sync::oneshot::channel::<()>();
        self._watch_guard = Some(guard);
        let me = myself.clone();
        let mut bus = self.bus.subscribe();
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
                    event = bus.recv() => {
                        let msg = match event {
                            Ok(Event { kind: EventKind::NodeDown { peer, .. }, .. }) => {
                                DispatcherMsg::NodeDown { node: peer }
                            }
                            Ok(Event { kind: EventKind::NodeUp { peer, .. }, .. }) => {
                                DispatcherMsg::NodeUp { node: peer }
                            }
                            Ok(_) | Err(BusError::Lagged { .. }) => continue,
                            Err(BusError::Closed) => break,
                        };
                        if me.cast(msg).is_err() {
                            break;
                        }
                    }
                }
            }
        });
        Ok(())
    }

    /// The instance of `name` is gone (or hung and killed): let it go and look for a
    /// stand-in. Nothing happens if the binding is already lost.
    pub(super) async fn lose(
        &mut self,
        myself: &ActorRef<DispatcherMsg>,
        name: &str,
        cause: LossCause,
    ) {
        let now = self.clock.now();
        let Some(b) = self.bindings.get_mut(name) else {
            return;
        };
        if b.lost.is_some() || self.ended {
            return;
        }
        if b.trial.is_some() {
            // an upgrade's new instance lost in its first activation: back to the old one
            let reason = format!("it was lost in its first activation: {cause}");
            if self.roll_back(myself, name, reason).await {
                return;
            }
        }
        let Some(b) = self.bindings.get_mut(name) else {
            return;
        };
        // however it showed (a closed reply port, a registry leave), the failure
        // detector's verdict says why
        let cause = if registry::is_declared_down(&b.node) {
            LossCause::NodeDown {
                node: b.node.clone(),
            }
        } else {
            cause
        };
        b.lose(cause.clone(), now);
        let incarnation = b.incarnation;
        tracing::warn!(op = %name, %cause, "operation lost; rebinding");
        self.emit(EventKind::Lost {
            operation: name.to_string(),
            cause,
        });
        self.checkpoint();
        // A lost operation of an action that is ending has nothing left to do in it.
        if let Some((generation, key)) = self.running_key(name) {
            let ending = self.live.get(&generation).is_some_and(|c| c.ending());
            if ending && self.give_up_on(myself, generation, &[key]) {
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
        // a restarted or spare instance usually shows up within this grace; a lost node's
        // does not, and then the cluster is asked to start one (`provision`)
        let grace = PROVISION_GRACE.min(self.mission.rebind_deadline / 2);
        let provision = Timer::cast_after(
            &self.clock,
            grace,
            myself,
            DispatcherMsg::ProvisionDue {
                name: name.to_string(),
                incarnation,
            },
        );
        if let Some(b) = self.bindings.get_mut(name) {
            b.deadline_timer = Some(timer);
            b.provision_timer = Some(provision);
        }
        // every live instance, asked at once and chosen among as at the start — but not
        // the lost one, nor one on a node declared down: they would only be waited for
        let Some(b) = self.bindings.get(name) else {
            return;
        };
        let dead = b.lost.as_ref().map(|l| l.dead);
        let found: Vec<Instance> = registry::lookup(ModuleKind::Operation, name)
            .into_iter()
            .filter(|i| Some(i.actor.get_id()) != dead && !registry::is_declared_down(&i.node))
            .collect();
        let cands = examine_all(name, found, b.deadline).await;
        self.adopt_best(myself, name, cands).await;
    }

    /// An instance of the lost binding `name` joined the registry: adopt it if it passes
    /// the binding's selection. True if adopted.
    pub(super) async fn try_adopt(
        &mut self,
        myself: &ActorRef<DispatcherMsg>,
        name: &str,
        inst: &Instance,
    ) -> bool {
        let Some(b) = self.bindings.get(name) else {
            return false;
        };
        if b.lost.is_none() {
            return false;
        }
        // what rules it out without a round trip to it
        if let Some(why) = b.ruled_out_unasked(inst.actor.get_id(), &inst.node) {
            tracing::debug!(op = %name, actor = %inst.actor.get_id(), %why, "no stand-in");
            return false;
        }
        match examine(inst, b.deadline).await {
            Ok(cand) => self.adopt_best(myself, name, vec![cand]).await,
            Err(e) => {
                tracing::debug!(op = %name, actor = %inst.actor.get_id(), error = %e, "stand-in does not answer");
                false
            }
        }
    }

    /// Choose a stand-in for the lost binding `name` among `cands` (the binding's
    /// selection: the mission's needs, then the ranking), explain the choice on the bus,
    /// and adopt the chosen one: its parameters restored and, if its action runs,
    /// re-activated. True if one was adopted.
    async fn adopt_best(
        &mut self,
        myself: &ActorRef<DispatcherMsg>,
        name: &str,
        mut cands: Vec<Prospect>,
    ) -> bool {
        if self.ended {
            return false; // over, or fenced off by an earlier refusal
        }
        let here = registry::local_node_name();
        let Some(b) = self.bindings.get_mut(name) else {
            return false;
        };
        if b.lost.is_none() || cands.is_empty() {
            return false; // adopted another while these were examined, or nothing to choose
        }
        let (choice, chosen) = b.choose_stand_in(&cands, &here);
        let Some(index) = chosen else {
            if let Some(lost) = b.lost.as_mut() {
                for c in &choice.candidates {
                    if let Verdict::Rejected { reason } = &c.verdict {
                        tracing::info!(op = %name, actor = %c.address, %reason, "instance cannot stand in");
                        if !lost.refused.iter().any(|(a, _)| *a == c.address) {
                            lost.refused.push((c.address.clone(), reason.clone()));
                        }
                    }
                }
            }
            self.emit(EventKind::Selected { choice });
            return false;
        };
        let now = self.clock.now();
        let Some((lost, downtime)) = b.adopt(cands.swap_remove(index), now) else {
            return false;
        };
        let record = RebindRecord {
            operation: name.to_string(),
            cause: lost.cause,
            from: lost.from,
            to: b.address(),
            from_node: lost.from_node,
            to_node: b.node.clone(),
            downtime_ms: downtime.as_millis() as u64,
            epoch: b.epoch,
        };
        tracing::info!(op = %name, from = %record.from, to = %record.to, downtime_ms = record.downtime_ms, "operation rebound");
        let (client, epoch, params, incarnation) =
            (b.client.clone(), b.epoch, b.params.clone(), b.incarnation);
        // the raised epoch is recorded before any command carries it: a dispatcher that a
        // standby replaced is refused here, fenced off at once, and never outbids its
        // successor (the epoch raised above the instance's may be above the successor's)
        if self.checkpoint_now(myself).await.is_err() {
            return false;
        }
        self.announce(Some(name)).await;
        self.emit(EventKind::Selected { choice });
        // the report's record of the running action takes the stand-in's address from it
        self.emit(EventKind::Rebound(record));
        let running = self
            .running_key(name)
            .filter(|(g, _)| self.live.get(g).is_some_and(|c| c.launched));
        match running {
            Some((generation, key)) => {
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
    pub(super) fn report_gone(
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

    /// Ask every bound instance whether it still answers, within its declared deadline.
    pub(super) fn probe(&mut self, myself: &ActorRef<DispatcherMsg>) {
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

    pub(super) async fn on_probe_done(
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
            None => b.last_alive = Some(self.clock.now()),
            Some(EoError::Timeout(_, deadline)) => {
                b.client.actor().kill();
                let cause = LossCause::Hung {
                    deadline_ms: deadline.as_millis() as u64,
                };
                self.lose(myself, &name, cause).await;
            }
            Some(EoError::Gone(_)) => {
                self.lose(myself, &name, LossCause::Gone).await;
            }
        }
    }

    /// A node declared down: every instance bound there is lost at once (the registry
    /// would tell the same a moment later).
    pub(super) async fn on_node_down(&mut self, myself: &ActorRef<DispatcherMsg>, node: String) {
        let there: Vec<String> = self
            .bindings
            .values()
            .filter(|b| b.lost.is_none() && b.node == node)
            .map(|b| b.name.clone())
            .collect();
        for name in there {
            self.lose(myself, &name, LossCause::NodeDown { node: node.clone() })
                .await;
        }
    }

    /// `node` is up again (a session with it is ready; the failure detector's verdict on
    /// it, if any, is lifted). Its instances reached the registry before that — a
    /// session's modules are exchanged before it is ready —, so those that joined while
    /// it was still declared down were ruled out as stand-ins: each lost binding
    /// considers its instances there now.
    pub(super) async fn on_node_up(&mut self, myself: &ActorRef<DispatcherMsg>, node: String) {
        let lost: Vec<String> = self
            .bindings
            .values()
            .filter(|b| b.lost.is_some())
            .map(|b| b.name.clone())
            .collect();
        for name in lost {
            let there = registry::lookup(ModuleKind::Operation, &name)
                .into_iter()
                .filter(|i| i.node == node);
            for inst in there {
                if self.try_adopt(myself, &name, &inst).await {
                    break;
                }
            }
        }
    }

    pub(super) async fn on_registry(
        &mut self,
        myself: &ActorRef<DispatcherMsg>,
        event: RegistryEvent,
    ) {
        match event {
            RegistryEvent::Left(inst) => {
                let id = inst.actor.get_id();
                self.forget_newer(id);
                let name = self
                    .bindings
                    .values()
                    .find(|b| b.lost.is_none() && b.actor_id() == id)
                    .map(|b| b.name.clone());
                if let Some(name) = name {
                    self.lose(myself, &name, LossCause::LeftRegistry).await;
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
                } else {
                    // perhaps a newer version, to move to at the next action's start
                    self.note_newer(&inst).await;
                }
            }
        }
    }

    /// The provisioning grace of `name` passed without a stand-in: ask the nodes that can
    /// start instances for one matching the binding's selection (in a task: it may take a
    /// while, and the new instance is adopted through the registry like any stand-in).
    pub(super) fn on_provision_due(&mut self, name: String, incarnation: u64) {
        let Some(b) = self.bindings.get(&name) else {
            return;
        };
        if b.lost.is_none() || b.incarnation != incarnation || self.ended {
            return;
        }
        let req = b.versions();
        tracing::info!(op = %name, %req, "no stand-in: asking the cluster to start one");
        tokio::spawn(async move {
            match crate::provision::request(&name, &req).await {
                Ok(node) => tracing::info!(op = %name, %node, "a stand-in is starting"),
                Err(e) => tracing::warn!(op = %name, "no node can start a stand-in: {e}"),
            }
        });
    }

    /// The rebind deadline of `name` passed with no stand-in: the run fails. When a
    /// replicated datamanager has no majority meanwhile, the reason names it and the nodes
    /// it misses: an operation that could not store dies of it (`eo::absence`), and its
    /// restarted instance waits for the datamanager before it registers, so the lost
    /// operation is the symptom and the datamanager the cause an operator acts on.
    pub(super) async fn on_rebind_deadline(
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
        let mut reason = format!(
            "operation `{name}` was lost ({}) and no compatible instance appeared within {:.1}s",
            lost.cause,
            self.mission.rebind_deadline.as_secs_f64()
        );
        if !lost.refused.is_empty() {
            let refused: Vec<String> = lost
                .refused
                .iter()
                .map(|(address, why)| format!("{address}: {why}"))
                .collect();
            reason += &format!("; refused as stand-ins: {}", refused.join("; "));
        }
        for lost in marie_dm::leaderless(marie_dm::VIEW_TIMEOUT).await {
            reason += &format!("; {lost}");
        }
        let gave_up = EventKind::RebindGaveUp {
            operation: name,
            cause: lost.cause.clone(),
            waited_ms: self.clock.now().saturating_sub(lost.since).as_millis() as u64,
        };
        self.emit(gave_up);
        self.finish(myself, Outcome::Failed, reason);
    }
}
