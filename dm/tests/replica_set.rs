//! The replicas of a replicated datamanager, as actors in one process (their protocol does not
//! care where they run: they find each other in `pg` groups and cast each other messages):
//! what the protocol's core asks of the actor is carried out, also by a leader stepping down,
//! which goes on as the same actor (a follower), and a leader answers reads only while it is
//! sure to lead.
//!
//! The process-level tests (`tests/dm_replicas.rs`, `tests/dm_checker.rs`) kill, freeze and
//! cut off nodes; here the point is one actor's order of doing things.

use marie_dm::{
    self as dm, DmClient, DmMsg, DmSpec, DmStats, Durability, NewRecord, Query, Replication,
    ReplicationTiming as Timing,
};
use marie_vocabulary::clock::RealClock;
use marie_vocabulary::events::{EventBus, EventKind, EventSubscription};
use marie_vocabulary::registry::{self, ModuleKind};
use marie_vocabulary::replica::ReplicaRole;
use ractor::rpc::CallResult;
use ractor::{Actor, ActorCell, ActorId, ActorProcessingErr, ActorRef, SupervisionEvent};
use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::task::JoinHandle;

/// Generous: elections and catch-up on a loaded 2-core machine.
const DEADLINE: Duration = Duration::from_secs(60);
const NAME: &str = "replicas-handover";
const MEMBERS: [&str; 3] = ["r1", "r2", "r3"];

/// The replicas' parent, as their node's supervisor would be: it notes every child that
/// stopped or failed (what a supervisor would restart).
struct Parent;

/// The children that stopped or failed: (which, how).
type Exits = Arc<Mutex<Vec<(ActorId, String)>>>;

impl Actor for Parent {
    type Msg = ();
    type State = Exits;
    type Arguments = Exits;

    async fn pre_start(
        &self,
        _: ActorRef<()>,
        exits: Self::Arguments,
    ) -> Result<Self::State, ActorProcessingErr> {
        Ok(exits)
    }

    async fn handle_supervisor_evt(
        &self,
        _: ActorRef<()>,
        event: SupervisionEvent,
        exits: &mut Self::State,
    ) -> Result<(), ActorProcessingErr> {
        match event {
            SupervisionEvent::ActorTerminated(who, _, why) => exits
                .lock()
                .unwrap()
                .push((who.get_id(), format!("stopped: {why:?}"))),
            SupervisionEvent::ActorFailed(who, e) => exits
                .lock()
                .unwrap()
                .push((who.get_id(), format!("failed: {e}"))),
            _ => {}
        }
        Ok(())
    }
}

/// A parent for replicas, and the exits it saw.
async fn parent() -> (ActorCell, Exits) {
    let exits = Arc::new(Mutex::new(Vec::new()));
    let (actor, _) = Actor::spawn(None, Parent, exits.clone())
        .await
        .expect("the parent starts");
    (actor.get_cell(), exits)
}

fn timing() -> Timing {
    Timing {
        heartbeat: Duration::from_millis(50),
        election: Duration::from_millis(1500),
        lease: Duration::from_millis(600),
    }
}

/// Replica `me` of datamanager `name`, journaled in `dir/me`, linked to `parent` (which
/// restarts nothing: a replica that stopped stays stopped), and its task.
async fn replica_of(
    name: &'static str,
    dir: &Path,
    me: &str,
    bus: &EventBus,
    parent: &ActorCell,
) -> (ActorRef<DmMsg>, JoinHandle<()>) {
    let mut replication = Replication::new(me, MEMBERS);
    replication.timing = timing();
    let mut args = DmSpec::new(name, 1201)
        .args(RealClock::shared())
        .with_journal(dir.join(me), Durability::Process)
        .with_replication(replication);
    args.events = Some(bus.clone());
    tokio::time::timeout(DEADLINE, dm::spawn_datamanager_linked(args, parent.clone()))
        .await
        .expect("spawned in time")
        .expect("the replica starts")
}

