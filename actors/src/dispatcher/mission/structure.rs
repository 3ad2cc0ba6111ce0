//! Stage 1's checks of how actions and groups name each other — a group's `children`, an
//! item's `on_failure` — once every name is resolved: an item is the child of one group at
//! most, no group contains itself, no recovery leads back to what it recovers, and the tree
//! they make stays of a size a mission can mean.
//!
//! The items and the names between them form a graph (an edge from a group to each child,
//! from an item to its recovery); the mission's tree is that graph unfolded from the
//! top-level items, so a loop in it would be an infinite tree. Every walk here is iterative:
//! nothing recurses on the file's nesting before the nesting is known to be bounded.

use super::parsed::{FlagRef, GroupKind, Item, ParsedControl};
use super::ParsedMission;
use marie_vocabulary::diagnostic::toml::{quote, Reader};
use marie_vocabulary::diagnostic::{Diagnostic, Pos};
use std::collections::BTreeSet;

/// How deeply groups and recoveries may nest (an item in a group in a group ... counts one
/// level each): far beyond what a mission means, and shallow enough for every walk of the
/// tree to recurse safely.
pub(crate) const MAX_NESTING: usize = 32;

/// How many nodes a mission's tree may have. A recovery is copied wherever it may run, so a
/// small file can unfold into a large tree.
pub(crate) const MAX_NODES: u64 = 10_000;

/// A name from one item to another: a child of a group, or a recovery.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Edge {
    /// The item named.
    pub(crate) to: Item,
    /// Where it is named.
    pub(crate) at: Pos,
    /// True for `on_failure`, false for a child.
    pub(crate) recovery: bool,
}

impl ParsedMission {
    /// The item's name.
    pub(crate) fn item_name(&self, item: Item) -> &str {
        match item {
            Item::Action(i) => self.actions.get(i).map_or("", |a| a.name.as_str()),
            Item::Group(i) => self.groups.get(i).map_or("", |g| g.name.as_str()),
        }
    }

    /// The item for a message: `` action `a` ``, `` group `g` ``.
    pub(crate) fn describe(&self, item: Item) -> String {
        let kind = match item {
            Item::Action(_) => "action",
            Item::Group(_) => "group",
        };
        format!("{kind} {}", quote(self.item_name(item)))
    }

    /// Where the item's name is written.
    pub(crate) fn item_at(&self, item: Item) -> Pos {
        match item {
            Item::Action(i) => self.actions.get(i).map(|a| a.at),
            Item::Group(i) => self.groups.get(i).map(|g| g.at),
        }
        .unwrap_or_default()
    }

    /// The item's `when` flags.
    pub(crate) fn item_when(&self, item: Item) -> &[FlagRef] {
        match item {
            Item::Action(i) => self.actions.get(i).map(|a| a.when.as_slice()),
            Item::Group(i) => self.groups.get(i).map(|g| g.when.as_slice()),
        }
        .unwrap_or_default()
    }

    /// The item's control keys.
    pub(crate) fn item_control(&self, item: Item) -> Option<&ParsedControl> {
        match item {
            Item::Action(i) => self.actions.get(i).map(|a| &a.control),
            Item::Group(i) => self.groups.get(i).map(|g| &g.control),
        }
    }

    /// The items `item` names: its children (a group's), then its recovery.
    pub(crate) fn edges(&self, item: Item) -> Vec<Edge> {
        let mut out = Vec::new();
        if let Item::Group(g) = item {
            if let Some(g) = self.groups.get(g) {
                out.extend(g.children.iter().map(|c| Edge {
                    to: c.item,
                    at: c.at,
                    recovery: false,
                }));
            }
        }
        if let Some(r) = self.item_control(item).and_then(|c| c.on_failure) {
            out.push(Edge {
                to: r.item,
                at: r.at,
                recovery: true,
            });
        }
        out
    }

    /// The top-level items, in file order: those neither a child of a group nor any item's
    /// recovery — the children of the tree's root schedule.
    pub(crate) fn roots(&self) -> Vec<Item> {
        let named: BTreeSet<Item> = self
            .items
            .iter()
            .flat_map(|i| self.edges(*i))
            .map(|e| e.to)
            .collect();
        self.items
            .iter()
            .copied()
            .filter(|i| !named.contains(i))
            .collect()
    }

