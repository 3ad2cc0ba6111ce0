//! What the tests of `marie monitor` share: a recorded run to replay, and the page's address
//! as the monitor prints it.

use super::cluster::Proc;
use super::http;
use super::{marie, text};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// A docking run whose wall follower is killed at 20 s, its events file written into `dir`
/// by the binary under test.
pub(crate) fn recorded_run(dir: &Path) -> PathBuf {
    let events = dir.join("run.jsonl");
    let out = marie(&[
        "run",
        "missions/docking.toml",
        "--speed",
        "max",
        "--fault",
        "kill:wall-follower@20",
        "--events",
        events.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    events
}

/// `monitor: http://127.0.0.1:PORT/?token=T (...)` → the page's URL as printed.
pub(crate) fn url_of(line: &str) -> String {
    line.split_whitespace()
        .find(|w| w.starts_with("http://"))
        .unwrap_or_else(|| panic!("no URL in {line:?}"))
        .to_string()
}

/// `monitor: http://127.0.0.1:PORT/?token=T (...)` → the address and the token.
pub(crate) fn page_of(line: &str) -> (SocketAddr, Option<String>) {
    let url = url_of(line);
    let rest = url.trim_start_matches("http://");
    let (addr, query) = rest.split_once('/').unwrap();
    let token = query.strip_prefix("?token=").map(str::to_string);
    (addr.parse().unwrap(), token)
}

/// `marie run` of docking at speed 4 with its wall follower killed at 20 s and its own
/// monitor on a port the OS picks: the process, its `monitor: http://…` line awaited next.
pub(crate) fn monitored_run() -> Proc {
    Proc::spawn(
        "run",
        &[
            "run",
            "missions/docking.toml",
            "--speed",
            "4",
            "--fault",
            "kill:wall-follower@20",
            "--monitor",
            "127.0.0.1:0",
        ],
    )
}

/// `marie up CLUSTER --monitor 127.0.0.1:0` plus `extra` flags (`--run`, `--speed`,
/// `--allow-faults`, …): the process and its `monitor: http://…` line.
pub(crate) fn monitored_up(cluster: &str, extra: &[&str]) -> (Proc, String) {
    let mut args = vec!["up", cluster, "--monitor", "127.0.0.1:0"];
    args.extend_from_slice(extra);
    let mut up = Proc::spawn("marie up", &args);
    let line = up.wait_line("monitor: http://");
    (up, line)
}

/// `marie monitor --events EVENTS --listen 127.0.0.1:0` plus `extra` flags: the process and
/// its `monitor: http://…` line.
pub(crate) fn replay_monitor(events: &Path, extra: &[&str]) -> (Proc, String) {
    let mut args = vec![
        "monitor",
        "--events",
        events.to_str().unwrap(),
        "--listen",
        "127.0.0.1:0",
    ];
    args.extend_from_slice(extra);
    let mut monitor = Proc::spawn("monitor", &args);
    let line = monitor.wait_line("monitor: http://");
    (monitor, line)
}

/// Poll `/api/state` until `ok` holds (at most [`super::cluster::EVENT_TIMEOUT`]).
pub(crate) fn state_until(
    addr: SocketAddr,
    what: &str,
    ok: impl Fn(&serde_json::Value) -> bool,
) -> serde_json::Value {
    let deadline = Instant::now() + super::cluster::EVENT_TIMEOUT;
    loop {
        let state = http::get_json(addr, "/api/state");
        if ok(&state) {
            return state;
        }
        assert!(Instant::now() < deadline, "never {what}: {state}");
        std::thread::sleep(Duration::from_millis(100));
    }
}
