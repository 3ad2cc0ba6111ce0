//! `marie up CLUSTER.toml [--run MISSION]`: a cluster in one command.
//!
//! Starts the nodes a cluster file lists as `marie node` children on 127.0.0.1 (the first
//! listens, the others join it), waits until the registry has converged — a member of its
//! own sees every module each node said it hosts —, prints each node with its address and
//! modules, runs the mission if asked (`run --join` from this process) and stops every child
//! on exit, on Ctrl-C or SIGTERM. The children hold a pipe to it and stop when it closes, so
//! none outlives `marie up`, even when it is killed.
//!
//! Every node keeps its datamanagers' journals in a data directory of its own (so they are
//! `process` durable: a datamanager or node process that crashes comes back with its
//! records), unless its config names one: `--data-dir DIR`/NODE, kept after `up` exits, or
//! else a fresh directory under the system's temporary one, removed when `up` exits (one a
//! `kill -9` left, the next `up` removes) — two `marie up` of one cluster file never share one.

use super::args::{parse_cluster_speed, parse_seed, RobotArgs};
use super::children::{stop_all, Line, Listening, NodeChild, NodeLaunch};
use super::error::BadInput;
use super::join::{join, member_name, JoinArgs};
use super::netns::{NetGuard, PrivateNet};
use super::run::{MissionOver, RunArgs};
use marie::cluster::fault::{FaultSpec, NodeChaos, NodeProcesses};
use marie::cluster::layout::ClusterLayout;
use marie::cluster::node::NodeConfig;
use marie::dispatcher::mission::ParsedMission;
use marie::registry::{self, Instance};
use marie::run::FaultKind;
use marie::run::FileRole;
use std::collections::BTreeMap;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;
use tokio::sync::mpsc;

/// How long a node may take to start listening, and the registry to converge.
const START_TIMEOUT: Duration = Duration::from_secs(60);

/// Flags of `marie up`.
#[derive(clap::Args, Debug)]
pub(crate) struct UpArgs {
    /// The cluster file (`missions/clusters/thesis.toml`).
    pub cluster: PathBuf,
    /// Run this mission once the cluster has converged, from a dispatcher of its own; then
    /// stop the cluster and exit as `marie run` would.
    #[arg(long, value_name = "MISSION")]
    pub run: Option<PathBuf>,
    /// The robot's world (default: the mission's, else the cluster file's).
    #[arg(long, value_name = "FILE")]
    pub world: Option<PathBuf>,
    /// The simulation's seed (default: the cluster file's, else the node configs').
    #[arg(long, value_name = "N", value_parser = parse_seed, allow_hyphen_values = true)]
    pub seed: Option<u64>,
    /// The cluster's speed factor (default: the cluster file's, else 1).
    #[arg(long, value_parser = parse_cluster_speed, allow_hyphen_values = true)]
    pub speed: Option<f64>,
    /// With `--run`: write the run report (JSON) here.
    #[arg(long, value_name = "FILE", requires = "run")]
    pub report: Option<PathBuf>,
    /// With `--run`: write every event of the run here (JSON lines).
    #[arg(long, value_name = "FILE.jsonl", requires = "run")]
    pub events: Option<PathBuf>,
    /// With `--run`: write the run as MCAP here, for Foxglove (every node's events: the
    /// cart's node draws the scene).
    #[arg(long, value_name = "FILE.mcap", requires = "run")]
    pub mcap: Option<PathBuf>,
    /// With `--run`: draw the robot's run here (SVG).
    #[arg(long, value_name = "FILE.svg", requires = "run")]
    pub svg: Option<PathBuf>,
    /// Show the cluster live in the browser: serve the monitor's page on ADDR (default
    /// 127.0.0.1:7700), print its address. With `--run`: the mission's run (its page stays
    /// up after the run until Ctrl-C).
    #[arg(long, value_name = "ADDR", num_args = 0..=1,
          default_missing_value = marie_monitor::DEFAULT_LISTEN)]
    pub monitor: Option<SocketAddr>,
    /// With `--monitor`: let the page inject faults — kill or hang an operation, stop a
    /// node's process (`SIGKILL`), freeze it or cut it off for 5 s — and watch the cluster
    /// fail over.
    #[arg(long, requires = "monitor")]
    pub allow_faults: bool,
    /// With `--run`: inject a fault while the mission runs, as `marie run --fault` does,
    /// and the node faults only `marie up` can do: `stop-node:NODE@SECS` (`SIGKILL`),
    /// `freeze-node:NODE@SECS+SECS` (`SIGSTOP`, then `SIGCONT`), `partition:A,B|C,D@SECS+SECS`
    /// (the two groups cannot reach each other; needs root and `ip`: the nodes then run in
    /// a private network of namespaces). Repeatable; checked before the run (exit 2).
    #[arg(
        long = "fault",
        value_name = "KIND:TARGET@SECS[+SECS]",
        requires = "run"
    )]
    pub faults: Vec<FaultSpec>,
    /// With `--run`: every 8 to 16 s of mission time, stop, freeze (2 to 6 s) or cut off
    /// (2 to 6 s, where the nodes run in a private network) a random node other than the
    /// cart's, drawn by a generator seeded with SEED. A stopped node stays down.
    #[arg(long, value_name = "SEED", value_parser = parse_seed, allow_hyphen_values = true,
          requires = "run")]
    pub chaos_nodes: Option<u64>,
    /// Start the nodes in a private network of Linux namespaces (needs root and `ip`), so
    /// that they can be cut apart: by `--fault partition:…` (which makes one by itself),
    /// `--chaos-nodes` (which makes one where it can) or the page (`--allow-faults`). Only
    /// this `marie up` reaches such a cluster (its run, its page); `--join` from another
    /// shell cannot.
    #[arg(long)]
    pub private_network: bool,
    /// Keep every node's datamanager journals in DIR/NODE (a node config's own `data_dir`
    /// wins), after exit too: a later `up --data-dir DIR` finds their records. Default: a
    /// fresh directory under the system's temporary one, removed when `up` exits.
    #[arg(long, value_name = "DIR")]
    pub data_dir: Option<PathBuf>,
}

