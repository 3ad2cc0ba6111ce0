//! What a datamanager's journal costs (issue 22), each figure against a baseline measured in
//! the same run:
//!
//! - **puts**: one producer casts N records (`put_raw`) into a local datamanager, then asks
//!   for its stats — the answer that acknowledges them all, so at `process` and `sync` it
//!   comes only once they are written (synced). Records per second from the first put to that
//!   answer, at `memory`, `process` and `sync`, rounds interleaved; ratios against `memory`.
//!   Goals: `process` ≥ 0.8× `memory` (and `memory` ≥ 0.95× the DM before the journal: an
//!   A/B of this bench's `memory` row across commits).
//! - **sync**: 8 producers, each with 8 `store` calls in flight (every one waits for its own
//!   acknowledgement), at `sync`: records per second and the acknowledgement's p50/p99.
//!   Goal: ≥ 100 000 records/s, p99 ≤ 5 ms.
//! - **restart**: a datamanager holding 1 000 000 records (at `process`) is stopped and
//!   started again: the time from the spawn to its first answer, its journal replayed.
//!   Goal: ≤ 1 s.
//!
//! ```text
//! cargo bench --bench durability              # all, under a minute
//! cargo bench --bench durability -- sync      # some sections: puts, sync, restart
//! ```
//!
//! Journals go to a fresh directory under the system's temp dir (`MARIE_BENCH_DIR` to put
//! them elsewhere, e.g. on the disk you want to measure), removed at the end.

use marie::clock::RealClock;
use marie::dm::{self, DmArgs, DmClient, DmSpec, Durability, NewRecord, Payload, Query};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

const PUTS: usize = 500_000;
const ROUNDS: usize = 5;

fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("runtime")
}

/// A sonar-like record: 44 bytes of payload, two sub-classes.
fn record(i: u64) -> NewRecord {
    NewRecord::new("sonar", Payload::encode(&(i, [0.5f64; 4])).expect("encode"))
        .with_sub1("front")
        .with_sub2("narrow")
}

fn args(name: &'static str, id: u32, dir: &Path, durability: Durability) -> DmArgs {
    let mut a = DmSpec::new(name, id).args(RealClock::shared());
    a.config = a.config.with_default_retention(usize::MAX);
    if durability != Durability::Memory {
        a = a.with_journal(dir, durability);
    }
    a
}

fn fresh(dir: &Path) {
    let _ = std::fs::remove_dir_all(dir);
    std::fs::create_dir_all(dir).expect("bench dir");
}

/// One round of the puts section: records per second.
async fn put_round(base: &Path, durability: Durability, round: usize) -> f64 {
    let dir = base.join(format!("puts-{durability}-{round}"));
    fresh(&dir);
    let (actor, handle) = dm::spawn_datamanager(args("bench-puts", 9901, &dir, durability))
        .await
        .expect("spawn");
    let client = DmClient::new(actor.clone(), "ultrasonic");
    let records: Vec<NewRecord> = (0..PUTS as u64).map(record).collect();
    let t = Instant::now();
    for (i, r) in records.into_iter().enumerate() {
        client.put_raw(r).expect("put");
        if i % 4096 == 4095 {
            // a producer between two samples: lets the DM run on a 2-core machine
            tokio::task::yield_now().await;
        }
    }
    let stats = client.stats().await.expect("stats");
    let secs = t.elapsed().as_secs_f64();
    assert_eq!(stats.records as usize, PUTS);
    actor.stop(None);
    handle.await.expect("stop");
    let _ = std::fs::remove_dir_all(&dir);
    PUTS as f64 / secs
}

