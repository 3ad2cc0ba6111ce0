//! The indexed in-memory record store behind a datamanager (no actor: plain data).
//!
//! # Layout
//! Each class owns its records, in seq order (a deque: new records go to the back, retention
//! takes the oldest from the front), and three sets of seqs, also sorted deques: per first
//! sub-class, per (first, second) sub-class, and per source. Beside them, a time index maps
//! time stamps to seq ranges.
//!
//! The store stamps records itself, so seqs only grow and time stamps never decrease with
//! seq: a time range becomes a seq range by two binary searches, every set is sorted by
//! construction, and storing a record is a few appends — no tree to rebalance on the path of
//! a high-rate sensor.
//!
//! # Invariant: select cost grows with the answer, not with the store
//! A select takes the narrowest set its query names within the class (the deepest sub-class
//! given, or the source set if that is smaller), binary-searches the seq range the query
//! allows, walks it (backwards for newest-N, stopping after N) and filters the remaining
//! criteria on the way. A query that names no class does the same in every class and merges
//! the classes by seq: its cost adds a term in the number of classes, not the records.
//!
//! # Retention
//! Each class holds at most its bound of records ([`DmConfig::retention_for`]); storing one
//! more drops the oldest record *of that class*, which is also the first of each of its sets.
//! Other classes are not touched. Names are interned (`Arc<str>`) and payloads of a few dozen
//! bytes live in the record's own slot ([`Packed`]): a record costs about 130 bytes plus any
//! larger payload. The dropped record's seqs are swept from the sub-class and source sets in
//! batches (a drop then costs no hash lookup), and sets that become empty are removed.

use super::error::DmError;
use super::index::{NameMap, SeqDeque, TimeIndex};
use super::name::Name;
use super::packed::Packed;
use super::query::{Query, Take};
use super::record::{NewRecord, Payload, Record};
use super::shared::Shared;
use serde::{Deserialize, Serialize};
use std::collections::{vec_deque, BTreeMap, HashMap, VecDeque};
use std::sync::{Arc, OnceLock};
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

/// A stored record, names interned (the class is its [`ClassIndex`]'s).
struct Entry {
    timestamp: Duration,
    source: Arc<str>,
    sub1: Option<Arc<str>>,
    sub2: Option<Arc<str>>,
    payload: Packed,
    /// The payload as its readers share it, made by the first select that hands the record
    /// out ([`Shared`]: the value decoded once for every reader in the process). A record
    /// nobody reads — most of a high-rate sensor's — never gets one.
    shared: OnceLock<Arc<Shared>>,
}

impl Entry {
    /// Bytes of its payload and names (its class's name counted once per record, as the
    /// record's own copy of it would be).
    fn bytes(&self, class: &str) -> usize {
        class.len()
            + self.source.len()
            + self.sub1.as_deref().map_or(0, str::len)
            + self.sub2.as_deref().map_or(0, str::len)
            + self.payload.as_bytes().len()
    }

    fn to_record(&self, seq: u64, class: &Arc<str>) -> Record {
        let shared = self
            .shared
            .get_or_init(|| Arc::new(Shared::new(self.payload.as_bytes())));
        Record {
            seq,
            timestamp: self.timestamp,
            source: Name::shared(&self.source),
            class: Name::shared(class),
            sub1: self.sub1.as_ref().map(Name::shared),
            sub2: self.sub2.as_ref().map(Name::shared),
            payload: Payload::shared(shared.clone()),
        }
    }

    fn matches(&self, seq: u64, class: &str, q: &Query) -> bool {
        q.matches_parts(
            seq,
            self.timestamp,
            &self.source,
            class,
            self.sub1.as_deref(),
            self.sub2.as_deref(),
        )
    }
}

/// The seqs of one key within a class, its interned name, and the next level down.
struct Level<Sub> {
    name: Arc<str>,
    seqs: SeqDeque,
    subs: NameMap<Sub>,
}

impl<Sub> Level<Sub> {
    fn new(name: Arc<str>) -> Self {
        Level {
            name,
            seqs: SeqDeque::default(),
            subs: NameMap::default(),
        }
    }
}

type Sub2Index = Level<()>;
type Sub1Index = Level<Sub2Index>;
type SourceIndex = Level<()>;

/// Retention victims whose seqs a class may leave at the fronts of its sets before it
/// sweeps them out (see [`ClassIndex::stale`]).
const STALE_LIMIT: usize = 64;

/// Everything stored under one class: its records, in seq order, and its sub-indexes.
struct ClassIndex {
    name: Arc<str>,
    bound: usize,
    entries: VecDeque<(u64, Entry)>,
    subs: NameMap<Sub1Index>,
    sources: NameMap<SourceIndex>,
    /// Records dropped by retention since the last sweep. Their seqs stay at the fronts of
    /// the sub-class and source sets until [`STALE_LIMIT`] of them have gathered, then one
    /// sweep takes them all out: a dropped record then costs no hash lookups. Every reader
    /// of a set starts at the class's first live seq, below which every seq is stale.
    stale: usize,
    /// Records of this class dropped by retention.
    dropped: u64,
    /// What its records take ([`Entry::bytes`] summed): kept as they come and go, for
    /// [`Store::record_bytes`], which a replica's stats read every 100 ms while a soak
    /// waits for a node to catch up.
    bytes: usize,
}

/// Which of a class's sequences a walk follows.
#[derive(Clone, Copy)]
enum Pick<'a> {
    Entries,
    Seqs(&'a SeqDeque),
}

impl ClassIndex {
    fn new(name: Arc<str>, bound: usize) -> Self {
        ClassIndex {
            name,
            bound,
            entries: VecDeque::new(),
            subs: NameMap::default(),
            sources: NameMap::default(),
            stale: 0,
            dropped: 0,
            bytes: 0,
        }
    }

    /// The seq of the oldest record still stored (`u64::MAX` when none).
    fn first_live(&self) -> u64 {
        self.entries.front().map_or(u64::MAX, |(s, _)| *s)
    }

    /// Take the seqs of dropped records out of every set, and the sets left empty.
    fn sweep_stale(&mut self) {
        let first = self.first_live();
        self.subs.retain(|_, si| {
            si.seqs.drop_below(first);
            si.subs.retain(|_, x| {
                x.seqs.drop_below(first);
                !x.seqs.is_empty()
            });
            !si.seqs.is_empty()
        });
        self.sources.retain(|_, so| {
            so.seqs.drop_below(first);
            !so.seqs.is_empty()
        });
        self.stale = 0;
    }

