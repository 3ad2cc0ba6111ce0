//! Self-configuration in one process, the thesis' experiments 1 and 2 (issue 11): with the
//! wall follower's version 1 (one parameter) and version 2 (two, corridor-capable) hosted
//! side by side, the dispatcher chooses by the properties it asks, following what the
//! mission supplies — and a mission that needs version 2 where only version 1 runs does
//! not start, and says why.

use crate::common;

use common::missions::{docking_edited, docking_variant};
use common::{marie, report_of, text};
use serde_json::Value;
use std::path::Path;

/// Run `mission` at `--speed max` on `node` (the default node without), with a report:
/// the exit code, the report (if written) and stderr.
fn run(mission: &Path, node: Option<&str>) -> (Option<i32>, Option<Value>, String) {
    let mut args = vec!["run", mission.to_str().unwrap(), "--speed", "max"];
    if let Some(node) = node {
        args.extend(["--node", node]);
    }
    let (out, report) = report_of(&args);
    let report = (!report.is_null()).then_some(report);
    (out.status.code(), report, text(&out.stderr))
}

/// The wall follower's choice in the report.
fn wall_follower_choice(report: &Value) -> &Value {
    report["selection"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["operation"] == "wall-follower")
        .unwrap_or_else(|| panic!("no choice for the wall follower: {report:#}"))
}

fn candidate<'a>(choice: &'a Value, version: &str) -> &'a Value {
    choice["candidates"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["version"] == version)
        .unwrap_or_else(|| panic!("no version {version} among {choice:#}"))
}

#[test]
fn a_mission_that_supplies_only_the_wall_distance_gets_version_1_and_is_told_why() {
    let dir = tempfile::tempdir().unwrap();
    let mission = docking_variant(dir.path(), "docking-variant", "", "");
    let (code, report, stderr) = run(&mission, None);
    assert_eq!(code, Some(0), "{stderr}");
    let report = report.unwrap();
    let choice = wall_follower_choice(&report);
    assert_eq!(candidate(choice, "1.0.0")["verdict"]["type"], "chosen");
    let v2 = candidate(choice, "2.0.0");
    assert_eq!(v2["verdict"]["type"], "lost", "{v2}");
    let reason = v2["verdict"]["reason"].as_str().unwrap();
    assert!(
        reason.contains("also declares mode") && reason.contains("fits exactly"),
        "{reason}"
    );
    assert_eq!(v2["schema"], serde_json::json!(["distance", "mode"]));
}

#[test]
fn a_mission_that_also_supplies_the_corridor_parameter_gets_version_2() {
    let dir = tempfile::tempdir().unwrap();
    let mission = docking_variant(dir.path(), "docking-variant", "mode = \"wall\"\n", "");
    let (code, report, stderr) = run(&mission, None);
    assert_eq!(code, Some(0), "{stderr}");
    let report = report.unwrap();
    let choice = wall_follower_choice(&report);
    assert_eq!(candidate(choice, "2.0.0")["verdict"]["type"], "chosen");
    let v1 = candidate(choice, "1.0.0");
    assert_eq!(v1["verdict"]["type"], "rejected", "{v1}");
    assert!(
        v1["verdict"]["reason"].as_str().unwrap().contains("mode"),
        "{v1}"
    );
    // the actions ran on version 2
    let follow = report["actions"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|a| a["operations"].as_array().unwrap())
        .find(|op| op["name"] == "wall-follower")
        .unwrap();
    assert_eq!(follow["version"], "2.0.0", "{follow}");
}

#[test]
fn a_mission_that_needs_version_2_where_only_version_1_runs_does_not_start() {
    let dir = tempfile::tempdir().unwrap();
    let v1_only = "missions/nodes/v1-only.toml";
    // it supplies the corridor parameter, which version 1 does not take
    let mission = docking_variant(dir.path(), "docking-variant", "mode = \"corridor\"\n", "");
    let (code, report, stderr) = run(&mission, Some(v1_only));
    assert_eq!(code, Some(2), "{stderr}");
    assert!(report.is_none());
    assert!(stderr.contains("mode"), "{stderr}");
    // it requires version 2 in so many words
    let mission = docking_variant(
        dir.path(),
        "docking-variant",
        "",
        "\n[requires]\nwall-follower = \"^2\"\n",
    );
    let (code, report, stderr) = run(&mission, Some(v1_only));
    assert_eq!(code, Some(2), "{stderr}");
    assert!(report.is_none());
    // at the requirement's line, naming the operation and why its instance does not fit
    assert!(
        stderr.contains("docking-variant.toml:")
            && stderr.contains("no instance of operation `wall-follower` fits")
            && stderr.contains("does not match the mission's requirement ^2"),
        "{stderr}"
    );
}

