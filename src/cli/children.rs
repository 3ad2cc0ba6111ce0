//! The node processes `marie up` starts: each a `marie node` child whose standard input is a
//! pipe it holds. Closing the pipe stops the child cleanly (`--stop-with-stdin`); the pipe
//! also closes when `marie up` dies in any way, even `kill -9`, so no child outlives it.

use marie::cluster::layout::Exit;
use std::io::{BufRead, BufReader};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::time::{Duration, Instant};
use tokio::sync::mpsc;

/// How long a child may take to stop after its pipe closed before it is killed.
const STOP_GRACE: Duration = Duration::from_secs(10);

/// A line a child printed on its standard output.
#[derive(Clone, Debug)]
pub(crate) struct Line {
    /// The child's node name.
    pub node: String,
    /// The line, or `None` once its output ended (it exited).
    pub text: Option<String>,
}

/// How to start one node.
#[derive(Clone, Debug)]
pub(crate) struct NodeLaunch {
    /// Its node name (for messages).
    pub name: String,
    /// Its node config file.
    pub config: PathBuf,
    /// Where it listens.
    pub listen: SocketAddr,
    /// Whom it joins.
    pub peers: Vec<SocketAddr>,
    /// The cluster's cookie.
    pub cookie: String,
    /// The cluster's speed factor.
    pub speed: f64,
    /// The robot's world, for a node with a simulation.
    pub world: Option<PathBuf>,
    /// The simulation's seed.
    pub seed: Option<u64>,
    /// Its data directory (`--data-dir`), unless its config names one.
    pub data_dir: Option<PathBuf>,
    /// The cluster file, when it declares replicated datamanagers (`--cluster`).
    pub cluster_file: Option<PathBuf>,
    /// The network namespace it runs in, in a private network (`super::netns`).
    pub netns: Option<std::sync::Arc<std::fs::File>>,
}

/// A running node process.
pub(crate) struct NodeChild {
    /// Its node name.
    pub name: String,
    child: Child,
    stdin: Option<ChildStdin>,
}

impl NodeChild {
    /// Start `marie node` (this same executable) as `launch` says; its output lines go to
    /// `lines`.
    pub(crate) fn start(
        exe: &Path,
        launch: &NodeLaunch,
        lines: mpsc::UnboundedSender<Line>,
    ) -> std::io::Result<NodeChild> {
        let mut cmd = Command::new(exe);
        cmd.arg("node")
            .arg("--config")
            .arg(&launch.config)
            .arg("--listen")
            .arg(launch.listen.to_string())
            .arg("--cookie")
            .arg(&launch.cookie)
            .arg("--speed")
            .arg(launch.speed.to_string())
            .arg("--stop-with-stdin");
        for p in &launch.peers {
            cmd.arg("--peer").arg(p.to_string());
        }
        if let Some(w) = &launch.world {
            cmd.arg("--world").arg(w);
        }
        if let Some(s) = launch.seed {
            cmd.arg("--seed").arg(s.to_string());
        }
        if let Some(d) = &launch.data_dir {
            cmd.arg("--data-dir").arg(d);
        }
        if let Some(f) = &launch.cluster_file {
            cmd.arg("--cluster").arg(f);
        }
        if let Some(ns) = launch.netns.clone() {
            // SAFETY: between fork and exec the child only calls setns(2), which is
            // async-signal-safe, on a descriptor the parent holds open
            unsafe {
                std::os::unix::process::CommandExt::pre_exec(&mut cmd, move || {
                    super::netns::set_ns(&ns)
                });
            }
        }
        let mut child = cmd
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()?;
        let stdin = child.stdin.take();
        if let Some(out) = child.stdout.take() {
            let node = launch.name.clone();
            std::thread::spawn(move || {
                for text in BufReader::new(out).lines().map_while(Result::ok) {
                    let line = Line {
                        node: node.clone(),
                        text: Some(text),
                    };
                    if lines.send(line).is_err() {
                        return;
                    }
                }
                let _ = lines.send(Line { node, text: None });
            });
        }
        Ok(NodeChild {
            name: launch.name.clone(),
            child,
            stdin,
        })
    }

    /// Its process id.
    pub(crate) fn pid(&self) -> u32 {
        self.child.id()
    }

    /// Ask it to stop (close its pipe); kill it if it has not within the grace period.
    /// How it ended.
    pub(crate) fn stop(&mut self) -> Exit {
        self.go_on();
        self.stdin.take();
        self.wait_until(Instant::now() + STOP_GRACE)
    }

