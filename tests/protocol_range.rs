//! Two builds side by side, across real processes on 127.0.0.1: a node that speaks the
//! protocol versions `ours..=ours+1` (a next build, claimed with the hidden
//! `--protocol-range`) joins nodes of this build (`ours` alone), agrees on `ours` with each,
//! its modules are found and its replica of a datamanager follows the leader; `marie ls`
//! shows the version agreed with every node. A node that speaks `ours+2` alone meets no
//! range: it is refused with a line naming both builds and both ranges and what to do, and
//! the rest keep serving — the replica on the next build's node still follows.

use crate::common;

use common::cluster::NodeProc;
use common::ONE_MEMBER;
use marie::cluster::net::{ClusterConfig, Transport, UPGRADE_ADVICE};
use marie::dm::{self, DmClient, DmMsg, DmStats, NewRecord};
use marie::wire::PROTOCOL_VERSION;
use ractor::ActorRef;
use std::path::Path;
use std::time::{Duration, Instant};

const COOKIE: &str = "ranges";
/// Generous: elections, a node's start, on a loaded 2-core machine.
const T: Duration = Duration::from_secs(60);

/// A node keeping a replica of `feature` on r1, r2, r3, and `more` (TOML tables).
fn hosts(dir: &Path, name: &str, more: &str) -> String {
    format!(
        "data_dir = \"{}\"\n[[datamanager]]\nname = \"feature\"\ncopies = [\"r1\", \"r2\", \"r3\"]\n{more}",
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

/// What the replica `actor` itself holds.
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

/// Store `n` records from `from` on, each acknowledged (retried until it is).
async fn store(client: &DmClient, from: u64, n: u64) {
    for v in from..from + n {
        let start = Instant::now();
        while let Err(e) = client
            .store_raw(NewRecord::encode("echo", &v).unwrap())
            .await
        {
            assert!(start.elapsed() < T, "{v} not acknowledged: {e}");
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    }
}

/// Wait until the replica on `node` holds `records` records.
async fn follows(node: &str, records: u64) {
    let start = Instant::now();
    loop {
        let held = match copy_on(node) {
            Some(c) => stats_of(&c).await.map(|s| s.records),
            None => None,
        };
        if held == Some(records) {
            return;
        }
        assert!(
            start.elapsed() < T,
            "the replica on {node} holds {held:?} records, not {records}"
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}

/// `marie ls --join` in text: its lines.
fn ls_lines(addr: &std::net::SocketAddr) -> Vec<String> {
    let out = common::marie(&["ls", "--join", &addr.to_string(), "--cookie", COOKIE]);
    assert!(out.status.success(), "{}", common::text(&out.stderr));
    common::text(&out.stdout)
        .lines()
        .map(str::to_string)
        .collect()
}

#[test]
fn a_node_of_the_next_build_works_beside_this_one_and_one_of_no_common_version_is_refused() {
    let _one = ONE_MEMBER.lock().unwrap_or_else(|e| e.into_inner());
    let ours = PROTOCOL_VERSION;
    let next = format!("{ours}-{}", ours + 1);
    let far = format!("{0}-{0}", ours + 2);
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut r1 = NodeProc::start(d, "r1", &hosts(d, "r1", ""), &[], COOKIE);
    let mut r2 = NodeProc::start(d, "r2", &hosts(d, "r2", ""), &[r1.addr], COOKIE);
    let sampler = "[[operation]]\nname = \"sampler\"\n";
    let mut r3 = NodeProc::start_with(
        d,
        "r3",
        &hosts(d, "r3", sampler),
        &[r1.addr, r2.addr],
        COOKIE,
        "",
        &["--protocol-range", &next],
    );
    r1.wait_line("node r1 sees r3");
    r3.wait_line("node r3 sees r1");
    r3.wait_line("node r3 sees r2");

    // ls, a member of this build, agreed on `ours` with every node, r3 included
    let deadline = Instant::now() + T;
    let wanted = [
        format!("node r1: protocol {ours} (speaks {ours}..={ours}), build "),
        format!("node r2: protocol {ours} (speaks {ours}..={ours}), build "),
        format!(
            "node r3: protocol {ours} (speaks {ours}..={}), build ",
            ours + 1
        ),
    ];
    loop {
        let lines = ls_lines(&r1.addr);
        let shown = wanted
            .iter()
            .all(|w| lines.iter().any(|l| l.starts_with(w.as_str())));
        // r3's operation is found
        if shown
            && lines
                .iter()
                .any(|l| l.contains("sampler") && l.contains("r3"))
        {
            break;
        }
        assert!(Instant::now() < deadline, "{lines:#?}");
    }

    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap();
    let mut me = ClusterConfig::new("127.0.0.1:0".parse().unwrap(), COOKIE);
    for n in [&r1, &r2, &r3] {
        me = me.with_peer(n.addr);
    }
    let (client, transport) = rt.block_on(async {
        let transport = Transport::start("producer", &me).await.unwrap();
        transport.wait_for_peers(3, T).await.unwrap();
        let client = DmClient::lookup("feature", "producer")
            .unwrap()
            .with_follow(T);
        // the replica on the next build's node follows the leader
        store(&client, 0, 50).await;
        follows("r3", 50).await;
        (client, transport)
    });

    // a node of no common version: refused by r1, naming both builds and both ranges
    let mark = r1.seen().len();
    let mut far_node = NodeProc::start_with(
        d,
        "far",
        sampler,
        &[r1.addr],
        COOKIE,
        "",
        &["--protocol-range", &far],
    );
    let refused = r1.wait_line_since(mark, "node r1 refused far");
    for said in [
        format!("it speaks protocol version {}", ours + 2),
        format!("this node speaks protocol version {ours}"),
        UPGRADE_ADVICE.to_string(),
    ] {
        assert!(refused.contains(&said), "{said:?} not in {refused}");
    }
    assert_eq!(refused.matches("(build ").count(), 2, "{refused}");
    assert!(refused.contains("commit"), "{refused}");
    let theirs = far_node.wait_line("node far refused r1");
    assert!(
        theirs.contains(&format!("it speaks protocol version {ours}"))
            && theirs.contains(&format!("this node speaks protocol version {}", ours + 2)),
        "{theirs}"
    );

    // the rest keep serving: records stored, the next build's replica follows, and the
    // refused node's operation is never listed
    rt.block_on(async {
        store(&client, 50, 20).await;
        follows("r3", 70).await;
    });
    // (a session with it may be ready a moment before its first beat refuses it: its
    // modules leave with it)
    let deadline = Instant::now() + T;
    loop {
        let lines = ls_lines(&r1.addr);
        if !lines.iter().any(|l| l.contains("far")) {
            break;
        }
        assert!(Instant::now() < deadline, "{lines:#?}");
    }
    assert!(far_node.alive() && r1.alive() && r2.alive() && r3.alive());

    rt.block_on(transport.stop());
    for node in [&mut far_node, &mut r3, &mut r2, &mut r1] {
        node.signal("TERM");
        node.wait_line("stopped");
        assert_eq!(node.wait_exit(), Some(0));
    }
    // the sessions closed at authentication are the versions' refusal, not a cookie's
    for node in [&r1, &far_node] {
        assert!(
            !node
                .seen()
                .iter()
                .any(|l| l.contains("failed authentication") || l.contains("was refused by")),
            "{:?}",
            node.seen()
        );
    }
}
