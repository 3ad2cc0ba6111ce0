//! The node a mission runs (or is checked) on: its world loaded, the mission checked
//! against the operations that run — shared by `run` and `check`.

use super::args::RobotArgs;
use marie::actors::dispatcher::mission::Mission;
use marie::embedded::{Embedded, EmbeddedOptions};
use marie::missions::robot::SimRobot;
use marie::node::{Node, NodeError};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A node started for a mission, with the mission checked against it.
pub struct Prepared {
    /// The node, with the robot when there is a world.
    pub node: Node,
    /// The simulated robot, when one runs.
    pub robot: Option<Arc<SimRobot>>,
    /// The mission, checked.
    pub mission: Mission,
    /// The world file the robot drives in, when one runs.
    pub world_path: Option<PathBuf>,
}

impl Prepared {
    /// `world `lab` from FILE, seed N`, when a robot runs.
    pub fn world_line(&self) -> Option<String> {
        let robot = self.robot.as_ref()?;
        Some(format!(
            "world `{}` from {}, seed {}",
            robot.world().name,
            self.world_path
                .as_deref()
                .map_or_else(|| "?".into(), |p| p.display().to_string()),
            robot.seed()
        ))
    }
}

/// Parse the mission, start the node (`--node FILE` or the built-in one; the robot's world
/// from `--world`, else the node config's, else the mission's, else none) and check the
/// mission against it.
pub async fn prepare(path: &Path, robot: RobotArgs) -> anyhow::Result<Prepared> {
    let parsed = Mission::parse_file(path).map_err(NodeError::Mission)?;
    let mut options = robot.options(parsed.world());
    options.mission_world_at = parsed.world_diagnostic("the world named here does not load:");
    let Embedded {
        node,
        robot,
        world_path,
    } = start_node(options).await?;
    match node.check_mission(&parsed).await {
        Ok(mission) => Ok(Prepared {
            node,
            robot,
            mission,
            world_path,
        }),
        Err(e) => {
            node.shutdown().await;
            Err(e.into())
        }
    }
}

/// Start the embedded node: the node config and world checked (bad ones → their
/// diagnostics, exit 2), the robot plugged in when there is a world. The node's clock is the
/// runtime's (virtual in `run`, paced there).
pub async fn start_node(options: EmbeddedOptions) -> anyhow::Result<Embedded> {
    Ok(Embedded::start(options).await?)
}
