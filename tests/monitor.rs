//! `marie monitor` and `run --monitor` as real processes, over HTTP on 127.0.0.1: a past
//! run replayed (its extent, its final state), the token a monitor may require, and a run's
//! own live page while the mission runs.

use crate::common;

use common::cluster::{NodeProc, Proc};
use common::monitor::{
    monitored_run, monitored_up, page_of, recorded_run, replay_monitor, state_until,
};

/// The thesis' cluster.
const THESIS: &str = "missions/clusters/thesis.toml";
/// What the first node of a small cluster hosts (`alpha`), and one that joins later (`beta`).
const ALPHA: &str = "[[datamanager]]\nname = \"feature\"\n[[operation]]\nname = \"sampler\"\n";
const BETA: &str = "[[datamanager]]\nname = \"world\"\n[[operation]]\nname = \"averager\"\n";
use common::{http, marie, text};

#[test]
fn a_replayed_run_answers_its_extent_and_ends_with_every_action_succeeded_and_the_rebind() {
    let dir = tempfile::tempdir().unwrap();
    let events = recorded_run(dir.path());
    let (mut monitor, line) = replay_monitor(&events, &[]);
    let (addr, token) = page_of(&line);
    assert_eq!(token, None, "no token on loopback unless asked");
    let info = http::get_json(addr, "/api/replay/info");
    let lines = std::fs::read_to_string(&events).unwrap().lines().count();
    assert_eq!(info["events"], lines);
    let end = info["end_ms"].as_u64().unwrap();
    let last = http::get_json(addr, &format!("/api/replay/state?at_ms={end}"));
    let actions = last["mission"]["actions"].as_array().unwrap();
    assert_eq!(actions.len(), 4);
    for a in actions {
        assert_eq!(a["state"], "succeeded", "{a}");
    }
    assert_eq!(last["bindings"]["wall-follower"]["rebinds"], 1);
    assert_eq!(last["mission"]["outcome"]["outcome"], "succeeded");
    let (status, page) = http::get(addr, "/", &[]);
    assert_eq!(status, 200);
    assert!(page.contains("id=\"tree\""), "{page}");
    monitor.signal("INT");
    assert_eq!(monitor.wait_exit(), Some(0));
}

#[test]
fn a_monitor_that_requires_its_token_refuses_requests_without_it() {
    let dir = tempfile::tempdir().unwrap();
    let events = dir.path().join("run.jsonl");
    std::fs::write(
        &events,
        include_str!("../monitor/tests/fixtures/docking-kill.jsonl"),
    )
    .unwrap();
    let (_monitor, line) = replay_monitor(&events, &["--require-token"]);
    let (addr, token) = page_of(&line);
    let token = token.expect("the printed URL carries the token");
    for path in ["/", "/app.js", "/api/state", "/api/replay/info"] {
        assert_eq!(http::get(addr, path, &[]).0, 401, "{path}");
        assert_eq!(
            http::get(addr, &format!("{path}?token=x{token}"), &[]).0,
            401
        );
        assert_eq!(
            http::get(addr, &format!("{path}?token={token}"), &[]).0,
            200
        );
    }
    let bearer = format!("Bearer {token}");
    assert_eq!(
        http::get(addr, "/api/replay/info", &[("Authorization", &bearer)]).0,
        200
    );
}

