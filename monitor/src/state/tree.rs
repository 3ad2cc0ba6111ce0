//! The mission's behaviour tree: its items (groups, decorators, actions) as the run
//! announced them
//! ([`EventKind::ControlPlan`]), each with
//! whether it runs now, how it ended when that is known, and the control decisions told of
//! it — what the page's tree panel draws.
//!
//! What the events say, and what is inferred:
//! - An `action` node runs between its action's `ActionStarted` and `ActionEnded`; any other
//!   node runs while one of its descendants does (the running branch).
//! - An action ended as its `ActionEnded` says (`result`); in an older stream that does not
//!   say, **failed** when one of its operations ended failed, lost or unresponsive, **halted** when an ancestor halted it (a timeout, a condition that no
//!   longer holds, a parallel decided) while it ran, **succeeded** otherwise — unless the
//!   decision that follows at once (a fallback, a recovery, a retry giving up) shows that
//!   it failed after all (it missed its deadline).
//! - A group's end follows from its children's (a sequence fails with one, a fallback
//!   succeeds with one, …) or from a decision of its own (a timeout, a retry that gave up, a
//!   parallel decided, a condition lost); the root ends with the run.
//! - A retry's `retry n of m` starts another attempt: its subtree's ends are forgotten.
//!
//! A stream without a plan (an older file) leaves the tree empty: the page then draws the
//! actions as [`mission`](super::mission) has them.

use marie_vocabulary::events::{ActionResult, EventKind, PlanItem};
use marie_vocabulary::run::{OpEnd, Outcome};
use serde::Serialize;
use std::collections::VecDeque;

/// The decisions each node keeps, the latest (counts are kept for all).
pub const DECISIONS_KEPT: usize = 4;

/// How a node ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum NodeEnd {
    /// It succeeded.
    Succeeded,
    /// It failed.
    Failed,
    /// An ancestor halted it while it ran.
    Halted,
}

/// A control decision told of a node.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Told {
    /// When, ms since the run began.
    pub run_ms: u64,
    /// The decision in words (`retry 2 of 3`, ``fallback to `wall` ``).
    pub text: String,
}

/// One node of the tree. Serialized without the counts that are zero, the flags that are
/// false and the ends that are unknown: a tree of hundreds of items goes to every viewer
/// ten times a second.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TreeItem {
    /// Its id: its place in preorder, the root 0.
    pub id: usize,
    /// Its parent's id (none for the root).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub parent: Option<usize>,
    /// How deep it is: the root 0.
    pub depth: usize,
    /// `schedule`, `sequence`, `reactive`, `fallback`, `parallel`, `retry`, `timeout`,
    /// `recover`, `action` or `condition`.
    pub kind: String,
    /// Its label (an action's or a group's name, a decorator and what it decorates).
    pub label: String,
    /// Its settings in words.
    #[serde(skip_serializing_if = "String::is_empty")]
    pub detail: String,
    /// Whether it runs now: an action between its start and its end, a group while one of
    /// its descendants runs.
    #[serde(skip_serializing_if = "is_false")]
    pub running: bool,
    /// How it ended, when known (none while it runs, before it ran, and after a retry
    /// above it started another attempt).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ended: Option<NodeEnd>,
    /// An action: how many times it started.
    #[serde(skip_serializing_if = "is_zero")]
    pub starts: u32,
    /// A retry: the attempt it is at and the attempts in all (`[2, 3]`), once it told one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub attempt: Option<[u32; 2]>,
    /// A retry: it gave up (its child failed on every attempt).
    #[serde(skip_serializing_if = "is_false")]
    pub gave_up: bool,
    /// A timeout: how many times it fired.
    #[serde(skip_serializing_if = "is_zero")]
    pub timeouts: u32,
    /// A fallback: how many times it fell back to its next child.
    #[serde(skip_serializing_if = "is_zero")]
    pub fallbacks: u32,
    /// A reactive sequence: how many times its condition stopped holding.
    #[serde(skip_serializing_if = "is_zero")]
    pub conditions_lost: u32,
    /// A recover: how many times its recovery ran.
    #[serde(skip_serializing_if = "is_zero")]
    pub recoveries: u32,
    /// Decisions told of it in all.
    #[serde(skip_serializing_if = "is_zero")]
    pub told: u32,
    /// The latest [`DECISIONS_KEPT`] decisions told of it, oldest first.
    #[serde(skip_serializing_if = "VecDeque::is_empty")]
    pub decisions: VecDeque<Told>,
    /// Its children's ids.
    #[serde(skip)]
    kids: Vec<usize>,
    /// Its subtree's size (itself included): its descendants are the ids after it.
    #[serde(skip)]
    size: usize,
    /// An action: started and not ended.
    #[serde(skip)]
    active: bool,
    /// An action: one of its operations failed in this run of it.
    #[serde(skip)]
    op_failed: bool,
    /// An action: an ancestor halted it while it ran.
    #[serde(skip)]
    halting: bool,
    /// What the events said of its end (an action's end, a decision): a group without one
    /// ends as its children say.
    #[serde(skip)]
    fact: Option<NodeEnd>,
}

