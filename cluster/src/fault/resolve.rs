//! The one resolver: what a [`Target`] names now — an operation instance in the registry
//! (the one a run bound, for a plain name), a datamanager (a name no operation has), or a
//! node process this process may stop.

use super::processes::NodeProcesses;
use super::target::{Target, TargetError};
use marie_actors::dispatcher::DISPATCHER_ID;
use marie_actors::eo::EoClient;
use marie_vocabulary::events::EventKind;
use marie_vocabulary::property::{Group, PropertyReply, PropertyRequest};
use marie_vocabulary::registry::{self, Instance, ModuleKind};
use std::collections::HashMap;

/// What a fault hits.
#[derive(Clone, Debug)]
pub enum Hit {
    /// A module instance: an operation, or a datamanager (its `kind` says which).
    Instance(Instance),
    /// A node's process.
    Process {
        /// The node's name.
        node: String,
        /// Its process id.
        pid: u32,
    },
    /// The network between two groups of nodes.
    Cut {
        /// One side.
        a: Vec<String>,
        /// The other side.
        b: Vec<String>,
    },
}

impl Hit {
    /// The node it is on (none for a cut, which is between nodes).
    pub fn node(&self) -> Option<&str> {
        match self {
            Hit::Instance(inst) => Some(&inst.node),
            Hit::Process { node, .. } => Some(node),
            Hit::Cut { .. } => None,
        }
    }
}

/// What a run has bound, as its events tell it: for each operation the instance that serves
/// it now (after a rebind, the stand-in), and the running action's operations. Fed every
/// event of the run ([`RunBindings::observe`]); a `run_started` starts over.
#[derive(Clone, Debug, Default)]
pub struct RunBindings {
    /// The keys of the running actions' operations, by action (chaos picks among them;
    /// more than one action runs under a parallel).
    running: Vec<(String, Vec<String>)>,
    /// Whether the run has bound its operations.
    bound: bool,
    /// Operation name → the address of the instance that serves it now.
    serving: HashMap<String, String>,
}

impl RunBindings {
    /// Take in an event of the run.
    pub fn observe(&mut self, kind: &EventKind) {
        match kind {
            EventKind::RunStarted { .. } => *self = RunBindings::default(),
            EventKind::Bound { operations } => {
                self.bound = true;
                for op in operations.iter().filter(|o| !o.address.is_empty()) {
                    self.serving.insert(op.name.clone(), op.address.clone());
                }
            }
            EventKind::ActionStarted {
                action, operations, ..
            } => {
                self.running.retain(|(a, _)| a != action);
                let keys = operations.iter().map(|o| o.key.clone()).collect();
                self.running.push((action.clone(), keys));
                for op in operations {
                    self.serving.insert(op.name.clone(), op.address.clone());
                }
            }
            EventKind::ActionEnded { action, .. } => self.running.retain(|(a, _)| a != action),
            EventKind::RunEnded { .. } => self.running.clear(),
            EventKind::Rebound(r) => {
                self.serving.insert(r.operation.clone(), r.to.clone());
            }
            _ => {}
        }
    }

    /// Whether the run has bound its operations.
    pub fn bound(&self) -> bool {
        self.bound
    }

    /// The keys of the running actions' operations, each once.
    pub fn running(&self) -> Vec<String> {
        let mut keys: Vec<String> = Vec::new();
        for key in self.running.iter().flat_map(|(_, k)| k) {
            if !keys.contains(key) {
                keys.push(key.clone());
            }
        }
        keys
    }

    /// The bindings of a run that binds none of the operations a target may name: a name
    /// that several instances share is then ambiguous (`marie kill`, `marie props`).
    pub fn none() -> RunBindings {
        RunBindings {
            bound: true,
            ..RunBindings::default()
        }
    }
}

