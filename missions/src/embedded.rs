//! The embedded, single-process node the `marie` command runs: a [`NodeConfig`] — the
//! built-in one that hosts everything, or a file's — with the simulated robot plugged in
//! when there is a world.
//!
//! A config *file* with a `[cluster]` table is refused here (these commands run a node of
//! their own in this process); a config given as a value joins its cluster, as any
//! [`Node`] does — what `marie node` gives it.
//!
//! Which world the robot drives in: `--world FILE`, else the node config's
//! `[simulation] world`, else the mission's `world`. With a node config file, a robot runs
//! only if the file has a `[simulation]` table: the node hosts exactly what the file says.
//!
//! ```no_run
//! use marie_missions::embedded::{Embedded, EmbeddedOptions};
//! # #[tokio::main] async fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let options = EmbeddedOptions {
//!     node: Some("missions/nodes/v1-only.toml".into()),
//!     mission_world: Some("missions/worlds/lab.toml".into()),
//!     ..EmbeddedOptions::default()
//! };
//! let embedded = Embedded::start(options).await?;
//! let mission = embedded.node.load_mission("missions/docking.toml".as_ref()).await?;
//! let options = marie_cluster::node::RunOptions::new();
//! let report = embedded.node.run(mission, options).await?;
//! println!("{:?}", report.outcome);
//! embedded.node.shutdown().await;
//! # Ok(()) }
//! ```

use crate::robot::{SimRobot, DEFAULT_SEED};
use crate::world::World;
use marie_cluster::net::TransportError;
use marie_cluster::node::{Node, NodeConfig, NodeError, NodeOptions, SimulationConfig};
use marie_vocabulary::clock::{RealClock, SharedClock};
use marie_vocabulary::diagnostic::{Diagnostic, Diagnostics};
use std::path::PathBuf;
use std::sync::Arc;

/// The name of the built-in node.
pub const EMBEDDED_NODE: &str = "embedded";

/// How to start the embedded node.
#[derive(Clone)]
pub struct EmbeddedOptions {
    /// A node config file; `None`: the built-in config that hosts everything.
    pub node: Option<PathBuf>,
    /// A node config given as a value (e.g. the dispatcher-only member of `marie run
    /// --join`, or `marie node`'s config with its flags applied); used when `node` is
    /// `None`. Its cluster, if it has one, is joined ([`Node::start`]).
    pub config: Option<NodeConfig>,
    /// `--world`: overrides the node config's and the mission's world.
    pub world: Option<PathBuf>,
    /// The mission's `world`, used when neither `--world` nor the node config names one.
    pub mission_world: Option<PathBuf>,
    /// Where the mission names its world, for the first line of an error about the world
    /// file ([`ParsedMission::world_diagnostic`](marie_actors::dispatcher::mission::ParsedMission::world_diagnostic)).
    pub mission_world_at: Option<Diagnostic>,
    /// `--seed`: overrides the node config's; default [`DEFAULT_SEED`].
    pub seed: Option<u64>,
    /// `--data-dir`: overrides the node config's `data_dir` — its datamanagers then keep
    /// journals there (`process` unless the config says otherwise). Default: the config's,
    /// and none for the built-in node (nothing written to disk).
    pub data_dir: Option<PathBuf>,
    /// The clock the node's actors share.
    pub clock: SharedClock,
}

impl std::fmt::Debug for EmbeddedOptions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("EmbeddedOptions")
            .field("node", &self.node)
            .field("config", &self.config)
            .field("world", &self.world)
            .field("mission_world", &self.mission_world)
            .field("seed", &self.seed)
            .finish_non_exhaustive()
    }
}

impl Default for EmbeddedOptions {
    fn default() -> Self {
        EmbeddedOptions {
            node: None,
            config: None,
            world: None,
            mission_world: None,
            mission_world_at: None,
            seed: None,
            data_dir: None,
            clock: RealClock::shared(),
        }
    }
}

