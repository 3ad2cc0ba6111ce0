//! Node faults a test scripts in one command: `marie up --run … --fault` with the node kinds
//! (`stop-node`, `freeze-node`, `partition`) and `--chaos-nodes SEED`, on the thesis' layout
//! as real processes on 127.0.0.1 — each parsed and checked before the run (exit 2 when it
//! cannot be done), injected at its time, undone after its duration, and in the report.

use crate::common;

use common::http;
use common::monitor::{monitored_up, page_of};
use common::{marie, report_of, text};

const THESIS: &str = "missions/clusters/thesis.toml";
/// Wall-clock time × 4 on every node: a 3 s freeze of mission time is 0.75 s of real time,
/// an 8 s one 2 s (past the failure detector's 1.2 s deadline, which is real time).
const SPEED: &str = "4";

/// The events of an events file, as JSON values.
fn events(path: &std::path::Path) -> Vec<serde_json::Value> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

#[test]
fn a_frozen_node_is_let_go_on_after_its_duration_and_the_mission_docks() {
    let dir = tempfile::tempdir().unwrap();
    let events_path = dir.path().join("events.jsonl");
    // the spare node (a wall follower the mission may bind) frozen for 8 s of mission time
    // during the wall following: past the failure detector's deadline
    let (out, report) = report_of(&[
        "up",
        THESIS,
        "--run",
        "missions/docking.toml",
        "--speed",
        SPEED,
        "--fault",
        "freeze-node:spare@6+8",
        "--events",
        events_path.to_str().unwrap(),
    ]);
    let stdout = text(&out.stdout);
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{stdout}\n{stderr}");
    assert!(
        stdout.contains("* injected freeze-node into spare (pid "),
        "{stdout}"
    );
    assert_eq!(report["outcome"], "succeeded");
    assert_eq!(report["collisions"], 0);
    // every record the operations were told was stored is still held at the end
    assert_eq!(report["acknowledged_lost"], 0, "{}", report["dm_checks"]);
    let faults = report["faults"].as_array().unwrap();
    assert_eq!(faults.len(), 1, "{faults:?}");
    let freeze = &faults[0];
    assert_eq!(freeze["fault"], "freeze-node");
    assert_eq!(freeze["operation"], "spare");
    assert_eq!(freeze["node"], "spare");
    assert_eq!(freeze["lasting_ms"], 8000);
    assert!(freeze["actor"].as_str().unwrap().starts_with("pid "));
    // thawed once its duration was over (mission time; scheduling may add a little)
    let (at, healed) = (
        freeze["at_ms"].as_u64().unwrap(),
        freeze["healed_at_ms"]
            .as_u64()
            .expect("the freeze was healed"),
    );
    // (the report counts from the run's start, the plan from before it: a few ms, a few
    // hundred on a loaded machine — 125 ms was seen)
    assert!((5500..7000).contains(&at), "{freeze}");
    assert!(healed >= at + 8000 && healed < at + 8000 + 4000, "{freeze}");
    // the events file holds the injection and the healing, in that order
    let kinds: Vec<String> = events(&events_path)
        .iter()
        .map(|e| e["kind"]["type"].as_str().unwrap().to_string())
        .filter(|t| t.starts_with("fault_"))
        .collect();
    assert_eq!(kinds, ["fault_injected", "fault_healed"]);
    // the run's node (marie up's) lost the frozen node, and saw it back
    let lost = report["nodes_lost"].as_array().unwrap();
    assert!(
        lost.iter().any(|n| n["peer"] == "spare"
            && n["declared_down"] == true
            && n["back_at_ms"].is_u64()),
        "{lost:?}"
    );
    assert!(
        stdout.contains("verdict: 1 fault injected (freeze-node 1), 1 node lost (1 back), "),
        "{stdout}"
    );
    // the frozen node's peers declared it down while it was frozen (2 s of real time)
    assert!(
        events(&events_path)
            .iter()
            .any(|e| e["kind"]["type"] == "node_down" && e["kind"]["peer"] == "spare"),
        "no node_down of spare in the events"
    );
    // spare also runs the standby dispatcher: woken, it saw every peer lost until they
    // redialled it, but the run's dispatcher (on features) never was — nothing taken over
    let takeovers: Vec<_> = events(&events_path)
        .into_iter()
        .filter(|e| e["kind"]["type"] == "takeover")
        .collect();
    assert!(takeovers.is_empty(), "{takeovers:?}");
}