/// What `target` names now, given what the run has bound and the node processes this
/// process may stop.
pub(super) async fn resolve(
    target: &Target,
    run: &RunBindings,
    processes: &NodeProcesses,
) -> Result<Hit, TargetError> {
    let no_process = |node: &String| TargetError::NoProcess {
        node: node.clone(),
        why: if processes.is_empty() {
            "only `marie up` stops node processes, the ones it started".into()
        } else {
            format!("it may stop {}", processes.names().join(", "))
        },
    };
    match target {
        Target::Node(node) => match processes.pid(node) {
            Some(pid) => Ok(Hit::Process {
                node: node.clone(),
                pid,
            }),
            None => Err(no_process(node)),
        },
        Target::Cut { a, b } => {
            if let Some(node) = a.iter().chain(b).find(|n| processes.pid(n).is_none()) {
                return Err(no_process(node));
            }
            if !processes.can_cut() {
                return Err(TargetError::NoNetwork);
            }
            Ok(Hit::Cut {
                a: a.clone(),
                b: b.clone(),
            })
        }
        Target::Actor(id) => modules()
            .into_iter()
            .find(|i| i.actor.get_id().to_string() == *id)
            .map(Hit::Instance)
            .ok_or_else(|| TargetError::NoActor(id.clone(), running_list())),
        Target::Version { operation, version } => {
            let mut running = Vec::new();
            for inst in instances_of(operation)? {
                let v = version_of(&inst).await;
                if v.as_deref() == Some(version.as_str()) {
                    return Ok(Hit::Instance(inst));
                }
                running.push(v.unwrap_or_else(|| "?".into()));
            }
            Err(TargetError::NoVersion {
                operation: operation.clone(),
                version: version.clone(),
                running: running.join(", "),
            })
        }
        Target::OnNode {
            operation,
            node,
            address,
        } => on_node(operation, node, address.as_deref()).map(Hit::Instance),
        Target::Bound(op) => bound(op, run).await.map(Hit::Instance),
    }
}

/// The operation instance `target` names now, outside a run: a plain name is its only
/// instance (a name several instances share is ambiguous) — what `marie props`, `marie
/// kill` and the monitor's properties ask.
pub async fn find(target: &Target) -> Result<Instance, TargetError> {
    let nobody = NodeProcesses::default();
    match resolve(target, &RunBindings::none(), &nobody).await? {
        Hit::Instance(inst) => Ok(inst),
        Hit::Process { node, .. } => Err(TargetError::NoProcess {
            node,
            why: "a node is no operation".into(),
        }),
        Hit::Cut { a, .. } => Err(TargetError::NoProcess {
            node: a.join(","),
            why: "a cut is no operation".into(),
        }),
    }
}

/// The instance the run bound for `op`; outside a run's bindings, its only instance.
async fn bound(op: &str, run: &RunBindings) -> Result<Instance, TargetError> {
    let found = instances_of(op)?;
    let name = found[0].name.clone();
    if let Some(address) = run.serving.get(&name) {
        return found
            .into_iter()
            .find(|i| i.actor.get_id().to_string() == *address)
            .ok_or(TargetError::Gone(name));
    }
    if found.len() == 1 {
        return Ok(found.into_iter().next().expect("one instance"));
    }
    let mut choices = Vec::new();
    for inst in &found {
        let v = version_of(inst).await.unwrap_or_else(|| "?".into());
        choices.push(format!("{name}#{v}"));
    }
    Err(TargetError::Ambiguous {
        operation: op.to_string(),
        count: found.len(),
        choices: choices.join(" or "),
    })
}

