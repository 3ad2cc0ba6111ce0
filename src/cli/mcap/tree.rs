//! The mission's task tree on `/control` (schema `marie.ControlState`): after each event
//! that changes it — the run's start, its plan (`control_plan`), an action's start or end,
//! a control decision, the run's end — the whole state as one JSON object: which actions
//! run (`running`, and `active`, the same joined in one string for Foxglove's State
//! Transitions panel, which plots a plain value over time), and every node of the plan
//! with its status so far (`idle`, `running`, `succeeded`, `failed`, `halted`), its starts,
//! attempts and latest decisions. Each message is the whole state, so the Raw Messages
//! panel shows it right at any time it is moved to.
//!
//! The statuses are the monitor's ([`ControlTree`]: what the events say, and what is
//! inferred from them — a group's end from its children's, an action that failed after
//! all from the decision that follows it), so the file and the page tell the same tree.
//! Bounded: the tree is the plan's size, each node keeps its latest
//! [`DECISIONS_KEPT`](marie_monitor::state::tree::DECISIONS_KEPT) decisions.

use super::schemas::{Message, Time, Topic};
use marie::events::{Event, EventKind};
use marie::run::Outcome;
use marie_monitor::state::tree::{ControlTree, NodeEnd, TreeItem};
use serde::Serialize;
use std::collections::BTreeSet;

/// The task tree so far.
#[derive(Debug, Default)]
pub(crate) struct Control {
    /// The plan's items and their states.
    tree: ControlTree,
    /// The actions started and not ended (kept apart from the tree: an older stream has
    /// no plan, and its actions still run).
    running: BTreeSet<String>,
    /// The mission's name.
    mission: String,
    /// When the run began, ms of its node's clock.
    start_ms: Option<u64>,
    /// How it ended, once it did.
    outcome: Option<Outcome>,
}

/// A `/control` message.
#[derive(Debug, Serialize)]
pub(crate) struct ControlState<'a> {
    /// When.
    timestamp: Time,
    /// When, ms since the run began.
    run_ms: u64,
    /// The event that changed the state: its `type`.
    event: &'static str,
    /// That event in words (as `/events` has it).
    text: String,
    /// The mission.
    mission: &'a str,
    /// `succeeded` or `failed` once the run ended, else empty.
    outcome: &'static str,
    /// The running actions, joined by `, ` (empty when none runs).
    active: String,
    /// The running actions.
    running: &'a BTreeSet<String>,
    /// Plans told so far (a new value: a new tree).
    plan: u64,
    /// The plan's items, the root first.
    items: Vec<ItemState<'a>>,
}

/// A node of the plan and its status.
#[derive(Debug, Serialize)]
struct ItemState<'a> {
    id: usize,
    #[serde(skip_serializing_if = "Option::is_none")]
    parent: Option<usize>,
    depth: usize,
    kind: &'a str,
    label: &'a str,
    detail: &'a str,
    /// `idle`, `running`, `succeeded`, `failed` or `halted`.
    status: &'static str,
    starts: u32,
    #[serde(skip_serializing_if = "Option::is_none")]
    attempt: Option<[u32; 2]>,
    told: u32,
    decisions: Vec<Decision<'a>>,
}

#[derive(Debug, Serialize)]
struct Decision<'a> {
    run_ms: u64,
    text: &'a str,
}

