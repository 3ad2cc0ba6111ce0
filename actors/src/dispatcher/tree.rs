//! Behaviour-tree control of a mission: what runs next, what is halted, when a retry or a
//! timeout fires — a pure state machine, with time passed in, which the dispatcher runs
//! (`running.rs`) and checkpoints ([`Tree::state`], [`Tree::restore`]).
//!
//! Why pure: the semantics of retries, fallbacks, timeouts, parallels and reactive
//! conditions are where behaviour-tree engines go wrong (a halt that takes more than one
//! tick; a reactive sequence that briefly runs two children at once). Here they are one
//! function of (tree, leaf results, flags, now), tested construct by construct; the
//! dispatcher only turns its [`Command`]s into activations and suspensions and its
//! [`Wake`]s into timers.
//!
//! A tree is [`Node`]s over the mission's actions (leaves, by index). [`Tree::tick`] walks
//! it from the root as BehaviorTree.CPP v4 does: each node answers
//! [`Status::Running`], [`Status::Succeeded`] or [`Status::Failed`]; a leaf is started the
//! first time it is ticked and answers `Running` until the dispatcher reports its end
//! ([`Tree::leaf_ended`]). Halting a node (a reactive condition that no longer holds, a
//! timeout, a parallel decided) halts every leaf running under it **within the same tick**:
//! the commands of one tick hold the halts before any start. A tick also says the control
//! decisions it took ([`Decision`]): what the run's events tell.
//!
//! | marie | BehaviorTree.CPP v4 | where marie differs |
//! |---|---|---|
//! | [`Node::Schedule`] | — | the thesis' dispatching by condition flags, at a mission's root |
//! | [`Node::Sequence`] | `Sequence` | — |
//! | [`Node::Reactive`] | `ReactiveSequence` | its conditions (`while_`, `unless`) are flags of the status word, re-checked at every tick; at most one child runs |
//! | [`Node::Fallback`] | `Fallback` | — |
//! | [`Node::Parallel`] | `Parallel` (thresholds) | — |
//! | [`Node::Retry`] | `RetryUntilSuccessful` | a backoff between attempts |
//! | [`Node::Timeout`] | `Timeout` | — |
//! | [`Node::Recover`] | (Nav2's recovery) | the recovery runs, then the node fails, so a retry above it tries again |
//!
//! ```
//! use marie_actors::dispatcher::tree::{Command, Node, Status, Tree};
//! use std::time::Duration;
//! // try action 0; if it fails, fall back to action 1
//! let mut tree = Tree::new(Node::Fallback(vec![Node::Action(0), Node::Action(1)]));
//! let t = tree.tick(0, Duration::ZERO);
//! assert_eq!((t.status, t.commands), (Status::Running, vec![Command::Start(0)]));
//! tree.leaf_ended(0, false);
//! let t = tree.tick(0, Duration::ZERO);
//! assert_eq!(t.commands, vec![Command::Start(1)]);
//! tree.leaf_ended(1, true);
//! assert_eq!(tree.tick(0, Duration::ZERO).status, Status::Succeeded);
//! ```

use serde::{Deserialize, Serialize};
use std::time::Duration;

