//! Flow control of remote puts: a producer in this process storing as fast as it can into
//! a datamanager on a `marie node` process is held to a window of unacknowledged puts —
//! refused with `Busy` when it is spent, never queueing without bound — and every put it
//! was allowed reaches the datamanager; batches of puts spend one credit per record and
//! arrive whole and in order; single puts coalesced in flight arrive in order too; and a
//! select whose answer is larger than ractor_cluster's 16 MiB frame comes back whole, in
//! pages (answered in one frame, it would end the session between the nodes). (Its own
//! process: it joins the cluster as a member.)

use crate::common;

use common::cluster::NodeProc;
use marie::cluster::net::{ClusterConfig, Transport};
use marie::dm::{DmClient, DmError, NewRecord, Payload, Query};
use marie::dm::{PUT_BATCH as BATCH, PUT_WINDOW as WINDOW};
use std::time::Duration;

const COOKIE: &str = "backpressure";
const PUTS: usize = 100_000;

/// One member of one cluster at a time in this test process (see there).
use common::ONE_MEMBER;

/// `alpha`, a node with the feature datamanager, and a runtime for this process' member.
fn feature_node(dir: &std::path::Path) -> (NodeProc, tokio::runtime::Runtime) {
    let alpha = NodeProc::start(
        dir,
        "alpha",
        "[[datamanager]]\nname = \"feature\"\n",
        &[],
        COOKIE,
    );
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap();
    (alpha, rt)
}

#[test]
fn a_fast_producer_is_held_to_its_window_and_loses_no_accepted_put() {
    let _one = ONE_MEMBER.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let (mut alpha, rt) = feature_node(dir.path());
    let (accepted, busy, max_in_flight, stats) = rt.block_on(async {
        let me = ClusterConfig::new("127.0.0.1:0".parse().unwrap(), COOKIE).with_peer(alpha.addr);
        let transport = Transport::start("producer", &me).await.unwrap();
        transport
            .wait_for_peers(1, Duration::from_secs(60))
            .await
            .unwrap();
        let client = DmClient::lookup("feature", "producer").unwrap();
        assert!(!client.actor().get_id().is_local());
        let (mut accepted, mut busy, mut max_in_flight) = (0usize, 0usize, 0usize);
        for i in 0..PUTS {
            match client.put("sonar", Some("front"), None, &(i as u64)) {
                Ok(()) => accepted += 1,
                Err(DmError::Busy { .. }) => busy += 1,
                Err(e) => panic!("put {i}: {e}"),
            }
            max_in_flight = max_in_flight.max(client.puts_in_flight());
            if i % 256 == 0 {
                tokio::task::yield_now().await; // a sensor's loop has awaits too
            }
        }
        // every accepted put has arrived by the time a later call is answered: the DM
        // answers a sender's call only after its earlier messages (what the credits rely on)
        let stats = client.stats().await.unwrap();
        transport.stop().await;
        (accepted, busy, max_in_flight, stats)
    });
    eprintln!(
        "{accepted} puts accepted, {busy} refused busy, at most {max_in_flight} in flight; the DM holds {} and dropped {}",
        stats.records, stats.dropped
    );
    assert!(busy > 0, "a producer this fast must have been held back");
    assert!(max_in_flight <= WINDOW, "{max_in_flight} in flight");
    assert_eq!(stats.records + stats.dropped, accepted as u64, "{stats:?}");
    assert_eq!(stats.refused_puts, 0);
    assert_eq!(accepted + busy, PUTS);
    alpha.signal("TERM");
    assert_eq!(alpha.wait_exit(), Some(0));
}

