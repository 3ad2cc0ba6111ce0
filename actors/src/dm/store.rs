//! The indexed in-memory record store behind a datamanager (no actor: plain data).
//!
//! # Indexes
//! - primary: `seq → record`, ordered;
//! - per class, per (class, sub1) and per (class, sub1, sub2): the ordered set of their seqs;
//! - per source: the ordered set of its seqs;
//! - time: `timestamp → (first seq, last seq, live count)`.
//!
//! The store stamps records itself, so time stamps are non-decreasing with seq: a time range
//! becomes a seq range by two ordered-map lookups, and every criterion narrows one ordered
//! set of seqs.
//!
//! # Invariant: select cost grows with the answer, not with the store
//! A select takes the narrowest index its query names (the deepest class level given, or the
//! source set if that is smaller), walks only the seq range the query allows (backwards for
//! newest-N, stopping after N) and filters the rest of the criteria on the way. Queries that
//! name no class and no source walk the primary map over their seq range.
//!
//! # Retention
//! Each class holds at most its bound of records ([`DmConfig::retention_for`]); storing one
//! more drops the oldest record *of that class* from every index. Other classes are not
//! touched. Class, sub-class and source names are interned (`Arc<str>`): a record costs its
//! payload plus about a hundred bytes, and empty index entries are removed.

use super::error::DmError;
use super::query::{Query, Take};
use super::record::{NewRecord, Payload, Record};
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::sync::Arc;
use std::time::Duration;

/// Limits of one datamanager.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default)]
pub struct DmConfig {
    /// Most records kept per class when the class has no bound of its own.
    pub default_retention: usize,
    /// Bounds of particular classes (`class → most records kept`).
    pub retention: HashMap<String, usize>,
    /// Largest payload accepted, in bytes. ractor_cluster refuses frames above 16 MiB.
    pub max_payload: usize,
}

impl DmConfig {
    /// Default [`DmConfig::default_retention`].
    pub const DEFAULT_RETENTION: usize = 10_000;
    /// Default [`DmConfig::max_payload`] (8 MiB).
    pub const DEFAULT_MAX_PAYLOAD: usize = 8 * 1024 * 1024;

    /// Keep at most `n` records of classes without a bound of their own.
    pub fn with_default_retention(mut self, n: usize) -> DmConfig {
        self.default_retention = n;
        self
    }

    /// Keep at most `n` records of `class`.
    pub fn with_retention(mut self, class: impl Into<String>, n: usize) -> DmConfig {
        self.retention.insert(class.into(), n);
        self
    }

    /// Accept payloads of at most `bytes`.
    pub fn with_max_payload(mut self, bytes: usize) -> DmConfig {
        self.max_payload = bytes;
        self
    }

    /// The bound of `class`: its own, else the default; at least 1, so the record just
    /// stored always survives.
    pub fn retention_for(&self, class: &str) -> usize {
        self.retention
            .get(class)
            .copied()
            .unwrap_or(self.default_retention)
            .max(1)
    }
}

impl Default for DmConfig {
    fn default() -> DmConfig {
        DmConfig {
            default_retention: Self::DEFAULT_RETENTION,
            retention: HashMap::new(),
            max_payload: Self::DEFAULT_MAX_PAYLOAD,
        }
    }
}

/// A stored record, names interned.
struct Entry {
    timestamp: Duration,
    source: Arc<str>,
    class: Arc<str>,
    sub1: Option<Arc<str>>,
    sub2: Option<Arc<str>>,
    payload: Payload,
}

impl Entry {
    fn to_record(&self, seq: u64) -> Record {
        Record {
            seq,
            timestamp: self.timestamp,
            source: self.source.to_string(),
            class: self.class.to_string(),
            sub1: self.sub1.as_deref().map(str::to_string),
            sub2: self.sub2.as_deref().map(str::to_string),
            payload: self.payload.clone(),
        }
    }

    fn matches(&self, seq: u64, q: &Query) -> bool {
        q.matches_parts(
            seq,
            self.timestamp,
            &self.source,
            &self.class,
            self.sub1.as_deref(),
            self.sub2.as_deref(),
        )
    }
}

