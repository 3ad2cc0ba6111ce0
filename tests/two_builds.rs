//! Two real builds side by side (issue 44, point 5): this build's `marie` and the next
//! build's, `marie-next` (feature `next-protocol`: protocol 2..=3, a field of protocol 3 in
//! the `joined` event, one more optional field in the followed wall's record, the wall
//! follower's version 1.2.0-rc.1; built by `scripts/build-next` or once by the first test
//! that asks, `common::next_build`).
//!
//! - The gate: the next build checks the corpus of version 2 (`compat/v2`) clean, and its
//!   own corpus differs from it by additions only; a corpus of a version a build does not
//!   speak is refused by it, either way round.
//! - A cluster: the thesis layout of this build docks, and a node of the next build joins
//!   mid-docking hosting the newer wall follower — as a node restarted with the new binary
//!   would. It agrees on protocol 2 with every node, the binding moves to its wall follower
//!   at the next action's start, nothing it sends fails to decode on this build's side
//!   (its `joined` events reach the run's watcher at version 2, without the field of 3),
//!   and the run docks with no acknowledged record lost. A third build that speaks 4 alone
//!   is refused at the handshake while the run goes on.

use crate::common;
use crate::compat::copy;
use crate::selection_cluster::{layout, COOKIE};
use crate::upgrade_cluster::{docked_on, docking_twice};

use common::cluster::{NodeProc, Proc};
use common::next_build::marie_next;
use common::{marie, text};
use serde_json::Value;
use std::net::SocketAddr;
use std::path::Path;
use std::process::Command;

/// The wall follower's version in the next build (`missions/src/ops/motion/wall_follower/next.rs`).
const NEXT: &str = "1.2.0-rc.1";

/// The cluster's speed: `follow-wall` takes about 12 s of wall time at 3 — ample for a
/// node to start and join while it runs, on a loaded machine.
const SPEED: &str = "3";

/// What a node or a run says when a frame or message of a peer does not decode, or is of
/// a version it does not speak: none may appear while two builds work side by side.
const DECODE_WARNINGS: [&str; 4] = [
    "does not decode",
    "unknown cast variant",
    "unknown call variant",
    "frame of protocol version",
];

/// `marie-next ARGS` from the package root.
fn next(args: &[&str]) -> std::process::Output {
    Command::new(marie_next())
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env_remove("RUST_LOG")
        .output()
        .expect("marie-next runs")
}

fn corpus_v2() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("compat/v2")
}

