//! What a datamanager's replicas cost and how fast they take over (issue 22), on real
//! `marie node` processes on 127.0.0.1:
//!
//! - **put-all**: a producer (this bench run again as a child, a member of the cluster)
//!   stores N records with `put_all` into `feature` and waits for the acknowledgement of the
//!   last: records per second into a datamanager on one node without replicas, and into one
//!   kept in three replicas (a record is acknowledged once two of them journaled it); rounds
//!   interleaved, the ratio in the same run. Goal: replicas ≥ 0.5× no replicas. (Each
//!   datamanager grants its own window of credits: the replicated one a wider one, as its
//!   acknowledgements take a round to the replicas — `marie::dm::credits`.)
//! - **failover**: the producer stores one record after another; the leader's node is
//!   killed (`kill -9`) or frozen (SIGSTOP): the time from the signal to the first store
//!   acknowledged by a replica on another node. p50 over the rounds. Each round waits for a
//!   whole cluster first (the leader has both replicas caught up): the node hit in the round
//!   before rejoins with the failure detector's redial backoff, and a round hit before it
//!   had was a second fault, not the first (one round in five took ~3.2 s so). Goals: `kill -9` p50
//!   ≤ 200 ms; SIGSTOP p50 ≤ the failure detector's deadline (1.2 s) + 200 ms.
//!
//! ```text
//! cargo bench --bench replicas                 # both
//! cargo bench --bench replicas -- failover     # one section: put-all, failover
//! MARIE_BENCH_DM='catch_up = 100000' cargo bench --bench replicas -- put-all
//!                                              # more lines for the datamanager's config
//! MARIE_BENCH_LOGS=/tmp/logs cargo bench --bench replicas -- failover
//!                                              # each node's log (info) in /tmp/logs/NAME.log
//! ```

use marie::cluster::net::{ClusterConfig, Transport};
use marie::dm::{DmClient, NewRecord, Payload};
use marie::registry::{self, ModuleKind};
use std::io::{BufRead, BufReader, Write};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

const COOKIE: &str = "bench-replicas";
/// Records per put-all round (`MARIE_BENCH_PUTS` to change it, e.g. for a profile).
fn puts() -> u64 {
    std::env::var("MARIE_BENCH_PUTS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1_000_000)
}
/// Put-all rounds of each kind. With 200 000 records and 3 rounds a 3-replica round ran at
/// either ~270 k/s or ~400 k/s (the first of a run often slow), and the median ratio swung
/// from 0.34x to 0.51x between runs of one build; with a million records and 5 rounds the
/// runs of one build still spread by ±0.03–0.04 (0.47x–0.52x over seven runs of b133ae9's
/// replication; 0.55x, 0.55x, 0.55x, 0.63x of f282138's window grant): compare builds by
/// each process's CPU too.
const ROUNDS: usize = 5;
const FAILOVERS: usize = 5;
/// The child's role, and what it needs.
const ROLE: &str = "MARIE_BENCH_ROLE";
const PEERS: &str = "MARIE_BENCH_PEERS";
/// The node the leader is wanted on before the child starts (the preferred replica's: a
/// leader elected elsewhere at the start hands it the role, and the puts in flight to the
/// old one would be sent again — a hand-over inside the measured rounds).
const PREFERRED: &str = "MARIE_BENCH_PREFERRED";

fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("runtime")
}

fn unix_ns() -> u128 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos())
}

// ---------------------------------------------------------------------------------------
// Processes

/// A child process and its stdout lines, killed when dropped.
struct Kid {
    child: Child,
    lines: mpsc::Receiver<String>,
}

impl Kid {
    fn spawn(mut command: Command, stderr: Stdio) -> Kid {
        // the parent's RUST_LOG is not the child's, unless the caller set one for it
        if !command.get_envs().any(|(k, _)| k == "RUST_LOG") {
            command.env_remove("RUST_LOG");
        }
        let mut child = command
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(stderr)
            .spawn()
            .expect("a child starts");
        let out = child.stdout.take().expect("stdout");
        let (tx, lines) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(out).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        Kid { child, lines }
    }

