//! `marie up`: the thesis' layout (`missions/clusters/thesis.toml`) as real processes on
//! 127.0.0.1 — its consistency experiment (the docking mission with the dispatcher on a
//! process of its own), the converged registry listed by `ls --join`, and no node left
//! running when `marie up` is killed.

use crate::common;

use common::cluster::{ls_join, ls_join_rows, node_line, signal_pid, wait_gone, Proc};
use common::layouts::thesis_with;
use common::monitor::page_of;
use common::{marie, report_of, text};
use std::collections::BTreeSet;
use std::io::Write;

const THESIS: &str = "missions/clusters/thesis.toml";
/// The cluster's speed factor in these tests: wall-clock time × 4, on every node.
const SPEED: &str = "4";

#[test]
fn the_thesis_layout_docks_with_the_dispatcher_on_a_process_of_its_own() {
    let (out, report) = report_of(&[
        "up",
        THESIS,
        "--run",
        "missions/docking.toml",
        "--speed",
        SPEED,
    ]);
    let stdout = text(&out.stdout);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{stdout}\n{}",
        text(&out.stderr)
    );
    // 24 modules and the run datamanager's leader and the active and standby desks
    assert!(stdout.contains("4 nodes, 27 modules"), "{stdout}");
    assert!(
        stdout.contains("the run is dispatched on features, standby on spare"),
        "{stdout}"
    );
    assert!(stdout.contains("outcome: succeeded"), "{stdout}");
    assert!(stdout.contains("cluster stopped"), "{stdout}");
    assert_eq!(report["outcome"], "succeeded");
    assert_eq!(report["collisions"], 0);
    // its provenance: every file `up` and the run read, every node with its build
    let p = &report["provenance"];
    let files: Vec<(&str, &str)> = p["files"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| (f["role"].as_str().unwrap(), f["path"].as_str().unwrap()))
        .collect();
    assert_eq!(files[0], ("mission", "missions/docking.toml"), "{files:?}");
    assert_eq!(files[1].0, "world", "{files:?}");
    assert_eq!(files[2], ("cluster", THESIS), "{files:?}");
    let configs: Vec<&str> = files[3..]
        .iter()
        .map(|(role, path)| {
            assert_eq!(*role, "node", "{files:?}");
            *path
        })
        .collect();
    assert_eq!(configs.len(), 4, "{files:?}");
    assert!(
        configs
            .iter()
            .all(|c| c.contains("missions/clusters/thesis/")),
        "{files:?}"
    );
    let nodes: BTreeSet<&str> = p["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| {
            assert_eq!(n["marie"], p["marie"], "every node runs this build: {n}");
            n["node"].as_str().unwrap()
        })
        .collect();
    for node in ["cart", "features", "operations", "spare"] {
        assert!(nodes.contains(node), "{node}: {nodes:?}");
    }
    assert_eq!(p["speed"], SPEED);
    // every operation ran where the layout put it, none on the dispatcher's process
    let mut placed = BTreeSet::new();
    for action in report["actions"].as_array().unwrap() {
        for op in action["operations"].as_array().unwrap() {
            placed.insert((
                op["name"].as_str().unwrap().to_string(),
                op["node"].as_str().unwrap().to_string(),
            ));
        }
    }
    for (op, node) in [("ultrasonic", "cart"), ("collision-avoidance", "cart")] {
        assert!(
            placed.contains(&(op.to_string(), node.to_string())),
            "{op} on {node}: {placed:?}"
        );
    }
    // the other operations run on the operations node and have a standby on the spare
    // one: one instance of each bound, on either
    for op in [
        "localizer",
        "path-planner",
        "trajectory-controller",
        "wall-follower",
    ] {
        let on: Vec<_> = placed.iter().filter(|(o, _)| o == op).collect();
        assert_eq!(on.len(), 1, "{op}: {placed:?}");
        assert!(
            ["operations", "spare"].contains(&on[0].1.as_str()),
            "{op}: {placed:?}"
        );
    }
}

