//! What the monitor's page may ask of the run it shows: an operation's live properties on a
//! click; with `--allow-faults` a fault of any kind — to an operation (wherever it runs:
//! the registry is the cluster's), or to a node whose process `marie up` started — through
//! the one road of faults ([`marie::cluster::fault`]); and with `--allow-changes` a replica
//! of a datamanager added on a node or removed, through the road `marie dm` takes
//! ([`marie::cluster::replicas`]), its refusals in the same words.
//!
//! The monitor runs this on its own thread and runtime; everything here is a registry
//! lookup, an actor message or a signal, none of which needs the node's runtime.

use super::props::ask_every_group;
use marie::cluster::fault::{self, FaultError, Hit, Injector, NodeProcesses, Target, TargetError};
use marie::cluster::replicas::{self, ChangeFailure, Step};
use marie::dm::ChangeError;
use marie::events::EventBus;
use marie::run::{Aim, FaultKind};
use marie_monitor::control::{
    Answer, Control, ControlError, FaultOn, FaultRequest, Offers, OperationRef, ReplicaChange,
    ReplicaRequest,
};
use std::sync::Arc;

/// The page's control of a run seen from this process: its registry (a cluster member's
/// covers the cluster), and the one road of faults — an [`Injector`] on the node's bus (a
/// fault done is told there, so the timeline, an events file and the run's report hold it)
/// that may stop the node processes this process started.
pub(crate) struct PageControl {
    injector: Injector,
}

impl PageControl {
    /// Control through this process's registry, telling `bus`; `processes`: the node
    /// processes that may be stopped (none outside `marie up`).
    pub(crate) fn new(bus: EventBus, processes: NodeProcesses) -> Arc<PageControl> {
        let injector = Injector::new(&bus)
            .with_processes(processes)
            .aiming_at_bindings();
        Arc::new(PageControl { injector })
    }
}

impl Control for PageControl {
    fn offers(&self) -> Offers {
        Offers {
            properties: true,
            operation_faults: true,
            stoppable_nodes: self.injector.processes().names(),
            cuttable: self.injector.processes().can_cut(),
        }
    }

    fn properties(&self, op: OperationRef) -> Answer<serde_json::Value> {
        Box::pin(async move {
            let target = target_of(&FaultOn::Operation(op));
            let inst = fault::find(&target)
                .await
                .map_err(|e| control_error(e.into()))?;
            let replies = ask_every_group(&inst)
                .await
                .map_err(|e| ControlError::Failed(format!("{} did not answer: {e}", inst.name)))?;
            serde_json::to_value(replies).map_err(|e| ControlError::Failed(e.to_string()))
        })
    }

    fn fault(&self, request: FaultRequest) -> Answer<String> {
        let injector = self.injector.clone();
        Box::pin(async move {
            let target = match (&request.on, request.fault.aim()) {
                // the page cuts a node off from every other node `marie up` started
                (FaultOn::Node { node }, Aim::Cut) => {
                    Target::cut_off(node, &injector.processes().names())
                }
                (on, _) => target_of(on),
            };
            let done = injector
                .inject(request.fault, &target)
                .await
                .map_err(control_error)?;
            Ok(match &done.hit {
                Hit::Instance(inst) => format!(
                    "{} injected into {} ({}) on {}",
                    done.kind,
                    inst.name,
                    done.victim(),
                    inst.node
                ),
                Hit::Process { node, pid } => match done.kind {
                    FaultKind::FreezeNode => format!(
                        "{} done: froze node {node}'s process (pid {pid}) for {:.1} s",
                        done.kind,
                        done.lasting.unwrap_or_default().as_secs_f64()
                    ),
                    _ => format!(
                        "{} done: killed node {node}'s process (pid {pid})",
                        done.kind
                    ),
                },
                Hit::Cut { a, b } => format!(
                    "{} done: cut {} off from {} for {:.1} s",
                    done.kind,
                    a.join(", "),
                    b.join(", "),
                    done.lasting.unwrap_or_default().as_secs_f64()
                ),
            })
        })
    }

    fn replicas(&self, request: ReplicaRequest) -> Answer<String> {
        Box::pin(async move {
            PageControl::change_replicas(request)
                .await
                .map_err(change_error)
        })
    }
}

impl PageControl {
    /// Add or remove the replica `request` names, as `marie dm` does (bounded by
    /// [`replicas::CHANGE_WITHIN`]); what was done, step by step.
    async fn change_replicas(request: ReplicaRequest) -> Result<String, ChangeFailure> {
        let ReplicaRequest { change, dm, node } = request;
        let mut steps = Vec::new();
        let tell = |step: &Step| steps.push(step.to_string());
        let within = replicas::CHANGE_WITHIN;
        match change {
            ReplicaChange::Add => replicas::add(&dm, &node, within, tell).await?,
            ReplicaChange::Remove => replicas::remove(&dm, &node, within, tell).await?,
        }
        let done = match change {
            ReplicaChange::Add => "added",
            ReplicaChange::Remove => "removed",
        };
        Ok(format!(
            "{dm}: replica on {node} {done} ({})",
            steps.join("; ")
        ))
    }
}

/// A change the cluster did not make, as the page is answered: 404 for a datamanager or
/// node it does not have (or a replica it does not keep), 409 for what it refuses as it is
/// now, 502 for what was tried and failed — in `marie dm`'s words.
fn change_error(e: ChangeFailure) -> ControlError {
    let why = e.to_string();
    match e {
        ChangeFailure::UnknownDm(_)
        | ChangeFailure::UnknownNode { .. }
        | ChangeFailure::Refused {
            why: ChangeError::NotAMember(_),
            ..
        } => ControlError::NotFound(why),
        ChangeFailure::Unreplicated(_) | ChangeFailure::NoLeader(_) => ControlError::Refused(why),
        ChangeFailure::Refused {
            why: ChangeError::Interrupted(_),
            ..
        } => ControlError::Failed(why),
        ChangeFailure::Refused { .. } => ControlError::Refused(why),
        ChangeFailure::Host(_) | ChangeFailure::Dm { .. } | ChangeFailure::TimedOut { .. } => {
            ControlError::Failed(why)
        }
    }
}

/// What the page names, as a fault's target: an instance on a node (by its pid there, the
/// same from every process), an operation's bound instance, or a node.
fn target_of(on: &FaultOn) -> Target {
    match on {
        FaultOn::Operation(op) => match &op.node {
            Some(node) => Target::OnNode {
                operation: op.operation.clone(),
                node: node.clone(),
                address: op.address.clone(),
            },
            None => Target::Bound(op.operation.clone()),
        },
        FaultOn::Node { node } => Target::Node(node.clone()),
    }
}

/// A fault's failure as the page is answered: 404 when its target is gone.
fn control_error(e: FaultError) -> ControlError {
    match &e {
        e if e.is_not_found() => ControlError::NotFound(e.to_string()),
        FaultError::Target(TargetError::Ambiguous { .. })
        | FaultError::Target(TargetError::Syntax(..))
        | FaultError::Mismatch { .. } => ControlError::Refused(e.to_string()),
        _ => ControlError::Failed(e.to_string()),
    }
}