/// Where `up`'s nodes keep their data: DIR/NODE for each node whose config names no
/// `data_dir`.
#[derive(Debug)]
struct DataDirs {
    base: PathBuf,
    /// Made for this invocation (no `--data-dir`): removed on drop, once the nodes stopped.
    temporary: bool,
}

impl DataDirs {
    /// `--data-dir`, created if missing; else a new directory
    /// `marie-up-CLUSTER-PID[.N]` under [`std::env::temp_dir`] — new, never one left by an
    /// earlier process of the same pid, whose journals the nodes would read back.
    fn new(kept: Option<&Path>, cluster: &Path) -> anyhow::Result<DataDirs> {
        if let Some(dir) = kept {
            std::fs::create_dir_all(dir)
                .map_err(|e| BadInput(format!("--data-dir {}: {e}", dir.display())))?;
            return Ok(DataDirs {
                base: dir.to_path_buf(),
                temporary: false,
            });
        }
        let stem: String = cluster
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default()
            .chars()
            .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
            .collect();
        let name = format!("marie-up-{stem}-{}", std::process::id());
        let tmp = std::env::temp_dir();
        sweep_left_behind(&tmp);
        for n in 0..1000 {
            let base = match n {
                0 => tmp.join(&name),
                n => tmp.join(format!("{name}.{n}")),
            };
            match std::fs::create_dir(&base) {
                Ok(()) => {
                    return Ok(DataDirs {
                        base,
                        temporary: true,
                    })
                }
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
                Err(e) => anyhow::bail!(
                    "cannot make the nodes' data directory {}: {e} (give one with --data-dir)",
                    base.display()
                ),
            }
        }
        anyhow::bail!(
            "cannot make the nodes' data directory: {}/{name}.N all exist (give one with \
             --data-dir)",
            tmp.display()
        )
    }

    /// The data directory of `node`, unless its config names one.
    fn of(&self, node: &NodeConfig) -> Option<PathBuf> {
        match node.data_dir {
            Some(_) => None,
            None => Some(self.base.join(&node.name)),
        }
    }
}

/// Remove the temporary data directories of `marie up`s that were killed (`kill -9` leaves
/// them): `marie-up-…-PID[.N]` whose process is gone. Where a process's liveness cannot be
/// read (no `/proc`), nothing is removed.
fn sweep_left_behind(tmp: &Path) {
    if !Path::new("/proc/self").exists() {
        return;
    }
    let Ok(entries) = std::fs::read_dir(tmp) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(name) = name.to_str() else { continue };
        let Some(rest) = name.strip_prefix("marie-up-") else {
            continue;
        };
        // …-PID, or …-PID.N
        let last = rest.rsplit('-').next().unwrap_or_default();
        let Ok(pid) = last.split('.').next().unwrap_or_default().parse::<u32>() else {
            continue;
        };
        if Path::new(&format!("/proc/{pid}")).exists() {
            continue;
        }
        match std::fs::remove_dir_all(entry.path()) {
            Ok(()) => {
                tracing::debug!(dir = %entry.path().display(), "a killed marie up's data directory removed")
            }
            Err(e) => tracing::debug!(dir = %entry.path().display(), "left: {e}"),
        }
    }
}

