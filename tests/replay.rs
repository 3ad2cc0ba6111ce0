//! `marie run --replay REPORT.json` (issue 25): a past run run again from its report
//! alone — the mission, world and node config from the texts its provenance holds, its
//! seed, its command's faults — and compared: outcome, bindings, final pose, parameters.

use crate::common;

use common::{marie, text};
use serde_json::Value;
use std::path::{Path, PathBuf};

/// Run `args` with `--report DIR/NAME`; the report's path.
fn reported(dir: &Path, name: &str, args: &[&str]) -> PathBuf {
    let path = dir.join(name);
    let mut all = args.to_vec();
    all.extend(["--report", path.to_str().unwrap()]);
    let out = marie(&all);
    assert!(
        matches!(out.status.code(), Some(0 | 1)),
        "{args:?}: {}",
        text(&out.stderr)
    );
    assert!(
        path.exists(),
        "{args:?} wrote no report: {}",
        text(&out.stderr)
    );
    path
}

/// `(x, y, heading°)` of a report's final pose.
fn pose(p: &Value) -> String {
    let n = |i: usize| p[i].as_f64().unwrap_or(f64::NAN);
    format!("({:.3}, {:.3}, {:.1}°)", n(0), n(1), n(2).to_degrees())
}

fn read(path: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// `--replay REPORT --report DIR/replayed-NAME`: the exit code, stdout, stderr and the
/// replay's own report.
fn replay(report: &Path) -> (Option<i32>, String, String, Value) {
    let again = report.with_file_name(format!(
        "replayed-{}",
        report.file_name().unwrap().to_str().unwrap()
    ));
    let out = marie(&[
        "run",
        "--replay",
        report.to_str().unwrap(),
        "--report",
        again.to_str().unwrap(),
    ]);
    let replayed = std::fs::read_to_string(&again)
        .ok()
        .and_then(|s| serde_json::from_str(&s).ok())
        .unwrap_or(Value::Null);
    (
        out.status.code(),
        text(&out.stdout),
        text(&out.stderr),
        replayed,
    )
}

#[test]
fn three_missions_at_two_seeds_each_replay_from_their_reports_alone_and_match() {
    let dir = tempfile::tempdir().unwrap();
    // the missions are copied to a directory that is gone before the replay: the replay
    // has only the report
    let gone = tempfile::tempdir().unwrap();
    let missions = Path::new(env!("CARGO_MANIFEST_DIR")).join("missions");
    let cases: Vec<(&str, &str, u64)> = [
        ("docking.toml", "lab.toml"),
        ("corner.toml", "corner.toml"),
        ("docking-recover.toml", "deadend.toml"),
    ]
    .into_iter()
    .flat_map(|(m, w)| [3, 8].map(|seed| (m, w, seed)))
    .collect();
    let reports: Vec<PathBuf> = std::thread::scope(|s| {
        let handles: Vec<_> = cases
            .iter()
            .map(|(mission, world, seed)| {
                let (dir, gone, missions) = (dir.path(), gone.path(), &missions);
                s.spawn(move || {
                    let m = gone.join(format!("{seed}-{mission}"));
                    let w = gone.join(format!("world-{seed}-{world}"));
                    std::fs::copy(missions.join(mission), &m).unwrap();
                    std::fs::copy(missions.join("worlds").join(world), &w).unwrap();
                    let name = format!("{seed}-{mission}.json");
                    let seed = seed.to_string();
                    let args = [
                        "run",
                        m.to_str().unwrap(),
                        "--world",
                        w.to_str().unwrap(),
                        "--seed",
                        &seed,
                    ];
                    reported(dir, &name, &args)
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    drop(gone);
    let results: Vec<_> = std::thread::scope(|s| {
        let handles: Vec<_> = reports.iter().map(|r| s.spawn(|| replay(r))).collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    let mut table = vec![
        "| mission | seed | outcome | final pose | outcome | bindings | final pose | parameters |"
            .to_string(),
        "|---|---|---|---|---|---|---|---|".to_string(),
    ];
    for (((mission, _, seed), report), (code, stdout, stderr, replayed)) in
        cases.iter().zip(&reports).zip(&results)
    {
        let was = read(report);
        let verdict = |what: &str| {
            let line = stdout
                .lines()
                .find(|l| l.starts_with(&format!("  {what} ")))
                .unwrap_or_else(|| panic!("no `{what}` row: {stdout}"));
            match line.contains(" match ") {
                true => "match",
                false => "DIFFERS",
            }
        };
        table.push(format!(
            "| {mission} | {seed} | {} | {} | {} | {} | {} | {} |",
            was["outcome"].as_str().unwrap(),
            pose(&was["final_pose"]),
            verdict("outcome"),
            verdict("bindings"),
            verdict("final pose"),
            verdict("parameters"),
        ));
        assert_eq!(*code, Some(0), "{mission} seed {seed}: {stdout}\n{stderr}");
        for what in ["outcome", "bindings", "final pose", "parameters"] {
            assert_eq!(verdict(what), "match", "{mission} seed {seed}: {stdout}");
        }
        assert!(
            stdout.contains("replay: matches the report"),
            "{mission} seed {seed}: {stdout}"
        );
        // the replay's own report: the same run, and the same files under their paths
        assert_eq!(replayed["outcome"], was["outcome"]);
        assert_eq!(replayed["final_pose"], was["final_pose"]);
        assert_eq!(replayed["actions"], was["actions"]);
        assert_eq!(replayed["provenance"]["seed"], was["provenance"]["seed"]);
        let files = |r: &Value| -> Vec<(Value, Value, Value)> {
            r["provenance"]["files"]
                .as_array()
                .unwrap()
                .iter()
                .map(|f| (f["role"].clone(), f["path"].clone(), f["sha256"].clone()))
                .collect()
        };
        assert_eq!(files(replayed), files(&was), "{mission} seed {seed}");
        assert_eq!(
            replayed["provenance"]["parameters"],
            was["provenance"]["parameters"]
        );
    }
    // the table the issue's note quotes
    eprintln!("{}", table.join("\n"));
}

#[test]
fn a_faulted_run_is_replayed_with_its_faults_and_matches() {
    let dir = tempfile::tempdir().unwrap();
    let report = reported(
        dir.path(),
        "faulted.json",
        &[
            "run",
            "missions/docking.toml",
            "--seed",
            "2",
            "--fault",
            "kill:wall-follower@20",
        ],
    );
    let (code, stdout, stderr, replayed) = replay(&report);
    assert_eq!(code, Some(0), "{stdout}\n{stderr}");
    assert!(stdout.contains("replay: matches the report"), "{stdout}");
    assert_eq!(replayed["faults"][0]["fault"], "kill", "{replayed}");
    assert_eq!(replayed["faults"][0]["operation"], "wall-follower");
    assert_eq!(replayed["rebinds_total"], read(&report)["rebinds_total"]);
}

#[test]
fn a_report_of_another_commit_is_replayed_with_a_warning_naming_both() {
    let dir = tempfile::tempdir().unwrap();
    let report = reported(
        dir.path(),
        "old.json",
        &["run", "missions/demo.toml", "--seed", "4"],
    );
    let mut old = read(&report);
    let commit = "feedfacefeedfacefeedfacefeedfacefeedface";
    old["provenance"]["marie"]["commit"] = commit.into();
    old["provenance"]["marie"]["uncommitted_changes"] = false.into();
    std::fs::write(&report, old.to_string()).unwrap();
    let (code, stdout, stderr, _) = replay(&report);
    assert_eq!(code, Some(0), "{stdout}\n{stderr}");
    let this = text(&marie(&["--version"]).stdout);
    let this = this.trim().strip_prefix("marie ").unwrap();
    assert!(
        stderr.contains(&format!("was made by marie 0.1.0 (commit {commit})"))
            && stderr.contains(&format!("this is marie {this}")),
        "{stderr}"
    );
    assert!(stdout.contains("replay: matches the report"), "{stdout}");
}

#[test]
fn a_replay_of_what_is_not_a_report_with_provenance_is_refused_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let not_json = dir.path().join("notes.txt");
    std::fs::write(&not_json, "hello").unwrap();
    let old = dir.path().join("old.json");
    std::fs::write(
        &old,
        r#"{"mission":"m","outcome":"failed","reason":"r","status":0,"flags":[],"actions":[],"rebinds":[],"duration_ms":5}"#,
    )
    .unwrap();
    let missing = dir.path().join("missing.json");
    for (path, why) in [
        (&not_json, "is not a run report"),
        (&old, "holds no provenance"),
        (&missing, "cannot be read"),
    ] {
        let out = marie(&["run", "--replay", path.to_str().unwrap()]);
        let stderr = text(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{stderr}");
        assert!(
            stderr.contains(&format!("--replay {}: {why}", path.display())),
            "{stderr}"
        );
    }
    // a replay runs what the report holds: no mission beside it
    let out = marie(&[
        "run",
        "missions/demo.toml",
        "--replay",
        old.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
}

/// A report written before a mission's tree said `item` (its control decisions name a
/// `node`: `tests/fixtures/report-before-items.json`, written by marie at 3af314e from
/// `docking-recover.toml` in the dead-end world, seed 3, where the tree falls back once)
/// still reads: `marie diff` finds it equal to itself, and `--replay` runs it again and
/// matches it.
#[test]
fn a_report_written_before_the_tree_said_item_is_diffed_and_replayed() {
    let dir = tempfile::tempdir().unwrap();
    let fixture =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/report-before-items.json");
    let old = read(&fixture);
    assert_eq!(
        old["control"][0]["node"], "find-dock",
        "the fixture is of the old form"
    );
    let report = dir.path().join("before.json");
    std::fs::copy(&fixture, &report).unwrap();
    let same = marie(&["diff", report.to_str().unwrap(), report.to_str().unwrap()]);
    assert_eq!(same.status.code(), Some(0), "{}", text(&same.stdout));
    let (code, stdout, stderr, replayed) = replay(&report);
    assert_eq!(code, Some(0), "{stdout}\n{stderr}");
    assert!(stdout.contains("replay: matches the report"), "{stdout}");
    assert_eq!(replayed["control"][0]["item"], "find-dock", "{replayed}");
}
