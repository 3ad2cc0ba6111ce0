//! Faults from the monitor's page, over its HTTP API, on a real run (issue 13): with
//! `--allow-faults` the page asks the bound wall follower for its live properties, kills it
//! and hangs its stand-in, and the dispatcher rebinds each time until docking succeeds.
//! (Without the flag the page's faults are refused: `monitor/tests/control.rs`, and on a
//! real run `monitor_browser`; stopping a node's process under `marie up`: `tests/monitor.rs`
//! and `monitor_browser`.)

mod common;

use common::cluster::Proc;
use common::http;
use common::monitor::{page_of, state_until};
use serde_json::{json, Value};

/// The wall follower's binding in `state`, as the page's fault buttons name it.
fn wall_follower(state: &Value) -> Value {
    let b = &state["bindings"]["wall-follower"];
    json!({"operation": "wall-follower", "node": b["node"], "address": b["address"]})
}

fn with_fault(target: &Value, fault: &str) -> Value {
    let mut request = target.clone();
    request["fault"] = json!(fault);
    request
}

#[test]
fn the_page_asks_the_wall_follower_kills_it_hangs_its_stand_in_and_docking_succeeds() {
    let dir = tempfile::tempdir().unwrap();
    let report = dir.path().join("report.json");
    let mut run = Proc::spawn(
        "run",
        &[
            "run",
            "missions/docking.toml",
            "--speed",
            "4",
            "--monitor",
            "127.0.0.1:0",
            "--allow-faults",
            "--report",
            report.to_str().unwrap(),
        ],
    );
    let (addr, _) = page_of(&run.wait_line("monitor: http://"));
    let info = http::get_json(addr, "/api/info");
    assert_eq!(info["faults_allowed"], true, "{info}");
    assert_eq!(
        info["offers"]["stoppable_nodes"],
        json!([]),
        "no node process to stop"
    );
    let state = state_until(addr, "the wall follower running", |s| {
        s["mission"]["actions"].as_array().is_some_and(|a| {
            a.iter()
                .any(|a| a["name"] == "follow-wall" && a["state"] == "running")
        })
    });
    let first = wall_follower(&state);

    // its properties, asked of the live instance
    let query = format!(
        "/api/props?operation=wall-follower&node={}&address={}",
        first["node"].as_str().unwrap(),
        first["address"].as_str().unwrap()
    );
    let props = http::get_json(addr, &query);
    let group = |name: &str| {
        props
            .as_array()
            .unwrap()
            .iter()
            .find_map(|g| g.get(name).cloned())
            .unwrap_or_else(|| panic!("no {name} in {props}"))
    };
    assert_eq!(group("Identification")["name"], "wall-follower");
    assert_eq!(
        group("Identification")["version"],
        state["bindings"]["wall-follower"]["version"]
    );
    assert_eq!(group("Location")["address"], first["address"]);
    assert_eq!(group("General")["in_use"], true, "{props}");

    // kill it: its supervisor restarts it, the dispatcher rebinds
    let (status, answer) = http::post_json(addr, "/api/fault", &with_fault(&first, "kill"));
    assert_eq!(status, 200, "{answer}");
    assert!(
        answer["done"].as_str().unwrap().contains("kill injected"),
        "{answer}"
    );
    let state = state_until(addr, "the first rebind", |s| {
        s["bindings"]["wall-follower"]["rebinds"] == 1
    });
    let second = wall_follower(&state);
    assert_ne!(second["address"], first["address"]);
    // the old address names nothing any more: a stale click hits no other instance
    let (status, answer) = http::post_json(addr, "/api/fault", &with_fault(&first, "kill"));
    assert_eq!(status, 404, "{answer}");
    assert!(
        answer["error"]
            .as_str()
            .unwrap()
            .contains("no longer running"),
        "{answer}"
    );

    // hang the stand-in: the dispatcher's deadline kills it and rebinds again
    let (status, answer) = http::post_json(addr, "/api/fault", &with_fault(&second, "hang"));
    assert_eq!(status, 200, "{answer}");
    let state = state_until(addr, "the rebind after the hang", |s| {
        s["bindings"]["wall-follower"]["history"]
            .as_array()
            .is_some_and(|h| {
                h.iter().any(|step| {
                    step["type"] == "lost" && step["cause"].as_str().unwrap_or("").contains("hung")
                })
            })
            && s["bindings"]["wall-follower"]["status"] == "bound"
    });
    let faults: Vec<&Value> = state["timeline"]["entries"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|e| e["class"] == "fault")
        .collect();
    assert!(faults.len() >= 2, "{faults:?}");

    let end = state_until(addr, "the outcome", |s| !s["mission"]["outcome"].is_null());
    assert_eq!(end["mission"]["outcome"]["outcome"], "succeeded", "{end}");
    run.wait_line("the run is over");
    // written when the run ended, not when the page is closed: two rebinds, one per fault
    let written: Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    assert_eq!(written["outcome"], "succeeded");
    assert_eq!(
        written["rebinds"].as_array().map(Vec::len),
        Some(2),
        "{written:#}"
    );
    run.signal("INT");
    assert_eq!(run.wait_exit(), Some(0), "{}", run.seen().join("\n"));
}
