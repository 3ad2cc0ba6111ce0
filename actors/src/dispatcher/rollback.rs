//! Rolling a binding back: the instance an upgrade moved it to failed its first activation,
//! and the binding goes back to the instance it moved from, which starts the action again.
//! When a failed first activation rolls back is [`super::upgrade`]'s pure decision
//! ([`upgrade::first_activation`], [`upgrade::after_failed_first_activation`]); this file
//! is its wiring.
//!
//! A first activation fails three ways, each noticed where that kind of failure always was:
//! an error reply (`Failed`, or `Rejected` parameters) in `running.rs`'s report handling;
//! the instance's actor gone (its reply port closed, its registry leave, its node down) and
//! no answer to a probe within its declared deadline (it hangs, and is killed) in
//! `healing.rs`'s `lose`, which asks for a rollback before it looks for a stand-in.
//!
//! # Invariants
//! - A rollback is an adoption of the old instance: the epoch is raised above both the
//!   binding's and the one the old instance accepted last, the incarnation grows (a late
//!   report of the failed instance is about one let go of), and the raised epoch is stored in
//!   the checkpoint and announced to the fence keepers before any command carries it.
//! - The old instance gets the action's parameters as its own schema takes them: its
//!   declared defaults, then what the mission gives, through its own migrations (a
//!   parameter only the newer version knows is not sent to it).
//! - The instance rolled back from is never taken to again in the run (the binding's
//!   `spurned`: [`upgrade::judge`] refuses it, and it stands in for nothing).

use super::actor::{DispatcherState, Start};
use super::candidates::{examine, Prospect};
use super::messages::DispatcherMsg;
use super::upgrade::{self, AfterFailure, FirstActivation};
use crate::eo::EoReport;
use marie_vocabulary::events::EventKind;
use marie_vocabulary::registry::{self, ModuleKind};
use marie_vocabulary::run::RollbackRecord;
use ractor::ActorRef;

impl DispatcherState {
    /// Operation `name` reported `report` for action `generation`: if that ends a move's
    /// trial, the move holds (passed) or the reason it failed is given back (an error
    /// reply). A lost instance (`None`) leaves the trial standing: `lose` decides.
    pub(super) fn first_activation_failed(
        &mut self,
        name: &str,
        generation: u64,
        report: Option<&EoReport>,
    ) -> Option<String> {
        let b = self.bindings.get_mut(name)?;
        if b.trial.as_ref()?.generation != generation {
            return None;
        }
        match upgrade::first_activation(report) {
            FirstActivation::Passed => {
                b.trial = None;
                None
            }
            FirstActivation::Failed(reason) => Some(reason),
            FirstActivation::Lost => None,
        }
    }

    /// The new instance of `name`'s binding failed its first activation for `reason`: go
    /// back to the old instance if it still lives and the action still runs, and start the
    /// action again on it. False if nothing was rolled back (the trial is over either way):
    /// the failure then takes its ordinary path.
    pub(super) async fn roll_back(
        &mut self,
        myself: &ActorRef<DispatcherMsg>,
        name: &str,
        reason: String,
    ) -> bool {
        let Some(trial) = self.bindings.get_mut(name).and_then(|b| b.trial.take()) else {
            return false;
        };
        let running = self
            .live
            .get(&trial.generation)
            .filter(|cur| !cur.ending() && !self.ended)
            .and_then(|cur| {
                let action = &self.mission.actions[cur.index];
                let op = action
                    .ops
                    .iter()
                    .find(|o| o.name == name && cur.running.contains(&o.key))?;
                Some((op.key.clone(), op.params.clone(), cur.launched))
            });
        let old = self.old_instance(name, &trial).await;
        let decision = upgrade::after_failed_first_activation(old.is_some(), running.is_some());
        let (Some(old), Some((key, mission_params, launched)), AfterFailure::RollBack) =
            (old, running, decision)
        else {
            tracing::info!(op = %name, %reason, "the new instance failed its first activation; no rollback (the old instance is gone, or the action ended)");
            return false;
        };
        let (now, run_ms) = (self.clock.now(), self.elapsed_ms());
        let Some(b) = self.bindings.get_mut(name) else {
            return false;
        };
        let (from, from_version, from_node) = (b.address(), b.version.clone(), b.node.clone());
        b.spurned.push((b.actor_id(), reason.clone()));
        // the failed instance's late reports are about an instance let go of
        b.incarnation += 1;
        b.adopt(old, now);
        let params = b.supplied(&mission_params);
        b.params = params.clone();
        let record = RollbackRecord {
            operation: name.to_string(),
            action: trial.action,
            from,
            from_version,
            from_node,
            to: b.address(),
            to_version: b.version.clone(),
            to_node: b.node.clone(),
            reason,
            epoch: b.epoch,
            run_ms,
        };
        let (epoch, incarnation) = (b.epoch, b.incarnation);
        // the raised epoch is stored before any command carries it (as an adoption's)
        if self.checkpoint_now(myself).await.is_err() {
            return true; // fenced off: the run ends here
        }
        self.announce(Some(name)).await;
        tracing::warn!(op = %name, action = %record.action, from = %record.from_version, to = %record.to_version, reason = %record.reason, "binding rolled back");
        self.emit(EventKind::BindingRolledBack(record));
        if launched {
            let start = Start {
                generation: trial.generation,
                incarnation,
                epoch,
                resume: false,
            };
            if let Err(e) = self.activate(myself, &key, start, params) {
                self.report_gone(myself, name, incarnation, e);
            }
        }
        true
    }

    /// The instance `trial` moved `name`'s binding from, if it still lives: in the registry,
    /// on a node not declared down, answering within its declared deadline as the same
    /// operation.
    async fn old_instance(&self, name: &str, trial: &super::binding::Trial) -> Option<Prospect> {
        let inst = registry::lookup(ModuleKind::Operation, name)
            .into_iter()
            .find(|i| i.actor.get_id() == trial.from && !registry::is_declared_down(&i.node))?;
        let cand = match examine(&inst, trial.from_deadline).await {
            Ok(cand) => cand,
            Err(e) => {
                tracing::info!(op = %name, error = %e, "the old instance does not answer");
                return None;
            }
        };
        let id = self.bindings.get(name)?.id;
        (cand.info.id == id).then_some(cand)
    }
}
