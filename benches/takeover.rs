//! A dispatcher's takeover (issue 23, benchmarks): `marie up` of the thesis' layout runs the
//! docking mission dispatched on the features node, with a standby dispatcher on spare, and
//! the features node is lost in the middle of the wall following:
//!
//! - **kill -9** (`stop-node:features`): the time from the kill to the standby's first
//!   command (its `bound`, told right before the commands, after its `takeover`). Goal:
//!   p50 ≤ 300 ms.
//! - **SIGSTOP** (`freeze-node:features`, longer than the failure detector's deadline): the
//!   same, from the freeze. Goal: p50 ≤ the detector's deadline (1.2 s) + 300 ms.
//! - **mission time lost** per takeover: the run's duration less the median of fault-free
//!   runs' measured in the same bench run.
//!
//! ```text
//! cargo bench --bench takeover          # 2 fault-free runs and 5 of each fault
//! cargo bench --bench takeover -- 3     # 3 of each
//! ```
//!
//! A plain bench binary: a node's loss cannot be repeated in a tight loop. It runs at
//! `--speed 2` (the detector's deadline is real time; the times below are real time too):
//! a docking run is about 64 s of mission time, 32 s of real time, plus the cluster's start.
//! Each `marie up` stops its nodes when it exits, and is killed by its pid if this bench is.

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::Duration;

/// The cluster's speed factor.
const SPEED: f64 = 2.0;
/// The failure detector's default deadline (`marie_cluster::net::DEFAULT_DEADLINE`).
const DEADLINE: Duration = Duration::from_millis(1200);
/// When the features node is lost, in mission seconds (in the wall following).
const AT: f64 = 14.0;
/// How long a freeze lasts, in mission seconds (4 s of real time at speed 2).
const FREEZE: f64 = 8.0;

/// `marie up`, killed by its pid when dropped.
struct Up(Child);

impl Drop for Up {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// What one run measured.
struct Measured {
    succeeded: bool,
    duration_ms: u64,
    /// Real ms from the loss to the standby's first command.
    first_command_ms: Option<f64>,
}

/// Run the docking mission with `fault` (none: fault-free).
fn run(fault: Option<&str>, dir: &Path, n: usize) -> Measured {
    let events = dir.join(format!("events-{n}.jsonl"));
    let report = dir.join(format!("report-{n}.json"));
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_marie"));
    cmd.args([
        "up",
        "missions/clusters/thesis.toml",
        "--run",
        "missions/docking.toml",
    ])
    .args(["--speed", &SPEED.to_string()])
    .arg("--events")
    .arg(&events)
    .arg("--report")
    .arg(&report)
    .stdout(Stdio::null())
    .stderr(Stdio::null());
    if let Some(fault) = fault {
        cmd.args(["--fault", fault]);
    }
    let mut up = Up(cmd.spawn().expect("marie up starts"));
    let _ = up.0.wait();
    let report: serde_json::Value = std::fs::read_to_string(&report)
        .ok()
        .and_then(|t| serde_json::from_str(&t).ok())
        .unwrap_or_default();
    let lines: Vec<serde_json::Value> = std::fs::read_to_string(&events)
        .unwrap_or_default()
        .lines()
        .filter_map(|l| serde_json::from_str(l).ok())
        .collect();
    // the member's clock is the cluster's: wall-clock ms since the Unix epoch × speed
    let injected = lines
        .iter()
        .find(|e| e["kind"]["type"] == "fault_injected")
        .and_then(|e| e["at_ms"].as_f64())
        .map(|at| at / SPEED);
    // the standby's first command: its bindings told (after its term is stored and its
    // operations bound), right before it commands them
    let taken_over = lines
        .iter()
        .position(|e| e["kind"]["type"] == "takeover")
        .and_then(|at| {
            let to = &lines[at]["kind"]["to"];
            lines[at..]
                .iter()
                .find(|e| e["kind"]["type"] == "bound" && &e["node"] == to)
        })
        .and_then(|e| e["at_ms"].as_f64())
        .map(|at| at / SPEED);
    Measured {
        succeeded: report["outcome"] == "succeeded",
        duration_ms: report["duration_ms"].as_u64().unwrap_or(0),
        first_command_ms: injected.zip(taken_over).map(|(i, t)| t - i),
    }
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let i = ((sorted.len() - 1) as f64 * p).round() as usize;
    sorted[i]
}

fn main() {
    let n: usize = std::env::args()
        .skip(1)
        .find_map(|a| a.parse().ok())
        .unwrap_or(5);
    let dir = tempfile::tempdir().expect("a temporary directory");
    println!("takeover bench: {n} runs of each, thesis layout, docking, speed {SPEED}");
    let mut k = 0;
    let mut baseline = Vec::new();
    for _ in 0..2 {
        k += 1;
        let m = run(None, dir.path(), k);
        println!(
            "  fault-free: {} in {:.1} s of mission time",
            if m.succeeded { "docked" } else { "FAILED" },
            m.duration_ms as f64 / 1000.0
        );
        baseline.push(m.duration_ms as f64);
    }
    baseline.sort_by(f64::total_cmp);
    let base = percentile(&baseline, 0.5);
    let kinds = [
        (
            "kill -9",
            format!("stop-node:features@{AT}"),
            Duration::from_millis(300),
        ),
        (
            "SIGSTOP",
            format!("freeze-node:features@{AT}+{FREEZE}"),
            DEADLINE + Duration::from_millis(300),
        ),
    ];
    for (label, fault, goal) in kinds {
        let mut firsts = Vec::new();
        let mut lost = Vec::new();
        let mut docked = 0;
        for _ in 0..n {
            k += 1;
            let m = run(Some(&fault), dir.path(), k);
            docked += usize::from(m.succeeded);
            if let Some(first) = m.first_command_ms {
                firsts.push(first);
            }
            lost.push(m.duration_ms as f64 - base);
            println!(
                "  {label}: {} — first command {} after the loss, run {:.1} s",
                if m.succeeded { "docked" } else { "FAILED" },
                m.first_command_ms
                    .map_or("never".to_string(), |f| format!("{f:.0} ms")),
                m.duration_ms as f64 / 1000.0
            );
        }
        firsts.sort_by(f64::total_cmp);
        lost.sort_by(f64::total_cmp);
        let p50 = percentile(&firsts, 0.5);
        println!(
            "{label}: {docked}/{n} docked, {} takeovers; first command after the loss p50 {p50:.0} ms, \
             max {:.0} ms (goal p50 ≤ {} ms: {}); mission time lost per takeover p50 {:.1} s \
             (runs {:.1} s vs fault-free {:.1} s)",
            firsts.len(),
            firsts.last().copied().unwrap_or(f64::NAN),
            goal.as_millis(),
            if p50 <= goal.as_millis() as f64 { "met" } else { "MISSED" },
            percentile(&lost, 0.5) / 1000.0,
            (percentile(&lost, 0.5) + base) / 1000.0,
            base / 1000.0
        );
    }
}
