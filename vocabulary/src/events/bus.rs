//! The event bus: a bounded broadcast of [`Event`]s, stamped with the mission clock and the
//! node's name.

use super::{Event, EventKind};
use crate::clock::SharedClock;
use std::sync::{Arc, Mutex, MutexGuard, Weak};
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
    /// The taps, and the lock that gives every event one order: stamped, tapped and
    /// broadcast under it.
    taps: Arc<Mutex<Taps>>,
}

/// A tap's function.
type TapFn = Arc<dyn Fn(&Event) + Send + Sync>;

/// The taps attached to a bus.
#[derive(Default)]
struct Taps {
    next: u64,
    attached: Vec<(u64, TapFn)>,
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
            taps: Arc::default(),
        }
    }

    /// Publish `kind`, stamped with the mission clock (ms) and the node's name; returns
    /// the event as published. Every [`Tap`] sees it before this returns; subscribers
    /// receive it when they next ask.
    pub fn publish(&self, kind: EventKind) -> Event {
        self.send(&self.node, kind)
    }

    /// Publish `kind` as node `origin` told it, stamped with this bus's clock: how a member
    /// that follows a run dispatched on another node puts that dispatcher's events onto its
    /// own bus, so that its report, fault injector and outputs see them as if published
    /// here (in this bus's one order, and on its clock, beside the faults it injects).
    pub fn republish(&self, origin: &str, kind: EventKind) -> Event {
        self.send(origin, kind)
    }

    /// Stamp `kind` as `node`'s, tap and broadcast it, under the lock that orders the bus.
    fn send(&self, node: &str, kind: EventKind) -> Event {
        let taps = lock(&self.taps);
        let event = Event {
            at_ms: self.clock.now().as_millis() as u64,
            node: node.to_string(),
            kind,
        };
        tracing::trace!(?event, "event");
        for (_, tap) in &taps.attached {
            tap(&event);
        }
        // no subscriber: nobody to tell, nothing kept
        let _ = self.tx.send(event.clone());
        event
    }

    /// Call `f` with every event published from now on, in publish order, until the
    /// returned [`Tap`] is dropped.
    ///
    /// Unlike a [subscription](Self::subscribe), a tap never falls behind: `f` runs in the
    /// publisher's call, under the lock that orders the bus's events. So it must be quick
    /// (fold, count, forward into a channel of its own) and must not publish on this bus.
    /// What must not lose an event of a run taps — its report
    /// ([`ReportBuilder::attach`](crate::report::ReportBuilder::attach)), the fault
    /// injector's view of the bindings; what may fall behind subscribes.
    ///
    /// ```
    /// use marie_vocabulary::clock::RealClock;
    /// use marie_vocabulary::events::{EventBus, EventKind};
    /// use std::sync::atomic::{AtomicU64, Ordering};
    /// use std::sync::Arc;
    ///
    /// let bus = EventBus::new("n", RealClock::shared());
    /// let seen = Arc::new(AtomicU64::new(0));
    /// let counter = seen.clone();
    /// let tap = bus.tap(move |_| {
    ///     counter.fetch_add(1, Ordering::Relaxed);
    /// });
    /// let robot = |what: &str| EventKind::Robot { what: what.into(), data: serde_json::Value::Null };
    /// bus.publish(robot("a"));
    /// bus.publish(robot("b"));
    /// drop(tap);
    /// bus.publish(robot("c"));
    /// assert_eq!(seen.load(Ordering::Relaxed), 2);
    /// ```
    pub fn tap(&self, f: impl Fn(&Event) + Send + Sync + 'static) -> Tap {
        let mut taps = lock(&self.taps);
        let id = taps.next;
        taps.next += 1;
        taps.attached.push((id, Arc::new(f)));
        Tap {
            taps: Arc::downgrade(&self.taps),
            id,
        }
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

fn lock(taps: &Mutex<Taps>) -> MutexGuard<'_, Taps> {
    // a tap that panicked leaves the list as it was
    taps.lock().unwrap_or_else(|e| e.into_inner())
}

/// A function attached to a bus by [`EventBus::tap`]; dropping it detaches the function.
#[must_use = "a tap is detached when dropped"]
pub struct Tap {
    taps: Weak<Mutex<Taps>>,
    id: u64,
}

impl Drop for Tap {
    fn drop(&mut self) {
        if let Some(taps) = self.taps.upgrade() {
            lock(&taps).attached.retain(|(id, _)| *id != self.id);
        }
    }
}

impl std::fmt::Debug for Tap {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Tap").field("id", &self.id).finish()
    }
}

impl std::fmt::Debug for EventBus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("EventBus")
            .field("node", &self.node)
            .field("subscribers", &self.tx.receiver_count())
            .field("taps", &lock(&self.taps).attached.len())
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

impl std::fmt::Debug for EventSubscription {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("EventSubscription")
            .field("waiting", &self.rx.len())
            .finish()
    }
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
    async fn a_tap_sees_every_event_in_publish_order_where_a_subscriber_lags() {
        let clock = Arc::new(ManualClock::new());
        let bus = EventBus::with_capacity("n", clock, 4);
        let seen = Arc::new(Mutex::new(Vec::new()));
        let into = seen.clone();
        let tap = bus.tap(move |e| into.lock().unwrap().push(e.kind.clone()));
        let mut sub = bus.subscribe();
        for n in 0..10 {
            bus.publish(kind(n));
        }
        assert_eq!(*seen.lock().unwrap(), (0..10).map(kind).collect::<Vec<_>>());
        assert_eq!(sub.recv().await, Err(BusError::Lagged { missed: 6 }));
        drop(tap);
        bus.publish(kind(10));
        assert_eq!(
            seen.lock().unwrap().len(),
            10,
            "a dropped tap sees nothing more"
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
