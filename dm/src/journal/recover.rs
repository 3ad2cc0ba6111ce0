//! Rebuilding a datamanager's store from its journal.
//!
//! The segments are read in order and their entries applied to an empty [`Store`]: a put
//! restores its record with the seq and time stamp it was stored with (retention drops what
//! it dropped then), a delete takes its seqs out, and a whole snapshot replaces everything
//! before it. Recovery stops at the first entry that is cut short or fails its checksum: the
//! segment is truncated there and the segments after it are removed, so the journal ends
//! with its last whole entry and the next write continues from there. A snapshot left open
//! by a crash is dropped, and the state before it kept. What was kept and dropped is the
//! [`Recovery`] report. Nothing here panics on any bytes, and nothing corrupt is served.

use super::reader::SegmentReader;
use super::segment::{self, Header};
use crate::entry::{self, Entry, Torn};
use crate::producers::Producers;
use crate::replica::tail::{Tail, KEEP_BYTES};
use crate::replica::{apply, Members, Op, OpBody};
use crate::store::{DmConfig, Store};
use marie_vocabulary::fence::FenceTable;
use serde::{Deserialize, Serialize};
use std::io;
use std::path::Path;
use std::time::Instant;

/// What a datamanager's start found in its journal.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default)]
pub struct Recovery {
    /// Records in the store after the replay (retention and deletes applied).
    pub records: u64,
    /// Entries replayed (puts, deletes, snapshot marks).
    pub entries: u64,
    /// Bytes of journal kept.
    pub bytes: u64,
    /// Bytes dropped: a torn or corrupt tail, the segments after it, an unfinished snapshot.
    pub dropped_bytes: u64,
    /// Whole puts among the dropped bytes (a torn entry counts as one).
    pub dropped_records: u64,
    /// How long the replay took, in milliseconds.
    pub millis: u64,
    /// Where and why the replay stopped early, if it did.
    pub torn: Option<String>,
}

/// A journal read back: the store, the sources' epochs, and where appending goes on.
pub(crate) struct Recovered {
    pub store: Store,
    pub fences: FenceTable,
    pub producers: Producers,
    pub report: Recovery,
    /// The segment to append to (the newest kept), and how many put entries the journal
    /// holds since its last snapshot (what decides the next one).
    pub tail: u64,
    pub puts: u64,
    /// A replicated datamanager's log, if the journal is one's.
    pub log: Option<ReplicaLog>,
}

/// What a replicated datamanager's journal says about its log beyond the store.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub(crate) struct ReplicaLog {
    /// (seq, term) of the last committed entry (applied to the store).
    pub committed: (u64, u64),
    /// The entries after it, not known committed, in order.
    pub tail: Vec<Op>,
    /// The term of the last entry written.
    pub term: u64,
    /// Committed entries the journal holds, ending with `committed` (at most
    /// [`TAIL_KEEP`], and [`KEEP_BYTES`](tail::KEEP_BYTES)): a replica that becomes the leader catches a lagging
    /// replica up from them rather than with a snapshot of its store.
    pub applied: Tail,
    /// (seq, term) of the entry just before the first of `applied`.
    pub before: (u64, u64),
    /// The newest committed configuration (from a committed entry, or a snapshot), and
    /// its seq: `None` if the journal holds none (the configured replicas are in use).
    pub members: Option<(u64, Members)>,
}

/// Committed entries a replay keeps ([`ReplicaLog::applied`]).
const TAIL_KEEP: usize = crate::replica::core::TAIL_KEEP;

impl ReplicaLog {
    /// Replay `entry` of the log: a put or a mark waits in the tail for its commit; a commit
    /// applies the tail up to it to `state`'s store; a truncation cuts the tail; a term mark
    /// sets the term. Any other entry (a snapshot's, a delete's) is handed back.
    fn replay(&mut self, entry: Entry, state: &mut State) -> Option<Entry> {
        let entry = match Op::from_entry(entry, self.term) {
            Ok(op) => {
                self.tail.push(op);
                return None;
            }
            Err(other) => other,
        };
        match entry {
            Entry::Commit { seq } => {
                let store = state.store.as_mut()?;
                let upto = self.tail.partition_point(|o| o.seq <= seq);
                if upto == 0 && seq > self.committed.0 {
                    // a commit mark after a snapshot: nothing to apply
                    self.committed = (seq, self.term);
                    self.applied.clear();
                }
                for op in self.tail.drain(..upto) {
                    if self.applied.is_empty() {
                        self.before = self.committed;
                    }
                    self.committed = (op.seq, op.term);
                    state.puts += matches!(op.body, OpBody::Put { .. }) as u64;
                    if let OpBody::Members(m) = &op.body {
                        state.members = Some((op.seq, m.clone()));
                    }
                    apply::apply(store, &mut state.fences, Some(&mut state.producers), &op);
                    self.applied.push_back(op);
                    let over = |len: usize, bytes: usize| len > TAIL_KEEP || bytes > KEEP_BYTES;
                    if let Some(last) = self
                        .applied
                        .drop_front_while(|_, len, bytes| over(len, bytes))
                    {
                        self.before = last;
                    }
                }
                None
            }
            Entry::Truncate { seq } => {
                self.tail.retain(|o| o.seq < seq);
                None
            }
            Entry::Term { term } => {
                self.term = term;
                None
            }
            other => Some(other),
        }
    }
}

