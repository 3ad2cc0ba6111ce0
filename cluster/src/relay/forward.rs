//! The forwarder: a node's own events, numbered, to every remote watcher — and what a
//! watcher missed while out of reach, from the backlog, when it comes back.

use super::backlog::Backlog;
use super::scope::Changes;
use super::watchers::{WatcherKey, Watchers};
use super::{WatcherMsg, GROUP, KIND, SCOPE};
use crate::net::Agreement;
use marie_vocabulary::events::{BusError, Event, EventBus, EventKind};
use marie_vocabulary::registry::node_name_of;
use marie_vocabulary::wire::{Envelope, EnvelopeError, PROTOCOL_VERSION};
use ractor::{pg, ActorRef};
use std::collections::BTreeMap;
use tokio::task::JoinHandle;
use tokio::time::Instant;

/// Forward every event `bus` publishes to the remote watchers, until the bus closes or the
/// task is aborted, each in a frame of the protocol version `agreement` says for its node
/// (a transport's [`Transport::agreement`](crate::net::Transport::agreement)). The watchers
/// are looked at on every event, and whenever one comes or goes: one back in reach gets
/// what it missed at once, even from a node that publishes nothing more.
pub fn forward(bus: EventBus, agreement: Agreement) -> JoinHandle<()> {
    let mut sub = bus.subscribe();
    tokio::spawn(async move {
        let mut forwarder = Forwarder::new(bus.node(), agreement);
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
    /// The frames of the latest events, each at this build's newest protocol version.
    backlog: Backlog,
    watchers: Watchers,
    /// The protocol version of a frame for each watcher's node.
    agreement: Agreement,
}

impl Forwarder {
    fn new(node: &str, agreement: Agreement) -> Forwarder {
        Forwarder {
            node: node.to_string(),
            stream: new_stream(),
            next: 1,
            backlog: Backlog::default(),
            watchers: Watchers::default(),
            agreement,
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
        // encoded once per protocol version: the watchers agreed on one share its frame
        let mut frames: BTreeMap<u16, Vec<u8>> = BTreeMap::new();
        for (_, w) in &in_reach {
            let version = self.agreement.for_session(w.get_id().node());
            let frame = match frames.entry(version) {
                std::collections::btree_map::Entry::Occupied(f) => f.into_mut(),
                std::collections::btree_map::Entry::Vacant(slot) => {
                    match frame_at(event, version) {
                        Ok(frame) => slot.insert(frame),
                        Err(e) => {
                            tracing::error!(error = %e, version, "cannot encode an event to forward");
                            continue;
                        }
                    }
                }
            };
            self.cast(w, seq, frame.clone());
        }
        let newest = match frames.remove(&PROTOCOL_VERSION) {
            Some(frame) => frame,
            None => match frame_at(event, PROTOCOL_VERSION) {
                Ok(frame) => frame,
                Err(e) => {
                    tracing::error!(error = %e, "cannot encode an event to keep");
                    return;
                }
            },
        };
        self.backlog.push(seq, newest);
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
            let version = self.agreement.for_session(w.get_id().node());
            for (seq, frame) in frames {
                match reframe(frame, version) {
                    Ok(frame) => self.cast(w, seq, frame),
                    Err(e) => {
                        tracing::error!(error = %e, version, "cannot encode a kept event again")
                    }
                }
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

/// The frame of `event` for a watcher agreed on protocol `version`: the event as that
/// version defines it, in an envelope of that version.
fn frame_at(event: &Event, version: u16) -> Result<Vec<u8>, EnvelopeError> {
    Envelope::at(version, KIND, &*event.spoken_at(version))?.to_bytes()
}

/// A kept frame (of this build's newest version) for a watcher agreed on `version`: itself,
/// or its event encoded again at that version.
fn reframe(frame: Vec<u8>, version: u16) -> Result<Vec<u8>, EnvelopeError> {
    if version == PROTOCOL_VERSION {
        return Ok(frame);
    }
    let event: Event = Envelope::from_bytes(&frame)?.payload()?;
    frame_at(&event, version)
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
        EventKind::Joined(ModuleInfo::new(
            ModuleKind::Operation,
            "sampler",
            1,
            node,
            "0.1",
        ))
    }

    #[test]
    fn a_module_is_told_by_its_own_node_only() {
        assert!(!echo_of_another_node(&event(joined("alpha")), "alpha"));
        assert!(echo_of_another_node(&event(joined("beta")), "alpha"));
        let frozen = event(EventKind::NodeFrozen { silent_ms: 1 });
        assert!(!echo_of_another_node(&frozen, "alpha"));
    }

    /// The version of `frame` and the keys of its event's `kind`.
    fn opened(frame: &[u8]) -> (u16, String) {
        let env = Envelope::from_bytes(frame).unwrap();
        let event: serde_json::Value = env.payload().unwrap();
        (env.version, event["kind"].to_string())
    }

    #[test]
    fn a_frame_for_a_watcher_is_of_the_version_agreed_with_it() {
        use marie_vocabulary::wire::OLDEST_PROTOCOL;
        let e = event(joined("alpha"));
        for version in OLDEST_PROTOCOL..=PROTOCOL_VERSION {
            let frame = frame_at(&e, version).unwrap();
            assert_eq!(opened(&frame).0, version);
            let back: Event = Envelope::from_bytes(&frame).unwrap().payload().unwrap();
            assert_eq!(back, *e.spoken_at(version));
            // a kept frame (of the newest version) sent again at that version is the same
            let kept = frame_at(&e, PROTOCOL_VERSION).unwrap();
            assert_eq!(reframe(kept, version).unwrap(), frame);
        }
    }

    /// The next build (protocol 3) tells the version of a module's node in its `joined`
    /// event; a watcher agreed on 2 gets a frame of 2 without it.
    #[cfg(feature = "next-protocol")]
    #[test]
    fn a_watcher_agreed_on_2_gets_no_field_of_3() {
        let mut info = ModuleInfo::new(ModuleKind::Operation, "wall-follower", 1, "alpha", "0.1");
        info.speaks = Some(3);
        let e = event(EventKind::Joined(info));
        let (v3, kind3) = opened(&frame_at(&e, 3).unwrap());
        assert_eq!(v3, 3);
        assert!(kind3.contains("\"speaks\":3"), "{kind3}");
        let (v2, kind2) = opened(&frame_at(&e, 2).unwrap());
        assert_eq!(v2, 2);
        assert!(!kind2.contains("speaks"), "{kind2}");
        let again = reframe(frame_at(&e, 3).unwrap(), 2).unwrap();
        assert_eq!(opened(&again), (2, kind2));
    }

    #[test]
    fn streams_differ() {
        assert_ne!(new_stream(), new_stream());
    }
}
