//! Datamanager benchmarks, each against its own baseline in the same run.
//!
//! - `dm_store`: N `Put` casts into a DM (a sonar class at its retention bound, so every put
//!   also drops the oldest record) vs the same N messages, carrying the same records, told to
//!   a trivial actor that only counts them; plus the store's index work alone and N unit
//!   messages for scale; and the same records in batches (`DmClient::put_all`). Each actor
//!   iteration ends with a call, so every message has been handled. Goal: DM rate ≥ 0.5 ×
//!   raw rate.
//! - `dm_select`: the newest 10 records of one class with a sub-class filter, with 1 000 vs
//!   1 000 000 records stored — on the store itself and through the actor. Goal: the 1M time
//!   ≤ 2 × the 1k time.
//!
//! `cargo bench --bench dm` (about a minute).

use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use marie::clock::{Clock, RealClock};
use marie::dm::{
    self, DmArgs, DmClient, DmConfig, DmMsg, Durability, NewRecord, Payload, Query, Store,
};
use ractor::{Actor, ActorProcessingErr, ActorRef, RpcReplyPort};
use std::time::{Duration, Instant};

mod common;

/// Messages per store iteration.
const N: u64 = 10_000;
/// Retention bound of the stored sonar class in the store benchmark.
const SONAR_BOUND: usize = 100_000;

/// A sonar reading like the ultrasonic EO stores it.
fn sonar(i: u64) -> NewRecord {
    common::sonar(i, "ultrasonic")
}

/// A mixed feature DM: 60 % sonar (four directions, two beams), 20 % segments, 20 % odometry.
fn feature(i: u64) -> NewRecord {
    match i % 10 {
        0..=5 => sonar(i / 10 * 6 + i % 10),
        6 | 7 => {
            NewRecord::new("segment", Payload::from_bytes(vec![0x90])).with_source("extractor")
        }
        _ => NewRecord::new("odometry", Payload::from_bytes(vec![0x90])).with_source("cart"),
    }
}

/// The baseline: an actor that counts what it is told.
struct Counter;
enum CountMsg {
    Record(#[allow(dead_code)] NewRecord),
    Unit,
    Get(RpcReplyPort<u64>),
}
impl ractor::Message for CountMsg {}
impl Actor for Counter {
    type Msg = CountMsg;
    type State = u64;
    type Arguments = ();
    async fn pre_start(&self, _: ActorRef<CountMsg>, _: ()) -> Result<u64, ActorProcessingErr> {
        Ok(0)
    }
    async fn handle(
        &self,
        _: ActorRef<CountMsg>,
        msg: CountMsg,
        count: &mut u64,
    ) -> Result<(), ActorProcessingErr> {
        match msg {
            CountMsg::Record(_) | CountMsg::Unit => *count += 1,
            CountMsg::Get(reply) => {
                let _ = reply.send(*count);
            }
        }
        Ok(())
    }
}

fn runtime() -> tokio::runtime::Runtime {
    // current-thread: sender and receiver share one core, so the ratio measures the work per
    // message rather than cross-thread wake-ups, which dominate and vary on a shared machine
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .expect("tokio runtime")
}

fn batch() -> Vec<NewRecord> {
    (0..N).map(sonar).collect()
}

fn store_rate(c: &mut Criterion) {
    let rt = runtime();
    let config = DmConfig::default().with_retention("sonar", SONAR_BOUND);
    let (dm_ref, _dm_handle) = rt
        .block_on(dm::spawn_datamanager(DmArgs {
            id: 9801,
            name: "bench-store".into(),
            clock: RealClock::shared(),
            config,
            durability: Durability::Memory,
            journal_dir: None,
            replication: None,
            events: None,
            heir: None,
        }))
        .expect("spawn dm");
    let (counter, _counter_handle) = rt
        .block_on(Actor::spawn(None, Counter, ()))
        .expect("spawn counter");
    let client = DmClient::new(dm_ref.clone(), "ultrasonic");
    // Fill the sonar class to its bound: from here on every put also drops a record.
    rt.block_on(async {
        for i in 0..SONAR_BOUND as u64 {
            client.put_raw(sonar(i)).expect("put");
        }
        client.stats().await.expect("stats");
    });

    let mut g = c.benchmark_group("dm_store");
    g.sample_size(20)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(5))
        .throughput(Throughput::Elements(N));

