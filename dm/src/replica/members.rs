//! Who keeps a replicated datamanager's replicas, and how that changes while it runs.
//!
//! A configuration ([`Members`]) is an entry of the replicated log, as a record is: a replica
//! uses the newest configuration its log holds, committed or not (Raft's single-server
//! changes, §4 of Ongaro's thesis), so a change takes effect where it is appended and is
//! undone if that entry is cut. One change at a time, each adding or removing one replica:
//! any majority of the configuration before and of the one after then share a replica,
//! so the two can never elect two leaders or commit two different entries at one seq.
//!
//! A replica added joins as a *learner*: it is sent the log (or a snapshot) like the
//! others, but counts for neither a commit nor an election, so a replica that starts empty
//! does not stall the commits while it catches up. The leader promotes it to a voter once it
//! holds everything committed (another change of one replica). A leader that removes itself
//! goes on leading without counting itself until the removal is committed, then hands its
//! role to the most up-to-date voter and steps down.

use serde::{Deserialize, Serialize};

/// A configuration of a replicated datamanager: which nodes keep a replica, and which of
/// them vote.
#[derive(Clone, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(default)]
pub struct Members {
    /// The replicas that vote: a majority of them commits an entry and elects a leader
    /// (their nodes, sorted).
    pub voters: Vec<String>,
    /// The replicas catching up: they take in the log but count for nothing until the
    /// leader promotes them (sorted).
    pub learners: Vec<String>,
}

impl Members {
    /// A configuration of `voters` and `learners` (sorted, each named once; a node named
    /// in both is a voter).
    pub fn new(
        voters: impl IntoIterator<Item = impl Into<String>>,
        learners: impl IntoIterator<Item = impl Into<String>>,
    ) -> Members {
        let mut voters: Vec<String> = voters.into_iter().map(Into::into).collect();
        voters.sort();
        voters.dedup();
        let mut learners: Vec<String> = learners
            .into_iter()
            .map(Into::into)
            .filter(|l| !voters.contains(l))
            .collect();
        learners.sort();
        learners.dedup();
        Members { voters, learners }
    }

    /// Whether `node` votes.
    pub fn is_voter(&self, node: &str) -> bool {
        self.voters.iter().any(|v| v == node)
    }

    /// Whether `node` is a learner.
    pub fn is_learner(&self, node: &str) -> bool {
        self.learners.iter().any(|l| l == node)
    }

    /// Whether `node` keeps a replica (voter or learner).
    pub fn contains(&self, node: &str) -> bool {
        self.is_voter(node) || self.is_learner(node)
    }

    /// Every node that keeps a replica, voters first.
    pub fn all(&self) -> impl Iterator<Item = &String> {
        self.voters.iter().chain(&self.learners)
    }

    /// How many voters make a majority.
    pub fn majority(&self) -> usize {
        self.voters.len() / 2 + 1
    }

    /// The configuration `change` makes of this one, or why it cannot (judged on this
    /// configuration alone; the leader checks the rest: one change at a time, a majority
    /// answering).
    pub fn changed(&self, change: &Change) -> Result<Members, ChangeError> {
        match change {
            Change::Add(node) if self.contains(node) => {
                Err(ChangeError::AlreadyMember(node.clone()))
            }
            Change::Add(node) => Ok(Members::new(
                self.voters.iter().cloned(),
                self.learners.iter().cloned().chain([node.clone()]),
            )),
            Change::Remove(node) if !self.contains(node) => {
                Err(ChangeError::NotAMember(node.clone()))
            }
            Change::Remove(node) if self.is_voter(node) && self.voters.len() <= MIN_VOTERS => {
                Err(ChangeError::TooFew {
                    node: node.clone(),
                    left: self.voters.len() - 1,
                })
            }
            Change::Remove(node) => Ok(Members::new(
                self.voters.iter().filter(|v| *v != node).cloned(),
                self.learners.iter().filter(|l| *l != node).cloned(),
            )),
        }
    }

    /// This configuration with learner `node` a voter.
    pub(crate) fn promoted(&self, node: &str) -> Members {
        Members::new(
            self.voters.iter().cloned().chain([node.to_string()]),
            self.learners.iter().filter(|l| *l != node).cloned(),
        )
    }
}