/// What a replay rebuilds.
#[derive(Default)]
struct State {
    store: Option<Store>,
    fences: FenceTable,
    producers: Producers,
    /// Put entries since the last snapshot.
    puts: u64,
    /// A snapshot's floor (next seq, last time stamp), raised once its records are in: they
    /// carry seqs below it.
    floor: Option<(u64, std::time::Duration)>,
    /// A replicated datamanager's newest committed configuration, and its seq.
    members: Option<(u64, Members)>,
}

/// The state being rebuilt: the store, and a snapshot being read into a store of its own.
struct Replay {
    config: DmConfig,
    state: State,
    /// A snapshot opened and not yet ended: its state, and where it began.
    open: Option<(State, u64, usize)>,
    report: Recovery,
    /// The newest segment that holds a whole snapshot: the ones before it are garbage.
    snapshot_segment: Option<u64>,
    /// Set by the first `Term` entry: the journal is a replicated datamanager's, whose
    /// entries count only once committed.
    log: Option<ReplicaLog>,
}

impl Replay {
    fn apply(&mut self, entry: Entry, segment: u64, at: usize) {
        self.report.entries += 1;
        let in_snapshot = self.open.is_some();
        let state = match &mut self.open {
            Some((s, _, _)) => s,
            None => &mut self.state,
        };
        if state.store.is_none() {
            return;
        }
        // a replicated journal, outside a snapshot: its log takes what is its own
        let entry = match (&mut self.log, in_snapshot) {
            (Some(log), false) => match log.replay(entry, state) {
                Some(entry) => entry,
                None => return,
            },
            _ => entry,
        };
        let Some(store) = state.store.as_mut() else {
            return;
        };
        match entry {
            Entry::Term { term } => {
                // the first one: from here on, a replicated datamanager's journal
                self.log = Some(ReplicaLog {
                    term,
                    ..ReplicaLog::default()
                });
            }
            Entry::Commit { .. } | Entry::Truncate { .. } | Entry::Mark { .. } => {
                tracing::warn!(
                    segment,
                    at,
                    "journal: a replica's mark outside a replicated journal; ignored"
                );
            }
            Entry::Put {
                seq,
                timestamp,
                record,
            } => {
                let _ = state.fences.admit_parts(&record.source, record.epoch);
                if record.producer != 0 {
                    state
                        .producers
                        .note(record.producer, record.producer_seq, seq);
                }
                state.puts += 1;
                if let Err(e) = store.restore(seq, timestamp, record) {
                    tracing::warn!(seq, error = %e, "journal: a put could not be restored; skipped");
                }
            }
            Entry::Delete { seqs } => {
                store.remove_seqs(&seqs);
            }
            Entry::Members {
                seq,
                voters,
                learners,
            } => {
                // (in a snapshot: the configuration committed when it was taken)
                state.members = Some((seq, Members { voters, learners }));
            }
            Entry::Producer { producer, pairs } => {
                for (pseq, seq) in pairs {
                    state.producers.note(producer, pseq, seq);
                }
            }
            Entry::SnapOpen {
                next_seq,
                last_time,
            } => {
                let fresh = State {
                    store: Some(Store::new(self.config.clone())),
                    floor: Some((next_seq, last_time)),
                    ..State::default()
                };
                self.open = Some((fresh, segment, at));
            }
            Entry::SnapEnd { .. } => match self.open.take() {
                Some((mut s, seg, _)) => {
                    if let (Some(store), Some((next_seq, last_time))) =
                        (s.store.as_mut(), s.floor.take())
                    {
                        store.raise_floor(next_seq, last_time);
                    }
                    self.state = s;
                    self.snapshot_segment = Some(seg);
                    if let Some(log) = &mut self.log {
                        // the snapshot holds the committed state; the uncommitted entries
                        // written before it are written again after it
                        log.tail.clear();
                        log.applied.clear();
                    }
                }
                None => tracing::warn!(
                    segment,
                    at,
                    "journal: a snapshot end without its start; ignored"
                ),
            },
        }
    }
}

