//! How a replicated datamanager's actor takes part in its replicas' protocol
//! (`replica`): the leader proposes writes and answers them once committed, every
//! replica carries out what the protocol's core asks (persist the vote, send, journal,
//! apply, publish itself or step down), and a replica too far behind takes in a snapshot.
//!
//! A change of role is a change of this actor's state, never a restart: elected, it is
//! published under the datamanager's name and id; stepping down, it withdraws that
//! publication and sends on every caller whose answer it still owed (the writes waiting
//! for a commit, the reads waiting for the leader to be confirmed, the waits filed) — their
//! reply ports dropped, so a `DmClient` follows the name to the new leader and asks again
//! there (a store sent again is stored once: `producers`). The actor, its `ActorRef` and
//! every client's reference to it live on: a request reaching it as a follower is sent on
//! to the leader it follows, which answers the caller (`forward`).

use super::messages::DmMsg;
use super::producers::Producers;
use super::query::Query;
use super::record::NewRecord;
use super::replica::core::Out;
use super::replica::incarnation::Incarnation;
use super::replica::{apply, Change, ChangeError, InstallPart, Members, OpBody, ReplicaMsg, SCOPE};
use super::replica_state::{group, Incoming, ReplicaState};
use super::state::DatamanagerState;
use super::store::Store;
use super::DmError;
use marie_vocabulary::events::EventKind;
use marie_vocabulary::fence::FenceTable;
use marie_vocabulary::registry::{self, ModuleKind};
use ractor::{pg, ActorCell, ActorRef, RpcReplyPort};
use std::time::Duration;

/// Records per snapshot part sent to a replica, at most.
const INSTALL_PART: usize = 2048;
/// Bytes of records per part, about (a part is one frame: ractor_cluster ends the session
/// on a frame above 16 MiB).
const INSTALL_BYTES: usize = super::page::PAGE_BYTES;
/// Producers per part of their pairs (at most [`super::producers::PER_PRODUCER`], 4096,
/// pairs each: ~1 MiB).
const INSTALL_PRODUCERS: usize = 16;

impl DatamanagerState {
    /// Whether this datamanager is a replica that is not the leader (it answers no client).
    pub(crate) fn is_follower(&self) -> bool {
        self.storage.replica().is_some_and(|r| !r.core.is_leader())
    }

    /// The replica's state, if this datamanager is a replicated one's leader.
    pub(crate) fn leader_mut(&mut self) -> Option<&mut ReplicaState> {
        self.storage.replica_mut().filter(|r| r.core.is_leader())
    }

    /// The leader's side of a store: propose the record. Its seq, once it is checked.
    pub(crate) fn propose_put(&mut self, record: NewRecord) -> Result<u64, DmError> {
        let now = self.clock.now();
        let Some((replica, journal)) = self.storage.replicated_mut() else {
            return Err(DmError::NotPrimary(self.name.clone()));
        };
        if !replica.core.is_leader() {
            return Err(DmError::NotPrimary(self.name.clone()));
        }
        journal.usable()?;
        self.store.check(&record)?;
        replica.last_time = replica.last_time.max(now);
        let time_ns = u64::try_from(replica.last_time.as_nanos()).unwrap_or(u64::MAX);
        let who = (record.producer, record.producer_seq);
        let op = replica
            .core
            .propose(OpBody::Put { time_ns, record })
            .expect("the leader proposes");
        journal.op(op);
        let seq = op.seq;
        replica.noted = seq;
        if who.0 != 0 {
            self.producers.note(who.0, who.1, seq);
        }
        Ok(seq)
    }

    /// The leader's side of a `Delete`: propose deleting what matches `query`, and answer
    /// how many once it is committed (0 if it cannot be).
    pub(crate) fn propose_delete_of(&mut self, query: &Query, reply: RpcReplyPort<u64>) {
        let seqs = self.store.matching_seqs(query);
        let n = self.propose_delete(seqs);
        self.acknowledge(reply, move |committed| match (committed, n) {
            (Ok(()), Ok(n)) => n,
            _ => 0,
        });
    }