fn is_false(b: &bool) -> bool {
    !*b
}

fn is_zero(n: &u32) -> bool {
    *n == 0
}

/// The tree: empty until a run announces its plan.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ControlTree {
    /// Plans announced so far: a new value is a new tree (the page builds its drawing once
    /// per plan and updates it after).
    pub plan: u64,
    /// The items by id (preorder, the root first); empty without a plan.
    pub items: Vec<TreeItem>,
    /// The action node whose end was the latest action event: the decision that follows it
    /// at once may show that it failed.
    #[serde(skip)]
    last_ended: Option<usize>,
}

impl ControlTree {
    /// Take the run's plan, its actions' events and its control decisions into the tree;
    /// others pass by.
    pub fn apply(&mut self, kind: &EventKind) {
        match kind {
            EventKind::RunStarted { .. } => self.run_started(),
            EventKind::ControlPlan { items: nodes } => self.planned(nodes),
            EventKind::ActionStarted { action, .. } => self.action_started(action),
            EventKind::OpEnded { action, ended, .. } => self.op_ended(action, *ended),
            EventKind::ActionEnded { action, result, .. } => self.action_ended(action, *result),
            EventKind::Control {
                item,
                decision,
                run_ms,
            } => self.decided(item, decision, *run_ms),
            EventKind::RunEnded { outcome, .. } => self.run_ended(*outcome),
            _ => {}
        }
    }

    /// A run begins: its plan (if any) comes next.
    pub fn run_started(&mut self) {
        self.items.clear();
        self.last_ended = None;
    }

    /// The run's plan: `nodes` (its items) in preorder, the root first. An item whose parent is not
    /// before it is taken as a root of its own (the plan would not be preorder).
    pub fn planned(&mut self, plan: &[PlanItem]) {
        self.plan += 1;
        self.last_ended = None;
        self.items = plan
            .iter()
            .enumerate()
            .map(|(id, p)| TreeItem {
                id,
                parent: p.parent.filter(|&parent| parent < id),
                depth: 0,
                kind: p.kind.clone(),
                label: p.label.clone(),
                detail: p.detail.clone(),
                running: false,
                ended: None,
                starts: 0,
                attempt: None,
                gave_up: false,
                timeouts: 0,
                fallbacks: 0,
                conditions_lost: 0,
                recoveries: 0,
                told: 0,
                decisions: VecDeque::new(),
                kids: Vec::new(),
                size: 1,
                active: false,
                op_failed: false,
                halting: false,
                fact: None,
            })
            .collect();
        for id in 1..self.items.len() {
            if let Some(parent) = self.items[id].parent {
                self.items[id].depth = self.items[parent].depth + 1;
                self.items[parent].kids.push(id);
            }
        }
        for id in (1..self.items.len()).rev() {
            if let Some(parent) = self.items[id].parent {
                self.items[parent].size += self.items[id].size;
            }
        }
    }

    /// The action items of action `name`.
    fn actions_named(&self, name: &str) -> Vec<usize> {
        self.items
            .iter()
            .filter(|n| n.kind == "action" && n.label == name)
            .map(|n| n.id)
            .collect()
    }

    /// The ids of `id`'s descendants (its subtree but itself).
    fn descendants(&self, id: usize) -> std::ops::Range<usize> {
        let end = (id + self.items[id].size).min(self.items.len());
        id + 1..end
    }

    /// Action `name` started.
    pub fn action_started(&mut self, name: &str) {
        for id in self.actions_named(name) {
            let n = &mut self.items[id];
            n.active = true;
            n.starts += 1;
            n.op_failed = false;
            n.halting = false;
            n.fact = None;
        }
        self.last_ended = None;
        self.settle();
    }

    /// An operation's part in action `name` ended as `ended`.
    pub fn op_ended(&mut self, name: &str, ended: OpEnd) {
        if matches!(ended, OpEnd::Failed | OpEnd::Lost | OpEnd::Unresponsive) {
            for id in self.actions_named(name) {
                if self.items[id].active {
                    self.items[id].op_failed = true;
                }
            }
        }
    }

