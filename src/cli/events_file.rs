//! `marie run --events FILE.jsonl`: every event of the node's bus during the run — and,
//! for a member of a cluster, every other node's ([`marie::cluster::relay`]) — one JSON object per
//! line ([`marie::events`] documents the schema), written as they come.

use super::feed::{Feed, Sink};
use marie::cluster::relay::Watch;
use marie::events::{Event, EventBus};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// A file being written from a bus.
pub(crate) struct EventsFile {
    feed: Feed<()>,
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

impl EventsFile {
    /// Create `path` and write every event `bus` publishes from now on, and those `others`
    /// receives from the other nodes, until [`finish`](EventsFile::finish).
    pub(crate) fn start(
        bus: &EventBus,
        others: Option<Watch>,
        path: &Path,
    ) -> std::io::Result<EventsFile> {
        let out = Lines(BufWriter::new(File::create(path)?));
        let feed = Feed::start(bus, others, out, |Lines(mut out)| {
            out.flush()?;
            Ok(())
        });
        Ok(EventsFile {
            feed,
            path: path.to_path_buf(),
        })
    }

    /// Write what was published before this call and close the file.
    pub(crate) async fn finish(self) -> anyhow::Result<()> {
        self.feed
            .finish("the events file")
            .await
            .map(drop)
            .map_err(|e| anyhow::anyhow!("cannot write the events to {}: {e}", self.path.display()))
    }
}
