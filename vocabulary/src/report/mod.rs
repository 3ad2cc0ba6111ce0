//! The run report: what happened during a mission, as JSON — the fold of the run's events.
//!
//! A [`RunReport`] is made by one thing only: a [`ReportBuilder`] folded over the events of
//! one run, in the order they were published. A node folds its bus while it runs a mission
//! ([`ReportBuilder::attach`]), and [`RunReport::from_events`] folds an events file, so the
//! report a run wrote and the one rebuilt from its events are equal by construction.
//!
//! The report is generic: it knows the dispatcher's actions, bindings, rebinds, faults and
//! choices, and carries what a robot said of the run as an untyped section
//! ([`RunReport::robot`], written as top-level keys: for marie's simulated cart
//! `final_pose`, `collisions`, `seed`, `inside_goal`, `judgement`, `refused_commands`).
//!
//! # Invariant: bounded
//! A long run (a chaos test, a robot on duty for days) keeps bounded memory: the report
//! keeps the counts `rebinds_total`, `faults_total` and `selection_total` and only the
//! latest [`REPORT_KEEPS`] rebinds, faults and choices of stand-ins (the choices of the
//! run's start, one per operation, are all kept); the full history is on the event stream
//! ([`crate::events`]).

mod builder;

pub use builder::{AttachedReport, ReportBuilder};

use crate::fence::BoundEpoch;
use crate::run::{
    Choice, DmCheck, FaultKind, OpEnd, Outcome, ParamSetting, ParamSource, Provenance,
    RebindRecord, RobotSection, RollbackRecord, TakeoverRecord, UpgradeRecord,
};
use serde::{Deserialize, Serialize};

/// How many of the latest rebinds, and of the latest faults, a report keeps (older ones are
/// only counted). 100 covers every ordinary run in full and keeps a report of a long chaos
/// run small enough to read.
pub const REPORT_KEEPS: usize = 100;

/// One operation's part in an action.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct OpRecord {
    /// Operation name.
    pub name: String,
    /// Numeric id.
    pub id: u32,
    /// Version of the instance used.
    pub version: String,
    /// Node it ran on.
    pub node: String,
    /// Actor address.
    pub address: String,
    /// How its part ended.
    pub ended: OpEnd,
    /// Names of the flags it raised (those the mission maps).
    pub flags: Vec<String>,
}

/// One action of the run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ActionRecord {
    /// Action name.
    pub name: String,
    /// Start, in ms of mission clock time since the run began.
    pub start_ms: u64,
    /// End, likewise.
    pub end_ms: u64,
    /// Status word after the action, as names.
    pub flags: Vec<String>,
    /// Status word after the action.
    pub status: u32,
    /// The operations it ran.
    pub operations: Vec<OpRecord>,
}

