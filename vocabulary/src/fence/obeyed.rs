//! What a receiver obeyed, by operation and epoch — and the check that none of it came
//! from an epoch already replaced.
//!
//! Why: a receiver's [`FenceTable`](super::FenceTable) counts the commands it refuses, but
//! a command it *obeyed* from a replaced incarnation leaves no trace there — that is the
//! very case a fence exists to prevent, so it must be observable from outside the fence. A
//! receiver keeps an [`ObeyedLog`] (per operation and epoch: how many commands, the first
//! and the last one's clock time); the run's report keeps when the dispatcher bound each
//! epoch ([`BoundEpoch`], from its `bound` and `rebound` events); [`obeyed_late`] says which
//! epochs were obeyed after a newer one of their operation had been bound.
//!
//! Both sides read the same clock: a node's clock, which every node of a cluster reads
//! alike (wall-clock time × the cluster's speed, [`crate::clock::ScaledClock::cluster`]).
//!
//! ```
//! use marie_vocabulary::fence::{obeyed_late, BoundEpoch, Fence, ObeyedLog};
//! use std::time::Duration;
//! let mut cart = ObeyedLog::default();
//! cart.record(&Fence::new("wall-follower", 7), Duration::from_millis(1_000));
//! cart.record(&Fence::new("wall-follower", 7), Duration::from_millis(2_500)); // late
//! cart.record(&Fence::new("wall-follower", 8), Duration::from_millis(2_600));
//! let bound = [
//!     BoundEpoch { operation: "wall-follower".into(), epoch: 7, clock_ms: 900 },
//!     BoundEpoch { operation: "wall-follower".into(), epoch: 8, clock_ms: 2_000 },
//! ];
//! let late = obeyed_late(&bound, &cart.entries());
//! assert_eq!(late.len(), 1);
//! assert_eq!((late[0].epoch, late[0].late_ms()), (7, 500));
//! ```

use super::Fence;
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, VecDeque};
use std::time::Duration;

/// The commands a receiver obeyed from one epoch of one operation.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Obeyed {
    /// The operation.
    pub operation: String,
    /// The epoch its commands carried.
    pub epoch: u64,
    /// How many were obeyed.
    pub commands: u64,
    /// The first one's time, on the receiver's node clock, ms.
    pub first_clock_ms: u64,
    /// The last one's, likewise.
    pub last_clock_ms: u64,
}

/// What a receiver obeyed: the latest [`ObeyedLog::KEEPS`] epochs of each operation
/// (a robot on duty for days rebinds without end; memory stays bounded).
#[derive(Clone, Debug, Default)]
pub struct ObeyedLog {
    by_operation: BTreeMap<String, VecDeque<Obeyed>>,
}

impl ObeyedLog {
    /// How many epochs of one operation the log keeps (the latest).
    pub const KEEPS: usize = 32;

    /// Record a command obeyed under `fence` at clock time `at`. Unfenced commands
    /// (epoch 0) are not recorded: nothing can replace them.
    pub fn record(&mut self, fence: &Fence, at: Duration) {
        if fence.epoch == 0 {
            return;
        }
        let ms = at.as_millis() as u64;
        // looked up before `entry`: no name cloned per command, only per new operation
        let epochs = match self.by_operation.get_mut(&fence.operation) {
            Some(epochs) => epochs,
            None => self
                .by_operation
                .entry(fence.operation.clone())
                .or_default(),
        };
        // a fence admits an operation's epochs in rising order: only the newest, last, can
        // be this one
        if let Some(o) = epochs.back_mut().filter(|o| o.epoch == fence.epoch) {
            o.commands += 1;
            o.last_clock_ms = o.last_clock_ms.max(ms);
            return;
        }
        if epochs.len() >= Self::KEEPS {
            epochs.pop_front();
        }
        epochs.push_back(Obeyed {
            operation: fence.operation.clone(),
            epoch: fence.epoch,
            commands: 1,
            first_clock_ms: ms,
            last_clock_ms: ms,
        });
    }

    /// Every entry, by operation, then epoch as recorded.
    pub fn entries(&self) -> Vec<Obeyed> {
        self.by_operation.values().flatten().cloned().collect()
    }

    /// Forget everything (the receiver starts anew, e.g. between the runs of a cluster
    /// kept up).
    pub fn clear(&mut self) {
        self.by_operation.clear();
    }
}

/// When the dispatcher bound an operation at an epoch (a run's start, a takeover, a
/// rebind), on its node's clock — after it had announced the epoch to the fence keepers
/// ([`super::announce`]) and before any command carried it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct BoundEpoch {
    /// The operation.
    pub operation: String,
    /// The binding's new epoch.
    pub epoch: u64,
    /// When, on the dispatcher's node clock, ms (the `bound` or `rebound` event's `at_ms`).
    pub clock_ms: u64,
}

/// An epoch obeyed after a newer one of its operation was bound: at least one command of
/// a replaced incarnation obeyed.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Late {
    /// The operation.
    pub operation: String,
    /// The replaced epoch.
    pub epoch: u64,
    /// The first epoch bound above it.
    pub replaced_by: u64,
    /// When that was bound, clock ms.
    pub replaced_clock_ms: u64,
    /// The last command of the replaced epoch obeyed, clock ms (later than the above).
    pub last_clock_ms: u64,
}

