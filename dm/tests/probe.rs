//! The probe of a replicated datamanager, as actors in one process: it writes and reads
//! back by name and from each replica while the leader is stopped and started again on its
//! journal — every road answers, no read is stale, the newest write is read back. (Under
//! real faults, cut-off leaders included, and with a control that must catch stale reads:
//! the root package's `tests/probe.rs`.)

use marie_dm::probe::{Probe, ProbeConfig, ProbeVerdict, ReadBack, BY_NAME};
use marie_dm::{
    self as dm, DmClient, DmMsg, DmSpec, Durability, Replication, ReplicationTiming as Timing,
};
use marie_vocabulary::clock::RealClock;
use ractor::ActorRef;
use std::path::Path;
use std::time::Duration;

/// Generous: elections on a loaded 2-core machine.
const DEADLINE: Duration = Duration::from_secs(60);
const NAME: &str = "probed";
const MEMBERS: [&str; 3] = ["p1", "p2", "p3"];

/// A replica on `me`, journaled in `dir/me`.
async fn start(dir: &Path, me: &str) -> ActorRef<DmMsg> {
    let mut replication = Replication::new(me, MEMBERS);
    replication.timing = Timing {
        heartbeat: Duration::from_millis(50),
        election: Duration::from_millis(1500),
        lease: Duration::from_millis(600),
    };
    let args = DmSpec::new(NAME, 1209)
        .args(RealClock::shared())
        .with_journal(dir.join(me), Durability::Process)
        .with_replication(replication);
    tokio::time::timeout(DEADLINE, dm::spawn_datamanager(args))
        .await
        .expect("spawned in time")
        .expect("the replica starts")
        .0
}

/// Wait until the probe's tally satisfies `done` (polled: the tally is a snapshot).
async fn until(probe: &Probe, what: &str, done: impl Fn(&ProbeVerdict) -> bool) -> ProbeVerdict {
    let start = std::time::Instant::now();
    loop {
        let t = probe.tally();
        if done(&t) {
            return t;
        }
        assert!(
            start.elapsed() < DEADLINE,
            "{what}: not within the deadline: {t}"
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

fn answered(v: &ProbeVerdict, road: &str) -> u64 {
    v.roads.get(road).map_or(0, |t| t.answered)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_probe_reads_every_road_while_the_leader_is_stopped_and_started_again_and_none_is_stale()
{
    let dir = tempfile::tempdir().unwrap();
    let mut replicas = Vec::new();
    for me in MEMBERS {
        replicas.push(start(dir.path(), me).await);
    }
    let probe = Probe::start(ProbeConfig::new(NAME))
        .await
        .expect("the probe finds the leader");
    let before = until(&probe, "writes and reads on every road", |v| {
        v.writes >= 20 && MEMBERS.iter().chain([&BY_NAME]).all(|r| answered(v, r) > 0)
    })
    .await;

    // the leader stopped: the writes go on at the next one
    let client = DmClient::lookup_within(NAME, "tester", DEADLINE)
        .await
        .unwrap();
    let leader = client.leader_node().await.expect("the leader's node");
    let i = MEMBERS.iter().position(|m| *m == leader).unwrap();
    replicas[i]
        .stop_and_wait(None, Some(DEADLINE))
        .await
        .unwrap();
    let during = until(&probe, "writes at the next leader", |v| {
        v.writes >= before.writes + 20
    })
    .await;
    // started again on its journal: its road answers again
    replicas[i] = start(dir.path(), &leader).await;
    until(&probe, "reads of the replica started again", |v| {
        answered(v, &leader) > answered(&during, &leader) + 10 && v.writes >= during.writes + 10
    })
    .await;

    let verdict = probe.stop().await;
    assert_eq!(verdict.stale(), 0, "{verdict}");
    assert_eq!(verdict.read_back, Some(ReadBack::Found), "{verdict}");
    assert!(verdict.holds(), "{verdict}");
    // the road to the stopped replica had nothing to ask for a while
    assert!(verdict.roads[leader.as_str()].absent > 0, "{verdict}");
    for r in replicas {
        r.stop_and_wait(None, Some(DEADLINE)).await.unwrap();
    }
}
