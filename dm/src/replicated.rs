//! How a replicated datamanager's actor takes part in its copies' protocol
//! (`replica`): the primary proposes writes and answers them once committed, every
//! copy carries out what the protocol's core asks (persist the vote, send, journal, apply,
//! publish itself or step down), and a copy too far behind takes in a snapshot.

use super::actor::DmState;
use super::copy::{group, Incoming};
use super::error::DmError;
use super::messages::DmMsg;
use super::producers::Producers;
use super::record::NewRecord;
use super::replica::core::Out;
use super::replica::{apply, vote, InstallPart, OpBody, ReplicaMsg, SCOPE};
use super::store::{DmConfig, Store};
use marie_vocabulary::fence::FenceTable;
use marie_vocabulary::registry::{self, ModuleKind};
use ractor::{pg, ActorCell, ActorRef};
use std::time::Duration;

/// Records per snapshot part sent to a copy, at most.
const INSTALL_PART: usize = 2048;
/// Bytes of records per part, about (a part is one frame: ractor_cluster ends the session
/// on a frame above 16 MiB).
const INSTALL_BYTES: usize = super::page::PAGE_BYTES;
/// Producers per part of their pairs (at most [`super::producers::PER_PRODUCER`], 4096,
/// pairs each: ~1 MiB).
const INSTALL_PRODUCERS: usize = 16;

impl DmState {
    /// Whether this datamanager is a copy that is not the primary (it answers no client).
    pub(crate) fn is_copy(&self) -> bool {
        self.replica.as_ref().is_some_and(|c| !c.core.is_leader())
    }

    /// The primary's side of a store: propose the record. Its seq, once it is checked.
    pub(crate) fn propose_put(&mut self, record: NewRecord) -> Result<u64, DmError> {
        let now = self.clock.now();
        let Some(copy) = self.replica.as_mut() else {
            return Err(DmError::NotPrimary(self.name.clone()));
        };
        if !copy.core.is_leader() {
            return Err(DmError::NotPrimary(self.name.clone()));
        }
        let journal = self.journal.as_mut().expect("a copy has a journal");
        journal.usable()?;
        self.store.check(&record)?;
        copy.last_time = copy.last_time.max(now);
        let time_ns = u64::try_from(copy.last_time.as_nanos()).unwrap_or(u64::MAX);
        let who = (record.producer, record.producer_seq);
        let op = copy
            .core
            .propose(OpBody::Put { time_ns, record })
            .expect("the primary proposes");
        journal.op(op);
        let seq = op.seq;
        copy.noted = seq;
        if who.0 != 0 {
            self.producers.note(who.0, who.1, seq);
        }
        Ok(seq)
    }

    /// The primary's side of a delete: propose it; how many records it deletes.
    pub(crate) fn propose_delete(&mut self, seqs: Vec<u64>) -> Result<u64, DmError> {
        let Some(copy) = self.replica.as_mut() else {
            return Err(DmError::NotPrimary(self.name.clone()));
        };
        let n = seqs.len() as u64;
        if n == 0 {
            return Ok(0);
        }
        let op = copy
            .core
            .propose(OpBody::Delete { seqs })
            .ok_or_else(|| DmError::NotPrimary(self.name.clone()))?;
        self.journal.as_mut().expect("a copy has a journal").op(op);
        Ok(n)
    }

    /// Send an answer once everything proposed so far is committed and applied.
    pub(crate) fn after_commit(&mut self, ack: super::copy::Ack) {
        let copy = self.replica.as_mut().expect("called on a copy");
        let last = copy.core.last().0;
        copy.after_applied(last, ack);
    }

    /// The journal's batch is handed over: learn when it is durable, and send the copies
    /// what they lack.
    pub(crate) fn replica_flush(&mut self, myself: &ActorRef<DmMsg>) {
        let (Some(copy), Some(journal)) = (self.replica.as_mut(), self.journal.as_mut()) else {
            return;
        };
        if let Some((seq, term)) = journal.take_last_op() {
            let me = myself.clone();
            journal.after_durable(Box::new(move |durable| {
                if durable.is_ok() {
                    let _ = me.cast(DmMsg::ReplicaDurable { seq, term });
                }
            }));
        }
        let mut out = Vec::new();
        let now = copy.now();
        copy.core.replicate(now, &mut out);
        self.carry_out(myself, out);
    }

