//! `marie up` supervises its node processes as an OTP supervisor does its children: a node
//! whose process ends is started again as its restart settings say (the cluster file's
//! `restart`, `max_restarts`, `restart_period`, `backoff`, `max_backoff`; see
//! [`marie::cluster::layout::NodeRestart`]) — at the address it listened on, joining every
//! other node, on its own data directory, so it recovers its journals and rejoins under its
//! name as a new process. Its peers tell it back (`node_back`); its datamanager replicas
//! catch up from their leaders.
//!
//! One task owns the children: it forwards their lines, reaps the one whose output ended,
//! decides ([`RestartTracker`]) and starts it again after the backoff; the fault injector's
//! table of processes follows every pid it gives up and every new one.

use crate::cli::children::{Line, Listening, NodeChild, NodeLaunch};
use marie::cluster::fault::NodeProcesses;
use marie::cluster::layout::{Exit, NodeRestart, RestartTracker, Verdict};
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::{Duration, Instant};
use tokio::sync::{mpsc, oneshot};
use tokio::task::{JoinHandle, JoinSet};

/// How long a child whose output ended may take to be reaped before it is taken as one
/// that closed its output but lives on (and is killed).
const REAP_WAIT: Duration = Duration::from_secs(2);

/// The children under supervision, and the way to stop supervising.
pub(super) struct Supervised {
    stop: Option<oneshot::Sender<()>>,
    task: JoinHandle<Stopped>,
}

/// What the supervisor gives back when it stops: the children, and the receiver of their
/// lines — kept until they have stopped, since a node writing to a closed pipe dies of
/// SIGPIPE instead of stopping cleanly.
pub(super) type Stopped = (Vec<NodeChild>, Option<mpsc::UnboundedReceiver<Line>>);

impl Supervised {
    /// Stop restarting; the children, to be stopped, and their lines' receiver.
    pub(super) async fn stop(mut self) -> Stopped {
        if let Some(stop) = self.stop.take() {
            let _ = stop.send(());
        }
        self.task.await.unwrap_or_default()
    }
}

/// A node started again, as the supervisor tells whoever watches (`marie up --runs`'s
/// soak): once it listens.
#[derive(Clone, Debug)]
pub(super) struct Restarted {
    /// The node.
    pub(super) node: String,
    /// When it listened again.
    pub(super) at: Instant,
    /// How long after its process had ended.
    pub(super) after: Duration,
}

/// A node under supervision.
struct Supervisee {
    launch: NodeLaunch,
    child: Option<NodeChild>,
    restarts: RestartTracker,
    /// When its last process ended (for "back after").
    ended_at: Option<Instant>,
}

/// What the supervising task holds.
struct Supervisor {
    exe: PathBuf,
    nodes: BTreeMap<String, Supervisee>,
    processes: NodeProcesses,
    /// The children's lines go here (a clone for each new child).
    raw_tx: mpsc::UnboundedSender<Line>,
    out: mpsc::UnboundedSender<Line>,
    due: JoinSet<String>,
    /// Told of every node started again, once it listens.
    restarted: Option<mpsc::UnboundedSender<Restarted>>,
}

/// The children's lines, as the supervisor hears them and as it passes them on.
pub(super) struct Lines {
    /// The children's own (every child holds a clone of `raw_tx`).
    pub(super) raw: mpsc::UnboundedReceiver<Line>,
    /// For the children started again.
    pub(super) raw_tx: mpsc::UnboundedSender<Line>,
    /// Every node's lines, and its end (`text: None`); closes when every node is down and
    /// none will be restarted.
    pub(super) out: mpsc::UnboundedSender<Line>,
    /// Told of every node started again, once it listens (`None`: nobody asks).
    pub(super) restarted: Option<mpsc::UnboundedSender<Restarted>>,
}

/// Supervise `children`, started from `launches` (at the addresses they bound), restarting
/// each as `restarts` says; `processes` is kept up to date.
pub(super) fn supervise(
    exe: PathBuf,
    children: Vec<NodeChild>,
    launches: &[NodeLaunch],
    restarts: &[NodeRestart],
    lines: Lines,
    processes: NodeProcesses,
) -> Supervised {
    let Lines {
        raw,
        raw_tx,
        out,
        restarted,
    } = lines;
    let mut children: BTreeMap<String, NodeChild> =
        children.into_iter().map(|c| (c.name.clone(), c)).collect();
    let nodes = launches
        .iter()
        .zip(restarts)
        .map(|(l, r)| {
            let supervisee = Supervisee {
                launch: l.clone(),
                child: children.remove(&l.name),
                restarts: RestartTracker::new(*r),
                ended_at: None,
            };
            (l.name.clone(), supervisee)
        })
        .collect();
    let supervisor = Supervisor {
        exe,
        nodes,
        processes,
        raw_tx,
        out,
        due: JoinSet::new(),
        restarted,
    };
    let (stop, stopped) = oneshot::channel();
    let task = tokio::spawn(supervisor.run(raw, stopped));
    Supervised {
        stop: Some(stop),
        task,
    }
}