    /// The actions (by index) the tree of `item` may run: itself or its descendants, and
    /// their recoveries.
    pub(crate) fn reach(&self, item: Item) -> BTreeSet<usize> {
        let mut seen = BTreeSet::from([item]);
        let mut todo = vec![item];
        while let Some(i) = todo.pop() {
            for e in self.edges(i) {
                if seen.insert(e.to) {
                    todo.push(e.to);
                }
            }
        }
        seen.into_iter()
            .filter_map(|i| match i {
                Item::Action(a) => Some(a),
                Item::Group(_) => None,
            })
            .collect()
    }

    /// True when the file has groups or control keys: its tree is more than the thesis'
    /// schedule.
    pub fn has_control(&self) -> bool {
        !self.groups.is_empty() || self.actions.iter().any(|a| !a.control.is_empty())
    }

    /// The item's index among all items (actions first).
    fn slot(&self, item: Item) -> usize {
        match item {
            Item::Action(i) => i,
            Item::Group(i) => self.actions.len() + i,
        }
    }
}

/// The checks of this module, on a mission whose names all resolved.
pub(crate) fn check(ctx: &mut Reader<'_>, m: &ParsedMission) {
    one_parent(ctx, m);
    if !no_loops(ctx, m) {
        return;
    }
    measure(ctx, m);
}

fn push(ctx: &mut Reader<'_>, at: Pos, message: String) {
    let d = Diagnostic::at(ctx.file(), at, message);
    ctx.push(d);
}

/// An item is the child of one group at most, and named once among its children.
fn one_parent(ctx: &mut Reader<'_>, m: &ParsedMission) {
    // by slot: the group it is a child of and where that names it
    let mut parent: Vec<Option<(usize, Pos)>> = vec![None; m.actions.len() + m.groups.len()];
    for item in &m.items {
        let Item::Group(g) = *item else { continue };
        for c in &m.groups[g].children {
            if c.item == *item {
                continue; // a group in itself: a loop, reported as one
            }
            let slot = m.slot(c.item);
            match parent[slot] {
                Some((p, first)) if p == g => push(
                    ctx,
                    c.at,
                    format!(
                        "{} is named twice among the children of group {} (first at {first})",
                        m.describe(c.item),
                        quote(&m.groups[g].name)
                    ),
                ),
                Some((p, first)) => push(
                    ctx,
                    c.at,
                    format!(
                        "{} is already a child of group {} (named at {first}): an action or group is the child of one group at most",
                        m.describe(c.item),
                        quote(&m.groups[p].name)
                    ),
                ),
                None => parent[slot] = Some((g, c.at)),
            }
        }
    }
}

/// No group contains itself and no recovery leads back to what it recovers: every loop of
/// names is reported. True when there is none.
fn no_loops(ctx: &mut Reader<'_>, m: &ParsedMission) -> bool {
    const NEW: u8 = 0;
    const ON_PATH: u8 = 1;
    const DONE: u8 = 2;
    let mut state = vec![NEW; m.actions.len() + m.groups.len()];
    let mut none = true;
    for &start in &m.items {
        if state[m.slot(start)] != NEW {
            continue;
        }
        state[m.slot(start)] = ON_PATH;
        // the path from `start`: each item, its edges, the next edge to follow; and the
        // edge taken from each item of the path to the next
        let mut path: Vec<(Item, Vec<Edge>, usize)> = vec![(start, m.edges(start), 0)];
        let mut taken: Vec<Edge> = Vec::new();
        while let Some((item, edges, next)) = path.last_mut() {
            let Some(e) = edges.get(*next).copied() else {
                state[m.slot(*item)] = DONE;
                path.pop();
                taken.pop();
                continue;
            };
            *next += 1;
            match state[m.slot(e.to)] {
                NEW => {
                    state[m.slot(e.to)] = ON_PATH;
                    taken.push(e);
                    path.push((e.to, m.edges(e.to), 0));
                }
                ON_PATH => {
                    // a loop: from where `e.to` is on the path, round to it again
                    if let Some(k) = path.iter().position(|(i, _, _)| *i == e.to) {
                        let items: Vec<Item> = path[k..].iter().map(|(i, _, _)| *i).collect();
                        let mut edges = taken[k..].to_vec();
                        edges.push(e);
                        report_loop(ctx, m, &items, &edges);
                        none = false;
                    }
                }
                _ => {}
            }
        }
    }
    none
}