    /// Propose a delete of `seqs`; how many records it deletes.
    fn propose_delete(&mut self, seqs: Vec<u64>) -> Result<u64, DmError> {
        let Some((replica, journal)) = self.storage.replicated_mut() else {
            return Err(DmError::NotPrimary(self.name.clone()));
        };
        let n = seqs.len() as u64;
        if n == 0 {
            return Ok(0);
        }
        let op = replica
            .core
            .propose(OpBody::Delete { seqs })
            .ok_or_else(|| DmError::NotPrimary(self.name.clone()))?;
        journal.op(op);
        Ok(n)
    }

    /// `ChangeReplicas`, on the leader: append the new configuration, and answer once it is
    /// committed (its seq), or at once why not. A leader that steps down first drops the
    /// answer (its caller learns it from its reply port: `Interrupted`, at the client).
    pub(crate) fn on_change_replicas(
        &mut self,
        myself: &ActorRef<DmMsg>,
        change: &Change,
        reply: RpcReplyPort<Result<u64, ChangeError>>,
    ) {
        let Some(replica) = self.storage.replica_mut() else {
            let _ = reply.send(Err(ChangeError::Unreplicated));
            return;
        };
        let now = replica.now();
        let mut out = Vec::new();
        match replica.core.change(change, now, &mut out) {
            Ok(seq) => {
                tracing::info!(dm = %replica.name, ?change, seq, members = %replica.core.members(), "replica: the replicas change");
                replica.after_applied(
                    seq,
                    Box::new(move |done| {
                        let _ = reply.send(
                            done.map(|()| seq)
                                .map_err(|e| ChangeError::Interrupted(e.to_string())),
                        );
                    }),
                );
                self.carry_out(myself, out);
            }
            Err(e) => {
                tracing::info!(dm = %replica.name, ?change, error = %e, "replica: a change of the replicas refused");
                let _ = reply.send(Err(e));
            }
        }
    }

