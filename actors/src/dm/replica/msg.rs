//! What the copies of a replicated datamanager tell each other (inside `DmMsg::Replica`).

use super::op::Op;
use crate::dm::record::NewRecord;
use serde::{Deserialize, Serialize};

/// One message between the copies of a datamanager; Raft's, with pre-votes.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum ReplicaMsg {
    /// The primary's entries from `prev_seq + 1` on (none: a heartbeat), and how far it has
    /// committed.
    Append {
        /// The primary's term.
        term: u64,
        /// The primary (its node).
        leader: String,
        /// The entry just before `ops`, which the copy must hold with `prev_term`.
        prev_seq: u64,
        /// Its term.
        prev_term: u64,
        /// The entries.
        ops: Vec<Op>,
        /// The primary's commit seq.
        commit: u64,
    },
    /// A copy's answer to an `Append` or to an installed snapshot.
    AppendAck {
        /// The copy's term.
        term: u64,
        /// The copy (its node).
        from: String,
        /// Whether it holds the entries; if not, `last` says from where to send.
        ok: bool,
        /// If `ok`, the last seq it holds as the primary does and durably; if not, the seq
        /// after which the primary should send again.
        last: u64,
    },
    /// A request for a vote (or, `pre`, whether a vote would be given: a copy that cannot
    /// win does not raise everyone's term).
    Vote {
        /// The term asked for.
        term: u64,
        /// Who asks (its node).
        candidate: String,
        /// Its last entry's seq.
        last_seq: u64,
        /// Its last entry's term.
        last_term: u64,
        /// A pre-vote: nobody changes their term for it.
        pre: bool,
        /// Asked at the primary's word (`TimeoutNow`): a copy that heard from that primary
        /// lately votes all the same.
        #[serde(default)]
        transfer: bool,
    },
    /// The primary hands its role to the preferred copy, which is as up to date as it:
    /// campaign now (Raft's leadership transfer). So the primary is where the configuration
    /// puts it — beside the operations that use it — whenever that copy runs.
    TimeoutNow {
        /// The primary's term.
        term: u64,
        /// The primary (its node).
        from: String,
    },
    /// An answer to a `Vote`.
    VoteAck {
        /// The voter's term.
        term: u64,
        /// The term the vote was for.
        asked: u64,
        /// The voter (its node).
        from: String,
        /// Given or not.
        granted: bool,
        /// An answer to a pre-vote.
        pre: bool,
    },
    /// A part of a snapshot of the primary's committed records, for a copy too far behind
    /// for entries (the primary no longer holds them).
    Install {
        /// The primary's term.
        term: u64,
        /// The primary (its node).
        leader: String,
        /// The seq the snapshot ends with.
        last_seq: u64,
        /// That entry's term.
        last_term: u64,
        /// This part.
        part: InstallPart,
    },
}

/// One part of a snapshot sent to a copy: records in seq order, then the end.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum InstallPart {
    /// Records (the first part of a snapshot has `first`).
    Records {
        /// The first part: a copy drops any snapshot it was receiving.
        first: bool,
        /// (seq, time stamp in ns, record, the epoch its source had).
        records: Vec<(u64, u64, NewRecord)>,
    },
    /// The snapshot is whole: the producers' recent pairs and the store's floor.
    End {
        /// Records sent in all parts (a check).
        records: u64,
        /// Each producer's recent (producer seq, seq) pairs.
        producers: Vec<(u64, Vec<(u64, u64)>)>,
        /// The newest time stamp handed out, in ns.
        last_time_ns: u64,
    },
}

impl ReplicaMsg {
    /// The term the sender is in.
    pub fn term(&self) -> u64 {
        match self {
            ReplicaMsg::Append { term, .. }
            | ReplicaMsg::AppendAck { term, .. }
            | ReplicaMsg::Vote { term, .. }
            | ReplicaMsg::VoteAck { term, .. }
            | ReplicaMsg::Install { term, .. }
            | ReplicaMsg::TimeoutNow { term, .. } => *term,
        }
    }
}
