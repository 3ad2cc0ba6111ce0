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
//! A `put` is no acknowledged record (`acks`), but the datamanager tells what its puts
//! applied (`dm_applied`, a span per class: `applied`), and each span is sorted the same
//! way, as a whole: **held** when the records of its class the datamanager holds in the
//! span's seqs are as many as it applied and their fingerprints add up to the span's — the
//! same records, not others a datamanager that started over stored at the same seqs;
//! **deleted** or **dropped by retention** under the same rules as above (retention: at
//! least the bound of newer records held than the span's first seq); **lost** otherwise
//! (`applied_lost`). When records are lost, the check says why if the run's events do: a
//! datamanager that restarted during the run (`child_restarted`) and started with nothing
//! — no journal read back, nothing inherited — "restarted empty".
//!
//! What it cannot see: an acknowledgement whose event never reached the checker (its
//! producer's node killed in the instant between the answer and the event's sending) is not
//! counted as acknowledged; puts applied in the last moments before a crash that were never
//! told (`applied`), and puts to a replicated datamanager, are not counted as applied.

use super::applied;
use super::client::DmClient;
use super::error::DmError;
use super::messages::{DmMsg, DmStats};
use super::query::Query;
use marie_vocabulary::events::EventKind;
use marie_vocabulary::registry::{self, Instance, ModuleKind};
use marie_vocabulary::replica::ReplicaRole;
use marie_vocabulary::run::{AppliedSpan, DmCheck};
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
    /// The latest [`KEEPS`] spans of records its puts applied, in the order heard.
    applied: VecDeque<AppliedSpan>,
}

