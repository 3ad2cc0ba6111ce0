//! Faults from the monitor's page, over its HTTP API, on a real run (issue 13): with
//! `--allow-faults` the page asks the bound wall follower for its live properties, kills it
//! and hangs its stand-in, and the dispatcher rebinds each time until docking succeeds.
//! (Without the flag the page's faults are refused: `monitor/tests/control.rs`, and on a
//! real run `monitor_browser`; stopping a node's process under `marie up`: `tests/monitor.rs`
//! and `monitor_browser`.)

use crate::common;

use common::cluster::Proc;
use common::http;
use common::monitor::{page_of, state_until};
use serde_json::{json, Value};

/// The wall follower's binding in `state`, as the page's fault buttons name it.
fn wall_follower(state: &Value) -> Value {
    let b = &state["bindings"]["wall-follower"];
    json!({"operation": "wall-follower", "node": b["node"], "address": b["address"]})
}

/// `marie run missions/docking.toml` at speed 4 with a page that may inject faults, and
/// `more` flags; the run and its page's address.
fn docking_with_a_page(more: &[&str]) -> (Proc, std::net::SocketAddr) {
    let mut args = vec![
        "run",
        "missions/docking.toml",
        "--speed",
        "4",
        "--monitor",
        "127.0.0.1:0",
        "--allow-faults",
    ];
    args.extend_from_slice(more);
    let mut run = Proc::spawn("run", &args);
    let (addr, _) = page_of(&run.wait_line("monitor: http://"));
    (run, addr)
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
    let (mut run, addr) = docking_with_a_page(&["--report", report.to_str().unwrap()]);
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

/// One run, one stream (issue 21): faults from a plan, from seeded chaos and from the page
/// all reach the report the run writes — and that report is exactly the fold of the run's
/// events file, whichever source a fault came from.
#[test]
fn faults_from_a_plan_chaos_and_the_page_are_in_the_report_which_is_the_fold_of_its_events() {
    use marie::events::Event;
    use marie::report::RunReport;
    let dir = tempfile::tempdir().unwrap();
    let report = dir.path().join("report.json");
    let events = dir.path().join("events.jsonl");
    let (mut run, addr) = docking_with_a_page(&[
        "--fault",
        "kill:wall-sensor@3",
        "--chaos",
        "5",
        "--report",
        report.to_str().unwrap(),
        "--events",
        events.to_str().unwrap(),
    ]);
    let state = state_until(addr, "the wall follower running", |s| {
        s["mission"]["actions"].as_array().is_some_and(|a| {
            a.iter()
                .any(|a| a["name"] == "follow-wall" && a["state"] == "running")
        }) && s["bindings"]["wall-follower"]["status"] == "bound"
    });
    let (status, answer) = http::post_json(
        addr,
        "/api/fault",
        &with_fault(&wall_follower(&state), "kill"),
    );
    assert_eq!(status, 200, "{answer}");
    state_until(addr, "the outcome", |s| !s["mission"]["outcome"].is_null());
    run.wait_line("the run is over");
    run.signal("INT");
    assert_eq!(run.wait_exit(), Some(0), "{}", run.seen().join("\n"));

    let written: Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    let lines = std::fs::read_to_string(&events).unwrap();
    let stream: Vec<Event> = lines
        .lines()
        .map(|l| Event::from_json_line(l).unwrap_or_else(|e| panic!("{l}: {e}")))
        .collect();
    let rebuilt = serde_json::to_value(RunReport::from_events(&stream)).unwrap();
    assert_eq!(rebuilt, written, "the report is the fold of its events");

    // each source's fault is there: the plan's (due at 3 s), the page's (an instance on a
    // node, as the page names it), and chaos' kills (the running action's operations by name)
    let faults = written["faults"].as_array().unwrap();
    let target = |f: &Value| f["operation"].as_str().unwrap_or_default().to_string();
    assert!(
        faults.iter().any(|f| target(f) == "wall-sensor"),
        "the plan's: {written:#}"
    );
    assert!(
        faults
            .iter()
            .any(|f| target(f).starts_with("wall-follower/") && f["error"].is_null()),
        "the page's: {written:#}"
    );
    let chaos = stream.iter().filter(|e| {
        matches!(&e.kind, marie::events::EventKind::FaultInjected { due_ms: None, operation, .. } if !operation.contains('/'))
    });
    assert!(chaos.count() >= 1, "chaos struck: {written:#}");
    assert_eq!(
        written["faults_total"].as_u64(),
        Some(faults.len() as u64),
        "{written:#}"
    );
}
