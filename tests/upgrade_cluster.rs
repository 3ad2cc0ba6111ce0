//! A newer compatible version of an operation takes its binding over at an action boundary
//! (issue 44, point 3): a docking run binds the wall follower's version 1.0.0 on a node of
//! its own; while the wall follower runs `follow-wall`, a node hosting version 1.1.0-rc.1
//! (one more optional parameter, the same behaviour by default) joins the cluster. The
//! binding does not move in the middle of `follow-wall`: the next action that uses the wall
//! follower starts on the new version, and the report and the run's lines say so.
//!
//! The docking mission uses the wall follower in one action only, so the test's variant also
//! runs it in `plan-parking` (until the path is planned: a control period or two of driving,
//! which the trajectory controller absorbs).
//!
//! Version 1.1.0-rc.1 calls version 1's `distance` `wall_distance` and declares the rename as
//! a migration: the mission's `distance` reaches it under its new name. Its range is
//! narrower (2.5 m): a mission asking for more is refused by `marie check`, unless it pins
//! the operation. If the new instance fails its first activation (a node config's
//! `fail_first_activations` knob), the binding goes back to version 1.0.0 (rollback).

use crate::common;
use crate::selection_cluster::{layout, COOKIE};

use common::cluster::{NodeProc, Proc};
use common::missions::docking_edited;
use serde_json::Value;
use std::net::SocketAddr;

/// The cluster's speed: `follow-wall` takes about 36 s of mission time, 12 s of wall time —
/// ample for a node to start and join while it runs, on a loaded machine.
const SPEED: &str = "3";

/// The newer wall follower (`missions/src/ops/motion/wall_follower.rs`): a release
/// candidate, hosted only where a node names it exactly.
const NEWER: &str = "1.1.0-rc.1";

/// The wall follower's record in action `action` of `report`.
fn follower_in<'a>(report: &'a Value, action: &str) -> &'a Value {
    report["actions"]
        .as_array()
        .unwrap()
        .iter()
        .find(|a| a["name"] == action)
        .unwrap_or_else(|| panic!("no action {action}: {report:#}"))["operations"]
        .as_array()
        .unwrap()
        .iter()
        .find(|op| op["name"] == "wall-follower")
        .unwrap_or_else(|| panic!("no wall follower in {action}: {report:#}"))
}

/// Wait for `run` to end and read its report from `path`: the run docked, and the wall
/// follower ran `follow-wall` and `plan-parking` on the (version, node) `ran` gives for each.
pub(crate) fn docked_on(run: &mut Proc, path: &std::path::Path, ran: [(&str, &str); 2]) -> Value {
    let code = run.wait_exit();
    let report: Value = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    assert_eq!(code, Some(0), "{report:#}");
    assert_eq!(report["outcome"], "succeeded", "{report:#}");
    for (action, (version, node)) in ["follow-wall", "plan-parking"].into_iter().zip(ran) {
        let op = follower_in(&report, action);
        assert_eq!(
            (&op["version"], &op["node"]),
            (&Value::from(version), &Value::from(node)),
            "{action}: {op:#}"
        );
    }
    report
}

/// The docking mission that also runs the wall follower in `plan-parking`, with `tail`
/// appended, written into `dir`.
pub(crate) fn docking_twice(dir: &std::path::Path, name: &str, tail: &str) -> std::path::PathBuf {
    let path = docking_edited(
        dir,
        name,
        &[(
            "[action.ops.path-planner]\n",
            "ends_on = [\"path-planner\"]\n[action.ops.wall-follower]\ndistance = 0.8\n\
             [action.ops.path-planner]\n",
        )],
    );
    let mut src = std::fs::read_to_string(&path).unwrap();
    src += tail;
    std::fs::write(&path, src).unwrap();
    path
}

