//! A run as MCAP (`marie run --mcap FILE.mcap`, `marie export EVENTS.jsonl --mcap
//! FILE.mcap`), with Foxglove's well-known schemas where they fit, so that Foxglove opens
//! the file and draws the run without setup. Its channels, one per topic, each registered
//! when its first message comes (a run without a robot has no scene):
//!
//! | topic           | schema                    | what it draws                                        | when                      |
//! |-----------------|---------------------------|------------------------------------------------------|---------------------------|
//! | `/events`       | `foxglove.Log`            | every event as a log line ([`log`])                  | every event               |
//! | `/control`      | `marie.ControlState`      | the task tree: running actions, each node's status   | the tree changed ([`tree`]) |
//! | `/world`        | `foxglove.SceneUpdate`    | walls, dock and goal as lines                        | `world`                   |
//! | `/cart`         | `foxglove.SceneUpdate`    | the cart's footprint, a box                          | `pose` (once the world told the cart's size) |
//! | `/tf`           | `foxglove.FrameTransform` | `world` → `cart`: the 3D panel can follow the cart   | `pose`                    |
//! | `/echoes`       | `foxglove.PointCloud`     | the sonar echoes                                     | `echoes`                  |
//! | `/path/planned` | `foxglove.SceneUpdate`    | the planned path, a line strip                       | `planned-path`            |
//! | `/path/driven`  | `foxglove.SceneUpdate`    | the driven path, a line strip (bounded)              | `pose`, at a bounded rate ([`scene`]), and at the end |
//! | `/detections`   | `foxglove.SceneUpdate`    | the followed wall, the dock found                    | `followed-wall`, `dock-found` |
//!
//! Messages are JSON (`json` message encoding, `jsonschema` schemas: [`schemas`]), in
//! uncompressed chunks: no compression library to build (see `Cargo.toml`), and JSON's
//! repeated keys would be the only gain. A message's log (and publish) time is its event's
//! `at_ms` in ns, its `timestamp` the same as `{sec, nsec}`; everything is drawn in the
//! frame `world`, metres.
//!
//! Sonar echoes are a `foxglove.PointCloud` rather than spheres of a scene: the 3D panel
//! draws a cloud's points at a fixed size on screen, colours them by a field, and can keep
//! past clouds for a decay time of the user's choosing (the echoes of the whole run, or
//! the last seconds of it), while a scene's spheres scale with the zoom and replace each
//! other; and 12 bytes a point, base64, is a tenth of a sphere's JSON.
//!
//! Streaming: one event in, its messages out — the writer keeps the channels, their counts
//! and what the next messages need ([`scene`]'s bounded path, [`tree`]'s plan), never the
//! run. Built without the `mcap` feature, `--mcap` and `marie export` say so (exit 2).

#[cfg(feature = "mcap")]
mod live;
#[cfg(feature = "mcap")]
mod log;
#[cfg(feature = "mcap")]
mod scene;
#[cfg(feature = "mcap")]
mod schemas;
#[cfg(feature = "mcap")]
mod tree;
#[cfg(not(feature = "mcap"))]
mod without;
#[cfg(feature = "mcap")]
mod writer;

#[cfg(feature = "mcap")]
pub(crate) use live::McapFile;
#[cfg(not(feature = "mcap"))]
pub(crate) use without::{McapFile, McapWriter};
#[cfg(feature = "mcap")]
pub(crate) use writer::McapWriter;

use super::error::BadInput;
use std::path::Path;

/// Refuse `path` as the output of `flag` (`--mcap`) when this marie cannot write MCAP or
/// the path cannot be written ([`super::files::output`]).
pub(crate) fn output(flag: &str, path: &Path) -> Result<(), BadInput> {
    if !cfg!(feature = "mcap") {
        return Err(BadInput(format!(
            "{flag} {}: this marie was built without MCAP support (its `mcap` feature); \
             build it with its default features to write MCAP",
            path.display()
        )));
    }
    super::files::output(flag, path)
}

/// What a file holds: its channels and their messages.
#[derive(Debug, Default)]
pub(crate) struct Written {
    /// Events read.
    pub events: u64,
    /// Each channel's topic and its messages, in the order of the module docs' table.
    pub channels: Vec<(&'static str, u64)>,
    /// Events the writer fell behind on and lost (a live run's bus is bounded).
    pub missed: u64,
}

impl Written {
    /// Messages in all.
    pub(crate) fn messages(&self) -> u64 {
        self.channels.iter().map(|(_, n)| n).sum()
    }

    /// `N channels, M messages (/events 1052, /control 11, ...)`, and the events lost if
    /// any were.
    pub(crate) fn summary(&self) -> String {
        let each: Vec<String> = self
            .channels
            .iter()
            .map(|(topic, n)| format!("{topic} {n}"))
            .collect();
        let lost = match self.missed {
            0 => String::new(),
            n => format!("; {n} events lost: the writer fell behind"),
        };
        format!(
            "{} channels, {} messages ({}){lost}",
            self.channels.len(),
            self.messages(),
            each.join(", ")
        )
    }
}
