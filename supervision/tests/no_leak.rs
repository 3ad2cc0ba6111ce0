//! 1000 crash/restart cycles leave the supervisor with exactly its children and leak no
//! actors. In its own test binary (= its own process), because ractor's pid registry, which
//! it counts, is process-global.

mod common;

use std::time::Duration;

use common::*;
use marie_supervision::{Supervisor, SupervisorSpec};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn thousand_crash_restart_cycles_leak_nothing() {
    let before = ractor::registry::get_all_pids().len();
    let log = Log::default();
    let (sup, _) = Supervisor::start(
        None,
        SupervisorSpec::one_for_one().with_intensity(100_000, Duration::from_secs(1)),
        vec![worker("crashy", &log), worker("steady", &log)],
    )
    .await
    .unwrap();
    let steady = running(&sup, "steady").await;
    let mut events = sup.subscribe().await.unwrap();
    let mut child = running(&sup, "crashy").await;
    let mut old = Vec::with_capacity(1000);
    for _ in 0..1000 {
        crash(&child);
        old.push(child);
        child = restarted(&mut events, "crashy").await;
    }
    drop(events);
    // a crashed incarnation unlinks itself just after its supervisor heard of the crash
    for cell in &old {
        stopped(cell).await;
    }

    let info = sup.which_children().await.unwrap();
    assert_eq!(info.len(), 2);
    assert_eq!(info[0].restarts, 1000);
    assert_eq!(running(&sup, "steady").await, steady);
    let linked = sup.get_cell().get_children();
    assert_eq!(
        linked.len(),
        2,
        "exactly the two current incarnations are linked"
    );
    assert!(linked.contains(&child) && linked.contains(&steady));
    for cell in &old {
        assert!(ractor::registry::where_is_pid(cell.get_id()).is_none());
    }
    // the supervisor and its two children
    assert_eq!(ractor::registry::get_all_pids().len(), before + 3);

    sup.stop().await;
    assert_eq!(ractor::registry::get_all_pids().len(), before);
}
