//! A replicated datamanager's replicas change while producers put records into it:
//! `marie dm add-replica` starts a replica on a node that kept none — a learner, promoted
//! once it caught up — and `marie dm remove-replica` removes one, the leader's too (it
//! hands its role over). From three replicas to five and back to three, nothing
//! acknowledged is lost, and every remaining replica ends at lag 0. And the verb says what
//! it cannot do, with its exit code: a datamanager or node that does not exist (2), a
//! removal below three voters (1).

use crate::common;

use common::cluster::{node_line, NodeProc};
use marie::cluster::net::{ClusterConfig, Transport};
use marie::dm::{DmClient, NewRecord, Query};
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

const COOKIE: &str = "membership";
/// Generous: elections, a node's start, a learner's catch-up, on a loaded 2-core machine.
const T: Duration = Duration::from_secs(90);
/// Producers putting while the replicas change.
const PRODUCERS: u64 = 4;

use common::ONE_MEMBER;

/// `data_dir`, and for the first three nodes the datamanager `feature` with its replicas.
fn hosts(dir: &Path, name: &str) -> String {
    let declared = match name {
        "r1" | "r2" | "r3" => {
            "[[datamanager]]\nname = \"feature\"\nreplicas = [\"r1\", \"r2\", \"r3\"]\n"
        }
        _ => "",
    };
    format!("data_dir = \"{}\"\n{declared}", dir.join(name).display())
}

fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap()
}

/// `marie dm VERB feature NODE --join ADDR --cookie C`: exit code, stdout, stderr.
async fn dm_verb(
    verb: &'static str,
    node: &'static str,
    addr: String,
) -> (Option<i32>, String, String) {
    tokio::task::spawn_blocking(move || {
        let out = common::marie(&[
            "dm", verb, "feature", node, "--join", &addr, "--cookie", COOKIE,
        ]);
        (
            out.status.code(),
            common::text(&out.stdout),
            common::text(&out.stderr),
        )
    })
    .await
    .unwrap()
}

/// Store values of producer `p` until `stop`, each until acknowledged (a retry is the same
/// put), into `acked` (seq → (producer, value)).
async fn produce(
    client: DmClient,
    p: u64,
    stop: Arc<std::sync::atomic::AtomicBool>,
    acked: Arc<Mutex<BTreeMap<u64, (u64, u64)>>>,
) {
    let mut v = 0u64;
    while !stop.load(std::sync::atomic::Ordering::Relaxed) {
        let start = Instant::now();
        let seq = loop {
            let mut record = NewRecord::encode("echo", &(p, v)).unwrap();
            record.producer = 0x1000 + p;
            record.producer_seq = v + 1;
            match client.store_raw(record).await {
                Ok(seq) => break seq,
                Err(e) => {
                    assert!(start.elapsed() < T, "({p}, {v}) not acknowledged: {e}");
                    tokio::time::sleep(Duration::from_millis(50)).await;
                }
            }
        };
        let old = acked.lock().unwrap().insert(seq, (p, v));
        assert!(
            old.is_none() || old == Some((p, v)),
            "seq {seq} acknowledged twice"
        );
        v += 1;
    }
}

