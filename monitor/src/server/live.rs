//! Live mode: the state kept up to date from a node's bus (and whatever else is fed in),
//! and pushed to every viewer over one server-sent-events connection.
//!
//! Why it cannot stall the node: the monitor reads the bus as one more subscriber (the bus
//! is a bounded broadcast; a subscriber that falls behind loses the oldest events, and the
//! state counts them in `missed`), on the monitor's own thread. The reducer only applies an
//! event under a short lock and bumps a version. At most [`UPDATES_PER_SECOND`] a ticker
//! serializes the changed state once, for every viewer, into a bounded broadcast of
//! [`VIEWER_BUFFER`] updates; each viewer's connection takes from it at its own pace. A
//! viewer that fell more than that behind is told `lagged` (with how many updates it lost),
//! then gets a fresh `snapshot` — its lag costs the node nothing.

use crate::state::MonitorState;
use axum::response::sse::{Event as SseEvent, KeepAlive, Sse};
use futures_util::stream::{self, Stream};
use marie_vocabulary::events::{BusError, Event, EventSubscription};
use std::convert::Infallible;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::sync::{broadcast, mpsc, watch};

/// How often the monitor takes the events waiting on the node's bus (see [`Live::reduce`]).
pub(crate) const BUS_POLL: Duration = Duration::from_millis(10);

/// Updates pushed to a viewer per second, at most.
pub(crate) const UPDATES_PER_SECOND: u64 = 10;
/// Updates a viewer may fall behind before it is told `lagged` and resynchronised.
pub(crate) const VIEWER_BUFFER: usize = 8;
/// Events fed in (not from the bus) that may wait for the reducer; more are lost, counted.
pub(crate) const FEED_CAPACITY: usize = 4096;

/// A request to [`Live::reduce`] to apply everything waiting, answered once it has.
pub(crate) type FlushRequest = std::sync::mpsc::SyncSender<()>;

/// The live state shared by the reducer, the ticker and the viewers.
pub(crate) struct Live {
    state: Mutex<MonitorState>,
    version: watch::Sender<u64>,
    updates: broadcast::Sender<Arc<str>>,
}

/// A way to feed events into a live monitor besides its bus: another node's events from the
/// cluster's relay, a listing of modules that joined before the monitor started. Never
/// waits: when the monitor is behind, an event is lost and counted in the state's `missed`.
#[derive(Clone)]
pub struct Feed {
    tx: mpsc::Sender<Event>,
    lost: Arc<AtomicU64>,
}

impl Feed {
    /// Offer one event; false when it was lost (the monitor behind, or stopped).
    pub fn offer(&self, event: Event) -> bool {
        let ok = self.tx.try_send(event).is_ok();
        if !ok {
            self.lost.fetch_add(1, Ordering::Relaxed);
        }
        ok
    }
}

impl std::fmt::Debug for Feed {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Feed").finish_non_exhaustive()
    }
}

impl Live {
    /// A live state, and the feed and its receiving end for [`Live::reduce`].
    pub(crate) fn new() -> (Arc<Live>, Feed, mpsc::Receiver<Event>) {
        let (tx, rx) = mpsc::channel(FEED_CAPACITY);
        let live = Arc::new(Live {
            state: Mutex::new(MonitorState::default()),
            version: watch::Sender::new(0),
            updates: broadcast::Sender::new(VIEWER_BUFFER),
        });
        let feed = Feed {
            tx,
            lost: Arc::new(AtomicU64::new(0)),
        };
        (live, feed, rx)
    }

    fn apply(&self, event: &Event) {
        self.lock().apply(event);
        self.version.send_modify(|v| *v += 1);
    }

