//! How a run and each operation's part in an action end.

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

impl fmt::Display for Outcome {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Outcome::Succeeded => "succeeded",
            Outcome::Failed => "failed",
        })
    }
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