    /// The journal's batch is handed over: learn when it is durable, and send the other
    /// replicas what they lack.
    pub(crate) fn replica_flush(&mut self, myself: &ActorRef<DmMsg>) {
        let Some((replica, journal)) = self.storage.replicated_mut() else {
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
        let now = replica.now();
        replica.core.replicate(now, &mut out);
        self.carry_out(myself, out);
    }

    /// `ReplicaTick`: time passed.
    pub(crate) fn on_replica_tick(&mut self, myself: &ActorRef<DmMsg>) {
        self.refresh_peers(myself);
        let Some(replica) = self.storage.replica_mut() else {
            return;
        };
        replica.look_at_strength();
        let mut out = Vec::new();
        let now = replica.now();
        replica.core.tick(now, &mut out);
        self.carry_out(myself, out);
    }

    /// `ReplicaDurable`: the journal made the entries up to `seq` (of `term`) durable.
    pub(crate) fn on_replica_durable(&mut self, myself: &ActorRef<DmMsg>, seq: u64, term: u64) {
        let Some(replica) = self.storage.replica_mut() else {
            return;
        };
        let mut out = Vec::new();
        replica.core.durable(seq, term, &mut out);
        self.carry_out(myself, out);
    }

    /// Which replicas are reachable now (from the replicas' groups): tell the core who came
    /// and went.
    pub(crate) fn refresh_peers(&mut self, myself: &ActorRef<DmMsg>) {
        let Some(replica) = self.storage.replica_mut() else {
            return;
        };
        let now = replica.now();
        let mut out = Vec::new();
        let members = replica.core.others();
        let mut others = members.clone();
        if replica.core.is_leader() {
            // and, on the leader, the replicas that run though no configuration names them:
            // it tells them they are out (`Core::outsider_seen`)
            others.extend(strangers(&replica.name, replica.core.me(), &members));
        }
        // and the leader it follows, though no configuration it holds names it (an outsider
        // being told it is out: its configurations are older than that leader)
        if let Some(l) = replica.core.leader() {
            if l != replica.core.me() && !others.iter().any(|o| o == l) {
                others.push(l.to_string());
            }
        }
        // a replica no configuration names any more is no peer (but an outsider told)
        replica.peers.retain(|p, _| others.contains(p));
        for m in others {
            let found = pg::get_scoped_members(&SCOPE.to_string(), &group(&replica.name, &m))
                .into_iter()
                .find(|c| c.get_status() <= ractor::ActorStatus::Running);
            let known = replica.peers.get(&m).map(ActorCell::get_id);
            match (known, found) {
                (Some(a), Some(b)) if a == b.get_id() => {}
                (_, Some(b)) => {
                    // first seen, back, or another actor: a new session to it (a remote
                    // actor's id is its session's) or a new start of it (its node
                    // restarted: it lags) — its incarnation tells which; an outsider (no
                    // configuration names it) counts for no strength
                    let start = Incarnation::of(&b);
                    if members.contains(&m) {
                        replica
                            .redundancy
                            .seen(&m, start, now, replica.core.last().0);
                    }
                    replica.peers.insert(m.clone(), b);
                    tracing::debug!(dm = %replica.name, peer = %m, ?start, "replica: a replica is reachable");
                    replica.core.peer_up(&m, now, &mut out);
                }
                (Some(_), None) => {
                    replica.peers.remove(&m);
                    if members.contains(&m) {
                        replica.redundancy.left(&m, now, replica.core.last().0);
                    }
                    tracing::debug!(dm = %replica.name, peer = %m, "replica: a replica is gone");
                    replica.core.peer_down(&m, now);
                }
                (None, None) => {}
            }
        }
        self.carry_out(myself, out);
    }

    /// `Replica`: a message from another replica.
    pub(crate) fn on_replica(&mut self, myself: &ActorRef<DmMsg>, msg: ReplicaMsg) {
        let Some(replica) = self.storage.replica_mut() else {
            return;
        };
        let now = replica.now();
        let mut out = Vec::new();
        match msg {
            ReplicaMsg::Install {
                term,
                leader,
                last_seq,
                last_term,
                part,
            } => {
                replica.reach(&leader);
                if replica
                    .core
                    .install_from(term, &leader, last_seq, now, &mut out)
                {
                    self.carry_out(myself, out);
                    self.take_part((last_seq, last_term), part, myself);
                    return;
                }
            }
            msg => {
                if let ReplicaMsg::Append {
                    ops, held, leader, ..
                } = &msg
                {
                    replica.reach(leader);
                    replica.arrived = Some(ops.raw());
                    replica.redundancy.held_everywhere(*held);
                }
                let ack = matches!(msg, ReplicaMsg::AppendAck { .. });
                replica.core.receive(msg, now, &mut out);
                // after an acknowledgement, not only at the next tick: the one that shows
                // a lost replica caught up may also hand it the role (the preferred
                // replica's)
                if ack {
                    replica.look_at_strength();
                }
            }
        }
        self.carry_out(myself, out);
        if let Some(replica) = self.storage.replica_mut() {
            replica.arrived = None;
        }
    }

    /// A part of a snapshot sent by the leader.
    fn take_part(&mut self, last: (u64, u64), part: InstallPart, myself: &ActorRef<DmMsg>) {
        match part {
            InstallPart::Records { first, records } => {
                let config = self.store.config().clone();
                if let Some(replica) = self.storage.replica_mut() {
                    replica.take_records(last, first, records, || Store::new(config));
                }
            }
            InstallPart::Producers { producers } => {
                if let Some(replica) = self.storage.replica_mut() {
                    replica.take_producers(last, producers);
                }
            }
            InstallPart::End {
                records,
                last_time_ns,
                members,
            } => self.install(myself, last, (records, last_time_ns), members),
        }
    }

    /// The snapshot ending at `last` came whole (`records` of them): it replaces the store,
    /// and is journaled as a snapshot; the core hears once it is durable.
    fn install(
        &mut self,
        myself: &ActorRef<DmMsg>,
        last: (u64, u64),
        (records, last_time_ns): (u64, u64),
        members: Option<(u64, Members)>,
    ) {
        let Some((replica, journal)) = self.storage.replicated_mut() else {
            return;
        };
        let Some(mut inc) = replica.incoming.take().filter(|i| i.last == last) else {
            return;
        };
        if inc.records != records {
            tracing::warn!(dm = %replica.name, got = inc.records, sent = records, "replica: a snapshot came incomplete; dropped");
            return;
        }
        inc.store
            .raise_floor(last.0 + 1, Duration::from_nanos(last_time_ns));
        let table = std::mem::take(&mut inc.producers);
        tracing::info!(dm = %replica.name, records, upto = last.0, "replica: a snapshot from the leader taken in");
        self.store = inc.store;
        self.fences = inc.fences;
        self.producers = table;
        let mut out = Vec::new();
        replica.core.installed(last.0, last.1, members, &mut out);
        replica.snapshots_taken += 1;
        replica.last_time = replica.last_time.max(self.store.last_time());
        journal.snapshot(
            &self.store,
            &self.fences,
            &self.producers,
            Some((last, Vec::new(), replica.core.committed_members())),
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
        // (an outsider told by the snapshot that it is out)
        self.carry_out(myself, out);
    }

    /// Carry out what the core asked for, in order; then answer the reads that may be, and
    /// send on (or answer) the requests kept for want of a leader.
    pub(crate) fn carry_out(&mut self, myself: &ActorRef<DmMsg>, out: Vec<Out>) {
        for o in out {
            let Some((replica, journal)) = self.storage.replicated_mut() else {
                return;
            };
            match o {
                Out::Persist => {
                    if let Err(e) = replica.persist_vote() {
                        // a replica that cannot keep its vote must not take part
                        tracing::error!(dm = %replica.name, error = %e, "replica: cannot persist its term and vote: stopping");
                        myself.stop(Some(format!("cannot persist its vote: {e}")));
                        return;
                    }
                }
                Out::Send(to, msg) => replica.send(&to, msg),
                Out::Truncate(seq) => journal.truncate(seq),
                Out::Journal(from, to) => replica.journal_ops(journal, from, to),
                Out::Apply(from, to) => self.apply_committed(from, to),
                Out::Lead => self.lead(myself),
                Out::StepDown(why) => self.step_down(myself, &why),
                Out::Install(to, seq, term) => self.send_snapshot(&to, (seq, term)),
                Out::Reconfigured { was, now } => replica.reconfigured(&was, &now),
                Out::Removed => replica.removed(),
            }
        }
        if let Some(replica) = self.storage.replica_mut() {
            replica.core.trim();
            let (reads, kept) = (!replica.reads.is_empty(), !replica.kept.is_empty());
            if reads {
                self.serve_reads(myself);
            }
            if kept {
                self.send_kept_on(myself);
            }
        }
    }

    /// This replica led and does not any more: it says so, withdraws its publication under
    /// the datamanager's name, and sends on every caller it owed an answer (see above). Its
    /// proposals not committed may be cut by the next leader, whose entries then take their
    /// seqs: their producers' pairs are forgotten, so that a retry is stored, not taken for
    /// another record.
    fn step_down(&mut self, myself: &ActorRef<DmMsg>, why: &str) {
        let Some(replica) = self.storage.replica_mut() else {
            return;
        };
        replica.stepped_down(why);
        replica.acks.clear();
        let applied = replica.core.applied();
        replica.noted = applied;
        self.producers.forget_after(applied);
        self.send_readers_on();
        registry::unpublish(
            ModuleKind::Datamanager,
            self.id,
            &self.name,
            &myself.get_cell(),
        );
    }

    /// Apply the committed entries `from` to `to` to the store, wake the waits they
    /// satisfy, journal the commit, and send the answers that waited for it.
    fn apply_committed(&mut self, from: u64, to: u64) {
        let Some(replica) = self.storage.replica_mut() else {
            return;
        };
        let mut woken = Vec::new();
        for op in replica.core.ops(from, to) {
            if let Some(t) = op.time() {
                replica.last_time = replica.last_time.max(t);
            }
            let producers = (op.seq > replica.noted).then_some(&mut self.producers);
            let class = apply::apply(&mut self.store, &mut self.fences, producers, op);
            if let Some(class) = class.filter(|_| !self.waits.is_empty()) {
                woken.push((class.to_string(), op.seq));
            }
        }
        for (class, seq) in woken {
            self.wake(&class, seq);
        }
        if let Some((replica, journal)) = self.storage.replicated_mut() {
            journal.commit(to);
            replica.answer_upto(to);
        }
    }

    /// This replica was elected leader: note the producers of the entries it holds not yet
    /// applied, tell it, and publish it under the datamanager's name.
    fn lead(&mut self, myself: &ActorRef<DmMsg>) {
        let Some(replica) = self.storage.replica_mut() else {
            return;
        };
        // its uncommitted entries will all be committed (a leader never cuts its own
        // log): a producer retrying one of them must get its seq, not a second record.
        // Those, and any committed not yet applied, are noted here, once (applying them
        // notes nothing again).
        let (applied, last) = (replica.core.applied(), replica.core.last().0);
        replica.noted = last;
        for op in replica.core.ops(applied + 1, last) {
            apply::note(&mut self.producers, op);
        }
        tracing::info!(dm = %replica.name, node = %replica.core.me(), term = replica.core.term(), "replica: this replica is the leader");
        // published before it is told: whoever hears `dm_promoted` finds it by name
        if let Err(e) = registry::publish(
            ModuleKind::Datamanager,
            self.id,
            &self.name,
            myself.get_cell(),
        ) {
            tracing::error!(dm = %self.name, error = %e, "replica: cannot publish the leader");
        }
        if let Some(bus) = &replica.events {
            bus.publish(EventKind::DmPromoted {
                dm: replica.name.clone(),
                node: replica.core.me().to_string(),
                term: replica.core.term(),
            });
        }
    }

    /// Send the replica on node `to` the committed store, which ends at `last`.
    fn send_snapshot(&mut self, to: &str, last: (u64, u64)) {
        let Some(replica) = self.storage.replica() else {
            return;
        };
        let (term, leader) = (replica.core.term(), replica.core.me().to_string());
        let part = |part| ReplicaMsg::Install {
            term,
            leader: leader.clone(),
            last_seq: last.0,
            last_term: last.1,
            part,
        };
        tracing::info!(dm = %replica.name, to, records = self.store.len(), upto = last.0, "replica: sending a snapshot to a replica too far behind");
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
                replica.send(to, part(InstallPart::Records { first, records }));
                first = false;
            }
        });
        replica.send(
            to,
            part(InstallPart::Records {
                first,
                records: batch,
            }),
        );
        let mut producers = Vec::with_capacity(INSTALL_PRODUCERS);
        // the pairs of what the snapshot holds, not of proposals after it (`each_upto`)
        for (p, pairs) in self.producers.each_upto(last.0) {
            producers.push((p, pairs));
            if producers.len() == INSTALL_PRODUCERS {
                let producers = std::mem::take(&mut producers);
                replica.send(to, part(InstallPart::Producers { producers }));
            }
        }
        if !producers.is_empty() {
            replica.send(to, part(InstallPart::Producers { producers }));
        }
        replica.send(
            to,
            part(InstallPart::End {
                records: n,
                last_time_ns: u64::try_from(self.store.last_time().as_nanos()).unwrap_or(u64::MAX),
                members: Some({
                    let (at, m) = replica.core.committed_members();
                    (at, m.clone())
                })
                .filter(|(at, _)| *at > 0),
            }),
        );
    }
}

