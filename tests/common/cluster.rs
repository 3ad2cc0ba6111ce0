//! Real `marie node` (and `marie up`) processes for the cluster tests — on 127.0.0.1, or in
//! network namespaces of the test's own ([`super::netns`]): each killed by its pid when its
//! handle drops (also when a test panics), each line of its stdout awaited as an event,
//! never a sleep.

use std::collections::VecDeque;
use std::io::{BufRead, BufReader};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// With this environment variable set to a directory, each process's log (stderr, at
/// `RUST_LOG=info`) is also written there as `NAME-TESTPID-N.log`; else only its last
/// lines are kept (at the default level: warnings and errors).
pub(crate) const LOGS: &str = "MARIE_TEST_LOGS";

/// Processes logged so far (part of the log files' names).
static LOGGED: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

/// Generous: a loaded 2-core machine may take seconds to start a process.
pub(crate) const EVENT_TIMEOUT: Duration = Duration::from_secs(60);

/// Lines of a child's stderr kept for a failure's message.
const STDERR_TAIL: usize = 40;

/// A running `marie` process whose stdout lines are awaited.
pub(crate) struct Proc {
    /// What it is, for messages.
    pub name: String,
    child: Child,
    /// Each line with the moment it was read.
    lines: Receiver<(Instant, String)>,
    seen: Vec<String>,
    /// When each line of `seen` was read.
    arrived: Vec<Instant>,
    /// The last lines of its stderr: what a panic shows, what [`Proc::wait_stderr`] awaits.
    stderr_tail: Arc<StderrTail>,
    /// The child's temporary directory (its `TMPDIR`), removed with the guard: what a
    /// killed process leaves there — a `marie up`'s nodes' data directory — goes with it.
    /// Declared after `child`: dropped once the child is dead.
    tmp: tempfile::TempDir,
}

/// The last [`STDERR_TAIL`] lines of a child's stderr, and a signal for each new one.
#[derive(Default)]
pub(crate) struct StderrTail {
    lines: Mutex<VecDeque<String>>,
    more: std::sync::Condvar,
}

/// A running `marie node`.
pub(crate) struct NodeProc {
    /// Where it listens.
    pub addr: SocketAddr,
    proc: Proc,
}

impl std::ops::Deref for NodeProc {
    type Target = Proc;
    fn deref(&self) -> &Proc {
        &self.proc
    }
}

impl std::ops::DerefMut for NodeProc {
    fn deref_mut(&mut self) -> &mut Proc {
        &mut self.proc
    }
}

impl NodeProc {
    /// Write `dir/NAME.toml` — `[node]`, then `hosts` (TOML tables), then `[cluster]` with
    /// `peers` and `cookie` — and start `marie node --config` on it.
    pub(crate) fn start(
        dir: &Path,
        name: &str,
        hosts: &str,
        peers: &[SocketAddr],
        cookie: &str,
    ) -> NodeProc {
        NodeProc::start_with(dir, name, hosts, peers, cookie, "", &[])
    }

    /// [`NodeProc::start`] with more `[cluster]` keys (`cluster_extra`, TOML lines) and
    /// more flags.
    pub(crate) fn start_with(
        dir: &Path,
        name: &str,
        hosts: &str,
        peers: &[SocketAddr],
        cookie: &str,
        cluster_extra: &str,
        flags: &[&str],
    ) -> NodeProc {
        // port 0: the node binds a port the OS picks and prints it. A port picked here and
        // released would be free for anyone until the node binds it — another node's
        // outgoing dial may take it first
        let any = SocketAddr::from(([127, 0, 0, 1], 0));
        let path = node_config(dir, name, hosts, any, peers, cookie, cluster_extra);
        let mut args = vec!["node", "--config", path.to_str().expect("utf-8 path")];
        args.extend_from_slice(flags);
        NodeProc::listening(name, Proc::spawn_in(None, name, &args))
    }

