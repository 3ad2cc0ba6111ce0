//! What the check of a run's datamanagers found: of the records the run's producers were
//! told were stored, and of those the datamanagers told they applied from puts, how many
//! the datamanager still holds at the end, and how many it lost.

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
    /// Records stored by `put`s — no producer is answered for those — that the
    /// datamanager told it applied (`dm_applied`). Sorted as the acknowledged ones are;
    /// `applied_lost` counts those neither held nor explained (retention, a delete).
    #[serde(skip_serializing_if = "is_zero")]
    pub applied: u64,
    /// Of `applied`, neither held nor explained: put records lost.
    #[serde(skip_serializing_if = "is_zero")]
    pub applied_lost: u64,
    /// Why records were lost, when the run's events say (e.g. `the feature datamanager
    /// restarted empty`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub why: Option<String>,
}

fn is_zero(n: &u64) -> bool {
    *n == 0
}

/// Records of one class a datamanager applied from puts, told together (`dm_applied`): how
/// many, the seqs they lie between, and the sum of their fingerprints — so that a check can
/// tell that the records it finds in that range are the same ones, not others stored at the
/// same seqs by a datamanager that started over.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default)]
pub struct AppliedSpan {
    /// Their class.
    pub class: String,
    /// The first one's seq.
    pub from: u64,
    /// The last one's seq.
    pub to: u64,
    /// How many (the class's records between `from` and `to`).
    pub records: u64,
    /// The wrapping sum of each record's fingerprint (its seq, source and payload: see
    /// `marie_dm`'s audit).
    pub digest: u64,
}