#[test]
fn a_bad_events_file_is_bad_input() {
    let out = marie(&[
        "monitor",
        "--events",
        "missions/docking.toml",
        "--listen",
        "127.0.0.1:0",
    ]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
    assert!(text(&out.stderr).contains("docking.toml:1: not an event"));
    let out = marie(&["monitor", "--listen", "127.0.0.1:0"]);
    assert_eq!(out.status.code(), Some(2));
}

#[test]
fn a_run_serves_its_live_state_while_the_mission_runs_and_its_outcome_after() {
    let mut run = monitored_run();
    let (addr, _) = page_of(&run.wait_line("monitor: http://"));
    assert_eq!(http::get_json(addr, "/api/info")["mode"], "live");
    // while it runs: the tree, an action running, the node and its modules
    let during = state_until(addr, "an action running", |s| {
        s["mission"]["actions"]
            .as_array()
            .is_some_and(|a| a.iter().any(|a| a["state"] == "running"))
    });
    assert_eq!(during["mission"]["name"], "docking");
    assert_eq!(during["mission"]["actions"].as_array().unwrap().len(), 4);
    assert!(during["mission"]["outcome"].is_null(), "{during}");
    let modules = during["cluster"]["embedded"]["modules"]
        .as_object()
        .unwrap();
    assert!(modules.len() >= 10, "{modules:?}");
    // the live stream opens with a snapshot
    let mut stream = http::EventStream::open(addr, "/api/live");
    assert_eq!(stream.next().0, "snapshot");
    drop(stream);
    // after the run the page stays up with the outcome
    // the run flushes its monitor before the line: the state holds the outcome by then
    run.wait_line("the run is over");
    let after = http::get_json(addr, "/api/state");
    assert_eq!(
        after["mission"]["outcome"]["outcome"], "succeeded",
        "{after}"
    );
    assert_eq!(after["bindings"]["wall-follower"]["rebinds"], 1);
    // the stand-in's epoch is above every epoch bound at the start (it fences the lost one)
    let epoch = |op: &str| after["bindings"][op]["epoch"].as_u64().unwrap_or(0);
    assert!(epoch("ultrasonic") > 0, "{after}");
    assert!(epoch("wall-follower") > epoch("ultrasonic"), "{after}");
    run.signal("INT");
    assert_eq!(run.wait_exit(), Some(0));
}

fn hosts(state: &serde_json::Value, node: &str, module: &str) -> bool {
    state["cluster"][node]["modules"]
        .as_object()
        .is_some_and(|m| m.values().any(|m| m["name"] == module))
}

#[test]
fn a_monitor_joined_to_a_cluster_shows_its_nodes_asks_their_operations_and_kills_one() {
    const COOKIE: &str = "monitored";
    let dir = tempfile::tempdir().unwrap();
    let alpha = NodeProc::start(dir.path(), "alpha", ALPHA, &[], COOKIE);
    let alpha_addr = alpha.addr.to_string();
    let mut monitor = Proc::spawn(
        "monitor",
        &[
            "monitor",
            "--join",
            &alpha_addr,
            "--cookie",
            COOKIE,
            "--listen",
            "127.0.0.1:0",
            "--allow-faults",
        ],
    );
    let (addr, _) = page_of(&monitor.wait_line("monitor: http://"));
    let info = http::get_json(addr, "/api/info");
    assert_eq!(info["offers"]["operation_faults"], true, "{info}");
    assert_eq!(
        info["offers"]["stoppable_nodes"],
        serde_json::json!([]),
        "a joined monitor started no node"
    );
    // what was there before the monitor joined
    state_until(addr, "alpha hosting the sampler", |s| {
        hosts(s, "alpha", "sampler")
    });
    // a node that comes later, its modules told by itself through the relay
    let _beta = NodeProc::start(dir.path(), "beta", BETA, &[alpha.addr], COOKIE);
    state_until(addr, "beta hosting the averager", |s| {
        hosts(s, "beta", "averager") && s["cluster"]["beta"]["status"] == "up"
    });
    // the page asks beta's operation, a node away, for its properties
    let props = http::get_json(addr, "/api/props?operation=averager&node=beta");
    assert_eq!(props[1]["Location"]["node"], "beta", "{props}");
    // a kill from the page: the restart on alpha reaches the timeline
    let kill = serde_json::json!({"fault": "kill", "operation": "sampler", "node": "alpha"});
    let (status, answer) = http::post_json(addr, "/api/fault", &kill);
    assert_eq!(status, 200, "{answer}");
    state_until(addr, "the restart on alpha in the timeline", |s| {
        s["timeline"]["entries"].as_array().is_some_and(|e| {
            e.iter()
                .any(|e| e["class"] == "restart" && e["node"] == "alpha")
        })
    });
    monitor.signal("INT");
    assert_eq!(monitor.wait_exit(), Some(0));
}

#[test]
fn up_with_a_monitor_shows_every_node_and_what_it_hosts_and_stops_one_from_the_page() {
    let (mut up, line) = monitored_up(THESIS, &["--allow-faults"]);
    let (addr, _) = page_of(&line);
    let info = http::get_json(addr, "/api/info");
    assert_eq!(
        info["offers"]["stoppable_nodes"],
        serde_json::json!(["cart", "features", "operations", "spare"]),
        "{info}"
    );
    let state = state_until(addr, "the thesis' four nodes with their modules", |s| {
        hosts(s, "cart", "virtual-cart")
            && hosts(s, "features", "feature")
            && hosts(s, "operations", "path-planner")
            && hosts(s, "spare", "wall-follower")
    });
    for node in ["cart", "features", "operations", "spare"] {
        assert_eq!(state["cluster"][node]["status"], "up", "{node}: {state}");
    }
    // each datamanager as last asked: the thesis keeps three replicas, the leader on the
    // features node says how far the two others lag
    let state = state_until(
        addr,
        "the feature datamanager's state, with its replicas",
        |s| {
            s["cluster"]["features"]["modules"]
                .as_object()
                .into_iter()
                .flat_map(|m| m.values())
                .any(|m| {
                    m["name"] == "feature"
                        && m["dm"]["role"] == "leader"
                        && m["dm"]["durability"] == "process"
                        && m["dm"]["lag"].as_object().is_some_and(|l| {
                            l.keys().cloned().collect::<Vec<_>>() == ["operations", "spare"]
                        })
                })
        },
    );
    let _ = state;
    // a datamanager from the page (its buttons: the kinds that hit one): its supervisor
    // restarts it, and — `up` gives the node a data dir — it reads its journal back
    assert_eq!(
        info["fault_kinds"]["datamanager"],
        serde_json::json!(["kill", "panic", "hang"]),
        "{info}"
    );
    let kill = serde_json::json!({"fault": "kill", "operation": "feature", "node": "features"});
    let (status, answer) = http::post_json(addr, "/api/fault", &kill);
    assert_eq!(status, 200, "{answer}");
    state_until(
        addr,
        "the feature DM's restart and recovery in the timeline",
        |s| {
            s["timeline"]["entries"].as_array().is_some_and(|e| {
                let at = |class: &str| {
                    e.iter()
                        .position(|e| e["class"] == class && e["node"] == "features")
                };
                let restart = at("restart");
                // the recovery told after the restart (the timeline is in order)
                restart.is_some_and(|r| {
                    e[r..]
                        .iter()
                        .any(|e| e["class"] == "datamanager" && e["node"] == "features")
                })
            })
        },
    );
    // no run: the node that runs the cart draws it anyway — its world (told again for a
    // monitor that joined after its start) and its poses
    state_until(addr, "the cart in its world", |s| {
        s["robot"]["world"]["walls"]
            .as_array()
            .is_some_and(|w| !w.is_empty())
            && s["robot"]["poses"].as_u64().is_some_and(|n| n > 0)
    });
    // stop the spare's process from the page: the cluster loses it
    let stop = serde_json::json!({"fault": "stop-node", "node": "spare"});
    let (status, answer) = http::post_json(addr, "/api/fault", &stop);
    assert_eq!(status, 200, "{answer}");
    state_until(addr, "the spare lost", |s| {
        ["lost", "down"].contains(&s["cluster"]["spare"]["status"].as_str().unwrap_or(""))
    });
    let (status, answer) = http::post_json(addr, "/api/fault", &stop);
    assert_eq!(status, 404, "stopped once: {answer}");
    up.wait_line("[spare] exited");
    up.signal("INT");
    up.wait_line("node spare was killed");
    up.wait_line("cluster stopped");
    assert_eq!(up.wait_exit(), Some(0));
}

#[test]
fn up_running_a_mission_with_a_monitor_draws_the_cart_of_another_node_and_lists_every_node() {
    let (mut up, line) = monitored_up(THESIS, &["--run", "missions/docking.toml", "--speed", "4"]);
    let (addr, _) = page_of(&line);
    up.wait_line("the run is over");
    // the run's own events are in (flushed before the line)
    let after = http::get_json(addr, "/api/state");
    assert_eq!(
        after["mission"]["outcome"]["outcome"], "succeeded",
        "{after}"
    );
    // the dispatcher's process told the world and tapped the datamanagers on the other
    // nodes (the planned path is stored on `operations`)
    assert!(
        after["robot"]["world"]["walls"]
            .as_array()
            .is_some_and(|w| !w.is_empty()),
        "{after}"
    );
    assert!(
        after["robot"]["planned_path"]
            .as_array()
            .is_some_and(|p| !p.is_empty()),
        "{after}"
    );
    // the poses come from the node that runs the cart (no dispatcher there), through the
    // cluster's relay
    let driven = state_until(addr, "the cart's driven path", |s| {
        s["robot"]["path"].as_array().is_some_and(|p| p.len() > 10)
    });
    assert!(driven["robot"]["pose"].is_object(), "{driven}");
    // every node with its modules
    for (node, module) in [
        ("cart", "virtual-cart"),
        ("features", "feature"),
        ("operations", "path-planner"),
        ("spare", "wall-follower"),
    ] {
        assert!(
            hosts(&driven, node, module),
            "{node} hosting {module}: {driven}"
        );
    }
    up.signal("INT");
    up.wait_line("cluster stopped");
    assert_eq!(up.wait_exit(), Some(0));
}

#[test]
fn a_run_joined_to_a_cluster_with_a_monitor_lists_the_modules_of_a_node_that_joins_later() {
    const COOKIE: &str = "joined-run";
    let dir = tempfile::tempdir().unwrap();
    let alpha = NodeProc::start(dir.path(), "alpha", ALPHA, &[], COOKIE);
    // a run that lasts: 100 000 samples, one every 2 ms (it is killed once seen)
    let mission = dir.path().join("long.toml");
    std::fs::write(
        &mission,
        "[mission]\nname = \"long\"\nsuccess = [\"sampled\"]\n[flags]\nsampled = 0\n\
         [[action]]\nname = \"sample\"\ndeadline_s = 600.0\n\
         [action.ops.sampler]\ncount = 100000\n",
    )
    .unwrap();
    let alpha_addr = alpha.addr.to_string();
    let mut run = Proc::spawn(
        "run",
        &[
            "run",
            mission.to_str().unwrap(),
            "--join",
            &alpha_addr,
            "--cookie",
            COOKIE,
            "--monitor",
            "127.0.0.1:0",
        ],
    );
    let (addr, _) = page_of(&run.wait_line("monitor: http://"));
    state_until(addr, "the action running on alpha's sampler", |s| {
        hosts(s, "alpha", "sampler") && s["mission"]["actions"][0]["state"] == "running"
    });
    // a node that joins while the run goes on: its modules reach the run's registry
    let _beta = NodeProc::start(dir.path(), "beta", BETA, &[alpha.addr], COOKIE);
    state_until(addr, "beta hosting the averager and the world DM", |s| {
        hosts(s, "beta", "averager") && hosts(s, "beta", "world")
    });
    assert!(run.alive(), "the run was still going on");
}

#[test]
fn the_page_says_no_majority_while_a_datamanager_lacks_one_and_a_node_back_once_it_returns() {
    // the spare node stays down once stopped (restart = "temporary"); then the operations
    // node is frozen from the page: of each datamanager's three replicas only the features
    // node's answers — no majority, said with the nodes it misses — until operations wakes:
    // a leader again, and operations back
    let dir = tempfile::tempdir().unwrap();
    let cluster = common::layouts::thesis_with(dir.path(), "");
    let layout = std::fs::read_to_string(&cluster).unwrap();
    let spare = layout
        .lines()
        .find(|l| l.ends_with("thesis/spare.toml\""))
        .unwrap()
        .to_string();
    std::fs::write(
        &cluster,
        layout.replace(&spare, &format!("{spare}\nrestart = \"temporary\"")),
    )
    .unwrap();
    let (mut up, line) = monitored_up(cluster.to_str().unwrap(), &["--allow-faults"]);
    let (addr, _) = page_of(&line);
    state_until(addr, "the feature datamanager's leader", |s| {
        s["cluster"]["features"]["modules"]
            .as_object()
            .into_iter()
            .flat_map(|m| m.values())
            .any(|m| m["name"] == "feature" && m["dm"]["role"] == "leader")
    });
    let stop = serde_json::json!({"fault": "stop-node", "node": "spare"});
    let (status, answer) = http::post_json(addr, "/api/fault", &stop);
    assert_eq!(status, 200, "{answer}");
    up.wait_line("node spare was killed (SIGKILL): it stays down");
    let freeze = serde_json::json!({"fault": "freeze-node", "node": "operations"});
    let (status, answer) = http::post_json(addr, "/api/fault", &freeze);
    assert_eq!(status, 200, "{answer}");
    let state = state_until(addr, "the feature datamanager without a majority", |s| {
        s["no_majority"]["feature"]["missing"] == serde_json::json!(["operations", "spare"])
    });
    let words = state["no_majority"]["feature"]["words"].as_str().unwrap();
    assert!(
        words.contains("has no majority: 1 of its 3 replicas answers (features), a leader needs 2"),
        "{words}"
    );
    // the freeze ends: operations is back, and the datamanager has a leader again
    let state = state_until(
        addr,
        "operations back and the feature datamanager led",
        |s| {
            s["cluster"]["operations"]["back"]["down_ms"].is_u64()
                && s["no_majority"].get("feature").is_none()
        },
    );
    assert_eq!(state["cluster"]["operations"]["status"], "up", "{state}");
    up.signal("INT");
    up.wait_line("cluster stopped");
    assert_eq!(up.wait_exit(), Some(0));
}
