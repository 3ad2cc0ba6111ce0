//! The checker of a replicated datamanager: several producers store records, each
//! acknowledged, into `feature` kept in three replicas on three `marie node` processes, while
//! a seeded schedule of faults hits the node of whichever replica is leader at that moment —
//! `kill -9` (and a restart on its data directory), a freeze (SIGSTOP, then SIGCONT), a
//! partition that cuts it off from everyone (network namespaces), a crash of the
//! datamanager itself (a panic, restarted by its supervisor). At the end it reads the
//! leader's records and every replica's digest and checks: every acknowledged record present
//! exactly once at its seq, each producer's records in its order, no record that was never
//! put, all replicas equal. It prints the table.
//!
//! CI runs a short schedule. For long runs (1000 faults):
//!
//! ```sh
//! MARIE_CHECKER_FAULTS=1000 MARIE_CHECKER_SEED=7 \
//!     cargo test --release --test e2e -- dm_checker:: --nocapture
//! ```
//! (`scripts/dm-checker` does that.)
//!
//! The producers run in a child process — this test binary again — inside a network
//! namespace of its own, so a partition can cut them off too; they print what they put and
//! what was acknowledged, and take orders (`crash`, `stop`) on stdin. Needs root for the
//! namespaces; skipped without (fails when `CI` is set).

use crate::common;

use common::cluster::{NodeProc, Proc};
use common::netns::Netns;
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;
use std::time::{Duration, Instant};

const COOKIE: &str = "checker";
const NODES: [&str; 3] = ["r1", "r2", "r3"];
const PORT: u16 = 7100;
/// The producers' namespace (after the nodes').
const PRODUCERS_NS: usize = 3;
/// Producers in the child.
const PRODUCERS: u64 = 4;
/// Records per class: a producer's records go in classes of this many, and once a class is
/// full it deletes the class two before it, so the store stays bounded however long the run
/// (and deletes are checked under faults too). No class reaches the default retention bound
/// (10 000), so every record put and not deleted must still be there.
const CLASS: u64 = 8192;
/// The child's orders and answers wait this long at most.
const T: Duration = Duration::from_secs(120);

fn env_or(name: &str, default: u64) -> u64 {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

struct Rng(u64);
impl Rng {
    fn below(&mut self, n: u64) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0 % n.max(1)
    }
    fn ms(&mut self, from: u64, to: u64) -> Duration {
        Duration::from_millis(from + self.below(to - from + 1))
    }
}

fn config(dir: &Path, name: &str) -> String {
    format!(
        "data_dir = \"{}\"\n[[datamanager]]\nname = \"feature\"\ncopies = [\"r1\", \"r2\", \"r3\"]\n",
        dir.join(format!("data-{name}")).display()
    )
}

/// Start node `i` in its namespace (the others joining node 0).
fn start_node(net: &Netns, dir: &Path, i: usize) -> NodeProc {
    let name = NODES[i];
    let listen = net.addr(i, PORT);
    let peers = if i == 0 {
        Vec::new()
    } else {
        vec![net.addr(0, PORT)]
    };
    let path =
        common::cluster::node_config(dir, name, &config(dir, name), listen, &peers, COOKIE, "");
    NodeProc::launch(
        Some(net.ns(i)),
        listen,
        name,
        &[
            "node",
            "--config",
            path.to_str().unwrap(),
            "--stop-with-stdin",
        ],
    )
}

/// What the child said, read so far.
#[derive(Default)]
struct Heard {
    read: usize,
    leader: Option<String>,
    /// How many times a leader was announced.
    leaders: u64,
    put: BTreeSet<(u64, u64)>,
    acked: BTreeMap<(u64, u64), u64>,
    have: Vec<(u64, u64, u64)>,
    /// (producer, class) deleted, acknowledged.
    deleted: BTreeSet<(u64, u64)>,
    replicas: Vec<(String, u64, u64, u64)>,
    done: bool,
}

