//! The run report (DESIGN.md §8): what happened during a mission, as JSON.
//!
//! # Invariant: bounded
//! A long run (a chaos test, a robot on duty for days) keeps bounded memory: the report
//! keeps the counts `rebinds_total` and `faults_total` and only the latest [`REPORT_KEEPS`]
//! rebinds and faults; the full history is on the event stream ([`crate::events`]).

use super::loss::LossCause;
use crate::eo::FaultKind;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fmt;

/// How many of the latest rebinds, and of the latest faults, a report keeps (older ones are
/// only counted). 100 covers every ordinary run in full and keeps a report of a long chaos
/// run small enough to read.
pub const REPORT_KEEPS: usize = 100;

/// How a mission ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Outcome {
    /// Every action ran and the success flags are set.
    Succeeded,
    /// Full stop: a stage failed, a deadline passed, or no action could run.
    Failed,
}

/// How an operation's part in an action ended. Serialized as its snake_case name
/// (`finished`, `suspended`, …), the values reports have always carried.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum OpEnd {
    /// Still running (the action has not ended, e.g. a report written at a full stop).
    Running,
    /// It reported that its task is done.
    Finished,
    /// It was suspended (its action ended on other operations), or suspended by another
    /// party — then the run failed.
    Suspended,
    /// It reported a failure, refused its parameters, or is bound by another dispatcher.
    Failed,
    /// Its instance was lost and no stand-in finished its part.
    Lost,
    /// It did not report within the suspension grace.
    Unresponsive,
}

impl OpEnd {
    /// The stable name, as serialized.
    pub fn name(self) -> &'static str {
        match self {
            OpEnd::Running => "running",
            OpEnd::Finished => "finished",
            OpEnd::Suspended => "suspended",
            OpEnd::Failed => "failed",
            OpEnd::Lost => "lost",
            OpEnd::Unresponsive => "unresponsive",
        }
    }
}

impl fmt::Display for OpEnd {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

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

/// A rebinding of an operation to another instance (filled by self-healing).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RebindRecord {
    /// Operation name.
    pub operation: String,
    /// Why the old instance was left.
    pub cause: LossCause,
    /// Old instance address.
    pub from: String,
    /// New instance address.
    pub to: String,
    /// The node the old instance ran on (empty in reports written before nodes were
    /// recorded).
    #[serde(default)]
    pub from_node: String,
    /// The node the new instance runs on.
    #[serde(default)]
    pub to_node: String,
    /// Time without a bound instance.
    pub downtime_ms: u64,
    /// The binding's epoch from the rebind on: every command of the stand-in carries it,
    /// and receivers refuse the lost instance's older one (0 in reports written before it
    /// was recorded).
    #[serde(default)]
    pub epoch: u64,
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
    /// Mission clock time the run took, in ms.
    pub duration_ms: u64,
    /// Final pose `[x, y, heading]` of a robot, where the mission drives one: metres, and the
    /// heading in radians.
    #[serde(default)]
    pub final_pose: Option<[f64; 3]>,
    /// Collisions counted by a simulation, where there is one.
    #[serde(default)]
    pub collisions: Option<u64>,
    /// Seed of a simulation, where there is one.
    #[serde(default)]
    pub seed: Option<u64>,
    /// Whether the robot's footprint ended inside the world's goal area, where there is a
    /// simulated robot in a world with a goal area.
    #[serde(default)]
    pub inside_goal: Option<bool>,
    /// The world's verdict on the robot's final state (e.g. `success: inside the goal area,
    /// heading error 2.1°, 0 collision(s)`), where there is a simulated robot.
    #[serde(default)]
    pub judgement: Option<String>,
    /// Commands the robot's drivers refused because they came from a replaced incarnation
    /// of an operation (an older epoch than its stand-in's: fencing, [`crate::fence`]), by
    /// operation name, where a simulated robot's cart told — e.g. a wall follower on a
    /// node cut off from the dispatcher, still driving after its binding moved.
    #[serde(default)]
    pub refused_commands: Option<BTreeMap<String, u64>>,
    /// The latest [`REPORT_KEEPS`] faults injected on purpose during the run
    /// (fault-injection tests, `--fault`, `--chaos`), oldest first.
    #[serde(default)]
    pub faults: Vec<FaultRecord>,
    /// How many faults were injected (or tried) in all.
    #[serde(default)]
    pub faults_total: u64,
    /// How each operation's instance was chosen: the candidates and their verdicts
    /// ([`crate::dispatcher::selection`]).
    #[serde(default)]
    pub selection: Vec<crate::dispatcher::selection::Choice>,
}

