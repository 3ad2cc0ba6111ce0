//! A probe of a running replicated datamanager, for fault tests: it writes numbered records
//! (class [`CLASS`]), one at a time, each acknowledged, and reads the newest of them back
//! over and over — through the datamanager's name, as an application's [`DmClient`] does,
//! and straight from each replica's actor, wherever it runs, so that a leader cut off from
//! the others is asked too. A read that shows an older record than one acknowledged before
//! the read was sent is *stale* ([`stale`]); at the end the newest acknowledged write must
//! be there. What `marie dm probe` and `marie up --probe` run beside a mission while faults
//! strike, and what an application's own fault tests can run beside their workload.
//!
//! Writer and readers share one process and its clock, so "acknowledged before the read
//! was sent" is an ordering this process saw, not an estimate across machines: the
//! writer counts a write acknowledged once its answer came, a reader takes that count
//! before it sends — the check can only err towards missing a stale read, never towards
//! accusing a fresh one.
//!
//! ```no_run
//! # async fn f() -> Result<(), marie_dm::DmError> {
//! use marie_dm::probe::{Probe, ProbeConfig};
//! // on a member of the cluster (its transport started)
//! let probe = Probe::start(ProbeConfig::new("feature")).await?;
//! // … kill, freeze and cut off nodes …
//! let verdict = probe.stop().await;
//! assert!(verdict.holds(), "{verdict}");
//! # Ok(()) }
//! ```

mod verdict;

pub use verdict::{
    stale, LostWrite, ProbeVerdict, ReadBack, RoadTally, StaleRead, Survivors, BY_NAME,
};

use super::client::DmClient;
use super::error::DmError;
use super::majority::replica_nodes;
use super::messages::DmMsg;
use super::query::Query;
use super::record::{NewRecord, Record};
use super::replica::SCOPE;
use ractor::rpc::CallResult;
use ractor::ActorRef;
use std::collections::{BTreeMap, BTreeSet};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::task::JoinHandle;

/// The class of the probe's records (a datamanager's retention keeps the newest of them).
pub const CLASS: &str = "probe";

/// How many stale reads a verdict describes one by one (all are counted).
pub const STALE_KEPT: usize = 20;

/// How a probe paces itself.
#[derive(Clone, Debug)]
pub struct ProbeConfig {
    /// The datamanager's name.
    pub dm: String,
    /// The pause after each acknowledged write.
    pub write_pause: Duration,
    /// The pause after each read, per road.
    pub read_pause: Duration,
    /// How long a read or a write waits for its answer (and a road by name for the next
    /// leader): a read not answered by then is counted unanswered.
    pub patience: Duration,
}

impl ProbeConfig {
    /// The default pace for `dm`: a write every 50 ms, a read per road every 20 ms, 2 s of
    /// patience — light beside a mission's own traffic.
    pub fn new(dm: impl Into<String>) -> ProbeConfig {
        ProbeConfig {
            dm: dm.into(),
            write_pause: Duration::from_millis(50),
            read_pause: Duration::from_millis(20),
            patience: Duration::from_secs(2),
        }
    }
}

/// A probe running (see the module's docs): [`Probe::tally`] while it runs,
/// [`Probe::stop`] for the verdict.
pub struct Probe {
    shared: Arc<Shared>,
    tasks: Vec<JoinHandle<()>>,
    config: ProbeConfig,
    source: String,
}

impl std::fmt::Debug for Probe {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Probe")
            .field("config", &self.config)
            .field("source", &self.source)
            .finish_non_exhaustive()
    }
}

impl Drop for Probe {
    /// A probe dropped without [`Probe::stop`] stops its tasks all the same.
    fn drop(&mut self) {
        self.shared.stop.store(true, Ordering::SeqCst);
    }
}

/// What the probe's tasks share.
struct Shared {
    started: Instant,
    stop: AtomicBool,
    /// The seq each acknowledged write was acknowledged with, by number: as many as were
    /// acknowledged (the newest acknowledged is their count minus 1).
    seqs: Mutex<Vec<u64>>,
    verdict: Mutex<ProbeVerdict>,
}

impl Shared {
    fn stopped(&self) -> bool {
        self.stop.load(Ordering::SeqCst)
    }

    fn tally(&self, f: impl FnOnce(&mut ProbeVerdict)) {
        f(&mut self.verdict.lock().unwrap_or_else(|p| p.into_inner()));
    }

