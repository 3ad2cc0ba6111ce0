//! Self-configuration's cost: the time from `marie run` to the first activation with 1, 10
//! and 100 candidate instances of every operation the docking mission uses, and the share
//! of it the selection takes (goal: selection well under 100 ms at 100 candidates).
//!
//! `cargo bench --bench selection`
//!
//! Two measurements per instance count N, on a node that hosts N instances of each of the
//! mission's ten operations:
//!
//! - **command**: `marie run missions/docking.toml --node CFG --speed max` as a child
//!   process, timed from its spawn to the line saying the mission is checked (the node with
//!   its 10·N operations started, every instance asked through its property interface and
//!   chosen among) and to the first action's start line (the dispatcher has bound an
//!   instance of every operation and activated the first action's). The child is killed
//!   there. The last column is the part between the two, per run: the dispatcher binds the
//!   check's choices (a registry read and one request to each chosen instance), so it
//!   should not grow with N.
//! - **selection**: in this process, on a node started from the same config,
//!   [`survey`](marie::dispatcher::survey): what the check does to choose — every
//!   live instance of every operation asked at once for its identity, schema and general
//!   properties, then chosen among.
//!
//! Ratios are against N = 1, measured in the same run.

use marie::dispatcher::mission::ParsedMission;
use marie::dispatcher::survey;
use marie_missions::embedded::{Embedded, EmbeddedOptions};
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

mod common;

/// The docking mission's operations (`missions/docking.toml`).
const OPERATIONS: [&str; 10] = [
    "ultrasonic",
    "localizer",
    "segment-extractor",
    "wall-sensor",
    "sensor-based-controller",
    "collision-avoidance",
    "wall-follower",
    "docking-detector",
    "path-planner",
    "trajectory-controller",
];
const COUNTS: [usize; 3] = [1, 10, 100];
/// `marie run` samples per count.
const RUNS: usize = 5;
/// Surveys per count.
const SURVEYS: usize = 20;

/// A node config hosting `n` instances of every operation of the mission (the wall
/// follower's version 1 only, so that `n` is the number of candidates), in entries of at
/// most 64 instances.
fn config(dir: &Path, n: usize) -> PathBuf {
    let mut text = format!(
        "[node]\nname = \"bench-{n}\"\ndispatcher = true\n\
         [[datamanager]]\nname = \"feature\"\n[[datamanager]]\nname = \"parameter\"\n\
         [[datamanager]]\nname = \"world\"\n[simulation]\ndrivers = true\n"
    );
    for op in OPERATIONS {
        let version = if op == "wall-follower" {
            "version = \"1\"\n"
        } else {
            ""
        };
        let mut left = n;
        while left > 0 {
            let here = left.min(marie::cluster::node::MAX_INSTANCES);
            text += &format!("[[operation]]\nname = \"{op}\"\n{version}instances = {here}\n");
            left -= here;
        }
    }
    let path = dir.join(format!("bench-{n}.toml"));
    std::fs::write(&path, text).expect("write the node config");
    path
}

/// One `marie run`: (spawn → mission checked, spawn → first action started).
fn command(node: &Path) -> (Duration, Duration) {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let started = Instant::now();
    let mut child = Command::new(env!("CARGO_BIN_EXE_marie"))
        .args(["run", "missions/docking.toml", "--speed", "max", "--node"])
        .arg(node)
        .current_dir(repo)
        .env_remove("RUST_LOG")
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("marie runs");
    let out = BufReader::new(child.stdout.take().expect("piped"));
    let mut checked = None;
    let mut first = None;
    for line in out.lines().map_while(Result::ok) {
        if line.starts_with("mission `") {
            checked = Some(started.elapsed());
        }
        if line.starts_with("> ") {
            first = Some(started.elapsed());
            break;
        }
    }
    let _ = child.kill();
    let _ = child.wait();
    (
        checked.expect("the mission was checked"),
        first.expect("an action started"),
    )
}

/// Surveys of the mission on a node hosting `n` of each: their durations, sorted.
async fn surveys(node: &Path, n: usize) -> Vec<Duration> {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let parsed =
        ParsedMission::parse_file(&repo.join("missions/docking.toml")).expect("docking parses");
    let embedded = Embedded::start(EmbeddedOptions {
        node: Some(node.to_path_buf()),
        mission_world: parsed.world().map(PathBuf::from),
        ..EmbeddedOptions::default()
    })
    .await
    .expect("the node starts");
    let mission = embedded
        .node
        .check_mission(&parsed)
        .await
        .expect("docking fits");
    let mut times = Vec::with_capacity(SURVEYS);
    for _ in 0..SURVEYS {
        let at = Instant::now();
        let s = survey(&mission).await;
        times.push(at.elapsed());
        assert!(s.all_chosen(), "every operation has an instance");
        for c in &s.choices {
            // a node shut down before must have taken its instances along
            assert_eq!(c.candidates.len(), n, "{}", c.operation);
        }
    }
    embedded.node.shutdown().await;
    times.sort();
    times
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1000.0
}

fn main() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("a runtime");
    println!(
        "selection: docking's {} operations, N candidate instances of each",
        OPERATIONS.len()
    );
    println!(
        "{:>4} | {:>22} | {:>26} | {:>22} | {:>22}",
        "N",
        "run → checked p50 (ms)",
        "run → 1st activation p50",
        "selection p50 / p95",
        "checked → 1st act. p50"
    );
    let mut base: Option<(f64, f64)> = None;
    for n in COUNTS {
        let node = config(dir.path(), n);
        let mut checked = Vec::new();
        let mut first = Vec::new();
        let mut bind = Vec::new();
        for _ in 0..RUNS {
            let (c, f) = command(&node);
            checked.push(c);
            first.push(f);
            bind.push(f.saturating_sub(c));
        }
        checked.sort();
        first.sort();
        bind.sort();
        let surveyed = runtime.block_on(surveys(&node, n));
        let (c50, f50) = (
            common::percentile(&checked, 0.5),
            common::percentile(&first, 0.5),
        );
        let (s50, s95) = (
            common::percentile(&surveyed, 0.5),
            common::percentile(&surveyed, 0.95),
        );
        let (bf, bs) = *base.get_or_insert((ms(f50), ms(s50)));
        println!(
            "{n:>4} | {:>22.1} | {:>16.1} ({:>5.2}×) | {:>7.2} / {:>6.2} ({:>5.1}×) | {:>22.1}",
            ms(c50),
            ms(f50),
            ms(f50) / bf,
            ms(s50),
            ms(s95),
            ms(s50) / bs,
            ms(common::percentile(&bind, 0.5))
        );
    }
    println!("goal: selection at N = 100 well under 100 ms");
}
