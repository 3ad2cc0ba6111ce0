//! Partitions with every process alive: the traffic between two nodes is dropped while both
//! run on, and the failure detector must tell it as it tells a freeze — each side declares
//! the other down within the deadline, drops its session, and they meet again when the
//! network heals. A partial partition — the dispatcher cut off from the node of the running
//! wall follower, the cart still reaching it — rebinds the wall follower to another node,
//! and the cut-off instance, which never hears that it was replaced and drives on, is
//! refused by the cart by epoch: the mission succeeds without a collision.
//!
//! # How the network is cut: network namespaces
//! Every process runs in a Linux network namespace of its own, the namespaces joined by
//! veth pairs to a hub namespace that routes between them ([`common::netns`]); a node
//! listens on its namespace's address (`10.77.<i+1>.2:7100`). A cut between two namespaces
//! is a blackhole route to the other's address in each of them: the packets of the open
//! sessions vanish silently, as behind a cut cable, while every other pair keeps talking;
//! healing deletes the routes. Chosen over a blackholing proxy because it cuts the real
//! connections wherever they were dialed — ractor_cluster's transitive mesh dials the
//! addresses nodes advertise, past any proxy — and changes no address a node advertises.
//! One difference from a cable: a new dial across the cut fails at once (the route lookup
//! refuses it) instead of timing out; either way the redials fail until it heals.
//!
//! Every address is inside namespaces the test creates and deletes. Needs root; without it
//! the tests are skipped with a line on stderr (they fail when `CI` is set).

use crate::common;

use common::cluster::{default_deadline_ms, node_config, silence_ms, NodeProc, Proc};
use common::layouts::thesis_node;
use common::netns::Netns;
use serde_json::Value;
use std::path::Path;
use std::time::{Duration, Instant};

/// The port every node listens on, each in a namespace of its own.
const PORT: u16 = 7100;

/// Wait until the last node of `nodes` (named `names`) and every earlier one see each
/// other. The tests start their nodes one at a time, each waited for, so that two nodes do
/// not dial each other at once. A joining node may still dial a peer twice (the peer lists
/// of several members reach it before its first dial is through): ractor_cluster then
/// closes one session as a duplicate, and both nodes tell the peer lost and seen again
/// within a few ms. So the tests look for trouble only from the cut on, seconds later.
fn wait_for_the_mesh(nodes: &mut [NodeProc], names: &[&str]) {
    let last = nodes.len() - 1;
    for i in 0..last {
        nodes[last].wait_line(&format!("node {} sees {} at", names[last], names[i]));
        nodes[i].wait_line(&format!("node {} sees {} at", names[i], names[last]));
    }
}

/// A mark in each node's lines: what it printed so far (see [`Proc::wait_line_since`]).
fn marks(nodes: &mut [NodeProc]) -> Vec<usize> {
    nodes.iter_mut().map(|n| n.drain().len()).collect()
}

/// The lines printed from `at` on that tell of a node declared down, lost or frozen.
fn troubles(node: &mut NodeProc, at: Instant) -> Vec<String> {
    node.lines_since(at)
        .into_iter()
        .filter(|l| l.contains("declared") || l.contains(" lost ") || l.contains("frozen"))
        .collect()
}