#[test]
fn node_faults_that_cannot_be_done_are_refused_before_the_run_with_exit_2() {
    for (args, want) in [
        // not a node `marie up` started
        (
            vec![
                "up",
                THESIS,
                "--run",
                "missions/docking.toml",
                "--fault",
                "freeze-node:moon@1+2",
            ],
            "no node process `moon`",
        ),
        // a freeze says how long
        (
            vec![
                "up",
                THESIS,
                "--run",
                "missions/docking.toml",
                "--fault",
                "freeze-node:spare@1",
            ],
            "say how long",
        ),
        // a stop does not last
        (
            vec![
                "up",
                THESIS,
                "--run",
                "missions/docking.toml",
                "--fault",
                "stop-node:spare@1+2",
            ],
            "does not last a while",
        ),
        // faults need a run
        (vec!["up", THESIS, "--fault", "stop-node:spare@1"], "--run"),
        (vec!["up", THESIS, "--chaos-nodes", "3"], "--run"),
        // a single process starts no node: nothing to stop, freeze or cut off
        (
            vec![
                "run",
                "missions/docking.toml",
                "--fault",
                "freeze-node:spare@1+2",
            ],
            "only `marie up` stops node processes",
        ),
    ] {
        let out = marie(&args);
        let stderr = text(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains(want), "{args:?}: {stderr}");
        assert!(
            !text(&out.stdout).contains("outcome:"),
            "{args:?} ran a mission"
        );
    }
}

#[test]
fn node_chaos_hits_nodes_other_than_the_carts_and_says_what_it_did() {
    let dir = tempfile::tempdir().unwrap();
    let events_path = dir.path().join("events.jsonl");
    let (out, report) = report_of(&[
        "up",
        THESIS,
        "--run",
        "missions/docking.toml",
        "--speed",
        SPEED,
        "--chaos-nodes",
        "1",
        "--events",
        events_path.to_str().unwrap(),
    ]);
    let stdout = text(&out.stdout);
    // the mission may or may not survive what chaos drew; the cluster stops either way
    assert!(
        stdout.contains("cluster stopped"),
        "{stdout}\n{}",
        text(&out.stderr)
    );
    assert!(report.is_object(), "no report: {stdout}");
    let injected: Vec<serde_json::Value> = events(&events_path)
        .into_iter()
        .filter(|e| e["kind"]["type"] == "fault_injected")
        .map(|e| e["kind"].clone())
        .collect();
    assert!(!injected.is_empty(), "chaos injected nothing: {stdout}");
    for f in &injected {
        let kind = f["fault"].as_str().unwrap();
        assert!(
            ["stop-node", "freeze-node", "partition"].contains(&kind),
            "{f}"
        );
        assert_ne!(f["node"], "cart", "the cart's node was hit: {f}");
        assert_ne!(f["operation"], "cart", "the cart's node was hit: {f}");
    }
}

#[test]
fn a_partition_cuts_a_node_off_in_a_private_network_heals_and_leaves_no_namespace() {
    if !common::netns::Netns::can_make() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let events_path = dir.path().join("events.jsonl");
    // the features node (the feature datamanager's leader; its replicas are on the others)
    // cut off from every other node for 8 s of mission time (2 s of real time)
    let (out, report) = report_of(&[
        "up",
        THESIS,
        "--run",
        "missions/docking.toml",
        "--speed",
        SPEED,
        "--fault",
        "partition:features|cart,operations,spare@6+8",
        "--events",
        events_path.to_str().unwrap(),
    ]);
    let stdout = text(&out.stdout);
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{stdout}\n{stderr}");
    // the nodes ran in the private network, each at its own address there
    for (node, ip) in [
        ("cart", "10.77.1.2"),
        ("features", "10.77.2.2"),
        ("operations", "10.77.3.2"),
        ("spare", "10.77.4.2"),
    ] {
        assert!(stdout.contains(&format!("  {node} at {ip}:")), "{stdout}");
    }
    assert_eq!(report["outcome"], "succeeded", "{stdout}");
    let cut = &report["faults"][0];
    assert_eq!(cut["fault"], "partition");
    assert_eq!(cut["operation"], "features|cart,operations,spare");
    assert_eq!(cut["lasting_ms"], 8000);
    assert!(cut["healed_at_ms"].as_u64().is_some(), "{cut}");
    // both sides declared the other down: the cut was real, both ways
    let downs: Vec<(String, String)> = events(&events_path)
        .iter()
        .filter(|e| e["kind"]["type"] == "node_down")
        .map(|e| {
            (
                e["node"].as_str().unwrap().to_string(),
                e["kind"]["peer"].as_str().unwrap().to_string(),
            )
        })
        .collect();
    assert!(
        downs
            .iter()
            .any(|(by, peer)| by == "features" && peer != "features"),
        "features declared nobody down: {downs:?}"
    );
    assert!(
        downs
            .iter()
            .any(|(by, peer)| by != "features" && peer == "features"),
        "nobody declared features down: {downs:?}"
    );
    // the namespaces of that `marie up` are gone
    let up_pid = stderr
        .lines()
        .find_map(|l| {
            l.strip_prefix("up-")?
                .split_once(' ')
                .map(|(p, _)| p.to_string())
        })
        .expect("the up member's line");
    let list = std::process::Command::new("ip")
        .args(["netns", "list"])
        .output()
        .unwrap();
    assert!(
        !text(&list.stdout).contains(&format!("marieup{up_pid}-")),
        "namespaces left: {}",
        text(&list.stdout)
    );
}

