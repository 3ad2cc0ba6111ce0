//! The run report (DESIGN.md §8): what happened during a mission, as JSON.

use serde::{Deserialize, Serialize};

/// How a mission ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Outcome {
    /// Every action ran and the success flags are set.
    Succeeded,
    /// Full stop: a stage failed, a deadline passed, or no action could run.
    Failed,
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
    /// `finished`, `suspended`, `failed` or `lost`.
    pub ended: String,
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
    pub cause: String,
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
    /// `kill`, `panic` or `hang`.
    pub fault: String,
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
}
