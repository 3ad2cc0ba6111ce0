//! The replicas of a replicated datamanager, as actors in one process (their protocol does not
//! care where they run: they find each other in `pg` groups and cast each other messages):
//! what the protocol's core asks of the actor is carried out, also by an actor on its way
//! out.
//!
//! The process-level tests (`tests/dm_replicas.rs`, `tests/dm_checker.rs`) kill, freeze and
//! cut off nodes; here the point is one actor's order of doing things.

use marie_dm::{
    self as dm, DmClient, DmMsg, DmSpec, DmStats, Durability, NewRecord, Replication,
    ReplicationTiming as Timing,
};
use marie_vocabulary::clock::RealClock;
use marie_vocabulary::events::{EventBus, EventKind, EventSubscription};
use ractor::ActorRef;
use std::path::Path;
use std::time::Duration;
use tokio::task::JoinHandle;

/// Generous: elections and catch-up on a loaded 2-core machine.
const DEADLINE: Duration = Duration::from_secs(60);
const NAME: &str = "replicas-handover";
const MEMBERS: [&str; 3] = ["r1", "r2", "r3"];

/// Copy `me` of [`NAME`], journaled in `dir/me`, with no supervisor (the test starts an
/// actor that stepped down again, as its node's supervisor would), and its task.
async fn replica(dir: &Path, me: &str, bus: &EventBus) -> (ActorRef<DmMsg>, JoinHandle<()>) {
    let mut replication = Replication::new(me, MEMBERS);
    replication.timing = Timing {
        heartbeat: Duration::from_millis(50),
        election: Duration::from_millis(1500),
    };
    let mut args = DmSpec::new(NAME, 1201)
        .args(RealClock::shared())
        .with_journal(dir.join(me), Durability::Process)
        .with_replication(replication);
    args.events = Some(bus.clone());
    tokio::time::timeout(DEADLINE, dm::spawn_datamanager(args))
        .await
        .expect("spawned in time")
        .expect("the replica starts")
}

async fn stats(actor: &ActorRef<DmMsg>) -> Option<DmStats> {
    match actor
        .call(|reply| DmMsg::Stats { reply }, Some(Duration::from_secs(5)))
        .await
    {
        Ok(ractor::rpc::CallResult::Success(s)) => Some(s),
        _ => None,
    }
}

/// Wait for the next replica of `among` to become the leader (its `dm_promoted` event):
/// which one, and its term.
async fn promoted(events: &mut EventSubscription, among: &[&str]) -> (String, u64) {
    tokio::time::timeout(DEADLINE, async {
        loop {
            let event = events.recv().await.expect("the bus");
            if let EventKind::DmPromoted { node, term, .. } = event.kind {
                if among.contains(&node.as_str()) {
                    return (node, term);
                }
            }
        }
    })
    .await
    .expect("a leader within the deadline")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_primary_handing_over_sends_its_vote_before_it_stops_so_the_preferred_copy_wins_at_once()
{
    // r2 and r3 elect one of them; then the other one is gone and r1, the preferred replica,
    // comes: the leader catches it up and hands it the role. r1's campaign can win only
    // with the old leader's vote (the third replica is gone), and the old leader steps down
    // when it grants it. An actor that stopped at its step-down without sending its answer
    // (as it did) cost r1 that election: r1 won only a later one, once its election timeout
    // passed, with the vote of the old leader started again as a follower.
    let dir = tempfile::tempdir().unwrap();
    let bus = EventBus::new("test", RealClock::shared());
    let mut events = bus.subscribe();
    let (r2, r2_task) = replica(dir.path(), "r2", &bus).await;
    let (r3, r3_task) = replica(dir.path(), "r3", &bus).await;
    let (name, term) = promoted(&mut events, &["r2", "r3"]).await;
    let ((leader, task), other) = if name == "r2" {
        ((r2, r2_task), r3)
    } else {
        ((r3, r3_task), r2)
    };
    eprintln!("{name} leader at term {term}");
    let client = DmClient::new(leader.clone(), "tester");
    for v in 0..100u64 {
        client
            .store_raw(NewRecord::encode("echo", &v).unwrap())
            .await
            .expect("stored and committed");
    }
    // gone before r1 comes (else its vote could elect r1 without the old leader's)
    other
        .stop_and_wait(None, Some(DEADLINE))
        .await
        .expect("the third replica stops");
    let (r1, _) = replica(dir.path(), "r1", &bus).await;
    // the old leader steps down when it votes for r1; it comes back as a follower (a leader's
    // writes are committed only with a second replica)
    tokio::time::timeout(DEADLINE, task)
        .await
        .expect("the old leader stepped down")
        .unwrap();
    let (again, _) = replica(dir.path(), &name, &bus).await;
    let (_, won) = promoted(&mut events, &["r1"]).await;
    assert_eq!(won, term + 1, "r1 won the hand-over's own election");
    let s = stats(&r1).await.expect("r1 answers");
    assert_eq!(
        s.records, 100,
        "r1 holds what the old leader committed: {s:#?}"
    );
    r1.stop(None);
    again.stop(None);
}
