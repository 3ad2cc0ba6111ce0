//! A short soak (issue 43, point 6; `scripts/soak` runs the size and prints the
//! table): one kept-up cluster of the thesis' layout runs the docking mission twice while
//! `--chaos-nodes` stops, freezes and cuts off nodes other than the cart's on one schedule
//! across both runs, each stopped node restarted by `marie up`. Every run must dock with
//! nothing acknowledged lost, no epoch obeyed late and no collision; at least five faults
//! must strike, on at least two of the nodes that each hold a replica of every datamanager
//! (features, operations, spare: two faults there hit two replicas of the same
//! datamanagers), and every fault's node must come back and catch up (or be hit again
//! first). How the soak is read: `tests/common/soak.rs`, the script's own.
//!
//! At `--speed 4`, as the other cluster tests: a docking run is some 64 s of mission time,
//! 16 s of real time, and the schedule (10 to 20 s of mission time between faults) strikes
//! 3 to 6 times in each; a freeze or a cut lasts 2 to 6 s of mission time, 0.5 to 1.5 s of
//! real time — some ride through the failure detector's 1.2 s deadline, the others are
//! declared down. Partitions are drawn where this process may make namespaces (root and
//! `ip`); elsewhere stops and freezes only.

use crate::common;

use common::soak::{Fault, Outcome, SoakArgs};
use std::collections::BTreeSet;
use std::time::Duration;

/// The soak CI runs.
const SOAK: SoakArgs = SoakArgs {
    runs: 2,
    seed: 3,
    speed: 4.0,
    every: None,
};

#[test]
fn faults_that_keep_coming_across_runs_fail_no_mission_and_lose_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let mut up = SOAK
        .start(dir.path(), Duration::from_secs(300))
        .expect("marie up starts");
    let exit = up.wait();
    let outcome = Outcome::read(dir.path(), SOAK.runs, exit);
    let shown = format!(
        "{}\n{}\n{}\n{}\nstderr's end:\n{}",
        outcome.fault_table(),
        outcome.run_table(),
        outcome.summary.join("\n"),
        outcome.totals(),
        up.stderr_tail(30)
    );
    println!("{shown}");
    let injected: Vec<_> = outcome.injected().collect();
    assert!(injected.len() >= 5, "fewer than five faults: {shown}");
    // faults of more than one run: the schedule went on across them
    let runs: BTreeSet<u32> = injected.iter().map(|f| f.run).collect();
    assert_eq!(runs.len(), SOAK.runs as usize, "{shown}");
    let holders = ["features", "operations", "spare"];
    let hit: BTreeSet<&str> = injected
        .iter()
        .map(|f| f.node.as_str())
        .filter(|n| holders.contains(n))
        .collect();
    assert!(hit.len() >= 2, "faults on one replica's node only: {shown}");
    assert!(injected.iter().all(|f| f.node != "cart"), "{shown}");
    for f in &injected {
        let seen_through = f.caught_up_after.is_some() || f.hit_again_by.is_some();
        assert!(
            seen_through,
            "fault {} was not seen through: {shown}",
            f.number
        );
    }
    assert!(
        outcome.runs.iter().all(|r| r.acknowledged > 0),
        "a run's check heard no store: {shown}"
    );
    // the probe read all along, every replica's node included, and nothing stale
    assert_eq!(outcome.stale_reads(), Some(0), "{shown}");
    let reads = outcome.reads().unwrap_or_default();
    for node in holders {
        assert!(
            reads.contains(&format!("; {node} ")),
            "{node} not read: {shown}"
        );
    }
    assert!(outcome.reads_answered().is_some_and(|n| n > 100), "{shown}");
    assert!(outcome.goal(), "the soak's goal does not hold: {shown}");
    assert!(
        outcome.memory().is_some_and(|m| m.contains("cart ")),
        "{shown}"
    );
}

#[test]
fn a_run_after_one_that_was_taken_over_is_not_fenced_off_by_its_term() {
    // the features node (the active dispatcher's) killed in each run: spare's standby takes
    // the run over at term 2. The next run's dispatcher starts at term 1 again — its
    // checkpoints were refused for the last run's term 2 (the fence was the dispatchers',
    // not the run's), and the run failed at once: "the dispatcher on `features` was fenced
    // off and no standby took the run over within 20 s"
    let (code, stdout, shown) = two_runs(&["stop-node:features@20"]);
    assert_eq!(code, Some(0), "{shown}");
    assert_eq!(
        stdout
            .matches("# the run taken over by spare from features")
            .count(),
        2,
        "{shown}"
    );
    assert!(!stdout.contains("fenced off by term"), "{shown}");
    assert!(
        stdout.contains("soak of docking: 2 runs, 2 succeeded, 0 failed"),
        "{shown}"
    );
    assert!(stdout.contains("): holds"), "{shown}");
}

#[test]
fn a_run_refused_while_its_dispatch_node_is_frozen_is_tried_again_once_it_is_back() {
    // the features node (the one the runs are dispatched on) frozen at 50 s of each run for
    // 40 s of mission time (10 s of real time): spare's standby takes the run over and docks,
    // run 1 ends while features is still frozen — its desk out of the registry — and run 2,
    // refused at first ("--dispatch-on features: that node runs no dispatcher desk"), is
    // tried again every second until features is back
    let (code, stdout, shown) = two_runs(&["freeze-node:features@50+40"]);
    assert!(
        stdout.contains(
            "run 2 of 2 could not start: --dispatch-on features: that node runs no dispatcher desk"
        ),
        "{shown}"
    );
    assert!(stdout.contains("trying again in 1 s"), "{shown}");
    assert!(!stdout.contains("could not run"), "{shown}");
    assert!(
        stdout.contains("soak of docking: 2 runs, 2 succeeded, 0 failed"),
        "{shown}"
    );
    assert_eq!(code, Some(0), "{shown}");
}

