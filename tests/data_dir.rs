//! Where the `marie` command keeps datamanagers' journals: nowhere for `marie run` (the
//! README's first command leaves no file), a directory per node for `marie up` — a fresh
//! one under the system's temporary directory, removed when `up` exits, or `--data-dir
//! DIR`/NODE, kept and locked: a second `up` on it is refused by its nodes, naming the
//! holder.

use crate::common;

use common::cluster::Proc;
use common::{marie, report_of, text};
use std::path::{Path, PathBuf};
use std::process::Command;

const THESIS: &str = "missions/clusters/thesis.toml";

/// The files under `dir`, recursively (directories too), relative to it.
fn files_under(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut todo = vec![dir.to_path_buf()];
    while let Some(d) = todo.pop() {
        for entry in std::fs::read_dir(&d).unwrap() {
            let path = entry.unwrap().path();
            out.push(path.strip_prefix(dir).unwrap().to_path_buf());
            if path.is_dir() {
                todo.push(path);
            }
        }
    }
    out.sort();
    out
}

#[test]
fn the_readmes_first_command_leaves_no_file() {
    let cwd = tempfile::tempdir().unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let mission = Path::new(env!("CARGO_MANIFEST_DIR")).join("missions/docking.toml");
    let out = Command::new(env!("CARGO_BIN_EXE_marie"))
        .arg("run")
        .arg(&mission)
        .current_dir(cwd.path())
        .env("TMPDIR", tmp.path())
        .env_remove("RUST_LOG")
        .output()
        .expect("marie runs");
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}\n{}",
        text(&out.stdout),
        text(&out.stderr)
    );
    assert!(text(&out.stdout).contains("outcome: succeeded"));
    assert_eq!(files_under(cwd.path()), Vec::<PathBuf>::new());
    assert_eq!(files_under(tmp.path()), Vec::<PathBuf>::new());
}

#[test]
fn up_gives_each_node_a_temporary_data_dir_and_removes_it_at_exit() {
    let mut up = Proc::spawn("marie up", &["up", THESIS]);
    up.wait_line("Ctrl-C stops the cluster");
    let base = up.tmp().join(format!("marie-up-thesis-{}", up.pid()));
    // each node its own directory, locked; the durable datamanagers' journals in them
    for node in ["cart", "features", "operations", "spare"] {
        assert!(base.join(node).join("LOCK").is_file(), "{node}");
    }
    for journal in [
        "features/dm/feature",
        "operations/dm/world",
        "operations/dm/parameter",
    ] {
        assert!(base.join(journal).is_dir(), "{journal}");
    }
    up.signal("INT");
    assert_eq!(up.wait_exit(), Some(0));
    assert!(!base.exists(), "{} is left behind", base.display());
}

#[test]
fn up_with_a_data_dir_keeps_it_and_a_second_up_on_it_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("thesis");
    let data_arg = data.to_str().unwrap();
    let mut up = Proc::spawn("marie up", &["up", THESIS, "--data-dir", data_arg]);
    up.wait_line("Ctrl-C stops the cluster");
    let temporary = up.tmp().join(format!("marie-up-thesis-{}", up.pid()));
    assert!(!temporary.exists());

    // its nodes hold their directories: another cluster's nodes on them are refused
    let second = marie(&["up", THESIS, "--data-dir", data_arg, "--speed", "4"]);
    let stderr = text(&second.stderr);
    assert_eq!(second.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains(&format!(
            "data_dir {} is in use by another marie node (pid ",
            data.join("cart").display()
        )),
        "{stderr}"
    );
    assert!(
        stderr.contains("node `cart` exited while starting"),
        "{stderr}"
    );

    up.signal("INT");
    assert_eq!(up.wait_exit(), Some(0));
    // kept, with the world's a-priori map in its journal
    let world = data.join("operations/dm/world");
    let journal: u64 = std::fs::read_dir(&world)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "log"))
        .map(|p| std::fs::metadata(p).unwrap().len())
        .sum();
    assert!(journal > 0, "{:?}", files_under(&data));
    assert!(data.join("features/dm/feature").is_dir());
}

