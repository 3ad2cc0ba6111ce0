//! Replicas of a datamanager on other nodes: a put is acknowledged once a majority of the
//! replicas hold it, and when the leader's node is lost a replica takes over, with no
//! acknowledged record lost and never two leaders acknowledging.
//!
//! # The protocol: Raft, on the datamanager's own journal
//! A replicated datamanager runs one replica on each of its member nodes (three, usually:
//! a majority of three survives the loss of any one). The replicas elect a *leader* by
//! Raft's rules (the `core` module, a pure state machine tested against thousands of seeded
//! schedules of lost messages, partitions and crashes); only the leader is published
//! under the datamanager's name and id, so clients find it, and only it takes writes. Every
//! write becomes an entry of a replicated log whose place *is* the record's seq: the
//! sequence numbers continue across a change of leader. An entry is committed once a
//! majority of replicas have journaled it at the datamanager's durability; only then is it
//! applied to a replica's store (on every replica alike), and only then does the leader answer
//! the write. A select on the leader sees committed records only, and only while no other
//! leader can have acknowledged a newer write (`lease`: a leader lease, or a round of the
//! replicas' word).
//!
//! - **Terms fence.** Each election raises the term; a replica's term and vote are synced to
//!   disk before they are used (`vote`). A leader that meets a newer term, or that has not
//!   heard from a majority for an election timeout, *steps down*: the same actor goes on as
//!   a follower — withdrawn from the datamanager's name, the callers it owed an answer sent
//!   on (their reply ports dropped), so clients follow the name to the new leader; a
//!   client's reference to it stays valid (a follower sends a client's request on to its
//!   leader, which answers it).
//! - **Uncommitted entries** of a lost leader are kept or cut by the next one (Raft's log
//!   matching); a client that got no answer retries with the same producer number, and the
//!   `producers` table (replicated with the records) stores it once.
//! - **Elections are fast and rare.** A replica campaigns as soon as it sees the leader's
//!   replica leave its group (the node's failure detector closes a lost node's sessions), the
//!   lower-ranked replicas first, once the lease's guard after their leader's last word has
//!   passed (it ends before the failure detector's deadline); an election timeout is the
//!   backstop. Pre-votes and leader stickiness keep a replica that was cut off from
//!   unseating a working leader when it comes back; a replica that refuses a less up-to-date candidate while no leader is known
//!   campaigns soon itself (the candidate cannot win, and this replica may have been refused
//!   by one that had not yet seen the leader go). A leader not on the configured node
//!   hands its role there once that replica caught up, and meanwhile sends the others nothing
//!   that replica may lack (so none of them refuses it its vote).
//! - **Catching up**: a replica that lags gets the entries it lacks, or — when the leader
//!   no longer holds them in memory — a snapshot of the committed store in parts.
//!
//! Replicas find each other in the `pg` scope [`SCOPE`], one group per (datamanager, node).
//! A replicated datamanager needs a journal (`process` or `sync`): Raft's vote must
//! survive a restart.

pub(crate) mod apply;
pub(crate) mod core;
pub(crate) mod incarnation;
pub(crate) mod kept;
pub(crate) mod lease;
mod members;
mod msg;
mod op;
pub(crate) mod redundancy;
pub(crate) mod samples;
pub(crate) mod tail;
pub(crate) mod vote;

pub use self::core::Timing;
pub use members::{Change, ChangeError, Members, MIN_VOTERS};
pub(crate) use msg::RawOps;
pub(crate) use msg::{InstallPart, ReplicaMsg};
pub(crate) use op::{Op, OpBody};

/// The `pg` scope the replicas of replicated datamanagers meet in.
pub const SCOPE: &str = "marie.dm";

/// Where a datamanager's replicas are: the nodes that keep one, and which is this one.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Replication {
    /// The node this replica runs on (its name in `members`).
    pub me: String,
    /// Every node that keeps a replica, the preferred leader first (it campaigns at once when
    /// it starts; the others wait for an election timeout).
    pub members: Vec<String>,
    /// The protocol's clocks.
    pub timing: Timing,
    /// Applied entries the leader keeps in memory to catch a lagging replica up (and at most
    /// `KEEP_BYTES` (32 MiB) of them); a replica further behind is sent a snapshot of the store
    /// instead ([`Replication::DEFAULT_CATCH_UP`]).
    pub catch_up: usize,
    /// The leader answers every read from its store at once, without its lease or a
    /// confirmation round: a leader cut off from the others then answers reads older than
    /// what a new leader acknowledged. For the checker's control run and the read bench
    /// only (`false` unless set; the environment variable [`UNCHECKED_READS_ENV`] sets it
    /// in a process).
    pub unchecked_reads: bool,
    /// A replica started on a node that is not among `members` (the datamanager's voters
    /// now), to join them: it takes itself for a learner until its leader's log says
    /// otherwise, and never campaigns before it is promoted ([`Replication::joining`]).
    pub joining: bool,
}

