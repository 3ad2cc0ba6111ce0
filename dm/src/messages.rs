//! dm-interface messages (thesis 3.2.5.2; see `docs/thesis.md`).

use super::error::DmError;
use super::query::Query;
use super::record::{NewRecord, Record};
use marie_vocabulary::replica::ReplicaRole;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// What a datamanager holds, from a `Stats` request.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default)]
pub struct DmStats {
    /// The DM's numeric id (e.g. 1203).
    pub id: u32,
    /// The DM's name (e.g. `world`).
    pub name: String,
    /// Records stored now.
    pub records: u64,
    /// Records stored now, per class.
    pub classes: BTreeMap<String, u64>,
    /// Seq of the oldest stored record.
    pub first_seq: Option<u64>,
    /// Seq of the newest stored record.
    pub last_seq: Option<u64>,
    /// The seq the next record will get (everything below it has been handed out).
    pub next_seq: u64,
    /// `SelectWait`s waiting for a record.
    pub pending_waits: u64,
    /// Records dropped by retention since the DM started.
    pub dropped: u64,
    /// Records deleted by query since the DM started.
    pub deleted: u64,
    /// `Put`s refused (bad names, payload too large) since the DM started; a cast has no
    /// reply to carry the error, so it is counted and logged.
    pub refused_puts: u64,
    /// Records refused because their source's epoch was replaced (counted in
    /// `refused_puts` too when they came as `Put`s).
    #[serde(default)]
    pub fenced: u64,
    /// How durable its acknowledged writes are.
    #[serde(default)]
    pub durability: super::journal::Durability,
    /// Bytes of its journal on disk (0 at `memory`).
    #[serde(default)]
    pub journal_bytes: u64,
    /// What its start read back from its journal (`None` at `memory`).
    #[serde(default)]
    pub recovery: Option<super::journal::Recovery>,
    /// Retried puts it found stored already and answered with their first seq
    /// (`producers`).
    #[serde(default)]
    pub duplicates: u64,
    /// At `memory`: what its start took from its previous incarnation (`None` if it was
    /// left nothing: its first start, or no heir).
    #[serde(default)]
    pub inherited: Option<super::heir::Inherited>,
    /// A replicated datamanager's replica: its role, term and how far each replica lags.
    #[serde(default)]
    pub replica: Option<ReplicaStats>,
    /// The window of credits it grants a remote producer: records it may have
    /// unacknowledged (`credits`; 0 from a node that does not say, read as
    /// [`super::credits::WINDOW`]).
    #[serde(default)]
    pub window: u64,
    /// The retention bound of a class it has no bound of its own for: at most this many
    /// records of a class are kept, the oldest dropped first (`None` from a node that does
    /// not say).
    #[serde(default)]
    pub retention: Option<u64>,
    /// The classes with a retention bound of their own, and their bounds.
    #[serde(default)]
    pub retention_by_class: BTreeMap<String, u64>,
    /// Records dropped by retention since the DM started, per class (classes that dropped
    /// none are not listed; their sum is [`DmStats::dropped`]).
    #[serde(default)]
    pub dropped_by_class: BTreeMap<String, u64>,
}

impl DmStats {
    /// The retention bound of `class`, if the datamanager said (see
    /// [`DmStats::retention`]).
    pub fn retention_of(&self, class: &str) -> Option<u64> {
        self.retention_by_class
            .get(class)
            .copied()
            .or(self.retention)
    }
}

/// What a datamanager's records come to, from a `Digest` request.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default)]
pub struct StoreDigest {
    /// The last seq applied to the store (the committed seq of a replica).
    pub upto: u64,
    /// Records stored.
    pub records: u64,
    /// [`crate::Store::digest`].
    pub digest: u64,
}

