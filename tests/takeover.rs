//! A dispatcher that fails over: `marie up --run` on the thesis' layout dispatches the run on
//! the features node (`dispatcher = "active"`) with a standby on spare, as real processes on
//! 127.0.0.1. Whatever happens to the active dispatcher — its node killed (`SIGKILL`) or
//! frozen (`SIGSTOP`) past the failure detector's deadline, its actor killed, panicking or
//! hanging — the standby takes the run over from its last checkpoint, the old one is fenced
//! off should it wake, and the mission docks: one run, one report, with its takeover. And
//! again and again: the dispatcher that took over may be lost in turn, and the other desk
//! takes the run back.

use crate::common;

use common::{marie, report_of, text};
use marie::events::Event;
use marie::report::RunReport;

const THESIS: &str = "missions/clusters/thesis.toml";
/// Wall-clock time × 4 on every node (the failure detector's deadline is real time).
const SPEED: &str = "4";

/// Run the docking mission on the thesis' layout with `fault`; stdout, the report and the
/// events.
fn faulted_run(fault: &str) -> (String, serde_json::Value, Vec<Event>) {
    faulted_runs(&[fault])
}

/// The same with every fault of `faults`.
fn faulted_runs(faults: &[&str]) -> (String, serde_json::Value, Vec<Event>) {
    faulted_runs_of("missions/docking.toml", faults)
}

/// Run `mission` on the thesis' layout with every fault of `faults`; stdout, the report and
/// the events.
fn faulted_runs_of(mission: &str, faults: &[&str]) -> (String, serde_json::Value, Vec<Event>) {
    faulted_runs_on(THESIS, mission, faults)
}

/// The same on the cluster file `layout`.
fn faulted_runs_on(
    layout: &str,
    mission: &str,
    faults: &[&str],
) -> (String, serde_json::Value, Vec<Event>) {
    let dir = tempfile::tempdir().unwrap();
    let events_path = dir.path().join("events.jsonl");
    let mut args = vec![
        "up",
        layout,
        "--run",
        mission,
        "--speed",
        SPEED,
        "--events",
        events_path.to_str().unwrap(),
    ];
    for fault in faults {
        args.extend(["--fault", fault]);
    }
    let (out, report) = report_of(&args);
    let stdout = text(&out.stdout);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{faults:?}: {stdout}\n{}",
        text(&out.stderr)
    );
    let events = std::fs::read_to_string(&events_path)
        .unwrap()
        .lines()
        .map(|l| Event::from_json_line(l).unwrap())
        .collect();
    (stdout, report, events)
}

/// The run was taken over once, from features by spare, and docked; the report is the
/// events folded (one run across the takeover), its end told by spare's dispatcher only.
fn assert_taken_over(fault: &str, stdout: &str, report: &serde_json::Value, events: &[Event]) {
    assert!(
        stdout.contains("the run is dispatched on features, standby on spare"),
        "{stdout}"
    );
    assert!(
        stdout.contains("# the run taken over by spare from features at "),
        "{fault}: {stdout}"
    );
    assert_eq!(report["outcome"], "succeeded", "{fault}: {stdout}");
    assert_eq!(report["collisions"], 0);
    assert_eq!(
        takeovers_of(report),
        [("features".to_string(), "spare".to_string(), 2)],
        "{fault}"
    );
    assert!(stdout.contains(", 1 takeover, "), "{fault}: {stdout}");
    assert_one_run(fault, report, events, "spare");
}

/// The report's takeovers as (from, to, term).
fn takeovers_of(report: &serde_json::Value) -> Vec<(String, String, u64)> {
    report["takeovers"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| {
            (
                t["from"].as_str().unwrap().to_string(),
                t["to"].as_str().unwrap().to_string(),
                t["term"].as_u64().unwrap(),
            )
        })
        .collect()
}

/// One run across its takeovers: started once (on features), ended once (on `end`); the
/// report is the events folded, every action of the mission in it once, the running one
/// carried across each takeover.
fn assert_one_run(what: &str, report: &serde_json::Value, events: &[Event], end: &str) {
    let of = |t: &str| -> Vec<&Event> {
        events
            .iter()
            .filter(|e| serde_json::to_value(&e.kind).unwrap()["type"] == t)
            .collect()
    };
    let started = of("run_started");
    assert_eq!(started.len(), 1, "{what}");
    assert_eq!(started[0].node, "features");
    let ended = of("run_ended");
    assert_eq!(ended.len(), 1, "{what}: {ended:?}");
    assert_eq!(ended[0].node, end);
    let folded = RunReport::from_events(events);
    let written: RunReport = serde_json::from_value(report.clone()).unwrap();
    assert_eq!(folded.takeovers, written.takeovers, "{what}");
    assert_eq!(folded.actions, written.actions, "{what}");
    // every takeover's epochs were announced to the cart before the standby's first
    // command: the cart obeyed no replaced one (its log checked against the bindings)
    assert_eq!(folded.bound_epochs, written.bound_epochs, "{what}");
    assert!(!written.bound_epochs.is_empty(), "{what}");
    assert_eq!(report["obeyed_late"], serde_json::json!([]), "{what}");
    let actions: Vec<&str> = written.actions.iter().map(|a| a.name.as_str()).collect();
    assert_eq!(
        actions,
        ["find-wall", "follow-wall", "plan-parking", "park"],
        "{what}"
    );
}

