//! What the monitor's page may ask of the run it shows: an operation's live properties on a
//! click, and with `--allow-faults` a fault — kill or hang an operation (wherever it runs:
//! the registry is the cluster's), or kill the process of a node `marie up` started.
//!
//! The monitor runs this on its own thread and runtime; everything here is a registry
//! lookup, an actor message or a signal, none of which needs the node's runtime.

use super::props::ask_every_group;
use marie::actors::events::{EventBus, EventKind};
use marie::actors::registry::{self, Instance, ModuleKind};
use marie::fault::{self, FaultKind};
use marie_monitor::control::{Answer, Control, ControlError, FaultRequest, Offers, OperationRef};
use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};

/// The node processes a page may stop: name → pid, of the children `marie up` started and
/// still holds (an exited child stays unreaped until `marie up` stops it, so its pid is
/// never another process's).
#[derive(Clone, Debug, Default)]
pub struct NodeProcesses(Arc<Mutex<BTreeMap<String, u32>>>);

impl NodeProcesses {
    /// The processes `(name, pid)`.
    pub fn new(nodes: impl IntoIterator<Item = (String, u32)>) -> NodeProcesses {
        NodeProcesses(Arc::new(Mutex::new(nodes.into_iter().collect())))
    }

    fn names(&self) -> Vec<String> {
        self.lock().keys().cloned().collect()
    }

    /// Kill `node`'s process (`SIGKILL`); gives its pid. A node is killed once.
    fn kill(&self, node: &str) -> Result<u32, ControlError> {
        let mut nodes = self.lock();
        let Some(&pid) = nodes.get(node) else {
            let known: Vec<&String> = nodes.keys().collect();
            return Err(ControlError::NotFound(format!(
                "no node process `{node}` to stop (still running: {known:?})"
            )));
        };
        // SAFETY: `kill` only sends a signal; `pid` is our own unreaped child
        if unsafe { libc::kill(pid as libc::pid_t, libc::SIGKILL) } != 0 {
            let e = std::io::Error::last_os_error();
            return Err(ControlError::Failed(format!(
                "cannot kill node {node} (pid {pid}): {e}"
            )));
        }
        nodes.remove(node);
        Ok(pid)
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, BTreeMap<String, u32>> {
        self.0.lock().unwrap_or_else(|p| p.into_inner())
    }
}

/// The page's control of a run seen from this process: its registry (a cluster member's
/// covers the cluster), its event bus (a fault done is told there, so the timeline and an
/// events file show it), and the node processes it may stop.
pub struct PageControl {
    bus: EventBus,
    processes: NodeProcesses,
}

impl PageControl {
    /// Control through this process's registry, telling `bus`; `processes`: the node
    /// processes that may be stopped (none outside `marie up`).
    pub fn new(bus: EventBus, processes: NodeProcesses) -> Arc<PageControl> {
        Arc::new(PageControl { bus, processes })
    }

    fn operation_fault(&self, kind: FaultKind, op: &OperationRef) -> Result<String, ControlError> {
        let inst = resolve(op)?;
        let done =
            fault::inject_into(kind, &inst).map_err(|e| ControlError::Failed(e.to_string()))?;
        self.bus.publish(EventKind::FaultInjected {
            run_ms: self.bus.clock().now().as_millis() as u64,
            fault: kind,
            operation: inst.name.clone(),
            actor: done.actor.to_string(),
        });
        Ok(format!(
            "{kind} injected into {} ({}) on {}",
            inst.name, done.actor, inst.node
        ))
    }
}

impl Control for PageControl {
    fn offers(&self) -> Offers {
        Offers {
            properties: true,
            operation_faults: true,
            stoppable_nodes: self.processes.names(),
        }
    }

    fn properties(&self, op: OperationRef) -> Answer<serde_json::Value> {
        Box::pin(async move {
            let inst = resolve(&op)?;
            let replies = ask_every_group(&inst)
                .await
                .map_err(|e| ControlError::Failed(format!("{} did not answer: {e}", inst.name)))?;
            serde_json::to_value(replies).map_err(|e| ControlError::Failed(e.to_string()))
        })
    }

    fn fault(&self, request: FaultRequest) -> Answer<String> {
        let done = match &request {
            FaultRequest::Kill(op) => self.operation_fault(FaultKind::Kill, op),
            FaultRequest::Hang(op) => self.operation_fault(FaultKind::Hang, op),
            FaultRequest::StopNode { node } => self.processes.kill(node).map(|pid| {
                self.bus.publish(EventKind::NodeKilled {
                    peer: node.clone(),
                    pid,
                });
                format!("killed node {node}'s process (pid {pid})")
            }),
        };
        Box::pin(std::future::ready(done))
    }
}

/// The live instance `op` names: the one at its address when it gives one, else its
/// operation's only instance on its node.
///
/// An address is compared by its actor's pid on its own node (`N.PID`: the `N` is which
/// node, as the process that wrote it numbers its peers; the pid is the same from every
/// process), on the node `op` names: the page may show addresses as the dispatcher's
/// process saw them, another process than this one.
fn resolve(op: &OperationRef) -> Result<Instance, ControlError> {
    let all = registry::lookup(ModuleKind::Operation, &op.operation);
    let on_node: Vec<Instance> = all
        .iter()
        .filter(|i| op.node.as_ref().is_none_or(|n| *n == i.node))
        .cloned()
        .collect();
    let where_ = op
        .node
        .as_ref()
        .map_or(String::new(), |n| format!(" on {n}"));
    if let Some(address) = &op.address {
        let pid = address.rsplit('.').next().unwrap_or(address);
        let same = |i: &&Instance| {
            let id = i.actor.get_id().to_string();
            id == *address || (op.node.is_some() && id.rsplit('.').next() == Some(pid))
        };
        return on_node.iter().find(same).cloned().ok_or_else(|| {
            ControlError::NotFound(format!(
                "{} at {address}{where_} is no longer running",
                op.operation
            ))
        });
    }
    match on_node.as_slice() {
        [one] => Ok(one.clone()),
        [] => Err(ControlError::NotFound(format!(
            "no instance of {}{where_} is running{}",
            op.operation,
            if all.is_empty() {
                String::new()
            } else {
                format!(
                    " (it runs on {})",
                    all.iter()
                        .map(|i| i.node.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                )
            }
        ))),
        several => Err(ControlError::Refused(format!(
            "{} instances of {}{where_} run ({}): name one by its address",
            several.len(),
            op.operation,
            several
                .iter()
                .map(|i| i.actor.get_id().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ))),
    }
}
