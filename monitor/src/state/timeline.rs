//! The timeline: faults, restarts, losses, rebinds, node news and the run's milestones, the
//! latest [`TIMELINE_LIMIT`] — what the page's timeline panel lists.

use serde::Serialize;
use std::collections::VecDeque;

/// The timeline keeps this many entries (the oldest go first).
pub const TIMELINE_LIMIT: usize = 500;

/// One entry.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Entry {
    /// Event time, ms of the publishing node's clock.
    pub at_ms: u64,
    /// The node that published it.
    pub node: String,
    /// What kind of entry: `run`, `action`, `fault`, `restart`, `exit`, `gave_up`, `lost`,
    /// `rebind`, `node`, `control` or `robot` — the page's CSS class of the entry.
    pub class: &'static str,
    /// One line of text.
    pub text: String,
}

/// The bounded timeline.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Timeline {
    /// The entries kept, oldest first.
    pub entries: VecDeque<Entry>,
    /// Entries dropped for the bound.
    pub dropped: u64,
}

impl Timeline {
    /// Add an entry, dropping the oldest beyond the bound.
    pub fn push(&mut self, at_ms: u64, node: &str, class: &'static str, text: String) {
        if self.entries.len() >= TIMELINE_LIMIT {
            self.entries.pop_front();
            self.dropped += 1;
        }
        self.entries.push_back(Entry {
            at_ms,
            node: node.to_string(),
            class,
            text,
        });
    }
}