impl ReplicaState {
    /// A part of records of the snapshot ending at `last`; the first part starts it afresh
    /// (in a store `empty` makes).
    fn take_records(
        &mut self,
        last: (u64, u64),
        first: bool,
        records: Vec<(u64, u64, NewRecord)>,
        empty: impl FnOnce() -> Store,
    ) {
        if first {
            self.incoming = Some(Incoming {
                last,
                store: empty(),
                fences: FenceTable::default(),
                records: 0,
                producers: Producers::default(),
            });
        }
        let Some(inc) = self.incoming.as_mut().filter(|i| i.last == last) else {
            return;
        };
        for (seq, time_ns, record) in records {
            let _ = inc.fences.admit_parts(&record.source, record.epoch);
            if let Err(e) = inc
                .store
                .restore(seq, Duration::from_nanos(time_ns), record)
            {
                tracing::warn!(dm = %self.name, seq, error = %e, "replica: a snapshot record refused");
            }
            inc.records += 1;
        }
    }

    /// A part of producers' pairs of the snapshot ending at `last`.
    fn take_producers(&mut self, last: (u64, u64), producers: Vec<(u64, Vec<(u64, u64)>)>) {
        let Some(inc) = self.incoming.as_mut().filter(|i| i.last == last) else {
            return;
        };
        // a leader of an older build sent every pair it held: those past the snapshot may
        // be of proposals never committed (`Producers::each_upto`)
        for (producer, pairs) in producers {
            for (pseq, seq) in pairs.into_iter().filter(|(_, s)| *s <= last.0) {
                inc.producers.note(producer, pseq, seq);
            }
        }
    }

