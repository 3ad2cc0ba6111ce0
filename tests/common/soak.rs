//! The soak of a cluster under faults that keep coming (issue 43, point 6), shared by
//! `benches/soak.rs` (`scripts/soak`: the size and the table) and `tests/soak.rs`
//! (CI: a short schedule).
//!
//! A soak is one `marie up CLUSTER --run MISSION --runs N --chaos-nodes SEED`: the mission
//! run N times on one kept-up cluster while a seeded schedule stops, freezes and cuts off
//! random nodes other than the cart's, each stopped node restarted by `up`. Everything is
//! read from what `up` writes: each run's report (`report-K.json`: outcome, acknowledged
//! records lost, epochs obeyed late, collisions) and its lines — one per fault once its
//! fate is known (`fault 7 (stop-node features, run 3 at 12.4 s): back 0.21 s after it
//! struck, caught up 0.84 s after it was back`: for a kill, "back" is the supervisor's
//! restart, measured from the process's end; "caught up" is when `up`, probing the
//! replicas every 100 ms, first saw every replica on the node counted at lag 0 by its
//! leader) and the summary's memory line (VmRSS of every node at the start and after the runs, and
//! whether it stayed flat).

use super::acceptance::Running;
use serde_json::Value;
use std::fmt::Write as _;
use std::path::Path;
use std::time::Duration;

/// The cluster file the soak runs on (the thesis' layout: the features, operations and
/// spare nodes each hold a replica of every datamanager).
pub(crate) const CLUSTER: &str = "missions/clusters/thesis.toml";
/// The mission it runs.
pub(crate) const MISSION: &str = "missions/docking.toml";
/// The datamanager `up --probe` writes into and reads back while the runs go on.
pub(crate) const PROBED: &str = "feature";

/// What a soak is asked for.
#[derive(Clone, Debug)]
pub(crate) struct SoakArgs {
    /// Runs of the mission.
    pub runs: u32,
    /// The node chaos's seed.
    pub seed: u64,
    /// The cluster's speed.
    pub speed: f64,
    /// The gaps between two faults, mission seconds (`None`: `up`'s 10 to 20).
    pub every: Option<(f64, f64)>,
}

impl SoakArgs {
    /// Start it, writing into `dir`; stopped if it runs past `timeout`.
    pub(crate) fn start(&self, dir: &Path, timeout: Duration) -> std::io::Result<Running> {
        std::fs::create_dir_all(dir)?;
        let report = dir.join("report.json");
        let (runs, seed, speed) = (
            self.runs.to_string(),
            self.seed.to_string(),
            self.speed.to_string(),
        );
        let every = self.every.map(|(a, b)| format!("{a}-{b}"));
        let mut args = vec![
            "up",
            CLUSTER,
            "--run",
            MISSION,
            "--runs",
            &runs,
            "--chaos-nodes",
            &seed,
            "--speed",
            &speed,
            "--report",
            report.to_str().unwrap_or_default(),
            // readers beside the runs: no read may be stale
            "--probe",
            PROBED,
        ];
        if let Some(every) = &every {
            args.extend(["--chaos-every", every]);
        }
        Running::start_with(&args, dir, timeout)
    }
}

/// A fault of the soak, from its line.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Fault {
    /// Its number.
    pub number: u64,
    /// `stop-node`, `freeze-node` or `partition`.
    pub kind: String,
    /// The node hit.
    pub node: String,
    /// For a freeze or a cut, how long, mission seconds.
    pub lasting: Option<f64>,
    /// The run it struck in.
    pub run: u32,
    /// When, mission seconds into its run.
    pub at: f64,
    /// Why it was not injected, if it was not.
    pub not_injected: Option<String>,
    /// Seconds from the strike until its node was back (a kill: from its process's end to
    /// its restart listening).
    pub back_after: Option<f64>,
    /// Seconds from its node's return until every replica on it was at lag 0.
    pub caught_up_after: Option<f64>,
    /// The fault that hit its node again first, if one did.
    pub hit_again_by: Option<u64>,
}

