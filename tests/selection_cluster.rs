//! Self-configuration across node processes, the thesis' experiments 1 and 2 (issue 11):
//! the wall follower's version 1 (one parameter) and version 2 (two, corridor-capable) run
//! on nodes of their own — both, only version 1, or only version 2 — and a dispatcher on a
//! process of its own (`run --join`) asks their properties over the wire and binds what the
//! mission's parameters call for; `check --join` tells the same choice without running.
//!
//! Each case is a `marie up` cluster: the thesis' layout without its wall followers, plus
//! a node per version. A docking run moves the cart, so each cluster runs one mission.

use crate::common;

use common::cluster::Proc;
use common::layouts::thesis_node;
use common::missions::docking_variant;
use common::{marie, text};
use serde_json::Value;
use std::path::{Path, PathBuf};

pub(crate) const COOKIE: &str = "selection";
/// The cluster's speed: a docking run takes about 8 s of wall time.
const SPEED: &str = "8";
/// The cluster's seed: not the default (1), so a run that names its own seed instead of the
/// cart's is seen.
const CLUSTER_SEED: u64 = 4;

/// Write the cluster file into `dir`: the thesis' cart, features and operations nodes (the
/// operations node without a wall follower), and for each `(node, version)` of `followers`
/// a node that hosts that version of the wall follower alone.
pub(crate) fn layout(dir: &Path, followers: &[(&str, &str)]) -> PathBuf {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let thesis = repo.join("missions/clusters/thesis");
    let without = "[[operation]]\nname = \"wall-follower\"\n";
    thesis_node(dir, "operations", |operations| {
        assert!(operations.contains(without), "operations.toml changed");
        operations.replace(without, "")
    });
    let features = thesis_node(dir, "features", |text| text);
    let mut text = format!(
        "[cluster]\ncookie = \"{COOKIE}\"\nworld = \"{}\"\nseed = {CLUSTER_SEED}\n\
         [[node]]\nconfig = \"{}\"\n[[node]]\nconfig = \"{}\"\n\
         [[node]]\nconfig = \"operations.toml\"\n",
        repo.join("missions/worlds/lab.toml").display(),
        thesis.join("cart.toml").display(),
        features.display(),
    );
    for (node, version) in followers {
        std::fs::write(
            dir.join(format!("{node}.toml")),
            format!(
                "[node]\nname = \"{node}\"\ndispatcher = false\n\
                 [[operation]]\nname = \"wall-follower\"\nversion = \"{version}\"\n"
            ),
        )
        .unwrap();
        text += &format!("[[node]]\nconfig = \"{node}.toml\"\n");
    }
    let cluster = dir.join("cluster.toml");
    std::fs::write(&cluster, text).unwrap();
    cluster
}

/// A running cluster and the address of a node to join it by.
pub(crate) struct Cluster {
    _up: Proc,
    pub(crate) join: String,
}

pub(crate) fn start(dir: &Path, followers: &[(&str, &str)]) -> Cluster {
    start_at(dir, followers, SPEED)
}

/// [`start`], the cluster's clock at `speed`.
pub(crate) fn start_at(dir: &Path, followers: &[(&str, &str)], speed: &str) -> Cluster {
    let cluster = layout(dir, followers);
    let mut up = Proc::spawn(
        "marie up",
        &["up", cluster.to_str().unwrap(), "--speed", speed],
    );
    up.wait_line("Ctrl-C stops the cluster");
    // `  cart at 127.0.0.1:4242 (pid 77): ...`
    let join = up
        .seen()
        .iter()
        .find_map(|l| {
            let rest = l.trim().strip_prefix("cart at ")?;
            Some(rest.split_once(' ')?.0.to_string())
        })
        .expect("the cart node's address");
    Cluster { _up: up, join }
}

impl Cluster {
    /// `marie check MISSION --join --json`: the exit code and the verdict.
    fn check(&self, mission: &Path) -> (Option<i32>, Value, String) {
        let out = marie(&[
            "check",
            mission.to_str().unwrap(),
            "--join",
            &self.join,
            "--cookie",
            COOKIE,
            "--json",
        ]);
        let json = serde_json::from_slice(&out.stdout)
            .unwrap_or_else(|e| panic!("{e}: {}{}", text(&out.stdout), text(&out.stderr)));
        (out.status.code(), json, text(&out.stderr))
    }

    /// `marie run MISSION --join --report`: the exit code, the report (`Null` if none) and
    /// stderr.
    fn run(&self, mission: &Path) -> (Option<i32>, Value, String) {
        let (code, report, stderr, _) = self.run_out(mission);
        (code, report, stderr)
    }

    /// [`Cluster::run`], with its stdout.
    fn run_out(&self, mission: &Path) -> (Option<i32>, Value, String, String) {
        let dir = tempfile::tempdir().unwrap();
        let report = dir.path().join("report.json");
        let out = marie(&[
            "run",
            mission.to_str().unwrap(),
            "--join",
            &self.join,
            "--cookie",
            COOKIE,
            "--speed",
            SPEED,
            "--report",
            report.to_str().unwrap(),
        ]);
        let report = std::fs::read_to_string(&report)
            .ok()
            .and_then(|s| serde_json::from_str(&s).ok())
            .unwrap_or(Value::Null);
        (
            out.status.code(),
            report,
            text(&out.stderr),
            text(&out.stdout),
        )
    }
}

