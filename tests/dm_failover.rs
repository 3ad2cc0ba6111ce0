//! The thesis layout survives the loss of a datamanager's node: `missions/clusters/
//! thesis.toml` keeps each datamanager in three replicas (features, operations, spare), and the
//! docking mission run by `marie up` succeeds when the features node — the feature
//! datamanager's leader, and replicas of the other two — is killed (`kill -9`) or frozen past
//! the failure detector's deadline at different moments of the run: a replica on another node
//! is elected leader (`dm_promoted` in the run's events), the operations' clients follow
//! it, and they carry on from the records they stored.

use crate::common;

use common::cluster::Proc;
use serde_json::Value;

/// Fast enough to keep the suite short, slow enough for a 2-core machine under load.
const SPEED: &str = "4";

/// Run docking on the thesis layout; at `moment` (a line of `marie up`), send `signal` to
/// the features node (a freeze lasts until `wake`). The report and the run's events.
fn lose_the_features_node(signal: &str, moment: &str, wake: &str) -> (Value, Vec<Value>) {
    let dir = tempfile::tempdir().unwrap();
    let report = dir.path().join("report.json");
    let events = dir.path().join("events.jsonl");
    let mut up = Proc::spawn(
        "marie up",
        &[
            "up",
            "missions/clusters/thesis.toml",
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
    let line = up.wait_line("  features at ");
    let pid: u32 = line
        .split_once("(pid ")
        .and_then(|(_, rest)| rest.split_once(')')?.0.parse().ok())
        .unwrap_or_else(|| panic!("no pid in {line:?}"));
    up.wait_line(moment);
    // a stopped node is continued however the test ends
    let stopped = match signal {
        "STOP" => Some(common::cluster::Stopped::stop(pid)),
        _ => {
            common::cluster::signal_pid(pid, signal);
            None
        }
    };
    up.wait_line(wake);
    drop(stopped);
    up.wait_line("cluster stopped");
    let code = up.wait_exit();
    assert!(
        common::cluster::wait_gone(pid),
        "features outlived marie up"
    );
    assert_eq!(
        code,
        Some(0),
        "{}\n(stderr:)\n{}",
        up.seen().join("\n"),
        up.stderr_tail()
    );
    common::cluster::report_and_events(&report, &events)
}

/// The mission succeeded, and the feature datamanager was promoted on another node.
fn assert_survived(report: &Value, events: &[Value]) {
    assert_eq!(report["outcome"], "succeeded", "{report:#}");
    let promoted: Vec<&Value> = events
        .iter()
        .filter(|e| e["kind"]["type"] == "dm_promoted" && e["kind"]["dm"] == "feature")
        .collect();
    assert!(
        promoted.iter().any(|e| e["kind"]["node"] != "features"),
        "no replica of feature was promoted elsewhere: {promoted:?}"
    );
}

#[test]
fn killing_the_features_node_while_the_wall_is_followed_loses_nothing_the_mission_needs() {
    let (report, events) =
        lose_the_features_node("KILL", "> follow-wall: start", "< follow-wall: end");
    assert_survived(&report, &events);
}

#[test]
fn killing_the_features_node_while_the_cart_parks_loses_nothing_the_mission_needs() {
    let (report, events) = lose_the_features_node("KILL", "> park: start", "mission ");
    assert_survived(&report, &events);
}

#[test]
fn freezing_the_features_node_while_the_wall_is_followed_loses_nothing_the_mission_needs() {
    let (report, events) =
        lose_the_features_node("STOP", "> follow-wall: start", "< follow-wall: end");
    assert_survived(&report, &events);
}