#[test]
fn up_lists_every_module_with_its_node_and_leaves_no_node_behind_when_killed() {
    let mut up = Proc::spawn("marie up", &["up", THESIS, "--speed", SPEED]);
    up.wait_line("Ctrl-C stops the cluster");
    let nodes: Vec<(String, String, u32)> = up.seen().iter().filter_map(|l| node_line(l)).collect();
    let names: Vec<&str> = nodes.iter().map(|(n, _, _)| n.as_str()).collect();
    assert_eq!(names, ["cart", "features", "operations", "spare"]);

    // any node lets a newcomer see the whole cluster
    let (code, rows, stderr) = ls_join(&nodes[3].1, "marie-thesis", &[]);
    assert_eq!(code, Some(0), "{stderr}");
    let listed: BTreeSet<(String, String)> = rows
        .iter()
        .map(|(_, name, node)| (name.clone(), node.clone()))
        .collect();
    assert_eq!(rows.len(), 27, "{listed:?}");
    for (module, node) in [
        ("dispatcher-desk", "features"),
        ("dispatcher-desk", "spare"),
        ("run", "operations"),
        ("virtual-cart", "cart"),
        ("ultrasonic", "cart"),
        ("feature", "features"),
        ("world", "operations"),
        ("parameter", "operations"),
        ("docking-detector", "operations"),
        ("wall-follower", "spare"),
        ("wall-follower", "operations"),
        ("localizer", "spare"),
        ("trajectory-controller", "spare"),
    ] {
        assert!(
            listed.contains(&(module.to_string(), node.to_string())),
            "{module} on {node}: {listed:?}"
        );
    }

    // killed without a chance to clean up, it still takes its nodes along
    up.signal("KILL");
    assert_eq!(up.wait_exit(), None);
    for (name, _, pid) in &nodes {
        assert!(wait_gone(*pid), "node {name} (pid {pid}) outlived marie up");
    }
}

