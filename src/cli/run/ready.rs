//! Between the node's start and the mission's: the cart put where the run starts, what only
//! the started node can refuse refused (exit 2), the run's provenance, its first lines.

use super::plan::Plan;
use crate::cli::error::BadInput;
use crate::cli::prepare::Prepared;
use marie::cluster::node::{NodeError, RunOptions};
use marie::run::{FileRole, Provenance};
use std::path::Path;

/// Make the run ready on `prepared`'s node: the cart's start, the picture's robot, the
/// provenance in the plan's options, the first lines, the faults and the desk checked.
/// An error leaves the node to the caller to stop.
pub(super) async fn ready(plan: &mut Plan, prepared: &Prepared) -> anyhow::Result<()> {
    // a joined run drives the cluster's cart from where it is, or from the world's start
    let start_line = prepared.cart_start(plan.from_start).await?;
    refuse_svg_without_robot(plan, prepared)?;
    let provenance = provenance(plan, prepared);
    plan.options = std::mem::take(&mut plan.options).provenance(provenance);
    first_lines(plan, prepared, start_line);
    refuse_faults(prepared, &plan.options).await?;
    refuse_dispatch_without_desk(&plan.options)?;
    Ok(())
}

/// `--svg` draws a robot's run: refused when none runs.
fn refuse_svg_without_robot(plan: &Plan, prepared: &Prepared) -> Result<(), BadInput> {
    if plan.outputs.svg.is_none() || prepared.robot.is_some() {
        return Ok(());
    }
    Err(BadInput(format!(
        "--svg draws a robot's run, but no robot runs: give a world with --world FILE \
         or `world = \"...\"` in the `[mission]` of {}",
        plan.mission.display()
    )))
}

/// What runs, the run's first event: the files as read, the seed, the speed — a replay's
/// files under the paths its report named.
fn provenance(plan: &Plan, prepared: &Prepared) -> Provenance {
    let mut read: Vec<(FileRole, &Path)> = vec![(FileRole::Mission, plan.mission.as_path())];
    if let Some(world) = &prepared.world_path {
        read.push((FileRole::World, world));
    }
    if let Some(node) = &plan.robot.node {
        read.push((FileRole::Node, node));
    }
    read.extend(plan.read_by_up.iter().map(|(role, p)| (*role, p.as_path())));
    let mut provenance = crate::cli::provenance::of_run(
        &read,
        prepared
            .robot
            .as_ref()
            .map(|r| prepared.cart_seed.unwrap_or_else(|| r.seed())),
        Some(plan.provenance_speed()),
    );
    if let Some(r) = &plan.replay {
        // the files as the report held them, under the paths it named
        for (file, was) in provenance.files.iter_mut().zip(&r.provenance.files) {
            if file.role == was.role && file.sha256 == was.sha256 {
                file.path = was.path.clone();
            }
        }
    }
    provenance
}

/// The replay's header and warnings, the mission, the world and where the cart starts.
fn first_lines(plan: &Plan, prepared: &Prepared, start_line: Option<String>) {
    let say = plan.says();
    if let Some(r) = &plan.replay {
        if say {
            println!("{}", r.header());
        }
        for warning in r.warnings(&crate::cli::this_build()) {
            eprintln!("marie: {warning}");
        }
    }
    if !say {
        return;
    }
    println!(
        "mission `{}` ({} actions) from {}",
        prepared.mission.name,
        prepared.mission.actions.len(),
        plan.mission.display()
    );
    if let Some(line) = prepared.world_line() {
        println!("{line}");
    }
    if let Some(line) = start_line {
        println!("{line}");
    }
}

/// A fault that names nothing is refused before anything runs.
async fn refuse_faults(prepared: &Prepared, options: &RunOptions) -> anyhow::Result<()> {
    match prepared.node.check_faults(&prepared.mission, options).await {
        Ok(()) => Ok(()),
        Err(NodeError::Fault { spec, error }) => {
            Err(BadInput(format!("--fault {spec}: {error}")).into())
        }
        Err(e @ NodeError::NodeChaos(_)) => Err(BadInput(e.to_string()).into()),
        Err(e) => Err(e.into()),
    }
}

/// A run dispatched on a node that runs no desk is refused before it starts.
fn refuse_dispatch_without_desk(options: &RunOptions) -> Result<(), BadInput> {
    let Some(on) = options.dispatched_on() else {
        return Ok(());
    };
    let desks = marie::registry::lookup(
        marie::registry::ModuleKind::Dispatcher,
        marie::cluster::node::desk::DESK_NAME,
    );
    if desks.iter().any(|d| d.node == on) {
        return Ok(());
    }
    let nodes: Vec<String> = desks.iter().map(|d| d.node.clone()).collect();
    Err(BadInput(format!(
        "--dispatch-on {on}: that node runs no dispatcher desk (`dispatcher = \
         \"active\"` or `\"standby\"` in its config); {}",
        match nodes.is_empty() {
            true => "no node of this cluster runs one".to_string(),
            false => format!("these do: {}", nodes.join(", ")),
        }
    )))
}