    /// [`NodeProc::start`] of another build's `marie`, `exe` (the two-build tests' next
    /// build), with more flags.
    pub(crate) fn start_exe(
        exe: &Path,
        dir: &Path,
        name: &str,
        hosts: &str,
        peers: &[SocketAddr],
        cookie: &str,
        flags: &[&str],
    ) -> NodeProc {
        let any = SocketAddr::from(([127, 0, 0, 1], 0));
        let path = node_config(dir, name, hosts, any, peers, cookie, "");
        let mut args = vec!["node", "--config", path.to_str().expect("utf-8 path")];
        args.extend_from_slice(flags);
        NodeProc::listening(name, Proc::spawn_exe(None, name, exe, &args, &[]))
    }

    /// `proc`, a node `name` started on port 0, once it says where it listens.
    fn listening(name: &str, mut proc: Proc) -> NodeProc {
        let line = proc.wait_line(&format!("node {name} listening on "));
        let addr =
            listening_addr(&line).unwrap_or_else(|| panic!("{name}: no address in `{line}`"));
        NodeProc { addr, proc }
    }

    /// Start `marie ARGS` (a `marie node` listening on `addr`), inside network namespace
    /// `netns` if one is given, and wait until it listens.
    pub(crate) fn launch(
        netns: Option<&str>,
        addr: SocketAddr,
        name: &str,
        args: &[&str],
    ) -> NodeProc {
        NodeProc::launch_with(netns, addr, name, args, &[])
    }

    /// [`NodeProc::launch`] with the environment variables `env` set for the node.
    pub(crate) fn launch_with(
        netns: Option<&str>,
        addr: SocketAddr,
        name: &str,
        args: &[&str],
        env: &[(&str, String)],
    ) -> NodeProc {
        let marie = Path::new(env!("CARGO_BIN_EXE_marie"));
        let proc = Proc::spawn_exe(netns, name, marie, args, env);
        let mut node = NodeProc { addr, proc };
        node.wait_line(&format!("node {name} listening on {addr}"));
        node
    }
}

/// `node NAME listening on ADDR ...` → ADDR.
fn listening_addr(line: &str) -> Option<SocketAddr> {
    let rest = line.split_once(" listening on ")?.1;
    rest.split_whitespace().next()?.parse().ok()
}

/// Write `dir/NAME.toml` — `[node]`, then `hosts` (TOML tables), then `[cluster]` with
/// `listen`, `peers`, `cookie` and `cluster_extra` (TOML lines) — and give its path.
pub(crate) fn node_config(
    dir: &Path,
    name: &str,
    hosts: &str,
    listen: SocketAddr,
    peers: &[SocketAddr],
    cookie: &str,
    cluster_extra: &str,
) -> PathBuf {
    let peers: Vec<String> = peers.iter().map(|p| format!("\"{p}\"")).collect();
    let config = format!(
        "[node]\nname = \"{name}\"\n{hosts}\n[cluster]\nlisten = \"{listen}\"\npeers = [{}]\ncookie = \"{cookie}\"\n{cluster_extra}\n",
        peers.join(", ")
    );
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, config).expect("write node config");
    path
}

impl Proc {
    /// Start `marie ARGS` in the repository's directory, its stdout read line by line.
    pub(crate) fn spawn(name: &str, args: &[&str]) -> Proc {
        Proc::spawn_in(None, name, args)
    }

    /// [`Proc::spawn`] inside network namespace `netns`, if one is given: through
    /// `ip netns exec NS`, which execs `marie` in place, so the child's pid is marie's (what
    /// [`Proc::signal`] and the drop kill). Its stdin is a pipe held until the drop: a
    /// `marie node --stop-with-stdin` stops even when this test process is killed.
    pub(crate) fn spawn_in(netns: Option<&str>, name: &str, args: &[&str]) -> Proc {
        Proc::spawn_exe(
            netns,
            name,
            Path::new(env!("CARGO_BIN_EXE_marie")),
            args,
            &[],
        )
    }