/// The number that follows `after` in `text`: `number_after("back 0.21 s", "back ")`.
fn number_after(text: &str, after: &str) -> Option<f64> {
    let rest = &text[text.find(after)? + after.len()..];
    rest.split_whitespace().next()?.parse().ok()
}

impl Fault {
    /// Parse a fault's line (`None` for any other line).
    pub(crate) fn parse(line: &str) -> Option<Fault> {
        let rest = line.strip_prefix("fault ")?;
        let (number, rest) = rest.split_once(" (")?;
        let (inside, fate) = rest.split_once("): ")?;
        let (what, when) = inside.rsplit_once(", run ")?;
        let mut words = what.split_whitespace();
        let (kind, node) = (words.next()?.to_string(), words.next()?.to_string());
        let lasting = match words.next() {
            Some("for") => Some(words.next()?.parse().ok()?),
            _ => None,
        };
        let (run, at) = when.split_once(" at ")?;
        Some(Fault {
            number: number.parse().ok()?,
            kind,
            node,
            lasting,
            run: run.parse().ok()?,
            at: at.trim_end_matches(" s").parse().ok()?,
            not_injected: fate.strip_prefix("not injected: ").map(str::to_string),
            back_after: number_after(fate, "back "),
            caught_up_after: number_after(fate, "caught up "),
            // "not caught up before fault N hit it again", "fault N hit its node again …"
            hit_again_by: number_after(fate, "before fault ")
                .or_else(|| number_after(fate.strip_prefix("fault")?, ""))
                .map(|n| n as u64),
        })
    }
}

/// One run's verdict, from its report.
#[derive(Clone, Debug)]
pub(crate) struct RunVerdict {
    /// Its number.
    pub run: u32,
    /// The mission succeeded with the cart inside the goal area.
    pub docked: bool,
    /// Why not.
    pub why: String,
    /// Acknowledged records checked.
    pub acknowledged: u64,
    /// Of them lost (`None`: no report or no check).
    pub lost: Option<u64>,
    /// Epochs obeyed after their replacement was bound (`None`: not said).
    pub obeyed_late: Option<u64>,
    /// Collisions.
    pub collisions: Option<u64>,
    /// Mission time, seconds.
    pub secs: f64,
}

impl RunVerdict {
    /// Run `run`'s verdict from `report` (`Null`: none written).
    pub(crate) fn of(run: u32, report: &Value) -> RunVerdict {
        let docked = report["outcome"] == "succeeded" && report["inside_goal"] == true;
        let why = match (report, docked) {
            (Value::Null, _) => "no report".to_string(),
            (_, true) => String::new(),
            (r, false) => r["reason"]
                .as_str()
                .filter(|s| !s.is_empty())
                .map_or_else(|| "the cart ended outside the goal".into(), str::to_string),
        };
        RunVerdict {
            run,
            docked,
            why,
            acknowledged: report["dm_checks"].as_array().map_or(0, |c| {
                c.iter().filter_map(|c| c["acknowledged"].as_u64()).sum()
            }),
            lost: report["acknowledged_lost"].as_u64(),
            obeyed_late: report["obeyed_late"].as_array().map(|a| a.len() as u64),
            collisions: report["collisions"].as_u64(),
            secs: report["duration_ms"].as_u64().unwrap_or_default() as f64 / 1000.0,
        }
    }

    /// Docked, checked with nothing lost, nothing obeyed late, no collision.
    pub(crate) fn passes(&self) -> bool {
        self.docked
            && self.lost == Some(0)
            && self.obeyed_late == Some(0)
            && self.collisions == Some(0)
    }
}

/// What a soak came to.
#[derive(Clone, Debug)]
pub(crate) struct Outcome {
    /// `marie up`'s exit code.
    pub exit: Option<i32>,
    /// Each run's verdict, in order.
    pub runs: Vec<RunVerdict>,
    /// Each fault, in order.
    pub faults: Vec<Fault>,
    /// `up`'s summary lines (from `soak of` on).
    pub summary: Vec<String>,
}

