//! The writer: events in, MCAP out, one event at a time — its messages written as they
//! come, each topic's channel (and schema) registered with its first message.

use super::log::log;
use super::scene::Scene;
use super::schemas::{Message, Topic};
use super::tree::Control;
use super::Written;
use anyhow::Context;
use marie::events::{Event, Teller};
use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

const CHANNELS: usize = Topic::ALL.len();

/// An MCAP file being written from events, one at a time.
pub(crate) struct McapWriter {
    out: mcap::Writer<BufWriter<File>>,
    path: PathBuf,
    /// Each topic's channel id, once registered.
    channels: [Option<u16>; CHANNELS],
    /// Each topic's messages so far.
    counts: [u64; CHANNELS],
    events: u64,
    /// Words the events for the log and the tree's states (follows the run).
    teller: Teller,
    scene: Scene,
    control: Control,
    /// The messages of the event at hand (reused).
    batch: Vec<Message>,
}

impl std::fmt::Debug for McapWriter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("McapWriter")
            .field("path", &self.path)
            .field("events", &self.events)
            .finish_non_exhaustive()
    }
}

impl McapWriter {
    /// Create (or truncate) `path` and start an MCAP file in it.
    pub(crate) fn create(path: &Path) -> anyhow::Result<McapWriter> {
        let file =
            File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
        // Never seeking back (to fill in a chunk's length): each chunk is put together in
        // memory first (1 MiB), as the output may be a device (`/dev/null`, a terminal)
        // where a seek lands nowhere — the crate's arithmetic then overflows.
        let options = mcap::WriteOptions::new()
            .compression(None)
            .disable_seeking(true)
            .library(format!("marie {}", env!("CARGO_PKG_VERSION")));
        let out = options
            .create(BufWriter::new(file))
            .with_context(|| format!("cannot write MCAP to {}", path.display()))?;
        Ok(McapWriter {
            out,
            path: path.to_path_buf(),
            channels: [None; CHANNELS],
            counts: [0; CHANNELS],
            events: 0,
            teller: Teller::default().with_robot_words(marie_telemetry::words),
            scene: Scene::default(),
            control: Control::default(),
            batch: Vec::new(),
        })
    }

    /// Write the messages of `event`.
    pub(crate) fn write(&mut self, event: &Event) -> anyhow::Result<()> {
        self.events += 1;
        let mut batch = std::mem::take(&mut self.batch);
        let words = self.teller.tell(event);
        batch.push(Message::new(
            Topic::Events,
            event.at_ms,
            &log(event, &words),
        )?);
        if let Some(state) = self.control.apply(event, &words.text)? {
            batch.push(state);
        }
        self.scene.apply(event, &mut batch)?;
        let written = batch.drain(..).try_for_each(|m| self.put(m));
        self.batch = batch;
        written
    }

    /// Write what is due at the end, close the file, and say what it holds.
    pub(crate) fn finish(mut self) -> anyhow::Result<Written> {
        let mut last = Vec::new();
        self.scene.finish(&mut last)?;
        for m in last {
            self.put(m)?;
        }
        let path = self.path.clone();
        let failed = || format!("cannot write MCAP to {}", path.display());
        self.out.finish().with_context(failed)?;
        let channels = Topic::ALL
            .iter()
            .filter(|t| self.channels[t.index()].is_some())
            .map(|t| (t.name(), self.counts[t.index()]))
            .collect();
        let mut file = self.out.into_inner();
        file.flush().with_context(failed)?;
        Ok(Written {
            events: self.events,
            channels,
            missed: 0,
        })
    }

    /// Write `message` on its topic's channel, registering the channel first if it is
    /// the topic's first.
    fn put(&mut self, message: Message) -> anyhow::Result<()> {
        let i = message.topic.index();
        let channel = match self.channels[i] {
            Some(id) => id,
            None => {
                let topic = message.topic;
                let schema = self.out.add_schema(
                    topic.schema_name(),
                    "jsonschema",
                    topic.schema().as_bytes(),
                )?;
                let id = self
                    .out
                    .add_channel(schema, topic.name(), "json", &BTreeMap::new())?;
                self.channels[i] = Some(id);
                id
            }
        };
        let ns = message.at_ms.saturating_mul(1_000_000);
        self.out
            .write_to_known_channel(
                &mcap::records::MessageHeader {
                    channel_id: channel,
                    // wraps after 4e9 messages of a topic, as MCAP's u32 does
                    sequence: self.counts[i] as u32,
                    log_time: ns,
                    publish_time: ns,
                },
                &message.data,
            )
            .with_context(|| format!("cannot write MCAP to {}", self.path.display()))?;
        self.counts[i] += 1;
        Ok(())
    }
}

impl crate::cli::feed::Sink for McapWriter {
    fn take(&mut self, event: &Event) -> anyhow::Result<()> {
        self.write(event)
    }
}