impl std::fmt::Display for Members {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "voters {}", self.voters.join(", "))?;
        if !self.learners.is_empty() {
            write!(f, "; learners {}", self.learners.join(", "))?;
        }
        Ok(())
    }
}

/// Fewer voters than this are refused by a removal: a majority of them could not survive
/// the loss of one (as a datamanager's start refuses fewer than three replicas).
pub const MIN_VOTERS: usize = 3;

/// A change of one replica asked of a replicated datamanager's leader.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Change {
    /// Add a replica on this node, as a learner: the leader promotes it to a voter once it
    /// caught up.
    Add(String),
    /// Remove the replica of this node (a voter or a learner).
    Remove(String),
}

impl Change {
    /// The node the change is about.
    pub fn node(&self) -> &str {
        match self {
            Change::Add(n) | Change::Remove(n) => n,
        }
    }
}

/// Why a leader refused a [`Change`].
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize, thiserror::Error)]
pub enum ChangeError {
    /// The replica asked is not the leader (its caller asks the one published).
    #[error("this replica is not the leader")]
    NotLeader,
    /// The datamanager keeps no replicas.
    #[error("this datamanager keeps no replicas")]
    Unreplicated,
    /// The leader that took the change stepped down before it was committed: it may be
    /// committed by the next leader, or cut. Ask the datamanager's replicas again.
    #[error("the leader stepped down before the change was committed ({0}): see whether it was, and ask again")]
    Interrupted(String),
    /// The leader was just elected and has not committed an entry of its own term: a
    /// change now could overlap with one its predecessor left uncommitted.
    #[error("the leader was just elected and has committed nothing of its term yet: try again in a moment")]
    NotReady,
    /// Another change is under way (one at a time).
    #[error("a change is under way: {0}")]
    Pending(String),
    /// A node name that cannot be one (empty, over 255 bytes, with white space).
    #[error("{0:?} is no node name")]
    InvalidNode(String),
    /// The node already keeps a replica.
    #[error("{0} already keeps a replica")]
    AlreadyMember(String),
    /// The node keeps no replica.
    #[error("{0} keeps no replica")]
    NotAMember(String),
    /// The removal would leave fewer than [`MIN_VOTERS`] voters.
    #[error("removing {node} would leave {left} voting replicas: a majority of them could not survive the loss of one; add a replica first")]
    TooFew {
        /// The node to remove.
        node: String,
        /// The voters left.
        left: usize,
    },
    /// The replicas that would remain and answer the leader are no majority of them: the
    /// change could never be committed.
    #[error("removing {node} would leave no majority: of the voters {remain:?}, only {live:?} answer the leader")]
    NoMajority {
        /// The node to remove.
        node: String,
        /// The voters that would remain.
        remain: Vec<String>,
        /// Those that answered the leader within an election timeout.
        live: Vec<String>,
    },
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_change_of_one_replica_makes_the_next_configuration_or_says_why_not() {
        let three = Members::new(["c", "a", "b"], Vec::<String>::new());
        assert_eq!(three.voters, ["a", "b", "c"]);
        assert_eq!(three.majority(), 2);
        let four = three.changed(&Change::Add("d".into())).unwrap();
        assert_eq!(
            (four.voters.len(), four.learners.clone()),
            (3, vec!["d".to_string()])
        );
        assert_eq!(four.majority(), 2, "a learner does not count");
        assert_eq!(four.promoted("d").majority(), 3);
        assert_eq!(
            four.changed(&Change::Add("d".into())),
            Err(ChangeError::AlreadyMember("d".into()))
        );
        assert_eq!(
            three.changed(&Change::Remove("x".into())),
            Err(ChangeError::NotAMember("x".into()))
        );
        assert_eq!(
            three
                .changed(&Change::Remove("a".into()))
                .unwrap_err()
                .to_string(),
            "removing a would leave 2 voting replicas: a majority of them could not survive \
             the loss of one; add a replica first"
        );
        assert_eq!(
            four.changed(&Change::Remove("d".into())).unwrap(),
            three,
            "a learner removed: the change cancelled"
        );
        assert_eq!(
            four.promoted("d")
                .changed(&Change::Remove("a".into()))
                .unwrap()
                .to_string(),
            "voters b, c, d"
        );
    }
}
