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
//! the next `marie up` that makes one.

use marie::cluster::fault::NodeNetwork;
use std::collections::BTreeMap;
use std::fs::File;
use std::net::{Ipv4Addr, SocketAddr, TcpListener};
use std::os::fd::AsRawFd;
use std::process::Command;
use std::sync::{Arc, Mutex, MutexGuard, OnceLock};

/// Prefix of every namespace made here: `marieup<pid>-hub`, `marieup<pid>-<i>`.
const PREFIX: &str = "marieup";

/// The private network this process runs in, once made ([`PrivateNet::enter`]).
static CURRENT: OnceLock<Arc<PrivateNet>> = OnceLock::new();

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
    pub(crate) fn enter(nodes: &[String]) -> Result<NetGuard, String> {
        if nodes.len() > 249 {
            return Err(format!(
                "a private network holds at most 249 nodes, not {}",
                nodes.len()
            ));
        }
        sweep_left_behind();
        let base = format!("{PREFIX}{}", std::process::id());
        let hub = format!("{base}-hub");
        ip(&["netns", "add", &hub])?;
        let mut guard = NetGuard {
            names: vec![hub.clone()],
        };
        let host = File::open("/proc/thread-self/ns/net")
            .map_err(|e| format!("cannot open this thread's network namespace: {e}"))?;
        ip(&["-n", &hub, "link", "set", "lo", "up"])?;
        ip(&[
            "netns",
            "exec",
            &hub,
            "sysctl",
            "-qw",
            "net.ipv4.ip_forward=1",
        ])?;
        let mut made = BTreeMap::new();
        for (i, node) in nodes.iter().enumerate() {
            let ns = format!("{base}-{i}");
            ip(&["netns", "add", &ns])?;
            guard.names.push(ns.clone());
            let hub_end = format!("h{i}"); // in the hub's namespace only: no clash
            let (hub_ip, node_ip) = (
                Ipv4Addr::new(10, 77, i as u8 + 1, 1),
                Ipv4Addr::new(10, 77, i as u8 + 1, 2),
            );
            ip(&["-n", &ns, "link", "set", "lo", "up"])?;
            ip(&[
                "-n", &hub, "link", "add", &hub_end, "type", "veth", "peer", "name", "eth0",
                "netns", &ns,
            ])?;
            ip(&[
                "-n",
                &hub,
                "addr",
                "add",
                &format!("{hub_ip}/24"),
                "dev",
                &hub_end,
            ])?;
            ip(&["-n", &hub, "link", "set", &hub_end, "up"])?;
            ip(&[
                "-n",
                &ns,
                "addr",
                "add",
                &format!("{node_ip}/24"),
                "dev",
                "eth0",
            ])?;
            ip(&["-n", &ns, "link", "set", "eth0", "up"])?;
            ip(&[
                "-n",
                &ns,
                "route",
                "add",
                "default",
                "via",
                &hub_ip.to_string(),
            ])?;
            let handle = File::open(format!("/var/run/netns/{ns}"))
                .map_err(|e| format!("cannot open namespace {ns}: {e}"))?;
            made.insert(
                node.clone(),
                NodeNs {
                    name: ns,
                    handle: Arc::new(handle),
                    ip: node_ip,
                },
            );
        }
        let hub_handle = File::open(format!("/var/run/netns/{hub}"))
            .map_err(|e| format!("cannot open namespace {hub}: {e}"))?;
        set_ns(&hub_handle).map_err(|e| format!("cannot enter namespace {hub}: {e}"))?;
        let net = PrivateNet {
            hub,
            nodes: made,
            host,
            cuts: Mutex::new(BTreeMap::new()),
        };
        tracing::info!(hub = %net.hub, nodes = net.nodes.len(), "the nodes run in a private network");
        CURRENT
            .set(Arc::new(net))
            .map_err(|_| "a private network was made twice".to_string())?;
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
            ip(&[
                "-n",
                &from.name,
                "route",
                verb,
                "blackhole",
                &format!("{}/32", to.ip),
            ])
            .map_err(std::io::Error::other)?;
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

/// Delete the namespaces of `marie up`s that are gone (a `kill -9` leaves them).
fn sweep_left_behind() {
    let Ok(out) = Command::new("ip").args(["netns", "list"]).output() else {
        return;
    };
    for line in String::from_utf8_lossy(&out.stdout).lines() {
        let Some(name) = line.split_whitespace().next() else {
            continue;
        };
        let Some(pid) = name
            .strip_prefix(PREFIX)
            .and_then(|rest| rest.split_once('-'))
            .and_then(|(pid, _)| pid.parse::<u32>().ok())
        else {
            continue;
        };
        if !std::path::Path::new(&format!("/proc/{pid}")).exists() {
            let _ = ip(&["netns", "del", name]);
        }
    }
}

/// Run `ip ARGS`; its stderr on failure.
fn ip(args: &[&str]) -> Result<(), String> {
    let out = Command::new("ip")
        .args(args)
        .output()
        .map_err(|e| format!("cannot run `ip`: {e}"))?;
    if out.status.success() {
        Ok(())
    } else {
        Err(format!(
            "ip {}: {}",
            args.join(" "),
            String::from_utf8_lossy(&out.stderr).trim()
        ))
    }
}