/// The whole report.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RunReport {
    /// Mission name.
    pub mission: String,
    /// `succeeded` or `failed`.
    pub outcome: Outcome,
    /// Why it failed (empty on success).
    pub reason: String,
    /// Final status word.
    pub status: u32,
    /// Final status word, as names.
    pub flags: Vec<String>,
    /// Actions in the order they ran.
    pub actions: Vec<ActionRecord>,
    /// The latest [`REPORT_KEEPS`] rebindings of the run, oldest first.
    pub rebinds: Vec<RebindRecord>,
    /// How many rebindings the run had in all.
    #[serde(default)]
    pub rebinds_total: u64,
    /// The latest [`REPORT_KEEPS`] bindings moved to a newer compatible version of their
    /// operation at an action's start, oldest first.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub upgrades: Vec<UpgradeRecord>,
    /// The latest [`REPORT_KEEPS`] bindings moved back from an upgrade whose instance
    /// failed its first activation, oldest first.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub rollbacks: Vec<RollbackRecord>,
    /// Mission clock time the run took, in ms.
    pub duration_ms: u64,
    /// What a robot said of the run ([`RobotSection`]; empty without a robot). Its keys
    /// are written beside the report's own (a key of the report's own is never
    /// overwritten: the builder drops it).
    #[serde(flatten)]
    pub robot: RobotSection,
    /// The latest [`REPORT_KEEPS`] faults injected on purpose during the run
    /// (fault-injection tests, `--fault`, `--chaos`), oldest first.
    #[serde(default)]
    pub faults: Vec<FaultRecord>,
    /// How many faults were injected (or tried) in all.
    #[serde(default)]
    pub faults_total: u64,
    /// How each operation's instance was chosen: the candidates and their verdicts
    /// (`marie_actors::dispatcher::selection`), in the order the choices were made — every
    /// choice of the run's start (one per operation), then the latest [`REPORT_KEEPS`]
    /// choices of stand-ins ([`Choice::replacing`] set). Every rebind makes such a choice,
    /// so a report that kept them all grew with the run (~350 bytes a failover).
    #[serde(default)]
    pub selection: Vec<Choice>,
    /// How many choices the run made in all, those of its start included.
    #[serde(default)]
    pub selection_total: u64,
    /// The peer nodes the run's node lost during the run — a session that ended, or a peer
    /// its failure detector declared down — and whether each came back: the latest
    /// [`REPORT_KEEPS`], oldest first.
    #[serde(default)]
    pub nodes_lost: Vec<NodeLossRecord>,
    /// The run's dispatcher lost and its run taken over by a standby: the latest
    /// [`REPORT_KEEPS`], oldest first.
    #[serde(default)]
    pub takeovers: Vec<TakeoverRecord>,
    /// The check of the datamanagers at the run's end, one per datamanager (`dm_checked`
    /// events): of the records the run's producers were told were stored, how many the
    /// datamanager's leader still held, and how many were lost ([`DmCheck`]).
    #[serde(default)]
    pub dm_checks: Vec<DmCheck>,
    /// Acknowledged records lost: the sum of `dm_checks`' `lost` — records a producer was
    /// told were stored that the datamanager's leader no longer held at the end, retention
    /// and acknowledged deletes accounted for. `None` when the run checked no datamanager.
    #[serde(default)]
    pub acknowledged_lost: Option<u64>,
    /// Put records lost: the sum of `dm_checks`' `applied_lost` — records a datamanager
    /// told it applied from `put`s (`dm_applied`) that it no longer held at the end,
    /// retention and deletes accounted for. `None` when the run checked no datamanager.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub applied_lost: Option<u64>,
    /// What each datamanager started from during the run: a journal read back
    /// (`dm_recovered`) or the records of its previous incarnation (`dm_inherited`), oldest
    /// first, the latest [`REPORT_KEEPS`].
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub dm_recoveries: Vec<DmRecoveryRecord>,
    /// When the dispatcher bound each operation at each epoch (the run's start, a takeover,
    /// a rebind), on its node's clock: what the receivers' logs of obeyed commands are
    /// checked against ([`crate::fence::obeyed_late`]). The latest
    /// [`BOUND_EPOCHS_KEEPS`], oldest first.
    #[serde(default)]
    pub bound_epochs: Vec<BoundEpoch>,
    /// The control decisions of the mission's tree — retries, fallbacks, timeouts,
    /// conditions lost, recoveries, parallels decided —, the latest [`REPORT_KEEPS`],
    /// oldest first. Empty for a thesis mission: its schedule decides nothing of the kind.
    #[serde(default)]
    pub control: Vec<ControlRecord>,
    /// What ran ([`Provenance`]): the build, the command line, the files read with their
    /// texts, the nodes and their builds, the seed and speed — from the run's first event —
    /// and every parameter value the operations ran with. `None` for a stream without a
    /// `provenance` event (older files).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub provenance: Option<Provenance>,
}

/// A control decision of a mission's tree ([`crate::events::EventKind::Control`]).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ControlRecord {
    /// When, in ms since the run began.
    pub at_ms: u64,
    /// The item of the mission's tree that decided, by its label (`node` in reports written
    /// before: read either way).
    #[serde(alias = "node")]
    pub item: String,
    /// What it decided.
    pub decision: String,
}

/// How many bindings' epochs a report keeps ([`RunReport::bound_epochs`]): the latest.
/// Several per rebind kept ([`REPORT_KEEPS`]), so a long chaos run's are all there while a
/// receiver still logs the epochs they replace ([`crate::fence::ObeyedLog::KEEPS`]).
pub const BOUND_EPOCHS_KEEPS: usize = 4 * REPORT_KEEPS;

/// A peer node lost during a run, as the run's node saw it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct NodeLossRecord {
    /// The peer's node name.
    pub peer: String,
    /// When it was lost, in ms since the run began.
    pub at_ms: u64,
    /// Whether the failure detector declared it down (it fell silent: frozen, cut off),
    /// rather than its sessions ending (its process gone).
    pub declared_down: bool,
    /// When it was seen again, in ms since the run began — if it was.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub back_at_ms: Option<u64>,
}

