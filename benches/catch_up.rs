//! How long a killed node takes to catch up once it is started again (issue 43's catch-up
//! bench), on real `marie node` processes on 127.0.0.1 in the thesis layout
//! (`missions/clusters/thesis.toml`: cart, features, operations, spare; the feature,
//! parameter, world and run datamanagers each kept in three replicas on features,
//! operations and spare), each node started as `marie up` starts it — same flags, a data
//! directory of its own, the cluster file — so a node started again reopens its journals.
//!
//! - **fill**: this bench joins the cluster as a member and stores N records (default
//!   1 000 000) into `feature` with `put_all`, every one acknowledged (in a majority of
//!   the replicas' journals); the feature datamanager holds them all (the bench's copy of
//!   the cluster file gives class `sonar` a retention bound above N: the default keeps
//!   10 000 per class).
//! - **rounds** (default 5): `kill -9` of a node that keeps a feature replica — a
//!   follower's node and the leader's node in turn, never the cart —; once every
//!   datamanager has a leader again, M more records (default 10 000) are stored while it is
//!   down; then it is started again with its own command line (its address, every other
//!   node as a peer, its data directory), as `marie up` restarts a node. Measured from the
//!   new process's spawn: when it listened (its journals read back: a datamanager recovers
//!   in its start), when every leader of a datamanager with a replica on it reached that
//!   replica again (rejoined), and when every such leader counted it at lag 0 or it led —
//!   caught up, by [`marie::dm::caught_up`] over [`marie::dm::replica_views`], as `marie up`
//!   judges a restarted node. The replicas are asked every 20 ms. Then what each of its
//!   replicas read back from its journal and what it received from its leader.
//! - **goal**: caught up ≤ 2 s from the restart, p50 over the rounds. A missed goal is
//!   said, and exits 0; a broken run (a node that does not start, a cluster that does not
//!   heal within its timeouts) panics, with every node killed by its pid.
//!
//! ```text
//! cargo bench --bench catch_up                          # 1 000 000 records, 5 rounds
//! MARIE_BENCH_RECORDS=100000 MARIE_BENCH_ROUNDS=2 cargo bench --profile dev --bench catch_up
//!                                                       # a quick one, in a debug build
//! ```
//!
//! Knobs: `MARIE_BENCH_RECORDS` (the fill), `MARIE_BENCH_ROUNDS`, `MARIE_BENCH_WHILE_DOWN`
//! (records stored while the node is down), `MARIE_TEST_LOGS=DIR` (each node's log, at
//! `RUST_LOG=info`, in DIR — the end-to-end tests' knob, as the nodes are started by their
//! helpers).

// both allow the parts a bench or a test does not use
mod common;
#[path = "../tests/common/mod.rs"]
mod e2e;

use e2e::cluster::Proc;
use marie::cluster::layout::ClusterLayout;
use marie::cluster::net::{ClusterConfig, Transport};
use marie::dm::{self, DmClient, DmMsg, DmStats, ReplicaStats};
use ractor::rpc::CallResult;
use ractor::ActorRef;
use std::collections::BTreeMap;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant};

/// The goal: caught up within this, p50 over the rounds, from the restart.
const GOAL: Duration = Duration::from_secs(2);
/// How often the replicas are asked while a restarted node catches up.
const PROBE_EVERY: Duration = Duration::from_millis(20);
/// How long a replica has to answer a probe.
const PROBE_TIMEOUT: Duration = Duration::from_millis(500);
/// How long the cluster may take to heal (a leader again, a node caught up) before the run
/// is taken as broken: generous, for a loaded 2-core machine and a debug build.
const HEAL_WITHIN: Duration = Duration::from_secs(120);
/// This bench's name as a member of the cluster.
const ME: &str = "catch-up-bench";

/// The bench's knobs, from the environment.
struct Knobs {
    records: u64,
    rounds: usize,
    while_down: u64,
}