/// Seqs of one index key, plus the interned key.
struct Keyed<Sub> {
    name: Arc<str>,
    seqs: BTreeSet<u64>,
    subs: HashMap<Arc<str>, Sub>,
}

impl<Sub> Keyed<Sub> {
    fn new(name: Arc<str>) -> Self {
        Keyed {
            name,
            seqs: BTreeSet::new(),
            subs: HashMap::new(),
        }
    }
}

type Sub2Index = Keyed<()>;
type Sub1Index = Keyed<Sub2Index>;

struct ClassIndex {
    bound: usize,
    keyed: Keyed<Sub1Index>,
}

/// Records stored at one time stamp: a seq range and how many of them are still stored.
struct TimeSlot {
    first: u64,
    last: u64,
    live: u64,
}

/// Which index a select walks (for tests and diagnostics).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Plan {
    /// The query names a key with no records: nothing to walk.
    Empty,
    /// The class set.
    Class,
    /// The (class, sub1) set.
    Sub1,
    /// The (class, sub1, sub2) set.
    Sub2,
    /// The source set.
    Source,
    /// The primary map (over the query's seq range).
    Scan,
}

enum Candidates<'a> {
    Empty,
    Set(&'a BTreeSet<u64>, Plan),
    All,
}

/// The indexed record store of one datamanager. See the module docs for the invariants.
pub struct Store {
    config: DmConfig,
    records: BTreeMap<u64, Entry>,
    classes: HashMap<Arc<str>, ClassIndex>,
    sources: HashMap<Arc<str>, Keyed<()>>,
    times: BTreeMap<Duration, TimeSlot>,
    next_seq: u64,
    last_time: Duration,
    dropped: u64,
    deleted: u64,
}

/// Run `work` on the value of `key`, creating it with `make` first if missing — one hash
/// lookup when the key exists, and no allocation for the key.
fn with_slot<V, R>(
    map: &mut HashMap<Arc<str>, V>,
    key: &str,
    make: impl FnOnce(Arc<str>) -> V,
    work: impl FnOnce(&mut V) -> R,
) -> R {
    match map.get_mut(key) {
        Some(v) => work(v),
        None => {
            let name: Arc<str> = Arc::from(key);
            work(map.entry(name.clone()).or_insert_with(|| make(name)))
        }
    }
}

impl Store {
    /// An empty store. The first record gets seq 1.
    pub fn new(config: DmConfig) -> Store {
        Store {
            config,
            records: BTreeMap::new(),
            classes: HashMap::new(),
            sources: HashMap::new(),
            times: BTreeMap::new(),
            next_seq: 1,
            last_time: Duration::ZERO,
            dropped: 0,
            deleted: 0,
        }
    }

    /// The store's limits.
    pub fn config(&self) -> &DmConfig {
        &self.config
    }

