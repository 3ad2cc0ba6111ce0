//! The run report (DESIGN.md §8): what happened during a mission, as JSON.

use super::loss::LossCause;
use crate::eo::FaultKind;
use serde::{Deserialize, Serialize};
use std::fmt;

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
    /// Time without a bound instance.
    pub downtime_ms: u64,
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
    /// Rebindings during the run.
    pub rebinds: Vec<RebindRecord>,
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
    /// Faults injected on purpose during the run (fault-injection tests, `--fault`,
    /// `--chaos`).
    #[serde(default)]
    pub faults: Vec<FaultRecord>,
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
    /// True when the mission succeeded.
    pub fn succeeded(&self) -> bool {
        self.outcome == Outcome::Succeeded
    }
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
                operation: "op".into(),
                cause: LossCause::Hung { deadline_ms: 300 },
                from: "0.2".into(),
                to: "0.3".into(),
                downtime_ms: 4,
            }],
            duration_ms: 10,
            final_pose: None,
            collisions: None,
            seed: None,
            inside_goal: None,
            judgement: None,
            faults: vec![FaultRecord {
                at_ms: 2,
                fault: FaultKind::Hang,
                operation: "op".into(),
                actor: "0.2".into(),
                error: None,
            }],
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
}
