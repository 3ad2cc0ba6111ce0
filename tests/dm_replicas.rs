//! A datamanager kept in three replicas on three `marie node` processes survives `kill -9` of
//! its leader's process, and a freeze (SIGSTOP) of the next one past the failure
//! detector's deadline: each time a replica is elected leader, the record seqs continue, the
//! producer (a member of the cluster in this process) follows the name to it, and nothing
//! it had acknowledged is lost or stored twice; the killed node, started again on its data
//! directory, and the frozen one, woken, come back as replicas and catch up (the woken one
//! fenced by the newer term), and the three replicas end equal with one leader — the
//! preferred replica (r1) is handed the role back once it has caught up. And a `put_all` under
//! way when the leader's process is killed stores every record once, in order: what was on
//! its way to the lost leader is sent again to the next. A replica that comes back further
//! behind than the leader keeps entries for is sent a snapshot of the store, and ends
//! equal; a leader started again catches replicas up from the entries its journal holds.
//! A follower killed while records are stored is not caught up until it is started again
//! and holds every entry its leader does — the judgement (`marie_dm::caught_up`) `marie up`
//! and the catch-up bench time a restarted node by.
//! A request whose answer is lost on another node than its caller's — a leader deposed with
//! it, or a follower that sent it on to a leader whose node is killed — is answered at once
//! as lost, and its client asks again at the next leader (not at its own deadline).

use crate::common;

use common::cluster::NodeProc;
use marie::cluster::net::{ClusterConfig, Transport};
use marie::dm::{self, DmClient, DmMsg, DmStats, NewRecord, Query};
use marie::registry::{self, ModuleKind};
use ractor::ActorRef;
use std::collections::BTreeMap;
use std::path::Path;
use std::time::{Duration, Instant};

const COOKIE: &str = "replicas";
const NODES: [&str; 3] = ["r1", "r2", "r3"];
/// Generous: elections, a node's start, a journal replay, on a loaded 2-core machine.
const T: Duration = Duration::from_secs(60);

/// One member of one cluster at a time in this test process (see there).
use common::ONE_MEMBER;

/// The three nodes, each keeping a replica of `feature` (`extra`: more of its keys).
fn start_nodes(dir: &Path, extra: &str) -> Vec<NodeProc> {
    let mut nodes: Vec<NodeProc> = Vec::new();
    for name in NODES {
        let peers: Vec<_> = nodes.iter().map(|n| n.addr).collect();
        let config = hosts_with(dir, name, extra);
        nodes.push(NodeProc::start(dir, name, &config, &peers, COOKIE));
    }
    nodes
}

/// This process as a member of the nodes' cluster.
async fn join(nodes: &[NodeProc]) -> Transport {
    let mut me = ClusterConfig::new("127.0.0.1:0".parse().unwrap(), COOKIE);
    for n in nodes {
        me = me.with_peer(n.addr);
    }
    let transport = Transport::start("producer", &me).await.unwrap();
    transport.wait_for_peers(nodes.len(), T).await.unwrap();
    transport
}

fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap()
}

fn hosts(dir: &Path, name: &str) -> String {
    hosts_with(dir, name, "")
}

/// [`hosts`], with more keys for the datamanager.
fn hosts_with(dir: &Path, name: &str, extra: &str) -> String {
    format!(
        "data_dir = \"{}\"\n[[datamanager]]\nname = \"feature\"\ncopies = [\"r1\", \"r2\", \"r3\"]\n{extra}",
        dir.join(name).display()
    )
}

/// The replica of `feature` on `node`, from the replicas' groups.
fn copy_on(node: &str) -> Option<ActorRef<DmMsg>> {
    ractor::pg::get_scoped_members(&dm::REPLICA_SCOPE.to_string(), &format!("feature/{node}"))
        .into_iter()
        .next()
        .map(Into::into)
}

/// What the replica `actor` itself holds (its `Stats` a follower sends on to its leader).
async fn stats_of(actor: &ActorRef<DmMsg>) -> Option<DmStats> {
    match actor
        .call(
            |reply| DmMsg::ReplicaStats { reply },
            Some(Duration::from_secs(5)),
        )
        .await
    {
        Ok(ractor::rpc::CallResult::Success(s)) => Some(s),
        _ => None,
    }
}

