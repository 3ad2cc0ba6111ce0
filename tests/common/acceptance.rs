//! The acceptance of a cluster without a single point of failure but the cart (issue 23,
//! point 5), shared by `benches/acceptance.rs` (`scripts/acceptance`: N schedules and the
//! table) and `tests/acceptance.rs` (CI: a fixed five of them).
//!
//! A **schedule** is one node fault in one run of `marie up CLUSTER --run MISSION`, drawn
//! by a generator seeded with the schedule's number (the project's xoshiro256**): its kind
//! — `stop-node`, `freeze-node` (+D) or `partition` (+D: the node cut off from every
//! other) —, its victim — any node of the cluster file but those that run the cart's
//! drivers (their loss is the robot's), so a node added to the file (a dispatcher's) is
//! among them by itself —, and its moment, uniform over the run (mission time; the run's
//! length measured on a fault-free run, or given). D is drawn in real seconds, past the
//! failure detector's deadline (1.2 s of real time) so that the peers declare the node
//! down, and passed as mission time (× the speed).
//!
//! Its **verdict** is read from the run's report: docked (the mission succeeded, the cart
//! inside the goal), acknowledged records lost (`acknowledged_lost`: the check of the
//! datamanagers at the run's end), commands the cart refused by epoch, collisions, rebinds,
//! takeovers (when the report has them), the fault injected or why not, and the epochs the
//! cart *obeyed* after the run had bound a newer one of their operation (`obeyed_late`:
//! the cart's log of what it obeyed, by epoch and when, checked against the report's
//! `bound_epochs` — each such epoch is at least one command of a replaced incarnation
//! obeyed).

use rand_xoshiro::rand_core::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256StarStar;
use serde_json::Value;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// The cluster file the acceptance runs on (the thesis' layout: DM copies on three nodes).
pub(crate) const CLUSTER: &str = "missions/clusters/thesis.toml";
/// The mission it runs.
pub(crate) const MISSION: &str = "missions/docking.toml";
/// Shortest freeze or cut, in real seconds: past the failure detector's default deadline
/// (1.2 s of real time, whatever the cluster's speed).
pub(crate) const LASTING_MIN: f64 = 1.5;
/// Longest freeze or cut, in real seconds.
pub(crate) const LASTING_MAX: f64 = 6.0;
/// The latest a fault is drawn: this long before the measured end of the run (mission
/// seconds), so that it lands inside the run.
pub(crate) const END_MARGIN: f64 = 2.0;
/// How long a run may take in all (start, mission, stop) before it is stopped.
pub(crate) const RUN_TIMEOUT: Duration = Duration::from_secs(600);
/// How long a run that was told to stop (SIGINT) has to stop its cluster before it is
/// killed.
const STOP_GRACE: Duration = Duration::from_secs(30);

/// The `marie` binary this crate was built with.
pub(crate) fn marie_exe() -> &'static Path {
    Path::new(env!("CARGO_BIN_EXE_marie"))
}

/// The package root (where the cluster and mission files are).
pub(crate) fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// The nodes of a cluster file, and the ones a schedule may hit.
#[derive(Clone, Debug)]
pub(crate) struct Layout {
    /// Every node, in file order.
    pub nodes: Vec<String>,
    /// The nodes but those that run the cart's drivers.
    pub victims: Vec<String>,
}

impl Layout {
    /// Read `cluster` (relative to the package root) as `marie up` does.
    pub(crate) fn load(cluster: &str) -> Result<Layout, String> {
        let catalog = marie_missions::catalog();
        let layout = marie::cluster::layout::ClusterLayout::load(&root().join(cluster), &catalog)
            .map_err(|d| d.to_string())?;
        let nodes: Vec<String> = layout.nodes.iter().map(|n| n.config.name.clone()).collect();
        let victims = layout
            .nodes
            .iter()
            .filter(|n| !n.config.simulation.as_ref().is_some_and(|s| s.drivers))
            .map(|n| n.config.name.clone())
            .collect();
        Ok(Layout { nodes, victims })
    }
}

/// A node fault's kind.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Kind {
    /// `stop-node` (SIGKILL; the node stays down).
    Stop,
    /// `freeze-node` (SIGSTOP, SIGCONT after D).
    Freeze,
    /// `partition` (the node cut off from every other for D).
    Partition,
}

