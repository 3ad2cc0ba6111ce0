//! `marie diff A.json B.json`: what differs between two runs, from their reports — exit 0
//! when nothing does, 1 when something does, 2 when a file is not a report.

use crate::common;

use common::{marie, text};
use std::path::{Path, PathBuf};
use std::process::Output;

/// Run `marie run MISSION ARGS… --report DIR/NAME` and give the report's path.
fn report(dir: &Path, name: &str, mission: &str, args: &[&str]) -> PathBuf {
    let path = dir.join(name);
    let mut all = vec!["run", mission];
    all.extend_from_slice(args);
    all.extend_from_slice(&["--report", path.to_str().expect("a UTF-8 temp path")]);
    let out = marie(&all);
    assert_eq!(out.status.code(), Some(0), "{all:?}: {}", text(&out.stderr));
    path
}

/// `marie diff A B` (and `extra` flags).
fn diff(a: &Path, b: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "diff",
        a.to_str().expect("UTF-8"),
        b.to_str().expect("UTF-8"),
    ];
    args.extend_from_slice(extra);
    marie(&args)
}

/// The lines of the section headed `name:` (up to the blank line that ends it).
fn section(stdout: &str, name: &str) -> String {
    let header = format!("{name}:");
    let mut lines = stdout.lines().skip_while(|l| *l != header);
    assert!(
        lines.next().is_some(),
        "no `{header}` section in:\n{stdout}"
    );
    lines
        .take_while(|l| !l.is_empty())
        .collect::<Vec<_>>()
        .join("\n")
}

/// The aspects the `same: …` line names.
fn same(stdout: &str) -> Vec<String> {
    stdout
        .lines()
        .find_map(|l| l.strip_prefix("same: "))
        .map(|l| l.split(", ").map(str::to_string).collect())
        .unwrap_or_default()
}

#[test]
fn two_seeds_of_the_docking_mission_differ_in_the_seed_and_the_final_pose_not_the_files() {
    let dir = tempfile::tempdir().unwrap();
    let a = report(
        dir.path(),
        "a.json",
        "missions/docking.toml",
        &["--seed", "3"],
    );
    let b = report(
        dir.path(),
        "b.json",
        "missions/docking.toml",
        &["--seed", "4"],
    );
    let out = diff(&a, &b, &[]);
    let stdout = text(&out.stdout);
    assert_eq!(
        out.status.code(),
        Some(1),
        "{stdout}\n{}",
        text(&out.stderr)
    );
    let first = stdout.lines().next().unwrap_or_default();
    assert!(
        first.starts_with("a: ") && first.contains("mission `docking`"),
        "{stdout}"
    );
    assert!(
        first.contains("started ") && first.contains("marie 0.1.0"),
        "{stdout}"
    );
    assert_eq!(section(&stdout, "run"), "  seed: 3 -> 4", "{stdout}");
    let pose = section(&stdout, "final pose");
    assert!(
        pose.contains("  a: (") && pose.contains("  b: ("),
        "{stdout}"
    );
    assert!(pose.contains(" m apart, heading "), "{stdout}");
    let same = same(&stdout);
    for aspect in ["marie", "files", "parameters", "bindings", "faults"] {
        assert!(
            same.iter().any(|s| s == aspect),
            "{aspect} not same:\n{stdout}"
        );
    }
    assert!(!stdout.contains("\nfiles:"), "{stdout}");

    // the same as JSON: aspect -> what differs
    let out = diff(&a, &b, &["--json"]);
    assert_eq!(out.status.code(), Some(1));
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON object");
    assert_eq!(
        json["differ"]["run"]["seed"],
        serde_json::json!({"a": "3", "b": "4"})
    );
    assert!(json["differ"]["final pose"]["distance_m"]
        .as_f64()
        .is_some_and(|d| d > 0.0));
    assert!(json["same"]
        .as_array()
        .is_some_and(|s| s.contains(&"files".into())));
    assert_eq!(json["a"]["mission"], "docking");
}

