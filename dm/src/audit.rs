//! The check of a run's datamanagers: every record a producer was told was stored, looked
//! up at the end in what the datamanager's leader holds.
//!
//! A [`Ledger`] takes the acknowledgements the producers' nodes publish as they come
//! (`dm_acked`, `dm_deleted`: `acks`) — each record's datamanager, seq, class,
//! source and a digest of its payload. At the end, [`Ledger::check`] asks the datamanager's
//! leader (the instance published under its name; of several, the leader with the newest
//! term) for its retention bounds and every record of the classes acknowledged, and
//! [`Ledger::compare`] sorts each acknowledged record into exactly one of:
//!
//! - **held**: a record at its seq, with its class, source and payload digest;
//! - **dropped by retention**: gone, and the datamanager holds at least its retention bound
//!   of newer records of that class — had it been kept, retention would have dropped it
//!   (a class keeps its newest N), so its absence is no loss;
//! - **deleted**: gone, and a delete of its class (or of any class) in that datamanager was
//!   acknowledged during the run;
//! - **unchecked**: the ledger keeps the latest [`KEEPS`] acknowledgements of each
//!   datamanager and only counts older ones (a run of days stays bounded);
//! - **lost**: anything else — also every acknowledged record of a datamanager that could
//!   not be asked at all.
//!
//! What it cannot see: an acknowledgement whose event never reached the checker (its
//! producer's node killed in the instant between the answer and the event's sending) is not
//! counted as acknowledged. A `put` is no acknowledged record (`acks`).

use super::client::DmClient;
use super::error::DmError;
use super::messages::{DmMsg, DmStats};
use super::query::Query;
use marie_vocabulary::events::EventKind;
use marie_vocabulary::registry::{self, Instance, ModuleKind};
use marie_vocabulary::replica::ReplicaRole;
use marie_vocabulary::run::DmCheck;
use ractor::rpc::CallResult;
use ractor::ActorRef;
use std::collections::{BTreeMap, BTreeSet, HashMap, VecDeque};
use std::sync::Arc;
use std::time::Duration;

/// Acknowledgements a [`Ledger`] keeps per datamanager, the latest (older ones are only
/// counted, as `unchecked`): ~100 bytes each.
pub(crate) const KEEPS: usize = 32_768;

/// The source name the checker's own client reads under.
const CHECKER: &str = "marie-checker";

/// Lost records the check names one by one in the log (the rest are counted).
const SAID: u64 = 3;

/// How long the checker waits for one instance's stats when it looks for the leader.
const ASK: Duration = Duration::from_secs(2);

/// A record a producer was told was stored.
#[derive(Clone, Debug, PartialEq, Eq)]
struct Acked {
    seq: u64,
    class: Arc<str>,
    source: Arc<str>,
    digest: u64,
}

/// What the ledger knows of one datamanager.
#[derive(Debug, Default)]
struct DmLedger {
    /// The latest [`KEEPS`] acknowledgements, in the order heard.
    acked: VecDeque<Acked>,
    /// Acknowledgements heard and no longer kept.
    forgotten: u64,
    /// Classes an acknowledged delete named (`None`: a delete of any class).
    deleted: BTreeSet<Option<String>>,
}

/// The acknowledgements of a run, by datamanager: what a check at its end looks up.
#[derive(Debug, Default)]
pub struct Ledger {
    dms: BTreeMap<String, DmLedger>,
    /// Class and source names, shared by the acknowledgements that carry them.
    names: HashMap<String, Arc<str>>,
}

/// What a datamanager holds of the classes the ledger looks up, as its leader answered.
#[derive(Clone, Debug, Default)]
pub struct Held {
    /// The node of the instance that answered.
    pub node: String,
    /// Its stats (the retention bounds are read from them).
    pub stats: DmStats,
    /// Each record held: seq → (class, source, digest of the payload).
    records: HashMap<u64, (String, String, u64)>,
    /// The seqs held per class, in order.
    by_class: HashMap<String, Vec<u64>>,
}

impl Held {
    /// What `node`'s instance holds, as `stats` and `records` (any order) say.
    pub fn new(
        node: impl Into<String>,
        stats: DmStats,
        records: impl IntoIterator<Item = super::Record>,
    ) -> Held {
        let mut held = Held {
            node: node.into(),
            stats,
            ..Held::default()
        };
        for r in records {
            let class = r.class.to_string();
            held.by_class.entry(class.clone()).or_default().push(r.seq);
            let digest = super::acks::digest(r.payload.as_bytes());
            held.records
                .insert(r.seq, (class, r.source.to_string(), digest));
        }
        for seqs in held.by_class.values_mut() {
            seqs.sort_unstable();
        }
        held
    }