    /// Action `name` ended, as `result` says (inferred when an older stream does not say).
    pub fn action_ended(&mut self, name: &str, result: Option<ActionResult>) {
        self.last_ended = None;
        for id in self.actions_named(name) {
            let n = &mut self.items[id];
            if !n.active {
                continue;
            }
            n.active = false;
            n.fact = Some(if let Some(result) = result {
                match result {
                    ActionResult::Succeeded => NodeEnd::Succeeded,
                    ActionResult::Failed => NodeEnd::Failed,
                    ActionResult::Halted => NodeEnd::Halted,
                }
            } else if n.halting {
                NodeEnd::Halted
            } else if n.op_failed {
                NodeEnd::Failed
            } else {
                NodeEnd::Succeeded
            });
            self.last_ended = Some(id);
        }
        self.settle();
    }

    /// Node `label` decided `decision` at `run_ms` (a decision naming no node of the tree
    /// is passed over: the timeline has it).
    pub fn decided(&mut self, label: &str, decision: &str, run_ms: u64) {
        // labels are unique enough; among equals, the one that runs
        let Some(id) = self
            .items
            .iter()
            .filter(|n| n.label == label)
            .max_by_key(|n| (n.running, std::cmp::Reverse(n.id)))
            .map(|n| n.id)
        else {
            return;
        };
        let node = &mut self.items[id];
        node.told += 1;
        if node.decisions.len() >= DECISIONS_KEPT {
            node.decisions.pop_front();
        }
        node.decisions.push_back(Told {
            run_ms,
            text: decision.to_string(),
        });
        if let Some(rest) = decision.strip_prefix("retry ") {
            // another attempt: the previous one's ends are forgotten
            let mut words = rest.split(" of ").map(|w| w.trim().parse::<u32>());
            if let (Some(Ok(at)), Some(Ok(of))) = (words.next(), words.next()) {
                node.attempt = Some([at, of]);
            }
            node.fact = None;
            self.last_ended = None;
            for d in self.descendants(id) {
                let n = &mut self.items[d];
                n.fact = None;
                n.halting = false;
            }
        } else if decision.starts_with("gave up") {
            node.gave_up = true;
            node.fact = Some(NodeEnd::Failed);
            if let Some(&kid) = self.items[id].kids.first() {
                self.failed_child(kid);
            }
        } else if decision.starts_with("timeout") {
            node.timeouts += 1;
            node.fact = Some(NodeEnd::Failed);
            self.halt_under(id);
        } else if decision.starts_with("condition no longer holds") {
            node.conditions_lost += 1;
            node.fact = Some(NodeEnd::Failed);
            self.halt_under(id);
        } else if let Some(succeeded) = match decision {
            "parallel succeeded" => Some(true),
            "parallel failed" => Some(false),
            _ => None,
        } {
            node.fact = Some(match succeeded {
                true => NodeEnd::Succeeded,
                false => NodeEnd::Failed,
            });
            self.halt_under(id);
        } else if decision.starts_with("fallback") {
            node.fallbacks += 1;
            // the child before the one fallen back to failed
            let to = between_backticks(decision);
            let kids = &self.items[id].kids;
            // the decision names the item it turns to, under its decorators (a retry, a
            // timeout): the child whose branch holds it
            let holds = |k: usize, to: &str| {
                let end = (k + self.items[k].size).min(self.items.len());
                self.items[k..end].iter().any(|n| n.label == to)
            };
            let at = to.and_then(|to| kids.iter().position(|&k| holds(k, to)));
            if let Some(failed) = at.and_then(|at| at.checked_sub(1)).map(|at| kids[at]) {
                self.failed_child(failed);
            }
        } else if decision.starts_with("recovery") {
            node.recoveries += 1;
            if let Some(&kid) = self.items[id].kids.first() {
                self.failed_child(kid);
            }
        }
        self.settle();
    }

    /// The run ended: what still runs ends with it (failed with a failed run), and the
    /// root ends as the run did.
    pub fn run_ended(&mut self, outcome: Outcome) {
        let end = match outcome {
            Outcome::Succeeded => NodeEnd::Succeeded,
            Outcome::Failed => NodeEnd::Failed,
        };
        for n in &mut self.items {
            if n.active {
                n.active = false;
                n.fact = Some(match end {
                    NodeEnd::Succeeded => NodeEnd::Halted,
                    _ => NodeEnd::Failed,
                });
            }
        }
        if let Some(root) = self.items.first_mut() {
            root.fact = Some(end);
        }
        self.settle();
    }