/// `marie run --data-dir DIR`: the feature datamanager killed at 20 s of the docking mission
/// comes back with what it held — the docking spot's evidence, read back from its journal —
/// and the mission succeeds, as the same run in memory does now (its next incarnation
/// takes what it left: `dm_inherited`; it used to come back empty, and the mission failed).
/// A second run on the same directory succeeds too: the first run's epochs, numbered on an
/// earlier clock, do not fence the second's.
#[test]
fn a_run_with_a_data_dir_docks_although_its_feature_datamanager_is_killed() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    let events = dir.path().join("events.jsonl");
    let events_arg = events.display().to_string();
    let run = |data_dir: Option<&Path>| {
        let mut args = vec![
            "run",
            "missions/docking.toml",
            "--events",
            events_arg.as_str(),
            "--speed",
            "max",
            "--fault",
            "kill:feature@20",
        ];
        let d;
        if let Some(p) = data_dir {
            d = p.display().to_string();
            args.extend(["--data-dir", d.as_str()]);
        }
        marie(&args)
    };
    let out = run(None);
    assert_eq!(
        out.status.code(),
        Some(0),
        "in memory: {}",
        text(&out.stdout)
    );
    assert!(text(&out.stdout).contains("injected kill into feature"));
    let inherited = std::fs::read_to_string(&events).unwrap();
    assert!(
        inherited.contains(r#""type":"dm_inherited","dm":"feature""#),
        "{inherited}"
    );
    for attempt in ["first", "second"] {
        let out = run(Some(&data));
        let stdout = text(&out.stdout);
        assert_eq!(
            out.status.code(),
            Some(0),
            "{attempt} run with a data dir:\n{stdout}\n{}",
            text(&out.stderr)
        );
        assert!(stdout.contains("injected kill into feature"), "{stdout}");
        assert!(stdout.contains("outcome: succeeded"), "{stdout}");
        // the restarted DM said what it read back (`dm_recovered`): the records it held
        let recovered: Vec<serde_json::Value> = std::fs::read_to_string(&events)
            .unwrap()
            .lines()
            .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
            .filter(|e| e["kind"]["type"] == "dm_recovered" && e["kind"]["dm"] == "feature")
            .collect();
        assert!(
            recovered
                .iter()
                .any(|e| e["kind"]["records"].as_u64() > Some(0) && e["kind"]["torn"].is_null()),
            "{attempt}: {recovered:?}"
        );
    }
    let journal = files_under(&data);
    assert!(
        journal.contains(&PathBuf::from("dm/feature/00000000000000000001.log")),
        "{journal:?}"
    );
}

/// The check of the datamanagers at a run's end looks every acknowledged record up: the
/// world datamanager killed 20 s into a run in memory comes back with what it held (its
/// heir: it used to come back empty but for the map, and the check counted its wall, pose
/// and search records lost — counting a loss is `marie_dm`'s `dm_heir` test now), and the
/// same run with a data directory reads them back from its journal: none lost either way,
/// the report and the verdict say so.
#[test]
fn the_check_finds_every_record_of_a_killed_datamanager_in_memory_and_with_a_journal() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data").display().to_string();
    let events = dir.path().join("events.jsonl");
    let events_arg = events.display().to_string();
    let world_check = |report: &serde_json::Value| {
        let checks = report["dm_checks"]
            .as_array()
            .expect("the datamanagers checked");
        let names: Vec<&str> = checks.iter().map(|c| c["dm"].as_str().unwrap()).collect();
        assert_eq!(names, ["feature", "parameter", "world"], "{checks:?}");
        checks[2].clone()
    };
    let (out, report) = report_of(&[
        "run",
        "missions/docking.toml",
        "--fault",
        "kill:world@20",
        "--events",
        &events_arg,
    ]);
    let stdout = text(&out.stdout);
    assert_eq!(out.status.code(), Some(0), "{stdout}");
    let world = world_check(&report);
    let acknowledged = world["acknowledged"].as_u64().unwrap();
    // what was stored before the kill is there, and what was stored after it
    assert!(acknowledged > 100, "{world}");
    assert_eq!(world["held"], acknowledged, "{world}");
    assert_eq!(world["lost"], 0, "{world}");
    assert_eq!(world["node"], "embedded");
    assert_eq!(report["acknowledged_lost"], 0, "{report}");
    let all: u64 = report["dm_checks"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["acknowledged"].as_u64().unwrap())
        .sum();
    assert!(
        stdout.contains(&format!("0 of {all} acknowledged records lost, ")),
        "the verdict: {stdout}"
    );
    // the events file holds the acknowledgements the check looked up, and its result
    let lines: Vec<serde_json::Value> = std::fs::read_to_string(&events)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let acked = lines
        .iter()
        .filter(|e| e["kind"]["type"] == "dm_acked" && e["kind"]["dm"] == "world")
        .count() as u64;
    assert_eq!(acked, acknowledged);
    assert!(lines.iter().any(|e| e["kind"]["type"] == "dm_checked"
        && e["kind"]["dm"] == "world"
        && e["kind"]["held"] == acknowledged));

    let (out, report) = report_of(&[
        "run",
        "missions/docking.toml",
        "--fault",
        "kill:world@20",
        "--data-dir",
        &data,
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stdout));
    let world = world_check(&report);
    assert!(world["acknowledged"].as_u64().unwrap() > 100, "{world}");
    assert_eq!(world["held"], world["acknowledged"], "{world}");
    assert_eq!(report["acknowledged_lost"], 0);
    let all: u64 = report["dm_checks"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["acknowledged"].as_u64().unwrap())
        .sum();
    let verdict = format!("0 of {all} acknowledged records lost");
    assert!(
        text(&out.stdout).contains(&verdict),
        "{}",
        text(&out.stdout)
    );
}

