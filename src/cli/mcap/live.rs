//! `marie run --mcap FILE.mcap`: the run written as MCAP while it runs, from the node's
//! bus — a subscriber like the events file ([`crate::cli::events_file`]), so a writer
//! that falls behind loses the oldest events (and says how many) rather than slowing the
//! run. A member of a cluster writes the other nodes' events too (the cart's node's robot
//! events draw the scene), as the events file does ([`crate::cli::feed`]).

use super::{McapWriter, Written};
use crate::cli::feed::Feed;
use marie::cluster::relay::Watch;
use marie::events::EventBus;
use std::path::{Path, PathBuf};

/// An MCAP file being written from a bus.
#[derive(Debug)]
pub(crate) struct McapFile {
    feed: Feed<Written>,
    path: PathBuf,
}

impl McapFile {
    /// Create `path` and write every event `bus` publishes from now on, and those `others`
    /// receives from the other nodes of a cluster, until [`finish`](McapFile::finish).
    pub(crate) fn start(
        bus: &EventBus,
        others: Option<Watch>,
        path: &Path,
    ) -> anyhow::Result<McapFile> {
        let out = McapWriter::create(path)?;
        Ok(McapFile {
            feed: Feed::start(bus, others, out, McapWriter::finish),
            path: path.to_path_buf(),
        })
    }

    /// Write what was published before this call, close the file, and say what it holds.
    pub(crate) async fn finish(self) -> anyhow::Result<Written> {
        let (mut written, missed) = self
            .feed
            .finish("the MCAP file")
            .await
            .map_err(|e| e.context(format!("--mcap {}", self.path.display())))?;
        written.missed = missed;
        Ok(written)
    }
}
