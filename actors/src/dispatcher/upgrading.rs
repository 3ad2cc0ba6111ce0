//! Upgrading bindings in the running dispatcher: noting a newer compatible instance when it
//! joins the registry, forgetting it when it leaves, and moving the binding to it as the
//! next action that uses the operation starts. What counts as newer and when a binding may
//! move is [`super::upgrade`]'s pure decision; this file is its wiring.
//!
//! # Invariants
//! - A binding moves only in [`DispatcherState::upgrade_at_start`], called as an action
//!   starts, before its parameters are set and before its start is recorded: the move's
//!   raised epoch is in the checkpoint the action's launch waits for, and the action's
//!   activation — the new instance's first command — carries the action's parameters
//!   (the declared defaults of the new schema for what the mission leaves out).
//! - The move's raised epoch is announced to the fence keepers, as an adoption's is, after
//!   that checkpoint is stored and before the launch sends the first command: a replaced
//!   dispatcher's commands to the new instance's node are refused from then on.
//! - The move raises the binding's incarnation as a loss does: a probe or report of the
//!   old instance that arrives late is about an instance the dispatcher has let go of.

use super::actor::DispatcherState;
use super::binding::Trial;
use super::candidates::examine;
use super::upgrade::{self, Judgement};
use marie_vocabulary::events::EventKind;
use marie_vocabulary::fence::Fence;
use marie_vocabulary::registry::Instance;
use marie_vocabulary::run::UpgradeRecord;
use ractor::ActorId;

impl DispatcherState {
    /// `inst` joined the registry while its operation's binding lives: note it as due if it
    /// is a newer compatible version the mission can use, tell why not if it is newer but
    /// the mission cannot use it.
    pub(super) async fn note_newer(&mut self, inst: &Instance) {
        let Some(b) = self.bindings.get(&inst.name) else {
            return;
        };
        if b.lost.is_some() || self.ended {
            return;
        }
        if let Some(why) = b.ruled_out_unasked(inst.actor.get_id(), &inst.node) {
            tracing::debug!(op = %inst.name, actor = %inst.actor.get_id(), %why, "not an upgrade");
            return;
        }
        let cand = match examine(inst, b.deadline).await {
            Ok(cand) => cand,
            Err(e) => {
                tracing::debug!(op = %inst.name, actor = %inst.actor.get_id(), error = %e, "a newer instance does not answer");
                return;
            }
        };
        // looked at again after the round trip: the binding may have been lost or moved since
        let Some(b) = self.bindings.get_mut(&inst.name) else {
            return;
        };
        if b.lost.is_some() || cand.info.id != b.id {
            return;
        }
        let due = b.due.as_ref().map(|d| d.info.version.as_str());
        let spurned = b.spurned(cand.client.actor().get_id());
        match upgrade::judge(&b.version, b.need(), &cand.info, due, spurned) {
            Judgement::Newer => {
                tracing::info!(op = %b.name, from = %b.version, to = %cand.info.version, node = %cand.node, "a newer version appeared: the binding moves at the next action's start");
                b.due = Some(cand);
            }
            Judgement::Refused(reason) => {
                let refused = EventKind::BindingUpgradeRefused {
                    operation: b.name.clone(),
                    address: cand.client.actor().get_id().to_string(),
                    version: cand.info.version.clone(),
                    node: cand.node.clone(),
                    reason,
                };
                self.emit(refused);
            }
            Judgement::Ignored(why) => {
                tracing::debug!(op = %b.name, actor = %cand.client.actor().get_id(), %why, "not an upgrade")
            }
        }
    }

    /// The instance `id` left the registry: a binding it was due to take forgets it.
    pub(super) fn forget_newer(&mut self, id: ActorId) {
        for b in self.bindings.values_mut() {
            if b.due
                .as_ref()
                .is_some_and(|d| d.client.actor().get_id() == id)
            {
                tracing::info!(op = %b.name, actor = %id, "the newer instance due left before the binding moved");
                b.due = None;
            }
        }
    }

    /// Action `action` (generation `generation`) starts and runs operation `name`: move
    /// its binding to the newer instance due, if any and if it may move now
    /// ([`upgrade::moves_at_start`]), and tell it (`binding_upgraded`). The move is on
    /// trial until that action's first activation reports ([`super::rollback`]). Gives the
    /// raised epoch to announce to the fence keepers if the binding moved (the action's
    /// launch waits for that, see `running.rs`).
    pub(super) fn upgrade_at_start(
        &mut self,
        name: &str,
        action: &str,
        generation: u64,
    ) -> Option<Fence> {
        let running_elsewhere = self.running_key(name).is_some();
        let run_ms = self.elapsed_ms();
        let now = self.clock.now();
        let b = self.bindings.get_mut(name)?;
        if !upgrade::moves_at_start(b.due.is_some(), b.lost.is_some(), running_elsewhere) {
            return None;
        }
        let cand = b.due.take()?;
        let (from, from_version, from_node, from_last_ms) = (
            b.address(),
            b.version.clone(),
            b.node.clone(),
            b.last_report_ms,
        );
        b.trial = Some(Trial {
            generation,
            action: action.to_string(),
            from: b.actor_id(),
            from_deadline: b.deadline,
        });
        // the old instance's late probes and reports are about an instance let go of
        b.incarnation += 1;
        b.adopt(cand, now);
        let record = UpgradeRecord {
            operation: name.to_string(),
            action: action.to_string(),
            from,
            from_version,
            from_node,
            to: b.address(),
            to_version: b.version.clone(),
            to_node: b.node.clone(),
            epoch: b.epoch,
            run_ms,
            from_last_ms,
        };
        tracing::info!(op = %name, %action, from = %record.from_version, to = %record.to_version, "binding upgraded");
        let fence = Fence::new(name.to_string(), record.epoch);
        self.emit(EventKind::BindingUpgraded(record));
        Some(fence)
    }
}
