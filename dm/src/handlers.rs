//! What a datamanager does with each message of the dm-interface and of its journal: one
//! `on_*` method per [`DmMsg`] variant, called by the actor's shell (`actor.rs`). The
//! replication protocol's messages are handled in `replicated.rs`.

use super::messages::{DmMsg, DmStats, StoreDigest};
use super::page::{self, Page};
use super::query::Query;
use super::record::{NewRecord, Record};
use super::state::DatamanagerState;
use super::storage::Storage;
use super::waits::WaitReply;
use super::DmError;
use marie_vocabulary::run::FaultKind;
use ractor::{ActorRef, RpcReplyPort};

impl DatamanagerState {
    /// A request of the dm-interface, where it is answered (a datamanager without replicas,
    /// or a replicated one's leader): each to its handler; the reads through `read`, which a
    /// leader answers once it knows it leads.
    pub(crate) fn on_request(&mut self, myself: &ActorRef<DmMsg>, msg: DmMsg) {
        match msg {
            DmMsg::Put { record } => self.on_put(myself, record),
            DmMsg::PutBatch { records } => self.on_put_batch(myself, records),
            DmMsg::Store { record, reply } => self.on_store(*record, reply),
            DmMsg::Delete { query, reply } => self.on_delete(&query, reply),
            read @ (DmMsg::Select { .. }
            | DmMsg::SelectPage { .. }
            | DmMsg::SelectWait { .. }
            | DmMsg::SelectWaitPage { .. }
            | DmMsg::Stats { .. }) => self.read(myself, read),
            DmMsg::ChangeReplicas { change, reply } => {
                self.on_change_replicas(myself, &change, reply);
            }
            other => {
                tracing::error!(dm = %self.name, msg = ?other, "not a request of the dm-interface: dropped")
            }
        }
    }

    /// `Put`: store it; a refusal is counted and logged (a cast has no answer).
    pub(crate) fn on_put(&mut self, myself: &ActorRef<DmMsg>, record: NewRecord) {
        self.put(myself, record);
    }

    /// `PutBatch`: store each in order, as `Put` does.
    pub(crate) fn on_put_batch(&mut self, myself: &ActorRef<DmMsg>, records: Vec<NewRecord>) {
        records.into_iter().for_each(|r| self.put(myself, r));
    }

    /// `Store`: store it, and answer its seq once it is durable (or why it was refused).
    pub(crate) fn on_store(
        &mut self,
        record: NewRecord,
        reply: RpcReplyPort<Result<u64, DmError>>,
    ) {
        let outcome = self.store(record);
        if let Err(e) = &outcome {
            tracing::debug!(dm = %self.name, error = %e, "store refused");
        }
        self.acknowledge(reply, move |durable| durable.and(outcome));
    }

    /// `Select`: every matching record, at once.
    pub(crate) fn on_select(&self, query: &Query, reply: RpcReplyPort<Vec<Record>>) {
        let _ = reply.send(self.store.select(query));
    }

    /// `SelectPage`: the first page of what `Select` answers.
    pub(crate) fn on_select_page(&self, query: &Query, max_bytes: u64, reply: RpcReplyPort<Page>) {
        let _ = reply.send(self.store.select_page(query, page::bound(max_bytes)));
    }

    /// `SelectWait`: answered at once if a record matches, else when one is stored or the
    /// wait passes.
    pub(crate) fn on_select_wait(
        &mut self,
        myself: &ActorRef<DmMsg>,
        query: Query,
        timeout_ms: u64,
        reply: RpcReplyPort<Vec<Record>>,
    ) {
        self.select_wait(myself, query, timeout_ms, WaitReply::Whole(reply));
    }

    /// `SelectWaitPage`: `SelectWait` answered with a first page.
    pub(crate) fn on_select_wait_page(
        &mut self,
        myself: &ActorRef<DmMsg>,
        query: Query,
        timeout_ms: u64,
        max_bytes: u64,
        reply: RpcReplyPort<Page>,
    ) {
        let max_bytes = page::bound(max_bytes);
        let reply = WaitReply::Paged { reply, max_bytes };
        self.select_wait(myself, query, timeout_ms, reply);
    }

    /// `WaitExpired`: the wait's time is up; it is answered with nothing (if it still waits).
    pub(crate) fn on_wait_expired(&mut self, id: u64) {
        if let Some(waiter) = self.waits.take(id) {
            tracing::trace!(dm = %self.name, wait = id, "wait timed out");
            waiter.reply.nothing();
        }
    }

    /// `Delete`: delete what matches, and answer how many once it is durable (on a
    /// replicated datamanager: proposed, and answered once committed).
    pub(crate) fn on_delete(&mut self, query: &Query, reply: RpcReplyPort<u64>) {
        if self.storage.is_replicated() {
            self.propose_delete_of(query, reply);
            return;
        }
        let seqs = self.store.delete_seqs(query);
        tracing::debug!(dm = %self.name, deleted = seqs.len(), "delete");
        if let Some(journal) = self.storage.journal_mut() {
            journal.delete(&seqs);
        }
        // a delete that could not be journaled still happened in memory; its count
        // stands (the records come back at the next start, which the log says)
        let n = seqs.len() as u64;
        let name = self.name.clone();
        self.acknowledge(reply, move |durable| {
            if let Err(e) = durable {
                tracing::warn!(dm = %name, error = %e, "a delete was not journaled");
            }
            n
        });
    }

