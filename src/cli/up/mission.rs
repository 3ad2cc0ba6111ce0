//! `marie up --run MISSION`: the mission run on the cluster from this process, as `marie run
//! --join` would run it — with the files `up` read, its node processes and node chaos, and
//! one Ctrl-C watch for both. Under `--runs N` it is one [`Turn`] of several: from the
//! world's start after the first, its outputs numbered, the node chaos's one schedule
//! going on.

use super::plan::UpPlan;
use super::UpArgs;
use crate::cli::args::RobotArgs;
use crate::cli::join::JoinArgs;
use crate::cli::run::{KeptReport, MissionOver, RunArgs};
use crate::cli::signal::Shutdown;
use marie::cluster::fault::{NodeChaos, NodeProcesses};
use marie::cluster::layout::ClusterLayout;
use marie::run::FileRole;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;

/// One run of the mission among the runs `marie up` makes (one without `--runs`).
pub(super) struct Turn {
    /// Its number, from 1.
    pub(super) number: u32,
    /// How many runs in all (`--runs`; 1 without).
    pub(super) of: u32,
    /// The Ctrl-C watch of `up` and its runs, from before the first.
    pub(super) stop: Shutdown,
    /// The node chaos, one schedule for every run.
    pub(super) chaos: Option<NodeChaos>,
    /// Where the run leaves its report.
    pub(super) kept: KeptReport,
}

impl Turn {
    /// The one run of `marie up --run` without `--runs`: watching Ctrl-C from now on (a
    /// Ctrl-C between the run's last line and its page's wait is heard by both).
    pub(super) fn only(args: &UpArgs, layout: &ClusterLayout) -> Turn {
        Turn {
            number: 1,
            of: 1,
            stop: Shutdown::watch(false),
            chaos: node_chaos(args, layout),
            kept: KeptReport::default(),
        }
    }

    /// `path` as this run writes it: as given for a single run, else numbered
    /// (`report.json` → `report-3.json`).
    fn output(&self, path: &Option<PathBuf>) -> Option<PathBuf> {
        let path = path.as_ref()?;
        if self.of == 1 {
            return Some(path.clone());
        }
        Some(numbered(path, self.number))
    }
}

/// `dir/name.ext` → `dir/name-N.ext` (`name-N` without an extension).
pub(super) fn numbered(path: &Path, n: u32) -> PathBuf {
    let stem = path.file_stem().unwrap_or_default().to_string_lossy();
    let name = match path.extension() {
        Some(ext) => format!("{stem}-{n}.{}", ext.to_string_lossy()),
        None => format!("{stem}-{n}"),
    };
    path.with_file_name(name)
}

/// The node chaos `args` ask for: `--chaos-nodes SEED`, striking every `--chaos-every`.
pub(super) fn node_chaos(args: &UpArgs, layout: &ClusterLayout) -> Option<NodeChaos> {
    let seed = args.chaos_nodes?;
    let chaos = NodeChaos::new(seed, cart_nodes(layout));
    Some(match args.chaos_every {
        Some(Gaps(min, max)) => chaos.with_gaps(min, max),
        None => chaos,
    })
}

/// `--chaos-every MIN-MAX`: the gaps between two node faults, mission seconds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Gaps(pub(crate) Duration, pub(crate) Duration);

/// Parse `--chaos-every MIN-MAX` (`10-20`, `2.5-4`): seconds of mission time, above 0,
/// MIN at most MAX, at most a day.
pub(crate) fn parse_gaps(s: &str) -> Result<Gaps, String> {
    let bad = || {
        format!(
            "`{s}` is not MIN-MAX: two numbers of seconds of mission time, above 0, the \
             first at most the second (e.g. 10-20)"
        )
    };
    let (min, max) = s.split_once('-').ok_or_else(bad)?;
    let secs = |t: &str| -> Result<f64, String> {
        let v: f64 = t.trim().parse().map_err(|_| bad())?;
        match v.is_finite() && v > 0.0 && v <= marie::cluster::fault::MAX_FAULT_SECS {
            true => Ok(v),
            false => Err(bad()),
        }
    };
    let (min, max) = (secs(min)?, secs(max)?);
    if min > max {
        return Err(bad());
    }
    Ok(Gaps(
        Duration::from_secs_f64(min),
        Duration::from_secs_f64(max),
    ))
}

/// Run `mission` on the cluster; a Ctrl-C before the mission ended stops it (exit 1), one
/// after it is the run's (it closes the run's page).
pub(super) async fn run_mission(
    args: &UpArgs,
    plan: &UpPlan,
    mission: &Path,
    processes: NodeProcesses,
    turn: &Turn,
) -> anyhow::Result<ExitCode> {
    let stop = turn.stop.clone();
    let run = run_flags(
        args,
        plan,
        mission,
        processes,
        MissionOver::heard_by(stop.clone()),
        turn,
    );
    if let (Some(node), 1) = (&run.dispatch_on, turn.number) {
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
    turn: &Turn,
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
        report: turn.output(&args.report),
        events: turn.output(&args.events),
        mcap: turn.output(&args.mcap),
        svg: turn.output(&args.svg),
        speed: Some(plan.speed),
        faults: args.faults.clone(),
        chaos: None,
        chaos_dms: false,
        // a clone shares the schedule: it goes on from the run before
        node_chaos: turn.chaos.clone().map(Box::new),
        monitor: args.monitor,
        allow_faults: args.allow_faults,
        allow_changes: args.allow_changes,
        node_processes: processes,
        mission_over,
        kept: turn.kept.clone(),
        // a node that says `dispatcher = "active"` runs the dispatcher: it can be lost
        // like any other, and its standbys take the run over
        dispatch_on: layout.dispatch_node().map(str::to_string),
        // a cluster of its own: the cart is at the world's start for the first run; the
        // next ones put it back there
        from_start: turn.number > 1,
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gaps_parse_and_outputs_are_numbered_per_run() {
        let secs = Duration::from_secs_f64;
        assert_eq!(parse_gaps("10-20"), Ok(Gaps(secs(10.0), secs(20.0))));
        assert_eq!(parse_gaps(" 2.5 - 4 "), Ok(Gaps(secs(2.5), secs(4.0))));
        assert_eq!(parse_gaps("3-3"), Ok(Gaps(secs(3.0), secs(3.0))));
        for bad in ["10", "20-10", "0-5", "-1-5", "a-b", "1-inf", "1-100000"] {
            let err = parse_gaps(bad).unwrap_err();
            assert!(err.contains("is not MIN-MAX"), "{bad}: {err}");
        }
        assert_eq!(
            numbered(Path::new("out/report.json"), 3),
            PathBuf::from("out/report-3.json")
        );
        assert_eq!(
            numbered(Path::new("events"), 12),
            PathBuf::from("events-12")
        );
    }
}