/// A replica of a replicated datamanager, in its [`DmStats`].
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default)]
pub struct ReplicaStats {
    /// The node this replica runs on.
    pub node: String,
    /// Leader or follower.
    pub role: ReplicaRole,
    /// Its term.
    pub term: u64,
    /// The leader's node, if it knows one (`primary` in builds before the word was
    /// settled).
    #[serde(alias = "primary")]
    pub leader: Option<String>,
    /// The last committed seq.
    pub commit: u64,
    /// The last seq in its log.
    pub last: u64,
    /// On the leader: how many entries each other replica lacks.
    pub lag: BTreeMap<String, u64>,
    /// Snapshots of the store this replica took in from a leader (it lagged further than the
    /// leader keeps entries for), since it started.
    pub snapshots_taken: u64,
    /// The voting replicas' nodes, as this replica knows them (the newest configuration in
    /// its log; empty from builds before it was told).
    #[serde(default)]
    pub members: Vec<String>,
    /// The replicas catching up before they vote (added while it runs).
    #[serde(default)]
    pub learners: Vec<String>,
    /// It was removed from the replicas (its journal says so): it takes no part.
    #[serde(default)]
    pub removed: bool,
    /// The other replicas' nodes it reaches now (it finds their actors): with itself, a
    /// majority of [`members`](Self::members) is what a leader needs.
    #[serde(default)]
    pub reachable: Vec<String>,
    /// What it holds in memory (0 from builds before it was told): a kept-up cluster's
    /// nodes' memory is read beside it, to tell stores and logs filling to their bounds
    /// from a leak.
    #[serde(default)]
    pub held: Held,
}

/// What a replica holds in memory ([`ReplicaStats::held`]).
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Held {
    /// Records in its store.
    pub records: u64,
    /// Bytes of those records' payloads and names.
    pub record_bytes: u64,
    /// Log entries it keeps in memory (uncommitted ones, and applied ones a lagging
    /// replica may still need).
    pub tail_entries: u64,
    /// Bytes those entries take (`op_bytes`, summed).
    pub tail_bytes: u64,
    /// Producers' pairs it keeps to store a retried put once.
    pub producer_pairs: u64,
}

