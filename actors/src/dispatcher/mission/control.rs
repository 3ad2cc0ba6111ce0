//! How a mission's actions are controlled: its behaviour tree ([`Control`]) over them.
//!
//! A mission without control keys is the thesis' mission (3.2.4.1): its root is a
//! [`Node::Schedule`] of its actions, each waiting for its `when` flags, run one at a time,
//! the first failure a full stop. The control keys (`retry`, `timeout_s`, `on_failure`,
//! `while`/`unless` on an action or a group, and `[[group]]`s) wrap actions and groups in
//! the tree's other constructs ([`crate::dispatcher::tree`]).

use super::parsed::{GroupKind, Item};
use super::{Action, ParsedMission};
use crate::dispatcher::tree::{Node, Scheduled};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// A mission's behaviour tree and a label for each of its nodes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Control {
    /// The tree's root.
    pub root: Node,
    /// By node id (preorder, the root 0): what the run's events and the monitor call it —
    /// an action's or a group's name, or a decorator's kind and what it decorates
    /// (`retry(follow-wall)`).
    pub labels: Vec<String>,
    /// Each [`Node::Recover`] of the tree (an `on_failure` of the file), in preorder.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub recoveries: Vec<Recovery>,
}

/// A recovery of the tree: what runs after what failed (`on_failure`).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Recovery {
    /// The id of its [`Node::Recover`].
    pub node: usize,
    /// The action or group whose failure it follows.
    pub of: String,
    /// The action or group it runs.
    pub recovery: String,
    /// The actions (by index) the recovery may run: itself or what it groups, and their
    /// own recoveries.
    pub actions: Vec<usize>,
}

impl Control {
    /// The thesis' control of `actions`: a schedule of them, each waiting for its flags.
    pub fn thesis(actions: &[Action]) -> Control {
        let root = Node::Schedule(
            actions
                .iter()
                .enumerate()
                .map(|(i, a)| Scheduled {
                    when: a.when.0,
                    node: Node::Action(i),
                })
                .collect(),
        );
        Control::new(root, "mission", actions, &[])
    }

    /// A control over `root`, its labels made from `actions`' names and `groups` (the
    /// label of each group node, by node id — or of any node whose made label it replaces,
    /// in the labels of the nodes above it too); `mission` labels a root schedule.
    pub fn new(
        root: Node,
        mission: &str,
        actions: &[Action],
        groups: &[(usize, String)],
    ) -> Control {
        let named: BTreeMap<usize, &str> = groups.iter().map(|(id, n)| (*id, n.as_str())).collect();
        let mut labels = Vec::new();
        label(&root, mission, actions, &named, &mut labels);
        Control {
            root,
            labels,
            recoveries: Vec::new(),
        }
    }

    /// True when the tree is the thesis' own: a schedule of bare actions.
    pub fn is_thesis(&self) -> bool {
        match &self.root {
            Node::Schedule(kids) => kids.iter().all(|k| matches!(k.node, Node::Action(_))),
            _ => false,
        }
    }

    /// The label of node `id`.
    pub fn label(&self, id: usize) -> &str {
        self.labels.get(id).map_or("?", String::as_str)
    }
}

/// Push the labels of `node`'s subtree in preorder (those `named` by id as named); `node`'s
/// own label.
fn label(
    node: &Node,
    mission: &str,
    actions: &[Action],
    named: &BTreeMap<usize, &str>,
    out: &mut Vec<String>,
) -> String {
    let at = out.len();
    out.push(String::new());
    let name = |i: usize| {
        actions
            .get(i)
            .map_or_else(|| format!("#{i}"), |a| a.name.clone())
    };
    let kids = |nodes: Vec<&Node>, out: &mut Vec<String>| -> Vec<String> {
        nodes
            .into_iter()
            .map(|n| label(n, mission, actions, named, out))
            .collect()
    };
    let text = match node {
        Node::Action(i) => name(*i),
        Node::Condition(mask) => format!("condition({mask:#x})"),
        Node::Schedule(c) => {
            kids(c.iter().map(|s| &s.node).collect(), out);
            mission.to_string()
        }
        Node::Sequence(c) => format!("sequence({})", kids(c.iter().collect(), out).join(", ")),
        Node::Fallback(c) => format!("fallback({})", kids(c.iter().collect(), out).join(", ")),
        Node::Reactive { children, .. } => {
            format!(
                "reactive({})",
                kids(children.iter().collect(), out).join(", ")
            )
        }
        Node::Parallel { children, .. } => {
            format!(
                "parallel({})",
                kids(children.iter().collect(), out).join(", ")
            )
        }
        Node::Retry { child, .. } => format!("retry({})", kids(vec![child], out)[0]),
        Node::Timeout { child, .. } => format!("timeout({})", kids(vec![child], out)[0]),
        Node::Recover { child, recovery } => {
            let k = kids(vec![child, recovery], out);
            format!("recover({}, then {})", k[0], k[1])
        }
    };
    let text = named.get(&at).map_or(text, |n| n.to_string());
    out[at] = text.clone();
    text
}

