//! Read latency on a replicated datamanager's leader, with the stale-read protection against
//! without it, in one run: three sets of three replicas in this process (they find each
//! other in `pg` as on three nodes), each set's leader asked one `select` after another
//! (the newest record of a class of 1 000) by a `DmClient` beside it:
//!
//! - **unchecked**: the leader answers every read at once (`Replication::unchecked_reads`,
//!   the protocol before leases — stale reads possible);
//! - **lease** (the default): answered at once while the lease holds, which heartbeats keep
//!   renewed — the cost is a look at the replicas' echoed send times;
//! - **round**: a lease of zero, so every read waits for a round of the replicas' word (a
//!   read index: what a leader does while its lease lapsed, and after a hand-over).
//!
//! Rounds interleaved (each mode in turn, so the machine's load falls on all alike); the
//! median per read over the rounds, and the ratios of read speed to unchecked. Goal: lease
//! ≥ 0.8× unchecked. The replicas run in-process, so a read costs what the datamanager does
//! (a remote read adds its network round trip to all three alike).
//!
//! `cargo bench -p marie-dm --bench reads` (about half a minute)

use marie_dm::{
    self as dm, DmClient, DmSpec, Durability, NewRecord, Query, Replication, ReplicationTiming,
};
use marie_vocabulary::clock::RealClock;
use std::time::{Duration, Instant};

/// Reads per round and mode.
const READS: usize = 20_000;
/// Rounds of each mode.
const ROUNDS: usize = 5;
const MEMBERS: [&str; 3] = ["r1", "r2", "r3"];

/// How a set's leader checks reads.
#[derive(Clone, Copy, Debug)]
enum Mode {
    Unchecked,
    Lease,
    Round,
}

impl Mode {
    fn spec(self) -> DmSpec {
        match self {
            Mode::Unchecked => DmSpec::new("reads-unchecked", 1301),
            Mode::Lease => DmSpec::new("reads-lease", 1302),
            Mode::Round => DmSpec::new("reads-round", 1303),
        }
    }

    fn replication(self, me: &str) -> Replication {
        let r = Replication::new(me, MEMBERS);
        match self {
            Mode::Unchecked => r.with_unchecked_reads(),
            Mode::Lease => r,
            Mode::Round => Replication {
                timing: ReplicationTiming {
                    lease: Duration::ZERO,
                    ..ReplicationTiming::default()
                },
                ..r
            },
        }
    }
}

/// A set of three replicas in `dir`, and a client of its leader holding `records` records.
async fn set(mode: Mode, dir: &std::path::Path, records: u64) -> DmClient {
    let spec = mode.spec();
    for me in MEMBERS {
        let args = spec
            .args(RealClock::shared())
            .with_journal(dir.join(spec.name).join(me), Durability::Process)
            .with_replication(mode.replication(me));
        dm::spawn_datamanager(args).await.expect("a replica starts");
    }
    let client = DmClient::lookup_within(spec.name, "bench", Duration::from_secs(60))
        .await
        .expect("a leader elected");
    for i in 0..records {
        client
            .store_raw(NewRecord::encode("x", &i).unwrap())
            .await
            .expect("stored");
    }
    client
}

/// `READS` reads one after another: the time per read.
async fn round(client: &DmClient) -> Duration {
    let query = Query::class("x").newest(1);
    let start = Instant::now();
    for _ in 0..READS {
        let got = client.select(query.clone()).await.expect("a read");
        assert_eq!(got.len(), 1);
    }
    start.elapsed() / READS as u32
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

fn main() {
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("a runtime");
    rt.block_on(async {
        let dir = tempfile::tempdir().expect("a temporary directory");
        let modes = [Mode::Unchecked, Mode::Lease, Mode::Round];
        let mut clients = Vec::new();
        for mode in modes {
            clients.push(set(mode, dir.path(), 1000).await);
        }
        // warm up
        for client in &clients {
            round(client).await;
        }
        let mut per = vec![Vec::new(); modes.len()];
        for _ in 0..ROUNDS {
            for (i, client) in clients.iter().enumerate() {
                per[i].push(round(client).await.as_secs_f64() * 1e6);
            }
        }
        let us: Vec<f64> = per.into_iter().map(median).collect();
        println!("read latency, {READS} reads x {ROUNDS} rounds per mode (median of rounds):");
        for (mode, us) in modes.iter().zip(&us) {
            println!(
                "  {:<10} {us:>8.2} µs per read ({:>7.0} reads/s)",
                format!("{mode:?}").to_lowercase(),
                1e6 / us
            );
        }
        println!(
            "  lease: {:.2}x the speed of unchecked reads (goal >= 0.8x); a round per read: {:.2}x",
            us[0] / us[1],
            us[0] / us[2]
        );
    });
}
