//! The forwarder: a node's own events, numbered, to every remote watcher — and what a
//! watcher missed while out of reach, from the backlog, when it comes back.

use super::backlog::Backlog;
use super::scope::Changes;
use super::watchers::{WatcherKey, Watchers};
use super::{WatcherMsg, GROUP, KIND, SCOPE};
use marie_vocabulary::events::{BusError, Event, EventBus, EventKind};
use marie_vocabulary::registry::node_name_of;
use marie_vocabulary::wire::Envelope;
use ractor::{pg, ActorRef};
use tokio::task::JoinHandle;
use tokio::time::Instant;

/// Forward every event `bus` publishes to the remote watchers, until the bus closes or the
/// task is aborted. The watchers are looked at on every event, and whenever one comes or
/// goes: one back in reach gets what it missed at once, even from a node that publishes
/// nothing more.
pub fn forward(bus: EventBus) -> JoinHandle<()> {
    let mut sub = bus.subscribe();
    tokio::spawn(async move {
        let mut forwarder = Forwarder::new(bus.node());
        let mut changes = match Changes::watch().await {
            Ok(changes) => Some(changes),
            Err(e) => {
                tracing::error!(error = %e, "cannot watch the event watchers come and go: they are looked at on this node's events only");
                None
            }
        };
        // the watchers already there
        forwarder.look_around();
        loop {
            tokio::select! {
                received = sub.recv() => match received {
                    Ok(event) => forwarder.publish(&event),
                    Err(BusError::Lagged { missed }) => {
                        tracing::warn!(missed, "the event forwarder fell behind its bus");
                        forwarder.skip(missed);
                    }
                    Err(BusError::Closed) => return,
                },
                () = next_change(&mut changes) => {
                    forwarder.look_around();
                }
            }
        }
    })
}

/// The next change of the watchers; pending forever without a watch of them.
async fn next_change(changes: &mut Option<Changes>) {
    match changes {
        Some(c) => c.next().await,
        None => std::future::pending().await,
    }
}

/// What a node's forwarder keeps.
struct Forwarder {
    node: String,
    /// This forwarder's numbering (a new one with every process).
    stream: u64,
    /// The number of the next event.
    next: u64,
    backlog: Backlog,
    watchers: Watchers,
}

impl Forwarder {
    fn new(node: &str) -> Forwarder {
        Forwarder {
            node: node.to_string(),
            stream: new_stream(),
            next: 1,
            backlog: Backlog::default(),
            watchers: Watchers::default(),
        }
    }

    /// Forward `event` of this node's bus to every watcher in reach (after what a watcher
    /// that came back missed), and keep it for those out of reach.
    fn publish(&mut self, event: &Event) {
        if echo_of_another_node(event, &self.node) {
            return;
        }
        let in_reach = self.look_around();
        let seq = self.next;
        self.next += 1;
        if !self.watchers.any() {
            return;
        }
        let frame = match Envelope::new(KIND, event).and_then(|e| e.to_bytes()) {
            Ok(frame) => frame,
            Err(e) => {
                tracing::error!(error = %e, "cannot encode an event to forward");
                return;
            }
        };
        for w in &in_reach {
            self.cast(&w.1, seq, frame.clone());
        }
        self.backlog.push(seq, frame);
    }

    /// The bus dropped `missed` events before this forwarder read them: their numbers are
    /// skipped, so that a watcher counts them lost.
    fn skip(&mut self, missed: u64) {
        self.next += missed;
    }

    /// Take in the watchers in reach now, resend to each one that came back what it
    /// missed, and give them all.
    fn look_around(&mut self) -> Vec<(WatcherKey, ActorRef<WatcherMsg>)> {
        let in_reach: Vec<(WatcherKey, ActorRef<WatcherMsg>)> =
            pg::get_scoped_members(&SCOPE.to_string(), &GROUP.to_string())
                .into_iter()
                .filter(|c| !c.get_id().is_local())
                .map(|c| {
                    let id = c.get_id();
                    let key = WatcherKey {
                        node: node_name_of(&id),
                        pid: id.pid(),
                    };
                    (key, c.into())
                })
                .collect();
        let back = self.watchers.observe(
            in_reach.iter().map(|(k, w)| (k.clone(), w.get_id())),
            self.next,
            Instant::now(),
        );
        for (key, from) in back {
            let Some((_, w)) = in_reach.iter().find(|(k, _)| *k == key) else {
                continue;
            };
            let frames: Vec<(u64, Vec<u8>)> = self
                .backlog
                .since(from)
                .map(|(seq, frame)| (seq, frame.clone()))
                .collect();
            tracing::info!(
                watcher = %w.get_id(),
                node = %key.node,
                resent = frames.len(),
                "an event watcher is back in reach: what it may have missed is sent again"
            );
            for (seq, frame) in frames {
                self.cast(w, seq, frame);
            }
        }
        if !self.watchers.any() {
            self.backlog.clear();
        }
        in_reach
    }

    fn cast(&self, watcher: &ActorRef<WatcherMsg>, seq: u64, frame: Vec<u8>) {
        let _ = watcher.cast(WatcherMsg::Numbered {
            stream: self.stream,
            seq,
            frame,
        });
    }
}

/// A number for a forwarder's stream, new with every forwarder: the std hasher's random
/// keys (from the OS, per process), over the time and the process id.
fn new_stream() -> u64 {
    use std::hash::{BuildHasher, Hasher};
    let mut h = std::collections::hash_map::RandomState::new().build_hasher();
    let since_epoch = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap_or_default();
    h.write_u128(since_epoch.as_nanos());
    h.write_u32(std::process::id());
    h.finish()
}

/// Whether `event` only echoes news of another node: a module of another node joining or
/// leaving this node's registry (that node tells it itself).
fn echo_of_another_node(event: &Event, here: &str) -> bool {
    matches!(&event.kind, EventKind::Joined(m) | EventKind::Left(m) if m.node != here)
}

#[cfg(test)]
mod tests {
    use super::*;
    use marie_vocabulary::events::ModuleInfo;
    use marie_vocabulary::registry::ModuleKind;

    fn event(kind: EventKind) -> Event {
        Event {
            at_ms: 7,
            node: "alpha".into(),
            kind,
        }
    }

    fn joined(node: &str) -> EventKind {
        EventKind::Joined(ModuleInfo {
            module: ModuleKind::Operation,
            name: "sampler".into(),
            id: 1,
            node: node.into(),
            address: "0.1".into(),
        })
    }

    #[test]
    fn a_module_is_told_by_its_own_node_only() {
        assert!(!echo_of_another_node(&event(joined("alpha")), "alpha"));
        assert!(echo_of_another_node(&event(joined("beta")), "alpha"));
        let frozen = event(EventKind::NodeFrozen { silent_ms: 1 });
        assert!(!echo_of_another_node(&frozen, "alpha"));
    }

    #[test]
    fn streams_differ() {
        assert_ne!(new_stream(), new_stream());
    }
}
