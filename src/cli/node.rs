//! `marie node --config FILE`: a cluster member that hosts what FILE says, until SIGINT or
//! SIGTERM.
//!
//! It prints one line when it listens and one whenever it starts or stops seeing a peer, so
//! whoever started it (a person, `marie up`, a test) can wait for those lines.

use super::error::BadInput;
use super::prepare::start_node;
use marie::actors::registry;
use marie::embedded::EmbeddedOptions;
use marie::net::{Peer, Transport};
use std::collections::BTreeSet;
use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

/// Flags of `marie node`.
#[derive(clap::Args, Debug)]
pub struct NodeArgs {
    /// The node config: `[node]`, what it hosts, and `[cluster]` (listen, peers, cookie).
    #[arg(long, value_name = "FILE")]
    pub config: PathBuf,
    /// World file of the simulated robot, when the config has `[simulation]` without one.
    #[arg(long, value_name = "FILE")]
    pub world: Option<PathBuf>,
    /// Seed of the simulation's noise; default: the config's, else 1.
    #[arg(long, value_name = "N", value_parser = super::args::parse_seed, allow_hyphen_values = true)]
    pub seed: Option<u64>,
}

/// Start the node and its transport, report whom it sees, stop cleanly on a signal.
pub async fn node(args: NodeArgs) -> anyhow::Result<ExitCode> {
    let embedded = start_node(EmbeddedOptions {
        node: Some(args.config.clone()),
        world: args.world,
        seed: args.seed,
        ..EmbeddedOptions::default()
    })
    .await?;
    let node = embedded.node;
    let name = node.config().name.clone();
    let Some(cluster) = node.config().cluster.clone() else {
        node.shutdown().await;
        return Err(BadInput(format!(
            "{}: no [cluster] table: a node needs `listen`, `peers` and `cookie` to join a \
             cluster (to run a mission on one process: marie run MISSION --node {0})",
            args.config.display()
        ))
        .into());
    };
    let transport = match Transport::start(&name, &cluster).await {
        Ok(t) => t,
        Err(e) => {
            node.shutdown().await;
            return Err(e.into());
        }
    };
    let modules = registry::list().len();
    say(&format!(
        "node {name} listening on {} with {modules} module(s); joining {}",
        transport.listen(),
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
    ));
    let stop = shutdown_signal();
    tokio::pin!(stop);
    let mut seen: BTreeSet<(String, String)> = BTreeSet::new();
    let mut changes = transport.changes();
    loop {
        report_peers(&name, &transport.peers(), &mut seen);
        tokio::select! {
            signal = &mut stop => {
                say(&format!("node {name} stopping ({signal})"));
                break;
            }
            changed = changes.changed() => if changed.is_err() { break },
        }
    }
    transport.stop().await;
    node.shutdown().await;
    say(&format!("node {name} stopped"));
    Ok(ExitCode::SUCCESS)
}

/// Print the peers that appeared and those that went since `seen`.
fn report_peers(node: &str, now: &[Peer], seen: &mut BTreeSet<(String, String)>) {
    let current: BTreeSet<(String, String)> = now
        .iter()
        .map(|p| (p.name.clone(), p.address.clone()))
        .collect();
    for (peer, addr) in current.difference(seen) {
        say(&format!("node {node} sees {peer} at {addr}"));
    }
    for (peer, addr) in seen.difference(&current) {
        say(&format!("node {node} lost {peer} at {addr}"));
    }
    *seen = current;
}

/// A line on stdout, flushed at once (stdout is a pipe when a parent waits for it).
fn say(line: &str) {
    let mut out = std::io::stdout().lock();
    let _ = writeln!(out, "{line}");
    let _ = out.flush();
}

/// SIGINT or SIGTERM, by name.
async fn shutdown_signal() -> &'static str {
    use tokio::signal::unix::{signal, SignalKind};
    let mut term = match signal(SignalKind::terminate()) {
        Ok(s) => s,
        Err(e) => {
            tracing::warn!("cannot watch SIGTERM: {e}");
            let _ = tokio::signal::ctrl_c().await;
            return "SIGINT";
        }
    };
    tokio::select! {
        _ = tokio::signal::ctrl_c() => "SIGINT",
        _ = term.recv() => "SIGTERM",
    }
}
