//! What `marie run`'s command line asks for, checked before anything starts: the mission or
//! the report replayed, the node and its robot, the outputs, the pace, the faults and chaos,
//! the live page, the cluster joined.
//!
//! Every refusal that needs no node is made here (exit 2), before a pacer, a node or a file
//! writer starts. What only a started node can say — a picture without a robot, a fault
//! that names nothing, a node without a dispatcher desk — is refused by the session
//! ([`super::ready`]) before the mission runs.

use super::flags::RunArgs;
use super::{KeptReport, MissionOver};
use crate::cli::args::{RobotArgs, MAX_SPEED};
use crate::cli::error::BadInput;
use crate::cli::files;
use crate::cli::join::Joining;
use crate::cli::output::Progress;
use crate::cli::replay::{Planned, Replay};
use marie::clock::{Paced, Pacer};
use marie::cluster::fault::{Chaos, FaultSpec, NodeChaos, NodeProcesses};
use marie::cluster::node::RunOptions;
use marie::run::FileRole;
use std::net::SocketAddr;
use std::path::PathBuf;

/// A run as asked for, checked.
pub(super) struct Plan {
    /// The mission file: the command line's, or the replayed report's written out.
    pub(super) mission: PathBuf,
    /// The report replayed, its files written out.
    pub(super) replay: Option<Replay>,
    /// The node, the world and the seed (a replay's own), and `--data-dir`.
    pub(super) robot: RobotArgs,
    /// The files `marie up` read to start the run's nodes, for the provenance.
    pub(super) read_by_up: Vec<(FileRole, PathBuf)>,
    /// The files to write.
    pub(super) outputs: Outputs,
    /// How the run's lines are printed.
    pub(super) progress: Progress,
    /// The cluster joined, with `--join`.
    pub(super) joining: Option<Joining>,
    /// `--speed`, as given.
    speed: Option<f64>,
    /// The faults, the chaos, the node processes, the node dispatched on (the provenance
    /// is added once the node has started and read the files).
    pub(super) options: RunOptions,
    /// `--from-start`.
    pub(super) from_start: bool,
    /// The live page, with `--monitor`.
    pub(super) monitor: Option<MonitorPlan>,
    /// Set once the mission has ended.
    pub(super) mission_over: MissionOver,
    /// Where the report is left for whoever ran the run (`marie up --runs`).
    pub(super) kept: KeptReport,
}

/// The files a run writes, each checked writable before it starts: a run must not end in a
/// report it cannot write.
pub(super) struct Outputs {
    /// `--report`.
    pub(super) report: Option<PathBuf>,
    /// `--events`.
    pub(super) events: Option<PathBuf>,
    /// `--mcap`.
    pub(super) mcap: Option<PathBuf>,
    /// `--svg`.
    pub(super) svg: Option<PathBuf>,
}

/// The live page of `--monitor`.
pub(super) struct MonitorPlan {
    /// Where it is served.
    pub(super) listen: SocketAddr,
    /// `--allow-faults`.
    pub(super) allow_faults: bool,
    /// `--allow-changes`.
    pub(super) allow_changes: bool,
    /// The node processes its faults may stop (`marie up`'s children).
    pub(super) processes: NodeProcesses,
}

/// The faults and chaos a run injects: the command line's, or a replayed report's.
struct Faults {
    faults: Vec<FaultSpec>,
    chaos: Option<u64>,
    chaos_dms: bool,
}

