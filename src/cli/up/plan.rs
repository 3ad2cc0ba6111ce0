//! What `marie up` asks for, checked before any process starts: the cluster file, the
//! mission (its world is the robot's), the speed and seed, the nodes' data directories and
//! how each node is launched.

use super::data_dirs::DataDirs;
use super::UpArgs;
use crate::cli::children::NodeLaunch;
use crate::cli::error::BadInput;
use crate::cli::join::ClusterEntry;
use crate::cli::netns::PrivateNet;
use marie::cluster::layout::ClusterLayout;
use marie::dispatcher::mission::ParsedMission;
use std::net::SocketAddr;
use std::path::PathBuf;

/// A cluster as asked for, checked.
pub(super) struct UpPlan {
    /// The cluster file, loaded.
    pub(super) layout: ClusterLayout,
    /// The cluster's speed factor: `--speed`, else the file's.
    pub(super) speed: f64,
    /// This executable, which the nodes run as `marie node`.
    pub(super) exe: PathBuf,
    /// How each node is started, in the file's order (the first is the one the others
    /// join); the addresses become those they bound once they listen.
    pub(super) launches: Vec<NodeLaunch>,
    /// Where the nodes keep their data; dropped (a temporary one removed) once the nodes
    /// have stopped.
    _data: DataDirs,
}

impl UpPlan {
    /// Load the cluster file, check the mission, pick the world, the speed and the seed,
    /// make the data directories and plan each node's launch; bad input is exit 2.
    pub(super) fn new(args: &UpArgs) -> anyhow::Result<UpPlan> {
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
        let data = DataDirs::new(args.data_dir.as_deref(), &args.cluster)?;
        let launches = launches(&layout, &data, speed, world, seed);
        if launches.is_empty() {
            return Err(BadInput(format!(
                "{}: `node = []` lists no node: a cluster file lists the nodes it runs",
                args.cluster.display()
            ))
            .into());
        }
        Ok(UpPlan {
            layout,
            speed,
            exe,
            launches,
            _data: data,
        })
    }

    /// How a member of `up`'s own joins the cluster: at the first node, the one the others
    /// joined.
    pub(super) fn first_node(&self) -> ClusterEntry {
        ClusterEntry {
            addr: self.launches[0].listen,
            cookie: self.layout.cookie.clone(),
            tls: None,
        }
    }
}

/// Each node's launch: its config, where it listens (in a private network, at its own
/// address there), the cluster's cookie, speed, world and seed, its data directory.
fn launches(
    layout: &ClusterLayout,
    data: &DataDirs,
    speed: f64,
    world: Option<PathBuf>,
    seed: Option<u64>,
) -> Vec<NodeLaunch> {
    let network = PrivateNet::current();
    layout
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
            cluster_file: (!layout.datamanagers.is_empty()).then(|| layout.path.clone()),
        })
        .collect()
}
