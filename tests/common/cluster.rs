//! Real `marie node` processes on 127.0.0.1 for the cluster tests: each killed by its pid
//! when its handle drops (also when a test panics), each line of its stdout awaited as an
//! event, never a sleep.

use std::io::{BufRead, BufReader};
use std::net::{SocketAddr, TcpListener};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::{self, Receiver};
use std::time::{Duration, Instant};

/// Generous: a loaded 2-core machine may take seconds to start a process.
pub const EVENT_TIMEOUT: Duration = Duration::from_secs(60);

/// A free port on 127.0.0.1 (the OS picks it; it is free again when this returns).
pub fn free_addr() -> SocketAddr {
    TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .expect("a free port")
}

/// A running `marie node`.
pub struct NodeProc {
    /// Its node name.
    pub name: String,
    /// Where it listens.
    pub addr: SocketAddr,
    child: Child,
    lines: Receiver<String>,
    seen: Vec<String>,
}

impl NodeProc {
    /// Write `dir/NAME.toml` — `[node]`, then `hosts` (TOML tables), then `[cluster]` with
    /// `peers` and `cookie` — and start `marie node --config` on it.
    pub fn start(
        dir: &Path,
        name: &str,
        hosts: &str,
        peers: &[SocketAddr],
        cookie: &str,
    ) -> NodeProc {
        let addr = free_addr();
        let peers: Vec<String> = peers.iter().map(|p| format!("\"{p}\"")).collect();
        let config = format!(
            "[node]\nname = \"{name}\"\n{hosts}\n[cluster]\nlisten = \"{addr}\"\npeers = [{}]\ncookie = \"{cookie}\"\n",
            peers.join(", ")
        );
        let path = dir.join(format!("{name}.toml"));
        std::fs::write(&path, config).expect("write node config");
        let mut child = Command::new(env!("CARGO_BIN_EXE_marie"))
            .args(["node", "--config", path.to_str().expect("utf-8 path")])
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .env_remove("RUST_LOG")
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("marie node starts");
        let stdout = child.stdout.take().expect("stdout");
        let (tx, lines) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        let mut node = NodeProc {
            name: name.to_string(),
            addr,
            child,
            lines,
            seen: Vec::new(),
        };
        node.wait_line(&format!("node {name} listening on {addr}"));
        node
    }

    /// Wait for a stdout line containing `needle` (lines seen earlier count too).
    #[track_caller]
    pub fn wait_line(&mut self, needle: &str) -> String {
        if let Some(l) = self.seen.iter().find(|l| l.contains(needle)) {
            return l.clone();
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
                    "node {}: no line with {needle:?} within {EVENT_TIMEOUT:?}; saw:\n{}",
                    self.name,
                    self.seen.join("\n")
                ),
            }
        }
    }

    /// Send `signal` (e.g. `TERM`, `KILL`, `STOP`) to the process.
    pub fn signal(&self, signal: &str) {
        let status = Command::new("kill")
            .args([&format!("-{signal}"), &self.child.id().to_string()])
            .status()
            .expect("kill runs");
        assert!(status.success(), "kill -{signal} {}", self.child.id());
    }

    /// Wait for the process to end (at most [`EVENT_TIMEOUT`]); its exit code.
    pub fn wait_exit(&mut self) -> Option<i32> {
        let deadline = Instant::now() + EVENT_TIMEOUT;
        loop {
            if let Some(status) = self.child.try_wait().expect("try_wait") {
                return status.code();
            }
            assert!(Instant::now() < deadline, "node {} did not exit", self.name);
            // polling a child's exit: the only wait std offers with a deadline
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

impl Drop for NodeProc {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
