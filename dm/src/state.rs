//! What a datamanager holds while it runs, and the steps its handlers share: storing a
//! record, waking the waits it satisfies, acknowledging a write once it is as durable as
//! the storage promises, telling what its puts applied, and telling its numbers. What it
//! leaves when it ends — however it ends — is in its `Drop`.

use super::applied::{self, Tally};
use super::error::DmError;
use super::heir::{Estate, Heir, Inherited};
use super::journal::Recovery;
use super::messages::{DmMsg, DmStats, ReplicaStats};
use super::producers::Producers;
use super::query::Query;
use super::record::NewRecord;
use super::storage::Storage;
use super::store::Store;
use super::waits::{TimerGuard, WaitReply, Waiter, Waits};
use marie_vocabulary::clock::{cast_after, SharedClock};
use marie_vocabulary::events::{EventBus, EventKind};
use marie_vocabulary::fence::FenceTable;
use marie_vocabulary::replica::ReplicaRole;
use ractor::{ActorRef, RpcReplyPort};
use std::time::Duration;

/// State of a [`Datamanager`](super::Datamanager).
pub struct DatamanagerState {
    pub(crate) id: u32,
    pub(crate) name: String,
    pub(crate) clock: SharedClock,
    pub(crate) store: Store,
    pub(crate) waits: Waits,
    pub(crate) refused_puts: u64,
    /// The newest epoch per source: records of a replaced incarnation are refused.
    pub(crate) fences: FenceTable,
    /// In memory only, in a journal, or in a journal as one replica of several.
    pub(crate) storage: Storage,
    /// What the start read back from the journal.
    pub(crate) recovery: Option<Recovery>,
    /// What each producer stored lately: a retried put is stored once.
    pub(crate) producers: Producers,
    /// Retried puts answered with the seq their first copy got.
    pub(crate) duplicates: u64,
    /// At `memory`: where its store goes when it ends, for its next incarnation (`heir`).
    pub(crate) heir: Option<Heir>,
    /// What its start took from its previous incarnation, if anything (at `memory`).
    pub(crate) inherited: Option<Inherited>,
    /// Where it tells what it does on its own: a class that starts dropping records by
    /// retention (`dm_retention`), what its puts applied (`applied`); a node gives its
    /// bus. `None`: it tells nothing.
    pub(crate) events: Option<EventBus>,
    /// What its puts applied since it last told.
    pub(crate) applied: Tally,
    /// The timer that tells the tally (set while the tally holds something).
    pub(crate) applied_timer: Option<TimerGuard>,
}

impl Drop for DatamanagerState {
    /// However the actor ended — stopped, killed, or panicked (when ractor runs no
    /// `post_stop`) — a memory datamanager tells what its puts applied, and leaves its
    /// records to its heir.
    fn drop(&mut self) {
        if matches!(self.storage, Storage::Memory) {
            self.tell_applied();
        }
        if let Some(heir) = self.heir.take() {
            let store = Store::new(self.store.config().clone());
            heir.leave(Estate {
                store: std::mem::replace(&mut self.store, store),
                producers: std::mem::take(&mut self.producers),
                fences: std::mem::take(&mut self.fences),
            });
        }
    }
}

impl std::fmt::Debug for DatamanagerState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("DatamanagerState")
            .field("id", &self.id)
            .field("name", &self.name)
            .field("records", &self.store.len())
            .field("refused_puts", &self.refused_puts)
            .finish_non_exhaustive()
    }
}

/// A retention bound as stats tell it.
fn bound(n: usize) -> u64 {
    u64::try_from(n).unwrap_or(u64::MAX)
}