/// Replica `me` of [`NAME`].
async fn replica(
    dir: &Path,
    me: &str,
    bus: &EventBus,
    parent: &ActorCell,
) -> (ActorRef<DmMsg>, JoinHandle<()>) {
    replica_of(NAME, dir, me, bus, parent).await
}

/// What the replica `actor` itself holds (its `Stats` a follower sends on to its leader).
async fn stats(actor: &ActorRef<DmMsg>) -> Option<DmStats> {
    match actor
        .call(
            |reply| DmMsg::ReplicaStats { reply },
            Some(Duration::from_secs(5)),
        )
        .await
    {
        Ok(CallResult::Success(s)) => Some(s),
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

/// Wait for the leader on `node` to step down (its `dm_fenced` event): why.
async fn fenced(events: &mut EventSubscription, node: &str) -> String {
    tokio::time::timeout(DEADLINE, async {
        loop {
            let event = events.recv().await.expect("the bus");
            if let EventKind::DmFenced { node: on, why, .. } = event.kind {
                if on == node {
                    return why;
                }
            }
        }
    })
    .await
    .expect("it stepped down within the deadline")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_leader_handing_over_sends_its_vote_and_goes_on_as_the_same_actor_a_follower() {
    // r2 and r3 elect one of them; then the other one is gone and r1, the preferred replica,
    // comes: the leader catches it up and hands it the role. r1's campaign can win only
    // with the old leader's vote (the third replica is gone), and the old leader steps down
    // when it grants it. An actor that stopped at its step-down without sending its answer
    // cost r1 that election (r1 won only a later one, once its election timeout passed).
    // The old leader used to stop and be started again as a follower (a supervisor restart
    // per change of role, and every client's reference to it dead); now it is the same
    // actor, a follower: not restarted, no longer published, and a client that holds it is
    // sent on to r1.
    let dir = tempfile::tempdir().unwrap();
    let bus = EventBus::new("test", RealClock::shared());
    let mut events = bus.subscribe();
    let (parent, exits) = parent().await;
    let (r2, r2_task) = replica(dir.path(), "r2", &bus, &parent).await;
    let (r3, r3_task) = replica(dir.path(), "r3", &bus, &parent).await;
    let (name, term) = promoted(&mut events, &["r2", "r3"]).await;
    let ((leader, task), other) = if name == "r2" {
        ((r2, r2_task), r3)
    } else {
        ((r3, r3_task), r2)
    };
    eprintln!("{name} leader at term {term}");
    let client = DmClient::new(leader.clone(), "tester");
    assert_eq!(client.actor().get_id(), leader.get_id());
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
    let (r1, _) = replica(dir.path(), "r1", &bus, &parent).await;
    // the old leader steps down when it votes for r1, and goes on as a follower
    let why = fenced(&mut events, &name).await;
    eprintln!("{name} stepped down: {why}");
    let (_, won) = promoted(&mut events, &["r1"]).await;
    assert_eq!(won, term + 1, "r1 won the hand-over's own election");
    let s = stats(&r1).await.expect("r1 answers");
    assert_eq!(
        s.records, 100,
        "r1 holds what the old leader committed: {s:#?}"
    );
    // the same actor, alive, a follower of r1
    assert!(!task.is_finished(), "the old leader's actor lives on");
    let s = stats(&leader)
        .await
        .expect("the old leader's actor answers");
    let replica = s.replica.expect("a replica's stats");
    assert_eq!(
        (replica.role, replica.leader.as_deref(), replica.term),
        (ReplicaRole::Follower, Some("r1"), won),
        "the old leader follows r1"
    );
    // withdrawn from the datamanager's name; only r1 published
    let published: Vec<_> = registry::lookup(ModuleKind::Datamanager, NAME)
        .into_iter()
        .map(|i| i.actor.get_id())
        .collect();
    assert_eq!(published, vec![r1.get_id()], "only r1 is published");
    // a client still holding the old leader keeps a valid reference: its requests are sent
    // on to r1, which answers them — a put, a select, a store
    assert_eq!(client.actor().get_id(), leader.get_id());
    client
        .put_raw(NewRecord::encode("put", &1u64).unwrap())
        .expect("a put cast");
    let records = client.select(Query::class("echo")).await.expect("a select");
    assert_eq!(records.len(), 100, "answered by r1");
    let seq = client
        .store_raw(NewRecord::encode("echo", &100u64).unwrap())
        .await
        .expect("a store sent on to r1");
    let r1_client = DmClient::new(r1.clone(), "reader");
    let echo = r1_client.select(Query::class("echo")).await.expect("r1's");
    assert_eq!(
        (echo.len(), echo.last().map(|r| r.seq)),
        (101, Some(seq)),
        "the store is at r1"
    );
    let put = r1_client
        .select_wait(Query::class("put"), DEADLINE)
        .await
        .expect("r1's");
    assert_eq!(put.len(), 1, "the put went on to r1");
    assert_eq!(
        client.actor().get_id(),
        leader.get_id(),
        "the same reference"
    );
    // the old leader never stopped: no restart for the supervisor
    let exits: Vec<_> = exits.lock().unwrap().clone();
    assert!(
        exits.iter().all(|(id, _)| *id != leader.get_id()),
        "the old leader stopped: {exits:?}"
    );
    r1.stop(None);
    leader.stop(None);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_leader_cut_off_from_its_replicas_refuses_reads_and_steps_down_as_the_same_actor() {
    // its lease lapses without the replicas' word; a read then waits for their word, which
    // never comes, and is refused (its reply port dropped: the caller looks for the leader
    // elsewhere) — never answered from a store a new leader may have moved past
    let name = "replicas-reads";
    let dir = tempfile::tempdir().unwrap();
    let bus = EventBus::new("test", RealClock::shared());
    let mut events = bus.subscribe();
    let (parent, exits) = parent().await;
    let mut replicas = Vec::new();
    for me in MEMBERS {
        replicas.push(replica_of(name, dir.path(), me, &bus, &parent).await);
    }
    let (leader_node, _) = promoted(&mut events, &MEMBERS).await;
    let i = MEMBERS.iter().position(|m| *m == leader_node).unwrap();
    let (leader, task) = replicas.remove(i);
    let client = DmClient::new(leader.clone(), "tester").with_follow(Duration::ZERO);
    client
        .store_raw(NewRecord::encode("echo", &1u64).unwrap())
        .await
        .expect("stored");
    let select = || {
        leader.call(
            |reply| DmMsg::Select {
                query: Box::new(Query::class("echo")),
                reply,
            },
            Some(DEADLINE),
        )
    };
    assert!(
        matches!(select().await, Ok(CallResult::Success(r)) if r.len() == 1),
        "answered while the replicas follow it"
    );
    for (other, _) in replicas {
        other
            .stop_and_wait(None, Some(DEADLINE))
            .await
            .expect("a follower stops");
    }
    // a read asked once its lease has lapsed is refused, not answered
    tokio::time::sleep(timing().lease).await;
    let answer = select().await;
    assert!(
        matches!(answer, Ok(CallResult::SenderError)),
        "a read refused: {answer:?}"
    );
    let why = fenced(&mut events, &leader_node).await;
    assert!(why.contains("majority"), "{why}");
    // the same actor, a follower now, refusing reads at once (a client follows the name)
    assert!(!task.is_finished(), "the actor lives on");
    let s = stats(&leader).await.expect("it answers its stats");
    assert_eq!(s.replica.unwrap().role, ReplicaRole::Follower);
    assert!(matches!(select().await, Ok(CallResult::SenderError)));
    assert!(registry::lookup(ModuleKind::Datamanager, name).is_empty());
    let exits: Vec<_> = exits.lock().unwrap().clone();
    assert!(
        exits.iter().all(|(id, _)| *id != leader.get_id()),
        "the old leader stopped: {exits:?}"
    );
    leader.stop(None);
}