    /// Append a record (its seq is larger than every stored one) and, if the class is now
    /// over its bound, take out and return its oldest record.
    fn add(
        &mut self,
        seq: u64,
        timestamp: Duration,
        source: &str,
        sub1: Option<&str>,
        sub2: Option<&str>,
        payload: Packed,
    ) -> Option<(u64, Entry)> {
        let (sub1, sub2) = match sub1 {
            None => (None, None),
            Some(s1) => with_slot(&mut self.subs, s1, Level::new, |si| {
                si.seqs.push(seq);
                let s2 = sub2.map(|s2| {
                    with_slot(&mut si.subs, s2, Level::new, |x| {
                        x.seqs.push(seq);
                        x.name.clone()
                    })
                });
                (Some(si.name.clone()), s2)
            }),
        };
        let source = with_slot(&mut self.sources, source, Level::new, |so| {
            so.seqs.push(seq);
            so.name.clone()
        });
        let entry = Entry {
            timestamp,
            source,
            sub1,
            sub2,
            payload,
            shared: OnceLock::new(),
        };
        self.bytes += entry.bytes(&self.name);
        self.entries.push_back((seq, entry));
        // The class held at most `bound` records before, so one drop restores the bound.
        if self.entries.len() <= self.bound {
            return None;
        }
        let (old, e) = self.entries.pop_front()?;
        self.bytes -= e.bytes(&self.name);
        // The victim is the oldest of the class, so its seq is below every live one: it is
        // stale in each of its sets, and swept out with the others in a while.
        self.stale += 1;
        if self.stale >= STALE_LIMIT {
            self.sweep_stale();
        }
        Some((old, e))
    }

    /// Take out the records `seqs` (ascending); each index of the class is rewritten at most
    /// once. Returns the removed records.
    fn remove_many(&mut self, seqs: &[u64]) -> Vec<(u64, Entry)> {
        let mut removed = Vec::with_capacity(seqs.len());
        if seqs.len() <= 8 {
            for &s in seqs {
                if let Some((_, e)) = self.position(s).and_then(|at| self.entries.remove(at)) {
                    removed.push((s, e));
                }
            }
        } else {
            let old = std::mem::take(&mut self.entries);
            self.entries = VecDeque::with_capacity(old.len().saturating_sub(seqs.len()));
            let mut i = 0;
            for (s, e) in old {
                while i < seqs.len() && seqs[i] < s {
                    i += 1;
                }
                if i < seqs.len() && seqs[i] == s {
                    removed.push((s, e));
                } else {
                    self.entries.push_back((s, e));
                }
            }
        }
        self.bytes -= removed
            .iter()
            .map(|(_, e)| e.bytes(&self.name))
            .sum::<usize>();
        type Sub2Groups<'e> = HashMap<&'e str, Vec<u64>>;
        let mut by_sub1: HashMap<&str, (Vec<u64>, Sub2Groups<'_>)> = HashMap::new();
        let mut by_source: HashMap<&str, Vec<u64>> = HashMap::new();
        for (seq, e) in &removed {
            if let Some(s1) = e.sub1.as_deref() {
                let (seqs1, subs2) = by_sub1.entry(s1).or_default();
                seqs1.push(*seq);
                if let Some(s2) = e.sub2.as_deref() {
                    subs2.entry(s2).or_default().push(*seq);
                }
            }
            by_source.entry(&*e.source).or_default().push(*seq);
        }
        for (s1, (seqs1, subs2)) in by_sub1 {
            let Some(si) = self.subs.get_mut(s1) else {
                continue;
            };
            si.seqs.remove_sorted(&seqs1);
            for (s2, seqs2) in subs2 {
                if let Some(x) = si.subs.get_mut(s2) {
                    x.seqs.remove_sorted(&seqs2);
                    if x.seqs.is_empty() {
                        si.subs.remove(s2);
                    }
                }
            }
            if si.seqs.is_empty() {
                self.subs.remove(s1);
            }
        }
        for (src, seqs_src) in by_source {
            if let Some(so) = self.sources.get_mut(src) {
                so.seqs.remove_sorted(&seqs_src);
                if so.seqs.is_empty() {
                    self.sources.remove(src);
                }
            }
        }
        removed
    }

    fn position(&self, seq: u64) -> Option<usize> {
        let at = self.entries.partition_point(|(s, _)| *s < seq);
        self.entries
            .get(at)
            .is_some_and(|(s, _)| *s == seq)
            .then_some(at)
    }

    fn get(&self, seq: u64) -> Option<&Entry> {
        self.position(seq)
            .and_then(|at| self.entries.get(at))
            .map(|(_, e)| e)
    }

    /// The narrowest sequence of this class for `q` (`q`'s class is this one or none), or
    /// `None` if nothing in this class can match.
    fn pick(&self, q: &Query) -> Option<(Pick<'_>, Plan)> {
        let mut best = (Pick::Entries, self.entries.len(), Plan::Class);
        // a set with no live seq (only stale ones not yet swept) counts as missing
        let first = self.first_live();
        let live = |seqs: &SeqDeque| seqs.last().is_some_and(|s| s >= first);
        // A set is walked only when it is narrower than the class: each of its seqs costs a
        // lookup among the class's entries, which the class's own walk does not. A set that
        // holds every record of its class — a class with one sub-class, the usual case of a
        // typed kind — narrows nothing.
        if let Some(s1) = q.sub1.as_deref() {
            let si = self.subs.get(s1).filter(|si| live(&si.seqs))?;
            if si.seqs.len() < best.1 {
                best = (Pick::Seqs(&si.seqs), si.seqs.len(), Plan::Sub1);
            }
            if let Some(s2) = q.sub2.as_deref() {
                let x = si.subs.get(s2).filter(|x| live(&x.seqs))?;
                if x.seqs.len() < best.1 {
                    best = (Pick::Seqs(&x.seqs), x.seqs.len(), Plan::Sub2);
                }
            }
        }
        if let Some(src) = q.source.as_deref() {
            let so = self.sources.get(src).filter(|so| live(&so.seqs))?;
            if so.seqs.len() < best.1 {
                best = (Pick::Seqs(&so.seqs), so.seqs.len(), Plan::Source);
            }
        }
        Some((best.0, best.2))
    }

    fn iter<'a>(&'a self, pick: Pick<'a>, lo: u64, hi: u64) -> ClassIter<'a> {
        match pick {
            Pick::Entries => {
                let a = self.entries.partition_point(|(s, _)| *s < lo);
                let b = self.entries.partition_point(|(s, _)| *s <= hi).max(a);
                ClassIter::Entries(self.entries.range(a..b))
            }
            // stale seqs all lie below the first live one
            Pick::Seqs(seqs) => ClassIter::Seqs(seqs.range(lo.max(self.first_live()), hi), self),
        }
    }
}

/// Records of one class over a seq range, either way round.
enum ClassIter<'a> {
    Entries(vec_deque::Iter<'a, (u64, Entry)>),
    Seqs(vec_deque::Iter<'a, u64>, &'a ClassIndex),
}

impl<'a> Iterator for ClassIter<'a> {
    type Item = (u64, &'a Entry);
    fn next(&mut self) -> Option<(u64, &'a Entry)> {
        match self {
            ClassIter::Entries(it) => it.next().map(|(s, e)| (*s, e)),
            ClassIter::Seqs(it, ci) => loop {
                let s = *it.next()?;
                if let Some(e) = ci.get(s) {
                    return Some((s, e));
                }
            },
        }
    }
}

impl ClassIter<'_> {
    /// Records left at most (fewer if some seqs of a set are stale).
    fn len(&self) -> usize {
        match self {
            ClassIter::Entries(it) => it.len(),
            ClassIter::Seqs(it, _) => it.len(),
        }
    }
}

impl<'a> DoubleEndedIterator for ClassIter<'a> {
    fn next_back(&mut self) -> Option<(u64, &'a Entry)> {
        match self {
            ClassIter::Entries(it) => it.next_back().map(|(s, e)| (*s, e)),
            ClassIter::Seqs(it, ci) => loop {
                let s = *it.next_back()?;
                if let Some(e) = ci.get(s) {
                    return Some((s, e));
                }
            },
        }
    }
}

/// The front of one class in a merged walk.
struct Head<'a> {
    class: &'a ClassIndex,
    seq: u64,
    entry: &'a Entry,
    rest: ClassIter<'a>,
}

