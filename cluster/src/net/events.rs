//! The transport's news on the node's event bus: peers up, lost, declared down or refused
//! become [`EventKind`]s, beside the dispatcher's and supervisors' events, for the events
//! file, a remote dispatcher and the monitor.

use super::heartbeat::NetEvent;
use super::transport::{Peer, Transport};
use marie_actors::events::{EventBus, EventKind};
use std::collections::BTreeSet;
use tokio::sync::broadcast::error::RecvError;

/// Publish what `transport` sees on `bus` until the transport stops; abort the returned task
/// to stop earlier.
pub fn publish_on(transport: &Transport, bus: EventBus) -> tokio::task::JoinHandle<()> {
    let mut changes = transport.changes();
    let mut net = transport.events();
    let sessions = transport.sessions();
    tokio::spawn(async move {
        let mut seen: BTreeSet<(String, String)> = BTreeSet::new();
        loop {
            let now: BTreeSet<(String, String)> = sessions
                .peers()
                .into_iter()
                .map(|Peer { name, address, .. }| (name, address))
                .collect();
            for (peer, address) in now.difference(&seen) {
                bus.publish(EventKind::NodeUp {
                    peer: peer.clone(),
                    address: address.clone(),
                });
            }
            for (peer, address) in seen.difference(&now) {
                bus.publish(EventKind::NodeLost {
                    peer: peer.clone(),
                    address: address.clone(),
                });
            }
            seen = now;
            tokio::select! {
                changed = changes.changed() => if changed.is_err() { return },
                event = net.recv() => match event {
                    Ok(NetEvent::PeerDown { peer, silent }) => {
                        bus.publish(EventKind::NodeDown {
                            peer,
                            silent_ms: silent.as_millis() as u64,
                        });
                    }
                    Ok(NetEvent::Frozen { silent }) => {
                        bus.publish(EventKind::NodeFrozen {
                            silent_ms: silent.as_millis() as u64,
                        });
                    }
                    Ok(NetEvent::PeerRefused { peer, theirs, ours }) => {
                        bus.publish(EventKind::NodeRefused { peer, theirs, ours });
                    }
                    Err(RecvError::Lagged(n)) => {
                        tracing::warn!("{n} transport event(s) lost before the bus");
                    }
                    Err(RecvError::Closed) => return,
                },
            }
        }
    })
}
