//! `marie node --config FILE`: a cluster member that hosts what FILE says, until SIGINT or
//! SIGTERM.
//!
//! It prints one line when it listens and one whenever it starts or stops seeing a peer, so
//! whoever started it (a person, `marie up`, a test) can wait for those lines.
//!
//! `--listen`, `--peer` and `--cookie` give or override the config's `[cluster]` table, and
//! `--data-dir` its `data_dir` (what `marie up` does for the nodes of a cluster file). Its
//! actors run on the cluster clock ([`ScaledClock::cluster`]): wall-clock time at `--speed`,
//! the same on every node.

use super::error::BadInput;
use super::prepare::start_node;
use marie::clock::ScaledClock;
use marie::cluster::net::ClusterConfig;
use marie::cluster::node::{Node, NodeConfig};
use marie::registry;
use marie_missions::embedded::{EmbeddedError, EmbeddedOptions};
use std::future::Future;
use std::io::Write;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;

/// Flags of `marie node`.
#[derive(clap::Args, Debug)]
pub(crate) struct NodeArgs {
    /// The node config: `[node]`, what it hosts, and `[cluster]` (listen, peers, cookie).
    #[arg(long, value_name = "FILE")]
    pub config: PathBuf,
    /// World file of the simulated robot, when the config has `[simulation]` without one.
    #[arg(long, value_name = "FILE")]
    pub world: Option<PathBuf>,
    /// Seed of the simulation's noise; default: the config's, else 1.
    #[arg(long, value_name = "N", value_parser = super::args::parse_seed, allow_hyphen_values = true)]
    pub seed: Option<u64>,
    /// Listen here (overrides the config's `listen`).
    #[arg(long, value_name = "ADDR")]
    pub listen: Option<SocketAddr>,
    /// Join the node at ADDR (repeatable; replaces the config's `peers`).
    #[arg(long = "peer", value_name = "ADDR")]
    pub peers: Vec<SocketAddr>,
    /// The cluster's cookie (overrides the config's `cookie`).
    #[arg(long, value_name = "C")]
    pub cookie: Option<String>,
    /// Keep the node's datamanager journals in DIR/dm/NAME (overrides the config's
    /// `data_dir`): its datamanagers are then `process` durable unless the config says
    /// otherwise, and a node started again on DIR finds their records. Locked while the node
    /// runs: one node per DIR. Without it or a `data_dir`, nothing is written to disk.
    #[arg(long, value_name = "DIR")]
    pub data_dir: Option<PathBuf>,
    /// The cluster's speed factor: wall-clock time times X, the same on every node.
    #[arg(long, default_value = "1", value_parser = super::args::parse_cluster_speed, allow_hyphen_values = true)]
    pub speed: f64,
    /// The cluster file: host a replica of each datamanager its `[[datamanager]]` tables
    /// declare for this node (what `marie up` gives its nodes). Only those tables are read.
    #[arg(long = "cluster", value_name = "FILE")]
    pub cluster_file: Option<PathBuf>,
    /// Stop, like on SIGTERM, when standard input closes: what `marie up` gives its
    /// children, so that none outlives it even when it is killed.
    #[arg(long)]
    pub stop_with_stdin: bool,
    /// Claim another protocol version in heartbeats (that one alone): only to see a
    /// cluster refuse it.
    #[arg(long, hide = true, value_name = "N", conflicts_with = "protocol_range")]
    pub protocol_version: Option<u16>,
    /// Claim to speak another range of protocol versions in heartbeats (`LO-HI`): only to
    /// see a cluster agree with a node of another build, or refuse it.
    #[arg(long, hide = true, value_name = "LO-HI")]
    pub protocol_range: Option<marie::wire::ProtocolRange>,
    /// Claim to be built from another commit (40 hex digits) in heartbeats and
    /// provenance: only to see a run name a node of another commit.
    #[arg(long, hide = true, value_name = "COMMIT")]
    pub claim_commit: Option<String>,
}

