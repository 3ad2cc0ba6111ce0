//! End-to-end tests of the datamanager, through a spawned actor.
//!
//! ractor's registry and pg are process-global and these tests run in parallel: every test
//! uses its own DM name and id, and registry checks look for their own actor id only.

use marie_dm::{
    self as dm, DmArgs, DmClient, DmConfig, DmError, DmMsg, NewRecord, Payload, Query, Record,
};
use marie_vocabulary::clock::{Clock, ManualClock, RealClock, SharedClock};
use marie_vocabulary::registry::{self, ModuleKind};
use ractor::ActorRef;
use serde::{Deserialize, Serialize};
use std::future::Future;
use std::sync::Arc;
use std::time::Duration;
use tokio::task::JoinHandle;

const DEADLINE: Duration = Duration::from_secs(10);

/// Await `fut`, failing the test after a generous deadline instead of hanging.
async fn within<T>(what: &str, fut: impl Future<Output = T>) -> T {
    tokio::time::timeout(DEADLINE, fut)
        .await
        .unwrap_or_else(|_| panic!("{what}: no result within {DEADLINE:?}"))
}

struct Dm {
    actor: ActorRef<DmMsg>,
    handle: JoinHandle<()>,
    client: DmClient,
}

impl Dm {
    async fn stop(self) {
        self.actor.stop(None);
        within("dm stops", self.handle).await.unwrap();
    }
}

async fn spawn(name: &str, id: u32, clock: SharedClock, config: DmConfig) -> Dm {
    let (actor, handle) = dm::spawn_datamanager(DmArgs {
        id,
        name: name.to_string(),
        clock,
        config,
        durability: dm::Durability::Memory,
        journal_dir: None,
        replication: None,
        events: None,
        heir: None,
    })
    .await
    .expect("spawn dm");
    let client = DmClient::new(actor.clone(), "tester");
    Dm {
        actor,
        handle,
        client,
    }
}

/// Wait until the DM has `n` pending waits: the event a waiting test needs before it stores.
async fn pending_waits(client: &DmClient, n: u64) {
    within("pending waits", async {
        while client.stats().await.unwrap().pending_waits != n {
            tokio::time::sleep(Duration::from_millis(1)).await;
        }
    })
    .await
}