impl Outcome {
    /// Read a soak of `runs` runs that wrote into `dir` and exited with `exit`.
    pub(crate) fn read(dir: &Path, runs: u32, exit: Option<i32>) -> Outcome {
        let stdout = std::fs::read_to_string(dir.join("stdout.txt")).unwrap_or_default();
        let mut faults: Vec<Fault> = stdout.lines().filter_map(Fault::parse).collect();
        faults.sort_by_key(|f| f.number);
        let summary = stdout
            .lines()
            .skip_while(|l| !l.starts_with("soak of "))
            .take_while(|l| !l.starts_with("cluster stopped"))
            .map(str::to_string)
            .collect();
        let runs = (1..=runs)
            .map(|k| {
                let report = std::fs::read_to_string(dir.join(format!("report-{k}.json")))
                    .ok()
                    .and_then(|s| serde_json::from_str(&s).ok())
                    .unwrap_or(Value::Null);
                RunVerdict::of(k, &report)
            })
            .collect();
        Outcome {
            exit,
            runs,
            faults,
            summary,
        }
    }

    /// Faults injected.
    pub(crate) fn injected(&self) -> impl Iterator<Item = &Fault> {
        self.faults.iter().filter(|f| f.not_injected.is_none())
    }

    /// Whether the goal holds: every run docked, checked with nothing lost, nothing obeyed
    /// late, no collision, the probe's reads checked with none stale, and `up` said so
    /// (exit 0).
    pub(crate) fn goal(&self) -> bool {
        !self.runs.is_empty()
            && self.runs.iter().all(RunVerdict::passes)
            && self.stale_reads() == Some(0)
            && self.memory_flat()
            && self.exit == Some(0)
    }

    /// Whether `up` found every node's memory flat (its memory line names none
    /// `GROWING`; a soak too short to compare halves is flat).
    pub(crate) fn memory_flat(&self) -> bool {
        self.memory().is_some_and(|m| !m.contains("GROWING"))
    }

    /// `up`'s line of the probe's verdict (`reads: probe of feature, …`).
    pub(crate) fn reads(&self) -> Option<&str> {
        self.summary
            .iter()
            .find(|l| l.starts_with("reads: "))
            .map(String::as_str)
    }

    /// The stale reads the probe counted (`None`: no verdict — not checked).
    pub(crate) fn stale_reads(&self) -> Option<u64> {
        stale_in(self.reads()?)
    }

    /// Reads the probe had answered (`None`: no verdict).
    pub(crate) fn reads_answered(&self) -> Option<u64> {
        Some(answered_in(self.reads()?).values().sum())
    }

    /// The table per fault.
    pub(crate) fn fault_table(&self) -> String {
        let mut s = String::from(
            "| # | node | kind | run | at (mission s) | back after (s) | caught up after (s) | records lost (its run) |\n\
             |---|---|---|---|---|---|---|---|\n",
        );
        let secs = |v: Option<f64>| v.map_or_else(|| "-".to_string(), |v| format!("{v:.2}"));
        for f in &self.faults {
            let kind = match f.lasting {
                Some(d) => format!("{} {d:.1} s", f.kind),
                None => f.kind.clone(),
            };
            let caught = match (&f.not_injected, f.caught_up_after, f.hit_again_by) {
                (Some(why), _, _) => format!("not injected: {why}"),
                (None, Some(c), _) => format!("{c:.2}"),
                (None, None, Some(n)) => format!("hit again by fault {n} first"),
                (None, None, None) => "not seen".to_string(),
            };
            let lost = self
                .runs
                .get(f.run as usize - 1)
                .and_then(|r| r.lost)
                .map_or_else(|| "-".to_string(), |l| l.to_string());
            let _ = writeln!(
                s,
                "| {} | {} | {kind} | {} | {:.1} | {} | {caught} | {lost} |",
                f.number,
                f.node,
                f.run,
                f.at,
                secs(f.back_after)
            );
        }
        s
    }

