//! The node's answer to [`marie_actors::provision`]: another instance of an operation its
//! config allows, started on request as a dynamic child — how failover finds a stand-in
//! when no compatible instance runs anywhere.

use super::tree;
use super::{NodeConfig, NodeError};
use marie_actors::clock::SharedClock;
use marie_actors::eo::{HostOptions, OperationFactory};
use marie_actors::provision::{self, ProvisionMsg};
use marie_supervision::{SupervisorError, SupervisorRef};
use ractor::{Actor, ActorCell, ActorProcessingErr, ActorRef};

/// What starting an instance needs: the config (what is allowed), the catalogue (how to
/// build it), the clock, and the root supervisor (whose `dynamic` child starts it).
#[derive(Clone)]
pub(crate) struct Starter {
    pub(crate) config: NodeConfig,
    pub(crate) catalog: Vec<OperationFactory>,
    pub(crate) clock: SharedClock,
    pub(crate) root: SupervisorRef,
}

impl Starter {
    /// See [`super::Node::start_instance`].
    pub(crate) async fn start(
        &self,
        name: &str,
        version: &semver::VersionReq,
    ) -> Result<ActorCell, NodeError> {
        let chosen = self
            .config
            .operations
            .iter()
            .flat_map(|op| {
                self.catalog
                    .iter()
                    .filter(move |f| op.allows(f) && f.name == name)
            })
            .filter(|f| f.semver().is_some_and(|v| version.matches(&v)))
            .max_by_key(|f| f.semver());
        let Some(factory) = chosen else {
            let allowed: Vec<String> = self
                .config
                .operations
                .iter()
                .map(|o| format!("{}@{}", o.name, o.version))
                .collect();
            return Err(NodeError::NotAllowed {
                node: self.config.name.clone(),
                operation: format!("{name}@{version}"),
                allowed: allowed.join(", "),
            });
        };
        let sup = self
            .root
            .which_children()
            .await?
            .into_iter()
            .find(|c| c.id == tree::DYNAMIC)
            .and_then(|c| c.state.actor().cloned())
            .and_then(SupervisorRef::from_cell)
            .ok_or_else(|| {
                NodeError::Supervisor(SupervisorError::NotFound(tree::DYNAMIC.to_string()))
            })?;
        let cell = sup
            .start_dynamic(tree::DynamicOp {
                factory: factory.clone(),
                host: HostOptions::with_clock(self.clock.clone()),
            })
            .await?;
        tracing::info!(node = %self.config.name, op = %factory.key(), "dynamic instance started");
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
            Err(e) => Err(format!("`{version}` is not a version requirement: {e}")),
            Ok(req) => match starter.start(&operation, &req).await {
                Ok(_) => Ok(starter.config.name.clone()),
                Err(e) => Err(e.to_string()),
            },
        };
        let _ = reply.send(answer);
        Ok(())
    }
}
