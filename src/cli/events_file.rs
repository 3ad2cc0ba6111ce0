//! `marie run --events FILE.jsonl`: every event of the node's bus during the run — and,
//! for a member of a cluster, every other node's ([`marie::cluster::relay`]) — one JSON object per
//! line ([`marie::actors::events`] documents the schema), written as they come.

use marie::actors::events::{BusError, EventBus};
use marie::cluster::relay::Watch;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use tokio::sync::oneshot;
use tokio::task::JoinHandle;

/// A file being written from a bus.
pub(crate) struct EventsFile {
    stop: oneshot::Sender<()>,
    task: JoinHandle<std::io::Result<Written>>,
    path: PathBuf,
}

/// What was written.
#[derive(Debug, Default)]
pub(crate) struct Written {
    /// Lines written.
    pub lines: u64,
    /// Events the writer fell behind on and lost (the bus is bounded).
    pub missed: u64,
}

impl EventsFile {
    /// Create `path` and write every event `bus` publishes from now on, and those `others`
    /// receives from the other nodes, until [`finish`](EventsFile::finish).
    pub(crate) fn start(
        bus: &EventBus,
        mut others: Option<Watch>,
        path: &Path,
    ) -> std::io::Result<EventsFile> {
        let mut out = BufWriter::new(File::create(path)?);
        let mut sub = bus.subscribe();
        let (stop, mut stopped) = oneshot::channel::<()>();
        let task = tokio::spawn(async move {
            let mut written = Written::default();
            loop {
                tokio::select! {
                    biased;
                    received = sub.recv() => match received {
                        Ok(event) => {
                            writeln!(out, "{}", event.to_json_line()?)?;
                            written.lines += 1;
                        }
                        Err(BusError::Lagged { missed }) => written.missed += missed,
                        Err(BusError::Closed) => break,
                    },
                    Some(event) = next_of(&mut others) => {
                        writeln!(out, "{}", event.to_json_line()?)?;
                        written.lines += 1;
                    }
                    _ = &mut stopped => {
                        for event in sub.drain() {
                            writeln!(out, "{}", event.to_json_line()?)?;
                            written.lines += 1;
                        }
                        while let Some(event) = others.as_mut().and_then(Watch::try_recv) {
                            writeln!(out, "{}", event.to_json_line()?)?;
                            written.lines += 1;
                        }
                        break;
                    }
                }
            }
            written.missed += others.as_ref().map_or(0, Watch::lost);
            out.flush()?;
            Ok(written)
        });
        Ok(EventsFile {
            stop,
            task,
            path: path.to_path_buf(),
        })
    }

    /// Write what was published before this call, close the file, and say how it went.
    pub(crate) async fn finish(self) -> anyhow::Result<Written> {
        let _ = self.stop.send(());
        let written = self
            .task
            .await
            .map_err(|e| anyhow::anyhow!("the events writer stopped: {e}"))?
            .map_err(|e| {
                anyhow::anyhow!("cannot write the events to {}: {e}", self.path.display())
            })?;
        if written.missed > 0 {
            tracing::warn!(
                missed = written.missed,
                "the events file fell behind the node's bus and lacks some events"
            );
        }
        Ok(written)
    }
}

/// The next event of the other nodes; pending forever without a watch (or once it ended).
async fn next_of(others: &mut Option<Watch>) -> Option<marie::actors::events::Event> {
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
