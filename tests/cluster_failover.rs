//! Failover across real processes: the node that hosts the running wall follower is killed
//! (`kill -9`) or frozen (`SIGSTOP`) while the docking mission runs; the dispatcher, on a
//! process of its own, rebinds to the wall follower of another node and the mission
//! succeeds, the rebind naming both nodes in the report.
//!
//! The layout is the thesis' with the wall follower on two nodes of its own (`wf-a`,
//! `wf-b`), so that whichever one the dispatcher binds can be lost alone.
//!
//! And the other way round: the only instance of an operation is on a node frozen past
//! the deadline; woken, the node restarts it, and the dispatcher adopts that one.

use crate::common;

use common::cluster::{NodeProc, Proc};
use common::layouts::failover_layout;
use serde_json::Value;

const SPEED: &str = "4";

/// Run docking on the layout; once the wall follower runs, send `signal` to its node.
/// Gives the report, the node hit, `marie up`'s lines and the run's events.
fn lose_the_wall_followers_node(
    signal: &str,
    followers: &[&str],
    standby: bool,
) -> (Value, String, Vec<String>, Vec<Value>) {
    let dir = tempfile::tempdir().unwrap();
    let cluster = failover_layout(dir.path(), followers, standby);
    let report = dir.path().join("report.json");
    let events = dir.path().join("events.jsonl");
    let mut up = Proc::spawn(
        "marie up",
        &[
            "up",
            cluster.to_str().unwrap(),
            "--run",
            "missions/docking.toml",
            "--speed",
            SPEED,
            "--report",
            report.to_str().unwrap(),
            "--events",
            events.to_str().unwrap(),
        ],
    );
    let bound = up.wait_line("bound wall-follower");
    let node = bound.rsplit(' ').next().unwrap().to_string();
    assert!(followers.contains(&node.as_str()), "{bound}");
    let pid: u32 = up
        .seen()
        .iter()
        .find_map(|l| {
            let rest = l.trim().strip_prefix(&format!("{node} at "))?;
            rest.split_once("(pid ")?.1.split_once(')')?.0.parse().ok()
        })
        .expect("the node's pid");
    up.wait_line("> follow-wall: start");
    // a stopped node is continued however the test ends
    let stopped = match signal {
        "STOP" => Some(common::cluster::Stopped::stop(pid)),
        _ => {
            common::cluster::signal_pid(pid, signal);
            None
        }
    };
    up.wait_line("wall-follower rebound");
    // wake it while the mission goes on; it must end with the cluster
    drop(stopped);
    up.wait_line("cluster stopped");
    let code = up.wait_exit();
    assert!(common::cluster::wait_gone(pid), "{node} outlived marie up");
    assert_eq!(code, Some(0), "{}", up.seen().join("\n"));
    let (report, events) = common::cluster::report_and_events(&report, &events);
    (report, node, up.seen().to_vec(), events)
}

fn assert_rebound_across_nodes(report: &Value, lost: &str, other: &str) {
    assert_eq!(report["outcome"], "succeeded", "{report:#}");
    assert_eq!(report["collisions"], 0);
    let rebinds = report["rebinds"].as_array().unwrap();
    let rebind = rebinds
        .iter()
        .find(|r| r["operation"] == "wall-follower")
        .unwrap_or_else(|| panic!("no wall-follower rebind: {rebinds:?}"));
    assert_eq!(rebind["from_node"], lost, "{rebind}");
    assert_eq!(rebind["to_node"], other, "{rebind}");
    // the actions after the loss ran on the survivor
    let park_ops: Vec<&Value> = report["actions"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|a| a["operations"].as_array().unwrap())
        .filter(|op| op["name"] == "wall-follower")
        .collect();
    assert_eq!(park_ops.last().unwrap()["node"], other, "{park_ops:?}");
}