    /// Store `record` at time `now`: validate it, give it the next seq and a time stamp (`now`,
    /// or the previous stamp if the clock went back), index it, and drop the oldest record of
    /// its class if the class is over its bound. Returns the seq.
    pub fn insert(&mut self, record: NewRecord, now: Duration) -> Result<u64, DmError> {
        record.validate()?;
        if record.payload.len() > self.config.max_payload {
            return Err(DmError::PayloadTooLarge {
                size: record.payload.len() as u64,
                max: self.config.max_payload as u64,
            });
        }
        let seq = self.next_seq;
        self.next_seq = seq.checked_add(1).ok_or(DmError::SeqExhausted)?;
        let timestamp = now.max(self.last_time);
        self.last_time = timestamp;

        let config = &self.config;
        let (class, sub1, sub2, evict) = with_slot(
            &mut self.classes,
            &record.class,
            |name| ClassIndex {
                bound: config.retention_for(&name),
                keyed: Keyed::new(name),
            },
            |ci| {
                ci.keyed.seqs.insert(seq);
                let subs = record.sub1.as_deref().map(|s1| {
                    with_slot(&mut ci.keyed.subs, s1, Keyed::new, |si| {
                        si.seqs.insert(seq);
                        let s2 = record.sub2.as_deref().map(|s2| {
                            with_slot(&mut si.subs, s2, Keyed::new, |s2i| {
                                s2i.seqs.insert(seq);
                                s2i.name.clone()
                            })
                        });
                        (si.name.clone(), s2)
                    })
                });
                // Before this insert the class held at most `bound` records, so one drop
                // restores the bound.
                let evict = if ci.keyed.seqs.len() > ci.bound {
                    ci.keyed.seqs.first().copied()
                } else {
                    None
                };
                let (sub1, sub2) = match subs {
                    Some((s1, s2)) => (Some(s1), s2),
                    None => (None, None),
                };
                (ci.keyed.name.clone(), sub1, sub2, evict)
            },
        );
        let source = with_slot(&mut self.sources, &record.source, Keyed::new, |si| {
            si.seqs.insert(seq);
            si.name.clone()
        });
        // Every stamp in the time index is <= `timestamp`: append, or extend the last slot.
        match self.times.last_entry() {
            Some(mut slot) if *slot.key() == timestamp => {
                let slot = slot.get_mut();
                slot.last = seq;
                slot.live += 1;
            }
            _ => {
                self.times.insert(
                    timestamp,
                    TimeSlot {
                        first: seq,
                        last: seq,
                        live: 1,
                    },
                );
            }
        }
        self.records.insert(
            seq,
            Entry {
                timestamp,
                source,
                class,
                sub1,
                sub2,
                payload: record.payload,
            },
        );
        if let Some(old) = evict {
            if self.remove(old).is_some() {
                self.dropped += 1;
                tracing::trace!(seq = old, "retention dropped a record");
            }
        }
        Ok(seq)
    }

    /// Remove one record from every index.
    fn remove(&mut self, seq: u64) -> Option<Entry> {
        let e = self.records.remove(&seq)?;
        if let Some(ci) = self.classes.get_mut(&*e.class) {
            let ck = &mut ci.keyed;
            ck.seqs.remove(&seq);
            if let Some(s1) = e.sub1.as_deref() {
                if let Some(si) = ck.subs.get_mut(s1) {
                    si.seqs.remove(&seq);
                    if let Some(s2) = e.sub2.as_deref() {
                        if let Some(s2i) = si.subs.get_mut(s2) {
                            s2i.seqs.remove(&seq);
                            if s2i.seqs.is_empty() {
                                si.subs.remove(s2);
                            }
                        }
                    }
                    if si.seqs.is_empty() {
                        ck.subs.remove(s1);
                    }
                }
            }
            if ck.seqs.is_empty() {
                self.classes.remove(&*e.class);
            }
        }
        if let Some(si) = self.sources.get_mut(&*e.source) {
            si.seqs.remove(&seq);
            if si.seqs.is_empty() {
                self.sources.remove(&*e.source);
            }
        }
        if let Some(slot) = self.times.get_mut(&e.timestamp) {
            slot.live = slot.live.saturating_sub(1);
            if slot.live == 0 {
                self.times.remove(&e.timestamp);
            }
        }
        Some(e)
    }

    /// The inclusive seq range a query allows, with its time range turned into seqs; `None`
    /// if it is empty.
    fn seq_bounds(&self, q: &Query) -> Option<(u64, u64)> {
        let mut lo = q.seq_from.unwrap_or(0);
        let mut hi = q.seq_to.unwrap_or(u64::MAX);
        if let (Some(from), Some(to)) = (q.time_from, q.time_to) {
            if from > to {
                return None;
            }
        }
        if let Some(from) = q.time_from {
            let (_, slot) = self.times.range(from..).next()?;
            lo = lo.max(slot.first);
        }
        if let Some(to) = q.time_to {
            let (_, slot) = self.times.range(..=to).next_back()?;
            hi = hi.min(slot.last);
        }
        (lo <= hi).then_some((lo, hi))
    }