impl DatamanagerState {
    /// What it holds, as a `Stats` request is answered.
    pub(crate) fn stats(&self) -> DmStats {
        DmStats {
            id: self.id,
            name: self.name.clone(),
            records: self.store.len() as u64,
            classes: self.store.class_counts(),
            first_seq: self.store.first_seq(),
            last_seq: self.store.last_seq(),
            next_seq: self.store.next_seq(),
            pending_waits: self.waits.len() as u64,
            dropped: self.store.dropped(),
            deleted: self.store.deleted(),
            refused_puts: self.refused_puts,
            fenced: self.fences.refused(),
            durability: self.storage.durability(),
            journal_bytes: self.storage.journal_bytes(),
            recovery: self.recovery.clone(),
            duplicates: self.duplicates,
            inherited: self.inherited,
            window: self.window() as u64,
            replica: self.storage.replica().map(|r| {
                let (core, last) = (&r.core, r.core.last().0);
                ReplicaStats {
                    node: core.me().to_string(),
                    role: if core.is_leader() {
                        ReplicaRole::Leader
                    } else {
                        ReplicaRole::Follower
                    },
                    term: core.term(),
                    leader: core.leader().map(str::to_string),
                    commit: core.commit(),
                    last,
                    lag: core.lag(),
                    snapshots_taken: r.snapshots_taken,
                    members: core.members().voters.clone(),
                    learners: core.members().learners.clone(),
                    removed: core.is_removed(),
                    // the replicas of its configurations (not an outsider being told)
                    reachable: {
                        let others = core.others();
                        r.peers
                            .keys()
                            .filter(|p| others.contains(p))
                            .cloned()
                            .collect()
                    },
                    held: {
                        let (tail_entries, tail_bytes) = core.tail_held();
                        crate::messages::Held {
                            records: self.store.len() as u64,
                            record_bytes: self.store.record_bytes(),
                            tail_entries: tail_entries as u64,
                            tail_bytes: tail_bytes as u64,
                            producer_pairs: self.producers.pairs() as u64,
                        }
                    },
                }
            }),
            retention: Some(bound(self.store.config().default_retention)),
            dropped_by_class: self.store.dropped_by_class(),
            retention_by_class: self
                .store
                .config()
                .retention
                .iter()
                .map(|(class, n)| (class.clone(), bound(*n)))
                .collect(),
        }
    }

    /// The window of credits it grants a remote producer (`credits`): wider for a
    /// replicated one, whose acknowledgements wait for its replicas.
    pub(crate) fn window(&self) -> usize {
        if self.storage.is_replicated() {
            super::credits::REPLICATED_WINDOW
        } else {
            super::credits::WINDOW
        }
    }

    /// A put (no answer): stored — and tallied, to be told (`applied`) — or counted and
    /// logged as refused.
    pub(crate) fn put(&mut self, myself: &ActorRef<DmMsg>, record: NewRecord) {
        let tallied = (self.events.is_some() && !self.storage.is_replicated()).then(|| {
            let content = applied::content(&record.source, record.payload.as_bytes());
            (record.class.clone(), content)
        });
        let next = self.store.next_seq();
        match self.store(record) {
            // a seq below the next one: a retried put, stored (and tallied) once already
            Ok(seq) if seq >= next => {
                if let Some((class, content)) = tallied {
                    self.tally(myself, &class, seq, content);
                }
            }
            Ok(_) => {}
            Err(e) => {
                self.refused_puts += 1;
                tracing::warn!(dm = %self.name, error = %e, "put refused");
            }
        }
    }

    /// Tally record `seq` of `class` as applied: told with the others once the timer goes
    /// off, or now if the tally is full.
    fn tally(&mut self, myself: &ActorRef<DmMsg>, class: &str, seq: u64, content: u64) {
        if self.applied.is_empty() {
            let timer = cast_after(
                &self.clock,
                applied::TELL_EVERY,
                myself,
                DmMsg::TellApplied {},
            );
            self.applied_timer = Some(TimerGuard(timer));
        }
        self.applied
            .note(class, seq, applied::fingerprint(seq, content));
        if self.applied.is_full() {
            self.tell_applied();
        }
    }

    /// Tell what the puts applied since it last told (`dm_applied`), once it is as
    /// durable as the storage promises.
    pub(crate) fn tell_applied(&mut self) {
        self.applied_timer = None;
        if self.applied.is_empty() {
            return;
        }
        let spans = self.applied.take();
        let Some(bus) = self.events.clone() else {
            return;
        };
        let kind = EventKind::DmApplied {
            dm: self.name.clone(),
            spans,
        };
        match &mut self.storage {
            Storage::Memory => {
                bus.publish(kind);
            }
            Storage::Journaled(journal) => journal.after_durable(Box::new(move |durable| {
                if durable.is_ok() {
                    bus.publish(kind);
                }
            })),
            // not tallied (see `applied`)
            Storage::Replicated { .. } => {}
        }
    }