impl Replay {
    /// Replay the `segments` (whose format `headers` were read) in order, up to the first
    /// entry that is not whole: where it is (index of the segment, offset), if there is one.
    fn read(
        &mut self,
        segments: &[(u64, std::path::PathBuf)],
        headers: &[Header],
    ) -> io::Result<Option<(usize, usize)>> {
        let name = |path: &Path| {
            path.file_name()
                .unwrap_or_default()
                .to_string_lossy()
                .into_owned()
        };
        for (i, ((n, path), header)) in segments.iter().zip(headers).enumerate() {
            let start = match header {
                Header::Format { start, .. } => *start,
                Header::Torn => {
                    // created, and its header cut short: it holds nothing
                    self.report.torn = Some(format!(
                        "segment {}: its format header is cut short",
                        name(path)
                    ));
                    return Ok(Some((i, 0)));
                }
            };
            let mut entries = SegmentReader::open(path, start)?;
            while let Some(next) = entries.next()? {
                match next {
                    Ok((e, at)) => self.apply(e, *n, at),
                    Err((torn, at)) => {
                        self.report.dropped_records += u64::from(torn != Torn::Short);
                        self.report.torn =
                            Some(format!("segment {} at byte {at}: {torn}", name(path)));
                        self.report.bytes += entries.offset() as u64;
                        return Ok(Some((i, at)));
                    }
                }
            }
            self.report.bytes += entries.offset() as u64;
        }
        Ok(None)
    }
}

/// Count the whole puts at the start of `bytes` (what a dropped region held).
fn count_puts(mut bytes: &[u8]) -> u64 {
    let mut n = 0;
    while let Ok((e, len)) = entry::decode(bytes) {
        n += matches!(e, Entry::Put { .. }) as u64;
        bytes = &bytes[len..];
    }
    n
}

/// Read the journal in `dir` into a store with `config`, repairing its end (see the module
/// docs). Errors are the file system's, and a segment of a journal format this build does
/// not read ([`FormatError`](segment::FormatError), before anything is changed); other
/// bytes never make it fail.
pub(crate) fn recover(dir: &Path, config: DmConfig) -> io::Result<Recovered> {
    let started = Instant::now();
    let segments = segment::list(dir)?;
    let mut r = Replay {
        state: State {
            store: Some(Store::new(config.clone())),
            ..State::default()
        },
        config,
        open: None,
        report: Recovery::default(),
        snapshot_segment: None,
        log: None,
    };
    // every segment's format first: one this build does not read refuses the journal
    // before anything is replayed, cut or removed
    let headers = segments
        .iter()
        .map(|(_, path)| segment::header(path))
        .collect::<io::Result<Vec<Header>>>()?;
    let mut tail = segments.last().map_or(1, |(n, _)| *n);
    let stop = r.read(&segments, &headers)?;
    // A torn end: cut the segment there, and drop every segment after it.
    if let Some((i, at)) = stop {
        let (n, path) = &segments[i];
        let len = std::fs::metadata(path)?.len();
        r.report.dropped_bytes += len - at as u64;
        truncate(path, at as u64)?;
        for (_, later) in &segments[i + 1..] {
            let bytes = std::fs::read(later)?;
            r.report.dropped_bytes += bytes.len() as u64;
            r.report.dropped_records += count_puts(&bytes);
            std::fs::remove_file(later)?;
        }
        tail = *n;
    }
    // A snapshot left open: the state before it stands; its bytes go.
    if let Some((open, seg, at)) = r.open.take() {
        let puts = open.puts;
        let path = segment::path(dir, seg);
        let len = std::fs::metadata(&path)?.len();
        r.report.dropped_bytes += len - at as u64;
        r.report.bytes -= (len - at as u64).min(r.report.bytes);
        tracing::warn!(
            segment = seg,
            records = puts,
            "journal: an unfinished snapshot dropped"
        );
        // the snapshot's start is the segment's first entry (after its format header, if
        // it has one: an entry is longer than a header)
        if at <= segment::HEADER_BYTES {
            // its header goes with it
            r.report.bytes -= (at as u64).min(r.report.bytes);
            r.report.dropped_bytes += at as u64;
            std::fs::remove_file(&path)?;
            tail = segments
                .iter()
                .map(|(n, _)| *n)
                .filter(|n| *n < seg)
                .max()
                .unwrap_or(seg);
        } else {
            truncate(&path, at as u64)?;
        }
        r.report
            .torn
            .get_or_insert_with(|| "an unfinished snapshot".to_string());
    }
    // Segments older than the last whole snapshot were due to be deleted.
    if let Some(snap) = r.snapshot_segment {
        for (n, path) in segments.iter().filter(|(n, _)| *n < snap) {
            r.report.bytes -= std::fs::metadata(path)
                .map_or(0, |m| m.len())
                .min(r.report.bytes);
            std::fs::remove_file(path)?;
            tracing::debug!(
                segment = n,
                "journal: a segment older than the snapshot removed"
            );
        }
    }
    if r.report.torn.is_some() || r.snapshot_segment.is_some() {
        segment::sync_dir(dir)?;
    }
    let store = r
        .state
        .store
        .take()
        .unwrap_or_else(|| Store::new(r.config.clone()));
    r.report.records = store.len() as u64;
    r.report.millis = started.elapsed().as_millis() as u64;
    Ok(Recovered {
        store,
        fences: r.state.fences,
        producers: r.state.producers,
        report: r.report,
        tail,
        puts: r.state.puts,
        log: r.log.map(|log| ReplicaLog {
            members: r.state.members,
            ..log
        }),
    })
}

