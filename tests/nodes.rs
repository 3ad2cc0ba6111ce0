//! `marie run --node FILE`: a node hosts exactly what its config says — the shipped node
//! configs of `missions/nodes/`, and a bad config's `file:line:col` diagnostics.

use crate::common;

use common::{marie, report_of, text};

/// The versions of `op` the report's actions ran.
fn versions_of(report: &serde_json::Value, op: &str) -> Vec<String> {
    let mut out: Vec<String> = report["actions"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|a| a["operations"].as_array().unwrap().iter())
        .filter(|o| o["name"] == op)
        .map(|o| o["version"].as_str().unwrap().to_string())
        .collect();
    out.dedup();
    out
}

#[test]
fn a_node_with_version_1_of_the_wall_follower_only_binds_version_1() {
    let (out, json) = report_of(&[
        "run",
        "missions/docking.toml",
        "--node",
        "missions/nodes/v1-only.toml",
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    assert_eq!(json["outcome"], "succeeded", "{json}");
    assert_eq!(versions_of(&json, "wall-follower"), ["1.0.0"]);
    let ls = text(&marie(&["ls", "--node", "missions/nodes/v1-only.toml"]).stdout);
    assert_eq!(ls.matches("name: wall-follower").count(), 1, "{ls}");
}

#[test]
fn a_node_without_a_spare_heals_a_killed_operation_by_restarting_it() {
    let (out, json) = report_of(&[
        "run",
        "missions/docking.toml",
        "--node",
        "missions/nodes/no-spare.toml",
        "--fault",
        "kill:wall-follower@20",
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stdout));
    assert_eq!(json["outcome"], "succeeded", "{json}");
    let rebinds = json["rebinds"].as_array().unwrap();
    assert_eq!(rebinds.len(), 1, "{json}");
    assert_eq!(rebinds[0]["operation"], "wall-follower");
    let ls = text(&marie(&["ls", "--node", "missions/nodes/no-spare.toml"]).stdout);
    assert_eq!(
        ls.matches("name: wall-follower").count(),
        2,
        "one per version: {ls}"
    );
}

#[test]
fn a_node_with_two_instances_hosts_both_and_survives_a_kill() {
    let ls = text(&marie(&["ls", "--node", "missions/nodes/everything.toml"]).stdout);
    assert_eq!(
        ls.matches("name: wall-follower").count(),
        4,
        "two of each version: {ls}"
    );
    let (out, json) = report_of(&[
        "run",
        "missions/docking.toml",
        "--node",
        "missions/nodes/everything.toml",
        "--fault",
        "kill:wall-follower@20",
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stdout));
    assert_eq!(json["outcome"], "succeeded", "{json}");
    assert_eq!(json["rebinds"].as_array().unwrap().len(), 1, "{json}");
}

#[test]
fn a_node_that_does_not_host_an_operation_the_mission_needs_refuses_it() {
    let dir = tempfile::tempdir().unwrap();
    let node = dir.path().join("demo-only.toml");
    std::fs::write(
        &node,
        "[node]\nname = \"demo-only\"\n\n[[datamanager]]\nname = \"feature\"\n\
         [[datamanager]]\nname = \"parameter\"\n[[datamanager]]\nname = \"world\"\n\n\
         [[operation]]\nname = \"sampler\"\n[[operation]]\nname = \"averager\"\n\
         [[operation]]\nname = \"checker\"\n",
    )
    .unwrap();
    let node = node.to_str().unwrap();
    // the demo runs on it
    let out = marie(&["run", "missions/demo.toml", "--node", node]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    // the docking mission needs operations it does not host, and no robot runs on it
    let out = marie(&["run", "missions/docking.toml", "--node", node]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
    let err = text(&out.stderr);
    assert!(err.contains("missions/docking.toml:"), "{err}");
    assert!(err.contains("wall-follower"), "{err}");
}

/// Each kind of bad node config gives its `file:line:col` and exit 2.
#[test]
fn each_bad_node_config_names_its_file_line_and_column() {
    let cases: &[(&str, &str)] = &[
        ("[node]\nname = \"\"\n", ":2:8: `name` must not be empty"),
        (
            "[nodes]\nname = \"x\"\n",
            ":1:2: unknown key `nodes` in the node config",
        ),
        (
            "[node]\nname = \"x\"\ncolour = 1\n",
            ":3:1: unknown key `colour` in [node]",
        ),
        (
            "[node]\nname = \"x\"\ndispatcher = \"yes\"\n",
            ":3:14: `yes` is not a dispatcher role: active or standby (or true, false)",
        ),
        (
            "[node]\nname = \"x\"\ndispatcher = 3\n",
            ":3:14: expected true or false for `dispatcher`",
        ),
        (
            "[node]\nname = \"x\"\n[[operation]]\nname = \"wall-folower\"\n",
            ":4:8: this node cannot host operation `wall-folower`",
        ),
        (
            "[node]\nname = \"x\"\n[[operation]]\nname = \"wall-follower\"\nversion = \"3\"\n",
            ":5:11: no version of `wall-follower` matches `^3` (available: 1.0.0, 1.1.0-rc.1, 2.0.0)",
        ),
        (
            "[node]\nname = \"x\"\n[[operation]]\nname = \"sampler\"\nversion = \"one\"\n",
            ":5:11: `version` must be a semver requirement",
        ),
        (
            "[node]\nname = \"x\"\n[[operation]]\nname = \"sampler\"\ninstances = 65\n",
            ":5:13: `instances` must be an integer in [0, 64], found 65",
        ),
        (
            "[node]\nname = \"x\"\n[[operation]]\nname = \"sampler\"\ninstances = 1.5\n",
            ":5:13: expected an integer for `instances`, found float",
        ),
        (
            "[node]\nname = \"x\"\n[[operation]]\nname = \"sampler\"\nsupervisor = \"fast\"\n",
            ":5:14: no supervisor `fast` is declared (expected one of: operations)",
        ),
        (
            "[node]\nname = \"x\"\n[[operation]]\nname = \"sampler\"\nrestart = \"often\"\n",
            ":5:11: unknown restart `often`",
        ),
        (
            "[node]\nname = \"x\"\n[[supervisor]]\nname = \"s\"\nstrategy = \"all\"\n",
            ":5:12: unknown strategy `all`",
        ),
        (
            "[node]\nname = \"x\"\n[[supervisor]]\nname = \"s\"\nperiod_s = 0\n",
            ":5:12: `period_s` must be in (0, 86400], found 0",
        ),
        (
            "[node]\nname = \"x\"\n[[supervisor]]\nname = \"s\"\n[[supervisor]]\nname = \"s\"\n",
            ":5:1: supervisor `s` is declared twice",
        ),
        (
            "[node]\nname = \"x\"\n[[datamanager]]\nname = \"cache\"\n",
            ":3:1: datamanager `cache` is not one of feature, parameter, world, run: it needs an `id`",
        ),
        (
            "[node]\nname = \"x\"\n[simulation]\nseed = -1\n",
            ":4:8: `seed` must be an integer in [0, 9223372036854775807], found -1",
        ),
        (
            "[node]\nname = \"x\"\n[simulation]\nworld = \"nowhere.toml\"\n",
            ":4:9: the world named here does not load:",
        ),
        ("[node\nname = \"x\"\n", ":1:6: syntax error"),
    ];
    let dir = tempfile::tempdir().unwrap();
    for (i, (config, want)) in cases.iter().enumerate() {
        let path = dir.path().join(format!("bad-{i}.toml"));
        std::fs::write(&path, config).unwrap();
        let path = path.to_str().unwrap();
        let out = marie(&["run", "missions/demo.toml", "--node", path]);
        let err = text(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "case {i}: {err}");
        assert!(
            err.contains(&format!("{path}{want}")),
            "case {i}: expected `{path}{want}` in:\n{err}"
        );
        assert!(!err.contains("panicked"), "case {i}: {err}");
    }
}

#[test]
fn a_node_config_that_is_not_a_regular_file_is_refused_unread() {
    let out = marie(&["run", "missions/demo.toml", "--node", "/dev/zero"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(text(&out.stderr).contains("not a regular file"));
    let out = marie(&["run", "missions/demo.toml", "--node", "missions"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(text(&out.stderr).contains("not a regular file (a directory)"));
}

#[test]
fn a_node_config_with_a_cluster_table_is_refused_by_a_command_that_runs_its_own_node() {
    // `run`, `check`, `ls` run a node of their own in their process: a [cluster] table is
    // refused (exit 2, pointing at `marie node`), neither ignored nor joined
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("member.toml");
    std::fs::write(
        &path,
        "[node]\nname = \"member\"\n[[operation]]\nname = \"sampler\"\n\
         [cluster]\nlisten = \"127.0.0.1:0\"\ncookie = \"c\"\n",
    )
    .unwrap();
    let path = path.to_str().unwrap();
    for args in [
        vec!["run", "missions/demo.toml", "--node", path],
        vec!["check", "missions/demo.toml", "--node", path],
        vec!["ls", "--node", path],
    ] {
        let out = marie(&args);
        let err = text(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(
            err.contains(path)
                && err.contains("[cluster] table")
                && err.contains("marie node --config"),
            "{args:?}: {err}"
        );
    }
}
