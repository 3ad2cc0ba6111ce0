//! Missions that recover (issue 24), end to end through the `marie` binary in the simulated
//! world: `missions/docking-recover.toml` finds the dock in the dead-end world where the
//! thesis' docking mission fails cleanly, a mission without control keys runs as it always
//! did, and self-healing still holds inside the new constructs — an operation killed in a
//! fallback's child under a timeout, in a retried action, or in a parallel's child under a
//! reactive condition is rebound and the mission docks.

use crate::common;

use common::{report_of, text};

const RECOVER: &str = "missions/docking-recover.toml";
const PARALLEL: &str = "tests/missions/docking-parallel.toml";

/// The report's control decisions as `item: decision`.
fn decisions(report: &serde_json::Value) -> Vec<String> {
    report["control"]
        .as_array()
        .unwrap_or_else(|| panic!("no control in {report}"))
        .iter()
        .map(|c| {
            format!(
                "{}: {}",
                c["item"].as_str().unwrap(),
                c["decision"].as_str().unwrap()
            )
        })
        .collect()
}

/// The report's actions by name, in the order they started.
fn actions(report: &serde_json::Value) -> Vec<String> {
    report["actions"]
        .as_array()
        .unwrap()
        .iter()
        .map(|a| a["name"].as_str().unwrap().to_string())
        .collect()
}

#[test]
fn the_recovery_mission_docks_in_the_dead_end_world_on_ten_seeds_without_a_collision() {
    for seed in 1..=10 {
        let seed = seed.to_string();
        let (out, report) = report_of(&["run", RECOVER, "--speed", "max", "--seed", &seed]);
        let stdout = text(&out.stdout);
        assert_eq!(out.status.code(), Some(0), "seed {seed}: {stdout}");
        assert_eq!(report["outcome"], "succeeded", "seed {seed}: {stdout}");
        assert_eq!(report["inside_goal"], true, "seed {seed}");
        assert_eq!(report["collisions"], 0, "seed {seed}");
        // the wall ahead led to the dead end: given up, and the dock found the other way
        let told = decisions(&report);
        assert!(
            told.contains(&"find-dock: fallback to `back-along-wall`".to_string()),
            "seed {seed}: {told:?}"
        );
        assert!(
            stdout.contains("< follow-wall: failed")
                && stdout.contains("? find-dock: fallback to `back-along-wall` at "),
            "seed {seed}: the run says the decision: {stdout}"
        );
        let ran = actions(&report);
        assert_eq!(
            ran[..3],
            ["find-wall", "follow-wall", "back-along-wall"],
            "seed {seed}"
        );
        assert_eq!(
            ran[ran.len() - 2..],
            ["plan-parking", "park"],
            "seed {seed}"
        );
    }
}

#[test]
fn the_thesis_docking_mission_fails_cleanly_in_the_dead_end_world() {
    let (out, report) = report_of(&[
        "run",
        "missions/docking.toml",
        "--world",
        "missions/worlds/deadend.toml",
        "--speed",
        "max",
        "--seed",
        "1",
    ]);
    let stdout = text(&out.stdout);
    assert_eq!(out.status.code(), Some(1), "{stdout}");
    assert_eq!(report["outcome"], "failed");
    let reason = report["reason"].as_str().unwrap();
    assert!(
        reason.contains("operation `wall-follower` failed in action `follow-wall`")
            && reason.contains("no progress along the wall"),
        "{reason}"
    );
    assert_eq!(report["collisions"], 0);
    assert_eq!(
        report["control"],
        serde_json::json!([]),
        "a thesis mission decides nothing"
    );
}

#[test]
fn a_mission_without_control_keys_runs_the_thesis_schedule_and_tells_no_control_decision() {
    let (out, report) = report_of(&["run", "missions/docking.toml", "--speed", "max"]);
    let stdout = text(&out.stdout);
    assert_eq!(out.status.code(), Some(0), "{stdout}");
    assert_eq!(report["outcome"], "succeeded");
    assert_eq!(
        actions(&report),
        ["find-wall", "follow-wall", "plan-parking", "park"]
    );
    assert_eq!(report["control"], serde_json::json!([]));
    assert!(!stdout.contains("\n? "), "no control line: {stdout}");
    assert!(
        !stdout.contains(": failed,") && !stdout.contains(": halted,"),
        "{stdout}"
    );
}

/// Run `mission` with `fault`; it docks, the fault hit `op` and `op` was rebound; the
/// report's control decisions.
fn heals_inside(mission: &str, fault: &str, op: &str) -> Vec<String> {
    let (out, report) = report_of(&["run", mission, "--speed", "max", "--fault", fault]);
    let stdout = text(&out.stdout);
    assert_eq!(out.status.code(), Some(0), "{fault}: {stdout}");
    assert_eq!(report["outcome"], "succeeded", "{fault}: {stdout}");
    assert_eq!(report["inside_goal"], true, "{fault}");
    let faults = report["faults"].as_array().unwrap();
    assert_eq!(faults.len(), 1, "{report}");
    assert_eq!(faults[0]["operation"], op);
    assert!(faults[0]["error"].is_null(), "{}", faults[0]);
    let rebound = report["rebinds"]
        .as_array()
        .unwrap()
        .iter()
        .any(|r| r["operation"] == op && r["from"] == faults[0]["actor"]);
    assert!(rebound, "{fault}: {op} not rebound: {report}");
    assert!(stdout.contains(&format!("~ {op} rebound")), "{stdout}");
    decisions(&report)
}

#[test]
fn an_operation_killed_in_a_fallbacks_first_child_under_a_timeout_is_rebound_and_the_fallback_goes_on(
) {
    // 40 s: the wall follower follows the wall ahead (follow-wall: a fallback's first
    // child, under a 100 s timeout), towards the dead end
    let told = heals_inside(RECOVER, "kill:wall-follower@40", "wall-follower");
    assert!(
        told.contains(&"find-dock: fallback to `back-along-wall`".to_string()),
        "{told:?}"
    );
}

#[test]
fn an_operation_killed_in_a_retried_action_is_rebound_and_the_attempt_goes_on() {
    // 130 s: backing along the wall (back-along-wall, retried), some 40 s after the
    // fallback to it
    let told = heals_inside(
        RECOVER,
        "kill:sensor-based-controller@130",
        "sensor-based-controller",
    );
    assert!(
        !told.iter().any(|d| d.contains("retry 2 of 2")),
        "the attempt carried on, not retried: {told:?}"
    );
}

#[test]
fn an_operation_killed_in_a_parallels_child_under_a_reactive_condition_is_rebound() {
    // 20 s: following the wall beside the detector (a parallel's children; the follower
    // unless the dock is found)
    let told = heals_inside(PARALLEL, "kill:wall-follower@20", "wall-follower");
    assert!(
        told.contains(&"follow-and-look: parallel succeeded".to_string()),
        "{told:?}"
    );
}
