//! Three real processes of `failover-app` on 127.0.0.1, built with `Node::builder` alone: B
//! hosts the pump, A the dispatcher and a pump on standby, C a pump on standby; each keeps
//! a replica of the application's own datamanager, the pump log (`pump-log`, B its
//! preferred leader), in a data directory of its own. A's mission runs on B's pump, which
//! stores each step in the log; once A says B holds the log's leader, B is killed with
//! `SIGKILL` mid-mission. The mission fails over to a pump A starts from its own factory —
//! and succeeds, with the rebind in its report — and the log's leader to A's or C's
//! replica, which A's client follows: every step B's or A's pump was told was stored is in
//! the log at the seq it was told, once.
//!
//! Every wait is for a line the processes print (no sleeps); every child is killed by its
//! pid when its handle drops, also when the test panics.

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader};
use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

/// Generous: a loaded 2-core machine may take seconds to start a process, and the failover
/// waits out the 1 s provisioning grace.
const EVENT_TIMEOUT: Duration = Duration::from_secs(120);

/// A running `failover-app`, its stdout read line by line; killed when dropped.
struct App {
    name: String,
    child: Child,
    lines: Receiver<String>,
    seen: Vec<String>,
}

impl App {
    /// Start `failover-app ARGS`; its stdin is a pipe held until the drop (a host without
    /// `--run` leaves when it closes, so none outlives this test even if it is killed).
    fn spawn(name: &str, args: &[&str]) -> App {
        let mut child = Command::new(env!("CARGO_BIN_EXE_failover-app"))
            .args(args)
            .env_remove("RUST_LOG")
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("failover-app starts");
        let stdout = child.stdout.take().expect("stdout");
        let (tx, lines) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        App {
            name: name.to_string(),
            child,
            lines,
            seen: Vec::new(),
        }
    }

    /// Wait for a line containing `needle` (lines seen earlier count too).
    #[track_caller]
    fn wait_line(&mut self, needle: &str) -> String {
        self.wait_line_from(0, needle, |_| true).1
    }