#[test]
fn the_dispatchers_node_killed_mid_run_is_taken_over_by_the_standby_and_the_mission_docks() {
    let fault = "stop-node:features@6";
    let (stdout, report, events) = faulted_run(fault);
    assert_taken_over(fault, &stdout, &report, &events);
    assert!(stdout.contains("node features was killed"), "{stdout}");
    // killed during the wall following, which the lost dispatcher had launched: the
    // standby attached to its activations, it did not start the action anew (the wall
    // follower would have lost its progress: acceptance schedule 20 failed so)
    let starts: Vec<(String, String)> = events
        .iter()
        .filter_map(|e| {
            let kind = serde_json::to_value(&e.kind).unwrap();
            (kind["type"] == "action_started")
                .then(|| (kind["action"].as_str().unwrap().to_string(), e.node.clone()))
        })
        .collect();
    let follows: Vec<&(String, String)> =
        starts.iter().filter(|(a, _)| a == "follow-wall").collect();
    assert_eq!(follows.len(), 1, "{starts:?}");
    assert_eq!(follows[0].1, "features", "{starts:?}");
}

#[test]
fn a_dispatcher_frozen_past_the_deadline_is_taken_over_and_fenced_off_when_it_wakes() {
    // 8 s of mission time: 2 s of real time, past the detector's 1.2 s
    let fault = "freeze-node:features@6+8";
    let (stdout, report, events) = faulted_run(fault);
    assert_taken_over(fault, &stdout, &report, &events);
    // woken, the old dispatcher found its checkpoint refused for the newer term, and
    // stopped without ending the run (asserted above: the one run_ended is spare's)
    let fenced: Vec<&Event> = events
        .iter()
        .filter(|e| {
            let kind = serde_json::to_value(&e.kind).unwrap();
            kind["type"] == "dispatcher_fenced" && kind["term"] == 1 && kind["newer"] == 2
        })
        .collect();
    assert_eq!(fenced.len(), 1, "{stdout}");
    assert_eq!(fenced[0].node, "features");
    assert!(
        stdout.contains("# the dispatcher on features (term 1) fenced off by term 2"),
        "{stdout}"
    );
}

#[test]
fn a_dispatcher_killed_then_panicking_then_hanging_is_taken_over_each_time_and_the_mission_docks() {
    // one run, three takeovers in turn, back and forth between the two desks: features'
    // dispatcher killed (spare's standby takes over, term 2), spare's panicking (features'
    // active desk takes over after its stagger, term 2 + 2), features' hanging (found by
    // spare's desk within its 5 s deadline, term 4 + 1)
    let faults = [
        "kill:dispatcher@6",
        "panic:dispatcher@20",
        "hang:dispatcher@32",
    ];
    let (stdout, report, events) = faulted_runs(&faults);
    assert_eq!(report["outcome"], "succeeded", "{stdout}");
    assert_eq!(report["collisions"], 0);
    for (fault, node) in faults.iter().zip(["features", "spare", "features"]) {
        let kind = fault.split(':').next().unwrap();
        assert!(
            stdout.contains(&format!("* injected {kind} into dispatcher (")),
            "{fault}: {stdout}"
        );
        assert!(
            report["faults"]
                .as_array()
                .unwrap()
                .iter()
                .any(|f| f["fault"] == kind && f["node"] == node),
            "{fault} on {node}: {}",
            report["faults"]
        );
    }
    let takeovers = takeovers_of(&report);
    let expected = [
        ("features", "spare", 2),
        ("spare", "features", 4),
        ("features", "spare", 5),
    ]
    .map(|(f, t, n)| (f.to_string(), t.to_string(), n));
    assert_eq!(takeovers, expected, "{stdout}");
    assert!(stdout.contains(", 3 takeovers, "), "{stdout}");
    assert_one_run(&format!("{faults:?}"), &report, &events, "spare");
}

