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
//!
//! - `plan.rs` — the cluster file, the mission, the launches: checked before any process
//!   starts;
//! - `data_dirs.rs` — where the nodes keep their journals;
//! - `network.rs` — the private network of namespaces, made before the runtime;
//! - `nodes.rs` — the node processes started, converged, stopped;
//! - `supervisor.rs` — a node whose process ends restarted as the cluster file says;
//! - `serve.rs` — the listing, then the mission or the cluster served until a signal;
//! - `mission.rs` — `--run`: the mission run as `run --join` would;
//! - `soak.rs` — `--runs N`: the mission run N times, then the summary;
//! - `catch_up.rs` — under `--runs`: when each node fault's node was back and caught up;
//! - `memory.rs` — the node processes' resident memory, at the soak's start and after each run, and when it is flat;
//! - `probe.rs` — `--probe DM`: `marie dm probe` beside the runs, its verdict in the summary.

mod catch_up;
mod data_dirs;
mod memory;
mod mission;
mod network;
mod nodes;
mod plan;
mod probe;
mod serve;
mod soak;
mod supervisor;

pub(crate) use network::private_network;

use crate::cli::args::{parse_cluster_speed, parse_seed};
use marie::cluster::fault::FaultSpec;
use mission::{parse_gaps, Gaps};
use nodes::Nodes;
use plan::UpPlan;
use serve::serve;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;

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
    /// With `--monitor`: let the page add a datamanager's replica on a node and remove one
    /// (what `marie dm add-replica` and `remove-replica` do).
    #[arg(long, requires = "monitor")]
    pub allow_changes: bool,
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
    /// With `--run`: every 10 to 20 s of mission time (`--chaos-every`), stop, freeze (2 to
    /// 6 s) or cut off (2 to 6 s, where the nodes run in a private network) a random node
    /// other than the cart's, drawn by a generator seeded with SEED. A stopped node is
    /// restarted as the cluster file says (by default at once: `restart = "permanent"`).
    /// With `--runs`: one schedule for all the runs — its clock is the runs' mission time,
    /// so the faults keep coming from one run to the next.
    #[arg(long, value_name = "SEED", value_parser = parse_seed, allow_hyphen_values = true,
          requires = "run")]
    pub chaos_nodes: Option<u64>,
    /// With `--chaos-nodes`: strike every MIN to MAX seconds of mission time instead of 10
    /// to 20 (e.g. `4-8`).
    #[arg(long, value_name = "MIN-MAX", value_parser = parse_gaps, requires = "chaos_nodes")]
    pub chaos_every: Option<Gaps>,
    /// With `--run`: run the mission N times on the same cluster, one after another — the
    /// first from where the cluster starts, every next one with the cart put back at the
    /// world's start (as `run --join --from-start`) — while the cluster's nodes are
    /// restarted as its file says: a soak. Each run prints its lines, outcome and verdict;
    /// then a summary of them all: runs failed, faults (with `--chaos-nodes`: each fault's
    /// node, when it was back and when every replica on it had caught up), acknowledged
    /// records lost, epochs obeyed late, collisions, and each node's memory (VmRSS) at the
    /// start and after every run, and whether it stayed flat. `--report`, `--events`,
    /// `--mcap`, `--svg` are written per run (`report.json` → `report-1.json`,
    /// `report-2.json`, …); a `--fault` strikes in every run. Keeps going after a failed run (one refused before it started — its node to
    /// dispatch on out at that moment — is tried again for up to 60 s); exit 0 when the
    /// soak's goal holds (every run succeeded with nothing lost, nothing obeyed late, no
    /// collision, no stale read with `--probe`, every node's memory flat). Not with
    /// `--monitor` (a run's page stays up until Ctrl-C).
    #[arg(long, value_name = "N", requires = "run", conflicts_with = "monitor",
          value_parser = clap::value_parser!(u32).range(1..))]
    pub runs: Option<u32>,
    /// With `--run`: probe datamanager DM while the runs go on, as `marie dm probe DM`
    /// does — write numbered records into it and read them back, by name and from each
    /// replica (a leader cut off from the others too), counting stale reads — and say the
    /// verdict after the runs (`reads: …`). A stale read, or the newest write missing, fails
    /// `up` (exit 1) as a failed run does.
    #[arg(long, value_name = "DM", requires = "run")]
    pub probe: Option<String>,
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

/// Start the cluster, wait for it, run the mission or wait for a signal, stop it.
pub(crate) async fn up(args: UpArgs) -> anyhow::Result<ExitCode> {
    // the cluster file, the mission and each node's launch, checked before any process starts
    let mut plan = UpPlan::new(&args)?;
    // the first node listens, the others join it
    let (mut nodes, started) = Nodes::start(&plan.exe, &mut plan.launches).await;
    let result = match started {
        Ok(()) => serve(&args, &plan, &mut nodes).await,
        Err(e) => Err(e),
    };
    nodes.stop().await?;
    result
}
