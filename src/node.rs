//! The embedded node: datamanagers, operations and a dispatcher in one process, no network.
//!
//! This is the default way to run marie (DESIGN.md §2). It starts the thesis' three
//! datamanagers (world 1203, feature 1201, parameter 1202) and the operations of the
//! [`marie_missions`] catalogue, each publishing itself in the registry, then runs missions
//! against them.

use marie_actors::clock::{RealClock, ScaledClock, SharedClock};
use marie_actors::dispatcher::mission::{Diagnostics, Mission};
use marie_actors::dispatcher::{self, DispatchError, DispatchEvent, RegistryCatalog, RunReport};
use marie_actors::dm::{self, DmArgs, DmConfig};
use marie_actors::eo::EoError;
use ractor::ActorCell;
use std::path::Path;
use std::sync::Arc;
use tokio::sync::mpsc;

/// How to start a node.
#[derive(Clone, Debug)]
pub struct NodeOptions {
    /// Clock speed: 1.0 is real time.
    pub speed: f64,
    /// Start the built-in operations of the mission catalogue.
    pub builtin_operations: bool,
}

impl Default for NodeOptions {
    fn default() -> Self {
        NodeOptions {
            speed: 1.0,
            builtin_operations: true,
        }
    }
}

/// Why a node could not do what was asked.
#[derive(Debug, thiserror::Error)]
pub enum NodeError {
    /// An actor did not start.
    #[error("could not start {what}: {source}")]
    Spawn {
        /// What was being started.
        what: String,
        /// Why.
        source: ractor::SpawnErr,
    },
    /// An operation did not answer while the mission was checked.
    #[error(transparent)]
    Operation(#[from] EoError),
    /// The mission is malformed or inconsistent.
    #[error("{0}")]
    Mission(Diagnostics),
    /// The dispatcher failed.
    #[error(transparent)]
    Dispatch(#[from] DispatchError),
}

/// A running embedded node.
pub struct Node {
    clock: SharedClock,
    actors: Vec<ActorCell>,
}

impl Node {
    /// Start the datamanagers and (optionally) the built-in operations.
    pub async fn start(options: NodeOptions) -> Result<Node, NodeError> {
        let clock: SharedClock = if (options.speed - 1.0).abs() < f64::EPSILON {
            RealClock::shared()
        } else {
            Arc::new(ScaledClock::new(options.speed))
        };
        let mut node = Node {
            clock: clock.clone(),
            actors: Vec::new(),
        };
        for spec in [dm::FEATURE, dm::PARAMETER, dm::WORLD] {
            let (actor, _) = dm::spawn_datamanager(DmArgs {
                id: spec.id,
                name: spec.name.to_string(),
                clock: clock.clone(),
                config: DmConfig::default(),
            })
            .await
            .map_err(|source| NodeError::Spawn {
                what: format!("datamanager {}", spec.name),
                source,
            })?;
            node.actors.push(actor.get_cell());
        }
        if options.builtin_operations {
            let cells = marie_missions::spawn_builtin(clock.clone())
                .await
                .map_err(|source| NodeError::Spawn {
                    what: "built-in operations".to_string(),
                    source,
                })?;
            node.actors.extend(cells);
        }
        Ok(node)
    }

    /// The node's clock.
    pub fn clock(&self) -> &SharedClock {
        &self.clock
    }

    /// Read, parse and check a mission against the operations running now.
    pub async fn load_mission(&self, path: &Path) -> Result<Mission, NodeError> {
        let parsed = Mission::parse_file(path).map_err(NodeError::Mission)?;
        let catalog = RegistryCatalog::gather(parsed.ops()).await?;
        parsed.validate(&catalog).map_err(NodeError::Mission)
    }

    /// Run a mission; progress events go to `events`.
    pub async fn run(
        &self,
        mission: Mission,
        events: Option<mpsc::UnboundedSender<DispatchEvent>>,
    ) -> Result<RunReport, NodeError> {
        Ok(dispatcher::run_mission(mission, self.clock.clone(), events).await?)
    }

    /// Stop every actor the node started.
    pub async fn shutdown(self) {
        for cell in self.actors.iter().rev() {
            cell.stop(None);
        }
    }
}
