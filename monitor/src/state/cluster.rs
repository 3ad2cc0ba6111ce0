//! The cluster: every node the stream names, whether it is up, and the modules it hosts —
//! what the page's cluster panel draws.
//!
//! A node is known from any event it publishes (it is up then) and from its peers' news of
//! it (seen, lost, declared down); what it hosts from the registry's joins and leaves, each
//! told by the module's own node.

use marie_vocabulary::events::{Event, EventKind, ModuleInfo};
use serde::Serialize;
use std::collections::BTreeMap;

/// What is known of one node.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct NodeView {
    /// Its name.
    pub name: String,
    /// `up`, `lost` (its sessions ended), `down` (declared down by a failure detector) or
    /// `frozen` (up again after it was frozen past its peers' deadline, its operations
    /// restarted as new incarnations: shown until it is lost or declared down again).
    pub status: &'static str,
    /// The address it listens on, when a peer said.
    pub address: Option<String>,
    /// When its status last changed, ms of the reporting node's clock.
    pub since_ms: u64,
    /// The modules it hosts, by actor address.
    pub modules: BTreeMap<String, ModuleView>,
}

/// A module in the location table.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ModuleView {
    /// `operation`, `datamanager`, `dispatcher` or `hardware`.
    pub kind: &'static str,
    /// Its name.
    pub name: String,
    /// Its numeric id.
    pub id: u32,
    /// Its actor address.
    pub address: String,
    /// A datamanager's state, as last asked.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dm: Option<DmView>,
}

/// What a datamanager holds, as the monitor last asked it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DmView {
    /// `memory`, `process` or `sync`.
    pub durability: String,
    /// Records stored.
    pub records: u64,
    /// Bytes of its journal.
    pub journal_bytes: u64,
    /// `leader` of a replicated datamanager.
    pub role: Option<marie_vocabulary::replica::ReplicaRole>,
    /// Its term.
    pub term: u64,
    /// How many entries each other replica lacks.
    pub lag: BTreeMap<String, u64>,
}

/// Every node, by name.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
#[serde(transparent)]
pub struct Cluster(pub BTreeMap<String, NodeView>);

impl Cluster {
    fn of(&mut self, name: &str, at_ms: u64) -> &mut NodeView {
        self.0.entry(name.to_string()).or_insert_with(|| NodeView {
            name: name.to_string(),
            status: "up",
            address: None,
            since_ms: at_ms,
            modules: BTreeMap::new(),
        })
    }

    fn set(&mut self, name: &str, at_ms: u64, status: &'static str) -> &mut NodeView {
        let node = self.of(name, at_ms);
        if node.status != status {
            node.status = status;
            node.since_ms = at_ms;
        }
        node
    }

    /// Take `event` in: its node was heard from, and the cluster's news — nodes up, lost,
    /// down, frozen; modules that joined or left; a datamanager's state — change the
    /// picture. Other events pass by.
    pub fn apply(&mut self, event: &Event) {
        let (node, at) = (event.node.as_str(), event.at_ms);
        self.heard_from(node, at);
        match &event.kind {
            EventKind::Joined(m) => self.joined(m, at),
            EventKind::Left(m) => self.left(m, at),
            EventKind::DmState {
                dm,
                durability,
                records,
                journal_bytes,
                role,
                term,
                lag,
            } => {
                let view = DmView {
                    durability: durability.clone(),
                    records: *records,
                    journal_bytes: *journal_bytes,
                    role: *role,
                    term: *term,
                    lag: lag.clone(),
                };
                self.dm_state(node, dm, view, at)
            }
            EventKind::NodeUp { peer, address } => self.up(peer, address, at),
            EventKind::NodeLost { peer, address } => self.lost(peer, address, at),
            EventKind::NodeDown { peer, .. } => self.down(peer, at),
            EventKind::NodeFrozen { .. } => self.frozen(node, at),
            _ => {}
        }
    }

    /// `node` published an event: it is alive (known, and up unless it said otherwise).
    pub fn heard_from(&mut self, node: &str, at_ms: u64) {
        if self.of(node, at_ms).status != "frozen" {
            // up again since now, not since it went down
            self.set(node, at_ms, "up");
        }
    }