impl Heard {
    fn take(&mut self, child: &mut Proc) {
        // only the lines not read yet (a long run prints millions)
        let lines = child.drain();
        for line in &lines[self.read..] {
            let w: Vec<&str> = line.split_whitespace().collect();
            let n = |i: usize| w.get(i).and_then(|s| s.parse::<u64>().ok()).unwrap_or(0);
            match w.first().copied() {
                Some("leader") => {
                    self.leader = w.get(1).map(|s| s.to_string());
                    self.leaders += 1;
                }
                Some("put") => {
                    self.put.insert((n(1), n(2)));
                }
                Some("ack") => {
                    let old = self.acked.insert((n(1), n(2)), n(3));
                    assert!(
                        old.is_none_or(|s| s == n(3)),
                        "record {} {} acknowledged with two seqs",
                        n(1),
                        n(2)
                    );
                }
                Some("have") => self.have.push((n(1), n(2), n(3))),
                Some("deleted") => {
                    self.deleted.insert((n(1), n(2)));
                }
                Some("replica") => {
                    self.replicas
                        .push((w.get(1).unwrap_or(&"").to_string(), n(2), n(3), n(4)))
                }
                Some("done") => self.done = true,
                _ => {}
            }
        }
        self.read = lines.len();
    }
}

#[test]
fn replicated_datamanager_checker_under_kill_freeze_partition_and_crash() {
    if std::env::var_os("MARIE_CHECKER_CHILD").is_some() {
        return; // the child runs the producers' test instead
    }
    let Some(net) = Netns::create(NODES.len() + 1) else {
        return;
    };
    let faults = env_or("MARIE_CHECKER_FAULTS", 8);
    let seed = env_or("MARIE_CHECKER_SEED", 1);
    let mut rng = Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1);
    let dir = tempfile::tempdir().unwrap();
    let mut nodes: Vec<NodeProc> = (0..NODES.len())
        .map(|i| start_node(&net, dir.path(), i))
        .collect();
    let peers: Vec<String> = (0..NODES.len())
        .map(|i| net.addr(i, PORT).to_string())
        .collect();
    let mut child = Proc::spawn_exe(
        Some(net.ns(PRODUCERS_NS)),
        "producers",
        &std::env::current_exe().unwrap(),
        &[
            "--exact",
            "dm_checker::producers",
            "--nocapture",
            "--test-threads",
            "1",
        ],
        &[
            ("MARIE_CHECKER_CHILD", "1".to_string()),
            ("MARIE_CHECKER_PEERS", peers.join(",")),
            (
                "MARIE_CHECKER_LISTEN",
                net.addr(PRODUCERS_NS, 0).to_string(),
            ),
        ],
    );
    let mut heard = Heard::default();
    let wait = |child: &mut Proc, heard: &mut Heard, what: &str, until: &dyn Fn(&Heard) -> bool| {
        let start = Instant::now();
        loop {
            heard.take(child);
            if until(heard) {
                return;
            }
            if start.elapsed() >= T {
                // what the child said last, to tell where it stands
                let lines = child.drain();
                let last = &lines[lines.len().saturating_sub(8)..];
                panic!(
                    "the producers: no {what} within {T:?} ({} acknowledged, leader {:?}); \
                     their last lines: {last:?}",
                    heard.acked.len(),
                    heard.leader
                );
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    };
    wait(&mut child, &mut heard, "leader", &|h| h.leader.is_some());
    let mut done: BTreeMap<&str, u64> = BTreeMap::new();
    for k in 0..faults {
        std::thread::sleep(rng.ms(300, 1500));
        heard.take(&mut child);
        let Some(leader) = heard.leader.clone() else {
            continue;
        };
        let i = NODES.iter().position(|n| *n == leader).expect("a node");
        // each kind once first, then as the seed draws them
        let pick = if k < 4 { k } else { rng.below(4) };
        let kind = ["kill", "freeze", "partition", "crash"][pick as usize];
        eprintln!("fault {k}: {kind} {leader}");
        match kind {
            "kill" => {
                nodes[i].signal("KILL");
                std::thread::sleep(rng.ms(300, 1500));
                nodes[i] = start_node(&net, dir.path(), i);
            }
            "freeze" => {
                let stopped = common::cluster::Stopped::stop(nodes[i].pid());
                std::thread::sleep(rng.ms(500, 3000));
                drop(stopped);
            }
            "partition" => {
                for j in 0..=PRODUCERS_NS {
                    if j != i {
                        net.cut(i, j);
                    }
                }
                std::thread::sleep(rng.ms(500, 3000));
                for j in 0..=PRODUCERS_NS {
                    if j != i {
                        net.heal(i, j);
                    }
                }
            }
            _ => child.tell("crash"),
        }
        *done.entry(kind).or_default() += 1;
        // the datamanager takes writes again (under a leader elected anew, or the same one
        // if the fault was shorter than the failure detector's deadline) before the next
        heard.take(&mut child);
        let acked = heard.acked.len();
        wait(&mut child, &mut heard, "progress after the fault", &|h| {
            h.acked.len() >= acked + PRODUCERS as usize
        });
    }
    child.tell("stop");
    wait(&mut child, &mut heard, "final reading", &|h| h.done);

    // the verdict
    let mut lost = 0;
    let mut where_is: BTreeMap<(u64, u64), Vec<u64>> = BTreeMap::new();
    for (seq, p, n) in &heard.have {
        where_is.entry((*p, *n)).or_default().push(*seq);
    }
    // a record of a class whose delete was acknowledged must be gone; any other must be there
    let mut resurrected = 0;
    for (rec, seq) in &heard.acked {
        if heard.deleted.contains(&(rec.0, rec.1 / CLASS)) {
            if where_is.contains_key(rec) {
                resurrected += 1;
                eprintln!(
                    "RESURRECTED: producer {} record {} (its class deleted, acknowledged)",
                    rec.0, rec.1
                );
            }
        } else if where_is.get(rec).is_none_or(|s| !s.contains(seq)) {
            lost += 1;
            eprintln!(
                "LOST: producer {} record {} (acknowledged as seq {seq})",
                rec.0, rec.1
            );
        }
    }
    let duplicated = where_is.values().filter(|s| s.len() > 1).count();
    let never_put = where_is.keys().filter(|r| !heard.put.contains(r)).count();
    let mut out_of_order = 0;
    for p in 0..PRODUCERS {
        let seqs: Vec<u64> = where_is
            .range((p, 0)..(p + 1, 0))
            .map(|(_, s)| s[0])
            .collect();
        out_of_order += seqs.windows(2).filter(|w| w[0] >= w[1]).count();
    }
    let first = heard.replicas.first().cloned().expect("a replica read");
    let divergent = heard
        .replicas
        .iter()
        .filter(|c| (c.1, c.2, c.3) != (first.1, first.2, first.3))
        .count();
    let kinds: Vec<String> = done.iter().map(|(k, n)| format!("{n} {k}")).collect();
    println!(
        "| seed | faults | acknowledged | deleted (classes) | stored | lost | duplicated | deleted yet there | out of order | never put | divergent replicas |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    println!(
        "| {seed} | {faults} ({}) | {} | {} | {} | {lost} | {duplicated} | {resurrected} | {out_of_order} | {never_put} | {divergent} of {} |",
        kinds.join(", "),
        heard.acked.len(),
        heard.deleted.len(),
        heard.have.len(),
        heard.replicas.len()
    );
    assert_eq!(
        heard.replicas.len(),
        3,
        "every replica read: {:?}",
        heard.replicas
    );
    assert!(
        heard.acked.len() as u64 > faults,
        "the producers made progress"
    );
    assert_eq!(
        (
            lost,
            duplicated,
            resurrected,
            out_of_order,
            never_put,
            divergent
        ),
        (0, 0, 0, 0, 0, 0)
    );
}

/// The child: the producers, in their own namespace. Does nothing unless run by the test
/// above.
#[test]
fn producers() {
    if std::env::var_os("MARIE_CHECKER_CHILD").is_none() {
        return;
    }
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap();
    rt.block_on(producers_run());
}

async fn producers_run() {
    use marie::cluster::net::{ClusterConfig, Transport};
    use marie::dm::{self, DmClient, DmMsg, NewRecord, Query};
    use marie::registry::{self, ModuleKind};
    use marie::run::FaultKind;
    use ractor::ActorRef;
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::Arc;

    // a line at a time, whole (libtest's own output may share the line otherwise)
    let say = |s: String| println!("\n{s}");
    let listen = std::env::var("MARIE_CHECKER_LISTEN")
        .unwrap()
        .parse()
        .unwrap();
    let mut me = ClusterConfig::new(listen, COOKIE);
    for p in std::env::var("MARIE_CHECKER_PEERS").unwrap().split(',') {
        me = me.with_peer(p.parse().unwrap());
    }
    let transport = Transport::start("producers", &me).await.unwrap();
    transport.wait_for_peers(3, T).await.unwrap();
    let leader = || {
        registry::lookup(ModuleKind::Datamanager, "feature")
            .into_iter()
            .next()
    };
    let start = Instant::now();
    while leader().is_none() {
        assert!(start.elapsed() < T, "no leader");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let client = DmClient::lookup("feature", "producers")
        .unwrap()
        .with_follow(T);
    let stop = Arc::new(AtomicBool::new(false));
    // who is leader, told at each change
    let watcher = {
        let stop = stop.clone();
        tokio::spawn(async move {
            let mut last: Option<ractor::ActorId> = None;
            while !stop.load(Ordering::Relaxed) {
                if let Some(p) = leader() {
                    if Some(p.actor.get_id()) != last {
                        last = Some(p.actor.get_id());
                        say(format!("leader {}", p.node));
                    }
                }
                tokio::time::sleep(Duration::from_millis(20)).await;
            }
        })
    };
    let mut tasks = Vec::new();
    for p in 0..PRODUCERS {
        let (client, stop) = (client.clone(), stop.clone());
        tasks.push(tokio::spawn(async move {
            let mut n = 0u64;
            while !stop.load(Ordering::Relaxed) {
                say(format!("put {p} {n}"));
                let start = Instant::now();
                let seq = loop {
                    let class = format!("rec-{p}-{}", n / CLASS);
                    let mut record = NewRecord::encode(&class, &(p, n)).unwrap();
                    record.producer = 1000 + p;
                    record.producer_seq = n + 1;
                    match client.store_raw(record).await {
                        Ok(seq) => break seq,
                        Err(e) => {
                            assert!(start.elapsed() < T, "producer {p} record {n}: {e}");
                            tokio::time::sleep(Duration::from_millis(50)).await;
                        }
                    }
                };
                say(format!("ack {p} {n} {seq}"));
                n += 1;
                if n % CLASS == 0 && n / CLASS >= 3 {
                    // retried until acknowledged: deleting a class twice deletes it once
                    let c = n / CLASS - 3;
                    let start = Instant::now();
                    while let Err(e) = client.delete(Query::class(format!("rec-{p}-{c}"))).await {
                        assert!(start.elapsed() < T, "producer {p} delete {c}: {e}");
                        tokio::time::sleep(Duration::from_millis(50)).await;
                    }
                    say(format!("deleted {p} {c}"));
                }
            }
        }));
    }
    // orders
    let (tx, mut orders) = tokio::sync::mpsc::unbounded_channel::<String>();
    std::thread::spawn(move || {
        use std::io::BufRead;
        for line in std::io::stdin().lock().lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    while let Some(line) = orders.recv().await {
        match line.trim() {
            "crash" => {
                if let Some(p) = leader() {
                    let actor: ActorRef<DmMsg> = p.actor.into();
                    let _ = actor.cast(DmMsg::Inject {
                        fault: FaultKind::Panic,
                    });
                }
            }
            "stop" => break,
            _ => {}
        }
    }
    stop.store(true, Ordering::Relaxed);
    for t in tasks {
        t.await.unwrap();
    }
    watcher.await.unwrap();
    // the replicas settle: the same seq applied everywhere, then their digests
    let start = Instant::now();
    let replicas = loop {
        let mut replicas = Vec::new();
        for node in NODES {
            let member = ractor::pg::get_scoped_members(
                &dm::REPLICA_SCOPE.to_string(),
                &format!("feature/{node}"),
            )
            .into_iter()
            .next();
            if let Some(cell) = member {
                let actor: ActorRef<DmMsg> = cell.into();
                if let Ok(ractor::rpc::CallResult::Success(d)) = actor
                    .call(
                        |reply| DmMsg::Digest { reply },
                        Some(Duration::from_secs(5)),
                    )
                    .await
                {
                    replicas.push((node, d));
                }
            }
        }
        if replicas.len() == 3 && replicas.iter().all(|(_, d)| d.upto == replicas[0].1.upto) {
            break replicas;
        }
        assert!(
            start.elapsed() < T,
            "the replicas did not settle: {replicas:?}"
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    };
    for (node, d) in replicas {
        say(format!(
            "replica {node} {} {} {}",
            d.upto, d.records, d.digest
        ));
    }
    for r in client.select(Query::all()).await.unwrap() {
        let (p, n): (u64, u64) = r.decode().unwrap();
        say(format!("have {} {p} {n}", r.seq));
    }
    say("done".to_string());
    transport.stop().await;
}
