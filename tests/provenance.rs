//! Every run says exactly what ran (issue 25): the build it was made by, the command line,
//! the files it read with their SHA-256 and text, the nodes and their builds — a node of
//! another commit named —, the seed and speed, and every parameter value with its source;
//! the events file's first line and the report's `provenance` section.

use crate::common;

use common::cluster::NodeProc;
use common::{marie, text};
use serde_json::Value;
use std::path::Path;

/// `0.1.0 (commit …)` as `marie --version` says it: this build.
fn this_build() -> String {
    let out = marie(&["--version"]);
    text(&out.stdout)
        .trim()
        .strip_prefix("marie ")
        .expect("`marie VERSION`")
        .to_string()
}

/// This build's commit (`None` outside a checkout).
fn this_commit() -> Option<String> {
    let build = this_build();
    let rest = build.split_once("(commit ")?.1;
    let commit: String = rest.chars().take_while(char::is_ascii_hexdigit).collect();
    (commit.len() == 40).then_some(commit)
}

fn sha256(bytes: &[u8]) -> String {
    let digest = aws_lc_rs::digest::digest(&aws_lc_rs::digest::SHA256, bytes);
    digest.as_ref().iter().map(|b| format!("{b:02x}")).collect()
}

#[test]
fn a_runs_report_and_events_file_begin_with_what_ran() {
    let dir = tempfile::tempdir().unwrap();
    let (report, events) = (dir.path().join("r.json"), dir.path().join("e.jsonl"));
    let args = [
        "run",
        "missions/docking.toml",
        "--node",
        "missions/nodes/everything.toml",
        "--seed",
        "5",
        "--report",
        report.to_str().unwrap(),
        "--events",
        events.to_str().unwrap(),
    ];
    let out = marie(&args);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let report: Value = serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let p = &report["provenance"];

    // the events file's first line is the same provenance, parameters aside
    let lines = std::fs::read_to_string(&events).unwrap();
    let first: Value = serde_json::from_str(lines.lines().next().unwrap()).unwrap();
    assert_eq!(first["kind"]["type"], "provenance", "{first}");
    for key in [
        "marie", "command", "started", "files", "nodes", "seed", "speed",
    ] {
        assert_eq!(first["kind"][key], p[key], "{key}");
    }

    // the build, as `--version` says it
    let build = this_build();
    assert!(
        build.starts_with(p["marie"]["version"].as_str().unwrap()),
        "{build} vs {p}"
    );
    assert_eq!(
        p["marie"]["commit"].as_str().map(str::to_string),
        this_commit()
    );
    // the command line, the start time, the seed and speed
    let command: Vec<&str> = p["command"]
        .as_array()
        .unwrap()
        .iter()
        .map(|a| a.as_str().unwrap())
        .collect();
    assert_eq!(&command[1..], &args, "{command:?}");
    assert!(p["started"].as_str().unwrap().ends_with('Z'), "{p}");
    assert!(p["started_unix_ms"].as_u64().unwrap() > 1_700_000_000_000);
    assert_eq!(p["seed"], 5);
    assert_eq!(p["speed"], "max");
    // every file read, with its SHA-256 and its text
    let files = p["files"].as_array().unwrap();
    let read: Vec<(&str, &str)> = files
        .iter()
        .map(|f| (f["role"].as_str().unwrap(), f["path"].as_str().unwrap()))
        .collect();
    assert_eq!(
        read,
        [
            ("mission", "missions/docking.toml"),
            ("world", "missions/worlds/lab.toml"),
            ("node", "missions/nodes/everything.toml"),
        ]
    );
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for f in files {
        let bytes = std::fs::read(root.join(f["path"].as_str().unwrap())).unwrap();
        assert_eq!(
            f["sha256"].as_str().unwrap(),
            sha256(&bytes),
            "{}",
            f["path"]
        );
        assert_eq!(f["text"].as_str().unwrap().as_bytes(), bytes.as_slice());
    }
    // the node and its build
    assert_eq!(
        p["nodes"][0]["node"], "everything",
        "the node config's name: {p}"
    );
    assert_eq!(p["nodes"][0]["marie"], p["marie"]);
    // every parameter each operation ran with, and where it came from: the mission's
    // `window = 20.0` of the segment extractor in find-wall, the defaults it left out
    let params = p["parameters"].as_array().unwrap();
    let find = |action: &str, op: &str, name: &str| {
        params
            .iter()
            .find(|s| s["action"] == action && s["operation"] == op && s["name"] == name)
            .unwrap_or_else(|| panic!("no {action}/{op}.{name} in {params:?}"))
    };
    let window = find("find-wall", "segment-extractor", "window");
    assert_eq!(window["source"], "mission");
    assert_eq!(window["value"]["Float"], 20.0);
    assert_eq!(
        find("find-wall", "ultrasonic", "min_range")["source"],
        "default"
    );
    // every operation of every action that ran is there
    for action in report["actions"].as_array().unwrap() {
        for op in action["operations"].as_array().unwrap() {
            assert!(
                params
                    .iter()
                    .any(|s| s["action"] == action["name"] && s["operation"] == op["name"]),
                "{} / {}",
                action["name"],
                op["name"]
            );
        }
    }
}