/// What a [`Store::walk`] does with the matches it finds.
trait Visit<'a> {
    /// At most `n` matches will follow.
    fn most(&mut self, _n: usize) {}
    /// The record `seq` of `class` matches.
    fn visit(&mut self, seq: u64, class: &'a ClassIndex, entry: &'a Entry);
    /// Whether it wants no more (the walk stops).
    fn full(&self) -> bool {
        false
    }
}

/// A select's answer: the matches as records.
struct Answer(Vec<Record>);

impl<'a> Visit<'a> for Answer {
    fn most(&mut self, n: usize) {
        // sized once (the walk may filter, so a large answer still grows as it comes)
        self.0.reserve_exact(n.min(256));
    }
    fn visit(&mut self, seq: u64, class: &'a ClassIndex, entry: &'a Entry) {
        self.0.push(entry.to_record(seq, &class.name));
    }
}

/// A page of a select's answer: records until about `max` bytes.
struct Budget {
    records: Vec<Record>,
    bytes: usize,
    max: usize,
}

impl<'a> Visit<'a> for Budget {
    fn visit(&mut self, seq: u64, class: &'a ClassIndex, entry: &'a Entry) {
        let record = entry.to_record(seq, &class.name);
        self.bytes += super::page::record_bytes(&record);
        self.records.push(record);
    }
    fn full(&self) -> bool {
        self.bytes >= self.max
    }
}

/// The first and last seq of an answer.
#[derive(Default)]
struct Ends(Option<(u64, u64)>);

impl<'a> Visit<'a> for Ends {
    fn visit(&mut self, seq: u64, _: &'a ClassIndex, _: &'a Entry) {
        let (lo, hi) = self.0.unwrap_or((seq, seq));
        self.0 = Some((lo.min(seq), hi.max(seq)));
    }
}

/// Whether anything matches (the walk stops at the first match).
#[derive(Default)]
struct Any(bool);

impl<'a> Visit<'a> for Any {
    fn visit(&mut self, _: u64, _: &'a ClassIndex, _: &'a Entry) {
        self.0 = true;
    }
    fn full(&self) -> bool {
        self.0
    }
}

/// A delete's victims: their seqs by class.
struct Victims<'m>(&'m mut HashMap<Arc<str>, Vec<u64>>);

impl<'a> Visit<'a> for Victims<'_> {
    fn visit(&mut self, seq: u64, class: &'a ClassIndex, _: &'a Entry) {
        self.0.entry(class.name.clone()).or_default().push(seq);
    }
}

/// Which index a select walks (for tests and diagnostics).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Plan {
    /// Nothing can match (a named key has no records): nothing to walk.
    Empty,
    /// The records of the named class.
    Class,
    /// The (class, sub1) set.
    Sub1,
    /// The (class, sub1, sub2) set.
    Sub2,
    /// The (class, source) set.
    Source,
    /// A query without a class walks every class's records, merged by seq.
    Scan,
    /// A query without a class whose narrowest set differs from class to class.
    Mixed,
}

/// A stored record's fields, borrowed from the store (what a journal's snapshot writes).
#[derive(Clone, Copy, Debug)]
pub(crate) struct LiveRecord<'a> {
    pub source: &'a str,
    pub class: &'a str,
    pub sub1: Option<&'a str>,
    pub sub2: Option<&'a str>,
    pub payload: &'a [u8],
}

/// The indexed record store of one datamanager. See the module docs for the invariants.
pub struct Store {
    config: DmConfig,
    classes: NameMap<ClassIndex>,
    times: TimeIndex,
    len: usize,
    next_seq: u64,
    last_time: Duration,
    dropped: u64,
    deleted: u64,
    /// Classes that dropped their first record by retention since the last
    /// [`Store::take_newly_full`], with their bounds: what the datamanager tells (an event
    /// and a warning, once per class), so that retention is never silent.
    newly_full: Vec<(Name, usize)>,
}