/// Wait until the leader of `feature` is published (on a node other than `not`).
async fn leader(not: Option<&str>) -> (String, Instant) {
    primary_where(|node| Some(node) != not).await
}

/// Wait until the leader of `feature` is published on a node `fits` accepts: the registry
/// watched (an event awaited, not a poll).
async fn primary_where(fits: impl Fn(&str) -> bool) -> (String, Instant) {
    // watching first, then looking: a leader published in between is in one or the other
    let mut watch = registry::watch(Some(ModuleKind::Datamanager))
        .await
        .unwrap();
    let found = |i: &registry::Instance| i.answers_to("feature") && fits(&i.node);
    if let Some(i) = registry::lookup(ModuleKind::Datamanager, "feature")
        .into_iter()
        .find(|i| found(i))
    {
        return (i.node, Instant::now());
    }
    tokio::time::timeout(T, async {
        while let Some(event) = watch.next().await {
            if let registry::RegistryEvent::Joined(i) = event {
                if found(&i) {
                    return (i.node, Instant::now());
                }
            }
        }
        panic!("the registry watch ended");
    })
    .await
    .unwrap_or_else(|_| panic!("no leader of feature within {T:?}"))
}

/// The producer id of this test's records: a retry of record `v` is the same put.
const PRODUCER: u64 = 0x5eed;

/// Store value `v` until it is acknowledged (a store cut off by a fault is sent again as the
/// same put, which the datamanager stores once); its seq.
async fn store_acked(client: &DmClient, v: u64) -> u64 {
    let start = Instant::now();
    loop {
        let mut record = NewRecord::encode("echo", &v).unwrap();
        record.producer = PRODUCER;
        record.producer_seq = v + 1;
        match client.store_raw(record).await {
            Ok(seq) => return seq,
            Err(e) => {
                assert!(
                    start.elapsed() < T,
                    "value {v} not acknowledged within {T:?}: {e}"
                );
                eprintln!("store of {v}: {e}; again");
                tokio::time::sleep(Duration::from_millis(50)).await;
            }
        }
    }
}

/// Store values `range`, each acknowledged, into `acked` (seq -> value); the time of the
/// first acknowledgement.
async fn store_all(
    client: &DmClient,
    range: std::ops::Range<u64>,
    acked: &mut BTreeMap<u64, u64>,
) -> Instant {
    let mut first = None;
    for v in range {
        let seq = store_acked(client, v).await;
        first.get_or_insert_with(Instant::now);
        if let Some(old) = acked.insert(seq, v) {
            assert_eq!(old, v, "seq {seq} acknowledged for {old} and {v}");
        }
    }
    first.expect("a store")
}

/// Every acknowledged record is in the leader once, at its seq.
async fn check_acked(client: &DmClient, acked: &BTreeMap<u64, u64>) {
    let records = client.select(Query::class("echo")).await.unwrap();
    let mut values: BTreeMap<u64, u64> = BTreeMap::new();
    for r in &records {
        let v: u64 = r.decode().unwrap();
        assert!(values.insert(r.seq, v).is_none());
    }
    let mut seen = std::collections::BTreeSet::new();
    for v in values.values() {
        assert!(seen.insert(*v), "value {v} stored twice");
    }
    for (seq, v) in acked {
        assert_eq!(
            values.get(seq),
            Some(v),
            "acknowledged record {seq} ({v}) lost"
        );
    }
    eprintln!(
        "{} acknowledged, {} stored, 0 lost, 0 duplicated",
        acked.len(),
        values.len()
    );
}