    fn wait_line(&self, needle: &str) -> String {
        let deadline = Instant::now() + Duration::from_secs(120);
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            let line = self
                .lines
                .recv_timeout(left)
                .unwrap_or_else(|_| panic!("no line with {needle:?}"));
            if line.contains(needle) {
                return line;
            }
        }
    }

    fn signal(&self, signal: i32) {
        // SAFETY: kill(2) on our own child's pid, which is not reaped before `Drop`.
        unsafe { libc::kill(self.child.id() as libc::pid_t, signal) };
    }
}

impl Drop for Kid {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// `marie node` NAME hosting `feature` (with `replicas`, if any), its journal under `dir`.
fn node(dir: &Path, name: &str, replicas: &[&str], peers: &[SocketAddr]) -> (Kid, SocketAddr) {
    let replicas = if replicas.is_empty() {
        String::new()
    } else {
        let list: Vec<String> = replicas.iter().map(|c| format!("\"{c}\"")).collect();
        format!("replicas = [{}]\n", list.join(", "))
    };
    let peers: Vec<String> = peers.iter().map(|p| format!("\"{p}\"")).collect();
    // more of the datamanager's settings, to compare (e.g. `catch_up = 16384`)
    let extra = std::env::var("MARIE_BENCH_DM")
        .map(|s| format!("{s}\n"))
        .unwrap_or_default();
    let config = format!(
        "[node]\nname = \"{name}\"\ndata_dir = \"{}\"\n[[datamanager]]\nname = \"feature\"\n{replicas}{extra}\
         [cluster]\nlisten = \"127.0.0.1:0\"\npeers = [{}]\ncookie = \"{COOKIE}\"\n",
        dir.join(name).display(),
        peers.join(", ")
    );
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, config).expect("config");
    let mut c = Command::new(env!("CARGO_BIN_EXE_marie"));
    c.args([
        "node",
        "--config",
        path.to_str().unwrap(),
        "--stop-with-stdin",
    ]);
    // a node's log, to read a slow round afterwards: `MARIE_BENCH_LOGS=DIR` keeps each
    // node's (RUST_LOG=info, appended per incarnation) in DIR/NAME.log
    let stderr = match std::env::var_os("MARIE_BENCH_LOGS") {
        Some(logs) => {
            let _ = std::fs::create_dir_all(&logs);
            c.env("RUST_LOG", "info");
            let file = std::fs::OpenOptions::new()
                .create(true)
                .append(true)
                .open(Path::new(&logs).join(format!("{name}.log")))
                .expect("a log file");
            Stdio::from(file)
        }
        None => Stdio::null(),
    };
    let kid = Kid::spawn(c, stderr);
    let line = kid.wait_line(&format!("node {name} listening on "));
    let addr = line
        .split_once(" listening on ")
        .and_then(|(_, r)| r.split_whitespace().next()?.parse().ok())
        .expect("an address");
    (kid, addr)
}

/// The producer child, with `role` and the nodes' addresses.
fn producer(role: &str, peers: &[SocketAddr], preferred: &str) -> Kid {
    let list: Vec<String> = peers.iter().map(ToString::to_string).collect();
    let mut c = Command::new(std::env::current_exe().expect("own path"));
    c.env(ROLE, role)
        .env(PEERS, list.join(","))
        .env(PREFERRED, preferred);
    Kid::spawn(c, Stdio::inherit())
}

fn fresh_dir(what: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "marie-bench-replicas-{what}-{}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("bench dir");
    dir
}

// ---------------------------------------------------------------------------------------
// The child: a member of the cluster that produces