impl Drop for DataDirs {
    fn drop(&mut self) {
        if self.temporary {
            if let Err(e) = std::fs::remove_dir_all(&self.base) {
                tracing::warn!(dir = %self.base.display(), "the nodes' data directory is left: {e}");
            }
        }
    }
}

/// Make the private network `args` need, and move this thread into it (see [`netns`]):
/// when a partition is planned or `--private-network` given — refused (exit 2) where it
/// cannot be made — and, where it can be, for `--chaos-nodes`.
///
/// [`netns`]: super::netns
pub(crate) fn private_network(args: &UpArgs) -> anyhow::Result<Option<NetGuard>> {
    let partitions = args.faults.iter().any(|f| f.kind == FaultKind::Partition);
    if !(partitions || args.private_network || args.chaos_nodes.is_some()) {
        return Ok(None);
    }
    let catalog = marie_missions::catalog();
    // a bad file is said by `up` itself, as without a network
    let Ok(layout) = ClusterLayout::load(&args.cluster, &catalog) else {
        return Ok(None);
    };
    let names: Vec<String> = layout.nodes.iter().map(|n| n.config.name.clone()).collect();
    match PrivateNet::enter(&names) {
        Ok(guard) => Ok(Some(guard)),
        Err(e) if partitions || args.private_network => Err(BadInput(format!(
            "{}: the nodes must run in a private network of namespaces, and none can be made \
             here (it needs root and `ip`): {e}",
            if partitions {
                "--fault partition"
            } else {
                "--private-network"
            }
        ))
        .into()),
        Err(e) => {
            tracing::info!("--chaos-nodes without partitions: no private network ({e})");
            Ok(None)
        }
    }
}

/// Start the cluster, wait for it, run the mission or wait for a signal, stop it.
pub(crate) async fn up(args: UpArgs) -> anyhow::Result<ExitCode> {
    let catalog = marie_missions::catalog();
    let layout =
        ClusterLayout::load(&args.cluster, &catalog).map_err(|d| BadInput(d.to_string()))?;
    // the mission is checked before any process starts; its world is the robot's
    let mission_world = match &args.run {
        Some(path) => ParsedMission::parse_file(path)
            .map_err(marie::cluster::node::NodeError::Mission)?
            .world()
            .map(PathBuf::from),
        None => None,
    };
    let world = args
        .world
        .clone()
        .or(mission_world)
        .or(layout.world.clone());
    let speed = args.speed.unwrap_or(layout.speed);
    let seed = args.seed.or(layout.seed);
    let exe = std::env::current_exe()?;
    // dropped (a temporary one removed) after `children`, whose nodes have stopped by then
    let data = DataDirs::new(args.data_dir.as_deref(), &args.cluster)?;

    let network = PrivateNet::current();
    let mut launches: Vec<NodeLaunch> = layout
        .nodes
        .iter()
        .map(|node| NodeLaunch {
            name: node.config.name.clone(),
            config: node.path.clone(),
            // port 0: the node binds a port the OS picks and prints it. A port picked here
            // and released would be free for anyone until the node binds it, and another
            // node's outgoing dial may take it first. In a private network, the node's own
            // address there
            listen: {
                let listen = node.listen.unwrap_or(SocketAddr::from(([127, 0, 0, 1], 0)));
                match network.as_ref().and_then(|n| n.ip_of(&node.config.name)) {
                    Some(ip) => SocketAddr::new(ip.into(), listen.port()),
                    None => listen,
                }
            },
            netns: network
                .as_ref()
                .and_then(|n| n.namespace_of(&node.config.name)),
            peers: Vec::new(),
            cookie: layout.cookie.clone(),
            speed,
            world: world.clone(),
            seed,
            data_dir: data.of(&node.config),
        })
        .collect();

    if launches.is_empty() {
        return Err(BadInput(format!(
            "{}: `node = []` lists no node: a cluster file lists the nodes it runs",
            args.cluster.display()
        ))
        .into());
    }
    let (tx, mut lines) = mpsc::unbounded_channel();
    let mut children = Vec::new();
    // the first listens; once its address is known, everyone joins it and marie's dialer
    // meshes the rest
    let mut hosted = BTreeMap::new();
    let mut started = start_children(&exe, &mut launches[..1], &tx, &mut children, &mut lines)
        .await
        .map(|h| hosted.extend(h));
    if started.is_ok() {
        let first = launches[0].listen;
        for l in launches.iter_mut().skip(1) {
            l.peers = vec![first];
        }
        started = start_children(&exe, &mut launches[1..], &tx, &mut children, &mut lines)
            .await
            .map(|h| hosted.extend(h));
    }
    drop(tx);
    let result = match started {
        Ok(()) => {
            serve(
                &args,
                &layout,
                &launches,
                &hosted,
                &mut children,
                &mut lines,
                speed,
            )
            .await
        }
        Err(e) => Err(e),
    };
    let stopped = tokio::task::spawn_blocking(move || stop_all(&mut children)).await?;
    for (name, code) in stopped {
        match code {
            Some(0) => {}
            Some(c) => println!("node {name} exited with code {c}"),
            None => println!("node {name} was killed"),
        }
    }
    println!("cluster stopped");
    result
}

