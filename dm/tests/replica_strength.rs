//! A replicated datamanager tells when it is back to full strength, as actors in one
//! process: a replica stopped (its node lost) and started again on its journal catches up,
//! and the leader tells `dm_replica_caught_up` for it, then `dm_redundancy_restored` — once,
//! with the time since the loss. What `marie up`, the page and an operator wait for before
//! the next fault may strike.

use marie_dm::{
    self as dm, DmClient, DmMsg, DmSpec, Durability, NewRecord, Replication,
    ReplicationTiming as Timing,
};
use marie_vocabulary::clock::RealClock;
use marie_vocabulary::events::{EventBus, EventKind, EventSubscription};
use ractor::ActorRef;
use std::path::Path;
use std::time::Duration;

/// Generous: elections and catch-up on a loaded 2-core machine.
const DEADLINE: Duration = Duration::from_secs(60);
const NAME: &str = "replicas-strength";
const MEMBERS: [&str; 3] = ["r1", "r2", "r3"];

/// A replica on `me`, journaled in `dir/me`.
async fn start(dir: &Path, me: &str, bus: &EventBus) -> ActorRef<DmMsg> {
    let mut replication = Replication::new(me, MEMBERS);
    replication.timing = Timing {
        heartbeat: Duration::from_millis(50),
        election: Duration::from_millis(1500),
        lease: Duration::from_millis(600),
    };
    let mut args = DmSpec::new(NAME, 1208)
        .args(RealClock::shared())
        .with_journal(dir.join(me), Durability::Process)
        .with_replication(replication);
    args.events = Some(bus.clone());
    tokio::time::timeout(DEADLINE, dm::spawn_datamanager(args))
        .await
        .expect("spawned in time")
        .expect("the replica starts")
        .0
}

/// The datamanager's news of its strength, in order, until (and with) the restoration.
async fn strength_until_restored(events: &mut EventSubscription) -> Vec<EventKind> {
    let mut seen = Vec::new();
    tokio::time::timeout(DEADLINE, async {
        loop {
            let kind = events.recv().await.expect("the bus").kind;
            match kind {
                EventKind::DmReplicaCaughtUp { .. } => seen.push(kind),
                EventKind::DmRedundancyRestored { .. } => {
                    seen.push(kind);
                    return;
                }
                _ => {}
            }
        }
    })
    .await
    .unwrap_or_else(|_| panic!("not restored within the deadline; saw {seen:?}"));
    seen
}

async fn store(client: &DmClient, from: u64, n: u64) {
    for v in from..from + n {
        client
            .store_raw(NewRecord::encode("echo", &v).unwrap())
            .await
            .expect("stored");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_lost_replica_started_again_is_told_caught_up_and_the_redundancy_restored_once() {
    let dir = tempfile::tempdir().unwrap();
    let bus = EventBus::new("test", RealClock::shared());
    let mut replicas = Vec::new();
    for me in MEMBERS {
        replicas.push(start(dir.path(), me, &bus).await);
    }
    let client = DmClient::lookup_within(NAME, "tester", DEADLINE)
        .await
        .expect("a leader");
    store(&client, 0, 100).await;
    let leader = client.leader_node().await.expect("the leader's node");
    let (i, lost) = MEMBERS
        .iter()
        .enumerate()
        .find(|(_, m)| **m != leader)
        .expect("a follower");
    let mut events = bus.subscribe();
    replicas[i]
        .stop_and_wait(None, Some(DEADLINE))
        .await
        .unwrap();
    // entries it lacks when it comes back
    store(&client, 100, 100).await;
    replicas[i] = start(dir.path(), lost, &bus).await;
    let news = strength_until_restored(&mut events).await;
    match news.as_slice() {
        [EventKind::DmReplicaCaughtUp {
            dm,
            node,
            after_ms: caught,
        }, EventKind::DmRedundancyRestored {
            replicas,
            after_ms: restored,
            ..
        }] => {
            assert_eq!((dm.as_str(), node.as_str()), (NAME, *lost));
            assert_eq!(*replicas, 3);
            assert!(*caught > 0 && caught <= restored, "{news:?}");
        }
        other => panic!("{other:?}"),
    }
    // told once: more writes, all current, nothing more to tell
    store(&client, 200, 50).await;
    let more = tokio::time::timeout(Duration::from_millis(500), async {
        loop {
            let kind = events.recv().await.expect("the bus").kind;
            if matches!(
                kind,
                EventKind::DmReplicaCaughtUp { .. } | EventKind::DmRedundancyRestored { .. }
            ) {
                return kind;
            }
        }
    })
    .await;
    assert!(more.is_err(), "told again: {more:?}");
}