/// Wait until the three replicas hold the same (records, last seq, commit) with one leader;
/// the replicas' stats.
async fn converged() -> Vec<DmStats> {
    let start = Instant::now();
    loop {
        let mut all = Vec::new();
        for n in NODES {
            if let Some(c) = copy_on(n) {
                if let Some(s) = stats_of(&c).await {
                    all.push(s);
                }
            }
        }
        let view = |s: &DmStats| {
            let r = s.replica.as_ref().unwrap();
            (s.records, s.last_seq, r.commit, s.classes.clone())
        };
        let leaders = all
            .iter()
            .filter(|s| s.replica.as_ref().unwrap().role == marie::replica::ReplicaRole::Leader)
            .count();
        if all.len() == 3 && leaders == 1 && all.iter().all(|s| view(s) == view(&all[0])) {
            let roles: Vec<_> = all
                .iter()
                .map(|s| {
                    let r = s.replica.as_ref().unwrap();
                    format!("{} {} term {}", r.node, r.role, r.term)
                })
                .collect();
            eprintln!("replicas equal: {:?}; {}", view(&all[0]), roles.join(", "));
            return all;
        }
        assert!(
            start.elapsed() < T,
            "the replicas did not converge: {all:#?}"
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}

#[test]
fn a_killed_and_a_frozen_leader_are_replaced_by_followers_and_no_acknowledged_record_is_lost() {
    let _one = ONE_MEMBER.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let mut nodes = start_nodes(dir.path(), "");
    let rt = runtime();
    let mut acked: BTreeMap<u64, u64> = BTreeMap::new();
    let (client, _transport) = rt.block_on(async {
        let transport = join(&nodes).await;
        let (first, _) = leader(None).await;
        assert_eq!(first, "r1", "the preferred replica is the first leader");
        let client = DmClient::lookup("feature", "producer")
            .unwrap()
            .with_follow(T);
        store_all(&client, 0..300, &mut acked).await;

        // kill -9 the leader's process
        let killed = Instant::now();
        nodes[0].signal("KILL");
        let first_after = store_all(&client, 300..600, &mut acked).await;
        let (second, _) = leader(Some("r1")).await;
        eprintln!(
            "r1 killed; {second} is leader; the first store acknowledged {} ms after the kill",
            (first_after - killed).as_millis()
        );
        check_acked(&client, &acked).await;
        (client, transport)
    });

    // r1 starts again on its data directory: a replica, which catches up
    let peers: Vec<_> = nodes[1..].iter().map(|n| n.addr).collect();
    nodes[0] = NodeProc::start(dir.path(), "r1", &hosts(dir.path(), "r1"), &peers, COOKIE);
    rt.block_on(async {
        // (r1 came back a follower and caught up; being the preferred replica, it may have been
        // handed the leader's role since)
        let all = converged().await;
        let r1 = all.iter().find(|s| s.replica.as_ref().unwrap().node == "r1").unwrap();
        assert!(r1.replica.as_ref().unwrap().term >= 2, "r1 is in a newer term");

        // freeze the leader past the failure detector's deadline, storing on
        let (frozen, _) = leader(None).await;
        let term_before = all
            .iter()
            .find(|s| s.replica.as_ref().unwrap().node == frozen)
            .map(|s| s.replica.as_ref().unwrap().term)
            .unwrap();
        let i = NODES.iter().position(|n| *n == frozen).unwrap();
        let stopped = Instant::now();
        nodes[i].signal("STOP");
        let first_after = store_all(&client, 600..900, &mut acked).await;
        let (next, _) = leader(Some(&frozen)).await;
        eprintln!(
            "{frozen} frozen; {next} is leader; the first store acknowledged {} ms after the freeze",
            (first_after - stopped).as_millis()
        );
        nodes[i].signal("CONT");
        let all = converged().await;
        let woken = all
            .iter()
            .find(|s| s.replica.as_ref().unwrap().node == frozen)
            .unwrap()
            .replica
            .clone()
            .unwrap();
        // fenced: it took the newer term (and, if it is the preferred replica, it may lead
        // again since, handed the role once it caught up)
        assert!(woken.term > term_before, "the woken leader took the newer term");
        check_acked(&client, &acked).await;
    });
}

#[test]
fn a_put_all_under_way_when_the_primary_is_killed_stores_every_record_once_in_order() {
    let _one = ONE_MEMBER.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let nodes = start_nodes(dir.path(), "");
    let rt = runtime();
    rt.block_on(async {
        let transport = join(&nodes).await;
        let (first, _) = leader(None).await;
        assert_eq!(first, "r1");
        let client = DmClient::lookup("feature", "bulk")
            .unwrap()
            .with_follow(T)
            .with_timeout(T);
        // a class per 8192 records: none reaches the retention bound (10 000)
        const N: u64 = 300_000;
        let class = |v: u64| format!("bulk-{}", v / 8192);
        // told when put_all takes the record a fifth of the way (it takes them as its window
        // lets it send)
        let fifth = std::sync::Arc::new(tokio::sync::Notify::new());
        let records = (0..N).map({
            let fifth = fifth.clone();
            move |v| {
                if v == N / 5 {
                    fifth.notify_one();
                }
                NewRecord::encode(class(v), &v).unwrap()
            }
        });
        let mut bulk = tokio::spawn({
            let client = client.clone();
            async move { client.put_all(records).await }
        });
        // kill -9 the leader's process with the transfer under way (watched from here:
        // polling r1's stats once saw the whole transfer end before it saw a fifth of it)
        tokio::select! {
            _ = fifth.notified() => {}
            ended = &mut bulk => panic!("the transfer ended before the kill: {ended:?}"),
        }
        nodes[0].signal("KILL");
        eprintln!("r1 killed with the transfer under way");
        bulk.await
            .unwrap()
            .expect("put_all completes on the next leader");
        // (which granted the wide window of a replicated datamanager: its acknowledgements
        // wait for a replica)
        assert_eq!(client.window(), Some(dm::REPLICATED_PUT_WINDOW));
        let (second, _) = leader(Some("r1")).await;
        let stored = client.select(Query::all()).await.unwrap();
        let values: Vec<u64> = stored
            .iter()
            .filter(|r| r.class.starts_with("bulk-"))
            .map(|r| r.decode::<u64>().unwrap())
            .collect();
        eprintln!("{second} is leader; {} of {N} records stored", values.len());
        // every record once, in the order put (seqs increase with the values)
        assert_eq!(values.len() as u64, N, "records lost or stored twice");
        assert!(
            values.iter().copied().eq(0..N),
            "every record once, in order"
        );
        transport.stop().await;
    });
}

#[test]
fn a_copy_further_behind_than_the_primary_keeps_entries_for_takes_in_a_snapshot() {
    let _one = ONE_MEMBER.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tempfile::tempdir().unwrap();
    // the leader keeps 100 applied entries in memory: a replica 600 behind needs a snapshot
    let extra = "catch_up = 100\n";
    let mut nodes = start_nodes(dir.path(), extra);
    let rt = runtime();
    rt.block_on(async {
        let transport = join(&nodes).await;
        let (first, _) = leader(None).await;
        assert_eq!(first, "r1");
        let client = DmClient::lookup("feature", "producer")
            .unwrap()
            .with_follow(T);
        let mut acked = BTreeMap::new();
        store_all(&client, 0..200, &mut acked).await;
        // r3 is lost; the others go on
        nodes[2].signal("KILL");
        store_all(&client, 200..800, &mut acked).await;
        let peers: Vec<_> = nodes[..2].iter().map(|n| n.addr).collect();
        let config = hosts_with(dir.path(), "r3", extra);
        nodes[2] = NodeProc::start(dir.path(), "r3", &config, &peers, COOKIE);
        let all = converged().await;
        let r3 = all
            .iter()
            .find(|s| s.replica.as_ref().unwrap().node == "r3")
            .unwrap();
        assert!(
            r3.replica.as_ref().unwrap().snapshots_taken >= 1,
            "r3 caught up from a snapshot: {r3:#?}"
        );
        // the snapshot carried the producers' numbers: a retried store is stored once
        let again = store_acked(&client, 799).await;
        assert_eq!(
            acked.iter().find(|(_, v)| **v == 799).map(|(s, _)| *s),
            Some(again)
        );
        check_acked(&client, &acked).await;
        transport.stop().await;
    });
}

#[test]
fn a_restarted_primary_catches_a_copy_up_from_its_journal_without_a_snapshot() {
    let _one = ONE_MEMBER.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let mut nodes = start_nodes(dir.path(), "");
    let restart = |nodes: &mut Vec<NodeProc>, i: usize| {
        let peers: Vec<_> = (0..3).filter(|j| *j != i).map(|j| nodes[j].addr).collect();
        let name = NODES[i];
        let config = hosts(dir.path(), name);
        nodes[i] = NodeProc::start(dir.path(), name, &config, &peers, COOKIE);
    };
    let rt = runtime();
    let transport = rt.block_on(join(&nodes));
    assert_eq!(rt.block_on(leader(None)).0, "r1");
    let client = DmClient::lookup("feature", "producer")
        .unwrap()
        .with_follow(T);
    let mut acked = BTreeMap::new();
    rt.block_on(store_all(&client, 0..100, &mut acked));
    // r3 is lost; 100 more; then the leader's process is killed and started again: it
    // leads again with the entries its journal holds, and r3, back, lacks entries from
    // before that restart
    nodes[2].signal("KILL");
    rt.block_on(store_all(&client, 100..200, &mut acked));
    nodes[0].signal("KILL");
    restart(&mut nodes, 0);
    rt.block_on(async {
        // r1 leads again
        primary_where(|node| node == "r1").await;
        store_all(&client, 200..250, &mut acked).await;
    });
    restart(&mut nodes, 2);
    rt.block_on(async {
        let all = converged().await;
        let r3 = all
            .iter()
            .find(|s| s.replica.as_ref().unwrap().node == "r3")
            .unwrap();
        assert_eq!(
            r3.replica.as_ref().unwrap().snapshots_taken,
            0,
            "r3 caught up from entries: {r3:#?}"
        );
        check_acked(&client, &acked).await;
        transport.stop().await;
    });
}

/// Wait until every leader of a datamanager with a replica on `node` counts it at lag 0 (or
/// it leads), as `marie up` and the catch-up bench judge it ([`dm::caught_up`]); the views
/// that said so.
async fn caught_up(node: &str) -> BTreeMap<String, Vec<marie::dm::ReplicaStats>> {
    let start = Instant::now();
    loop {
        let views = dm::replica_views(Duration::from_secs(1)).await;
        if dm::caught_up(node, &views) {
            return views;
        }
        assert!(
            start.elapsed() < T,
            "{node} not caught up within {T:?}: {views:#?}"
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

#[test]
fn a_follower_killed_while_records_are_stored_is_caught_up_once_restarted_and_not_before() {
    let _one = ONE_MEMBER.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let mut nodes = start_nodes(dir.path(), "");
    let rt = runtime();
    let transport = rt.block_on(join(&nodes));
    assert_eq!(rt.block_on(leader(None)).0, "r1");
    let client = DmClient::lookup("feature", "producer")
        .unwrap()
        .with_follow(T);
    let mut acked = BTreeMap::new();
    rt.block_on(async {
        store_all(&client, 0..100, &mut acked).await;
        caught_up("r3").await;
    });
    // r3 is killed; 200 records are acknowledged by r1 and r2 while it is down: it is not
    // caught up, whatever the leader remembers of it
    nodes[2].signal("KILL");
    rt.block_on(async {
        store_all(&client, 100..300, &mut acked).await;
        let views = dm::replica_views(Duration::from_secs(1)).await;
        assert!(!dm::caught_up("r3", &views), "{views:#?}");
    });
    // started again on its data directory, with its own command line: caught up, and when
    // the leader says so, r3's own log holds every entry the leader's did
    let peers: Vec<_> = nodes[..2].iter().map(|n| n.addr).collect();
    let config = hosts(dir.path(), "r3");
    nodes[2] = NodeProc::start(dir.path(), "r3", &config, &peers, COOKIE);
    rt.block_on(async {
        let views = caught_up("r3").await;
        let leader = dm::newest_leader(&views["feature"]).unwrap().clone();
        assert_eq!(leader.node, "r1");
        // this member redials r3 with backoff: its replica is found here a little later
        let start = Instant::now();
        let r3 = loop {
            if let Some(s) = match copy_on("r3") {
                Some(actor) => stats_of(&actor).await,
                None => None,
            } {
                break s;
            }
            assert!(start.elapsed() < T, "r3's replica does not answer");
            tokio::time::sleep(Duration::from_millis(50)).await;
        };
        let own = r3.replica.as_ref().unwrap();
        assert!(
            own.last >= leader.last,
            "counted at lag 0 with its log at {} of the leader's {}: {r3:#?}",
            own.last,
            leader.last
        );
        assert!(
            r3.recovery.as_ref().is_some_and(|r| r.entries >= 100),
            "r3 read its records back from its journal: {r3:#?}"
        );
        converged().await;
        check_acked(&client, &acked).await;
        transport.stop().await;
    });
}

#[test]
fn the_primary_recognises_a_retry_of_any_put_of_a_whole_window_and_answers_its_first_seq() {
    // a producer may have a window of puts unacknowledged (the wide one a replicated
    // datamanager grants); each one retried must be stored once. The leader notes each
    // put's pair when it proposes it: noting it again when it is applied filled the table
    // (then a producer's last 1024 pairs) twice as fast, and a retry of a put 513 back was
    // stored a second time
    let _one = ONE_MEMBER.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let nodes = start_nodes(dir.path(), "");
    let rt = runtime();
    let transport = rt.block_on(join(&nodes));
    let window = dm::REPLICATED_PUT_WINDOW as u64;
    rt.block_on(async {
        leader(None).await;
        let client = DmClient::lookup("feature", "producer")
            .unwrap()
            .with_follow(T);
        let mut acked = BTreeMap::new();
        store_all(&client, 0..window, &mut acked).await;
        let seq_of = |v: u64| acked.iter().find(|(_, w)| **w == v).map(|(s, _)| *s);
        for v in [0, window / 2 - 1, window - 1] {
            assert_eq!(
                Some(store_acked(&client, v).await),
                seq_of(v),
                "value {v} sent again was stored again"
            );
        }
        check_acked(&client, &acked).await;
        let stats = client.stats().await.unwrap();
        assert_eq!(stats.records, window, "{stats:#?}");
        transport.stop().await;
    });
}

/// How long a road of a client may take to reach the new leader once it is published:
/// generous (a loaded 2-core machine); a road that does not follow fails for ever.
const FOLLOWED_WITHIN: Duration = Duration::from_secs(20);

/// Put (`waiting`: `put_waiting`) value after value into class `road` through `client`, from
/// before the leader's node is killed until a put succeeds after the new leader is
/// published (`published`): how long after the publication that was, and the errors seen
/// since it; or the last error, if none succeeded within [`FOLLOWED_WITHIN`].
async fn produce(
    client: DmClient,
    road: &'static str,
    mut published: tokio::sync::watch::Receiver<Option<Instant>>,
) -> Result<(Duration, usize), String> {
    let waiting = road == "put_waiting";
    let mut errors_since = 0;
    for v in 0u64.. {
        let put = match waiting {
            true => client.put_waiting(road, None, None, &v).await,
            false => client.put(road, None, None, &v),
        };
        let now = Instant::now();
        let since = *published.borrow_and_update();
        if let Some(at) = since.filter(|at| now > *at) {
            match put {
                Ok(()) => return Ok((now - at, errors_since)),
                Err(e) if now - at >= FOLLOWED_WITHIN => return Err(e.to_string()),
                Err(_) => errors_since += 1,
            }
        }
        // about a thousand puts a second (a sensor's pace), awaiting as a sensor's loop does
        tokio::time::sleep(Duration::from_millis(1)).await;
    }
    unreachable!()
}

/// Take a road until it succeeds: how long that took; or its last error, if it did not
/// within [`FOLLOWED_WITHIN`].
async fn until_ok<F, Fut, T>(mut go: F) -> Result<Duration, String>
where
    F: FnMut() -> Fut,
    Fut: std::future::Future<Output = Result<T, dm::DmError>>,
{
    let start = Instant::now();
    loop {
        match go().await {
            Ok(_) => return Ok(start.elapsed()),
            Err(e) if start.elapsed() >= FOLLOWED_WITHIN => return Err(e.to_string()),
            Err(_) => tokio::time::sleep(Duration::from_millis(20)).await,
        }
    }
}

#[test]
fn after_the_leaders_node_is_killed_every_road_of_a_client_follows_the_new_leader() {
    // an application's own clients on a member of the cluster: producers put and
    // put_waiting in a loop, and clients of every other road were used once before the
    // kill and not since. Once the new leader is published, each road reaches it by itself
    // — no other request on the client needed to move it
    let _one = ONE_MEMBER.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let nodes = start_nodes(dir.path(), "");
    let rt = runtime();
    rt.block_on(async {
        let transport = join(&nodes).await;
        let (first, _) = leader(None).await;
        assert_eq!(first, "r1");
        let client = |source: &str| DmClient::lookup("feature", source).unwrap().with_follow(T);
        let roads = [
            "put_batch",
            "ready",
            "store",
            "put_all",
            "select",
            "select_wait",
            "delete",
            "stats",
            "leader_node",
        ];
        let mut clients = BTreeMap::new();
        for road in roads {
            let c = client(road);
            c.put(road, None, None, &0u64).unwrap();
            c.stats().await.unwrap();
            clients.insert(road, c);
        }
        let mut subscription = client("subscriber")
            .subscribe(Query::class("news"))
            .await
            .unwrap();
        let (tell, published) = tokio::sync::watch::channel(None);
        let producers = ["put", "put_waiting"]
            .map(|road| tokio::spawn(produce(client(road), road, published.clone())));
        // the producers are under way
        clients["stats"]
            .select(Query::class("put_waiting"))
            .await
            .unwrap();

        nodes[0].signal("KILL");
        let (second, at) = leader(Some("r1")).await;
        let at = Instant::now().min(at);
        tell.send(Some(at)).unwrap();
        eprintln!("r1 killed; {second} published as leader");

        let c = &clients;
        let batch = || {
            (0..10u64)
                .map(|v| NewRecord::encode("put_batch", &v).unwrap())
                .collect::<Vec<_>>()
        };
        let took = tokio::join!(
            until_ok(|| async { c["put_batch"].put_batch(batch()) }),
            until_ok(|| c["ready"].ready(1)),
            until_ok(|| c["store"].store("news", None, None, &1u64)),
            until_ok(|| c["put_all"].put_all(batch())),
            until_ok(|| c["select"].select(Query::class("put"))),
            until_ok(|| c["select_wait"]
                .select_wait(Query::class("put_batch"), Duration::from_millis(100))),
            until_ok(|| c["delete"].delete(Query::class("nothing"))),
            until_ok(|| c["stats"].stats()),
            until_ok(|| c["leader_node"].leader_node()),
        );
        let mut report = vec![
            ("put_batch", took.0),
            ("ready", took.1),
            ("store", took.2),
            ("put_all", took.3),
            ("select", took.4),
            ("select_wait", took.5),
            ("delete", took.6),
            ("stats", took.7),
            ("leader_node", took.8),
        ];
        for (road, producer) in ["put", "put_waiting"].into_iter().zip(producers) {
            let outcome = producer.await.unwrap().map(|(after, errors)| {
                eprintln!("{road}: {errors} calls failed after the publication");
                after
            });
            report.push((road, outcome));
        }
        // the record the store road stored, once it did, reaches the subscriber
        let stored = report.iter().any(|(r, o)| *r == "store" && o.is_ok());
        let waited = Instant::now();
        let news = match stored {
            true => tokio::time::timeout(FOLLOWED_WITHIN, subscription.next())
                .await
                .map_err(|_| "no record".to_string())
                .and_then(|r| r.ok_or_else(|| "the subscription ended".to_string()))
                .map(|r| {
                    assert_eq!(r.decode::<u64>().unwrap(), 1);
                    // (the time it waited for the stored record, once the store was done)
                    waited.elapsed()
                }),
            false => Err("nothing was stored".to_string()),
        };
        report.push(("subscription", news));
        for (road, outcome) in &report {
            match outcome {
                Ok(after) => eprintln!(
                    "{road}: ok {} ms after the new leader was published",
                    after.as_millis()
                ),
                Err(e) => eprintln!("{road}: still failing after {FOLLOWED_WITHIN:?}: {e}"),
            }
        }
        let stuck: Vec<_> = report
            .iter()
            .filter(|(_, o)| o.is_err())
            .map(|(r, _)| *r)
            .collect();
        assert!(
            stuck.is_empty(),
            "roads that did not follow the new leader: {stuck:?}"
        );
        // what they say is the new leader's
        assert_eq!(c["leader_node"].leader_node().await.unwrap(), second);
        let stats = c["stats"].stats().await.unwrap();
        assert_eq!(stats.replica.unwrap().node, second);
        for road in ["put", "put_waiting", "put_batch"] {
            let n = c["select"].select(Query::class(road)).await.unwrap().len();
            assert!(n > 0, "nothing of {road} reached the new leader");
        }
        transport.stop().await;
    });
}

/// The wait a parked `select_wait` asks for: far longer than a failover, so that only the
/// road's following — not the wait's end — can answer it in time.
const PARKED: Duration = Duration::from_secs(30);

/// A `select_wait` for class `class` through `client`, once it waits in the replica on
/// `node` (its `pending_waits`).
async fn park(
    client: &DmClient,
    node: &str,
    class: &'static str,
) -> tokio::task::JoinHandle<Result<Vec<dm::Record>, dm::DmError>> {
    let parked = {
        let client = client.clone();
        tokio::spawn(async move { client.select_wait(Query::class(class), PARKED).await })
    };
    let start = Instant::now();
    loop {
        if let Some(copy) = copy_on(node) {
            if stats_of(&copy).await.is_some_and(|s| s.pending_waits > 0) {
                return parked;
            }
        }
        assert!(start.elapsed() < T, "no select_wait reached {node}");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

/// Store a record of `class` through `producer` (which follows the name), then the parked
/// wait's outcome: that record, if the road whose answer was lost followed the datamanager
/// and asked again there; a `Timeout` after its own deadline (the wait and the client's
/// 5 s) if it was left hanging.
async fn unparked(
    parked: tokio::task::JoinHandle<Result<Vec<dm::Record>, dm::DmError>>,
    class: &'static str,
    producer: &DmClient,
) -> Result<Vec<dm::Record>, dm::DmError> {
    until_ok(|| producer.store(class, None, None, &7u64))
        .await
        .unwrap_or_else(|e| panic!("no store of {class} after the fault: {e}"));
    parked.await.unwrap()
}

#[test]
fn a_request_whose_leader_is_lost_is_answered_and_asked_again_at_the_next_leader() {
    // Clients in this process (a member of the cluster, a node of its own) whose requests
    // wait in a replica on another node: (a) in the leader, which is deposed — the
    // preferred replica, back, is handed the role — and stays a follower, the same actor;
    // (b) sent on by that follower to the leader, whose node is then killed (kill -9). Each
    // answer owed is lost on a node other than the caller's; each road must follow the
    // datamanager to the next leader and ask again there, not wait for its own deadline
    // (a dispatcher waiting that long for a checkpoint is taken for hung and taken over).
    let _one = ONE_MEMBER.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let mut nodes = start_nodes(dir.path(), "");
    let rt = runtime();
    let client = |source: &str| DmClient::lookup("feature", source).unwrap().with_follow(T);
    let (deposed, transport, idle, producer, parked) = rt.block_on(async {
        let transport = join(&nodes).await;
        assert_eq!(leader(None).await.0, "r1");
        let (parker, idle, producer) = (client("parker"), client("idle"), client("producer"));
        producer.store("before", None, None, &0u64).await.unwrap();
        // r1's node killed: r2 or r3 leads, and every client follows it
        nodes[0].signal("KILL");
        let (second, _) = leader(Some("r1")).await;
        for c in [&parker, &idle, &producer] {
            until_ok(|| c.store("after", None, None, &1u64))
                .await
                .unwrap();
        }
        // (a) a wait parked in the leader, which r1, back, will depose
        let parked = park(&parker, &second, "a").await;
        (second, transport, idle, producer, parked)
    });
    // r1 starts again: once caught up, the preferred replica is handed the role back
    let peers: Vec<_> = nodes[1..].iter().map(|n| n.addr).collect();
    nodes[0] = NodeProc::start(dir.path(), "r1", &hosts(dir.path(), "r1"), &peers, COOKIE);
    rt.block_on(async {
        primary_where(|n| n == "r1").await;
        let a = unparked(parked, "a", &producer).await;
        assert!(
            a.as_ref().is_ok_and(|r| r.len() == 1),
            "the wait parked in the deposed leader {deposed}: {a:?}"
        );
        // the idle client still holds the deposed leader: a follower now, the same actor
        let held = idle.actor();
        assert_eq!(held.get_id(), copy_on(&deposed).unwrap().get_id());
        let role = stats_of(&held).await.unwrap().replica.unwrap().role;
        assert_eq!(role, marie::replica::ReplicaRole::Follower);

        // (b) a wait that follower sent on to r1, whose node is then killed
        let parked = park(&idle, "r1", "b").await;
        nodes[0].signal("KILL");
        leader(Some("r1")).await;
        let b = unparked(parked, "b", &producer).await;
        assert!(
            b.as_ref().is_ok_and(|r| r.len() == 1),
            "the wait sent on to r1, killed: {b:?}"
        );
        // the road followed the next leader: its next calls are answered there
        until_ok(|| idle.store("next", None, None, &2u64))
            .await
            .unwrap();
        let stats = idle.stats().await.unwrap();
        assert!(stats.classes.contains_key("next"), "{stats:?}");
        transport.stop().await;
    });
}
