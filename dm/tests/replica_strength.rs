//! A replicated datamanager tells when it is back to full strength, as actors in one
//! process: a replica stopped (its node lost) and started again on its journal catches up,
//! and the leader tells `dm_replica_caught_up` for it, then `dm_redundancy_restored` — once,
//! with the time since the loss. What `marie up`, the page and an operator wait for before
//! the next fault may strike. A replica that only blinks out of its group and back as the
//! same actor — what the others see when a session to its node is dialled anew — was never
//! lost: nothing is told.

use marie_dm::{
    self as dm, DmClient, DmMsg, DmSpec, Durability, NewRecord, Replication,
    ReplicationTiming as Timing,
};
use marie_vocabulary::clock::RealClock;
use marie_vocabulary::events::{EventBus, EventKind, EventSubscription};
use ractor::{pg, ActorRef};
use std::path::Path;
use std::time::Duration;

/// Generous: elections and catch-up on a loaded 2-core machine.
const DEADLINE: Duration = Duration::from_secs(60);
const NAME: &str = "replicas-strength";
const MEMBERS: [&str; 3] = ["r1", "r2", "r3"];

/// A replica of `NAME` on `me`, journaled in `dir/me`.
async fn start(dir: &Path, me: &str, bus: &EventBus) -> ActorRef<DmMsg> {
    start_of((NAME, 1208), dir, me, bus).await
}

/// A replica of datamanager `(name, id)` on `me`, journaled in `dir/me` (each test its
/// own datamanager: the replicas' groups are the process's).
async fn start_of(
    (name, id): (&'static str, u32),
    dir: &Path,
    me: &str,
    bus: &EventBus,
) -> ActorRef<DmMsg> {
    let mut replication = Replication::new(me, MEMBERS);
    replication.timing = Timing {
        heartbeat: Duration::from_millis(50),
        election: Duration::from_millis(1500),
        lease: Duration::from_millis(600),
    };
    let mut args = DmSpec::new(name, id)
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

/// The replica `actor`'s own view (its node, role, lag and the replicas it reaches).
async fn view_of(actor: &ActorRef<DmMsg>) -> dm::ReplicaStats {
    actor
        .call(|reply| DmMsg::ReplicaStats { reply }, Some(DEADLINE))
        .await
        .expect("the replica answers")
        .expect("in time")
        .replica
        .expect("a replica")
}

/// Wait until the leader's view `fits` (asked again as it changes: the view is the leader's
/// own, not published anywhere to watch).
async fn until_leader_sees(
    leader: &ActorRef<DmMsg>,
    what: &str,
    fits: impl Fn(&dm::ReplicaStats) -> bool,
) {
    let start = std::time::Instant::now();
    loop {
        let view = view_of(leader).await;
        if fits(&view) {
            return;
        }
        assert!(
            start.elapsed() < DEADLINE,
            "{what}: not within {DEADLINE:?}: {view:?}"
        );
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
}

/// The datamanager of the test below.
const BLINKED: &str = "replicas-blinked";

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_replica_out_of_its_group_for_a_moment_and_back_as_itself_is_no_loss() {
    let dir = tempfile::tempdir().unwrap();
    let bus = EventBus::new("test", RealClock::shared());
    let mut replicas = Vec::new();
    for me in MEMBERS {
        replicas.push(start_of((BLINKED, 1209), dir.path(), me, &bus).await);
    }
    let client = DmClient::lookup_within(BLINKED, "tester", DEADLINE)
        .await
        .expect("a leader");
    store(&client, 0, 50).await;
    let leader = client.leader_node().await.expect("the leader's node");
    let at = |node: &str| MEMBERS.iter().position(|m| *m == node).unwrap();
    let lead = replicas[at(&leader)].clone();
    let blinked = *MEMBERS.iter().find(|m| **m != leader).expect("a follower");
    let cell = replicas[at(blinked)].get_cell();
    let group = format!("{BLINKED}/{blinked}");
    let mut events = bus.subscribe();
    // what its peers see when the session to its node ends and is dialled anew: it leaves
    // the group, and comes back — the same live actor, the same start
    pg::leave_scoped(
        dm::REPLICA_SCOPE.to_string(),
        group.clone(),
        vec![cell.clone()],
    );
    until_leader_sees(&lead, "the follower gone", |v| {
        !v.reachable.iter().any(|r| r == blinked)
    })
    .await;
    store(&client, 50, 20).await;
    pg::join_scoped(dm::REPLICA_SCOPE.to_string(), group, vec![cell]);
    store(&client, 70, 20).await;
    // back and current in the leader's view: the acknowledgement that made it current is
    // the one after which a loss would have been told caught up (before this answer)
    until_leader_sees(&lead, "the follower back and current", |v| {
        v.reachable.iter().any(|r| r == blinked) && v.lag.get(blinked) == Some(&0)
    })
    .await;
    let told: Vec<EventKind> = events
        .drain()
        .into_iter()
        .map(|e| e.kind)
        .filter(|k| {
            matches!(
                k,
                EventKind::DmReplicaCaughtUp { .. } | EventKind::DmRedundancyRestored { .. }
            )
        })
        .collect();
    assert!(
        told.is_empty(),
        "a replica never lost told caught up: {told:?}"
    );
}
