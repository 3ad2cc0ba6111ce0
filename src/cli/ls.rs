//! `marie ls`: the location table — of the embedded node, or of a running cluster
//! (`--join ADDR --cookie C`).

use super::args::RobotArgs;
use super::join::{join, member_name, JoinArgs};
use super::prepare::start_node;
use marie::actors::registry::{self, Instance};
use std::process::ExitCode;

/// Flags of `marie ls`.
#[derive(clap::Args, Debug)]
pub(crate) struct LsArgs {
    /// Print JSON instead of the start-up log format.
    #[arg(long)]
    pub json: bool,
    /// `--join ADDR --cookie C`: list every module of a running cluster, with its node.
    #[command(flatten)]
    pub cluster: JoinArgs,
    /// `--node FILE`: list what that node hosts; `--world FILE`: with the robot too.
    #[command(flatten)]
    pub robot: RobotArgs,
}

/// Start the node (or join the cluster) and list what is published.
pub(crate) async fn ls(args: LsArgs) -> anyhow::Result<ExitCode> {
    if let Some(target) = args.cluster.target_alone(&args.robot, "lists")? {
        // a member that hosts nothing: what it lists is the others'
        let transport = join(&member_name("ls"), &target).await?;
        let result = print_listing(&registry::list(), args.json);
        transport.stop().await;
        return result.map(|()| ExitCode::SUCCESS);
    }
    let node = start_node(args.robot.options(None)).await?.node;
    print_listing(&registry::list(), args.json)?;
    node.shutdown().await;
    Ok(ExitCode::SUCCESS)
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
