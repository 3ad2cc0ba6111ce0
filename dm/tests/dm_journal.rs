//! The datamanager's journal, end to end: what a DM at `process` or `sync` durability
//! acknowledges is there again when it starts anew on the same directory — after a graceful
//! stop, a crash, and `kill -9` of its process (a child process of this test) — and a torn or
//! corrupt journal is read up to its last whole entry, never further.
//!
//! Each test uses its own DM name and id (the registry is process-wide) and its own directory.

use marie_dm::{
    self as dm, DmArgs, DmClient, DmConfig, DmError, DmMsg, DmSpec, Durability, NewRecord, Payload,
    Query,
};
use marie_vocabulary::clock::RealClock;
use marie_vocabulary::run::FaultKind;
use ractor::ActorRef;
use std::future::Future;
use std::path::{Path, PathBuf};
use std::time::Duration;
use tokio::task::JoinHandle;

const DEADLINE: Duration = Duration::from_secs(30);

async fn within<T>(what: &str, fut: impl Future<Output = T>) -> T {
    tokio::time::timeout(DEADLINE, fut)
        .await
        .unwrap_or_else(|_| panic!("{what}: no result within {DEADLINE:?}"))
}

/// A fresh directory for one test, removed when it passes.
struct TempDir(PathBuf);

