//! What a replica of a replicated datamanager holds beside its store and its journal: the
//! protocol's [`Core`], the other replicas it can reach, the answers waiting for a commit, a
//! snapshot being received. Its actor's handlers for the replicas' messages are in
//! `replicated.rs`.

use super::error::DmError;
use super::journal::{Journal, ReplicaLog};
use super::messages::DmMsg;
use super::replica::core::{Core, Restored};
use super::replica::kept::Kept;
use super::replica::redundancy::Redundancy;
use super::replica::{vote, Members, Op, ReplicaMsg, Replication, SCOPE, UNCHECKED_READS_ENV};
use super::store::Store;
use marie_vocabulary::events::EventKind;
use marie_vocabulary::fence::FenceTable;
use ractor::{pg, ActorCell, ActorRef};
use std::collections::{BTreeMap, VecDeque};
use std::io;
use std::path::PathBuf;
use std::time::Duration;

/// Why a replica could not start.
#[derive(Debug, thiserror::Error)]
pub(crate) enum ReplicaStartError {
    /// Its term and vote could not be read.
    #[error("reading the vote in {}: {error}", dir.display())]
    Vote {
        /// The journal's directory.
        dir: PathBuf,
        /// Why.
        error: io::Error,
    },
    /// Its journal holds records, and no log: a datamanager without replicas wrote it.
    #[error(
        "the journal in {} was written by a datamanager without replicas: its records are on \
         no other replica (start the replicas on empty directories)",
        dir.display()
    )]
    Unreplicated {
        /// The journal's directory.
        dir: PathBuf,
    },
}

/// An answer waiting for its entry's commit.
pub(crate) type Ack = Box<dyn FnOnce(Result<(), DmError>) + Send>;

/// The replication side of a datamanager's state: one replica's part in the protocol.
pub(crate) struct ReplicaState {
    pub(crate) core: Core,
    /// The journal's directory (where the vote is kept).
    pub(crate) dir: PathBuf,
    /// The other replicas reachable now, by node.
    pub(crate) peers: BTreeMap<String, ActorCell>,
    /// Answers waiting for the commit of the entry they name.
    pub(crate) acks: BTreeMap<u64, Vec<Ack>>,
    /// Reads waiting for a majority's word (`reads`), oldest first, with when they came on
    /// the protocol's clock.
    pub(crate) reads: VecDeque<(Duration, DmMsg)>,
    /// Requests of the dm-interface that reached this replica, not leading, while it knew no
    /// leader to send them on to (`forward`), oldest first, with when they came.
    pub(crate) kept: Kept<DmMsg>,
    started: tokio::time::Instant,
    /// The newest time stamp handed out.
    pub(crate) last_time: Duration,
    /// A snapshot being received from the leader.
    pub(crate) incoming: Option<Incoming>,
    /// The entries of the `Append` being handled, as they came: journaled as they are.
    pub(crate) arrived: Option<std::sync::Arc<super::replica::RawOps>>,
    /// Snapshots taken in since it started.
    pub(crate) snapshots_taken: u64,
    /// The last entry whose producer's pair was noted before it was applied (a leader
    /// notes its proposals, and at election every entry it holds not yet applied):
    /// applying one up to it notes nothing again — a pair noted twice halved the retries a
    /// leader recognised (the table then kept a producer's last 1024 pairs, one window).
    pub(crate) noted: u64,
    ticker: tokio::task::JoinHandle<()>,
    /// The datamanager's name.
    pub(crate) name: String,
    /// Where it tells that it became the leader or stepped down.
    pub(crate) events: Option<marie_vocabulary::events::EventBus>,
    /// The replicas lost and not yet caught up: what it tells, as the leader, once they are.
    pub(crate) redundancy: super::replica::redundancy::Redundancy,
}

impl Drop for ReplicaState {
    fn drop(&mut self) {
        self.ticker.abort();
    }
}

/// A snapshot being received.
pub(crate) struct Incoming {
    /// Where the snapshot ends, (seq, term).
    pub(crate) last: (u64, u64),
    /// The records so far.
    pub(crate) store: Store,
    /// Their sources' epochs.
    pub(crate) fences: FenceTable,
    /// How many came.
    pub(crate) records: u64,
    /// The producers' recent pairs so far.
    pub(crate) producers: super::producers::Producers,
}

/// The group the replica of `dm` on node `me` joins (in [`SCOPE`]).
pub(crate) fn group(dm: &str, me: &str) -> String {
    format!("{dm}/{me}")
}