/// A loop: `edges[i]` leads from `items[i]` to the next item (the last back to the first).
fn report_loop(ctx: &mut Reader<'_>, m: &ParsedMission, items: &[Item], edges: &[Edge]) {
    let name = |i: Item| quote(m.item_name(i));
    let Some(r) = edges.iter().position(|e| e.recovery) else {
        let first = items[0];
        let at = edges[edges.len() - 1].at;
        let msg = if items.len() == 1 {
            format!(
                "group {} names itself among its children (a group cannot contain itself)",
                name(first)
            )
        } else {
            let chain: Vec<String> = edges
                .iter()
                .zip(items)
                .map(|(e, from)| format!("{} contains {}", name(*from), name(e.to)))
                .collect();
            format!(
                "group {} contains itself: {} (a group cannot contain itself)",
                name(first),
                chain.join(", ")
            )
        };
        push(ctx, at, msg);
        return;
    };
    // from the first recovery on
    let n = items.len();
    let from = items[r];
    let msg = if n == 1 {
        format!(
            "{} names itself in `on_failure` (a recovery cannot be what it recovers)",
            m.describe(from)
        )
    } else {
        let chain: Vec<String> = (0..n)
            .map(|k| (items[(r + k) % n], edges[(r + k) % n]))
            .map(|(i, e)| {
                if e.recovery {
                    format!("{} recovers with {}", name(i), name(e.to))
                } else {
                    format!("{} contains {}", name(i), name(e.to))
                }
            })
            .collect();
        format!(
            "the recovery of {} leads back to it: {} (a recovery cannot contain what it recovers)",
            m.describe(from),
            chain.join(", ")
        )
    };
    push(ctx, edges[r].at, msg);
}

/// The tree the names make is at most [`MAX_NESTING`] deep and [`MAX_NODES`] large. Only on
/// a mission without loops.
fn measure(ctx: &mut Reader<'_>, m: &ParsedMission) {
    let n = m.actions.len() + m.groups.len();
    // by slot: the nodes of the item's tree without its `when` guard, and its nesting
    let mut size = vec![0u64; n];
    let mut depth = vec![0usize; n];
    let guard = |i: Item| if m.item_when(i).is_empty() { 0 } else { 2 };
    for item in post_order(m) {
        let Some(c) = m.item_control(item) else {
            continue;
        };
        let reactive_group = matches!(item, Item::Group(g)
            if m.groups[g].kind == GroupKind::Reactive);
        let wrappers = u64::from(!reactive_group && c.reactive())
            + u64::from(c.timeout.is_some())
            + u64::from(c.on_failure.is_some())
            + u64::from(c.retry.is_some());
        let mut s = 1 + wrappers;
        let mut d = 0;
        for e in m.edges(item) {
            s = s.saturating_add(size[m.slot(e.to)].saturating_add(guard(e.to)));
            d = d.max(depth[m.slot(e.to)]);
        }
        size[m.slot(item)] = s;
        depth[m.slot(item)] = d + 1;
    }
    if let Some(deep) = m.items.iter().find(|i| depth[m.slot(**i)] > MAX_NESTING) {
        push(
            ctx,
            m.item_at(*deep),
            format!(
                "{} nests groups and recoveries {} levels deep (at most {MAX_NESTING})",
                m.describe(*deep),
                depth[m.slot(*deep)]
            ),
        );
        return;
    }
    let roots = m.roots();
    let total = roots
        .iter()
        .fold(1u64, |t, r| t.saturating_add(size[m.slot(*r)]));
    if total > MAX_NODES {
        if let Some(big) = roots.iter().max_by_key(|r| size[m.slot(**r)]) {
            push(
                ctx,
                m.item_at(*big),
                format!(
                    "the mission's behaviour tree would have {total} nodes (at most {MAX_NODES}); {} alone makes {}: a recovery is copied wherever it may run",
                    m.describe(*big),
                    size[m.slot(*big)]
                ),
            );
        }
    }
}

/// Every item after the items it names (a mission without loops).
fn post_order(m: &ParsedMission) -> Vec<Item> {
    let mut seen = vec![false; m.actions.len() + m.groups.len()];
    let mut out = Vec::new();
    for &start in &m.items {
        if seen[m.slot(start)] {
            continue;
        }
        seen[m.slot(start)] = true;
        let mut stack: Vec<(Item, Vec<Edge>, usize)> = vec![(start, m.edges(start), 0)];
        while let Some((item, edges, next)) = stack.last_mut() {
            match edges.get(*next).copied() {
                Some(e) => {
                    *next += 1;
                    if !seen[m.slot(e.to)] {
                        seen[m.slot(e.to)] = true;
                        stack.push((e.to, m.edges(e.to), 0));
                    }
                }
                None => {
                    out.push(*item);
                    stack.pop();
                }
            }
        }
    }
    out
}
