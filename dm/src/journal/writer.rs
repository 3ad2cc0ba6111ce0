//! The journal's writer: it writes the datamanager's batches, makes them durable, and only
//! then acknowledges them — on tokio's blocking pool, one group of batches at a time.
//!
//! # Group commit
//! The datamanager gathers the records and deletes it handles into a batch, and hands the
//! batch over each time its mailbox has drained (a `JournalFlush` it sent itself lands
//! behind the messages waiting). One group of batches is written at a time: while it is
//! being written — and at `sync` durability made durable with one `fdatasync` — every batch
//! handed over queues, and the same blocking task takes them all as its next group (no hop
//! through the datamanager's mailbox in between); it ends once the queue is empty. The busier the datamanager, the
//! larger the group, and the cost of a sync is shared by every record in it. At `process`
//! durability there is no sync: a record acknowledged has been written to the OS, which
//! keeps it through `kill -9`; and a batch handed over while the writer is idle is written
//! by the datamanager itself, at once (one `write(2)` to the page cache: the hop to the
//! blocking pool and back cost two thread wake-ups per batch — on a replica of a replicated
//! datamanager, half of its context switches in the put-all bench: 13 k → 6 k per million
//! records, the leader's 23 k → 12 k).
//!
//! # Why the blocking pool, not a thread of its own
//! Under a simulated clock (tokio's paused time, `marie run --speed max`) the runtime moves
//! time forward whenever it has nothing to run, so a wait on a thread tokio does not know
//! would see every timeout fire at once. A blocking-pool task holds time still while it runs
//! (tokio does not auto-advance then): disk I/O takes no simulated time, as it should.
//!
//! # Failures
//! A write that fails (a full or unwritable disk) is cut back to the last whole batch, its
//! records are refused (the datamanager takes them out of its store, then their
//! acknowledgements say [`DmError::Storage`]), and the writer goes on: the next batch may
//! find room. A failed `fdatasync` cannot be retried (the kernel may have dropped the dirty
//! pages it could not write), so the journal is then *failed*: every later put is refused
//! until the datamanager is restarted and reads back what the disk really holds.

use super::lock::DirLock;
use super::segment;
use crate::error::DmError;
use std::fs::File;
use std::io::Write;
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, OnceLock};

/// An acknowledgement the writer runs once what came before it is durable (or refused).
pub(crate) type Ack = Box<dyn FnOnce(Result<(), DmError>) + Send>;

/// What the datamanager hands its writer.
pub(crate) enum Job {
    /// Entries to append, the acknowledgements waiting for them, and the seqs of the records
    /// they put (refused together if the write fails).
    Batch {
        bytes: Vec<u8>,
        acks: Vec<Ack>,
        seqs: Vec<u64>,
    },
    /// A whole snapshot: it starts a new segment, and the older ones go once it is durable.
    Snapshot { bytes: Vec<u8> },
}

/// What the writer and the datamanager both see.
#[derive(Debug, Default)]
pub(crate) struct Shared {
    /// Bytes of the journal on disk.
    pub bytes: AtomicU64,
    /// Why the journal failed (a sync failed), once it has; every later put is refused. Set
    /// once (the first failure is the one that counts); read on every put, lock-free.
    failed: OnceLock<String>,
}

impl Shared {
    /// The journal has failed: nothing more can be made durable.
    pub(crate) fn fail(&self, why: String) {
        if self.failed.set(why).is_ok() {
            tracing::error!(error = %self.failed.get().map_or("", String::as_str),
                "journal failed: puts are refused until the datamanager restarts");
        }
    }

    /// Why the journal failed, if it did.
    pub(crate) fn failure(&self) -> Option<&str> {
        self.failed.get().map(String::as_str)
    }
}

/// Why a batch could not be appended (its acknowledgements say it, as `Storage`).
#[derive(Debug, thiserror::Error)]
enum AppendError {
    /// The current segment is full and the next could not be opened.
    #[error("new segment in {}: {error}", dir.display())]
    Roll { dir: PathBuf, error: std::io::Error },
    /// The batch could not be written.
    #[error("write to {}: {error}", dir.display())]
    Write { dir: PathBuf, error: std::io::Error },
}

/// The files the journal writes, and how.
pub(crate) struct Writer {
    pub dir: PathBuf,
    pub segment: u64,
    pub file: File,
    pub len: u64,
    pub sync: bool,
    pub shared: Arc<Shared>,
    /// Called with the seqs of records whose write failed (the datamanager removes them).
    pub refused: Box<dyn Fn(Vec<u64>) + Send>,
    /// Held for as long as the writer may write.
    pub _lock: DirLock,
}

impl Writer {
    /// Do `jobs` in order: each run of batches written and synced as one group, then
    /// acknowledged; each snapshot after the batches before it.
    pub(crate) fn run(&mut self, jobs: Vec<Job>) {
        let mut group = Vec::new();
        for job in jobs {
            match job {
                Job::Batch { bytes, acks, seqs } => group.push((bytes, acks, seqs)),
                Job::Snapshot { bytes } => {
                    self.commit(std::mem::take(&mut group));
                    self.snapshot(bytes);
                }
            }
        }
        self.commit(group);
    }