impl<'a> ItemState<'a> {
    fn of(n: &'a TreeItem) -> ItemState<'a> {
        ItemState {
            id: n.id,
            parent: n.parent,
            depth: n.depth,
            kind: &n.kind,
            label: &n.label,
            detail: &n.detail,
            status: match (n.running, n.ended) {
                (true, _) => "running",
                (false, Some(NodeEnd::Succeeded)) => "succeeded",
                (false, Some(NodeEnd::Failed)) => "failed",
                (false, Some(NodeEnd::Halted)) => "halted",
                (false, None) => "idle",
            },
            starts: n.starts,
            attempt: n.attempt,
            told: n.told,
            decisions: n
                .decisions
                .iter()
                .map(|d| Decision {
                    run_ms: d.run_ms,
                    text: &d.text,
                })
                .collect(),
        }
    }
}

impl Control {
    /// Apply `event`; the `/control` message when it changed the state.
    pub(crate) fn apply(
        &mut self,
        event: &Event,
        said: &str,
    ) -> Result<Option<Message>, serde_json::Error> {
        let (name, run_ms) = match &event.kind {
            EventKind::RunStarted { mission, .. } => {
                self.tree.run_started();
                self.running.clear();
                self.mission = mission.clone();
                self.start_ms = Some(event.at_ms);
                self.outcome = None;
                ("run_started", None)
            }
            EventKind::ControlPlan { items: nodes } => {
                self.tree.planned(nodes);
                ("control_plan", None)
            }
            EventKind::ActionStarted { action, run_ms, .. } => {
                self.tree.action_started(action);
                self.running.insert(action.clone());
                ("action_started", Some(*run_ms))
            }
            EventKind::OpEnded { action, ended, .. } => {
                // what an action's end is inferred from; the end itself tells
                self.tree.op_ended(action, *ended);
                return Ok(None);
            }
            EventKind::ActionEnded {
                action,
                run_ms,
                result,
                ..
            } => {
                self.tree.action_ended(action, *result);
                self.running.remove(action);
                ("action_ended", Some(*run_ms))
            }
            EventKind::Control {
                item: node,
                decision,
                run_ms,
            } => {
                self.tree.decided(node, decision, *run_ms);
                ("control", Some(*run_ms))
            }
            EventKind::RunEnded {
                outcome, run_ms, ..
            } => {
                self.tree.run_ended(*outcome);
                self.running.clear();
                self.outcome = Some(*outcome);
                ("run_ended", Some(*run_ms))
            }
            _ => return Ok(None),
        };
        let run_ms = run_ms.unwrap_or_else(|| {
            event
                .at_ms
                .saturating_sub(self.start_ms.unwrap_or(event.at_ms))
        });
        let state = ControlState {
            timestamp: Time::from_ms(event.at_ms),
            run_ms,
            event: name,
            text: said.to_string(),
            mission: &self.mission,
            outcome: match self.outcome {
                None => "",
                Some(Outcome::Succeeded) => "succeeded",
                Some(Outcome::Failed) => "failed",
            },
            active: self
                .running
                .iter()
                .map(String::as_str)
                .collect::<Vec<_>>()
                .join(", "),
            running: &self.running,
            plan: self.tree.plan,
            items: self.tree.items.iter().map(ItemState::of).collect(),
        };
        Message::new(Topic::Control, event.at_ms, &state).map(Some)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cli::mcap::schemas::tests::fits;
    use serde_json::Value;

    const RUN: &str = r#"{"at_ms":1200,"node":"n","kind":{"type":"run_started","mission":"docking"}}
{"at_ms":1201,"node":"n","kind":{"type":"control_plan","items":[{"id":0,"parent":null,"kind":"schedule","label":"mission"},{"id":1,"parent":0,"kind":"retry","label":"retry(follow)","detail":"2 attempts, 1.0 s apart"},{"id":2,"parent":1,"kind":"action","label":"follow","detail":"wall-follower"}]}}
{"at_ms":1260,"node":"n","kind":{"type":"action_started","action":"follow","run_ms":60,"operations":[]}}
{"at_ms":9800,"node":"n","kind":{"type":"op_ended","action":"follow","key":"wall-follower","ended":"failed","flags":[]}}
{"at_ms":9810,"node":"n","kind":{"type":"action_ended","action":"follow","run_ms":8610,"flags":[],"status":0,"result":"failed"}}
{"at_ms":9811,"node":"n","kind":{"type":"control","node":"retry(follow)","decision":"retry 2 of 2","run_ms":8611}}
{"at_ms":9900,"node":"n","kind":{"type":"action_started","action":"follow","run_ms":8700,"operations":[]}}
{"at_ms":20000,"node":"n","kind":{"type":"action_ended","action":"follow","run_ms":18800,"flags":[],"status":4,"result":"succeeded"}}
{"at_ms":20001,"node":"n","kind":{"type":"run_ended","outcome":"succeeded","reason":"","run_ms":18801,"status":4,"flags":[]}}"#;

    #[test]
    fn each_change_of_the_tree_is_a_whole_state() {
        let mut control = Control::default();
        let mut teller = marie::events::Teller::default();
        let states: Vec<Value> = RUN
            .lines()
            .filter_map(|l| {
                let event = Event::from_json_line(l).unwrap();
                let said = teller.tell(&event).text;
                control
                    .apply(&event, &said)
                    .unwrap()
                    .map(|m| serde_json::from_slice(&m.data).unwrap())
            })
            .collect();
        // every line but the operation's end
        assert_eq!(states.len(), 8);
        let schema: Value = serde_json::from_str(&Topic::Control.schema()).unwrap();
        for s in &states {
            fits(s, &schema, "/control");
        }
        let status = |s: &Value| -> Vec<String> {
            s["items"]
                .as_array()
                .unwrap()
                .iter()
                .map(|n| n["status"].as_str().unwrap().to_string())
                .collect()
        };
        assert_eq!(states[1]["items"][2]["detail"], "wall-follower");
        assert_eq!(states[2]["active"], "follow");
        assert_eq!(status(&states[2]), ["running", "running", "running"]);
        assert_eq!(states[3]["active"], "");
        assert_eq!(states[3]["run_ms"], 8610);
        assert_eq!(
            states[4]["items"][1]["decisions"][0]["text"],
            "retry 2 of 2"
        );
        assert_eq!(states[4]["items"][1]["attempt"], serde_json::json!([2, 2]));
        let last = &states[7];
        assert_eq!(last["outcome"], "succeeded");
        assert_eq!(status(last), ["succeeded", "succeeded", "succeeded"]);
        assert_eq!(last["items"][2]["starts"], 2);
        assert!(last["items"][0].get("parent").is_none());
        assert_eq!(last["items"][2]["parent"], 1);
    }
}