#[test]
fn a_partition_between_two_live_nodes_is_detected_like_a_freeze_and_heals() {
    // declared first: it drops last, after the processes it hosts are killed
    let Some(net) = Netns::create(3) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let names = ["alpha", "beta", "gamma"];
    let hosts = [
        "[[datamanager]]\nname = \"feature\"\n",
        "[[operation]]\nname = \"sampler\"\n",
        "[[datamanager]]\nname = \"parameter\"\n",
    ];
    let mut nodes: Vec<NodeProc> = Vec::new();
    for (i, name) in names.iter().enumerate() {
        // beta and gamma join alpha; the mesh does the rest
        let peers = if i == 0 {
            Vec::new()
        } else {
            vec![net.addr(0, PORT)]
        };
        let config = node_config(
            dir.path(),
            name,
            hosts[i],
            net.addr(i, PORT),
            &peers,
            "partition",
            "",
        );
        let args = [
            "node",
            "--config",
            config.to_str().unwrap(),
            "--stop-with-stdin",
        ];
        nodes.push(NodeProc::launch(
            Some(net.ns(i)),
            net.addr(i, PORT),
            name,
            &args,
        ));
        wait_for_the_mesh(&mut nodes, &names[..=i]);
    }
    let start = marks(&mut nodes);

    // cut alpha from beta: both run on, each still talking to gamma
    let cut = Instant::now();
    net.cut(0, 1);
    for (me, peer) in [(0, "beta"), (1, "alpha")] {
        let name = names[me];
        let (line, at) =
            nodes[me].wait_line_timed(start[me], &format!("node {name} declared {peer} down"));
        let silent = silence_ms(&line);
        eprintln!(
            "{name} declared {peer} down {} ms after the cut: {line}",
            (at - cut).as_millis()
        );
        // not before the deadline; and by the detector's rule (a tick more than a
        // deadline late is this node's own freeze) before twice the deadline
        let deadline = default_deadline_ms();
        assert!((deadline..2 * deadline).contains(&silent), "{line}");
        assert!(at - cut < Duration::from_secs(10), "{line}");
        // its session closed: the peer's modules left this node's registry
        nodes[me].wait_line_since(start[me], &format!("node {name} lost {peer}"));
    }
    assert!(
        nodes[0].alive() && nodes[1].alive(),
        "a partition kills nobody"
    );

    // healed, beta redials alpha (its configured peer) and they see each other again
    let marks = marks(&mut nodes);
    let heal = Instant::now();
    net.heal(0, 1);
    for (me, peer) in [(0, "beta"), (1, "alpha")] {
        let name = names[me];
        let (line, at) = nodes[me].wait_line_timed(marks[me], &format!("node {name} sees {peer}"));
        eprintln!(
            "{name} sees {peer} again {} ms after the heal: {line}",
            (at - heal).as_millis()
        );
        assert!(at - heal < Duration::from_secs(20), "{line}");
    }

    // gamma, which reached both all along, lost nobody; nobody took the partition for a
    // freeze of its own, nor declared anyone else down
    assert_eq!(troubles(&mut nodes[2], cut), Vec::<String>::new());
    for (me, peer) in [(0, "beta"), (1, "alpha")] {
        let expected = [
            format!("node {} declared {peer} down", names[me]),
            format!("node {} lost {peer} at", names[me]),
        ];
        for line in troubles(&mut nodes[me], cut) {
            assert!(
                expected.iter().any(|e| line.starts_with(e.as_str())),
                "{}: {line}",
                names[me]
            );
        }
    }
    for node in &mut nodes {
        node.signal("TERM");
        assert_eq!(node.wait_exit(), Some(0), "{}", node.name);
    }
}

const SPEED: &str = "4";
const COOKIE: &str = "partial";

/// The nodes of the partial-partition test, by namespace index: the thesis' layout with
/// the wall follower on two nodes of its own (as in `tests/cluster_failover.rs`); the
/// dispatcher runs in namespace [`DISPATCHER`].
const NODES: [&str; 5] = ["cart", "features", "operations", "wf-a", "wf-b"];
const CART: usize = 0;
const DISPATCHER: usize = 5;

/// Write the nodes' configs into `dir` (`NAME.toml`, without `[cluster]`: the flags give
/// it).
fn layout(dir: &Path) {
    thesis_node(dir, "cart", |text| text);
    thesis_node(dir, "features", |text| text);
    thesis_node(dir, "operations", |operations| {
        let without_wf = operations.replace("[[operation]]\nname = \"wall-follower\"\n", "");
        assert_ne!(
            without_wf, operations,
            "the operations node hosts a wall follower"
        );
        without_wf
    });
    for wf in ["wf-a", "wf-b"] {
        std::fs::write(
            dir.join(format!("{wf}.toml")),
            format!(
                "[node]\nname = \"{wf}\"\ndispatcher = false\n[[operation]]\nname = \"wall-follower\"\n"
            ),
        )
        .unwrap();
    }
}