/// A fault injected (or tried) during a run, from any source: a plan, chaos, the monitor's
/// page, `marie kill`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FaultRecord {
    /// When, in ms of mission clock time since the run began: when it was injected or
    /// found impossible — or, for a planned fault the run ended before, when it was due.
    pub at_ms: u64,
    /// What was injected.
    pub fault: FaultKind,
    /// What it was meant for, as asked: an operation (`NAME`, `ID`, `NAME#VERSION`, an
    /// actor id) or, for a node fault, the node's name.
    pub operation: String,
    /// The instance that got it (its address), or for a node fault the process (`pid N`);
    /// empty if none did.
    pub actor: String,
    /// The node it landed on, where known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub node: Option<String>,
    /// Why it could not be injected, if it could not.
    #[serde(default)]
    pub error: Option<String>,
    /// For a fault that lasts (a freeze, a cut): for how long it was asked, in ms.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lasting_ms: Option<u64>,
    /// For a fault that lasts: when it was undone (ms since the run began), once it was.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub healed_at_ms: Option<u64>,
}

/// What a datamanager started from during a run (the report's `dm_recoveries`).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct DmRecoveryRecord {
    /// When, in ms since the run began.
    pub at_ms: u64,
    /// The datamanager.
    pub dm: String,
    /// The node it runs on.
    pub node: String,
    /// `journal` (read back from its journal) or `heir` (its previous incarnation's
    /// records, at durability `memory`).
    pub from: String,
    /// Records it held after.
    pub records: u64,
    /// Records dropped: a journal's torn or corrupt end, or those an inherited store's
    /// check refused.
    pub dropped_records: u64,
    /// Where and why a journal's replay stopped early, if it did.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub torn: Option<String>,
}

impl RunReport {
    /// The report's own JSON keys: a robot's section cannot take them.
    pub const OWN_KEYS: [&'static str; 25] = [
        "mission",
        "outcome",
        "reason",
        "status",
        "flags",
        "actions",
        "rebinds",
        "rebinds_total",
        "upgrades",
        "rollbacks",
        "duration_ms",
        "faults",
        "faults_total",
        "selection",
        "selection_total",
        "nodes_lost",
        "dm_checks",
        "acknowledged_lost",
        "applied_lost",
        "dm_recoveries",
        "bound_epochs",
        "control",
        "takeovers",
        "provenance",
        "robot",
    ];

    /// The report of mission `mission` that ended with `outcome` for `reason`, before any
    /// action, rebind, fault or judgement is recorded in it.
    pub fn new(mission: impl Into<String>, outcome: Outcome, reason: impl Into<String>) -> Self {
        RunReport {
            mission: mission.into(),
            outcome,
            reason: reason.into(),
            status: 0,
            flags: Vec::new(),
            actions: Vec::new(),
            rebinds: Vec::new(),
            rebinds_total: 0,
            upgrades: Vec::new(),
            rollbacks: Vec::new(),
            duration_ms: 0,
            selection: Vec::new(),
            selection_total: 0,
            nodes_lost: Vec::new(),
            takeovers: Vec::new(),
            dm_checks: Vec::new(),
            acknowledged_lost: None,
            applied_lost: None,
            dm_recoveries: Vec::new(),
            bound_epochs: Vec::new(),
            control: Vec::new(),
            provenance: None,
            robot: RobotSection::new(),
            faults: Vec::new(),
            faults_total: 0,
        }
    }

    /// True when the mission succeeded.
    pub fn succeeded(&self) -> bool {
        self.outcome == Outcome::Succeeded
    }

    /// Keep a takeover among the latest [`REPORT_KEEPS`].
    pub fn record_takeover(&mut self, takeover: TakeoverRecord) {
        keep_latest(&mut self.takeovers, takeover);
    }

    /// Keep when operation `operation` was bound at `epoch`, among the latest
    /// [`BOUND_EPOCHS_KEEPS`].
    pub fn record_bound_epoch(&mut self, operation: &str, epoch: u64, clock_ms: u64) {
        let bound = BoundEpoch {
            operation: operation.to_string(),
            epoch,
            clock_ms,
        };
        keep_last(&mut self.bound_epochs, bound, BOUND_EPOCHS_KEEPS);
    }

    /// Keep a control decision among the latest [`REPORT_KEEPS`].
    pub fn record_control(&mut self, record: ControlRecord) {
        keep_latest(&mut self.control, record);
    }