fn puts(base: &Path) {
    let rt = runtime();
    let levels = Durability::ALL;
    let mut rates = vec![Vec::new(); levels.len()];
    // a warm-up round of each, not counted (the allocator's and the page cache's first use)
    for d in levels {
        rt.block_on(put_round(base, d, usize::MAX));
    }
    for round in 0..ROUNDS {
        for (k, d) in levels.iter().enumerate() {
            rates[k].push(rt.block_on(put_round(base, *d, round)));
        }
    }
    let median = |v: &Vec<f64>| {
        let mut v = v.clone();
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let base_rate = median(&rates[0]);
    println!("puts: {PUTS} records cast by one producer, then acknowledged by one stats answer; median of {ROUNDS} interleaved rounds after a warm-up");
    println!("  durability   records/s   ratio to memory   rounds");
    for (k, d) in levels.iter().enumerate() {
        let m = median(&rates[k]);
        let each: Vec<String> = rates[k]
            .iter()
            .map(|r| format!("{:.0}k", r / 1e3))
            .collect();
        println!(
            "  {:<10} {:>11.0}   {:>15.2}   {}",
            d.as_str(),
            m,
            m / base_rate,
            each.join(" ")
        );
    }
}

fn sync(base: &Path) {
    const PRODUCERS: usize = 8;
    const IN_FLIGHT: usize = 8;
    const EACH: usize = 4_000;
    let rt = runtime();
    let dir = base.join("sync");
    fresh(&dir);
    let (rate, p50, p99, max) = rt.block_on(async {
        let (actor, handle) =
            dm::spawn_datamanager(args("bench-sync", 9902, &dir, Durability::Sync))
                .await
                .expect("spawn");
        let t = Instant::now();
        let mut tasks = Vec::new();
        for p in 0..PRODUCERS {
            let client = DmClient::new(actor.clone(), format!("producer-{p}"));
            for lane in 0..IN_FLIGHT {
                let client = client.clone();
                tasks.push(tokio::spawn(async move {
                    let mut lat = Vec::with_capacity(EACH / IN_FLIGHT);
                    for i in 0..EACH / IN_FLIGHT {
                        let r = record((lane * EACH + i) as u64);
                        let s = Instant::now();
                        client.store_raw(r).await.expect("store");
                        lat.push(s.elapsed());
                    }
                    lat
                }));
            }
        }
        let mut lat: Vec<Duration> = Vec::new();
        for t in tasks {
            lat.extend(t.await.expect("producer"));
        }
        let secs = t.elapsed().as_secs_f64();
        let stats = DmClient::new(actor.clone(), "x")
            .stats()
            .await
            .expect("stats");
        assert_eq!(stats.records as usize, lat.len());
        actor.stop(None);
        handle.await.expect("stop");
        lat.sort();
        let q = |f: f64| lat[((lat.len() as f64 * f) as usize).min(lat.len() - 1)];
        (lat.len() as f64 / secs, q(0.5), q(0.99), lat[lat.len() - 1])
    });
    let _ = std::fs::remove_dir_all(&dir);
    println!(
        "sync: {PRODUCERS} producers × {IN_FLIGHT} stores in flight, {} records, group commit",
        PRODUCERS * EACH
    );
    println!(
        "  {rate:.0} records/s (goal ≥ 100000)   ack p50 {:.2} ms   p99 {:.2} ms (goal ≤ 5)   max {:.2} ms",
        ms(p50),
        ms(p99),
        ms(max)
    );
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

fn restart(base: &Path) {
    const N: u64 = 1_000_000;
    let rt = runtime();
    let dir = base.join("restart");
    fresh(&dir);
    let (fill, bytes) = rt.block_on(async {
        let (actor, handle) =
            dm::spawn_datamanager(args("bench-restart", 9903, &dir, Durability::Process))
                .await
                .expect("spawn");
        let client = DmClient::new(actor.clone(), "filler");
        let t = Instant::now();
        for i in 0..N {
            client.put_raw(record(i)).expect("put");
            if i % 4096 == 4095 {
                tokio::task::yield_now().await;
            }
        }
        let stats = client.stats().await.expect("stats");
        assert_eq!(stats.records, N);
        let fill = t.elapsed();
        actor.stop(None);
        handle.await.expect("stop");
        (fill, stats.journal_bytes)
    });
    println!(
        "restart: a datamanager of {N} records ({:.0} MiB of journal, filled in {:.2} s)",
        bytes as f64 / (1 << 20) as f64,
        fill.as_secs_f64()
    );
    for run in 1..=2 {
        let (took, recovery) = rt.block_on(async {
            let t = Instant::now();
            let (actor, handle) =
                dm::spawn_datamanager(args("bench-restart", 9903, &dir, Durability::Process))
                    .await
                    .expect("spawn");
            let client = DmClient::new(actor.clone(), "reader");
            let newest = client.select(Query::all().newest(1)).await.expect("select");
            let took = t.elapsed();
            assert_eq!(newest[0].seq, N);
            let stats = client.stats().await.expect("stats");
            actor.stop(None);
            handle.await.expect("stop");
            (took, stats.recovery.expect("a recovery"))
        });
        println!(
            "  start {run}: first answer after {:.3} s (goal ≤ 1 s); replay {} ms, {} records, {} bytes",
            took.as_secs_f64(),
            recovery.millis,
            recovery.records,
            recovery.bytes
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

fn main() {
    let wanted: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let runs = |s: &str| wanted.is_empty() || wanted.iter().any(|w| w == s);
    let base: PathBuf = std::env::var_os("MARIE_BENCH_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(std::env::temp_dir)
        .join(format!("marie-bench-durability-{}", std::process::id()));
    fresh(&base);
    if runs("puts") {
        puts(&base);
    }
    if runs("sync") {
        sync(&base);
    }
    if runs("restart") {
        restart(&base);
    }
    let _ = std::fs::remove_dir_all(&base);
}
