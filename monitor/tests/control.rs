//! The page's control routes over real HTTP on 127.0.0.1: what `/api/info` offers, the
//! properties asked on a click, faults and changes of replicas — refused unless allowed,
//! refused without a JSON content type, passed to the [`Control`] and answered with what it
//! did or why not.
//!
//! The control here records what it is asked (the real one, the CLI's, kills real actors
//! and processes and moves real replicas: the `marie` package's tests `monitor_faults` and
//! `monitor_browser`).

#[allow(dead_code)] // each test file uses part of it
#[path = "../../tests/common/http.rs"]
mod http;

use marie_monitor::control::{
    Answer, Control, ControlError, FaultOn, FaultRequest, Offers, OperationRef, ReplicaChange,
    ReplicaRequest,
};
use marie_monitor::{Monitor, MonitorOptions};
use marie_vocabulary::clock::ManualClock;
use marie_vocabulary::events::EventBus;
use marie_vocabulary::run::FaultKind;
use serde_json::json;
use std::path::Path;
use std::sync::{Arc, Mutex};

/// Answers properties for `wall-follower` only, does any fault, remembers the faults;
/// changes the replicas of `feature` only, on nodes `cart` (add) and `spare` (remove, which
/// it refuses as the last but two), and remembers the changes.
#[derive(Default)]
struct Recording {
    faults: Mutex<Vec<FaultRequest>>,
    changes: Mutex<Vec<ReplicaRequest>>,
}

impl Control for Recording {
    fn offers(&self) -> Offers {
        Offers {
            properties: true,
            operation_faults: true,
            stoppable_nodes: vec!["wf-a".into()],
            cuttable: false,
        }
    }

    fn properties(&self, op: OperationRef) -> Answer<serde_json::Value> {
        Box::pin(async move {
            if op.operation == "wall-follower" {
                Ok(json!([{"Identification": {"name": op.operation, "version": "1.0.0"}}]))
            } else {
                Err(ControlError::NotFound(format!("no {}", op.operation)))
            }
        })
    }

    fn fault(&self, fault: FaultRequest) -> Answer<String> {
        let done = match &fault.on {
            FaultOn::Node { node } if node != "wf-a" => {
                Err(ControlError::NotFound(format!("no node {node}")))
            }
            _ => Ok(format!("did {:?} {:?}", fault.fault, fault.on)),
        };
        self.faults.lock().unwrap().push(fault);
        Box::pin(std::future::ready(done))
    }

    fn replicas(&self, change: ReplicaRequest) -> Answer<String> {
        let done = match (change.dm.as_str(), change.change, change.node.as_str()) {
            ("feature", ReplicaChange::Add, "cart") => {
                Ok("feature: replica on cart added".to_string())
            }
            ("feature", ReplicaChange::Remove, "spare") => Err(ControlError::Refused(
                "removing spare would leave 2 voting replicas".into(),
            )),
            ("feature", _, node) => Err(ControlError::NotFound(format!("no node `{node}`"))),
            (dm, _, _) => Err(ControlError::NotFound(format!("no datamanager `{dm}`"))),
        };
        self.changes.lock().unwrap().push(change);
        Box::pin(std::future::ready(done))
    }
}

fn live(control: Arc<Recording>, allow_faults: bool) -> marie_monitor::MonitorHandle {
    let bus = EventBus::new("n1", Arc::new(ManualClock::new()));
    let options =
        MonitorOptions::new("127.0.0.1:0".parse().unwrap()).with_control(control, allow_faults);
    Monitor::live(&bus, options).unwrap()
}

fn kill_wall_follower() -> serde_json::Value {
    json!({"fault": "kill", "operation": "wall-follower", "node": "wf-a", "address": "2.3"})
}

