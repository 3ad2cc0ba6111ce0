//! A rebind: a binding's lost instance replaced by a stand-in, as the run records it.

use super::LossCause;
use serde::{Deserialize, Serialize};

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