impl Plan {
    /// Check `flags` — the replayed report, the mission, `--join`, the outputs — and plan
    /// the run; a refusal is [`BadInput`] (exit 2).
    pub(super) fn new(flags: RunArgs) -> anyhow::Result<Plan> {
        let mut robot = flags.robot;
        // a replay: the report's files written out, its seed, its command's faults and chaos
        let replay = flags.replay.map(|p| Replay::load(&p)).transpose()?;
        let (mission, faults) = match &replay {
            Some(r) => (r.mission.clone(), replayed(r, &mut robot)),
            None => (
                flags.mission.ok_or_else(|| {
                    BadInput("a mission file is needed (or --replay REPORT.json)".into())
                })?,
                Faults {
                    faults: flags.faults,
                    chaos: flags.chaos,
                    chaos_dms: flags.chaos_dms,
                },
            ),
        };
        robot.data_dir = flags.data_dir;
        let joining = flags
            .cluster
            .joining("run", &robot, flags.speed.unwrap_or(1.0))?;
        let outputs = Outputs {
            report: flags.report,
            events: flags.events,
            mcap: flags.mcap,
            svg: flags.svg,
        };
        outputs.check()?;
        let options = faults
            .options(flags.node_chaos)
            .node_processes(flags.node_processes.clone());
        Ok(Plan {
            mission,
            replay,
            robot,
            read_by_up: flags.read_by_up,
            outputs,
            progress: match (flags.explain, flags.json) {
                (true, true) => Progress::ChoicesAsJson,
                (true, false) => Progress::Explained,
                _ => Progress::Lines,
            },
            joining,
            speed: flags.speed,
            options: match flags.dispatch_on {
                Some(node) => options.dispatch_on(node),
                None => options,
            },
            from_start: flags.from_start,
            monitor: flags.monitor.map(|listen| MonitorPlan {
                listen,
                allow_faults: flags.allow_faults,
                allow_changes: flags.allow_changes,
                processes: flags.node_processes,
            }),
            mission_over: flags.mission_over,
            kept: flags.kept,
        })
    }

    /// Whether the run's lines go to stdout (all but `--explain --json`'s choices).
    pub(super) fn says(&self) -> bool {
        self.progress != Progress::ChoicesAsJson
    }

    /// Whether the run is dispatched on another node (`--dispatch-on`): its dispatcher's
    /// events come to this node's bus, not (again) with the other nodes' events.
    pub(super) fn dispatched_elsewhere(&self) -> bool {
        self.options.dispatched_on().is_some()
    }

    /// Hold the mission clock back to `--speed`, from now until dropped.
    ///
    /// The runtime's paused clock is the mission clock (the node's "real" clock reads it);
    /// the pacer only holds it back. A member of a cluster runs on the cluster's wall clock
    /// instead: no pacer.
    pub(super) fn pace(&self) -> Option<Paced> {
        self.joining
            .is_none()
            .then(|| Pacer::new(self.speed.unwrap_or(f64::INFINITY)).spawn())
    }

    /// The speed the provenance names: `--speed` (default `max`), or the cluster's.
    pub(super) fn provenance_speed(&self) -> f64 {
        match &self.joining {
            None => self.speed.unwrap_or(MAX_SPEED),
            Some(j) => j.speed,
        }
    }
}

/// A replayed report's world, node and seed put in `robot`, its planned faults and chaos
/// read from its command line (what cannot be read is warned of).
fn replayed(replay: &Replay, robot: &mut RobotArgs) -> Faults {
    robot.world = replay.world.clone();
    robot.node = replay.node.clone();
    robot.seed = replay.provenance.seed;
    let (planned, warnings) = replay.planned();
    for warning in warnings {
        eprintln!("marie: {warning}");
    }
    let Planned {
        faults,
        chaos,
        chaos_dms,
    } = planned;
    Faults {
        faults,
        chaos,
        chaos_dms,
    }
}

impl Faults {
    /// The run's options with these faults, the chaos, and the node chaos of `marie up`.
    fn options(self, node_chaos: Option<Box<NodeChaos>>) -> RunOptions {
        let mut options = RunOptions::new().faults(self.faults);
        if let Some(seed) = self.chaos {
            let chaos = Chaos::new(seed);
            options = options.chaos(match self.chaos_dms {
                true => chaos.with_datamanagers(),
                false => chaos,
            });
        }
        if let Some(chaos) = node_chaos {
            options = options.node_chaos(*chaos);
        }
        options
    }
}

impl Outputs {
    /// Refuse an output that cannot be written.
    fn check(&self) -> Result<(), BadInput> {
        if let Some(p) = &self.report {
            files::output("--report", p)?;
        }
        if let Some(p) = &self.svg {
            files::output("--svg", p)?;
        }
        if let Some(p) = &self.events {
            files::output("--events", p)?;
        }
        if let Some(p) = &self.mcap {
            crate::cli::mcap::output("--mcap", p)?;
        }
        Ok(())
    }
}
