//! The timeline: faults, restarts, losses, rebinds, node news and the run's milestones, the
//! latest [`TIMELINE_LIMIT`] — what the page's timeline panel lists.

use marie_vocabulary::events::EventKind;
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

/// The timeline's class (the page's CSS class) of `kind`, or `None` for an event it does
/// not list: choices and bindings (the bindings panel shows them), an operation's part, the
/// tree's plan, the registry's comings and goings and a datamanager's state (the cluster
/// panel), a supervisor starting a child, records acknowledged, applied or deleted (too
/// many to list: the check at the run's end tells them), and the robot's events the robot panel
/// draws (`drawn`) but a dock found and a collision.
pub fn class(kind: &EventKind, drawn: bool) -> Option<&'static str> {
    Some(match kind {
        EventKind::RunStarted { .. }
        | EventKind::Provenance(_)
        | EventKind::RunEnded { .. }
        | EventKind::Judged { .. } => "run",
        EventKind::Reparameterized { .. } => "param",
        EventKind::ActionStarted { .. } | EventKind::ActionEnded { .. } => "action",
        EventKind::Control { .. } => "control",
        EventKind::Lost { .. } => "lost",
        EventKind::Rebound(_)
        | EventKind::BindingUpgraded(_)
        | EventKind::BindingRolledBack(_) => "rebind",
        EventKind::RebindGaveUp { .. } | EventKind::SupervisorGaveUp { .. } => "gave_up",
        EventKind::Takeover { .. } => "takeover",
        EventKind::DispatcherFenced { .. } => "fenced",
        EventKind::ChildExited { .. } => "exit",
        EventKind::ChildRestarted { .. } => "restart",
        EventKind::FaultInjected { .. }
        | EventKind::FaultHealed { .. }
        | EventKind::FaultNotInjected { .. } => "fault",
        EventKind::NodeUp { .. }
        | EventKind::NodeBack { .. }
        | EventKind::NodeLost { .. }
        | EventKind::NodeDown { .. }
        | EventKind::NodeFrozen { .. }
        | EventKind::NodeRefused { .. }
        | EventKind::ConnectionRefused { .. } => "node",
        EventKind::DmPromoted { .. }
        | EventKind::DmFenced { .. }
        | EventKind::DmRetention { .. }
        | EventKind::DmRecovered { .. }
        | EventKind::DmInherited { .. }
        | EventKind::DmReplicaAdded { .. }
        | EventKind::DmReplicaPromoted { .. }
        | EventKind::DmReplicaRemoved { .. }
        | EventKind::DmReplicaOut { .. }
        | EventKind::DmReplicaReplaced { .. }
        | EventKind::DmReplicaCaughtUp { .. }
        | EventKind::DmRedundancyRestored { .. }
        | EventKind::DmChecked(_) => "datamanager",
        EventKind::Robot { what, .. }
            if !drawn || matches!(what.as_str(), "dock-found" | "collision") =>
        {
            "robot"
        }
        EventKind::Selected { .. }
        | EventKind::BindingUpgradeRefused { .. }
        | EventKind::Bound { .. }
        | EventKind::OpEnded { .. }
        | EventKind::ControlPlan { .. }
        | EventKind::Joined(_)
        | EventKind::Left(_)
        | EventKind::DmState { .. }
        // the poll's news every 2 s while it lasts: the cluster panel says it
        | EventKind::DmNoMajority { .. }
        | EventKind::ChildStarted { .. }
        | EventKind::DmAcked { .. }
        | EventKind::DmDeleted { .. }
        | EventKind::DmApplied { .. }
        | EventKind::Robot { .. } => return None,
    })
}
