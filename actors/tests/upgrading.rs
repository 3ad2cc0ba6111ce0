//! A binding moved to a newer version at an action's start, in-process: the move's raised
//! epoch reaches the fence keepers, as an adoption's does, before the new instance's first
//! command (the keepers' tables hold it; only an announcement advances them).

mod common;

use common::ops::Worker;
use marie_actors::dispatcher::mission::ParsedMission;
use marie_actors::dispatcher::{run_mission, RegistryCatalog};
use marie_vocabulary::clock::RealClock;
use marie_vocabulary::events::{EventBus, EventKind};
use marie_vocabulary::fence::{spawn_keeper, FenceTable};
use marie_vocabulary::run::Outcome;
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::time::timeout;

const T: Duration = Duration::from_secs(30);

/// Two actions of operation `mover`: the first long enough (3 s of 2 ms steps) for a newer
/// instance to join while it runs, the second the one whose start moves the binding.
const MISSION: &str = r#"
    [mission]
    name = "move"
    success = ["done"]
    [flags]
    done = 0
    [[action]]
    name = "first"
    [action.ops.mover]
    steps = 1500
    [[action]]
    name = "second"
    [action.ops.mover]
    steps = 5
"#;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_moves_raised_epoch_is_announced_to_the_fence_keepers() {
    let old = Worker::new("mover", 4301, "1.0.0").start().await;
    let table = Arc::new(Mutex::new(FenceTable::default()));
    let _keeper = spawn_keeper(table.clone(), old.actor().get_cell())
        .await
        .unwrap();
    let parsed = ParsedMission::parse(MISSION, None).expect("mission parses");
    let keys: Vec<String> = parsed.ops().map(str::to_string).collect();
    let catalog = RegistryCatalog::gather(keys).await.unwrap();
    let mission = parsed.validate(&catalog).expect("mission validates");
    let clock = RealClock::shared();
    let bus = EventBus::new("test", clock.clone());
    let mut events = bus.subscribe();
    let run = tokio::spawn(async move {
        timeout(T, run_mission(mission, clock, Some(bus)))
            .await
            .expect("mission ends")
            .expect("dispatcher runs")
    });
    // the newer version joins while `first` runs on version 1.0.0
    timeout(T, async {
        loop {
            let e = events.recv().await.expect("events end early");
            if matches!(&e.kind, EventKind::ActionStarted { action, .. } if action == "first") {
                return;
            }
        }
    })
    .await
    .expect("first starts");
    let newer = Worker::new("mover", 4301, "1.1.0").start().await;
    let report = run.await.unwrap();
    assert_eq!(report.outcome, Outcome::Succeeded, "{report:#?}");
    let [up] = report.upgrades.as_slice() else {
        panic!("one move expected: {:#?}", report.upgrades)
    };
    assert_eq!(
        (up.action.as_str(), up.to_version.as_str()),
        ("second", "1.1.0")
    );
    assert_eq!(up.to, newer.actor().get_id().to_string());
    // the keeper's table holds the move's epoch: announced (a command advances only the
    // receiver's own table, never a keeper's)
    assert_eq!(table.lock().unwrap().newest("mover"), Some(up.epoch));
    newer.actor().stop(None);
    old.actor().stop(None);
}
