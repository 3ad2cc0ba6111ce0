//! What changing a datamanager's replicas costs the producers (issue 43's membership
//! bench), on real `marie node` processes on 127.0.0.1: `feature` kept on r1, r2, r3; this
//! bench joins the cluster as a member with 8 producers storing records, each store
//! acknowledged (a majority journaled it), for a baseline while nothing changes; then,
//! while they go on, it grows the replicas to five and shrinks them back to three — add r4,
//! add r5 (each a learner caught up and promoted), remove r1 (the leader: it hands its role
//! over), remove r2 — with `marie::cluster::replicas`, as `marie dm add-replica` does.
//! Printed: stores per second before and during the change, their ratio (goal ≥ 0.5×), and
//! the acknowledged records lost (goal 0), checked against the leader at the end.
//!
//! ```text
//! cargo bench --bench membership
//! ```

use marie::cluster::net::{ClusterConfig, Transport};
use marie::cluster::replicas;
use marie::dm::{DmClient, NewRecord, Query};
use std::collections::BTreeMap;
use std::io::{BufRead, BufReader};
use std::net::SocketAddr;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{mpsc, Arc, Mutex};
use std::time::{Duration, Instant};

const COOKIE: &str = "bench-membership";
const PRODUCERS: u64 = 8;
/// How long the baseline is measured.
const BASELINE: Duration = Duration::from_secs(10);

/// A `marie node` process, killed when dropped.
struct Kid(Child);

impl Drop for Kid {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// `marie node` NAME with a data directory under `dir`, keeping `feature` on r1–r3 if it is
/// one of them.
fn node(dir: &Path, name: &str, peers: &[SocketAddr]) -> (Kid, SocketAddr) {
    let declared = match name {
        "r1" | "r2" | "r3" => {
            // every record kept (the default retention is 10 000 per class): all are checked
            "[[datamanager]]\nname = \"feature\"\nreplicas = [\"r1\", \"r2\", \"r3\"]\nretention = 100000000\n"
        }
        _ => "",
    };
    let peers: Vec<String> = peers.iter().map(|p| format!("\"{p}\"")).collect();
    let config = format!(
        "[node]\nname = \"{name}\"\ndata_dir = \"{}\"\n{declared}\
         [cluster]\nlisten = \"127.0.0.1:0\"\npeers = [{}]\ncookie = \"{COOKIE}\"\n",
        dir.join(name).display(),
        peers.join(", ")
    );
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, config).expect("config");
    let mut child = Command::new(env!("CARGO_BIN_EXE_marie"))
        .args([
            "node",
            "--config",
            path.to_str().unwrap(),
            "--stop-with-stdin",
        ])
        .env_remove("RUST_LOG")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("a node starts");
    let out = child.stdout.take().expect("stdout");
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(out).lines().map_while(Result::ok) {
            let _ = tx.send(line);
        }
    });
    let addr = loop {
        let line = rx
            .recv_timeout(Duration::from_secs(120))
            .expect("the node listens");
        if let Some((_, rest)) = line.split_once(" listening on ") {
            break rest
                .split_whitespace()
                .next()
                .and_then(|a| a.parse().ok())
                .expect("an address");
        }
    };
    (Kid(child), addr)
}

/// Store records of producer `p` until `stop`, each until acknowledged (a retry is the same
/// put), counting them in `count` and noting them in `acked` (seq → (producer, value)).
async fn produce(
    client: DmClient,
    p: u64,
    stop: Arc<AtomicBool>,
    count: Arc<AtomicU64>,
    acked: Arc<Mutex<BTreeMap<u64, (u64, u64)>>>,
) {
    let mut v = 0u64;
    while !stop.load(Ordering::Relaxed) {
        let seq = loop {
            let mut record = NewRecord::encode("echo", &(p, v)).expect("encodes");
            record.producer = 0x2000 + p;
            record.producer_seq = v + 1;
            match client.store_raw(record).await {
                Ok(seq) => break seq,
                Err(_) => tokio::time::sleep(Duration::from_millis(20)).await,
            }
        };
        acked.lock().unwrap().insert(seq, (p, v));
        count.fetch_add(1, Ordering::Relaxed);
        v += 1;
    }
}