impl TempDir {
    fn new(name: &str) -> TempDir {
        let dir = std::env::temp_dir().join(format!("marie-journal-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        TempDir(dir)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        if !std::thread::panicking() {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

fn args(name: &'static str, id: u32, dir: &Path, durability: Durability) -> DmArgs {
    DmSpec::new(name, id)
        .args(RealClock::shared())
        .with_journal(dir, durability)
}

async fn start(args: DmArgs) -> (ActorRef<DmMsg>, JoinHandle<()>, DmClient) {
    let (actor, handle) = within("spawn", dm::spawn_datamanager(args))
        .await
        .expect("the DM starts");
    let client = DmClient::new(actor.clone(), "tester");
    (actor, handle, client)
}

async fn stop(actor: ActorRef<DmMsg>, handle: JoinHandle<()>) {
    actor.stop(None);
    within("the DM stops", handle).await.unwrap();
}

/// Every record, as (seq, source, class, sub1, payload bytes).
async fn everything(client: &DmClient) -> Vec<(u64, String, String, Option<String>, Vec<u8>)> {
    client
        .select(Query::all())
        .await
        .unwrap()
        .into_iter()
        .map(|r| {
            (
                r.seq,
                r.source.to_string(),
                r.class.to_string(),
                r.sub1.as_ref().map(|s| s.to_string()),
                r.payload.as_bytes().to_vec(),
            )
        })
        .collect()
}

/// Put `n` records of class `sonar` (numbered from 0) in batches of 1000, each batch
/// acknowledged before the next.
async fn put_sonar(client: &DmClient, n: u32) {
    for chunk in (0..n).collect::<Vec<_>>().chunks(1000) {
        let batch = chunk
            .iter()
            .map(|i| NewRecord::encode("sonar", i).unwrap())
            .collect();
        client.put_batch(batch).unwrap();
        client.stats().await.unwrap();
    }
}

/// Start a DM with `args`, store ten records of class `c` (numbered 0 to 9), stop it: the
/// segment that holds them.
async fn ten_stored(args: DmArgs) -> PathBuf {
    let dir = args.journal_dir.clone().unwrap();
    let (actor, handle, client) = start(args).await;
    for i in 0..10u32 {
        client.store("c", None, None, &i).await.unwrap();
    }
    stop(actor, handle).await;
    segments(&dir).pop().unwrap()
}

fn segments(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "log"))
        .collect();
    v.sort();
    v
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_stopped_dm_starts_again_with_its_records_its_seqs_and_its_deletes() {
    let tmp = TempDir::new("restart");
    let (actor, handle, client) =
        start(args("jr-restart", 4401, &tmp.0, Durability::Process)).await;
    for i in 0..50u32 {
        client
            .store("sonar", Some("front"), None, &i)
            .await
            .unwrap();
    }
    for i in 0..30u32 {
        client.put("wall", Some("left"), None, &(i, "x")).unwrap();
    }
    client
        .put_batch(
            (0..20u32)
                .map(|i| NewRecord::encode("pose", &i).unwrap())
                .collect(),
        )
        .unwrap();
    let deleted = client
        .delete(Query::class("sonar").oldest(10))
        .await
        .unwrap();
    assert_eq!(deleted, 10);
    let before = everything(&client).await;
    assert_eq!(before.len(), 90);
    let stats = client.stats().await.unwrap();
    assert_eq!(stats.durability, Durability::Process);
    assert!(stats.journal_bytes > 0, "{stats:?}");
    assert_eq!(stats.recovery.as_ref().unwrap().records, 0);
    stop(actor, handle).await;

    let (actor, handle, client) =
        start(args("jr-restart", 4401, &tmp.0, Durability::Process)).await;
    assert_eq!(everything(&client).await, before);
    let stats = client.stats().await.unwrap();
    let recovery = stats.recovery.clone().unwrap();
    assert_eq!(recovery.records, 90, "{recovery:?}");
    assert_eq!((recovery.dropped_bytes, recovery.torn.clone()), (0, None));
    // the journal's size is what the replay kept, and what is on disk
    let on_disk: u64 = segments(&tmp.0)
        .iter()
        .map(|p| std::fs::metadata(p).unwrap().len())
        .sum();
    assert_eq!((stats.journal_bytes, recovery.bytes), (on_disk, on_disk));
    assert_eq!(
        stats.next_seq, 101,
        "seqs continue after the last one handed out"
    );
    let seq = client.store("sonar", None, None, &99u32).await.unwrap();
    assert_eq!(seq, 101);
    stop(actor, handle).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn what_a_crashed_dm_acknowledged_its_next_incarnation_holds() {
    let tmp = TempDir::new("crash");
    let (actor, handle, client) = start(args("jr-crash", 4402, &tmp.0, Durability::Sync)).await;
    let mut acked = Vec::new();
    for i in 0..200u32 {
        acked.push((client.store("feature", None, None, &i).await.unwrap(), i));
    }
    // a panic mid-stream: the journal's writer of this incarnation still holds the directory
    // while it finishes; the next start waits for it
    actor
        .cast(DmMsg::Inject {
            fault: FaultKind::Panic,
        })
        .unwrap();
    let _ = within("the DM dies", handle).await;
    let (actor, handle, client) = start(args("jr-crash", 4402, &tmp.0, Durability::Sync)).await;
    let got = client.select(Query::class("feature")).await.unwrap();
    let got: Vec<(u64, u32)> = got.iter().map(|r| (r.seq, r.decode().unwrap())).collect();
    assert_eq!(got, acked);
    stop(actor, handle).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_torn_tail_is_cut_off_reported_and_written_over() {
    let tmp = TempDir::new("torn");
    let seg = ten_stored(args("jr-torn", 4403, &tmp.0, Durability::Process)).await;
    // a write cut short: half of an eleventh entry (the entries start after the segment's
    // format header)
    let whole = std::fs::read(&seg).unwrap();
    let first = if whole.starts_with(b"MJNL") { 8 } else { 0 };
    let one = (whole.len() - first) / 10;
    let mut torn = whole.clone();
    torn.extend_from_slice(&whole[first..first + one / 2]);
    std::fs::write(&seg, &torn).unwrap();

    let (actor, handle, client) = start(args("jr-torn", 4403, &tmp.0, Durability::Process)).await;
    let r = client.stats().await.unwrap().recovery.unwrap();
    assert_eq!(r.records, 10);
    assert_eq!(r.dropped_bytes, (one / 2) as u64, "{r:?}");
    assert_eq!(r.dropped_records, 0, "a cut entry was never whole: {r:?}");
    assert!(r.torn.as_deref().unwrap().contains("cut short"), "{r:?}");
    assert_eq!(
        std::fs::read(&seg).unwrap(),
        whole,
        "the segment is cut back to its last whole entry"
    );
    assert_eq!(
        r.bytes,
        whole.len() as u64,
        "what was kept is what is on disk"
    );
    // the next write continues after the last whole entry, and is read back
    assert_eq!(client.store("c", None, None, &10u32).await.unwrap(), 11);
    stop(actor, handle).await;
    let (actor, handle, client) = start(args("jr-torn", 4403, &tmp.0, Durability::Process)).await;
    assert_eq!(client.select(Query::class("c")).await.unwrap().len(), 11);
    assert_eq!(client.stats().await.unwrap().recovery.unwrap().torn, None);
    stop(actor, handle).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_flipped_bit_stops_the_replay_before_it_and_nothing_corrupt_is_served() {
    let tmp = TempDir::new("flip");
    let seg = ten_stored(args("jr-flip", 4404, &tmp.0, Durability::Process)).await;
    let mut bytes = std::fs::read(&seg).unwrap();
    let one = bytes.len() / 10;
    bytes[6 * one + one / 2] ^= 0x10; // inside the 7th entry's body
    std::fs::write(&seg, &bytes).unwrap();

    let (actor, handle, client) = start(args("jr-flip", 4404, &tmp.0, Durability::Process)).await;
    let got: Vec<u32> = client
        .select(Query::class("c"))
        .await
        .unwrap()
        .iter()
        .map(|r| r.decode().unwrap())
        .collect();
    assert_eq!(got, (0..6).collect::<Vec<_>>());
    let r = client.stats().await.unwrap().recovery.unwrap();
    assert!(r.torn.as_deref().unwrap().contains("checksum"), "{r:?}");
    assert_eq!(
        r.dropped_records, 1,
        "the corrupt entry; what follows it is cut with it: {r:?}"
    );
    assert_eq!(r.dropped_bytes, (4 * one) as u64, "{r:?}");
    stop(actor, handle).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn retention_and_snapshots_keep_the_journal_near_the_size_of_the_store() {
    let tmp = TempDir::new("snapshot");
    let config = DmConfig::default().with_retention("sonar", 1000);
    let mut a = args("jr-snap", 4405, &tmp.0, Durability::Process);
    a.config = config.clone();
    let (actor, handle, client) = start(a.clone()).await;
    let n = 4 * dm::SNAPSHOT_MIN as u32;
    put_sonar(&client, n).await;
    let stats = client.stats().await.unwrap();
    assert_eq!(stats.records, 1000);
    let per_record = stats.journal_bytes as f64 / n as f64;
    // 4 × SNAPSHOT_MIN puts were written; a journal that was never compacted would hold all
    assert!(
        stats.journal_bytes < (3 * dm::SNAPSHOT_MIN) * 40,
        "journal of {} bytes ({per_record:.1} per put) after {n} puts into a store of 1000",
        stats.journal_bytes
    );
    let newest: Vec<u32> = client
        .select(Query::class("sonar").newest(3))
        .await
        .unwrap()
        .iter()
        .map(|r| r.decode().unwrap())
        .collect();
    stop(actor, handle).await;
    assert_eq!(
        segments(&tmp.0).len(),
        1,
        "the segments before the snapshot are gone"
    );

    let (actor, handle, client) = start(a).await;
    let stats = client.stats().await.unwrap();
    assert_eq!(stats.records, 1000);
    assert_eq!(stats.next_seq, n as u64 + 1);
    let again: Vec<u32> = client
        .select(Query::class("sonar").newest(3))
        .await
        .unwrap()
        .iter()
        .map(|r| r.decode().unwrap())
        .collect();
    assert_eq!(again, newest);
    stop(actor, handle).await;
}

/// A journal that is mostly garbage when it is read back — here its class's retention was
/// lowered between two starts; a node killed on a journal written under a higher
/// [`dm::SNAPSHOT_MIN`] is the other way — is snapshotted at the start, so the next start
/// replays the live records, not the whole history again.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_journal_read_back_mostly_garbage_is_snapshotted_at_the_start() {
    let tmp = TempDir::new("startsnap");
    let n = dm::SNAPSHOT_MIN as u32 + 1000;
    let mut a = args("jr-startsnap", 4410, &tmp.0, Durability::Process);
    // every put kept: the journal is never due while they are written
    a.config = DmConfig::default().with_retention("sonar", n as usize);
    let (actor, handle, client) = start(a.clone()).await;
    put_sonar(&client, n).await;
    stop(actor, handle).await;
    let before = segments(&tmp.0);
    assert_eq!(before.len(), 1);

    a.config = DmConfig::default().with_retention("sonar", 1000);
    let (actor, handle, client) = start(a.clone()).await;
    let stats = client.stats().await.unwrap();
    let recovery = stats.recovery.clone().expect("read back");
    assert!(
        recovery.entries >= n as u64,
        "the whole history: {recovery:?}"
    );
    assert_eq!(stats.records, 1000);
    let newest = client
        .select(Query::class("sonar").newest(1))
        .await
        .unwrap();
    assert_eq!(newest[0].decode::<u32>().unwrap(), n - 1);
    stop(actor, handle).await;
    let after = segments(&tmp.0);
    assert_eq!(
        after.len(),
        1,
        "the old segment gone for the snapshot's: {after:?}"
    );
    assert_ne!(after, before);

    let (actor, handle, client) = start(a).await;
    let stats = client.stats().await.unwrap();
    let recovery = stats.recovery.clone().expect("read back");
    // the snapshot's records, its open and end marks and its producers' table
    assert!(
        recovery.entries < 1100,
        "the live records only: {recovery:?}"
    );
    assert!(recovery.torn.is_none(), "{recovery:?}");
    assert_eq!(stats.records, 1000);
    assert_eq!(stats.next_seq, n as u64 + 1);
    let again = client
        .select(Query::class("sonar").newest(1))
        .await
        .unwrap();
    assert_eq!(
        (again[0].seq, again[0].decode::<u32>().unwrap()),
        (newest[0].seq, n - 1)
    );
    stop(actor, handle).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn eight_producers_at_sync_are_acknowledged_in_groups_and_all_come_back() {
    let tmp = TempDir::new("sync8");
    let (actor, handle, _) = start(args("jr-sync8", 4406, &tmp.0, Durability::Sync)).await;
    let mut tasks = Vec::new();
    for p in 0..8u32 {
        let client = DmClient::new(actor.clone(), format!("producer-{p}"));
        tasks.push(tokio::spawn(async move {
            let mut seqs = Vec::new();
            for i in 0..250u32 {
                seqs.push(client.store("x", None, None, &(p, i)).await.unwrap());
            }
            seqs
        }));
    }
    let mut acked = 0;
    for t in tasks {
        let seqs = within("a producer", t).await.unwrap();
        assert!(
            seqs.windows(2).all(|w| w[0] < w[1]),
            "a producer's records in its order"
        );
        acked += seqs.len();
    }
    stop(actor, handle).await;
    let (actor, handle, client) = start(args("jr-sync8", 4406, &tmp.0, Durability::Sync)).await;
    assert_eq!(client.select(Query::class("x")).await.unwrap().len(), acked);
    stop(actor, handle).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_durable_dm_without_a_directory_does_not_start_and_says_why() {
    let mut a = DmSpec::new("jr-nodir", 4407).args(RealClock::shared());
    a.durability = Durability::Sync;
    let err = dm::spawn_datamanager(a).await.unwrap_err().to_string();
    assert!(
        err.contains("durability sync needs a journal directory"),
        "{err}"
    );
}

/// A full disk: a tmpfs of 1 MiB (mounted by this test; it needs root, as CI runs).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_full_disk_refuses_the_put_and_the_dm_carries_on() {
    let tmp = TempDir::new("full");
    let mount = tmp.0.join("small");
    std::fs::create_dir_all(&mount).unwrap();
    let mounted = std::process::Command::new("mount")
        .args(["-t", "tmpfs", "-o", "size=1m", "tmpfs"])
        .arg(&mount)
        .status()
        .is_ok_and(|s| s.success());
    if !mounted {
        eprintln!("skipped: cannot mount a tmpfs here (not root?)");
        return;
    }
    struct Unmount(PathBuf);
    impl Drop for Unmount {
        fn drop(&mut self) {
            let _ = std::process::Command::new("umount")
                .arg("-l") // lazily: also while a failed test's DM still holds files open
                .arg(&self.0)
                .status();
        }
    }
    let _unmount = Unmount(mount.clone());
    let (actor, handle, client) = start(args("jr-full", 4408, &mount, Durability::Sync)).await;
    let big = Payload::from_bytes(vec![7; 64 << 10]);
    let mut stored = Vec::new();
    let refusal = loop {
        match client.store_raw(NewRecord::new("blob", big.clone())).await {
            Ok(seq) => stored.push(seq),
            Err(e) => break e,
        }
        assert!(
            stored.len() < 100,
            "1 MiB cannot hold 100 records of 64 KiB"
        );
    };
    assert!(matches!(refusal, DmError::Storage(_)), "{refusal:?}");
    assert!(refusal.to_string().contains("No space left"), "{refusal}");
    // the refused record is not served, and the DM answers on
    let stats = client.stats().await.unwrap();
    assert_eq!(stats.records as usize, stored.len(), "{stats:?}");
    // room again: puts are taken again
    let deleted = client.delete(Query::class("blob").oldest(4)).await.unwrap();
    assert_eq!(deleted, 4);
    let small = client.store("note", None, None, &1u8).await;
    assert!(small.is_ok(), "{small:?}");
    stop(actor, handle).await;
    let (actor, handle, client) = start(args("jr-full", 4408, &mount, Durability::Sync)).await;
    let blobs = client.select(Query::class("blob")).await.unwrap();
    assert_eq!(blobs.len(), stored.len() - 4);
    assert_eq!(client.select(Query::class("note")).await.unwrap().len(), 1);
    stop(actor, handle).await;
}

/// A record written long before the last snapshot — a map stored once, then a sensor's
/// stream — lives on only in the snapshot: after a restart it is there, with its seq.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_record_that_only_the_snapshot_holds_comes_back() {
    let tmp = TempDir::new("snaponly");
    let mut a = args("jr-snaponly", 4409, &tmp.0, Durability::Process);
    a.config = DmConfig::default().with_retention("sonar", 100);
    let (actor, handle, client) = start(a.clone()).await;
    let map_seq = client.store("map", None, None, &"walls").await.unwrap();
    // enough sonar for a snapshot, and few after it: the last snapshot is the map's only copy
    let n = dm::SNAPSHOT_MIN as u32 + 50;
    put_sonar(&client, n).await;
    stop(actor, handle).await;
    let (actor, handle, client) = start(a).await;
    let map = client.select(Query::class("map")).await.unwrap();
    assert_eq!(map.len(), 1, "the map, from the snapshot");
    assert_eq!(map[0].seq, map_seq);
    assert_eq!(map[0].decode::<String>().unwrap(), "walls");
    let stats = client.stats().await.unwrap();
    assert_eq!(stats.records, 101);
    assert_eq!(stats.next_seq, n as u64 + 2);
    stop(actor, handle).await;
}