marie_vocabulary::remote_message! {
    /// Messages a [`super::Datamanager`] understands: the dm-interface.
    pub enum DmMsg {
        /// Store a record; the reply is its seq, or why it was refused.
        Store {
            /// The record, without the header the DM fills in (boxed, like the queries below,
            /// so every message is no larger than a `Put`: the mailbox moves each one several
            /// times).
            record: Box<NewRecord>,
        } -> Result<u64, DmError>,
        /// Store a record without waiting for the answer (for high-rate sensors). A refused
        /// record is logged and counted in [`DmStats::refused_puts`].
        Put {
            /// The record, without the header the DM fills in.
            record: NewRecord,
        },
        /// Store records in order without waiting for the answer: many `Put`s in one
        /// message (see `credits`). Each refused record is logged and counted in
        /// [`DmStats::refused_puts`]; the others are stored.
        PutBatch {
            /// The records, without the headers the DM fills in.
            records: Vec<NewRecord>,
        },
        /// Every stored record matching the query, oldest-first. The answer crosses to another
        /// node in one frame: [`super::DmClient::select`] asks such a datamanager for pages
        /// (`SelectPage`) instead.
        Select {
            /// What to select.
            query: Box<Query>,
        } -> Vec<Record>,
        /// Like `Select`, but if nothing matches yet, wait until a matching record is stored
        /// (then answer as `Select` would) or until `timeout_ms` pass on the DM's clock (then
        /// answer with nothing). The thesis DM's pending wait. The answer crosses to
        /// another node in one frame: [`super::DmClient::select_wait`] asks such a
        /// datamanager with `SelectWaitPage` instead.
        SelectWait {
            /// What to select, or wait for.
            query: Box<Query>,
            /// How long to wait, in milliseconds of the DM's clock; 0 is a plain select.
            timeout_ms: u64,
        } -> Vec<Record>,
        /// `SelectWait` for a caller on another node: the answer's first page of about
        /// `max_bytes` (at most [`super::page::PAGE_BYTES`]), whose `rest` the caller asks
        /// for with `SelectPage` (see `page`). An empty page means the wait passed.
        SelectWaitPage {
            /// What to select, or wait for.
            query: Box<Query>,
            /// How long to wait, in milliseconds of the DM's clock; 0 is a plain select.
            timeout_ms: u64,
            /// About how many bytes of records the page may carry.
            max_bytes: u64,
        } -> super::page::Page,
        /// Delete every record matching the query (respecting its newest/oldest limit); the
        /// reply is how many were deleted.
        Delete {
            /// What to delete.
            query: Box<Query>,
        } -> u64,
        /// What the DM holds. A replicated datamanager's follower sends it on to its leader,
        /// as every request of the dm-interface (`ReplicaStats` asks a replica itself).
        Stats {} -> DmStats,
        /// Commit `fault` on purpose (fault injection): a kill, a panic or a hang (only a
        /// kill ends it). Its supervisor restarts it. Any other kind is ignored with a
        /// warning. A kill sent this way is how one reaches a DM on another node, where
        /// killing its local stand-in would only kill the stand-in.
        Inject {
            /// The fault.
            fault: marie_vocabulary::run::FaultKind,
        },
        /// A digest of the records it holds, and up to which seq (a checker compares the
        /// replicas of a replicated datamanager by it; a replica answers it too).
        Digest {} -> StoreDigest,
        /// What this replica holds now, whatever its role (a follower answers it itself,
        /// where it sends `Stats`, the datamanager's, on to its leader): its role, term,
        /// journal and lag, what its start read back. A datamanager without replicas answers it as `Stats`, at
        /// once.
        ReplicaStats {} -> DmStats,
        /// The first page, of about `max_bytes`, of what `Select` answers, and the query
        /// for the rest: how a client on another node selects (`page`; an answer
        /// above ractor_cluster's 16 MiB frame limit would end the session between the
        /// nodes).
        SelectPage {
            /// What to select.
            query: Box<Query>,
            /// About how many bytes of records the page may carry.
            max_bytes: u64,
        } -> super::page::Page,
        /// Change the replicas of a replicated datamanager by one: add a replica on a node
        /// (started there first; it catches up as a learner and the leader promotes it once it
        /// holds everything committed), or remove one. Answered once the new configuration is
        /// committed — with its seq — or with why it was refused (one change at a time; a
        /// removal that would leave no majority answering). A follower sends it on to its
        /// leader.
        ChangeReplicas {
            /// The change.
            change: super::replica::Change,
        } -> Result<u64, super::replica::ChangeError>,
        /// A message between the replicas of a replicated datamanager: the replication
        /// protocol's own, not part of the dm-interface (hidden, and its type private).
        #[doc(hidden)]
        Replica {
            /// The message (boxed: it is seldom the hot path, and large).
            msg: Box<super::replica::ReplicaMsg>,
        },
    }
    local {
        /// The timeout of a pending wait passed.
        WaitExpired {
            /// The wait's id.
            id: u64,
        },
        /// Hand the journal's batch to its writer (sent by the datamanager to itself: it
        /// lands behind the messages already waiting, which join the batch).
        JournalFlush {},
        /// The journal's writer could not write these records: take them out, count them
        /// refused (their acknowledgements said so).
        JournalRefused {
            /// Their seqs.
            seqs: Vec<u64>,
        },
        /// Answer a `Stats` now (a leader's, once the puts before it are committed).
        AnswerStats {
            /// Where the answer goes.
            reply: ractor::RpcReplyPort<DmStats>,
        },
        /// A replica's clock: campaign, send heartbeats, see who is reachable.
        ReplicaTick {},
        /// Tell what the puts applied since it last told (`applied`).
        TellApplied {},
        /// The journal made a replica's entries up to `seq` (of `term`) durable.
        ReplicaDurable {
            /// The last entry durable.
            seq: u64,
            /// Its term.
            term: u64,
        },
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn no_message_is_larger_than_a_put() {
        // a put is the high-rate message: the others must not make every message bigger
        let put = std::mem::size_of::<super::NewRecord>() + 8;
        assert!(std::mem::size_of::<super::DmMsg>() <= put);
    }

    use super::*;
    use crate::record::Payload;
    use ractor::message::SerializedMessage;
    use ractor::Message;

    #[test]
    fn put_crosses_the_wire() {
        let rec = NewRecord::new("sonar", Payload::from_bytes(vec![1, 2]))
            .with_sub1("front")
            .with_source("us");
        let wire = DmMsg::Put {
            record: rec.clone(),
        }
        .serialize()
        .unwrap();
        match DmMsg::deserialize(wire).unwrap() {
            DmMsg::Put { record } => assert_eq!(record, rec),
            other => panic!("wrong variant {other:?}"),
        }
        assert!(DmMsg::WaitExpired { id: 1 }.serialize().is_err());
    }

    #[tokio::test]
    async fn store_reply_crosses_the_bridge() {
        let (tx, rx) = ractor::concurrency::oneshot();
        let wire = DmMsg::Store {
            record: Box::default(),
            reply: tx.into(),
        }
        .serialize()
        .unwrap();
        assert!(matches!(wire, SerializedMessage::Call { .. }));
        match DmMsg::deserialize(wire).unwrap() {
            DmMsg::Store { reply, .. } => {
                reply.send(Err(DmError::InvalidRecord("x".into()))).unwrap();
            }
            other => panic!("wrong variant {other:?}"),
        }
        assert_eq!(rx.await.unwrap(), Err(DmError::InvalidRecord("x".into())));
    }
}