fn main() {
    if std::env::args().any(|a| a == "--list") {
        println!("membership: bench");
        return;
    }
    let dir = std::env::temp_dir().join(format!("marie-bench-membership-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("bench dir");
    let mut kids = Vec::new();
    let mut addrs: Vec<SocketAddr> = Vec::new();
    for name in ["r1", "r2", "r3", "r4", "r5"] {
        let (kid, addr) = node(&dir, name, &addrs);
        kids.push(kid);
        addrs.push(addr);
    }
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("runtime");
    rt.block_on(async {
        let mut me = ClusterConfig::new("127.0.0.1:0".parse().unwrap(), COOKIE);
        for a in &addrs {
            me = me.with_peer(*a);
        }
        let transport = Transport::start("bench", &me).await.expect("joins");
        transport
            .wait_for_peers(addrs.len(), Duration::from_secs(60))
            .await
            .expect("peers");
        let client = DmClient::lookup_within("feature", "bench", Duration::from_secs(60))
            .await
            .expect("a leader")
            .with_follow(Duration::from_secs(30));
        while client.leader_node().await.ok().as_deref() != Some("r1") {
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
        let stop = Arc::new(AtomicBool::new(false));
        let count = Arc::new(AtomicU64::new(0));
        let acked = Arc::new(Mutex::new(BTreeMap::new()));
        let producers: Vec<_> = (0..PRODUCERS)
            .map(|p| {
                tokio::spawn(produce(
                    client.clone(),
                    p,
                    stop.clone(),
                    count.clone(),
                    acked.clone(),
                ))
            })
            .collect();
        // warm up, then the baseline
        tokio::time::sleep(Duration::from_secs(2)).await;
        let (n0, t0) = (count.load(Ordering::Relaxed), Instant::now());
        tokio::time::sleep(BASELINE).await;
        let before = (count.load(Ordering::Relaxed) - n0) as f64 / t0.elapsed().as_secs_f64();
        let (n1, t1) = (count.load(Ordering::Relaxed), Instant::now());
        let mut steps = Vec::new();
        for (add, node) in [(true, "r4"), (true, "r5"), (false, "r1"), (false, "r2")] {
            let t = Instant::now();
            let done = match add {
                true => replicas::add("feature", node, replicas::CHANGE_WITHIN, |_| {}).await,
                false => replicas::remove("feature", node, replicas::CHANGE_WITHIN, |_| {}).await,
            };
            done.unwrap_or_else(|e| panic!("{} {node}: {e}", if add { "add" } else { "remove" }));
            steps.push(format!(
                "{} {node} {:.2} s",
                if add { "add" } else { "remove" },
                t.elapsed().as_secs_f64()
            ));
        }
        let took = t1.elapsed();
        let during = (count.load(Ordering::Relaxed) - n1) as f64 / took.as_secs_f64();
        stop.store(true, Ordering::Relaxed);
        for p in producers {
            p.await.expect("a producer");
        }
        let acked = acked.lock().unwrap().clone();
        let records = client.select(Query::class("echo")).await.expect("select");
        let stored: BTreeMap<u64, (u64, u64)> = records
            .iter()
            .map(|r| (r.seq, r.decode().expect("decodes")))
            .collect();
        let lost = acked
            .iter()
            .filter(|(s, v)| stored.get(s) != Some(v))
            .count();
        let leader = client.leader_node().await.unwrap_or_default();
        println!("membership: 3 -> 5 -> 3 replicas of `feature` under {PRODUCERS} producers (each store acknowledged)");
        println!("  changes: {} ({:.2} s in all); leader now {leader}", steps.join(", "), took.as_secs_f64());
        println!("  before: {before:.0} stores/s over {:.0} s", BASELINE.as_secs_f64());
        println!("  during: {during:.0} stores/s over {:.2} s", took.as_secs_f64());
        println!("  ratio during/before: {:.2}x (goal >= 0.5x)", during / before);
        println!("  acknowledged {}, stored {}, lost {lost} (goal 0)", acked.len(), stored.len());
        transport.stop().await;
    });
    drop(kids);
    let _ = std::fs::remove_dir_all(&dir);
}
