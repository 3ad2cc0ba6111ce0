//! This marie was built without the `mcap` feature: the writers exist only as types that
//! cannot be made, so the verbs that would write MCAP compile the same and never get one
//! ([`super::output`] refuses `--mcap` before anything runs).

use super::Written;
use marie::events::{Event, EventBus};
use std::path::Path;

/// No MCAP writer: none can be made.
#[derive(Debug)]
pub(crate) enum McapWriter {}

impl McapWriter {
    /// Refused: see [`super::output`].
    pub(crate) fn create(path: &Path) -> anyhow::Result<McapWriter> {
        Err(super::output("--mcap", path).err().map_or_else(
            || anyhow::anyhow!("this marie was built without MCAP support"),
            anyhow::Error::from,
        ))
    }

    /// Never called: there is no writer.
    pub(crate) fn write(&mut self, _event: &Event) -> anyhow::Result<()> {
        match *self {}
    }

    /// Never called: there is no writer.
    pub(crate) fn finish(self) -> anyhow::Result<Written> {
        match self {}
    }
}

/// No MCAP file of a run: none can be made.
#[derive(Debug)]
pub(crate) enum McapFile {}

impl McapFile {
    /// Refused: see [`super::output`].
    pub(crate) fn start(
        _bus: &EventBus,
        _others: Option<marie::cluster::relay::Watch>,
        path: &Path,
    ) -> anyhow::Result<McapFile> {
        McapWriter::create(path).map(|w| match w {})
    }

    /// Never called: there is no file.
    pub(crate) async fn finish(self) -> anyhow::Result<Written> {
        match self {}
    }
}