    /// The narrowest index the query names.
    fn candidates(&self, q: &Query) -> Candidates<'_> {
        let mut best: Option<(&BTreeSet<u64>, Plan)> = None;
        if let Some(class) = q.class.as_deref() {
            let Some(ci) = self.classes.get(class) else {
                return Candidates::Empty;
            };
            best = Some((&ci.keyed.seqs, Plan::Class));
            if let Some(s1) = q.sub1.as_deref() {
                let Some(si) = ci.keyed.subs.get(s1) else {
                    return Candidates::Empty;
                };
                best = Some((&si.seqs, Plan::Sub1));
                if let Some(s2) = q.sub2.as_deref() {
                    let Some(s2i) = si.subs.get(s2) else {
                        return Candidates::Empty;
                    };
                    best = Some((&s2i.seqs, Plan::Sub2));
                }
            }
        }
        if let Some(source) = q.source.as_deref() {
            let Some(si) = self.sources.get(source) else {
                return Candidates::Empty;
            };
            if best.is_none_or(|(set, _)| si.seqs.len() < set.len()) {
                best = Some((&si.seqs, Plan::Source));
            }
        }
        match best {
            Some((set, plan)) => Candidates::Set(set, plan),
            None => Candidates::All,
        }
    }

    /// Which index a select with `q` walks.
    pub fn plan(&self, q: &Query) -> Plan {
        match self.candidates(q) {
            Candidates::Empty => Plan::Empty,
            Candidates::Set(_, plan) => plan,
            Candidates::All => Plan::Scan,
        }
    }

    /// Call `out` for every match of `q` (newest-first for `Take::Newest`, else oldest-first).
    /// Returns how many records were looked at.
    fn walk<'a>(&'a self, q: &Query, mut out: impl FnMut(u64, &'a Entry)) -> usize {
        let (newest, limit) = match q.take {
            None => (false, usize::MAX),
            Some(Take::Oldest(n)) => (false, n),
            Some(Take::Newest(n)) => (true, n),
        };
        if limit == 0 {
            return 0;
        }
        let Some((lo, hi)) = self.seq_bounds(q) else {
            return 0;
        };
        let mut visited = 0;
        let mut taken = 0;
        let mut visit = |seq: u64, e: &'a Entry| {
            visited += 1;
            if e.matches(seq, q) {
                out(seq, e);
                taken += 1;
            }
            taken < limit
        };
        match self.candidates(q) {
            Candidates::Empty => {}
            Candidates::Set(set, _) => {
                let mut it = set
                    .range(lo..=hi)
                    .filter_map(|s| self.records.get(s).map(|e| (*s, e)));
                if newest {
                    it.rev().try_for_each(|(s, e)| visit(s, e).then_some(()));
                } else {
                    it.try_for_each(|(s, e)| visit(s, e).then_some(()));
                }
            }
            Candidates::All => {
                let mut it = self.records.range(lo..=hi).map(|(s, e)| (*s, e));
                if newest {
                    it.rev().try_for_each(|(s, e)| visit(s, e).then_some(()));
                } else {
                    it.try_for_each(|(s, e)| visit(s, e).then_some(()));
                }
            }
        }
        visited
    }

    /// Every record matching `q`, oldest-first.
    pub fn select(&self, q: &Query) -> Vec<Record> {
        self.select_counting(q).0
    }

    /// [`Store::select`], plus how many stored records it looked at.
    pub fn select_counting(&self, q: &Query) -> (Vec<Record>, usize) {
        let mut out = Vec::new();
        let visited = self.walk(q, |seq, e| out.push(e.to_record(seq)));
        if matches!(q.take, Some(Take::Newest(_))) {
            out.reverse();
        }
        (out, visited)
    }

    /// Delete every record matching `q` (respecting its newest/oldest limit). Returns how
    /// many were deleted.
    pub fn delete(&mut self, q: &Query) -> u64 {
        let mut seqs = Vec::new();
        self.walk(q, |seq, _| seqs.push(seq));
        let mut n = 0;
        for seq in seqs {
            if self.remove(seq).is_some() {
                n += 1;
            }
        }
        self.deleted += n;
        n
    }

    /// Whether the stored record `seq` matches `q` (false if there is none).
    pub fn matches(&self, seq: u64, q: &Query) -> bool {
        self.records.get(&seq).is_some_and(|e| e.matches(seq, q))
    }

    /// The stored record `seq`.
    pub fn get(&self, seq: u64) -> Option<Record> {
        self.records.get(&seq).map(|e| e.to_record(seq))
    }

    /// The class of the stored record `seq`.
    pub fn class_of(&self, seq: u64) -> Option<&str> {
        self.records.get(&seq).map(|e| &*e.class)
    }

    /// Number of stored records.
    pub fn len(&self) -> usize {
        self.records.len()
    }

    /// True when nothing is stored.
    pub fn is_empty(&self) -> bool {
        self.records.is_empty()
    }

    /// Seq of the oldest stored record.
    pub fn first_seq(&self) -> Option<u64> {
        self.records.first_key_value().map(|(s, _)| *s)
    }

    /// Seq of the newest stored record.
    pub fn last_seq(&self) -> Option<u64> {
        self.records.last_key_value().map(|(s, _)| *s)
    }

    /// The seq the next record will get.
    pub fn next_seq(&self) -> u64 {
        self.next_seq
    }

    /// Records dropped by retention so far.
    pub fn dropped(&self) -> u64 {
        self.dropped
    }

    /// Records deleted by query so far.
    pub fn deleted(&self) -> u64 {
        self.deleted
    }

    /// Number of stored records per class.
    pub fn class_counts(&self) -> BTreeMap<String, u64> {
        self.classes
            .iter()
            .map(|(name, ci)| (name.to_string(), ci.keyed.seqs.len() as u64))
            .collect()
    }
}

