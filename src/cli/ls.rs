//! `marie ls`: the location table — of the embedded node, or of a running cluster
//! (`--join ADDR --cookie C`).

use super::args::RobotArgs;
use super::error::BadInput;
use super::prepare::start_node;
use marie::actors::registry::{self, Instance};
use marie::net::{ClusterConfig, Transport};
use std::net::SocketAddr;
use std::process::ExitCode;
use std::time::Duration;

/// How long `ls --join` waits for the node it dials.
const JOIN_TIMEOUT: Duration = Duration::from_secs(10);
/// `ls --join` lists once no new peer has appeared for this long (the peers behind the one
/// it dialed are dialed a moment after).
const QUIET: Duration = Duration::from_millis(300);

/// Flags of `marie ls`.
#[derive(clap::Args, Debug)]
pub struct LsArgs {
    /// Print JSON instead of the start-up log format.
    #[arg(long)]
    pub json: bool,
    /// List a running cluster's modules: the address of any one of its nodes.
    #[arg(long, value_name = "ADDR", requires = "cookie", conflicts_with_all = ["node", "world"])]
    pub join: Option<SocketAddr>,
    /// The cluster's cookie (with `--join`).
    #[arg(long, value_name = "C", requires = "join")]
    pub cookie: Option<String>,
    /// `--node FILE`: list what that node hosts; `--world FILE`: with the robot too.
    #[command(flatten)]
    pub robot: RobotArgs,
}

/// Start the node (or join the cluster) and list what is published.
pub async fn ls(args: LsArgs) -> anyhow::Result<ExitCode> {
    if let (Some(addr), Some(cookie)) = (args.join, &args.cookie) {
        return ls_cluster(addr, cookie, args.json).await;
    }
    let node = start_node(args.robot.options(None)).await?.node;
    print_listing(&registry::list(), args.json)?;
    node.shutdown().await;
    Ok(ExitCode::SUCCESS)
}

/// Join the cluster at `addr` as a node that hosts nothing, list every node's modules.
async fn ls_cluster(addr: SocketAddr, cookie: &str, json: bool) -> anyhow::Result<ExitCode> {
    let me = format!("ls-{}", std::process::id());
    let any_port = SocketAddr::new(std::net::Ipv4Addr::LOCALHOST.into(), 0);
    let config = ClusterConfig::new(any_port, cookie).with_peer(addr);
    config.validate(&me).map_err(|e| BadInput(e.to_string()))?;
    let transport = Transport::start(&me, &config).await?;
    if let Err(e) = transport.wait_for_peers(1, JOIN_TIMEOUT).await {
        transport.stop().await;
        anyhow::bail!("{me} could not join the cluster at {addr}: {e} (is a node listening there, with this cookie?)");
    }
    let peers = transport.settle(QUIET, JOIN_TIMEOUT).await;
    eprintln!(
        "{me} sees {}",
        peers
            .iter()
            .map(|p| format!("{} ({})", p.name, p.address))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let result = print_listing(&registry::list(), json);
    transport.stop().await;
    result.map(|()| ExitCode::SUCCESS)
}

fn print_listing(list: &[Instance], json: bool) -> anyhow::Result<()> {
    if json {
        let rows: Vec<_> = list
            .iter()
            .map(|i| {
                serde_json::json!({
                    "kind": i.kind.label(), "id": i.id, "name": i.name,
                    "node": i.node, "address": i.actor.get_id().to_string(),
                })
            })
            .collect();
        println!("{}", serde_json::to_string_pretty(&rows)?);
    } else {
        print!("{}", registry::render_listing(list));
    }
    Ok(())
}
