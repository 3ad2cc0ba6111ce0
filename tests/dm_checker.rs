//! The checker of a replicated datamanager: several producers store records, each
//! acknowledged, into `feature` kept in three replicas on three `marie node` processes, while
//! readers on every node's side read each producer's newest record, and a seeded schedule of
//! faults hits the node of whichever replica is leader at that moment — `kill -9` (and a
//! restart on its data directory), a freeze (SIGSTOP, then SIGCONT), a partition that cuts it
//! off from everyone (network namespaces), a crash of the datamanager itself (a panic,
//! restarted by its supervisor). At the end it reads the leader's records and every replica's
//! digest and checks: every acknowledged record present exactly once at its seq, each
//! producer's records in its order, no record that was never put, all replicas equal — and no
//! stale read: a read answered never shows a producer's newest record older than one
//! acknowledged before the read began (the reads are linearizable against the acknowledged
//! writes). It prints the table.
//!
//! CI runs a short schedule, and a control: the same checker on nodes whose replicas answer
//! reads unchecked (no leases: `MARIE_DM_UNCHECKED_READS`), a leader cut off for long enough
//! to be replaced — its readers must catch stale reads there. For long runs (1000 faults):
//!
//! ```sh
//! MARIE_CHECKER_FAULTS=1000 MARIE_CHECKER_SEED=7 \
//!     cargo test --release --test e2e -- dm_checker:: --nocapture
//! ```
//! (`scripts/dm-checker` does that; `MARIE_CHECKER_UNCHECKED=1` runs the schedule with reads
//! unchecked, and expects stale reads.)
//!
//! The producers run in a child process — this test binary again — inside a network
//! namespace of its own, so a partition can cut them off too; they print what they put and
//! what was acknowledged, and take orders (`crash`, `stop`) on stdin. The readers run in
//! three more children, one in each node's namespace, so that a partition leaves one with
//! the node cut off; they print every read with when it began and ended (the monotonic
//! clock, which the namespaces share), the acknowledgements likewise. Needs root for the
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
/// Which child this test binary runs as (unset: the checker itself).
const CHILD: &str = "MARIE_CHECKER_CHILD";

/// The machine's monotonic clock, in ns: the same in every namespace and process, so that a
/// read's start and an acknowledgement printed by different children compare.
fn mono_ns() -> u64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid timespec for the call to fill
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}

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