/// The wall follower's (first) choice among `choices`.
fn wall_follower(choices: &Value) -> &Value {
    choices
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["operation"] == "wall-follower")
        .unwrap_or_else(|| panic!("no choice for the wall follower: {choices:#}"))
}

/// The candidate on `node`.
fn on<'a>(choice: &'a Value, node: &str) -> &'a Value {
    choice["candidates"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["node"] == node)
        .unwrap_or_else(|| panic!("no candidate on {node}: {choice:#}"))
}

/// The node and version the actions ran the wall follower on.
fn ran_on(report: &Value) -> (String, String) {
    let op = report["actions"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|a| a["operations"].as_array().unwrap())
        .find(|op| op["name"] == "wall-follower")
        .unwrap_or_else(|| panic!("the wall follower never ran: {report:#}"));
    (
        op["node"].as_str().unwrap().to_string(),
        op["version"].as_str().unwrap().to_string(),
    )
}

#[test]
fn with_both_versions_on_other_nodes_the_missions_parameters_choose_the_node() {
    let dir = tempfile::tempdir().unwrap();
    let cluster = start(dir.path(), &[("wf-one", "1"), ("wf-two", "2")]);
    let distance_only = docking_variant(dir.path(), "distance-only", "", "");
    let corridor = docking_variant(dir.path(), "corridor", "mode = \"wall\"\n", "");

    // the wall distance alone: version 1 fits exactly, version 2 only as a superset
    let (code, verdict, stderr) = cluster.check(&distance_only);
    assert_eq!(code, Some(0), "{stderr}");
    let choice = wall_follower(&verdict["survey"]["choices"]);
    assert_eq!(
        on(choice, "wf-one")["verdict"]["type"],
        "chosen",
        "{choice:#}"
    );
    assert_eq!(on(choice, "wf-one")["version"], "1.0.0");
    let v2 = on(choice, "wf-two");
    assert_eq!(v2["verdict"]["type"], "lost", "{v2}");
    assert!(
        v2["verdict"]["reason"]
            .as_str()
            .unwrap()
            .contains("also declares mode"),
        "{v2}"
    );

    // the corridor parameter too: only version 2 takes it
    let (code, verdict, stderr) = cluster.check(&corridor);
    assert_eq!(code, Some(0), "{stderr}");
    let choice = wall_follower(&verdict["survey"]["choices"]);
    assert_eq!(
        on(choice, "wf-two")["verdict"]["type"],
        "chosen",
        "{choice:#}"
    );
    assert_eq!(on(choice, "wf-one")["verdict"]["type"], "rejected");

    // and a dispatcher on a process of its own binds it and docks with it
    let (code, report, stderr, stdout) = cluster.run_out(&corridor);
    assert_eq!(code, Some(0), "{stderr}\n{report:#}");
    assert_eq!(report["outcome"], "succeeded");
    let choice = wall_follower(&report["selection"]);
    assert_eq!(
        on(choice, "wf-two")["verdict"]["type"],
        "chosen",
        "{choice:#}"
    );
    assert_eq!(ran_on(&report), ("wf-two".into(), "2.0.0".into()));
    // the seed the cart drove with is the cluster's, which the run (given none) names
    assert_eq!(report["seed"], CLUSTER_SEED, "{report:#}");
    assert!(
        stdout.contains(&format!(", seed {CLUSTER_SEED}\n")),
        "{stdout}"
    );
}

#[test]
fn with_only_version_1_on_another_node_a_corridor_mission_does_not_start_and_a_wall_mission_runs_on_it(
) {
    let dir = tempfile::tempdir().unwrap();
    let cluster = start(dir.path(), &[("wf-one", "1")]);
    let corridor = docking_variant(dir.path(), "corridor", "mode = \"corridor\"\n", "");

    let (code, verdict, _) = cluster.check(&corridor);
    assert_eq!(code, Some(2));
    assert_eq!(verdict["ok"], false);
    let errors = verdict["errors"].to_string();
    assert!(
        errors.contains("wall-follower") && errors.contains("mode"),
        "{errors}"
    );

    let (code, report, stderr) = cluster.run(&corridor);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(report.is_null(), "it must not start: {report:#}");
    assert!(
        stderr.contains("corridor.toml:") && stderr.contains("mode"),
        "{stderr}"
    );

    let distance_only = docking_variant(dir.path(), "distance-only", "", "");
    let (code, report, stderr) = cluster.run(&distance_only);
    assert_eq!(code, Some(0), "{stderr}\n{report:#}");
    assert_eq!(ran_on(&report), ("wf-one".into(), "1.0.0".into()));
}

#[test]
fn with_only_version_2_on_another_node_a_wall_mission_takes_it_as_a_compatible_superset() {
    let dir = tempfile::tempdir().unwrap();
    let cluster = start(dir.path(), &[("wf-two", "2")]);
    let distance_only = docking_variant(dir.path(), "distance-only", "", "");
    let (code, report, stderr) = cluster.run(&distance_only);
    assert_eq!(code, Some(0), "{stderr}\n{report:#}");
    let choice = wall_follower(&report["selection"]);
    assert_eq!(choice["candidates"].as_array().unwrap().len(), 1);
    assert_eq!(on(choice, "wf-two")["verdict"]["type"], "chosen");
    assert_eq!(ran_on(&report), ("wf-two".into(), "2.0.0".into()));
}