#[test]
fn faults_are_refused_unless_allowed_and_properties_are_always_asked() {
    let control = Arc::new(Recording::default());
    let monitor = live(control.clone(), false);
    let addr = monitor.addr();
    let info = http::get_json(addr, "/api/info");
    assert_eq!(info["faults_allowed"], false);
    assert_eq!(
        info["offers"],
        json!({"properties": true, "operation_faults": false, "stoppable_nodes": [], "cuttable": false})
    );
    let (status, answer) = http::post_json(addr, "/api/fault", &kill_wall_follower());
    assert_eq!(status, 403, "{answer}");
    assert!(
        answer["error"].as_str().unwrap().contains("--allow-faults"),
        "{answer}"
    );
    assert!(control.faults.lock().unwrap().is_empty(), "nothing done");
    // properties need no permission
    let props = http::get_json(addr, "/api/props?operation=wall-follower&node=wf-a");
    assert_eq!(props[0]["Identification"]["version"], "1.0.0");
    let (status, body) = http::get(addr, "/api/props?operation=ghost", &[]);
    assert_eq!(status, 404, "{body}");
    assert!(body.contains("no ghost"), "{body}");
}

#[test]
fn an_allowed_fault_is_done_by_the_control_and_its_answer_returned() {
    let control = Arc::new(Recording::default());
    let monitor = live(control.clone(), true);
    let addr = monitor.addr();
    let info = http::get_json(addr, "/api/info");
    assert_eq!(info["faults_allowed"], true);
    assert_eq!(info["offers"]["stoppable_nodes"], json!(["wf-a"]));
    let (status, answer) = http::post_json(addr, "/api/fault", &kill_wall_follower());
    assert_eq!(status, 200, "{answer}");
    assert!(
        answer["done"].as_str().unwrap().starts_with("did Kill"),
        "{answer}"
    );
    let (status, answer) = http::post_json(
        addr,
        "/api/fault",
        &json!({"fault": "stop-node", "node": "wf-z"}),
    );
    assert_eq!(status, 404, "{answer}");
    assert_eq!(answer["error"], "no node wf-z");
    assert_eq!(
        *control.faults.lock().unwrap(),
        vec![
            FaultRequest {
                fault: FaultKind::Kill,
                on: FaultOn::Operation(OperationRef {
                    operation: "wall-follower".into(),
                    node: Some("wf-a".into()),
                    address: Some("2.3".into()),
                }),
            },
            FaultRequest {
                fault: FaultKind::StopNode,
                on: FaultOn::Node {
                    node: "wf-z".into()
                },
            },
        ]
    );
}

#[test]
fn a_fault_must_be_json_of_a_known_kind() {
    let control = Arc::new(Recording::default());
    let monitor = live(control.clone(), true);
    let addr = monitor.addr();
    // a form post (what a page elsewhere may send without asking) is refused
    let body = kill_wall_follower().to_string();
    let (status, _) = http::request(
        addr,
        "POST",
        "/api/fault",
        &[("Content-Type", "text/plain")],
        &body,
    );
    assert_eq!(status, 415);
    let (status, _) = http::post_json(addr, "/api/fault", &json!({"fault": "explode"}));
    assert_eq!(status, 422);
    // a kind aimed at what it does not aim at
    for wrong in [
        json!({"fault": "stop-node", "operation": "wall-follower"}),
        json!({"fault": "kill", "node": "wf-a"}),
    ] {
        let (status, answer) = http::post_json(addr, "/api/fault", &wrong);
        assert_eq!(status, 422, "{wrong}: {answer}");
    }
    // the page is told every kind, by what it aims at
    let info = http::get_json(addr, "/api/info");
    assert_eq!(
        info["fault_kinds"]["node"],
        json!(["stop-node", "freeze-node"])
    );
    assert_eq!(info["fault_kinds"]["cut"], json!(["partition"]));
    assert!(info["fault_kinds"]["operation"]
        .as_array()
        .unwrap()
        .contains(&json!("kill")));
    assert_eq!(http::get(addr, "/api/fault", &[]).0, 405);
    assert!(control.faults.lock().unwrap().is_empty());
}

#[test]
fn a_replay_offers_no_control() {
    let fixture = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/fixtures/docking-kill.jsonl"
    );
    let options = MonitorOptions::new("127.0.0.1:0".parse().unwrap())
        .with_control(Arc::new(Recording::default()), true)
        .allowing_changes(true);
    let monitor = Monitor::replay(Path::new(fixture), options).unwrap();
    let addr = monitor.addr();
    let info = http::get_json(addr, "/api/info");
    assert_eq!(info["faults_allowed"], false);
    assert_eq!(info["offers"]["properties"], false);
    assert_eq!(
        http::get(addr, "/api/props?operation=wall-follower", &[]).0,
        404
    );
    assert_eq!(
        http::post_json(addr, "/api/fault", &kill_wall_follower()).0,
        404
    );
    assert_eq!(info["changes_allowed"], false);
    assert_eq!(
        http::post_json(addr, "/api/replicas", &change("add", "feature", "cart")).0,
        404
    );
}