impl ReplicaState {
    /// The replica `replication.me` of datamanager `name`, with what its journal (in `dir`)
    /// held: joins its group, starts its ticker.
    pub(crate) fn start(
        name: &str,
        replication: &Replication,
        dir: PathBuf,
        log: Option<ReplicaLog>,
        store: &Store,
        myself: &ActorRef<DmMsg>,
        events: Option<marie_vocabulary::events::EventBus>,
    ) -> Result<ReplicaState, ReplicaStartError> {
        let (term, voted_for) = vote::load(&dir).map_err(|error| ReplicaStartError::Vote {
            dir: dir.clone(),
            error,
        })?;
        // a replica started on a log of its own was lost (its process, or its actor): its
        // datamanager is short of a replica until it is current again
        let started_again = log.is_some();
        let restored = match log {
            Some(log) => Restored {
                term: term.max(log.term),
                voted_for,
                committed: log.committed,
                tail: log.tail,
                applied: log.applied,
                before: log.before,
                members: log.members,
            },
            None if store.next_seq() > 1 => return Err(ReplicaStartError::Unreplicated { dir }),
            None => Restored {
                term,
                voted_for,
                ..Restored::default()
            },
        };
        let eager = !replication.joining && replication.members.first() == Some(&replication.me);
        let unchecked =
            replication.unchecked_reads || std::env::var_os(UNCHECKED_READS_ENV).is_some();
        if unchecked {
            tracing::warn!(dm = name, "replica: reads unchecked (a control run): a leader cut off from the others answers stale reads");
        }
        let started = tokio::time::Instant::now();
        let mut core = Core::new(
            &replication.me,
            &replication.members,
            replication.timing,
            restored,
            eager,
            Duration::ZERO,
        )
        .with_tail_keep(replication.catch_up)
        .with_unchecked_reads(unchecked);
        if replication.joining {
            core = core.joining();
        }
        if core.is_removed() {
            tracing::warn!(dm = name, node = %replication.me, members = %core.members(), "replica: its journal says it was removed from the replicas: it takes no part");
        }
        pg::join_scoped(
            SCOPE.to_string(),
            group(name, &replication.me),
            vec![myself.get_cell()],
        );
        pg::monitor_scope(SCOPE.to_string(), myself.get_cell());
        let me = myself.clone();
        let every = replication.timing.heartbeat / 2;
        let ticker = tokio::spawn(async move {
            let mut ticks = tokio::time::interval(every);
            ticks.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
            loop {
                ticks.tick().await;
                if me.cast(DmMsg::ReplicaTick {}).is_err() {
                    break;
                }
            }
        });
        let state = ReplicaState {
            core,
            dir,
            peers: BTreeMap::new(),
            acks: BTreeMap::new(),
            reads: VecDeque::new(),
            kept: Kept::default(),
            started,
            last_time: store.last_time(),
            incoming: None,
            arrived: None,
            snapshots_taken: 0,
            noted: 0,
            ticker,
            name: name.to_string(),
            events,
            redundancy: Redundancy::new(started_again.then_some(Duration::ZERO)),
        };
        if state.core.is_removed() {
            state.tell_out();
        }
        Ok(state)
    }

    /// Tell `dm_replica_out` on its node: it took in a configuration without it (or its
    /// journal says so at its start).
    pub(crate) fn tell_out(&self) {
        if let Some(bus) = &self.events {
            bus.publish(EventKind::DmReplicaOut {
                dm: self.name.clone(),
                node: self.core.me().to_string(),
                voters: self.core.members().voters.clone(),
            });
        }
    }

    /// Time since it started: the protocol's clock.
    pub(crate) fn now(&self) -> Duration {
        self.started.elapsed()
    }

