//! `marie up --run MISSION`: the mission run on the cluster from this process, as `marie run
//! --join` would run it — with the files `up` read, its node processes and node chaos, and
//! one Ctrl-C watch for both.

use super::plan::UpPlan;
use super::UpArgs;
use crate::cli::args::RobotArgs;
use crate::cli::join::JoinArgs;
use crate::cli::run::{MissionOver, RunArgs};
use crate::cli::signal::Shutdown;
use marie::cluster::fault::{NodeChaos, NodeProcesses};
use marie::cluster::layout::ClusterLayout;
use marie::run::FileRole;
use std::path::Path;
use std::process::ExitCode;

/// Run `mission` on the cluster; a Ctrl-C before the mission ended stops it (exit 1), one
/// after it is the run's (it closes the run's page).
pub(super) async fn run_mission(
    args: &UpArgs,
    plan: &UpPlan,
    mission: &Path,
    processes: NodeProcesses,
) -> anyhow::Result<ExitCode> {
    // one Ctrl-C watch for up and its run, from before the run: a Ctrl-C between the
    // run's last line and its page's wait is heard by both
    let stop = Shutdown::watch(false);
    let run = run_flags(
        args,
        plan,
        mission,
        processes,
        MissionOver::heard_by(stop.clone()),
    );
    if let Some(node) = &run.dispatch_on {
        let standbys = plan.layout.standby_nodes();
        println!(
            "the run is dispatched on {node}{}",
            match standbys.is_empty() {
                true => " (no standby: its loss ends the run)".to_string(),
                false => format!(", standby on {}", standbys.join(", ")),
            }
        );
    }
    let over = run.mission_over.clone();
    let run = crate::cli::run::run(run);
    tokio::pin!(run);
    tokio::select! {
        biased;
        result = &mut run => result,
        signal = stop.wait() => {
            if over.is_set() {
                // the mission is over: the run heard the same Ctrl-C (with --monitor it was
                // waiting for it to close its page) and ends with the mission's outcome
                run.await
            } else {
                println!("stopping the cluster ({signal}) before the mission ended");
                Ok(ExitCode::from(1))
            }
        }
    }
}

/// The flags of `marie run --join` that run `mission` on `up`'s cluster.
fn run_flags(
    args: &UpArgs,
    plan: &UpPlan,
    mission: &Path,
    processes: NodeProcesses,
    mission_over: MissionOver,
) -> RunArgs {
    let layout = &plan.layout;
    RunArgs {
        explain: false,
        json: false,
        mission: Some(mission.to_path_buf()),
        replay: None,
        read_by_up: std::iter::once((FileRole::Cluster, args.cluster.clone()))
            .chain(
                layout
                    .nodes
                    .iter()
                    .map(|n| (FileRole::Node, n.path.clone())),
            )
            .collect(),
        robot: RobotArgs {
            world: args.world.clone(),
            seed: args.seed.or(layout.seed),
            node: None,
            data_dir: None,
        },
        data_dir: None,
        report: args.report.clone(),
        events: args.events.clone(),
        mcap: args.mcap.clone(),
        svg: args.svg.clone(),
        speed: Some(plan.speed),
        faults: args.faults.clone(),
        chaos: None,
        chaos_dms: false,
        node_chaos: args
            .chaos_nodes
            .map(|seed| Box::new(NodeChaos::new(seed, cart_nodes(layout)))),
        monitor: args.monitor,
        allow_faults: args.allow_faults,
        node_processes: processes,
        mission_over,
        // a node that says `dispatcher = "active"` runs the dispatcher: it can be lost
        // like any other, and its standbys take the run over
        dispatch_on: layout.dispatch_node().map(str::to_string),
        // a cluster of its own: the cart is at the world's start
        from_start: false,
        cluster: JoinArgs {
            join: Some(plan.launches[0].listen),
            cookie: Some(layout.cookie.clone()),
            tls_cert: None,
            tls_key: None,
            tls_ca: None,
            tls_server_name: None,
        },
    }
}

/// The nodes that run the cart's drivers: a node chaos spares them (their loss is the
/// robot's).
fn cart_nodes(layout: &ClusterLayout) -> Vec<String> {
    layout
        .nodes
        .iter()
        .filter(|n| n.config.simulation.as_ref().is_some_and(|s| s.drivers))
        .map(|n| n.config.name.clone())
        .collect()
}
