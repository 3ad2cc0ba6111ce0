//! Each replicated datamanager's way back to full strength, as its leader told it: the
//! replicas lost and caught up since (`dm_replica_caught_up`, with how long after the
//! loss), and the last time every replica was current again (`dm_redundancy_restored`) —
//! what the page's cluster panel says beside "no majority", so an operator sees when the
//! cluster can take the next fault.

use marie_vocabulary::events::EventKind;
use serde::Serialize;
use std::collections::BTreeMap;

/// One datamanager's latest news of its strength.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct StrengthView {
    /// The replicas caught up since the last restoration: node, ms after its loss.
    pub caught_up: BTreeMap<String, u64>,
    /// The last restoration: when (ms of the leader's clock), how long after the first
    /// loss, and how many replicas are current.
    pub restored: Option<Restored>,
}

/// A datamanager back to full strength.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Restored {
    /// When its leader told it, ms of that node's clock.
    pub at_ms: u64,
    /// How long after the first replica was lost, ms.
    pub after_ms: u64,
    /// Its replicas, all current.
    pub replicas: u32,
}

/// Every replicated datamanager that told of its strength, by name.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(transparent)]
pub struct Strengths(pub BTreeMap<String, StrengthView>);

impl Strengths {
    /// Take `kind` in at `at_ms`.
    pub fn apply(&mut self, at_ms: u64, kind: &EventKind) {
        match kind {
            EventKind::DmReplicaCaughtUp { dm, node, after_ms } => {
                let view = self.0.entry(dm.clone()).or_default();
                view.caught_up.insert(node.clone(), *after_ms);
            }
            EventKind::DmRedundancyRestored {
                dm,
                replicas,
                after_ms,
            } => {
                let view = self.0.entry(dm.clone()).or_default();
                view.caught_up.clear();
                view.restored = Some(Restored {
                    at_ms,
                    after_ms: *after_ms,
                    replicas: *replicas,
                });
            }
            _ => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_replica_caught_up_is_listed_until_the_redundancy_is_restored() {
        let mut s = Strengths::default();
        s.apply(
            1_000,
            &EventKind::DmReplicaCaughtUp {
                dm: "feature".into(),
                node: "spare".into(),
                after_ms: 2_400,
            },
        );
        assert_eq!(s.0["feature"].caught_up["spare"], 2_400);
        assert_eq!(s.0["feature"].restored, None);
        s.apply(
            1_200,
            &EventKind::DmRedundancyRestored {
                dm: "feature".into(),
                replicas: 3,
                after_ms: 2_600,
            },
        );
        let view = &s.0["feature"];
        assert!(view.caught_up.is_empty());
        assert_eq!(
            view.restored,
            Some(Restored {
                at_ms: 1_200,
                after_ms: 2_600,
                replicas: 3
            })
        );
    }
}
