//! `marie up`'s node processes: started (the first listens, the others join it), waited for
//! until the registry has converged, supervised (restarted as the cluster file says),
//! stopped on the way out.

use super::plan::UpPlan;
use super::supervisor::{self, Lines, Restarted, Supervised};
use crate::cli::children::{stop_all, Line, Listening, NodeChild, NodeLaunch};
use crate::cli::join::{join, member_name};
use marie::cluster::fault::NodeProcesses;
use marie::registry::{self, Instance};
use std::collections::BTreeMap;
use std::path::Path;
use std::time::Duration;
use tokio::sync::mpsc;

/// How long a node may take to start listening, and the registry to converge.
const START_TIMEOUT: Duration = Duration::from_secs(60);

/// The node processes started, and their lines.
pub(super) struct Nodes {
    children: Vec<NodeChild>,
    /// Every node's stdout, a line at a time; ends when every node has exited.
    pub(super) lines: mpsc::UnboundedReceiver<Line>,
    /// How many modules each node hosts itself, as it said when it listened.
    hosted: BTreeMap<String, usize>,
    /// The sender the children hold, for children started again; taken by the supervisor.
    raw_tx: Option<mpsc::UnboundedSender<Line>>,
    /// Once the cluster is up: the task that restarts nodes (it holds the children).
    supervised: Option<Supervised>,
}

impl Nodes {
    /// Start a node process for each of `launches`: the first listens; once its address is
    /// known, everyone joins it and marie's dialer meshes the rest. A node that does not
    /// start fails the start (the result); the nodes started are given back all the same,
    /// to be stopped.
    pub(super) async fn start(
        exe: &Path,
        launches: &mut [NodeLaunch],
    ) -> (Nodes, anyhow::Result<()>) {
        let (tx, lines) = mpsc::unbounded_channel();
        let mut nodes = Nodes {
            children: Vec::new(),
            lines,
            hosted: BTreeMap::new(),
            raw_tx: Some(tx.clone()),
            supervised: None,
        };
        let mut started = nodes.start_some(exe, &mut launches[..1], &tx).await;
        if started.is_ok() {
            let first = launches[0].listen;
            for l in launches.iter_mut().skip(1) {
                l.peers = vec![first];
            }
            started = nodes.start_some(exe, &mut launches[1..], &tx).await;
        }
        (nodes, started)
    }

    /// Start a node process for each of `launches` and wait until every one printed that it
    /// listens; their addresses become the ones they bound, their module counts are kept.
    /// A node that exits first fails the start.
    async fn start_some(
        &mut self,
        exe: &Path,
        launches: &mut [NodeLaunch],
        tx: &mpsc::UnboundedSender<Line>,
    ) -> anyhow::Result<()> {
        for l in launches.iter() {
            let child = NodeChild::start(exe, l, tx.clone())
                .map_err(|e| anyhow::anyhow!("cannot start node `{}`: {e}", l.name))?;
            self.children.push(child);
        }
        let mut hosted = BTreeMap::new();
        let lines = &mut self.lines;
        let wait = async {
            while hosted.len() < launches.len() {
                match lines.recv().await {
                    Some(Line {
                        node,
                        text: Some(text),
                    }) => {
                        let Some(listening) = Listening::parse(&text) else {
                            continue;
                        };
                        if let Some(l) = launches.iter_mut().find(|l| l.name == node) {
                            l.listen = listening.addr;
                            hosted.insert(node, listening.modules);
                        }
                    }
                    Some(Line { node, text: None }) => {
                        anyhow::bail!("node `{node}` exited while starting (its errors are above)")
                    }
                    // never: `self.raw_tx` holds a sender
                    None => anyhow::bail!("every node exited while starting"),
                }
            }
            Ok(())
        };
        match tokio::time::timeout(START_TIMEOUT, wait).await {
            Ok(r) => r?,
            Err(_) => anyhow::bail!(
                "only {} of {} nodes listened within {START_TIMEOUT:?}",
                hosted.len(),
                launches.len()
            ),
        }
        self.hosted.extend(hosted);
        Ok(())
    }

    /// How many modules the nodes host, all told.
    pub(super) fn modules(&self) -> usize {
        self.hosted.values().sum()
    }

    /// The nodes' process ids, in the order they were started.
    pub(super) fn pids(&self) -> impl Iterator<Item = u32> + '_ {
        self.children.iter().map(NodeChild::pid)
    }

    /// What the page and the faults may stop, freeze or cut apart: the nodes' processes,
    /// by name, and their private network if they run in one.
    pub(super) fn processes(&self, launches: &[NodeLaunch]) -> NodeProcesses {
        let processes = NodeProcesses::new(
            launches
                .iter()
                .zip(self.pids())
                .map(|(l, pid)| (l.name.clone(), pid)),
        );
        match crate::cli::netns::PrivateNet::current() {
            Some(network) => processes.with_network(network),
            None => processes,
        }
    }

    /// From now on, restart a node whose process ends as the cluster file says; `lines`
    /// gives what the supervisor passes on (it ends when every node is down for good);
    /// `restarted`, if given, hears of every node started again once it listens.
    pub(super) fn supervise(
        &mut self,
        plan: &UpPlan,
        processes: NodeProcesses,
        restarted: Option<mpsc::UnboundedSender<Restarted>>,
    ) {
        let Some(raw_tx) = self.raw_tx.take() else {
            return;
        };
        let (out, lines) = mpsc::unbounded_channel();
        let raw = std::mem::replace(&mut self.lines, lines);
        let restarts: Vec<_> = plan.layout.nodes.iter().map(|n| n.restart).collect();
        self.supervised = Some(supervisor::supervise(
            plan.exe.clone(),
            std::mem::take(&mut self.children),
            &plan.launches,
            &restarts,
            Lines {
                raw,
                raw_tx,
                out,
                restarted,
            },
            processes,
        ));
    }

    /// Stop every node (first the restarts), say how each that did not exit cleanly ended,
    /// and that the cluster stopped.
    pub(super) async fn stop(mut self) -> anyhow::Result<()> {
        // the children's lines are read until they have stopped (see `Stopped`)
        let mut _raw = None;
        if let Some(supervised) = self.supervised.take() {
            (self.children, _raw) = supervised.stop().await;
        }
        let mut children = self.children;
        let stopped = tokio::task::spawn_blocking(move || stop_all(&mut children)).await?;
        for (name, exit) in stopped {
            if !exit.is_normal() {
                println!("node {name} {exit}");
            }
        }
        println!("cluster stopped");
        Ok(())
    }
}

/// Join the cluster as a member of its own until its registry lists `total` modules of the
/// nodes (the registry has converged); gives that listing.
pub(super) async fn converged(plan: &UpPlan, total: usize) -> anyhow::Result<Vec<Instance>> {
    let me = member_name("up");
    let transport = join(&me, &plan.first_node()).await?;
    // watching before the first listing: no change between the two goes unseen
    let mut watch = registry::watch(None).await?;
    let wait = async {
        loop {
            let list: Vec<Instance> = registry::list()
                .into_iter()
                .filter(|i| i.node != me)
                .collect();
            if list.len() >= total {
                return Some(list);
            }
            watch.next().await?;
            // a node's modules arrive in a burst: list again once per burst, not per module
            while watch.try_next().is_some() {}
        }
    };
    let result = tokio::time::timeout(START_TIMEOUT, wait).await;
    transport.stop().await;
    result.ok().flatten().ok_or_else(|| {
        anyhow::anyhow!(
            "the registry did not converge within {START_TIMEOUT:?}: {} of {total} modules seen",
            registry::list().len()
        )
    })
}