    /// Count a read on `road`, sent when `acked_before` writes had been acknowledged, at
    /// `sent` from the start.
    fn read(&self, road: &str, acked_before: u64, sent: Duration, outcome: Outcome) {
        let acked_seq = acked_before.checked_sub(1).and_then(|n| self.seq_of(n));
        self.tally(|v| {
            let t = v.roads.entry(road.to_string()).or_default();
            match outcome {
                Outcome::Seen(seen) => {
                    t.answered += 1;
                    if stale(acked_before, seen.map(|(n, _)| n)) {
                        t.stale += 1;
                        let read = StaleRead {
                            road: road.to_string(),
                            seen: seen.map(|(n, _)| n),
                            newest_acked: acked_before - 1,
                            at_ms: sent.as_millis() as u64,
                            seen_seq: seen.map(|(_, seq)| seq),
                            acked_seq,
                        };
                        tracing::warn!(dm = %v.dm, "stale read: {read}");
                        if v.stale_reads.len() < STALE_KEPT {
                            v.stale_reads.push(read);
                        }
                    }
                }
                Outcome::Refused => t.refused += 1,
                Outcome::Unanswered => t.unanswered += 1,
                Outcome::Absent => t.absent += 1,
            }
        })
    }
}

impl Shared {
    fn seqs(&self) -> std::sync::MutexGuard<'_, Vec<u64>> {
        self.seqs.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// The next write was acknowledged with `seq`.
    fn acknowledged(&self, seq: u64) {
        self.seqs().push(seq);
    }

    /// How many writes were acknowledged.
    fn acked(&self) -> u64 {
        self.seqs().len() as u64
    }

    /// The seq write `n` was acknowledged with.
    fn seq_of(&self, n: u64) -> Option<u64> {
        self.seqs().get(usize::try_from(n).ok()?).copied()
    }
}

/// How one read ended.
enum Outcome {
    /// Answered: the newest of the probe's records it showed (number, seq).
    Seen(Option<(u64, u64)>),
    Refused,
    Unanswered,
    Absent,
}

impl Probe {
    /// Start probing `config.dm` from this process (a member of the cluster), once its
    /// leader is found (within the patience, else [`DmError::NotRegistered`]).
    pub async fn start(config: ProbeConfig) -> Result<Probe, DmError> {
        let source = format!("probe-{}", std::process::id());
        let client = DmClient::lookup_within(&config.dm, &source, config.patience)
            .await?
            .with_timeout(config.patience)
            .with_follow(config.patience);
        let shared = Arc::new(Shared {
            started: Instant::now(),
            stop: AtomicBool::new(false),
            seqs: Mutex::new(Vec::new()),
            verdict: Mutex::new(ProbeVerdict {
                dm: config.dm.clone(),
                ran_ms: 0,
                writes: 0,
                write_failures: 0,
                roads: BTreeMap::new(),
                stale_reads: Vec::new(),
                read_back: None,
                survivors: None,
            }),
        });
        let tasks = vec![
            tokio::spawn(write(shared.clone(), client.clone(), config.clone())),
            tokio::spawn(read_by_name(
                shared.clone(),
                DmClient::lookup(&config.dm, &source)?
                    .with_timeout(config.patience)
                    .with_follow(config.patience),
                config.clone(),
                source.clone(),
            )),
            tokio::spawn(read_replicas(
                shared.clone(),
                config.clone(),
                source.clone(),
            )),
        ];
        Ok(Probe {
            shared,
            tasks,
            config,
            source,
        })
    }

    /// What it saw so far (no read back yet).
    pub fn tally(&self) -> ProbeVerdict {
        let mut v = self
            .shared
            .verdict
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .clone();
        v.ran_ms = self.shared.started.elapsed().as_millis() as u64;
        v
    }

    /// Stop writing and reading (each task ends after its request in flight, within the
    /// patience), look for the newest acknowledged write by name, and say everything.
    pub async fn stop(mut self) -> ProbeVerdict {
        self.shared.stop.store(true, Ordering::SeqCst);
        for task in std::mem::take(&mut self.tasks) {
            let _ = task.await;
        }
        let mut verdict = self.tally();
        let (read_back, survivors) = read_back(&self.shared, &self.config, &self.source).await;
        verdict.read_back = Some(read_back);
        verdict.survivors = survivors;
        verdict
    }
}

