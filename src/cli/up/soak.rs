//! `marie up CLUSTER --run MISSION --runs N`: the mission run N times on one kept-up
//! cluster — a soak. The first run starts where the cluster does, every next one puts the
//! cart back at the world's start; the nodes are restarted as the cluster file says
//! meanwhile, and `--chaos-nodes` strikes on one schedule across the runs. Each run prints
//! its lines, outcome and verdict as a single run does, then how the soak stands; with
//! node chaos every fault's fate is said once known ([`super::catch_up`]); at the end a
//! summary: runs failed, faults, records lost, epochs obeyed late, collisions and each
//! node's resident memory at the start and after every run, and whether it is flat
//! ([`super::memory`]). A failed run does not end the soak (a
//! Ctrl-C does, with the summary so far).

use super::catch_up::{CatchUp, Fate};
use super::memory::{mib, Memory, Readings, FLAT_WITHIN};
use super::mission::{node_chaos, run_mission, Turn};
use super::plan::UpPlan;
use super::probe::{self, ProbeChild};
use super::supervisor::Restarted;
use super::UpArgs;
use crate::cli::error::BadInput;
use crate::cli::run::KeptReport;
use crate::cli::signal::Shutdown;
use marie::cluster::fault::NodeProcesses;
use marie::dm::probe::ProbeVerdict;
use marie::report::RunReport;
use marie::run::{FaultKind, Outcome};
use marie_missions::robot::RobotReport;
use std::collections::BTreeMap;
use std::path::Path;
use std::process::ExitCode;
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::mpsc;

/// Run `mission` `runs` times on the cluster, then sum up; exit 0 when the soak's goal
/// holds (every run succeeded, nothing acknowledged lost, no epoch obeyed late, no
/// collision) and it was not cut short.
pub(super) async fn soak(
    args: &UpArgs,
    plan: &UpPlan,
    mission: &Path,
    processes: NodeProcesses,
    restarted: mpsc::UnboundedReceiver<Restarted>,
    runs: u32,
    probe: Option<ProbeChild>,
) -> anyhow::Result<ExitCode> {
    let names: Vec<String> = plan.launches.iter().map(|l| l.name.clone()).collect();
    let mut memory = Readings {
        start: Memory::of(&processes, &names),
        after: Vec::new(),
    };
    // one Ctrl-C watch for the whole soak and each of its runs
    let stop = Shutdown::watch(false);
    let chaos = node_chaos(args, &plan.layout);
    let run_now = Arc::new(AtomicU32::new(1));
    let watch = chaos
        .as_ref()
        .map(|c| CatchUp::start(c.watch(), restarted, run_now.clone(), plan.speed));
    let mut tallies = Vec::new();
    let mut interrupted = None;
    for number in 1..=runs {
        run_now.store(number, Ordering::SeqCst);
        println!(
            "run {number} of {runs}{}",
            if number > 1 {
                ", the cart put back at the world's start"
            } else {
                ""
            }
        );
        let turn = Turn {
            number,
            of: runs,
            stop: stop.clone(),
            chaos: chaos.clone(),
            kept: KeptReport::default(),
        };
        let ran = match start_run(args, plan, mission, &processes, &turn).await {
            Ok(code) => Ok(code == ExitCode::SUCCESS),
            // the first run refuses what every run would (bad input): as `--run` alone
            Err(e) if number == 1 => return Err(e),
            Err(e) => {
                println!("run {number} of {runs} could not run: {e:#}");
                Err(format!("{e:#}"))
            }
        };
        tallies.push(Tally::of(number, ran, turn.kept.take()));
        // stored records grow to their classes' retention bound, then level off: a
        // reading after every run tells that from a leak, which grows on
        memory.after.push(Memory::of(&processes, &names));
        if let Some(signal) = stop.heard() {
            interrupted = Some(signal);
            break;
        }
        println!("{}", so_far(&tallies, runs));
    }
    let fates = match watch {
        Some(w) => w.finish(plan).await,
        None => Vec::new(),
    };
    let probe = match probe {
        Some(p) => Some(p.finish().await),
        None => None,
    };
    let summary = Summary {
        mission: tallies
            .iter()
            .find_map(|t| t.mission.clone())
            .unwrap_or_else(|| mission.display().to_string()),
        runs,
        tallies,
        fates,
        memory,
        interrupted,
        probe,
    };
    for line in summary.lines() {
        println!("{line}");
    }
    Ok(match summary.goal() && interrupted.is_none() {
        true => ExitCode::SUCCESS,
        false => ExitCode::from(1),
    })
}