impl Supervisor {
    /// Forward lines, reap and restart, until told to stop or every node is down for good;
    /// the children left.
    async fn run(
        mut self,
        mut raw: mpsc::UnboundedReceiver<Line>,
        mut stopped: oneshot::Receiver<()>,
    ) -> Stopped {
        loop {
            tokio::select! {
                _ = &mut stopped => break,
                line = raw.recv() => match line {
                    Some(line) => self.heard(line).await,
                    None => break,
                },
                Some(Ok(node)) = self.due.join_next(), if !self.due.is_empty() => {
                    self.restart(&node)
                }
            }
            if self.all_down_for_good() {
                // `out` is dropped with `self`: the lines end
                break;
            }
        }
        self.due.abort_all();
        let children = self.nodes.into_values().filter_map(|n| n.child).collect();
        (children, Some(raw))
    }

    /// A line of a child: forwarded; its end reaps the child and decides its restart.
    async fn heard(&mut self, line: Line) {
        let node = line.node.clone();
        let ended = line.text.is_none();
        if let Some(text) = &line.text {
            self.back(&node, text);
        }
        let _ = self.out.send(line);
        if ended {
            self.ended(&node).await;
        }
    }

    /// A restarted node said it listens: say it is back.
    fn back(&mut self, node: &str, text: &str) {
        let Some(n) = self.nodes.get_mut(node) else {
            return;
        };
        let (Some(at), Some(listening)) = (n.ended_at, Listening::parse(text)) else {
            return;
        };
        n.ended_at = None;
        let pid = n.child.as_ref().map(NodeChild::pid).unwrap_or(0);
        let after = at.elapsed();
        println!(
            "node {node} restarted: listening on {} (pid {pid}), {:.2} s after its process \
             ended",
            listening.addr,
            after.as_secs_f64()
        );
        if let Some(tell) = &self.restarted {
            let _ = tell.send(Restarted {
                node: node.to_string(),
                at: Instant::now(),
                after,
            });
        }
    }

    /// `node`'s output ended: reap it, take it out of the fault table, restart it or not.
    async fn ended(&mut self, node: &str) {
        let Some(n) = self.nodes.get_mut(node) else {
            return;
        };
        let Some(child) = n.child.take() else {
            return;
        };
        self.processes.ended(node);
        let exit = reap(child).await;
        self.decide(node, exit);
    }

    /// `node`'s process ended (`exit`): restart it after the backoff, or say why not.
    fn decide(&mut self, node: &str, exit: Exit) {
        let Some(n) = self.nodes.get_mut(node) else {
            return;
        };
        n.ended_at = Some(Instant::now());
        let policy = n.restarts.settings().policy.word();
        match n.restarts.ended(exit, Instant::now()) {
            Verdict::Restart { after, nth } => {
                let max = n.restarts.settings().max_restarts;
                let period = n.restarts.settings().period.as_secs_f64();
                println!(
                    "node {node} {exit}: restarting it in {:.2} s (restart {nth} of at most \
                     {max} within {period} s)",
                    after.as_secs_f64()
                );
                let node = node.to_string();
                self.due.spawn(async move {
                    tokio::time::sleep(after).await;
                    node
                });
            }
            Verdict::StaysDown => {
                println!("node {node} {exit}: it stays down (restart = \"{policy}\")")
            }
            Verdict::GiveUp {
                max_restarts,
                period,
            } => println!(
                "node {node} {exit}: given up — more than {max_restarts} restarts within {} \
                 s; it stays down",
                period.as_secs_f64()
            ),
        }
    }

    /// Start `node` again: where it listened, joining every other node (any of them may be
    /// the one the cluster was first joined at, and that one may be this one).
    fn restart(&mut self, node: &str) {
        let peers: Vec<_> = self
            .nodes
            .values()
            .filter(|n| n.launch.name != node)
            .map(|n| n.launch.listen)
            .collect();
        let Some(n) = self.nodes.get_mut(node) else {
            return;
        };
        let mut launch = n.launch.clone();
        launch.peers = peers;
        match NodeChild::start(&self.exe, &launch, self.raw_tx.clone()) {
            Ok(child) => {
                self.processes.started(node, child.pid());
                n.child = Some(child);
            }
            Err(e) => {
                println!("node {node}: cannot start it again: {e}");
                // counted as an end (127: as a shell says a command it cannot run): the
                // intensity gives it up in the end
                self.decide(node, Exit::Code(127));
            }
        }
    }

    /// Whether no node runs and none is due to start again.
    fn all_down_for_good(&self) -> bool {
        self.due.is_empty() && self.nodes.values().all(|n| n.child.is_none())
    }
}

/// Reap a child whose output ended (on a blocking thread: the wait polls); one that lives
/// on after [`REAP_WAIT`] is killed.
async fn reap(mut child: NodeChild) -> Exit {
    let deadline = std::time::Instant::now() + REAP_WAIT;
    tokio::task::spawn_blocking(move || child.wait_until(deadline))
        .await
        .unwrap_or(Exit::Signal(libc::SIGKILL))
}