/// The newest of the probe's records in `records` (their payload is its number), with its
/// seq.
fn newest(records: &[Record]) -> Option<(u64, u64)> {
    records
        .iter()
        .filter_map(|r| r.decode::<u64>().ok().map(|n| (n, r.seq)))
        .max()
}

/// Every acknowledged write (`acked`: the seq of write 0, 1, …) against the probe's
/// records the datamanager holds: those not older than the oldest held must be held under
/// the seq they were acknowledged with.
pub fn survivors(acked: &[u64], held: &[Record]) -> Survivors {
    // a number may be held twice (a retry stored again): each seq it is held under
    let mut found: BTreeMap<u64, BTreeSet<u64>> = BTreeMap::new();
    for (n, seq) in held
        .iter()
        .filter_map(|r| r.decode::<u64>().ok().map(|n| (n, r.seq)))
    {
        found.entry(n).or_default().insert(seq);
    }
    let oldest = found.keys().next().copied().unwrap_or(0);
    let mut s = Survivors::default();
    for (n, &seq) in acked.iter().enumerate().skip(oldest as usize) {
        let n = n as u64;
        s.looked_for += 1;
        let at = found.get(&n);
        if !at.is_some_and(|seqs| seqs.contains(&seq)) {
            s.lost += 1;
            if s.missing.len() < STALE_KEPT {
                s.missing.push(LostWrite {
                    number: n,
                    acked_seq: seq,
                    found_seq: at.and_then(|seqs| seqs.first().copied()),
                });
            }
        }
    }
    s
}

/// The query of the probe's newest record.
fn newest_query(source: &str) -> Query {
    Query::class(CLASS).source(source).newest(1)
}

/// Write records 0, 1, 2, … one at a time; each tried again until acknowledged (with the
/// same producer number: stored once) or the probe stops.
async fn write(shared: Arc<Shared>, client: DmClient, config: ProbeConfig) {
    let producer = client.producer();
    let mut n = 0u64;
    while !shared.stopped() {
        let record = match NewRecord::encode(CLASS, &n) {
            Ok(mut r) => {
                r.source = client.source().to_string();
                r.producer = producer;
                r.producer_seq = n + 1;
                r
            }
            Err(e) => {
                tracing::error!("the probe cannot encode its record: {e}");
                return;
            }
        };
        match client.store_raw(record).await {
            Ok(seq) => {
                shared.acknowledged(seq);
                n += 1;
                shared.tally(|v| v.writes = n);
                tokio::time::sleep(config.write_pause).await;
            }
            Err(e) => {
                tracing::debug!(dm = %config.dm, "a probe write failed, tried again: {e}");
                shared.tally(|v| v.write_failures += 1);
                tokio::time::sleep(Duration::from_millis(50)).await;
            }
        }
    }
}

/// Read the newest record through the datamanager's name, following it to its leader.
async fn read_by_name(shared: Arc<Shared>, client: DmClient, config: ProbeConfig, source: String) {
    while !shared.stopped() {
        let acked_before = shared.acked();
        let sent = shared.started.elapsed();
        let outcome = match client.select(newest_query(&source)).await {
            Ok(records) => Outcome::Seen(newest(&records)),
            Err(DmError::Timeout { .. }) => Outcome::Unanswered,
            Err(_) => Outcome::Refused,
        };
        shared.read(BY_NAME, acked_before, sent, outcome);
        tokio::time::sleep(config.read_pause).await;
    }
}

/// Read from every replica of the datamanager: a reader per replica's node, started as
/// its node is first found (a replica added while the probe runs is read too).
async fn read_replicas(shared: Arc<Shared>, config: ProbeConfig, source: String) {
    let mut readers: Vec<JoinHandle<()>> = Vec::new();
    let mut known = BTreeSet::new();
    while !shared.stopped() {
        for node in replica_nodes(&config.dm) {
            if known.insert(node.clone()) {
                readers.push(tokio::spawn(read_replica(
                    shared.clone(),
                    config.clone(),
                    source.clone(),
                    node,
                )));
            }
        }
        tokio::time::sleep(Duration::from_millis(500)).await;
    }
    for r in readers {
        let _ = r.await;
    }
}

