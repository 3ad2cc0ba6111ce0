//! The transport's news on the node's event bus: each [`NetEvent`] as an [`EventKind`],
//! beside the dispatcher's and supervisors' events, for the events file, a remote dispatcher
//! and the monitor.

use super::events::NetEvent;
use super::sessions::Peer;
use super::transport::Transport;
use marie_vocabulary::events::{EventBus, EventKind};
use tokio::sync::broadcast::error::RecvError;

/// Publish what `transport` tells on `bus` until the transport stops; abort the returned
/// task to stop earlier.
pub fn publish_on(transport: &Transport, bus: EventBus) -> tokio::task::JoinHandle<()> {
    let (ready, mut net) = transport.events();
    tokio::spawn(async move {
        for Peer { name, address, .. } in ready {
            bus.publish(EventKind::NodeUp {
                peer: name,
                address,
            });
        }
        loop {
            let kind = match net.recv().await {
                Ok(NetEvent::PeerUp { peer, address }) => EventKind::NodeUp { peer, address },
                Ok(NetEvent::PeerLost { peer, address }) => EventKind::NodeLost { peer, address },
                Ok(NetEvent::PeerDown { peer, silent }) => EventKind::NodeDown {
                    peer,
                    silent_ms: silent.as_millis() as u64,
                },
                Ok(NetEvent::Frozen { silent }) => EventKind::NodeFrozen {
                    silent_ms: silent.as_millis() as u64,
                },
                Ok(NetEvent::PeerRefused { peer, theirs, ours }) => {
                    EventKind::NodeRefused { peer, theirs, ours }
                }
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