/// How long a run refused before its mission ran (the node it is dispatched on frozen or cut
/// off at that moment by the soak's last fault, its desk out of the registry) is tried again
/// before it counts as failed.
const START_WITHIN: Duration = Duration::from_secs(60);
/// The pause between two tries.
const START_RETRY: Duration = Duration::from_secs(1);

/// Run `turn`; a run after the first refused before its mission ran (bad input now: a fault
/// of the soak may have the node it is dispatched on out at that moment; the first run
/// refuses what every run would) is tried again every [`START_RETRY`] for [`START_WITHIN`] —
/// a refused run ran nothing, so nothing of it is hidden — unless a Ctrl-C came.
async fn start_run(
    args: &UpArgs,
    plan: &UpPlan,
    mission: &Path,
    processes: &NodeProcesses,
    turn: &Turn,
) -> anyhow::Result<ExitCode> {
    let until = std::time::Instant::now() + START_WITHIN;
    loop {
        match run_mission(args, plan, mission, processes.clone(), turn).await {
            Err(e)
                if turn.number > 1
                    && e.downcast_ref::<BadInput>().is_some()
                    && turn.kept.is_empty()
                    && turn.stop.heard().is_none()
                    && std::time::Instant::now() < until =>
            {
                println!(
                    "run {} of {} could not start: {e:#}; trying again in {} s",
                    turn.number,
                    turn.of,
                    START_RETRY.as_secs()
                );
                tokio::time::sleep(START_RETRY).await;
            }
            ended => return ended,
        }
    }
}

/// One run, as the summary counts it.
#[derive(Clone, Debug, Default, PartialEq)]
struct Tally {
    number: u32,
    /// The mission's name.
    mission: Option<String>,
    /// It succeeded (the cart inside the goal, with a robot), its outputs written.
    succeeded: bool,
    /// Why not.
    why: String,
    /// Mission time, ms.
    duration_ms: u64,
    /// Acknowledged records checked at its end.
    acknowledged: u64,
    /// Of them lost (`None`: no check).
    lost: Option<u64>,
    /// Epochs the cart obeyed after their replacement was bound (`None`: not said).
    obeyed_late: Option<u64>,
    /// Collisions (`None`: no robot said).
    collisions: Option<u64>,
    /// Commands the cart refused by epoch.
    refused: u64,
}

impl Tally {
    /// Run `number`'s tally: `ran` is whether it exited 0, or why it could not run.
    fn of(number: u32, ran: Result<bool, String>, report: Option<RunReport>) -> Tally {
        let mut t = Tally {
            number,
            ..Tally::default()
        };
        let Some(report) = report else {
            t.why = match ran {
                Err(why) => why,
                Ok(_) => "it ended without a report (stopped)".to_string(),
            };
            return t;
        };
        let cart = RobotReport::of(&report);
        t.mission = Some(report.mission.clone());
        t.duration_ms = report.duration_ms;
        t.acknowledged = report.dm_checks.iter().map(|c| c.acknowledged).sum();
        t.lost = report.acknowledged_lost;
        t.obeyed_late = cart.obeyed_late.as_ref().map(|l| l.len() as u64);
        t.collisions = cart.collisions;
        t.refused = cart
            .refused_commands
            .as_ref()
            .map_or(0, |r| r.values().sum());
        let inside = cart.inside_goal != Some(false);
        t.succeeded = report.outcome == Outcome::Succeeded && inside && ran == Ok(true);
        t.why = match (report.outcome, inside, &ran) {
            (Outcome::Failed, _, _) => report.reason.clone(),
            (_, false, _) => "the cart ended outside the goal area".to_string(),
            (_, _, Ok(false)) => "an output could not be written".to_string(),
            _ => String::new(),
        };
        t
    }

    /// Whether it holds the soak's goal: succeeded, checked with nothing lost, no epoch
    /// obeyed late, no collision.
    fn holds(&self) -> bool {
        self.succeeded
            && self.lost == Some(0)
            && self.obeyed_late == Some(0)
            && self.collisions.unwrap_or(0) == 0
    }
}