/// Everything between starting the children and stopping them.
async fn serve(
    args: &UpArgs,
    layout: &ClusterLayout,
    launches: &[NodeLaunch],
    hosted: &BTreeMap<String, usize>,
    children: &mut [NodeChild],
    lines: &mut mpsc::UnboundedReceiver<Line>,
    speed: f64,
) -> anyhow::Result<ExitCode> {
    let listening = std::time::Instant::now();
    let total: usize = hosted.values().sum();
    let listing = converged(launches, &layout.cookie, total).await?;
    let convergence = listening.elapsed();
    // the nodes' lines so far tell of the joins just summed up
    while lines.try_recv().is_ok() {}
    println!(
        "cluster {} up: {} nodes, {total} modules, speed {speed} (registry converged {:.2} s \
         after the last node listened)",
        layout.path.display(),
        launches.len(),
        convergence.as_secs_f64()
    );
    for (l, c) in launches.iter().zip(children.iter()) {
        let modules: Vec<String> = listing
            .iter()
            .filter(|i| i.node == l.name)
            .map(|i| format!("{} {}", i.kind.label(), i.name))
            .collect();
        println!(
            "  {} at {} (pid {}): {}",
            l.name,
            l.listen,
            c.pid(),
            modules.join(", ")
        );
    }
    // what the page and the faults may stop, freeze or cut apart: the nodes' processes,
    // by name, and their private network if they run in one
    let mut processes = NodeProcesses::new(
        launches
            .iter()
            .zip(children.iter())
            .map(|(l, c)| (l.name.clone(), c.pid())),
    );
    if let Some(network) = PrivateNet::current() {
        processes = processes.with_network(network);
    }
    let Some(mission) = &args.run else {
        let watching = match args.monitor {
            Some(listen) => {
                let target = first_node(launches, &layout.cookie);
                let options = PrivateNet::monitor_options(listen);
                Some(
                    super::monitor::ClusterWatch::start(
                        &target,
                        options,
                        args.allow_faults,
                        processes,
                    )
                    .await?,
                )
            }
            None => None,
        };
        let result = wait_for_signal(lines).await;
        if let Some(w) = watching {
            w.stop().await;
        }
        return result;
    };

    // one Ctrl-C watch for up and its run, from before the run: a Ctrl-C between the
    // run's last line and its page's wait is heard by both
    let stop = super::signal::Shutdown::watch(false);
    let run = RunArgs {
        explain: false,
        json: false,
        mission: Some(mission.clone()),
        replay: None,
        read_by_up: std::iter::once((FileRole::Cluster, args.cluster.clone()))
            .chain(
                layout
                    .nodes
                    .iter()
                    .map(|n| (FileRole::Node, n.path.clone())),
            )
            .collect(),
        robot: RobotArgs {
            world: args.world.clone(),
            seed: args.seed.or(layout.seed),
            node: None,
            data_dir: None,
        },
        data_dir: None,
        report: args.report.clone(),
        events: args.events.clone(),
        mcap: args.mcap.clone(),
        svg: args.svg.clone(),
        speed: Some(speed),
        faults: args.faults.clone(),
        chaos: None,
        chaos_dms: false,
        node_chaos: args
            .chaos_nodes
            .map(|seed| Box::new(NodeChaos::new(seed, cart_nodes(layout)))),
        monitor: args.monitor,
        allow_faults: args.allow_faults,
        node_processes: processes,
        mission_over: MissionOver::heard_by(stop.clone()),
        // a node that says `dispatcher = "active"` runs the dispatcher: it can be lost
        // like any other, and its standbys take the run over
        dispatch_on: layout.dispatch_node().map(str::to_string),
        // a cluster of its own: the cart is at the world's start
        from_start: false,
        cluster: JoinArgs {
            join: Some(launches[0].listen),
            cookie: Some(layout.cookie.clone()),
            tls_cert: None,
            tls_key: None,
            tls_ca: None,
            tls_server_name: None,
        },
    };
    if let Some(node) = &run.dispatch_on {
        let standbys = layout.standby_nodes();
        println!(
            "the run is dispatched on {node}{}",
            match standbys.is_empty() {
                true => " (no standby: its loss ends the run)".to_string(),
                false => format!(", standby on {}", standbys.join(", ")),
            }
        );
    }
    let over = run.mission_over.clone();
    let run = super::run::run(run);
    tokio::pin!(run);
    tokio::select! {
        biased;
        result = &mut run => result,
        signal = stop.wait() => {
            if over.is_set() {
                // the mission is over: the run heard the same Ctrl-C (with --monitor it was
                // waiting for it to close its page) and ends with the mission's outcome
                run.await
            } else {
                println!("stopping the cluster ({signal}) before the mission ended");
                Ok(ExitCode::from(1))
            }
        }
    }
}

