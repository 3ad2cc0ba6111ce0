//! The node a mission runs (or is checked) on: its world loaded, the mission checked
//! against the operations that run — shared by `run` and `check`.

use super::args::RobotArgs;
use super::error::WorldFile;
use super::files;
use marie::actors::dispatcher::mission::Mission;
use marie::missions::world::World;
use marie::node::{Node, NodeError, NodeOptions};
use std::path::{Path, PathBuf};

/// A node started for a mission, with the mission checked against it.
pub struct Prepared {
    /// The node, with the robot when there is a world.
    pub node: Node,
    /// The mission, checked.
    pub mission: Mission,
    /// The world file the robot drives in, when one runs.
    pub world_path: Option<PathBuf>,
}

impl Prepared {
    /// `world `lab` from FILE, seed N`, when a robot runs.
    pub fn world_line(&self) -> Option<String> {
        let world = self.node.world()?;
        Some(format!(
            "world `{}` from {}, seed {}",
            world.name,
            self.world_path
                .as_deref()
                .map_or_else(|| "?".into(), |p| p.display().to_string()),
            self.node.seed().unwrap_or_default()
        ))
    }
}

/// Parse the mission, load its world (`--world`, else the mission's `world`, else none),
/// start the node (with the robot when there is a world) and check the mission against it.
pub async fn prepare(path: &Path, robot: RobotArgs) -> anyhow::Result<Prepared> {
    files::input("mission file", path)?;
    let parsed = Mission::parse_file(path).map_err(NodeError::Mission)?;
    let world_path = robot
        .world
        .or_else(|| parsed.world().map(Path::to_path_buf));
    let node = start_node(world_path.as_deref(), robot.seed).await?;
    match node.check_mission(&parsed).await {
        Ok(mission) => Ok(Prepared {
            node,
            mission,
            world_path,
        }),
        Err(e) => {
            node.shutdown().await;
            Err(e.into())
        }
    }
}

/// Load the world at `world_path` (if any; bad world → its diagnostics, exit 2) and start the
/// node with it — with the robot when there is a world. Speed 1: the node's clock is the
/// runtime's (virtual in `run`, paced there).
pub async fn start_node(world_path: Option<&Path>, seed: u64) -> anyhow::Result<Node> {
    let world = match world_path {
        Some(p) => {
            files::input("world file", p)?;
            Some(World::load(p).map_err(WorldFile)?)
        }
        None => None,
    };
    Ok(Node::start(NodeOptions {
        world,
        seed,
        ..Default::default()
    })
    .await?)
}