#[test]
fn operations_cut_off_from_the_cart_hold_until_it_is_back_and_the_mission_docks() {
    if !common::netns::Netns::can_make() {
        return;
    }
    // the operations and spare nodes (the localizer, wall sensor, wall follower, ... are
    // bound on one of them) lose the cart for 8 s of mission time while all still reach
    // the features node and marie up: the operations that drive or read the cart hold
    // their steps until it is back in their registry, instead of failing the mission (they
    // did: `the virtual cart did not answer`, a full stop)
    let (out, report) = report_of(&[
        "up",
        THESIS,
        "--run",
        "missions/docking.toml",
        "--speed",
        SPEED,
        "--fault",
        "partition:operations,spare|cart@6+8",
    ]);
    let stdout = text(&out.stdout);
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{stdout}\n{stderr}");
    assert!(
        stderr.contains("module gone: waiting for it") && stderr.contains("module=virtual-cart"),
        "no operation waited for the cart: {stderr}"
    );
    assert_eq!(report["outcome"], "succeeded");
    assert_eq!(report["collisions"], 0);
    assert!(report["faults"][0]["healed_at_ms"].as_u64().is_some());
}

#[test]
fn the_killed_node_of_the_bound_operations_is_replaced_by_the_other_and_the_mission_docks() {
    // the node the mission bound most of its operations on (operations or spare: the
    // layout has a standby of each on the other; which is bound is the selection's call) is
    // killed from the page while the wall is followed: its operations are rebound to their
    // standbys, the datamanagers fail over to a replica where the node held a leader, and a
    // stand-in whose `activate` waited for its datamanager runs it again once it is back
    // (it stepped without its map before)
    let (mut up, line) = monitored_up(
        THESIS,
        &[
            "--run",
            "missions/docking.toml",
            "--speed",
            SPEED,
            "--allow-faults",
        ],
    );
    let (addr, _) = page_of(&line);
    // `  bound localizer v1.0.0 on spare`
    let bound = up.wait_line("bound localizer v1.0.0 on ");
    let node = bound.rsplit(' ').next().unwrap().to_string();
    assert!(["operations", "spare"].contains(&node.as_str()), "{bound}");
    let other = if node == "operations" {
        "spare"
    } else {
        "operations"
    };
    up.wait_line("> follow-wall: start");
    let stop = serde_json::json!({"fault": "stop-node", "node": node});
    let (status, answer) = http::post_json(addr, "/api/fault", &stop);
    assert_eq!(status, 200, "{answer}");
    let rebound = up.wait_line("localizer rebound: ");
    assert!(
        rebound.contains(&format!(" on {node} -> "))
            && rebound.contains(&format!(" on {other} after ")),
        "{rebound}"
    );
    up.wait_line("mission succeeded");
    let outcome = up.wait_line("outcome: ");
    assert!(outcome.contains("outcome: succeeded"), "{outcome}");
    assert!(outcome.ends_with("collisions: 0"), "{outcome}");
    let verdict = up.wait_line("verdict: ");
    assert!(
        // `up` restarts the killed node (the thesis layout's nodes are permanent)
        verdict.starts_with("verdict: 1 fault injected (stop-node 1), 1 node lost (1 back), "),
        "{verdict}"
    );
    // the dispatcher (on features) was not lost: its checkpoints and its answers to the
    // standby desk went on through the failover of the leaders on the killed node — no
    // request of it waited for its client's deadline — so nothing was taken over
    assert!(verdict.contains(", 0 takeovers, "), "{verdict}");
    // the datamanagers' leaders on the killed node failed over to replicas that hold every
    // record the operations were told was stored, the killed node's own producers' too
    // (`N of M acknowledged records lost`, M > 0: the stores were heard from the nodes)
    let counts: Vec<u64> = verdict
        .split(", ")
        .find(|part| part.ends_with(" acknowledged records lost"))
        .unwrap_or_else(|| panic!("no check in {verdict}"))
        .split(' ')
        .filter_map(|w| w.parse().ok())
        .collect();
    assert!(counts[0] == 0 && counts[1] > 0, "{verdict}");
    up.wait_line("the run is over");
    up.signal("INT");
    up.wait_line("cluster stopped");
    assert_eq!(up.wait_exit(), Some(0), "{}", up.seen().join("\n"));
}

