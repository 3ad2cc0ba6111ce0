//! One entry of a replicated datamanager's log, as it is journaled and sent to replicas.

use super::members::Members;
use crate::entry::{self, Entry};
use crate::record::NewRecord;
use serde::{Deserialize, Serialize};
use std::time::Duration;

/// One entry of the replicated log. Its `seq` is its place in the log *and* the seq the
/// datamanager's record gets: every entry takes one, so a delete or a no-op leaves a gap in
/// the record seqs (a subscriber already reads a gap as records it will not see).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Op {
    /// Place in the log (1, 2, 3, … without gaps).
    pub seq: u64,
    /// The term of the leader that appended it.
    pub term: u64,
    /// What it does once committed.
    pub body: OpBody,
}

/// What an [`Op`] does to the datamanager's store once it is committed.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum OpBody {
    /// Store `record` as record `seq`, stamped `time_ns` on the leader's clock.
    Put {
        /// The time stamp, in nanoseconds of the leader's clock.
        time_ns: u64,
        /// The record.
        record: NewRecord,
    },
    /// Delete these records.
    Delete {
        /// Their seqs.
        seqs: Vec<u64>,
    },
    /// Nothing: a new leader's first entry, which commits what its predecessors left
    /// uncommitted (Raft's rule: a leader counts replicas only of its own term's entries).
    Noop,
    /// The datamanager's replicas from here on (`members`): taken in use where it is
    /// appended, committed or not; to the store, a no-op.
    Members(Members),
}

impl Op {
    /// Append its journal entry to `out` ([`crate::entry`]'s format: a put, or a mark
    /// for a delete or a no-op) — what the journal writes and an `Append` carries.
    pub(crate) fn encode(&self, out: &mut Vec<u8>) {
        match &self.body {
            OpBody::Put { time_ns, record } => {
                entry::encode_put(out, self.seq, Duration::from_nanos(*time_ns), record);
            }
            OpBody::Delete { seqs } => entry::encode_mark(out, self.seq, seqs),
            OpBody::Noop => entry::encode_mark(out, self.seq, &[]),
            OpBody::Members(m) => entry::encode_members(out, self.seq, &m.voters, &m.learners),
        }
    }

    /// The log entry of `term` that journal entry `entry` is ([`Op::encode`]'s inverse), or
    /// the entry back if it is no log entry (a term, a commit, a snapshot's part …).
    // (the `Err` is the caller's entry handed back by move, not an error carried up)
    #[allow(clippy::result_large_err)]
    pub(crate) fn from_entry(entry: Entry, term: u64) -> Result<Op, Entry> {
        let (seq, body) = match entry {
            Entry::Put {
                seq,
                timestamp,
                record,
            } => {
                let time_ns = u64::try_from(timestamp.as_nanos()).unwrap_or(u64::MAX);
                (seq, OpBody::Put { time_ns, record })
            }
            Entry::Mark { seq, seqs } if seqs.is_empty() => (seq, OpBody::Noop),
            Entry::Mark { seq, seqs } => (seq, OpBody::Delete { seqs }),
            Entry::Members {
                seq,
                voters,
                learners,
            } => (seq, OpBody::Members(Members { voters, learners })),
            other => return Err(other),
        };
        Ok(Op { seq, term, body })
    }

    /// The time stamp of a put.
    pub fn time(&self) -> Option<Duration> {
        match &self.body {
            OpBody::Put { time_ns, .. } => Some(Duration::from_nanos(*time_ns)),
            _ => None,
        }
    }
}
