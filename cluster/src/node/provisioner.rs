//! The node's answer to [`marie_actors::provision`]: another instance of an operation its
//! config allows, started on request as a dynamic child — how failover finds a stand-in
//! when no compatible instance runs anywhere.

use super::tree;
use super::{NodeError, OperationConfig};
use marie_actors::eo::{HostOptions, OperationFactory};
use marie_actors::provision::{self, ProvisionMsg, Refusal};
use marie_supervision::{ChildSpec, SupervisorRef};
use marie_vocabulary::clock::SharedClock;
use ractor::{Actor, ActorCell, ActorProcessingErr, ActorRef};

/// Child id of the provisioner under the node's root supervisor.
pub(crate) const PROVISIONER: &str = "provisioner";

/// The provisioner as a permanent child of the node's root: restarted (and published
/// again) if it crashes, stopped with the node. Added once the root runs, since it starts
/// instances through the root it is a child of.
pub(crate) fn child_spec(starter: Starter) -> ChildSpec {
    ChildSpec::worker(PROVISIONER, move |sup| {
        let starter = starter.clone();
        async move {
            let (actor, _) = Actor::spawn_linked(None, Provisioner, starter, sup).await?;
            Ok(actor.get_cell())
        }
    })
}

/// What starting an instance needs: what the config allows (its operations), the catalogue
/// (how to build them), the clock, and the root supervisor (whose `dynamic` child starts
/// them). Built once by the node; the provisioner holds a clone.
#[derive(Clone)]
pub(crate) struct Starter {
    pub(crate) node: String,
    pub(crate) operations: Vec<OperationConfig>,
    pub(crate) catalog: Vec<OperationFactory>,
    pub(crate) clock: SharedClock,
    pub(crate) root: SupervisorRef,
    /// Where the instances' datamanager clients tell what they get acknowledged (the
    /// node's bus).
    pub(crate) acks: marie_dm::AckSink,
    /// Where the instances tell a change of their parameters (the node's bus).
    pub(crate) events: marie_vocabulary::events::EventBus,
}

impl Starter {
    /// See [`super::Node::start_instance`].
    pub(crate) async fn start(
        &self,
        name: &str,
        version: &semver::VersionReq,
    ) -> Result<ActorCell, NodeError> {
        let chosen = self
            .operations
            .iter()
            .flat_map(|op| {
                self.catalog
                    .iter()
                    .filter(move |f| op.allows(f) && f.name == name)
                    .map(move |f| (op, f))
            })
            .filter(|(_, f)| f.semver().is_some_and(|v| version.matches(&v)))
            .max_by_key(|(_, f)| f.semver());
        let Some((op, factory)) = chosen else {
            let allowed: Vec<String> = self
                .operations
                .iter()
                .map(|o| format!("{}@{}", o.name, o.version))
                .collect();
            return Err(NodeError::NotAllowed {
                node: self.node.clone(),
                operation: format!("{name}@{version}"),
                allowed: allowed.join(", "),
            });
        };
        let cell = tree::child_supervisor(&self.root, tree::DYNAMIC)
            .await?
            .start_dynamic(tree::DynamicOp {
                factory: factory.clone(),
                host: HostOptions {
                    acks: Some(self.acks.clone()),
                    events: Some(self.events.clone()),
                    // the entry's pin and knob, as its configured instances have them
                    pinned: op.pin,
                    fail_first_activations: op.fail_first_activations,
                    ..HostOptions::with_clock(self.clock.clone())
                },
            })
            .await?;
        tracing::info!(node = %self.node, op = %factory.key(), "dynamic instance started");
        Ok(cell)
    }
}

/// The provisioner actor, published in [`provision::GROUP`].
pub(crate) struct Provisioner;

impl Actor for Provisioner {
    type Msg = ProvisionMsg;
    type State = Starter;
    type Arguments = Starter;

    async fn pre_start(
        &self,
        myself: ActorRef<ProvisionMsg>,
        starter: Starter,
    ) -> Result<Starter, ActorProcessingErr> {
        provision::publish(myself.get_cell());
        Ok(starter)
    }

    async fn handle(
        &self,
        _myself: ActorRef<ProvisionMsg>,
        msg: ProvisionMsg,
        starter: &mut Starter,
    ) -> Result<(), ActorProcessingErr> {
        let ProvisionMsg::Start {
            operation,
            version,
            reply,
        } = msg;
        let answer = match semver::VersionReq::parse(&version) {
            Err(e) => Err(Refusal::Requirement {
                requirement: version,
                reason: e.to_string(),
            }),
            Ok(req) => match starter.start(&operation, &req).await {
                Ok(_) => Ok(starter.node.clone()),
                Err(NodeError::NotAllowed {
                    node,
                    operation,
                    allowed,
                }) => Err(Refusal::NotAllowed {
                    node,
                    operation,
                    allowed,
                }),
                Err(e) => Err(Refusal::Failed {
                    node: starter.node.clone(),
                    operation: format!("{operation}@{req}"),
                    reason: e.to_string(),
                }),
            },
        };
        let _ = reply.send(answer);
        Ok(())
    }
}