    fn missed(&self, n: u64) {
        self.lock().missed += n;
        self.version.send_modify(|v| *v += 1);
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, MonitorState> {
        // a panic while applying leaves a state worth showing still
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The state as the page draws it, as JSON.
    pub(crate) fn snapshot(&self) -> Arc<str> {
        // serialized under the lock: the reducer shares the monitor's one thread, so it
        // waits no longer than it would for a copy, and nothing is copied
        Arc::from(serde_json::to_string(&*self.lock()).unwrap_or_else(|e| {
            tracing::error!(error = %e, "cannot serialize the monitor's state");
            "{}".into()
        }))
    }

    /// Apply the bus's events and the fed ones until both end and no flush can be asked
    /// for any more.
    ///
    /// The bus is polled every [`BUS_POLL`], not awaited: a subscriber waiting on the bus
    /// is woken by every publish, a wake across threads that the robot's own thread pays
    /// for on each event; a polled one costs the publisher nothing. (`cargo bench --bench
    /// monitor`, a `--speed max` docking run with ten viewers against none: 1.08× and
    /// 1.13× with the reducer awaiting the bus, 1.01× polled.) The bus holds 4096 events,
    /// far more than a run publishes in a poll period.
    ///
    /// So the state may trail the bus by a poll period. A [`FlushRequest`] from `flushes`
    /// closes that gap for whoever needs the state complete (a run that says it is over):
    /// the reducer takes everything waiting on the bus and in the feed at once, then
    /// answers. It cannot miss an event published or fed before the request was sent: the
    /// request reaches the reducer after it (a channel orders the two), a publish is in the
    /// bus's buffer when `publish` returns, an offer in the feed's when `offer` returns, and
    /// the reducer empties both after taking the request.
    pub(crate) async fn reduce(
        self: Arc<Self>,
        mut bus: Option<EventSubscription>,
        mut fed: mpsc::Receiver<Event>,
        feed: Feed,
        mut flushes: mpsc::UnboundedReceiver<FlushRequest>,
    ) {
        let mut fed_open = true;
        let mut flushes_open = true;
        let mut poll = tokio::time::interval(BUS_POLL);
        poll.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
        loop {
            tokio::select! {
                _ = poll.tick(), if bus.is_some() => {
                    self.drain(&mut bus);
                    // what the feed lost while nothing else was fed is told too
                    self.count_lost(&feed);
                }
                event = fed.recv(), if fed_open => match event {
                    Some(event) => self.apply_fed(&event, &feed),
                    None => fed_open = false,
                },
                request = flushes.recv(), if flushes_open => match request {
                    Some(done) => {
                        self.drain(&mut bus);
                        fed_open = self.drain_fed(&mut fed, &feed);
                        // the asker may have given up waiting: nothing to tell then
                        let _ = done.send(());
                    }
                    None => flushes_open = false,
                },
            }
            if bus.is_none() && !fed_open && !flushes_open {
                return;
            }
        }
    }

    /// Apply one fed event, and count the events the feed lost meanwhile.
    fn apply_fed(&self, event: &Event, feed: &Feed) {
        self.apply(event);
        self.count_lost(feed);
    }

    /// Count in `missed` the events the feed lost since last asked.
    fn count_lost(&self, feed: &Feed) {
        let lost = feed.lost.swap(0, Ordering::Relaxed);
        if lost > 0 {
            self.missed(lost);
        }
    }

    /// Apply every fed event waiting; false once the feed has closed (after its last).
    fn drain_fed(&self, fed: &mut mpsc::Receiver<Event>, feed: &Feed) -> bool {
        loop {
            match fed.try_recv() {
                Ok(event) => self.apply_fed(&event, feed),
                Err(mpsc::error::TryRecvError::Empty) => return true,
                Err(mpsc::error::TryRecvError::Disconnected) => return false,
            }
        }
    }

    /// Apply every event waiting on the bus; `None` once it has closed (after its last).
    fn drain(&self, bus: &mut Option<EventSubscription>) {
        let Some(subscription) = bus else {
            return;
        };
        // one lock and one wake of the ticker for the whole batch (a poll period brings
        // tens of the robot's poses)
        let mut changed = false;
        let mut state = self.lock();
        loop {
            match subscription.try_recv() {
                Ok(Some(event)) => state.apply(&event),
                Ok(None) => break,
                Err(BusError::Lagged { missed }) => {
                    tracing::warn!(missed, "the monitor fell behind the node's bus");
                    state.missed += missed;
                }
                Err(BusError::Closed) => {
                    *bus = None;
                    break;
                }
            }
            changed = true;
        }
        drop(state);
        if changed {
            self.version.send_modify(|v| *v += 1);
        }
    }

    /// Push the state to the viewers whenever it changed, at most
    /// [`UPDATES_PER_SECOND`] times a second, for as long as the monitor's runtime runs
    /// (it holds the state, and so the version's sender, itself).
    pub(crate) async fn tick(self: Arc<Self>) {
        let mut version = self.version.subscribe();
        let period = Duration::from_millis(1000 / UPDATES_PER_SECOND);
        loop {
            if version.changed().await.is_err() {
                return;
            }
            if self.updates.receiver_count() > 0 {
                let _ = self.updates.send(self.snapshot());
            }
            tokio::time::sleep(period).await;
        }
    }

    /// A viewer's connection: `snapshot` first, then `state` on every update; after a lag,
    /// `lagged` (`{"missed": n}`) and a fresh `snapshot`.
    pub(crate) fn viewer(self: Arc<Self>) -> Sse<impl Stream<Item = Result<SseEvent, Infallible>>> {
        let rx = self.updates.subscribe();
        let first = SseEvent::default()
            .event("snapshot")
            .data(self.snapshot().as_ref());
        let pending = vec![first];
        let stream = stream::unfold((self, rx, pending), |(live, mut rx, mut pending)| async {
            if let Some(next) = pending.pop() {
                return Some((Ok(next), (live, rx, pending)));
            }
            let event = match rx.recv().await {
                Ok(update) => SseEvent::default().event("state").data(update.as_ref()),
                Err(broadcast::error::RecvError::Lagged(missed)) => {
                    pending.push(
                        SseEvent::default()
                            .event("snapshot")
                            .data(live.snapshot().as_ref()),
                    );
                    SseEvent::default()
                        .event("lagged")
                        .data(format!("{{\"missed\":{missed}}}"))
                }
                Err(broadcast::error::RecvError::Closed) => return None,
            };
            Some((Ok(event), (live, rx, pending)))
        });
        Sse::new(stream).keep_alive(KeepAlive::default())
    }
}
