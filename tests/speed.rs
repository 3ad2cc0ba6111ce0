//! `--speed` only paces a run: the same mission, world and seed end the same way at every
//! speed (ARCHITECTURE.md, the `marie` package: time). The report has no wall-clock field — `duration_ms`,
//! `start_ms`/`end_ms`, `downtime_ms` and `at_ms` are mission clock time — so the reports
//! must be identical — but for its provenance's command line, start time and speed —, and so
//! must the progress lines.

use crate::common;

use common::{report_of, text};

/// Run `mission` (with `extra` flags) at each speed; each must exit with `exit`, and every
/// report and stdout must equal the first.
fn same_at_every_speed(mission: &str, extra: &[&str], speeds: &[&str], exit: i32) {
    let mut first: Option<(String, serde_json::Value, String)> = None;
    for speed in speeds {
        let started = std::time::Instant::now();
        let mut args = vec!["run", mission, "--speed", speed];
        args.extend(extra);
        let (out, mut report) = report_of(&args);
        // what says how this run was started, and when, differs by nature: the command
        // line (its --speed and --report), the start time, the speed itself
        if let Some(p) = report["provenance"].as_object_mut() {
            for key in ["command", "started", "started_unix_ms", "speed"] {
                assert!(p.remove(key).is_some(), "{speed}: no provenance `{key}`");
            }
        }
        let stdout = text(&out.stdout);
        let stderr = text(&out.stderr);
        assert_eq!(out.status.code(), Some(exit), "{speed}: {stdout}\n{stderr}");
        assert_ne!(report, serde_json::Value::Null, "{speed}: no report");
        if let Ok(factor) = speed.parse::<f64>() {
            // paced: never ahead of `factor` × real time
            let mission_ms = report["duration_ms"].as_u64().unwrap() as f64;
            let real_ms = started.elapsed().as_secs_f64() * 1000.0;
            assert!(
                real_ms >= mission_ms / factor * 0.9,
                "{mission} at {speed}: {mission_ms} ms of mission time in {real_ms:.0} ms"
            );
        }
        match &first {
            None => first = Some((speed.to_string(), report, stdout)),
            Some((s0, r0, o0)) => {
                assert_eq!(
                    &report, r0,
                    "{mission}: report at {speed} differs from {s0}"
                );
                assert_eq!(
                    &stdout, o0,
                    "{mission}: output at {speed} differs from {s0}"
                );
            }
        }
    }
}

#[test]
fn the_demo_mission_ends_the_same_at_every_speed() {
    same_at_every_speed("missions/demo.toml", &[], &["max", "1", "100", "1000"], 0);
}

#[test]
fn the_docking_mission_ends_the_same_at_every_speed() {
    // at 1 it takes a minute of real time; 100 and 1000 pace it, max does not
    same_at_every_speed(
        "missions/docking.toml",
        &[],
        &["max", "100", "1000", "max"],
        0,
    );
}

#[test]
fn faults_and_chaos_land_the_same_at_every_speed() {
    // a hang is found by a deadline, chaos by seeded gaps: all on the mission clock. Nine
    // faults, every one healed, the same way every time.
    let faults = [
        "--fault",
        "hang:trajectory-controller@50",
        "--fault",
        "panic:wall-follower@20",
        "--chaos",
        "3",
    ];
    same_at_every_speed("missions/docking.toml", &faults, &["max", "1000"], 0);
}
