//! What the check of a run's datamanagers found: of the records the run's producers were
//! told were stored, how many the datamanager still holds at the end, and how many it lost.

use serde::{Deserialize, Serialize};

/// The check of one datamanager at the end of a run (`dm_checked` event, the report's
/// `dm_checks`): every record a producer of the run was told was stored — a `store`
/// answered with the record's seq — looked up in what the datamanager's leader holds at
/// the end. Each such record is counted once, in one of `held`, `dropped_by_retention`,
/// `deleted`, `unchecked` or `lost`, which add up to `acknowledged`.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default)]
pub struct DmCheck {
    /// The datamanager's name.
    pub dm: String,
    /// The node of the instance that was asked (a replicated datamanager's leader); `None`
    /// when none could be asked (see `error`).
    pub node: Option<String>,
    /// Records the run heard acknowledged: stores answered with a seq, as the producers'
    /// nodes told them on the event stream (`dm_acked`).
    pub acknowledged: u64,
    /// Of those, held at the end at the seq they were acknowledged with, with the same
    /// class, source and content.
    pub held: u64,
    /// Of those, gone where the datamanager holds at least its retention bound of newer
    /// records of the same class: retention would have dropped them had they been kept.
    pub dropped_by_retention: u64,
    /// Of those, gone where an acknowledged delete of the run may have removed them (a
    /// delete of their class, or of every class, in that datamanager).
    pub deleted: u64,
    /// Of those, not looked up: the checker keeps a bounded number of acknowledgements per
    /// datamanager, the latest, and forgot these older ones.
    pub unchecked: u64,
    /// Of those, neither held nor explained: acknowledged records lost. When the
    /// datamanager could not be asked at all, every acknowledged record counts here.
    pub lost: u64,
    /// Why the datamanager could not be asked, if it could not.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}