const COOKIE: &str = "provenance";
const ALPHA_HOSTS: &str =
    "[[datamanager]]\nname = \"feature\"\n[[datamanager]]\nname = \"world\"\n\
     [[operation]]\nname = \"sampler\"\n[[operation]]\nname = \"averager\"\n\
     [[operation]]\nname = \"checker\"\n";
const OLD_HOSTS: &str = "[[datamanager]]\nname = \"parameter\"\n";
/// The commit the old node claims to be built from.
const OLD_COMMIT: &str = "0123456789abcdef0123456789abcdef01234567";

#[test]
fn a_cluster_runs_provenance_names_every_node_and_a_node_of_another_commit() {
    let dir = tempfile::tempdir().unwrap();
    let mut alpha = NodeProc::start(dir.path(), "alpha", ALPHA_HOSTS, &[], COOKIE);
    let mut old = NodeProc::start_with(
        dir.path(),
        "old",
        OLD_HOSTS,
        &[alpha.addr],
        COOKIE,
        "",
        &["--claim-commit", OLD_COMMIT],
    );
    old.wait_line("node old sees alpha");
    alpha.wait_line("node alpha sees old");
    let report = dir.path().join("r.json");
    let out = marie(&[
        "run",
        "missions/demo.toml",
        "--join",
        &alpha.addr.to_string(),
        "--cookie",
        COOKIE,
        "--report",
        report.to_str().unwrap(),
    ]);
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    // named as the run starts, beside this build
    let build = this_build();
    assert!(
        stderr.contains(&format!(
            "warning: node `old` runs marie 0.1.0 (commit {OLD_COMMIT})"
        )) && stderr.contains(&format!("this is marie {build}")),
        "{stderr}"
    );
    assert!(!stderr.contains("node `alpha` runs"), "{stderr}");
    let report: Value = serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let nodes = report["provenance"]["nodes"].as_array().unwrap();
    let named: Vec<(&str, Option<&str>)> = nodes
        .iter()
        .map(|n| (n["node"].as_str().unwrap(), n["marie"]["commit"].as_str()))
        .collect();
    // the run's own member first, then its peers by name
    assert_eq!(named.len(), 3, "{named:?}");
    assert_eq!(named[1].0, "alpha");
    assert_eq!(named[1].1.map(str::to_string), this_commit());
    assert_eq!(named[2], ("old", Some(OLD_COMMIT)));
    assert_eq!(report["provenance"]["speed"], "1", "a cluster's factor");
    for node in [&mut alpha, &mut old] {
        node.signal("TERM");
        assert_eq!(node.wait_exit(), Some(0));
    }
}
