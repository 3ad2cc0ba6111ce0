//! Assembling a [`RunReport`] from events: the dispatcher feeds every event it publishes to
//! a [`ReportBuilder`] and sends the report the builder holds, so a report replayed from the
//! event stream ([`RunReport::from_events`]) equals the one the dispatcher sent.
//!
//! # Invariants
//! - Only the events decide the report: no other input, no clock.
//! - Bounded: rebinds and faults go through [`RunReport::record_rebind`] /
//!   [`RunReport::record_faults`] (the latest [`REPORT_KEEPS`](super::REPORT_KEEPS)).

use super::report::{ActionRecord, OpEnd, OpRecord, Outcome, RunReport};
use super::FaultRecord;
use crate::events::{Event, EventKind};

/// A run report being assembled from the events of one run.
#[derive(Clone, Debug)]
pub struct ReportBuilder {
    report: RunReport,
    /// The action that started and has not ended.
    open: Option<OpenAction>,
}

/// An action that started and has not ended.
#[derive(Clone, Debug)]
struct OpenAction {
    name: String,
    start_ms: u64,
    /// `(key, record)` per operation, in the mission's order.
    ops: Vec<(String, OpRecord)>,
}

impl Default for ReportBuilder {
    fn default() -> Self {
        ReportBuilder::new()
    }
}

impl ReportBuilder {
    /// A builder before any event: a failed report whose reason says the run never ended.
    pub fn new() -> ReportBuilder {
        ReportBuilder {
            report: RunReport::new("", Outcome::Failed, "the run has not ended"),
            open: None,
        }
    }

    /// Take one event into account. Kinds that a report does not show (registry,
    /// supervisors, generic robot events) change nothing; a [`EventKind::RunStarted`]
    /// starts a new report.
    pub fn apply(&mut self, kind: &EventKind) {
        match kind {
            EventKind::RunStarted { mission, .. } => {
                *self = ReportBuilder::new();
                self.report.mission = mission.clone();
            }
            EventKind::Selected { choice } => self.report.selection.push(choice.clone()),
            EventKind::ActionStarted {
                action,
                run_ms,
                operations,
            } => {
                self.close(*run_ms);
                let ops = operations
                    .iter()
                    .map(|o| {
                        let rec = OpRecord {
                            name: o.name.clone(),
                            id: o.id,
                            version: o.version.clone(),
                            node: o.node.clone(),
                            address: o.address.clone(),
                            ended: OpEnd::Running,
                            flags: Vec::new(),
                        };
                        (o.key.clone(), rec)
                    })
                    .collect();
                self.open = Some(OpenAction {
                    name: action.clone(),
                    start_ms: *run_ms,
                    ops,
                });
            }
            EventKind::OpEnded {
                key, ended, flags, ..
            } => {
                if let Some(rec) = self.open_op(|k, _| k == key) {
                    rec.ended = *ended;
                    rec.flags = flags.clone();
                }
            }
            EventKind::ActionEnded {
                run_ms,
                flags,
                status,
                ..
            } => {
                self.report.status = *status;
                self.report.flags = flags.clone();
                self.close(*run_ms);
            }
            EventKind::Rebound(rebind) => {
                // the stand-in carries on the running part of its operation
                let name = rebind.operation.as_str();
                if let Some(rec) = self.open_op(|_, r| r.name == name && r.ended == OpEnd::Running)
                {
                    rec.address = rebind.to.clone();
                    if !rebind.to_node.is_empty() {
                        rec.node = rebind.to_node.clone();
                    }
                }
                self.report.record_rebind(rebind.clone());
            }
            EventKind::RunEnded {
                outcome,
                reason,
                run_ms,
                status,
                flags,
            } => {
                self.report.status = *status;
                self.report.flags = flags.clone();
                self.close(*run_ms);
                self.report.outcome = *outcome;
                self.report.reason = reason.clone();
                self.report.duration_ms = *run_ms;
            }
            EventKind::FaultInjected {
                run_ms,
                fault,
                operation,
                actor,
            } => self.report.record_faults([FaultRecord {
                at_ms: *run_ms,
                fault: *fault,
                operation: operation.clone(),
                actor: actor.clone(),
                error: None,
            }]),
            EventKind::FaultNotInjected {
                run_ms,
                fault,
                operation,
                why,
            } => self.report.record_faults([FaultRecord {
                at_ms: *run_ms,
                fault: *fault,
                operation: operation.clone(),
                actor: String::new(),
                error: Some(why.clone()),
            }]),
            EventKind::Judged {
                outcome,
                reason,
                final_pose,
                collisions,
                seed,
                inside_goal,
                judgement,
                refused_commands,
            } => {
                self.report.outcome = *outcome;
                self.report.reason = reason.clone();
                self.report.final_pose = *final_pose;
                self.report.collisions = *collisions;
                self.report.seed = *seed;
                self.report.inside_goal = *inside_goal;
                self.report.judgement = judgement.clone();
                self.report.refused_commands = refused_commands.clone();
            }
            EventKind::Bound { .. }
            | EventKind::Lost { .. }
            | EventKind::RebindGaveUp { .. }
            | EventKind::Joined(_)
            | EventKind::Left(_)
            | EventKind::ChildStarted { .. }
            | EventKind::ChildExited { .. }
            | EventKind::ChildRestarted { .. }
            | EventKind::SupervisorGaveUp { .. }
            | EventKind::NodeUp { .. }
            | EventKind::NodeLost { .. }
            | EventKind::NodeDown { .. }
            | EventKind::NodeFrozen { .. }
            | EventKind::NodeKilled { .. }
            | EventKind::NodeRefused { .. }
            | EventKind::ConnectionRefused { .. }
            | EventKind::Robot { .. } => {}
        }
    }

    /// The report as the events so far make it.
    pub fn report(&self) -> &RunReport {
        &self.report
    }

    /// The report, taken.
    pub fn finish(self) -> RunReport {
        self.report
    }

    /// The first operation record of the open action that `pick` chooses.
    fn open_op(&mut self, pick: impl Fn(&str, &OpRecord) -> bool) -> Option<&mut OpRecord> {
        let open = self.open.as_mut()?;
        open.ops
            .iter_mut()
            .find(|(k, r)| pick(k, r))
            .map(|(_, r)| r)
    }

    /// Record the open action as ended at `end_ms`, with the report's status word.
    fn close(&mut self, end_ms: u64) {
        let Some(OpenAction {
            name,
            start_ms,
            ops,
        }) = self.open.take()
        else {
            return;
        };
        self.report.actions.push(ActionRecord {
            name,
            start_ms,
            end_ms,
            flags: self.report.flags.clone(),
            status: self.report.status,
            operations: ops.into_iter().map(|(_, r)| r).collect(),
        });
    }
}

impl RunReport {
    /// Rebuild the report of a run from its events (those of one run: a
    /// [`EventKind::RunStarted`] starts over; events of other kinds are skipped).
    pub fn from_events<'a>(events: impl IntoIterator<Item = &'a Event>) -> RunReport {
        let mut builder = ReportBuilder::new();
        for event in events {
            builder.apply(&event.kind);
        }
        builder.finish()
    }
}