    /// Node `id` (a child of the node that decided) failed. When the action that ended
    /// just before is in its subtree and was taken as succeeded — and no condition after
    /// it could have failed instead — that action failed after all (a missed deadline
    /// ends an action without a failed operation).
    fn failed_child(&mut self, id: usize) {
        self.items[id].fact = Some(NodeEnd::Failed);
        let Some(action) = self.last_ended else {
            return;
        };
        let end = (id + self.items[id].size).min(self.items.len());
        if !(id..end).contains(&action) || self.items[action].fact != Some(NodeEnd::Succeeded) {
            return;
        }
        if !self.items[action + 1..end]
            .iter()
            .any(|n| n.kind == "condition")
        {
            self.items[action].fact = Some(NodeEnd::Failed);
        }
    }

    /// A decision of node `id` halts the actions running under it.
    fn halt_under(&mut self, id: usize) {
        for d in self.descendants(id) {
            if self.items[d].active {
                self.items[d].halting = true;
            }
        }
    }

    /// Work out every node's `running` and `ended` from the actions and the facts,
    /// children before parents (in preorder a child's id is above its parent's).
    fn settle(&mut self) {
        for n in &mut self.items {
            n.running = n.active;
        }
        for id in (0..self.items.len()).rev() {
            let derived = match self.items[id].fact {
                Some(fact) => Some(fact),
                None => self.derived_end(id),
            };
            let n = &mut self.items[id];
            n.ended = if n.running { None } else { derived };
            if let (true, Some(parent)) = (n.running, n.parent) {
                self.items[parent].running = true;
            }
        }
    }

    /// A group's end as its children's ends say (its own decisions aside).
    fn derived_end(&self, id: usize) -> Option<NodeEnd> {
        let n = &self.items[id];
        let ends: Vec<Option<NodeEnd>> = n.kids.iter().map(|&k| self.items[k].ended).collect();
        let any = |e: NodeEnd| ends.contains(&Some(e));
        let all = |e: NodeEnd| !ends.is_empty() && ends.iter().all(|x| *x == Some(e));
        match n.kind.as_str() {
            "sequence" | "reactive" | "schedule" => {
                if any(NodeEnd::Failed) {
                    Some(NodeEnd::Failed)
                } else if all(NodeEnd::Succeeded) {
                    Some(NodeEnd::Succeeded)
                } else {
                    None
                }
            }
            "fallback" => {
                if any(NodeEnd::Succeeded) {
                    Some(NodeEnd::Succeeded)
                } else if all(NodeEnd::Failed) {
                    Some(NodeEnd::Failed)
                } else {
                    None
                }
            }
            "timeout" => ends
                .first()
                .copied()
                .flatten()
                .filter(|e| *e != NodeEnd::Halted),
            "retry" => match ends.first().copied().flatten() {
                Some(NodeEnd::Succeeded) => Some(NodeEnd::Succeeded),
                // the last attempt failed (the retry tells no give-up of a single attempt)
                Some(NodeEnd::Failed) => {
                    let [at, of] = n.attempt.unwrap_or([1, attempts_in(&n.detail)]);
                    (at >= of).then_some(NodeEnd::Failed)
                }
                _ => None,
            },
            "recover" => match (
                ends.first().copied().flatten(),
                ends.get(1).copied().flatten(),
            ) {
                (Some(NodeEnd::Succeeded), _) => Some(NodeEnd::Succeeded),
                // recovered or not, the node failed
                (_, Some(NodeEnd::Succeeded | NodeEnd::Failed)) => Some(NodeEnd::Failed),
                _ => None,
            },
            _ => None,
        }
    }
}

/// `3 attempts, 2.0 s apart` → 3 (`u32::MAX`, never reached, when the detail does not say).
fn attempts_in(detail: &str) -> u32 {
    detail
        .split_whitespace()
        .next()
        .and_then(|w| w.parse().ok())
        .unwrap_or(u32::MAX)
}

/// ``fallback to `wall` `` → `wall`.
fn between_backticks(text: &str) -> Option<&str> {
    let (_, rest) = text.split_once('`')?;
    rest.rsplit_once('`').map(|(inner, _)| inner)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn words_of_decisions() {
        assert_eq!(between_backticks("fallback to `wall`"), Some("wall"));
        assert_eq!(
            between_backticks("fallback to `retry(a, b)`"),
            Some("retry(a, b)")
        );
        assert_eq!(between_backticks("fallback"), None);
        assert_eq!(attempts_in("3 attempts, 2.0 s apart"), 3);
        assert_eq!(attempts_in(""), u32::MAX);
    }
}