    /// Write a group of batches, sync them once, and acknowledge them.
    fn commit(&mut self, group: Vec<(Vec<u8>, Vec<Ack>, Vec<u64>)>) {
        if group.is_empty() {
            return;
        }
        let failed = self.shared.failure().map(str::to_string);
        let mut written = Vec::with_capacity(group.len());
        let mut wrote = false;
        for (bytes, acks, seqs) in group {
            let outcome = match &failed {
                Some(why) => Err(why.clone()),
                None => self.append(&bytes).map_err(|e| e.to_string()),
            };
            match outcome {
                Ok(()) => {
                    wrote |= !bytes.is_empty();
                    written.push((acks, seqs));
                }
                Err(why) => self.refuse(acks, seqs, &why),
            }
        }
        if self.sync && wrote {
            if let Err(e) = self.file.sync_data() {
                let why = format!("fdatasync of {}: {e}", self.dir.display());
                self.shared.fail(why.clone());
                for (acks, seqs) in written {
                    self.refuse(acks, seqs, &why);
                }
                return;
            }
        }
        for (acks, _) in written {
            for ack in acks {
                ack(Ok(()));
            }
        }
    }

    /// Refuse a batch: its records are taken out first (the message is in the datamanager's
    /// mailbox before any producer hears of the refusal, so nothing it asks next sees them),
    /// then its acknowledgements say why.
    pub(crate) fn refuse(&self, acks: Vec<Ack>, seqs: Vec<u64>, why: &str) {
        if !seqs.is_empty() {
            (self.refused)(seqs);
        }
        for ack in acks {
            ack(Err(DmError::Storage(why.to_string())));
        }
    }

    /// Append one batch to the current segment (a new one if it is full); on failure cut the
    /// segment back to where the batch began.
    fn append(&mut self, bytes: &[u8]) -> Result<(), AppendError> {
        if bytes.is_empty() {
            return Ok(());
        }
        if self.len >= segment::SEGMENT_BYTES {
            self.roll().map_err(|error| AppendError::Roll {
                dir: self.dir.clone(),
                error,
            })?;
        }
        match self.file.write_all(bytes) {
            Ok(()) => {
                self.len += bytes.len() as u64;
                self.shared
                    .bytes
                    .fetch_add(bytes.len() as u64, Ordering::Relaxed);
                Ok(())
            }
            Err(error) => {
                let why = AppendError::Write {
                    dir: self.dir.clone(),
                    error,
                };
                if let Err(cut) = self.file.set_len(self.len) {
                    // a torn batch would hide every later one from recovery
                    self.shared
                        .fail(format!("{why}; and cutting it back failed: {cut}"));
                }
                Err(why)
            }
        }
    }

    /// Close the current segment (durably at `sync`) and open the next.
    fn roll(&mut self) -> std::io::Result<()> {
        if self.sync {
            self.file.sync_data()?;
        }
        let file = segment::open(&self.dir, self.segment + 1)?;
        if self.sync {
            segment::sync_dir(&self.dir)?;
        }
        self.segment += 1;
        // its format header: what a torn batch is cut back to, at the least
        self.len = file.metadata()?.len();
        self.file = file;
        Ok(())
    }

    /// Write `bytes` (a whole snapshot) as a new segment, make it durable, then delete the
    /// segments before it. A snapshot that cannot be written is dropped: the journal stays as
    /// it was, only longer.
    fn snapshot(&mut self, bytes: Vec<u8>) {
        if self.shared.failure().is_some() {
            return;
        }
        let next = self.segment + 1;
        let written = segment::open(&self.dir, next).and_then(|mut f| {
            f.write_all(&bytes)?;
            f.sync_data()?;
            segment::sync_dir(&self.dir)?;
            Ok(f)
        });
        match written {
            Ok(file) => {
                let old: Vec<_> = segment::list(&self.dir)
                    .unwrap_or_default()
                    .into_iter()
                    .filter(|(n, _)| *n < next)
                    .collect();
                for (_, path) in &old {
                    if let Err(e) = std::fs::remove_file(path) {
                        tracing::warn!(path = %path.display(), error = %e, "journal: an old segment could not be removed");
                    }
                }
                let _ = segment::sync_dir(&self.dir);
                self.segment = next;
                self.len = file.metadata().map_or(bytes.len() as u64, |m| m.len());
                self.file = file;
                self.shared.bytes.store(self.len, Ordering::Relaxed);
                tracing::debug!(journal = %self.dir.display(), bytes = self.len, removed = old.len(), "journal snapshot");
            }
            Err(e) => {
                tracing::warn!(journal = %self.dir.display(), error = %e, "journal: a snapshot could not be written; the journal keeps growing");
                let _ = std::fs::remove_file(segment::path(&self.dir, next));
            }
        }
    }
}
