//! Assembling a [`RunReport`] from events: a [`ReportBuilder`] folds the events of one run.
//! A node attaches one to its bus for each run ([`ReportBuilder::attach`]: a
//! [`Tap`](crate::events::Tap), so it sees every event, in order), and
//! [`RunReport::from_events`] folds an events file the same way — so the report a run wrote
//! equals the one rebuilt from its events.
//!
//! # Invariants
//! - Only the events decide the report: no other input, no clock. Times are the events'
//!   own: a fault's time is its stamp less the run's start (`run_started`'s stamp), whoever
//!   injected it.
//! - Bounded: rebinds, faults and choices go through [`RunReport::record_rebind`],
//!   [`RunReport::record_faults`] and [`RunReport::record_choice`] (the latest
//!   [`REPORT_KEEPS`](super::REPORT_KEEPS); every choice of the run's start).
//! - One dispatcher speaks for the run: the node of its `run_started`, then the `to` of each
//!   `takeover`. What another node's dispatcher says of the run (one fenced off, woken from a
//!   freeze or back from a partition) is not folded — a stream that holds every node's events
//!   makes the same report as the run's own bus.

use super::{keep_latest, ActionRecord, DmRecoveryRecord, FaultRecord, OpRecord, RunReport};
use crate::events::{DispatcherVoice, Event, EventBus, EventKind, Family, OpStarted, Tap};
use crate::property::Value;
use crate::run::{OpEnd, Outcome, ParamSetting, ParamSource, TakeoverRecord};
use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};

