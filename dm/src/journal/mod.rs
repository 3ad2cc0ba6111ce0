//! A datamanager's journal: its records on disk, so that a crash of the datamanager — or
//! `kill -9` of its process, or at `sync` a power loss — loses nothing it acknowledged.
//!
//! # What the datamanager does
//! At a [`Durability`] other than `memory` it opens its journal directory (locked: one
//! datamanager per directory, see [`DirLock`]) and *replays* it before it is published: its
//! store is what the journal says, and its seqs continue where they ended ([`Recovery`]
//! reports what was kept and dropped). From then on every record it stores, and every delete,
//! is encoded into the current batch before it is indexed, and every answer that
//! *acknowledges* a write — a `Store`'s seq, a `Delete`'s count, the `Stats` that return a
//! remote producer's credits — waits until what came before it is written (`process`) or
//! synced (`sync`). A select is answered at once and may see a record not yet durable; such
//! a record was never acknowledged, so losing it breaks no promise. A `Put` (a cast) is
//! acknowledged by nothing but a later answer to the same producer.
//!
//! # On disk
//! Segments of CRC-32C-checksummed entries (the `segment` and `entry` modules), written on
//! tokio's blocking pool with group commit (at `process`, by the datamanager itself when
//! the writer is idle; the `writer` module says why, and why not a thread of its own).
//! Deletes and retention make records garbage; once the journal holds more than twice the
//! live records (and at least [`SNAPSHOT_MIN`] puts), the datamanager writes a snapshot of
//! its live records to a new segment and the older segments are deleted, so the journal
//! stays within about three times the store. It checks at its start too, on the journal it
//! has just read back: a journal left long (its process killed before it was due) is not
//! replayed whole again at every later start. The replay reads a segment through a buffer
//! of a megabyte (the `reader` module), not the whole file.
//!
//! # Why a journal of our own
//! Measured against redb 4.6 and fjall 3.1 on this project's records (see ARCHITECTURE.md):
//! the journal appends 1.1 M records/s acknowledged one by one at `process`, group-commits
//! 8 producers at 185 k records/s with p99 ≤ 1.1 ms at `sync`, and replays 1 M records in
//! 0.39 s; redb has no mode that survives `kill -9` without a sync per commit (it lost acked
//! puts), and both need a newer Rust and tens of crates more. A datamanager needs an ordered
//! log and a replay, not a B-tree: its index is in memory already.

mod lock;
mod reader;
mod recover;
mod segment;
mod writer;

pub use lock::{DirLock, LockError};
pub use recover::Recovery;
pub(crate) use recover::ReplicaLog;
pub use segment::{FormatError, FORMAT, OLDEST_FORMAT};

use super::entry;
use super::error::DmError;
use super::producers::Producers;
use super::record::NewRecord;
use super::replica::{Members, Op, OpBody};
use super::store::{DmConfig, Store};
use marie_vocabulary::fence::FenceTable;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;
use writer::{Ack, Job, Shared, Writer};

/// How durable a datamanager's acknowledged writes are.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Durability {
    /// In memory only: survives a crash of the datamanager, not of its process. A
    /// datamanager restarted from the same arguments (its supervisor's restart) takes the
    /// records its previous incarnation left — its store kept outside the actor and handed
    /// over when the actor ends, as an ETS table goes to its heir ([`Heir`](crate::Heir)),
    /// and rebuilt from its records on the way, so a crash in the middle of a change hands
    /// over no half-updated index. `kill -9` of the process loses every record. Why not a
    /// journal in a temporary directory: it would cost every put of every embedded run a
    /// write for a promise (surviving the process) nobody asks of `memory`.
    /// The fastest; right for data a run makes and needs only while it lasts.
    #[default]
    Memory,
    /// Written to the OS before it is acknowledged: survives a crash of the datamanager and
    /// `kill -9` of its process, not a power loss or a kernel crash.
    Process,
    /// Group commit: a batch of writes is made durable with one `fdatasync`, then
    /// acknowledged together. Survives a power loss.
    Sync,
}

impl Durability {
    /// Every durability, as written in a config.
    pub const ALL: [Durability; 3] = [Durability::Memory, Durability::Process, Durability::Sync];

    /// The name a config uses.
    pub fn as_str(self) -> &'static str {
        match self {
            Durability::Memory => "memory",
            Durability::Process => "process",
            Durability::Sync => "sync",
        }
    }
}

