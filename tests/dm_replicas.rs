//! A datamanager kept in three copies on three `marie node` processes survives `kill -9` of
//! its primary's process: a copy is elected primary, the record seqs continue, the producer
//! (a member of the cluster in this process) follows the name to it, and nothing it had
//! acknowledged is lost or stored twice; the killed node, started again on its data
//! directory, comes back as a copy and catches up, and the three copies end equal.

mod common;

use common::cluster::NodeProc;
use marie::actors::dm::{self, DmClient, DmMsg, DmStats, Query};
use marie::actors::registry::{self, ModuleKind};
use marie::cluster::net::{ClusterConfig, Transport};
use ractor::ActorRef;
use std::collections::BTreeMap;
use std::path::Path;
use std::time::{Duration, Instant};

const COOKIE: &str = "replicas";
const NODES: [&str; 3] = ["r1", "r2", "r3"];
/// Generous: elections, a node's start, a journal replay, on a loaded 2-core machine.
const T: Duration = Duration::from_secs(60);

fn hosts(dir: &Path, name: &str) -> String {
    format!(
        "data_dir = \"{}\"\n[[datamanager]]\nname = \"feature\"\ncopies = [\"r1\", \"r2\", \"r3\"]\n",
        dir.join(name).display()
    )
}

/// The copy of `feature` on `node`, from the copies' groups.
fn copy_on(node: &str) -> Option<ActorRef<DmMsg>> {
    ractor::pg::get_scoped_members(&dm::replica::SCOPE.to_string(), &format!("feature/{node}"))
        .into_iter()
        .next()
        .map(Into::into)
}

async fn stats_of(actor: &ActorRef<DmMsg>) -> Option<DmStats> {
    match actor
        .call(|reply| DmMsg::Stats { reply }, Some(Duration::from_secs(5)))
        .await
    {
        Ok(ractor::rpc::CallResult::Success(s)) => Some(s),
        _ => None,
    }
}

/// Wait until the primary of `feature` is published (on a node other than `not`).
async fn primary(not: Option<&str>) -> (String, Instant) {
    let start = Instant::now();
    loop {
        if let Some(i) = registry::lookup(ModuleKind::Datamanager, "feature")
            .into_iter()
            .find(|i| Some(i.node.as_str()) != not)
        {
            return (i.node, Instant::now());
        }
        assert!(start.elapsed() < T, "no primary of feature within {T:?}");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}

#[test]
fn a_killed_primary_is_replaced_by_a_copy_and_no_acknowledged_record_is_lost() {
    let dir = tempfile::tempdir().unwrap();
    let mut nodes: Vec<NodeProc> = Vec::new();
    for name in NODES {
        let peers: Vec<_> = nodes.iter().map(|n| n.addr).collect();
        nodes.push(NodeProc::start(
            dir.path(),
            name,
            &hosts(dir.path(), name),
            &peers,
            COOKIE,
        ));
    }
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap();
    let addrs: Vec<_> = nodes.iter().map(|n| n.addr).collect();
    rt.block_on(async {
        let mut me = ClusterConfig::new("127.0.0.1:0".parse().unwrap(), COOKIE);
        for a in &addrs {
            me = me.with_peer(*a);
        }
        let transport = Transport::start("producer", &me).await.unwrap();
        transport.wait_for_peers(3, T).await.unwrap();
        let (first, _) = primary(None).await;
        assert_eq!(first, "r1", "the preferred copy is the first primary");
        let client = DmClient::lookup("feature", "producer")
            .unwrap()
            .with_follow(T);

        // acknowledged stores before the kill
        let mut acked: BTreeMap<u64, u64> = BTreeMap::new(); // seq -> value
        for v in 0..300u64 {
            let seq = client.store("echo", None, None, &v).await.expect("store");
            assert!(acked.insert(seq, v).is_none(), "seq {seq} handed out twice");
        }

        // kill -9 the primary's process while a store is on its way
        let killed = Instant::now();
        nodes[0].signal("KILL");
        let mut first_after = None;
        for v in 300..600u64 {
            let seq = client
                .store("echo", None, None, &v)
                .await
                .expect("store after the kill");
            first_after.get_or_insert_with(Instant::now);
            assert!(acked.insert(seq, v).is_none(), "seq {seq} handed out twice");
        }
        let (second, _) = primary(Some("r1")).await;
        eprintln!(
            "r1 killed; {second} is primary; the first store acknowledged {} ms after the kill",
            (first_after.unwrap() - killed).as_millis()
        );
        assert_ne!(second, "r1");

        // every acknowledged record is there once, at its seq
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
        for (seq, v) in &acked {
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
        values
    });

    // r1 starts again on its data directory: a copy, which catches up
    let peers: Vec<_> = nodes[1..].iter().map(|n| n.addr).collect();
    nodes[0] = NodeProc::start(dir.path(), "r1", &hosts(dir.path(), "r1"), &peers, COOKIE);
    rt.block_on(async {
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
            if all.len() == 3 && all.iter().all(|s| view(s) == view(&all[0])) {
                let roles: Vec<_> = all
                    .iter()
                    .map(|s| {
                        let r = s.replica.as_ref().unwrap();
                        format!("{} {} term {}", r.node, r.role, r.term)
                    })
                    .collect();
                eprintln!("copies equal: {:?}; {}", view(&all[0]), roles.join(", "));
                assert_eq!(
                    all.iter()
                        .filter(|s| s.replica.as_ref().unwrap().role == "primary")
                        .count(),
                    1
                );
                break;
            }
            assert!(start.elapsed() < T, "the copies did not converge: {all:#?}");
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
    });
}
