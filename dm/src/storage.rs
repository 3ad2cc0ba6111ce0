//! Where a datamanager keeps what it acknowledges: in memory only, in a journal, or in a
//! journal as one replica of a replicated datamanager.
//!
//! One enum rather than an optional journal beside an optional replica: a replica cannot
//! be without its journal (its vote and log must survive its restart), and the type says so
//! — the handlers match on the mode instead of expecting a journal to be there.

use super::journal::{Durability, Journal};
use super::replica_state::ReplicaState;

/// How a datamanager stores, chosen at its start from its [`DmArgs`](super::DmArgs).
pub(crate) enum Storage {
    /// Durability `memory`: nothing on disk.
    Memory,
    /// Durability `process` or `sync`, without replicas: a journal of its own.
    Journaled(Journal),
    /// One replica of a replicated datamanager: its journal, and its side of the protocol.
    Replicated {
        /// Its journal: the records, and the protocol's log entries.
        journal: Journal,
        /// The protocol's state: its core, the other replicas reachable, the answers
        /// waiting for a commit (boxed: it is large, and the other modes hold nothing like it).
        replica: Box<ReplicaState>,
    },
}

impl Storage {
    /// The journal, unless the durability is `memory`.
    pub(crate) fn journal(&self) -> Option<&Journal> {
        match self {
            Storage::Memory => None,
            Storage::Journaled(journal) | Storage::Replicated { journal, .. } => Some(journal),
        }
    }

    /// The journal, unless the durability is `memory`.
    pub(crate) fn journal_mut(&mut self) -> Option<&mut Journal> {
        match self {
            Storage::Memory => None,
            Storage::Journaled(journal) | Storage::Replicated { journal, .. } => Some(journal),
        }
    }

    /// The replica's state, if this datamanager is replicated.
    pub(crate) fn replica(&self) -> Option<&ReplicaState> {
        match self {
            Storage::Replicated { replica, .. } => Some(&**replica),
            Storage::Memory | Storage::Journaled(_) => None,
        }
    }

    /// The replica's state, if this datamanager is replicated.
    pub(crate) fn replica_mut(&mut self) -> Option<&mut ReplicaState> {
        match self {
            Storage::Replicated { replica, .. } => Some(&mut **replica),
            Storage::Memory | Storage::Journaled(_) => None,
        }
    }

    /// The replica's state and its journal, if this datamanager is replicated.
    pub(crate) fn replicated_mut(&mut self) -> Option<(&mut ReplicaState, &mut Journal)> {
        match self {
            Storage::Replicated { replica, journal } => Some((&mut **replica, journal)),
            Storage::Memory | Storage::Journaled(_) => None,
        }
    }

    /// Whether this datamanager is one replica of several.
    pub(crate) fn is_replicated(&self) -> bool {
        matches!(self, Storage::Replicated { .. })
    }

    /// How durable its acknowledged writes are.
    pub(crate) fn durability(&self) -> Durability {
        self.journal()
            .map_or(Durability::Memory, Journal::durability)
    }

    /// Bytes of its journal on disk (0 at `memory`).
    pub(crate) fn journal_bytes(&self) -> u64 {
        self.journal().map_or(0, Journal::bytes)
    }

    /// Close the journal, if there is one: it waits for the writer to finish what it was
    /// handed. The replica's state (its ticker) goes once the journal is closed.
    pub(crate) async fn close(self) {
        match self {
            Storage::Memory => {}
            Storage::Journaled(journal) => journal.close().await,
            Storage::Replicated { journal, replica } => {
                journal.close().await;
                drop(replica);
            }
        }
    }
}