impl Knobs {
    fn from_env() -> Knobs {
        let var = |name: &str, default: u64| {
            std::env::var(name)
                .ok()
                .map(|v| {
                    v.parse()
                        .unwrap_or_else(|_| panic!("{name}={v}: a whole number, please"))
                })
                .unwrap_or(default)
        };
        Knobs {
            records: var("MARIE_BENCH_RECORDS", 1_000_000),
            rounds: var("MARIE_BENCH_ROUNDS", 5).max(1) as usize,
            while_down: var("MARIE_BENCH_WHILE_DOWN", 10_000),
        }
    }

    /// Every record the bench stores, fill and rounds.
    fn total(&self) -> u64 {
        self.records + self.rounds as u64 * self.while_down
    }
}

// ---------------------------------------------------------------------------------------
// The nodes, started as `marie up` starts them

/// One node of the layout: how it is started, and its process.
struct Node {
    name: String,
    config: PathBuf,
    data_dir: PathBuf,
    /// Where it listens (the port its first start bound, kept for its restarts).
    addr: SocketAddr,
    proc: Option<Proc>,
}

/// The thesis layout's node processes.
struct Cluster {
    layout: ClusterLayout,
    nodes: Vec<Node>,
}

impl Cluster {
    /// The layout of `file`, its nodes not started yet; their data directories under `dir`.
    fn new(file: &Path, dir: &Path) -> Cluster {
        let layout = ClusterLayout::load(file, &marie_missions::catalog())
            .unwrap_or_else(|d| panic!("{}: {d}", file.display()));
        let nodes = layout
            .nodes
            .iter()
            .map(|n| Node {
                name: n.config.name.clone(),
                config: n.path.clone(),
                data_dir: dir.join("data").join(&n.config.name),
                addr: SocketAddr::from(([127, 0, 0, 1], 0)),
                proc: None,
            })
            .collect();
        Cluster { layout, nodes }
    }

    /// Start every node as `marie up` does: the first listens, the others join it; each
    /// waited for until it listens.
    fn start_all(&mut self) {
        for i in 0..self.nodes.len() {
            let peers = match i {
                0 => Vec::new(),
                _ => vec![self.nodes[0].addr],
            };
            self.spawn(i, peers);
            self.listening(i);
        }
    }

    /// Spawn node `i` — at its address, joining `peers` —, with `marie up`'s flags (its
    /// `NodeChild::start`): its config, the cluster's cookie, speed, world and seed, its
    /// data directory and the cluster file that declares the replicas. The moment of the
    /// spawn.
    fn spawn(&mut self, i: usize, peers: Vec<SocketAddr>) -> Instant {
        let l = &self.layout;
        let n = &self.nodes[i];
        let mut args: Vec<String> = vec![
            "node".into(),
            "--config".into(),
            n.config.display().to_string(),
            "--listen".into(),
            n.addr.to_string(),
            "--cookie".into(),
            l.cookie.clone(),
            "--speed".into(),
            l.speed.to_string(),
            "--stop-with-stdin".into(),
        ];
        for p in peers {
            args.extend(["--peer".into(), p.to_string()]);
        }
        if let Some(w) = &l.world {
            args.extend(["--world".into(), w.display().to_string()]);
        }
        if let Some(s) = l.seed {
            args.extend(["--seed".into(), s.to_string()]);
        }
        args.extend(["--data-dir".into(), n.data_dir.display().to_string()]);
        args.extend(["--cluster".into(), l.path.display().to_string()]);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let spawned = Instant::now();
        let proc = Proc::spawn(&n.name, &args);
        self.nodes[i].proc = Some(proc);
        spawned
    }

    /// Wait until node `i` says it listens (its datamanagers started, their journals read
    /// back); when its line came. Its address is the one it bound.
    fn listening(&mut self, i: usize) -> Instant {
        let n = &mut self.nodes[i];
        let proc = n.proc.as_mut().expect("started");
        let (line, at) = proc.wait_line_timed(0, &format!("node {} listening on ", n.name));
        n.addr = line
            .split_once(" listening on ")
            .and_then(|(_, rest)| rest.split_whitespace().next()?.parse().ok())
            .unwrap_or_else(|| panic!("no address in {line:?}"));
        at
    }

    /// `kill -9` node `i`, and reap it.
    fn kill(&mut self, i: usize) {
        let mut proc = self.nodes[i].proc.take().expect("running");
        proc.signal_now(libc::SIGKILL);
        proc.wait_exit();
    }

