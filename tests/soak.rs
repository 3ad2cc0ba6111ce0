//! Soaks (issue 43, point 6): one kept-up cluster, the mission run again and again under
//! faults.

use crate::common;

#[test]
fn a_run_after_one_that_was_taken_over_is_not_fenced_off_by_its_term() {
    // the features node (the active dispatcher's) killed in each run: spare's standby takes
    // the run over at term 2. The next run's dispatcher starts at term 1 again — its
    // checkpoints were refused for the last run's term 2 (the fence was the dispatchers',
    // not the run's), and the run failed at once: "the dispatcher on `features` was fenced
    // off and no standby took the run over within 20 s"
    let out = common::marie(&[
        "up",
        "missions/clusters/thesis.toml",
        "--run",
        "missions/docking.toml",
        "--runs",
        "2",
        "--speed",
        "4",
        "--fault",
        "stop-node:features@20",
    ]);
    let stdout = common::text(&out.stdout);
    let shown = format!("{stdout}\n{}", common::text(&out.stderr));
    assert_eq!(out.status.code(), Some(0), "{shown}");
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
