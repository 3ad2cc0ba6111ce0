//! A simple-one-for-one supervisor's instances leave nothing behind: started, crashed and
//! restarted, terminated by actor or stopped with the supervisor, no actor and no entry
//! remains. In its own test binary (= its own process), because ractor's pid registry, which
//! it counts, is process-global.

mod common;

use std::time::Duration;

use common::*;
use marie_supervision::{Restart, Supervisor, SupervisorSpec};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn thousand_instances_leak_nothing() {
    let before = ractor::registry::get_all_pids().len();
    let log = Log::default();
    let (sup, _) = Supervisor::start(
        None,
        SupervisorSpec::simple_one_for_one(template(&log).with_restart(Restart::Transient))
            .with_intensity(100_000, Duration::from_secs(1)),
        vec![],
    )
    .await
    .unwrap();
    let mut events = sup.subscribe().await.unwrap();
    let mut instances = Vec::with_capacity(1000);
    for n in 0..1000 {
        instances.push(
            sup.start_dynamic(Inst::named(&format!("i{n}")))
                .await
                .unwrap(),
        );
    }
    // every other instance crashes and is restarted as a new actor
    for n in (0..1000).step_by(2) {
        let old = instances[n].clone();
        crash(&old);
        instances[n] = restarted(&mut events, &format!("child#{}", n + 1)).await;
        stopped(&old).await;
    }
    assert_eq!(sup.count_children().await.unwrap().active, 1000);
    assert_eq!(sup.get_cell().get_children().len(), 1000);
    assert_eq!(ractor::registry::get_all_pids().len(), before + 1001);

    // half terminated by actor, half stopped with the supervisor
    for cell in &instances[..500] {
        sup.terminate_actor(cell.get_id()).await.unwrap();
    }
    assert_eq!(sup.which_children().await.unwrap().len(), 500);
    assert_eq!(sup.get_cell().get_children().len(), 500);
    assert_eq!(ractor::registry::get_all_pids().len(), before + 501);
    sup.stop().await;
    assert_eq!(ractor::registry::get_all_pids().len(), before);
    // crashed incarnations run no post_stop; the 500 terminated and the 500 shut down do
    assert_eq!(log.with_prefix("stopped ").len(), 1000);
}
