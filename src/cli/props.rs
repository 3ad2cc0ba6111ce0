//! `marie props NAME|ID`: every property group of an operation.

use super::args::RobotArgs;
use super::error::BadInput;
use super::join::{join, member_name, JoinArgs};
use super::prepare::start_node;
use marie::cluster::fault::{find, Target};
use marie::eo::{EoClient, EoError};
use marie::property::{Group, PropertyReply, PropertyRequest};
use marie::registry::Instance;
use marie::run::Aim;
use std::process::ExitCode;

/// Flags of `marie props`.
#[derive(clap::Args, Debug)]
pub(crate) struct PropsArgs {
    /// The operation: its name or numeric id, `NAME#VERSION` when several versions run,
    /// `NAME/NODE`, or an actor id like `0.42`.
    pub operation: String,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
    /// `--node FILE`: ask an operation of that node; `--world FILE`: with the robot.
    #[command(flatten)]
    pub robot: RobotArgs,
    /// `--join ADDR --cookie C`: ask an operation of a running cluster, wherever it runs.
    #[command(flatten)]
    pub cluster: JoinArgs,
}

/// Start the node, ask the operation and print its answers.
pub(crate) async fn props(args: PropsArgs) -> anyhow::Result<ExitCode> {
    if let Some(target) = args.cluster.target_alone(&args.robot, "asks")? {
        let transport = join(&member_name("props"), &target).await?;
        let result = props_on(&args.operation, args.json).await;
        transport.stop().await;
        return result;
    }
    let node = start_node(args.robot.options(None)).await?.node;
    let result = props_on(&args.operation, args.json).await;
    node.shutdown().await;
    result
}

async fn props_on(operation: &str, json: bool) -> anyhow::Result<ExitCode> {
    let inst = match Target::parse(operation, Aim::Operation) {
        Ok(target) => find(&target).await,
        Err(e) => Err(e),
    };
    let inst = inst.map_err(|e| BadInput(e.to_string()))?;
    let replies = ask_every_group(&inst).await?;
    if json {
        println!("{}", serde_json::to_string_pretty(&replies)?);
        return Ok(ExitCode::SUCCESS);
    }
    for reply in &replies {
        print_reply(reply);
    }
    Ok(ExitCode::SUCCESS)
}

/// Every property group of `inst` (identification, location, general, specific), asked of
/// the live instance: what `marie props` prints and the monitor's page shows on a click.
pub(crate) async fn ask_every_group(inst: &Instance) -> Result<Vec<PropertyReply>, EoError> {
    let client = EoClient::from_cell(inst.actor.clone());
    let mut replies = Vec::new();
    for req in [
        PropertyRequest::Group(Group::Identification),
        PropertyRequest::Group(Group::Location),
        PropertyRequest::Group(Group::General),
        PropertyRequest::Group(Group::Specific),
    ] {
        replies.push(client.property(req).await?);
    }
    Ok(replies)
}

fn print_reply(reply: &PropertyReply) {
    match reply {
        PropertyReply::Identification(i) => {
            println!("identification");
            println!("  name:        {}", i.name);
            println!("  id:          {}", i.id);
            println!("  version:     {}", i.version);
            println!("  description: {}", i.description);
        }
        PropertyReply::Location(l) => {
            println!("location");
            println!("  node:    {}", l.node);
            println!("  address: {}", l.address);
            println!("  alive:   {}", l.alive);
        }
        PropertyReply::General(g) => {
            println!("general");
            println!("  parameters:  {}", g.param_count);
            println!("  up-time:     {} ms", g.uptime_ms);
            println!("  in use:      {}", g.in_use);
            println!("  activations: {}", g.activations);
        }
        PropertyReply::Specific(s) => {
            println!("parameters");
            for d in &s.params {
                let range = match (d.min, d.max) {
                    (None, None) => String::new(),
                    (a, b) => format!(
                        " [{}, {}]",
                        a.map_or("-inf".into(), |v| v.to_string()),
                        b.map_or("+inf".into(), |v| v.to_string())
                    ),
                };
                let unit = d
                    .unit
                    .as_deref()
                    .map(|u| format!(" {u}"))
                    .unwrap_or_default();
                let current = s
                    .current
                    .get(&d.name)
                    .map(|v| v.to_string())
                    .unwrap_or_default();
                println!(
                    "  {:<18} {:<10} default {}{unit}{range}; current {current}{}  {}",
                    d.name,
                    d.ty.to_string(),
                    d.default,
                    if d.read_only { " (read-only)" } else { "" },
                    d.description
                );
            }
            if !s.flags.is_empty() {
                println!("flags");
                for (i, f) in s.flags.iter().enumerate() {
                    println!("  bit {i}: {:<14} {}", f.name, f.description);
                }
            }
        }
        other => println!("{other:?}"),
    }
}