impl Kind {
    fn name(self) -> &'static str {
        match self {
            Kind::Stop => "stop-node",
            Kind::Freeze => "freeze-node",
            Kind::Partition => "partition",
        }
    }
}

/// What a schedule's fault may be.
#[derive(Clone, Debug)]
pub(crate) struct Draw {
    /// The run's length, mission seconds: the moment is drawn over it.
    pub run_secs: f64,
    /// The cluster's speed (durations drawn in real seconds are passed as mission time).
    pub speed: f64,
    /// Whether partitions may be drawn (they need root and `ip`).
    pub partitions: bool,
}

/// One schedule: one node fault at one moment of one run.
#[derive(Clone, Debug)]
pub(crate) struct Schedule {
    /// Its number, which seeds it.
    pub number: u64,
    /// The fault's kind.
    pub kind: Kind,
    /// The node hit.
    pub victim: String,
    /// When, mission seconds since the run began.
    pub at: f64,
    /// For a freeze or a cut, how long, mission seconds.
    pub lasting: Option<f64>,
    /// Every node (a cut separates the victim from the others).
    nodes: Vec<String>,
}

/// A uniform draw in [0, 1) from 64 random bits.
fn unit(rng: &mut Xoshiro256StarStar) -> f64 {
    (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64
}

impl Schedule {
    /// Schedule `number` of `layout`, drawn by a generator seeded with it.
    pub(crate) fn draw(number: u64, layout: &Layout, draw: &Draw) -> Schedule {
        let mut rng = Xoshiro256StarStar::seed_from_u64(number);
        let kinds: &[Kind] = if draw.partitions {
            &[Kind::Stop, Kind::Freeze, Kind::Partition]
        } else {
            &[Kind::Stop, Kind::Freeze]
        };
        let kind = kinds[(rng.next_u64() % kinds.len() as u64) as usize];
        let victim =
            layout.victims[(rng.next_u64() % layout.victims.len() as u64) as usize].clone();
        let latest = (draw.run_secs - END_MARGIN).max(1.0);
        // tenths of a second: what the table shows is what ran
        let at = (unit(&mut rng) * latest * 10.0).floor() / 10.0;
        let real = LASTING_MIN + unit(&mut rng) * (LASTING_MAX - LASTING_MIN);
        let lasting = (kind != Kind::Stop).then(|| (real * draw.speed * 10.0).ceil() / 10.0);
        Schedule {
            number,
            kind,
            victim,
            at,
            lasting,
            nodes: layout.nodes.clone(),
        }
    }

    /// The `--fault` of `marie up`.
    pub(crate) fn spec(&self) -> String {
        let lasting = self.lasting.map(|d| format!("+{d:.1}")).unwrap_or_default();
        match self.kind {
            Kind::Partition => {
                let others: Vec<&str> = self
                    .nodes
                    .iter()
                    .filter(|n| **n != self.victim)
                    .map(String::as_str)
                    .collect();
                format!(
                    "partition:{}|{}@{:.1}{lasting}",
                    self.victim,
                    others.join(","),
                    self.at
                )
            }
            kind => format!("{}:{}@{:.1}{lasting}", kind.name(), self.victim, self.at),
        }
    }

    /// The fault as the table shows it: `freeze-node spare @31.4 +9.2`.
    pub(crate) fn label(&self) -> String {
        let lasting = self
            .lasting
            .map(|d| format!(" +{d:.1}"))
            .unwrap_or_default();
        format!(
            "{} {} @{:.1}{lasting}",
            self.kind.name(),
            self.victim,
            self.at
        )
    }
}

/// `marie up … --run …` of one schedule (or of none: a fault-free run), its output and
/// report in a directory of its own. Dropped before it ended, it is told to stop (SIGINT:
/// `marie up` lets a frozen node go on, stops its nodes, deletes its namespaces and data
/// directories) and killed if it has not within [`STOP_GRACE`].
pub(crate) struct Running {
    child: Option<Child>,
    started: Instant,
    /// How long it may run before it is stopped.
    timeout: Duration,
    /// Where its report, events, stdout and stderr go.
    pub dir: PathBuf,
}

impl Running {
    /// Start `marie up` on [`CLUSTER`] with [`MISSION`] at `speed`, with `fault` if any,
    /// writing into `dir` (made if missing). In a process group of its own: a Ctrl-C at
    /// the terminal reaches whoever started it, who tells it to stop once.
    pub(crate) fn start(fault: Option<&str>, speed: f64, dir: &Path) -> std::io::Result<Running> {
        std::fs::create_dir_all(dir)?;
        let speed = speed.to_string();
        let report = dir.join("report.json");
        let events = dir.join("events.jsonl");
        let mut args = vec![
            "up",
            CLUSTER,
            "--run",
            MISSION,
            "--speed",
            &speed,
            "--report",
            report.to_str().unwrap_or_default(),
            "--events",
            events.to_str().unwrap_or_default(),
        ];
        if let Some(f) = fault {
            args.extend(["--fault", f]);
        }
        Running::start_with(&args, dir, RUN_TIMEOUT)
    }

    /// Start `marie` with `args` (from the package root, without `RUST_LOG`), its stdout
    /// and stderr into `dir` (made if missing), stopped once it has run for `timeout`.
    pub(crate) fn start_with(
        args: &[&str],
        dir: &Path,
        timeout: Duration,
    ) -> std::io::Result<Running> {
        use std::os::unix::process::CommandExt;
        std::fs::create_dir_all(dir)?;
        let child = Command::new(marie_exe())
            .args(args)
            .current_dir(root())
            .env_remove("RUST_LOG")
            .stdin(Stdio::null())
            .stdout(std::fs::File::create(dir.join("stdout.txt"))?)
            .stderr(std::fs::File::create(dir.join("stderr.txt"))?)
            .process_group(0)
            .spawn()?;
        Ok(Running {
            child: Some(child),
            started: Instant::now(),
            timeout,
            dir: dir.to_path_buf(),
        })
    }

    /// Its exit code once it has ended (`Some(None)`: killed by a signal); `None` while it
    /// runs. Past its timeout ([`RUN_TIMEOUT`] for a schedule's run) it is stopped.
    pub(crate) fn poll(&mut self) -> Option<Option<i32>> {
        let child = self.child.as_mut()?;
        match child.try_wait() {
            Ok(Some(status)) => {
                self.child = None;
                Some(status.code())
            }
            Ok(None) if self.started.elapsed() > self.timeout => {
                self.stop();
                Some(None)
            }
            Ok(None) => None,
            Err(_) => {
                self.stop();
                Some(None)
            }
        }
    }

    /// Wait for it to end; its exit code.
    pub(crate) fn wait(&mut self) -> Option<i32> {
        loop {
            if let Some(code) = self.poll() {
                return code;
            }
            // polling a child's exit: the only wait std offers with a deadline
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// How long it has run.
    pub(crate) fn elapsed(&self) -> Duration {
        self.started.elapsed()
    }

    /// Tell it to stop (SIGINT) and wait at most [`STOP_GRACE`]; then kill it.
    pub(crate) fn stop(&mut self) {
        let Some(mut child) = self.child.take() else {
            return;
        };
        if let Ok(pid) = i32::try_from(child.id()) {
            // SAFETY: kill(2) takes plain integers and touches no memory of this process
            unsafe { libc::kill(pid, libc::SIGINT) };
        }
        let deadline = Instant::now() + STOP_GRACE;
        while Instant::now() < deadline {
            if let Ok(Some(_)) = child.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        let _ = child.kill();
        let _ = child.wait();
    }

    /// Its report (`Null` if none was written).
    pub(crate) fn report(&self) -> Value {
        std::fs::read_to_string(self.dir.join("report.json"))
            .ok()
            .and_then(|s| serde_json::from_str(&s).ok())
            .unwrap_or(Value::Null)
    }

    /// The last `n` lines of its stderr.
    pub(crate) fn stderr_tail(&self, n: usize) -> String {
        let text = std::fs::read_to_string(self.dir.join("stderr.txt")).unwrap_or_default();
        let lines: Vec<&str> = text.lines().collect();
        lines[lines.len().saturating_sub(n)..].join("\n")
    }
}

impl Drop for Running {
    fn drop(&mut self) {
        self.stop();
    }
}

/// What one schedule's run came to, from its report.
#[derive(Clone, Debug)]
pub(crate) struct Verdict {
    /// The schedule.
    pub schedule: Schedule,
    /// `marie up`'s exit code (`None`: killed).
    pub exit: Option<i32>,
    /// The mission succeeded with the cart inside the goal area.
    pub docked: bool,
    /// Why not, if not (the report's reason, or what went wrong with the run).
    pub why: String,
    /// The run wrote a report.
    pub reported: bool,
    /// The fault was injected (`Err`: why not).
    pub injected: Result<(), String>,
    /// Acknowledged records lost (`None`: the report has no check).
    pub lost: Option<u64>,
    /// Acknowledged records checked.
    pub acknowledged: u64,
    /// Commands the cart refused by epoch.
    pub refused: u64,
    /// Epochs the cart obeyed after their replacement was bound (`None`: not reported).
    pub obeyed_late: Option<u64>,
    /// Collisions (`None`: not reported).
    pub collisions: Option<u64>,
    /// Rebinds.
    pub rebinds: u64,
    /// Dispatcher takeovers, when the report tells them.
    pub takeovers: Option<u64>,
    /// Mission time of the run, ms.
    pub duration_ms: u64,
    /// Wall-clock time of the whole `marie up`.
    pub wall: Duration,
}

fn count(v: &Value) -> Option<u64> {
    v.as_u64().or_else(|| v.as_array().map(|a| a.len() as u64))
}

impl Verdict {
    /// The verdict of `schedule` from its run's `report` and exit code.
    pub(crate) fn of(
        schedule: &Schedule,
        report: &Value,
        exit: Option<i32>,
        wall: Duration,
    ) -> Verdict {
        let fault = report["faults"].as_array().and_then(|f| f.first());
        let injected = match fault {
            None => Err("no fault in the report".to_string()),
            Some(f) => match f["error"].as_str() {
                Some(why) => Err(why.to_string()),
                None => Ok(()),
            },
        };
        let docked = report["outcome"] == "succeeded" && report["inside_goal"] == true;
        let why = match (&report, docked) {
            (Value::Null, _) if wall >= RUN_TIMEOUT => format!(
                "no report: still running after {:.0} s, stopped",
                RUN_TIMEOUT.as_secs_f64()
            ),
            (Value::Null, _) => format!("no report (exit {exit:?})"),
            (_, true) => String::new(),
            (r, false) => r["reason"]
                .as_str()
                .filter(|s| !s.is_empty())
                .map_or_else(|| format!("outcome {}", r["outcome"]), str::to_string),
        };
        let acknowledged = report["dm_checks"].as_array().map_or(0, |c| {
            c.iter().filter_map(|c| c["acknowledged"].as_u64()).sum()
        });
        let refused = report["refused_commands"]
            .as_object()
            .map_or(0, |m| m.values().filter_map(Value::as_u64).sum());
        let takeovers = count(&report["takeovers_total"]).or_else(|| count(&report["takeovers"]));
        Verdict {
            schedule: schedule.clone(),
            exit,
            docked,
            why,
            reported: !report.is_null(),
            injected,
            lost: report["acknowledged_lost"].as_u64(),
            acknowledged,
            refused,
            obeyed_late: report["obeyed_late"].as_array().map(|a| a.len() as u64),
            collisions: report["collisions"].as_u64(),
            rebinds: report["rebinds_total"].as_u64().unwrap_or_default(),
            takeovers,
            duration_ms: report["duration_ms"].as_u64().unwrap_or_default(),
            wall,
        }
    }

    /// Docked, with its fault injected, nothing acknowledged lost, no command obeyed from
    /// an old epoch, no collision.
    pub(crate) fn passes(&self) -> bool {
        self.docked
            && self.injected.is_ok()
            && self.lost == Some(0)
            && self.obeyed_late == Some(0)
            && self.collisions == Some(0)
    }

    /// The table's row.
    pub(crate) fn row(&self) -> String {
        let outcome = match (&self.injected, self.docked) {
            _ if !self.reported => format!("FAILED: {}", self.why),
            (Err(why), _) => format!("fault not injected: {why}"),
            (Ok(()), true) => "docked".to_string(),
            (Ok(()), false) => format!("FAILED: {}", self.why),
        };
        let opt = |v: Option<u64>| v.map_or_else(|| "-".to_string(), |v| v.to_string());
        format!(
            "| {} | {} | {} | {} of {} | {} | {} | {} | {} | {} | {:.1} s ({:.0} s) |",
            self.schedule.number,
            self.schedule.label(),
            outcome,
            opt(self.lost),
            self.acknowledged,
            self.refused,
            opt(self.obeyed_late),
            opt(self.collisions),
            self.rebinds,
            opt(self.takeovers),
            self.duration_ms as f64 / 1000.0,
            self.wall.as_secs_f64()
        )
    }
}

/// The table's header.
pub(crate) fn header() -> String {
    "| # | fault (mission s) | outcome | acked records lost | refused by epoch | obeyed old epoch | collisions | rebinds | takeovers | duration mission (wall) |\n\
     |---|---|---|---|---|---|---|---|---|---|"
        .to_string()
}

/// The summary under the table, and whether the goal holds: at most one run in 30 does
/// not dock, none loses an acknowledged record, none obeys a command from an old epoch,
/// none collides, every fault injected.
pub(crate) fn summary(verdicts: &[Verdict]) -> (String, bool) {
    let n = verdicts.len();
    let docked = verdicts.iter().filter(|v| v.docked).count();
    let passed = verdicts.iter().filter(|v| v.passes()).count();
    let lost: u64 = verdicts.iter().map(|v| v.lost.unwrap_or(0)).sum();
    let unchecked = verdicts.iter().filter(|v| v.lost.is_none()).count();
    let collisions: u64 = verdicts.iter().map(|v| v.collisions.unwrap_or(0)).sum();
    let not_injected = verdicts
        .iter()
        .filter(|v| v.reported && v.injected.is_err())
        .count();
    let refused: u64 = verdicts.iter().map(|v| v.refused).sum();
    let late: u64 = verdicts.iter().map(|v| v.obeyed_late.unwrap_or(0)).sum();
    let unsaid = verdicts
        .iter()
        .filter(|v| v.reported && v.obeyed_late.is_none())
        .count();
    let allowed = n / 30;
    let goal = n > 0
        && docked + allowed >= n
        && lost == 0
        && late == 0
        && unsaid == 0
        && unchecked == 0
        && collisions == 0
        && not_injected == 0;
    let mut s = String::new();
    let _ = write!(
        s,
        "{passed} of {n} passed (docked, 0 lost, 0 obeyed from an old epoch, 0 collisions): \
         {docked} docked, {lost} acknowledged records lost, {late} epochs obeyed after their \
         replacement, {collisions} collisions, {refused} commands refused by epoch"
    );
    if unsaid > 0 {
        let _ = write!(
            s,
            ", {unsaid} run{} whose cart did not say what it obeyed",
            if unsaid == 1 { "" } else { "s" }
        );
    }
    if unchecked > 0 {
        let _ = write!(
            s,
            ", {unchecked} run{} without a check of its datamanagers (no report)",
            if unchecked == 1 { "" } else { "s" }
        );
    }
    if not_injected > 0 {
        let _ = write!(
            s,
            ", {not_injected} fault{} not injected",
            if not_injected == 1 { "" } else { "s" }
        );
    }
    let _ = write!(
        s,
        ". Goal (at least {} of {n} dock, 0 lost, 0 obeyed from an old epoch, 0 \
         collisions): {}",
        n - allowed,
        if goal { "holds" } else { "NOT met" }
    );
    (s, goal)
}

/// The mission time of a fault-free run at `speed`, seconds (its report's `duration_ms`).
pub(crate) fn measure(speed: f64, dir: &Path) -> Result<f64, String> {
    let mut run = Running::start(None, speed, dir).map_err(|e| e.to_string())?;
    let exit = run.wait();
    let report = run.report();
    match (exit, report["duration_ms"].as_u64()) {
        (Some(0), Some(ms)) => Ok(ms as f64 / 1000.0),
        _ => Err(format!(
            "the fault-free run did not dock (exit {exit:?}): {}\n{}",
            report["reason"],
            run.stderr_tail(20)
        )),
    }
}