fn seqs(records: &[Record]) -> Vec<u64> {
    records.iter().map(|r| r.seq).collect()
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct Echo {
    range_m: f64,
}

#[tokio::test]
async fn store_fills_seq_timestamp_and_source() {
    let clock = ManualClock::new();
    let dm = spawn(
        "dm-t-header",
        9101,
        Arc::new(clock.clone()),
        DmConfig::default(),
    )
    .await;
    clock.advance(Duration::from_millis(1500));
    let c = dm.client.clone();
    let s1 = within(
        "store",
        c.store("sonar", Some("front"), None, &Echo { range_m: 1.0 }),
    )
    .await
    .unwrap();
    clock.advance(Duration::from_millis(500));
    let other = DmClient::new(dm.actor.clone(), "planner");
    let s2 = within("store", other.store("path", None, None, &vec![1, 2, 3]))
        .await
        .unwrap();
    assert_eq!((s1, s2), (1, 2));
    let all = within("select", c.select(Query::all())).await.unwrap();
    assert_eq!(all.len(), 2);
    assert_eq!(all[0].seq, 1);
    assert_eq!(all[0].timestamp, Duration::from_millis(1500));
    assert_eq!(all[0].source, "tester");
    assert_eq!(all[0].class, "sonar");
    assert_eq!(all[0].sub1.as_deref(), Some("front"));
    assert_eq!(all[0].decode::<Echo>().unwrap(), Echo { range_m: 1.0 });
    assert_eq!(all[1].timestamp, Duration::from_secs(2));
    assert_eq!(all[1].source, "planner");
    // store_raw keeps an explicit source and fills an empty one
    let raw = NewRecord::encode("path", &0u8).unwrap();
    let s3 = within("store_raw", c.store_raw(raw.clone())).await.unwrap();
    let s4 = within("store_raw", c.store_raw(raw.with_source("replay")))
        .await
        .unwrap();
    let got = within("select", c.select(Query::all().seq_from(s3)))
        .await
        .unwrap();
    assert_eq!(seqs(&got), vec![s3, s4]);
    assert_eq!(got[0].source, "tester");
    assert_eq!(got[1].source, "replay");
    dm.stop().await;
}

#[tokio::test]
async fn select_by_each_criterion_and_a_mix() {
    let clock = ManualClock::new();
    let dm = spawn(
        "dm-t-select",
        9102,
        Arc::new(clock.clone()),
        DmConfig::default(),
    )
    .await;
    let us = DmClient::new(dm.actor.clone(), "ultrasonic");
    let ex = DmClient::new(dm.actor.clone(), "extractor");
    // seq i (1..=12) stored at t = i seconds
    for i in 1..=12u64 {
        clock.advance(Duration::from_secs(1));
        let seq = match i % 4 {
            1 => us.store("sonar", Some("front"), Some("narrow"), &i).await,
            2 => us.store("sonar", Some("front"), Some("wide"), &i).await,
            3 => us.store("sonar", Some("rear"), None, &i).await,
            _ => ex.store("segment", None, None, &i).await,
        };
        assert_eq!(seq.unwrap(), i);
    }
    let c = &dm.client;
    let sel = |q: Query| async move { seqs(&within("select", c.select(q)).await.unwrap()) };
    assert_eq!(
        sel(Query::class("sonar")).await,
        vec![1, 2, 3, 5, 6, 7, 9, 10, 11]
    );
    assert_eq!(
        sel(Query::all().sub1("front")).await,
        vec![1, 2, 5, 6, 9, 10]
    );
    assert_eq!(sel(Query::all().sub2("wide")).await, vec![2, 6, 10]);
    assert_eq!(sel(Query::all().source("extractor")).await, vec![4, 8, 12]);
    assert_eq!(sel(Query::all().seq_range(5, 7)).await, vec![5, 6, 7]);
    assert_eq!(
        sel(Query::all().time_range(Duration::from_secs(3), Duration::from_secs(4))).await,
        vec![3, 4]
    );
    assert_eq!(sel(Query::all().newest(3)).await, vec![10, 11, 12]);
    assert_eq!(sel(Query::all().oldest(2)).await, vec![1, 2]);
    let mix = Query::class("sonar")
        .sub1("front")
        .source("ultrasonic")
        .seq_from(2)
        .time_to(Duration::from_secs(9))
        .newest(2);
    assert_eq!(sel(mix).await, vec![6, 9]);
    assert!(sel(Query::class("nothing")).await.is_empty());
    // typed select
    let typed = within(
        "select_typed",
        c.select_typed::<u64>(Query::class("segment")),
    )
    .await
    .unwrap();
    let values: Vec<(u64, u64)> = typed.iter().map(|(h, v)| (h.seq, *v)).collect();
    assert_eq!(values, vec![(4, 4), (8, 8), (12, 12)]);
    assert!(matches!(
        c.select_typed::<String>(Query::class("segment")).await,
        Err(DmError::Decode(_))
    ));
    dm.stop().await;
}

#[tokio::test]
async fn select_wait_wakes_when_a_matching_record_arrives() {
    let clock = ManualClock::new();
    let dm = spawn(
        "dm-t-wait",
        9103,
        Arc::new(clock.clone()),
        DmConfig::default(),
    )
    .await;
    let c = dm.client.clone();
    c.store("sonar", Some("front"), None, &1u8).await.unwrap(); // seq 1: too old to match
    let waiter = {
        let c = c.clone();
        tokio::spawn(async move {
            c.select_wait(
                Query::class("sonar").sub1("rear").seq_from(2),
                Duration::from_secs(60),
            )
            .await
        })
    };
    pending_waits(&c, 1).await;
    // records that do not match leave it waiting
    c.store("sonar", Some("front"), None, &2u8).await.unwrap();
    c.store("segment", None, None, &3u8).await.unwrap();
    assert_eq!(c.stats().await.unwrap().pending_waits, 1);
    assert!(!waiter.is_finished());
    let seq = c.store("sonar", Some("rear"), None, &4u8).await.unwrap();
    let answer = within("wait answered", waiter).await.unwrap().unwrap();
    assert_eq!(seqs(&answer), vec![seq]);
    assert_eq!(answer[0].decode::<u8>().unwrap(), 4);
    assert_eq!(c.stats().await.unwrap().pending_waits, 0);
    // a wait whose answer already exists is answered at once, clock untouched
    let now = within(
        "immediate",
        c.select_wait(Query::class("segment"), Duration::from_secs(60)),
    )
    .await
    .unwrap();
    assert_eq!(now.len(), 1);
    // a class-less wait is woken by any matching class
    let waiter = {
        let c = c.clone();
        tokio::spawn(async move {
            c.select_wait(Query::all().source("late"), Duration::from_secs(60))
                .await
        })
    };
    pending_waits(&c, 1).await;
    let late = DmClient::new(dm.actor.clone(), "late");
    late.put("map", None, None, &0u8).unwrap();
    let answer = within("wait answered", waiter).await.unwrap().unwrap();
    assert_eq!(answer.len(), 1);
    assert_eq!(answer[0].source, "late");
    dm.stop().await;
}

#[tokio::test]
async fn select_wait_times_out_with_an_empty_answer() {
    let clock = ManualClock::new();
    let dm = spawn(
        "dm-t-timeout",
        9104,
        Arc::new(clock.clone()),
        DmConfig::default(),
    )
    .await;
    let c = dm.client.clone();
    let waiter = {
        let c = c.clone();
        tokio::spawn(async move {
            c.select_wait(Query::class("never"), Duration::from_millis(500))
                .await
        })
    };
    pending_waits(&c, 1).await;
    clock.advance(Duration::from_millis(499));
    c.store("other", None, None, &0u8).await.unwrap();
    assert!(!waiter.is_finished());
    clock.advance(Duration::from_millis(1));
    let answer = within("wait timed out", waiter).await.unwrap().unwrap();
    assert!(answer.is_empty());
    pending_waits(&c, 0).await;
    // a zero wait is a plain select
    let none = within(
        "zero wait",
        c.select_wait(Query::class("never"), Duration::ZERO),
    )
    .await
    .unwrap();
    assert!(none.is_empty());
    dm.stop().await;
}

#[tokio::test]
async fn abandoned_waits_are_dropped() {
    let clock = ManualClock::new();
    let dm = spawn(
        "dm-t-abandon",
        9105,
        Arc::new(clock.clone()),
        DmConfig::default(),
    )
    .await;
    // the caller goes away while its wait is pending (its reply port closes)
    let caller = {
        let c = dm.client.clone();
        tokio::spawn(async move {
            c.select_wait(Query::class("sonar"), Duration::from_secs(60))
                .await
        })
    };
    pending_waits(&dm.client, 1).await;
    caller.abort();
    assert!(within("caller gone", caller).await.is_err());
    // the next matching store finds the port closed and drops the waiter without answering
    dm.client.store("sonar", None, None, &0u8).await.unwrap();
    assert_eq!(dm.client.stats().await.unwrap().pending_waits, 0);
    // a caller whose own deadline passes first gets a Timeout, distinct from Unreachable
    let impatient = dm.client.clone().with_timeout(Duration::from_millis(20));
    let r = within(
        "impatient wait",
        impatient.select_wait(Query::class("never"), Duration::from_millis(10)),
    )
    .await;
    assert!(matches!(r, Err(DmError::Timeout { .. })), "{r:?}");
    dm.stop().await;
}

#[tokio::test]
async fn retention_drops_the_oldest_of_a_class_only() {
    let clock = ManualClock::new();
    let config = DmConfig::default()
        .with_default_retention(1000)
        .with_retention("sonar", 5);
    let dm = spawn("dm-t-retention", 9106, Arc::new(clock.clone()), config).await;
    let c = &dm.client;
    let map = c.store("map", None, None, &"walls").await.unwrap();
    for i in 0..20u32 {
        c.put("sonar", Some("front"), None, &i).unwrap();
    }
    let stats = within("stats", c.stats()).await.unwrap();
    assert_eq!(stats.records, 6);
    assert_eq!(stats.dropped, 15);
    assert_eq!(stats.classes.get("sonar"), Some(&5));
    assert_eq!(stats.classes.get("map"), Some(&1));
    let sonar = c.select_typed::<u32>(Query::class("sonar")).await.unwrap();
    let values: Vec<u32> = sonar.iter().map(|(_, v)| *v).collect();
    assert_eq!(values, vec![15, 16, 17, 18, 19]);
    assert_eq!(
        seqs(&c.select(Query::class("map")).await.unwrap()),
        vec![map]
    );
    dm.stop().await;
}

#[tokio::test]
async fn delete_by_query_returns_the_count() {
    let dm = spawn(
        "dm-t-delete",
        9107,
        RealClock::shared(),
        DmConfig::default(),
    )
    .await;
    let c = &dm.client;
    for i in 0..10u32 {
        let sub = if i % 2 == 0 { "even" } else { "odd" };
        c.store("n", Some(sub), None, &i).await.unwrap();
    }
    let n = within("delete", c.delete(Query::class("n").sub1("odd")))
        .await
        .unwrap();
    assert_eq!(n, 5);
    assert!(c.select(Query::all().sub1("odd")).await.unwrap().is_empty());
    assert_eq!(c.select(Query::class("n")).await.unwrap().len(), 5);
    assert_eq!(c.delete(Query::class("n").oldest(2)).await.unwrap(), 2);
    assert_eq!(seqs(&c.select(Query::all()).await.unwrap()), vec![5, 7, 9]);
    assert_eq!(c.delete(Query::class("absent")).await.unwrap(), 0);
    let stats = c.stats().await.unwrap();
    assert_eq!((stats.records, stats.deleted), (3, 7));
    dm.stop().await;
}

#[tokio::test]
async fn subscribe_receives_later_records_in_order() {
    let clock = ManualClock::new();
    let dm = spawn(
        "dm-t-subscribe",
        9108,
        Arc::new(clock.clone()),
        DmConfig::default(),
    )
    .await;
    let c = dm.client.clone();
    c.store("sonar", None, None, &0u32).await.unwrap(); // before subscribing: not delivered
    let mut sub = within("subscribe", c.subscribe(Query::class("sonar")))
        .await
        .unwrap();
    let mut stored = Vec::new();
    for i in 1..=300u32 {
        // more than one poll batch, interleaved with records of another class
        c.put("segment", None, None, &i).unwrap();
        stored.push(c.store("sonar", Some("front"), None, &i).await.unwrap());
    }
    let mut got = Vec::new();
    for _ in 0..stored.len() {
        let r = within("subscription record", sub.next())
            .await
            .expect("record");
        assert_eq!(r.class, "sonar");
        got.push(r.seq);
    }
    assert_eq!(got, stored);
    assert_eq!(sub.last_seq(), stored.last().copied());
    // a replay from an explicit seq (seq 2 is a segment), ending at its seq_to
    let mut replay = c
        .subscribe(Query::class("sonar").seq_range(1, 4))
        .await
        .unwrap();
    assert_eq!(within("replay", replay.next()).await.unwrap().seq, 1);
    assert_eq!(within("replay", replay.next()).await.unwrap().seq, 3);
    assert!(
        within("replay ends", replay.next()).await.is_none(),
        "past seq_to the subscription ends"
    );
    // the subscription ends when the DM goes away
    dm.stop().await;
    assert!(within("subscription ends", sub.next()).await.is_none());
}

#[tokio::test]
async fn registry_lists_the_dm_until_it_stops() {
    let (actor, handle) = dm::spawn_datamanager(dm::WORLD.args(RealClock::shared()))
        .await
        .unwrap();
    let mine = actor.get_id();
    for key in ["world", "1203"] {
        let found = registry::lookup(ModuleKind::Datamanager, key);
        assert!(
            found
                .iter()
                .any(|i| i.actor_id() == mine && i.id == 1203 && i.name == "world"),
            "lookup {key}: {found:?}"
        );
    }
    let client = DmClient::lookup("1203", "tester").unwrap();
    assert_eq!(client.dm_name(), "world");
    client.store("wall", None, None, &1u8).await.unwrap();
    let stats = client.stats().await.unwrap();
    assert_eq!((stats.id, stats.name.as_str()), (1203, "world"));

    actor.stop(None);
    within("dm stops", handle).await.unwrap();
    for key in ["world", "1203"] {
        assert!(!registry::lookup(ModuleKind::Datamanager, key)
            .iter()
            .any(|i| i.actor_id() == mine));
    }
    // a client of a stopped DM gets Unreachable, naming it
    assert_eq!(
        client.select(Query::all()).await,
        Err(DmError::Unreachable("world".into()))
    );
    assert_eq!(
        client.put("wall", None, None, &1u8),
        Err(DmError::Unreachable("world".into()))
    );
}

#[tokio::test]
async fn lookup_of_an_unknown_dm_names_it() {
    match DmClient::lookup("dm-t-nowhere", "tester") {
        Err(DmError::NotRegistered(name)) => assert_eq!(name, "dm-t-nowhere"),
        other => panic!("expected NotRegistered, got {other:?}"),
    }
}

#[tokio::test]
async fn bad_records_are_refused_and_puts_keep_order() {
    let dm = spawn(
        "dm-t-refuse",
        9109,
        RealClock::shared(),
        DmConfig::default().with_max_payload(64),
    )
    .await;
    let c = &dm.client;
    assert!(matches!(
        c.store("", None, None, &0u8).await,
        Err(DmError::InvalidName { .. })
    ));
    assert!(matches!(
        c.put("sonar", None, Some("narrow"), &0u8),
        Err(DmError::InvalidRecord(_))
    ));
    assert!(matches!(
        c.store("blob", None, None, &vec![0u32; 100]).await,
        Err(DmError::PayloadTooLarge { max: 64, .. })
    ));
    // a put the DM refuses is counted, not answered
    c.put_raw(NewRecord::new("blob", Payload::from_bytes(vec![0; 65])))
        .unwrap();
    for i in 0..1000u32 {
        c.put("sonar", None, None, &i).unwrap();
    }
    let stats = within("stats", c.stats()).await.unwrap();
    assert_eq!(stats.records, 1000);
    assert_eq!(stats.refused_puts, 1);
    assert_eq!((stats.first_seq, stats.last_seq), (Some(1), Some(1000)));
    let values: Vec<u32> = c
        .select_typed::<u32>(Query::class("sonar"))
        .await
        .unwrap()
        .into_iter()
        .map(|(_, v)| v)
        .collect();
    assert_eq!(values, (0..1000).collect::<Vec<_>>());
    dm.stop().await;
}

#[tokio::test]
async fn spawn_refuses_a_bad_name() {
    let mut args = dm::FEATURE.args(RealClock::shared());
    args.name = "not a name".into();
    assert!(dm::spawn_datamanager(args).await.is_err());
    let clock = ManualClock::new();
    assert_eq!(clock.now(), Duration::ZERO);
}

#[tokio::test]
async fn records_of_a_replaced_incarnation_are_refused_and_change_nothing() {
    let dm = spawn("dm-t-fence", 9190, RealClock::shared(), DmConfig::default()).await;
    // the stand-in (epoch 8) stores first; the woken original (epoch 7) then tries
    let stand_in = DmClient::new(dm.actor.clone(), "wall-follower").with_epoch(8);
    let original = DmClient::new(dm.actor.clone(), "wall-follower").with_epoch(7);
    let other = DmClient::new(dm.actor.clone(), "localizer").with_epoch(3);
    within("stand-in", stand_in.store("wall", None, None, &1u32))
        .await
        .unwrap();
    let refused = within("original", original.store("wall", None, None, &2u32)).await;
    match refused {
        Err(DmError::Fenced(stale)) => {
            assert_eq!(
                (stale.operation.as_str(), stale.got, stale.current),
                ("wall-follower", 7, 8)
            )
        }
        other => panic!("expected Fenced, got {other:?}"),
    }
    original.put("wall", None, None, &3u32).unwrap(); // a put is refused too, counted
                                                      // another operation, and unfenced records, are not concerned
    within("other", other.store("pose", None, None, &4u32))
        .await
        .unwrap();
    within("unfenced", dm.client.store("wall", None, None, &5u32))
        .await
        .unwrap();
    let walls: Vec<u32> = within("select", dm.client.select(Query::class("wall")))
        .await
        .unwrap()
        .iter()
        .map(|r| r.decode().unwrap())
        .collect();
    assert_eq!(walls, [1, 5]);
    let stats = within("stats", dm.client.stats()).await.unwrap();
    assert_eq!((stats.fenced, stats.refused_puts), (2, 1));
    dm.stop().await;
}

#[tokio::test]
async fn batches_store_in_order_all_or_nothing() {
    let dm = spawn(
        "dm-t-batch",
        9111,
        RealClock::shared(),
        DmConfig::default().with_max_payload(64),
    )
    .await;
    let c = &dm.client;
    let rec = |i: u32| NewRecord::new("sonar", Payload::encode(&i).unwrap());
    // a bad record refuses the whole batch here: nothing is sent
    let bad = vec![rec(0), NewRecord::new("", Payload::default())];
    assert!(matches!(c.put_batch(bad), Err(DmError::InvalidName { .. })));
    c.put_batch(Vec::new()).unwrap();
    c.put_batch((0..10).map(rec).collect()).unwrap();
    // what the DM refuses is counted and skipped, the rest of the batch is stored
    c.put_batch(vec![
        rec(10),
        NewRecord::new("blob", Payload::from_bytes(vec![0; 65])),
        rec(11),
    ])
    .unwrap();
    // put_all cuts a long sequence into batches (a local DM: no credits to wait for)
    within("put_all", c.put_all((12..5000).map(rec)))
        .await
        .unwrap();
    c.put_raw(rec(5000)).unwrap();
    let stats = within("stats", c.stats()).await.unwrap();
    assert_eq!(stats.records, 5001);
    assert_eq!(stats.refused_puts, 1);
    let stored = c.select_typed::<u32>(Query::class("sonar")).await.unwrap();
    assert!(stored.iter().all(|(h, _)| h.source == "tester"));
    let values: Vec<u32> = stored.into_iter().map(|(_, v)| v).collect();
    assert_eq!(values, (0..=5000).collect::<Vec<_>>());
    assert_eq!(c.puts_in_flight(), 0, "local puts are not metered");
    dm.stop().await;
}

#[tokio::test]
async fn a_class_reaching_its_retention_bound_is_told_once_and_its_drops_counted() {
    use marie_vocabulary::events::{EventBus, EventKind};
    let bus = EventBus::new("here", RealClock::shared());
    let mut events = bus.subscribe();
    let (actor, handle) = dm::spawn_datamanager(DmArgs {
        id: 4610,
        name: "retention-told".to_string(),
        clock: RealClock::shared(),
        config: DmConfig::default().with_retention("sonar", 3),
        durability: dm::Durability::Memory,
        journal_dir: None,
        replication: None,
        events: Some(bus.clone()),
        heir: None,
    })
    .await
    .expect("spawn dm");
    let client = DmClient::new(actor.clone(), "tester");
    for i in 0..3u64 {
        client.store("sonar", None, None, &i).await.unwrap();
    }
    client.store("wall", None, None, &0u64).await.unwrap();
    let quiet = client.stats().await.unwrap();
    assert_eq!(quiet.dropped, 0);
    assert!(
        events
            .drain()
            .iter()
            .all(|e| !matches!(e.kind, EventKind::DmRetention { .. })),
        "nothing dropped, nothing told"
    );
    for i in 3..10u64 {
        client.put("sonar", None, None, &i).unwrap();
    }
    let stats = client.stats().await.unwrap();
    assert_eq!(stats.dropped, 7);
    assert_eq!(stats.dropped_by_class.get("sonar"), Some(&7));
    assert_eq!(stats.retention_of("sonar"), Some(3));
    let told: Vec<_> = events
        .drain()
        .into_iter()
        .filter_map(|e| match e.kind {
            EventKind::DmRetention {
                dm, class, bound, ..
            } => Some((dm, class, bound)),
            _ => None,
        })
        .collect();
    assert_eq!(
        told,
        [("retention-told".to_string(), "sonar".to_string(), 3)],
        "told once, at the first record dropped"
    );
    actor.stop(None);
    within("dm stops", handle).await.unwrap();
}
