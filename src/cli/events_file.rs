//! `marie run --events FILE.jsonl`: every event of the node's bus during the run, one JSON
//! object per line ([`marie::actors::events`] documents the schema), written as they come.

use marie::actors::events::{BusError, EventBus};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use tokio::sync::oneshot;
use tokio::task::JoinHandle;

/// A file being written from a bus.
pub struct EventsFile {
    stop: oneshot::Sender<()>,
    task: JoinHandle<std::io::Result<Written>>,
    path: PathBuf,
}

/// What was written.
#[derive(Debug, Default)]
pub struct Written {
    /// Lines written.
    pub lines: u64,
    /// Events the writer fell behind on and lost (the bus is bounded).
    pub missed: u64,
}

impl EventsFile {
    /// Create `path` and write every event `bus` publishes from now on, until
    /// [`finish`](EventsFile::finish).
    pub fn start(bus: &EventBus, path: &Path) -> std::io::Result<EventsFile> {
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
                    _ = &mut stopped => {
                        for event in sub.drain() {
                            writeln!(out, "{}", event.to_json_line()?)?;
                            written.lines += 1;
                        }
                        break;
                    }
                }
            }
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
    pub async fn finish(self) -> anyhow::Result<Written> {
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