impl std::fmt::Display for Durability {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl std::str::FromStr for Durability {
    type Err = UnknownDurability;
    fn from_str(s: &str) -> Result<Durability, UnknownDurability> {
        Durability::ALL
            .into_iter()
            .find(|d| d.as_str() == s)
            .ok_or_else(|| UnknownDurability(s.to_string()))
    }
}

/// A word that names no [`Durability`] (parsing one).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown durability {0:?}: use memory, process or sync")]
pub struct UnknownDurability(pub String);

/// What a replicated datamanager's snapshot writes after its store: where its committed log
/// ends (seq, term), its entries after that, and its committed configuration with its seq.
pub(crate) type LogAfterCommit<'a> = ((u64, u64), Vec<&'a Op>, (u64, &'a Members));

/// A journal of fewer put entries than this is never snapshotted (nor is one of fewer than
/// twice its store's records).
///
/// Why this low: what a start replays is every put since the last snapshot, and the replay
/// decodes each one, indexes it, and drops it again if retention or a delete took it — so a
/// long journal costs its start time and leaves the process's memory scattered (each put is
/// an allocation freed among the records kept). At 65 536 a kept-up cluster of the thesis'
/// layout never snapshotted its feature journal in 24 runs (~19 000 puts, 9 MB), and its
/// nodes restarted on it came back at 71–75 MiB; on the same journals with the feature one
/// snapshotted (1.9 MB), 56–62 MiB. The rule's other half (twice the store) already bounds
/// the cost of snapshotting — at most one record written again per two puts — so the floor
/// is only there to leave tiny journals alone.
pub const SNAPSHOT_MIN: u64 = 8_192;

/// A batch this large is handed to the writer without waiting for the mailbox to drain.
const BATCH_BYTES: usize = 1 << 20;

/// How long a datamanager's start waits for its previous incarnation's writer to let go of
/// the journal (it finishes the batches it was handed, at most one sync).
const LOCK_WAIT: Duration = Duration::from_secs(10);

/// The journal as its datamanager holds it: the batch being gathered, the jobs waiting for
/// the writer, and the writer when it is idle.
pub(crate) struct Journal {
    durability: Durability,
    dir: PathBuf,
    batch: Vec<u8>,
    acks: Vec<Ack>,
    seqs: Vec<u64>,
    /// A `JournalFlush` is in the mailbox.
    flush_sent: bool,
    /// The writer and the jobs waiting for it, shared with the blocking task that writes.
    core: Arc<Core>,
    /// Put entries in the journal since its last snapshot.
    puts: u64,
    shared: Arc<Shared>,
    /// Sends the datamanager its `JournalFlush`.
    flush: Box<dyn Fn() -> bool + Send>,
    /// A replicated datamanager's: the term of the last entry written, and the last entry
    /// written since [`Journal::take_last_op`] was asked.
    term: Option<u64>,
    last_op: Option<(u64, u64)>,
}

/// How the journal reaches its datamanager (given by the actor: the journal knows no
/// message of it).
pub(crate) struct Hooks {
    /// Send the datamanager a `JournalFlush` (it lands behind the messages waiting); false
    /// if it is gone.
    pub flush: Box<dyn Fn() -> bool + Send>,
    /// Tell the datamanager that these records could not be written (`JournalRefused`).
    pub refused: Box<dyn Fn(Vec<u64>) + Send>,
}

/// The writer and its queue. While a blocking task writes (`running`), jobs handed over
/// join the queue and the same task takes them all as its next group when it is done — no
/// hop through the datamanager's mailbox between two groups; once the queue is empty the task
/// puts the writer back and ends.
#[derive(Default)]
struct Core {
    inner: std::sync::Mutex<Inner>,
    /// Told when a task ends (a stopping datamanager waits for it in `close`).
    idle: tokio::sync::Notify,
}

#[derive(Default)]
struct Inner {
    queue: Vec<Job>,
    /// `None` while a task writes, or once the writer was lost (a panic in it).
    writer: Option<Writer>,
    running: bool,
}

impl Core {
    fn lock(&self) -> std::sync::MutexGuard<'_, Inner> {
        self.inner.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Write `jobs`, then every group that queued meanwhile, then put the writer back.
    fn drain(self: Arc<Self>, mut writer: Writer, mut jobs: Vec<Job>, shared: Arc<Shared>) {
        loop {
            let ran = std::panic::catch_unwind(std::panic::AssertUnwindSafe(move || {
                writer.run(jobs);
                writer
            }));
            let mut inner = self.lock();
            match ran {
                Ok(w) if !inner.queue.is_empty() => {
                    writer = w;
                    jobs = std::mem::take(&mut inner.queue);
                }
                Ok(w) => {
                    inner.writer = Some(w);
                    inner.running = false;
                    break;
                }
                Err(_) => {
                    shared.fail("the journal's writer panicked".to_string());
                    inner.running = false;
                    break;
                }
            }
        }
        self.idle.notify_one();
    }
}

/// A store read back from its journal, and the journal ready to append to.
pub(crate) struct Opened {
    pub journal: Journal,
    pub store: Store,
    pub fences: FenceTable,
    pub producers: Producers,
    pub recovery: Recovery,
    /// A replicated datamanager's log beyond the store.
    pub log: Option<ReplicaLog>,
}

impl Journal {
    /// Lock `dir` (waiting for a previous incarnation to let go), replay it into a store with
    /// `config`, and start its writer. Errors say which directory and why.
    pub(crate) async fn open(
        dir: &Path,
        durability: Durability,
        config: DmConfig,
        hooks: Hooks,
    ) -> Result<Opened, DmError> {
        let storage = |what: &str, e: &dyn std::fmt::Display| {
            DmError::Storage(format!("{what} {}: {e}", dir.display()))
        };
        let started = tokio::time::Instant::now();
        let lock = loop {
            match DirLock::acquire(dir) {
                Ok(lock) => break lock,
                Err(LockError::Held { .. }) if started.elapsed() < LOCK_WAIT => {
                    // the runtime's own timer: a paused simulation clock must not hold this
                    tokio::time::sleep(Duration::from_millis(5)).await;
                }
                Err(e) => return Err(DmError::Storage(e.to_string())),
            }
        };
        let path = dir.to_path_buf();
        let recovered = tokio::task::spawn_blocking(move || recover::recover(&path, config))
            .await
            .map_err(|e| storage("replaying", &e))?
            .map_err(|e| storage("replaying", &e))?;
        let file = segment::open(dir, recovered.tail).map_err(|e| storage("opening", &e))?;
        let len = file.metadata().map_err(|e| storage("opening", &e))?.len();
        let shared = Arc::new(Shared::default());
        // what the replay kept is what is on disk (it cut and removed the rest)
        shared
            .bytes
            .store(recovered.report.bytes, Ordering::Relaxed);
        let Hooks { flush, refused } = hooks;
        let writer = Writer {
            dir: dir.to_path_buf(),
            segment: recovered.tail,
            file,
            len,
            sync: durability == Durability::Sync,
            shared: shared.clone(),
            refused,
            _lock: lock,
        };
        let report = &recovered.report;
        if report.torn.is_some() {
            tracing::warn!(journal = %dir.display(), records = report.records, bytes = report.bytes, dropped_bytes = report.dropped_bytes, dropped_records = report.dropped_records, ms = report.millis, torn = report.torn.as_deref().unwrap_or(""), "journal recovered up to a torn end");
        } else {
            tracing::info!(journal = %dir.display(), records = report.records, bytes = report.bytes, ms = report.millis, "journal recovered");
        }
        Ok(Opened {
            journal: Journal {
                durability,
                dir: dir.to_path_buf(),
                batch: Vec::with_capacity(64 << 10),
                acks: Vec::new(),
                seqs: Vec::new(),
                flush_sent: false,
                core: Arc::new(Core {
                    inner: std::sync::Mutex::new(Inner {
                        queue: Vec::new(),
                        writer: Some(writer),
                        running: false,
                    }),
                    idle: Default::default(),
                }),
                puts: recovered.puts,
                shared,
                flush,
                term: recovered.log.as_ref().map(|l| l.term),
                last_op: None,
            },
            store: recovered.store,
            fences: recovered.fences,
            producers: recovered.producers,
            recovery: recovered.report,
            log: recovered.log,
        })
    }

    /// The journal's durability.
    pub(crate) fn durability(&self) -> Durability {
        self.durability
    }

    /// Bytes of the journal on disk.
    pub(crate) fn bytes(&self) -> u64 {
        self.shared.bytes.load(Ordering::Relaxed)
    }

    /// `Storage` if the journal has failed: nothing more can be made durable.
    pub(crate) fn usable(&self) -> Result<(), DmError> {
        match self.shared.failure() {
            Some(why) => Err(DmError::Storage(why.to_string())),
            None => Ok(()),
        }
    }

    /// Journal a put of `record` as `seq` at `timestamp` (before it is indexed).
    pub(crate) fn put(&mut self, seq: u64, timestamp: Duration, record: &NewRecord) {
        entry::encode_put(&mut self.batch, seq, timestamp, record);
        self.seqs.push(seq);
        self.puts += 1;
        self.written();
    }

    /// Journal a delete of `seqs`.
    pub(crate) fn delete(&mut self, seqs: &[u64]) {
        if seqs.is_empty() {
            return;
        }
        entry::encode_delete(&mut self.batch, seqs);
        self.written();
    }

    /// Journal a replicated datamanager's entry (after a term mark if its term is new here).
    pub(crate) fn op(&mut self, op: &Op) {
        self.term_mark(op.term);
        op.encode(&mut self.batch);
        self.logged(op);
    }

    /// [`Journal::op`] of an entry given as its journal entry `bytes` (as the leader sent
    /// it: see `replica::Ops`).
    pub(crate) fn op_encoded(&mut self, op: &Op, bytes: &[u8]) {
        self.term_mark(op.term);
        self.batch.extend_from_slice(bytes);
        self.logged(op);
    }

    /// `op` is in the batch.
    fn logged(&mut self, op: &Op) {
        if matches!(op.body, OpBody::Put { .. }) {
            self.puts += 1;
        }
        self.last_op = Some((op.seq, op.term));
        self.written();
    }

    fn term_mark(&mut self, term: u64) {
        if self.term != Some(term) {
            entry::encode_term(&mut self.batch, term);
            self.term = Some(term);
        }
    }

    /// Journal that the entries up to `seq` are committed.
    pub(crate) fn commit(&mut self, seq: u64) {
        entry::encode_commit(&mut self.batch, seq);
        self.written();
    }

    /// Journal that the uncommitted entries from `seq` on are gone.
    pub(crate) fn truncate(&mut self, seq: u64) {
        entry::encode_truncate(&mut self.batch, seq);
        if self.last_op.is_some_and(|(s, _)| s >= seq) {
            self.last_op = None;
        }
        self.written();
    }

    /// The last entry journaled since the last time this was asked (to learn when it is
    /// durable).
    pub(crate) fn take_last_op(&mut self) -> Option<(u64, u64)> {
        self.last_op.take()
    }

    /// Run `ack` once everything journaled before it is durable (at once if it is already),
    /// or with `Storage` if it could not be made so.
    pub(crate) fn after_durable(&mut self, ack: Ack) {
        let idle = self.batch.is_empty() && self.acks.is_empty() && {
            let inner = self.core.lock();
            !inner.running && inner.queue.is_empty() && inner.writer.is_some()
        };
        if idle {
            ack(self.usable());
            return;
        }
        self.acks.push(ack);
        self.schedule();
    }

    fn written(&mut self) {
        if self.batch.len() >= BATCH_BYTES {
            self.flush();
        } else {
            self.schedule();
        }
    }

    /// Make sure a `JournalFlush` is on its way: it lands behind the messages already in the
    /// mailbox, so everything they write joins one batch.
    fn schedule(&mut self) {
        if !self.flush_sent {
            self.flush_sent = (self.flush)();
        }
    }

    /// Hand the batch gathered so far to the writer (the datamanager's `JournalFlush`).
    pub(crate) fn flush(&mut self) {
        self.flush_sent = false;
        if self.batch.is_empty() && self.acks.is_empty() {
            return;
        }
        let job = Job::Batch {
            bytes: std::mem::replace(&mut self.batch, Vec::with_capacity(64 << 10)),
            acks: std::mem::take(&mut self.acks),
            seqs: std::mem::take(&mut self.seqs),
        };
        self.submit(job);
    }

    /// Give `job` to the writer: to the running task's queue, or to a new blocking task.
    fn submit(&mut self, job: Job) {
        let mut inner = self.core.lock();
        inner.queue.push(job);
        if inner.running {
            return;
        }
        let Some(writer) = inner.writer.take() else {
            // the writer was lost (a panic in it): nothing can be made durable any more
            let jobs = std::mem::take(&mut inner.queue);
            drop(inner);
            self.shared.fail("the journal's writer stopped".to_string());
            self.answer_only(jobs);
            return;
        };
        // Only acknowledgements waiting, and the writer idle: all before them is durable.
        let only_acks = inner
            .queue
            .iter()
            .all(|j| matches!(j, Job::Batch { bytes, .. } if bytes.is_empty()));
        if only_acks {
            let jobs = std::mem::take(&mut inner.queue);
            inner.writer = Some(writer);
            drop(inner);
            self.answer_only(jobs);
            return;
        }
        let jobs = std::mem::take(&mut inner.queue);
        // At `process` a batch only goes to the page cache: one write(2), done here — the
        // hop to the blocking pool and back cost more (see the writer module). Syncs, and
        // snapshots, stay on the pool.
        let inline = self.durability == Durability::Process
            && jobs.iter().all(|j| matches!(j, Job::Batch { .. }));
        inner.running = true;
        drop(inner);
        let (core, shared) = (self.core.clone(), self.shared.clone());
        if inline {
            // (nothing queues meanwhile: this datamanager is the one writing)
            core.drain(writer, jobs, shared);
        } else {
            tokio::task::spawn_blocking(move || core.drain(writer, jobs, shared));
        }
    }

    /// Run the acknowledgements of `jobs` (nothing of theirs to write): `Storage` if the
    /// journal failed.
    fn answer_only(&self, jobs: Vec<Job>) {
        for job in jobs {
            if let Job::Batch { acks, .. } = job {
                acks.into_iter().for_each(|ack| ack(self.usable()));
            }
        }
    }

    /// Whether the journal holds enough garbage for a snapshot of a store of `live` records.
    pub(crate) fn wants_snapshot(&self, live: usize) -> bool {
        self.puts >= SNAPSHOT_MIN && self.puts > 2 * live as u64
    }

    /// Hand the batch gathered so far, then a snapshot of `store` (the state right after it).
    /// A replicated datamanager's snapshot also says where its committed log ends, and
    /// writes its uncommitted entries again after it (the older segments, which hold them,
    /// are deleted).
    pub(crate) fn snapshot(
        &mut self,
        store: &Store,
        fences: &FenceTable,
        producers: &Producers,
        log: Option<LogAfterCommit<'_>>,
    ) {
        self.flush();
        let mut bytes = Vec::with_capacity(store.len() * 96 + 64);
        entry::encode_snap_open(&mut bytes, store.next_seq(), store.last_time());
        let mut n = 0;
        store.for_each_in_seq_order(|seq, timestamp, record| {
            let epoch = fences.newest(record.source).unwrap_or(0);
            entry::encode_parts(&mut bytes, seq, timestamp, epoch, (0, 0), record);
            n += 1;
        });
        // a replica's pairs up to its committed store only: those of its proposals after
        // it may be of entries the next leader cuts (`Producers::each_upto`)
        let upto = log.as_ref().map_or(u64::MAX, |((commit, _), _, _)| *commit);
        for (producer, pairs) in producers.each_upto(upto) {
            entry::encode_producer(&mut bytes, producer, pairs.into_iter());
        }
        if let Some((_, _, (at, members))) = &log {
            // the configuration committed then: the entry that made it goes with the
            // segments before (0: the configured one, nothing to keep)
            if *at > 0 {
                entry::encode_members(&mut bytes, *at, &members.voters, &members.learners);
            }
        }
        entry::encode_snap_end(&mut bytes, n);
        self.puts = n;
        if let Some(((seq, term), tail, _)) = log {
            entry::encode_term(&mut bytes, term);
            entry::encode_commit(&mut bytes, seq);
            self.term = Some(term);
            self.submit(Job::Snapshot { bytes });
            for op in tail {
                self.op(op);
            }
            self.flush();
            return;
        }
        self.submit(Job::Snapshot { bytes });
    }

    /// Hand what is left to the writer and wait for it to finish (a graceful stop: nothing
    /// journaled is left behind). The writer, and with it the directory's lock, is dropped.
    pub(crate) async fn close(mut self) {
        self.flush();
        loop {
            let idle = self.core.idle.notified();
            if !self.core.lock().running {
                return;
            }
            idle.await;
        }
    }
}

impl std::fmt::Debug for Journal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Journal")
            .field("dir", &self.dir)
            .field("durability", &self.durability)
            .field("puts", &self.puts)
            .finish_non_exhaustive()
    }
}

/// The journal directory of datamanager `name` under a node's data directory.
pub fn journal_dir(data_dir: &Path, name: &str) -> PathBuf {
    data_dir.join("dm").join(name)
}

#[cfg(test)]
mod tests {
    use super::{Durability, UnknownDurability};

    #[test]
    fn durabilities_parse_by_their_names() {
        for d in Durability::ALL {
            assert_eq!(d.as_str().parse::<Durability>(), Ok(d));
        }
        let e = "disk".parse::<Durability>().unwrap_err();
        assert_eq!(e, UnknownDurability("disk".into()));
        assert_eq!(
            e.to_string(),
            "unknown durability \"disk\": use memory, process or sync"
        );
    }
}
