//! No input makes `marie` panic, stall or lie: every bad number, file or name is refused
//! with exit 2 and a message that names it — before anything runs — and a fault that could
//! not be injected is reported, never dropped.

use crate::common;

use common::{marie, report_of, text};
use std::process::Output;
use std::time::{Duration, Instant};

/// `out` is a refusal: exit 2, nothing ran, stderr names `needle` and nothing panicked.
#[track_caller]
fn refused(out: &Output, needle: &str) {
    let (stdout, stderr) = (text(&out.stdout), text(&out.stderr));
    assert_eq!(out.status.code(), Some(2), "{stdout}\n{stderr}");
    assert!(stderr.contains(needle), "`{needle}` in: {stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(!stdout.contains("> "), "nothing ran: {stdout}");
}

#[test]
fn speeds_out_of_range_are_refused() {
    for speed in [
        "0", "-1", "nan", "NaN", "inf", "-inf", "1e7", "0.001", "", "fast",
    ] {
        let out = marie(&["run", "missions/demo.toml", "--speed", speed]);
        refused(&out, "--speed");
        assert!(text(&out.stderr).contains("or `max`"), "{speed}");
    }
}

#[test]
fn seeds_that_are_no_whole_number_are_refused() {
    for (flag, seed) in [
        ("--seed", "-1"),
        ("--seed", "18446744073709551616"),
        ("--seed", "1.5"),
        ("--chaos", "-3"),
        ("--chaos", "x"),
    ] {
        let out = marie(&["run", "missions/demo.toml", flag, seed]);
        refused(&out, "expected a whole number");
        assert!(!text(&out.stderr).contains("-- -"), "no false hint");
    }
}

#[test]
fn fault_times_out_of_range_are_refused() {
    for at in ["-1", "nan", "inf", "1e300", "1000001", "soon", ""] {
        let spec = format!("kill:wall-follower@{at}");
        let out = marie(&["run", "missions/docking.toml", "--fault", &spec]);
        refused(&out, &spec);
    }
}

#[test]
fn faults_from_the_page_need_a_live_page() {
    let out = marie(&["run", "missions/demo.toml", "--allow-faults"]);
    refused(&out, "--monitor");
    let out = marie(&["up", "missions/clusters/thesis.toml", "--allow-faults"]);
    refused(&out, "--monitor");
    // a replay has no run to hurt
    let out = marie(&["monitor", "--events", "run.jsonl", "--allow-faults"]);
    refused(&out, "cannot be used with '--allow-faults'");
}

#[test]
fn changes_from_the_page_need_a_live_page_and_a_watchers_speed_is_checked() {
    let out = marie(&["run", "missions/demo.toml", "--allow-changes"]);
    refused(&out, "--monitor");
    let out = marie(&["up", "missions/clusters/thesis.toml", "--allow-changes"]);
    refused(&out, "--monitor");
    // a replay has no cluster to change
    let out = marie(&["monitor", "--events", "run.jsonl", "--allow-changes"]);
    refused(&out, "cannot be used with '--allow-changes'");
    // a cluster's speed is a factor of real time, checked before joining
    let out = marie(&[
        "monitor",
        "--join",
        "127.0.0.1:9",
        "--cookie",
        "c",
        "--speed",
        "0",
    ]);
    refused(&out, "--speed: expected a factor of real time");
    let out = marie(&["monitor", "--events", "run.jsonl", "--speed", "2"]);
    refused(&out, "--join");
}

#[test]
fn malformed_fault_targets_are_refused() {
    for spec in [
        "kill:wall follower@1",
        "kill:#1.0.0@1",
        "kill:wall-follower#@1",
        "kill:0.@1",
        "melt:wall-follower@1",
        "kill",
    ] {
        let out = marie(&["run", "missions/docking.toml", "--fault", spec]);
        refused(&out, spec);
    }
}

#[test]
fn a_fault_names_a_running_instance_or_is_refused_before_the_run() {
    let docking = "missions/docking.toml";
    let cases = [
        ("kill:no-such-op@5", "no operation `no-such-op` is running"),
        (
            "kill:wall-follower#3.0.0@5",
            "no instance of `wall-follower` has version 3.0.0 (running: 1.0.0, 2.0.0)",
        ),
        ("kill:0.9999@5", "no operation instance 0.9999 is running"),
    ];
    for (spec, want) in cases {
        refused(&marie(&["run", docking, "--fault", spec]), want);
    }
    // the demo binds no wall follower, and two versions run: a name alone does not say which
    let out = marie(&[
        "run",
        "missions/demo.toml",
        "--fault",
        "kill:wall-follower@5",
    ]);
    refused(
        &out,
        "2 instances of `wall-follower` run and no mission binds one: \
         name one as wall-follower#1.0.0 or wall-follower#2.0.0",
    );
}

#[test]
fn a_fault_hits_the_instance_the_mission_bound_or_the_one_it_names() {
    // the mission binds wall-follower 1.0.0; after the first kill, its stand-in
    let (out, json) = report_of(&[
        "run",
        "missions/docking.toml",
        "--fault",
        "kill:wall-follower@20",
        "--fault",
        "kill:wall-follower@30",
    ]);
    let stdout = text(&out.stdout);
    assert_eq!(out.status.code(), Some(0), "{stdout}");
    let rebinds = json["rebinds"].as_array().unwrap();
    assert_eq!(rebinds.len(), 2, "{json}");
    let faults = json["faults"].as_array().unwrap();
    assert_eq!(faults[0]["actor"], rebinds[0]["from"], "{json}");
    assert_eq!(faults[1]["actor"], rebinds[0]["to"], "the stand-in: {json}");
    assert_eq!(faults[1]["actor"], rebinds[1]["from"], "{json}");

    // the other version: the mission does not notice
    let (out, json) = report_of(&[
        "run",
        "missions/docking.toml",
        "--fault",
        "kill:wall-follower#2.0.0@20",
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stdout));
    assert_eq!(json["rebinds"], serde_json::json!([]), "{json}");
    assert_eq!(json["faults"][0]["error"], serde_json::Value::Null);
    let v2 = json["faults"][0]["actor"].as_str().unwrap().to_string();

    // by actor id: the same instance, runs being repeatable
    let spec = format!("kill:{v2}@20");
    let (out, json) = report_of(&["run", "missions/docking.toml", "--fault", &spec]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stdout));
    assert_eq!(json["faults"][0]["actor"], v2.as_str(), "{json}");
}