/// A run report being assembled from the events of one run.
#[derive(Clone, Debug)]
pub struct ReportBuilder {
    report: RunReport,
    /// The actions that started and have not ended (more than one under a parallel), in
    /// the order they started.
    open: Vec<OpenAction>,
    /// The stamp of the run's `run_started`: where its times count from.
    start_ms: Option<u64>,
    /// Whose word the run is (see the module invariants).
    voice: DispatcherVoice,
    /// The value each operation's parameter ran with last, by (operation, parameter): what
    /// a `reparameterized` is a change from.
    ran_with: BTreeMap<(String, String), Value>,
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
            open: Vec::new(),
            start_ms: None,
            voice: DispatcherVoice::default(),
            ran_with: BTreeMap::new(),
        }
    }

    /// Fold every event `bus` publishes from now on into a new builder, until the returned
    /// [`AttachedReport`] is finished: the report of the run that runs on the bus
    /// meanwhile.
    pub fn attach(bus: &EventBus) -> AttachedReport {
        let builder = Arc::new(Mutex::new(ReportBuilder::new()));
        let fold = builder.clone();
        let tap = bus.tap(move |event| lock(&fold).apply(event));
        AttachedReport { builder, tap }
    }

    /// Take one event into account. Kinds that a report does not show (registry,
    /// supervisors, generic robot events) change nothing; a [`EventKind::RunStarted`]
    /// starts a new report.
    pub fn apply(&mut self, event: &Event) {
        if !self.voice.hears(event) {
            return;
        }
        match event.kind.family() {
            Family::Run => self.on_run(event),
            Family::Action => self.on_action(event),
            Family::Binding => self.on_binding(event),
            Family::Dispatcher => self.on_dispatcher(event),
            Family::Fault => self.on_fault(event),
            Family::Node => self.on_node(event),
            Family::Datamanager => self.on_datamanager(event),
            // the location table's, the supervisors' and the robot's own news are the
            // monitor's; a robot's word on the run comes as its judgement
            Family::Registry | Family::Supervisor | Family::Robot => {}
        }
    }

    /// What runs, the run's start, end and judgement.
    fn on_run(&mut self, event: &Event) {
        match &event.kind {
            EventKind::Provenance(provenance) => {
                self.report.provenance = Some(provenance.as_ref().clone());
            }
            EventKind::RunStarted { mission, .. } => {
                let voice = std::mem::take(&mut self.voice);
                // what runs, and what its datamanagers started from, was told right before
                let provenance = self.report.provenance.take();
                let recoveries = std::mem::take(&mut self.report.dm_recoveries);
                *self = ReportBuilder::new();
                self.voice = voice;
                self.report.provenance = provenance;
                self.report.dm_recoveries = recoveries;
                self.report.mission = mission.clone();
                self.start_ms = Some(event.at_ms);
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
                while let Some(open) = self.open.first() {
                    let name = open.name.clone();
                    self.close(&name, *run_ms);
                }
                self.report.outcome = *outcome;
                self.report.reason = reason.clone();
                self.report.duration_ms = *run_ms;
            }
            EventKind::Judged {
                outcome,
                reason,
                robot,
            } => {
                self.report.outcome = *outcome;
                self.report.reason = reason.clone();
                self.report.robot = robot
                    .iter()
                    .filter(|(key, _)| !RunReport::OWN_KEYS.contains(&key.as_str()))
                    .map(|(k, v)| (k.clone(), v.clone()))
                    .collect();
            }
            _ => {}
        }
    }

    /// An action's start and end, its operations' parts and parameters, the tree's decisions.
    fn on_action(&mut self, event: &Event) {
        match &event.kind {
            EventKind::ActionStarted {
                action,
                run_ms,
                operations,
            } => self.action_started(action, *run_ms, operations),
            EventKind::OpEnded {
                action,
                key,
                ended,
                flags,
            } => {
                if let Some(rec) = self.open_op(Some(action), |k, _| k == key) {
                    rec.ended = *ended;
                    rec.flags = flags.clone();
                }
            }
            EventKind::ActionEnded {
                action,
                run_ms,
                flags,
                status,
                ..
            } => {
                self.report.status = *status;
                self.report.flags = flags.clone();
                self.close(action, *run_ms);
            }
            EventKind::Reparameterized {
                operation, values, ..
            } => {
                let at_ms = self.run_ms(event);
                // the action it runs in, if any: the newest open one that runs it
                let action = self
                    .open
                    .iter()
                    .rev()
                    .find(|o| o.ops.iter().any(|(_, r)| r.name == *operation))
                    .map(|o| o.name.clone())
                    .unwrap_or_default();
                for v in values {
                    let key = (operation.clone(), v.name.clone());
                    if self.ran_with.get(&key) == Some(&v.value) {
                        // the dispatcher restoring a stand-in to what its operation ran
                        // with: no change
                        continue;
                    }
                    self.ran_with.insert(key, v.value.clone());
                    self.report.record_parameter(ParamSetting {
                        action: action.clone(),
                        operation: operation.clone(),
                        name: v.name.clone(),
                        value: v.value.clone(),
                        source: ParamSource::Reparameterized,
                        at_ms: Some(at_ms),
                    });
                }
            }
            EventKind::Control {
                item: node,
                decision,
                run_ms,
            } => self.report.record_control(super::ControlRecord {
                at_ms: *run_ms,
                item: node.clone(),
                decision: decision.clone(),
            }),
            _ => {}
        }
    }

    /// Choices, bindings and rebinds (a loss is told by the rebind or the run's end that follows it).
    fn on_binding(&mut self, event: &Event) {
        match &event.kind {
            EventKind::Selected { choice } => self.report.record_choice(choice.clone()),
            EventKind::Bound { operations } => {
                for op in operations {
                    self.report
                        .record_bound_epoch(&op.name, op.epoch, event.at_ms);
                }
            }
            EventKind::Rebound(rebind) => {
                self.report
                    .record_bound_epoch(&rebind.operation, rebind.epoch, event.at_ms);
                // the stand-in carries on the running part of its operation
                let name = rebind.operation.as_str();
                if let Some(rec) =
                    self.open_op(None, |_, r| r.name == name && r.ended == OpEnd::Running)
                {
                    rec.address = rebind.to.clone();
                    if !rebind.to_node.is_empty() {
                        rec.node = rebind.to_node.clone();
                    }
                }
                self.report.record_rebind(rebind.clone());
            }
            EventKind::BindingUpgraded(upgrade) => {
                self.report
                    .record_bound_epoch(&upgrade.operation, upgrade.epoch, event.at_ms);
                self.report.record_upgrade(upgrade.clone());
            }
            EventKind::BindingRolledBack(rollback) => {
                self.report
                    .record_bound_epoch(&rollback.operation, rollback.epoch, event.at_ms);
                // the action starts again on the old instance: its record says so
                let name = rollback.operation.as_str();
                if let Some(rec) = self.open_op(Some(&rollback.action), |_, r| {
                    r.name == name && r.ended == OpEnd::Running
                }) {
                    rec.address = rollback.to.clone();
                    rec.node = rollback.to_node.clone();
                    rec.version = rollback.to_version.clone();
                }
                self.report.record_rollback(rollback.clone());
            }
            _ => {}
        }
    }

    /// A takeover (a dispatcher fenced off changes nothing of the run).
    fn on_dispatcher(&mut self, event: &Event) {
        if let EventKind::Takeover {
            from,
            to,
            term,
            gap_ms,
            ..
        } = &event.kind
        {
            let at_ms = self.run_ms(event);
            self.report.record_takeover(TakeoverRecord {
                at_ms,
                from: from.clone(),
                to: to.clone(),
                term: *term,
                gap_ms: *gap_ms,
            });
        }
    }

    /// Faults injected, healed, or not injected.
    fn on_fault(&mut self, event: &Event) {
        match &event.kind {
            EventKind::FaultInjected {
                fault,
                operation,
                actor,
                node,
                due_ms: _,
                lasting_ms,
            } => {
                let at_ms = self.run_ms(event);
                self.report.record_faults([FaultRecord {
                    at_ms,
                    fault: *fault,
                    operation: operation.clone(),
                    actor: actor.clone(),
                    node: node.clone(),
                    error: None,
                    lasting_ms: *lasting_ms,
                    healed_at_ms: None,
                }])
            }
            EventKind::FaultHealed { fault, operation } => {
                let at_ms = self.run_ms(event);
                // the latest of that fault on that target not healed yet
                if let Some(f) = self.report.faults.iter_mut().rev().find(|f| {
                    f.fault == *fault
                        && f.operation == *operation
                        && f.error.is_none()
                        && f.healed_at_ms.is_none()
                }) {
                    f.healed_at_ms = Some(at_ms);
                }
            }
            EventKind::FaultNotInjected {
                fault,
                operation,
                why,
                due_ms,
            } => {
                // a planned one is reported at the time it was due (the run may have
                // ended before it)
                let at_ms = due_ms.unwrap_or_else(|| self.run_ms(event));
                self.report.record_faults([FaultRecord {
                    at_ms,
                    fault: *fault,
                    operation: operation.clone(),
                    actor: String::new(),
                    node: None,
                    error: Some(why.clone()),
                    lasting_ms: None,
                    healed_at_ms: None,
                }])
            }
            _ => {}
        }
    }

    /// Nodes lost and back.
    fn on_node(&mut self, event: &Event) {
        match &event.kind {
            EventKind::NodeLost { peer, .. } | EventKind::NodeDown { peer, .. } => {
                let at_ms = self.run_ms(event);
                let down = matches!(event.kind, EventKind::NodeDown { .. });
                self.report.record_node_lost(peer, at_ms, down);
            }
            EventKind::NodeUp { peer, .. } => {
                let at_ms = self.run_ms(event);
                if let Some(open) = self.report.node_loss_open(peer) {
                    open.back_at_ms = Some(at_ms);
                }
            }
            _ => {}
        }
    }

    /// The check of a datamanager at the run's end, and what each started from.
    fn on_datamanager(&mut self, event: &Event) {
        let record = |from: &str, dm: &str, records, dropped_records, torn| DmRecoveryRecord {
            at_ms: self.run_ms(event),
            dm: dm.to_string(),
            node: event.node.clone(),
            from: from.to_string(),
            records,
            dropped_records,
            torn,
        };
        let recovery = match &event.kind {
            EventKind::DmChecked(check) => {
                self.report.record_dm_check(check.clone());
                return;
            }
            EventKind::DmRecovered {
                dm,
                records,
                dropped_records,
                torn,
                ..
            } => record("journal", dm, *records, *dropped_records, torn.clone()),
            EventKind::DmInherited {
                dm,
                records,
                refused,
            } => record("heir", dm, *records, *refused, None),
            _ => return,
        };
        keep_latest(&mut self.report.dm_recoveries, recovery);
    }

    /// An action started: a start told again (by a standby that launched what its lost
    /// predecessor had recorded) is one action; the values each operation runs with are the
    /// run's parameters.
    fn action_started(&mut self, action: &str, run_ms: u64, operations: &[OpStarted]) {
        // the same start told again — by a standby that launched an action its lost
        // predecessor had recorded, and may have launched — is one action
        let again = self
            .open
            .iter()
            .position(|o| o.name == action && o.start_ms == run_ms);
        match again {
            Some(at) => drop(self.open.remove(at)),
            // an action that starts again before its end was told: its first run
            // ends here
            None => self.close(action, run_ms),
        }
        for o in operations {
            for p in &o.params {
                self.ran_with
                    .insert((o.name.clone(), p.name.clone()), p.value.clone());
                self.report.record_parameter(ParamSetting {
                    action: action.to_string(),
                    operation: o.name.clone(),
                    name: p.name.clone(),
                    value: p.value.clone(),
                    source: p.source,
                    at_ms: None,
                });
            }
        }
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
        self.open.push(OpenAction {
            name: action.to_string(),
            start_ms: run_ms,
            ops,
        });
    }

    /// Mission time of `event` since the run began, in ms (0 before a run began).
    fn run_ms(&self, event: &Event) -> u64 {
        self.start_ms
            .map_or(0, |start| event.at_ms.saturating_sub(start))
    }

    /// The report as the events so far make it.
    pub fn report(&self) -> &RunReport {
        &self.report
    }

    /// The report, taken.
    pub fn finish(self) -> RunReport {
        self.report
    }

    /// The first operation record that `pick` chooses among the open actions (of the
    /// action named `action`, if given).
    fn open_op(
        &mut self,
        action: Option<&str>,
        pick: impl Fn(&str, &OpRecord) -> bool,
    ) -> Option<&mut OpRecord> {
        self.open
            .iter_mut()
            .filter(|o| action.is_none_or(|a| o.name == a))
            .flat_map(|o| o.ops.iter_mut())
            .find(|(k, r)| pick(k, r))
            .map(|(_, r)| r)
    }

    /// Record the open action `action` as ended at `end_ms`, with the report's status
    /// word.
    fn close(&mut self, action: &str, end_ms: u64) {
        let Some(at) = self.open.iter().position(|o| o.name == action) else {
            return;
        };
        let OpenAction {
            name,
            start_ms,
            ops,
        } = self.open.remove(at);
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
            builder.apply(event);
        }
        builder.finish()
    }
}

