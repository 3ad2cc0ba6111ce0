//! Telling the run: every step is published on the bus, in one place
//! ([`DispatcherState::emit`]), and the run ends with its outcome.
//!
//! # Invariants
//! - The bus is the dispatcher's only account of the run: whoever wants the report folds
//!   the events ([`marie_vocabulary::report::ReportBuilder`]).
//! - The run ends once (success or full stop): what still runs is suspended first,
//!   `run_ended` is published, the outcome answered, and the dispatcher then stops
//!   normally.

use super::actor::DispatcherState;
use super::messages::DispatcherMsg;
use marie_vocabulary::events::EventKind;
use marie_vocabulary::run::Outcome;
use ractor::ActorRef;

impl DispatcherState {
    /// Publish `kind` on the bus.
    pub(super) fn emit(&mut self, kind: EventKind) {
        self.bus.publish(kind);
    }

    /// Mission clock time since the run began, in ms.
    pub(super) fn elapsed_ms(&self) -> u64 {
        self.clock.now().saturating_sub(self.started).as_millis() as u64
    }

    /// The mission's status word now, as `(word, flag names)`.
    pub(super) fn status_now(&self) -> (u32, Vec<String>) {
        (self.status.0, self.mission.flags_to_names(self.status))
    }

    /// End the run: suspend what still runs, publish the end and answer the outcome.
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
        self.wake = None;
        for cur in std::mem::take(&mut self.live).into_values() {
            for key in &cur.running {
                if let Some(b) = self.binding(key).filter(|b| b.lost.is_none()) {
                    let _ = b.client.suspend(b.epoch);
                }
            }
        }
        // a recorded run ends once its end is stored: a dispatcher fenced off meanwhile
        // never ends the run its successor carries on
        if self.checkpoint_end(myself, outcome, &reason) {
            self.conclude(myself, outcome, reason);
        }
    }

    /// Publish the run's end and answer its outcome; the dispatcher then stops.
    pub(super) fn conclude(
        &mut self,
        myself: &ActorRef<DispatcherMsg>,
        outcome: Outcome,
        reason: String,
    ) {
        match outcome {
            Outcome::Succeeded => tracing::info!(mission = %self.mission.name, "mission succeeded"),
            Outcome::Failed => {
                tracing::warn!(mission = %self.mission.name, %reason, "mission failed: full stop")
            }
        }
        let (status, flags) = self.status_now();
        self.emit(EventKind::RunEnded {
            outcome,
            reason,
            run_ms: self.elapsed_ms(),
            status,
            flags,
        });
        if let Some(reply) = self.reply.take() {
            let _ = reply.send(outcome);
        }
        myself.stop(None); // a normal exit: its work is done
    }
}