#[test]
fn a_fault_due_after_the_mission_is_reported_not_dropped() {
    let (out, json) = report_of(&["run", "missions/demo.toml", "--fault", "kill:sampler@5000"]);
    let stdout = text(&out.stdout);
    assert_eq!(out.status.code(), Some(0), "{stdout}");
    assert!(
        stdout.contains("* could not inject kill into sampler at 5000.0s: the mission was over"),
        "{stdout}"
    );
    let f = &json["faults"][0];
    assert_eq!(f["at_ms"], 5_000_000);
    assert!(f["error"]
        .as_str()
        .unwrap()
        .contains("the mission was over"));
}

#[test]
fn input_files_that_are_not_regular_files_or_huge_are_refused_without_reading_them() {
    let dir = tempfile::tempdir().unwrap();
    let huge = dir.path().join("huge.toml");
    std::fs::File::create(&huge)
        .unwrap()
        .set_len(64 * 1024 * 1024)
        .unwrap();
    let fifo = dir.path().join("fifo.toml");
    let made_fifo = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .is_ok_and(|s| s.success());
    let d = dir.path().to_str().unwrap();
    let mut cases = vec![
        (d.to_string(), "a directory"),
        ("/dev/zero".to_string(), "a character device"),
        (huge.to_str().unwrap().to_string(), "more than the 4 MiB"),
    ];
    if made_fifo {
        cases.push((fifo.to_str().unwrap().to_string(), "a fifo"));
    }
    for (path, why) in &cases {
        for args in [
            vec!["run", path.as_str()],
            vec!["check", path.as_str()],
            vec!["run", "missions/demo.toml", "--world", path.as_str()],
            vec!["ls", "--world", path.as_str()],
        ] {
            let started = Instant::now();
            let out = marie(&args);
            refused(&out, why);
            assert!(text(&out.stderr).contains(path.as_str()), "names the file");
            assert!(started.elapsed() < Duration::from_secs(20), "no stall");
        }
    }
}