    /// The table per run.
    pub(crate) fn run_table(&self) -> String {
        let mut s = String::from(
            "| run | outcome | acked records lost | obeyed old epoch | collisions | faults | mission s |\n\
             |---|---|---|---|---|---|---|\n",
        );
        let opt = |v: Option<u64>| v.map_or_else(|| "-".to_string(), |v| v.to_string());
        for r in &self.runs {
            let faults = self.injected().filter(|f| f.run == r.run).count();
            let _ = writeln!(
                s,
                "| {} | {} | {} of {} | {} | {} | {faults} | {:.1} |",
                r.run,
                if r.docked {
                    "docked".to_string()
                } else {
                    format!("FAILED: {}", r.why)
                },
                opt(r.lost),
                r.acknowledged,
                opt(r.obeyed_late),
                opt(r.collisions),
                r.secs
            );
        }
        s
    }

    /// The totals, as the reports and the fault lines give them, and the goal.
    pub(crate) fn totals(&self) -> String {
        let failed = self.runs.iter().filter(|r| !r.docked).count();
        let lost: u64 = self.runs.iter().filter_map(|r| r.lost).sum();
        let acked: u64 = self.runs.iter().map(|r| r.acknowledged).sum();
        let late: u64 = self.runs.iter().filter_map(|r| r.obeyed_late).sum();
        let collisions: u64 = self.runs.iter().filter_map(|r| r.collisions).sum();
        let unchecked = self.runs.iter().filter(|r| r.lost.is_none()).count();
        let injected = self.injected().count();
        let mut kinds = std::collections::BTreeMap::<&str, usize>::new();
        for f in self.injected() {
            *kinds.entry(&f.kind).or_default() += 1;
        }
        let kinds: Vec<String> = kinds.iter().map(|(k, n)| format!("{k} {n}")).collect();
        let caught = self
            .injected()
            .filter(|f| f.caught_up_after.is_some())
            .count();
        format!(
            "missions run: {}, failed: {failed}; faults: {injected} ({}), {} not injected, {caught} \
             caught up; acknowledged records lost: {lost} of {acked}{}; epochs obeyed late: {late}; \
             collisions: {collisions}; stale reads: {} of {} answered. Goal (0 missions failed, 0 \
             lost, 0 obeyed late, 0 stale reads, node memory flat): {}",
            self.runs.len(),
            kinds.join(", "),
            self.faults.len() - injected,
            if unchecked > 0 {
                format!(" ({unchecked} runs unchecked)")
            } else {
                String::new()
            },
            self.stale_reads()
                .map_or_else(|| "not checked".to_string(), |n| n.to_string()),
            self.reads_answered()
                .map_or_else(|| "-".to_string(), |n| n.to_string()),
            if self.goal() { "holds" } else { "NOT met" }
        )
    }

    /// `up`'s memory line.
    pub(crate) fn memory(&self) -> Option<&str> {
        self.summary
            .iter()
            .find(|l| l.starts_with("node memory"))
            .map(String::as_str)
    }
}

/// The stale reads a probe's verdict line says (`… ; 2 stale; …`).
pub(crate) fn stale_in(verdict: &str) -> Option<u64> {
    let (before, _) = verdict.split_once(" stale")?;
    before.rsplit("; ").next()?.trim().parse().ok()
}

/// The reads answered per road that a probe's verdict line says (`reads: by name 841
/// answered; features 783 answered, 3 refused; …`): road → answered.
pub(crate) fn answered_in(verdict: &str) -> std::collections::BTreeMap<String, u64> {
    let Some((_, tallies)) = verdict.rsplit_once("reads: ") else {
        return Default::default();
    };
    tallies
        .split("; ")
        .filter_map(|road| {
            let (who, _) = road.split_once(" answered")?;
            let (name, n) = who.rsplit_once(' ')?;
            Some((name.to_string(), n.parse().ok()?))
        })
        .collect()
}