    /// Records of `class` held with a seq above `seq`.
    fn newer_in(&self, class: &str, seq: u64) -> u64 {
        self.by_class.get(class).map_or(0, |seqs| {
            (seqs.len() - seqs.partition_point(|s| *s <= seq)) as u64
        })
    }
}

impl Ledger {
    /// An empty ledger.
    pub fn new() -> Ledger {
        Ledger::default()
    }

    /// Take `kind` into account if it is an acknowledgement (`dm_acked`, `dm_deleted`);
    /// whether it was one.
    pub fn note(&mut self, kind: &EventKind) -> bool {
        match kind {
            EventKind::DmAcked {
                dm,
                source,
                class,
                seq,
                digest,
            } => {
                let acked = Acked {
                    seq: *seq,
                    class: self.name(class),
                    source: self.name(source),
                    digest: *digest,
                };
                let ledger = self.dms.entry(dm.clone()).or_default();
                if ledger.acked.len() >= KEEPS {
                    ledger.acked.pop_front();
                    ledger.forgotten += 1;
                }
                ledger.acked.push_back(acked);
                true
            }
            EventKind::DmDeleted { dm, class, .. } => {
                self.dms
                    .entry(dm.clone())
                    .or_default()
                    .deleted
                    .insert(class.clone());
                true
            }
            _ => false,
        }
    }

    fn name(&mut self, s: &str) -> Arc<str> {
        if let Some(n) = self.names.get(s) {
            return n.clone();
        }
        let n: Arc<str> = Arc::from(s);
        self.names.insert(s.to_string(), n.clone());
        n
    }

    /// The datamanagers acknowledgements were heard of, by name.
    pub fn datamanagers(&self) -> Vec<String> {
        self.dms.keys().cloned().collect()
    }

    /// Acknowledged records heard of in `dm` (kept or forgotten).
    pub fn acknowledged(&self, dm: &str) -> u64 {
        self.dms
            .get(dm)
            .map_or(0, |l| l.acked.len() as u64 + l.forgotten)
    }

    /// The classes of `dm`'s acknowledged records kept.
    fn classes(&self, dm: &str) -> BTreeSet<Arc<str>> {
        self.dms.get(dm).map_or_else(BTreeSet::new, |l| {
            l.acked.iter().map(|a| a.class.clone()).collect()
        })
    }

    /// Sort every acknowledged record of `dm` by what `held` — its leader's answer —
    /// says of it (see the module docs).
    pub fn compare(&self, dm: &str, held: &Held) -> DmCheck {
        let mut check = DmCheck {
            dm: dm.to_string(),
            node: Some(held.node.clone()),
            ..DmCheck::default()
        };
        let Some(ledger) = self.dms.get(dm) else {
            return check;
        };
        check.acknowledged = self.acknowledged(dm);
        check.unchecked = ledger.forgotten;
        let any_deleted = ledger.deleted.contains(&None);
        for a in &ledger.acked {
            let here = held.records.get(&a.seq);
            if here.is_some_and(|(class, source, digest)| {
                **class == *a.class && **source == *a.source && *digest == a.digest
            }) {
                check.held += 1;
            } else if any_deleted || ledger.deleted.contains(&Some(a.class.to_string())) {
                check.deleted += 1;
            } else if held
                .stats
                .retention_of(&a.class)
                .is_some_and(|bound| held.newer_in(&a.class, a.seq) >= bound)
            {
                check.dropped_by_retention += 1;
            } else {
                check.lost += 1;
                // the first few by name; the count says the rest
                if check.lost <= SAID {
                    let now = match here {
                        Some((class, source, _)) => format!("holds {class} of {source} now"),
                        None => "holds no record now".to_string(),
                    };
                    tracing::warn!(
                        dm,
                        seq = a.seq,
                        "acknowledged record lost: {} of {} was acknowledged at this seq, \
                         which {now}",
                        a.class,
                        a.source
                    );
                }
            }
        }
        check
    }

    /// Check `dm`: ask its leader what it holds — waiting at most `within` for one to
    /// answer (a datamanager being failed over at the end of a run elects one within a
    /// few seconds) — and [compare](Ledger::compare). A datamanager that cannot be asked
    /// has every acknowledged record counted lost, and why in `error`.
    pub async fn check(&self, dm: &str, within: Duration) -> DmCheck {
        let classes = self.classes(dm);
        let deadline = tokio::time::Instant::now() + within;
        let last = loop {
            let why = match held_by(dm, &classes, deadline).await {
                Ok(held) => return self.compare(dm, &held),
                Err(e) => e,
            };
            if tokio::time::Instant::now() >= deadline {
                break why;
            }
            tokio::time::sleep(Duration::from_millis(200)).await;
        };
        let acknowledged = self.acknowledged(dm);
        DmCheck {
            dm: dm.to_string(),
            node: None,
            acknowledged,
            lost: acknowledged,
            error: Some(last.to_string()),
            ..DmCheck::default()
        }
    }
}