/// Wait until the leader says the voters are `voters`, no learner, every replica at lag 0.
async fn settled(client: &DmClient, voters: &[&str]) {
    let start = Instant::now();
    loop {
        if let Ok(s) = client.stats().await {
            let r = s.replica.clone().unwrap();
            if r.members == voters
                && r.learners.is_empty()
                && r.lag.len() == voters.len() - 1
                && r.lag.values().all(|l| *l == 0)
            {
                eprintln!(
                    "settled: leader {} term {}, lag {:?}",
                    r.node, r.term, r.lag
                );
                return;
            }
            assert!(start.elapsed() < T, "not settled on {voters:?}: {r:?}");
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}

#[test]
fn a_datamanager_grows_from_three_replicas_to_five_and_back_while_producers_put_and_loses_nothing()
{
    let _one = ONE_MEMBER.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let mut nodes: Vec<NodeProc> = Vec::new();
    for name in ["r1", "r2", "r3", "r4", "r5"] {
        let peers: Vec<_> = nodes.iter().map(|n| n.addr).collect();
        nodes.push(NodeProc::start(
            dir.path(),
            name,
            &hosts(dir.path(), name),
            &peers,
            COOKIE,
        ));
    }
    let addr = nodes[2].addr.to_string();
    let rt = runtime();
    rt.block_on(async {
        let mut me = ClusterConfig::new("127.0.0.1:0".parse().unwrap(), COOKIE);
        for n in &nodes {
            me = me.with_peer(n.addr);
        }
        let transport = Transport::start("producer", &me).await.unwrap();
        transport.wait_for_peers(nodes.len(), T).await.unwrap();
        let client = DmClient::lookup_within("feature", "producer", T)
            .await
            .unwrap()
            .with_follow(T);
        settled(&client, &["r1", "r2", "r3"]).await;
        assert_eq!(client.leader_node().await.unwrap(), "r1");

        // bad input first: nothing changes
        let (code, _, err) = dm_verb("add-replica", "nowhere", addr.clone()).await;
        assert_eq!(code, Some(2), "an unknown node: {err}");
        assert!(err.contains("no node `nowhere` hosts replicas"), "{err}");
        let a = addr.clone();
        let out = tokio::task::spawn_blocking(move || {
            common::marie(&[
                "dm",
                "add-replica",
                "nothing",
                "r4",
                "--join",
                &a,
                "--cookie",
                COOKIE,
            ])
        })
        .await
        .unwrap();
        let err = common::text(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "an unknown datamanager: {err}");
        assert!(
            err.contains("no datamanager `nothing` in the cluster"),
            "{err}"
        );
        let (code, _, err) = dm_verb("remove-replica", "r1", addr.clone()).await;
        assert_eq!(code, Some(1), "below three voters: {err}");
        assert!(err.contains("would leave 2 voting replicas"), "{err}");

        let stop = Arc::new(std::sync::atomic::AtomicBool::new(false));
        let acked = Arc::new(Mutex::new(BTreeMap::new()));
        let producers: Vec<_> = (0..PRODUCERS)
            .map(|p| tokio::spawn(produce(client.clone(), p, stop.clone(), acked.clone())))
            .collect();
        let acked_now = || acked.lock().unwrap().len();
        while acked_now() < 200 {
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        for node in ["r4", "r5"] {
            let (code, out, err) = dm_verb("add-replica", node, addr.clone()).await;
            eprintln!("add-replica {node}:\n{out}{err}");
            assert_eq!(code, Some(0), "add-replica {node}: {out}{err}");
            assert!(
                out.contains(&format!("feature: replica started on {node}")),
                "{out}"
            );
            assert!(
                out.contains(&format!("feature: {node} votes: voters")),
                "{out}"
            );
            assert!(
                out.contains(&format!("feature: replica on {node} added")),
                "{out}"
            );
            assert!(
                dir.path().join(node).join("dm").join("feature").is_dir(),
                "{node} journals its replica"
            );
        }
        settled(&client, &["r1", "r2", "r3", "r4", "r5"]).await;
        let (code, _, err) = dm_verb("add-replica", "r4", addr.clone()).await;
        assert_eq!(code, Some(2), "a node that already keeps one: {err}");
        let during = acked_now();
        // the original leader first: it hands its role over
        for node in ["r1", "r2"] {
            let (code, out, err) = dm_verb("remove-replica", node, addr.clone()).await;
            eprintln!("remove-replica {node}:\n{out}{err}");
            assert_eq!(code, Some(0), "remove-replica {node}: {out}{err}");
            assert!(
                out.contains(&format!("feature: {node} removed: voters")),
                "{out}"
            );
            assert!(
                out.contains(&format!("feature: replica on {node} stopped")),
                "{out}"
            );
        }
        while acked_now() < during + 200 {
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        stop.store(true, std::sync::atomic::Ordering::Relaxed);
        for p in producers {
            p.await.unwrap();
        }
        settled(&client, &["r3", "r4", "r5"]).await;
        let leader = client.leader_node().await.unwrap();
        assert!(["r3", "r4", "r5"].contains(&leader.as_str()), "{leader}");

        // every acknowledged record is in the leader once, at its seq
        let acked = acked.lock().unwrap().clone();
        let records = client.select(Query::class("echo")).await.unwrap();
        let mut stored: BTreeMap<u64, (u64, u64)> = BTreeMap::new();
        for r in &records {
            assert!(stored.insert(r.seq, r.decode().unwrap()).is_none());
        }
        let lost: Vec<_> = acked
            .iter()
            .filter(|(s, v)| stored.get(s) != Some(v))
            .collect();
        eprintln!(
            "{} acknowledged, {} stored, {} lost",
            acked.len(),
            stored.len(),
            lost.len()
        );
        assert!(lost.is_empty(), "acknowledged records lost: {lost:?}");
        assert!(acked.len() >= 400);
        transport.stop().await;
    });
    // a replica added while the cluster ran starts again with its node
    let r4 = nodes.remove(3);
    drop(r4);
    let peers: Vec<_> = nodes.iter().map(|n| n.addr).collect();
    let _r4 = NodeProc::start(dir.path(), "r4", &hosts(dir.path(), "r4"), &peers, COOKIE);
    let start = Instant::now();
    loop {
        let (code, rows, err) = common::cluster::ls_join_rows(&addr, COOKIE, &[]);
        assert_eq!(code, Some(0), "{err}");
        let back = rows.iter().any(|r| {
            let replica = &r["replica"];
            r["name"] == "feature"
                && replica["reachable"]
                    .as_array()
                    .is_some_and(|a| a.iter().any(|n| n == "r4"))
                && replica["lag"]["r4"] == 0
                && replica["members"] == serde_json::json!(["r3", "r4", "r5"])
        });
        if back {
            break;
        }
        assert!(
            start.elapsed() < T,
            "r4's replica did not come back: {rows:#?}"
        );
        std::thread::sleep(Duration::from_millis(500));
    }
    // r1, removed, started again on a wiped data directory: its config declares it a
    // replica, so it runs one — which the leader tells it is none of the replicas (a
    // snapshot: it holds nothing), and its node stops it. (Before, it ran on for good,
    // and `ls` said it was none of the replicas.)
    drop(nodes.remove(0));
    std::fs::remove_dir_all(dir.path().join("r1")).unwrap();
    let peers: Vec<_> = nodes.iter().map(|n| n.addr).collect();
    let mut r1 = NodeProc::start(dir.path(), "r1", &hosts(dir.path(), "r1"), &peers, COOKIE);
    r1.wait_line("datamanager feature: the replica on r1 knows it is none of the replicas");
    no_stray(&addr, "r1");
    drop(nodes);
}

/// Wait until `marie ls` lists no replica of `feature` on `node` that is none of its
/// replicas: its node stopped the replica told it is out.
fn no_stray(addr: &str, node: &str) {
    let start = Instant::now();
    loop {
        let out = common::marie(&["ls", "--join", addr, "--cookie", COOKIE]);
        let listing = common::text(&out.stdout);
        if out.status.success()
            && listing.contains("DM feature on ")
            && !listing.contains(&format!("DM feature: the replica on {node} is none"))
        {
            return;
        }
        assert!(
            start.elapsed() < T,
            "{node}'s replica still runs: {listing}"
        );
        std::thread::sleep(Duration::from_millis(500));
    }
}

/// The leader's word on the replicas.
async fn leader_stats(client: &DmClient) -> marie::dm::ReplicaStats {
    client.stats().await.unwrap().replica.unwrap()
}

/// A replica removed while its node was down (kill -9) is told so once its node is started
/// again with its own command line: the node's journal still names it a voter, nobody is
/// left to stop it, and the leader — seeing a replica no configuration names — sends it the
/// configuration without it. It says it is out on its node (`dm_replica_out`) and its node
/// stops it; `marie ls` lists no replica there; the leader keeps its role and its term (the
/// replica's vote requests unseat nobody); the remaining replicas go on storing.
#[test]
fn a_replica_removed_while_its_node_was_down_is_told_once_the_node_is_back() {
    let _one = ONE_MEMBER.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let mut nodes: Vec<NodeProc> = Vec::new();
    for name in ["r1", "r2", "r3", "r4"] {
        let peers: Vec<_> = nodes.iter().map(|n| n.addr).collect();
        nodes.push(NodeProc::start(
            dir.path(),
            name,
            &hosts(dir.path(), name),
            &peers,
            COOKIE,
        ));
    }
    let addr = nodes[0].addr.to_string();
    let rt = runtime();
    rt.block_on(async move {
        let mut me = ClusterConfig::new("127.0.0.1:0".parse().unwrap(), COOKIE);
        for n in &nodes {
            me = me.with_peer(n.addr);
        }
        let transport = Transport::start("producer", &me).await.unwrap();
        transport.wait_for_peers(nodes.len(), T).await.unwrap();
        let client = DmClient::lookup_within("feature", "producer", T)
            .await
            .unwrap()
            .with_follow(T);
        settled(&client, &["r1", "r2", "r3"]).await;
        // four voters, so that one can go
        let (code, out, err) = dm_verb("add-replica", "r4", addr.clone()).await;
        assert_eq!(code, Some(0), "add-replica r4: {out}{err}");
        settled(&client, &["r1", "r2", "r3", "r4"]).await;
        for v in 0..50u64 {
            client.store("echo", None, None, &(0u64, v)).await.unwrap();
        }

        // r3's node killed, its replica removed while it is down
        let r3 = nodes.remove(2);
        drop(r3);
        let (code, out, err) = dm_verb("remove-replica", "r3", addr.clone()).await;
        eprintln!("remove-replica r3:\n{out}{err}");
        assert_eq!(code, Some(0), "remove-replica r3: {out}{err}");
        assert!(
            out.contains("feature: r3 removed: voters r1, r2, r4"),
            "{out}"
        );
        settled(&client, &["r1", "r2", "r4"]).await;
        for v in 50..100u64 {
            client.store("echo", None, None, &(0u64, v)).await.unwrap();
        }
        let before = leader_stats(&client).await;
        eprintln!("leader {} at term {}", before.node, before.term);

        // r3's node started again with its own command line: its journal names its replica
        // a voter of r1, r2, r3, r4
        let peers: Vec<_> = nodes.iter().map(|n| n.addr).collect();
        let r3 = tokio::task::spawn_blocking(move || {
            let mut r3 =
                NodeProc::start(dir.path(), "r3", &hosts(dir.path(), "r3"), &peers, COOKIE);
            let told = r3.wait_line(
                "datamanager feature: the replica on r3 knows it is none of the replicas",
            );
            eprintln!("{told}");
            assert!(told.contains("(voters: r1, r2, r4)"), "{told}");
            assert!(
                dir.path().join("r3").join("dm").join("feature").is_dir(),
                "a declared replica's journal is kept: it says the replica was removed"
            );
            (r3, dir)
        });
        let (_r3, dir) = r3.await.unwrap();
        let a = addr.clone();
        tokio::task::spawn_blocking(move || no_stray(&a, "r3"))
            .await
            .unwrap();
        assert!(
            !marie::dm::replica_nodes("feature").contains(&"r3".to_string()),
            "its replica stopped: {:?}",
            marie::dm::replica_nodes("feature")
        );

        // the leader kept its role and its term; the others go on storing, all current
        for v in 100..150u64 {
            client.store("echo", None, None, &(0u64, v)).await.unwrap();
        }
        settled(&client, &["r1", "r2", "r4"]).await;
        let after = leader_stats(&client).await;
        assert_eq!(
            (after.node.as_str(), after.term),
            (before.node.as_str(), before.term),
            "no new leader, no new term"
        );
        let records = client.select(Query::class("echo")).await.unwrap();
        assert_eq!(records.len(), 150);
        transport.stop().await;
        drop(dir);
    });
}

/// A node of `replace_after = 2` killed for good (restart = "temporary") is replaced: its
/// datamanager's leader adds a replica on the live node that keeps none, waits for its
/// promotion, removes the gone one and says so (`dm_replica_replaced`, on `marie up`'s
/// output) — back to three voters, and stores acknowledged before, during and after are
/// all there.
#[test]
fn a_node_gone_longer_than_replace_after_has_its_replica_replaced_on_a_live_node() {
    let _one = ONE_MEMBER.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tempfile::tempdir().unwrap();
    for n in ["n1", "n2", "n3", "n4"] {
        std::fs::write(
            dir.path().join(format!("{n}.toml")),
            format!("[node]\nname = \"{n}\"\n"),
        )
        .unwrap();
    }
    let file = dir.path().join("cluster.toml");
    std::fs::write(
        &file,
        "[cluster]\ncookie = \"replace\"\n\
         [[node]]\nconfig = \"n1.toml\"\n[[node]]\nconfig = \"n2.toml\"\n\
         [[node]]\nconfig = \"n3.toml\"\nrestart = \"temporary\"\n[[node]]\nconfig = \"n4.toml\"\n\
         [[datamanager]]\nname = \"feature\"\nreplicas = [\"n1\", \"n2\", \"n3\"]\nreplace_after = 2\n",
    )
    .unwrap();
    let mut up = common::cluster::Proc::spawn("marie up", &["up", file.to_str().unwrap()]);
    up.wait_line("Ctrl-C stops the cluster");
    let nodes: Vec<(String, String, u32)> = up.seen().iter().filter_map(|l| node_line(l)).collect();
    assert_eq!(nodes.len(), 4, "{:?}", up.seen());
    let rt = runtime();
    rt.block_on(async {
        let mut me = ClusterConfig::new("127.0.0.1:0".parse().unwrap(), "replace");
        me = me.with_peer(nodes[0].1.parse().unwrap());
        let transport = Transport::start("producer", &me).await.unwrap();
        transport.wait_for_peers(4, T).await.unwrap();
        let client = DmClient::lookup_within("feature", "producer", T)
            .await
            .unwrap()
            .with_follow(T);
        settled(&client, &["n1", "n2", "n3"]).await;
        let stop = Arc::new(std::sync::atomic::AtomicBool::new(false));
        let acked = Arc::new(Mutex::new(BTreeMap::new()));
        let producer = tokio::spawn(produce(client.clone(), 0, stop.clone(), acked.clone()));
        let acked_now = || acked.lock().unwrap().len();
        while acked_now() < 100 {
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        let (_, _, pid) = &nodes[2];
        common::cluster::signal_pid(*pid, "KILL");
        let waited = tokio::task::spawn_blocking(move || {
            up.wait_line("node n3 was killed (SIGKILL): it stays down (restart = \"temporary\")");
            let replaced = up.wait_line("n3 had been gone");
            (up, replaced)
        });
        let (up, replaced) = waited.await.unwrap();
        eprintln!("{replaced}");
        assert!(
            replaced.contains("datamanager feature: n3 had been gone")
                && replaced.contains("its replica was replaced by one on n4, caught up and voting (voters: n1, n2, n4)"),
            "{replaced}"
        );
        settled(&client, &["n1", "n2", "n4"]).await;
        let after = acked_now();
        while acked_now() < after + 100 {
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        stop.store(true, std::sync::atomic::Ordering::Relaxed);
        producer.await.unwrap();
        let acked = acked.lock().unwrap().clone();
        let records = client.select(Query::class("echo")).await.unwrap();
        let stored: BTreeMap<u64, (u64, u64)> =
            records.iter().map(|r| (r.seq, r.decode().unwrap())).collect();
        let lost = acked.iter().filter(|(s, v)| stored.get(s) != Some(v)).count();
        eprintln!("{} acknowledged, {} stored, {lost} lost", acked.len(), stored.len());
        assert_eq!(lost, 0);
        transport.stop().await;
        let mut up = up;
        up.signal("INT");
        up.wait_line("cluster stopped");
    });
}

/// Without `--join` the verb has no cluster to act on: bad input, said at once.
#[test]
fn a_change_of_replicas_without_a_cluster_to_join_is_bad_input() {
    let out = common::marie(&["dm", "add-replica", "feature", "r4"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        common::text(&out.stderr).contains(
            "marie dm add-replica acts on a running cluster: give --join ADDR --cookie C"
        ),
        "{}",
        common::text(&out.stderr)
    );
}