    /// Start program `exe` with `args` and the environment variables `env` (inside network
    /// namespace `netns` if one is given), guarded like `marie`: a test's own binary run
    /// again as a child, for one.
    pub(crate) fn spawn_exe(
        netns: Option<&str>,
        name: &str,
        exe: &Path,
        args: &[&str],
        env: &[(&str, String)],
    ) -> Proc {
        let mut command = match netns {
            Some(ns) => {
                let mut c = Command::new("ip");
                c.args(["netns", "exec", ns]).arg(exe);
                c
            }
            None => Command::new(exe),
        };
        command.envs(env.iter().map(|(k, v)| (k, v)));
        let mut log = match std::env::var_os(LOGS) {
            Some(dir) => {
                command.env("RUST_LOG", "info");
                let n = LOGGED.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                let file = Path::new(&dir).join(format!(
                    "{}-{}-{n}.log",
                    name.replace(' ', "_"),
                    std::process::id()
                ));
                Some(std::fs::File::create(&file).expect("create a log file"))
            }
            None => {
                command.env_remove("RUST_LOG");
                None
            }
        };
        let tmp = tempfile::tempdir().expect("a temporary directory");
        let mut child = command
            .args(args)
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .env("TMPDIR", tmp.path())
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap_or_else(|e| panic!("{} starts: {e}", exe.display()));
        // its stderr's last lines, for a failure's message (a child that ends at once
        // says why there) and for lines awaited; all of them to the log file if there is one
        let stderr_tail = Arc::new(StderrTail::default());
        if let Some(err) = child.stderr.take() {
            let tail = stderr_tail.clone();
            std::thread::spawn(move || {
                use std::io::Write;
                for line in BufReader::new(err).lines().map_while(Result::ok) {
                    if let Some(file) = log.as_mut() {
                        let _ = writeln!(file, "{line}");
                    }
                    let mut lines = tail.lines.lock().unwrap_or_else(|e| e.into_inner());
                    if lines.len() == STDERR_TAIL {
                        lines.pop_front();
                    }
                    lines.push_back(line);
                    tail.more.notify_all();
                }
            });
        }
        let stdout = child.stdout.take().expect("stdout");
        let (tx, lines) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                if tx.send((Instant::now(), line)).is_err() {
                    break;
                }
            }
        });
        Proc {
            name: name.to_string(),
            child,
            lines,
            seen: Vec::new(),
            arrived: Vec::new(),
            stderr_tail,
            tmp,
        }
    }

    /// Its temporary directory (its `TMPDIR`).
    pub(crate) fn tmp(&self) -> &Path {
        self.tmp.path()
    }

    /// Its process id.
    pub(crate) fn pid(&self) -> u32 {
        self.child.id()
    }

    /// Whether it still runs.
    pub(crate) fn alive(&mut self) -> bool {
        matches!(self.child.try_wait(), Ok(None))
    }

    /// The last lines its stderr printed.
    pub(crate) fn stderr_tail(&self) -> String {
        let tail = self
            .stderr_tail
            .lines
            .lock()
            .unwrap_or_else(|e| e.into_inner());
        Vec::from(tail.clone()).join("\n")
    }

    /// Wait for a line of its stderr containing `needle`, among its last lines (those
    /// printed earlier count too, while they are among the last [`STDERR_TAIL`]).
    #[track_caller]
    pub(crate) fn wait_stderr(&self, needle: &str) -> String {
        let deadline = Instant::now() + EVENT_TIMEOUT;
        let mut lines = self
            .stderr_tail
            .lines
            .lock()
            .unwrap_or_else(|e| e.into_inner());
        loop {
            if let Some(line) = lines.iter().find(|l| l.contains(needle)) {
                return line.clone();
            }
            let left = deadline.saturating_duration_since(Instant::now());
            assert!(
                !left.is_zero(),
                "{}: no line with {needle:?} on stderr within {EVENT_TIMEOUT:?}; its last lines:\n{}",
                self.name,
                Vec::from(lines.clone()).join("\n")
            );
            lines = self
                .stderr_tail
                .more
                .wait_timeout(lines, left)
                .unwrap_or_else(|e| e.into_inner())
                .0;
        }
    }

    /// Every line seen so far.
    pub(crate) fn seen(&self) -> &[String] {
        &self.seen
    }

    /// Wait for a stdout line containing `needle` (lines seen earlier count too).
    #[track_caller]
    pub(crate) fn wait_line(&mut self, needle: &str) -> String {
        self.wait_line_since(0, needle)
    }

    /// Wait for a line containing `needle` among the lines from the `mark`-th on (a mark
    /// is `seen().len()` taken earlier).
    #[track_caller]
    pub(crate) fn wait_line_since(&mut self, mark: usize, needle: &str) -> String {
        self.wait_line_timed(mark, needle).0
    }

    /// [`Proc::wait_line_since`], with the moment the line was read (by a thread that
    /// reads every line as it comes, whenever the test waits).
    #[track_caller]
    pub(crate) fn wait_line_timed(&mut self, mark: usize, needle: &str) -> (String, Instant) {
        if let Some(i) = (mark..self.seen.len()).find(|&i| self.seen[i].contains(needle)) {
            return (self.seen[i].clone(), self.arrived[i]);
        }
        let deadline = Instant::now() + EVENT_TIMEOUT;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.lines.recv_timeout(left) {
                Ok((at, line)) => {
                    self.seen.push(line.clone());
                    self.arrived.push(at);
                    if line.contains(needle) {
                        return (line, at);
                    }
                }
                Err(why) => panic!(
                    "{}: no line with {needle:?} {}; saw:\n{}\n(the last lines of its stderr:)\n{}",
                    self.name,
                    match why {
                        RecvTimeoutError::Timeout => format!("within {EVENT_TIMEOUT:?}"),
                        RecvTimeoutError::Disconnected => "before its stdout closed".into(),
                    },
                    self.seen.join("\n"),
                    self.stderr_tail()
                ),
            }
        }
    }

    /// Take in the lines printed so far without waiting; every line seen.
    pub(crate) fn drain(&mut self) -> &[String] {
        while let Ok((at, line)) = self.lines.try_recv() {
            self.seen.push(line);
            self.arrived.push(at);
        }
        &self.seen
    }

    /// The lines read at or after `at`, taking in those printed so far.
    pub(crate) fn lines_since(&mut self, at: Instant) -> Vec<String> {
        self.drain();
        let first = self.arrived.partition_point(|t| *t < at);
        self.seen[first..].to_vec()
    }

    /// Write `line` to the process's standard input.
    pub(crate) fn tell(&mut self, line: &str) {
        use std::io::Write;
        if let Some(stdin) = self.child.stdin.as_mut() {
            let _ = writeln!(stdin, "{line}");
            let _ = stdin.flush();
        }
    }

    /// Send `signal` (e.g. `TERM`, `KILL`, `STOP`) to the process.
    pub(crate) fn signal(&self, signal: &str) {
        signal_pid(self.child.id(), signal);
    }

    /// Send `signal` (`libc::SIGINT`, …) to the process at once, from this process: no
    /// `kill` command is started between the moment the test chose and the signal (a
    /// process start takes milliseconds, longer than some races this aims at).
    pub(crate) fn signal_now(&self, signal: i32) {
        let pid = i32::try_from(self.child.id()).expect("a pid fits in pid_t");
        // SAFETY: kill(2) takes plain integers and touches no memory of this process
        let sent = unsafe { libc::kill(pid, signal) };
        assert_eq!(
            sent,
            0,
            "kill({pid}, {signal}): {}",
            std::io::Error::last_os_error()
        );
    }

    /// Wait for the process to end (at most [`EVENT_TIMEOUT`]); its exit code.
    pub(crate) fn wait_exit(&mut self) -> Option<i32> {
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

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// `... declared beta down: no heartbeat for 1234 ms` → 1234.
pub(crate) fn silence_ms(line: &str) -> u64 {
    line.rsplit_once("for ")
        .and_then(|(_, rest)| rest.split_whitespace().next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no silence in {line:?}"))
}

/// The failure detector's default deadline, in ms (what `marie node` runs with unless its
/// config says otherwise).
pub(crate) fn default_deadline_ms() -> u64 {
    marie::cluster::net::detector::DEFAULT_DEADLINE.as_millis() as u64
}

/// A module `marie ls` lists: (kind, name, node).
pub(crate) type Listed = (String, String, String);

/// `marie ls --join ADDR --cookie C --json` and `extra` flags: the exit code, every listed
/// module sorted, and stderr.
pub(crate) fn ls_join(
    addr: &str,
    cookie: &str,
    extra: &[String],
) -> (Option<i32>, Vec<Listed>, String) {
    let (code, rows, stderr) = ls_join_rows(addr, cookie, extra);
    let mut entries: Vec<Listed> = rows
        .iter()
        .map(|r| {
            let s = |k: &str| r[k].as_str().unwrap_or_default().to_string();
            (s("kind"), s("name"), s("node"))
        })
        .collect();
    entries.sort();
    (code, entries, stderr)
}

/// [`ls_join`]'s rows as `ls --json` gives them (a datamanager's `replica`, one without a
/// leader's `no_majority`).
pub(crate) fn ls_join_rows(
    addr: &str,
    cookie: &str,
    extra: &[String],
) -> (Option<i32>, Vec<serde_json::Value>, String) {
    let mut args = vec!["ls", "--join", addr, "--cookie", cookie, "--json"];
    args.extend(extra.iter().map(String::as_str));
    let out = super::marie(&args);
    let rows = serde_json::from_slice::<serde_json::Value>(&out.stdout)
        .ok()
        .and_then(|v| v.as_array().cloned())
        .unwrap_or_default();
    (out.status.code(), rows, super::text(&out.stderr))
}

/// A node's line as `marie up` lists it at the start — `  cart at 127.0.0.1:4242 (pid 77):
/// EO ultrasonic, ...` → (name, address, pid).
pub(crate) fn node_line(line: &str) -> Option<(String, String, u32)> {
    let (name, rest) = line.trim().split_once(" at ")?;
    let (addr, rest) = rest.split_once(" (pid ")?;
    let pid = rest.split_once(')')?.0.parse().ok()?;
    Some((name.to_string(), addr.to_string(), pid))
}

/// Send `signal` (e.g. `TERM`, `KILL`, `STOP`) to process `pid`.
#[track_caller]
pub(crate) fn signal_pid(pid: u32, signal: &str) {
    let status = Command::new("kill")
        .args([&format!("-{signal}"), &pid.to_string()])
        .status()
        .expect("kill runs");
    assert!(status.success(), "kill -{signal} {pid}");
}

/// A process stopped with `SIGSTOP` (not a child of this one), continued when this drops —
/// also when a test panics: a stopped process never reads the end of its stdin, so it
/// would outlive the test frozen.
pub(crate) struct Stopped(pub u32);

impl Stopped {
    /// Stop process `pid`.
    pub(crate) fn stop(pid: u32) -> Stopped {
        signal_pid(pid, "STOP");
        Stopped(pid)
    }
}

impl Drop for Stopped {
    fn drop(&mut self) {
        let _ = Command::new("kill")
            .args(["-CONT", &self.0.to_string()])
            .status();
    }
}

/// Wait until process `pid` (not a child of this one) has ended: gone from `/proc`, or a
/// zombie waiting for its new parent to reap it. False after [`EVENT_TIMEOUT`].
pub(crate) fn wait_gone(pid: u32) -> bool {
    let deadline = Instant::now() + EVENT_TIMEOUT;
    while Instant::now() < deadline {
        match std::fs::read_to_string(format!("/proc/{pid}/stat")) {
            Err(_) => return true,
            // the state follows the command name in parentheses
            Ok(stat)
                if stat
                    .rsplit_once(") ")
                    .is_some_and(|(_, rest)| rest.starts_with('Z')) =>
            {
                return true
            }
            // polling /proc: a process that is not our child offers no other wait
            Ok(_) => std::thread::sleep(Duration::from_millis(50)),
        }
    }
    false
}

/// A run's report (`--report FILE`) and its events, one per line (`--events FILE`).
pub(crate) fn report_and_events(
    report: &Path,
    events: &Path,
) -> (serde_json::Value, Vec<serde_json::Value>) {
    let report =
        serde_json::from_slice(&std::fs::read(report).expect("the report")).expect("a JSON report");
    let events = std::fs::read_to_string(events)
        .expect("the events file")
        .lines()
        .map(|l| serde_json::from_str(l).expect("a JSON event"))
        .collect();
    (report, events)
}
