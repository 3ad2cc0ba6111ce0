//! A node cut off from the cluster tells what happened to it once it is back: the
//! `operations` node is frozen (`SIGSTOP`) past the failure detector's deadline while a
//! `marie run --join --events FILE --monitor` runs, then woken (`SIGCONT`). What it
//! publishes as it wakes — that it was frozen, the sessions it lost, the restart of its
//! operations as a new incarnation — has no session to a watcher to go through; its
//! forwarder keeps it and sends it once the run's watchers are in reach again. So the
//! events file holds it, once each, in order, and the run's page shows the node frozen.

use crate::common;

use common::cluster::{default_deadline_ms, NodeProc, Proc};
use common::monitor::{page_of, state_until};
use marie::events::{Event, EventKind};

const COOKIE: &str = "frozen";
/// The mission's node: the sampler and the datamanager it stores into.
const ALPHA: &str = "[[datamanager]]\nname = \"feature\"\n[[operation]]\nname = \"sampler\"\n";
/// The node that is frozen: an operation the mission does not use, restarted as a new
/// incarnation when the node wakes.
const OPERATIONS: &str = "[[operation]]\nname = \"checker\"\n";
/// One action: 7500 samples, a step every 2 ms of the cluster's clock (wall-clock time
/// here) — at least 15 s, however fast the machine, for the freeze and the wake.
const MISSION: &str = r#"
[mission]
name = "sample"
description = "sample a noisy sine while a node of the cluster is frozen and woken"
success = ["sampled"]
deadline_s = 600.0

[flags]
sampled = 0

[[action]]
name = "sample"
ends_on = ["sampler"]
deadline_s = 600.0

[action.ops.sampler]
count = 7500
"#;

#[test]
fn a_woken_nodes_freeze_and_restart_reach_the_events_file_and_the_page_once_each_in_order() {
    let dir = tempfile::tempdir().unwrap();
    let mission = dir.path().join("sample.toml");
    std::fs::write(&mission, MISSION).unwrap();
    let events = dir.path().join("run.jsonl");
    // alpha declares a silent peer down only after 2.4 s (beating every 100 ms, so that its
    // peers' 1.2 s deadline never finds it silent): once it has, operations has been
    // frozen twice its own deadline, and finds so when it wakes
    let mut alpha = NodeProc::start_with(
        dir.path(),
        "alpha",
        ALPHA,
        &[],
        COOKIE,
        "deadline_ms = 2400\nheartbeat_ms = 100\n",
        &[],
    );
    let mut operations =
        NodeProc::start(dir.path(), "operations", OPERATIONS, &[alpha.addr], COOKIE);
    operations.wait_line("node operations sees alpha");
    let mut run = Proc::spawn(
        "run",
        &[
            "run",
            mission.to_str().unwrap(),
            "--join",
            &alpha.addr.to_string(),
            "--cookie",
            COOKIE,
            "--events",
            events.to_str().unwrap(),
            "--monitor",
            "127.0.0.1:0",
        ],
    );
    let member = format!("run-{}", run.pid());
    let (page, _) = page_of(&run.wait_line("monitor: http://"));
    run.wait_line("> sample: start");

    operations.signal("STOP");
    // the run's own member declares it down (and closes their session): only then is
    // what the node publishes as it wakes cut off from the run's watchers. The page has
    // every peer's news of the node's loss before it wakes
    let said = |state: &serde_json::Value, node: &str, text: &str| {
        state["timeline"]["entries"]
            .as_array()
            .is_some_and(|entries| {
                entries.iter().any(|e| {
                    e["node"] == node && e["text"].as_str().is_some_and(|t| t.contains(text))
                })
            })
    };
    state_until(
        page,
        "the run's member and alpha declaring operations down",
        |s| {
            [member.as_str(), "alpha"].iter().all(|node| {
                said(s, node, "declared operations down") && said(s, node, "lost operations")
            })
        },
    );
    let mark = operations.seen().len();
    operations.signal("CONT");
    operations.wait_line_since(mark, "node operations was frozen for");
    operations.wait_line_since(
        mark,
        "node operations restarted its 1 operation instance(s) as a new incarnation",
    );
    // the page: the node's own news, forwarded once it was back in reach, and the node up
    // again, saying it woke from its freeze (it used to show `frozen` for good)
    let woken = state_until(page, "operations' wake on the page", |s| {
        let node = &s["cluster"]["operations"];
        said(s, "operations", "was frozen")
            && node["status"] == "up"
            && node["woke"]["silent_ms"].as_u64() >= Some(default_deadline_ms())
    });

    run.wait_line("monitor: the run is over");
    // and still up, long after it woke (the run went on)
    let later = common::http::get_json(page, "/api/state");
    assert_eq!(later["cluster"]["operations"]["status"], "up", "{later}");
    assert_eq!(
        later["cluster"]["operations"]["woke"],
        woken["cluster"]["operations"]["woke"]
    );
    run.signal("INT");
    assert_eq!(
        run.wait_exit(),
        Some(0),
        "{}\n{}",
        run.seen().join("\n"),
        run.stderr_tail()
    );
    for node in [&mut operations, &mut alpha] {
        node.signal("TERM");
        assert_eq!(node.wait_exit(), Some(0));
    }

    let lines = std::fs::read_to_string(&events).unwrap();
    let theirs: Vec<(&str, Event)> = lines
        .lines()
        .map(|l| {
            (
                l,
                Event::from_json_line(l).unwrap_or_else(|e| panic!("{e}: {l}")),
            )
        })
        .filter(|(_, e)| e.node == "operations")
        .collect();
    let all = |pred: &dyn Fn(&EventKind) -> bool| -> Vec<usize> {
        (0..theirs.len())
            .filter(|&i| pred(&theirs[i].1.kind))
            .collect()
    };
    // what it published as it woke, each once: that it was frozen (past its deadline) and
    // then restarted the checker; that it lost the run's member (its session, closed by the
    // member, may end before or after it finds it was frozen), then saw it again
    let once = |what: &str, found: Vec<usize>| {
        assert_eq!(found.len(), 1, "{what}: {found:?} in\n{lines}");
        found[0]
    };
    let frozen = once(
        "one freeze",
        all(&|k| matches!(k, EventKind::NodeFrozen { .. })),
    );
    let EventKind::NodeFrozen { silent_ms } = theirs[frozen].1.kind else {
        unreachable!()
    };
    assert!(silent_ms >= default_deadline_ms(), "{}", theirs[frozen].0);
    let restarted = once(
        "one restart of the checker",
        all(&|k| {
            matches!(k, EventKind::ChildRestarted { supervisor, child, .. }
                if supervisor == "operations" && child.starts_with("checker@"))
        }),
    );
    assert!(frozen < restarted, "{lines}");
    let lost = once(
        "the run's member lost once",
        all(&|k| matches!(k, EventKind::NodeLost { peer, .. } if *peer == member)),
    );
    let back = all(&|k| matches!(k, EventKind::NodeUp { peer, .. } if *peer == member));
    once(
        "the run's member seen again",
        back.into_iter().filter(|&i| i > lost).collect(),
    );
    // in the order the node published them, each once
    for pair in theirs.windows(2) {
        assert!(
            pair[0].1.at_ms <= pair[1].1.at_ms,
            "{} before {}",
            pair[0].0,
            pair[1].0
        );
    }
    let mut distinct: Vec<&str> = theirs.iter().map(|(l, _)| *l).collect();
    distinct.sort();
    distinct.dedup();
    assert_eq!(distinct.len(), theirs.len(), "an event twice in\n{lines}");
}
