//! A replicated datamanager's leader tells a replica lost and caught up only when it was:
//! a session to a live replica's node that ends and is dialled anew — what ractor_cluster
//! shows as another actor of that replica (a remote actor's id is its session's), after a
//! moment out of its group — is no loss, and nothing is told; the same replica's node
//! killed and started again is one, told caught up and the redundancy restored.
//!
//! The leader is a replica in this test process (the preferred one, `r1`), a member of the
//! cluster of two `marie node` processes that keep the others: here the session can be
//! ended as ractor_cluster ends it (its `NodeSession` stopped), and the leader's own events
//! read from its bus.

use crate::common;

use common::cluster::NodeProc;
use common::ONE_MEMBER;
use marie::cluster::net::{ClusterConfig, Transport};
use marie::dm::{self, DmClient, DmMsg, Durability, NewRecord, ReplicaStats};
use marie::events::{EventBus, EventKind, EventSubscription};
use marie::replica::ReplicaRole;
use ractor::{pg, ActorRef};
use std::path::Path;
use std::time::{Duration, Instant};

const COOKIE: &str = "strength";
/// The replicas' nodes: `r1` is this process.
const NODES: [&str; 3] = ["r1", "r2", "r3"];
/// Generous: a node's start, elections, catching up, on a loaded 2-core machine.
const T: Duration = Duration::from_secs(60);

/// Node `name`'s config: a replica of `feature` on each of [`NODES`].
fn hosts(dir: &Path, name: &str) -> String {
    format!(
        "data_dir = \"{}\"\n[[datamanager]]\nname = \"feature\"\ncopies = [\"r1\", \"r2\", \"r3\"]\n",
        dir.join(name).display()
    )
}

/// The replica `actor`'s own view.
async fn view_of(actor: &ActorRef<DmMsg>) -> ReplicaStats {
    actor
        .call(|reply| DmMsg::ReplicaStats { reply }, Some(T))
        .await
        .expect("the replica answers")
        .expect("in time")
        .replica
        .expect("a replica")
}

