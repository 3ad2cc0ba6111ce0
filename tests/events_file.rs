//! `marie run --events FILE.jsonl`: the node's event stream of a run, one JSON object per
//! line — a faulted docking run holds the loss, the restart and the rebind in that order, and
//! replays into the very report the run wrote.

mod common;

use common::{marie, text};
use marie::actors::dispatcher::RunReport;
use marie::actors::events::{Event, EventKind};

#[test]
fn the_events_of_a_faulted_docking_run_hold_loss_restart_rebind_in_order_and_replay_into_its_report(
) {
    let dir = tempfile::tempdir().unwrap();
    let (events, report) = (dir.path().join("run.jsonl"), dir.path().join("run.json"));
    let out = marie(&[
        "run",
        "missions/docking.toml",
        "--fault",
        "kill:wall-follower@20",
        "--events",
        events.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let lines = std::fs::read_to_string(&events).unwrap();
    let events: Vec<Event> = lines
        .lines()
        .map(|l| Event::from_json_line(l).unwrap_or_else(|e| panic!("{e}: {l}")))
        .collect();
    assert!(events.iter().all(|e| e.node == "embedded"));
    assert!(
        events.windows(2).all(|w| w[0].at_ms <= w[1].at_ms),
        "mission time never goes back"
    );
    let at = |what: &str, pred: &dyn Fn(&EventKind) -> bool| {
        events
            .iter()
            .position(|e| pred(&e.kind))
            .unwrap_or_else(|| panic!("no {what} in:\n{lines}"))
    };
    let injected = at(
        "injection",
        &|k| matches!(k, EventKind::FaultInjected { operation, .. } if operation == "wall-follower"),
    );
    let lost = at(
        "loss",
        &|k| matches!(k, EventKind::Lost { operation, .. } if operation == "wall-follower"),
    );
    let restarted = at("restart", &|k| {
        matches!(k, EventKind::ChildRestarted { supervisor, child, .. }
            if supervisor == "operations" && child.starts_with("wall-follower@"))
    });
    let rebound = at(
        "rebind",
        &|k| matches!(k, EventKind::Rebound(r) if r.operation == "wall-follower"),
    );
    let judged = at("judgement", &|k| matches!(k, EventKind::Judged { .. }));
    assert!(
        injected < lost && lost < restarted && restarted < rebound && rebound < judged,
        "order: injected {injected}, lost {lost}, restarted {restarted}, rebound {rebound}, judged {judged}"
    );

    let written: RunReport =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let replayed = RunReport::from_events(&events);
    assert_eq!(replayed, written, "the events replay into the report");
}

#[test]
fn an_events_path_that_cannot_be_written_is_refused_before_the_run() {
    let out = marie(&[
        "run",
        "missions/demo.toml",
        "--events",
        "no/such/dir/run.jsonl",
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(text(&out.stderr).contains("--events no/such/dir/run.jsonl"));
    assert!(out.stdout.is_empty(), "nothing ran");
}
