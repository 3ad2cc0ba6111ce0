//! Replay mode: a past run's events file, the state at any moment of it.
//!
//! The page plays a run by asking for the state at successive times (at the speed chosen),
//! pauses by not asking, and seeks with its slider: the state at T is every event up to T
//! applied in order. A cursor remembers the latest state asked for, so playing forward
//! applies only the events since; seeking back starts over (a run's file is small: a
//! docking run writes 820 events, the robot's included).

use crate::error::MonitorError;
use crate::state::MonitorState;
use marie_vocabulary::events::Event;
use serde::Serialize;
use std::path::Path;
use std::sync::Mutex;

/// A loaded run.
pub(crate) struct Replay {
    events: Vec<Event>,
    cursor: Mutex<(usize, MonitorState)>,
    /// The state after the whole run, as JSON: asked for by every `/api/state`, computed
    /// once (and without moving the cursor a playing page uses).
    final_json: String,
}

/// What the page needs to set up its controls.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub(crate) struct ReplayInfo {
    /// Events in the file.
    pub events: usize,
    /// Time of the first event, ms.
    pub start_ms: u64,
    /// Time of the last event, ms.
    pub end_ms: u64,
    /// `end_ms - start_ms`.
    pub duration_ms: u64,
}

impl Replay {
    /// Read `path` (one event per line; blank lines skipped), ordered by time (a cluster's
    /// file interleaves nodes; their order at equal times is kept).
    pub(crate) fn load(path: &Path) -> Result<Replay, MonitorError> {
        let text = std::fs::read_to_string(path).map_err(|source| MonitorError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        let mut events = Vec::new();
        for (i, line) in text.lines().enumerate() {
            if line.trim().is_empty() {
                continue;
            }
            events.push(
                Event::from_json_line(line).map_err(|source| MonitorError::Parse {
                    path: path.to_path_buf(),
                    line: i + 1,
                    source,
                })?,
            );
        }
        Ok(Replay::new(events))
    }

    /// A replay of `events`.
    pub(crate) fn new(mut events: Vec<Event>) -> Replay {
        events.sort_by_key(|e| e.at_ms);
        let final_json = to_json(&MonitorState::from_events(&events));
        Replay {
            events,
            cursor: Mutex::new((0, MonitorState::default())),
            final_json,
        }
    }

    /// Its extent.
    pub(crate) fn info(&self) -> ReplayInfo {
        let start_ms = self.events.first().map_or(0, |e| e.at_ms);
        let end_ms = self.events.last().map_or(0, |e| e.at_ms);
        ReplayInfo {
            events: self.events.len(),
            start_ms,
            end_ms,
            duration_ms: end_ms - start_ms,
        }
    }

    /// The state after every event at or before `at_ms`, as JSON for the page (serialized
    /// at the cursor: no copy of the state).
    pub(crate) fn state_json_at(&self, at_ms: u64) -> String {
        self.at(at_ms, to_json)
    }

    /// The state after the whole run, as JSON.
    pub(crate) fn final_json(&self) -> &str {
        &self.final_json
    }

    /// `read` of the state after every event at or before `at_ms`: the cursor moved there
    /// (forward from where it is, or from the start when `at_ms` is earlier).
    fn at<R>(&self, at_ms: u64, read: impl FnOnce(&MonitorState) -> R) -> R {
        let mut cursor = self.cursor.lock().unwrap_or_else(|e| e.into_inner());
        let (next, state) = &mut *cursor;
        if *next > 0 && self.events[*next - 1].at_ms > at_ms {
            *next = 0;
            *state = MonitorState::default();
        }
        while let Some(e) = self.events.get(*next).filter(|e| e.at_ms <= at_ms) {
            state.apply(e);
            *next += 1;
        }
        read(state)
    }
}

fn to_json(state: &MonitorState) -> String {
    serde_json::to_string(state).unwrap_or_else(|e| {
        tracing::error!(error = %e, "cannot serialize a replayed state");
        "{}".into()
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use marie_vocabulary::events::EventKind;

    fn at(ms: u64) -> Event {
        Event {
            at_ms: ms,
            node: "n".into(),
            kind: EventKind::NodeFrozen { silent_ms: ms },
        }
    }

    #[test]
    fn the_state_at_a_time_has_every_event_up_to_it_forward_and_back() {
        let replay = Replay::new(vec![at(30), at(10), at(20), at(20)]);
        assert_eq!(
            replay.info(),
            ReplayInfo {
                events: 4,
                start_ms: 10,
                end_ms: 30,
                duration_ms: 20
            }
        );
        let events_at = |ms| replay.at(ms, |s| s.events);
        assert_eq!(events_at(5), 0);
        assert_eq!(events_at(20), 3);
        assert_eq!(events_at(25), 3);
        assert_eq!(events_at(10), 1);
        let end: serde_json::Value = serde_json::from_str(replay.final_json()).unwrap();
        assert_eq!(end["events"], 4);
        assert_eq!(events_at(0), 0);
        // the JSON at a time is that state's
        let at_20: serde_json::Value = serde_json::from_str(&replay.state_json_at(20)).unwrap();
        assert_eq!(at_20["events"], 3);
    }
}