/// A [`ReportBuilder`] attached to a bus ([`ReportBuilder::attach`]).
#[derive(Debug)]
pub struct AttachedReport {
    builder: Arc<Mutex<ReportBuilder>>,
    tap: Tap,
}

impl AttachedReport {
    /// The report as the events so far make it.
    pub fn report(&self) -> RunReport {
        lock(&self.builder).report().clone()
    }

    /// Detach from the bus and give the report.
    pub fn finish(self) -> RunReport {
        drop(self.tap);
        let builder = std::mem::take(&mut *lock(&self.builder));
        builder.finish()
    }
}

fn lock(builder: &Mutex<ReportBuilder>) -> std::sync::MutexGuard<'_, ReportBuilder> {
    builder.lock().unwrap_or_else(|e| e.into_inner())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::events::OpStarted;
    use crate::property::Value;
    use crate::run::{ParamSource, ParamValue, Provenance};

    fn event(at_ms: u64, kind: EventKind) -> Event {
        Event {
            at_ms,
            node: "n".into(),
            kind,
        }
    }

    fn started(action: &str, run_ms: u64, distance: f64) -> EventKind {
        EventKind::ActionStarted {
            action: action.into(),
            run_ms,
            operations: vec![OpStarted {
                key: "follower".into(),
                name: "follower".into(),
                id: 1,
                version: "1.0.0".into(),
                node: "n".into(),
                address: "0.4".into(),
                params: vec![
                    ParamValue {
                        name: "distance".into(),
                        value: Value::Float(distance),
                        source: ParamSource::Mission,
                    },
                    ParamValue {
                        name: "gain".into(),
                        value: Value::Float(1.0),
                        source: ParamSource::Default,
                    },
                ],
            }],
        }
    }

    fn changed(distance: f64) -> EventKind {
        EventKind::Reparameterized {
            operation: "follower".into(),
            address: "0.4".into(),
            values: vec![ParamValue {
                name: "distance".into(),
                value: Value::Float(distance),
                source: ParamSource::Reparameterized,
            }],
        }
    }

    #[test]
    fn the_provenance_keeps_each_value_an_operation_ran_with_and_where_it_came_from() {
        let provenance = Provenance {
            seed: Some(3),
            ..Provenance::default()
        };
        let events = [
            event(0, EventKind::Provenance(Box::new(provenance))),
            event(
                10,
                EventKind::RunStarted {
                    mission: "m".into(),
                    actions: Vec::new(),
                    success: Vec::new(),
                },
            ),
            event(20, started("follow", 10, 0.5)),
            // a stand-in restored to the value it ran with: no change
            event(30, changed(0.5)),
            // an application's change while it runs
            event(40, changed(0.7)),
            // the same action run again with the mission's values: nothing new
            event(50, started("follow", 40, 0.5)),
            event(
                60,
                EventKind::ActionEnded {
                    action: "follow".into(),
                    run_ms: 50,
                    flags: Vec::new(),
                    status: 0,
                    result: None,
                },
            ),
            // between actions, a stand-in restored to what it last ran with: no change
            event(70, changed(0.5)),
            // and a change between actions
            event(80, changed(0.9)),
        ];
        let report = RunReport::from_events(&events);
        let p = report.provenance.expect("told before run_started, kept");
        assert_eq!(p.seed, Some(3));
        let told: Vec<(&str, &str, String, ParamSource, Option<u64>)> = p
            .parameters
            .iter()
            .map(|s| {
                (
                    s.action.as_str(),
                    s.name.as_str(),
                    s.value.to_string(),
                    s.source,
                    s.at_ms,
                )
            })
            .collect();
        assert_eq!(
            told,
            vec![
                (
                    "follow",
                    "distance",
                    "0.5".into(),
                    ParamSource::Mission,
                    None
                ),
                ("follow", "gain", "1".into(), ParamSource::Default, None),
                (
                    "follow",
                    "distance",
                    "0.7".into(),
                    ParamSource::Reparameterized,
                    Some(30)
                ),
                (
                    "",
                    "distance",
                    "0.9".into(),
                    ParamSource::Reparameterized,
                    Some(70)
                ),
            ]
        );
    }
}