#[test]
fn the_next_build_reads_the_corpus_of_2_and_its_own_adds_fields_only() {
    let out = next(&["compat", "check", corpus_v2().to_str().unwrap()]);
    let said = text(&out.stdout);
    assert_eq!(out.status.code(), Some(0), "{said}{}", text(&out.stderr));
    assert!(said.contains(", 0 broken"), "{said}");
    assert!(!said.contains("BROKEN"), "{said}");

    let dir = tempfile::tempdir().unwrap();
    let mine = dir.path().join("v3");
    let out = next(&["compat", "write", mine.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    assert!(
        text(&out.stdout).contains("(protocol 3)"),
        "{}",
        text(&out.stdout)
    );

    // this build's diff of the two: every sample the same, or with fields added
    let out = marie(&[
        "compat",
        "diff",
        corpus_v2().to_str().unwrap(),
        mine.to_str().unwrap(),
    ]);
    let diff = text(&out.stdout);
    assert_eq!(out.status.code(), Some(1), "they differ: {diff}");
    for line in diff.lines() {
        let ok = line.starts_with("same ")
            || line.starts_with("new ")
            || line.contains("samples differ")
            || (line.starts_with("changed ")
                && line
                    .split_once(": ")
                    .is_some_and(|(_, c)| c.split("; ").all(|c| c.ends_with(" is new"))));
        assert!(ok, "not an addition: {line}\n{diff}");
    }
    // protocol 3's field in the `joined` event of the demo run
    assert!(
        diff.lines()
            .any(|l| l.starts_with("changed ") && l.contains("speaks` is new")),
        "{diff}"
    );
    assert!(
        diff.contains("protocol 2) →") && diff.contains("protocol 3):"),
        "{diff}"
    );
}

#[test]
fn a_corpus_of_a_version_a_build_does_not_speak_is_refused_either_way_round() {
    let dir = tempfile::tempdir().unwrap();
    // a third build's corpus, of version 4 alone: refused by both
    let far = dir.path().join("v4");
    copy(&corpus_v2(), &far);
    let manifest = far.join("manifest.toml");
    let m = std::fs::read_to_string(&manifest).unwrap();
    assert!(m.contains("\nprotocol = 2\n"), "{m}");
    std::fs::write(&manifest, m.replace("\nprotocol = 2\n", "\nprotocol = 4\n")).unwrap();
    let out = marie(&["compat", "check", far.to_str().unwrap()]);
    let err = text(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}{}", text(&out.stdout));
    assert!(
        err.contains("is a corpus of protocol version 4")
            && err.contains("this build speaks protocol version 2")
            && err.contains("refuse each other at the handshake"),
        "{err}"
    );
    assert!(text(&out.stdout).is_empty(), "no sample read");
    let out = next(&["compat", "check", far.to_str().unwrap()]);
    let err = text(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("this build speaks protocol versions 2..=3"),
        "{err}"
    );

    // the next build's corpus, of 3: the build before refuses it, never misreads it
    let mine = dir.path().join("v3");
    let out = next(&["compat", "write", mine.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let out = marie(&["compat", "check", mine.to_str().unwrap()]);
    let err = text(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("is a corpus of protocol version 3"), "{err}");
}

/// Every line `lines` holds that warns of a frame that does not decode.
fn decode_warnings(lines: &[String]) -> Vec<String> {
    lines
        .iter()
        .filter(|l| DECODE_WARNINGS.iter().any(|w| l.contains(w)))
        .cloned()
        .collect()
}

#[test]
fn a_node_of_the_next_build_joins_mid_docking_and_its_wall_follower_takes_over() {
    let next_exe = marie_next();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // the thesis layout of this build, the wall follower 1.0.0 on a node of its own
    let cluster = layout(d, &[("wf-one", "1")]);
    let mut up = Proc::spawn(
        "marie up",
        &["up", cluster.to_str().unwrap(), "--speed", SPEED],
    );
    up.wait_line("Ctrl-C stops the cluster");
    let join = up
        .seen()
        .iter()
        .find_map(|l| {
            let rest = l.trim().strip_prefix("cart at ")?;
            Some(rest.split_once(' ')?.0.to_string())
        })
        .expect("the cart node's address");
    let join_addr: SocketAddr = join.parse().unwrap();

    let mission = docking_twice(d, "docking-twice", "");
    let report = d.join("report.json");
    let events = d.join("events.jsonl");
    let mut run = Proc::spawn(
        "marie run",
        &[
            "run",
            mission.to_str().unwrap(),
            "--join",
            &join,
            "--cookie",
            COOKIE,
            "--speed",
            SPEED,
            "--report",
            report.to_str().unwrap(),
            "--events",
            events.to_str().unwrap(),
        ],
    );
    run.wait_line("> follow-wall: start");

    // a node of the next build joins while version 1.0.0 follows the wall
    let hosts = format!(
        "dispatcher = false\n[[operation]]\nname = \"wall-follower\"\nversion = \"={NEXT}\"\n"
    );
    let mut wf_next =
        NodeProc::start_exe(next_exe, d, "wf-next", &hosts, &[join_addr], COOKIE, &[]);
    let upgraded = run.wait_line("wall-follower upgraded at `plan-parking`");
    assert!(
        upgraded.contains(&format!("v{NEXT}")) && upgraded.contains("on wf-next"),
        "{upgraded}"
    );

    // it agreed on 2 with every node: `ls` of this build says so
    let out = marie(&["ls", "--join", &join, "--cookie", COOKIE]);
    let ls = text(&out.stdout);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(
        ls.lines()
            .any(|l| l.starts_with("node wf-next: protocol 2 (speaks 2..=3), build ")),
        "{ls}"
    );

    // a third build, of protocol 4 alone, is refused at the handshake
    let mut far = NodeProc::start_with(
        d,
        "far",
        "[[operation]]\nname = \"sampler\"\n",
        &[join_addr],
        COOKIE,
        "",
        &["--protocol-range", "4-4"],
    );
    let refused = far.wait_line("node far refused ");
    assert!(
        refused.contains("it speaks protocol version 2")
            && refused.contains("this node speaks protocol version 4"),
        "{refused}"
    );

    // the run docks on, with the next build's wall follower
    let report = docked_on(&mut run, &report, [("1.0.0", "wf-one"), (NEXT, "wf-next")]);
    assert_eq!(report["acknowledged_lost"], 0, "{}", report["dm_checks"]);
    let upgrades = report["upgrades"].as_array().expect("an upgrades section");
    assert_eq!(upgrades.len(), 1, "{upgrades:#?}");
    assert_eq!(
        (&upgrades[0]["to_version"], &upgrades[0]["to_node"]),
        (&Value::from(NEXT), &Value::from("wf-next")),
        "{upgrades:#?}"
    );

    // nothing failed to decode on either side: the run (this build's watcher of the next
    // build's events), the cluster of this build, the next build's node
    let mut said: Vec<String> = run.drain().to_vec();
    said.extend(run.stderr_tail().lines().map(str::to_string));
    said.extend(up.drain().iter().cloned());
    said.extend(up.stderr_tail().lines().map(str::to_string));
    said.extend(wf_next.drain().iter().cloned());
    said.extend(wf_next.stderr_tail().lines().map(str::to_string));
    let warnings = decode_warnings(&said);
    assert!(warnings.is_empty(), "{warnings:#?}");
    // the refusal reached the run's events, naming both ranges
    let events = std::fs::read_to_string(&events).unwrap();
    let refused: Vec<Value> = events
        .lines()
        .filter_map(|l| serde_json::from_str::<Value>(l).ok())
        .filter(|e| e["kind"]["type"] == "node_refused" && e["kind"]["peer"] == "far")
        .collect();
    assert!(
        !refused.is_empty(),
        "no node_refused of far in the run's events"
    );
    for e in &refused {
        let k = &e["kind"];
        assert_eq!(
            k["theirs_speak"],
            serde_json::json!({"oldest": 4, "newest": 4}),
            "{e}"
        );
        // what the refusing node speaks: 2 alone, or 2..=3 when the next build's node
        // refused it too (far's dials reach every node it learns of)
        let ours = if e["node"] == "wf-next" { 3 } else { 2 };
        assert_eq!(
            k["ours_speak"],
            serde_json::json!({"oldest": 2, "newest": ours}),
            "{e}"
        );
    }

    // the cluster keeps running after the refusal: the next build's node and the refused
    // one are alive, and `ls` still lists the next build's wall follower, not `far`'s sampler
    assert!(wf_next.alive() && far.alive());
    let out = marie(&["ls", "--join", &join, "--cookie", COOKIE]);
    let ls = text(&out.stdout);
    assert!(
        ls.contains("wall-follower") && ls.contains("wf-next"),
        "{ls}"
    );
    assert!(!ls.contains("far"), "{ls}");
}