/// Print the nodes' lines until SIGINT or SIGTERM (success) or every node has exited
/// (failure).
async fn wait_for_signal(lines: &mut mpsc::UnboundedReceiver<Line>) -> anyhow::Result<ExitCode> {
    let stop = super::signal::shutdown_signal(false);
    tokio::pin!(stop);
    println!("Ctrl-C stops the cluster");
    loop {
        tokio::select! {
            signal = &mut stop => {
                println!("stopping the cluster ({signal})");
                return Ok(ExitCode::SUCCESS);
            }
            line = lines.recv() => match line {
                Some(Line { node, text: Some(text) }) => println!("[{node}] {text}"),
                Some(Line { node, text: None }) => println!("[{node}] exited"),
                None => {
                    println!("every node has exited");
                    return Ok(ExitCode::from(1));
                }
            },
        }
    }
}

/// Start a node process for each of `launches` and wait until every one printed that it
/// listens; their addresses become the ones they bound. Gives each node's own module count.
/// A node that exits first fails the start.
async fn start_children(
    exe: &Path,
    launches: &mut [NodeLaunch],
    tx: &mpsc::UnboundedSender<Line>,
    children: &mut Vec<NodeChild>,
    lines: &mut mpsc::UnboundedReceiver<Line>,
) -> anyhow::Result<BTreeMap<String, usize>> {
    for l in launches.iter() {
        let child = NodeChild::start(exe, l, tx.clone())
            .map_err(|e| anyhow::anyhow!("cannot start node `{}`: {e}", l.name))?;
        children.push(child);
    }
    let mut hosted = BTreeMap::new();
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
    Ok(hosted)
}

/// Join the cluster as a member of its own until its registry lists `total` modules of the
/// nodes (the registry has converged); gives that listing.
async fn converged(
    launches: &[NodeLaunch],
    cookie: &str,
    total: usize,
) -> anyhow::Result<Vec<Instance>> {
    let me = member_name("up");
    let target = first_node(launches, cookie);
    let transport = join(&me, &target).await?;
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

/// The nodes that run the cart's drivers: a node chaos spares them (their loss is the
/// robot's).
fn cart_nodes(layout: &ClusterLayout) -> Vec<String> {
    layout
        .nodes
        .iter()
        .filter(|n| n.config.simulation.as_ref().is_some_and(|s| s.drivers))
        .map(|n| n.config.name.clone())
        .collect()
}

/// How a member of `up`'s own joins the cluster: at the first node, the one the others
/// joined.
fn first_node(launches: &[NodeLaunch], cookie: &str) -> super::join::ClusterEntry {
    super::join::ClusterEntry {
        addr: launches[0].listen,
        cookie: cookie.to_string(),
        tls: None,
    }
}
