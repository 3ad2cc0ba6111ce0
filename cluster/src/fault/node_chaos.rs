//! Seeded random node faults for `marie up --run … --chaos-nodes SEED`: every few seconds,
//! one node other than the spared ones (the cart's: its loss is the robot's) is stopped,
//! frozen for a while, or cut off from all the others for a while.

use super::{Chaos, NodeProcesses, Target};
use marie_vocabulary::run::FaultKind;
use std::time::Duration;

/// Random node faults, seeded: the same seed and the same nodes give the same faults at the
/// same times.
#[derive(Clone, Debug)]
pub struct NodeChaos {
    chaos: Chaos,
    /// Nodes never hit (the cart's).
    spared: Vec<String>,
    /// Shortest a freeze or a cut lasts.
    pub min_lasting: Duration,
    /// Longest a freeze or a cut lasts.
    pub max_lasting: Duration,
}

/// One node fault a [`NodeChaos`] drew.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct NodeStrike {
    /// What.
    pub kind: FaultKind,
    /// To what: a node, or a node cut off from the others.
    pub target: Target,
    /// How long, for a freeze or a cut.
    pub lasting: Option<Duration>,
}

impl NodeChaos {
    /// Node chaos seeded by `seed`, a fault every 8 to 16 seconds of mission time, each
    /// freeze or cut lasting 2 to 6 seconds of mission time, never touching the `spared`
    /// nodes. At wall-clock speed that is past the failure detector's default deadline
    /// (1.2 s of real time), so the peers declare the node down; a cluster run faster
    /// (`--speed 4`: 0.5 to 1.5 s of real time) may see a short one ride through.
    pub fn new(seed: u64, spared: impl IntoIterator<Item = String>) -> NodeChaos {
        NodeChaos {
            chaos: Chaos::new(seed).with_gaps(Duration::from_secs(8), Duration::from_secs(16)),
            spared: spared.into_iter().collect(),
            min_lasting: Duration::from_secs(2),
            max_lasting: Duration::from_secs(6),
        }
    }

    /// The time until the next fault.
    pub fn next_gap(&mut self) -> Duration {
        self.chaos.next_gap()
    }

    /// Draw the next fault among the nodes `processes` may hit now (a stopped node is no
    /// longer among them): a node other than the spared ones, and a kind among `stop-node`,
    /// `freeze-node` and — when the nodes run in a network that can be cut — `partition`
    /// (that node against every other). `None` when no node may be hit.
    pub fn draw(&mut self, processes: &NodeProcesses) -> Option<NodeStrike> {
        let all = processes.names();
        let victims: Vec<&String> = all.iter().filter(|n| !self.spared.contains(n)).collect();
        let node = (*self.chaos.pick(&victims)?).clone();
        let mut kinds = vec![FaultKind::StopNode, FaultKind::FreezeNode];
        if processes.can_cut() && all.len() > 1 {
            kinds.push(FaultKind::Partition);
        }
        let kind = *self.chaos.pick(&kinds)?;
        let lasting = kind
            .lasts()
            .then(|| self.chaos.between(self.min_lasting, self.max_lasting));
        let target = match kind {
            FaultKind::Partition => Target::cut_off(&node, &all),
            _ => Target::Node(node),
        };
        Some(NodeStrike {
            kind,
            target,
            lasting,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn node_chaos_is_deterministic_spares_the_cart_and_stays_within_its_bounds() {
        let processes = NodeProcesses::new(
            ["cart", "features", "operations", "spare"]
                .into_iter()
                .enumerate()
                .map(|(i, n)| (n.to_string(), 1000 + i as u32)),
        );
        let mut a = NodeChaos::new(3, ["cart".to_string()]);
        let mut b = NodeChaos::new(3, ["cart".to_string()]);
        let mut kinds = std::collections::BTreeSet::new();
        for _ in 0..200 {
            let gap = a.next_gap();
            assert_eq!(gap, b.next_gap());
            assert!((Duration::from_secs(8)..=Duration::from_secs(16)).contains(&gap));
            let strike = a.draw(&processes).unwrap();
            assert_eq!(Some(&strike), b.draw(&processes).as_ref());
            match &strike.target {
                Target::Node(n) => assert_ne!(n, "cart"),
                other => panic!("no network to cut: {other:?}"),
            }
            assert_eq!(strike.lasting.is_some(), strike.kind.lasts());
            if let Some(d) = strike.lasting {
                assert!((a.min_lasting..=a.max_lasting).contains(&d), "{d:?}");
            }
            kinds.insert(strike.kind);
        }
        assert_eq!(
            kinds.into_iter().collect::<Vec<_>>(),
            [FaultKind::StopNode, FaultKind::FreezeNode]
        );
        // only the cart left: nothing to hit
        let cart_only = NodeProcesses::new([("cart".to_string(), 1)]);
        assert_eq!(a.draw(&cart_only), None);
    }
}