/// The environment variable that makes every replica started in the process answer reads
/// unchecked ([`Replication::unchecked_reads`]): what the checker's control run sets on its
/// nodes, to show that its readers catch stale reads.
pub const UNCHECKED_READS_ENV: &str = "MARIE_DM_UNCHECKED_READS";

impl Replication {
    /// Default [`Replication::catch_up`]: 16 384 entries — over a second of puts at
    /// 10 000 a second, so a replica frozen for less than the failure detector's deadline
    /// catches up from memory, at a few MB with small records. (It was 262 144, about a
    /// second at the bench's full rate: a replica's memory 141 MB against 81 MB now, even
    /// under `KEEP_BYTES` (32 MiB), in a put-all round of 1 M records; and ~24 % of a replica's time
    /// spent filling fresh memory.) A faster producer's lagging replica takes a snapshot.
    pub const DEFAULT_CATCH_UP: usize = core::TAIL_KEEP;

    /// Replica `me` of a datamanager kept on `members` (the first is the preferred leader).
    pub fn new(
        me: impl Into<String>,
        members: impl IntoIterator<Item = impl Into<String>>,
    ) -> Replication {
        Replication {
            me: me.into(),
            members: members.into_iter().map(Into::into).collect(),
            timing: Timing::default(),
            catch_up: Self::DEFAULT_CATCH_UP,
            unchecked_reads: false,
            joining: false,
        }
    }

    /// Replica `me` of a datamanager whose voters are `members` now, started to join them
    /// while it runs (its leader adds it as a learner and promotes it once it caught up:
    /// `marie dm add-replica`). A journal of it that says otherwise wins: restarted, it is
    /// what its log says.
    pub fn joining(
        me: impl Into<String>,
        members: impl IntoIterator<Item = impl Into<String>>,
    ) -> Replication {
        Replication {
            joining: true,
            ..Replication::new(me, members)
        }
    }

    /// Answer reads unchecked ([`Replication::unchecked_reads`]): stale reads become
    /// possible. For a control run or a bench only.
    pub fn with_unchecked_reads(mut self) -> Replication {
        self.unchecked_reads = true;
        self
    }

    /// Keep `entries` applied entries in memory to catch a lagging replica up (at least 1).
    pub fn with_catch_up(mut self, entries: usize) -> Replication {
        self.catch_up = entries.max(1);
        self
    }

    /// Why this cannot work, if it cannot: `me` not among the members, a duplicate member,
    /// fewer than three (no majority survives a loss then).
    pub fn check(&self) -> Result<(), ReplicationError> {
        let mut sorted = self.members.clone();
        sorted.sort();
        sorted.dedup();
        if sorted.len() != self.members.len() {
            return Err(ReplicationError::Duplicate(self.members.clone()));
        }
        if !self.joining && !self.members.contains(&self.me) {
            return Err(ReplicationError::NotAMember {
                me: self.me.clone(),
                members: self.members.clone(),
            });
        }
        if self.members.len() < 3 {
            return Err(ReplicationError::TooFew(self.members.len()));
        }
        Ok(())
    }
}

/// Why a [`Replication`] cannot work ([`Replication::check`]). Its texts speak of
/// "replicas", the word of a node's config (`replicas = [...]`).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ReplicationError {
    /// A node is named twice among the members.
    #[error("a node is named twice in the replicas {0:?}")]
    Duplicate(Vec<String>),
    /// `me` is not among the members.
    #[error("this node ({me}) is not among the replicas {members:?}")]
    NotAMember {
        /// This node.
        me: String,
        /// The members.
        members: Vec<String>,
    },
    /// Fewer than three members: a majority of them cannot survive the loss of one.
    #[error("{0} replicas: a majority of them cannot survive the loss of one; keep three or more")]
    TooFew(usize),
}

#[cfg(test)]
mod tests {
    use super::Replication;

    #[test]
    fn a_replication_that_cannot_work_says_why() {
        let check = |me: &str, members: &[&str]| {
            Replication::new(me, members.iter().copied())
                .check()
                .map_err(|e| e.to_string())
        };
        assert_eq!(check("a", &["a", "b", "c"]), Ok(()));
        assert_eq!(
            check("a", &["a", "b", "a"]),
            Err(r#"a node is named twice in the replicas ["a", "b", "a"]"#.to_string())
        );
        assert_eq!(
            check("d", &["a", "b", "c"]),
            Err(r#"this node (d) is not among the replicas ["a", "b", "c"]"#.to_string())
        );
        assert_eq!(
            check("a", &["a", "b"]),
            Err(
                "2 replicas: a majority of them cannot survive the loss of one; keep three or more"
                    .to_string()
            )
        );
    }
}
