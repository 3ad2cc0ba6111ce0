//! The copies of a replicated datamanager, as actors in one process (their protocol does not
//! care where they run: they find each other in `pg` groups and cast each other messages):
//! what the protocol's core asks of the actor is carried out, also by an actor on its way
//! out.
//!
//! The process-level tests (`tests/dm_replicas.rs`, `tests/dm_checker.rs`) kill, freeze and
//! cut off nodes; here the point is one actor's order of doing things.

use marie_actors::clock::RealClock;
use marie_actors::dm::replica::{Replication, Timing};
use marie_actors::dm::{self, DmClient, DmMsg, DmSpec, DmStats, Durability, NewRecord};
use ractor::ActorRef;
use std::path::Path;
use std::time::Duration;
use tokio::task::JoinHandle;

/// Generous: elections and catch-up on a loaded 2-core machine.
const DEADLINE: Duration = Duration::from_secs(60);
const NAME: &str = "copies-handover";
const MEMBERS: [&str; 3] = ["r1", "r2", "r3"];

/// Copy `me` of [`NAME`], journaled in `dir/me`, with no supervisor (the test starts an
/// actor that stepped down again, as its node's supervisor would), and its task.
async fn copy(dir: &Path, me: &str) -> (ActorRef<DmMsg>, JoinHandle<()>) {
    let mut replication = Replication::new(me, MEMBERS);
    replication.timing = Timing {
        heartbeat: Duration::from_millis(50),
        election: Duration::from_millis(1500),
    };
    let args = DmSpec::new(NAME, 1201)
        .args(RealClock::shared())
        .with_journal(dir.join(me), Durability::Process)
        .with_replication(replication);
    tokio::time::timeout(DEADLINE, dm::spawn_datamanager(args))
        .await
        .expect("spawned in time")
        .expect("the copy starts")
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

/// Wait until one of `copies` says it is the primary: which one, and its term.
async fn primary_among(copies: &[&ActorRef<DmMsg>]) -> (usize, u64) {
    tokio::time::timeout(DEADLINE, async {
        loop {
            for (i, c) in copies.iter().enumerate() {
                if let Some(r) = stats(c).await.and_then(|s| s.replica) {
                    if r.role == "primary" {
                        return (i, r.term);
                    }
                }
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    })
    .await
    .expect("a primary within the deadline")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_primary_handing_over_sends_its_vote_before_it_stops_so_the_preferred_copy_wins_at_once()
{
    // r2 and r3 elect one of them; then the other one is gone and r1, the preferred copy,
    // comes: the primary catches it up and hands it the role. r1's campaign can win only
    // with the old primary's vote (the third copy is gone), and the old primary steps down
    // when it grants it. An actor that stopped at its step-down without sending its answer
    // (as it did) cost r1 that election: r1 won only a later one, once its election timeout
    // passed, with the vote of the old primary started again as a copy.
    let dir = tempfile::tempdir().unwrap();
    let (r2, r2_task) = copy(dir.path(), "r2").await;
    let (r3, r3_task) = copy(dir.path(), "r3").await;
    let (i, term) = primary_among(&[&r2, &r3]).await;
    let ((primary, task, name), other) = if i == 0 {
        ((r2, r2_task, "r2"), r3)
    } else {
        ((r3, r3_task, "r3"), r2)
    };
    eprintln!("{name} primary at term {term}");
    let client = DmClient::new(primary.clone(), "tester");
    for v in 0..100u64 {
        client
            .store_raw(NewRecord::encode("echo", &v).unwrap())
            .await
            .expect("stored and committed");
    }
    other.stop(None);
    let (r1, _) = copy(dir.path(), "r1").await;
    // the old primary steps down when it votes for r1; it comes back as a copy (a primary's
    // writes are committed only with a second copy)
    tokio::time::timeout(DEADLINE, task)
        .await
        .expect("the old primary stepped down")
        .unwrap();
    let (again, _) = copy(dir.path(), name).await;
    let (_, won) = primary_among(&[&r1]).await;
    assert_eq!(won, term + 1, "r1 won the hand-over's own election");
    let s = stats(&r1).await.expect("r1 answers");
    assert_eq!(
        s.records, 100,
        "r1 holds what the old primary committed: {s:#?}"
    );
    r1.stop(None);
    again.stop(None);
}
