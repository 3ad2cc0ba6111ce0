//! The `marie` command, end to end: exit codes, stdout results, stderr diagnostics.

use crate::common;
use std::path::PathBuf;

use common::{marie, text};
use std::process::Command;

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
    assert!(stdout.contains("ID: 1601 node: embedded"), "{stdout}");
    // the robot's operations too: the built-in node hosts everything
    assert!(stdout.contains("ID: 1514 node: embedded"), "{stdout}");
    assert!(
        stdout.contains("DM found 0: ID: 1201 node: embedded"),
        "{stdout}"
    );
    assert!(stdout.contains("name: world"), "{stdout}");
    // each datamanager's state: the built-in node keeps them in memory
    assert!(
        stdout.contains("DM feature on embedded: 0 records, in memory"),
        "{stdout}"
    );
    let out = marie(&["ls", "--json"]);
    let rows: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(rows.as_array().unwrap().len() >= 6);
    let world = rows
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["name"] == "world")
        .unwrap();
    assert_eq!(world["durability"], "memory", "{world}");
    assert!(world["records"].as_u64().is_some(), "{world}");
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

// ---------------------------------------------------------------------------------------------
// Missions with a world: the simulated robot

fn world_file(name: &str) -> PathBuf {
    marie_missions::world::worlds_dir().join(format!("{name}.toml"))
}

/// The demo mission (demo operations only, so the cart never moves), naming `world`.
fn demo_in_world(dir: &tempfile::TempDir, name: &str, world: &str) -> PathBuf {
    let line = format!("world = {:?}\n", world);
    let body = DEMO.replacen(
        "deadline_s = 60.0\n",
        &format!("deadline_s = 60.0\n{line}"),
        1,
    );
    assert!(body.contains(&line));
    mission_file(dir, name, &body)
}