fn truncate(path: &Path, len: u64) -> io::Result<()> {
    let f = std::fs::OpenOptions::new().write(true).open(path)?;
    f.set_len(len)?;
    f.sync_all()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::{NewRecord, Payload};
    use std::time::Duration;

    /// A fresh directory of this test's own (removed when dropped).
    struct Dir(std::path::PathBuf);
    impl Dir {
        fn new(name: &str) -> Dir {
            let d =
                std::env::temp_dir().join(format!("marie-recover-{name}-{}", std::process::id()));
            let _ = std::fs::remove_dir_all(&d);
            std::fs::create_dir_all(&d).unwrap();
            Dir(d)
        }
        fn path(&self) -> &Path {
            &self.0
        }
    }
    impl Drop for Dir {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }

    fn rec(v: u8) -> NewRecord {
        NewRecord::new("c", Payload::from_bytes(vec![v])).with_source("p")
    }

    #[test]
    fn a_replicated_journal_applies_only_committed_entries_and_keeps_the_rest_aside() {
        let dir = Dir::new("replicated");
        let mut b = Vec::new();
        let t = Duration::from_millis;
        entry::encode_term(&mut b, 1);
        entry::encode_mark(&mut b, 1, &[]); // a leader's no-op
        entry::encode_put(&mut b, 2, t(10), &rec(2));
        entry::encode_put(&mut b, 3, t(11), &rec(3));
        entry::encode_commit(&mut b, 2);
        entry::encode_put(&mut b, 4, t(12), &rec(4));
        // a new leader cut entry 4 and wrote its own
        entry::encode_truncate(&mut b, 4);
        entry::encode_term(&mut b, 2);
        entry::encode_mark(&mut b, 4, &[]);
        entry::encode_mark(&mut b, 5, &[2]); // a delete of record 2
        entry::encode_commit(&mut b, 5);
        entry::encode_put(&mut b, 6, t(13), &rec(6));
        std::fs::write(segment::path(dir.path(), 1), &b).unwrap();
        let r = recover(dir.path(), DmConfig::default()).unwrap();
        let log = r.log.expect("a replicated journal");
        assert_eq!(log.committed, (5, 2));
        assert_eq!(log.term, 2);
        assert_eq!(
            log.tail.iter().map(|o| (o.seq, o.term)).collect::<Vec<_>>(),
            [(6, 2)]
        );
        // the committed entries are kept too (a leader catches a replica up from them)
        assert_eq!(
            log.applied
                .iter()
                .map(|o| (o.seq, o.term))
                .collect::<Vec<_>>(),
            [(1, 1), (2, 1), (3, 1), (4, 2), (5, 2)]
        );
        assert_eq!(log.before, (0, 0));
        // committed: 3 stays, 2 deleted, 4 (the cut put) never applied
        let seqs: Vec<u64> = r
            .store
            .select(&crate::Query::all())
            .iter()
            .map(|r| r.seq)
            .collect();
        assert_eq!(seqs, [3]);
        assert_eq!(r.store.next_seq(), 6);
    }

    #[test]
    fn a_journal_without_term_marks_is_applied_as_it_is_read() {
        let dir = Dir::new("plain");
        let mut b = Vec::new();
        entry::encode_put(&mut b, 1, Duration::from_millis(1), &rec(1));
        std::fs::write(segment::path(dir.path(), 1), &b).unwrap();
        let r = recover(dir.path(), DmConfig::default()).unwrap();
        assert!(r.log.is_none());
        assert_eq!(r.store.len(), 1);
    }
}
