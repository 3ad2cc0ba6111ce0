//! A node's data directory: locked for the node's life (a second node on it is refused by
//! name until the first stops), and home of its durable datamanagers' journals — a node
//! started again on it finds its records with their seqs, and the robot's a-priori records
//! once, not once per start.
//!
//! The registry is one per process and these tests run in parallel: each owns the
//! datamanager names it starts.

use marie_cluster::node::{
    AprioriRecord, BoxFuture, DatamanagerConfig, Node, NodeError, Robot, RunJudgement,
};
use marie_dm::{DmClient, Durability, NewRecord, Query, Record};
use marie_supervision::ChildSpec;
use marie_vocabulary::clock::SharedClock;
use marie_vocabulary::events::EventBus;
use marie_vocabulary::registry::{self, ModuleKind, RegistryEvent};
use marie_vocabulary::report::RunReport;
use marie_vocabulary::run::RobotSection;
use std::sync::Arc;
use std::time::Duration;
use tokio::time::timeout;

/// Generous: a node start, a journal replay, a datamanager's restart.
const T: Duration = Duration::from_secs(30);

/// A robot whose only part is an a-priori record in `feature`: a map known before any run.
struct Mapped;

impl Robot for Mapped {
    fn describe(&self) -> String {
        "a map in feature".into()
    }
    fn apriori(&self) -> Vec<AprioriRecord> {
        vec![AprioriRecord {
            datamanager: "feature".into(),
            record: NewRecord::encode("map", &vec![(0.0, 0.0, 4.0, 0.0)])
                .unwrap()
                .with_sub1("walls"),
        }]
    }
    fn drivers(&self, _: &SharedClock, _: &EventBus) -> Vec<ChildSpec> {
        Vec::new()
    }
    fn judge<'a>(&'a self, run: &'a RunReport) -> BoxFuture<'a, RunJudgement> {
        Box::pin(async move {
            RunJudgement {
                outcome: run.outcome,
                reason: run.reason.clone(),
                robot: RobotSection::default(),
            }
        })
    }
}

/// A node named `name` on `dir` with the datamanager `feature` at its default durability
/// (process, with a data_dir) and [`Mapped`]'s a-priori record.
async fn mapped_node(name: &str, dir: &std::path::Path) -> Node {
    timeout(
        T,
        Node::builder(name)
            .data_dir(dir)
            .datamanager(marie_dm::FEATURE)
            .robot(Arc::new(Mapped))
            .start(),
    )
    .await
    .expect("the node starts in time")
    .expect("the node starts")
}

/// Every record of `feature`, as (seq, class, source, payload bytes).
async fn everything(dm: &DmClient) -> Vec<(u64, String, String, Vec<u8>)> {
    let records: Vec<Record> = dm.select(Query::all()).await.unwrap();
    records
        .into_iter()
        .map(|r| {
            (
                r.seq,
                r.class.to_string(),
                r.source.to_string(),
                r.payload.as_bytes().to_vec(),
            )
        })
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_second_node_on_a_data_dir_is_refused_by_name_until_the_first_stops() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("node");
    let first = Node::builder("dd-first")
        .data_dir(&data)
        .datamanager(("dd-lock", 7811))
        .start()
        .await
        .unwrap();

    let second = Node::builder("dd-second")
        .data_dir(&data)
        .datamanager(("dd-lock", 7811))
        .start()
        .await;
    let err = match second {
        Ok(_) => panic!("a second node started on a data_dir in use"),
        Err(e) => e,
    };
    let text = err.to_string();
    match err {
        NodeError::DataDirInUse { dir, holder } => {
            assert_eq!(dir, data);
            assert_eq!(holder, Some(std::process::id()));
        }
        other => panic!("expected DataDirInUse, got {other:?}"),
    }
    assert_eq!(
        text,
        format!(
            "data_dir {} is in use by another marie node (pid {}): one node per data_dir \
             (stop that node, or give this one another data_dir)",
            data.display(),
            std::process::id()
        )
    );
    // refused before anything started: the first node's datamanager is the only one
    assert_eq!(
        registry::lookup(ModuleKind::Datamanager, "dd-lock").len(),
        1
    );

    first.shutdown().await;
    let third = Node::builder("dd-third")
        .data_dir(&data)
        .datamanager(("dd-lock", 7811))
        .start()
        .await
        .expect("the data_dir is free once the first node stopped");
    assert!(data.join("dm").join("dd-lock").is_dir());
    third.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_node_started_again_on_its_data_dir_finds_its_records_and_the_apriori_ones_once() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("node");
    let node = mapped_node("dd-keeper", &data).await;
    let feature = DmClient::lookup("feature", "test").unwrap();
    let stats = feature.stats().await.unwrap();
    assert_eq!(stats.durability, Durability::Process);
    assert!(data.join("dm").join("feature").is_dir());
    let mut seqs = Vec::new();
    for i in 0..20u32 {
        let seq = feature
            .store("echo", Some("front"), None, &(i, f64::from(i) / 4.0))
            .await
            .unwrap();
        seqs.push(seq);
    }
    let before = everything(&feature).await;
    // the a-priori map first, then the echoes
    assert_eq!(before.len(), 21);
    assert_eq!(
        (before[0].1.as_str(), before[0].2.as_str()),
        ("map", "node")
    );
    assert_eq!(
        before[1..].iter().map(|r| r.0).collect::<Vec<_>>(),
        seqs,
        "{before:?}"
    );

    // a datamanager restarted by its supervisor reads its journal back: nothing lost,
    // the map not stored again
    let old = registry::lookup(ModuleKind::Datamanager, "feature");
    assert_eq!(old.len(), 1);
    let old_id = old[0].actor.get_id();
    let mut watch = registry::watch(Some(ModuleKind::Datamanager))
        .await
        .unwrap();
    old[0].actor.kill();
    timeout(T, async {
        loop {
            match watch.next().await.expect("the registry") {
                RegistryEvent::Joined(i) if i.name == "feature" && i.actor.get_id() != old_id => {
                    return
                }
                _ => {}
            }
        }
    })
    .await
    .expect("feature restarted");
    let feature = DmClient::lookup("feature", "test").unwrap();
    assert_eq!(everything(&feature).await, before);

    // a new node on the same data_dir
    node.shutdown().await;
    let node = mapped_node("dd-keeper-again", &data).await;
    let feature = DmClient::lookup("feature", "test").unwrap();
    let stats = feature.stats().await.unwrap();
    let recovery = stats
        .recovery
        .expect("a durable datamanager tells its recovery");
    assert_eq!(recovery.torn, None);
    assert_eq!(recovery.records, 21);
    assert_eq!(everything(&feature).await, before);
    assert_eq!(stats.next_seq, before.last().unwrap().0 + 1);
    // and it goes on from there
    let next = feature.store("echo", None, None, &0u32).await.unwrap();
    assert_eq!(next, stats.next_seq);
    node.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_memory_datamanager_on_a_node_with_a_data_dir_writes_no_journal() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("node");
    let node = Node::builder("dd-volatile")
        .data_dir(&data)
        .datamanager(
            DatamanagerConfig::new("dd-volatile", 7812).with_durability(Durability::Memory),
        )
        .start()
        .await
        .unwrap();
    let dm = DmClient::lookup("dd-volatile", "test").unwrap();
    dm.store("echo", None, None, &1u32).await.unwrap();
    let stats = dm.stats().await.unwrap();
    assert_eq!(stats.durability, Durability::Memory);
    assert_eq!(stats.recovery, None);
    assert!(!data.join("dm").exists());
    node.shutdown().await;
}