    /// Start node `i` again as `marie up` restarts it: where it listened, joining every
    /// other node. The moment of the spawn.
    fn restart(&mut self, i: usize) -> Instant {
        let peers = (0..self.nodes.len())
            .filter(|j| *j != i)
            .map(|j| self.nodes[j].addr)
            .collect();
        self.spawn(i, peers)
    }

    fn index(&self, name: &str) -> usize {
        self.nodes
            .iter()
            .position(|n| n.name == name)
            .unwrap_or_else(|| panic!("no node {name} in the layout"))
    }

    /// The replicated datamanagers with a replica on `node`.
    fn dms_on(&self, node: &str) -> Vec<String> {
        self.layout
            .datamanagers
            .iter()
            .filter(|d| d.replicas.iter().any(|r| r == node))
            .map(|d| d.name.clone())
            .collect()
    }

    /// Every node that keeps a replica.
    fn replica_nodes(&self) -> Vec<String> {
        self.nodes
            .iter()
            .map(|n| n.name.clone())
            .filter(|n| !self.dms_on(n).is_empty())
            .collect()
    }
}

/// The thesis cluster file, written into `dir` with the nodes' configs and the world at
/// their paths in the repository, and a retention bound for class `sonar` of the feature
/// datamanager that keeps every record the bench stores.
fn cluster_file(dir: &Path, keep: u64) -> PathBuf {
    let file = e2e::layouts::thesis_with(dir, "");
    let text = std::fs::read_to_string(&file).expect("the cluster file");
    let declared = "name = \"feature\"\n";
    assert!(
        text.contains(declared),
        "thesis.toml declares no feature datamanager"
    );
    let text = text.replace(
        declared,
        &format!("{declared}class_retention = {{ sonar = {keep} }}\n"),
    );
    std::fs::write(&file, text).expect("the cluster file");
    file
}

// ---------------------------------------------------------------------------------------
// What the replicas say

/// Every replica's view, by datamanager.
async fn views() -> BTreeMap<String, Vec<ReplicaStats>> {
    dm::replica_views(PROBE_TIMEOUT).await
}

/// Whether every declared datamanager's leader (answering from here) is on a node other
/// than `not`.
fn led_without(cluster: &Cluster, views: &BTreeMap<String, Vec<ReplicaStats>>, not: &str) -> bool {
    cluster.layout.datamanagers.iter().all(|d| {
        views
            .get(&d.name)
            .and_then(|v| dm::newest_leader(v))
            .is_some_and(|l| l.node != not)
    })
}

/// Whether every leader of a datamanager with a replica on `node` reaches that replica
/// again (or it leads).
fn rejoined(cluster: &Cluster, views: &BTreeMap<String, Vec<ReplicaStats>>, node: &str) -> bool {
    cluster.dms_on(node).iter().all(|d| {
        views
            .get(d)
            .and_then(|v| dm::newest_leader(v))
            .is_some_and(|l| l.node == node || l.reachable.iter().any(|n| n == node))
    })
}

/// Wait until `done` holds of the replicas' views (asked every [`PROBE_EVERY`]); when the
/// probe that found it ended. A cluster that does not get there within [`HEAL_WITHIN`] is a
/// broken run.
async fn until(
    what: &str,
    mut done: impl FnMut(&BTreeMap<String, Vec<ReplicaStats>>) -> bool,
) -> Instant {
    let start = Instant::now();
    loop {
        let v = views().await;
        if done(&v) {
            return Instant::now();
        }
        assert!(
            start.elapsed() < HEAL_WITHIN,
            "not {what} within {HEAL_WITHIN:?}; the replicas say: {v:#?}"
        );
        tokio::time::sleep(PROBE_EVERY).await;
    }
}

/// The whole cluster: every declared datamanager led, every replica caught up.
async fn whole(cluster: &Cluster) {
    let nodes = cluster.replica_nodes();
    until("whole", |v| {
        led_without(cluster, v, "") && nodes.iter().all(|n| dm::caught_up(n, v))
    })
    .await;
}