    /// A peer's session is ready. A frozen node stays frozen: being up again is part of
    /// what that tells.
    pub fn up(&mut self, peer: &str, address: &str, at_ms: u64) {
        let node = self.of(peer, at_ms);
        if node.status != "frozen" {
            self.set(peer, at_ms, "up");
        }
        self.of(peer, at_ms).address = Some(address.to_string());
    }

    /// A peer's sessions ended: its modules left.
    pub fn lost(&mut self, peer: &str, address: &str, at_ms: u64) {
        let node = self.of(peer, at_ms);
        // declared down is the stronger news; losing the sessions follows it
        if node.status != "down" {
            node.status = "lost";
            node.since_ms = at_ms;
        }
        node.address = Some(address.to_string());
        node.modules.clear();
    }

    /// A failure detector declared a peer down.
    pub fn down(&mut self, peer: &str, at_ms: u64) {
        self.set(peer, at_ms, "down").modules.clear();
    }

    /// A node found it was frozen past its peers' deadline. Its own news, which reaches a
    /// watcher only once the node is back in session (its forwarder resends it then):
    /// before or after its peers' news that they see it again, as the streams of two
    /// nodes happen to interleave. So neither undoes the other: the node shows frozen —
    /// up again, its operations restarted — until it is lost or declared down again.
    pub fn frozen(&mut self, node: &str, at_ms: u64) {
        self.set(node, at_ms, "frozen");
    }

    /// A module joined the location table.
    pub fn joined(&mut self, m: &ModuleInfo, at_ms: u64) {
        let node = self.of(&m.node, at_ms);
        node.modules.insert(
            m.address.clone(),
            ModuleView {
                kind: kind_label(m),
                name: m.name.clone(),
                id: m.id,
                address: m.address.clone(),
                dm: None,
            },
        );
    }

    /// What datamanager `dm` on `node` holds now.
    pub fn dm_state(&mut self, node: &str, dm: &str, view: DmView, at_ms: u64) {
        let node = self.of(node, at_ms);
        for m in node.modules.values_mut() {
            if m.kind == "datamanager" && m.name == dm {
                m.dm = Some(view.clone());
            }
        }
    }

    /// A module left the location table.
    pub fn left(&mut self, m: &ModuleInfo, at_ms: u64) {
        self.of(&m.node, at_ms).modules.remove(&m.address);
    }
}

fn kind_label(m: &ModuleInfo) -> &'static str {
    use marie_vocabulary::registry::ModuleKind;
    match m.module {
        ModuleKind::Operation => "operation",
        ModuleKind::Datamanager => "datamanager",
        ModuleKind::Dispatcher => "dispatcher",
        ModuleKind::Hardware => "hardware",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_node_heard_from_after_it_went_down_is_up_since_then() {
        let mut c = Cluster::default();
        c.heard_from("a", 10);
        c.down("a", 20);
        assert_eq!((c.0["a"].status, c.0["a"].since_ms), ("down", 20));
        c.heard_from("a", 35);
        assert_eq!((c.0["a"].status, c.0["a"].since_ms), ("up", 35));
        // a frozen node stays frozen until it says otherwise
        c.frozen("a", 40);
        c.heard_from("a", 50);
        assert_eq!((c.0["a"].status, c.0["a"].since_ms), ("frozen", 40));
    }

    #[test]
    fn a_woken_node_shows_frozen_whichever_news_comes_first_until_it_is_gone_again() {
        for freeze_first in [true, false] {
            let mut c = Cluster::default();
            c.up("a", "127.0.0.1:1", 10);
            c.down("a", 20);
            // the node's own news, stamped when it woke, and a peer's seeing it again
            if freeze_first {
                c.frozen("a", 30);
                c.up("a", "127.0.0.1:1", 31);
            } else {
                c.up("a", "127.0.0.1:1", 31);
                c.frozen("a", 30);
            }
            c.heard_from("a", 32);
            assert_eq!(c.0["a"].status, "frozen", "freeze first: {freeze_first}");
            assert_eq!(c.0["a"].address.as_deref(), Some("127.0.0.1:1"));
            c.lost("a", "127.0.0.1:1", 40);
            assert_eq!(c.0["a"].status, "lost");
            c.up("a", "127.0.0.1:1", 50);
            assert_eq!((c.0["a"].status, c.0["a"].since_ms), ("up", 50));
        }
    }
}