#[test]
fn a_desk_taken_over_from_takes_the_run_back_when_the_standby_is_lost_in_turn() {
    // features' dispatcher hangs: spare's desk takes the run over (term 2), while features'
    // desk still runs the hung one — superseded, but it writes no checkpoint to learn so;
    // then spare's node is killed: features' desk kills its hung dispatcher and takes the
    // run back (term 4)
    let faults = ["hang:dispatcher@6", "stop-node:spare@34"];
    let (stdout, report, events) = faulted_runs(&faults);
    assert_eq!(report["outcome"], "succeeded", "{stdout}");
    assert_eq!(report["collisions"], 0);
    let takeovers = takeovers_of(&report);
    let expected = [("features", "spare", 2), ("spare", "features", 4)]
        .map(|(f, t, n)| (f.to_string(), t.to_string(), n));
    assert_eq!(takeovers, expected, "{stdout}");
    assert_one_run(&format!("{faults:?}"), &report, &events, "features");
}

#[test]
fn a_run_left_without_a_dispatcher_is_resumed_by_its_restarted_node_and_docks() {
    // spare, the standby, is killed and stays down (`restart = "temporary"`); then features,
    // the node of the run's dispatcher, is killed and restarted by `up`: no standby is
    // left, and its new process's desk finds the run without a dispatcher and followed
    // still, and takes it over (term 1 + 2). Before, `up` waited for the run's end for
    // ever: the node came back, without the run's dispatcher
    let dir = tempfile::tempdir().unwrap();
    let layout = common::layouts::thesis_with_temporary(dir.path(), "spare");
    let faults = ["stop-node:spare@2", "stop-node:features@6"];
    let (stdout, report, events) =
        faulted_runs_on(layout.to_str().unwrap(), "missions/docking.toml", &faults);
    assert_eq!(report["outcome"], "succeeded", "{stdout}");
    assert!(
        stdout.contains("node spare was killed (SIGKILL): it stays down"),
        "{stdout}"
    );
    let takeovers = takeovers_of(&report);
    assert_eq!(
        takeovers,
        [("features".to_string(), "features".to_string(), 3)],
        "{stdout}"
    );
    assert_one_run(&format!("{faults:?}"), &report, &events, "features");
}

#[test]
fn a_dispatcher_fault_it_cannot_suffer_is_refused_before_the_run() {
    let out = marie(&[
        "up",
        THESIS,
        "--run",
        "missions/docking.toml",
        "--fault",
        "slow:dispatcher@1",
    ]);
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("dispatcher"), "{stderr}");
    assert!(!text(&out.stdout).contains("outcome:"));
}

#[test]
fn a_dispatcher_lost_after_a_fallback_is_taken_over_inside_the_retry_and_the_recovery_mission_docks(
) {
    // 110 s of mission time: the wall ahead led to the dead end, the fallback chose to back
    // along the wall (a retried action), and the cart backs towards the dock
    let fault = "stop-node:features@110";
    let (stdout, report, events) = faulted_runs_of("missions/docking-recover.toml", &[fault]);
    assert!(
        stdout.contains("# the run taken over by spare from features at "),
        "{stdout}"
    );
    assert_eq!(report["outcome"], "succeeded", "{stdout}");
    assert_eq!(report["collisions"], 0);
    assert_eq!(
        takeovers_of(&report),
        [("features".to_string(), "spare".to_string(), 2)]
    );
    assert_eq!(report["obeyed_late"], serde_json::json!([]));
    let folded = RunReport::from_events(&events);
    let written: RunReport = serde_json::from_value(report.clone()).unwrap();
    assert_eq!(folded.actions, written.actions);
    assert_eq!(folded.control, written.control);
    // the standby carried the tree on where it was: the fallback decided once (by
    // features), the retried action attached to, not started again, nor the wall ahead
    // followed again
    let told: Vec<(String, String)> = events
        .iter()
        .filter_map(|e| match &e.kind {
            marie::events::EventKind::Control {
                item: node,
                decision,
                ..
            } => Some((format!("{node}: {decision}"), e.node.clone())),
            _ => None,
        })
        .collect();
    assert_eq!(
        told,
        [(
            "find-dock: fallback to `back-along-wall`".to_string(),
            "features".to_string()
        )],
        "{stdout}"
    );
    let actions: Vec<&str> = written.actions.iter().map(|a| a.name.as_str()).collect();
    assert_eq!(
        actions,
        [
            "find-wall",
            "follow-wall",
            "back-along-wall",
            "plan-parking",
            "park"
        ],
        "{stdout}"
    );
}