#[test]
fn a_standby_woken_after_its_run_was_taken_back_commands_nothing_of_it() {
    // in each of two runs: the features node (the active dispatcher's) killed at 6 s, spare's
    // standby takes the run over (term 2); spare frozen at 30 s for 16 s of mission time (4 s
    // of real time), features' desk takes the run back (term 4) and holds the cart's
    // operations at its epochs. Woken, spare's dispatcher finds its instances gone (its
    // sessions redialled), adopts them again above term 4's epochs, and learns only then that
    // its checkpoints are refused. The soak's run failed so: "operation `ultrasonic` was
    // suspended by another party" — the woken dispatcher ended an action on the cart's
    // operations, at an epoch it raised and never stored (the order of its messages decides;
    // actors/tests/fenced_dispatcher.rs makes it the failing one every time)
    let (code, stdout, shown) = two_runs(&["stop-node:features@6", "freeze-node:spare@30+16"]);
    assert!(!stdout.contains("another party"), "{shown}");
    assert_eq!(code, Some(0), "{shown}");
    for (from, to, term) in [("features", "spare", 2), ("spare", "features", 4)] {
        let line = format!("# the run taken over by {to} from {from} at ");
        assert_eq!(stdout.matches(&line).count(), 2, "{line}: {shown}");
        assert!(
            stdout.contains(&format!("(term {term}, claimed")),
            "{shown}"
        );
    }
    // woken, it was fenced off, in each run
    let fenced = "# the dispatcher on spare (term 2) fenced off by term 4";
    assert_eq!(stdout.matches(fenced).count(), 2, "{shown}");
    assert!(
        stdout.contains("soak of docking: 2 runs, 2 succeeded, 0 failed"),
        "{shown}"
    );
    assert!(stdout.contains("): holds"), "{shown}");
}

#[test]
fn the_probes_line_parses() {
    let outcome = Outcome {
        exit: Some(0),
        runs: Vec::new(),
        faults: Vec::new(),
        summary: vec![
            "records: 0 of 10 acknowledged records lost".into(),
            "reads: probe of feature, 34.3 s: 345 writes acknowledged (1 failed and tried \
             again), reads: by name 841 answered; features 783 answered, 3 refused; spare 7 \
             answered, 1 unanswered; 2 stale; 0 of the 345 acknowledged writes still kept \
             lost; the newest acknowledged write read back"
                .into(),
        ],
    };
    assert_eq!(outcome.stale_reads(), Some(2));
    assert_eq!(outcome.reads_answered(), Some(841 + 783 + 7));
    let unchecked = Outcome {
        summary: vec!["reads: NOT checked: the probe ended".into()],
        ..outcome
    };
    assert_eq!(unchecked.stale_reads(), None);
    assert!(!unchecked.goal());
}

#[test]
fn fault_lines_parse() {
    let f = Fault::parse(
        "fault 7 (stop-node features, run 3 at 12.4 s): back 0.21 s after it struck, \
         caught up 0.84 s after it was back",
    )
    .unwrap();
    assert_eq!(
        (f.number, f.kind.as_str(), f.node.as_str(), f.run, f.at),
        (7, "stop-node", "features", 3, 12.4)
    );
    assert_eq!((f.back_after, f.caught_up_after), (Some(0.21), Some(0.84)));
    let f = Fault::parse(
        "fault 8 (freeze-node features for 5.9 s, run 1 at 68.4 s): fault 9 hit its node \
         again before it was back",
    )
    .unwrap();
    assert_eq!(
        (f.lasting, f.hit_again_by, f.back_after),
        (Some(5.9), Some(9), None)
    );
    let f = Fault::parse(
        "fault 2 (partition spare for 2.3 s, run 1 at 9.0 s): back 0.58 s after it struck, \
         not caught up before fault 3 hit it again",
    )
    .unwrap();
    assert_eq!((f.hit_again_by, f.caught_up_after), (Some(3), None));
    let f = Fault::parse(
        "fault 4 (freeze-node spare for 2.0 s, run 2 at 1.5 s): not injected: it is frozen already",
    )
    .unwrap();
    assert_eq!(f.not_injected.as_deref(), Some("it is frozen already"));
    assert_eq!(
        Fault::parse("* injected stop-node into features (pid 1) at 14.0s"),
        None
    );
}

/// `marie up` running the mission twice at speed 4 with `faults` (`--fault` each): its exit
/// code, its stdout, and stdout and stderr together (what a failed assertion shows).
fn two_runs(faults: &[&str]) -> (Option<i32>, String, String) {
    let mut args = vec![
        "up",
        common::soak::CLUSTER,
        "--run",
        common::soak::MISSION,
        "--runs",
        "2",
        "--speed",
        "4",
    ];
    for fault in faults {
        args.extend(["--fault", fault]);
    }
    let out = common::marie(&args);
    let stdout = common::text(&out.stdout);
    let shown = format!("{stdout}\n{}", common::text(&out.stderr));
    (out.status.code(), stdout, shown)
}