#[test]
fn output_paths_are_checked_before_the_run() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().to_str().unwrap();
    let not_a_dir = dir.path().join("file");
    std::fs::write(&not_a_dir, "x").unwrap();
    let under_file = not_a_dir.join("r.json");
    let missing = dir.path().join("no/such/r.json");
    for (flag, path, why) in [
        ("--report", d, "is not a regular file (a directory)"),
        ("--svg", d, "is not a regular file (a directory)"),
        ("--report", missing.to_str().unwrap(), "no directory"),
        ("--svg", under_file.to_str().unwrap(), "is not a directory"),
    ] {
        let out = marie(&["run", "missions/docking.toml", flag, path]);
        refused(&out, &format!("{flag} {path}"));
        assert!(text(&out.stderr).contains(why), "{}", text(&out.stderr));
        assert!(out.stdout.is_empty(), "nothing ran: {}", text(&out.stdout));
    }
    // the check creates nothing
    let fresh = dir.path().join("fresh.json");
    let out = marie(&[
        "run",
        "missions/demo.toml",
        "--report",
        fresh.to_str().unwrap(),
        "--speed",
        "fast",
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(!fresh.exists());
}

#[test]
fn hints_name_commands_that_work() {
    // `marie props` and `marie kill` list what runs (the built-in node hosts every operation)
    for verb in ["props", "kill"] {
        let out = marie(&[verb, "wall-flower"]);
        refused(
            &out,
            "no operation `wall-flower` is running (running: trajectory-controller (1511)",
        );
        assert!(text(&out.stderr).contains("sampler (1601)"));
    }
    let world = "missions/worlds/lab.toml";
    // two versions of the wall follower run: a name alone does not say which
    for verb in ["props", "kill"] {
        let out = marie(&[verb, "wall-follower", "--world", world]);
        refused(
            &out,
            "2 instances of `wall-follower` run and no mission binds one: \
             name one as wall-follower#1.0.0 or wall-follower#2.0.0",
        );
    }
    let out = marie(&["props", "wall-follower#2.0.0", "--world", world]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    assert!(text(&out.stdout).contains("version:     2.0.0"));
    let out = marie(&["ls", "--world", world]);
    assert!(text(&out.stdout).contains("name: wall-follower"));
}

#[test]
fn logs_on_a_pipe_have_no_colour() {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_marie"))
        .args(["check", "missions/demo.toml"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env("RUST_LOG", "debug")
        .output()
        .unwrap();
    let stderr = text(&out.stderr);
    assert!(!stderr.is_empty());
    assert!(!stderr.contains('\u{1b}'), "no escape codes: {stderr:?}");
}

#[test]
fn a_slow_fault_delays_the_bound_instance_and_is_reported() {
    let (out, json) = report_of(&["run", "missions/demo.toml", "--fault", "slow:sampler@0.5"]);
    let stdout = text(&out.stdout);
    assert_ne!(out.status.code(), Some(2), "{stdout}{}", text(&out.stderr));
    let f = &json["faults"][0];
    assert_eq!(f["fault"], "slow", "{json:#}");
    assert_eq!(f["error"], serde_json::Value::Null, "{json:#}");
    // it hit the sampler the mission bound, and nothing replaced it: slow is not dead
    assert_eq!(
        f["actor"], json["actions"][0]["operations"][0]["address"],
        "{json:#}"
    );
    assert_eq!(json["rebinds_total"], 0, "{json:#}");
    assert!(stdout.contains("* injected slow into sampler"), "{stdout}");
}
