//! `marie run --events FILE.jsonl`: the node's event stream of a run, one JSON object per
//! line — a faulted docking run holds the loss, the restart and the rebind in that order, and
//! replays into the very report the run wrote.

use crate::common;

use common::{marie, text};
use marie::events::{Event, EventKind};
use marie::report::RunReport;

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

/// The robot's live events (`marie_missions::telemetry`): what the after-run picture shows,
/// put into the stream as it happens, so a monitor or a replay of the file can draw the run.
#[test]
fn a_docking_runs_events_draw_the_robot_world_first_then_poses_path_and_dock() {
    let dir = tempfile::tempdir().unwrap();
    let events = dir.path().join("run.jsonl");
    let out = marie(&[
        "run",
        "missions/docking.toml",
        "--events",
        events.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let lines = std::fs::read_to_string(&events).unwrap();
    let robot: Vec<(u64, String, serde_json::Value)> = lines
        .lines()
        .map(|l| Event::from_json_line(l).unwrap_or_else(|e| panic!("{e}: {l}")))
        .filter_map(|e| match e.kind {
            EventKind::Robot { what, data } => Some((e.at_ms, what, data)),
            _ => None,
        })
        .collect();
    let of = |what: &'static str| robot.iter().filter(move |(_, w, _)| w == what);
    let (_, first, world) = robot.first().expect("robot events");
    assert_eq!(first, "world", "the world comes first");
    assert_eq!(of("world").count(), 1, "one world per run");
    assert_eq!(
        world["walls"][0],
        serde_json::json!([[0.0, 0.0], [4.0, 0.0]])
    );
    assert_eq!(world["goal"].as_array().map(Vec::len), Some(4));
    assert_eq!(world["dock"].as_array().map(Vec::len), Some(4));
    assert_eq!(world["cart"]["length"], serde_json::json!(1.0));

    let poses: Vec<_> = of("pose").collect();
    // about a minute of mission time, a pose every 100 ms
    assert!(poses.len() > 200, "{} poses", poses.len());
    assert!(
        poses.windows(2).all(|w| w[0].0 < w[1].0),
        "one pose per sample time, in order"
    );
    let gaps: Vec<u64> = poses.windows(2).map(|w| w[1].0 - w[0].0).collect();
    assert!(gaps.iter().all(|g| (80..=200).contains(g)), "{gaps:?}");
    let (_, _, start) = poses[0];
    assert!(
        start["x"].as_f64().is_some_and(|x| (x - 12.5).abs() < 0.5),
        "{start}"
    );
    assert!(start["heading"].is_f64() && start["y"].is_f64());

    let echoes: Vec<_> = of("echoes").collect();
    assert!(echoes.len() > 20, "{} echo events", echoes.len());
    assert!(echoes
        .iter()
        .any(|(_, _, d)| d["points"].as_array().is_some_and(|p| !p.is_empty())));
    let (_, _, wall) = of("followed-wall").next().expect("a followed wall");
    assert!(wall["from"][1].is_f64() && wall["to"][0].is_f64(), "{wall}");
    let (dock_at, _, dock) = of("dock-found").next().expect("a dock found");
    assert_eq!(dock["corners"].as_array().map(Vec::len), Some(4), "{dock}");
    let (path_at, _, path) = of("planned-path").next().expect("a planned path");
    assert!(
        path["points"].as_array().is_some_and(|p| p.len() >= 2),
        "{path}"
    );
    assert!(dock_at <= path_at, "the path is planned to the dock found");
}