/// The instance of `op` on `node`: the one whose actor has `address`'s pid when given (a
/// pid is the same from every process; the `N.` of an address is not), else the only one.
fn on_node(op: &str, node: &str, address: Option<&str>) -> Result<Instance, TargetError> {
    let all = lookup(op);
    let there: Vec<Instance> = all.iter().filter(|i| i.node == node).cloned().collect();
    if let Some(address) = address {
        let pid = address.rsplit('.').next().unwrap_or(address);
        return there
            .into_iter()
            .find(|i| {
                let id = i.actor.get_id().to_string();
                id == address || id.rsplit('.').next() == Some(pid)
            })
            .ok_or_else(|| TargetError::NoLongerRunning(format!("{op} at {address} on {node}")));
    }
    match there.len() {
        1 => Ok(there.into_iter().next().expect("one instance")),
        0 => Err(TargetError::NotOnNode {
            operation: op.to_string(),
            node: node.to_string(),
            elsewhere: if all.is_empty() {
                String::new()
            } else {
                let nodes: Vec<&str> = all.iter().map(|i| i.node.as_str()).collect();
                format!(" (it runs on {})", nodes.join(", "))
            },
        }),
        n => Err(TargetError::Ambiguous {
            operation: format!("{op} on {node}"),
            count: n,
            choices: there
                .iter()
                .map(|i| format!("{op}/{node}/{}", i.actor.get_id()))
                .collect::<Vec<_>>()
                .join(" or "),
        }),
    }
}

/// Every live module instance a fault may hit: operations, datamanagers and the running
/// dispatchers (not their desks).
fn modules() -> Vec<Instance> {
    registry::list()
        .into_iter()
        .filter(|i| match i.kind {
            ModuleKind::Operation | ModuleKind::Datamanager => true,
            ModuleKind::Dispatcher => i.id == DISPATCHER_ID,
            _ => false,
        })
        .collect()
}

/// The live modules, as an error lists them: the operations, then the datamanagers.
fn running_list() -> String {
    let (operations, others): (Vec<Instance>, Vec<Instance>) = modules()
        .into_iter()
        .partition(|i| i.kind == ModuleKind::Operation);
    let (datamanagers, dispatchers): (Vec<Instance>, Vec<Instance>) = others
        .into_iter()
        .partition(|i| i.kind == ModuleKind::Datamanager);
    let names = |instances: &[Instance]| {
        instances
            .iter()
            .map(|i| format!("{} ({}) {}", i.name, i.id, i.actor.get_id()))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let mut parts = Vec::new();
    if !operations.is_empty() {
        parts.push(names(&operations));
    }
    if !datamanagers.is_empty() {
        parts.push(format!("datamanagers: {}", names(&datamanagers)));
    }
    if !dispatchers.is_empty() {
        parts.push(format!("dispatchers: {}", names(&dispatchers)));
    }
    parts.join("; ")
}

/// The live instances of the operation `key` (name or id) — or, when no operation is
/// known by it, of the datamanager, or of the dispatcher (`dispatcher`, 1500: operations,
/// datamanagers and the dispatcher have names of their own).
fn lookup(key: &str) -> Vec<Instance> {
    let operations = registry::lookup(ModuleKind::Operation, key);
    if !operations.is_empty() {
        return operations;
    }
    let datamanagers = registry::lookup(ModuleKind::Datamanager, key);
    if !datamanagers.is_empty() {
        return datamanagers;
    }
    registry::lookup(ModuleKind::Dispatcher, key)
        .into_iter()
        .filter(|i| i.id == DISPATCHER_ID)
        .collect()
}

/// The live instances of `op` (an operation's or a datamanager's name or id); none is an
/// error that lists what runs.
fn instances_of(op: &str) -> Result<Vec<Instance>, TargetError> {
    let found = lookup(op);
    if found.is_empty() {
        Err(TargetError::NotRunning(op.to_string(), running_list()))
    } else {
        Ok(found)
    }
}

/// The version an instance reports (identification property); `None` if it does not answer.
async fn version_of(inst: &Instance) -> Option<String> {
    let client = EoClient::from_cell(inst.actor.clone());
    match client
        .property(PropertyRequest::Group(Group::Identification))
        .await
    {
        Ok(PropertyReply::Identification(i)) => Some(i.version.to_string()),
        _ => None,
    }
}