/// `--chaos SEED --chaos-dms`: the datamanagers are among chaos's victims. Seed 4 kills
/// `feature` twice and `parameter` twice among the operations; with a data dir each comes
/// back with its records and the mission docks.
#[test]
fn chaos_with_datamanagers_and_a_data_dir_still_docks() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data").display().to_string();
    let (out, report) = report_of(&[
        "run",
        "missions/docking.toml",
        "--chaos",
        "4",
        "--chaos-dms",
        "--data-dir",
        &data,
    ]);
    let stdout = text(&out.stdout);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{stdout}\n{}",
        text(&out.stderr)
    );
    let hit: Vec<&str> = report["faults"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["operation"].as_str().unwrap())
        .collect();
    for dm in ["feature", "parameter"] {
        assert!(hit.contains(&dm), "{dm} among {hit:?}");
    }
    assert!(hit.len() > 4, "operations too: {hit:?}");
    // the killed datamanagers came back with every record they acknowledged
    assert_eq!(report["acknowledged_lost"], 0, "{:?}", report["dm_checks"]);
}

/// A run that starts on an existing data directory tells what each datamanager read back
/// (`dm_recovered`: records, bytes, a torn end if any) as the run begins — they were read
/// at the node's start, before the run listened, and used to be told to no one — and the
/// report says it (`dm_recoveries`).
#[test]
fn a_run_on_an_existing_data_dir_tells_what_its_datamanagers_read_back() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data").display().to_string();
    let events = dir.path().join("events.jsonl");
    let events_arg = events.display().to_string();
    let run = || {
        report_of(&[
            "run",
            "missions/docking.toml",
            "--speed",
            "max",
            "--data-dir",
            &data,
            "--events",
            &events_arg,
        ])
    };
    let (first, _) = run();
    assert_eq!(first.status.code(), Some(0), "{}", text(&first.stdout));
    let (out, report) = run();
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stdout));
    let lines: Vec<serde_json::Value> = std::fs::read_to_string(&events)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let started = lines
        .iter()
        .position(|e| e["kind"]["type"] == "run_started")
        .expect("run_started");
    let recovered: Vec<&serde_json::Value> = lines
        .iter()
        .filter(|e| e["kind"]["type"] == "dm_recovered")
        .map(|e| &e["kind"])
        .collect();
    let names: Vec<&str> = recovered
        .iter()
        .map(|k| k["dm"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["feature", "parameter", "world"], "{recovered:?}");
    for k in &recovered {
        assert!(k["records"].as_u64() > Some(0), "{k}");
        assert!(k["bytes"].as_u64() > Some(0), "{k}");
        assert!(k["torn"].is_null(), "{k}");
    }
    // told once each, as the run begins
    assert!(
        lines
            .iter()
            .take(started)
            .filter(|e| e["kind"]["type"] == "dm_recovered")
            .count()
            == 3
    );
    let folded = report["dm_recoveries"].as_array().expect("dm_recoveries");
    assert_eq!(folded.len(), 3, "{folded:?}");
    for (r, k) in folded.iter().zip(&recovered) {
        assert_eq!((&r["dm"], &r["records"]), (&k["dm"], &k["records"]));
        assert_eq!(
            (&r["from"], &r["node"]),
            (&"journal".into(), &"embedded".into())
        );
    }
}

/// A run on a data directory another process holds is bad input (exit 2), said once,
/// naming the directory and the holder's pid; so is a `--data-dir` that is a file.
#[test]
fn a_data_dir_held_by_another_run_or_that_is_a_file_is_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    let data_arg = data.to_str().unwrap();
    // a slow run holds the directory while the second one starts
    let mut holder = Proc::spawn(
        "marie run",
        &[
            "run",
            "missions/docking.toml",
            "--data-dir",
            data_arg,
            "--speed",
            "0.1",
        ],
    );
    holder.wait_line("mission `docking`");
    let out = marie(&["run", "missions/docking.toml", "--data-dir", data_arg]);
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert_eq!(
        stderr.trim_end(),
        format!(
            "marie: data_dir {data_arg} is in use by another marie node (pid {}): one node per \
             data_dir (stop that node, or give this one another data_dir)",
            holder.pid()
        )
    );
    drop(holder);

    let file = dir.path().join("a-file");
    std::fs::write(&file, "not a directory").unwrap();
    for path in [file.clone(), file.join("below")] {
        let path = path.display().to_string();
        let out = marie(&["run", "missions/docking.toml", "--data-dir", &path]);
        let stderr = text(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{stderr}");
        assert_eq!(
            stderr.trim_end(),
            format!(
                "marie: data_dir {path}: it is a file, not a directory (give a directory, or a \
                 path that does not exist yet)"
            )
        );
    }
}
