//! The node processes a process may stop: what makes a fault that aims at a node
//! ([`Aim::Node`](marie_actors::run::Aim::Node)) possible here.

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex, MutexGuard};

/// The node processes this process may stop, by node name: the children `marie up`
/// started and still holds (an exited child stays unreaped until `marie up` stops it, so
/// its pid is never another process's). Empty in any other process: there, a node fault is
/// refused before it is tried. Cheap to clone; clones share the table.
#[derive(Clone, Debug, Default)]
pub struct NodeProcesses(Arc<Mutex<BTreeMap<String, u32>>>);

impl NodeProcesses {
    /// The processes `(name, pid)`.
    pub fn new(nodes: impl IntoIterator<Item = (String, u32)>) -> NodeProcesses {
        NodeProcesses(Arc::new(Mutex::new(nodes.into_iter().collect())))
    }

    /// The names of the nodes that may be stopped, in order.
    pub fn names(&self) -> Vec<String> {
        self.lock().keys().cloned().collect()
    }

    /// The pid of `node`'s process, if it may be stopped.
    pub fn pid(&self, node: &str) -> Option<u32> {
        self.lock().get(node).copied()
    }

    /// Whether no node may be stopped here.
    pub fn is_empty(&self) -> bool {
        self.lock().is_empty()
    }

    /// Kill `node`'s process (`SIGKILL`, as a crash would); its pid. A node is killed
    /// once: it is no longer offered afterwards.
    pub(crate) fn kill(&self, node: &str) -> Result<u32, std::io::Error> {
        let mut nodes = self.lock();
        let pid = nodes.get(node).copied().ok_or_else(|| {
            std::io::Error::new(std::io::ErrorKind::NotFound, "no such node process")
        })?;
        let pid_t = libc::pid_t::try_from(pid).map_err(|_| {
            std::io::Error::new(std::io::ErrorKind::InvalidInput, "pid out of range")
        })?;
        // SAFETY: `kill` only sends a signal; `pid` is a child the table's owner holds
        if unsafe { libc::kill(pid_t, libc::SIGKILL) } != 0 {
            return Err(std::io::Error::last_os_error());
        }
        nodes.remove(node);
        Ok(pid)
    }

    fn lock(&self) -> MutexGuard<'_, BTreeMap<String, u32>> {
        self.0.lock().unwrap_or_else(|p| p.into_inner())
    }
}