/// How the soak stands after a run: `runs so far: 3 of 30, 3 succeeded, 0 failed`.
fn so_far(tallies: &[Tally], runs: u32) -> String {
    let ok = tallies.iter().filter(|t| t.succeeded).count();
    format!(
        "runs so far: {} of {runs}, {ok} succeeded, {} failed",
        tallies.len(),
        tallies.len() - ok
    )
}

/// The end of a soak.
struct Summary {
    mission: String,
    runs: u32,
    tallies: Vec<Tally>,
    fates: Vec<Fate>,
    /// Every node's memory at the start and after each run.
    memory: Readings,
    interrupted: Option<&'static str>,
    /// With `--probe`: its verdict, or why there is none.
    probe: Option<Result<ProbeVerdict, String>>,
}

impl Summary {
    /// Whether the goal holds: every run ran and held it, the probe (with `--probe`)
    /// found no stale read and its newest write, and every node's memory is flat.
    fn goal(&self) -> bool {
        self.tallies.len() == self.runs as usize
            && self.tallies.iter().all(Tally::holds)
            && self
                .probe
                .as_ref()
                .is_none_or(|p| p.as_ref().is_ok_and(ProbeVerdict::holds))
            && self.memory_flat()
    }

    fn lines(&self) -> Vec<String> {
        let mut lines = vec![self.runs_line()];
        for t in self.tallies.iter().filter(|t| !t.succeeded) {
            lines.push(format!("  run {} FAILED: {}", t.number, t.why));
        }
        if !self.fates.is_empty() {
            lines.push(self.faults_line());
        }
        lines.push(self.records_line());
        if let Some(p) = &self.probe {
            lines.extend(probe::lines(p));
        }
        lines.push(self.memory_line());
        lines.push(format!(
            "soak goal (every run succeeded, 0 acknowledged records lost, 0 epochs obeyed \
             from an old epoch, 0 collisions{}, node memory flat): {}",
            if self.probe.is_some() {
                ", 0 stale reads"
            } else {
                ""
            },
            if self.goal() { "holds" } else { "NOT met" }
        ));
        lines
    }

    /// `soak of docking: 30 runs, 30 succeeded, 0 failed, 33.1 min of mission time`.
    fn runs_line(&self) -> String {
        let ok = self.tallies.iter().filter(|t| t.succeeded).count();
        let ms: u64 = self.tallies.iter().map(|t| t.duration_ms).sum();
        let mut line = format!(
            "soak of {}: {} runs, {ok} succeeded, {} failed, {:.1} min of mission time",
            self.mission,
            self.tallies.len(),
            self.tallies.len() - ok,
            ms as f64 / 60_000.0
        );
        if let Some(signal) = self.interrupted {
            line += &format!(" (cut short by {signal} after run {})", self.tallies.len());
        }
        line
    }

    /// The node faults: how many of each kind, when their nodes were back and caught up.
    fn faults_line(&self) -> String {
        let mut kinds: BTreeMap<String, u64> = BTreeMap::new();
        for f in self.fates.iter().filter(|f| f.struck.outcome.is_ok()) {
            *kinds.entry(f.struck.strike.kind.to_string()).or_default() += 1;
        }
        let injected: u64 = kinds.values().sum();
        let not_injected = self.fates.len() as u64 - injected;
        let by_kind: Vec<String> = kinds.iter().map(|(k, n)| format!("{k} {n}")).collect();
        let restarts: Vec<Duration> = self
            .fates
            .iter()
            .filter(|f| f.struck.strike.kind == FaultKind::StopNode)
            .filter_map(|f| f.back_after)
            .collect();
        let caught: Vec<Duration> = self
            .fates
            .iter()
            .filter_map(|f| f.caught_up_after)
            .collect();
        let hit_again = self
            .fates
            .iter()
            .filter(|f| f.caught_up_after.is_none() && f.hit_again_by.is_some())
            .count();
        let unseen = self
            .fates
            .iter()
            .filter(|f| f.struck.outcome.is_ok() && f.caught_up_after.is_none())
            .count()
            - hit_again;
        format!(
            "node faults: {injected} ({}), {not_injected} not injected; nodes restarted {} \
             times, {} after their process ended; caught up {} after they were back; {unseen} \
             not seen caught up, {hit_again} hit again first",
            by_kind.join(", "),
            restarts.len(),
            spread(&restarts),
            spread(&caught),
        )
    }