impl std::fmt::Debug for Store {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Store")
            .field("records", &self.records.len())
            .field("classes", &self.classes.len())
            .field("next_seq", &self.next_seq)
            .finish_non_exhaustive()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn secs(s: u64) -> Duration {
        Duration::from_secs(s)
    }

    fn new(class: &str, sub1: Option<&str>, sub2: Option<&str>, src: &str) -> NewRecord {
        let mut r = NewRecord::new(class, Payload::default()).with_source(src);
        r.sub1 = sub1.map(Into::into);
        r.sub2 = sub2.map(Into::into);
        r
    }

    fn seqs(records: &[Record]) -> Vec<u64> {
        records.iter().map(|r| r.seq).collect()
    }

    /// seq 1..=12: sonar/front/narrow, sonar/front/wide, sonar/rear, segment — from two sources,
    /// one record per second starting at t=1s.
    fn sample() -> Store {
        let mut s = Store::new(DmConfig::default());
        let kinds = [
            ("sonar", Some("front"), Some("narrow"), "us"),
            ("sonar", Some("front"), Some("wide"), "us"),
            ("sonar", Some("rear"), None, "us"),
            ("segment", None, None, "extractor"),
        ];
        for i in 0..12u64 {
            let (c, s1, s2, src) = kinds[(i % 4) as usize];
            assert_eq!(s.insert(new(c, s1, s2, src), secs(i + 1)).unwrap(), i + 1);
        }
        s
    }

    #[test]
    fn insert_stamps_seq_and_time() {
        let mut s = Store::new(DmConfig::default());
        assert_eq!(s.insert(new("a", None, None, "p"), secs(5)).unwrap(), 1);
        // a clock that goes back cannot break the time order
        assert_eq!(s.insert(new("a", None, None, "p"), secs(3)).unwrap(), 2);
        let all = s.select(&Query::all());
        assert_eq!(seqs(&all), vec![1, 2]);
        assert_eq!(all[0].timestamp, secs(5));
        assert_eq!(all[1].timestamp, secs(5));
        assert_eq!(all[0].source, "p");
        assert_eq!(s.next_seq(), 3);
    }

    #[test]
    fn class_index() {
        let s = sample();
        let q = Query::class("sonar");
        assert_eq!(s.plan(&q), Plan::Class);
        assert_eq!(seqs(&s.select(&q)), vec![1, 2, 3, 5, 6, 7, 9, 10, 11]);
        let q = Query::class("segment").newest(2);
        assert_eq!(seqs(&s.select(&q)), vec![8, 12]);
        assert_eq!(s.plan(&Query::class("nothing")), Plan::Empty);
        assert!(s.select(&Query::class("nothing")).is_empty());
    }

