//! What `marie up` does while its nodes run: wait for the registry to converge and list the
//! nodes, then run the mission (`--run`, `--runs` times) or serve the cluster — its page
//! with `--monitor`, the nodes' lines — until a signal.

use super::mission::{run_mission, Turn};
use super::nodes::{converged, Nodes};
use super::plan::UpPlan;
use super::probe::{self, ProbeChild};
use super::soak::soak;
use super::UpArgs;
use crate::cli::children::Line;
use crate::cli::monitor::ClusterWatch;
use crate::cli::netns::PrivateNet;
use marie::cluster::fault::NodeProcesses;
use std::process::ExitCode;
use tokio::sync::mpsc;

/// Everything between starting the nodes and stopping them.
pub(super) async fn serve(
    args: &UpArgs,
    plan: &UpPlan,
    nodes: &mut Nodes,
) -> anyhow::Result<ExitCode> {
    list_when_converged(plan, nodes).await?;
    let processes = nodes.processes(&plan.launches);
    let probe = match &args.probe {
        Some(dm) => Some(
            ProbeChild::start(plan, dm)
                .map_err(|e| anyhow::anyhow!("cannot start the probe of {dm}: {e}"))?,
        ),
        None => None,
    };
    match (&args.run, args.runs) {
        (Some(mission), Some(runs)) => {
            // the soak hears of every node restarted, for its faults' fates
            let (tell, restarted) = mpsc::unbounded_channel();
            nodes.supervise(plan, processes.clone(), Some(tell));
            soak(args, plan, mission, processes, restarted, runs, probe).await
        }
        (Some(mission), None) => {
            nodes.supervise(plan, processes.clone(), None);
            let turn = Turn::only(args, &plan.layout);
            let ran = run_mission(args, plan, mission, processes, &turn).await;
            let Some(probe) = probe else { return ran };
            let verdict = probe.finish().await;
            for line in probe::lines(&verdict) {
                println!("{line}");
            }
            match (ran, verdict) {
                (Ok(code), Ok(v)) if v.holds() => Ok(code),
                (Ok(_), _) => Ok(ExitCode::from(1)),
                (Err(e), _) => Err(e),
            }
        }
        (None, _) => {
            nodes.supervise(plan, processes.clone(), None);
            watch(args, plan, &mut nodes.lines, processes).await
        }
    }
}

/// Wait until the registry has converged, then say so with each node's address, pid and
/// modules.
async fn list_when_converged(plan: &UpPlan, nodes: &mut Nodes) -> anyhow::Result<()> {
    let listening = std::time::Instant::now();
    let total = nodes.modules();
    let listing = converged(plan, total).await?;
    let convergence = listening.elapsed();
    // the nodes' lines so far tell of the joins just summed up
    while nodes.lines.try_recv().is_ok() {}
    println!(
        "cluster {} up: {} nodes, {total} modules, speed {} (registry converged {:.2} s \
         after the last node listened)",
        plan.layout.path.display(),
        plan.launches.len(),
        plan.speed,
        convergence.as_secs_f64()
    );
    for (l, pid) in plan.launches.iter().zip(nodes.pids()) {
        let modules: Vec<String> = listing
            .iter()
            .filter(|i| i.node == l.name)
            .map(|i| format!("{} {}", i.kind.label(), i.name))
            .collect();
        println!(
            "  {} at {} (pid {pid}): {}",
            l.name,
            l.listen,
            modules.join(", ")
        );
    }
    Ok(())
}

/// No mission: serve the cluster's page with `--monitor`, print the nodes' lines, until a
/// signal or every node has exited.
async fn watch(
    args: &UpArgs,
    plan: &UpPlan,
    lines: &mut mpsc::UnboundedReceiver<Line>,
    processes: NodeProcesses,
) -> anyhow::Result<ExitCode> {
    let watching = match args.monitor {
        Some(listen) => {
            let options = PrivateNet::monitor_options(listen).allowing_changes(args.allow_changes);
            Some(
                ClusterWatch::start(
                    &plan.first_node(),
                    plan.speed,
                    options,
                    args.allow_faults,
                    processes,
                )
                .await?,
            )
        }
        None => None,
    };
    let result = wait_for_signal(lines).await;
    if let Some(w) = watching {
        w.stop().await;
    }
    result
}

/// Print the nodes' lines until SIGINT or SIGTERM (success) or every node has exited
/// (failure).
async fn wait_for_signal(lines: &mut mpsc::UnboundedReceiver<Line>) -> anyhow::Result<ExitCode> {
    let stop = crate::cli::signal::shutdown_signal(false);
    tokio::pin!(stop);
    println!("Ctrl-C stops the cluster");
    loop {
        tokio::select! {
            signal = &mut stop => {
                println!("stopping the cluster ({signal})");
                return Ok(ExitCode::SUCCESS);
            }
            line = lines.recv() => match line {
                Some(Line { node, text: Some(text) }) => println!("[{node}] {text}"),
                Some(Line { node, text: None }) => println!("[{node}] exited"),
                None => {
                    println!("every node has exited");
                    return Ok(ExitCode::from(1));
                }
            },
        }
    }
}