    /// Store `record`: its seq, or why it was refused. A retried put gets the seq its first
    /// replica got; a replicated datamanager's leader proposes it (applied, and its waits
    /// woken, once committed).
    pub(crate) fn store(&mut self, record: NewRecord) -> Result<u64, DmError> {
        self.fences
            .admit_parts(&record.source, record.epoch)
            .map_err(DmError::Fenced)?;
        let who = (record.producer, record.producer_seq);
        if who.0 != 0 {
            if let Some(seq) = self.producers.seen(who.0, who.1) {
                self.duplicates += 1;
                tracing::debug!(dm = %self.name, seq, source = %record.source, "a retried put: stored once already");
                return Ok(seq);
            }
        }
        if self.storage.is_replicated() {
            return self.propose_put(record);
        }
        // The class is needed after the insert only if someone waits (the common high-rate
        // case has no waits and pays nothing).
        let class = (!self.waits.is_empty()).then(|| record.class.clone());
        let seq = match self.storage.journal_mut() {
            None => self.store.insert(record, self.clock.now())?,
            Some(journal) => {
                // on disk before it is indexed: what a select can see, the journal holds
                journal.usable()?;
                self.store.check(&record)?;
                let (seq, timestamp) = self.store.stamp(self.clock.now());
                journal.put(seq, timestamp, &record);
                self.store.restore(seq, timestamp, record)?;
                seq
            }
        };
        if who.0 != 0 {
            self.producers.note(who.0, who.1, seq);
        }
        if let Some(class) = class {
            self.wake(&class, seq);
        }
        Ok(seq)
    }

    /// Tell of every class that dropped its first record by retention since the last call:
    /// a warning and a `dm_retention` event, once per class (a follower's store drops what
    /// its leader's does, which the leader tells). Retention is never silent.
    pub(crate) fn tell_retention(&mut self) {
        let full = self.store.take_newly_full();
        if full.is_empty() || self.is_follower() {
            return;
        }
        let node = marie_vocabulary::registry::local_node_name();
        for (class, bound) in full {
            tracing::warn!(dm = %self.name, %class, bound, "a class holds its retention bound: storing more drops its oldest records");
            if let Some(bus) = &self.events {
                bus.publish(marie_vocabulary::events::EventKind::DmRetention {
                    dm: self.name.clone(),
                    node: node.clone(),
                    class: class.to_string(),
                    bound: bound as u64,
                });
            }
        }
    }

    /// Answer the waits that the record `seq` of `class` satisfies.
    pub(crate) fn wake(&mut self, class: &str, seq: u64) {
        let store = &self.store;
        let ready = self
            .waits
            .take_satisfied(class, |query| store.matches_in(class, seq, query));
        for waiter in ready {
            let records = waiter.reply.answer(&self.store, &waiter.query);
            tracing::trace!(dm = %self.name, wait = waiter.id, records, "wait answered");
        }
    }

    /// Send an answer that acknowledges writes: at once without a journal, else once what
    /// came before it is durable — on a replica, once everything proposed before it is
    /// committed. `answer` is given whether it is (`Err(Storage)` if it cannot be made so).
    pub(crate) fn acknowledge<T: Send + 'static>(
        &mut self,
        reply: RpcReplyPort<T>,
        answer: impl FnOnce(Result<(), DmError>) -> T + Send + 'static,
    ) {
        let ack = move |done: Result<(), DmError>| {
            let _ = reply.send(answer(done));
        };
        match &mut self.storage {
            Storage::Memory => ack(Ok(())),
            Storage::Journaled(journal) => journal.after_durable(Box::new(ack)),
            Storage::Replicated { replica, .. } => replica.after_commit(Box::new(ack)),
        }
    }

    /// Answer `query` now if a record matches it (or it does not wait), else once one is
    /// stored or `timeout_ms` pass on its clock.
    pub(crate) fn select_wait(
        &mut self,
        myself: &ActorRef<DmMsg>,
        query: Query,
        timeout_ms: u64,
        reply: WaitReply,
    ) {
        if timeout_ms == 0 || self.store.matches_any(&query) {
            reply.answer(&self.store, &query);
            return;
        }
        if reply.is_closed() {
            return;
        }
        let id = self.waits.next_id();
        let timer = cast_after(
            &self.clock,
            Duration::from_millis(timeout_ms),
            myself,
            DmMsg::WaitExpired { id },
        );
        self.waits.add(Waiter {
            id,
            query,
            reply,
            _timer: Some(TimerGuard(timer)),
        });
    }
}
