//! The `marie` command, end to end: exit codes, stdout results, stderr diagnostics.

use std::path::PathBuf;
use std::process::{Command, Output};

fn marie(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_marie"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env_remove("RUST_LOG")
        .output()
        .expect("marie runs")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

fn mission_file(dir: &tempfile::TempDir, name: &str, body: &str) -> PathBuf {
    let p = dir.path().join(name);
    std::fs::write(&p, body).unwrap();
    p
}

const DEMO: &str = include_str!("../missions/demo.toml");

#[test]
fn the_demo_mission_succeeds_with_exit_0_and_writes_a_report() {
    let dir = tempfile::tempdir().unwrap();
    let report = dir.path().join("run.json");
    let out = marie(&[
        "run",
        "missions/demo.toml",
        "--speed",
        "4",
        "--report",
        report.to_str().unwrap(),
    ]);
    let stdout = text(&out.stdout);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{stdout}\n{}",
        text(&out.stderr)
    );
    assert!(stdout.contains("> sample-and-average: start"), "{stdout}");
    assert!(stdout.contains("< verify: end"), "{stdout}");
    assert!(stdout.contains("mission succeeded"), "{stdout}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(json["outcome"], "succeeded");
    assert_eq!(json["actions"][0]["operations"][0]["name"], "sampler");
    assert_eq!(json["actions"][0]["operations"][0]["ended"], "suspended");
    assert_eq!(json["actions"][0]["operations"][1]["ended"], "finished");
    assert_eq!(json["actions"][0]["operations"][1]["version"], "1.0.0");
    for key in ["reason", "rebinds", "final_pose", "collisions", "seed"] {
        assert!(json.get(key).is_some(), "report lacks {key}");
    }
}

#[test]
fn a_failing_mission_exits_1_with_the_reason() {
    let dir = tempfile::tempdir().unwrap();
    // the checker expects a variance the signal cannot have: the verify stage fails
    let body = DEMO.replace("expected_variance = 0.5", "expected_variance = 5.0");
    let p = mission_file(&dir, "wrong.toml", &body);
    let out = marie(&["run", p.to_str().unwrap(), "--speed", "4"]);
    let stdout = text(&out.stdout);
    assert_eq!(
        out.status.code(),
        Some(1),
        "{stdout}\n{}",
        text(&out.stderr)
    );
    assert!(stdout.contains("mission FAILED (full stop)"), "{stdout}");
    assert!(stdout.contains("`checker` failed"), "{stdout}");
    assert!(stdout.contains("statistics out of bounds"), "{stdout}");
}

#[test]
fn a_malformed_mission_exits_2_naming_file_line_and_column() {
    let dir = tempfile::tempdir().unwrap();
    let p = mission_file(
        &dir,
        "syntax.toml",
        "[mission]\nname = \"x\"\nsuccess = [\n",
    );
    let out = marie(&["run", p.to_str().unwrap()]);
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("syntax.toml:"), "{stderr}");
    assert!(out.stdout.is_empty(), "nothing ran: {}", text(&out.stdout));
}

#[test]
fn an_inconsistent_mission_exits_2_before_anything_runs() {
    let dir = tempfile::tempdir().unwrap();
    let body = DEMO
        .replace("window = 200", "window = 0") // out of range
        .replace("[action.ops.checker]", "[action.ops.chekcer]"); // unknown operation
    let p = mission_file(&dir, "bad.toml", &body);
    let out = marie(&["run", p.to_str().unwrap()]);
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    let window_line = body.lines().position(|l| l.starts_with("window")).unwrap() + 1;
    assert!(
        stderr.contains(&format!("bad.toml:{window_line}:")),
        "window error names line {window_line}: {stderr}"
    );
    assert!(stderr.contains("`chekcer`"), "{stderr}");
    assert!(!text(&out.stdout).contains("start"), "nothing ran");
}

#[test]
fn a_missing_mission_file_exits_2() {
    let out = marie(&["run", "no/such/mission.toml"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(text(&out.stderr).contains("no/such/mission.toml"));
}

#[test]
fn check_validates_without_running() {
    let out = marie(&["check", "missions/demo.toml"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    assert!(text(&out.stdout).contains("ok"));
}

#[test]
fn ls_lists_datamanagers_and_operations_like_the_thesis_log() {
    let out = marie(&["ls"]);
    let stdout = text(&out.stdout);
    assert_eq!(out.status.code(), Some(0));
    assert!(
        stdout.contains("EO found 0: ID: 1601 node: local"),
        "{stdout}"
    );
    assert!(
        stdout.contains("DM found 0: ID: 1201 node: local"),
        "{stdout}"
    );
    assert!(stdout.contains("name: world"), "{stdout}");
    let out = marie(&["ls", "--json"]);
    let rows: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(rows.as_array().unwrap().len() >= 6);
}

#[test]
fn props_shows_every_group_by_name_or_id() {
    for key in ["sampler", "1601"] {
        let out = marie(&["props", key]);
        let stdout = text(&out.stdout);
        assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
        for needle in [
            "identification",
            "version:     1.0.0",
            "location",
            "general",
            "frequency",
            "Hz",
            "bit 0: sampled",
        ] {
            assert!(stdout.contains(needle), "{needle} in {stdout}");
        }
    }
    let out = marie(&["props", "sampler", "--json"]);
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json[0]["Identification"]["id"], 1601);
    let out = marie(&["props", "nosuch"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(text(&out.stderr).contains("no operation `nosuch`"));
}

#[test]
fn bad_flags_exit_2_and_json_logs_go_to_stderr() {
    let out = marie(&["run", "missions/demo.toml", "--speed", "fast"]);
    assert_eq!(out.status.code(), Some(2));
    let out = Command::new(env!("CARGO_BIN_EXE_marie"))
        .args(["--log-format", "json", "check", "missions/demo.toml"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env("RUST_LOG", "debug")
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(0));
    let stderr = text(&out.stderr);
    let first = stderr.lines().next().expect("debug logs");
    let line: serde_json::Value = serde_json::from_str(first).expect("a JSON line");
    assert!(line.get("level").is_some());
    assert!(
        !text(&out.stdout).contains("\"level\""),
        "logs stay off stdout"
    );
}

#[test]
fn speed_max_runs_the_mission_in_virtual_time() {
    let dir = tempfile::tempdir().unwrap();
    let report = dir.path().join("max.json");
    let out = marie(&[
        "run",
        "missions/demo.toml",
        "--speed",
        "max",
        "--report",
        report.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(json["outcome"], "succeeded");
    // the averager needs 200 samples at one per 2 ms of (virtual) sampler time
    assert!(json["duration_ms"].as_u64().unwrap() >= 400, "{json}");
}