    /// Keep a parameter's value as an operation ran with it: once per action, operation,
    /// parameter, value and source (an action run again with the same values adds nothing);
    /// of the re-parameterizations, the latest [`REPORT_KEEPS`].
    pub fn record_parameter(&mut self, setting: ParamSetting) {
        let provenance = self.provenance.get_or_insert_with(Provenance::default);
        let params = &mut provenance.parameters;
        if setting.source != ParamSource::Reparameterized {
            let known = params.iter().any(|p| {
                p.source == setting.source
                    && p.action == setting.action
                    && p.operation == setting.operation
                    && p.name == setting.name
                    && p.value == setting.value
            });
            if !known {
                params.push(setting);
            }
            return;
        }
        params.push(setting);
        let changes = params
            .iter()
            .filter(|p| p.source == ParamSource::Reparameterized)
            .count();
        if changes > REPORT_KEEPS {
            if let Some(oldest) = params
                .iter()
                .position(|p| p.source == ParamSource::Reparameterized)
            {
                params.remove(oldest);
            }
        }
    }

    /// Count a rebind and keep it among the latest [`REPORT_KEEPS`].
    pub fn record_rebind(&mut self, rebind: RebindRecord) {
        self.rebinds_total += 1;
        keep_latest(&mut self.rebinds, rebind);
    }

    /// Keep a binding's move to a newer version among the latest [`REPORT_KEEPS`].
    pub fn record_upgrade(&mut self, upgrade: UpgradeRecord) {
        keep_latest(&mut self.upgrades, upgrade);
    }

    /// Keep a binding's move back from a failed upgrade among the latest [`REPORT_KEEPS`].
    pub fn record_rollback(&mut self, rollback: RollbackRecord) {
        keep_latest(&mut self.rollbacks, rollback);
    }

    /// Count faults and keep them among the latest [`REPORT_KEEPS`].
    pub fn record_faults(&mut self, faults: impl IntoIterator<Item = FaultRecord>) {
        for fault in faults {
            self.faults_total += 1;
            keep_latest(&mut self.faults, fault);
        }
    }

    /// Record the check of a datamanager at the run's end (a second check of the same
    /// datamanager replaces the first), and the sum of the records lost.
    pub fn record_dm_check(&mut self, check: DmCheck) {
        self.dm_checks.retain(|c| c.dm != check.dm);
        self.dm_checks.push(check);
        self.acknowledged_lost = Some(self.dm_checks.iter().map(|c| c.lost).sum());
        self.applied_lost = Some(self.dm_checks.iter().map(|c| c.applied_lost).sum());
    }

    /// Record that the run's node lost `peer` at `at_ms` (`declared_down` by its failure
    /// detector, or its sessions ended): a peer still lost is one loss however it is told
    /// (declared down, then its sessions closed), the latest [`REPORT_KEEPS`] kept.
    pub fn record_node_lost(&mut self, peer: &str, at_ms: u64, declared_down: bool) {
        match self.node_loss_open(peer) {
            Some(open) => open.declared_down |= declared_down,
            None => keep_latest(
                &mut self.nodes_lost,
                NodeLossRecord {
                    peer: peer.to_string(),
                    at_ms,
                    declared_down,
                    back_at_ms: None,
                },
            ),
        }
    }

    /// The loss of `peer` it has not come back from yet.
    pub(crate) fn node_loss_open(&mut self, peer: &str) -> Option<&mut NodeLossRecord> {
        self.nodes_lost
            .iter_mut()
            .rev()
            .find(|n| n.peer == peer && n.back_at_ms.is_none())
    }

    /// Count a choice and keep it: a choice of the run's start always (there is one per
    /// operation of the mission), a stand-in's among the latest [`REPORT_KEEPS`] stand-ins'
    /// (a run may rebind without end; what a choice at the start was is what `--explain`
    /// and a reader of the report look for first).
    pub fn record_choice(&mut self, choice: Choice) {
        self.selection_total += 1;
        if choice.replacing.is_some() {
            let stand_ins = self
                .selection
                .iter()
                .filter(|c| c.replacing.is_some())
                .count();
            if stand_ins >= REPORT_KEEPS {
                // the oldest stand-in's choice goes; the start's stay where they are
                if let Some(oldest) = self.selection.iter().position(|c| c.replacing.is_some()) {
                    self.selection.remove(oldest);
                }
            }
        }
        self.selection.push(choice);
    }
}

/// Append `item`, dropping the oldest so that at most [`REPORT_KEEPS`] remain.
fn keep_latest<T>(list: &mut Vec<T>, item: T) {
    keep_last(list, item, REPORT_KEEPS);
}