    #[test]
    fn sub_class_indexes() {
        let s = sample();
        let q = Query::class("sonar").sub1("front");
        assert_eq!(s.plan(&q), Plan::Sub1);
        assert_eq!(seqs(&s.select(&q)), vec![1, 2, 5, 6, 9, 10]);
        let q = Query::class("sonar").sub1("front").sub2("wide");
        assert_eq!(s.plan(&q), Plan::Sub2);
        assert_eq!(seqs(&s.select(&q)), vec![2, 6, 10]);
        let q = Query::class("sonar").sub1("rear").sub2("wide");
        assert_eq!(s.plan(&q), Plan::Empty);
        // sub-classes without a class are filtered on a scan
        let q = Query::all().sub2("narrow");
        assert_eq!(s.plan(&q), Plan::Scan);
        assert_eq!(seqs(&s.select(&q)), vec![1, 5, 9]);
        // sub2 without sub1 filters the class set
        let q = Query::class("sonar").sub2("narrow").oldest(2);
        assert_eq!(s.plan(&q), Plan::Class);
        assert_eq!(seqs(&s.select(&q)), vec![1, 5]);
    }

    #[test]
    fn source_index_and_narrowest_choice() {
        let s = sample();
        let q = Query::all().source("extractor");
        assert_eq!(s.plan(&q), Plan::Source);
        assert_eq!(seqs(&s.select(&q)), vec![4, 8, 12]);
        // the source set (3) is smaller than the sonar set (9)
        let q = Query::class("sonar").source("extractor");
        assert_eq!(s.plan(&q), Plan::Source);
        assert!(s.select(&q).is_empty());
        // the sub1 set (6) is smaller than the "us" set (9)
        let q = Query::class("sonar").sub1("front").source("us");
        assert_eq!(s.plan(&q), Plan::Sub1);
        assert_eq!(s.select(&q).len(), 6);
        assert_eq!(s.plan(&Query::all().source("nobody")), Plan::Empty);
    }

    #[test]
    fn seq_and_time_ranges() {
        let s = sample();
        let q = Query::all().seq_range(3, 5);
        assert_eq!(s.plan(&q), Plan::Scan);
        assert_eq!(seqs(&s.select(&q)), vec![3, 4, 5]);
        assert_eq!(seqs(&s.select(&Query::all().seq_from(11))), vec![11, 12]);
        assert_eq!(seqs(&s.select(&Query::all().seq_to(2))), vec![1, 2]);
        assert!(s.select(&Query::all().seq_range(5, 3)).is_empty());
        let q = Query::all().time_range(secs(3), secs(5));
        assert_eq!(seqs(&s.select(&q)), vec![3, 4, 5]);
        // bounds between stamps
        let q = Query::all().time_range(Duration::from_millis(2500), Duration::from_millis(4500));
        assert_eq!(seqs(&s.select(&q)), vec![3, 4]);
        assert!(s.select(&Query::all().time_from(secs(13))).is_empty());
        assert!(s
            .select(&Query::all().time_to(Duration::from_millis(999)))
            .is_empty());
        assert!(s
            .select(&Query::all().time_range(secs(5), secs(3)))
            .is_empty());
        let q = Query::class("sonar")
            .sub1("front")
            .time_from(secs(4))
            .seq_to(9);
        assert_eq!(seqs(&s.select(&q)), vec![5, 6, 9]);
    }

    #[test]
    fn equal_time_stamps_share_a_slot() {
        let mut s = Store::new(DmConfig::default());
        for _ in 0..3 {
            s.insert(new("a", None, None, "p"), secs(1)).unwrap();
        }
        s.insert(new("a", None, None, "p"), secs(2)).unwrap();
        assert_eq!(
            seqs(&s.select(&Query::all().time_to(secs(1)))),
            vec![1, 2, 3]
        );
        s.delete(&Query::all().seq_range(1, 2));
        assert_eq!(seqs(&s.select(&Query::all().time_to(secs(1)))), vec![3]);
        s.delete(&Query::all().seq_to(3));
        assert!(s.select(&Query::all().time_to(secs(1))).is_empty());
        assert_eq!(s.times.len(), 1);
    }