/// A node of a mission's tree.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Node {
    /// A leaf: the mission's action of this index.
    Action(usize),
    /// A condition leaf: succeeds when every flag of the mask is set in the status word,
    /// fails otherwise (never runs).
    Condition(u32),
    /// The thesis' dispatching (3.2.4.1), a mission's root: again and again, the first
    /// child not yet done whose `when` flags the status word implies runs; succeeds once
    /// every child is done, fails when one fails or when none can run.
    Schedule(Vec<Scheduled>),
    /// The children in order; fails at the first that fails, succeeds when all did.
    Sequence(Vec<Node>),
    /// A sequence whose conditions are re-checked at every tick while a child runs: when
    /// the `while_` flags no longer all hold, or one of the `unless` flags is set, the
    /// running child is halted and the sequence fails.
    Reactive {
        /// Flags that must all be set while the sequence runs.
        while_: u32,
        /// Flags none of which may be set while the sequence runs.
        #[serde(default)]
        unless: u32,
        /// The children, in order.
        children: Vec<Node>,
    },
    /// The children in order until one succeeds; fails when all failed.
    Fallback(Vec<Node>),
    /// Every child at once: succeeds once `success` of them succeeded, fails once
    /// `failure` of them failed (the others halted then).
    Parallel {
        /// The children.
        children: Vec<Node>,
        /// How many successes make it succeed.
        success: usize,
        /// How many failures make it fail.
        failure: usize,
    },
    /// The child again after a failure, up to `attempts` in all, waiting `backoff` between.
    Retry {
        /// The child.
        child: Box<Node>,
        /// Attempts in all (at least 1).
        attempts: u32,
        /// Time between a failure and the next attempt.
        backoff: Duration,
    },
    /// The child, failed and halted when it runs longer than `limit`.
    Timeout {
        /// The child.
        child: Box<Node>,
        /// How long it may run.
        limit: Duration,
    },
    /// The child; when it fails, `recovery` runs, and then the node fails (a retry above
    /// tries again after the recovery).
    Recover {
        /// The child.
        child: Box<Node>,
        /// What runs after its failure.
        recovery: Box<Node>,
    },
}

/// A child of a [`Node::Schedule`]: it may start once the status word implies `when`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Scheduled {
    /// The flags it waits for.
    pub when: u32,
    /// The child.
    pub node: Node,
}

/// What a node answers a tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    /// Not done yet.
    Running,
    /// Done, succeeded.
    Succeeded,
    /// Done, failed.
    Failed,
}

/// What the dispatcher must do after a tick, in this order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Command {
    /// Halt action `i` (suspend its operations).
    Halt(usize),
    /// Start action `i` (activate its operations).
    Start(usize),
}

/// One tick's answer.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Tick {
    /// The root's status.
    pub status: Status,
    /// The halts, then the starts.
    pub commands: Vec<Command>,
    /// Tick again at this time at the latest (a backoff or a timeout), if anything waits.
    pub wake: Option<Wake>,
    /// The control decisions the tick took, in the order it took them.
    pub decisions: Vec<Decision>,
}

/// A control decision, for the run's events and `--explain`. Nodes are named by their id
/// (preorder, the root 0: [`Tree::preorder`]).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "decision", rename_all = "snake_case")]
pub enum Decision {
    /// A retry starts attempt `attempt` of `of` of its child (after the backoff).
    Retry {
        /// The retry node.
        node: usize,
        /// This attempt, from 2.
        attempt: u32,
        /// Attempts in all.
        of: u32,
    },
    /// A retry gave up: its child failed `of` times.
    GaveUp {
        /// The retry node.
        node: usize,
        /// Attempts in all.
        of: u32,
    },
    /// A fallback's child failed: the next one (`to`) is tried.
    Fallback {
        /// The fallback node.
        node: usize,
        /// The child tried next.
        to: usize,
    },
    /// A timeout passed: its child is halted and the node fails.
    Timeout {
        /// The timeout node.
        node: usize,
        /// Its limit, ms.
        limit_ms: u64,
    },
    /// A reactive sequence's condition no longer holds: its running child is halted.
    ConditionLost {
        /// The reactive node.
        node: usize,
    },
    /// A node's child failed: its recovery runs.
    Recovery {
        /// The recover node.
        node: usize,
    },
    /// A parallel reached a threshold: the children still running are halted.
    Decided {
        /// The parallel node.
        node: usize,
        /// Whether it succeeded.
        succeeded: bool,
    },
}

/// When the tree must be ticked again though no leaf ended.
pub type Wake = Duration;