#[test]
fn killing_the_wall_followers_node_rebinds_to_the_other_node_and_the_mission_succeeds() {
    let (report, lost, lines, events) =
        lose_the_wall_followers_node("KILL", &["wf-a", "wf-b"], false);
    assert_rebound_across_nodes(&report, &lost, other(&lost));
    assert!(
        lines
            .iter()
            .any(|l| l.contains(&format!("node {lost} was killed"))),
        "{lines:?}"
    );
    // the events file has every surviving node's events, forwarded to the run's member:
    // each of them lost the killed node
    let mut losers: Vec<&str> = events
        .iter()
        .filter(|e| e["kind"]["type"] == "node_lost" && e["kind"]["peer"] == lost.as_str())
        .filter_map(|e| e["node"].as_str())
        .collect();
    losers.sort();
    losers.dedup();
    for node in ["cart", "features", "operations", other(&lost)] {
        assert!(losers.contains(&node), "{node} not in {losers:?}");
    }
}

#[test]
fn freezing_the_wall_followers_node_gets_it_declared_down_rebound_and_the_mission_succeeds() {
    let (report, lost, _, events) = lose_the_wall_followers_node("STOP", &["wf-a", "wf-b"], false);
    assert_rebound_across_nodes(&report, &lost, other(&lost));
    // noticed by the failure detector — the dispatcher's node declared it down,
    // then the instance was lost and rebound — not by a broken connection
    // the node the run was dispatched on (`marie up`'s member, or a node's desk)
    let dispatcher = events
        .iter()
        .find(|e| e["kind"]["type"] == "run_started")
        .and_then(|e| e["node"].as_str())
        .expect("a run_started")
        .to_string();
    let position = |kind: &str, key: &str, value: &str| {
        events
            .iter()
            .position(|e| {
                // the dispatcher's node's own events, not those other nodes forward
                e["node"].as_str() == Some(dispatcher.as_str())
                    && e["kind"]["type"] == kind
                    && e["kind"][key] == value
            })
            .unwrap_or_else(|| panic!("no {kind} with {key} {value}: {events:?}"))
    };
    let down = position("node_down", "peer", &lost);
    let rebound = position("rebound", "operation", "wall-follower");
    assert!(down < rebound, "{:?}", &events[down..=rebound]);
    assert!(
        events[down]["kind"]["silent_ms"].as_u64().unwrap()
            >= common::cluster::default_deadline_ms()
    );
    // and the rebind blames the node
    assert_eq!(
        events[rebound]["kind"]["cause"],
        serde_json::json!({"type": "node_down", "node": lost}),
        "{}",
        events[rebound]
    );
}

fn other(wf: &str) -> &'static str {
    if wf == "wf-a" {
        "wf-b"
    } else {
        "wf-a"
    }
}

#[test]
fn when_no_wall_follower_survives_a_node_that_allows_one_starts_it_and_the_mission_succeeds() {
    // the only running wall follower is on wf-a; the operations node may start one
    let (report, lost, _, events) = lose_the_wall_followers_node("KILL", &["wf-a"], true);
    assert_eq!(lost, "wf-a");
    assert_rebound_across_nodes(&report, &lost, "operations");
    // the operations node started it under its dynamic supervisor, and says so in the
    // events file, once
    assert!(
        events.iter().any(|e| e["node"] == "operations"
            && e["kind"]["type"] == "child_started"
            && e["kind"]["supervisor"] == "dynamic"),
        "{events:?}"
    );
    let started = events
        .iter()
        .filter(|e| {
            e["node"] == "operations"
                && e["kind"]["type"] == "child_started"
                && e["kind"]["supervisor"] == "dynamic"
        })
        .count();
    assert_eq!(started, 1, "{events:?}");
    let joined = events
        .iter()
        .filter(|e| {
            e["node"] != e["kind"]["node"]
                && e["kind"]["type"] == "joined"
                && !e["node"].as_str().is_some_and(|n| n.starts_with("run-"))
        })
        .count();
    assert_eq!(joined, 0, "a node echoed another node's module");
}

/// The frozen node's layout: `alpha` with the feature datamanager, `ops` with the only
/// sampler of the cluster (and no other node that could start one).
const ALPHA: &str = "[[datamanager]]\nname = \"feature\"\n";
const OPS: &str = "[[operation]]\nname = \"sampler\"\n";
/// One action: 3000 samples, a step every 2 ms of the cluster's clock (at least 6 s).
const SAMPLE: &str = r#"
[mission]
name = "sample"
description = "sample while the only sampler's node is frozen past the deadline and woken"
success = ["sampled"]
deadline_s = 600.0
rebind_deadline_s = 20.0