    /// A configuration was committed: the leader tells each replica added, promoted or
    /// removed (a leader that removed itself, too: it steps down after this).
    pub(crate) fn reconfigured(&self, was: &Members, now: &Members) {
        tracing::info!(dm = %self.name, node = %self.core.me(), was = %was, now = %now, "replica: the replicas changed");
        let leads = self.core.is_leader() || self.core.is_removed() && was.is_voter(self.core.me());
        let Some(bus) = self.events.as_ref().filter(|_| leads) else {
            return;
        };
        let (dm, voters) = (self.name.clone(), now.voters.clone());
        for node in now.learners.iter().filter(|n| !was.contains(n)) {
            bus.publish(EventKind::DmReplicaAdded {
                dm: dm.clone(),
                node: node.clone(),
                voters: voters.clone(),
            });
        }
        for node in now.voters.iter().filter(|n| was.is_learner(n)) {
            bus.publish(EventKind::DmReplicaPromoted {
                dm: dm.clone(),
                node: node.clone(),
                voters: voters.clone(),
            });
        }
        for node in was.all().filter(|n| !now.contains(n)) {
            bus.publish(EventKind::DmReplicaRemoved {
                dm: dm.clone(),
                node: node.clone(),
                voters: voters.clone(),
            });
        }
    }