#[test]
fn batches_spend_a_credit_per_record_and_arrive_whole_and_in_order() {
    let _one = ONE_MEMBER.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let (mut alpha, rt) = feature_node(dir.path());
    rt.block_on(async {
        let me = ClusterConfig::new("127.0.0.1:0".parse().unwrap(), COOKIE).with_peer(alpha.addr);
        let transport = Transport::start("batcher", &me).await.unwrap();
        transport
            .wait_for_peers(1, Duration::from_secs(60))
            .await
            .unwrap();
        let client = DmClient::lookup("feature", "batcher").unwrap();
        assert!(!client.actor().get_id().is_local());
        let rec = |i: u64| NewRecord::new("sonar", Payload::encode(&i).unwrap());
        // a batch the window could never hold is refused, not sent
        match client.put_batch((0..WINDOW as u64 + 1).map(rec).collect()) {
            Err(DmError::BatchTooLarge { records, window }) => {
                assert_eq!((records, window), (WINDOW as u64 + 1, WINDOW as u64))
            }
            other => panic!("{other:?}"),
        }
        assert_eq!(client.puts_in_flight(), 0);
        // a producer that waits for credits is never refused, and never over the window
        let mut max_in_flight = 0;
        let mut next = 0u64;
        while next < PUTS as u64 {
            let batch: Vec<NewRecord> = (next..next + BATCH as u64).map(rec).collect();
            next += BATCH as u64;
            client.ready(batch.len()).await.unwrap();
            client.put_batch(batch).unwrap();
            max_in_flight = max_in_flight.max(client.puts_in_flight());
        }
        assert!(max_in_flight <= WINDOW, "{max_in_flight} in flight");
        // (the window a datamanager without copies grants, acknowledgements in)
        assert_eq!(client.window(), Some(WINDOW));
        // and put_all does the same by itself
        tokio::time::timeout(
            Duration::from_secs(60),
            client.put_all((next..next + PUTS as u64 / 2).map(rec)),
        )
        .await
        .expect("put_all ends")
        .unwrap();
        let total = next + PUTS as u64 / 2;
        let stats = client.stats().await.unwrap();
        assert_eq!(stats.records + stats.dropped, total, "{stats:?}");
        assert_eq!(stats.refused_puts, 0);
        let newest: Vec<u64> = client
            .select_typed::<u64>(Query::class("sonar").newest(1000))
            .await
            .unwrap()
            .into_iter()
            .map(|(_, v)| v)
            .collect();
        assert_eq!(newest, (total - 1000..total).collect::<Vec<_>>());
        transport.stop().await;
    });
    alpha.signal("TERM");
    assert_eq!(alpha.wait_exit(), Some(0));
}

#[test]
fn single_puts_coalesced_in_flight_arrive_in_order_within_the_window() {
    let _one = ONE_MEMBER.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let (mut alpha, rt) = feature_node(dir.path());
    rt.block_on(async {
        let me = ClusterConfig::new("127.0.0.1:0".parse().unwrap(), COOKIE).with_peer(alpha.addr);
        let transport = Transport::start("coalescer", &me).await.unwrap();
        transport
            .wait_for_peers(1, Duration::from_secs(60))
            .await
            .unwrap();
        let client = DmClient::lookup("feature", "coalescer").unwrap();
        assert!(!client.actor().get_id().is_local());
        // two tasks of one producer (clones share the outbox and the window), each putting
        // its own sequence one record at a time; one also stores a marker (a request) now
        // and then. Under the datamanager's retention of 10 000 per class.
        const EACH: u64 = 4_000;
        let producer = |sub1: &'static str, client: DmClient| async move {
            let mut max_in_flight = 0;
            let mut markers = Vec::new();
            for i in 0..EACH {
                // both tasks spend one window: waiting for a credit and taking it is one
                // step, else the other task may take the credit `ready` saw free
                client
                    .put_waiting("seq", Some(sub1), None, &i)
                    .await
                    .unwrap();
                max_in_flight = max_in_flight.max(client.puts_in_flight());
                if sub1 == "a" && i % 997 == 996 {
                    let seq = client.store("marker", None, None, &i).await.unwrap();
                    markers.push((i, seq));
                }
                if i % 100 == 99 {
                    tokio::task::yield_now().await;
                }
            }
            (max_in_flight, markers)
        };
        let (a, b) = tokio::join!(
            tokio::spawn(producer("a", client.clone())),
            tokio::spawn(producer("b", client.clone())),
        );
        let ((max_a, markers), (max_b, _)) = (a.unwrap(), b.unwrap());
        assert!(max_a.max(max_b) <= WINDOW, "{max_a} / {max_b} in flight");
        let stats = client.stats().await.unwrap();
        assert_eq!(stats.refused_puts, 0);
        assert_eq!(stats.dropped, 0);
        for sub1 in ["a", "b"] {
            let stored = client
                .select_typed::<u64>(Query::class("seq").sub1(sub1))
                .await
                .unwrap();
            let values: Vec<u64> = stored.iter().map(|(_, v)| *v).collect();
            assert_eq!(
                values,
                (0..EACH).collect::<Vec<_>>(),
                "{sub1}: every put, in order"
            );
            if sub1 == "a" {
                // a request leaves after the puts made before it, and before those after
                for (i, marker_seq) in &markers {
                    let seq_of = |v: u64| stored[v as usize].0.seq;
                    assert!(seq_of(*i) < *marker_seq, "put {i} before its marker");
                    if *i + 1 < EACH {
                        assert!(seq_of(*i + 1) > *marker_seq, "put {} after it", i + 1);
                    }
                }
            }
        }
        transport.stop().await;
    });
    alpha.signal("TERM");
    assert_eq!(alpha.wait_exit(), Some(0));
}

