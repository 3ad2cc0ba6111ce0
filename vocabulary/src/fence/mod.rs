//! Fencing tokens: the commands an operation sends carry its binding's epoch, and whoever
//! obeys them — a datamanager, a robot's drivers — refuses an epoch older than the newest it
//! has seen for that operation.
//!
//! Why: a node that froze or was cut off is declared down and its operations are replaced by
//! instances elsewhere, under a higher epoch (the dispatcher raises the epoch on every
//! rebind, and starts every run above the previous ones). When the old node wakes up or the
//! partition heals, its operations do not know they were replaced and carry on; the first
//! command of the stand-in has already told the receivers the new epoch, so every command of
//! the old incarnation is refused and changes nothing. Epoch 0 is unfenced: commands from
//! outside any activation (an embedder's own code, a robot's a-priori records).
//!
//! The fence is per operation *name*: one binding drives an operation at a time.
//!
//! A receiver learns an epoch from two sides: the commands themselves, and the dispatcher,
//! which *announces* every epoch it binds to the receivers that keep a [`FenceKeeper`] before any
//! command carries it — so no command of a replaced incarnation is obeyed in the moment
//! between a rebind and its stand-in's first command. What a receiver obeyed, by epoch and
//! when ([`ObeyedLog`]), is checked against when each epoch was bound ([`obeyed_late`]).
//!
//! ```
//! use marie_vocabulary::fence::{Fence, FenceTable};
//! let mut cart = FenceTable::default();
//! assert!(cart.admit(&Fence::new("wall-follower", 7)).is_ok()); // the stand-in
//! let stale = cart.admit(&Fence::new("wall-follower", 6)).unwrap_err(); // the woken original
//! assert_eq!((stale.got, stale.current), (6, 7));
//! assert_eq!(cart.refused(), 1);
//! assert_eq!(cart.refused_by()["wall-follower"], 1);
//! ```

mod keeper;
mod obeyed;

pub use keeper::{
    announce, spawn_keeper, Announced, FenceKeeper, FenceMsg, ANNOUNCE_TIMEOUT, GROUP, SCOPE,
};
pub use obeyed::{obeyed_late, BoundEpoch, Late, Obeyed, ObeyedLog};

use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, HashMap};

/// Who sends a command, and under which epoch.
#[derive(Clone, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Fence {
    /// The operation's name.
    pub operation: String,
    /// Its binding's epoch (0: unfenced).
    pub epoch: u64,
}

impl Fence {
    /// `operation` at `epoch`.
    pub fn new(operation: impl Into<String>, epoch: u64) -> Fence {
        Fence {
            operation: operation.into(),
            epoch,
        }
    }
}

/// A command refused: an older epoch of its operation than one already seen.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error, Serialize, Deserialize)]
#[error("operation `{operation}` at epoch {got} is fenced off: epoch {current} has replaced it")]
pub struct Stale {
    /// The operation.
    pub operation: String,
    /// The command's epoch.
    pub got: u64,
    /// The newest epoch seen for the operation.
    pub current: u64,
}

/// The newest epoch seen per operation, and how many commands were refused.
#[derive(Clone, Debug, Default)]
pub struct FenceTable {
    newest: HashMap<String, u64>,
    refused_by: BTreeMap<String, u64>,
}

impl FenceTable {
    /// Admit a command of `fence`: epoch 0, or at least the newest seen for its operation
    /// (then the newest), is admitted; an older one is refused and counted.
    pub fn admit(&mut self, fence: &Fence) -> Result<(), Stale> {
        self.admit_parts(&fence.operation, fence.epoch)
    }

    /// [`FenceTable::admit`] for an operation name and an epoch held apart (a record's
    /// source and epoch).
    pub fn admit_parts(&mut self, operation: &str, epoch: u64) -> Result<(), Stale> {
        if epoch == 0 {
            return Ok(());
        }
        match self.newest.get_mut(operation) {
            Some(newest) if epoch < *newest => {
                *self.refused_by.entry(operation.to_string()).or_default() += 1;
                Err(Stale {
                    operation: operation.to_string(),
                    got: epoch,
                    current: *newest,
                })
            }
            Some(newest) => {
                *newest = epoch;
                Ok(())
            }
            None => {
                self.newest.insert(operation.to_string(), epoch);
                Ok(())
            }
        }
    }

    /// Raise `fence.operation`'s newest epoch to `fence.epoch` (a dispatcher announced it,
    /// [`announce`]); an older or unfenced one changes nothing and is not counted as refused.
    pub fn advance(&mut self, fence: &Fence) {
        if fence.epoch == 0 {
            return;
        }
        let newest = self.newest.entry(fence.operation.clone()).or_default();
        *newest = (*newest).max(fence.epoch);
    }

    /// The newest epoch seen for `operation`, if any.
    pub fn newest(&self, operation: &str) -> Option<u64> {
        self.newest.get(operation).copied()
    }

    /// Commands refused so far.
    pub fn refused(&self) -> u64 {
        self.refused_by.values().sum()
    }

    /// Commands refused so far, by operation (only those with at least one).
    pub fn refused_by(&self) -> &BTreeMap<String, u64> {
        &self.refused_by
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_newest_epoch_of_each_operation_holds_it() {
        let mut t = FenceTable::default();
        assert!(t.admit(&Fence::new("a", 5)).is_ok());
        assert!(t.admit(&Fence::new("a", 5)).is_ok(), "the same epoch again");
        assert!(t.admit(&Fence::new("b", 1)).is_ok(), "another operation");
        assert!(t.admit(&Fence::new("a", 4)).is_err());
        assert!(t.admit(&Fence::new("a", 9)).is_ok());
        assert_eq!(
            t.admit(&Fence::new("a", 5)),
            Err(Stale {
                operation: "a".into(),
                got: 5,
                current: 9
            })
        );
        assert_eq!(t.refused(), 2);
        assert_eq!(
            t.refused_by().iter().collect::<Vec<_>>(),
            [(&"a".to_string(), &2)]
        );
    }

    #[test]
    fn an_announced_epoch_fences_before_any_command_carries_it() {
        let mut t = FenceTable::default();
        t.admit(&Fence::new("a", 3)).unwrap();
        t.advance(&Fence::new("a", 5));
        assert!(
            t.admit(&Fence::new("a", 3)).is_err(),
            "the replaced incarnation"
        );
        assert!(
            t.admit(&Fence::new("a", 5)).is_ok(),
            "the announced stand-in"
        );
        t.advance(&Fence::new("a", 4));
        t.advance(&Fence::new("a", 0));
        assert_eq!(
            t.newest("a"),
            Some(5),
            "an announcement never lowers a fence"
        );
        assert_eq!(t.refused(), 1, "an announcement is no refused command");
    }

    #[test]
    fn epoch_zero_is_unfenced() {
        let mut t = FenceTable::default();
        t.admit(&Fence::new("a", 3)).unwrap();
        assert!(t.admit(&Fence::new("a", 0)).is_ok());
        assert_eq!(t.refused(), 0);
        assert!(t.refused_by().is_empty());
    }
}