/// Start node `i` in its namespace (the others joining node 0); with its replicas
/// answering reads unchecked if `unchecked` (the control run).
fn start_node(net: &Netns, dir: &Path, i: usize, unchecked: bool) -> NodeProc {
    let name = NODES[i];
    let listen = net.addr(i, PORT);
    let peers = if i == 0 {
        Vec::new()
    } else {
        vec![net.addr(0, PORT)]
    };
    let path =
        common::cluster::node_config(dir, name, &config(dir, name), listen, &peers, COOKIE, "");
    let env: Vec<(&str, String)> = if unchecked {
        vec![(marie::dm::UNCHECKED_READS_ENV, "1".to_string())]
    } else {
        Vec::new()
    };
    NodeProc::launch_with(
        Some(net.ns(i)),
        listen,
        name,
        &[
            "node",
            "--config",
            path.to_str().unwrap(),
            "--stop-with-stdin",
        ],
        &env,
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
    /// Per producer, (when acknowledged, its record number), in the order they came.
    acked_at: BTreeMap<u64, Vec<(u64, u64)>>,
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
                    self.acked_at.entry(n(1)).or_default().push((n(4), n(2)));
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

/// What a checker's run does: how many faults of which kinds, how long a partition lasts,
/// and whether the replicas answer reads unchecked (a control run, which must catch stale
/// reads).
struct Plan {
    faults: u64,
    seed: u64,
    kinds: Vec<&'static str>,
    /// A partition lasts between these (ms).
    partition_ms: (u64, u64),
    unchecked: bool,
}

const KINDS: [&str; 4] = ["kill", "freeze", "partition", "crash"];

/// One read of a producer's newest record, as a reader told it.
struct Read {
    reader: String,
    producer: u64,
    /// The newest record number it showed (`None`: not answered — refused, or no answer in
    /// time).
    seen: Option<u64>,
    /// When it began and ended (ns of the monotonic clock).
    began: u64,
    ended: u64,
}

/// What a reader said, read so far.
#[derive(Default)]
struct Reads {
    read: usize,
    reads: Vec<Read>,
    done: bool,
}

impl Reads {
    fn take(&mut self, reader: &mut Proc) {
        let lines = reader.drain();
        for line in &lines[self.read..] {
            let w: Vec<&str> = line.split_whitespace().collect();
            let n = |i: usize| w.get(i).and_then(|s| s.parse::<u64>().ok());
            match w.first().copied() {
                // read READER PRODUCER SEEN|- BEGAN ENDED
                Some("read") if w.len() == 6 => self.reads.push(Read {
                    reader: w[1].to_string(),
                    producer: n(2).unwrap_or(0),
                    seen: n(3),
                    began: n(4).unwrap_or(0),
                    ended: n(5).unwrap_or(0),
                }),
                Some("done") => self.done = true,
                _ => {}
            }
        }
        self.read = lines.len();
    }
}

/// Tell the readers to stop, and gather every read they made.
fn stop_readers(readers: &mut [(Proc, Reads)]) -> Vec<Read> {
    for (proc, _) in readers.iter_mut() {
        proc.tell("stop");
    }
    let start = Instant::now();
    for (proc, reads) in readers.iter_mut() {
        while !reads.done {
            reads.take(proc);
            assert!(
                start.elapsed() < T,
                "a reader did not stop within {T:?}: {:?}",
                proc.stderr_tail()
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }
    readers
        .iter_mut()
        .flat_map(|(_, r)| std::mem::take(&mut r.reads))
        .collect()
}

/// The reads answered with an older state than one acknowledged before they began: a
/// producer's newest record shown below the newest of its records acknowledged before the
/// read began. Each is printed.
fn stale_reads(heard: &Heard, reads: &[Read]) -> usize {
    let mut stale = 0;
    for r in reads {
        let Some(seen) = r.seen else { continue };
        let acked = heard
            .acked_at
            .get(&r.producer)
            .map_or(&[][..], Vec::as_slice);
        // acknowledgements come in order of their record numbers, and of time
        let before = acked.partition_point(|(t, _)| *t < r.began);
        let Some((at, must)) = before.checked_sub(1).map(|i| acked[i]) else {
            continue;
        };
        if seen < must {
            stale += 1;
            if stale <= 20 {
                eprintln!(
                    "STALE: reader on {} saw producer {}'s record {seen} in a read of {} ms; \
                     record {must} was acknowledged {} ms before the read began",
                    r.reader,
                    r.producer,
                    (r.ended - r.began) / 1_000_000,
                    (r.began - at) / 1_000_000
                );
            }
        }
    }
    stale
}

#[test]
fn replicated_datamanager_checker_under_kill_freeze_partition_and_crash() {
    if std::env::var_os(CHILD).is_some() {
        return; // a child runs the producers' or the readers' test instead
    }
    // the kinds of faults (`MARIE_CHECKER_KINDS=partition,freeze`) and how long a
    // partition lasts (`MARIE_CHECKER_PARTITION_MS=3000,3500`) may be chosen: the control's
    // own schedule, with leases, is `MARIE_CHECKER_KINDS=partition
    // MARIE_CHECKER_PARTITION_MS=3000,3500 MARIE_CHECKER_FAULTS=2`
    let kinds = match std::env::var("MARIE_CHECKER_KINDS") {
        Ok(list) => KINDS
            .into_iter()
            .filter(|k| list.split(',').any(|w| w.trim() == *k))
            .collect(),
        Err(_) => KINDS.to_vec(),
    };
    assert!(
        !kinds.is_empty(),
        "MARIE_CHECKER_KINDS names none of {KINDS:?}"
    );
    let ms: Vec<u64> = std::env::var("MARIE_CHECKER_PARTITION_MS")
        .ok()
        .map(|v| v.split(',').filter_map(|w| w.trim().parse().ok()).collect())
        .unwrap_or_default();
    let partition_ms = match ms[..] {
        [from, to] if from <= to => (from, to),
        _ => (500, 3000),
    };
    run(Plan {
        faults: env_or("MARIE_CHECKER_FAULTS", 8),
        seed: env_or("MARIE_CHECKER_SEED", 1),
        kinds,
        partition_ms,
        unchecked: std::env::var_os("MARIE_CHECKER_UNCHECKED").is_some(),
    });
}

#[test]
fn without_leases_the_readers_catch_stale_reads() {
    // the control of the check: replicas answering reads at once (the protocol before
    // leases), the leader cut off for longer than the others take to elect a new one and
    // acknowledge writes, while the reader on its side reads on — they must see it answer
    // stale reads, else the check above proves nothing
    if std::env::var_os(CHILD).is_some() {
        return;
    }
    run(Plan {
        faults: 2,
        seed: env_or("MARIE_CHECKER_SEED", 1),
        kinds: vec!["partition"],
        partition_ms: (3000, 3500),
        unchecked: true,
    });
}

/// Start one of this test binary's children: `role` (`producers` or `readers`, the test it
/// runs) in namespace `ns`, joining `peers`, with `env` besides.
fn child(net: &Netns, ns: usize, role: &str, peers: &[String], env: &[(&str, String)]) -> Proc {
    let mut all = vec![
        (CHILD, role.to_string()),
        ("MARIE_CHECKER_PEERS", peers.join(",")),
        ("MARIE_CHECKER_LISTEN", net.addr(ns, 0).to_string()),
    ];
    all.extend(env.iter().cloned());
    Proc::spawn_exe(
        Some(net.ns(ns)),
        &format!("{role}-{ns}"),
        &std::env::current_exe().unwrap(),
        &[
            "--exact",
            &format!("dm_checker::{role}"),
            "--nocapture",
            "--test-threads",
            "1",
        ],
        &all,
    )
}

fn run(plan: Plan) {
    let Some(net) = Netns::create(NODES.len() + 1) else {
        return;
    };
    let (faults, seed) = (plan.faults, plan.seed);
    let mut rng = Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1);
    let dir = tempfile::tempdir().unwrap();
    let mut nodes: Vec<NodeProc> = (0..NODES.len())
        .map(|i| start_node(&net, dir.path(), i, plan.unchecked))
        .collect();
    let peers: Vec<String> = (0..NODES.len())
        .map(|i| net.addr(i, PORT).to_string())
        .collect();
    let mut producers = child(&net, PRODUCERS_NS, "producers", &peers, &[]);
    // a reader on each node's side
    let mut readers: Vec<(Proc, Reads)> = (0..NODES.len())
        .map(|i| {
            let env = [("MARIE_CHECKER_READER", NODES[i].to_string())];
            (child(&net, i, "readers", &peers, &env), Reads::default())
        })
        .collect();
    let child = &mut producers;
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
    wait(child, &mut heard, "leader", &|h| h.leader.is_some());
    let mut done: BTreeMap<&str, u64> = BTreeMap::new();
    let n_kinds = plan.kinds.len() as u64;
    for k in 0..faults {
        std::thread::sleep(rng.ms(300, 1500));
        heard.take(child);
        for (proc, reads) in readers.iter_mut() {
            reads.take(proc);
        }
        let Some(leader) = heard.leader.clone() else {
            continue;
        };
        let i = NODES.iter().position(|n| *n == leader).expect("a node");
        // each kind once first, then as the seed draws them
        let pick = if k < n_kinds { k } else { rng.below(n_kinds) };
        let kind = plan.kinds[pick as usize];
        eprintln!("fault {k}: {kind} {leader}");
        match kind {
            "kill" => {
                nodes[i].signal("KILL");
                std::thread::sleep(rng.ms(300, 1500));
                nodes[i] = start_node(&net, dir.path(), i, plan.unchecked);
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
                std::thread::sleep(rng.ms(plan.partition_ms.0, plan.partition_ms.1));
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
        heard.take(child);
        let acked = heard.acked.len();
        wait(child, &mut heard, "progress after the fault", &|h| {
            h.acked.len() >= acked + PRODUCERS as usize
        });
    }
    let reads = stop_readers(&mut readers);
    child.tell("stop");
    wait(child, &mut heard, "final reading", &|h| h.done);
    let (answered, refused) = (
        reads.iter().filter(|r| r.seen.is_some()).count(),
        reads.iter().filter(|r| r.seen.is_none()).count(),
    );
    let stale = stale_reads(&heard, &reads);

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
    let reads_kind = if plan.unchecked { " (unchecked)" } else { "" };
    println!(
        "| seed | faults | acknowledged | deleted (classes) | stored | lost | duplicated | deleted yet there | out of order | never put | divergent replicas | reads{reads_kind} (answered, refused) | stale reads |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    println!(
        "| {seed} | {faults} ({}) | {} | {} | {} | {lost} | {duplicated} | {resurrected} | {out_of_order} | {never_put} | {divergent} of {} | {} ({answered}, {refused}) | {stale} |",
        kinds.join(", "),
        heard.acked.len(),
        heard.deleted.len(),
        heard.have.len(),
        heard.replicas.len(),
        reads.len()
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
    assert!(answered > 0, "the readers read");
    if plan.unchecked {
        assert!(stale > 0, "reads unchecked, and no stale read caught");
    } else {
        assert_eq!(stale, 0, "stale reads");
    }
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
    if std::env::var(CHILD).as_deref() != Ok("producers") {
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
                    // a source per producer: the readers ask for each one's newest record
                    record.source = format!("p{p}");
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
                say(format!("ack {p} {n} {seq} {}", mono_ns()));
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

/// A reader, in a node's namespace. Does nothing unless run by the checker.
#[test]
fn readers() {
    if std::env::var(CHILD).as_deref() != Ok("readers") {
        return;
    }
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap();
    rt.block_on(readers_run());
}

/// Read each producer's newest record, one after another (a select, then a select_wait,
/// by turns), and print every read: `read READER PRODUCER SEEN|- BEGAN ENDED`.
async fn readers_run() {
    use marie::cluster::net::{ClusterConfig, Transport};
    use marie::dm::{DmClient, Query};
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::Arc;

    let say = |s: String| println!("\n{s}");
    let me = std::env::var("MARIE_CHECKER_READER").unwrap();
    let listen = std::env::var("MARIE_CHECKER_LISTEN")
        .unwrap()
        .parse()
        .unwrap();
    let mut config = ClusterConfig::new(listen, COOKIE);
    for p in std::env::var("MARIE_CHECKER_PEERS").unwrap().split(',') {
        config = config.with_peer(p.parse().unwrap());
    }
    let transport = Transport::start(&format!("reader-{me}"), &config)
        .await
        .unwrap();
    transport.wait_for_peers(3, T).await.unwrap();
    // a read that waits longer than this is counted unanswered, and the reader goes on
    let patience = Duration::from_secs(5);
    let client = DmClient::lookup_within("feature", &format!("reader-{me}"), T)
        .await
        .expect("a leader published")
        .with_timeout(patience)
        .with_follow(patience);
    let stop = Arc::new(AtomicBool::new(false));
    let task = {
        let stop = stop.clone();
        tokio::spawn(async move {
            let mut turn = 0u64;
            while !stop.load(Ordering::Relaxed) {
                for p in 0..PRODUCERS {
                    let query = Query::all().source(format!("p{p}")).newest(1);
                    let began = mono_ns();
                    let answer = if turn % 2 == 0 {
                        client.select(query).await
                    } else {
                        client.select_wait(query, Duration::from_millis(50)).await
                    };
                    let ended = mono_ns();
                    let seen = match answer {
                        Ok(records) => match records.last() {
                            Some(r) => {
                                let (_, n): (u64, u64) = r.decode().unwrap();
                                n.to_string()
                            }
                            None => continue, // nothing stored yet
                        },
                        Err(_) => "-".to_string(),
                    };
                    say(format!("read {me} {p} {seen} {began} {ended}"));
                }
                turn += 1;
                tokio::time::sleep(Duration::from_millis(5)).await;
            }
        })
    };
    // the order to stop
    let (tx, rx) = tokio::sync::oneshot::channel::<()>();
    std::thread::spawn(move || {
        use std::io::BufRead;
        for line in std::io::stdin().lock().lines().map_while(Result::ok) {
            if line.trim() == "stop" {
                break;
            }
        }
        let _ = tx.send(());
    });
    let _ = rx.await;
    stop.store(true, Ordering::Relaxed);
    let _ = tokio::time::timeout(T, task).await;
    say("done".to_string());
    transport.stop().await;
}