/// What the replica of `dm` on `node` holds — its own numbers, and what its start read
/// back from its journal — once this member finds it (it redials a restarted node with
/// backoff).
async fn replica_stats(dm: &str, node: &str) -> DmStats {
    let scope = dm::REPLICA_SCOPE.to_string();
    let group = format!("{dm}/{node}");
    let start = Instant::now();
    loop {
        for cell in ractor::pg::get_scoped_members(&scope, &group) {
            let actor = ActorRef::<DmMsg>::from(cell);
            let asked = actor
                .call(|reply| DmMsg::ReplicaStats { reply }, Some(PROBE_TIMEOUT))
                .await;
            if let Ok(CallResult::Success(stats)) = asked {
                return stats;
            }
        }
        assert!(
            start.elapsed() < HEAL_WITHIN,
            "the replica of {dm} on {node} does not answer"
        );
        tokio::time::sleep(PROBE_EVERY).await;
    }
}

// ---------------------------------------------------------------------------------------
// The rounds

/// What one round measured, from the restart's spawn.
struct Round {
    listening: Duration,
    rejoined: Duration,
    caught_up: Duration,
    /// The longest of its replicas' journal replays (in its start, before it listened).
    replay: Duration,
}

/// The records of the bench, `from..to`, class `sonar`.
fn records(from: u64, to: u64) -> impl Iterator<Item = marie::dm::NewRecord> {
    (from..to).map(|i| common::sonar(i, ME))
}

/// Store `from..to`, every one acknowledged; how long it took.
async fn store(client: &DmClient, from: u64, to: u64) -> Duration {
    let start = Instant::now();
    client
        .put_all(records(from, to))
        .await
        .unwrap_or_else(|e| panic!("put_all of records {from}..{to}: {e}"));
    start.elapsed()
}

/// Round `r`: kill a node, store while it is down, start it again and time its catch-up.
fn round(
    rt: &tokio::runtime::Runtime,
    cluster: &mut Cluster,
    client: &DmClient,
    knobs: &Knobs,
    r: usize,
) -> Round {
    // a whole cluster first: the node hit in the round before has caught up, and the
    // leaders have settled
    rt.block_on(whole(cluster));
    let victim = rt.block_on(victim(cluster, r));
    let roles = rt.block_on(roles_of(&victim));
    let i = cluster.index(&victim);
    let killed = Instant::now();
    cluster.kill(i);
    let led = rt.block_on(led_again(cluster, &victim, killed));
    let from = knobs.records + r as u64 * knobs.while_down;
    let wrote = rt.block_on(store(client, from, from + knobs.while_down));
    // the measure must start from a node that has something to catch up
    let v = rt.block_on(views());
    assert!(
        !dm::caught_up(&victim, &v),
        "{victim} counts as caught up while it is down: {v:#?}"
    );
    let spawned = cluster.restart(i);
    let rejoined = rt.block_on(until("rejoined", |v| rejoined(cluster, v, &victim)));
    let caught = rt.block_on(until("caught up", |v| dm::caught_up(&victim, v)));
    let listening = cluster.listening(i);
    println!(
        "  round {}: kill -9 of {victim} ({roles}); led again after {led}; {} records \
         stored while it was down in {:.2} s",
        r + 1,
        knobs.while_down,
        wrote.as_secs_f64()
    );
    let mut round = Round {
        listening: listening.saturating_duration_since(spawned),
        rejoined: rejoined.saturating_duration_since(spawned),
        caught_up: caught.saturating_duration_since(spawned),
        replay: Duration::ZERO,
    };
    println!(
        "    from its restart: listening {:.2} s, rejoined {:.2} s, caught up {:.2} s",
        round.listening.as_secs_f64(),
        round.rejoined.as_secs_f64(),
        round.caught_up.as_secs_f64()
    );
    for d in cluster.dms_on(&victim) {
        let (said, replay) = rt.block_on(recovered(&d, &victim));
        println!("    {said}");
        round.replay = round.replay.max(replay);
    }
    round
}