/// A node's state between ticks.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct NodeState {
    status: Option<Status>,
    /// Composite: the child being run; Retry: attempts made; Recover: 1 once recovering.
    cursor: usize,
    /// Timeout: when the child's run ends; Retry: when the backoff ends.
    deadline: Option<Duration>,
    /// Action: started and not ended yet.
    running: bool,
}

/// A tree and its state.
#[derive(Clone, Debug)]
pub struct Tree {
    root: Node,
    /// By node id (preorder: a node's first child is its id + 1), its subtree's size.
    sizes: Vec<usize>,
    /// By node id.
    state: Vec<NodeState>,
    /// Results of leaves since the last tick, by action index.
    ended: Vec<(usize, bool)>,
}

/// Push the sizes of `node`'s subtrees in preorder; `node`'s own.
fn fill_sizes(node: &Node, sizes: &mut Vec<usize>) -> usize {
    let id = sizes.len();
    sizes.push(0);
    let size = 1 + children(node)
        .into_iter()
        .map(|c| fill_sizes(c, sizes))
        .sum::<usize>();
    sizes[id] = size;
    size
}

fn children(node: &Node) -> Vec<&Node> {
    match node {
        Node::Action(_) | Node::Condition(_) => Vec::new(),
        Node::Schedule(c) => c.iter().map(|s| &s.node).collect(),
        Node::Sequence(c) | Node::Fallback(c) => c.iter().collect(),
        Node::Reactive { children, .. } | Node::Parallel { children, .. } => {
            children.iter().collect()
        }
        Node::Retry { child, .. } | Node::Timeout { child, .. } => vec![child],
        Node::Recover { child, recovery } => vec![child, recovery],
    }
}

impl Status {
    /// Succeeded or failed.
    fn of(succeeded: bool) -> Status {
        if succeeded {
            Status::Succeeded
        } else {
            Status::Failed
        }
    }
}

/// What one tick sees and says.
struct Ctx {
    flags: u32,
    now: Duration,
    halts: Vec<Command>,
    starts: Vec<Command>,
    wake: Option<Duration>,
    decisions: Vec<Decision>,
}

impl Ctx {
    fn wake_at(&mut self, at: Duration) {
        self.wake = Some(self.wake.map_or(at, |w| w.min(at)));
    }
}

/// One tick's walk: the tree's state, borrowed apart from its nodes (which it reads).
struct Walk<'t> {
    sizes: &'t [usize],
    state: &'t mut [NodeState],
    ended: &'t [(usize, bool)],
}

impl Tree {
    /// A tree at rest: nothing started.
    pub fn new(root: Node) -> Tree {
        let mut sizes = Vec::new();
        let n = fill_sizes(&root, &mut sizes);
        Tree {
            root,
            sizes,
            state: vec![NodeState::default(); n],
            ended: Vec::new(),
        }
    }

    /// Action `action` ended: succeeded or not. Taken into account at the next tick.
    pub fn leaf_ended(&mut self, action: usize, succeeded: bool) {
        self.ended.push((action, succeeded));
    }

    /// Walk the tree with the status word `flags` at time `now`: the root's status and what
    /// to halt and start.
    pub fn tick(&mut self, flags: u32, now: Duration) -> Tick {
        let mut ctx = Ctx {
            flags,
            now,
            halts: Vec::new(),
            starts: Vec::new(),
            wake: None,
            decisions: Vec::new(),
        };
        let mut walk = Walk {
            sizes: &self.sizes,
            state: &mut self.state,
            ended: &self.ended,
        };
        let status = walk.tick_node(&self.root, 0, &mut ctx);
        self.ended.clear();
        let mut commands = ctx.halts;
        commands.extend(ctx.starts);
        Tick {
            status,
            commands,
            wake: if status == Status::Running {
                ctx.wake
            } else {
                None
            },
            decisions: ctx.decisions,
        }
    }

