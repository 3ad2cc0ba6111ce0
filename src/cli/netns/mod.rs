//! A private network for `marie up`'s nodes, so a fault can cut them apart
//! (`partition:A,B|C,D@T+D`): each node runs in a Linux network namespace of its own, joined
//! by a veth pair to a hub namespace that routes between them — and `marie up` itself runs
//! in the hub, so it reaches every node whatever is cut.
//!
//! ```text
//!   node 0 (10.77.1.2) ──veth── 10.77.1.1 ┐
//!   node 1 (10.77.2.2) ──veth── 10.77.2.1 ├─ hub: marie up (its run, its members)
//!   node 2 (10.77.3.2) ──veth── 10.77.3.1 ┘
//! ```
//!
//! Every address lives inside namespaces made here (none on the machine's own network); the
//! monitor's page alone is bound in the namespace `marie up` started in, so a browser there
//! reaches it. A cut between nodes X and Y is a blackhole route to the other's address in
//! each of the two namespaces: packets on their way vanish silently, as behind a cut cable
//! (only a new dial fails at once); healing deletes the two routes. A pair two cuts
//! separate stays cut until both healed.
//!
//! Made only when a run may partition (a `partition` fault planned, `--chaos-nodes`) or
//! `--private-network` asks; it needs root (`CAP_SYS_ADMIN`, `CAP_NET_ADMIN`) and `ip`.
//! The namespaces are deleted when `marie up` exits; those a `kill -9` left are deleted by
//! the next `marie up` that makes one. The `ip` commands are [`wiring`]'s, shared with the
//! partition tests.

mod wiring;

use marie::cluster::fault::NodeNetwork;
use std::collections::BTreeMap;
use std::fs::File;
use std::net::{Ipv4Addr, SocketAddr, TcpListener};
use std::os::fd::AsRawFd;
use std::sync::{Arc, Mutex, MutexGuard, OnceLock};
use wiring::{ip, IpError};

/// Prefix of every namespace made here: `marieup<pid>-hub`, `marieup<pid>-<i>`.
const PREFIX: &str = "marieup";

/// The private network this process runs in, once made ([`PrivateNet::enter`]).
static CURRENT: OnceLock<Arc<PrivateNet>> = OnceLock::new();