    /// `Stats`: what it holds. It returns a remote producer's credits, so it acknowledges
    /// the puts before it; a leader's numbers are taken once those are committed and
    /// applied (`AnswerStats`), not as they were when it was asked.
    pub(crate) fn on_stats(&mut self, myself: &ActorRef<DmMsg>, reply: RpcReplyPort<DmStats>) {
        if let Some(leader) = self.leader_mut() {
            let me = myself.clone();
            leader.after_commit(Box::new(move |_| {
                let _ = me.cast(DmMsg::AnswerStats { reply });
            }));
            return;
        }
        let stats = self.stats();
        self.acknowledge(reply, move |_| stats);
    }

    /// `AnswerStats`: a leader's `Stats`, answered now that the puts before it are applied;
    /// and `ReplicaStats`: this replica's numbers, now.
    pub(crate) fn on_answer_stats(&self, reply: RpcReplyPort<DmStats>) {
        let _ = reply.send(self.stats());
    }

    /// `JournalFlush`: hand the journal's batch to its writer (a replica also sends the
    /// others what they lack), and snapshot the journal once it holds mostly garbage.
    pub(crate) fn on_journal_flush(&mut self, myself: &ActorRef<DmMsg>) {
        self.replica_flush(myself);
        if let Some(journal) = self.storage.journal_mut() {
            journal.flush();
        }
        self.snapshot_if_due();
    }

    /// Snapshot the journal if it holds mostly garbage (`Journal::wants_snapshot`): after
    /// a flush, and at the start on the journal just read back — a replay goes through every
    /// put since the last snapshot, so a journal left long (a node killed before its
    /// journal was due) made every start after it replay it all again, and leave what the
    /// replay decoded and dropped scattered in the process's memory. True if it took one.
    pub(crate) fn snapshot_if_due(&mut self) -> bool {
        let (journal, replica) = match &mut self.storage {
            Storage::Memory => return false,
            Storage::Journaled(journal) => (journal, None),
            Storage::Replicated { journal, replica } => (journal, Some(&*replica)),
        };
        if !journal.wants_snapshot(self.store.len()) {
            return false;
        }
        let log = replica.map(|r| r.log_after_commit());
        journal.snapshot(&self.store, &self.fences, &self.producers, log);
        true
    }

    /// `Digest`: a digest of its records, and up to which seq (a replica's: what it applied).
    pub(crate) fn on_digest(&self, reply: RpcReplyPort<StoreDigest>) {
        let upto = match self.storage.replica() {
            Some(r) => r.core.applied(),
            None => self.store.next_seq().saturating_sub(1),
        };
        let _ = reply.send(StoreDigest {
            upto,
            records: self.store.len() as u64,
            digest: self.store.digest(),
        });
    }

    /// `JournalRefused`: the writer could not write these records; they are taken out and
    /// counted refused (their acknowledgements said so).
    pub(crate) fn on_journal_refused(&mut self, seqs: &[u64]) {
        let n = self.store.remove_seqs(seqs);
        self.refused_puts += seqs.len() as u64;
        tracing::warn!(dm = %self.name, records = seqs.len(), removed = n, "records refused: the journal could not write them");
    }

    /// `Inject`: commit `fault` on purpose; its supervisor restarts it.
    pub(crate) async fn on_inject(&mut self, myself: &ActorRef<DmMsg>, fault: FaultKind) {
        tracing::warn!(dm = %self.name, actor = %myself.get_id(), %fault, "injected fault");
        match fault {
            FaultKind::Panic => panic!("injected fault: datamanager {} panics", self.name),
            // Only a kill ends this (ractor's kill signal interrupts a running handler).
            FaultKind::Hang => std::future::pending::<()>().await,
            FaultKind::Kill => myself.kill(),
            // the injector refuses these (`FaultKind::hits_datamanager`); a new
            // operation-only kind needs nothing here
            _ => tracing::warn!(%fault, "not a datamanager's fault: ignored"),
        }
    }

    /// A request this replica cannot answer (not leading, and no leader known for an
    /// election timeout; or a read whose leader was not confirmed in time): it is not
    /// answered — its reply port is dropped, so a `DmClient` follows the datamanager's name
    /// to the leader — and a put is counted refused.
    pub(crate) fn refuse(&mut self, msg: DmMsg) {
        match msg {
            DmMsg::Put { .. } | DmMsg::PutBatch { .. } => {
                self.refused_puts += 1;
                tracing::debug!(dm = %self.name, "a put reached a replica, not the leader: refused");
            }
            other => drop(other),
        }
    }
}
