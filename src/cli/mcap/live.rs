//! `marie run --mcap FILE.mcap`: the run written as MCAP while it runs, from the node's
//! bus — a subscriber like the events file ([`crate::cli::events_file`]), so a writer
//! that falls behind loses the oldest events (and says how many) rather than slowing the
//! run. The local bus only: a member of a cluster writes its own node's events (and the
//! dispatcher's, which a run dispatched elsewhere republishes on it).

use super::{McapWriter, Written};
use marie::actors::events::{BusError, EventBus};
use std::path::{Path, PathBuf};
use tokio::sync::oneshot;
use tokio::task::JoinHandle;

/// An MCAP file being written from a bus.
#[derive(Debug)]
pub(crate) struct McapFile {
    stop: oneshot::Sender<()>,
    task: JoinHandle<anyhow::Result<Written>>,
    path: PathBuf,
}

impl McapFile {
    /// Create `path` and write every event `bus` publishes from now on, until
    /// [`finish`](McapFile::finish).
    pub(crate) fn start(bus: &EventBus, path: &Path) -> anyhow::Result<McapFile> {
        let mut out = McapWriter::create(path)?;
        let mut sub = bus.subscribe();
        let (stop, mut stopped) = oneshot::channel::<()>();
        let task = tokio::spawn(async move {
            let mut missed = 0;
            loop {
                tokio::select! {
                    biased;
                    received = sub.recv() => match received {
                        Ok(event) => out.write(&event)?,
                        Err(BusError::Lagged { missed: n }) => missed += n,
                        Err(BusError::Closed) => break,
                    },
                    _ = &mut stopped => {
                        for event in sub.drain() {
                            out.write(&event)?;
                        }
                        break;
                    }
                }
            }
            let mut written = out.finish()?;
            written.missed = missed;
            Ok(written)
        });
        Ok(McapFile {
            stop,
            task,
            path: path.to_path_buf(),
        })
    }

    /// Write what was published before this call, close the file, and say what it holds.
    pub(crate) async fn finish(self) -> anyhow::Result<Written> {
        let _ = self.stop.send(());
        let written = self
            .task
            .await
            .map_err(|e| anyhow::anyhow!("the MCAP writer stopped: {e}"))?
            .map_err(|e| e.context(format!("--mcap {}", self.path.display())))?;
        if written.missed > 0 {
            tracing::warn!(
                missed = written.missed,
                "the MCAP file fell behind the node's bus and lacks some events"
            );
        }
        Ok(written)
    }
}