    /// Wait for a line containing `needle` that `also` accepts, among the lines from the
    /// `from`th seen on: its index and the line.
    #[track_caller]
    fn wait_line_from(
        &mut self,
        from: usize,
        needle: &str,
        also: impl Fn(&str) -> bool,
    ) -> (usize, String) {
        let fits = |l: &str| l.contains(needle) && also(l);
        if let Some(i) = (from..self.seen.len()).find(|&i| fits(&self.seen[i])) {
            return (i, self.seen[i].clone());
        }
        let deadline = Instant::now() + EVENT_TIMEOUT;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.lines.recv_timeout(left) {
                Ok(line) => {
                    self.seen.push(line.clone());
                    if fits(&line) {
                        return (self.seen.len() - 1, line);
                    }
                }
                Err(_) => panic!(
                    "{}: no line with {needle:?} within {EVENT_TIMEOUT:?}; saw:\n{}",
                    self.name,
                    self.seen.join("\n")
                ),
            }
        }
    }

    /// Every line it printed, once its standard output closed (it was killed or exited).
    #[track_caller]
    fn all_lines(&mut self) -> Vec<String> {
        let deadline = Instant::now() + EVENT_TIMEOUT;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.lines.recv_timeout(left) {
                Ok(line) => self.seen.push(line),
                Err(RecvTimeoutError::Disconnected) => return self.seen.clone(),
                Err(RecvTimeoutError::Timeout) => {
                    panic!("{}: its output did not close", self.name)
                }
            }
        }
    }

    /// The address of its `node NAME listening on ADDR` line.
    #[track_caller]
    fn listening(&mut self) -> SocketAddr {
        let line = self.wait_line(" listening on ");
        line.rsplit(' ')
            .next()
            .and_then(|a| a.parse().ok())
            .unwrap_or_else(|| panic!("{}: no address in {line:?}", self.name))
    }

    /// Wait for it to exit (at most [`EVENT_TIMEOUT`]): its exit code.
    fn wait_exit(&mut self) -> Option<i32> {
        let deadline = Instant::now() + EVENT_TIMEOUT;
        loop {
            if let Some(status) = self.child.try_wait().expect("try_wait") {
                return status.code();
            }
            assert!(Instant::now() < deadline, "{} did not exit", self.name);
            // polling a child's exit: the only wait std offers with a deadline
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

impl Drop for App {
    fn drop(&mut self) {
        // SIGKILL by pid (std's `kill`), then reap it
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The processes' data directories, removed when dropped.
struct DataDirs(PathBuf);

impl DataDirs {
    fn new() -> DataDirs {
        let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
            .join(format!("failover-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        DataDirs(dir)
    }

    fn of(&self, node: &str) -> String {
        self.0.join(node).display().to_string()
    }
}

impl Drop for DataDirs {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// The pump log's replicas, B the preferred leader.
const REPLICAS: &str = "b,a,c";

/// The steps a process printed as stored: `STATION#STEP` → seq.
fn stored(lines: &[String]) -> BTreeMap<String, u64> {
    lines
        .iter()
        .filter_map(|l| l.strip_prefix("pump-log: "))
        .map(|l| {
            let (label, seq) = l.split_once(" stored as seq ").expect("a stored line");
            (label.to_string(), seq.parse().expect("a seq"))
        })
        .collect()
}

#[test]
fn a_mission_and_the_pump_log_fail_over_when_the_pumps_and_log_leaders_process_is_killed() {
    let dirs = DataDirs::new();
    // B: the pump, on a slow station (50 l at 0.1 l per 100 ms step: 50 s, far longer than
    // the test needs to kill it), port 0 — no port is picked here and released
    let (b_dir, a_dir, c_dir) = (dirs.of("b"), dirs.of("a"), dirs.of("c"));
    let mut b = App::spawn(
        "b",
        &[
            "--name",
            "b",
            "--rate",
            "0.1",
            "--data-dir",
            &b_dir,
            "--replicas",
            REPLICAS,
        ],
    );
    let peer = b.listening().to_string();
    // C: a replica of the log, and a standby pump
    let mut c = App::spawn(
        "c",
        &[
            "--name",
            "c",
            "--peer",
            &peer,
            "--standby",
            "--data-dir",
            &c_dir,
            "--replicas",
            REPLICAS,
        ],
    );
    c.listening();
    // A: the dispatcher, a replica, and a standby pump on a fast station (50 l in 5 steps)
    let mut a = App::spawn(
        "a",
        &[
            "--name",
            "a",
            "--peer",
            &peer,
            "--standby",
            "--rate",
            "10",
            "--run",
            "50",
            "--data-dir",
            &a_dir,
            "--replicas",
            REPLICAS,
        ],
    );
    a.listening();
    a.wait_line("pump found on node b");
    a.wait_line("pump runs on node b");
    // B holds the log's leader (its preferred node: another replica elected first hands the
    // role to B once B caught up), and its pump logged a few steps there
    let (told, _) = a.wait_line_from(0, "pump-log leader: b", |l| l.ends_with(": b"));
    b.wait_line("pump-log: b#3 stored as seq");

    // B's process dies mid-mission, with the log's leader
    b.child.kill().expect("SIGKILL b");
    b.child.wait().expect("b reaped");
    let b_stored = stored(&b.all_lines());
    assert!(b_stored.len() >= 3, "{b_stored:?}");

    a.wait_line("pump lost");
    // A's client asks the new leader, on A's or C's replica
    let (_, leader) = a.wait_line_from(told + 1, "pump-log leader: ", |l| !l.ends_with(": b"));
    assert!(
        ["pump-log leader: a", "pump-log leader: c"].contains(&leader.as_str()),
        "{leader}"
    );
    let rebound = a.wait_line("pump rebound from node b to node a");
    let outcome = a.wait_line("outcome:");
    assert_eq!(outcome, "outcome: succeeded", "{:#?}", a.seen);
    // the report has the rebind, from B's node to A's
    a.wait_line("rebind: pump from b to a");
    // the run's own check of the log: nothing it heard acknowledged is lost
    let check = a.wait_line("pump-log check: ");
    assert!(check.ends_with(", 0 lost"), "{check}");
    let holds = a.wait_line("pump-log holds ");
    assert_eq!(a.wait_exit(), Some(0), "{rebound}; {:#?}", a.seen);

    // every step B's and A's pumps were told was stored is held at its seq, once
    let a_stored = stored(&a.seen);
    assert!(
        !a_stored.is_empty(),
        "A's pump logged nothing: {:#?}",
        a.seen
    );
    let listed: Vec<(String, u64)> = holds
        .split_once(" records: ")
        .expect("a list")
        .1
        .split(' ')
        .map(|e| {
            let (label, seq) = e.split_once('=').expect("STEP=SEQ");
            (label.to_string(), seq.parse().expect("a seq"))
        })
        .collect();
    let held: BTreeMap<String, u64> = listed.iter().cloned().collect();
    assert_eq!(held.len(), listed.len(), "a step held twice: {holds}");
    for (label, seq) in b_stored.iter().chain(&a_stored) {
        assert_eq!(
            held.get(label),
            Some(seq),
            "{label} (seq {seq}) lost: {holds}"
        );
    }
    // the seqs went on past B's under the new leader
    let b_last = b_stored.values().max().copied().unwrap_or(0);
    assert!(
        a_stored.values().all(|&s| s > b_last),
        "{a_stored:?} after {b_last}"
    );
    drop(c);
}