    /// Time passed.
    pub(crate) fn replica_tick(&mut self, myself: &ActorRef<DmMsg>) {
        self.refresh_peers(myself);
        let Some(copy) = self.replica.as_mut() else {
            return;
        };
        let mut out = Vec::new();
        let now = copy.now();
        copy.core.tick(now, &mut out);
        self.carry_out(myself, out);
    }

    /// The journal made the entries up to `seq` (of `term`) durable.
    pub(crate) fn replica_durable(&mut self, myself: &ActorRef<DmMsg>, seq: u64, term: u64) {
        let Some(copy) = self.replica.as_mut() else {
            return;
        };
        let mut out = Vec::new();
        copy.core.durable(seq, term, &mut out);
        self.carry_out(myself, out);
    }

    /// Which copies are reachable now (from the copies' groups): tell the core who came
    /// and went.
    pub(crate) fn refresh_peers(&mut self, myself: &ActorRef<DmMsg>) {
        let Some(copy) = self.replica.as_mut() else {
            return;
        };
        let now = copy.now();
        let mut out = Vec::new();
        for m in copy.core.others() {
            let found = pg::get_scoped_members(&SCOPE.to_string(), &group(&copy.name, &m))
                .into_iter()
                .find(|c| c.get_status() <= ractor::ActorStatus::Running);
            let known = copy.peers.get(&m).map(ActorCell::get_id);
            match (known, found) {
                (Some(a), Some(b)) if a == b.get_id() => {}
                (_, Some(b)) => {
                    copy.peers.insert(m.clone(), b);
                    tracing::debug!(dm = %copy.name, peer = %m, "replica: a copy is reachable");
                    copy.core.peer_up(&m, now, &mut out);
                }
                (Some(_), None) => {
                    copy.peers.remove(&m);
                    tracing::debug!(dm = %copy.name, peer = %m, "replica: a copy is gone");
                    copy.core.peer_down(&m, now);
                }
                (None, None) => {}
            }
        }
        self.carry_out(myself, out);
    }

    /// A message from another copy.
    pub(crate) fn replica_message(&mut self, myself: &ActorRef<DmMsg>, msg: ReplicaMsg) {
        let Some(copy) = self.replica.as_mut() else {
            return;
        };
        let now = copy.now();
        let mut out = Vec::new();
        match msg {
            ReplicaMsg::Install {
                term,
                leader,
                last_seq,
                last_term,
                part,
            } => {
                if copy
                    .core
                    .install_from(term, &leader, last_seq, now, &mut out)
                {
                    self.carry_out(myself, out);
                    self.take_part((last_seq, last_term), part, myself);
                    return;
                }
            }
            msg => {
                if let ReplicaMsg::Append { ops, .. } = &msg {
                    copy.arrived = Some(ops.raw());
                }
                copy.core.receive(msg, now, &mut out);
            }
        }
        self.carry_out(myself, out);
        if let Some(copy) = self.replica.as_mut() {
            copy.arrived = None;
        }
    }