fn read_json(path: &std::path::Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

#[test]
fn a_mission_with_a_world_runs_the_robot_and_writes_report_and_picture() {
    let dir = tempfile::tempdir().unwrap();
    let lab = world_file("lab");
    let world = marie_missions::world::World::load(&lab).unwrap();
    let mission = demo_in_world(&dir, "lab.toml", lab.to_str().unwrap());
    let (report, svg) = (dir.path().join("run.json"), dir.path().join("run.svg"));
    let out = marie(&[
        "run",
        mission.to_str().unwrap(),
        "--speed",
        "max",
        "--seed",
        "7",
        "--report",
        report.to_str().unwrap(),
        "--svg",
        svg.to_str().unwrap(),
    ]);
    let stdout = text(&out.stdout);
    // the dispatcher succeeds, but the cart never left its start: the world fails the run
    assert_eq!(
        out.status.code(),
        Some(1),
        "{stdout}\n{}",
        text(&out.stderr)
    );
    let world_line = stdout.find("world `lab` from").expect("a world line");
    assert!(
        stdout[world_line..].starts_with(&format!("world `lab` from {}, seed 7\n", lab.display()))
    );
    assert!(world_line < stdout.find("> sample-and-average").unwrap());
    assert!(
        stdout.contains("mission FAILED (full stop): the cart did not end in the goal area: failure: outside the goal area"),
        "{stdout}"
    );
    assert!(!stdout.contains("mission succeeded"), "{stdout}");
    assert!(
        stdout.contains(
            "outcome: failed — final pose (12.50, 1.50, 180.0°), inside goal: no, collisions: 0"
        ),
        "{stdout}"
    );

    let json = read_json(&report);
    assert_eq!(json["outcome"], "failed");
    assert!(json["reason"]
        .as_str()
        .unwrap()
        .starts_with("the cart did not end in the goal area: "));
    let pose: Vec<f64> = serde_json::from_value(json["final_pose"].clone()).unwrap();
    let start = [world.start.x, world.start.y, world.start.theta];
    for (got, want) in pose.iter().zip(start) {
        assert!(
            (got - want).abs() < 1e-9,
            "final pose {pose:?}, start {start:?}"
        );
    }
    assert_eq!(pose.len(), 3);
    assert_eq!(json["collisions"], 0);
    assert_eq!(json["seed"], 7);
    assert_eq!(json["inside_goal"], false);
    assert!(json["judgement"]
        .as_str()
        .unwrap()
        .contains("outside the goal area"));
    // the dispatcher's own account is untouched
    assert_eq!(json["flags"], serde_json::json!(["averaged", "verified"]));

    let svg = std::fs::read_to_string(&svg).unwrap();
    assert!(svg.starts_with("<svg"), "{svg}");
    assert!(svg.trim_end().ends_with("</svg>"));
    // one polyline per wall, through its first point
    let walls = svg
        .lines()
        .filter(|l| l.starts_with("<polyline") && l.contains(r##"stroke="#222""##))
        .count();
    assert_eq!(walls, world.walls.len(), "{svg}");
    assert!(svg.contains("demo — failed — seed 7"), "the caption");
    assert!(svg.contains("<title>final footprint</title>"));
}

#[test]
fn the_world_flag_overrides_the_missions_world_and_a_world_without_goal_judges_nothing() {
    let dir = tempfile::tempdir().unwrap();
    // a relative `world` is resolved against the mission's directory
    std::fs::create_dir(dir.path().join("worlds")).unwrap();
    std::fs::copy(world_file("lab"), dir.path().join("worlds/lab.toml")).unwrap();
    let mission = demo_in_world(&dir, "m.toml", "worlds/lab.toml");
    let out = marie(&["check", mission.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    assert!(
        text(&out.stdout).contains("ok — mission `demo`, 2 actions, 3 operations, world `lab`"),
        "{}",
        text(&out.stdout)
    );
    let out = marie(&["run", mission.to_str().unwrap(), "--speed", "max"]);
    let expected = format!(
        "world `lab` from {}, seed 1\n",
        dir.path().join("worlds/lab.toml").display()
    );
    assert!(
        text(&out.stdout).contains(&expected),
        "{}",
        text(&out.stdout)
    );

    let report = dir.path().join("run.json");
    let nodock = world_file("nodock");
    let out = marie(&[
        "run",
        mission.to_str().unwrap(),
        "--world",
        nodock.to_str().unwrap(),
        "--speed",
        "max",
        "--report",
        report.to_str().unwrap(),
    ]);
    let stdout = text(&out.stdout);
    // no goal area: only the dispatcher's outcome counts
    assert_eq!(
        out.status.code(),
        Some(0),
        "{stdout}\n{}",
        text(&out.stderr)
    );
    assert!(stdout.contains("world `nodock` from"), "{stdout}");
    assert!(stdout.contains(", seed 1\n"), "the default seed: {stdout}");
    assert!(!stdout.contains("world `lab`"), "{stdout}");
    assert!(stdout.contains("mission succeeded"), "{stdout}");
    assert!(
        stdout.contains("inside goal: no goal area, collisions: 0"),
        "{stdout}"
    );
    let json = read_json(&report);
    assert_eq!(json["outcome"], "succeeded");
    assert_eq!(json["seed"], 1);
    assert_eq!(json["inside_goal"], serde_json::Value::Null);
    assert!(json["judgement"].as_str().unwrap().contains("no goal area"));
    assert_eq!(json["final_pose"][0], 12.5);
}

#[test]
fn a_bad_world_file_exits_2_naming_file_line_and_column() {
    let dir = tempfile::tempdir().unwrap();
    let bad = mission_file(
        &dir,
        "bad-world.toml",
        "[world]\nname = \"x\"\ncolour = 3\n",
    );
    let out = marie(&[
        "run",
        "missions/demo.toml",
        "--world",
        bad.to_str().unwrap(),
    ]);
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains(&format!("{}:3:1: unknown key `colour`", bad.display())),
        "{stderr}"
    );
    assert!(out.stdout.is_empty(), "nothing ran: {}", text(&out.stdout));

    // a world the mission names but that is not there
    let mission = demo_in_world(&dir, "m.toml", "no-such-world.toml");
    let out = marie(&["run", mission.to_str().unwrap(), "--speed", "max"]);
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("no-such-world.toml:1:1: cannot read world file"),
        "{stderr}"
    );

    // a `world` that is not a path is a mission error at its position
    let body = DEMO.replacen("deadline_s = 60.0\n", "deadline_s = 60.0\nworld = 3\n", 1);
    let mission = mission_file(&dir, "typed.toml", &body);
    let out = marie(&["check", mission.to_str().unwrap()]);
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    let line = body.lines().position(|l| l == "world = 3").unwrap() + 1;
    assert!(
        stderr.contains(&format!(
            "typed.toml:{line}:9: expected a string for `mission.world`"
        )),
        "{stderr}"
    );
}

#[test]
fn without_a_world_no_robot_runs_and_svg_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let report = dir.path().join("run.json");
    let out = marie(&[
        "run",
        "missions/demo.toml",
        "--speed",
        "max",
        "--report",
        report.to_str().unwrap(),
    ]);
    let stdout = text(&out.stdout);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    assert!(!stdout.contains("world `"), "{stdout}");
    assert!(!stdout.contains("outcome:"), "{stdout}");
    let json = read_json(&report);
    for key in [
        "final_pose",
        "collisions",
        "seed",
        "inside_goal",
        "judgement",
        "refused_commands",
        "obeyed_late",
    ] {
        assert_eq!(json[key], serde_json::Value::Null, "{key}");
    }

    let svg = dir.path().join("run.svg");
    let out = marie(&[
        "run",
        "missions/demo.toml",
        "--speed",
        "max",
        "--svg",
        svg.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(text(&out.stderr).contains("--svg"), "{}", text(&out.stderr));
    assert!(!svg.exists());
}

#[test]
fn an_unwritable_picture_is_refused_before_the_run() {
    let dir = tempfile::tempdir().unwrap();
    let report = dir.path().join("run.json");
    let svg = dir.path().join("no/such/dir/run.svg");
    let nodock = world_file("nodock");
    let out = marie(&[
        "run",
        "missions/demo.toml",
        "--world",
        nodock.to_str().unwrap(),
        "--speed",
        "max",
        "--report",
        report.to_str().unwrap(),
        "--svg",
        svg.to_str().unwrap(),
    ]);
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains(&format!("--svg {}: no directory", svg.display())),
        "{stderr}"
    );
    assert!(out.stdout.is_empty(), "nothing ran: {}", text(&out.stdout));
    assert!(!report.exists());
}

#[test]
fn the_version_names_the_commit_it_was_built_from() {
    let out = marie(&["--version"]);
    assert_eq!(out.status.code(), Some(0));
    let line = text(&out.stdout);
    let head = Command::new("git")
        .args(["rev-parse", "HEAD"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map(|o| text(&o.stdout).trim().to_string());
    let expected = match head {
        Some(commit) => format!("marie {} (commit {commit}", env!("CARGO_PKG_VERSION")),
        None => format!("marie {} (commit unknown)", env!("CARGO_PKG_VERSION")),
    };
    assert!(
        line.starts_with(&expected),
        "{line:?} (expected {expected:?}…)"
    );
}