/// Run `work` on the value of `key`, creating it with `make` first if missing — one hash
/// lookup when the key exists, and no allocation for the key.
fn with_slot<V, R>(
    map: &mut NameMap<V>,
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
            classes: NameMap::default(),
            times: TimeIndex::default(),
            len: 0,
            next_seq: 1,
            last_time: Duration::ZERO,
            dropped: 0,
            deleted: 0,
            newly_full: Vec::new(),
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
        self.check(&record)?;
        let (seq, timestamp) = self.stamp(now);
        self.place(seq, timestamp, record)?;
        Ok(seq)
    }

    /// Whether [`Store::insert`] would take `record`: its names are valid and its payload
    /// within the limit.
    pub fn check(&self, record: &NewRecord) -> Result<(), DmError> {
        record.validate()?;
        if record.payload.len() > self.config.max_payload {
            return Err(DmError::PayloadTooLarge {
                size: record.payload.len() as u64,
                max: self.config.max_payload as u64,
            });
        }
        Ok(())
    }

    /// The seq and the time stamp the next record stored at `now` gets (a journal writes
    /// them before the record is indexed).
    pub(crate) fn stamp(&self, now: Duration) -> (u64, Duration) {
        (self.next_seq, now.max(self.last_time))
    }

    /// Index a record recovered from a journal with the seq and time stamp it was stored
    /// with. Seqs must come in ascending order; the next record stored gets a larger one.
    pub(crate) fn restore(
        &mut self,
        seq: u64,
        timestamp: Duration,
        record: NewRecord,
    ) -> Result<(), DmError> {
        self.check_restored_seq(seq)?;
        self.place(seq, timestamp, record)
    }

    /// A restored record's seq is at least the next seq.
    fn check_restored_seq(&self, seq: u64) -> Result<(), DmError> {
        if seq < self.next_seq {
            return Err(DmError::InvalidRecord(format!(
                "seq {seq} is below the next seq {}",
                self.next_seq
            )));
        }
        Ok(())
    }

    /// Raise the next seq and the last time stamp to at least these (a snapshot's floor:
    /// seqs handed out before it are never handed out again, even if their records are gone).
    pub(crate) fn raise_floor(&mut self, next_seq: u64, last_time: Duration) {
        self.next_seq = self.next_seq.max(next_seq);
        self.last_time = self.last_time.max(last_time);
    }

    /// Index `record` as `seq` at `timestamp` (`seq` ≥ the next seq, names checked).
    fn place(&mut self, seq: u64, timestamp: Duration, record: NewRecord) -> Result<(), DmError> {
        let NewRecord {
            source,
            class,
            sub1,
            sub2,
            payload,
            epoch: _,
            producer: _,
            producer_seq: _,
        } = record;
        let names = (&*class, &*source, sub1.as_deref(), sub2.as_deref());
        self.place_parts(seq, timestamp, names, payload.into_packed())
    }

    /// [`Store::restore`] of a record it does not own (a replicated entry, which its log
    /// keeps): its names are interned as ever, its payload copied once.
    pub(crate) fn restore_ref(
        &mut self,
        seq: u64,
        timestamp: Duration,
        record: &NewRecord,
    ) -> Result<(), DmError> {
        self.check_restored_seq(seq)?;
        let names = (
            &*record.class,
            &*record.source,
            record.sub1.as_deref(),
            record.sub2.as_deref(),
        );
        let payload = Packed::copy_of(record.payload.as_bytes());
        self.place_parts(seq, timestamp, names, payload)
    }

    /// Index a record of (class, source, sub1, sub2) as `seq` at `timestamp`.
    fn place_parts(
        &mut self,
        seq: u64,
        timestamp: Duration,
        (class, source, sub1, sub2): (&str, &str, Option<&str>, Option<&str>),
        payload: Packed,
    ) -> Result<(), DmError> {
        self.next_seq = seq.checked_add(1).ok_or(DmError::SeqExhausted)?;
        self.last_time = self.last_time.max(timestamp);
        let config = &self.config;
        let newly_full = &mut self.newly_full;
        let evicted = with_slot(
            &mut self.classes,
            class,
            |name| {
                let bound = config.retention_for(&name);
                ClassIndex::new(name, bound)
            },
            |ci| {
                let evicted = ci.add(seq, timestamp, source, sub1, sub2, payload);
                if evicted.is_some() {
                    if ci.dropped == 0 {
                        newly_full.push((Name::shared(&ci.name), ci.bound));
                    }
                    ci.dropped += 1;
                }
                evicted
            },
        );
        self.times.push(timestamp, seq);
        self.len += 1;
        if let Some((_, e)) = evicted {
            self.times.remove(e.timestamp);
            self.len -= 1;
            self.dropped += 1;
        }
        Ok(())
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
            lo = lo.max(self.times.first_seq_from(from)?);
        }
        if let Some(to) = q.time_to {
            hi = hi.min(self.times.last_seq_to(to)?);
        }
        (lo <= hi).then_some((lo, hi))
    }

    /// The classes a query can match: the named one, or all.
    fn classes_for<'a>(&'a self, q: &Query) -> Box<dyn Iterator<Item = &'a ClassIndex> + 'a> {
        match q.class.as_deref() {
            Some(c) => Box::new(self.classes.get(c).into_iter()),
            None => Box::new(self.classes.values()),
        }
    }

    /// Which index a select with `q` walks.
    pub fn plan(&self, q: &Query) -> Plan {
        let mut plans = self
            .classes_for(q)
            .filter_map(|ci| ci.pick(q).map(|(_, p)| p));
        let Some(first) = plans.next() else {
            return Plan::Empty;
        };
        let plan = if plans.all(|p| p == first) {
            first
        } else {
            Plan::Mixed
        };
        match (q.class.is_some(), plan) {
            (false, Plan::Class) => Plan::Scan,
            (_, plan) => plan,
        }
    }

    /// Call `out` for every match of `q` (newest-first for `Take::Newest`, else oldest-first):
    /// each class named (or every class) walks its narrowest set over the seq range, and
    /// several classes are merged by seq. `most` is told first how many matches there can be
    /// at most (to size an answer once). Returns how many records were looked at.
    fn walk<'a>(&'a self, q: &Query, out: &mut impl Visit<'a>) -> usize {
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
        let step = |it: &mut ClassIter<'a>| if newest { it.next_back() } else { it.next() };
        let mut heads: Vec<Head<'a>> = Vec::new();
        for ci in self.classes_for(q) {
            let Some((pick, _)) = ci.pick(q) else {
                continue;
            };
            let mut rest = ci.iter(pick, lo, hi);
            if let Some((seq, entry)) = step(&mut rest) {
                heads.push(Head {
                    class: ci,
                    seq,
                    entry,
                    rest,
                });
            }
        }
        out.most(
            heads
                .iter()
                .map(|h| 1 + h.rest.len())
                .sum::<usize>()
                .min(limit),
        );
        let mut visited = 0;
        let mut taken = 0;
        while !heads.is_empty() {
            // the next seq in walking order among the classes (usually just one)
            let mut i = 0;
            for (j, h) in heads.iter().enumerate().skip(1) {
                if (h.seq > heads[i].seq) == newest {
                    i = j;
                }
            }
            let head = &mut heads[i];
            let (seq, class, entry) = (head.seq, head.class, head.entry);
            match step(&mut head.rest) {
                Some((s, e)) => {
                    head.seq = s;
                    head.entry = e;
                }
                None => {
                    heads.swap_remove(i);
                }
            }
            visited += 1;
            if entry.matches(seq, &class.name, q) {
                out.visit(seq, class, entry);
                taken += 1;
                if taken >= limit || out.full() {
                    break;
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
        let mut out = Answer(Vec::new());
        let visited = self.walk(q, &mut out);
        let Answer(mut out) = out;
        if matches!(q.take, Some(Take::Newest(_))) {
            out.reverse();
        }
        (out, visited)
    }

    /// The first page, of about `max_bytes`, of what [`Store::select`] answers to `q`, and
    /// the query for the rest (`page`: the pages add up to the answer as it is
    /// now).
    pub fn select_page(&self, q: &Query, max_bytes: usize) -> super::page::Page {
        let mut q = q.clone();
        // the answer's seq range, fixed now: later pages ask for the rest of it
        if q.take.is_some() {
            let mut ends = Ends::default();
            self.walk(&q, &mut ends);
            let Some((lo, hi)) = ends.0 else {
                return super::page::Page::default();
            };
            q.take = None;
            q.seq_from = Some(lo);
            q.seq_to = Some(hi);
        } else {
            let last = self.next_seq().saturating_sub(1);
            q.seq_to = Some(q.seq_to.map_or(last, |to| to.min(last)));
        }
        let mut page = Budget {
            records: Vec::new(),
            bytes: 0,
            max: max_bytes,
        };
        self.walk(&q, &mut page);
        let rest = match page.records.last() {
            Some(last) if page.full() && Some(last.seq) < q.seq_to => {
                Some(q.seq_from(last.seq + 1))
            }
            _ => None,
        };
        super::page::Page {
            records: page.records,
            rest,
        }
    }

    /// Delete every record matching `q` (respecting its newest/oldest limit). Returns how
    /// many were deleted.
    pub fn delete(&mut self, q: &Query) -> u64 {
        self.delete_seqs(q).len() as u64
    }

    /// [`Store::delete`], returning the seqs deleted (ascending): what a journal writes.
    pub(crate) fn delete_seqs(&mut self, q: &Query) -> Vec<u64> {
        let mut victims: HashMap<Arc<str>, Vec<u64>> = HashMap::new();
        self.walk(q, &mut Victims(&mut victims));
        let mut gone = Vec::new();
        for (class, mut seqs) in victims {
            seqs.sort_unstable();
            gone.extend(self.remove_from(&class, &seqs));
        }
        gone.sort_unstable();
        self.deleted += gone.len() as u64;
        gone
    }

    /// The seqs [`Store::delete`] would delete (ascending), without deleting them: what a
    /// replicated datamanager's leader proposes.
    pub(crate) fn matching_seqs(&self, q: &Query) -> Vec<u64> {
        let mut victims: HashMap<Arc<str>, Vec<u64>> = HashMap::new();
        self.walk(q, &mut Victims(&mut victims));
        let mut seqs: Vec<u64> = victims.into_values().flatten().collect();
        seqs.sort_unstable();
        seqs
    }

    /// Count `n` records deleted (a replicated delete, applied by `remove_seqs`).
    pub(crate) fn count_deleted(&mut self, n: u64) {
        self.deleted += n;
    }

    /// Take the records `seqs` out, whatever their classes (a journal's replayed delete, or
    /// records whose journal write failed); how many were there. Counted in no statistic.
    pub(crate) fn remove_seqs(&mut self, seqs: &[u64]) -> u64 {
        // each seq to the class that holds it (a binary search per class), so that a class
        // is rewritten only for its own records — not walked whole for every delete replayed
        let mut by_class: HashMap<Arc<str>, Vec<u64>> = HashMap::new();
        for &seq in seqs {
            if let Some(ci) = self.classes.values().find(|ci| ci.get(seq).is_some()) {
                by_class.entry(ci.name.clone()).or_default().push(seq);
            }
        }
        let mut n = 0;
        for (class, mut held) in by_class {
            held.sort_unstable();
            held.dedup();
            n += self.remove_from(&class, &held).len() as u64;
        }
        n
    }

    /// Take the records `seqs` (ascending) of `class` out of every index; their seqs.
    fn remove_from(&mut self, class: &str, seqs: &[u64]) -> Vec<u64> {
        let Some(ci) = self.classes.get_mut(class) else {
            return Vec::new();
        };
        let removed = ci.remove_many(seqs);
        if ci.entries.is_empty() {
            self.classes.remove(class);
        }
        for (_, e) in &removed {
            self.times.remove(e.timestamp);
        }
        self.len = self.len.saturating_sub(removed.len());
        removed.into_iter().map(|(s, _)| s).collect()
    }

    /// Every stored record, in seq order, as the journal's snapshot writes it.
    /// A digest of every stored record (seq, time stamp, names, payload), in seq order: two
    /// stores with the same records have the same digest (a checker compares replicas by it).
    pub fn digest(&self) -> u64 {
        // FNV-1a, 64 bits: no dependency, and a replica differing in any byte differs here
        // but with a chance of 2^-64
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        let mut eat = |bytes: &[u8]| {
            for b in bytes {
                h = (h ^ u64::from(*b)).wrapping_mul(0x100_0000_01b3);
            }
        };
        self.for_each_in_seq_order(|seq, t, r| {
            eat(&seq.to_le_bytes());
            eat(&u64::try_from(t.as_nanos())
                .unwrap_or(u64::MAX)
                .to_le_bytes());
            for name in [Some(r.source), Some(r.class), r.sub1, r.sub2] {
                let name = name.unwrap_or("\u{0}");
                eat(&(name.len() as u64).to_le_bytes());
                eat(name.as_bytes());
            }
            eat(&(r.payload.len() as u64).to_le_bytes());
            eat(r.payload);
        });
        h
    }

    /// The same records in a store built anew: every index, count and time re-derived from
    /// the records alone, in seq order, through the path a journal's replay takes — what an
    /// heir does with a store its predecessor may have left half-updated by a panic
    /// (`heir`). Seqs and time stamps handed out stay handed out; a record that does not
    /// fit (a seq twice) is refused. Returns the store and how many records were refused.
    pub(crate) fn rebuilt(self) -> (Store, u64) {
        let Store {
            config,
            classes,
            next_seq,
            last_time,
            dropped,
            deleted,
            ..
        } = self;
        let mut all: Vec<(u64, Arc<str>, Entry)> = Vec::new();
        for (_, ci) in classes {
            let name = ci.name;
            all.extend(ci.entries.into_iter().map(|(s, e)| (s, name.clone(), e)));
        }
        all.sort_unstable_by_key(|(s, _, _)| *s);
        let mut store = Store::new(config);
        let mut refused = 0;
        for (seq, class, e) in all {
            let names = (&*class, &*e.source, e.sub1.as_deref(), e.sub2.as_deref());
            let placed = store
                .check_restored_seq(seq)
                .and_then(|()| store.place_parts(seq, e.timestamp, names, e.payload));
            if placed.is_err() {
                refused += 1;
            }
        }
        store.raise_floor(next_seq, last_time);
        store.dropped += dropped;
        store.deleted += deleted;
        (store, refused)
    }

    pub(crate) fn for_each_in_seq_order(&self, mut f: impl FnMut(u64, Duration, LiveRecord<'_>)) {
        let mut all: Vec<(u64, &ClassIndex, &Entry)> = Vec::with_capacity(self.len);
        for ci in self.classes.values() {
            all.extend(ci.entries.iter().map(|(s, e)| (*s, ci, e)));
        }
        all.sort_unstable_by_key(|(s, _, _)| *s);
        for (seq, ci, e) in all {
            f(
                seq,
                e.timestamp,
                LiveRecord {
                    source: &e.source,
                    class: &ci.name,
                    sub1: e.sub1.as_deref(),
                    sub2: e.sub2.as_deref(),
                    payload: e.payload.as_bytes(),
                },
            );
        }
    }

    /// If the newest time stamp is later than `now` — a journal read back by a process whose
    /// clock began anew — move every time stamp back so that the newest is `now`: records
    /// keep their order and their ages relative to each other (the oldest saturate at zero),
    /// new ones are stamped `now` and later, and a select by time means what it says again.
    /// The time the datamanager was down is not counted. Returns by how much.
    pub(crate) fn rebase_times(&mut self, now: Duration) -> Duration {
        let Some(by) = self.last_time.checked_sub(now).filter(|d| !d.is_zero()) else {
            return Duration::ZERO;
        };
        for ci in self.classes.values_mut() {
            for (_, e) in ci.entries.iter_mut() {
                e.timestamp = e.timestamp.saturating_sub(by);
            }
        }
        self.times.shift_back(by);
        self.last_time = now;
        by
    }

    /// The newest time stamp handed out.
    pub(crate) fn last_time(&self) -> Duration {
        self.last_time
    }

    /// Whether the stored record `seq` matches `q` (false if there is none).
    pub fn matches(&self, seq: u64, q: &Query) -> bool {
        self.classes_for(q)
            .find_map(|ci| ci.get(seq).map(|e| e.matches(seq, &ci.name, q)))
            .unwrap_or(false)
    }

    /// Whether the stored record `seq` of `class` matches `q` (false if there is none).
    /// Whether any stored record matches `q` (a wait answers at once if one does).
    pub(crate) fn matches_any(&self, q: &Query) -> bool {
        let mut any = Any::default();
        self.walk(q, &mut any);
        any.0
    }

    pub(crate) fn matches_in(&self, class: &str, seq: u64, q: &Query) -> bool {
        self.classes
            .get(class)
            .and_then(|ci| ci.get(seq).map(|e| e.matches(seq, &ci.name, q)))
            .unwrap_or(false)
    }

    /// The stored record `seq`.
    pub fn get(&self, seq: u64) -> Option<Record> {
        self.classes
            .values()
            .find_map(|ci| ci.get(seq).map(|e| e.to_record(seq, &ci.name)))
    }

    /// Number of stored records.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Bytes of the stored records' payloads and names.
    pub fn record_bytes(&self) -> u64 {
        self.classes.values().map(|ci| ci.bytes as u64).sum()
    }

    /// True when nothing is stored.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Seq of the oldest stored record.
    pub fn first_seq(&self) -> Option<u64> {
        self.classes
            .values()
            .filter_map(|ci| ci.entries.front().map(|(s, _)| *s))
            .min()
    }

    /// Seq of the newest stored record.
    pub fn last_seq(&self) -> Option<u64> {
        self.classes
            .values()
            .filter_map(|ci| ci.entries.back().map(|(s, _)| *s))
            .max()
    }

    /// The seq the next record will get.
    pub fn next_seq(&self) -> u64 {
        self.next_seq
    }

    /// Records dropped by retention so far.
    pub fn dropped(&self) -> u64 {
        self.dropped
    }

    /// Records dropped by retention so far, per class (classes that dropped none are not
    /// listed).
    pub fn dropped_by_class(&self) -> BTreeMap<String, u64> {
        self.classes
            .values()
            .filter(|c| c.dropped > 0)
            .map(|c| (c.name.to_string(), c.dropped))
            .collect()
    }

    /// The classes that dropped their first record by retention since the last call, each
    /// with its bound: once per class in a store's life.
    pub fn take_newly_full(&mut self) -> Vec<(Name, usize)> {
        std::mem::take(&mut self.newly_full)
    }

    /// Records deleted by query so far.
    pub fn deleted(&self) -> u64 {
        self.deleted
    }

    /// Number of stored records per class.
    pub fn class_counts(&self) -> BTreeMap<String, u64> {
        self.classes
            .iter()
            .map(|(name, ci)| (String::from(&**name), ci.entries.len() as u64))
            .collect()
    }
}

impl std::fmt::Debug for Store {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Store")
            .field("records", &self.len)
            .field("classes", &self.classes.len())
            .field("next_seq", &self.next_seq)
            .finish_non_exhaustive()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::page;

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

    /// Every page of `q` at `max` bytes a page, read one after another with `between` run
    /// before each later page.
    fn pages(s: &mut Store, q: &Query, max: usize, between: impl Fn(&mut Store)) -> Vec<Vec<u64>> {
        let mut out = Vec::new();
        let mut next = Some(q.clone());
        while let Some(q) = next.take() {
            if !out.is_empty() {
                between(s);
            }
            let page = s.select_page(&q, max);
            out.push(seqs(&page.records));
            next = page.rest;
        }
        out
    }

    /// What the store's records take, walked.
    fn walked_bytes(s: &Store) -> u64 {
        let mut bytes = 0;
        s.for_each_in_seq_order(|_, _, r| {
            bytes += r.class.len()
                + r.source.len()
                + r.sub1.map_or(0, str::len)
                + r.sub2.map_or(0, str::len)
                + r.payload.len();
        });
        bytes as u64
    }

    #[test]
    fn the_bytes_of_its_records_are_kept_as_they_are_stored_dropped_and_deleted() {
        let mut s = Store::new(DmConfig::default().with_retention("sonar", 3));
        assert_eq!(s.record_bytes(), 0);
        for i in 0..6 {
            s.insert(new("sonar", Some("front"), None, "us"), secs(i))
                .unwrap();
            s.insert(new("scan", None, None, "lidar"), secs(i)).unwrap();
            assert_eq!(s.record_bytes(), walked_bytes(&s), "after {i}");
        }
        s.delete(&Query::class("scan").newest(2));
        assert_eq!(s.record_bytes(), walked_bytes(&s));
        // one at a time and many at once take different roads out
        let many: Vec<u64> = (0..20).collect();
        s.remove_seqs(&many);
        assert_eq!((s.record_bytes(), s.len()), (0, 0));
    }

    #[test]
    fn pages_add_up_to_the_select_they_stand_for() {
        // every sample record is at most `one` bytes; a page ends at the record that reaches
        // its bound, so it holds at most `per_page` of them
        let one = sample()
            .select(&Query::all())
            .iter()
            .map(page::record_bytes)
            .max()
            .unwrap();
        for q in [
            Query::all(),
            Query::class("sonar"),
            Query::class("sonar").sub1("front"),
            Query::all().newest(5),
            Query::all().oldest(5),
            Query::class("sonar").seq_from(3).newest(4),
            Query::all().time_from(secs(4)).seq_to(10),
            Query::class("none"),
        ] {
            for per_page in [1, 2, 3, 100] {
                let mut s = sample();
                let whole = seqs(&s.select(&q));
                let got = pages(&mut s, &q, one * (per_page - 1) + 1, |_| {});
                assert!(got.iter().all(|p| p.len() <= per_page), "{q:?}: {got:?}");
                assert_eq!(got.concat(), whole, "{q:?} at {per_page} a page");
            }
        }
    }

    #[test]
    fn pages_stand_for_the_answer_at_the_first_page() {
        // records stored between pages are not in it (they would move a "newest 5"); a
        // record deleted before its page is read is not either
        for q in [Query::all(), Query::class("sonar").newest(5)] {
            let mut s = sample();
            let mut whole = seqs(&s.select(&q));
            let one = page::record_bytes(&s.select(&Query::all())[0]);
            let got = pages(&mut s, &q, one * 2, |s| {
                s.insert(new("sonar", Some("front"), None, "us"), secs(99))
                    .unwrap();
            });
            assert_eq!(got.concat(), whole, "{q:?}");
            let mut s = sample();
            let last = *whole.last().unwrap();
            let got = pages(&mut s, &q, one * 2, |s| {
                s.delete(&Query::all().seq_range(last, last));
            });
            whole.pop();
            assert_eq!(got.concat(), whole, "{q:?}");
        }
    }

    #[test]
    fn a_record_larger_than_a_page_is_a_page_alone() {
        let mut s = Store::new(DmConfig::default());
        for n in [10usize, 5000, 10] {
            s.insert(
                NewRecord::new("scan", Payload::from_bytes(vec![7; n])).with_source("lidar"),
                secs(1),
            )
            .unwrap();
        }
        let got = pages(&mut s, &Query::all(), 1000, |_| {});
        assert_eq!(got, vec![vec![1, 2], vec![3]]);
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
    fn selects_hand_out_one_payload_decoded_once() {
        let mut s = Store::new(DmConfig::default());
        let scan = vec![(1.0f64, 2.0f64); 8]; // over the inline size: a heap payload
        for v in [&scan, &vec![(3.0, 4.0)]] {
            let rec = NewRecord::encode("scan", v).unwrap().with_source("us");
            s.insert(rec, secs(1)).unwrap();
        }
        let a = s.select(&Query::class("scan"));
        let b = s.select(&Query::class("scan").newest(2));
        assert_eq!(a, b);
        for (x, y) in a.iter().zip(&b) {
            let (vx, vy) = (
                x.decode_shared::<Vec<(f64, f64)>>().unwrap(),
                y.decode_shared::<Vec<(f64, f64)>>().unwrap(),
            );
            assert!(Arc::ptr_eq(&vx, &vy), "decoded once for both selects");
            // the same value and bytes as the record's own bytes decode to
            let own = Payload::from_bytes(x.payload.as_bytes().to_vec());
            assert_eq!(*vx, own.decode::<Vec<(f64, f64)>>().unwrap());
            assert_eq!(x.payload, own);
            // a wrong type stays a decoding error
            assert!(matches!(x.decode::<String>(), Err(DmError::Decode(_))));
        }
        assert_eq!(a[0].decode::<Vec<(f64, f64)>>().unwrap(), scan);
        // on the wire a shared payload is its bytes, as before
        let wire = marie_vocabulary::wire::encode(&a[0]).unwrap();
        assert_eq!(
            marie_vocabulary::wire::decode::<Record>(&wire).unwrap(),
            a[0]
        );
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
        // the extractor is the segment class's only writer: its records are the walk
        let q = Query::all().source("extractor");
        let (answer, visited) = s.select_counting(&q);
        assert_eq!((seqs(&answer), visited), (vec![4, 8, 12], 3));
        // no sonar from the extractor: nothing to walk
        let q = Query::class("sonar").source("extractor");
        assert_eq!(s.plan(&q), Plan::Empty);
        assert!(s.select(&q).is_empty());
        // the (class, source) set is narrower than the class
        let mut s2 = sample();
        for i in 0..3 {
            s2.insert(new("sonar", Some("front"), None, "other"), secs(20 + i))
                .unwrap();
        }
        let q = Query::class("sonar").source("other");
        assert_eq!(s2.plan(&q), Plan::Source);
        assert_eq!(seqs(&s2.select(&q)), vec![13, 14, 15]);
        // a class-less query merges the classes by seq, each with its own set
        let q = Query::all().source("us").newest(4);
        assert_eq!(seqs(&s2.select(&q)), vec![7, 9, 10, 11]);
        assert_eq!(s2.plan(&Query::all().sub1("front")), Plan::Sub1);
        assert_eq!(s2.plan(&Query::all()), Plan::Scan);
        // the sub1 set (6) is smaller than the "us" set (9)
        let q = Query::class("sonar").sub1("front").source("us");
        assert_eq!(s.plan(&q), Plan::Sub1);
        assert_eq!(s.select(&q).len(), 6);
        assert_eq!(s.plan(&Query::all().source("nobody")), Plan::Empty);
    }

    #[test]
    fn a_sub_class_every_record_of_its_class_has_walks_the_class_itself() {
        let mut s = Store::new(DmConfig::default());
        for i in 0..5u64 {
            s.insert(new("scan", Some("sonar"), Some("all"), "us"), secs(i + 1))
                .unwrap();
        }
        // the sets hold the whole class: no lookup per record, the same answer
        let q = Query::class("scan")
            .sub1("sonar")
            .sub2("all")
            .time_from(secs(2));
        assert_eq!(s.plan(&q), Plan::Class);
        assert_eq!(seqs(&s.select(&q)), vec![2, 3, 4, 5]);
        // one record of another sub-class: the set is narrower again
        s.insert(new("scan", Some("laser"), None, "us"), secs(6))
            .unwrap();
        assert_eq!(s.plan(&Query::class("scan").sub1("sonar")), Plan::Sub1);
        assert_eq!(s.select(&Query::class("scan").sub1("sonar")).len(), 5);
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
        assert_eq!(s.times.slots(), 1);
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
        assert_eq!((seqs(&answer), visited), (vec![501], 1));
    }

    #[test]
    fn a_class_that_starts_dropping_by_retention_is_told_once_with_its_bound() {
        let mut s = Store::new(DmConfig::default().with_retention("sonar", 2));
        for _ in 0..2 {
            s.insert(new("sonar", None, None, "s"), Duration::ZERO)
                .unwrap();
        }
        assert!(s.take_newly_full().is_empty(), "nothing dropped yet");
        for _ in 0..5 {
            s.insert(new("sonar", None, None, "s"), Duration::ZERO)
                .unwrap();
            s.insert(new("wall", None, None, "s"), Duration::ZERO)
                .unwrap();
        }
        let told = s.take_newly_full();
        assert_eq!(told, vec![(Name::from("sonar"), 2)]);
        assert!(s.take_newly_full().is_empty(), "told once");
        assert_eq!(
            s.dropped_by_class(),
            BTreeMap::from([("sonar".to_string(), 5)])
        );
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
    fn retention_victims_leave_the_sets_in_batches() {
        let mut s = Store::new(DmConfig::default().with_retention("sonar", 2));
        s.insert(new("sonar", Some("rare"), Some("x"), "old"), secs(0))
            .unwrap(); // seq 1
        for i in 0..3 {
            s.insert(new("sonar", Some("front"), None, "us"), secs(i))
                .unwrap(); // seq 2..=4
        }
        // seqs 1 and 2 are dropped but not yet swept: readers must not see them
        let sonar = s.classes.get("sonar").unwrap();
        assert_eq!(sonar.stale, 2);
        assert!(sonar.subs.contains_key("rare"));
        for q in [
            Query::class("sonar").sub1("rare"),
            Query::class("sonar").sub1("rare").sub2("x"),
            Query::class("sonar").source("old"),
        ] {
            assert_eq!(s.plan(&q), Plan::Empty, "{q:?}");
            assert!(s.select(&q).is_empty());
        }
        let q = Query::class("sonar").sub1("front").oldest(1);
        assert_eq!(seqs(&s.select(&q)), vec![3]);
        assert_eq!(seqs(&s.select(&Query::all().source("us"))), vec![3, 4]);
        // after enough drops one sweep takes them all out, and the empty sets with them
        for i in 0..STALE_LIMIT as u64 {
            s.insert(new("sonar", Some("front"), None, "us"), secs(10 + i))
                .unwrap();
        }
        let sonar = s.classes.get("sonar").unwrap();
        assert!(sonar.stale < STALE_LIMIT);
        assert!(!sonar.subs.contains_key("rare") && !sonar.sources.contains_key("old"));
        assert!(sonar.subs["front"].seqs.len() <= 2 + sonar.stale);
        assert_eq!(s.select(&Query::class("sonar").sub1("front")).len(), 2);
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
        assert!(s.classes.is_empty() && s.times.slots() == 0);
        assert_eq!(s.delete(&Query::all()), 0);
        // seqs are never reused
        assert_eq!(s.insert(new("a", None, None, "p"), secs(20)).unwrap(), 13);
    }

    #[test]
    fn limits_and_bad_input() {
        let mut s = Store::new(DmConfig::default().with_max_payload(4));
        let big = NewRecord::new("a", Payload::from_bytes(vec![0; 5])).with_source("p");
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
        let (mut answered, mut max_deleted) = (0, 0);
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
                // every tenth delete drops its limit and criteria but the class: big batches
                if round % 500 == 499 {
                    q = Query {
                        class: q.class.clone(),
                        ..Query::all()
                    };
                    want = model.iter().filter(|r| q.matches(r)).cloned().collect();
                }
                let deleted = s.delete(&q);
                assert_eq!(deleted, want.len() as u64, "delete {q:?}");
                max_deleted = max_deleted.max(deleted);
                model.retain(|r| !want.iter().any(|w| w.seq == r.seq));
            } else {
                assert_eq!(s.select(&q), want, "select {q:?}");
                answered += usize::from(!want.is_empty());
            }
            assert_eq!(s.len(), model.len());
            assert_eq!(s.first_seq(), model.first().map(|r| r.seq));
        }
        assert!(answered > 1000, "{answered} non-empty answers");
        assert!(max_deleted > 8, "largest delete {max_deleted}");
    }

    #[test]
    fn remove_seqs_takes_records_out_of_whatever_class_holds_them() {
        let mut s = Store::new(DmConfig::default());
        for (i, class) in ["a", "b", "c", "a", "b", "c", "a", "b", "c", "a"]
            .iter()
            .enumerate()
        {
            s.insert(
                new(class, None, None, "src"),
                Duration::from_millis(i as u64),
            )
            .unwrap();
        }
        // across classes, a seq twice, one that never was: 3 removed
        assert_eq!(s.remove_seqs(&[1, 5, 5, 9, 99]), 3);
        assert_eq!(s.len(), 7);
        let left: Vec<u64> = s.select(&Query::all()).iter().map(|r| r.seq).collect();
        assert_eq!(left, vec![2, 3, 4, 6, 7, 8, 10]);
        assert_eq!(s.class_counts()["a"], 3);
        assert_eq!(s.deleted(), 0, "a removal is no delete");
        // a time range still reads right once the records are gone
        let window = Query::all().time_range(Duration::from_millis(4), Duration::from_millis(6));
        let seqs: Vec<u64> = s.select(&window).iter().map(|r| r.seq).collect();
        assert_eq!(seqs, vec![6, 7]);
    }

    #[test]
    fn a_store_left_half_updated_is_rebuilt_from_its_records() {
        let mut s = sample();
        s.delete(&Query::class("segment").seq_range(4, 4));
        let (next, digest) = (s.next_seq(), s.digest());
        // what a panic in the middle of an insert leaves: the record in its class, seq and
        // time handed out, but in no sub-class or source set, the time index or the count
        let ci = s.classes.get_mut("sonar").unwrap();
        let (source, sub1) = (ci.entries[0].1.source.clone(), ci.entries[0].1.sub1.clone());
        ci.entries.push_back((
            next,
            Entry {
                timestamp: secs(20),
                source,
                sub1,
                sub2: None,
                payload: Packed::copy_of(b""),
                shared: OnceLock::new(),
            },
        ));
        s.next_seq = next + 1;
        assert_eq!(s.len(), 11, "the count does not know of it");
        assert!(!seqs(&s.select(&Query::class("sonar").sub1("front"))).contains(&next));

        let (rebuilt, refused) = s.rebuilt();
        assert_eq!(refused, 0);
        assert_eq!(rebuilt.len(), 12);
        assert!(seqs(&rebuilt.select(&Query::class("sonar").sub1("front"))).contains(&next));
        assert!(seqs(&rebuilt.select(&Query::all().time_range(secs(20), secs(20)))) == [next]);
        assert_eq!(rebuilt.next_seq(), next + 1);
        assert_eq!(rebuilt.deleted(), 1, "its counts are kept");
        assert_ne!(rebuilt.digest(), digest);

        // a store rebuilt as it was: the same records, the same answers
        let s = sample();
        let (all, digest) = (s.select(&Query::all()), s.digest());
        let (rebuilt, refused) = s.rebuilt();
        assert_eq!((refused, rebuilt.digest()), (0, digest));
        assert_eq!(rebuilt.select(&Query::all()), all);
    }

    #[test]
    fn a_record_twice_in_a_store_left_corrupt_is_refused_by_its_rebuild() {
        let mut s = sample();
        // seq 1 (sonar) also in another class: two records for one seq
        let e = s.classes.get("sonar").unwrap().entries[0].1.source.clone();
        s.classes.get_mut("segment").unwrap().entries.push_front((
            1,
            Entry {
                timestamp: secs(1),
                source: e,
                sub1: None,
                sub2: None,
                payload: Packed::copy_of(b""),
                shared: OnceLock::new(),
            },
        ));
        let (rebuilt, refused) = s.rebuilt();
        assert_eq!((refused, rebuilt.len()), (1, 12));
    }
}
