//! The journal's promise under `kill -9`: a checker.
//!
//! A child process (this test binary, started again in child mode) runs a datamanager at
//! `process` or `sync` durability with four producers storing numbered records as fast as it
//! acknowledges them, and prints each acknowledgement. The test kills it with `SIGKILL` at
//! a seeded moment, starts the datamanager on the same directory in its own process, and
//! checks what survived against what was acknowledged: every acknowledged record present
//! exactly once with the seq it was acknowledged with, each producer's records in its order,
//! no record that was never put. Five rounds on one directory: each round also recovers the
//! journal the previous kill left.

use marie_dm::{self as dm, DmClient, DmSpec, Durability, Query};
use marie_vocabulary::clock::RealClock;
use std::collections::{BTreeMap, HashMap, HashSet};
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::Duration;

const CHILD_ENV: &str = "MARIE_JOURNAL_KILL_CHILD";
const PRODUCERS: u32 = 4;
const SPEC: DmSpec = DmSpec::new("jk-checked", 4451);

/// The checked DM: no retention bound (a dropped record would count as lost).
fn dm_args(dir: &Path, durability: Durability) -> dm::DmArgs {
    let mut args = SPEC.args(RealClock::shared()).with_journal(dir, durability);
    args.config = args.config.with_default_retention(usize::MAX);
    args
}

/// Not a test of its own: the child's entry. Without the environment variable it does nothing.
#[test]
fn journal_kill_child_entry() {
    let Ok(spec) = std::env::var(CHILD_ENV) else {
        return;
    };
    let (dir, durability, round) = {
        let mut parts = spec.split(';');
        let dir = PathBuf::from(parts.next().unwrap());
        let durability: Durability = parts.next().unwrap().parse().unwrap();
        let round: u32 = parts.next().unwrap().parse().unwrap();
        (dir, durability, round)
    };
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap();
    rt.block_on(async move {
        let args = dm_args(&dir, durability);
        let (actor, _) = dm::spawn_datamanager(args)
            .await
            .expect("child: the DM starts");
        // Each line is written to the pipe before the next step (stdout is line-buffered):
        // a `put` line before the record is sent — so the parent knows every record that
        // may exist — and an `ack` line once it is acknowledged.
        // (libtest's "test … " has no line end of its own)
        println!();
        let mut tasks = Vec::new();
        for p in 0..PRODUCERS {
            let source = format!("r{round}-p{p}");
            let client = DmClient::new(actor.clone(), source.clone());
            tasks.push(tokio::spawn(async move {
                for i in 0u64.. {
                    println!("put {source} {i}");
                    let seq = client
                        .store("count", None, None, &i)
                        .await
                        .expect("child: store");
                    println!("ack {source} {i} {seq}");
                }
            }));
        }
        for t in tasks {
            let _ = t.await;
        }
    });
}

/// Kills the child on drop (also when the test panics).
struct Killed(Child);

impl Drop for Killed {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// A tiny seeded generator (xorshift): the kill moments are the same on every run.
struct Seeded(u64);

impl Seeded {
    fn below(&mut self, n: u64) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0 % n
    }
}

/// What a child said before it died: the records it sent, and those acknowledged (with seqs).
#[derive(Default)]
struct Said {
    put: Vec<(String, u64)>,
    acked: Vec<(String, u64, u64)>,
}