impl NodeArgs {
    /// The config's `[cluster]` table with the flags applied; `None` when neither gives a
    /// listen address and a cookie.
    fn cluster(&self, from_file: Option<ClusterConfig>) -> Option<ClusterConfig> {
        let mut cluster = match (from_file, self.listen, &self.cookie) {
            (Some(c), _, _) => c,
            (None, Some(listen), Some(cookie)) => ClusterConfig::new(listen, cookie.clone()),
            (None, _, _) => return None,
        };
        if let Some(listen) = self.listen {
            cluster.listen = listen;
        }
        if let Some(cookie) = &self.cookie {
            cluster.cookie = cookie.clone();
        }
        if !self.peers.is_empty() {
            cluster.peers = self.peers.clone();
        }
        if let Some(v) = self.protocol_version {
            cluster.protocol = marie::wire::ProtocolRange::single(v);
        }
        if let Some(range) = self.protocol_range {
            cluster.protocol = range;
        }
        Some(cluster)
    }
}

/// Start the node as a cluster member (the node joins through its config's cluster: one
/// road with embedders), report whom it sees, stop cleanly on a signal.
pub(crate) async fn node(args: NodeArgs) -> anyhow::Result<ExitCode> {
    // the config with the flags applied, checked before the node starts
    let (config, cluster) = args.config()?;
    let embedded = start_node(EmbeddedOptions {
        config: Some(config.with_cluster(cluster.clone())),
        world: args.world.clone(),
        seed: args.seed,
        clock: Arc::new(ScaledClock::cluster(args.speed)),
        ..EmbeddedOptions::default()
    })
    .await?;
    let node = embedded.node;
    // what the journals' replay freed goes back to the system
    super::give_back::spawn();
    // watched before the line that tells whoever waits for it that the node runs
    let stop = super::signal::shutdown_signal(args.stop_with_stdin);
    say(&listening_line(&node, &cluster, args.speed));
    // whom it sees, until a signal
    let signal = tell_until(&node, stop).await;
    let name = node.config().name.clone();
    say(&format!("node {name} stopping ({signal})"));
    // leaves the cluster, then stops its tree
    node.shutdown().await;
    say(&format!("node {name} stopped"));
    Ok(ExitCode::SUCCESS)
}

impl NodeArgs {
    /// The node config with the flags applied — `--data-dir` — and its `[cluster]` with
    /// theirs (bad input without one).
    fn config(&self) -> anyhow::Result<(NodeConfig, ClusterConfig)> {
        let mut config = NodeConfig::load(&self.config, &marie_missions::catalog())
            .map_err(EmbeddedError::Config)?;
        let Some(cluster) = self.cluster(config.cluster.take()) else {
            return Err(BadInput(format!(
                "{}: no [cluster] table: a node needs `listen`, `peers` and `cookie` to join a \
                 cluster, in the file or as --listen and --cookie (to run a mission on one \
                 process: marie run MISSION --node {0})",
                self.config.display()
            ))
            .into());
        };
        if let Some(dir) = &self.data_dir {
            config.data_dir = Some(dir.clone());
        }
        if let Some(file) = &self.cluster_file {
            let declared = marie::cluster::layout::declared_for(file, &config.name)
                .map_err(EmbeddedError::Config)?;
            for dm in declared {
                if config.datamanagers.iter().any(|own| own.name == dm.name) {
                    return Err(BadInput(format!(
                        "datamanager `{}` is declared in {} and in {}: declare it once",
                        dm.name,
                        file.display(),
                        self.config.display()
                    ))
                    .into());
                }
                config.datamanagers.push(dm);
            }
        }
        Ok((config, cluster))
    }
}

