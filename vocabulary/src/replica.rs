//! What a replica of a replicated datamanager is at a moment, in the words of Raft, which
//! the datamanager's replication follows: the one replica that answers (the **leader**) and
//! the others, which journal what it sends (its **followers**).
//!
//! The datamanager's stats and the monitor's `dm_state` event say it; `marie ls` and the
//! page show it. Builds before this word was settled said `primary` and `copy`; both are
//! still read.
//!
//! ```
//! use marie_vocabulary::replica::ReplicaRole;
//! let role: ReplicaRole = serde_json::from_str("\"primary\"").unwrap();
//! assert_eq!(role, ReplicaRole::Leader);
//! assert_eq!(role.to_string(), "leader");
//! ```

use serde::{Deserialize, Serialize};
use std::fmt;

/// A replica's role: the leader answers and replicates; a follower journals what the
/// leader sends and may be elected when it is lost.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ReplicaRole {
    /// The replica that answers reads and writes, acknowledging a write once a majority
    /// journaled it.
    #[serde(alias = "primary")]
    Leader,
    /// A replica that journals the leader's entries (or has no leader yet).
    #[default]
    #[serde(alias = "copy")]
    Follower,
}

impl ReplicaRole {
    /// The role's word, as its JSON says it.
    pub fn word(self) -> &'static str {
        match self {
            ReplicaRole::Leader => "leader",
            ReplicaRole::Follower => "follower",
        }
    }
}

impl fmt::Display for ReplicaRole {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.word())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The wire (rmp-serde, named) says the role as its word, which a build that read it as
    /// a string reads; the older words still decode.
    #[test]
    fn a_role_crosses_nodes_as_its_word_and_the_old_words_still_read() {
        for role in [ReplicaRole::Leader, ReplicaRole::Follower] {
            let bytes = rmp_serde::to_vec_named(&role).unwrap();
            let as_string: String = rmp_serde::from_slice(&bytes).unwrap();
            assert_eq!(as_string, role.word());
            assert_eq!(rmp_serde::from_slice::<ReplicaRole>(&bytes).unwrap(), role);
        }
        for (old, role) in [
            ("primary", ReplicaRole::Leader),
            ("copy", ReplicaRole::Follower),
        ] {
            let bytes = rmp_serde::to_vec_named(old).unwrap();
            assert_eq!(rmp_serde::from_slice::<ReplicaRole>(&bytes).unwrap(), role);
            let json = serde_json::to_string(old).unwrap();
            assert_eq!(serde_json::from_str::<ReplicaRole>(&json).unwrap(), role);
        }
        assert!(serde_json::from_str::<ReplicaRole>("\"boss\"").is_err());
    }
}