    /// A part of a snapshot sent by the primary.
    fn take_part(&mut self, last: (u64, u64), part: InstallPart, myself: &ActorRef<DmMsg>) {
        let config: DmConfig = self.store.config().clone();
        let Some(copy) = self.replica.as_mut() else {
            return;
        };
        match part {
            InstallPart::Records { first, records } => {
                if first {
                    copy.incoming = Some(Incoming {
                        last,
                        store: Store::new(config),
                        fences: FenceTable::default(),
                        records: 0,
                        producers: Producers::default(),
                    });
                }
                let Some(inc) = copy.incoming.as_mut().filter(|i| i.last == last) else {
                    return;
                };
                for (seq, time_ns, record) in records {
                    let _ = inc.fences.admit_parts(&record.source, record.epoch);
                    if let Err(e) = inc
                        .store
                        .restore(seq, Duration::from_nanos(time_ns), record)
                    {
                        tracing::warn!(dm = %copy.name, seq, error = %e, "replica: a snapshot record refused");
                    }
                    inc.records += 1;
                }
            }
            InstallPart::Producers { producers } => {
                let Some(inc) = copy.incoming.as_mut().filter(|i| i.last == last) else {
                    return;
                };
                for (producer, pairs) in producers {
                    for (pseq, seq) in pairs {
                        inc.producers.note(producer, pseq, seq);
                    }
                }
            }
            InstallPart::End {
                records,
                last_time_ns,
            } => {
                let Some(mut inc) = copy.incoming.take().filter(|i| i.last == last) else {
                    return;
                };
                if inc.records != records {
                    tracing::warn!(dm = %copy.name, got = inc.records, sent = records, "replica: a snapshot came incomplete; dropped");
                    return;
                }
                inc.store
                    .raise_floor(last.0 + 1, Duration::from_nanos(last_time_ns));
                let table = std::mem::take(&mut inc.producers);
                tracing::info!(dm = %copy.name, records, upto = last.0, "replica: a snapshot from the primary taken in");
                self.store = inc.store;
                self.fences = inc.fences;
                self.producers = table;
                copy.core.installed(last.0, last.1);
                copy.snapshots_taken += 1;
                copy.last_time = copy.last_time.max(self.store.last_time());
                let journal = self.journal.as_mut().expect("a copy has a journal");
                journal.snapshot(
                    &self.store,
                    &self.fences,
                    &self.producers,
                    Some((last, Vec::new())),
                );
                let me = myself.clone();
                journal.after_durable(Box::new(move |durable| {
                    if durable.is_ok() {
                        let _ = me.cast(DmMsg::ReplicaDurable {
                            seq: last.0,
                            term: last.1,
                        });
                    }
                }));
            }
        }
    }

    /// Carry out what the core asked for, in order.
    fn carry_out(&mut self, myself: &ActorRef<DmMsg>, out: Vec<Out>) {
        // once it steps down, it still keeps its term and vote and sends its answers (a
        // vote it granted, a refusal), and then stops: a granted vote dropped with the
        // actor could cost the candidate its election
        let mut stopping: Option<String> = None;
        for o in out {
            let Some(copy) = self.replica.as_mut() else {
                return;
            };
            if stopping.is_some() && !matches!(o, Out::Persist | Out::Send(..)) {
                continue;
            }
            match o {
                Out::Persist => {
                    let (term, vote) = (copy.core.term(), copy.core.voted_for());
                    if let Err(e) = vote::save(&copy.dir, term, vote) {
                        // a copy that cannot keep its vote must not take part
                        tracing::error!(dm = %copy.name, error = %e, "replica: cannot persist its term and vote: stopping");
                        myself.stop(Some(format!("cannot persist its vote: {e}")));
                        return;
                    }
                }
                Out::Send(to, msg) => copy.send(&to, msg),
                Out::Truncate(seq) => {
                    if let Some(j) = self.journal.as_mut() {
                        j.truncate(seq);
                    }
                }
                Out::Journal(from, to) => {
                    let journal = self.journal.as_mut().expect("a copy has a journal");
                    for op in copy.core.ops(from, to) {
                        // the entries just arrived: their bytes as the primary encoded them
                        match copy.arrived.as_ref().and_then(|r| r.entry(op.seq, op.term)) {
                            Some(bytes) => journal.op_encoded(op, bytes),
                            None => journal.op(op),
                        }
                    }
                }
                Out::Apply(from, to) => {
                    let mut woken = Vec::new();
                    for op in copy.core.ops(from, to) {
                        if let Some(t) = op.time() {
                            copy.last_time = copy.last_time.max(t);
                        }
                        let producers = (op.seq > copy.noted).then_some(&mut self.producers);
                        let class = apply::apply(&mut self.store, &mut self.fences, producers, op);
                        if let Some(class) = class.filter(|_| !self.waits.is_empty()) {
                            woken.push((class.to_string(), op.seq));
                        }
                    }
                    for (class, seq) in woken {
                        self.wake(&class, seq);
                    }
                    if let Some(j) = self.journal.as_mut() {
                        j.commit(to);
                    }
                    let copy = self.replica.as_mut().expect("checked above");
                    let later = copy.acks.split_off(&(to + 1));
                    for ack in std::mem::replace(&mut copy.acks, later)
                        .into_values()
                        .flatten()
                    {
                        ack(Ok(()));
                    }
                }
                Out::Lead => {
                    // its uncommitted entries will all be committed (a primary never cuts
                    // its own log): a producer retrying one of them must get its seq, not
                    // a second copy. Those, and any committed not yet applied, are noted
                    // here, once (applying them notes nothing again).
                    let (applied, last) = (copy.core.applied(), copy.core.last().0);
                    copy.noted = last;
                    for op in copy.core.ops(applied + 1, last) {
                        apply::note(&mut self.producers, op);
                    }
                    tracing::info!(dm = %copy.name, node = %copy.core.me(), term = copy.core.term(), "replica: this copy is the primary");
                    if let Some(bus) = &copy.events {
                        bus.publish(marie_vocabulary::events::EventKind::DmPromoted {
                            dm: copy.name.clone(),
                            node: copy.core.me().to_string(),
                            term: copy.core.term(),
                        });
                    }
                    if let Err(e) = registry::publish(
                        ModuleKind::Datamanager,
                        self.id,
                        &self.name,
                        myself.get_cell(),
                    ) {
                        tracing::error!(dm = %self.name, error = %e, "replica: cannot publish the primary");
                    }
                }
                Out::StepDown(why) => {
                    // every client's reference dies with this actor: they follow the name
                    // to the new primary; the supervisor starts this copy again, from its
                    // journal, as a follower
                    tracing::warn!(dm = %copy.name, node = %copy.core.me(), term = copy.core.term(), why, "replica: no longer the primary: restarting as a copy");
                    if let Some(bus) = &copy.events {
                        bus.publish(marie_vocabulary::events::EventKind::DmFenced {
                            dm: copy.name.clone(),
                            node: copy.core.me().to_string(),
                            term: copy.core.term(),
                            why: why.clone(),
                        });
                    }
                    stopping = Some(why);
                }
                Out::Install(to, seq, term) => self.send_snapshot(&to, (seq, term)),
            }
        }
        if let Some(why) = stopping {
            myself.stop(Some(format!("no longer the primary: {why}")));
            return;
        }
        if let Some(copy) = self.replica.as_mut() {
            copy.core.trim();
        }
    }

