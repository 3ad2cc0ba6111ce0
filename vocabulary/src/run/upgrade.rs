//! An upgrade: a binding moved to a newer compatible version of its operation at an
//! action's start, as the run records it.

use serde::{Deserialize, Serialize};

/// A binding moved from its instance to one of a newer compatible version (the dispatcher's
/// `upgrade` decision): told when the first action that uses the operation after the newer
/// instance appeared starts, before that action's commands go out.
///
/// The times let a bench measure the gap between the two instances: the old instance's
/// last report (`from_last_ms`, when its previous action's part ended) and the new one's
/// first command (`run_ms`, the activation that follows this record at once).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct UpgradeRecord {
    /// Operation name.
    pub operation: String,
    /// The action whose start moved the binding.
    pub action: String,
    /// The old instance's address.
    pub from: String,
    /// Its version.
    pub from_version: String,
    /// Its node.
    pub from_node: String,
    /// The new instance's address.
    pub to: String,
    /// Its version.
    pub to_version: String,
    /// Its node.
    pub to_node: String,
    /// The binding's epoch from the move on (the new instance's commands carry it).
    pub epoch: u64,
    /// When the binding moved, in ms since the run began: the new instance's first command
    /// (the action's activation) goes out at this time.
    pub run_ms: u64,
    /// When the old instance last reported to the dispatcher, in ms since the run began
    /// (`None`: it never reported in this run).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub from_last_ms: Option<u64>,
}

/// A binding moved back from the instance an upgrade took it to, because that instance failed
/// its first activation (an error reply, its actor gone, or no answer within its declared
/// deadline): the old instance still lived, its parameters were restored and the action
/// started again on it. The newer instance is not taken to again in the run.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct RollbackRecord {
    /// Operation name.
    pub operation: String,
    /// The action whose first activation on the newer instance failed, started again on the
    /// old one.
    pub action: String,
    /// The newer instance's address (the one given up).
    pub from: String,
    /// Its version.
    pub from_version: String,
    /// Its node.
    pub from_node: String,
    /// The old instance's address (the binding's again).
    pub to: String,
    /// Its version.
    pub to_version: String,
    /// Its node.
    pub to_node: String,
    /// Why the first activation failed.
    pub reason: String,
    /// The binding's epoch from the rollback on (above the move's).
    pub epoch: u64,
    /// When the binding moved back, in ms since the run began.
    pub run_ms: u64,
}