    /// The tree's nodes in preorder: a node's id is its position here.
    pub fn preorder(&self) -> Vec<&Node> {
        fn walk<'n>(node: &'n Node, out: &mut Vec<&'n Node>) {
            out.push(node);
            for c in children(node) {
                walk(c, out);
            }
        }
        let mut out = Vec::with_capacity(self.sizes.len());
        walk(&self.root, &mut out);
        out
    }

    /// The root.
    pub fn root(&self) -> &Node {
        &self.root
    }

    /// The ids of the children of node `id`.
    pub fn child_ids(&self, id: usize) -> Vec<usize> {
        child_ids(&self.sizes, id)
    }

    /// The state of every node, by id (for a checkpoint: [`Tree::restore`]).
    pub fn state(&self) -> Vec<NodeState> {
        self.state.clone()
    }

    /// A tree in the state `state` recorded by [`Tree::state`] of the same root; `None` when
    /// the state does not fit the tree.
    pub fn restore(root: Node, state: Vec<NodeState>) -> Option<Tree> {
        let mut tree = Tree::new(root);
        if state.len() != tree.state.len() {
            return None;
        }
        tree.state = state;
        Some(tree)
    }

    /// For each node, whether it runs now (started, not done), by id: the branch a monitor
    /// draws as running.
    pub fn running(&self) -> Vec<bool> {
        self.state
            .iter()
            .map(|s| s.status.is_none() && (s.running || s.cursor > 0 || s.deadline.is_some()))
            .collect()
    }

    /// A root [`Node::Schedule`]'s children not done yet, as (id, the flags each waits
    /// for): what a stuck mission waits for.
    pub fn waiting(&self) -> Vec<(usize, u32)> {
        let Node::Schedule(kids) = &self.root else {
            return Vec::new();
        };
        let ids = self.child_ids(0);
        kids.iter()
            .zip(ids)
            .filter(|(_, id)| self.state[*id].status.is_none())
            .map(|(k, id)| (id, k.when))
            .collect()
    }
}

/// The ids of node `id`'s children, from the subtree sizes alone: in preorder the first
/// child follows its parent, and each next one follows its elder sibling's subtree.
fn child_ids(sizes: &[usize], id: usize) -> Vec<usize> {
    let end = id + sizes[id];
    let mut ids = Vec::new();
    let mut next = id + 1;
    while next < end {
        ids.push(next);
        next += sizes[next];
    }
    ids
}

