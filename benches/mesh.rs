//! What a full mesh of nodes costs as it grows (issue 23, point 6): `marie up` of a cluster
//! file of N nodes (processes on 127.0.0.1) hosting 2000 operation instances between them,
//! at N = 4, 8 and 16:
//!
//! - **convergence**: the time from the last node listening until `marie up`'s own member
//!   sees all 2000 modules in its registry (as `marie up` prints it). Goal at 16 nodes:
//!   ≤ 2 s.
//! - **idle cost**: each node's CPU (user + system, from `/proc/PID/stat`) over 10 s of an
//!   idle cluster — heartbeats, the failure detector, sessions — as a share of one core;
//!   median and max over the nodes. Goal at 16 nodes: ≤ 2 % of a core.
//! - **loss**: a node is frozen (`SIGSTOP`) at a random moment of the heartbeats' rhythm;
//!   the time until each other node has printed that it declared it down, as `marie up`
//!   forwards the lines. Goal: the slowest peer within the default deadline (1.2 s) +
//!   300 ms. Three nodes are frozen in turn, each let go on (`SIGCONT`) and seen again by
//!   every peer before the next.
//!
//! ```text
//! cargo bench --bench mesh             # 4, 8 and 16 nodes, about two minutes
//! cargo bench --bench mesh -- 16       # one size
//! ```
//!
//! A plain bench binary (not criterion): a cluster's start and a node's loss cannot be
//! repeated in a tight loop. `marie up` is this package's binary (built with the bench's
//! profile); it stops its nodes when it exits, also when this bench is killed (its
//! children stop when its pipe closes), and a `Drop` guard kills it by its pid.

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// Operation instances of the whole cluster.
const INSTANCES: usize = 2000;
/// The operations each node hosts, in equal numbers.
const OPERATIONS: [&str; 5] = [
    "sampler",
    "averager",
    "checker",
    "segment-extractor",
    "wall-sensor",
];
/// The failure detector's default deadline (`marie_cluster::net::DEFAULT_DEADLINE`).
const DEADLINE: Duration = Duration::from_millis(1200);
/// How long a start may take.
const START: Duration = Duration::from_secs(180);

/// `marie up`, killed by its pid when dropped.
struct Up {
    child: Child,
    lines: mpsc::Receiver<(Instant, String)>,
}

impl Drop for Up {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Up {
    fn start(file: &Path) -> Up {
        let mut child = Command::new(env!("CARGO_BIN_EXE_marie"))
            .args(["up", file.to_str().expect("a UTF-8 path")])
            // its errors only: a frozen node's peers warn of it, as they should
            .env("RUST_LOG", "error")
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("marie up starts");
        let out = child.stdout.take().expect("piped");
        let (tx, lines) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(out).lines().map_while(Result::ok) {
                if tx.send((Instant::now(), line)).is_err() {
                    return;
                }
            }
        });
        Up { child, lines }
    }

    /// The next line that contains `what`, and when it came.
    fn wait_line(&self, what: &str, within: Duration) -> (Instant, String) {
        let deadline = Instant::now() + within;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.lines.recv_timeout(left) {
                Ok((at, line)) if line.contains(what) => return (at, line),
                Ok(_) => {}
                Err(mpsc::RecvTimeoutError::Timeout) => {
                    panic!("no line with `{what}` within {within:?}")
                }
                Err(mpsc::RecvTimeoutError::Disconnected) => {
                    panic!("marie up ended before a line with `{what}` (its errors are above)")
                }
            }
        }
    }
}

/// Write a cluster file of `n` nodes sharing [`INSTANCES`] operation instances.
fn cluster_file(dir: &Path, n: usize) -> std::path::PathBuf {
    let per_op = INSTANCES / n / OPERATIONS.len();
    assert_eq!(per_op * OPERATIONS.len() * n, INSTANCES, "{n} nodes");
    let mut cluster = String::from("[cluster]\ncookie = \"mesh\"\n");
    for i in 0..n {
        let name = format!("n{i:02}");
        let mut config = format!("[node]\nname = \"{name}\"\ndispatcher = false\n");
        for op in OPERATIONS {
            // a config entry starts at most 64 instances: as many entries as it takes
            let mut left = per_op;
            while left > 0 {
                let these = left.min(64);
                config += &format!("[[operation]]\nname = \"{op}\"\ninstances = {these}\n");
                left -= these;
            }
        }
        std::fs::write(dir.join(format!("{name}.toml")), config).expect("write a config");
        cluster += &format!("[[node]]\nconfig = \"{name}.toml\"\n");
    }
    let file = dir.join("mesh.toml");
    std::fs::write(&file, cluster).expect("write the cluster file");
    file
}

/// CPU ticks (user + system) of process `pid` so far.
fn cpu_ticks(pid: u32) -> u64 {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).unwrap_or_default();
    let fields: Vec<&str> = stat
        .rsplit(')')
        .next()
        .unwrap_or_default()
        .split_whitespace()
        .collect();
    // after the command: state is field 3, utime 14 and stime 15 (1-based)
    let at = |i: usize| {
        fields
            .get(i - 3)
            .and_then(|f| f.parse::<u64>().ok())
            .unwrap_or(0)
    };
    at(14) + at(15)
}