/// Append `item`, dropping the oldest so that at most `keeps` remain.
fn keep_last<T>(list: &mut Vec<T>, item: T, keeps: usize) {
    if list.len() >= keeps {
        let excess = list.len() + 1 - keeps;
        list.drain(..excess);
    }
    list.push(item);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::run::LossCause;

    #[test]
    fn a_report_written_before_the_tree_said_item_still_reads() {
        let old = r#"{"at_ms":3,"node":"retry(a)","decision":"retry 2 of 3"}"#;
        let record: ControlRecord = serde_json::from_str(old).unwrap();
        assert_eq!(record.item, "retry(a)");
        let now = serde_json::to_string(&record).unwrap();
        assert_eq!(
            now,
            r#"{"at_ms":3,"item":"retry(a)","decision":"retry 2 of 3"}"#
        );
    }

    #[test]
    fn a_report_keeps_only_the_latest_bound_epochs() {
        let mut report = RunReport::new("m", Outcome::Succeeded, "");
        for epoch in 0..(BOUND_EPOCHS_KEEPS as u64 + 5) {
            report.record_bound_epoch("op", epoch, epoch);
        }
        assert_eq!(report.bound_epochs.len(), BOUND_EPOCHS_KEEPS);
        assert_eq!(report.bound_epochs[0].epoch, 5);
    }

    #[test]
    fn reports_without_the_robot_fields_still_read() {
        let json = r#"{"mission":"m","outcome":"failed","reason":"r","status":0,"flags":[],
                       "actions":[],"rebinds":[],"duration_ms":5}"#;
        let report: RunReport = serde_json::from_str(json).expect("an older report reads");
        assert_eq!(report.outcome, Outcome::Failed);
        // no robot said anything of it: its section is empty, none of a robot's keys is set
        for key in [
            "final_pose",
            "collisions",
            "seed",
            "inside_goal",
            "judgement",
            "refused_commands",
        ] {
            assert_eq!(report.robot.get(key), None, "{key}");
        }
        assert!(report.robot.is_empty());
        let round: RunReport =
            serde_json::from_str(&serde_json::to_string(&report).expect("writes")).expect("reads");
        assert_eq!(round, report);
    }

    #[test]
    fn a_report_with_typed_values_keeps_its_json_shape_and_reads_back_equal() {
        let report = RunReport {
            mission: "m".into(),
            outcome: Outcome::Succeeded,
            reason: String::new(),
            status: 1,
            flags: vec!["done".into()],
            actions: vec![ActionRecord {
                name: "a".into(),
                start_ms: 1,
                end_ms: 9,
                flags: vec!["done".into()],
                status: 1,
                operations: vec![OpRecord {
                    name: "op".into(),
                    id: 7,
                    version: "1.0.0".into(),
                    node: "local".into(),
                    address: "0.3".into(),
                    ended: OpEnd::Finished,
                    flags: vec!["done".into()],
                }],
            }],
            rebinds: vec![RebindRecord {
                from_node: String::new(),
                to_node: String::new(),
                operation: "op".into(),
                cause: LossCause::Hung { deadline_ms: 300 },
                from: "0.2".into(),
                to: "0.3".into(),
                downtime_ms: 4,
                epoch: 7,
            }],
            rebinds_total: 1,
            upgrades: vec![UpgradeRecord {
                operation: "op".into(),
                action: "a".into(),
                from: "0.3".into(),
                from_version: "1.0.0".into(),
                from_node: "local".into(),
                to: "1.4".into(),
                to_version: "1.1.0".into(),
                to_node: "other".into(),
                epoch: 8,
                run_ms: 6,
                from_last_ms: Some(5),
            }],
            rollbacks: vec![RollbackRecord {
                operation: "op".into(),
                action: "a".into(),
                from: "1.4".into(),
                from_version: "1.1.0".into(),
                from_node: "other".into(),
                to: "0.3".into(),
                to_version: "1.0.0".into(),
                to_node: "local".into(),
                reason: "it failed: no".into(),
                epoch: 9,
                run_ms: 7,
            }],
            duration_ms: 10,
            selection: Vec::new(),
            selection_total: 0,
            nodes_lost: Vec::new(),
            takeovers: vec![TakeoverRecord {
                at_ms: 5,
                from: "a".into(),
                to: "b".into(),
                term: 2,
                gap_ms: 80,
            }],
            dm_checks: Vec::new(),
            acknowledged_lost: None,
            applied_lost: None,
            dm_recoveries: Vec::new(),
            bound_epochs: vec![BoundEpoch {
                operation: "op".into(),
                epoch: 7,
                clock_ms: 1_764_216_000_004,
            }],
            control: vec![ControlRecord {
                at_ms: 3,
                item: "retry(a)".into(),
                decision: "retry 2 of 3".into(),
            }],
            provenance: Some(crate::run::Provenance {
                seed: Some(7),
                parameters: vec![ParamSetting {
                    action: "a".into(),
                    operation: "op".into(),
                    name: "gain".into(),
                    value: crate::property::Value::Float(0.5),
                    source: ParamSource::Default,
                    at_ms: None,
                }],
                ..Default::default()
            }),
            faults: vec![FaultRecord {
                at_ms: 2,
                fault: FaultKind::Hang,
                operation: "op".into(),
                actor: "0.2".into(),
                node: Some("local".into()),
                error: None,
                lasting_ms: None,
                healed_at_ms: None,
            }],
            faults_total: 1,
            robot: serde_json::json!({"final_pose": [1.0, 2.0, 0.5], "collisions": 0})
                .as_object()
                .cloned()
                .unwrap_or_default(),
        };
        let json: serde_json::Value = serde_json::to_value(&report).expect("writes");
        assert_eq!(json["outcome"], "succeeded");
        assert_eq!(json["actions"][0]["operations"][0]["ended"], "finished");
        assert_eq!(json["faults"][0]["fault"], "hang");
        assert_eq!(json["rebinds"][0]["cause"]["type"], "hung");
        assert_eq!(json["rebinds"][0]["cause"]["deadline_ms"], 300);
        // the robot's section is written beside the report's own keys
        assert_eq!(json["final_pose"][1], 2.0);
        assert_eq!(json["collisions"], 0);
        assert!(json.get("robot").is_none());
        let back: RunReport = serde_json::from_value(json).expect("reads");
        assert_eq!(back, report);
    }

    #[test]
    fn a_report_keeps_counts_and_only_the_latest_rebinds_and_faults() {
        let mut report: RunReport = serde_json::from_str(
            r#"{"mission":"m","outcome":"failed","reason":"r","status":0,"flags":[],
                "actions":[],"rebinds":[],"duration_ms":5}"#,
        )
        .expect("reads");
        let rebind = |i: u64| RebindRecord {
            from_node: String::new(),
            to_node: String::new(),
            operation: "op".into(),
            cause: LossCause::Gone,
            from: format!("0.{i}"),
            to: format!("0.{}", i + 1),
            downtime_ms: i,
            epoch: i + 1,
        };
        for i in 0..1000 {
            report.record_rebind(rebind(i));
        }
        report.record_faults((0..250).map(|i| FaultRecord {
            at_ms: i,
            fault: FaultKind::Kill,
            operation: "op".into(),
            actor: String::new(),
            node: None,
            error: None,
            lasting_ms: None,
            healed_at_ms: None,
        }));
        assert_eq!((report.rebinds_total, report.faults_total), (1000, 250));
        assert_eq!(report.rebinds.len(), REPORT_KEEPS);
        assert_eq!(report.faults.len(), REPORT_KEEPS);
        assert_eq!(
            report.rebinds.first(),
            Some(&rebind(900)),
            "the latest, oldest first"
        );
        assert_eq!(report.rebinds.last(), Some(&rebind(999)));
        assert_eq!(report.faults[0].at_ms, 150);
    }

    #[test]
    fn a_report_keeps_every_choice_of_the_start_and_only_the_latest_stand_ins() {
        let mut report = RunReport::new("m", Outcome::Failed, "r");
        let choice = |operation: &str, replacing: Option<u64>| Choice {
            operation: operation.into(),
            candidates: Vec::new(),
            replacing: replacing.map(|i| format!("0.{i}")),
        };
        report.record_choice(choice("a", None));
        report.record_choice(choice("b", None));
        // a run that rebinds without end: a stand-in's choice per failover
        for i in 0..1000 {
            report.record_choice(choice("a", Some(i)));
        }
        assert_eq!(report.selection_total, 1002);
        assert_eq!(report.selection.len(), 2 + REPORT_KEEPS);
        assert_eq!(
            report.selection[..2],
            [choice("a", None), choice("b", None)],
            "the start's choices stay, first"
        );
        assert_eq!(
            report.selection[2],
            choice("a", Some(900)),
            "then the latest"
        );
        assert_eq!(report.selection.last(), Some(&choice("a", Some(999))));
    }
}
