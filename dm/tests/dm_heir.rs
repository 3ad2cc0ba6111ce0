//! A datamanager at durability `memory` survives its own crash, not its process's: a
//! datamanager restarted from clones of the same arguments (as its supervisor restarts it)
//! takes what the one before left — after a kill, a panic, or a stop — and one without an
//! heir starts empty, which the check of the run counts as put records lost.
//!
//! ractor's registry is process-global and these tests run in parallel: each uses its own
//! datamanager name and id.

use marie_dm::{self as dm, DmArgs, DmClient, DmMsg, Ledger, Query};
use marie_vocabulary::clock::RealClock;
use marie_vocabulary::events::{EventBus, Tap};
use marie_vocabulary::run::FaultKind;
use ractor::ActorRef;
use std::future::Future;
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::task::JoinHandle;

const DEADLINE: Duration = Duration::from_secs(20);

async fn within<T>(what: &str, fut: impl Future<Output = T>) -> T {
    tokio::time::timeout(DEADLINE, fut)
        .await
        .unwrap_or_else(|_| panic!("{what}: no result within {DEADLINE:?}"))
}

/// A memory datamanager's arguments, telling what its puts applied on `bus`.
fn args(name: &str, id: u32, bus: &EventBus) -> DmArgs {
    let mut args = dm::DmSpec::new("unused", id).args(RealClock::shared());
    args.name = name.to_string();
    args.events = Some(bus.clone());
    args
}

/// A ledger that takes every event of `bus` (as a run's check does).
fn ledger_of(bus: &EventBus) -> (Arc<Mutex<Ledger>>, Tap) {
    let ledger = Arc::new(Mutex::new(Ledger::new()));
    let tap = {
        let ledger = ledger.clone();
        bus.tap(move |event| {
            ledger.lock().unwrap().note(&event.kind);
        })
    };
    (ledger, tap)
}

/// Spawn a datamanager from `args`, and a client whose acknowledgements are told on the
/// datamanager's bus (as a node's operations' are).
async fn spawn(args: &DmArgs) -> (ActorRef<DmMsg>, JoinHandle<()>, DmClient) {
    let (actor, handle) = within("spawn", dm::spawn_datamanager(args.clone()))
        .await
        .expect("spawn dm");
    let mut client = DmClient::new(actor.clone(), "ultrasonic");
    if let Some(bus) = &args.events {
        client = client.with_acks(dm::AckSink::publishing_on(bus.clone()));
    }
    (actor, handle, client)
}

/// Put `n` sonar readings and `n` acknowledged walls, and wait until the datamanager has
/// them all.
async fn fill(client: &DmClient, n: u64) {
    for i in 0..n {
        client.put("sonar", Some("front"), None, &i).unwrap();
        client.store("wall", None, None, &(i, "w")).await.unwrap();
    }
    within("puts applied", async {
        while client.stats().await.unwrap().records < 2 * n {
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
    })
    .await;
}

async fn records(client: &DmClient) -> Vec<(u64, u64)> {
    client
        .select_typed::<u64>(Query::class("sonar"))
        .await
        .unwrap()
        .into_iter()
        .map(|(r, v)| (r.seq, v))
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_memory_datamanager_killed_or_panicking_keeps_its_records_in_its_next_incarnation() {
    let bus = EventBus::new("heir-test", RealClock::shared());
    let args = args("heir-kept", 9101, &bus);
    let (actor, handle, client) = spawn(&args).await;
    fill(&client, 200).await;
    let before = records(&client).await;
    assert_eq!(before.len(), 200);

    // killed: the next incarnation holds the same records at the same seqs
    actor.kill();
    within("killed", handle).await.unwrap();
    let (actor, handle, client) = spawn(&args).await;
    assert_eq!(records(&client).await, before);
    let stats = client.stats().await.unwrap();
    assert_eq!(stats.records, 400);
    assert_eq!(
        stats.inherited,
        Some(dm::Inherited {
            records: 400,
            refused: 0
        })
    );
    // seqs go on where they were: nothing is handed out twice
    let seq = client.store("wall", None, None, &"after").await.unwrap();
    assert_eq!(seq, 401);

    // a panic (the state dropped by ractor, no post_stop): the same; the next incarnation
    // is spawned at once, before the one that panicked is seen to have ended
    actor
        .cast(DmMsg::Inject {
            fault: FaultKind::Panic,
        })
        .unwrap();
    let (next, next_handle, client) = spawn(&args).await;
    let _ = within("panicked", handle).await;
    let (actor, handle) = (next, next_handle);
    assert_eq!(records(&client).await, before);
    assert_eq!(client.stats().await.unwrap().next_seq, 402);
    actor.stop(None);
    within("stopped", handle).await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_check_counts_the_puts_of_a_datamanager_restarted_empty_as_lost() {
    for heir in [true, false] {
        let bus = EventBus::new("heir-test", RealClock::shared());
        let (ledger, _tap) = ledger_of(&bus);
        let name = format!("heir-audit-{heir}");
        let mut args = args(&name, 9102 + u32::from(heir), &bus);
        if !heir {
            args = args.without_heir();
        }
        let (actor, handle, client) = spawn(&args).await;
        fill(&client, 100).await;
        actor.kill();
        within("killed", handle).await.unwrap();
        let (actor, handle, client) = spawn(&args).await;
        // the next incarnation stores as many again (at the same seqs, when it started
        // over): the same classes, other records
        for i in 1000..1100u64 {
            client.put("sonar", Some("front"), None, &i).unwrap();
        }
        client.stats().await.unwrap();
        // the tally is told on the datamanager's clock: wait until all 200 are
        within("tallies told", async {
            while ledger.lock().unwrap().applied(&name) < 200 {
                tokio::time::sleep(Duration::from_millis(20)).await;
            }
        })
        .await;
        ledger
            .lock()
            .unwrap()
            .note(&marie_vocabulary::events::EventKind::ChildRestarted {
                supervisor: "datamanagers".into(),
                child: name.clone(),
                actor: actor.get_id().to_string(),
                restarts: 1,
                reason: "killed".into(),
            });
        let check = {
            let ledger = std::mem::take(&mut *ledger.lock().unwrap());
            within("check", ledger.check(&name, Duration::from_secs(5))).await
        };
        assert_eq!(check.applied, 200, "{check:?}");
        if heir {
            assert_eq!((check.applied_lost, check.lost), (0, 0), "{check:?}");
            assert_eq!(check.acknowledged, 100, "{check:?}");
        } else {
            // the first incarnation's 100 sonar puts and 100 acknowledged walls are gone
            assert_eq!((check.applied_lost, check.lost), (100, 100), "{check:?}");
            assert_eq!(
                check.why.as_deref(),
                Some(format!("the {name} datamanager restarted empty").as_str())
            );
        }
        actor.stop(None);
        within("stopped", handle).await.unwrap();
    }
}