/// Why a datamanager could not be asked what it holds (the check's `error`).
#[derive(Debug, thiserror::Error)]
enum CheckError {
    /// None was found under its name in time.
    #[error("{0}")]
    Lookup(DmError),
    /// The one found did not answer a select.
    #[error("{dm} on {node}: {error}")]
    Select {
        dm: String,
        node: String,
        error: DmError,
    },
    /// None is published under its name.
    #[error("no instance of datamanager `{0}` is published")]
    NonePublished(String),
    /// The last one asked did not answer its stats in time.
    #[error("`{dm}` on {node} did not answer within {:?}", ASK)]
    NoAnswer { dm: String, node: String },
}

/// What `dm`'s leader holds of `classes`.
async fn held_by(
    dm: &str,
    classes: &BTreeSet<Arc<str>>,
    deadline: tokio::time::Instant,
) -> Result<Held, CheckError> {
    let left = deadline.saturating_duration_since(tokio::time::Instant::now());
    if registry::lookup(ModuleKind::Datamanager, dm).is_empty() {
        // none published now: one may be on its way (a leader being elected)
        DmClient::lookup_within(dm, CHECKER, left)
            .await
            .map_err(CheckError::Lookup)?;
    }
    let (instance, stats) = leader(dm).await?;
    let client = DmClient::from_instance(&instance, CHECKER)
        .with_follow(Duration::ZERO)
        .with_timeout(left.max(ASK));
    let mut records = Vec::new();
    for class in classes {
        let got = client
            .select(Query::class(&**class))
            .await
            .map_err(|error| CheckError::Select {
                dm: dm.to_string(),
                node: instance.node.clone(),
                error,
            })?;
        records.extend(got);
    }
    Ok(Held::new(instance.node, stats, records))
}