#[test]
fn an_edited_mission_shows_its_hunk_and_the_parameter_it_changed_with_its_source() {
    let dir = tempfile::tempdir().unwrap();
    let a = report(dir.path(), "a.json", "missions/docking.toml", &[]);
    // the mission copied beside its world, the wall follower's distance edited
    let text_of = std::fs::read_to_string("missions/docking.toml").unwrap();
    let edited = text_of.replace(
        "[action.ops.wall-follower]\ndistance = 0.8\n",
        "[action.ops.wall-follower]\ndistance = 0.7\n",
    );
    assert_ne!(
        edited, text_of,
        "the mission still sets the wall follower's distance"
    );
    std::fs::create_dir(dir.path().join("worlds")).unwrap();
    std::fs::copy(
        "missions/worlds/lab.toml",
        dir.path().join("worlds").join("lab.toml"),
    )
    .unwrap();
    let mission = dir.path().join("docking.toml");
    std::fs::write(&mission, edited).unwrap();
    let b = report(dir.path(), "b.json", mission.to_str().unwrap(), &[]);
    let out = diff(&a, &b, &[]);
    let stdout = text(&out.stdout);
    assert_eq!(
        out.status.code(),
        Some(1),
        "{stdout}\n{}",
        text(&out.stderr)
    );
    let files = section(&stdout, "files");
    assert!(
        files.contains("--- a/missions/docking.toml\n+++ b/"),
        "{stdout}"
    );
    assert!(files.contains("\n@@ -"), "{stdout}");
    assert!(
        files.contains(" [action.ops.wall-follower]\n-distance = 0.8\n+distance = 0.7\n"),
        "{stdout}"
    );
    assert_eq!(
        section(&stdout, "parameters"),
        "  follow-wall/wall-follower.distance: 0.8 (mission) -> 0.7 (mission)",
        "{stdout}"
    );
    // the world is the same text from another path: the same file
    assert!(!files.contains("world"), "{stdout}");
    assert!(!stdout.contains("\nrun:"), "{stdout}");
}

#[test]
fn a_report_diffed_with_itself_is_the_same_in_every_aspect() {
    let dir = tempfile::tempdir().unwrap();
    let a = report(
        dir.path(),
        "a.json",
        "missions/docking.toml",
        &["--seed", "3"],
    );
    let out = diff(&a, &a, &[]);
    let stdout = text(&out.stdout);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{stdout}\n{}",
        text(&out.stderr)
    );
    assert!(
        stdout.contains("the runs are the same in every aspect"),
        "{stdout}"
    );
    assert_eq!(
        same(&stdout),
        [
            "marie",
            "run",
            "files",
            "parameters",
            "bindings",
            "faults",
            "outcome",
            "final pose"
        ],
        "{stdout}"
    );
    let out = diff(&a, &a, &["--json"]);
    assert_eq!(out.status.code(), Some(0));
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON object");
    assert_eq!(json["differ"], serde_json::json!({}));
}

#[test]
fn a_killed_operation_shows_in_the_faults_and_the_rebinds() {
    let dir = tempfile::tempdir().unwrap();
    let a = report(dir.path(), "a.json", "missions/docking.toml", &[]);
    let b = report(
        dir.path(),
        "b.json",
        "missions/docking.toml",
        &["--fault", "kill:wall-follower@20"],
    );
    let out = diff(&a, &b, &[]);
    let stdout = text(&out.stdout);
    assert_eq!(
        out.status.code(),
        Some(1),
        "{stdout}\n{}",
        text(&out.stderr)
    );
    let faults = section(&stdout, "faults");
    assert!(faults.contains("  a: none\n  b: 1 fault\n"), "{stdout}");
    assert!(
        faults.contains("    20.000 s kill wall-follower: "),
        "{stdout}"
    );
    let bindings = section(&stdout, "bindings");
    assert!(bindings.contains("  rebinds: 0 -> 1"), "{stdout}");
    assert!(bindings.contains("    b: wall-follower: "), "{stdout}");
    // the same inputs otherwise: the files and parameters are the same
    let same = same(&stdout);
    for aspect in ["files", "parameters", "run"] {
        assert!(
            same.iter().any(|s| s == aspect),
            "{aspect} not same:\n{stdout}"
        );
    }
}

#[test]
fn a_missing_file_or_one_that_is_not_a_report_exits_2_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let a = report(dir.path(), "a.json", "missions/demo.toml", &[]);
    let missing = dir.path().join("missing.json");
    let out = diff(&a, &missing, &[]);
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains(&format!("{}: cannot be read", missing.display())),
        "{stderr}"
    );
    assert!(out.stdout.is_empty(), "{}", text(&out.stdout));

    let other = dir.path().join("other.json");
    std::fs::write(&other, r#"{"name": "not a report"}"#).unwrap();
    let out = diff(&other, &a, &[]);
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains(&format!("{}: is not a run report", other.display())),
        "{stderr}"
    );
}
