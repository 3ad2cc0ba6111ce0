//! The node's watchdog watches every datamanager the node hosts now — a replica added while
//! the node runs too (`marie dm add-replica` has the node's replica host start one), which
//! a list of names taken at the node's start never held: hung, it is killed, and its
//! supervisor starts it again.

use marie_cluster::net::ClusterConfig;
use marie_cluster::node::{watchdog, Node};
use marie_cluster::replicas::{self, Declaration, HostMsg};
use marie_dm::DmMsg;
use marie_vocabulary::run::FaultKind;
use ractor::rpc::CallResult;
use ractor::{pg, ActorCell, ActorRef};
use std::time::{Duration, Instant};

const T: Duration = Duration::from_secs(30);

/// The replica of `dm` on `node` that runs in this process now.
fn replica(dm: &str, node: &str) -> Option<ActorCell> {
    pg::get_scoped_members(
        &marie_dm::REPLICA_SCOPE.to_string(),
        &format!("{dm}/{node}"),
    )
    .into_iter()
    .find(|c| c.get_status() <= ractor::ActorStatus::Running)
}

/// Whether `cell` answers `ReplicaStats` within `within`.
async fn answers(cell: &ActorCell, within: Duration) -> bool {
    let actor = ActorRef::<DmMsg>::from(cell.clone());
    matches!(
        actor
            .call(|reply| DmMsg::ReplicaStats { reply }, Some(within))
            .await,
        Ok(CallResult::Success(_))
    )
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_replica_added_while_the_node_runs_is_watched_and_restarted_when_hung() {
    let dir = tempfile::tempdir().unwrap();
    // a node that keeps no datamanager at its start, and hosts replicas on request
    let node = Node::builder("wd1")
        .data_dir(dir.path())
        .cluster(ClusterConfig::new("127.0.0.1:0".parse().unwrap(), "wd"))
        .start()
        .await
        .unwrap();
    let host = replicas::host_of("wd1").expect("its replica host");
    // a replica of a datamanager whose voters are elsewhere, joining them (as `marie dm
    // add-replica` has it started): it runs, a learner that hears no leader
    let declaration = Declaration {
        name: "feature-wd".into(),
        id: 1401,
        durability: None,
        catch_up: None,
        retention: None,
        class_retention: Default::default(),
        replace_after: None,
        spares: Vec::new(),
    };
    let started = host
        .call(
            |reply| HostMsg::Start {
                declaration,
                voters: vec!["x1".into(), "x2".into(), "x3".into()],
                reply,
            },
            Some(T),
        )
        .await
        .unwrap();
    assert!(
        matches!(started, CallResult::Success(Ok(()))),
        "{started:?}"
    );
    let added = replica("feature-wd", "wd1").expect("the replica added runs");
    assert!(answers(&added, T).await);

    // hung: it answers nothing, and nothing but the watchdog would notice
    ActorRef::<DmMsg>::from(added.clone())
        .cast(DmMsg::Inject {
            fault: FaultKind::Hang,
        })
        .unwrap();
    assert!(!answers(&added, Duration::from_millis(300)).await, "hung");

    // the watchdog asks within its period, gives up after its deadline and kills it; its
    // supervisor starts it again, and the new one answers
    let start = Instant::now();
    let restarted = loop {
        if let Some(r) = replica("feature-wd", "wd1").filter(|r| r.get_id() != added.get_id()) {
            break r;
        }
        assert!(
            start.elapsed() < watchdog::PERIOD + watchdog::DEADLINE + T,
            "the hung replica was never restarted"
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    };
    assert!(
        answers(&restarted, T).await,
        "the restarted replica answers"
    );
    node.shutdown().await;
}
