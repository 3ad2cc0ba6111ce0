//! The flags of `marie run`, as clap parses them: what [`Plan::new`](super::plan::Plan::new)
//! checks and turns into a plan. `marie up --run` builds them too, with the fields clap
//! skips (the files it read, its node processes, its node chaos, its Ctrl-C watch).

use super::{KeptReport, MissionOver};
use crate::cli::args::{parse_seed, parse_speed, RobotArgs};
use crate::cli::join::JoinArgs;
use marie::cluster::fault::{FaultSpec, NodeChaos, NodeProcesses};
use marie::run::FileRole;
use std::path::PathBuf;

/// Flags of `marie run`.
#[derive(clap::Args, Debug)]
pub(crate) struct RunArgs {
    /// Mission file (TOML task tree).
    #[arg(required_unless_present = "replay")]
    pub mission: Option<PathBuf>,
    /// Run a past run again from its report alone (`--report`'s JSON: its provenance holds
    /// the mission, world and node config texts, the seed, the command's faults), on this
    /// node, and say whether the outcome, the bindings, the final pose and the parameters
    /// match; exit 0 when they all do. A report of another marie commit is replayed with a
    /// warning naming both.
    #[arg(long, value_name = "REPORT.json",
          conflicts_with_all = ["mission", "join", "world", "node", "seed", "faults", "chaos"])]
    pub replay: Option<PathBuf>,
    /// The files `marie up` read to start the run's nodes — its cluster file, then the node
    /// configs it names — for the run's provenance.
    #[arg(skip)]
    pub read_by_up: Vec<(FileRole, PathBuf)>,
    #[command(flatten)]
    pub robot: RobotArgs,
    /// Keep the datamanagers' records in journals in DIR (`process` durability: what they
    /// acknowledged survives their crash and the process's); DIR is locked while the run
    /// lasts. Default: the node config's `data_dir`, and none for the built-in node —
    /// in memory, nothing written to disk. Not with `--join` (the cluster's datamanagers
    /// are its nodes').
    #[arg(long, value_name = "DIR", conflicts_with = "join")]
    pub data_dir: Option<PathBuf>,
    /// Write the run report (JSON) here.
    #[arg(long, value_name = "FILE")]
    pub report: Option<PathBuf>,
    /// Explain the self-configuration: for each operation, every live instance (node,
    /// version, schema), the one chosen and why each other lost or was rejected.
    #[arg(long)]
    pub explain: bool,
    /// With `--explain`: print only the choices, each as one JSON object per line (the
    /// `choice` of the `selected` event: operation, candidates with node, version, schema,
    /// flags and verdict, and `replacing` for a stand-in after a failure); the outcome is
    /// the exit code, and the report if `--report` is given.
    #[arg(long, requires = "explain")]
    pub json: bool,
    /// Write every event of the run here, one JSON object per line (the schema is in the
    /// docs of `marie::events`): dispatcher, bindings, supervisors, registry, faults,
    /// the robot. The report can be rebuilt from it.
    #[arg(long, value_name = "FILE.jsonl")]
    pub events: Option<PathBuf>,
    /// Write the run as MCAP here, for Foxglove: the world, the cart, the sonar echoes and
    /// the paths in its 3D panel, every event in its log, the task tree's state as JSON
    /// (the same as `marie export` makes of an events file).
    #[arg(long, value_name = "FILE.mcap")]
    pub mcap: Option<PathBuf>,
    /// Draw the robot's run (walls, driven path, sonar echoes, segments, followed wall,
    /// detected dock, planned path, final footprint) as an SVG picture here. Needs a world.
    #[arg(long, value_name = "FILE.svg")]
    pub svg: Option<PathBuf>,
    /// Clock speed: a factor of real time (`1` is real time), or `max`: as fast as the CPU
    /// allows (the default). Only paces the run: the outcome is the same at every speed.
    /// With `--join`: the cluster's factor (default 1; `max` is refused, a cluster runs on
    /// the wall clock).
    #[arg(long, value_parser = parse_speed, allow_hyphen_values = true)]
    pub speed: Option<f64>,
    /// `--join ADDR --cookie C`: run the dispatcher as a member of a running cluster; the
    /// operations, datamanagers and cart are the cluster's.
    #[command(flatten)]
    pub cluster: JoinArgs,
    /// With `--join`: put the cluster's simulated cart back at rest at the world's start
    /// before the run, its collisions and path started anew. Without it a run starts where
    /// the cluster's last run left the cart (parked in the dock, after docking).
    #[arg(long, requires = "join")]
    pub from_start: bool,
    /// Inject a fault while the mission runs: KIND `kill`, `panic`, `hang` or `slow` (an
    /// operation) or `stop-node`, `freeze-node` or `partition` (node processes `marie up`
    /// started: see `marie up --fault`); TARGET the operation's name or id
    /// (the instance the mission bound), `NAME#VERSION` (the instance with that version),
    /// `NAME/NODE` (the one on that node) or an actor id like `0.42` — a datamanager's
    /// name, id or address (`kill`, `panic`, `hang`) — or a node's name;
    /// SECS mission time, 0 to 86400 (a day). Repeatable. A fault that cannot be injected
    /// is reported, never dropped.
    #[arg(long = "fault", value_name = "KIND:TARGET@SECS")]
    pub faults: Vec<FaultSpec>,
    /// Kill a random operation of the running action every 4 to 12 s of mission time,
    /// picked by a generator seeded with SEED.
    #[arg(long, value_name = "SEED", value_parser = parse_seed, allow_hyphen_values = true)]
    pub chaos: Option<u64>,
    /// With `--chaos`: the datamanagers are among the victims too (a kill of a
    /// datamanager, which its supervisor restarts: with `--data-dir` it comes back with its
    /// records).
    #[arg(long, requires = "chaos")]
    pub chaos_dms: bool,
    /// Show the run live in the browser: serve the monitor's page on ADDR (default
    /// 127.0.0.1:7700; port 0: one the OS picks), print its address, and after the run keep
    /// serving its final state until Ctrl-C. With `--join`, the other nodes' events too.
    #[arg(long, value_name = "ADDR", num_args = 0..=1,
          default_missing_value = marie_monitor::DEFAULT_LISTEN)]
    pub monitor: Option<std::net::SocketAddr>,
    /// With `--monitor`: let the page inject faults — kill or hang an operation (and, under
    /// `marie up`, stop a node's process) — and watch the dispatcher rebind.
    #[arg(long, requires = "monitor")]
    pub allow_faults: bool,
    /// With `--monitor`: let the page add a datamanager's replica on a node and remove one
    /// (what `marie dm add-replica` and `remove-replica` do; a run that joined a cluster).
    #[arg(long, requires = "monitor")]
    pub allow_changes: bool,
    /// The node processes the page and the faults may stop, freeze or cut apart (`marie
    /// up`'s children; none otherwise).
    #[arg(skip)]
    pub node_processes: NodeProcesses,
    /// Random node faults (`marie up --chaos-nodes`).
    #[arg(skip)]
    pub node_chaos: Option<Box<NodeChaos>>,
    /// Set once the mission has ended and a Ctrl-C is the run's own to hear (see
    /// [`MissionOver`]).
    #[arg(skip)]
    pub mission_over: MissionOver,
    /// Where the run leaves its report for whoever ran it from this process (`marie up
    /// --runs`).
    #[arg(skip)]
    pub kept: KeptReport,
    /// With `--join`: dispatch the run on NODE (a node whose config says `dispatcher =
    /// "active"` or `"standby"`, e.g. `features` of the thesis layout) instead of this
    /// member, and follow it there — and to the standby that takes it over should NODE be
    /// lost. `marie up --run` does so on the cluster file's active node.
    #[arg(long, value_name = "NODE", requires = "join")]
    pub dispatch_on: Option<String>,
}