/// Run one child until it has acknowledged `acks` records, then `kill -9` it.
fn run_and_kill(dir: &Path, durability: Durability, round: u32, acks: usize) -> Said {
    let exe = std::env::current_exe().unwrap();
    let child = Command::new(exe)
        .args([
            "--exact",
            "journal_kill_child_entry",
            "--nocapture",
            "--test-threads=1",
        ])
        .env(CHILD_ENV, format!("{};{durability};{round}", dir.display()))
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap();
    let mut child = Killed(child);
    let stdout = child.0.stdout.take().unwrap();
    let (tx, rx) = mpsc::channel();
    let reader = std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines() {
            let Ok(line) = line else { break };
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    let mut said = Said::default();
    let take = |said: &mut Said, line: &str| {
        let mut w = line.split(' ');
        let (kind, source, i) = (w.next(), w.next(), w.next().and_then(|i| i.parse().ok()));
        let (Some(source), Some(i)) = (source, i) else {
            return;
        };
        match (kind, w.next().and_then(|s| s.parse().ok())) {
            (Some("put"), _) => said.put.push((source.to_string(), i)),
            (Some("ack"), Some(seq)) => said.acked.push((source.to_string(), i, seq)),
            _ => {}
        }
    };
    while said.acked.len() < acks {
        let line = rx
            .recv_timeout(Duration::from_secs(60))
            .expect("the child acknowledges records");
        take(&mut said, &line);
    }
    // SIGKILL: no destructor, no flush of anything the DM had not yet written
    child.0.kill().unwrap();
    child.0.wait().unwrap();
    reader.join().unwrap();
    // what it printed before it died counts too
    for line in rx.try_iter() {
        take(&mut said, &line);
    }
    said
}

fn checker(durability: Durability, seed: u64) {
    let dir = std::env::temp_dir().join(format!(
        "marie-journal-kill-{durability}-{}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    let mut rng = Seeded(seed);
    let mut acked: BTreeMap<(String, u64), u64> = BTreeMap::new();
    let mut put: HashSet<(String, u64)> = HashSet::new();
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap();
    println!("round  kill after  acknowledged  survived  lost  duplicated  never put");
    for round in 0..5 {
        let kill_after = 200 + rng.below(3000) as usize;
        let said = run_and_kill(&dir, durability, round, kill_after);
        put.extend(said.put);
        for (source, i, seq) in said.acked {
            acked.insert((source, i), seq);
        }
        // read back in this process
        let stored = rt.block_on(async {
            let args = dm_args(&dir, durability);
            let (actor, handle) = dm::spawn_datamanager(args).await.expect("the DM recovers");
            let client = DmClient::new(actor.clone(), "checker");
            let records = client.select(Query::class("count")).await.unwrap();
            actor.stop(None);
            handle.await.unwrap();
            records
        });
        let mut seen: HashMap<(String, u64), Vec<u64>> = HashMap::new();
        let mut by_source: BTreeMap<String, Vec<(u64, u64)>> = BTreeMap::new();
        for r in &stored {
            let i: u64 = r.decode().unwrap();
            seen.entry((r.source.to_string(), i))
                .or_default()
                .push(r.seq);
            by_source
                .entry(r.source.to_string())
                .or_default()
                .push((r.seq, i));
        }
        let lost = acked
            .iter()
            .filter(|(k, seq)| seen.get(*k).is_none_or(|s| !s.contains(seq)))
            .count();
        let duplicated = seen.values().filter(|s| s.len() > 1).count();
        let never_put: Vec<_> = seen.keys().filter(|k| !put.contains(*k)).collect();
        if !never_put.is_empty() {
            eprintln!("never put: {never_put:?}");
        }
        let never_put = never_put.len();
        println!(
            "{round:>5}  {kill_after:>10}  {:>12}  {:>8}  {lost:>4}  {duplicated:>10}  {never_put:>9}",
            acked.len(),
            stored.len()
        );
        assert_eq!((lost, duplicated, never_put), (0, 0, 0), "round {round}");
        for (source, records) in by_source {
            let in_order = records.windows(2).all(|w| w[0].1 < w[1].1);
            assert!(in_order, "{source}'s records out of its order");
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn kill_9_loses_no_record_acknowledged_at_process_durability() {
    checker(Durability::Process, 0x5eed_0001);
}

#[test]
fn kill_9_loses_no_record_acknowledged_at_sync_durability() {
    checker(Durability::Sync, 0x5eed_0002);
}