/// The acknowledgements of a run, by datamanager: what a check at its end looks up.
#[derive(Debug, Default)]
pub struct Ledger {
    dms: BTreeMap<String, DmLedger>,
    /// Restarts heard of, by child name (a datamanager's child is named after it).
    restarts: HashMap<String, u64>,
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
    /// Each record's fingerprint (`applied`), by seq.
    fingerprints: HashMap<u64, u64>,
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
            let content = applied::content(&r.source, r.payload.as_bytes());
            held.fingerprints
                .insert(r.seq, applied::fingerprint(r.seq, content));
            held.records
                .insert(r.seq, (class, r.source.to_string(), digest));
        }
        for seqs in held.by_class.values_mut() {
            seqs.sort_unstable();
        }
        held
    }

    /// How many records of `class` are held with a seq in `from..=to`, and the sum of their
    /// fingerprints.
    fn in_span(&self, class: &str, from: u64, to: u64) -> (u64, u64) {
        let Some(seqs) = self.by_class.get(class) else {
            return (0, 0);
        };
        let (lo, hi) = (
            seqs.partition_point(|s| *s < from),
            seqs.partition_point(|s| *s <= to),
        );
        let sum = seqs[lo..hi].iter().fold(0u64, |sum, s| {
            sum.wrapping_add(self.fingerprints.get(s).copied().unwrap_or_default())
        });
        ((hi - lo) as u64, sum)
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
            EventKind::DmApplied { dm, spans } => {
                let ledger = self.dms.entry(dm.clone()).or_default();
                for span in spans {
                    if ledger.applied.len() >= KEEPS {
                        ledger.applied.pop_front();
                    }
                    ledger.applied.push_back(span.clone());
                }
                true
            }
            EventKind::ChildRestarted { child, .. } => {
                *self.restarts.entry(child.clone()).or_default() += 1;
                false
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

    /// Records `dm` told its puts applied, in the spans kept.
    pub fn applied(&self, dm: &str) -> u64 {
        self.dms
            .get(dm)
            .map_or(0, |l| l.applied.iter().map(|s| s.records).sum())
    }

    /// The classes of `dm`'s acknowledged records and applied spans kept.
    fn classes(&self, dm: &str) -> BTreeSet<Arc<str>> {
        self.dms.get(dm).map_or_else(BTreeSet::new, |l| {
            let acked = l.acked.iter().map(|a| a.class.clone());
            let applied = l.applied.iter().map(|s| Arc::from(s.class.as_str()));
            acked.chain(applied).collect()
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
        for span in &ledger.applied {
            check.applied += span.records;
            let lost = Self::compare_span(span, held, &ledger.deleted);
            if lost > 0 && check.applied_lost < SAID {
                tracing::warn!(
                    dm,
                    class = %span.class,
                    from = span.from,
                    to = span.to,
                    "{lost} of {} put records the datamanager applied between these seqs are lost",
                    span.records
                );
            }
            check.applied_lost += lost;
        }
        if check.lost + check.applied_lost > 0 {
            check.why = self.why(dm, held);
        }
        check
    }

    /// How many of the records of `span` are lost (see the module docs), given what `held`
    /// holds and the classes `deleted` by acknowledged deletes.
    fn compare_span(span: &AppliedSpan, held: &Held, deleted: &BTreeSet<Option<String>>) -> u64 {
        let (found, sum) = held.in_span(&span.class, span.from, span.to);
        if found == span.records && sum == span.digest {
            return 0;
        }
        if deleted.contains(&None) || deleted.contains(&Some(span.class.clone())) {
            return 0;
        }
        let newer = held.newer_in(&span.class, span.from.saturating_sub(1));
        if held
            .stats
            .retention_of(&span.class)
            .is_some_and(|bound| newer >= bound)
        {
            return 0;
        }
        // not the same records: none of them can be vouched for
        span.records
    }

    /// Why `dm` lost records, if the run's events say: it restarted during the run, and
    /// its instance that answered started with nothing (no journal, nothing inherited).
    fn why(&self, dm: &str, held: &Held) -> Option<String> {
        let restarts = self.restarts.get(dm).copied().unwrap_or_default();
        if restarts == 0 {
            return None;
        }
        let stats = &held.stats;
        Some(if stats.recovery.is_none() && stats.inherited.is_none() {
            format!("the {dm} datamanager restarted empty")
        } else {
            let times = if restarts == 1 {
                "once"
            } else {
                "more than once"
            };
            format!("the {dm} datamanager restarted {times} and no longer holds them")
        })
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
        let (acknowledged, applied) = (self.acknowledged(dm), self.applied(dm));
        // a replicated datamanager without a majority holds its records in the journals of
        // nodes that are gone: counted lost here (none can be read), and said why
        let error = match super::majority::without_leader(dm, super::majority::VIEW_TIMEOUT).await {
            Some(no_majority) => no_majority.to_string(),
            None => last.to_string(),
        };
        DmCheck {
            dm: dm.to_string(),
            node: None,
            acknowledged,
            lost: acknowledged,
            applied,
            applied_lost: applied,
            error: Some(error),
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
        let stats = match actor
            .call(|reply| DmMsg::ReplicaStats { reply }, Some(ASK))
            .await
        {
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

    /// The `dm_applied` a datamanager tells of `records` (seq, payload) of `class` by `source`.
    fn applied(dm: &str, class: &str, source: &str, records: &[(u64, &[u8])]) -> EventKind {
        let mut tally = crate::applied::Tally::default();
        for (seq, payload) in records {
            let content = crate::applied::content(source, payload);
            tally.note(class, *seq, crate::applied::fingerprint(*seq, content));
        }
        EventKind::DmApplied {
            dm: dm.into(),
            spans: tally.take(),
        }
    }

    #[test]
    fn put_records_applied_and_held_are_no_loss_and_others_at_their_seqs_are() {
        let mut ledger = Ledger::new();
        let sonar: Vec<(u64, &[u8])> = vec![(1, b"s1"), (3, b"s3"), (5, b"s5")];
        assert!(ledger.note(&applied("feature", "sonar", "ultrasonic", &sonar)));
        assert!(ledger.note(&applied("feature", "segments", "extractor", &[(6, b"g")])));
        let all = |s: &[(u64, &[u8])]| {
            s.iter()
                .map(|(seq, p)| record(*seq, "sonar", "ultrasonic", p))
                .collect::<Vec<_>>()
        };
        let mut held = all(&sonar);
        held.push(record(2, "other", "x", b"o"));
        held.push(record(6, "segments", "extractor", b"g"));
        let check = ledger.compare("feature", &Held::new("embedded", stats(100), held));
        assert_eq!((check.applied, check.applied_lost), (4, 0), "{check:?}");
        assert_eq!(check.why, None);

        // the datamanager started over: records of the same class at the same seqs, but
        // not the same ones (another payload), and the segment gone — all lost
        let over: Vec<(u64, &[u8])> = vec![(1, b"n1"), (3, b"n3"), (5, b"n5")];
        let check = ledger.compare("feature", &Held::new("embedded", stats(100), all(&over)));
        assert_eq!((check.applied, check.applied_lost), (4, 4), "{check:?}");
        // the run saw no restart: the words say where they were looked for
        assert_eq!(check.why, None);
        // one record of the span missing: the span cannot be vouched for
        let check = ledger.compare(
            "feature",
            &Held::new("embedded", stats(100), all(&sonar[..2])),
        );
        assert_eq!(check.applied_lost, 3 + 1, "{check:?}");
    }

    #[test]
    fn a_lost_put_of_a_datamanager_that_restarted_with_nothing_says_it_restarted_empty() {
        let mut ledger = Ledger::new();
        ledger.note(&applied(
            "feature",
            "sonar",
            "ultrasonic",
            &[(1, b"a"), (2, b"b")],
        ));
        ledger.note(&EventKind::ChildRestarted {
            supervisor: "datamanagers".into(),
            child: "feature".into(),
            actor: "0.9".into(),
            restarts: 1,
            reason: "killed".into(),
        });
        let empty = Held::new("embedded", stats(100), []);
        let check = ledger.compare("feature", &empty);
        assert_eq!(check.applied_lost, 2);
        assert_eq!(
            check.why.as_deref(),
            Some("the feature datamanager restarted empty")
        );
        // one that inherited its predecessor's records and still misses some says so
        let mut inherited = stats(100);
        inherited.inherited = Some(crate::Inherited {
            records: 1,
            refused: 0,
        });
        let check = ledger.compare(
            "feature",
            &Held::new(
                "embedded",
                inherited,
                [record(1, "sonar", "ultrasonic", b"a")],
            ),
        );
        assert_eq!(check.applied_lost, 2);
        assert_eq!(
            check.why.as_deref(),
            Some("the feature datamanager restarted once and no longer holds them")
        );
    }

    #[test]
    fn put_records_retention_or_a_delete_took_are_no_loss() {
        let mut ledger = Ledger::new();
        let old: Vec<(u64, &[u8])> = vec![(1, b"1"), (2, b"2")];
        ledger.note(&applied("feature", "sonar", "ultrasonic", &old));
        let new: Vec<(u64, &[u8])> = vec![(3, b"3"), (4, b"4"), (5, b"5")];
        ledger.note(&applied("feature", "sonar", "ultrasonic", &new));
        // bound 3: the first span dropped by retention, the second held
        let held = new
            .iter()
            .map(|(seq, p)| record(*seq, "sonar", "ultrasonic", p));
        let check = ledger.compare("feature", &Held::new("embedded", stats(3), held.clone()));
        assert_eq!((check.applied, check.applied_lost), (5, 0), "{check:?}");
        // bound 4: retention would have kept one of the first span — lost
        let check = ledger.compare("feature", &Held::new("embedded", stats(4), held));
        assert_eq!(check.applied_lost, 2, "{check:?}");
        // a delete of the class explains what is gone
        ledger.note(&EventKind::DmDeleted {
            dm: "feature".into(),
            source: "planner".into(),
            class: Some("sonar".into()),
            deleted: 5,
        });
        let check = ledger.compare("feature", &Held::new("embedded", stats(4), []));
        assert_eq!(check.applied_lost, 0, "{check:?}");
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