    /// A configuration without this replica was committed: it is out, and says so in the
    /// log and on its node (`dm_replica_out`: it campaigns no more; its node's replica host
    /// stops it).
    pub(crate) fn removed(&self) {
        tracing::warn!(dm = %self.name, node = %self.core.me(), "replica: removed from the replicas: it takes no part any more");
        self.tell_out();
    }

    /// It was the leader and is not any more: say so (the log and the `dm_fenced` event).
    fn stepped_down(&self, why: &str) {
        tracing::warn!(dm = %self.name, node = %self.core.me(), term = self.core.term(), why, "replica: no longer the leader: a follower now");
        if let Some(bus) = &self.events {
            bus.publish(EventKind::DmFenced {
                dm: self.name.clone(),
                node: self.core.me().to_string(),
                term: self.core.term(),
                why: why.to_string(),
            });
        }
    }
}

/// The nodes where a replica of `dm` runs, as the replicas' groups show (`DM/NODE` in
/// [`SCOPE`]), that are neither `me` nor among `known`.
fn strangers(dm: &str, me: &str, known: &[String]) -> Vec<String> {
    let prefix = format!("{dm}/");
    pg::which_scoped_groups(&SCOPE.to_string())
        .into_iter()
        .filter_map(|g| g.strip_prefix(&prefix).map(str::to_string))
        .filter(|n| n != me && !known.contains(n))
        .collect()
}