#[test]
fn a_select_larger_than_a_frame_comes_back_whole_in_pages_also_waiting_or_subscribed() {
    let _one = ONE_MEMBER.lock().unwrap_or_else(|e| e.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let (mut alpha, rt) = feature_node(dir.path());
    rt.block_on(async {
        let me = ClusterConfig::new("127.0.0.1:0".parse().unwrap(), COOKIE).with_peer(alpha.addr);
        let transport = Transport::start("pager", &me).await.unwrap();
        transport
            .wait_for_peers(1, Duration::from_secs(60))
            .await
            .unwrap();
        let client = DmClient::lookup("feature", "pager")
            .unwrap()
            .with_timeout(Duration::from_secs(60));
        assert!(!client.actor().get_id().is_local());
        // 40 MiB in 40 records, and small ones between them
        const BIG: usize = 1 << 20;
        let mut want = Vec::new();
        for i in 0..40u8 {
            let seq = client
                .store_raw(NewRecord::new("scan", Payload::from_bytes(vec![i; BIG])))
                .await
                .unwrap();
            want.push((seq, i, BIG));
            let seq = client.store("note", None, None, &i).await.unwrap();
            want.push((seq, i, 0));
        }
        let got = client.select(Query::all()).await.unwrap();
        let got: Vec<(u64, u8, usize)> = got
            .iter()
            .map(|r| match r.class.as_ref() {
                "scan" => (r.seq, r.payload.as_bytes()[0], r.payload.len()),
                _ => (r.seq, r.decode::<u8>().unwrap(), 0),
            })
            .collect();
        assert_eq!(got, want);
        // the newest 3 scans: a limit keeps its meaning across pages
        let newest = client.select(Query::class("scan").newest(3)).await.unwrap();
        let firsts: Vec<u8> = newest.iter().map(|r| r.payload.as_bytes()[0]).collect();
        assert_eq!(firsts, vec![37, 38, 39]);
        // a wait-select that finds records at once answers in pages too
        let waited = client
            .select_wait(Query::all(), Duration::from_secs(1))
            .await
            .unwrap();
        let waited: Vec<u64> = waited.iter().map(|r| r.seq).collect();
        let seqs: Vec<u64> = want.iter().map(|w| w.0).collect();
        assert_eq!(waited, seqs);
        // a subscription's polls (up to 256 records each: 40 MiB here) as well
        let mut sub = client
            .subscribe(Query::class("scan").seq_from(1))
            .await
            .unwrap();
        for i in 0..40u8 {
            let r = tokio::time::timeout(Duration::from_secs(60), sub.next())
                .await
                .expect("a scan within 60 s")
                .expect("the subscription goes on");
            assert_eq!((r.payload.as_bytes()[0], r.payload.len()), (i, BIG));
        }
        // and a wait answered when its record comes
        let waiter = {
            let c = client.clone();
            tokio::spawn(async move {
                c.select_wait(Query::class("late"), Duration::from_secs(60))
                    .await
            })
        };
        while client.stats().await.unwrap().pending_waits == 0 {
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
        let seq = client
            .store_raw(NewRecord::new("late", Payload::from_bytes(vec![7; BIG])))
            .await
            .unwrap();
        let late = waiter.await.unwrap().unwrap();
        assert_eq!(late.len(), 1);
        assert_eq!((late[0].seq, late[0].payload.len()), (seq, BIG));
        // the session held: the node still answers
        assert_eq!(client.stats().await.unwrap().records, 81);
        transport.stop().await;
    });
    alpha.signal("TERM");
    assert_eq!(alpha.wait_exit(), Some(0));
}
