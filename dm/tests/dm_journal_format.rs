//! Journals carry their format: a datamanager of this build opens a journal written by the
//! build before formats (format 1, no header: `tests/fixtures/journal-format-1`, written by
//! that build's writer) and reads it the same, and refuses at its start a journal with a
//! segment of a format it does not know — naming both formats and the directory — without
//! replaying, cutting or removing anything, also when an earlier segment has a torn tail.

use marie_dm::{
    self as dm, DmArgs, DmClient, DmSpec, Durability, Query, JOURNAL_FORMAT, OLDEST_JOURNAL_FORMAT,
};
use marie_vocabulary::clock::RealClock;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// A fresh directory for one test, removed when it passes.
struct TempDir(PathBuf);

impl TempDir {
    fn new(name: &str) -> TempDir {
        let dir = std::env::temp_dir().join(format!("marie-jformat-{name}-{}", std::process::id()));
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

const SEGMENT_1: &str = "00000000000000000001.log";
const SEGMENT_2: &str = "00000000000000000002.log";

/// The segment today's writer wrote, before formats.
fn format_1_segment() -> Vec<u8> {
    let fixture = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/journal-format-1")
        .join(SEGMENT_1);
    std::fs::read(fixture).unwrap()
}

fn args(name: &'static str, id: u32, dir: &Path) -> DmArgs {
    DmSpec::new(name, id)
        .args(RealClock::shared())
        .with_journal(dir, Durability::Process)
}

/// Every `.log` file of `dir` and its bytes.
fn segments(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "log"))
        .map(|p| {
            let bytes = std::fs::read(&p).unwrap();
            (p.file_name().unwrap().to_string_lossy().into_owned(), bytes)
        })
        .collect()
}