impl Late {
    /// How long after its replacement the replaced epoch was still obeyed, ms.
    pub fn late_ms(&self) -> u64 {
        self.last_clock_ms.saturating_sub(self.replaced_clock_ms)
    }
}

impl std::fmt::Display for Late {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "`{}` obeyed at epoch {} until {} ms after epoch {} replaced it",
            self.operation,
            self.epoch,
            self.late_ms(),
            self.replaced_by
        )
    }
}

/// The epochs of `obeyed` whose last command came after a newer epoch of their operation
/// was bound (the earliest such binding in `bound`), in `obeyed`'s order. An epoch no
/// binding of `bound` replaced (the newest, or one older than what `bound` covers) is
/// never late.
pub fn obeyed_late(bound: &[BoundEpoch], obeyed: &[Obeyed]) -> Vec<Late> {
    obeyed
        .iter()
        .filter_map(|o| {
            let replacing = bound
                .iter()
                .filter(|b| b.operation == o.operation && b.epoch > o.epoch)
                .min_by_key(|b| b.clock_ms)?;
            (o.last_clock_ms > replacing.clock_ms).then(|| Late {
                operation: o.operation.clone(),
                epoch: o.epoch,
                replaced_by: replacing.epoch,
                replaced_clock_ms: replacing.clock_ms,
                last_clock_ms: o.last_clock_ms,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(ms: u64) -> Duration {
        Duration::from_millis(ms)
    }

    fn bound(operation: &str, epoch: u64, clock_ms: u64) -> BoundEpoch {
        BoundEpoch {
            operation: operation.into(),
            epoch,
            clock_ms,
        }
    }

    #[test]
    fn the_log_counts_each_epoch_from_its_first_to_its_last_command() {
        let mut log = ObeyedLog::default();
        log.record(&Fence::new("a", 3), at(10));
        log.record(&Fence::new("a", 3), at(30));
        log.record(&Fence::new("b", 1), at(20));
        log.record(&Fence::new("a", 5), at(40));
        log.record(&Fence::new("a", 0), at(50));
        let e = log.entries();
        assert_eq!(e.len(), 3, "{e:?}");
        assert_eq!(
            (
                e[0].epoch,
                e[0].commands,
                e[0].first_clock_ms,
                e[0].last_clock_ms
            ),
            (3, 2, 10, 30)
        );
        assert_eq!((e[1].epoch, e[1].commands), (5, 1));
        assert_eq!(e[2].operation, "b");
        log.clear();
        assert!(log.entries().is_empty());
    }

    #[test]
    fn the_log_keeps_only_the_latest_epochs_of_an_operation() {
        let mut log = ObeyedLog::default();
        for epoch in 1..=(ObeyedLog::KEEPS as u64 + 10) {
            log.record(&Fence::new("a", epoch), at(epoch));
        }
        let e = log.entries();
        assert_eq!(e.len(), ObeyedLog::KEEPS);
        assert_eq!(e[0].epoch, 11);
    }

    #[test]
    fn an_epoch_obeyed_after_its_replacement_was_bound_is_late_and_one_before_is_not() {
        let bound = [bound("a", 3, 0), bound("a", 5, 100), bound("a", 6, 300)];
        let obeyed = [
            Obeyed {
                operation: "a".into(),
                epoch: 3,
                commands: 9,
                first_clock_ms: 0,
                last_clock_ms: 100, // at the very moment: not after
            },
            Obeyed {
                operation: "a".into(),
                epoch: 5,
                commands: 4,
                first_clock_ms: 120,
                last_clock_ms: 320,
            },
            Obeyed {
                operation: "a".into(),
                epoch: 6,
                commands: 1,
                first_clock_ms: 330,
                last_clock_ms: 900, // the newest: nothing replaced it
            },
            Obeyed {
                operation: "b".into(),
                epoch: 1,
                commands: 1,
                first_clock_ms: 500,
                last_clock_ms: 500, // no binding of `b` known: never late
            },
        ];
        let late = obeyed_late(&bound, &obeyed);
        assert_eq!(
            late,
            [Late {
                operation: "a".into(),
                epoch: 5,
                replaced_by: 6,
                replaced_clock_ms: 300,
                last_clock_ms: 320,
            }]
        );
        assert_eq!(late[0].late_ms(), 20);
        assert!(late[0].to_string().contains("until 20 ms after epoch 6"));
    }

    #[test]
    fn the_earliest_replacement_counts_whatever_the_order_of_the_bindings() {
        // a takeover's `bound` can be folded after a rebind of the dispatcher it replaced
        let bound = [bound("a", 9, 500), bound("a", 7, 200)];
        let obeyed = [Obeyed {
            operation: "a".into(),
            epoch: 6,
            commands: 1,
            first_clock_ms: 100,
            last_clock_ms: 300,
        }];
        let late = obeyed_late(&bound, &obeyed);
        assert_eq!((late[0].replaced_by, late[0].replaced_clock_ms), (7, 200));
    }
}
