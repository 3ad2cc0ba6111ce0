//! The replicated datamanagers that have no leader now — what the page's cluster panel says
//! "no majority" of while it lasts.
//!
//! Only a monitor learns it (its poll asks the replicas, `dm_no_majority`); a leader's
//! `dm_state` of the same datamanager, which the same poll brings once one is elected, ends
//! it.

use marie_vocabulary::events::{no_majority, EventKind};
use serde::Serialize;
use std::collections::BTreeMap;

/// A datamanager without a majority.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct NoMajorityView {
    /// Since when, ms of the reporting node's clock.
    pub since_ms: u64,
    /// The nodes a majority misses.
    pub missing: Vec<String>,
    /// The words, as `marie ls` and a failed run say them.
    pub words: String,
}

/// Every datamanager without a majority, by name.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(transparent)]
pub struct NoMajorities(pub BTreeMap<String, NoMajorityView>);

impl NoMajorities {
    /// Take `kind` in at `at_ms`: news of a datamanager without a leader, or of its leader.
    pub fn apply(&mut self, at_ms: u64, kind: &EventKind) {
        match kind {
            EventKind::DmNoMajority {
                dm,
                members,
                answering,
                missing,
            } => {
                let since_ms = self.0.get(dm).map_or(at_ms, |v| v.since_ms);
                let words = no_majority(dm, members, answering, missing);
                let view = NoMajorityView {
                    since_ms,
                    missing: missing.clone(),
                    words,
                };
                self.0.insert(dm.clone(), view);
            }
            EventKind::DmState {
                dm,
                role: Some(marie_vocabulary::replica::ReplicaRole::Leader),
                ..
            } => {
                self.0.remove(dm);
            }
            _ => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use marie_vocabulary::replica::ReplicaRole;

    fn lost(dm: &str, missing: &[&str]) -> EventKind {
        EventKind::DmNoMajority {
            dm: dm.into(),
            members: ["features", "operations", "spare"]
                .map(String::from)
                .to_vec(),
            answering: vec!["spare".into()],
            missing: missing.iter().map(|m| m.to_string()).collect(),
        }
    }

    fn state(dm: &str, role: ReplicaRole) -> EventKind {
        EventKind::DmState {
            dm: dm.into(),
            durability: "sync".into(),
            records: 1,
            journal_bytes: 1,
            role: Some(role),
            term: 3,
            lag: Default::default(),
        }
    }

    #[test]
    fn a_datamanager_without_a_leader_is_listed_from_its_first_news_until_its_leader_is_heard() {
        let mut n = NoMajorities::default();
        n.apply(10, &lost("run", &["features", "operations"]));
        n.apply(20, &lost("run", &["operations"]));
        let view = &n.0["run"];
        assert_eq!(
            (view.since_ms, view.missing.clone()),
            (10, vec!["operations".into()])
        );
        assert!(view
            .words
            .contains("has no majority: 1 of its 3 replicas answers (spare)"));
        // a follower's state does not end it; the leader's does
        n.apply(30, &state("run", ReplicaRole::Follower));
        assert!(n.0.contains_key("run"));
        n.apply(40, &state("run", ReplicaRole::Leader));
        assert!(n.0.is_empty());
    }
}