/// (seq, class, sub1, value) of every record.
async fn records(client: &DmClient) -> Vec<(u64, String, Option<String>, String)> {
    let mut out = Vec::new();
    for r in client.select(Query::all()).await.unwrap() {
        let value = match r.class.as_ref() {
            "c" => r.decode::<u32>().unwrap().to_string(),
            _ => r.decode::<String>().unwrap(),
        };
        out.push((
            r.seq,
            r.class.to_string(),
            r.sub1.as_ref().map(|s| s.to_string()),
            value,
        ));
    }
    out
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_journal_of_the_build_before_formats_is_read_the_same_and_written_on() {
    let tmp = TempDir::new("v1");
    let old = format_1_segment();
    assert!(!old.starts_with(b"MJNL"), "the fixture has no header");
    std::fs::write(tmp.0.join(SEGMENT_1), &old).unwrap();

    let (actor, handle) = dm::spawn_datamanager(args("jf-v1", 4901, &tmp.0))
        .await
        .unwrap();
    let client = DmClient::new(actor.clone(), "tester");
    // six puts of c (0..6 at seqs 1..=6, sub1 front), d at 7, seqs 2 and 3 deleted
    let front = || Some("front".to_string());
    let c = |seq, v: u32| (seq, "c".to_string(), front(), v.to_string());
    let expected = vec![
        c(1, 0),
        c(4, 3),
        c(5, 4),
        c(6, 5),
        (7, "d".to_string(), None, "last".to_string()),
    ];
    assert_eq!(records(&client).await, expected);
    let r = client.stats().await.unwrap().recovery.unwrap();
    assert_eq!((r.records, r.torn.clone()), (5, None), "{r:?}");
    assert_eq!(r.bytes, old.len() as u64, "{r:?}");
    // read, not rewritten
    assert_eq!(segments(&tmp.0)[SEGMENT_1], old);

    // this build writes on, and reads back both
    assert_eq!(client.store("d", None, None, &"new").await.unwrap(), 8);
    actor.stop(None);
    handle.await.unwrap();
    let (actor, handle) = dm::spawn_datamanager(args("jf-v1", 4901, &tmp.0))
        .await
        .unwrap();
    let client = DmClient::new(actor.clone(), "tester");
    let mut more = expected.clone();
    more.push((8, "d".to_string(), None, "new".to_string()));
    assert_eq!(records(&client).await, more);
    assert_eq!(client.stats().await.unwrap().recovery.unwrap().torn, None);
    actor.stop(None);
    handle.await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_new_journal_starts_each_segment_with_its_format() {
    let tmp = TempDir::new("v2");
    let (actor, handle) = dm::spawn_datamanager(args("jf-v2", 4902, &tmp.0))
        .await
        .unwrap();
    let client = DmClient::new(actor.clone(), "tester");
    client.store("c", None, None, &1u32).await.unwrap();
    actor.stop(None);
    handle.await.unwrap();
    let seg = &segments(&tmp.0)[SEGMENT_1];
    assert_eq!(&seg[..4], b"MJNL");
    assert_eq!(seg[4..8], JOURNAL_FORMAT.to_le_bytes());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_journal_of_a_newer_format_is_refused_at_the_start_and_left_untouched() {
    let tmp = TempDir::new("v99");
    // a first segment of the build before formats whose tail is torn (what a replay
    // would cut), and a second of format 99
    let mut first = format_1_segment();
    first.extend_from_slice(&[0x42, 0, 0, 0, 1, 2]);
    std::fs::write(tmp.0.join(SEGMENT_1), &first).unwrap();
    let mut newer = b"MJNL".to_vec();
    newer.extend_from_slice(&99u32.to_le_bytes());
    newer.extend_from_slice(b"entries of a format this build never saw");
    std::fs::write(tmp.0.join(SEGMENT_2), &newer).unwrap();
    let before = segments(&tmp.0);

    let err = dm::spawn_datamanager(args("jf-v99", 4903, &tmp.0))
        .await
        .unwrap_err()
        .to_string();
    for said in [
        "journal format 99".to_string(),
        format!("reads journal formats {OLDEST_JOURNAL_FORMAT}..={JOURNAL_FORMAT}"),
        tmp.0.display().to_string(),
        SEGMENT_2.to_string(),
        "start this datamanager with that build or a newer one".to_string(),
    ] {
        assert!(err.contains(&said), "{said:?} not in {err}");
    }
    assert_eq!(segments(&tmp.0), before, "nothing cut, removed or written");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_segment_whose_header_was_cut_at_its_creation_holds_nothing_and_is_written_over() {
    let tmp = TempDir::new("cut-header");
    std::fs::write(tmp.0.join(SEGMENT_1), format_1_segment()).unwrap();
    // the process died as it created the next segment: six of its eight header bytes
    let mut cut = b"MJNL".to_vec();
    cut.extend_from_slice(&JOURNAL_FORMAT.to_le_bytes()[..2]);
    std::fs::write(tmp.0.join(SEGMENT_2), &cut).unwrap();

    let (actor, handle) = dm::spawn_datamanager(args("jf-cut", 4904, &tmp.0))
        .await
        .unwrap();
    let client = DmClient::new(actor.clone(), "tester");
    assert_eq!(records(&client).await.len(), 5);
    let r = client.stats().await.unwrap().recovery.unwrap();
    assert!(
        r.torn
            .as_deref()
            .unwrap_or("")
            .contains("format header is cut short"),
        "{r:?}"
    );
    assert_eq!(client.store("d", None, None, &"after").await.unwrap(), 8);
    actor.stop(None);
    handle.await.unwrap();
    // the segment starts again with a whole header, and the record after it reads back
    let seg = &segments(&tmp.0)[SEGMENT_2];
    assert_eq!(&seg[..4], b"MJNL");
    assert_eq!(seg[4..8], JOURNAL_FORMAT.to_le_bytes());
    let (actor, handle) = dm::spawn_datamanager(args("jf-cut", 4904, &tmp.0))
        .await
        .unwrap();
    let client = DmClient::new(actor.clone(), "tester");
    assert_eq!(records(&client).await.len(), 6);
    assert_eq!(client.stats().await.unwrap().recovery.unwrap().torn, None);
    actor.stop(None);
    handle.await.unwrap();
}