    /// What the runs' checks found.
    fn records_line(&self) -> String {
        let lost: u64 = self.tallies.iter().filter_map(|t| t.lost).sum();
        let acknowledged: u64 = self.tallies.iter().map(|t| t.acknowledged).sum();
        let late: u64 = self.tallies.iter().filter_map(|t| t.obeyed_late).sum();
        let collisions: u64 = self.tallies.iter().filter_map(|t| t.collisions).sum();
        let refused: u64 = self.tallies.iter().map(|t| t.refused).sum();
        let unchecked = self.tallies.iter().filter(|t| t.lost.is_none()).count();
        let unsaid = self
            .tallies
            .iter()
            .filter(|t| t.obeyed_late.is_none())
            .count();
        let mut line = format!(
            "records: {lost} of {acknowledged} acknowledged records lost, {late} epochs obeyed \
             from an old epoch, {collisions} collisions, {refused} commands refused by epoch"
        );
        if unchecked > 0 {
            line += &format!(", {unchecked} runs without a check of their datamanagers");
        }
        if unsaid > 0 {
            line += &format!(", {unsaid} runs whose cart did not say what it obeyed");
        }
        line
    }

    /// `node memory (VmRSS at the soak's start → after run 7 → after run 18 → its end;
    /// median of runs 8–18 → of runs 19–30): cart 17.9 → 18.2 → 18.3 → 18.4 MiB (18.2 →
    /// 18.3 MiB, flat), …` (start and end only for a soak of fewer than 4 runs; see
    /// `memory.rs` for when memory is flat).
    fn memory_line(&self) -> String {
        let mut restarted: BTreeMap<&str, u64> = BTreeMap::new();
        for f in self
            .fates
            .iter()
            .filter(|f| f.struck.strike.kind == FaultKind::StopNode && f.struck.outcome.is_ok())
        {
            *restarted.entry(f.struck.strike.node()).or_default() += 1;
        }
        let nodes: Vec<String> = self
            .memory
            .start
            .0
            .keys()
            .map(|node| {
                let trend = self.memory.trend(node);
                let read: Vec<String> = trend.marks.iter().map(|(_, kib)| mib(*kib)).collect();
                let medians = match trend.medians {
                    Some((first, second)) => format!(
                        " ({} → {}, {})",
                        mib(Some(first)),
                        mib(Some(second)),
                        if trend.flat() { "flat" } else { "GROWING" }
                    ),
                    None => String::new(),
                };
                let again = match restarted.get(node.as_str()) {
                    Some(n) => format!(" (killed {n} times: its latest process)"),
                    None => String::new(),
                };
                format!("{node} {}{medians}{again}", read.join(" → "))
            })
            .collect();
        let marks = self.memory.mark_words().join(" → ");
        let halves = match self.memory.halves() {
            Some((from, second, last)) => format!(
                "; median of runs {from}–{} → of runs {second}–{last}, flat within {:.0} %",
                second - 1,
                FLAT_WITHIN * 100.0
            ),
            None => String::new(),
        };
        format!(
            "node memory (VmRSS at {marks}{halves}): {}",
            nodes.join(", ")
        )
    }

    /// Whether every node's memory is flat (`memory.rs`).
    fn memory_flat(&self) -> bool {
        self.memory
            .start
            .0
            .keys()
            .all(|node| self.memory.trend(node).flat())
    }
}