    /// Let it go on if a fault froze it (`SIGCONT`; nothing happens to a running process):
    /// a stopped process would not hear its pipe close.
    fn go_on(&self) {
        if let Ok(pid) = libc::pid_t::try_from(self.child.id()) {
            // SAFETY: a signal to our own child, not yet reaped — so the pid is still its
            // own, even once it exited (a zombie ignores it)
            unsafe { libc::kill(pid, libc::SIGCONT) };
        }
    }

    /// Wait for it to exit until `deadline`, then kill it; how it ended. Polling: a child's
    /// exit has no wait with a deadline in std. For the stop, and for a child whose output
    /// ended (its exit is at hand; one that closed its output but lives on is killed).
    pub(crate) fn wait_until(&mut self, deadline: Instant) -> Exit {
        match exit_by(&mut self.child, deadline) {
            Ok(status) => exit_of(status),
            Err(killed) => {
                tracing::warn!(node = %self.name, "did not end in time: killed");
                killed.map_or(Exit::Signal(libc::SIGKILL), exit_of)
            }
        }
    }
}

/// Wait for `child` to exit until `deadline` (polling: a child's exit has no wait with a
/// deadline in std); `Ok` with its status if it did, else it is killed and reaped: `Err`
/// with the status of that, if any.
pub(crate) fn exit_by(
    child: &mut Child,
    deadline: Instant,
) -> Result<std::process::ExitStatus, Option<std::process::ExitStatus>> {
    loop {
        match child.try_wait() {
            Ok(Some(status)) => return Ok(status),
            Ok(None) if Instant::now() < deadline => std::thread::sleep(Duration::from_millis(20)),
            _ => {
                let _ = child.kill();
                return Err(child.wait().ok());
            }
        }
    }
}

/// How a process ended, as its status says.
fn exit_of(status: std::process::ExitStatus) -> Exit {
    use std::os::unix::process::ExitStatusExt;
    match (status.code(), status.signal()) {
        (Some(code), _) => Exit::Code(code),
        (None, Some(signal)) => Exit::Signal(signal),
        (None, None) => Exit::Code(-1),
    }
}

/// Stop every child: all pipes closed at once, then each awaited (killed after the grace
/// period). Gives each node's name and how it ended.
pub(crate) fn stop_all(children: &mut [NodeChild]) -> Vec<(String, Exit)> {
    for c in children.iter_mut() {
        c.go_on();
        c.stdin.take();
    }
    // one grace for all: they stop side by side
    let deadline = Instant::now() + STOP_GRACE;
    children
        .iter_mut()
        .map(|c| (c.name.clone(), c.wait_until(deadline)))
        .collect()
}

impl Drop for NodeChild {
    fn drop(&mut self) {
        if matches!(self.child.try_wait(), Ok(None)) {
            self.stop();
        }
    }
}

/// What a node prints once it listens: `node NAME listening on ADDR[ (mutual TLS)] with N
/// module(s) ...` — the address it bound (its port, when it was given port 0) and how many
/// modules it hosts itself.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Listening {
    /// The address it bound.
    pub addr: SocketAddr,
    /// The modules it hosts itself.
    pub modules: usize,
}

impl Listening {
    /// The line's address and module count, if it is that line.
    pub(crate) fn parse(line: &str) -> Option<Listening> {
        let rest = line.strip_prefix("node ")?.split_once(" listening on ")?.1;
        let addr = rest.split_whitespace().next()?.parse().ok()?;
        let modules = rest
            .split_once(" with ")?
            .1
            .split_whitespace()
            .next()?
            .parse()
            .ok()?;
        Some(Listening { addr, modules })
    }
}

#[cfg(test)]
mod tests {
    use super::Listening;

    #[test]
    fn a_nodes_listening_line_gives_its_address_and_module_count() {
        let line = "node alpha listening on 127.0.0.1:40211 with 7 module(s) at speed 1; \
                    joining nobody (others join it)";
        assert_eq!(
            Listening::parse(line),
            Some(Listening {
                addr: "127.0.0.1:40211".parse().unwrap(),
                modules: 7
            })
        );
        let tls = "node b listening on 127.0.0.1:1 (mutual TLS) with 0 module(s) at speed 2";
        assert_eq!(Listening::parse(tls).map(|l| l.modules), Some(0));
        assert_eq!(Listening::parse("node alpha sees beta"), None);
    }
}