fn change(change: &str, dm: &str, node: &str) -> serde_json::Value {
    json!({"change": change, "dm": dm, "node": node})
}

#[test]
fn a_change_of_replicas_is_refused_unless_allowed_even_with_faults_allowed() {
    let control = Arc::new(Recording::default());
    // faults allowed, changes not: each has its own permission
    let monitor = live(control.clone(), true);
    let addr = monitor.addr();
    let info = http::get_json(addr, "/api/info");
    assert_eq!(info["changes_allowed"], false);
    let (status, answer) =
        http::post_json(addr, "/api/replicas", &change("add", "feature", "cart"));
    assert_eq!(status, 403, "{answer}");
    assert!(
        answer["error"]
            .as_str()
            .unwrap()
            .contains("--allow-changes"),
        "{answer}"
    );
    assert!(control.changes.lock().unwrap().is_empty(), "nothing done");
}

#[test]
fn an_allowed_change_of_replicas_is_done_by_the_control_and_its_refusals_said() {
    let control = Arc::new(Recording::default());
    let bus = EventBus::new("n1", Arc::new(ManualClock::new()));
    let options = MonitorOptions::new("127.0.0.1:0".parse().unwrap())
        .with_control(control.clone(), false)
        .allowing_changes(true);
    let monitor = Monitor::live(&bus, options).unwrap();
    let addr = monitor.addr();
    let info = http::get_json(addr, "/api/info");
    assert_eq!(info["changes_allowed"], true);
    assert_eq!(info["faults_allowed"], false, "changes allow no fault");
    assert_eq!(
        http::post_json(addr, "/api/fault", &kill_wall_follower()).0,
        403
    );
    let (status, answer) =
        http::post_json(addr, "/api/replicas", &change("add", "feature", "cart"));
    assert_eq!(status, 200, "{answer}");
    assert_eq!(answer["done"], "feature: replica on cart added");
    // the cluster's refusals, with the control's words
    let (status, answer) =
        http::post_json(addr, "/api/replicas", &change("remove", "feature", "spare"));
    assert_eq!(status, 409, "{answer}");
    assert_eq!(
        answer["error"],
        "removing spare would leave 2 voting replicas"
    );
    let (status, answer) =
        http::post_json(addr, "/api/replicas", &change("add", "feature", "nowhere"));
    assert_eq!(status, 404, "{answer}");
    assert_eq!(answer["error"], "no node `nowhere`");
    // a blank name is not asked of the cluster at all
    let (status, answer) = http::post_json(addr, "/api/replicas", &change("add", "feature", " "));
    assert_eq!(status, 422, "{answer}");
    assert_eq!(
        answer["error"],
        "name the node whose replica of feature to add"
    );
    let (status, answer) = http::post_json(addr, "/api/replicas", &change("remove", "", "cart"));
    assert_eq!(status, 422, "{answer}");
    // neither an unknown change nor a form post (what a page elsewhere may send)
    assert_eq!(
        http::post_json(addr, "/api/replicas", &change("move", "feature", "cart")).0,
        422
    );
    let body = change("add", "feature", "cart").to_string();
    let (status, _) = http::request(
        addr,
        "POST",
        "/api/replicas",
        &[("Content-Type", "application/x-www-form-urlencoded")],
        &body,
    );
    assert_eq!(status, 415);
    assert_eq!(http::get(addr, "/api/replicas", &[]).0, 405);
    assert_eq!(
        *control.changes.lock().unwrap(),
        vec![
            ReplicaRequest {
                change: ReplicaChange::Add,
                dm: "feature".into(),
                node: "cart".into()
            },
            ReplicaRequest {
                change: ReplicaChange::Remove,
                dm: "feature".into(),
                node: "spare".into()
            },
            ReplicaRequest {
                change: ReplicaChange::Add,
                dm: "feature".into(),
                node: "nowhere".into()
            },
        ]
    );
}