[flags]
sampled = 0

[[action]]
name = "sample"
ends_on = ["sampler"]
deadline_s = 600.0

[action.ops.sampler]
count = 3000
"#;

#[test]
fn the_only_instance_restarted_by_its_node_woken_from_a_freeze_is_adopted_and_the_mission_succeeds()
{
    let dir = tempfile::tempdir().unwrap();
    let mission = dir.path().join("sample.toml");
    std::fs::write(&mission, SAMPLE).unwrap();
    let report = dir.path().join("report.json");
    let events = dir.path().join("events.jsonl");
    const COOKIE: &str = "adopt";
    let alpha = NodeProc::start(dir.path(), "alpha", ALPHA, &[], COOKIE);
    let mut ops = NodeProc::start(dir.path(), "ops", OPS, &[alpha.addr], COOKIE);
    ops.wait_line("node ops sees alpha");
    let mut run = Proc::spawn(
        "run",
        &[
            "run",
            mission.to_str().unwrap(),
            "--join",
            &alpha.addr.to_string(),
            "--cookie",
            COOKIE,
            "--report",
            report.to_str().unwrap(),
            "--events",
            events.to_str().unwrap(),
        ],
    );
    run.wait_line("bound sampler v1.0.0 on ops");
    run.wait_line("> sample: start");
    // (every process is a child of this test, killed with SIGKILL when its handle drops:
    // also when it is stopped)
    ops.signal_now(libc::SIGSTOP);
    run.wait_line("! sampler lost: its node `ops` went down");
    // its grace passed, the dispatcher asked the cluster for a stand-in while ops was
    // still frozen: no node could start one
    run.wait_stderr("no node can start a stand-in");
    // the dispatcher's process is held while ops wakes and restarts its sampler as a new
    // incarnation: that one reaches the dispatcher's registry as their session opens, and
    // so before ops is up again there (its verdict lifted only by a ready session)
    run.signal_now(libc::SIGSTOP);
    let mark = ops.seen().len();
    ops.signal_now(libc::SIGCONT);
    ops.wait_line_since(
        mark,
        "node ops restarted its 1 operation instance(s) as a new incarnation",
    );
    run.signal_now(libc::SIGCONT);
    run.wait_line("~ sampler rebound");
    assert_eq!(
        run.wait_exit(),
        Some(0),
        "{}\n{}",
        run.seen().join("\n"),
        run.stderr_tail()
    );
    let (report, events) = common::cluster::report_and_events(&report, &events);
    assert_eq!(report["outcome"], "succeeded", "{report:#}");
    let rebinds = report["rebinds"].as_array().unwrap();
    assert_eq!(rebinds.len(), 1, "{report:#}");
    let rebind = &rebinds[0];
    assert_eq!(rebind["operation"], "sampler");
    assert_eq!(rebind["from_node"], "ops", "{rebind}");
    assert_eq!(rebind["to_node"], "ops", "{rebind}");
    assert_ne!(rebind["from"], rebind["to"], "{rebind}");
    assert_eq!(
        rebind["cause"],
        serde_json::json!({"type": "node_down", "node": "ops"}),
        "{rebind}"
    );
    // the stand-in is the sampler ops restarted when it woke, not one started on request
    // (its provisioner was asked while it was frozen)
    let restarted = events
        .iter()
        .filter(|e| {
            e["node"] == "ops"
                && e["kind"]["type"] == "child_restarted"
                && e["kind"]["child"]
                    .as_str()
                    .is_some_and(|c| c.starts_with("sampler@"))
        })
        .count();
    assert_eq!(restarted, 1, "{events:?}");
    assert!(
        !events.iter().any(|e| e["node"] == "ops"
            && e["kind"]["type"] == "child_started"
            && e["kind"]["supervisor"] == "dynamic"),
        "{events:?}"
    );
}
