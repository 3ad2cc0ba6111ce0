//! A mission's behaviour tree as its run announces it ([`EventKind::ControlPlan`]): each
//! node with its parent, kind, label and settings in words — what a monitor draws.
//!
//! [`EventKind::ControlPlan`]: marie_vocabulary::events::EventKind::ControlPlan

use super::mission::Mission;
use super::tree::{Node, Tree};
use marie_vocabulary::events::PlanItem;
use marie_vocabulary::status::StatusFlags;

/// The nodes of `mission`'s tree in preorder, the root first.
pub fn control_plan(mission: &Mission) -> Vec<PlanItem> {
    let tree = Tree::new(mission.control.root.clone());
    let nodes = tree.preorder();
    let mut parents = vec![None; nodes.len()];
    for id in 0..nodes.len() {
        for kid in tree.child_ids(id) {
            parents[kid] = Some(id);
        }
    }
    let flags = |mask: u32| mission.flags_to_names(StatusFlags(mask)).join(", ");
    nodes
        .iter()
        .enumerate()
        .map(|(id, node)| {
            let (kind, detail) = match node {
                Node::Action(i) => (
                    "action",
                    mission
                        .actions
                        .get(*i)
                        .map(|a| a.ops.iter().map(|o| o.key.as_str()).collect::<Vec<_>>())
                        .unwrap_or_default()
                        .join(", "),
                ),
                Node::Condition(mask) => ("condition", format!("needs {}", flags(*mask))),
                Node::Schedule(_) => ("schedule", String::new()),
                Node::Sequence(_) => ("sequence", String::new()),
                Node::Reactive { while_, unless, .. } => {
                    let mut words = Vec::new();
                    if *while_ != 0 {
                        words.push(format!("while {}", flags(*while_)));
                    }
                    if *unless != 0 {
                        words.push(format!("unless {}", flags(*unless)));
                    }
                    ("reactive", words.join(", "))
                }
                Node::Fallback(_) => ("fallback", String::new()),
                Node::Parallel {
                    children,
                    success,
                    failure,
                } => (
                    "parallel",
                    format!(
                        "succeeds at {success} of {}, fails at {failure}",
                        children.len()
                    ),
                ),
                Node::Retry {
                    attempts, backoff, ..
                } => (
                    "retry",
                    format!("{attempts} attempts, {:.1} s apart", backoff.as_secs_f64()),
                ),
                Node::Timeout { limit, .. } => ("timeout", format!("{:.1} s", limit.as_secs_f64())),
                Node::Recover { .. } => ("recover", String::new()),
            };
            // a schedule's child waits for its flags: said on the child
            let detail = match parents[id].map(|p| nodes[p]) {
                Some(Node::Schedule(kids)) => {
                    let k = tree.child_ids(parents[id].unwrap_or(0));
                    let when = k
                        .iter()
                        .position(|c| *c == id)
                        .map_or(0, |at| kids[at].when);
                    match (when, detail.is_empty()) {
                        (0, _) => detail,
                        (w, true) => format!("when {}", flags(w)),
                        (w, false) => format!("when {}; {detail}", flags(w)),
                    }
                }
                _ => detail,
            };
            PlanItem {
                id,
                parent: parents[id],
                kind: kind.to_string(),
                label: mission.control.label(id).to_string(),
                detail,
            }
        })
        .collect()
}