#[test]
fn a_bad_cluster_file_or_speed_exits_2_before_any_node_starts() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.toml");
    std::fs::write(
        &bad,
        "[cluster]\ncookie = \"c\"\n[[node]]\nconfig = \"missing.toml\"\n",
    )
    .unwrap();
    let out = marie(&["up", bad.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = text(&out.stderr);
    assert!(
        stderr.contains(&format!(
            "{}:4:10: the node config named here does not load:",
            bad.display()
        )),
        "{stderr}"
    );
    assert!(stderr.contains("missing.toml"), "{stderr}");

    for speed in ["max", "0", "1000"] {
        let out = marie(&["up", THESIS, "--speed", speed]);
        assert_eq!(out.status.code(), Some(2), "--speed {speed}");
        assert!(
            text(&out.stderr).contains("wall clock"),
            "{}",
            text(&out.stderr)
        );
    }
    let out = marie(&[
        "run",
        "missions/docking.toml",
        "--join",
        "127.0.0.1:9",
        "--cookie",
        "c",
        "--speed",
        "max",
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        text(&out.stderr).contains("--speed with --join"),
        "{}",
        text(&out.stderr)
    );
}

#[test]
fn a_thousand_operations_on_three_nodes_converge_in_every_members_registry() {
    let dir = tempfile::tempdir().unwrap();
    let mut cluster = String::from("[cluster]\ncookie = \"big\"\n");
    for node in ["a", "b", "c"] {
        let mut config = format!("[node]\nname = \"{node}\"\ndispatcher = false\n");
        for op in [
            "sampler",
            "averager",
            "checker",
            "segment-extractor",
            "wall-sensor",
        ] {
            config += &format!("[[operation]]\nname = \"{op}\"\ninstances = 64\n");
        }
        config += "[[operation]]\nname = \"docking-detector\"\ninstances = 14\n";
        std::fs::write(dir.path().join(format!("{node}.toml")), config).unwrap();
        cluster += &format!("[[node]]\nconfig = \"{node}.toml\"\n");
    }
    let file = dir.path().join("big.toml");
    std::fs::write(&file, cluster).unwrap();
    let mut up = Proc::spawn("marie up", &["up", file.to_str().unwrap()]);
    // `up` prints this once its own member sees every module the nodes said they host
    let line = up.wait_line("cluster ");
    assert!(line.contains("3 nodes, 1002 modules"), "{line}");
    up.wait_line("Ctrl-C stops the cluster");
    let nodes: Vec<(String, String, u32)> = up.seen().iter().filter_map(|l| node_line(l)).collect();
    // a newcomer sees them all too, through any node
    let (code, rows, stderr) = ls_join(&nodes[2].1, "big", &[]);
    assert_eq!(code, Some(0), "{stderr}");
    assert_eq!(rows.len(), 1002);
    up.signal("TERM");
    assert_eq!(up.wait_exit(), Some(0));
    for (name, _, pid) in &nodes {
        assert!(wait_gone(*pid), "node {name} (pid {pid}) outlived marie up");
    }
}

/// A cluster of one node that hosts everything the docking mission needs, at 10 times
/// wall-clock speed: `marie up --run` of docking over it is short.
fn one_node_cluster(dir: &std::path::Path) -> std::path::PathBuf {
    let repo = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let file = dir.join("one.toml");
    std::fs::write(
        &file,
        format!(
            "[cluster]\ncookie = \"one\"\nspeed = 10\n[[node]]\nconfig = \"{}\"\n",
            repo.join("missions/nodes/everything.toml").display()
        ),
    )
    .unwrap();
    file
}

/// One Ctrl-C stops `marie up --run --monitor` whenever it comes once the mission is over:
/// right with the `outcome:` line (before the run listens for the Ctrl-C that closes its
/// page), or once the run says its page stays up. It exits with the mission's code and
/// leaves no node behind.
#[test]
fn one_ctrl_c_at_the_end_of_a_monitored_run_stops_up_whenever_it_comes() {
    let dir = tempfile::tempdir().unwrap();
    let cluster = one_node_cluster(dir.path());
    // the signal is sent the moment the line is read, by this process itself: the stretch
    // between the run's last lines and its wait is short (hence the outcome line thrice),
    // and a `kill` process would come late
    for moment in [
        "mission succeeded",
        "outcome:",
        "outcome:",
        "outcome:",
        "monitor: the run is over",
    ] {
        let mut up = Proc::spawn(
            &format!("marie up (Ctrl-C at {moment:?})"),
            &[
                "up",
                cluster.to_str().unwrap(),
                "--run",
                "missions/docking.toml",
                "--monitor",
                "127.0.0.1:0",
            ],
        );
        // a viewer on the page, as a user who watches the run has: the monitor's thread
        // streams to it as the run ends
        let (page, _) = page_of(&up.wait_line("monitor: http://"));
        let mut viewer = std::net::TcpStream::connect(page).unwrap();
        write!(
            viewer,
            "GET /api/live HTTP/1.1\r\nHost: {page}\r\nAccept: text/event-stream\r\n\r\n"
        )
        .unwrap();
        std::thread::spawn(move || std::io::copy(&mut viewer, &mut std::io::sink()));
        let node = up.wait_line("  everything at ");
        let pid: u32 = node
            .split_once("(pid ")
            .and_then(|(_, rest)| rest.split_once(')')?.0.parse().ok())
            .unwrap_or_else(|| panic!("no pid in {node:?}"));
        up.wait_line(moment);
        up.signal_now(libc::SIGINT);
        let code = up.wait_exit();
        let lines = up.drain().to_vec();
        // the mission's own code
        assert_eq!(
            code,
            Some(0),
            "Ctrl-C at {moment:?}:\n{}\n{}",
            lines.join("\n"),
            up.stderr_tail()
        );
        assert!(
            lines.iter().any(|l| l.contains("outcome: succeeded")),
            "{lines:?}"
        );
        assert!(lines.iter().any(|l| l == "cluster stopped"), "{lines:?}");
        assert!(
            wait_gone(pid),
            "the node outlived marie up (Ctrl-C at {moment:?})"
        );
    }
}

/// A cluster kept up keeps its cart between runs: a second `run --join` of docking starts
/// where the first parked it, and says so; `--from-start` puts the cart back at rest at the
/// world's start, its collisions and path anew, and docking succeeds from there again.
#[test]
fn a_run_on_a_cluster_kept_up_starts_where_the_last_left_the_cart_or_from_the_start_if_asked() {
    // a run of its own starts from the world's start anyway: the flag is refused there
    let out = marie(&["run", "missions/docking.toml", "--from-start"]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
    assert!(
        text(&out.stderr).contains("--join"),
        "{}",
        text(&out.stderr)
    );

    let dir = tempfile::tempdir().unwrap();
    let mut up = Proc::spawn("marie up", &["up", THESIS, "--speed", SPEED]);
    up.wait_line("Ctrl-C stops the cluster");
    let nodes: Vec<(String, String, u32)> = up.seen().iter().filter_map(|l| node_line(l)).collect();
    let run = |name: &str, extra: &[&str]| {
        let report = dir.path().join(format!("{name}.json"));
        let mut args = vec![
            "run",
            "missions/docking.toml",
            "--join",
            &nodes[0].1,
            "--cookie",
            "marie-thesis",
            "--speed",
            SPEED,
            "--report",
            report.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let out = marie(&args);
        let report: serde_json::Value = std::fs::read_to_string(&report)
            .ok()
            .and_then(|s| serde_json::from_str(&s).ok())
            .unwrap_or_default();
        (out, report)
    };
    let starts = "the cart starts";

    let (first, report) = run("first", &[]);
    let stdout = text(&first.stdout);
    assert_eq!(
        first.status.code(),
        Some(0),
        "{stdout}{}",
        text(&first.stderr)
    );
    assert!(
        !stdout.contains(starts),
        "a fresh cluster's cart is at the start: {stdout}"
    );
    assert_eq!(report["outcome"], "succeeded");
    let parked = &report["final_pose"];

    // the next run finds the cart where the first parked it (docking's goal is the dock —
    // where in it varies with the run), and says so
    let (second, _) = run("second", &[]);
    let stdout = text(&second.stdout);
    let said = "the cart starts where the cluster's last run left it, at (";
    let line = stdout
        .lines()
        .find_map(|l| l.strip_prefix(said))
        .unwrap_or_else(|| panic!("{stdout}{}", text(&second.stderr)));
    let xy: Vec<f64> = line
        .split([',', ')'])
        .take(2)
        .map(|v| v.trim().parse().unwrap())
        .collect();
    for (said, parked) in xy.iter().zip([&parked[0], &parked[1]]) {
        let parked = parked.as_f64().unwrap();
        // within 2 cm: the cart settles under the watchdog's brake after the report
        assert!((said - parked).abs() < 0.02, "{line} vs {parked}: {stdout}");
    }

    // a node without a desk cannot dispatch a run: refused before it starts
    let (refused, _) = run("refused", &["--dispatch-on", "cart"]);
    let stderr = text(&refused.stderr);
    assert_eq!(refused.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("--dispatch-on cart: that node runs no dispatcher desk")
            && stderr.contains("these do: ")
            && stderr.contains("features")
            && stderr.contains("spare"),
        "{stderr}"
    );
    // from the start, dispatched on the features node's desk (as `marie up --run` does)
    let events = dir.path().join("third.jsonl");
    let (third, report) = run(
        "third",
        &[
            "--from-start",
            "--dispatch-on",
            "features",
            "--events",
            events.to_str().unwrap(),
        ],
    );
    let started: Vec<String> = std::fs::read_to_string(&events)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
        .filter(|e| e["kind"]["type"] == "run_started")
        .map(|e| e["node"].as_str().unwrap().to_string())
        .collect();
    assert_eq!(started, ["features"]);
    let stdout = text(&third.stdout);
    assert_eq!(
        third.status.code(),
        Some(0),
        "{stdout}{}",
        text(&third.stderr)
    );
    assert!(
        stdout.contains("the cart starts at the world's start (--from-start)"),
        "{stdout}"
    );
    assert_eq!(report["outcome"], "succeeded", "{report:#}");
    assert_eq!(report["collisions"], 0);

    up.signal("INT");
    assert_eq!(up.wait_exit(), Some(0));
    for (name, _, pid) in &nodes {
        assert!(wait_gone(*pid), "node {name} (pid {pid}) outlived marie up");
    }
}

/// Ask `ls` until `done` holds of its rows (every 250 ms, for at most 60 s); the last rows.
fn ls_until(addr: &str, done: impl Fn(&[serde_json::Value]) -> bool) -> Vec<serde_json::Value> {
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
    loop {
        let (_, rows, _) = ls_join_rows(addr, "marie-thesis", &[]);
        if done(&rows) || std::time::Instant::now() > deadline {
            return rows;
        }
        std::thread::sleep(std::time::Duration::from_millis(250));
    }
}

#[test]
fn a_node_killed_under_up_is_restarted_rejoins_and_its_replicas_catch_up() {
    let mut up = Proc::spawn("marie up", &["up", THESIS, "--speed", SPEED]);
    up.wait_line("Ctrl-C stops the cluster");
    let nodes: Vec<(String, String, u32)> = up.seen().iter().filter_map(|l| node_line(l)).collect();
    let (_, cart, _) = &nodes[0];
    let (name, _, pid) = &nodes[2];
    assert_eq!(name, "operations");
    // killed by something else than a fault of marie's: `up` sees its process end
    let mark = up.seen().len();
    signal_pid(*pid, "KILL");
    up.wait_line("node operations was killed (SIGKILL): restarting it in 0.10 s");
    let back = up.wait_line("node operations restarted: listening on ");
    assert!(!back.contains(&format!("(pid {pid})")), "{back}");
    // every datamanager's leader tells the replica on operations caught up, then its
    // redundancy restored (each has a replica there)
    for dm in ["feature", "parameter", "world", "run"] {
        let caught = up.wait_line_since(
            mark,
            &format!("datamanager {dm}: the replica on operations caught up"),
        );
        assert!(caught.contains("s after it was lost"), "{caught}");
        up.wait_line_since(
            mark,
            &format!("datamanager {dm}: redundancy restored, all 3 replicas current"),
        );
    }
    // the whole cluster is listed again, and every datamanager's leader sees both of its
    // followers with nothing left to catch up
    let caught_up = |rows: &[serde_json::Value]| {
        let dms: Vec<&serde_json::Value> =
            rows.iter().filter(|r| r["replica"].is_object()).collect();
        rows.len() == 27
            && dms.len() == 4
            && dms.iter().all(|r| {
                let lag = r["replica"]["lag"].as_object().cloned().unwrap_or_default();
                lag.len() == 2 && lag.values().all(|l| l == 0)
            })
    };
    let rows = ls_until(cart, caught_up);
    assert!(caught_up(&rows), "{rows:#?}");
    assert!(
        rows.iter()
            .any(|r| r["node"] == "operations" && r["name"] == "localizer"),
        "{rows:#?}"
    );
    // each replica says what it holds in memory, the one restarted too: caught up, it
    // holds the leader's records
    for dm in rows.iter().filter(|r| r["replica"].is_object()) {
        let replicas = dm["replicas"].as_array().cloned().unwrap_or_default();
        let mut nodes: Vec<&str> = replicas.iter().filter_map(|r| r["node"].as_str()).collect();
        nodes.sort();
        assert_eq!(nodes, ["features", "operations", "spare"], "{dm:#}");
        let records: Vec<&serde_json::Value> =
            replicas.iter().map(|r| &r["held"]["records"]).collect();
        assert!(records[0].is_u64(), "{dm:#}");
        assert!(records.iter().all(|r| *r == records[0]), "{dm:#}");
    }
    up.signal("INT");
    up.wait_line("cluster stopped");
    assert_eq!(up.wait_exit(), Some(0), "{}", up.seen().join("\n"));
}

#[test]
fn datamanagers_that_lost_their_majority_are_listed_with_the_nodes_they_miss() {
    // the thesis layout, but nodes stay down once killed
    let dir = tempfile::tempdir().unwrap();
    let file = thesis_with(dir.path(), "restart = \"temporary\"");
    let mut up = Proc::spawn(
        "marie up",
        &["up", file.to_str().unwrap(), "--speed", SPEED],
    );
    up.wait_line("Ctrl-C stops the cluster");
    let nodes: Vec<(String, String, u32)> = up.seen().iter().filter_map(|l| node_line(l)).collect();
    for (name, _, pid) in &nodes[1..3] {
        signal_pid(*pid, "KILL");
        up.wait_line(&format!(
            "node {name} was killed (SIGKILL): it stays down (restart = \"temporary\")"
        ));
    }
    let leaderless = |rows: &[serde_json::Value]| {
        rows.iter().filter(|r| r["no_majority"].is_object()).count() == 4
    };
    let rows = ls_until(&nodes[3].1, leaderless);
    assert!(leaderless(&rows), "{rows:#?}");
    for r in rows.iter().filter(|r| r["no_majority"].is_object()) {
        let lost = &r["no_majority"];
        assert_eq!(lost["answering"], serde_json::json!(["spare"]), "{r}");
        assert_eq!(
            lost["missing"],
            serde_json::json!(["features", "operations"]),
            "{r}"
        );
        assert!(
            lost["why"].as_str().unwrap().contains(&format!(
                "datamanager `{}` has no majority: 1 of its 3 replicas answers (spare)",
                r["name"].as_str().unwrap()
            )),
            "{r}"
        );
    }
    // and in words
    let out = marie(&["ls", "--join", &nodes[3].1, "--cookie", "marie-thesis"]);
    let listing = text(&out.stdout);
    assert!(
        listing.contains("DM run: no majority — datamanager `run` has no majority: 1 of its 3 \
                          replicas answers (spare), a leader needs 2; missing: features, operations"),
        "{listing}"
    );
    up.signal("INT");
    up.wait_line("cluster stopped");
    assert_eq!(up.wait_exit(), Some(0), "{}", up.seen().join("\n"));
}