#[test]
fn run_explain_lists_every_candidate_with_why_it_lost() {
    let out = marie(&[
        "run",
        "missions/docking.toml",
        "--speed",
        "max",
        "--explain",
    ]);
    let stdout = text(&out.stdout);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let lines: Vec<&str> = stdout.lines().collect();
    let at = lines
        .iter()
        .position(|l| l.starts_with("? wall-follower: 2 candidate(s)"))
        .unwrap_or_else(|| panic!("{stdout}"));
    assert!(
        lines[at + 1].trim_start().starts_with("chosen")
            && lines[at + 1].contains("version 1.0.0, schema [distance]"),
        "{stdout}"
    );
    assert!(
        lines[at + 2].trim_start().starts_with("lost")
            && lines[at + 2].contains("version 2.0.0, schema [distance, mode]")
            && lines[at + 2].contains("also declares mode"),
        "{stdout}"
    );
}

#[test]
fn a_closed_stdout_ends_the_command_quietly() {
    use std::os::unix::process::ExitStatusExt;
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_marie"))
        .args([
            "run",
            "missions/docking.toml",
            "--speed",
            "max",
            "--explain",
        ])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // closed before the command prints anything, as `| head -0` would
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    assert!(
        !text(&out.stderr).contains("panicked"),
        "{}",
        text(&out.stderr)
    );
    assert_eq!(
        out.status.signal(),
        Some(13),
        "ended by SIGPIPE: {:?}",
        out.status
    );
}

#[test]
fn check_names_the_instance_that_would_serve_each_operation_and_counts_control_details() {
    let out = marie(&["check", "missions/docking.toml"]);
    let stdout = text(&out.stdout);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let wf = stdout
        .lines()
        .find(|l| l.trim_start().starts_with("wall-follower"))
        .unwrap_or_else(|| panic!("{stdout}"));
    assert!(wf.contains("version 1.0.0, of 2 candidate(s)"), "{wf}");
    let counts = stdout
        .lines()
        .find_map(|l| l.strip_prefix("control details: "))
        .unwrap_or_else(|| panic!("{stdout}"));
    let numbers: Vec<u32> = counts.split(' ').filter_map(|w| w.parse().ok()).collect();
    assert!(
        numbers.len() == 2 && numbers[0] > 0 && numbers[1] > 0,
        "{counts}"
    );
    // docking.toml supplies 16 values; the operations it runs declare 66 more it leaves at
    // their defaults (counted per action that runs them)
    assert_eq!(numbers, [16, 66], "{counts}");
    // a mission no running instance fits: refused before anything runs
    let dir = tempfile::tempdir().unwrap();
    let mission = docking_variant(
        dir.path(),
        "docking-variant",
        "",
        "\n[requires]\nwall-follower = \"^3\"\n",
    );
    let out = marie(&["check", mission.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        text(&out.stderr).contains("no instance of operation `wall-follower` fits"),
        "{}",
        text(&out.stderr)
    );
}

/// `marie check --json` on `mission`: the exit code and the verdict.
fn check_json(mission: &Path) -> (Option<i32>, Value) {
    let out = marie(&["check", mission.to_str().unwrap(), "--json"]);
    let verdict = serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|e| panic!("{e}: {}{}", text(&out.stdout), text(&out.stderr)));
    (out.status.code(), verdict)
}