/// Wait until every declared datamanager has a leader on a node other than `victim`
/// (killed at `killed`); when each had one: `feature 0.02 s, parameter 1.15 s, ...`.
async fn led_again(cluster: &Cluster, victim: &str, killed: Instant) -> String {
    let mut led: BTreeMap<String, Duration> = BTreeMap::new();
    until("led again", |v| {
        for d in &cluster.layout.datamanagers {
            let now = v
                .get(&d.name)
                .and_then(|v| dm::newest_leader(v))
                .is_some_and(|l| l.node != victim);
            if now && !led.contains_key(&d.name) {
                led.insert(d.name.clone(), killed.elapsed());
            }
        }
        led_without(cluster, v, victim)
    })
    .await;
    led.iter()
        .map(|(d, t)| format!("{d} {:.2} s", t.as_secs_f64()))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The node to kill in round `r`: the feature datamanager's leader's in odd rounds, in
/// even ones a follower's (each in turn).
async fn victim(cluster: &Cluster, r: usize) -> String {
    let v = views().await;
    let leader = v
        .get(dm::FEATURE.name)
        .and_then(|v| dm::newest_leader(v))
        .map(|l| l.node.clone())
        .expect("a whole cluster has a feature leader");
    if r % 2 == 1 {
        return leader;
    }
    let followers: Vec<String> = cluster
        .layout
        .datamanagers
        .iter()
        .find(|d| d.name == dm::FEATURE.name)
        .expect("the layout declares the feature datamanager")
        .replicas
        .iter()
        .filter(|n| **n != leader)
        .cloned()
        .collect();
    followers[(r / 2) % followers.len()].clone()
}

/// What `node`'s replicas are: `leads feature, follows parameter, world, run`.
async fn roles_of(node: &str) -> String {
    let v = views().await;
    let (mut leads, mut follows) = (Vec::new(), Vec::new());
    for (d, replicas) in &v {
        match dm::newest_leader(replicas) {
            Some(l) if l.node == node => leads.push(d.as_str()),
            _ if replicas.iter().any(|r| r.node == node) => follows.push(d.as_str()),
            _ => {}
        }
    }
    let mut said = Vec::new();
    if !leads.is_empty() {
        said.push(format!("leads {}", leads.join(", ")));
    }
    if !follows.is_empty() {
        said.push(format!("follows {}", follows.join(", ")));
    }
    said.join("; ")
}

/// What the replica of `dm` on `node` read back from its journal and received since:
/// `feature: journal 1000000 records (1000003 entries) in 812 ms; received 10000 records,
/// no snapshot`; and how long its replay took.
async fn recovered(dm: &str, node: &str) -> (String, Duration) {
    let stats = replica_stats(dm, node).await;
    let snapshots = stats.replica.as_ref().map_or(0, |r| r.snapshots_taken);
    let journal = match &stats.recovery {
        Some(r) => format!(
            "journal {} records ({} entries, {:.1} MB) in {} ms",
            r.records,
            r.entries,
            r.bytes as f64 / 1e6,
            r.millis
        ),
        None => "no journal".to_string(),
    };
    let from_journal = stats.recovery.as_ref().map_or(0, |r| r.records);
    let replay = Duration::from_millis(stats.recovery.as_ref().map_or(0, |r| r.millis));
    let said = format!(
        "{dm}: {journal}; received {} records, {}",
        stats.records.saturating_sub(from_journal),
        match snapshots {
            0 => "no snapshot".to_string(),
            n => format!("{n} snapshot(s) of the leader's store"),
        }
    );
    (said, replay)
}

// ---------------------------------------------------------------------------------------

/// The machine's load averages (`/proc/loadavg`), for the numbers' context.
fn load() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|l| l.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_else(|_| "unknown".into())
}

fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("a runtime")
}

/// This process as a member of the cluster.
async fn join(cluster: &Cluster) -> Transport {
    let mut me = ClusterConfig::new("127.0.0.1:0".parse().unwrap(), &cluster.layout.cookie);
    for n in &cluster.nodes {
        me = me.with_peer(n.addr);
    }
    let transport = Transport::start(ME, &me).await.expect("joins the cluster");
    transport
        .wait_for_peers(cluster.nodes.len(), HEAL_WITHIN)
        .await
        .expect("sees every node");
    transport
}