/// The control of a validated mission: the tree its control keys make over `actions`
/// (those of `pm`, in order), each top-level item scheduled by its `when` at the root.
/// Without control keys and groups, exactly [`Control::thesis`].
///
/// For an item X, innermost first: its base (the action; the group's construct over its
/// children), then a reactive sequence for its `while`/`unless` (unless X is a reactive
/// group, whose own they are), its timeout, its recovery, its retry, and — when X is not
/// at the top level — a guard for its `when`.
pub(crate) fn build(pm: &ParsedMission, actions: &[Action]) -> Control {
    let mut marks = vec![Mark::Made];
    let kids = pm
        .roots()
        .into_iter()
        .map(|item| {
            let (node, m) = tree(pm, item, false);
            marks.extend(m);
            Scheduled {
                when: bits(pm.item_when(item)),
                node,
            }
        })
        .collect();
    let named: Vec<(usize, String)> = marks
        .iter()
        .enumerate()
        .filter_map(|(id, m)| match m {
            Mark::Made => None,
            Mark::Label(l) | Mark::Recover { label: l, .. } => Some((id, l.clone())),
        })
        .collect();
    let mut control = Control::new(Node::Schedule(kids), "mission", actions, &named);
    control.recoveries = marks
        .into_iter()
        .enumerate()
        .filter_map(|(node, m)| match m {
            Mark::Recover { of, recovery, .. } => Some(Recovery {
                node,
                actions: pm.reach(recovery).into_iter().collect(),
                of: pm.item_name(of).to_string(),
                recovery: pm.item_name(recovery).to_string(),
            }),
            _ => None,
        })
        .collect();
    control
}

/// What the builder knows of a node, by id.
enum Mark {
    /// Its label is made from the tree ([`label`]).
    Made,
    /// Its label.
    Label(String),
    /// A recovery of `of` by `recovery`.
    Recover {
        label: String,
        of: Item,
        recovery: Item,
    },
}

fn bits(flags: &[super::parsed::FlagRef]) -> u32 {
    flags.iter().fold(0, |acc, f| acc | (1u32 << (f.bit & 31)))
}

/// The tree of `item` and its nodes' marks in preorder; `nested` when it is not at the top
/// level (then its `when` is a guard).
fn tree(pm: &ParsedMission, item: Item, nested: bool) -> (Node, Vec<Mark>) {
    let name = pm.item_name(item).to_string();
    let (mut node, mut marks) = match item {
        Item::Action(i) => (Node::Action(i), vec![Mark::Made]),
        Item::Group(g) => {
            let group = &pm.groups[g];
            let mut marks = vec![Mark::Label(name.clone())];
            let children: Vec<Node> = group
                .children
                .iter()
                .map(|c| {
                    let (n, m) = tree(pm, c.item, true);
                    marks.extend(m);
                    n
                })
                .collect();
            let node = match group.kind {
                GroupKind::Sequence => Node::Sequence(children),
                GroupKind::Fallback => Node::Fallback(children),
                GroupKind::Parallel => Node::Parallel {
                    children,
                    success: group.success,
                    failure: group.failure,
                },
                GroupKind::Reactive => Node::Reactive {
                    while_: bits(&group.control.while_),
                    unless: bits(&group.control.unless),
                    children,
                },
            };
            (node, marks)
        }
    };
    let Some(c) = pm.item_control(item) else {
        return (node, marks);
    };
    let wrap = |label: String, marks: Vec<Mark>| {
        let mut out = vec![Mark::Label(label)];
        out.extend(marks);
        out
    };
    let reactive_group = matches!(node, Node::Reactive { .. });
    if !reactive_group && c.reactive() {
        node = Node::Reactive {
            while_: bits(&c.while_),
            unless: bits(&c.unless),
            children: vec![node],
        };
        marks = wrap(format!("reactive({name})"), marks);
    }
    if let Some(limit) = c.timeout {
        node = Node::Timeout {
            child: Box::new(node),
            limit,
        };
        marks = wrap(format!("timeout({name})"), marks);
    }
    if let Some(r) = c.on_failure {
        let (recovery, m) = tree(pm, r.item, true);
        node = Node::Recover {
            child: Box::new(node),
            recovery: Box::new(recovery),
        };
        let mut out = vec![Mark::Recover {
            label: format!("recover({name}, then {})", pm.item_name(r.item)),
            of: item,
            recovery: r.item,
        }];
        out.extend(marks);
        out.extend(m);
        marks = out;
    }
    if let Some(retry) = c.retry {
        node = Node::Retry {
            child: Box::new(node),
            attempts: retry.attempts,
            backoff: retry.backoff,
        };
        marks = wrap(format!("retry({name})"), marks);
    }
    let when = bits(pm.item_when(item));
    if nested && when != 0 {
        node = Node::Sequence(vec![Node::Condition(when), node]);
        let mut out = vec![Mark::Label(format!("when({name})")), Mark::Made];
        out.extend(marks);
        marks = out;
    }
    (node, marks)
}