/// `marie up` of the selection tests' cluster whose wall follower is version 1 on node
/// `wf-one`, its `[[operation]]` table ending with `wf_one` (`pin = true`): the process, to
/// keep until the run ended, and the cart node's address to join by.
fn start(dir: &std::path::Path, wf_one: &str) -> (Proc, String) {
    let cluster = layout(dir, &[("wf-one", "1")]);
    let config = dir.join("wf-one.toml");
    let text = std::fs::read_to_string(&config).unwrap() + wf_one;
    std::fs::write(&config, text).unwrap();
    let mut up = Proc::spawn(
        "marie up",
        &["up", cluster.to_str().unwrap(), "--speed", SPEED],
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
    (up, join)
}

/// Start a cluster whose wall follower is version 1.0.0 on node `wf-one` (its
/// `[[operation]]` table ending with `wf_one`), run `mission` on it, and start node `wf-new`
/// hosting the newer version (its table ending with `knobs`) once `follow-wall` started: the
/// run's process (its lines read until `wait_for`, a line the run prints after the newer
/// instance joined), the new node and the cluster, to keep until the run ended.
fn run_with_newer(
    dir: &std::path::Path,
    mission: &std::path::Path,
    report: &std::path::Path,
    (wf_one, knobs): (&str, &str),
    wait_for: &str,
) -> (Proc, String, NodeProc, (Proc, String)) {
    let cluster = start(dir, wf_one);
    let mut run = Proc::spawn(
        "marie run",
        &[
            "run",
            mission.to_str().unwrap(),
            "--join",
            &cluster.1,
            "--cookie",
            COOKIE,
            "--speed",
            SPEED,
            "--report",
            report.to_str().unwrap(),
            "--events",
            report.with_extension("jsonl").to_str().unwrap(),
        ],
    );
    run.wait_line("> follow-wall: start");
    // the newer version joins while version 1.0.0 follows the wall
    let join: SocketAddr = cluster.1.parse().unwrap();
    let hosts = format!(
        "dispatcher = false\n[[operation]]\nname = \"wall-follower\"\nversion = \"={NEWER}\"\n{knobs}"
    );
    let newer = NodeProc::start(dir, "wf-new", &hosts, &[join], COOKIE);
    let line = run.wait_line(wait_for);
    (run, line, newer, cluster)
}

#[test]
fn a_newer_wall_follower_started_mid_action_takes_the_binding_at_the_next_action() {
    let dir = tempfile::tempdir().unwrap();
    let mission = docking_twice(dir.path(), "docking-twice", "");
    let report = dir.path().join("report.json");
    let (mut run, upgraded, _newer, _cluster) = run_with_newer(
        dir.path(),
        &mission,
        &report,
        ("", ""),
        "wall-follower upgraded at `plan-parking`",
    );
    assert!(
        upgraded.contains("v1.0.0") && upgraded.contains(&format!("v{NEWER}")),
        "{upgraded}"
    );
    assert!(
        upgraded.contains("on wf-one") && upgraded.contains("on wf-new"),
        "{upgraded}"
    );
    // the action running when the newer version appeared finished on the old instance, and
    // the next one that used the wall follower started on the new one
    let report = docked_on(&mut run, &report, [("1.0.0", "wf-one"), (NEWER, "wf-new")]);
    let upgrades = report["upgrades"].as_array().expect("an upgrades section");
    assert_eq!(upgrades.len(), 1, "{upgrades:#?}");
    let up = &upgrades[0];
    assert_eq!(up["operation"], "wall-follower");
    assert_eq!(up["action"], "plan-parking");
    assert_eq!(up["from_version"], "1.0.0");
    assert_eq!(up["to_version"], NEWER);
    assert_eq!(up["from_node"], "wf-one");
    assert_eq!(up["to_node"], "wf-new");
    let new = follower_in(&report, "plan-parking");
    assert_eq!(up["to"], new["address"], "{up:#}\n{new:#}");
    // the move happened at the action boundary: after the old instance's last report,
    // when follow-wall had ended, at plan-parking's start
    let follow_end = report["actions"]
        .as_array()
        .unwrap()
        .iter()
        .find(|a| a["name"] == "follow-wall")
        .unwrap()["end_ms"]
        .as_u64()
        .unwrap();
    let (at, last) = (
        up["run_ms"].as_u64().unwrap(),
        up["from_last_ms"].as_u64().unwrap(),
    );
    assert!(
        last <= at && follow_end <= at,
        "{up:#}, follow-wall ended at {follow_end}"
    );
    // the binding's epoch went up with the move
    let epochs = report["bound_epochs"].to_string();
    assert!(epochs.contains("wall-follower"), "{epochs}");
    // the mission's `distance` (version 1's name) reached version 1.1 as `wall_distance`,
    // through the migration it declares
    let settings: Vec<&Value> = report["provenance"]["parameters"]
        .as_array()
        .expect("the provenance's parameters")
        .iter()
        .filter(|p| p["action"] == "plan-parking" && p["operation"] == "wall-follower")
        .collect();
    let distance = settings
        .iter()
        .find(|p| p["name"] == "wall_distance")
        .unwrap_or_else(|| panic!("no wall_distance in {settings:#?}"));
    assert_eq!(distance["source"], "mission", "{distance:#}");
    assert!(
        distance["value"].to_string().contains("0.8"),
        "{distance:#}"
    );
    assert!(
        !settings.iter().any(|p| p["name"] == "distance"),
        "{settings:#?}"
    );
}

#[test]
fn a_pinned_wall_follower_stays_on_its_version_when_a_newer_one_appears() {
    stays_pinned(
        "docking-pinned",
        "\n[pin]\nwall-follower = \"1.0.0\"\n",
        "",
        "the mission pins it to =1.0.0",
    );
}

#[test]
fn a_wall_follower_its_node_config_pins_stays_on_its_version_when_a_newer_one_appears() {
    stays_pinned(
        "docking-node-pinned",
        "",
        "pin = true\n",
        "node wf-one's config pins it to =1.0.0",
    );
}

/// Docking twice (`name`, with `header` in its `[mission]`), wf-one's wall follower with
/// `knobs` in its `[[operation]]`, a newer one started mid-run: the binding stays on
/// version 1.0.0 on wf-one, the refusal saying `why`, and the mission docks.
fn stays_pinned(name: &str, header: &str, knobs: &str, why: &str) {
    let dir = tempfile::tempdir().unwrap();
    let mission = docking_twice(dir.path(), name, header);
    let report = dir.path().join("report.json");
    let (mut run, refused, _newer, _cluster) = run_with_newer(
        dir.path(),
        &mission,
        &report,
        (knobs, ""),
        "wall-follower stays",
    );
    assert!(
        refused.contains(&format!("not moving to v{NEWER}"))
            && refused.contains("on wf-new")
            && refused.contains(why),
        "{refused}"
    );
    let report = docked_on(&mut run, &report, [("1.0.0", "wf-one"); 2]);
    assert!(report.get("upgrades").is_none(), "{report:#}");
    let lines = run.drain();
    assert!(!lines.iter().any(|l| l.contains("upgraded")), "{lines:#?}");
}

#[test]
fn a_newer_wall_follower_whose_first_activation_fails_rolls_the_binding_back() {
    let dir = tempfile::tempdir().unwrap();
    let mission = docking_twice(dir.path(), "docking-rollback", "");
    let report_path = dir.path().join("report.json");
    let report = report_path.clone();
    // the newer version's instance fails its first activation (the node's test knob)
    let (mut run, rolled, _newer, _cluster) = run_with_newer(
        dir.path(),
        &mission,
        &report,
        ("", "fail_first_activations = 1\n"),
        "wall-follower rolled back at `plan-parking`",
    );
    assert!(
        rolled.contains(&format!("v{NEWER}"))
            && rolled.contains("on wf-new")
            && rolled.contains("-> v1.0.0")
            && rolled.contains("on wf-one")
            && rolled.contains("its first activation failed")
            && rolled.contains("fail_first_activations"),
        "{rolled}"
    );
    let report = docked_on(&mut run, &report, [("1.0.0", "wf-one"); 2]);
    assert_eq!(report["acknowledged_lost"], 0, "{report:#}");

    // the binding moved at plan-parking's start, and went back at once
    let upgrades = report["upgrades"].as_array().expect("an upgrades section");
    assert_eq!(upgrades.len(), 1, "{upgrades:#?}");
    assert_eq!(upgrades[0]["action"], "plan-parking");
    let rollbacks = report["rollbacks"].as_array().expect("a rollbacks section");
    assert_eq!(rollbacks.len(), 1, "{rollbacks:#?}");
    let back = &rollbacks[0];
    assert_eq!(back["operation"], "wall-follower");
    assert_eq!(back["action"], "plan-parking");
    assert_eq!(
        (&back["from_version"], &back["from_node"]),
        (&Value::from(NEWER), &Value::from("wf-new")),
        "{back:#}"
    );
    assert_eq!(
        (&back["to_version"], &back["to_node"]),
        (&Value::from("1.0.0"), &Value::from("wf-one")),
        "{back:#}"
    );
    assert_eq!(back["from"], upgrades[0]["to"], "{back:#}");
    assert_eq!(back["to"], upgrades[0]["from"], "{back:#}");
    assert!(
        back["epoch"].as_u64() > upgrades[0]["epoch"].as_u64(),
        "the rollback raises the epoch above the move's: {back:#}"
    );
    // plan-parking ran on the old instance in the end, and so did the rest of the run
    for action in ["follow-wall", "plan-parking"] {
        let op = follower_in(&report, action);
        assert_eq!(
            (&op["version"], &op["node"], &op["address"]),
            (&Value::from("1.0.0"), &Value::from("wf-one"), &back["to"]),
            "{action}: {op:#}"
        );
    }
    // the instance rolled back from was not taken again, and no rebind happened
    assert_eq!(report["rebinds_total"], 0, "{report:#}");
    // the events file has the fact, as the run's lines had it
    let (_, events) =
        common::cluster::report_and_events(&report_path, &report_path.with_extension("jsonl"));
    let told: Vec<&Value> = events
        .iter()
        .filter(|e| e["kind"]["type"] == "binding_rolled_back")
        .collect();
    assert_eq!(told.len(), 1, "{told:#?}");
    assert_eq!(told[0]["kind"]["to_version"], "1.0.0", "{:#}", told[0]);
}

/// `marie check MISSION`: the exit code and stderr.
fn check(mission: &std::path::Path) -> (Option<i32>, String) {
    let out = common::marie(&["check", mission.to_str().unwrap()]);
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn check_refuses_a_mission_a_newer_version_could_not_take_unless_it_pins_the_operation() {
    let dir = tempfile::tempdir().unwrap();
    // version 1.1.0-rc.1 (this build's) keeps the wall within 2.5 m: 2.8 is refused ...
    let far = docking_edited(
        dir.path(),
        "docking-far",
        &[("distance = 0.8", "distance = 2.8")],
    );
    let (code, stderr) = check(&far);
    assert_eq!(code, Some(2), "{stderr}");
    for want in [
        "a newer version could not take the mission's parameters",
        &format!("operation `wall-follower`: version {NEWER} (known from this build)"),
        "could not take over from 1.0.0",
        "wall_distance: 2.8 is out of range",
        "[pin] wall-follower = \"1.0.0\"",
    ] {
        assert!(stderr.contains(want), "{want:?} not in:\n{stderr}");
    }
    // ... unless the mission pins the wall follower (it never moves)
    let pinned = docking_edited(
        dir.path(),
        "docking-far-pinned",
        &[("distance = 0.8", "distance = 2.8")],
    );
    let mut src = std::fs::read_to_string(&pinned).unwrap();
    src += "\n[pin]\nwall-follower = \"1.0.0\"\n";
    std::fs::write(&pinned, src).unwrap();
    let (code, stderr) = check(&pinned);
    assert_eq!(code, Some(0), "{stderr}");
    // and version 1's `distance` within range reaches version 1.1 through its migration
    let near = docking_twice(dir.path(), "docking-near", "");
    let (code, stderr) = check(&near);
    assert_eq!(code, Some(0), "{stderr}");
}