/// Wait until `r1`'s view `fits` (its own view: asked again until it does).
async fn until_r1(r1: &ActorRef<DmMsg>, what: &str, fits: impl Fn(&ReplicaStats) -> bool) {
    let start = Instant::now();
    loop {
        let view = view_of(r1).await;
        if fits(&view) {
            return;
        }
        assert!(start.elapsed() < T, "{what}: not within {T:?}: {view:#?}");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}

/// `r1` leads, reaches both others, and counts them current.
fn leads_with_all_current(v: &ReplicaStats) -> bool {
    v.role == ReplicaRole::Leader
        && ["r2", "r3"]
            .iter()
            .all(|n| v.reachable.iter().any(|r| r == n) && v.lag.get(*n) == Some(&0))
}

async fn store(client: &DmClient, values: std::ops::Range<u64>) {
    for v in values {
        client
            .store_raw(NewRecord::encode("echo", &v).unwrap())
            .await
            .expect("stored");
    }
}

/// The leader's news of its strength waiting on the bus now.
fn strength_news(events: &mut EventSubscription) -> Vec<EventKind> {
    events
        .drain()
        .into_iter()
        .map(|e| e.kind)
        .filter(|k| {
            matches!(
                k,
                EventKind::DmReplicaCaughtUp { .. } | EventKind::DmRedundancyRestored { .. }
            )
        })
        .collect()
}

/// The actor standing in here for r2's replica (a remote one's shim, a child of its
/// session), if r2's replica is reachable.
fn r2_stand_in() -> Option<ractor::ActorCell> {
    pg::get_scoped_members(&dm::REPLICA_SCOPE.to_string(), &"feature/r2".to_string())
        .into_iter()
        .find(|c| !c.get_id().is_local() && c.get_status() <= ractor::ActorStatus::Running)
}

#[test]
fn a_session_to_a_live_replica_dialled_anew_is_no_loss_and_its_node_restarted_is_one() {
    let _one = ONE_MEMBER.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let mut nodes: Vec<NodeProc> = Vec::new();
    for name in ["r2", "r3"] {
        let peers: Vec<_> = nodes.iter().map(|n| n.addr).collect();
        let config = hosts(dir.path(), name);
        nodes.push(NodeProc::start(dir.path(), name, &config, &peers, COOKIE));
    }
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap();
    rt.block_on(async {
        let mut me = ClusterConfig::new("127.0.0.1:0".parse().unwrap(), COOKIE);
        for n in &nodes {
            me = me.with_peer(n.addr);
        }
        let transport = Transport::start("r1", &me).await.unwrap();
        transport.wait_for_peers(2, T).await.unwrap();
        let clock = marie::clock::RealClock::shared();
        let bus = EventBus::new("r1", clock.clone());
        let mut args = dm::FEATURE
            .args(clock)
            .with_journal(dir.path().join("r1"), Durability::Process)
            .with_replication(dm::Replication::new("r1", NODES));
        args.events = Some(bus.clone());
        let (r1, _) = dm::spawn_datamanager(args).await.expect("r1 starts");
        // the preferred replica is handed the role once it caught up
        until_r1(&r1, "r1 leading, r2 and r3 current", leads_with_all_current).await;
        let client = DmClient::lookup("feature", "producer")
            .unwrap()
            .with_follow(T);
        store(&client, 0..50).await;
        until_r1(&r1, "r2 and r3 current", leads_with_all_current).await;
        let mut events = bus.subscribe();

        // the session to r2's node ends, as ractor_cluster ends one (its NodeSession
        // stopped), and the transport dials it anew: r2's replica, alive all along, is
        // found through another session — another actor id, the same start
        let before = r2_stand_in().expect("r2's replica reachable");
        let session = before.try_get_supervisor().expect("its session");
        session.stop(Some("test: the session ends".into()));
        let start = Instant::now();
        let after = loop {
            if let Some(c) = r2_stand_in().filter(|c| c.get_id() != before.get_id()) {
                break c;
            }
            assert!(start.elapsed() < T, "no new session to r2 within {T:?}");
            tokio::time::sleep(Duration::from_millis(10)).await;
        };
        eprintln!(
            "r2's replica found through a new session {} ms after the old one ended",
            start.elapsed().as_millis()
        );
        assert_eq!(
            (after.get_id().pid(), after.get_name()),
            (before.get_id().pid(), before.get_name()),
            "the same remote actor through another session"
        );
        store(&client, 50..100).await;
        // back and current in the leader's view: a loss would have been told caught up
        // at the acknowledgement that made it so, before this answer
        until_r1(&r1, "r2 back and current", leads_with_all_current).await;
        let told = strength_news(&mut events);
        assert!(told.is_empty(), "a replica never lost told caught up: {told:?}");

        // r2's node killed and started again: its replica is lost, and told caught up
        nodes[0].signal("KILL");
        until_r1(&r1, "r2 gone", |v| !v.reachable.iter().any(|r| r == "r2")).await;
        store(&client, 100..150).await;
        let peers = [nodes[1].addr, transport.listen()];
        let config = hosts(dir.path(), "r2");
        nodes[0] = NodeProc::start(dir.path(), "r2", &config, &peers, COOKIE);
        let mut news = Vec::new();
        tokio::time::timeout(T, async {
            loop {
                let kind = events.recv().await.expect("the bus").kind;
                if let EventKind::DmReplicaCaughtUp { .. } = kind {
                    news.push(kind);
                } else if let EventKind::DmRedundancyRestored { .. } = kind {
                    news.push(kind);
                    return;
                }
            }
        })
        .await
        .unwrap_or_else(|_| panic!("r2 not told caught up within {T:?}: {news:?}"));
        match news.as_slice() {
            [EventKind::DmReplicaCaughtUp { node, after_ms, .. }, EventKind::DmRedundancyRestored { replicas: 3, .. }] =>
            {
                assert_eq!(node, "r2");
                assert!(*after_ms > 0, "{news:?}");
            }
            other => panic!("{other:?}"),
        }
        transport.stop().await;
    });
}