/// Why no private network could be made.
#[derive(Debug, thiserror::Error)]
pub(crate) enum NetError {
    /// More nodes than the network's addresses.
    #[error("a private network holds at most 249 nodes, not {0}")]
    TooMany(usize),
    /// An `ip` command failed (not root, no `ip`).
    #[error(transparent)]
    Ip(#[from] IpError),
    /// This thread's own namespace cannot be held.
    #[error("cannot open this thread's network namespace: {0}")]
    Host(#[source] std::io::Error),
    /// A namespace made cannot be opened.
    #[error("cannot open namespace {ns}: {source}")]
    Open {
        /// The namespace.
        ns: String,
        /// Why.
        source: std::io::Error,
    },
    /// The hub cannot be entered.
    #[error("cannot enter namespace {ns}: {source}")]
    Enter {
        /// The hub's namespace.
        ns: String,
        /// Why.
        source: std::io::Error,
    },
    /// [`PrivateNet::enter`] was called twice.
    #[error("a private network was made twice")]
    Twice,
}

/// The network of one `marie up`: a hub and a namespace per node.
#[derive(Debug)]
pub(crate) struct PrivateNet {
    hub: String,
    /// By node name: its namespace, an open handle to it, its address.
    nodes: BTreeMap<String, NodeNs>,
    /// The namespace this process started in, where the monitor's page is bound.
    host: File,
    /// Pairs of nodes cut apart now, by how many cuts separate them.
    cuts: Mutex<BTreeMap<(String, String), u32>>,
}

#[derive(Debug)]
struct NodeNs {
    name: String,
    handle: Arc<File>,
    ip: Ipv4Addr,
}

/// Deletes the namespaces when dropped (after the nodes stopped).
#[derive(Debug)]
pub(crate) struct NetGuard {
    names: Vec<String>,
}

impl Drop for NetGuard {
    fn drop(&mut self) {
        for ns in &self.names {
            if let Err(e) = ip(&["netns", "del", ns]) {
                tracing::warn!("could not delete network namespace {ns}: {e}");
            }
        }
    }
}

impl PrivateNet {
    /// Make a hub and a namespace per node of `nodes` (at most 249), and move the calling
    /// thread into the hub — call it on the main thread before any other thread exists, so
    /// that every thread of the process (the runtime's) runs there.
    pub(crate) fn enter(nodes: &[String]) -> Result<NetGuard, NetError> {
        if nodes.len() > 249 {
            return Err(NetError::TooMany(nodes.len()));
        }
        wiring::sweep_left_behind(PREFIX);
        let base = format!("{PREFIX}{}", std::process::id());
        let hub = format!("{base}-hub");
        ip(&["netns", "add", &hub])?;
        let mut guard = NetGuard {
            names: vec![hub.clone()],
        };
        let host = File::open("/proc/thread-self/ns/net").map_err(NetError::Host)?;
        wiring::route_through(&hub)?;
        let mut made = BTreeMap::new();
        for (i, node) in nodes.iter().enumerate() {
            let ns = format!("{base}-{i}");
            ip(&["netns", "add", &ns])?;
            guard.names.push(ns.clone());
            wiring::join(&hub, &ns, i)?;
            let handle = open(&ns)?;
            made.insert(
                node.clone(),
                NodeNs {
                    name: ns,
                    handle: Arc::new(handle),
                    ip: wiring::addresses(i).1,
                },
            );
        }
        let hub_handle = open(&hub)?;
        set_ns(&hub_handle).map_err(|source| NetError::Enter {
            ns: hub.clone(),
            source,
        })?;
        let net = PrivateNet {
            hub,
            nodes: made,
            host,
            cuts: Mutex::new(BTreeMap::new()),
        };
        tracing::info!(hub = %net.hub, nodes = net.nodes.len(), "the nodes run in a private network");
        CURRENT.set(Arc::new(net)).map_err(|_| NetError::Twice)?;
        Ok(guard)
    }

    /// The private network this process runs in, if it made one.
    pub(crate) fn current() -> Option<Arc<PrivateNet>> {
        CURRENT.get().cloned()
    }

    /// Node `node`'s address in the network.
    pub(crate) fn ip_of(&self, node: &str) -> Option<Ipv4Addr> {
        self.nodes.get(node).map(|n| n.ip)
    }

    /// An open handle to node `node`'s namespace (its process is started in it).
    pub(crate) fn namespace_of(&self, node: &str) -> Option<Arc<File>> {
        self.nodes.get(node).map(|n| n.handle.clone())
    }

    /// Bind a listener on `addr` in the namespace this process started in (where a browser
    /// reaches it): on a thread of its own, which enters that namespace, binds and ends.
    pub(crate) fn bind_in_host(&self, addr: SocketAddr) -> std::io::Result<TcpListener> {
        let host = self.host.try_clone()?;
        std::thread::scope(|s| {
            s.spawn(move || {
                set_ns(&host)?;
                TcpListener::bind(addr)
            })
            .join()
            .unwrap_or_else(|_| Err(std::io::Error::other("the binding thread panicked")))
        })
    }

    /// Monitor options for `listen`: bound where a browser reaches it, in the namespace
    /// this process started in when it runs in a private network.
    pub(crate) fn monitor_options(listen: SocketAddr) -> marie_monitor::MonitorOptions {
        let options = marie_monitor::MonitorOptions::new(listen);
        match PrivateNet::current() {
            Some(net) => options.with_binder(Arc::new(move |addr| net.bind_in_host(addr))),
            None => options,
        }
    }

    fn cuts(&self) -> MutexGuard<'_, BTreeMap<(String, String), u32>> {
        self.cuts.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Add (`add`) or delete (`del`) the blackhole routes between nodes `x` and `y`.
    fn blackhole(&self, verb: &str, x: &str, y: &str) -> std::io::Result<()> {
        let node = |n: &str| {
            self.nodes
                .get(n)
                .ok_or_else(|| std::io::Error::other(format!("no node `{n}` in the network")))
        };
        let (x, y) = (node(x)?, node(y)?);
        for (from, to) in [(x, y), (y, x)] {
            wiring::blackhole(verb, &from.name, to.ip).map_err(std::io::Error::other)?;
        }
        Ok(())
    }
}

/// The unordered pair `(x, y)`.
fn pair(x: &str, y: &str) -> (String, String) {
    if x <= y {
        (x.to_string(), y.to_string())
    } else {
        (y.to_string(), x.to_string())
    }
}

impl NodeNetwork for PrivateNet {
    fn cut(&self, a: &[String], b: &[String]) -> std::io::Result<()> {
        let mut cuts = self.cuts();
        for x in a {
            for y in b {
                let count = cuts.entry(pair(x, y)).or_insert(0);
                if *count == 0 {
                    self.blackhole("add", x, y)?;
                }
                *count += 1;
            }
        }
        Ok(())
    }

    fn heal(&self, a: &[String], b: &[String]) -> std::io::Result<()> {
        let mut cuts = self.cuts();
        for x in a {
            for y in b {
                let key = pair(x, y);
                match cuts.get_mut(&key) {
                    Some(1) => {
                        cuts.remove(&key);
                        self.blackhole("del", x, y)?;
                    }
                    Some(count) => *count -= 1,
                    None => {}
                }
            }
        }
        Ok(())
    }
}

/// Move the calling thread into the network namespace `ns`.
pub(crate) fn set_ns(ns: &File) -> std::io::Result<()> {
    // SAFETY: setns on a namespace file this process holds open; it changes only the
    // calling thread's network namespace
    if unsafe { libc::setns(ns.as_raw_fd(), libc::CLONE_NEWNET) } != 0 {
        return Err(std::io::Error::last_os_error());
    }
    Ok(())
}

/// Open namespace `ns` (one made here).
fn open(ns: &str) -> Result<File, NetError> {
    File::open(format!("/var/run/netns/{ns}")).map_err(|source| NetError::Open {
        ns: ns.to_string(),
        source,
    })
}