/// Read the newest record from the replica on `node`, whichever actor it is now: a
/// follower sends the read on to the leader it knows, a leader answers it only when no
/// other can have acknowledged anything newer.
async fn read_replica(shared: Arc<Shared>, config: ProbeConfig, source: String, node: String) {
    let group = format!("{}/{node}", config.dm);
    let scope = SCOPE.to_string();
    while !shared.stopped() {
        let Some(cell) = ractor::pg::get_scoped_members(&scope, &group)
            .into_iter()
            .next()
        else {
            shared.read(&node, 0, shared.started.elapsed(), Outcome::Absent);
            tokio::time::sleep(config.read_pause * 10).await;
            continue;
        };
        let actor: ActorRef<DmMsg> = cell.into();
        let acked_before = shared.acked();
        let sent = shared.started.elapsed();
        let answer = actor
            .call(
                |reply| DmMsg::Select {
                    query: Box::new(newest_query(&source)),
                    reply,
                },
                Some(config.patience),
            )
            .await;
        let outcome = match answer {
            Ok(CallResult::Success(records)) => Outcome::Seen(newest(&records)),
            Ok(CallResult::Timeout) => Outcome::Unanswered,
            Ok(CallResult::SenderError) | Err(_) => Outcome::Refused,
        };
        shared.read(&node, acked_before, sent, outcome);
        tokio::time::sleep(config.read_pause).await;
    }
}

/// Look for the newest acknowledged write by name (a few tries, each following the
/// datamanager to its leader: a fault may have struck just before the stop), and then for
/// every acknowledged write the datamanager still keeps ([`survivors`]).
async fn read_back(
    shared: &Shared,
    config: &ProbeConfig,
    source: &str,
) -> (ReadBack, Option<Survivors>) {
    let acked = shared.acked();
    if acked == 0 {
        return (ReadBack::NothingWritten, None);
    }
    let client = match DmClient::lookup_within(&config.dm, source, config.patience * 5).await {
        Ok(c) => c
            .with_timeout(config.patience)
            .with_follow(config.patience * 5),
        Err(e) => {
            let error = e.to_string();
            return (ReadBack::Unreachable { error }, None);
        }
    };
    let mut last = String::new();
    for _ in 0..3 {
        match client.select(newest_query(source)).await {
            Ok(records) => {
                let seen = newest(&records).map(|(n, _)| n);
                let back = match stale(acked, seen) {
                    false => ReadBack::Found,
                    true => ReadBack::Missing {
                        newest_acked: acked - 1,
                        seen,
                    },
                };
                let all = Query::class(CLASS).source(source);
                let seqs = shared.seqs().clone();
                let kept = match client.select(all).await {
                    Ok(held) => Some(survivors(&seqs, &held)),
                    Err(e) => {
                        tracing::warn!(dm = %config.dm, "the probe's records could not be read back: {e}");
                        None
                    }
                };
                return (back, kept);
            }
            Err(e) => last = e.to_string(),
        }
    }
    (ReadBack::Unreachable { error: last }, None)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::Payload;

    fn held(n: u64, seq: u64) -> Record {
        Record {
            seq,
            timestamp: Duration::ZERO,
            source: "probe-1".into(),
            class: CLASS.into(),
            sub1: None,
            sub2: None,
            payload: Payload::encode(&n).unwrap(),
        }
    }

    #[test]
    fn an_acknowledged_write_still_kept_must_be_held_under_its_seq() {
        // writes 0..=5 acknowledged as seqs 10..=15; retention dropped 0 and 1
        let acked: Vec<u64> = (10..=15).collect();
        let all = [held(2, 12), held(3, 13), held(4, 14), held(5, 15)];
        let s = survivors(&acked, &all);
        assert_eq!((s.looked_for, s.lost), (4, 0));
        // write 4 gone, write 3 held under another seq (a copy stored again)
        let s = survivors(&acked, &[held(2, 12), held(3, 17), held(5, 15)]);
        assert_eq!((s.looked_for, s.lost), (4, 2));
        assert_eq!(
            s.missing,
            vec![
                LostWrite {
                    number: 3,
                    acked_seq: 13,
                    found_seq: Some(17)
                },
                LostWrite {
                    number: 4,
                    acked_seq: 14,
                    found_seq: None
                },
            ]
        );
        // a copy stored twice: held under its seq, so not lost
        let twice = [
            held(2, 12),
            held(3, 13),
            held(3, 17),
            held(4, 14),
            held(5, 15),
        ];
        assert_eq!(survivors(&acked, &twice).lost, 0);
        // nothing held: every acknowledged write is looked for, and lost
        assert_eq!(survivors(&acked, &[]).lost, 6);
    }
}