    #[test]
    fn newest_walks_only_the_answer() {
        let mut s = Store::new(DmConfig::default().with_default_retention(usize::MAX));
        for i in 0..100_000u64 {
            let sub1 = if i % 10 == 0 { "rare" } else { "common" };
            s.insert(
                new("sonar", Some(sub1), None, "us"),
                Duration::from_millis(i),
            )
            .unwrap();
        }
        let (answer, visited) = s.select_counting(&Query::class("sonar").sub1("rare").newest(10));
        assert_eq!(answer.len(), 10);
        assert_eq!(visited, 10);
        assert!(answer.windows(2).all(|w| w[0].seq < w[1].seq));
        assert_eq!(answer[9].seq, 99_991);
        let (answer, visited) = s.select_counting(
            &Query::all()
                .time_range(Duration::from_millis(500), Duration::from_millis(509))
                .sub1("rare"),
        );
        assert_eq!((seqs(&answer), visited), (vec![501], 10));
    }

    #[test]
    fn retention_drops_the_oldest_of_a_class_only() {
        let cfg = DmConfig::default()
            .with_default_retention(100)
            .with_retention("sonar", 3);
        let mut s = Store::new(cfg);
        s.insert(new("map", None, None, "planner"), secs(0))
            .unwrap(); // seq 1
        for i in 0..5 {
            s.insert(new("sonar", Some("front"), Some("narrow"), "us"), secs(i))
                .unwrap(); // seq 2..=6
        }
        assert_eq!(seqs(&s.select(&Query::class("sonar"))), vec![4, 5, 6]);
        assert_eq!(seqs(&s.select(&Query::class("map"))), vec![1]);
        assert_eq!(s.dropped(), 2);
        assert_eq!(s.len(), 4);
        // the dropped records are gone from every index
        assert_eq!(
            seqs(&s.select(&Query::class("sonar").sub1("front").sub2("narrow"))),
            vec![4, 5, 6]
        );
        assert_eq!(seqs(&s.select(&Query::all().source("us"))), vec![4, 5, 6]);
        assert_eq!(seqs(&s.select(&Query::all().time_to(secs(1)))), vec![1]);
        assert_eq!(s.class_counts().get("sonar"), Some(&3));
        // a bound of 0 still keeps the newest record
        let mut s = Store::new(DmConfig::default().with_default_retention(0));
        s.insert(new("a", None, None, "p"), secs(0)).unwrap();
        s.insert(new("a", None, None, "p"), secs(0)).unwrap();
        assert_eq!(seqs(&s.select(&Query::all())), vec![2]);
    }

    #[test]
    fn delete_by_query_cleans_every_index() {
        let mut s = sample();
        assert_eq!(s.delete(&Query::class("sonar").sub1("front")), 6);
        assert_eq!(s.deleted(), 6);
        assert!(s.select(&Query::class("sonar").sub1("front")).is_empty());
        assert_eq!(s.plan(&Query::class("sonar").sub1("front")), Plan::Empty);
        assert_eq!(seqs(&s.select(&Query::all().source("us"))), vec![3, 7, 11]);
        assert_eq!(s.delete(&Query::all().newest(1)), 1);
        assert_eq!(seqs(&s.select(&Query::all())), vec![3, 4, 7, 8, 11]);
        assert_eq!(s.delete(&Query::all()), 5);
        assert!(s.is_empty());
        assert!(s.classes.is_empty() && s.sources.is_empty() && s.times.is_empty());
        assert_eq!(s.delete(&Query::all()), 0);
        // seqs are never reused
        assert_eq!(s.insert(new("a", None, None, "p"), secs(20)).unwrap(), 13);
    }

