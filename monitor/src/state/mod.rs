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
//! ([`tree`]), the bindings ([`bindings`]), the cluster ([`cluster`]), the robot
//! ([`robot`]), the timeline ([`timeline`]). Every part is bounded (history, timeline,
//! path, a node's decisions), so a long run cannot grow the monitor without limit.

pub mod bindings;
pub mod cluster;
pub mod mission;
pub mod robot;
pub mod timeline;
pub mod tree;

use bindings::Bindings;
use cluster::Cluster;
use marie_vocabulary::events::{Event, EventKind};
use marie_vocabulary::run::{Aim, Outcome};
use mission::MissionView;
use robot::RobotView;
use serde::Serialize;
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
    /// The robot in its world.
    pub robot: RobotView,
    /// Faults, restarts, rebinds, node news.
    pub timeline: Timeline,
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

    /// Apply one event.
    pub fn apply(&mut self, event: &Event) {
        self.events += 1;
        self.at_ms = self.at_ms.max(event.at_ms);
        self.start_ms = Some(self.start_ms.map_or(event.at_ms, |s| s.min(event.at_ms)));
        let (at, node) = (event.at_ms, event.node.as_str());
        self.cluster.heard_from(node, at);
        let line = &mut self.timeline;
        match &event.kind {
            EventKind::RunStarted {
                mission,
                actions,
                success,
            } => {
                self.mission.started(mission, actions, success);
                self.tree.run_started();
                self.bindings.clear();
                line.push(at, node, "run", format!("mission `{mission}` started"));
            }
            EventKind::Provenance(p) => {
                let files: Vec<String> = p
                    .files
                    .iter()
                    .map(|f| format!("{} {}", f.role, f.path))
                    .collect();
                let build = p
                    .marie
                    .as_ref()
                    .map_or_else(|| "marie of unknown build".into(), |b| format!("marie {b}"));
                line.push(at, node, "run", format!("{build}; {}", files.join(", ")));
            }
            EventKind::Reparameterized {
                operation, values, ..
            } => {
                let values: Vec<String> = values
                    .iter()
                    .map(|v| format!("{} = {}", v.name, v.value))
                    .collect();
                line.push(
                    at,
                    node,
                    "param",
                    format!("`{operation}` parameters set: {}", values.join(", ")),
                );
            }
            EventKind::Selected { choice } => self.bindings.selected(choice),
            EventKind::Bound { operations } => self.bindings.bound(operations),
            EventKind::ActionStarted {
                action,
                run_ms,
                operations,
            } => {
                self.mission.action_started(action, *run_ms, operations);
                self.tree.action_started(action);
                self.bindings.activated(operations);
                line.push(at, node, "action", format!("action `{action}` started"));
            }
            EventKind::OpEnded {
                action,
                key,
                ended,
                flags,
            } => {
                self.mission.op_ended(action, key, *ended, flags);
                self.tree.op_ended(action, *ended);
            }
            EventKind::ActionEnded {
                action,
                run_ms,
                flags,
                result,
                ..
            } => {
                self.mission.action_ended(action, *run_ms, flags);
                self.tree.action_ended(action, *result);
                line.push(at, node, "action", format!("action `{action}` ended"));
            }
            EventKind::ControlPlan { nodes } => self.tree.planned(nodes),
            EventKind::Control {
                node: by,
                decision,
                run_ms,
            } => {
                self.tree.decided(by, decision, *run_ms);
                line.push(at, node, "control", format!("{by}: {decision}"));
            }
            EventKind::RunEnded {
                outcome,
                reason,
                run_ms,
                flags,
                ..
            } => {
                self.mission.run_ended(*outcome, reason, *run_ms, flags);
                self.tree.run_ended(*outcome);
                line.push(at, node, "run", ended_text("run", *outcome, reason));
            }
            EventKind::Judged {
                outcome,
                reason,
                robot,
            } => {
                // what marie's simulated robot says of a run, by its documented keys
                // (another robot's may lack them)
                let key = |k: &str| robot.get(k).cloned().unwrap_or_default();
                let judgement: Option<String> =
                    serde_json::from_value(key("judgement")).ok().flatten();
                self.mission.judged(
                    *outcome,
                    reason,
                    judgement.as_deref(),
                    serde_json::from_value(key("final_pose")).ok().flatten(),
                    serde_json::from_value(key("collisions")).ok().flatten(),
                );
                line.push(at, node, "run", ended_text("judged", *outcome, reason));
            }
            EventKind::Lost { operation, cause } => {
                self.bindings.lost(at, operation, cause);
                line.push(at, node, "lost", format!("{operation} lost: {cause}"));
            }
            EventKind::Rebound(r) => {
                self.bindings.rebound(at, r);
                line.push(
                    at,
                    node,
                    "rebind",
                    format!(
                        "{} rebound: {} -> {} ({} ms)",
                        r.operation, r.from, r.to, r.downtime_ms
                    ),
                );
            }
            EventKind::RebindGaveUp {
                operation,
                cause,
                waited_ms,
            } => {
                self.bindings.gave_up(at, operation, cause, *waited_ms);
                line.push(
                    at,
                    node,
                    "gave_up",
                    format!("no stand-in for {operation} within {waited_ms} ms"),
                );
            }
            EventKind::Takeover {
                from,
                to,
                term,
                gap_ms,
                ..
            } => line.push(
                at,
                node,
                "takeover",
                format!("the run taken over by {to} from {from} (term {term}, {gap_ms} ms)"),
            ),
            EventKind::DispatcherFenced { term, newer, .. } => line.push(
                at,
                node,
                "fenced",
                format!("the dispatcher of term {term} fenced off by term {newer}"),
            ),
            EventKind::Joined(m) => self.cluster.joined(m, at),
            EventKind::DmState {
                dm,
                durability,
                records,
                journal_bytes,
                role,
                term,
                lag,
            } => self.cluster.dm_state(
                node,
                dm,
                cluster::DmView {
                    durability: durability.clone(),
                    records: *records,
                    journal_bytes: *journal_bytes,
                    role: role.clone(),
                    term: *term,
                    lag: lag.clone(),
                },
                at,
            ),
            EventKind::Left(m) => self.cluster.left(m, at),
            EventKind::ChildStarted { .. } => {}
            EventKind::ChildExited {
                supervisor,
                child,
                reason,
            } => line.push(
                at,
                node,
                "exit",
                format!("{child} exited under {supervisor}: {reason}"),
            ),
            EventKind::ChildRestarted {
                supervisor,
                child,
                restarts,
                reason,
                ..
            } => line.push(
                at,
                node,
                "restart",
                format!("{supervisor} restarted {child} (restart {restarts}): {reason}"),
            ),
            EventKind::SupervisorGaveUp { supervisor, reason } => line.push(
                at,
                node,
                "gave_up",
                format!("supervisor {supervisor} gave up: {reason}"),
            ),
            EventKind::FaultInjected {
                fault,
                operation,
                actor,
                lasting_ms,
                ..
            } => {
                let lasting = lasting_ms
                    .map(|ms| format!(" for {:.1} s", ms as f64 / 1000.0))
                    .unwrap_or_default();
                line.push(
                    at,
                    node,
                    "fault",
                    match fault.aim() {
                        Aim::Operation => format!("{fault} injected into {operation} ({actor})"),
                        Aim::Node => format!("{node} did {fault} to {operation} ({actor}){lasting}"),
                        Aim::Cut => format!("{node} cut {operation} apart{lasting}"),
                    },
                )
            }
            EventKind::FaultHealed { fault, operation } => line.push(
                at,
                node,
                "fault",
                format!("{fault} of {operation} healed"),
            ),
            EventKind::FaultNotInjected {
                fault,
                operation,
                why,
                ..
            } => line.push(
                at,
                node,
                "fault",
                format!("{fault} not injected into {operation}: {why}"),
            ),
            EventKind::NodeUp { peer, address } => {
                self.cluster.up(peer, address, at);
                line.push(at, node, "node", format!("{node} sees {peer} ({address})"));
            }
            EventKind::NodeLost { peer, address } => {
                self.cluster.lost(peer, address, at);
                line.push(at, node, "node", format!("{node} lost {peer} ({address})"));
            }
            EventKind::NodeDown { peer, silent_ms } => {
                self.cluster.down(peer, at);
                line.push(
                    at,
                    node,
                    "node",
                    format!("{node} declared {peer} down (silent {silent_ms} ms)"),
                );
            }
            EventKind::NodeFrozen { silent_ms } => {
                self.cluster.frozen(node, at);
                line.push(
                    at,
                    node,
                    "node",
                    format!("{node} was frozen {silent_ms} ms: restarts its operations"),
                );
            }
            EventKind::NodeRefused { peer, theirs, ours } => line.push(
                at,
                node,
                "node",
                format!("{node} refused {peer} (protocol {theirs}, ours {ours})"),
            ),
            EventKind::DmPromoted { dm, node: on, term } => line.push(
                at,
                node,
                "datamanager",
                format!("datamanager {dm}: the copy on {on} is the primary now (term {term})"),
            ),
            EventKind::DmFenced {
                dm,
                node: on,
                term,
                why,
            } => line.push(
                at,
                node,
                "datamanager",
                format!("datamanager {dm}: the primary on {on} (term {term}) stepped down: {why}; it restarts as a copy"),
            ),
            EventKind::DmRecovered {
                dm,
                records,
                bytes,
                ms,
                dropped_bytes,
                dropped_records,
                torn,
            } => line.push(
                at,
                node,
                "datamanager",
                match torn {
                    None => format!(
                        "datamanager {dm} on {node} read its journal back: {records} records ({bytes} bytes) in {ms} ms"
                    ),
                    Some(why) => format!(
                        "datamanager {dm} on {node} read its journal back up to a torn end ({why}): {records} records ({bytes} bytes) kept, {dropped_records} records ({dropped_bytes} bytes) dropped, in {ms} ms"
                    ),
                },
            ),
            // a store acknowledged is what the check at the run's end looks up: too many to
            // list, and told by the check
            EventKind::DmAcked { .. } | EventKind::DmDeleted { .. } => {}
            EventKind::DmChecked(check) => line.push(
                at,
                node,
                "datamanager",
                match &check.error {
                    None => format!(
                        "datamanager {}: {} acknowledged records, {} held on {}, {} lost",
                        check.dm,
                        check.acknowledged,
                        check.held,
                        check.node.as_deref().unwrap_or("?"),
                        check.lost
                    ),
                    Some(why) => format!(
                        "datamanager {}: could not be checked ({why}): {} acknowledged records count lost",
                        check.dm, check.lost
                    ),
                },
            ),
            EventKind::ConnectionRefused { from, reason } => line.push(
                at,
                node,
                "node",
                format!("{node} refused a connection from {from}: {reason}"),
            ),
            EventKind::Robot { what, data } => {
                let drawn = self.robot.apply(what, data);
                if !drawn || matches!(what.as_str(), "dock-found" | "collision") {
                    line.push(at, node, "robot", format!("robot: {what}"));
                }
            }
        }
    }
}

fn ended_text(what: &str, outcome: Outcome, reason: &str) -> String {
    match outcome {
        Outcome::Succeeded => format!("{what}: succeeded"),
        Outcome::Failed => format!("{what}: failed: {reason}"),
    }
}
