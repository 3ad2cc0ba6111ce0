//! The event bus: a bounded broadcast of [`Event`]s, stamped with the mission clock and the
//! node's name.

use super::{Event, EventKind};
use crate::clock::SharedClock;
use std::sync::Arc;
use tokio::sync::broadcast;

/// How many events a bus holds for its slowest subscriber before that one starts to lose
/// the oldest (it is told how many, [`BusError::Lagged`]).
pub const DEFAULT_CAPACITY: usize = 4096;

/// A node's event bus. Cheap to clone; every clone publishes onto the same stream.
///
/// Publishing never blocks and never fails: with no subscriber an event is simply not
/// kept, and a slow subscriber loses the oldest events rather than slowing the publisher
/// (bounded memory, whatever the subscribers do).
#[derive(Clone)]
pub struct EventBus {
    tx: broadcast::Sender<Event>,
    node: Arc<str>,
    clock: SharedClock,
}

impl EventBus {
    /// A bus for node `node`, stamping events with `clock` (the node's clock, so events
    /// and runs agree on time), holding [`DEFAULT_CAPACITY`] events.
    pub fn new(node: impl Into<String>, clock: SharedClock) -> EventBus {
        EventBus::with_capacity(node, clock, DEFAULT_CAPACITY)
    }

    /// [`EventBus::new`] holding `capacity` events (at least 1).
    pub fn with_capacity(node: impl Into<String>, clock: SharedClock, capacity: usize) -> EventBus {
        let (tx, _) = broadcast::channel(capacity.max(1));
        EventBus {
            tx,
            node: Arc::from(node.into()),
            clock,
        }
    }

    /// Publish `kind`, stamped with the mission clock (ms) and the node's name; returns
    /// the event as published.
    pub fn publish(&self, kind: EventKind) -> Event {
        let event = Event {
            at_ms: self.clock.now().as_millis() as u64,
            node: self.node.to_string(),
            kind,
        };
        tracing::trace!(?event, "event");
        // no subscriber: nobody to tell, nothing kept
        let _ = self.tx.send(event.clone());
        event
    }

    /// A subscription to every event published from now on.
    pub fn subscribe(&self) -> EventSubscription {
        EventSubscription {
            rx: self.tx.subscribe(),
        }
    }

    /// The node's name the events carry.
    pub fn node(&self) -> &str {
        &self.node
    }

    /// The clock the events are stamped with.
    pub fn clock(&self) -> &SharedClock {
        &self.clock
    }
}

impl std::fmt::Debug for EventBus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("EventBus")
            .field("node", &self.node)
            .field("subscribers", &self.tx.receiver_count())
            .finish()
    }
}

/// Why a subscription gave no event.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum BusError {
    /// The subscriber fell behind and lost the `missed` oldest events; the next receive
    /// goes on with the oldest event still held.
    #[error("fell behind the event bus: {missed} event(s) lost")]
    Lagged {
        /// How many events it lost.
        missed: u64,
    },
    /// Every handle of the bus is gone: no event will come.
    #[error("the event bus is closed")]
    Closed,
}

/// One subscriber's view of a bus.
pub struct EventSubscription {
    rx: broadcast::Receiver<Event>,
}

impl EventSubscription {
    /// The next event; waits for one.
    pub async fn recv(&mut self) -> Result<Event, BusError> {
        self.rx.recv().await.map_err(|e| match e {
            broadcast::error::RecvError::Lagged(missed) => BusError::Lagged { missed },
            broadcast::error::RecvError::Closed => BusError::Closed,
        })
    }

    /// The next event if one is waiting (`Ok(None)`: none yet).
    pub fn try_recv(&mut self) -> Result<Option<Event>, BusError> {
        match self.rx.try_recv() {
            Ok(event) => Ok(Some(event)),
            Err(broadcast::error::TryRecvError::Empty) => Ok(None),
            Err(broadcast::error::TryRecvError::Lagged(missed)) => Err(BusError::Lagged { missed }),
            Err(broadcast::error::TryRecvError::Closed) => Err(BusError::Closed),
        }
    }

    /// Every event waiting now, in order (skipping over a lag, which is logged).
    pub fn drain(&mut self) -> Vec<Event> {
        let mut out = Vec::new();
        loop {
            match self.try_recv() {
                Ok(Some(event)) => out.push(event),
                Ok(None) | Err(BusError::Closed) => return out,
                Err(e) => tracing::warn!("{e}"),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::clock::{Clock, ManualClock};
    use std::time::Duration;

    fn kind(n: u64) -> EventKind {
        EventKind::Robot {
            what: "tick".into(),
            data: serde_json::json!(n),
        }
    }

    #[tokio::test]
    async fn events_are_stamped_with_the_clock_and_the_node() {
        let clock = Arc::new(ManualClock::new());
        let bus = EventBus::new("n1@host", clock.clone());
        let mut sub = bus.subscribe();
        clock.advance(Duration::from_millis(1234));
        let sent = bus.publish(kind(1));
        let got = sub.recv().await.unwrap();
        assert_eq!(got, sent);
        assert_eq!(
            (got.at_ms, got.node.as_str()),
            (clock.now().as_millis() as u64, "n1@host")
        );
    }

    #[tokio::test]
    async fn a_lagging_subscriber_is_told_how_many_it_lost() {
        let clock = Arc::new(ManualClock::new());
        let bus = EventBus::with_capacity("n", clock, 4);
        let mut sub = bus.subscribe();
        for n in 0..10 {
            bus.publish(kind(n));
        }
        assert_eq!(sub.recv().await, Err(BusError::Lagged { missed: 6 }));
        assert_eq!(sub.recv().await.unwrap().kind, kind(6));
        assert_eq!(sub.drain().len(), 3);
        assert_eq!(sub.try_recv(), Ok(None));
        drop(bus);
        assert_eq!(sub.recv().await, Err(BusError::Closed));
    }
}
