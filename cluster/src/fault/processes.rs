//! The node processes a process may stop, freeze or cut off: what makes a fault that aims
//! at a node ([`Aim::Node`](marie_vocabulary::run::Aim::Node)) or a cut between nodes
//! ([`Aim::Cut`](marie_vocabulary::run::Aim::Cut)) possible here.

use super::network::NodeNetwork;
use std::collections::{BTreeMap, BTreeSet};
use std::io::{Error, ErrorKind};
use std::sync::{Arc, Mutex, MutexGuard};

/// The node processes this process may stop, by node name: the children `marie up`
/// started and still holds (a child that ended is taken out before it is reaped, so a pid
/// here is never another process's; one `up` restarted is put back) — and, when it started them in a network it can
/// cut, that network. Empty in any other process: there, a node fault is refused before it
/// is tried. Cheap to clone; clones share the table.
#[derive(Clone, Debug, Default)]
pub struct NodeProcesses(Arc<Mutex<Table>>);

#[derive(Debug, Default)]
struct Table {
    pids: BTreeMap<String, u32>,
    /// The nodes frozen now (`SIGSTOP`, not yet `SIGCONT`).
    frozen: BTreeSet<String>,
    network: Option<Arc<dyn NodeNetwork>>,
}

impl NodeProcesses {
    /// The processes `(name, pid)`.
    pub fn new(nodes: impl IntoIterator<Item = (String, u32)>) -> NodeProcesses {
        NodeProcesses(Arc::new(Mutex::new(Table {
            pids: nodes.into_iter().collect(),
            ..Table::default()
        })))
    }

    /// The nodes run in `network`, where they can be cut apart
    /// ([`FaultKind::Partition`](marie_vocabulary::run::FaultKind::Partition)).
    pub fn with_network(self, network: Arc<dyn NodeNetwork>) -> NodeProcesses {
        self.lock().network = Some(network);
        self
    }

    /// The names of the nodes that may be stopped, in order.
    pub fn names(&self) -> Vec<String> {
        self.lock().pids.keys().cloned().collect()
    }

    /// The pid of `node`'s process, if it may be stopped.
    pub fn pid(&self, node: &str) -> Option<u32> {
        self.lock().pids.get(node).copied()
    }

    /// Whether no node may be stopped here.
    pub fn is_empty(&self) -> bool {
        self.lock().pids.is_empty()
    }

    /// Whether the nodes run in a network that can be cut.
    pub fn can_cut(&self) -> bool {
        self.lock().network.is_some()
    }

    /// `node`'s process was started again (by `marie up`'s restart) as `pid`: it may be
    /// stopped, frozen and cut off again.
    pub fn started(&self, node: &str, pid: u32) {
        let mut table = self.lock();
        table.pids.insert(node.to_string(), pid);
        table.frozen.remove(node);
    }

    /// `node`'s process ended and was reaped: its pid may be another process's soon, so it
    /// is no longer offered (until [`started`](Self::started) again).
    pub fn ended(&self, node: &str) {
        let mut table = self.lock();
        table.pids.remove(node);
        table.frozen.remove(node);
    }

    /// Kill `node`'s process (`SIGKILL`, as a crash would); its pid. A node is killed
    /// once: it is no longer offered afterwards.
    pub(crate) fn kill(&self, node: &str) -> Result<u32, Error> {
        let mut table = self.lock();
        let pid = table.pid(node)?;
        signal(pid, libc::SIGKILL)?;
        table.pids.remove(node);
        table.frozen.remove(node);
        Ok(pid)
    }

    /// Freeze `node`'s process (`SIGSTOP`) until [`thaw`](Self::thaw); its pid. A node
    /// frozen already is refused.
    pub(crate) fn freeze(&self, node: &str) -> Result<u32, Error> {
        let mut table = self.lock();
        let pid = table.pid(node)?;
        if table.frozen.contains(node) {
            return Err(Error::new(ErrorKind::AlreadyExists, "it is frozen already"));
        }
        signal(pid, libc::SIGSTOP)?;
        table.frozen.insert(node.to_string());
        Ok(pid)
    }

    /// Let a frozen `node` go on (`SIGCONT`). Nothing to do when it is not frozen (any
    /// more: it was killed meanwhile).
    pub(crate) fn thaw(&self, node: &str) -> Result<(), Error> {
        let mut table = self.lock();
        if !table.frozen.remove(node) {
            return Ok(());
        }
        match table.pids.get(node) {
            Some(&pid) => signal(pid, libc::SIGCONT),
            None => Ok(()),
        }
    }

    /// Cut the nodes of `a` off from those of `b` (see [`NodeNetwork::cut`]). Every node
    /// must be one of this process's, and the nodes must run in a network that can be cut.
    pub(crate) fn cut(&self, a: &[String], b: &[String]) -> Result<(), Error> {
        let network = self.network_of(a.iter().chain(b))?;
        network.cut(a, b)
    }

    /// Heal a [`cut`](Self::cut).
    pub(crate) fn heal(&self, a: &[String], b: &[String]) -> Result<(), Error> {
        let network = self.lock().network.clone();
        match network {
            Some(n) => n.heal(a, b),
            None => Ok(()),
        }
    }

    /// The network, if every one of `nodes` runs in it.
    fn network_of<'a>(
        &self,
        mut nodes: impl Iterator<Item = &'a String>,
    ) -> Result<Arc<dyn NodeNetwork>, Error> {
        let table = self.lock();
        let network = table.network.clone().ok_or_else(|| {
            Error::new(
                ErrorKind::Unsupported,
                "the nodes do not run in a network marie can cut (marie up makes one of \
                 network namespaces when a run may partition; that needs root and `ip`)",
            )
        })?;
        if let Some(n) = nodes.find(|n| !table.pids.contains_key(*n)) {
            return Err(Error::new(
                ErrorKind::NotFound,
                format!("no node `{n}` runs here"),
            ));
        }
        Ok(network)
    }

    fn lock(&self) -> MutexGuard<'_, Table> {
        self.0.lock().unwrap_or_else(|p| p.into_inner())
    }
}

impl Table {
    fn pid(&self, node: &str) -> Result<u32, Error> {
        self.pids
            .get(node)
            .copied()
            .ok_or_else(|| Error::new(ErrorKind::NotFound, "no such node process"))
    }
}

/// Send `sig` to `pid`.
fn signal(pid: u32, sig: libc::c_int) -> Result<(), Error> {
    let pid_t = libc::pid_t::try_from(pid)
        .map_err(|_| Error::new(ErrorKind::InvalidInput, "pid out of range"))?;
    // SAFETY: `kill` only sends a signal; `pid` is a child the table's owner holds
    if unsafe { libc::kill(pid_t, sig) } != 0 {
        return Err(Error::last_os_error());
    }
    Ok(())
}
