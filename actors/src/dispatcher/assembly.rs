//! Assembling the report: the records of finished actions, the final outcome, and the live
//! progress events that go with them.
//!
//! # Invariants
//! - The report is sent once, when the mission ends (success or full stop); what still runs
//!   is suspended first, and the dispatcher then stops normally.

use super::actor::DispatcherState;
use super::messages::{DispatchEvent, DispatcherMsg};
use super::report::{ActionRecord, Outcome, RunReport};
use ractor::ActorRef;

impl DispatcherState {
    pub(super) fn emit(&self, evt: DispatchEvent) {
        if let Some(tx) = &self.events {
            let _ = tx.send(evt);
        }
    }

    pub(super) fn elapsed_ms(&self) -> u64 {
        self.clock.now().saturating_sub(self.started).as_millis() as u64
    }

    pub(super) fn record_current(&mut self) {
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

    pub(super) fn finish(
        &mut self,
        myself: &ActorRef<DispatcherMsg>,
        outcome: Outcome,
        reason: String,
    ) {
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
            rebinds_total: self.rebinds_total,
            duration_ms: self.elapsed_ms(),
            final_pose: None,
            collisions: None,
            seed: None,
            inside_goal: None,
            judgement: None,
            faults: Vec::new(),
            faults_total: 0,
        };
        self.emit(DispatchEvent::Ended { outcome, reason });
        if let Some(reply) = self.reply.take() {
            let _ = reply.send(report);
        }
        myself.stop(None); // a normal exit: its work is done
    }
}