fn signal(pid: u32, sig: libc::c_int) {
    // SAFETY: a signal to a node process of the `marie up` this bench started
    unsafe { libc::kill(pid as libc::pid_t, sig) };
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// One cluster of `n` nodes: its figures, printed.
fn measure(n: usize, seed: &mut u64) {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let file = cluster_file(dir.path(), n);
    let up = Up::start(&file);
    let (_, line) = up.wait_line("registry converged", START);
    // `cluster F up: 16 nodes, 2000 modules, speed 1 (registry converged 0.84 s after ...`
    let converged: f64 = line
        .split("registry converged ")
        .nth(1)
        .and_then(|r| r.split(' ').next())
        .and_then(|s| s.parse().ok())
        .expect("the convergence time");
    // `  n03 at 127.0.0.1:4242 (pid 77): EO sampler, ...`
    let mut pids = BTreeMap::new();
    while pids.len() < n {
        let (_, line) = up.wait_line(" (pid ", START);
        let name = line
            .split_whitespace()
            .next()
            .unwrap_or_default()
            .to_string();
        let pid: u32 = line
            .split("(pid ")
            .nth(1)
            .and_then(|r| r.split(')').next())
            .and_then(|p| p.parse().ok())
            .expect("a pid");
        pids.insert(name, pid);
    }
    up.wait_line("Ctrl-C stops the cluster", START);

    // idle: settle, then 10 s of CPU
    std::thread::sleep(Duration::from_secs(3));
    let tick = unsafe { libc::sysconf(libc::_SC_CLK_TCK) } as f64;
    let window = Duration::from_secs(10);
    let before: Vec<u64> = pids.values().map(|p| cpu_ticks(*p)).collect();
    let t0 = Instant::now();
    std::thread::sleep(window);
    let secs = t0.elapsed().as_secs_f64();
    let shares: Vec<f64> = pids
        .values()
        .zip(&before)
        .map(|(p, b)| (cpu_ticks(*p) - b) as f64 / tick / secs * 100.0)
        .collect();
    let (idle_median, idle_max) = (
        median(shares.clone()),
        shares.iter().cloned().fold(0.0, f64::max),
    );
    let idle_total: f64 = shares.iter().sum();

    // loss: freeze three nodes in turn (never the first, which everyone joined through)
    let names: Vec<String> = pids.keys().cloned().collect();
    let mut slowest = Vec::new();
    let mut all = Vec::new();
    for k in 0..3 {
        let victim = &names[1 + (k * (n - 1) / 3) % (n - 1)];
        let pid = pids[victim];
        // a random moment of the heartbeats' rhythm (a period is deadline / 5)
        *seed ^= *seed << 13;
        *seed ^= *seed >> 7;
        *seed ^= *seed << 17;
        std::thread::sleep(Duration::from_millis(500 + *seed % 240));
        while up.lines.try_recv().is_ok() {}
        let frozen = Instant::now();
        signal(pid, libc::SIGSTOP);
        let mut seen = BTreeMap::new();
        let want = format!("declared {victim} down");
        while seen.len() < n - 1 {
            let (at, line) = up.wait_line(&want, Duration::from_secs(30));
            // `[n04] node n04 declared n01 down: no heartbeat for 1244 ms`
            let by = line
                .trim_start_matches('[')
                .split(']')
                .next()
                .unwrap_or_default();
            seen.entry(by.to_string()).or_insert(at - frozen);
        }
        let times: Vec<f64> = seen.values().map(|d| d.as_secs_f64() * 1000.0).collect();
        slowest.push(times.iter().cloned().fold(0.0, f64::max));
        all.extend(times);
        signal(pid, libc::SIGCONT);
        // seen again by every peer before the next
        let back = format!("sees {victim} at");
        let mut again = 0;
        while again < n - 1 {
            up.wait_line(&back, Duration::from_secs(60));
            again += 1;
        }
    }
    let goal = (DEADLINE + Duration::from_millis(300)).as_millis();
    println!(
        "{n:>2} nodes, {INSTANCES} instances: converged {converged:.2} s after the last node \
         listened{}; idle CPU per node median {idle_median:.2} % max {idle_max:.2} % of a core \
         (all {n}: {idle_total:.1} %){}; a frozen node declared down by every peer in p50 \
         {:.0} ms, slowest peer {:?} ms (goal ≤ {goal} ms){}",
        if n == 16 && converged > 2.0 {
            " (goal ≤ 2 s: MISSED)"
        } else {
            ""
        },
        if n == 16 && idle_max > 2.0 {
            " (goal ≤ 2 %: MISSED)"
        } else {
            ""
        },
        median(all),
        slowest.iter().map(|s| s.round() as u64).collect::<Vec<_>>(),
        if slowest.iter().any(|s| *s > goal as f64) {
            " MISSED"
        } else {
            ""
        },
    );
    drop(up);
}

fn main() {
    let sizes: Vec<usize> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    let sizes = if sizes.is_empty() {
        vec![4, 8, 16]
    } else {
        sizes
    };
    let mut seed = 0x9E37_79B9_7F4A_7C15u64;
    for n in sizes {
        measure(n, &mut seed);
    }
}