/// Whether `kind` is a change of a datamanager's replicas or of their strength (a lost
/// replica caught up, redundancy restored): told on the node's stdout, so `marie up` shows
/// it.
fn replicas_changed(kind: &marie::events::EventKind) -> bool {
    use marie::events::EventKind;
    matches!(
        kind,
        EventKind::DmReplicaAdded { .. }
            | EventKind::DmReplicaPromoted { .. }
            | EventKind::DmReplicaRemoved { .. }
            | EventKind::DmReplicaOut { .. }
            | EventKind::DmReplicaReplaced { .. }
            | EventKind::DmReplicaCaughtUp { .. }
            | EventKind::DmRedundancyRestored { .. }
    )
}

/// `node NAME listening on ADDR with N module(s) at speed X; joining PEERS`: the line
/// `marie up` and the tests wait for.
fn listening_line(node: &Node, cluster: &ClusterConfig, speed: f64) -> String {
    let Some(transport) = node.transport() else {
        unreachable!("a node whose config has a cluster has joined it")
    };
    format!(
        "node {} listening on {}{} with {} module(s) at speed {speed}; joining {}",
        node.config().name,
        transport.listen(),
        if cluster.tls.is_some() {
            " (mutual TLS)"
        } else {
            ""
        },
        hosted_modules(node),
        if cluster.peers.is_empty() {
            "nobody (others join it)".to_string()
        } else {
            cluster
                .peers
                .iter()
                .map(ToString::to_string)
                .collect::<Vec<_>>()
                .join(", ")
        }
    )
}

/// What the node hosts itself (peers' modules may be in the registry already). A
/// replicated datamanager is one module wherever its leader is elected: counted by the
/// node that prefers it (the first of its replicas), not by the node that may host it now.
fn hosted_modules(node: &Node) -> usize {
    let name = &node.config().name;
    let replicated: Vec<&str> = node
        .config()
        .datamanagers
        .iter()
        .filter(|d| !d.replicas.is_empty())
        .map(|d| d.name.as_str())
        .collect();
    let preferred = node
        .config()
        .datamanagers
        .iter()
        .filter(|d| d.replicas.first() == Some(name))
        .count();
    registry::list()
        .iter()
        .filter(|m| m.actor.get_id().is_local())
        .filter(|m| {
            !(m.kind == registry::ModuleKind::Datamanager && replicated.contains(&m.name.as_str()))
        })
        .count()
        + preferred
}

/// Say whom the node sees — the peers it sees already, then every peer seen or lost — and
/// when it restarts its operations after being frozen, until `stop`; gives the signal.
async fn tell_until(node: &Node, stop: impl Future<Output = &'static str>) -> &'static str {
    let name = &node.config().name;
    let Some(transport) = node.transport() else {
        unreachable!("a node whose config has a cluster has joined it")
    };
    tokio::pin!(stop);
    let (ready, mut net) = transport.events();
    for peer in ready {
        say(&format!(
            "node {name} sees {} at {}",
            peer.name, peer.address
        ));
    }
    // the node restarts its operations when it finds it was frozen; this tells it
    let mut reincarnations = node
        .reincarnations()
        .expect("a node in a cluster tells its reincarnations");
    // the changes of the replicas this node's leaders make, in the Teller's words
    let mut bus = node.events().subscribe();
    let mut teller = marie::events::Teller::default();
    loop {
        tokio::select! {
            signal = &mut stop => return signal,
            event = bus.recv() => if let Ok(event) = event {
                if replicas_changed(&event.kind) {
                    say(&format!("node {name}: {}", teller.tell(&event).text));
                }
            },
            event = net.recv() => if let Ok(event) = event {
                say(&format!("node {name} {event}"));
            },
            again = reincarnations.recv() => if let Ok(again) = again {
                say(&format!(
                    "node {name} restarted its {} operation instance(s) as a new incarnation",
                    again.restarted
                ));
            },
        }
    }
}

/// A line on stdout, flushed at once (stdout is a pipe when a parent waits for it).
fn say(line: &str) {
    let mut out = std::io::stdout().lock();
    let _ = writeln!(out, "{line}");
    let _ = out.flush();
}
