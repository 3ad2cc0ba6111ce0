//! The replicas of a replicated datamanager changed while it runs, as actors in one process:
//! a replica started to join catches up as a learner and is promoted, one is removed, each
//! step told as an event; the configuration is journaled, so a replica restarted with the
//! configured members (which do not name it) recovers the current ones from its journal.
//! The process-level proof (3 → 5 → 3 under puts) is `tests/dm_members.rs`.

use marie_dm::{
    self as dm, Change, ChangeError, DmClient, DmMsg, DmSpec, DmStats, Durability, NewRecord,
    Query, Replication, ReplicationTiming as Timing,
};
use marie_vocabulary::clock::RealClock;
use marie_vocabulary::events::{EventBus, EventKind, EventSubscription};
use ractor::rpc::CallResult;
use ractor::ActorRef;
use std::path::Path;
use std::time::Duration;

/// Generous: elections and catch-up on a loaded 2-core machine.
const DEADLINE: Duration = Duration::from_secs(60);
const NAME: &str = "replicas-members";
const MEMBERS: [&str; 3] = ["r1", "r2", "r3"];

fn timing() -> Timing {
    Timing {
        heartbeat: Duration::from_millis(50),
        election: Duration::from_millis(1500),
        lease: Duration::from_millis(600),
    }
}

/// A replica on `me`, journaled in `dir/me`, as `replication` says.
async fn start(dir: &Path, mut replication: Replication, bus: &EventBus) -> ActorRef<DmMsg> {
    replication.timing = timing();
    let me = replication.me.clone();
    let mut args = DmSpec::new(NAME, 1207)
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

/// What the replica `actor` itself holds.
async fn stats(actor: &ActorRef<DmMsg>) -> DmStats {
    match actor
        .call(
            |reply| DmMsg::ReplicaStats { reply },
            Some(Duration::from_secs(5)),
        )
        .await
    {
        Ok(CallResult::Success(s)) => s,
        other => panic!("no stats: {other:?}"),
    }
}

/// Wait for the first event `pick` takes.
async fn event<T>(
    events: &mut EventSubscription,
    mut pick: impl FnMut(EventKind) -> Option<T>,
) -> T {
    tokio::time::timeout(DEADLINE, async {
        loop {
            if let Some(t) = pick(events.recv().await.expect("the bus").kind) {
                return t;
            }
        }
    })
    .await
    .expect("the event within the deadline")
}

/// Wait until `actor`'s own stats satisfy `ok`.
async fn until(actor: &ActorRef<DmMsg>, ok: impl Fn(&DmStats) -> bool) -> DmStats {
    let since = std::time::Instant::now();
    loop {
        let s = stats(actor).await;
        if ok(&s) {
            return s;
        }
        assert!(since.elapsed() < DEADLINE, "never: {s:#?}");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_replica_joins_as_a_learner_is_promoted_another_is_removed_and_a_restart_remembers() {
    let dir = tempfile::tempdir().unwrap();
    let bus = EventBus::new("test", RealClock::shared());
    let mut events = bus.subscribe();
    let mut replicas = Vec::new();
    for me in MEMBERS {
        replicas.push(start(dir.path(), Replication::new(me, MEMBERS), &bus).await);
    }
    let client = DmClient::lookup_within(NAME, "tester", DEADLINE)
        .await
        .expect("a leader");
    for v in 0..200u64 {
        client
            .store_raw(NewRecord::encode("echo", &v).unwrap())
            .await
            .expect("stored");
    }
    // refused as they must be
    assert_eq!(
        client
            .change_replicas(Change::Add("r1".into()))
            .await
            .unwrap(),
        Err(ChangeError::AlreadyMember("r1".into()))
    );
    assert!(matches!(
        client
            .change_replicas(Change::Remove("r1".into()))
            .await
            .unwrap(),
        Err(ChangeError::TooFew { left: 2, .. })
    ));
    // r4 starts to join, and is added: a learner, caught up, promoted
    let r4 = start(dir.path(), Replication::joining("r4", MEMBERS), &bus).await;
    let seq = client
        .change_replicas(Change::Add("r4".into()))
        .await
        .expect("asked")
        .expect("added");
    assert!(seq > 200, "a log entry after the records: {seq}");
    let added = event(&mut events, |k| match k {
        EventKind::DmReplicaAdded { node, voters, .. } => Some((node, voters)),
        _ => None,
    })
    .await;
    assert_eq!(
        added,
        (
            "r4".to_string(),
            vec!["r1".into(), "r2".into(), "r3".into()]
        )
    );
    let promoted = event(&mut events, |k| match k {
        EventKind::DmReplicaPromoted { node, voters, .. } => Some((node, voters)),
        _ => None,
    })
    .await;
    assert_eq!(promoted.0, "r4");
    assert_eq!(promoted.1, ["r1", "r2", "r3", "r4"]);
    let s = until(&r4, |s| s.records == 200).await;
    let r = s.replica.expect("a replica");
    assert_eq!(r.members, ["r1", "r2", "r3", "r4"]);
    assert!(r.learners.is_empty());
    // r2 removed: the others go on, it takes no part
    client
        .change_replicas(Change::Remove("r2".into()))
        .await
        .expect("asked")
        .expect("removed");
    let removed = event(&mut events, |k| match k {
        EventKind::DmReplicaRemoved { node, voters, .. } => Some((node, voters)),
        _ => None,
    })
    .await;
    assert_eq!(
        removed,
        (
            "r2".to_string(),
            vec!["r1".into(), "r3".into(), "r4".into()]
        )
    );
    until(&replicas[1], |s| {
        s.replica.as_ref().is_some_and(|r| r.removed)
    })
    .await;
    let seq = client
        .store_raw(NewRecord::encode("echo", &200u64).unwrap())
        .await
        .expect("stored by the three voters left");
    // r4 restarted as the cluster file would start it (its members do not name it): its
    // journal says what the replicas are
    r4.stop_and_wait(None, Some(DEADLINE)).await.unwrap();
    let r4 = start(dir.path(), Replication::joining("r4", MEMBERS), &bus).await;
    let s = until(&r4, |s| s.replica.as_ref().is_some_and(|r| r.commit >= seq)).await;
    let r = s.replica.expect("a replica");
    assert_eq!(r.members, ["r1", "r3", "r4"], "from its journal");
    assert!(!r.removed);
    assert_eq!(s.records, 201);
    let all = client.select(Query::class("echo")).await.expect("a select");
    assert_eq!(all.len(), 201);
}