    /// As the leader: tell each lost replica that caught up since the last look, and the
    /// redundancy restored once every replica is current (`dm_replica_caught_up`,
    /// `dm_redundancy_restored`).
    pub(crate) fn look_at_strength(&mut self) {
        use super::replica::redundancy::Strength;
        if !self.core.is_leader() || !self.redundancy.reduced() {
            return;
        }
        let present = self.peers.keys().cloned().collect();
        let news = self
            .redundancy
            .look(&present, &self.core.lacking_committed(), self.now());
        for news in news {
            let ms = |d: Duration| u64::try_from(d.as_millis()).unwrap_or(u64::MAX);
            let kind = match news {
                Strength::CaughtUp { node, after } => {
                    tracing::info!(dm = %self.name, %node, ?after, "replica: a lost replica caught up");
                    EventKind::DmReplicaCaughtUp {
                        dm: self.name.clone(),
                        node,
                        after_ms: ms(after),
                    }
                }
                Strength::Restored { replicas, after } => {
                    tracing::info!(dm = %self.name, replicas, ?after, "replica: redundancy restored");
                    EventKind::DmRedundancyRestored {
                        dm: self.name.clone(),
                        replicas: u32::try_from(replicas).unwrap_or(u32::MAX),
                        after_ms: ms(after),
                    }
                }
            };
            if let Some(bus) = &self.events {
                bus.publish(kind);
            }
        }
    }

    /// Run `ack` once the entries up to `seq` are applied (at once if they are).
    pub(crate) fn after_applied(&mut self, seq: u64, ack: Ack) {
        if seq <= self.core.applied() {
            ack(Ok(()));
        } else {
            self.acks.entry(seq).or_default().push(ack);
        }
    }

    /// Run `ack` once everything proposed so far is committed and applied.
    pub(crate) fn after_commit(&mut self, ack: Ack) {
        let last = self.core.last().0;
        self.after_applied(last, ack);
    }

    /// Where its committed log ends, (seq, term), and the entries after it: what a
    /// snapshot of its journal writes again after the store (`Journal::snapshot`).
    pub(crate) fn log_after_commit(&self) -> ((u64, u64), Vec<&Op>, (u64, &Members)) {
        let core = &self.core;
        let commit = core.commit().min(core.applied());
        let term = core.term_at(commit).unwrap_or(0);
        (
            (commit, term),
            core.ops(commit + 1, core.last().0).collect(),
            core.committed_members(),
        )
    }

    /// Send the answers waiting for the entries up to `seq`: they are committed and applied.
    pub(crate) fn answer_upto(&mut self, seq: u64) {
        let later = self.acks.split_off(&(seq + 1));
        for ack in std::mem::replace(&mut self.acks, later)
            .into_values()
            .flatten()
        {
            ack(Ok(()));
        }
    }

    /// Sync its term and vote to disk (before anything that depends on them is sent).
    pub(crate) fn persist_vote(&self) -> io::Result<()> {
        vote::save(&self.dir, self.core.term(), self.core.voted_for())
    }

    /// Journal the entries `from` to `to`: those that just arrived with their bytes as the
    /// leader encoded them, the others encoded here.
    pub(crate) fn journal_ops(&self, journal: &mut Journal, from: u64, to: u64) {
        for op in self.core.ops(from, to) {
            match self.arrived.as_ref().and_then(|r| r.entry(op.seq, op.term)) {
                Some(bytes) => journal.op_encoded(op, bytes),
                None => journal.op(op),
            }
        }
    }

    /// The leader this replica follows, if it is another replica and reachable: where a
    /// client's request to this one is sent on.
    pub(crate) fn leader_actor(&self) -> Option<ActorRef<DmMsg>> {
        let leader = self.core.leader().filter(|l| *l != self.core.me())?;
        self.peers.get(leader).cloned().map(Into::into)
    }

    /// Make the replica on `node` reachable if it is not yet (a leader no configuration it
    /// holds names sends to it: it answers that leader at once, not after its next look at
    /// the replicas' groups).
    pub(crate) fn reach(&mut self, node: &str) {
        if node == self.core.me() || self.peers.contains_key(node) {
            return;
        }
        if let Some(cell) = pg::get_scoped_members(&SCOPE.to_string(), &group(&self.name, node))
            .into_iter()
            .find(|c| c.get_status() <= ractor::ActorStatus::Running)
        {
            self.peers.insert(node.to_string(), cell);
        }
    }

    /// Send `msg` to the replica on node `to`, if it is reachable.
    pub(crate) fn send(&self, to: &str, msg: ReplicaMsg) {
        match self.peers.get(to) {
            Some(cell) => {
                let actor: ActorRef<DmMsg> = cell.clone().into();
                if let Err(e) = actor.cast(DmMsg::Replica { msg: Box::new(msg) }) {
                    tracing::debug!(dm = %self.name, to, error = %e, "replica: a message not sent");
                }
            }
            None => tracing::trace!(dm = %self.name, to, "replica: not reachable; not sent"),
        }
    }
}