fn child(role: &str) {
    let peers: Vec<SocketAddr> = std::env::var(PEERS)
        .expect("peers")
        .split(',')
        .map(|p| p.parse().expect("an address"))
        .collect();
    runtime().block_on(async {
        let mut me = ClusterConfig::new("127.0.0.1:0".parse().unwrap(), COOKIE);
        for p in &peers {
            me = me.with_peer(*p);
        }
        let transport = Transport::start("producer", &me).await.expect("joins");
        transport
            .wait_for_peers(peers.len(), Duration::from_secs(60))
            .await
            .expect("peers");
        let preferred = std::env::var(PREFERRED).unwrap_or_default();
        let start = Instant::now();
        while !registry::lookup(ModuleKind::Datamanager, "feature")
            .iter()
            .any(|i| i.node == preferred)
        {
            assert!(
                start.elapsed() < Duration::from_secs(60),
                "no leader on {preferred}"
            );
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
        let client = DmClient::lookup("feature", "producer")
            .expect("feature")
            .with_follow(Duration::from_secs(30));
        match role {
            "put-all" => {
                let puts = puts();
                println!("putting");
                let records = (0..puts).map(|i| {
                    NewRecord::new("sonar", Payload::encode(&(i, [0.5f64; 4])).unwrap())
                        .with_sub1("front")
                });
                let start = Instant::now();
                client.put_all(records).await.expect("put_all");
                // the answer that acknowledges them all
                let stats = client.stats().await.expect("stats");
                let secs = start.elapsed().as_secs_f64();
                // (retention keeps the newest 10 000 of the class; the rest it dropped)
                let stored = stats.records + stats.dropped;
                assert!(stored >= puts, "{stored} of {puts} stored");
                println!("rate {:.0}", puts as f64 / secs);
            }
            _ => {
                // whether the cluster is whole: the leader has both other replicas, caught
                // up (a replica frozen or killed in the round before rejoins with the failure
                // detector's redial backoff; a round must hit one node of a whole cluster,
                // not the second of two)
                let watcher = client.clone();
                tokio::spawn(async move {
                    loop {
                        if let Ok(stats) = watcher.stats().await {
                            if let Some(r) = stats.replica {
                                let whole = r.lag.len() == 2 && r.lag.values().all(|l| *l < 64);
                                println!("whole {whole}");
                            }
                        }
                        tokio::time::sleep(Duration::from_millis(100)).await;
                    }
                });
                // one store after another, each acknowledged: when, and by which node
                let mut n = 0u64;
                loop {
                    let mut record = NewRecord::encode("echo", &n).unwrap();
                    record.producer = 7;
                    record.producer_seq = n + 1;
                    if client.store_raw(record).await.is_ok() {
                        let node = registry::node_name_of(&client.actor().get_id());
                        println!("ack {} {node}", unix_ns());
                        n += 1;
                    }
                }
            }
        }
        transport.stop().await;
    });
}

// ---------------------------------------------------------------------------------------
// The parent

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn put_all() {
    println!(
        "put-all: {} records with put_all, acknowledged; {ROUNDS} rounds interleaved",
        puts()
    );
    let (mut plain, mut copied) = (Vec::new(), Vec::new());
    for round in 0..ROUNDS {
        for replicas in [false, true] {
            let dir = fresh_dir("put-all");
            let names: &[&str] = if replicas {
                &["r1", "r2", "r3"]
            } else {
                &["p1"]
            };
            let list: &[&str] = if replicas { names } else { &[] };
            let mut nodes = Vec::new();
            let mut addrs = Vec::new();
            for name in names {
                let (kid, addr) = node(&dir, name, list, &addrs);
                nodes.push(kid);
                addrs.push(addr);
            }
            let kid = producer("put-all", &addrs, names[0]);
            kid.wait_line("putting");
            // (a mark for a profiler started by hand: the round's puts begin)
            eprintln!(
                "  round {round}: putting, {}",
                if replicas {
                    "3 replicas"
                } else {
                    "no replicas"
                }
            );
            let line = kid.wait_line("rate ");
            let rate: f64 = line[5..].trim().parse().expect("a rate");
            println!(
                "  round {round}: {} {rate:.0} records/s",
                if replicas {
                    "3 replicas "
                } else {
                    "no replicas"
                }
            );
            if replicas { &mut copied } else { &mut plain }.push(rate);
            drop(kid);
            drop(nodes);
            let _ = std::fs::remove_dir_all(&dir);
        }
    }
    let (p, c) = (median(&mut plain), median(&mut copied));
    println!(
        "put-all medians: no replicas {p:.0}/s, 3 replicas {c:.0}/s: {:.2}x (goal >= 0.5x)",
        c / p
    );
}

fn failover() {
    println!("failover: from the signal to the first store acknowledged by another node's replica");
    let dir = fresh_dir("failover");
    let names = ["r1", "r2", "r3"];
    let mut nodes: Vec<Option<Kid>> = Vec::new();
    let mut addrs = Vec::new();
    for name in names {
        let (kid, addr) = node(&dir, name, &names, &addrs);
        nodes.push(Some(kid));
        addrs.push(addr);
    }
    let kid = producer("stream", &addrs, "r1");
    let mut gaps: Vec<(&str, f64)> = Vec::new();
    for round in 0..2 * FAILOVERS {
        let kind = if round < FAILOVERS {
            "kill -9"
        } else {
            "SIGSTOP"
        };
        // settle — the cluster whole again —, then hit the node of the replica that
        // acknowledges now
        std::thread::sleep(Duration::from_secs(2));
        while kid.lines.try_recv().is_ok() {}
        kid.wait_line("whole true");
        let line = kid.wait_line("ack ");
        let leader = line.split_whitespace().nth(2).expect("a node").to_string();
        let i = names
            .iter()
            .position(|n| *n == leader)
            .expect("a known node");
        let hit = unix_ns();
        nodes[i]
            .as_ref()
            .expect("running")
            .signal(if kind == "kill -9" {
                libc::SIGKILL
            } else {
                libc::SIGSTOP
            });
        let gap = loop {
            let line = kid.wait_line("ack ");
            let mut w = line.split_whitespace().skip(1);
            let at: u128 = w.next().and_then(|t| t.parse().ok()).expect("a time");
            let by = w.next().unwrap_or_default();
            if by != leader && at > hit {
                break (at - hit) as f64 / 1e6;
            }
        };
        println!(
            "  {kind} of {leader} at {:.3} (unix s): the first store acknowledged by another replica after {gap:.0} ms",
            hit as f64 / 1e9
        );
        gaps.push((kind, gap));
        if kind == "kill -9" {
            nodes[i] = None;
            let peers: Vec<SocketAddr> = addrs
                .iter()
                .enumerate()
                .filter(|(j, _)| *j != i)
                .map(|(_, a)| *a)
                .collect();
            let (k, a) = node(&dir, names[i], &names, &peers);
            nodes[i] = Some(k);
            addrs[i] = a;
        } else {
            nodes[i].as_ref().expect("running").signal(libc::SIGCONT);
        }
    }
    for kind in ["kill -9", "SIGSTOP"] {
        let mut v: Vec<f64> = gaps
            .iter()
            .filter(|(k, _)| *k == kind)
            .map(|(_, g)| *g)
            .collect();
        let goal = if kind == "kill -9" { 200.0 } else { 1400.0 };
        println!(
            "failover {kind}: p50 {:.0} ms over {} rounds (goal <= {goal:.0} ms)",
            median(&mut v),
            v.len()
        );
    }
    drop(kid);
    drop(nodes);
    let _ = std::fs::remove_dir_all(&dir);
}

fn main() {
    if let Ok(role) = std::env::var(ROLE) {
        child(&role);
        return;
    }
    let wanted: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with('-'))
        .collect();
    let runs = |s: &str| wanted.is_empty() || wanted.iter().any(|w| w == s);
    let _ = std::io::stdout().flush();
    if runs("put-all") {
        put_all();
    }
    if runs("failover") {
        failover();
    }
}