/// `marie up CLUSTER --run` docking with the dispatcher's node killed at 3 s and the
/// operations' node at 9 s (each keeps a replica of every datamanager), and `extra` flags:
/// its stdout, once it exited with `code`.
fn two_kills(cluster: &str, extra: &[&str], code: i32) -> String {
    let mut args = vec![
        "up",
        cluster,
        "--run",
        "missions/docking.toml",
        "--speed",
        SPEED,
        "--fault",
        "stop-node:features@3",
        "--fault",
        "stop-node:operations@9",
    ];
    args.extend_from_slice(extra);
    let out = marie(&args);
    let stdout = text(&out.stdout);
    assert_eq!(
        out.status.code(),
        Some(code),
        "{stdout}\n{}",
        text(&out.stderr)
    );
    stdout
}

#[test]
fn two_nodes_of_every_datamanager_killed_six_seconds_apart_are_restarted_and_the_mission_docks() {
    // the dispatcher's node (a replica of every datamanager) killed at 3 s, then the
    // operations' node (another) at 9 s: `up` restarts each (permanent, the default), it
    // recovers its journals and its replicas catch up, so when the second dies the first is
    // back and every datamanager keeps its majority; the standby carries the run on
    let dir = tempfile::tempdir().unwrap();
    let report_path = dir.path().join("report.json");
    let events_path = dir.path().join("events.jsonl");
    let stdout = two_kills(
        THESIS,
        &[
            "--report",
            report_path.to_str().unwrap(),
            "--events",
            events_path.to_str().unwrap(),
        ],
        0,
    );
    for node in ["features", "operations"] {
        assert!(
            stdout.contains(&format!(
                "node {node} was killed (SIGKILL): restarting it in 0.10 s (restart 1 of at \
                 most 5 within 60 s)"
            )),
            "{stdout}"
        );
        assert!(
            stdout.contains(&format!("node {node} restarted: listening on ")),
            "{stdout}"
        );
    }
    assert!(stdout.contains("mission succeeded"), "{stdout}");
    // the two killed nodes lost and back, and the run taken over from features; on a
    // machine loaded far past its cores a starved node may be declared down too (and a
    // takeover follow): every node lost is back all the same
    assert!(
        stdout.contains("2 faults injected (stop-node 2)"),
        "{stdout}"
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report_path).unwrap()).unwrap();
    assert_eq!(report["outcome"], "succeeded");
    assert_eq!(report["acknowledged_lost"], 0, "{report}");
    assert!(
        !report["takeovers"].as_array().unwrap().is_empty(),
        "{report}"
    );
    let lost = report["nodes_lost"].as_array().unwrap();
    for node in ["features", "operations"] {
        assert!(lost.iter().any(|n| n["peer"] == node), "{lost:?}");
    }
    for n in lost {
        assert!(
            n["back_at_ms"].as_u64().unwrap() > n["at_ms"].as_u64().unwrap(),
            "{lost:?}"
        );
    }
    // the peers that lost each node tell it back, with how long it was away
    let events = events(&events_path);
    for node in ["features", "operations"] {
        assert!(
            events.iter().any(|e| e["kind"]["type"] == "node_back"
                && e["kind"]["peer"] == node
                && e["kind"]["down_ms"].as_u64().is_some_and(|ms| ms > 0)),
            "no node_back of {node}"
        );
    }
}

#[test]
fn a_datamanager_that_lost_its_majority_ends_the_run_in_bounded_time_naming_the_nodes_it_misses() {
    // the same two kills, but the nodes stay down: the run datamanager (and the others)
    // lose their majority; the run waits for it (marie_dm::MAJORITY_WAIT, 15 s), then
    // fails with a reason an operator can act on — not a wait without end
    let dir = tempfile::tempdir().unwrap();
    let cluster = common::layouts::thesis_with(dir.path(), "restart = \"temporary\"");
    let stdout = two_kills(cluster.to_str().unwrap(), &[], 1);
    assert!(
        stdout.contains(
            "node operations was killed (SIGKILL): it stays down (restart = \"temporary\")"
        ),
        "{stdout}"
    );
    let failed = stdout
        .lines()
        .find(|l| l.starts_with("mission FAILED (full stop): "))
        .unwrap_or_else(|| panic!("no failure in {stdout}"));
    assert!(
        failed.contains(
            "has no majority: 1 of its 3 replicas answers (spare), a leader needs 2; \
                         missing: features, operations"
        ),
        "{failed}"
    );
}