/// Fill the feature datamanager from its preferred leader's start; the client.
async fn fill(cluster: &Cluster, knobs: &Knobs) -> DmClient {
    let preferred = cluster
        .layout
        .datamanagers
        .iter()
        .find(|d| d.name == dm::FEATURE.name)
        .map(|d| d.replicas[0].clone())
        .expect("the layout declares the feature datamanager");
    // the leader on its preferred node first: one elected elsewhere at the start hands it
    // the role, and the puts in flight would be sent again — a hand-over inside the fill
    until("led from its preferred node", |v| {
        v.get(dm::FEATURE.name)
            .and_then(|v| dm::newest_leader(v))
            .is_some_and(|l| l.node == preferred)
    })
    .await;
    let client = DmClient::lookup_within(dm::FEATURE.name, ME, HEAL_WITHIN)
        .await
        .expect("the feature datamanager")
        .with_follow(Duration::from_secs(30));
    let took = store(&client, 0, knobs.records).await;
    let stats = client
        .stats()
        .await
        .expect("the feature datamanager's stats");
    assert!(
        stats.records >= knobs.records && stats.dropped == 0,
        "the feature datamanager holds {} of {} records ({} dropped)",
        stats.records,
        knobs.records,
        stats.dropped
    );
    println!(
        "fill: {} records stored into feature with put_all, every one acknowledged, in \
         {:.1} s ({:.0} records/s); it holds {}",
        knobs.records,
        took.as_secs_f64(),
        knobs.records as f64 / took.as_secs_f64(),
        stats.records
    );
    client
}

fn main() -> ExitCode {
    if std::env::args().any(|a| a == "--list") {
        println!("catch_up: bench");
        return ExitCode::SUCCESS;
    }
    let knobs = Knobs::from_env();
    println!(
        "catch-up: the thesis layout, {} records in feature, {} rounds of kill -9, {} records \
         stored while the node is down, then its restart (load average {})",
        knobs.records,
        knobs.rounds,
        knobs.while_down,
        load()
    );
    let dir = tempfile::Builder::new()
        .prefix("marie-bench-catch-up-")
        .tempdir()
        .expect("a temporary directory");
    let file = cluster_file(dir.path(), knobs.total());
    let mut cluster = Cluster::new(&file, dir.path());
    cluster.start_all();
    let rt = runtime();
    let transport = rt.block_on(join(&cluster));
    let client = rt.block_on(async {
        whole(&cluster).await;
        fill(&cluster, &knobs).await
    });
    let rounds: Vec<Round> = (0..knobs.rounds)
        .map(|r| round(&rt, &mut cluster, &client, &knobs, r))
        .collect();
    rt.block_on(transport.stop());
    drop(cluster);
    summary(&rounds);
    ExitCode::SUCCESS
}

/// p50, p90 and max of each measure over the rounds, and the goal.
fn summary(rounds: &[Round]) {
    let spread = |f: fn(&Round) -> Duration| {
        let mut v: Vec<Duration> = rounds.iter().map(f).collect();
        v.sort();
        let s = |p| common::percentile(&v, p).as_secs_f64();
        (s(0.5), s(0.9), s(1.0))
    };
    for (what, f) in [
        (
            "listening from the restart",
            (|r: &Round| r.listening) as fn(&Round) -> Duration,
        ),
        ("journal replay (its longest, before it listened)", |r| {
            r.replay
        }),
        ("rejoined from the restart", |r| r.rejoined),
        ("caught up from the restart", |r| r.caught_up),
    ] {
        let (p50, p90, max) = spread(f);
        println!(
            "{what} over {} rounds: p50 {p50:.2} s, p90 {p90:.2} s, max {max:.2} s",
            rounds.len()
        );
    }
    let (p50, _, _) = spread(|r| r.caught_up);
    println!(
        "goal: every replica caught up <= {:.0} s from the restart, p50: {p50:.2} s — {} (load average {})",
        GOAL.as_secs_f64(),
        if p50 <= GOAL.as_secs_f64() {
            "PASS"
        } else {
            "MISSED"
        },
        load()
    );
}
