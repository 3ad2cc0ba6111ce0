//! A datamanager's clients follow it to its next instance (issue 22, point 1) and a put sent
//! again is stored once (point 3).
//!
//! A supervisor restarts a crashed datamanager as a new actor under the same name; here the
//! test plays the supervisor (kills the DM, spawns the next one), so that it can choose the
//! moment. Each test has its own DM name and id (the registry is process-wide).

use marie_dm::{
    self as dm, DmArgs, DmClient, DmMsg, DmSpec, Durability, NewRecord, Payload, Query,
};
use marie_vocabulary::clock::RealClock;
use ractor::ActorRef;
use std::future::Future;
use std::path::PathBuf;
use std::time::Duration;
use tokio::task::JoinHandle;

const DEADLINE: Duration = Duration::from_secs(30);

async fn within<T>(what: &str, fut: impl Future<Output = T>) -> T {
    tokio::time::timeout(DEADLINE, fut)
        .await
        .unwrap_or_else(|_| panic!("{what}: no result within {DEADLINE:?}"))
}

async fn start(args: DmArgs) -> (ActorRef<DmMsg>, JoinHandle<()>) {
    within("spawn", dm::spawn_datamanager(args))
        .await
        .expect("the DM starts")
}

/// Kill the DM, as a crash would, and wait until it is gone.
async fn crash(actor: ActorRef<DmMsg>, handle: JoinHandle<()>) {
    actor.kill();
    let _ = within("the DM dies", handle).await;
}

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("marie-follow-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// Wait until the DM holds `n` pending waits.
async fn pending_waits(client: &DmClient, n: u64) {
    within("pending waits", async {
        while client.stats().await.map(|s| s.pending_waits) != Ok(n) {
            tokio::task::yield_now().await;
        }
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_open_wait_select_is_re_armed_on_the_next_instance() {
    let spec = DmSpec::new("fw-wait", 4501);
    let (actor, handle) = start(spec.args(RealClock::shared())).await;
    let client = DmClient::new(actor.clone(), "consumer");
    let waiter = {
        let c = client.clone();
        tokio::spawn(async move {
            c.select_wait(Query::class("spot"), Duration::from_secs(20))
                .await
        })
    };
    pending_waits(&client, 1).await;
    crash(actor, handle).await;
    let (next, next_handle) = start(spec.args(RealClock::shared())).await;
    // the wait moves to the next instance, and is answered there
    pending_waits(&DmClient::new(next.clone(), "probe"), 1).await;
    let producer = DmClient::new(next.clone(), "detector");
    let seq = producer
        .store("spot", None, None, &(1.0, 2.0))
        .await
        .unwrap();
    let answer = within("the wait", waiter).await.unwrap().unwrap();
    assert_eq!(answer.len(), 1);
    assert_eq!(answer[0].seq, seq);
    assert_eq!(client.actor().get_id(), next.get_id(), "the client moved");
    next.stop(None);
    next_handle.await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_subscription_carries_on_into_an_instance_that_started_empty() {
    let spec = DmSpec::new("fw-sub", 4502);
    let (actor, handle) = start(spec.args(RealClock::shared())).await;
    let client = DmClient::new(actor.clone(), "consumer");
    let mut sub = client.subscribe(Query::class("pose")).await.unwrap();
    for i in 0..5u32 {
        client.store("pose", None, None, &i).await.unwrap();
    }
    for i in 0..5u32 {
        let r = within("a record", sub.next()).await.unwrap();
        assert_eq!(r.decode::<u32>().unwrap(), i);
    }
    crash(actor, handle).await;
    // a memory DM comes back empty and numbers from 1 again: the subscription takes it all
    let (next, next_handle) = start(spec.args(RealClock::shared())).await;
    let producer = DmClient::new(next.clone(), "localizer");
    for i in 5..8u32 {
        producer.store("pose", None, None, &i).await.unwrap();
    }
    for i in 5..8u32 {
        let r = within("a record from the next instance", sub.next())
            .await
            .unwrap();
        assert_eq!(r.decode::<u32>().unwrap(), i);
    }
    next.stop(None);
    next_handle.await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_store_to_a_gone_dm_waits_for_the_next_instance_and_lands_there() {
    let spec = DmSpec::new("fw-store", 4503);
    let (actor, handle) = start(spec.args(RealClock::shared())).await;
    let client = DmClient::new(actor.clone(), "planner");
    client.store("path", None, None, &0u8).await.unwrap();
    crash(actor, handle).await;
    let store = {
        let c = client.clone();
        tokio::spawn(async move { c.store("path", None, None, &1u8).await })
    };
    let (next, next_handle) = start(spec.args(RealClock::shared())).await;
    let seq = within("the store", store)
        .await
        .unwrap()
        .expect("stored in the next instance");
    let got = DmClient::new(next.clone(), "x")
        .select(Query::class("path"))
        .await
        .unwrap();
    assert_eq!(got.len(), 1);
    assert_eq!((got[0].seq, got[0].decode::<u8>().unwrap()), (seq, 1));
    // a put goes to the next instance too, now that it is published
    client.put("path", None, None, &2u8).unwrap();
    assert_eq!(client.select(Query::class("path")).await.unwrap().len(), 2);
    next.stop(None);
    next_handle.await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_delete_to_a_gone_dm_is_not_sent_again_but_a_retry_reaches_the_next_instance() {
    let spec = DmSpec::new("fw-delete", 4507);
    let (actor, handle) = start(spec.args(RealClock::shared())).await;
    let client = DmClient::new(actor.clone(), "planner");
    crash(actor, handle).await;
    let delete = {
        let c = client.clone();
        tokio::spawn(async move { c.delete(Query::class("path")).await })
    };
    let (next, next_handle) = start(spec.args(RealClock::shared())).await;
    let producer = DmClient::new(next.clone(), "x");
    producer.store("path", None, None, &1u8).await.unwrap();
    // it may have been done before the DM went: not sent again by itself
    let err = within("the delete", delete).await.unwrap().unwrap_err();
    assert_eq!(err, dm::DmError::Unreachable("fw-delete".into()));
    assert_eq!(producer.select(Query::all()).await.unwrap().len(), 1);
    // but the client moved: the caller's retry reaches the next instance
    assert_eq!(client.actor().get_id(), next.get_id(), "the client moved");
    assert_eq!(client.delete(Query::class("path")).await, Ok(1));
    assert!(producer.select(Query::all()).await.unwrap().is_empty());
    next.stop(None);
    next_handle.await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn without_a_next_instance_a_request_fails_unreachable_after_the_follow_wait() {
    let spec = DmSpec::new("fw-none", 4504);
    let (actor, handle) = start(spec.args(RealClock::shared())).await;
    let client = DmClient::new(actor.clone(), "x").with_follow(Duration::from_millis(200));
    crash(actor, handle).await;
    let err = within("the select", client.select(Query::all()))
        .await
        .unwrap_err();
    assert_eq!(err, dm::DmError::Unreachable("fw-none".into()));
    let err = client.put("c", None, None, &1u8).unwrap_err();
    assert_eq!(err, dm::DmError::Unreachable("fw-none".into()));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_record_sent_twice_is_stored_once_and_answered_with_its_first_seq() {
    let spec = DmSpec::new("fw-twice", 4505);
    let (actor, handle) = start(spec.args(RealClock::shared())).await;
    let mut record = NewRecord::new("c", Payload::encode(&7u8).unwrap()).with_source("p");
    record.producer = 42;
    record.producer_seq = 1;
    let store = |r: NewRecord| {
        let actor = actor.clone();
        async move {
            actor
                .call(
                    |reply| DmMsg::Store {
                        record: Box::new(r),
                        reply,
                    },
                    None,
                )
                .await
                .unwrap()
                .unwrap()
        }
    };
    let first = store(record.clone()).await.unwrap();
    let again = store(record.clone()).await.unwrap();
    assert_eq!(again, first);
    let mut next = record.clone();
    next.producer_seq = 2;
    assert_eq!(store(next).await.unwrap(), first + 1);
    let mut other = record.clone();
    other.producer = 43; // another producer's number 1 is its own
    assert_eq!(store(other).await.unwrap(), first + 2);
    let stats = DmClient::new(actor.clone(), "x").stats().await.unwrap();
    assert_eq!((stats.records, stats.duplicates), (3, 1));
    actor.stop(None);
    handle.await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_restarted_dm_still_knows_what_its_predecessor_stored_also_after_a_snapshot() {
    let dir = temp("idem");
    let spec = DmSpec::new("fw-idem", 4506);
    let args = || {
        let mut a = spec
            .args(RealClock::shared())
            .with_journal(&dir, Durability::Process);
        a.config = a.config.with_retention("c", 10);
        a
    };
    let (actor, handle) = start(args()).await;
    let client = DmClient::new(actor.clone(), "producer");
    // enough puts for a snapshot: the idempotence table must survive it
    let n = dm::SNAPSHOT_MIN + 100;
    let records: Vec<NewRecord> = (0..n)
        .map(|i| {
            let mut r = NewRecord::new("c", Payload::encode(&i).unwrap()).with_source("producer");
            r.producer = 7;
            r.producer_seq = i + 1;
            r
        })
        .collect();
    for chunk in records.chunks(1000) {
        client.put_batch(chunk.to_vec()).unwrap();
    }
    let last = records.last().unwrap().clone();
    let seq = client.store_raw(last.clone()).await.unwrap();
    assert_eq!(seq, n, "the put of the batch, answered with its seq");
    crash(actor, handle).await;
    let (actor, handle) = start(args()).await;
    let client = DmClient::new(actor.clone(), "producer");
    assert_eq!(
        client.store_raw(last).await.unwrap(),
        n,
        "the retry after the restart"
    );
    let stats = client.stats().await.unwrap();
    assert_eq!((stats.next_seq, stats.duplicates), (n + 1, 1));
    actor.stop(None);
    handle.await.unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
}
