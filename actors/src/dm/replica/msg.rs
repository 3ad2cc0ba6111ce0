//! What the copies of a replicated datamanager tell each other (inside `DmMsg::Replica`).

use super::op::Op;
use crate::dm::record::NewRecord;
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::sync::{Arc, OnceLock};

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
        ops: Ops,
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
    /// Some producers' recent (producer seq, seq) pairs (a part of its own: a full table
    /// is larger than a frame).
    Producers {
        /// Each producer's pairs.
        producers: Vec<(u64, Vec<(u64, u64)>)>,
    },
    /// The snapshot is whole (records and producers sent): the store's floor.
    End {
        /// Records sent in all parts (a check).
        records: u64,
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

/// The entries of an `Append`. The primary sends the same new entries to every copy: the
/// `Append`s of one round share them, and they are encoded once for all (each copy's
/// message is serialized on its own when it is cast; without this, every copy cost the
/// primary's actor a clone and an encoding of every entry). On the wire: the entries'
/// MessagePack, as bytes.
#[derive(Clone)]
pub struct Ops(Arc<OpsInner>);

struct OpsInner {
    ops: Vec<Op>,
    wire: OnceLock<Result<Vec<u8>, String>>,
}

impl Ops {
    /// These entries.
    pub fn new(ops: Vec<Op>) -> Ops {
        Ops(Arc::new(OpsInner {
            ops,
            wire: OnceLock::new(),
        }))
    }

    /// The entries, owned (a copy of them if they are shared).
    pub fn into_vec(self) -> Vec<Op> {
        match Arc::try_unwrap(self.0) {
            Ok(inner) => inner.ops,
            Err(shared) => shared.ops.clone(),
        }
    }
}

impl std::ops::Deref for Ops {
    type Target = [Op];
    fn deref(&self) -> &[Op] {
        &self.0.ops
    }
}

impl From<Vec<Op>> for Ops {
    fn from(ops: Vec<Op>) -> Ops {
        Ops::new(ops)
    }
}

impl PartialEq for Ops {
    fn eq(&self, other: &Ops) -> bool {
        self.0.ops == other.0.ops
    }
}

impl Eq for Ops {}

impl std::fmt::Debug for Ops {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.0.ops.fmt(f)
    }
}

impl Serialize for Ops {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let wire = self
            .0
            .wire
            .get_or_init(|| rmp_serde::to_vec(&self.0.ops).map_err(|e| e.to_string()));
        match wire {
            Ok(bytes) => serializer.serialize_bytes(bytes),
            Err(e) => Err(serde::ser::Error::custom(e)),
        }
    }
}

impl<'de> Deserialize<'de> for Ops {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Ops, D::Error> {
        struct Bytes;
        impl<'de> serde::de::Visitor<'de> for Bytes {
            type Value = Ops;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str("entries as MessagePack bytes")
            }
            fn visit_bytes<E: serde::de::Error>(self, v: &[u8]) -> Result<Ops, E> {
                rmp_serde::from_slice::<Vec<Op>>(v)
                    .map(Ops::new)
                    .map_err(E::custom)
            }
        }
        deserializer.deserialize_bytes(Bytes)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dm::replica::OpBody;

    #[test]
    fn shared_entries_are_encoded_once_and_cross_the_wire_whole() {
        let ops = Ops::new(vec![
            Op {
                seq: 7,
                term: 2,
                body: OpBody::Put {
                    time_ns: 5,
                    record: NewRecord::new("sonar", crate::dm::Payload::from_bytes(vec![1, 2]))
                        .with_source("us"),
                },
            },
            Op {
                seq: 8,
                term: 2,
                body: OpBody::Delete { seqs: vec![3, 4] },
            },
        ]);
        let msg = |ops: Ops| ReplicaMsg::Append {
            term: 2,
            leader: "r1".into(),
            prev_seq: 6,
            prev_term: 1,
            ops,
            commit: 5,
        };
        let (a, b) = (msg(ops.clone()), msg(ops.clone()));
        let wa = rmp_serde::to_vec(&a).unwrap();
        assert!(ops.0.wire.get().is_some(), "encoded by the first");
        assert_eq!(rmp_serde::to_vec(&b).unwrap(), wa);
        let back: ReplicaMsg = rmp_serde::from_slice(&wa).unwrap();
        assert_eq!(back, a);
        let ReplicaMsg::Append { ops: got, .. } = back else {
            unreachable!()
        };
        assert_eq!(got.into_vec(), ops.into_vec());
    }
}