/// The instance of `dm` to ask, and its stats: of those published under its name that
/// answer, the leader with the newest term (an old leader cut off may still be published
/// for a moment beside the new one); without replicas, the first that answers.
async fn leader(dm: &str) -> Result<(Instance, DmStats), CheckError> {
    let mut best: Option<(Instance, DmStats)> = None;
    let mut why = CheckError::NonePublished(dm.to_string());
    for instance in registry::lookup(ModuleKind::Datamanager, dm) {
        let actor: ActorRef<DmMsg> = instance.actor.clone().into();
        let stats = match actor.call(|reply| DmMsg::Stats { reply }, Some(ASK)).await {
            Ok(CallResult::Success(stats)) => stats,
            Ok(_) | Err(_) => {
                why = CheckError::NoAnswer {
                    dm: dm.to_string(),
                    node: instance.node.clone(),
                };
                continue;
            }
        };
        let term = |s: &DmStats| {
            s.replica
                .as_ref()
                .map(|r| (r.role == ReplicaRole::Leader, r.term))
        };
        if best.as_ref().is_none_or(|(_, b)| term(&stats) > term(b)) {
            best = Some((instance, stats));
        }
    }
    best.ok_or(why)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Payload, Record};

    fn acked(dm: &str, class: &str, source: &str, seq: u64, payload: &[u8]) -> EventKind {
        EventKind::DmAcked {
            dm: dm.into(),
            source: source.into(),
            class: class.into(),
            seq,
            digest: crate::acks::digest(payload),
        }
    }

    fn record(seq: u64, class: &str, source: &str, payload: &[u8]) -> Record {
        Record {
            seq,
            timestamp: Duration::ZERO,
            source: source.into(),
            class: class.into(),
            sub1: None,
            sub2: None,
            payload: Payload::from_bytes(payload.to_vec()),
        }
    }

    fn stats(retention: u64) -> DmStats {
        DmStats {
            retention: Some(retention),
            ..DmStats::default()
        }
    }

    #[test]
    fn every_acknowledged_record_is_held_or_counted_lost() {
        let mut ledger = Ledger::new();
        for (seq, payload) in [(1, b"a"), (2, b"b"), (3, b"c"), (4, b"d")] {
            assert!(ledger.note(&acked("world", "wall", "sensor", seq, payload)));
        }
        assert!(!ledger.note(&EventKind::NodeFrozen { silent_ms: 1 }));
        // 1 held; 2 gone; 3 at its seq but another record (a new leader reused the seq);
        // 4 at its seq but from another source
        let held = Held::new(
            "features",
            stats(100),
            [
                record(1, "wall", "sensor", b"a"),
                record(3, "wall", "sensor", b"x"),
                record(4, "wall", "planner", b"d"),
            ],
        );
        let check = ledger.compare("world", &held);
        assert_eq!(
            (check.acknowledged, check.held, check.lost),
            (4, 1, 3),
            "{check:?}"
        );
        assert_eq!(check.node.as_deref(), Some("features"));
        // a datamanager the run heard nothing of is checked with nothing to find
        let none = ledger.compare("feature", &held);
        assert_eq!((none.acknowledged, none.lost), (0, 0));
    }

    #[test]
    fn what_retention_would_have_dropped_anyway_is_no_loss() {
        let mut ledger = Ledger::new();
        for seq in 1..=5 {
            ledger.note(&acked("world", "pose", "localizer", seq, &[seq as u8]));
        }
        // bound 3: the newest three of the class are held, the two older ones dropped
        let held = Held::new(
            "operations",
            stats(3),
            (3..=5).map(|s| record(s, "pose", "localizer", &[s as u8])),
        );
        let check = ledger.compare("world", &held);
        assert_eq!(
            (check.held, check.dropped_by_retention, check.lost),
            (3, 2, 0)
        );
        // held only two newer (the third gone): the oldest is lost, not dropped — a class
        // under its bound drops nothing
        let held = Held::new(
            "operations",
            stats(3),
            (4..=5).map(|s| record(s, "pose", "localizer", &[s as u8])),
        );
        let check = ledger.compare("world", &held);
        assert_eq!(
            (check.held, check.dropped_by_retention, check.lost),
            (2, 0, 3)
        );
        // a class's own bound wins over the default
        let mut by_class = stats(100);
        by_class.retention_by_class.insert("pose".into(), 2);
        let held = Held::new(
            "operations",
            by_class,
            (4..=5).map(|s| record(s, "pose", "localizer", &[s as u8])),
        );
        let check = ledger.compare("world", &held);
        assert_eq!(
            (check.held, check.dropped_by_retention, check.lost),
            (2, 3, 0)
        );
        // a datamanager that does not say its bounds gets no benefit of the doubt
        let held = Held::new(
            "operations",
            DmStats::default(),
            (4..=5).map(|s| record(s, "pose", "localizer", &[s as u8])),
        );
        assert_eq!(ledger.compare("world", &held).lost, 3);
    }

    #[test]
    fn records_an_acknowledged_delete_may_have_removed_are_deleted_not_lost() {
        let mut ledger = Ledger::new();
        ledger.note(&acked("parameter", "path", "planner", 1, b"p"));
        ledger.note(&acked("parameter", "progress", "controller", 2, b"q"));
        ledger.note(&EventKind::DmDeleted {
            dm: "parameter".into(),
            source: "planner".into(),
            class: Some("path".into()),
            deleted: 1,
        });
        let held = Held::new("operations", stats(100), []);
        let check = ledger.compare("parameter", &held);
        assert_eq!((check.deleted, check.lost), (1, 1), "{check:?}");
        // a delete of any class covers every class
        ledger.note(&EventKind::DmDeleted {
            dm: "parameter".into(),
            source: "planner".into(),
            class: None,
            deleted: 1,
        });
        assert_eq!(ledger.compare("parameter", &held).deleted, 2);
    }

    #[test]
    fn the_ledger_keeps_the_latest_and_counts_the_rest_unchecked() {
        let mut ledger = Ledger::new();
        for seq in 1..=(KEEPS as u64 + 10) {
            ledger.note(&acked("world", "wall", "sensor", seq, b"w"));
        }
        let held = Held::new(
            "operations",
            stats(u64::MAX),
            (11..=KEEPS as u64 + 10).map(|s| record(s, "wall", "sensor", b"w")),
        );
        let check = ledger.compare("world", &held);
        assert_eq!(check.acknowledged, KEEPS as u64 + 10);
        assert_eq!(
            (check.held, check.unchecked, check.lost),
            (KEEPS as u64, 10, 0)
        );
    }

    #[tokio::test]
    async fn a_datamanager_nobody_publishes_has_every_acknowledged_record_lost() {
        let mut ledger = Ledger::new();
        ledger.note(&acked("audit-nobody", "wall", "sensor", 1, b"w"));
        let check = ledger
            .check("audit-nobody", Duration::from_millis(50))
            .await;
        assert_eq!((check.acknowledged, check.lost), (1, 1));
        assert!(check.node.is_none());
        assert!(check.error.unwrap().contains("audit-nobody"));
    }
}