impl Walk<'_> {
    fn done(&mut self, id: usize, status: Status) -> Status {
        self.state[id].status = Some(status);
        status
    }

    // One arm per construct, a few lines each: read together they are the table of the
    // tree's semantics (as BehaviorTree.CPP documents its nodes), which is why the match is
    // kept whole rather than cut into a function per construct.
    fn tick_node(&mut self, node: &Node, id: usize, ctx: &mut Ctx) -> Status {
        if let Some(done) = self.state[id].status {
            return done;
        }
        match node {
            Node::Condition(mask) => self.done(id, Status::of(ctx.flags & mask == *mask)),
            Node::Action(i) => {
                if !self.state[id].running {
                    self.state[id].running = true;
                    ctx.starts.push(Command::Start(*i));
                    return Status::Running;
                }
                match self.ended.iter().find(|(a, _)| a == i) {
                    Some(&(_, ok)) => {
                        self.state[id].running = false;
                        self.done(id, Status::of(ok))
                    }
                    None => Status::Running,
                }
            }
            Node::Schedule(kids) => {
                let ids = child_ids(self.sizes, id);
                loop {
                    let at = match self.state[id].cursor {
                        0 => {
                            let next = kids.iter().zip(&ids).position(|(k, kid)| {
                                self.state[*kid].status.is_none() && ctx.flags & k.when == k.when
                            });
                            match next {
                                Some(k) => k,
                                None => {
                                    let all = ids.iter().all(|k| self.state[*k].status.is_some());
                                    return self.done(id, Status::of(all));
                                }
                            }
                        }
                        c => c - 1,
                    };
                    self.state[id].cursor = at + 1;
                    match self.tick_node(&kids[at].node, ids[at], ctx) {
                        Status::Running => return Status::Running,
                        Status::Failed => return self.done(id, Status::Failed),
                        Status::Succeeded => self.state[id].cursor = 0,
                    }
                }
            }
            Node::Sequence(_) | Node::Fallback(_) | Node::Reactive { .. } => {
                let ids = child_ids(self.sizes, id);
                let kids = children(node);
                if let Node::Reactive { while_, unless, .. } = node {
                    if ctx.flags & while_ != *while_ || ctx.flags & unless != 0 {
                        ctx.decisions.push(Decision::ConditionLost { node: id });
                        self.halt(node, id, ctx);
                        return self.done(id, Status::Failed);
                    }
                }
                let (go_on, stop) = match node {
                    Node::Fallback(_) => (Status::Failed, Status::Succeeded),
                    _ => (Status::Succeeded, Status::Failed),
                };
                loop {
                    let at = self.state[id].cursor;
                    if at == kids.len() {
                        return self.done(id, go_on);
                    }
                    match self.tick_node(kids[at], ids[at], ctx) {
                        Status::Running => return Status::Running,
                        s if s == stop => return self.done(id, stop),
                        _ => {
                            self.state[id].cursor += 1;
                            if matches!(node, Node::Fallback(_)) && at + 1 < kids.len() {
                                ctx.decisions.push(Decision::Fallback {
                                    node: id,
                                    to: ids[at + 1],
                                });
                            }
                        }
                    }
                }
            }
            Node::Parallel {
                children: kids,
                success,
                failure,
            } => {
                let ids = child_ids(self.sizes, id);
                let (mut ok, mut failed) = (0, 0);
                for (k, kid) in kids.iter().enumerate() {
                    match self.tick_node(kid, ids[k], ctx) {
                        Status::Succeeded => ok += 1,
                        Status::Failed => failed += 1,
                        Status::Running => {}
                    }
                }
                if ok >= *success || failed >= *failure {
                    ctx.decisions.push(Decision::Decided {
                        node: id,
                        succeeded: ok >= *success,
                    });
                    self.halt(node, id, ctx);
                    return self.done(id, Status::of(ok >= *success));
                }
                Status::Running
            }
            Node::Retry {
                child,
                attempts,
                backoff,
            } => {
                let kid = id + 1;
                loop {
                    if let Some(until) = self.state[id].deadline {
                        if ctx.now < until {
                            ctx.wake_at(until);
                            return Status::Running;
                        }
                        self.state[id].deadline = None;
                        self.reset(kid);
                        ctx.decisions.push(Decision::Retry {
                            node: id,
                            attempt: self.state[id].cursor as u32 + 1,
                            of: (*attempts).max(1),
                        });
                    }
                    match self.tick_node(child, kid, ctx) {
                        Status::Failed => {
                            self.state[id].cursor += 1;
                            if self.state[id].cursor as u32 >= (*attempts).max(1) {
                                if *attempts > 1 {
                                    ctx.decisions.push(Decision::GaveUp {
                                        node: id,
                                        of: *attempts,
                                    });
                                }
                                return self.done(id, Status::Failed);
                            }
                            self.state[id].deadline = Some(ctx.now + *backoff);
                        }
                        Status::Succeeded => return self.done(id, Status::Succeeded),
                        Status::Running => return Status::Running,
                    }
                }
            }
            Node::Timeout { child, limit } => {
                let kid = id + 1;
                let until = *self.state[id].deadline.get_or_insert(ctx.now + *limit);
                if ctx.now >= until {
                    ctx.decisions.push(Decision::Timeout {
                        node: id,
                        limit_ms: limit.as_millis() as u64,
                    });
                    self.halt(child, kid, ctx);
                    return self.done(id, Status::Failed);
                }
                match self.tick_node(child, kid, ctx) {
                    Status::Running => {
                        ctx.wake_at(until);
                        Status::Running
                    }
                    s => self.done(id, s),
                }
            }
            Node::Recover { child, recovery } => {
                let ids = child_ids(self.sizes, id);
                if self.state[id].cursor == 0 {
                    match self.tick_node(child, ids[0], ctx) {
                        Status::Failed => {
                            self.state[id].cursor = 1;
                            ctx.decisions.push(Decision::Recovery { node: id });
                        }
                        Status::Succeeded => return self.done(id, Status::Succeeded),
                        Status::Running => return Status::Running,
                    }
                }
                match self.tick_node(recovery, ids[1], ctx) {
                    Status::Running => Status::Running,
                    // recovered or not, the node failed: a retry above tries again
                    _ => self.done(id, Status::Failed),
                }
            }
        }
    }

    /// Halt every leaf running under `node` (id `id`), in this tick.
    fn halt(&mut self, node: &Node, id: usize, ctx: &mut Ctx) {
        if let Node::Action(i) = node {
            if self.state[id].running {
                self.state[id].running = false;
                ctx.halts.push(Command::Halt(*i));
            }
            return;
        }
        for (kid, kid_id) in children(node).into_iter().zip(child_ids(self.sizes, id)) {
            self.halt(kid, kid_id, ctx);
        }
    }

    /// Forget `node`'s (id `id`) state and its subtree's, for another attempt.
    fn reset(&mut self, id: usize) {
        for st in &mut self.state[id..id + self.sizes[id]] {
            *st = NodeState::default();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const T0: Duration = Duration::ZERO;

    fn secs(s: u64) -> Duration {
        Duration::from_secs(s)
    }

    /// Actions `0..n` in parallel.
    fn parallel(n: usize, success: usize, failure: usize) -> Tree {
        Tree::new(Node::Parallel {
            children: (0..n).map(Node::Action).collect(),
            success,
            failure,
        })
    }

    /// Action 0, retried.
    fn retried(attempts: u32, backoff: Duration) -> Tree {
        Tree::new(Node::Retry {
            child: Box::new(Node::Action(0)),
            attempts,
            backoff,
        })
    }

    fn starts(t: &Tick) -> Vec<usize> {
        t.commands
            .iter()
            .filter_map(|c| match c {
                Command::Start(i) => Some(*i),
                Command::Halt(_) => None,
            })
            .collect()
    }

    #[test]
    fn a_sequence_runs_its_children_in_order_and_fails_at_the_first_failure() {
        let mut tree = Tree::new(Node::Sequence(vec![
            Node::Action(0),
            Node::Action(1),
            Node::Action(2),
        ]));
        assert_eq!(starts(&tree.tick(0, T0)), [0]);
        assert_eq!(tree.tick(0, T0).commands, [], "nothing new while 0 runs");
        tree.leaf_ended(0, true);
        assert_eq!(starts(&tree.tick(0, T0)), [1]);
        tree.leaf_ended(1, false);
        let t = tree.tick(0, T0);
        assert_eq!((t.status, t.commands), (Status::Failed, vec![]));
    }

    #[test]
    fn a_fallback_tries_its_children_until_one_succeeds_and_fails_when_all_failed() {
        let mut tree = Tree::new(Node::Fallback(vec![Node::Action(0), Node::Action(1)]));
        tree.tick(0, T0);
        tree.leaf_ended(0, false);
        assert_eq!(starts(&tree.tick(0, T0)), [1]);
        tree.leaf_ended(1, false);
        assert_eq!(tree.tick(0, T0).status, Status::Failed);
    }

    #[test]
    fn a_retry_runs_its_child_again_after_the_backoff_and_gives_up_after_its_attempts() {
        let mut tree = retried(3, secs(2));
        assert_eq!(starts(&tree.tick(0, T0)), [0]);
        tree.leaf_ended(0, false);
        let t = tree.tick(0, secs(10));
        assert_eq!((t.status, t.wake), (Status::Running, Some(secs(12))));
        assert_eq!(t.commands, [], "not before the backoff");
        assert_eq!(starts(&tree.tick(0, secs(12))), [0], "attempt 2");
        tree.leaf_ended(0, false);
        tree.tick(0, secs(13));
        assert_eq!(starts(&tree.tick(0, secs(15))), [0], "attempt 3");
        tree.leaf_ended(0, false);
        assert_eq!(tree.tick(0, secs(16)).status, Status::Failed, "3 in all");
    }

    #[test]
    fn a_retry_ends_at_the_first_success() {
        let mut tree = retried(5, T0);
        tree.tick(0, T0);
        tree.leaf_ended(0, false);
        assert_eq!(starts(&tree.tick(0, T0)), [0]);
        tree.leaf_ended(0, true);
        assert_eq!(tree.tick(0, T0).status, Status::Succeeded);
    }

    #[test]
    fn a_timeout_halts_its_child_in_the_tick_it_passes_and_fails() {
        let mut tree = Tree::new(Node::Timeout {
            child: Box::new(Node::Action(4)),
            limit: secs(40),
        });
        let t = tree.tick(0, secs(1));
        assert_eq!((starts(&t), t.wake), (vec![4], Some(secs(41))));
        assert_eq!(tree.tick(0, secs(40)).status, Status::Running);
        let t = tree.tick(0, secs(41));
        assert_eq!(
            (t.status, t.commands),
            (Status::Failed, vec![Command::Halt(4)])
        );
        // its end reported after the halt changes nothing
        tree.leaf_ended(4, true);
        assert_eq!(tree.tick(0, secs(42)).status, Status::Failed);
    }

    #[test]
    fn a_reactive_sequence_halts_its_running_child_when_its_condition_no_longer_holds() {
        let mut tree = Tree::new(Node::Reactive {
            while_: 0b1,
            unless: 0,
            children: vec![Node::Action(0), Node::Action(1)],
        });
        assert_eq!(starts(&tree.tick(0b1, T0)), [0]);
        let t = tree.tick(0b0, T0);
        assert_eq!(
            (t.status, t.commands),
            (Status::Failed, vec![Command::Halt(0)])
        );
    }

    #[test]
    fn a_reactive_sequence_never_runs_two_children_at_once() {
        let mut tree = Tree::new(Node::Reactive {
            while_: 0b1,
            unless: 0,
            children: vec![Node::Action(0), Node::Action(1), Node::Action(2)],
        });
        let mut running = std::collections::BTreeSet::new();
        for (ended, flags) in [(None, 1), (Some(0), 1), (None, 1), (Some(1), 1), (None, 0)] {
            if let Some(i) = ended {
                tree.leaf_ended(i, true);
                running.remove(&i);
            }
            // within one tick the halts come before the starts: apply them in order
            for c in tree.tick(flags, T0).commands {
                match c {
                    Command::Halt(i) => assert!(running.remove(&i)),
                    Command::Start(i) => {
                        running.insert(i);
                        assert_eq!(running.len(), 1, "{running:?}");
                    }
                }
            }
        }
        assert!(running.is_empty(), "the last was halted: {running:?}");
    }

    #[test]
    fn a_parallel_succeeds_at_its_threshold_and_halts_the_others_in_that_tick() {
        let mut tree = parallel(3, 2, 2);
        assert_eq!(starts(&tree.tick(0, T0)), [0, 1, 2]);
        tree.leaf_ended(0, true);
        assert_eq!(tree.tick(0, T0).status, Status::Running);
        tree.leaf_ended(2, true);
        let t = tree.tick(0, T0);
        assert_eq!(
            (t.status, t.commands),
            (Status::Succeeded, vec![Command::Halt(1)])
        );
    }

    #[test]
    fn a_parallel_fails_at_its_failure_threshold() {
        let mut tree = parallel(2, 2, 1);
        tree.tick(0, T0);
        tree.leaf_ended(1, false);
        let t = tree.tick(0, T0);
        assert_eq!(
            (t.status, t.commands),
            (Status::Failed, vec![Command::Halt(0)])
        );
    }

    #[test]
    fn a_recovery_runs_after_a_failure_and_a_retry_above_it_tries_again() {
        // back off and turn (action 9) after a failed docking pass (action 0), 2 attempts
        let mut tree = Tree::new(Node::Retry {
            child: Box::new(Node::Recover {
                child: Box::new(Node::Action(0)),
                recovery: Box::new(Node::Action(9)),
            }),
            attempts: 2,
            backoff: T0,
        });
        assert_eq!(starts(&tree.tick(0, T0)), [0]);
        tree.leaf_ended(0, false);
        assert_eq!(starts(&tree.tick(0, T0)), [9], "the recovery");
        tree.leaf_ended(9, true);
        assert_eq!(starts(&tree.tick(0, T0)), [0], "the second attempt");
        tree.leaf_ended(0, true);
        assert_eq!(tree.tick(0, T0).status, Status::Succeeded);
    }

    #[test]
    fn the_thesis_schedule_runs_the_first_action_whose_flags_hold_and_fails_when_none_can() {
        // action 1 waits for flag 0b1, which action 0 raises; action 2 for 0b100, never
        let schedule = |when: [u32; 3]| {
            Tree::new(Node::Schedule(
                when.iter()
                    .enumerate()
                    .map(|(i, w)| Scheduled {
                        when: *w,
                        node: Node::Action(i),
                    })
                    .collect(),
            ))
        };
        let mut tree = schedule([0b1, 0, 0b100]);
        assert_eq!(
            starts(&tree.tick(0, T0)),
            [1],
            "file order yields to the flags"
        );
        tree.leaf_ended(1, true);
        assert_eq!(starts(&tree.tick(0b1, T0)), [0]);
        tree.leaf_ended(0, true);
        let t = tree.tick(0b1, T0);
        assert_eq!((t.status, t.commands), (Status::Failed, vec![]), "stuck");
        assert_eq!(
            tree.waiting(),
            [(3, 0b100)],
            "what the stuck mission waits for"
        );
        let mut tree = schedule([0, 0, 0]);
        for i in 0..3 {
            assert_eq!(starts(&tree.tick(0, T0)), [i]);
            tree.leaf_ended(i, true);
        }
        assert_eq!(tree.tick(0, T0).status, Status::Succeeded);
        let mut tree = schedule([0, 0, 0]);
        tree.tick(0, T0);
        tree.leaf_ended(0, false);
        assert_eq!(tree.tick(0, T0).status, Status::Failed, "a full stop");
    }

    #[test]
    fn a_trees_state_restored_from_a_checkpoint_carries_on_mid_retry() {
        let mut tree = retried(3, secs(2));
        tree.tick(0, T0);
        tree.leaf_ended(0, false);
        tree.tick(0, secs(1));
        // a standby restores the state: attempt 2 after the same backoff, 3 in all
        let mut standby = Tree::restore(tree.root().clone(), tree.state()).unwrap();
        assert_eq!(
            standby.tick(0, secs(2)).commands,
            [],
            "still in the backoff"
        );
        let t = standby.tick(0, secs(3));
        assert_eq!(starts(&t), [0]);
        assert_eq!(
            t.decisions,
            [Decision::Retry {
                node: 0,
                attempt: 2,
                of: 3
            }]
        );
        assert!(
            Tree::restore(Node::Action(0), tree.state()).is_none(),
            "another tree"
        );
    }

    #[test]
    fn a_condition_gates_a_sequence_by_the_status_word() {
        let mut tree = Tree::new(Node::Sequence(vec![Node::Condition(0b10), Node::Action(0)]));
        assert_eq!(tree.tick(0b01, T0).status, Status::Failed);
        let mut tree = Tree::new(Node::Sequence(vec![Node::Condition(0b10), Node::Action(0)]));
        assert_eq!(starts(&tree.tick(0b11, T0)), [0]);
    }
}