    #[test]
    fn limits_and_bad_input() {
        let mut s = Store::new(DmConfig::default().with_max_payload(4));
        let big = NewRecord::new("a", Payload(vec![0; 5])).with_source("p");
        assert_eq!(
            s.insert(big, secs(0)),
            Err(DmError::PayloadTooLarge { size: 5, max: 4 })
        );
        assert!(matches!(
            s.insert(new("", None, None, "p"), secs(0)),
            Err(DmError::InvalidName { .. })
        ));
        assert!(s.is_empty());
        assert_eq!(s.next_seq(), 1, "refused records take no seq");
        s.insert(new("a", None, None, "p"), secs(0)).unwrap();
        assert!(s.select(&Query::all().newest(0)).is_empty());
        assert_eq!(seqs(&s.select(&Query::all().oldest(5))), vec![1]);
        s.next_seq = u64::MAX;
        assert_eq!(
            s.insert(new("a", None, None, "p"), secs(0)),
            Err(DmError::SeqExhausted)
        );
    }

    /// A small deterministic generator (no dependency on `rand`).
    struct XorShift(u64);
    impl XorShift {
        fn next(&mut self, n: u64) -> u64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            self.0 % n
        }
    }

    #[test]
    fn agrees_with_a_naive_model() {
        let mut rng = XorShift(0x9e37_79b9_7f4a_7c15);
        let cfg = DmConfig::default()
            .with_default_retention(40)
            .with_retention("b", 15);
        let mut s = Store::new(cfg.clone());
        let mut model: Vec<Record> = Vec::new();
        let classes = ["a", "b", "c"];
        let subs = [None, Some("x"), Some("y")];
        let mut now = 0u64;
        for round in 0..3_000 {
            now += rng.next(3); // equal time stamps happen
            let class = classes[rng.next(3) as usize];
            let sub1 = subs[rng.next(3) as usize];
            let sub2 = sub1.and(subs[rng.next(3) as usize]);
            let src = ["p", "q"][rng.next(2) as usize];
            let seq = s
                .insert(new(class, sub1, sub2, src), Duration::from_millis(now))
                .unwrap();
            model.push(Record {
                seq,
                timestamp: Duration::from_millis(now),
                source: src.into(),
                class: class.into(),
                sub1: sub1.map(Into::into),
                sub2: sub2.map(Into::into),
                payload: Payload::default(),
            });
            let in_class = model.iter().filter(|r| r.class == class).count();
            if in_class > cfg.retention_for(class) {
                let pos = model.iter().position(|r| r.class == class).unwrap();
                model.remove(pos);
            }
            let mut q = Query::all();
            if rng.next(2) == 0 {
                q = q.in_class(classes[rng.next(3) as usize]);
            }
            if let Some(s1) = subs[rng.next(3) as usize] {
                q = q.sub1(s1);
            }
            if rng.next(4) == 0 {
                q = q.sub2(["x", "y"][rng.next(2) as usize]);
            }
            if rng.next(3) == 0 {
                q = q.source(["p", "q"][rng.next(2) as usize]);
            }
            if rng.next(3) == 0 {
                q = q.seq_from(seq.saturating_sub(rng.next(200)));
            }
            if rng.next(3) == 0 {
                q = q.seq_to(seq.saturating_sub(rng.next(100)));
            }
            if rng.next(3) == 0 {
                q = q.time_from(Duration::from_millis(now.saturating_sub(rng.next(300))));
            }
            if rng.next(3) == 0 {
                q = q.time_to(Duration::from_millis(now.saturating_sub(rng.next(150))));
            }
            let n = rng.next(6) as usize;
            match rng.next(3) {
                0 => q = q.newest(n),
                1 => q = q.oldest(n),
                _ => {}
            }
            let mut want: Vec<Record> = model.iter().filter(|r| q.matches(r)).cloned().collect();
            match q.take {
                Some(Take::Newest(n)) => want = want.split_off(want.len().saturating_sub(n)),
                Some(Take::Oldest(n)) => want.truncate(n),
                None => {}
            }
            if round % 50 == 49 {
                let deleted = s.delete(&q);
                assert_eq!(deleted, want.len() as u64, "delete {q:?}");
                model.retain(|r| !want.iter().any(|w| w.seq == r.seq));
            } else {
                assert_eq!(s.select(&q), want, "select {q:?}");
            }
            assert_eq!(s.len(), model.len());
        }
    }
}
