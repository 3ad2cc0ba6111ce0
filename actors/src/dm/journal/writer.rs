//! The journal's writer: a thread of its own that writes the datamanager's batches, makes
//! them durable, and only then acknowledges them.
//!
//! # Group commit
//! The datamanager hands over a batch each time its mailbox has drained of puts (a
//! `JournalFlush` it sent itself lands behind them). The writer takes *every* batch waiting
//! in its queue, writes them in order and — at `sync` durability — makes them durable with one
//! `fdatasync`; then it runs their acknowledgements. While one `fdatasync` runs, the next
//! group gathers: the busier the datamanager, the larger the group, and the cost of a sync
//! is shared by every record in it. At `process` durability the same path skips the sync: a
//! record acknowledged has been written to the OS, which keeps it through `kill -9`.
//!
//! # Failures
//! A write that fails (a full or unwritable disk) is cut back to the last whole batch, its
//! records are refused (their acknowledgements say [`DmError::Storage`], and the datamanager
//! takes them out of its store), and the writer goes on: the next batch may find room. A
//! failed `fdatasync` cannot be retried (the kernel may have dropped the dirty pages it could
//! not write), so the journal is then *failed*: every later put is refused until the
//! datamanager is restarted and reads back what the disk really holds.

use super::lock::DirLock;
use super::segment;
use crate::dm::error::DmError;
use std::fs::File;
use std::io::Write;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::Receiver;
use std::sync::{Arc, Mutex};

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
    /// Batches the writer has finished (written, or refused).
    pub done: AtomicU64,
    /// Bytes of the journal on disk.
    pub bytes: AtomicU64,
    /// Set when a sync failed: why; every later put is refused.
    pub failed: Mutex<Option<String>>,
    pub is_failed: AtomicBool,
}

impl Shared {
    pub(crate) fn fail(&self, why: String) {
        tracing::error!(error = %why, "journal failed: puts are refused until the datamanager restarts");
        *self.failed.lock().unwrap_or_else(|e| e.into_inner()) = Some(why);
        self.is_failed.store(true, Ordering::Release);
    }

    /// Why the journal failed, if it did.
    pub(crate) fn failure(&self) -> Option<String> {
        if !self.is_failed.load(Ordering::Acquire) {
            return None;
        }
        self.failed
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }
}

/// The writer thread's state.
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
    pub lock: DirLock,
}

/// Largest group written before its acknowledgements go out.
const GROUP_BYTES: usize = 8 << 20;

impl Writer {
    /// Run until the datamanager drops its end of the queue and every job is done.
    pub(crate) fn run(mut self, jobs: Receiver<Job>) {
        let name = self.lock.dir().display().to_string();
        while let Ok(first) = jobs.recv() {
            let mut group = Vec::new();
            let mut size = 0;
            let mut next = Some(first);
            while let Some(job) = next.take() {
                match job {
                    Job::Snapshot { bytes } => {
                        self.commit(std::mem::take(&mut group));
                        size = 0;
                        self.snapshot(bytes);
                    }
                    Job::Batch { bytes, acks, seqs } => {
                        size += bytes.len();
                        group.push((bytes, acks, seqs));
                    }
                }
                if size < GROUP_BYTES {
                    next = jobs.try_recv().ok();
                }
            }
            self.commit(group);
        }
        tracing::debug!(journal = %name, "journal writer done");
    }

    /// Write a group of batches, sync them once, and acknowledge them.
    fn commit(&mut self, group: Vec<(Vec<u8>, Vec<Ack>, Vec<u64>)>) {
        if group.is_empty() {
            return;
        }
        let failed = self.shared.failure();
        let mut written = Vec::with_capacity(group.len());
        for (bytes, acks, seqs) in group {
            let outcome = match &failed {
                Some(why) => Err(why.clone()),
                None => self.append(&bytes),
            };
            match outcome {
                Ok(()) => written.push((acks, seqs)),
                Err(why) => self.refuse(acks, seqs, &why),
            }
        }
        if self.sync && !written.is_empty() {
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
            self.shared.done.fetch_add(1, Ordering::AcqRel);
        }
    }

    /// Refuse a batch: its records are taken out first (the message is in the datamanager's
    /// mailbox before any producer hears of the refusal, so nothing it asks next sees them),
    /// then its acknowledgements say why.
    fn refuse(&self, acks: Vec<Ack>, seqs: Vec<u64>, why: &str) {
        if !seqs.is_empty() {
            (self.refused)(seqs);
        }
        for ack in acks {
            ack(Err(DmError::Storage(why.to_string())));
        }
        self.shared.done.fetch_add(1, Ordering::AcqRel);
    }

    /// Append one batch to the current segment (a new one if it is full); on failure cut the
    /// segment back to where the batch began.
    fn append(&mut self, bytes: &[u8]) -> Result<(), String> {
        if bytes.is_empty() {
            return Ok(());
        }
        if self.len >= segment::SEGMENT_BYTES {
            self.roll()
                .map_err(|e| format!("new segment in {}: {e}", self.dir.display()))?;
        }
        match self.file.write_all(bytes) {
            Ok(()) => {
                self.len += bytes.len() as u64;
                self.shared
                    .bytes
                    .fetch_add(bytes.len() as u64, Ordering::Relaxed);
                Ok(())
            }
            Err(e) => {
                let why = format!("write to {}: {e}", self.dir.display());
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
        self.file = file;
        self.len = 0;
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
                self.file = file;
                self.len = bytes.len() as u64;
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