#[test]
fn check_refuses_one_bad_mission_per_kind_of_error_naming_the_line() {
    let dir = tempfile::tempdir().unwrap();
    let trajectory = "[action.ops.trajectory-controller]\nspeed = 0.3";
    // (what is wrong, the edit, what the error must say, the line it must name)
    let cases: [(&str, (&str, &str), &str, &str); 9] = [
        (
            "syntax",
            ("[[action]]\nname = \"park\"", "[[action]\nname = \"park\""),
            "",
            "[[action]",
        ),
        (
            "unknown operation",
            ("[action.ops.path-planner]", "[action.ops.path-planer]"),
            "path-planer",
            "[action.ops.path-planer]",
        ),
        (
            "unknown parameter",
            ("breadth = 2.8", "broadth = 2.8"),
            "broadth",
            "broadth = 2.8",
        ),
        (
            "wrong type",
            ("breadth = 2.8", "breadth = \"wide\""),
            "breadth",
            "breadth = \"wide\"",
        ),
        (
            "out of range",
            (
                trajectory,
                "[action.ops.trajectory-controller]\nspeed = 9.0",
            ),
            "speed",
            "speed = 9.0",
        ),
        (
            "a flag no operation raises",
            (
                "success = [\"path-driven\"]\ndeadline_s = 600.0\n\n[flags]\n",
                "success = [\"teleported\"]\ndeadline_s = 600.0\n\n[flags]\nteleported = 9\n",
            ),
            "teleported",
            "success = [\"teleported\"]",
        ),
        (
            "no instance fits the version required",
            (
                "[flags]\n",
                "[requires]\nwall-follower = \"^3\"\n\n[flags]\n",
            ),
            "no instance of operation `wall-follower` fits",
            "wall-follower = \"^3\"",
        ),
        (
            "a requirement on an operation no action runs",
            ("[flags]\n", "[requires]\naverager = \"1\"\n\n[flags]\n"),
            "averager",
            "averager = \"1\"",
        ),
        (
            "a world file that does not load",
            ("deadline_s = 600.0", "deadline_s = 600.0\n"),
            "nowhere.toml",
            "",
        ),
    ];
    for (i, (kind, edit, needle, line)) in cases.into_iter().enumerate() {
        let name = format!("bad-{i}");
        let mission = if kind == "a world file that does not load" {
            let p = docking_edited(dir.path(), &name, &[edit]);
            let src = std::fs::read_to_string(&p).unwrap();
            let src = src
                .lines()
                .map(|l| {
                    if l.starts_with("world = ") {
                        "world = \"nowhere.toml\"".to_string()
                    } else {
                        l.to_string()
                    }
                })
                .collect::<Vec<_>>()
                .join("\n");
            std::fs::write(&p, src).unwrap();
            p
        } else {
            docking_edited(dir.path(), &name, &[edit])
        };
        let (code, verdict) = check_json(&mission);
        assert_eq!(code, Some(2), "{kind}: {verdict:#}");
        assert_eq!(verdict["ok"], false, "{kind}: {verdict:#}");
        let errors = verdict["errors"].as_array().unwrap();
        assert!(!errors.is_empty(), "{kind}");
        let all = verdict["errors"].to_string();
        assert!(all.contains(needle), "{kind}: {all}");
        // the first error names the line the fault is on (in the mission file)
        if !line.is_empty() {
            let src = std::fs::read_to_string(&mission).unwrap();
            let at = src.lines().position(|l| l.trim() == line.trim()).unwrap() + 1;
            let named = errors.iter().any(|e| {
                e["line"] == at
                    && e["path"]
                        .as_str()
                        .unwrap()
                        .ends_with(&format!("{name}.toml"))
            });
            assert!(named, "{kind}: no error at line {at}: {all}");
        }
    }
    // and a good one: ok, every choice made, every awaited flag raised
    let (code, verdict) = check_json(Path::new("missions/docking.toml"));
    assert_eq!(code, Some(0), "{verdict:#}");
    assert_eq!(verdict["ok"], true);
    let flags = verdict["survey"]["flags"].as_array().unwrap();
    assert!(!flags.is_empty());
    for f in flags {
        assert!(
            !f["raised_by"].as_array().unwrap().is_empty() || f["initial"] == true,
            "{f}"
        );
    }
    assert_eq!(
        verdict["survey"]["control_details"],
        serde_json::json!({"supplied": 16, "defaulted": 66})
    );
}

#[test]
fn with_only_version_2_hosted_a_wall_distance_mission_takes_it_as_a_compatible_superset() {
    let dir = tempfile::tempdir().unwrap();
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let v1_only = std::fs::read_to_string(repo.join("missions/nodes/v1-only.toml")).unwrap();
    let anchor = "version = \"1\"";
    assert!(v1_only.contains(anchor), "v1-only.toml changed");
    let v2_only = dir.path().join("v2-only.toml");
    std::fs::write(&v2_only, v1_only.replace(anchor, "version = \"2\"")).unwrap();
    let mission = docking_variant(dir.path(), "docking-variant", "", "");
    let (code, report, stderr) = run(&mission, Some(v2_only.to_str().unwrap()));
    assert_eq!(code, Some(0), "{stderr}");
    let report = report.unwrap();
    let choice = wall_follower_choice(&report);
    assert_eq!(
        choice["candidates"].as_array().unwrap().len(),
        1,
        "{choice:#}"
    );
    assert_eq!(candidate(choice, "2.0.0")["verdict"]["type"], "chosen");
}
