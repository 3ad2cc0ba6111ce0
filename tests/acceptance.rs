//! Five of the acceptance's schedules (issue 23, point 5; `scripts/acceptance` runs any
//! number and prints the table): each one node fault — a stop, a freeze or a cut of a node
//! other than the cart's, at a moment of the run — in one `marie up
//! missions/clusters/thesis.toml --run missions/docking.toml`, and each must dock with its
//! fault injected, no acknowledged record lost and no collision. The schedules and their
//! verdicts are `tests/common/acceptance.rs`'s, the script's own.
//!
//! A fixed, seeded subset: schedule numbers whose draws cover the three kinds and the three
//! nodes a fault may hit (checked below, so a change in the cluster file or the draw that
//! loses one is seen): a 3.3 s freeze of the operations node, a 3.9 s cut of it, a 5.9 s cut
//! of the features node (its datamanager's leader), the spare node stopped late in the
//! run, the operations node stopped early.
//!
//! At wall-clock speed, as the script's default: a failover's delays are real time (the
//! failure detector's 1.2 s deadline, an election, an operation's 5 s wait for a module
//! gone), its limits mission time (a wall follower fails after 15 s without progress, a
//! binding after 10 s without a stand-in); faster, a real-time stall eats a multiple of
//! mission time, and at `--speed 4` schedule 4 failed where it docks at speed 1 (a 5 s
//! stall of the wall following is 20 s of mission time there). The five runs go at once:
//! at speed 1 a run of the layout (five processes) takes about a fifth of a core, so the
//! test lasts one run, about 75 s.

use crate::common;

use common::acceptance::{header, summary, Draw, Kind, Layout, Running, Schedule, Verdict};
use std::collections::BTreeSet;

/// The schedules CI runs (of `scripts/acceptance`'s numbering).
const SCHEDULES: [u64; 5] = [1, 3, 4, 7, 30];
/// The cluster's speed: wall-clock time.
const SPEED: f64 = 1.0;
/// The mission time of a fault-free docking run, about (`scripts/acceptance` measures it:
/// 64 s at the time of writing); the faults' moments are drawn over it. A fault drawn
/// after the run's end would not be injected, and the test says so.
const RUN_SECS: f64 = 62.0;
/// Runs at once: all of them.
const AT_ONCE: usize = 5;

#[test]
fn five_seeded_node_faults_dock_with_nothing_lost_no_old_epoch_obeyed_no_collision() {
    if !common::netns::Netns::can_make() {
        // partitions need root and `ip` (CI has both: there this fails instead)
        return;
    }
    let layout = Layout::load(common::acceptance::CLUSTER).unwrap();
    let draw = Draw {
        run_secs: RUN_SECS,
        speed: SPEED,
        partitions: true,
    };
    let schedules: Vec<Schedule> = SCHEDULES
        .iter()
        .map(|n| Schedule::draw(*n, &layout, &draw))
        .collect();
    // the subset covers every kind and every node a fault may hit
    let kinds: BTreeSet<String> = schedules.iter().map(|s| format!("{:?}", s.kind)).collect();
    let victims: BTreeSet<&str> = schedules.iter().map(|s| s.victim.as_str()).collect();
    assert_eq!(kinds.len(), 3, "{schedules:?}");
    assert_eq!(victims.len(), layout.victims.len(), "{schedules:?}");
    assert!(schedules.iter().any(|s| s.kind == Kind::Stop));

    let dir = tempfile::tempdir().unwrap();
    let mut verdicts = Vec::new();
    for group in schedules.chunks(AT_ONCE) {
        let mut runs: Vec<(Schedule, Running)> = group
            .iter()
            .map(|s| {
                let run = Running::start(
                    Some(&s.spec()),
                    SPEED,
                    &dir.path().join(s.number.to_string()),
                )
                .expect("marie up starts");
                (s.clone(), run)
            })
            .collect();
        for (s, run) in &mut runs {
            let exit = run.wait();
            let v = Verdict::of(s, &run.report(), exit, run.elapsed());
            if !v.passes() {
                eprintln!(
                    "schedule {} (--fault {}), its stderr's end:\n{}",
                    s.number,
                    s.spec(),
                    run.stderr_tail(30)
                );
            }
            verdicts.push(v);
        }
    }
    let table: Vec<String> = verdicts.iter().map(Verdict::row).collect();
    let (line, _) = summary(&verdicts);
    let shown = format!("{}\n{}\n{line}", header(), table.join("\n"));
    println!("{shown}");
    for v in &verdicts {
        assert!(
            v.passes(),
            "schedule {} failed:\n{shown}",
            v.schedule.number
        );
        assert_eq!(v.exit, Some(0), "{shown}");
        assert!(v.acknowledged > 0, "the check heard no store: {shown}");
    }
}