#[test]
fn a_partial_partition_does_not_let_the_cut_off_wall_follower_drive_the_cart() {
    let Some(net) = Netns::create(NODES.len() + 1) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    layout(dir.path());
    let cart = net.addr(CART, PORT).to_string();
    let mut nodes: Vec<NodeProc> = Vec::new();
    for (i, name) in NODES.iter().enumerate() {
        let config = dir.path().join(format!("{name}.toml"));
        let listen = net.addr(i, PORT);
        let listen_arg = listen.to_string();
        // the thesis' datamanagers keep copies: a journal each
        let data_dir = dir.path().join(format!("data-{name}"));
        let mut args = vec![
            "node",
            "--config",
            config.to_str().unwrap(),
            "--data-dir",
            data_dir.to_str().unwrap(),
            "--listen",
            &listen_arg,
            "--cookie",
            COOKIE,
            "--speed",
            SPEED,
            "--world",
            "missions/worlds/lab.toml",
            "--seed",
            "1",
            "--stop-with-stdin",
        ];
        if i != CART {
            args.extend(["--peer", &cart]);
        }
        nodes.push(NodeProc::launch(Some(net.ns(i)), listen, name, &args));
        wait_for_the_mesh(&mut nodes, &NODES[..=i]);
    }
    let start = marks(&mut nodes);

    let report = dir.path().join("report.json");
    let events = dir.path().join("events.jsonl");
    let mut run = Proc::spawn_in(
        Some(net.ns(DISPATCHER)),
        "marie run",
        &[
            "run",
            "missions/docking.toml",
            "--join",
            &cart,
            "--cookie",
            COOKIE,
            "--speed",
            SPEED,
            "--report",
            report.to_str().unwrap(),
            "--events",
            events.to_str().unwrap(),
        ],
    );
    // `  bound wall-follower v1.0.0 on wf-a`
    let bound = run.wait_line("bound wall-follower");
    let old_name = bound.rsplit(' ').next().unwrap().to_string();
    let old = NODES
        .iter()
        .position(|n| *n == old_name)
        .unwrap_or_else(|| panic!("bound on an unknown node: {bound}"));
    let new_name = if old_name == "wf-a" { "wf-b" } else { "wf-a" };
    run.wait_line("> follow-wall: start");

    // the dispatcher loses the wall follower's node; the cart (and everyone else) keeps it
    let member = format!("run-{}", run.pid());
    let cut = Instant::now();
    net.cut(DISPATCHER, old);
    let (rebound, at) = run.wait_line_timed(0, "wall-follower rebound");
    eprintln!(
        "rebound {} ms after the cut: {rebound}",
        (at - cut).as_millis()
    );
    // `~ wall-follower rebound: 0.40 on wf-a -> 0.52 on wf-b after 1377 ms`
    assert!(
        rebound.contains(&format!(" on {old_name} -> "))
            && rebound.contains(&format!(" on {new_name} after ")),
        "{rebound}"
    );
    // the cut-off node declared the dispatcher down too, for its part
    let (line, at) = nodes[old].wait_line_timed(
        start[old],
        &format!("node {old_name} declared {member} down"),
    );
    eprintln!(
        "{old_name} declared the dispatcher down {} ms after the cut: {line}",
        (at - cut).as_millis()
    );
    run.wait_line("mission succeeded");
    assert_eq!(run.wait_exit(), Some(0), "{}", run.seen().join("\n"));

    let report: Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    assert_eq!(report["outcome"], "succeeded", "{report:#}");
    assert_eq!(report["collisions"], 0, "{report:#}");
    assert_eq!(report["inside_goal"], true, "{report:#}");
    let rebinds = report["rebinds"].as_array().unwrap();
    let rebind = rebinds
        .iter()
        .find(|r| r["operation"] == "wall-follower")
        .unwrap_or_else(|| panic!("no wall-follower rebind: {rebinds:?}"));
    assert_eq!(rebind["from_node"], old_name.as_str(), "{rebind}");
    assert_eq!(rebind["to_node"], new_name, "{rebind}");
    // The cut-off instance was never suspended (the dispatcher cannot reach it): it drove on
    // under its old epoch, reading the sonar through the features node and commanding the
    // cart, which it still reaches — and the cart, which had taken the stand-in's newer
    // epoch, refused every one of those commands. Refusals of the wall follower can only be
    // its: the stand-in holds the newest epoch.
    let refused = &report["refused_commands"];
    let by_wall_follower = refused["wall-follower"].as_u64().unwrap_or(0);
    eprintln!("the cart refused {refused}");
    assert!(by_wall_follower > 0, "{report:#}");
    // and not one was obeyed after the rebind: the dispatcher announced the stand-in's
    // epoch to the cart before its first command (without that, the cut-off instance is
    // obeyed until the stand-in's first command reaches the cart)
    assert_eq!(report["obeyed_late"], serde_json::json!([]), "{report:#}");

    // noticed by the failure detector of the dispatcher's member, then rebound
    let events: Vec<Value> = std::fs::read_to_string(&events)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let position = |kind: &str, key: &str, value: &str| {
        events
            .iter()
            .position(|e| e["kind"]["type"] == kind && e["kind"][key] == value)
            .unwrap_or_else(|| panic!("no {kind} with {key} {value}: {events:?}"))
    };
    let down = position("node_down", "peer", &old_name);
    let rebound = position("rebound", "operation", "wall-follower");
    assert!(down < rebound, "{:?}", &events[down..=rebound]);
    assert!(events[down]["kind"]["silent_ms"].as_u64().unwrap() >= default_deadline_ms());
    // and the rebind blames the node
    assert_eq!(
        events[rebound]["kind"]["cause"],
        serde_json::json!({"type": "node_down", "node": old_name}),
        "{}",
        events[rebound]
    );

    // a partial partition: the cut-off node lost only the dispatcher; the cart and the
    // others never lost it; every node still runs
    for (i, node) in nodes.iter_mut().enumerate() {
        assert!(node.alive(), "{} died", NODES[i]);
        for line in troubles(node, cut) {
            assert!(
                line.contains(&member),
                "{}: only the dispatcher may be lost: {line}\n{}",
                NODES[i],
                node.seen().join("\n")
            );
        }
    }
    for node in &mut nodes {
        node.signal("TERM");
        assert_eq!(node.wait_exit(), Some(0), "{}", node.name);
    }
}
