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
    /// `up`, `lost` (its sessions ended) or `down` (declared down by a failure detector).
    /// A node frozen past its peers' deadline is `down` while it is frozen, and `up` again
    /// once it woke (see `woke`).
    pub status: &'static str,
    /// Its latest freeze past its peers' deadline, once it woke: its operations restarted
    /// as new incarnations then. (It used to be a status of its own, `frozen`, that
    /// nothing but another loss ended: a node that had long been back showed frozen.)
    #[serde(skip_serializing_if = "Option::is_none")]
    pub woke: Option<Woke>,
    /// Its latest return after it was lost (a process restarted under its name, or a
    /// node declared down heard again), as a peer told it (`node_back`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub back: Option<Back>,
    /// The address it listens on, when a peer said.
    pub address: Option<String>,
    /// When its status last changed, ms of the reporting node's clock.
    pub since_ms: u64,
    /// The modules it hosts, by actor address.
    pub modules: BTreeMap<String, ModuleView>,
}

/// A node's wake from a freeze past its peers' deadline (`node_frozen`, told by the node
/// once it woke).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Woke {
    /// When it woke, ms of its clock.
    pub at_ms: u64,
    /// How long it was frozen, ms of real time.
    pub silent_ms: u64,
}

/// A node's return after it was lost (`node_back`, told by a peer that sees it again).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Back {
    /// When the peer saw it back, ms of the peer's clock.
    pub at_ms: u64,
    /// How long it was lost, ms of real time.
    pub down_ms: u64,
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
            woke: None,
            back: None,
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
            EventKind::NodeBack { peer, down_ms, .. } => self.back(peer, at, *down_ms),
            EventKind::NodeFrozen { silent_ms } => self.woke(node, at, *silent_ms),
            _ => {}
        }
    }

    /// `node` published an event: it is alive (known, and up).
    pub fn heard_from(&mut self, node: &str, at_ms: u64) {
        // up again since now, not since it went down
        self.set(node, at_ms, "up");
    }

    /// A peer's session is ready.
    pub fn up(&mut self, peer: &str, address: &str, at_ms: u64) {
        self.set(peer, at_ms, "up").address = Some(address.to_string());
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
        node.back = None;
    }

    /// A peer saw `peer` back after it was lost `down_ms`: up, and the page says since when
    /// and after how long. Each peer tells it; the first to tell of a return is kept (a
    /// loss forgets the previous return).
    pub fn back(&mut self, peer: &str, at_ms: u64, down_ms: u64) {
        let node = self.set(peer, at_ms, "up");
        if node.back.is_none() {
            node.back = Some(Back { at_ms, down_ms });
        }
    }

    /// A failure detector declared a peer down.
    pub fn down(&mut self, peer: &str, at_ms: u64) {
        let node = self.set(peer, at_ms, "down");
        node.modules.clear();
        node.back = None;
    }

    /// A node found, as it woke at `at_ms`, that it was frozen `silent_ms` past its peers'
    /// deadline. Its own news, which reaches a watcher only once the node is back in
    /// session (its forwarder resends it then): before or after its peers' news that they
    /// see it again, as the streams of two nodes interleave — either way it is up again.
    /// Only a loss newer than the wake (a second freeze, a kill) stands.
    pub fn woke(&mut self, node: &str, at_ms: u64, silent_ms: u64) {
        let view = self.of(node, at_ms);
        view.woke = Some(Woke { at_ms, silent_ms });
        let gone_since = matches!(view.status, "down" | "lost") && view.since_ms > at_ms;
        if !gone_since {
            self.set(node, at_ms, "up");
        }
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
    fn a_node_back_is_told_once_per_return_by_the_first_peer_that_sees_it() {
        let mut c = Cluster::default();
        c.down("a", 20);
        c.lost("a", "127.0.0.1:1", 21);
        c.back("a", 300, 270);
        // the other peers' news of the same return keep the first
        c.back("a", 320, 295);
        assert_eq!(c.0["a"].status, "up");
        assert_eq!(
            c.0["a"].back,
            Some(Back {
                at_ms: 300,
                down_ms: 270
            })
        );
        // lost again: the return is forgotten until the next
        c.lost("a", "127.0.0.1:1", 900);
        assert_eq!((c.0["a"].status, c.0["a"].back), ("lost", None));
        c.back("a", 1_400, 480);
        assert_eq!(
            c.0["a"].back,
            Some(Back {
                at_ms: 1_400,
                down_ms: 480
            })
        );
    }

    #[test]
    fn a_node_heard_from_after_it_went_down_is_up_since_then() {
        let mut c = Cluster::default();
        c.heard_from("a", 10);
        c.down("a", 20);
        assert_eq!((c.0["a"].status, c.0["a"].since_ms), ("down", 20));
        c.heard_from("a", 35);
        assert_eq!((c.0["a"].status, c.0["a"].since_ms), ("up", 35));
    }

    /// What a watcher hears of a node frozen (SIGSTOP) past its peers' deadline and woken
    /// (SIGCONT): a peer declares it down and loses its sessions; once it woke, its own
    /// `node_frozen` and a peer's `node_up`, in either order; then its events as ever. It
    /// is up again — not frozen for good — and says it woke.
    #[test]
    fn a_frozen_node_that_woke_is_up_again_whichever_news_comes_first() {
        let event = |at_ms, node: &str, kind| Event {
            at_ms,
            node: node.into(),
            kind,
        };
        let address = "127.0.0.1:1".to_string();
        for frozen_first in [true, false] {
            let mut c = Cluster::default();
            let before = [
                event(
                    10,
                    "b",
                    EventKind::NodeUp {
                        peer: "a".into(),
                        address: address.clone(),
                    },
                ),
                event(
                    20,
                    "b",
                    EventKind::NodeDown {
                        peer: "a".into(),
                        silent_ms: 1500,
                    },
                ),
                event(
                    21,
                    "b",
                    EventKind::NodeLost {
                        peer: "a".into(),
                        address: address.clone(),
                    },
                ),
            ];
            let frozen = event(30, "a", EventKind::NodeFrozen { silent_ms: 4200 });
            let seen = event(
                31,
                "b",
                EventKind::NodeUp {
                    peer: "a".into(),
                    address: address.clone(),
                },
            );
            for e in &before {
                c.apply(e);
            }
            // (declared down is the stronger news: losing its sessions follows it)
            assert_eq!(c.0["a"].status, "down");
            let woke = if frozen_first {
                [&frozen, &seen]
            } else {
                [&seen, &frozen]
            };
            for e in woke {
                c.apply(e);
            }
            let a = &c.0["a"];
            assert_eq!(a.status, "up", "frozen first: {frozen_first}");
            assert_eq!(
                a.woke,
                Some(Woke {
                    at_ms: 30,
                    silent_ms: 4200
                })
            );
            assert_eq!(a.address.as_deref(), Some("127.0.0.1:1"));
            // long after: still up
            c.apply(&event(
                70_000,
                "a",
                EventKind::Robot {
                    what: "pose".into(),
                    data: serde_json::Value::Null,
                },
            ));
            assert_eq!(c.0["a"].status, "up");
            // lost again: lost, and back: up
            c.lost("a", "127.0.0.1:1", 80_000);
            assert_eq!(c.0["a"].status, "lost");
            c.up("a", "127.0.0.1:1", 80_050);
            assert_eq!((c.0["a"].status, c.0["a"].since_ms), ("up", 80_050));
        }
    }

    #[test]
    fn a_wake_told_late_does_not_undo_a_newer_loss() {
        let mut c = Cluster::default();
        c.up("a", "127.0.0.1:1", 10);
        c.down("a", 50);
        // the node's news of a wake at 30, reaching the watcher after the newer loss
        c.woke("a", 30, 4200);
        assert_eq!((c.0["a"].status, c.0["a"].since_ms), ("down", 50));
        assert_eq!(c.0["a"].woke.map(|w| w.silent_ms), Some(4200));
    }
}
