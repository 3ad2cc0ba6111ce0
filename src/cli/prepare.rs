//! The node a mission runs (or is checked) on: its world loaded, the mission checked
//! against the operations that run — shared by `run` and `check`.

use super::args::RobotArgs;
use super::join::{join, Joining};
use marie::clock::ScaledClock;
use marie::cluster::net::Transport;
use marie::cluster::node::{Node, NodeError};
use marie::dispatcher::mission::{Mission, ParsedMission};
use marie_missions::embedded::{Embedded, EmbeddedOptions};
use marie_missions::fresh_start::{at_world_start, restart_at_world_start, FreshStartError};
use marie_missions::hardware::CartClient;
use marie_missions::robot::SimRobot;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A node started for a mission, with the mission checked against it.
pub(crate) struct Prepared {
    /// The node, with the robot when there is a world.
    pub node: Node,
    /// The simulated robot, when one runs.
    pub robot: Option<Arc<SimRobot>>,
    /// The mission, checked.
    pub mission: Mission,
    /// The world file the robot drives in, when one runs.
    pub world_path: Option<PathBuf>,
    /// The cluster transport, when the node joined one.
    pub transport: Option<Transport>,
    /// The seed the cart drives with, when it runs on another node of a cluster joined
    /// (that node's: this process's `--seed` does not reach it).
    pub cart_seed: Option<u64>,
}

impl Prepared {
    /// Stop the node, then leave the cluster if it joined one.
    pub(crate) async fn shutdown(self) {
        self.node.shutdown().await;
        if let Some(t) = self.transport {
            t.stop().await;
        }
    }

    /// Where the cart of a cluster joined starts the run: put back at the world's start
    /// first if `from_start` (the run fails if it cannot be), else where the cluster's last
    /// run left it — said when that is not the world's start, since a mission written for
    /// the start fails from there. `None` without a cluster's cart (the embedded node's
    /// starts at the world's start) or when nothing needs saying.
    pub(crate) async fn cart_start(
        &self,
        from_start: bool,
    ) -> Result<Option<String>, FreshStartError> {
        let (Some(_), Some(robot)) = (&self.transport, &self.robot) else {
            return Ok(None);
        };
        if from_start {
            restart_at_world_start().await?;
            return Ok(Some(
                "the cart starts at the world's start (--from-start)".into(),
            ));
        }
        let pose = match CartClient::lookup() {
            Ok(cart) => cart.status().await.map(|s| s.pose),
            Err(e) => Err(e),
        };
        Ok(match pose {
            Ok(p) if !at_world_start(robot.world(), &p) => Some(format!(
                "the cart starts where the cluster's last run left it, at ({:.2}, {:.2}, \
                 {:.1}°), not at the world's start: --from-start puts it back there",
                p.x,
                p.y,
                p.theta.to_degrees()
            )),
            _ => None,
        })
    }

    /// `world `lab` from FILE, seed N`, when a robot runs.
    pub(crate) fn world_line(&self) -> Option<String> {
        let robot = self.robot.as_ref()?;
        Some(format!(
            "world `{}` from {}, seed {}",
            robot.world().name,
            self.world_path
                .as_deref()
                .map_or_else(|| "?".into(), |p| p.display().to_string()),
            self.cart_seed.unwrap_or_else(|| robot.seed())
        ))
    }
}

/// Parse the mission, start the node (`--node FILE` or the built-in one; the robot's world
/// from `--world`, else the node config's, else the mission's, else none) — or, `joining`,
/// a dispatcher-only member of the cluster — and check the mission against it.
pub(crate) async fn prepare(
    path: &Path,
    robot: RobotArgs,
    joining: Option<&Joining>,
) -> anyhow::Result<Prepared> {
    let parsed = ParsedMission::parse_file(path).map_err(NodeError::Mission)?;
    let asked_seed = robot.seed;
    let mut options = robot.options(parsed.world());
    options.mission_world_at = parsed.world_diagnostic("the world named here does not load:");
    if let Some(j) = joining {
        options.config = Some(j.config());
        options.clock = Arc::new(ScaledClock::cluster(j.speed));
    }
    let Embedded {
        node,
        robot,
        world_path,
    } = start_node(options).await?;
    let transport = match joining {
        Some(j) => match join(&j.me, &j.target).await {
            Ok(t) => Some(t),
            Err(e) => {
                node.shutdown().await;
                return Err(e);
            }
        },
        None => None,
    };
    match node.check_mission(&parsed).await {
        Ok(mission) => {
            let cart_seed = match (&transport, &robot) {
                (Some(_), Some(_)) => cart_seed(asked_seed).await,
                _ => None,
            };
            Ok(Prepared {
                node,
                robot,
                mission,
                world_path,
                transport,
                cart_seed,
            })
        }
        Err(e) => {
            node.shutdown().await;
            if let Some(t) = transport {
                t.stop().await;
            }
            Err(e.into())
        }
    }
}

/// Start the embedded node: the node config and world checked (bad ones → their
/// diagnostics, exit 2), the robot plugged in when there is a world. The node's clock is the
/// runtime's (virtual in `run`, paced there).
pub(crate) async fn start_node(options: EmbeddedOptions) -> anyhow::Result<Embedded> {
    Ok(Embedded::start(options).await?)
}

/// The seed of the cart a joined run drives (on another node: that node's), if it answers;
/// a `--seed` given here that differs is said not to reach it.
async fn cart_seed(asked: Option<u64>) -> Option<u64> {
    let status = match CartClient::lookup() {
        Ok(cart) => cart.status().await,
        Err(e) => Err(e),
    };
    let seed = match status {
        Ok(status) => status.seed?,
        Err(e) => {
            // (a cluster without a cart, e.g. for `marie check`: this process's seed stands)
            tracing::debug!("the cart's seed is not known: {e}");
            return None;
        }
    };
    if let Some(asked) = asked.filter(|a| *a != seed) {
        eprintln!(
            "marie: --seed {asked} does not reach the cart, which runs on another node with \
             seed {seed} (its node's, e.g. `marie up --seed`): the run drives with seed {seed}"
        );
    }
    Some(seed)
}