/// A fault injected during a run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FaultRecord {
    /// When, in ms of mission clock time since the run began.
    pub at_ms: u64,
    /// What was injected.
    pub fault: FaultKind,
    /// The operation it was meant for (name or id, as asked).
    pub operation: String,
    /// The instance that got it; empty if none did.
    pub actor: String,
    /// Why it could not be injected, if it could not.
    #[serde(default)]
    pub error: Option<String>,
}

impl RunReport {
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
            duration_ms: 0,
            final_pose: None,
            collisions: None,
            seed: None,
            inside_goal: None,
            judgement: None,
            refused_commands: None,
            selection: Vec::new(),
            faults: Vec::new(),
            faults_total: 0,
        }
    }

    /// True when the mission succeeded.
    pub fn succeeded(&self) -> bool {
        self.outcome == Outcome::Succeeded
    }

    /// Count a rebind and keep it among the latest [`REPORT_KEEPS`].
    pub fn record_rebind(&mut self, rebind: RebindRecord) {
        self.rebinds_total += 1;
        keep_latest(&mut self.rebinds, rebind);
    }

    /// Count faults and keep them among the latest [`REPORT_KEEPS`].
    pub fn record_faults(&mut self, faults: impl IntoIterator<Item = FaultRecord>) {
        for fault in faults {
            self.faults_total += 1;
            keep_latest(&mut self.faults, fault);
        }
    }
}

/// Append `item`, dropping the oldest so that at most [`REPORT_KEEPS`] remain.
fn keep_latest<T>(list: &mut Vec<T>, item: T) {
    if list.len() >= REPORT_KEEPS {
        let excess = list.len() + 1 - REPORT_KEEPS;
        list.drain(..excess);
    }
    list.push(item);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reports_without_the_robot_fields_still_read() {
        let json = r#"{"mission":"m","outcome":"failed","reason":"r","status":0,"flags":[],
                       "actions":[],"rebinds":[],"duration_ms":5}"#;
        let report: RunReport = serde_json::from_str(json).expect("an older report reads");
        assert_eq!(report.outcome, Outcome::Failed);
        assert_eq!(
            (report.final_pose, report.collisions, report.seed),
            (None, None, None)
        );
        assert_eq!(
            (report.inside_goal, report.judgement.as_deref()),
            (None, None)
        );
        assert_eq!(report.refused_commands, None);
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
            duration_ms: 10,
            final_pose: None,
            collisions: None,
            seed: None,
            inside_goal: None,
            judgement: None,
            refused_commands: None,
            selection: Vec::new(),
            faults: vec![FaultRecord {
                at_ms: 2,
                fault: FaultKind::Hang,
                operation: "op".into(),
                actor: "0.2".into(),
                error: None,
            }],
            faults_total: 1,
        };
        let json: serde_json::Value = serde_json::to_value(&report).expect("writes");
        assert_eq!(json["outcome"], "succeeded");
        assert_eq!(json["actions"][0]["operations"][0]["ended"], "finished");
        assert_eq!(json["faults"][0]["fault"], "hang");
        assert_eq!(json["rebinds"][0]["cause"]["type"], "hung");
        assert_eq!(json["rebinds"][0]["cause"]["deadline_ms"], 300);
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
            error: None,
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
}
