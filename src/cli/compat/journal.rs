//! A datamanager's journal as a sample: a `process`-durability datamanager started in this
//! process on a directory of the corpus, a few stores and a delete through its client, then
//! stopped; the sample's file holds the records it kept (`wire::encode` of what a select
//! answers), its journal directory sits beside it. The check starts a datamanager of this
//! build on a copy of that directory — its own replay — and requires the same records.

use super::samples::{Form, Sample};
use marie::clock::RealClock;
use marie::dm::{self, DmArgs, DmClient, DmMsg, DmSpec, Durability, Query, Record};
use ractor::ActorRef;
use std::future::Future;
use std::path::{Path, PathBuf};
use std::time::Duration;
use tokio::task::JoinHandle;

/// The type named in the manifest.
pub(crate) const TYPE: &str = "DmJournal";
/// The variant: the durability its journal was written at.
const VARIANT: &str = "process";
/// How long a start, a request or a stop may take.
const WITHIN: Duration = Duration::from_secs(30);

/// The journal directory of a journal sample's file (`DmJournal.process.msgpack` →
/// `DmJournal.process/`).
pub(crate) fn dir_of(corpus: &Path, file: &str) -> PathBuf {
    corpus.join(file.trim_end_matches(".msgpack"))
}

async fn within<T>(what: &str, fut: impl Future<Output = T>) -> Result<T, String> {
    tokio::time::timeout(WITHIN, fut)
        .await
        .map_err(|_| format!("{what}: no answer within {WITHIN:?}"))
}

fn args(name: &'static str, dir: &Path) -> DmArgs {
    DmSpec::new(name, 9_044)
        .args(RealClock::shared())
        .with_journal(dir, Durability::Process)
        .without_heir()
}

async fn start(args: DmArgs) -> Result<(ActorRef<DmMsg>, JoinHandle<()>), String> {
    within("the datamanager's start", dm::spawn_datamanager(args))
        .await?
        .map_err(|e| format!("the datamanager does not start: {e}"))
}

async fn stop(actor: ActorRef<DmMsg>, handle: JoinHandle<()>) -> Result<(), String> {
    actor.stop(None);
    within("the datamanager's stop", handle)
        .await?
        .map_err(|e| format!("the datamanager's task: {e}"))
}

async fn everything(client: &DmClient) -> Result<Vec<Record>, String> {
    within("a select", client.select(Query::all()))
        .await?
        .map_err(|e| format!("a select: {e}"))
}

/// Write a journal into `corpus` and give its sample.
pub(crate) async fn write(corpus: &Path) -> Result<Sample, String> {
    let mut sample = Sample {
        ty: TYPE,
        variant: VARIANT.into(),
        label: None,
        form: Form::Journal,
        bytes: Vec::new(),
    };
    let dir = dir_of(corpus, &sample.file());
    if dir.exists() {
        std::fs::remove_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    }
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let (actor, handle) = start(args("compat-journal", &dir)).await?;
    let client = DmClient::new(actor.clone(), "wall-follower");
    let stored = async {
        for (class, sub1, n) in [
            ("feature", "corner", 1u32),
            ("feature", "door", 2),
            ("world", "map", 3),
        ] {
            client
                .store(class, Some(sub1), None, &(n, format!("sample {n}")))
                .await
                .map_err(|e| format!("a store: {e}"))?;
        }
        client
            .delete(Query::class("feature").sub1("door"))
            .await
            .map_err(|e| format!("a delete: {e}"))?;
        everything(&client).await
    };
    let kept = within("the stores", stored).await.and_then(|r| r);
    stop(actor, handle).await?;
    // the lock file names the writer's pid: not part of the format, and noise in a corpus
    let _ = std::fs::remove_file(dir.join("LOCK"));
    sample.bytes = marie::wire::encode(&kept?).map_err(|e| e.to_string())?;
    Ok(sample)
}

/// Replay the journal of a sample with this build and compare what it keeps with what the
/// build that wrote it kept. Gives this build's encoding of the records replayed.
pub(crate) async fn replay(corpus: &Path, file: &str, expected: &[u8]) -> Result<Vec<u8>, String> {
    let expected: Vec<Record> =
        marie::wire::decode(expected).map_err(|e| format!("its records do not decode: {e}"))?;
    let tmp = std::env::temp_dir().join(format!("marie-compat-journal-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&tmp);
    copy_dir(&dir_of(corpus, file), &tmp).map_err(|e| format!("its journal: {e}"))?;
    let replayed = async {
        let (actor, handle) = start(args("compat-journal-check", &tmp)).await?;
        let kept = everything(&DmClient::new(actor.clone(), "compat")).await;
        stop(actor, handle).await?;
        kept
    }
    .await;
    let _ = std::fs::remove_dir_all(&tmp);
    let replayed = replayed?;
    // a journal read back by a process whose clock began anew moves its time stamps back
    // (`Store::rebase_times`): what must come back is everything else
    let untimed = |records: &[Record]| -> Vec<Record> {
        records
            .iter()
            .map(|r| Record {
                timestamp: Duration::ZERO,
                ..r.clone()
            })
            .collect()
    };
    let (expected_untimed, replayed_untimed) = (untimed(&expected), untimed(&replayed));
    if let Some((was, now)) = expected_untimed
        .iter()
        .zip(&replayed_untimed)
        .find(|(was, now)| was != now)
    {
        return Err(format!(
            "the journal replays record {} as {now:?}, its writer kept {was:?}",
            was.seq
        ));
    }
    if replayed_untimed != expected_untimed {
        return Err(format!(
            "the journal replays to {} records (seqs {:?}), its writer kept {} (seqs {:?})",
            replayed.len(),
            replayed.iter().map(|r| r.seq).collect::<Vec<_>>(),
            expected.len(),
            expected.iter().map(|r| r.seq).collect::<Vec<_>>()
        ));
    }
    marie::wire::encode(&replayed).map_err(|e| e.to_string())
}

fn copy_dir(from: &Path, to: &Path) -> std::io::Result<()> {
    std::fs::create_dir_all(to)?;
    for entry in std::fs::read_dir(from)? {
        let entry = entry?;
        let target = to.join(entry.file_name());
        if entry.file_type()?.is_dir() {
            copy_dir(&entry.path(), &target)?;
        } else {
            std::fs::copy(entry.path(), target)?;
        }
    }
    Ok(())
}