/// `0.12–0.31 s (median 0.18 s)`, or `-` for none.
fn spread(times: &[Duration]) -> String {
    if times.is_empty() {
        return "-".to_string();
    }
    let mut sorted = times.to_vec();
    sorted.sort();
    let median = sorted[sorted.len() / 2];
    format!(
        "{:.2}–{:.2} s (median {:.2} s)",
        sorted[0].as_secs_f64(),
        sorted[sorted.len() - 1].as_secs_f64(),
        median.as_secs_f64()
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_run_holds_the_goal_only_when_it_succeeded_with_nothing_lost_or_obeyed_late() {
        let good = Tally {
            number: 1,
            succeeded: true,
            lost: Some(0),
            obeyed_late: Some(0),
            collisions: Some(0),
            ..Tally::default()
        };
        assert!(good.holds());
        for bad in [
            Tally {
                succeeded: false,
                ..good.clone()
            },
            Tally {
                lost: Some(1),
                ..good.clone()
            },
            Tally {
                lost: None,
                ..good.clone()
            },
            Tally {
                obeyed_late: None,
                ..good.clone()
            },
            Tally {
                collisions: Some(2),
                ..good.clone()
            },
        ] {
            assert!(!bad.holds(), "{bad:?}");
        }
        // a run that could not run
        let failed = Tally::of(4, Err("cannot join".into()), None);
        assert!(
            !failed.succeeded && failed.why == "cannot join",
            "{failed:?}"
        );
        let summary = Summary {
            mission: "docking".into(),
            runs: 2,
            tallies: vec![good.clone(), failed],
            fates: Vec::new(),
            memory: Readings::default(),
            interrupted: None,
            probe: None,
        };
        assert!(!summary.goal());
        let lines = summary.lines();
        assert!(
            lines[0].starts_with("soak of docking: 2 runs, 1 succeeded, 1 failed"),
            "{lines:?}"
        );
        assert_eq!(lines[1], "  run 4 FAILED: cannot join");
        assert!(lines.last().unwrap().ends_with("NOT met"));
        // every run held it, but the soak was cut short
        let short = Summary {
            runs: 3,
            tallies: vec![good.clone()],
            ..summary
        };
        assert!(!short.goal());
        // every run held it, and the probe's verdict decides
        let verdict = |stale: u64| ProbeVerdict {
            dm: "feature".into(),
            ran_ms: 1000,
            writes: 10,
            write_failures: 0,
            roads: [(
                "spare".to_string(),
                marie::dm::probe::RoadTally {
                    answered: 40,
                    stale,
                    ..Default::default()
                },
            )]
            .into_iter()
            .collect(),
            stale_reads: Vec::new(),
            read_back: Some(marie::dm::probe::ReadBack::Found),
            survivors: None,
        };
        let probed = |probe| Summary {
            mission: "docking".into(),
            runs: 1,
            tallies: vec![good.clone()],
            fates: Vec::new(),
            memory: Readings::default(),
            interrupted: None,
            probe: Some(probe),
        };
        let fresh = probed(Ok(verdict(0)));
        assert!(fresh.goal());
        assert!(
            fresh
                .lines()
                .iter()
                .any(|l| l.starts_with("reads: probe of feature") && l.contains("; 0 stale")),
            "{:?}",
            fresh.lines()
        );
        assert!(fresh
            .lines()
            .last()
            .unwrap()
            .contains("0 stale reads, node memory flat): holds"));
        assert!(!probed(Ok(verdict(1))).goal());
        let unread = probed(Err("the probe ended".into()));
        assert!(!unread.goal());
        assert!(unread
            .lines()
            .contains(&"reads: NOT checked: the probe ended".to_string()));
        // the memory line: its marks and halves once there are 4 runs, and a node that
        // grows on fails the goal
        let kib = |v: u64| Memory([("cart".to_string(), Some(v * 1024))].into_iter().collect());
        let soaked = |after: &[u64]| Summary {
            mission: "docking".into(),
            runs: after.len() as u32,
            tallies: (1..=after.len() as u32)
                .map(|n| Tally {
                    number: n,
                    ..good.clone()
                })
                .collect(),
            memory: Readings {
                start: kib(18),
                after: after.iter().map(|v| kib(*v)).collect(),
            },
            fates: Vec::new(),
            interrupted: None,
            probe: None,
        };
        let level = soaked(&[25, 30, 33, 34, 33, 34, 35, 34]);
        assert_eq!(
            level.memory_line(),
            "node memory (VmRSS at the soak's start → after run 2 → after run 5 → its end; \
             median of runs 3–5 → of runs 6–8, flat within 10 %): cart 18.0 MiB → 30.0 MiB → \
             33.0 MiB → 34.0 MiB (33.0 MiB → 34.0 MiB, flat)"
        );
        assert!(level.goal());
        let growing = soaked(&[20, 22, 24, 26, 28, 30, 32, 34]);
        assert!(growing
            .memory_line()
            .contains("(26.0 MiB → 32.0 MiB, GROWING)"));
        assert!(!growing.goal());
        assert!(growing
            .lines()
            .last()
            .unwrap()
            .contains("node memory flat): NOT met"));
        let two = soaked(&[25, 30]);
        assert_eq!(
            two.memory_line(),
            "node memory (VmRSS at the soak's start → its end): cart 18.0 MiB → 30.0 MiB"
        );
        assert_eq!(
            spread(&[Duration::from_millis(300), Duration::from_millis(100)]),
            "0.10–0.30 s (median 0.30 s)"
        );
    }
}
