//! The monitor's state: everything the page shows, reduced from the node's (or the
//! cluster's) event stream one [`Event`] at a time.
//!
//! Why a reducer: the live page, a replay at any moment of a past run and the tests all
//! need the same picture of a run, and the event stream is the one source that every node,
//! every `--events` file and the relay of a cluster already carry. Applying the events of a
//! file up to time T gives the page's state at T; applying them as they come gives the
//! live state. Nothing here waits or does I/O.
//!
//! One concept per file: the mission's task tree ([`mission`]), its behaviour tree
//! ([`tree`]), the bindings ([`bindings`]), the cluster ([`cluster`]), the datamanagers
//! without a majority ([`majority`]), the robot ([`robot`]), the timeline ([`timeline`]).
//! Every part is bounded (history, timeline,
//! path, a node's decisions), so a long run cannot grow the monitor without limit.

pub mod bindings;
pub mod cluster;
pub mod majority;
pub mod mission;
pub mod robot;
pub mod strength;
pub mod timeline;
pub mod tree;

use bindings::Bindings;
use cluster::Cluster;
use majority::NoMajorities;
use marie_vocabulary::events::{Event, EventKind, Teller};
use mission::MissionView;
use robot::RobotView;
use serde::Serialize;
use strength::Strengths;
use timeline::Timeline;
use tree::ControlTree;

/// Everything the page shows. Serialized as JSON for it: an object with these fields, each
/// part as its type documents (field names as written here, enums in snake_case).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct MonitorState {
    /// Events applied so far.
    pub events: u64,
    /// The time of the latest event applied, ms of its node's clock.
    pub at_ms: u64,
    /// The time of the earliest event applied: the page shows times relative to it (a
    /// cluster's clocks count from the Unix epoch).
    pub start_ms: Option<u64>,
    /// Events the monitor itself lost (it fell behind the bus or the relay).
    pub missed: u64,
    /// The mission's run: task tree, flags, outcome.
    pub mission: MissionView,
    /// The mission's behaviour tree, when the run announced one: nodes, the running
    /// branch, the control decisions.
    pub tree: ControlTree,
    /// The bindings, by operation.
    pub bindings: Bindings,
    /// The nodes, by name.
    pub cluster: Cluster,
    /// The replicated datamanagers without a leader now ("no majority"), by name.
    pub no_majority: NoMajorities,
    /// The replicated datamanagers' way back to full strength after a loss, by name.
    pub strength: Strengths,
    /// The robot in its world.
    pub robot: RobotView,
    /// Faults, restarts, rebinds, node news.
    pub timeline: Timeline,
    /// Words the events for the timeline (follows the run).
    #[serde(skip)]
    voice: Voice,
}

impl MonitorState {
    /// The state after `events`, in order.
    pub fn from_events<'a>(events: impl IntoIterator<Item = &'a Event>) -> MonitorState {
        let mut state = MonitorState::default();
        for e in events {
            state.apply(e);
        }
        state
    }

    /// Apply one event: each part takes in what concerns it, and the timeline lists it in
    /// the words every reader of events shares.
    pub fn apply(&mut self, event: &Event) {
        self.events += 1;
        self.at_ms = self.at_ms.max(event.at_ms);
        self.start_ms = Some(self.start_ms.map_or(event.at_ms, |s| s.min(event.at_ms)));
        let kind = &event.kind;
        self.mission.apply(kind);
        self.tree.apply(kind);
        self.bindings.apply(event.at_ms, kind);
        self.cluster.apply(event);
        self.no_majority.apply(event.at_ms, kind);
        self.strength.apply(event.at_ms, kind);
        let drawn = match kind {
            EventKind::Robot { what, data } => self.robot.apply(what, data),
            _ => false,
        };
        match timeline::class(kind, drawn) {
            Some(class) => {
                let words = self.voice.0.tell(event);
                self.timeline
                    .push(event.at_ms, &event.node, class, words.text);
            }
            None => self.voice.0.heed(event),
        }
    }
}

/// The words of a run's events, following the stream: the vocabulary's one voice, with the
/// robot's words. Not part of what the page is sent, nor of what makes two states equal.
#[derive(Clone, Debug)]
struct Voice(Teller);

impl Default for Voice {
    fn default() -> Voice {
        Voice(Teller::default().with_robot_words(marie_telemetry::words))
    }
}

impl PartialEq for Voice {
    fn eq(&self, _: &Voice) -> bool {
        true
    }
}
