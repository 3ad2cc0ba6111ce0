//! `marie run --events FILE.jsonl`: every event of the node's bus during the run — and,
//! for a member of a cluster, every other node's ([`marie::cluster::relay`]) — one JSON object per
//! line ([`marie::actors::events`] documents the schema), written as they come.

use super::follow::{follow, Sink};
use marie::actors::events::{Event, EventBus};
use marie::cluster::relay::Watch;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use tokio::sync::oneshot;
use tokio::task::JoinHandle;

/// A file being written from a bus.
pub(crate) struct EventsFile {
    stop: oneshot::Sender<()>,
    task: JoinHandle<anyhow::Result<Written>>,
    path: PathBuf,
}

/// The file's writer: one JSON line an event.
struct Lines(BufWriter<File>);

impl Sink for Lines {
    fn take(&mut self, event: &Event) -> anyhow::Result<()> {
        writeln!(self.0, "{}", event.to_json_line()?)?;
        Ok(())
    }
}

/// What was written.
#[derive(Debug, Default)]
pub(crate) struct Written {
    /// Events the writer fell behind on and lost (the bus is bounded).
    pub missed: u64,
}

impl EventsFile {
    /// Create `path` and write every event `bus` publishes from now on, and those `others`
    /// receives from the other nodes, until [`finish`](EventsFile::finish).
    pub(crate) fn start(
        bus: &EventBus,
        others: Option<Watch>,
        path: &Path,
    ) -> std::io::Result<EventsFile> {
        let out = BufWriter::new(File::create(path)?);
        let sub = bus.subscribe();
        let (stop, stopped) = oneshot::channel::<()>();
        let task = tokio::spawn(async move {
            let (Lines(mut out), missed) = follow(sub, others, stopped, Lines(out)).await?;
            out.flush()?;
            Ok(Written { missed })
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