    /// Send the copy on node `to` the committed store, which ends at `last`.
    fn send_snapshot(&mut self, to: &str, last: (u64, u64)) {
        let Some(copy) = self.replica.as_ref() else {
            return;
        };
        let (term, leader) = (copy.core.term(), copy.core.me().to_string());
        let part = |part| ReplicaMsg::Install {
            term,
            leader: leader.clone(),
            last_seq: last.0,
            last_term: last.1,
            part,
        };
        tracing::info!(dm = %copy.name, to, records = self.store.len(), upto = last.0, "replica: sending a snapshot to a copy too far behind");
        // sent part by part as the store is walked (a part is serialized when it is cast)
        let mut batch = Vec::with_capacity(INSTALL_PART);
        let mut first = true;
        let mut n = 0u64;
        let mut bytes = 0usize;
        let fences = &self.fences;
        self.store.for_each_in_seq_order(|seq, timestamp, r| {
            let record = NewRecord {
                source: r.source.to_string(),
                class: r.class.to_string(),
                sub1: r.sub1.map(str::to_string),
                sub2: r.sub2.map(str::to_string),
                payload: crate::Payload::from_bytes(r.payload.to_vec()),
                epoch: fences.newest(r.source).unwrap_or(0),
                producer: 0,
                producer_seq: 0,
            };
            let t = u64::try_from(timestamp.as_nanos()).unwrap_or(u64::MAX);
            bytes += record.wire_bytes();
            batch.push((seq, t, record));
            n += 1;
            if batch.len() == INSTALL_PART || bytes >= INSTALL_BYTES {
                bytes = 0;
                let records = std::mem::take(&mut batch);
                copy.send(to, part(InstallPart::Records { first, records }));
                first = false;
            }
        });
        copy.send(
            to,
            part(InstallPart::Records {
                first,
                records: batch,
            }),
        );
        let mut producers = Vec::with_capacity(INSTALL_PRODUCERS);
        for (p, pairs) in self.producers.each() {
            producers.push((p, pairs.iter().copied().collect()));
            if producers.len() == INSTALL_PRODUCERS {
                let producers = std::mem::take(&mut producers);
                copy.send(to, part(InstallPart::Producers { producers }));
            }
        }
        if !producers.is_empty() {
            copy.send(to, part(InstallPart::Producers { producers }));
        }
        copy.send(
            to,
            part(InstallPart::End {
                records: n,
                last_time_ns: u64::try_from(self.store.last_time().as_nanos()).unwrap_or(u64::MAX),
            }),
        );
    }
}
