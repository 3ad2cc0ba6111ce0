//! The transport's news on the node's event bus: each [`NetEvent`] as an [`EventKind`],
//! beside the dispatcher's and supervisors' events, for the events file, a remote dispatcher
//! and the monitor — and a peer up again after this node lost it as a return
//! ([`EventKind::NodeBack`], after its `node_up`).

use super::events::NetEvent;
use super::sessions::Peer;
use super::transport::Transport;
use marie_vocabulary::events::{EventBus, EventKind};
use std::collections::BTreeMap;
use std::time::{Duration, Instant};
use tokio::sync::broadcast::error::RecvError;

/// The peers this node lost and has not seen back, with when it first lost each: what
/// makes a `node_up` a return ([`EventKind::NodeBack`]).
#[derive(Debug, Default)]
struct Absences(BTreeMap<String, Instant>);

impl Absences {
    /// `peer` was lost (its sessions ended, or it was declared down) at `now`; a loss
    /// already counted keeps its first time.
    fn lost(&mut self, peer: &str, now: Instant) {
        self.0.entry(peer.to_string()).or_insert(now);
    }

    /// `peer` is up at `now`: how long it was away, if it was.
    fn up(&mut self, peer: &str, now: Instant) -> Option<Duration> {
        self.0
            .remove(peer)
            .map(|since| now.saturating_duration_since(since))
    }
}

/// Publish what `transport` tells on `bus` until the transport stops; abort the returned
/// task to stop earlier.
pub fn publish_on(transport: &Transport, bus: EventBus) -> tokio::task::JoinHandle<()> {
    let (ready, mut net) = transport.events();
    tokio::spawn(async move {
        let mut absences = Absences::default();
        for Peer { name, address, .. } in ready {
            bus.publish(EventKind::NodeUp {
                peer: name,
                address,
            });
        }
        loop {
            let kind = match net.recv().await {
                Ok(NetEvent::PeerUp { peer, address }) => {
                    let back = absences.up(&peer, Instant::now());
                    bus.publish(EventKind::NodeUp {
                        peer: peer.clone(),
                        address: address.clone(),
                    });
                    match back {
                        Some(away) => EventKind::NodeBack {
                            peer,
                            address,
                            down_ms: away.as_millis() as u64,
                        },
                        None => continue,
                    }
                }
                Ok(NetEvent::PeerLost { peer, address }) => {
                    absences.lost(&peer, Instant::now());
                    EventKind::NodeLost { peer, address }
                }
                Ok(NetEvent::PeerDown { peer, silent }) => {
                    absences.lost(&peer, Instant::now());
                    EventKind::NodeDown {
                        peer,
                        silent_ms: silent.as_millis() as u64,
                    }
                }
                Ok(NetEvent::Frozen { silent }) => EventKind::NodeFrozen {
                    silent_ms: silent.as_millis() as u64,
                },
                // both ranges (and the newest of each, what a reader of the build before
                // ranges knows); the node's own line (its stderr, `marie node`'s stdout)
                // names both builds too
                Ok(NetEvent::PeerRefused {
                    peer, theirs, ours, ..
                }) => EventKind::NodeRefused {
                    peer,
                    theirs: theirs.newest,
                    ours: ours.newest,
                    theirs_speak: Some(theirs),
                    ours_speak: Some(ours),
                },
                Ok(NetEvent::ConnectionRefused { from, reason }) => EventKind::ConnectionRefused {
                    from: from.to_string(),
                    reason,
                },
                // refusals around this node's own dials: no kind of the events' vocabulary
                // says them (`connection_refused` is an incoming connection's); they are
                // told on the node's stderr, and by `marie node` on stdout
                Ok(NetEvent::DialRefused { .. } | NetEvent::RefusedBy { .. }) => continue,
                Err(RecvError::Lagged(n)) => {
                    tracing::warn!("{n} transport event(s) lost before the bus");
                    continue;
                }
                Err(RecvError::Closed) => return,
            };
            bus.publish(kind);
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_peer_up_again_after_a_loss_is_back_for_as_long_as_since_its_first_loss() {
        let t0 = Instant::now();
        let mut a = Absences::default();
        // seen for the first time: no return
        assert_eq!(a.up("b", t0), None);
        a.lost("b", t0);
        // declared down after its sessions ended: the first loss counts
        a.lost("b", t0 + Duration::from_millis(300));
        assert_eq!(
            a.up("b", t0 + Duration::from_millis(900)),
            Some(Duration::from_millis(900))
        );
        // back once: a second session of it is no return
        assert_eq!(a.up("b", t0 + Duration::from_secs(2)), None);
    }
}
