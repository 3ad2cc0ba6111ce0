//! A private network of Linux network namespaces for the partition tests: a hub namespace
//! that routes between node namespaces, each joined to it by a veth pair, so that the
//! traffic between two nodes can be dropped while both processes run on.
//!
//! ```text
//!   node 0 (10.77.1.2) ──veth── 10.77.1.1 ┐
//!   node 1 (10.77.2.2) ──veth── 10.77.2.1 ├─ hub (forwards)
//!   node 2 (10.77.3.2) ──veth── 10.77.3.1 ┘
//! ```
//!
//! Every address lives inside namespaces this guard creates (none on the machine's own
//! network). A cut between nodes X and Y is a blackhole route to the other's address in
//! each of the two namespaces: packets already on their way — a session's heartbeats, its
//! TCP retransmissions — vanish silently, as behind a cut cable, and nothing tells either
//! process; only a new dial fails at once (the route lookup refuses it) instead of timing
//! out. Healing deletes the two routes. Every other pair keeps talking.
//!
//! The guard deletes its namespaces (and so their veths) when it drops, also when a test
//! panics, after killing whatever still runs inside them. Declare it before the processes
//! it hosts, so that it drops after them.
//!
//! Needs root (`CAP_NET_ADMIN`) and `ip`. Without them a test is skipped with a line on
//! stderr — or fails, when the environment variable `CI` is set.
//!
//! The `ip` commands are `marie up`'s own ([`wiring`], included from the binary's sources:
//! the tests cannot link to a binary), so the network these tests cut is wired as the one
//! `marie up --fault partition:…` cuts.

#[path = "../../src/cli/netns/wiring.rs"]
mod wiring;

use std::io::Write;
use std::net::{Ipv4Addr, SocketAddr};
use std::process::Command;
use std::sync::atomic::{AtomicUsize, Ordering};
use wiring::{ip, IpError};

/// Prefix of every namespace these tests create: `mariep<pid>-<n>-hub`, `mariep<pid>-<n>-<i>`.
const PREFIX: &str = "mariep";

/// Networks made by this test process so far (part of the names, so parallel tests differ).
static MADE: AtomicUsize = AtomicUsize::new(0);

/// The hub and the node namespaces of one test.
pub(crate) struct Netns {
    hub: String,
    nodes: Vec<String>,
}

impl Netns {
    /// A hub and `n` node namespaces, each node reaching every other through the hub.
    /// `None` when namespaces cannot be made here (not root): the test should return at
    /// once; it was told on stderr. With `CI` set, that panics instead.
    pub(crate) fn create(n: usize) -> Option<Netns> {
        assert!(n < 250, "at most 249 nodes");
        // namespaces of test processes killed before their guards dropped (their
        // processes, started with `--stop-with-stdin`, stopped with them)
        wiring::sweep_left_behind(PREFIX);
        let k = MADE.fetch_add(1, Ordering::Relaxed);
        let base = format!("{PREFIX}{}-{k}", std::process::id());
        let hub = format!("{base}-hub");
        if let Err(e) = ip(&["netns", "add", &hub]) {
            let why = format!("cannot create network namespaces ({e})");
            if std::env::var_os("CI").is_some() {
                panic!("{why}: the partition tests need root and `ip` (CI is set, so this fails)");
            }
            // past the test harness's capture: a skip must be seen
            let _ = writeln!(
                std::io::stderr(),
                "skipped: needs root for network namespaces — {why}"
            );
            return None;
        }
        let mut net = Netns {
            hub,
            nodes: Vec::new(),
        };
        let mut setup = || -> Result<(), IpError> {
            wiring::route_through(&net.hub)?;
            for i in 0..n {
                let ns = format!("{base}-{i}");
                ip(&["netns", "add", &ns])?;
                net.nodes.push(ns.clone());
                wiring::join(&net.hub, &ns, i)?;
            }
            Ok(())
        };
        if let Err(e) = setup() {
            // `net` drops here: what was made is deleted
            panic!("cannot set up the test network {base}: {e}");
        }
        Some(net)
    }

    /// Whether namespaces can be made here (as [`Netns::create`]: told on stderr when not,
    /// a panic under `CI`).
    pub(crate) fn can_make() -> bool {
        Netns::create(1).is_some()
    }

    /// Node `i`'s namespace (for `ip netns exec`).
    pub(crate) fn ns(&self, i: usize) -> &str {
        &self.nodes[i]
    }

    /// Node `i`'s address: `10.77.<i+1>.2`.
    pub(crate) fn ip(&self, i: usize) -> Ipv4Addr {
        assert!(i < self.nodes.len());
        wiring::addresses(i).1
    }

    /// Node `i`'s address with `port` (any port is free in a namespace of its own).
    pub(crate) fn addr(&self, i: usize, port: u16) -> SocketAddr {
        SocketAddr::new(self.ip(i).into(), port)
    }

    /// Drop every packet between nodes `a` and `b`, both ways; the others are untouched.
    pub(crate) fn cut(&self, a: usize, b: usize) {
        self.blackhole("add", a, b);
    }

    /// Undo [`Netns::cut`] of `a` and `b`.
    pub(crate) fn heal(&self, a: usize, b: usize) {
        self.blackhole("del", a, b);
    }

    fn blackhole(&self, verb: &str, a: usize, b: usize) {
        for (from, to) in [(a, b), (b, a)] {
            let target = self.ip(to);
            wiring::blackhole(verb, self.ns(from), target).unwrap_or_else(|e| {
                panic!("route {verb} blackhole {target}/32 in node {from}: {e}")
            });
        }
    }
}

impl Drop for Netns {
    fn drop(&mut self) {
        for ns in self.nodes.iter().chain([&self.hub]) {
            delete(ns);
        }
    }
}

/// Kill what still runs in namespace `ns` (only processes of these tests run there), then
/// delete it; its veth ends go with it.
fn delete(ns: &str) {
    if let Ok(out) = Command::new("ip").args(["netns", "pids", ns]).output() {
        for pid in String::from_utf8_lossy(&out.stdout).split_whitespace() {
            let _ = Command::new("kill").args(["-KILL", pid]).status();
        }
    }
    if let Err(e) = ip(&["netns", "del", ns]) {
        eprintln!("could not delete network namespace {ns}: {e}");
    }
}
