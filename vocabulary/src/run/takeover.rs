//! A dispatcher's run taken over by a standby, as the run records it.

use serde::{Deserialize, Serialize};

/// A standby dispatcher took the run over from one whose node was lost (`takeover` event):
/// the run went on from the lost one's last checkpoint under a higher term.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct TakeoverRecord {
    /// Mission time of the takeover, ms since the run began.
    pub at_ms: u64,
    /// The node of the dispatcher that was lost.
    pub from: String,
    /// The node of the dispatcher that carries the run on.
    pub to: String,
    /// The new dispatcher's term: a checkpoint or an adoption of an older term is refused.
    pub term: u64,
    /// Real ms from the standby learning of the loss to its term stored (the run claimed;
    /// its first command follows once it has bound the operations).
    pub gap_ms: u64,
}