/// Why the embedded node did not start.
#[derive(Debug, thiserror::Error)]
pub enum EmbeddedError {
    /// The node config file is not valid (bad input).
    #[error("{0}")]
    Config(Diagnostics),
    /// The world file does not load (bad input); diagnostics of the file that named it come
    /// first.
    #[error("{0}")]
    World(Diagnostics),
    /// The node config file has a `[cluster]` table, but the command runs a node of its own
    /// in this process (bad input): a cluster member is `marie node --config FILE`.
    #[error(
        "{0}: has a [cluster] table, but this command runs a node of its own in this \
         process; start the member with `marie node --config {0}`, and act on the cluster \
         with --join ADDR --cookie C"
    )]
    Clustered(String),
    /// The node did not start.
    #[error(transparent)]
    Node(#[from] NodeError),
}

impl EmbeddedError {
    /// Whether the error is the user's input (exit 2) rather than a failure (exit 1).
    pub fn is_bad_input(&self) -> bool {
        matches!(
            self,
            EmbeddedError::Config(_)
                | EmbeddedError::World(_)
                | EmbeddedError::Clustered(_)
                | EmbeddedError::Node(NodeError::Config(_))
                // the data directory asked for: one another node holds, or a file
                | EmbeddedError::Node(NodeError::DataDirInUse { .. })
                | EmbeddedError::Node(NodeError::DataDir { .. })
                | EmbeddedError::Node(NodeError::Cluster(TransportError::Tls(_)))
        )
    }
}

/// A started embedded node, with the robot it drives.
pub struct Embedded {
    /// The node.
    pub node: Node,
    /// The simulated robot, when one runs.
    pub robot: Option<Arc<SimRobot>>,
    /// The world file it drives in.
    pub world_path: Option<PathBuf>,
}

impl std::fmt::Debug for Embedded {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Embedded")
            .field("node", &self.node)
            .field("robot", &self.robot)
            .field("world_path", &self.world_path)
            .finish()
    }
}

impl Embedded {
    /// Load the node config (or take the built-in one), the world, and start the node.
    pub async fn start(options: EmbeddedOptions) -> Result<Embedded, EmbeddedError> {
        let catalog = crate::catalog();
        let mut config = match (&options.node, options.config.clone()) {
            (Some(path), _) => {
                let config = NodeConfig::load(path, &catalog).map_err(EmbeddedError::Config)?;
                // honoured or refused, never ignored: this node is the command's own
                if config.cluster.is_some() {
                    return Err(EmbeddedError::Clustered(path.display().to_string()));
                }
                config
            }
            (None, Some(config)) => config,
            // the built-in node runs the robot whenever there is a world
            (None, None) => NodeConfig {
                simulation: Some(SimulationConfig {
                    world: None,
                    world_at: None,
                    seed: None,
                    drivers: true,
                }),
                ..NodeConfig::everything(EMBEDDED_NODE, &catalog)
            },
        };
        if let Some(dir) = &options.data_dir {
            config.data_dir = Some(dir.clone());
        }
        let mut robot = None;
        let mut world_path = None;
        if let Some(sim) = &config.simulation {
            // what named the world, for the first line of an error about it
            let named_at = if options.world.is_some() {
                None
            } else if sim.world.is_some() {
                sim.world_at.clone()
            } else {
                options.mission_world_at.clone()
            };
            let path = options
                .world
                .clone()
                .or_else(|| sim.world.clone())
                .or_else(|| options.mission_world.clone());
            if let Some(path) = path {
                let world = World::load(&path).map_err(|d| {
                    let mut all: Vec<Diagnostic> = named_at.into_iter().collect();
                    all.extend(d);
                    EmbeddedError::World(Diagnostics(all))
                })?;
                let seed = options.seed.or(sim.seed).unwrap_or(DEFAULT_SEED);
                robot = Some(Arc::new(
                    SimRobot::new(world, seed).with_drivers(sim.drivers),
                ));
                world_path = Some(path);
            }
        }
        let mut node_options = NodeOptions::with_catalog(catalog).with_clock(options.clock);
        if let Some(robot) = &robot {
            node_options = node_options.with_robot(robot.clone());
        }
        let node = Node::start(config, node_options).await?;
        Ok(Embedded {
            node,
            robot,
            world_path,
        })
    }
}
