//! Two real processes of `failover-app` on 127.0.0.1, built with `Node::builder` alone: B
//! hosts the pump, A the dispatcher and a pump on standby. A's mission runs on B's pump;
//! B is killed with `SIGKILL` mid-mission, and the mission fails over to a pump A starts
//! from its own factory — and succeeds, with the rebind in its report.
//!
//! Every wait is for a line the processes print (no sleeps); every child is killed by its
//! pid when its handle drops, also when the test panics.

use std::io::{BufRead, BufReader};
use std::net::SocketAddr;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::{self, Receiver};
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
        if let Some(line) = self.seen.iter().find(|l| l.contains(needle)) {
            return line.clone();
        }
        let deadline = Instant::now() + EVENT_TIMEOUT;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.lines.recv_timeout(left) {
                Ok(line) => {
                    self.seen.push(line.clone());
                    if line.contains(needle) {
                        return line;
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

#[test]
fn a_mission_fails_over_to_the_other_process_when_its_pumps_process_is_killed() {
    // B: the pump, on a slow station (50 l at 0.1 l per 100 ms step: 50 s, far longer than
    // the test needs to kill it), port 0 — no port is picked here and released
    let mut b = App::spawn("b", &["--name", "b", "--rate", "0.1"]);
    let b_addr = b.listening();
    // A: the dispatcher and a standby pump on a fast station (50 l in 5 steps)
    let peer = b_addr.to_string();
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
        ],
    );
    a.listening();
    a.wait_line("pump found on node b");
    a.wait_line("pump runs on node b");

    // B's process dies mid-mission
    b.child.kill().expect("SIGKILL b");
    b.child.wait().expect("b reaped");

    a.wait_line("pump lost");
    let rebound = a.wait_line("pump rebound from node b to node a");
    let outcome = a.wait_line("outcome:");
    assert_eq!(outcome, "outcome: succeeded", "{:#?}", a.seen);
    // the report has the rebind, from B's node to A's
    a.wait_line("rebind: pump from b to a");
    assert_eq!(a.wait_exit(), Some(0), "{rebound}; {:#?}", a.seen);
}
