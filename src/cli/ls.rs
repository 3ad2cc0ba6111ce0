//! `marie ls`: the location table of the embedded node.

use super::args::RobotArgs;
use super::prepare::start_node;
use marie::actors::registry;
use std::process::ExitCode;

/// Flags of `marie ls`.
#[derive(clap::Args, Debug)]
pub struct LsArgs {
    /// Print JSON instead of the start-up log format.
    #[arg(long)]
    pub json: bool,
    /// `--node FILE`: list what that node hosts; `--world FILE`: with the robot too.
    #[command(flatten)]
    pub robot: RobotArgs,
}

/// Start the node and list what it published.
pub async fn ls(args: LsArgs) -> anyhow::Result<ExitCode> {
    let node = start_node(args.robot.options(None)).await?.node;
    let list = registry::list();
    if args.json {
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
        print!("{}", registry::render_listing(&list));
    }
    node.shutdown().await;
    Ok(ExitCode::SUCCESS)
}
