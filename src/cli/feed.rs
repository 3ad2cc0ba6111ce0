//! A run's events fed to a file writer: every event the node's bus publishes from a
//! subscription on, and — for a member of a cluster — every other node's
//! ([`marie::cluster::relay`]), handed one at a time to a sink until told to stop, then what
//! was published before the stop. The `--events` file and the `--mcap` file are two sinks.

use marie::cluster::relay::Watch;
use marie::events::{BusError, Event, EventBus, EventSubscription};
use tokio::sync::oneshot;

/// What takes a run's events, one at a time: a file's writer.
pub(crate) trait Sink {
    /// Take one event.
    fn take(&mut self, event: &Event) -> anyhow::Result<()>;
}

/// Hand `sink` every event of `sub` and of `others` until `stopped`, then those published
/// before it; give back the sink and how many events the subscription fell behind on and
/// lost (the bus is bounded, the relay's backlog too). A sink's error ends it.
async fn feed<S: Sink>(
    mut sub: EventSubscription,
    mut others: Option<Watch>,
    mut stopped: oneshot::Receiver<()>,
    mut sink: S,
) -> anyhow::Result<(S, u64)> {
    let mut missed = 0;
    loop {
        tokio::select! {
            biased;
            received = sub.recv() => match received {
                Ok(event) => sink.take(&event)?,
                Err(BusError::Lagged { missed: n }) => missed += n,
                Err(BusError::Closed) => break,
            },
            Some(event) = next_of(&mut others) => sink.take(&event)?,
            _ = &mut stopped => {
                for event in sub.drain() {
                    sink.take(&event)?;
                }
                while let Some(event) = others.as_mut().and_then(Watch::try_recv) {
                    sink.take(&event)?;
                }
                break;
            }
        }
    }
    missed += others.as_ref().map_or(0, Watch::lost);
    Ok((sink, missed))
}

/// The next event of the other nodes; pending forever without a watch (or once it ended).
async fn next_of(others: &mut Option<Watch>) -> Option<Event> {
    match others {
        Some(w) => match w.recv().await {
            Some(e) => Some(e),
            None => {
                *others = None;
                std::future::pending().await
            }
        },
        None => std::future::pending().await,
    }
}

/// A sink fed from a bus (and the relay) in a task of its own, until
/// [`finish`](Feed::finish): the one way a run's files are written.
#[derive(Debug)]
pub(crate) struct Feed<T> {
    stop: oneshot::Sender<()>,
    task: tokio::task::JoinHandle<anyhow::Result<(T, u64)>>,
}

impl<T: Send + 'static> Feed<T> {
    /// Hand `sink` every event of `bus` from now on and of `others`; once stopped, `close`
    /// makes of the sink what [`finish`](Feed::finish) gives.
    pub(crate) fn start<S>(
        bus: &EventBus,
        others: Option<Watch>,
        sink: S,
        close: impl FnOnce(S) -> anyhow::Result<T> + Send + 'static,
    ) -> Feed<T>
    where
        S: Sink + Send + 'static,
    {
        let sub = bus.subscribe();
        let (stop, stopped) = oneshot::channel::<()>();
        let task = tokio::spawn(async move {
            let (sink, missed) = feed(sub, others, stopped, sink).await?;
            Ok((close(sink)?, missed))
        });
        Feed { stop, task }
    }

    /// Take what was published before this call, close the sink, and give what it made and
    /// how many events it lost; a loss is warned of, naming `what` (`the events file`).
    pub(crate) async fn finish(self, what: &str) -> anyhow::Result<(T, u64)> {
        let _ = self.stop.send(());
        let (made, missed) = self
            .task
            .await
            .map_err(|e| anyhow::anyhow!("the writer of {what} stopped: {e}"))??;
        if missed > 0 {
            tracing::warn!(
                missed,
                "{what} fell behind the node's bus and lacks some events"
            );
        }
        Ok((made, missed))
    }
}