    // The records are built outside the timed part: both sides get the same messages.
    g.bench_function("dm_put", |b| {
        b.to_async(&rt).iter_custom(|iters| {
            let dm_ref = dm_ref.clone();
            let client = client.clone();
            async move {
                let mut total = Duration::ZERO;
                for _ in 0..iters {
                    let records = batch();
                    let start = Instant::now();
                    for record in records {
                        dm_ref.cast(DmMsg::Put { record }).expect("dm alive");
                    }
                    client.stats().await.expect("stats");
                    total += start.elapsed();
                }
                total
            }
        })
    });
    // The same records in `PutBatch` messages of `marie::dm::PUT_BATCH` (what `put_all` sends).
    g.bench_function("dm_put_batch", |b| {
        b.to_async(&rt).iter_custom(|iters| {
            let client = client.clone();
            async move {
                let mut total = Duration::ZERO;
                for _ in 0..iters {
                    let records = batch();
                    let start = Instant::now();
                    client.put_all(records).await.expect("put_all");
                    client.stats().await.expect("stats");
                    total += start.elapsed();
                }
                total
            }
        })
    });
    // The index work alone, on a store at the same bound: what the DM adds to a tell.
    let clock = RealClock::new();
    let mut store = Store::new(DmConfig::default().with_retention("sonar", SONAR_BOUND));
    for i in 0..SONAR_BOUND as u64 {
        store.insert(sonar(i), clock.now()).expect("insert");
    }
    g.bench_function("store_insert_only", |b| {
        b.iter_custom(|iters| {
            let mut total = Duration::ZERO;
            for _ in 0..iters {
                let records = batch();
                let start = Instant::now();
                for record in records {
                    store.insert(record, clock.now()).expect("insert");
                }
                total += start.elapsed();
            }
            total
        })
    });
    drop(store);
    g.bench_function("raw_tell_same_records", |b| {
        b.to_async(&rt).iter_custom(|iters| {
            let counter = counter.clone();
            async move {
                let mut total = Duration::ZERO;
                for _ in 0..iters {
                    let records = batch();
                    let start = Instant::now();
                    for record in records {
                        counter.cast(CountMsg::Record(record)).expect("alive");
                    }
                    ractor::call!(counter, CountMsg::Get).expect("count");
                    total += start.elapsed();
                }
                total
            }
        })
    });
    g.bench_function("raw_tell_unit", |b| {
        b.to_async(&rt).iter_custom(|iters| {
            let counter = counter.clone();
            async move {
                let start = Instant::now();
                for _ in 0..iters {
                    for _ in 0..N {
                        counter.cast(CountMsg::Unit).expect("alive");
                    }
                    ractor::call!(counter, CountMsg::Get).expect("count");
                }
                start.elapsed()
            }
        })
    });
    g.finish();
    dm_ref.stop(None);
    counter.stop(None);
}

fn filled_store(n: u64) -> Store {
    let mut store = Store::new(DmConfig::default().with_default_retention(usize::MAX));
    for i in 0..n {
        store
            .insert(feature(i), Duration::from_micros(i * 100))
            .expect("insert");
    }
    store
}

fn select_scaling(c: &mut Criterion) {
    let query = Query::class("sonar").sub1("front").newest(10);
    let mut g = c.benchmark_group("dm_select");
    g.sample_size(30)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3));

    for (label, n) in [("1k", 1_000u64), ("1M", 1_000_000)] {
        let store = filled_store(n);
        assert_eq!(store.select(&query).len(), 10);
        g.bench_function(format!("store_newest10_{label}"), |b| {
            b.iter(|| store.select(&query))
        });
        // a time window holding 10 records, anywhere in the store
        let to = Duration::from_micros((n - 1) * 100);
        let window = Query::all().time_range(to - Duration::from_micros(900), to);
        assert_eq!(store.select(&window).len(), 10);
        g.bench_function(format!("store_time_window10_{label}"), |b| {
            b.iter(|| store.select(&window))
        });
    }

    let rt = runtime();
    for (label, n, id) in [("1k", 1_000u64, 9802), ("1M", 1_000_000, 9803)] {
        let (dm_ref, _handle) = rt
            .block_on(dm::spawn_datamanager(DmArgs {
                id,
                name: format!("bench-select-{label}"),
                clock: RealClock::shared(),
                config: DmConfig::default().with_default_retention(usize::MAX),
                durability: Durability::Memory,
                journal_dir: None,
                replication: None,
                events: None,
                heir: None,
            }))
            .expect("spawn dm");
        let client = DmClient::new(dm_ref.clone(), "bench");
        rt.block_on(async {
            for i in 0..n {
                client.put_raw(feature(i)).expect("put");
            }
            let stats = client.stats().await.expect("stats");
            assert_eq!(stats.records, n);
        });
        g.bench_function(format!("actor_newest10_{label}"), |b| {
            b.to_async(&rt).iter_batched(
                || query.clone(),
                |q| {
                    let client = client.clone();
                    async move { client.select(q).await.expect("select") }
                },
                BatchSize::SmallInput,
            )
        });
        dm_ref.stop(None);
    }
    g.finish();
}

criterion_group!(benches, store_rate, select_scaling);
criterion_main!(benches);
