//! The node: what it hosts, as a supervision tree, and the runs of missions on it.
//!
//! A node is configured by what it hosts ([`NodeConfig`]): datamanagers, operations (by name,
//! version and number of instances, under named supervisors with restart policies), a
//! simulated robot, a dispatcher. [`Node::start`] builds its supervision tree
//! from that config and nothing else; the operations come from a catalogue of
//! [`OperationFactory`]s and a robot plugs in through the [`Robot`] trait — a node knows no
//! robot. [`Node::run`] runs a mission ([`RunOptions`]: faults, chaos, observers); a crashed
//! operation is restarted by its supervisor and the dispatcher rebinds to the new instance,
//! and [`Node::start_instance`] starts another instance of an operation the config allows (a
//! dynamic child), for failover when no spare runs.
//!
//! A config with a cluster ([`NodeConfig::cluster`], or [`NodeBuilder::cluster`]) makes the
//! node a cluster member: [`Node::start`] starts its transport once the tree runs (listens,
//! dials the peers, runs the failure detector), publishes the cluster's news on the node's
//! bus and forwards the node's events to whoever watches the cluster; [`Node::shutdown`]
//! leaves. A cluster setting is never ignored: one that cannot work (an empty cookie, a
//! node name with `@`, a taken port, TLS files that do not load) is refused
//! ([`NodeError::Cluster`]).
//!
//! A config with a data directory ([`NodeConfig::data_dir`], [`NodeBuilder::data_dir`])
//! keeps its datamanagers' journals there, `process` durable unless a datamanager says
//! otherwise; [`Node::start`] locks the directory before anything starts and the node
//! holds it until it is dropped, so a second node on it is refused
//! ([`NodeError::DataDirInUse`]). A node started again on the directory finds its records,
//! and the robot's a-priori records are stored only in a datamanager that starts empty.
//!
//! ```
//! use marie_cluster::node::{Node, NodeConfig, NodeOptions, OperationConfig};
//! use marie_actors::eo::OperationFactory;
//! # #[derive(Default)] struct Echo;
//! # impl marie_actors::eo::Operation for Echo {
//! #   fn identity(&self) -> marie_actors::eo::Identity {
//! #       marie_actors::eo::Identity::new("echo", 4242, "1.0.0", "echo")
//! #   }
//! #   async fn step(&mut self, _: &mut marie_actors::eo::OpContext)
//! #       -> Result<marie_actors::eo::Step, marie_actors::eo::OpError> {
//! #       Ok(marie_actors::eo::Step::Finish(marie_vocabulary::status::StatusFlags(0)))
//! #   }
//! # }
//! # #[tokio::main] async fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let catalog = vec![OperationFactory::of::<Echo>("echo")];
//! let mut config = NodeConfig::new("doc-node");
//! config.operations.push(OperationConfig::new("echo").with_instances(2));
//! config.validate(&catalog)?;
//! let node = Node::start(config, NodeOptions::with_catalog(catalog)).await?;
//! assert_eq!(node.instances("echo").len(), 2);
//! node.shutdown().await;
//! # Ok(()) }
//! ```

mod audit;
mod builder;
pub mod config;
pub mod desk;
mod events;
mod membership;
mod mission_input;
mod provisioner;
mod remote_run;
mod replica_host;
pub mod robot;
mod run;
mod tree;
pub mod watchdog;

pub use builder::NodeBuilder;
pub use config::{
    ConfigError, DatamanagerConfig, NodeConfig, OperationConfig, SimulationConfig,
    SupervisorConfig, MAX_INSTANCES, OPERATIONS,
};
pub use desk::DeskRole;
pub use membership::Reincarnation;
pub use mission_input::MissionInput;
pub use remote_run::TAKEOVER_WAIT;
pub use robot::{AprioriRecord, BoxFuture, Robot, RunJudgement};
pub use run::RunOptions;

use crate::fault::FaultError;
use crate::net::{Transport, TransportError};
use marie_actors::dispatcher::mission::{Diagnostics, Mission, ParsedMission};
use marie_actors::dispatcher::{DispatchError, RegistryCatalog};
use marie_actors::eo::{EoError, OperationFactory};
use marie_dm::DmError;
use marie_dm::{DirLock, LockError};
use marie_supervision::{SupervisorError, SupervisorRef};
use marie_vocabulary::clock::{RealClock, SharedClock};
use marie_vocabulary::events::{bridge_registry, EventBus, RegistryBridge};
use marie_vocabulary::registry::{self, Instance, ModuleKind};
use membership::Membership;
use ractor::ActorCell;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicU64;
use std::sync::Arc;
use std::time::{Duration, Instant};
use tree::DATAMANAGERS;

/// What a node is built with besides its config: the operations it can build, the robot it
/// drives, the clock its actors share.
#[derive(Clone)]
pub struct NodeOptions {
    /// Every operation this node *can* host; its config picks which it *does*.
    pub catalog: Vec<OperationFactory>,
    /// The robot, if the node drives one.
    pub robot: Option<Arc<dyn Robot>>,
    /// The clock every actor of the node reads and sleeps on.
    pub clock: SharedClock,
}

impl std::fmt::Debug for Node {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Node")
            .field("name", &self.config.name)
            .field("bus", &self.bus)
            .field("robot", &self.robot.as_ref().map(|r| r.describe()))
            .finish_non_exhaustive()
    }
}

impl NodeOptions {
    /// A catalogue, no robot, the process's clock ([`RealClock::process`]).
    pub fn with_catalog(catalog: Vec<OperationFactory>) -> Self {
        NodeOptions {
            catalog,
            robot: None,
            clock: RealClock::process(),
        }
    }

    /// With a robot.
    pub fn with_robot(mut self, robot: Arc<dyn Robot>) -> Self {
        self.robot = Some(robot);
        self
    }

    /// With a clock.
    pub fn with_clock(mut self, clock: SharedClock) -> Self {
        self.clock = clock;
        self
    }
}

impl std::fmt::Debug for NodeOptions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("NodeOptions")
            .field("catalog", &self.catalog)
            .field("robot", &self.robot.as_ref().map(|r| r.describe()))
            .finish_non_exhaustive()
    }
}

/// How long an operation gets to stop before it is killed.
const OPERATION_SHUTDOWN: Duration = Duration::from_secs(1);
/// How long a member of a cluster checking a mission looks again for operations no
/// instance answered for ([`Node::check_mission`]): a few times the registry's usual
/// convergence (0.1–0.4 s after the last node listened, as `marie up` prints it).
pub const CHECK_SETTLE: Duration = Duration::from_secs(5);
/// How long it waits between two looks.
const CHECK_AGAIN: Duration = Duration::from_millis(250);

/// Why a node could not do what was asked.
#[derive(Debug, thiserror::Error)]
pub enum NodeError {
    /// The config asks for what this node cannot host.
    #[error("node config: {0}")]
    Config(#[from] ConfigError),
    /// An operation type declares something it cannot run with (found before it starts).
    #[error(transparent)]
    Declaration(marie_actors::eo::DeclarationError),
    /// The node's supervision tree did not start or refused a request.
    #[error("node supervisor: {0}")]
    Supervisor(#[from] SupervisorError),
    /// An operation did not answer while the mission was checked.
    #[error(transparent)]
    Operation(#[from] EoError),
    /// The mission is malformed or inconsistent.
    #[error("{0}")]
    Mission(Diagnostics),
    /// The dispatcher failed.
    #[error(transparent)]
    Dispatch(#[from] DispatchError),
    /// A datamanager refused or did not answer a request of the node itself.
    #[error("datamanager request failed: {0}")]
    Datamanager(#[from] DmError),
    /// A fault of a run names nothing to hit (checked before the run starts).
    #[error("--fault {spec}: {error}")]
    Fault {
        /// The fault, as written.
        spec: String,
        /// Why.
        error: FaultError,
    },
    /// Node chaos was asked where no node process may be hit.
    #[error("--chaos-nodes: {0}")]
    NodeChaos(String),
    /// A run dispatched on a desk could not be recorded: no run datamanager.
    #[error(transparent)]
    NoRunDm(#[from] desk::NoRunDm),
    /// A run could not be dispatched on another node's desk.
    #[error("{0}")]
    Desk(String),
    /// A run was asked of a node whose config runs no dispatcher.
    #[error("node `{0}` runs no dispatcher (its config says `dispatcher = false`)")]
    NoDispatcher(String),
    /// The node's cluster settings cannot work, or it could not join: a bad cookie or node
    /// name, its listen address taken, TLS files that do not load.
    #[error(transparent)]
    Cluster(#[from] TransportError),
    /// The node's data directory is held by another node — of another process or of this
    /// one — still running (its datamanagers' journals take one writer at a time).
    #[error(
        "data_dir {} is in use by another marie node{}: one node per data_dir (stop that \
         node, or give this one another data_dir)",
        dir.display(),
        holder.map(|pid| format!(" (pid {pid})")).unwrap_or_default()
    )]
    DataDirInUse {
        /// The directory.
        dir: PathBuf,
        /// The holder's process id, as its lock file says.
        holder: Option<u32>,
    },
    /// The node's data directory cannot be created or locked (said once: the reason is
    /// part of the message, not a source a chain of errors would print again).
    #[error("data_dir {}: {}", dir.display(), data_dir_problem(error))]
    DataDir {
        /// The directory.
        dir: PathBuf,
        /// Why.
        error: std::io::Error,
    },
    /// An instance was asked of an operation the config does not allow.
    #[error("node `{node}` does not host operation `{operation}` (its config allows: {allowed})")]
    NotAllowed {
        /// The node.
        node: String,
        /// The operation asked for.
        operation: String,
        /// What the config allows.
        allowed: String,
    },
}

/// A running node: the supervision tree below, built from its [`NodeConfig`].
///
/// ```text
/// node (one_for_one)
///  ├─ datamanagers (one_for_one) ── one per [[datamanager]]; a-priori records in an empty one
///  ├─ the robot's drivers           (temporary: a simulation is not restarted)
///  ├─ operations (one_for_one) ──── one EO host per operation instance
///  ├─ <other [[supervisor]]s> ───── their operations
///  ├─ dynamic (simple_one_for_one)─ instances started on request (start_instance)
///  ├─ provisioner                   (another node's requests for an instance; when the
///  │                                 config has operations)
///  ├─ replica-host                  (replicas added or dropped while the cluster runs;
///  │                                 with a data directory and a cluster)
///  └─ dispatcher-N                  (temporary, one per run; with `dispatcher = true`)
/// ```
pub struct Node {
    config: NodeConfig,
    bus: EventBus,
    _registry: Option<RegistryBridge>,
    /// The node's own tasks, aborted at shutdown: the supervisors' event bridges and the
    /// datamanagers' watchdog.
    tasks: Vec<tokio::task::JoinHandle<()>>,
    /// The robot's own tasks on a node without a dispatcher ([`Robot::dispatched_elsewhere`]).
    robot_tasks: Vec<tokio::task::JoinHandle<()>>,
    /// The robot's reporting of the latest run ([`Robot::run_starting`]).
    run_tasks: std::sync::Mutex<Vec<tokio::task::JoinHandle<()>>>,
    /// Starts instances on request (the node's own and the provisioner's); holds the
    /// node's clock and root supervisor.
    starter: provisioner::Starter,
    robot: Option<Arc<dyn Robot>>,
    runs: AtomicU64,
    /// Held while a mission runs: one run at a time.
    one_run: tokio::sync::Mutex<()>,
    /// Its place in a cluster, when its config has one.
    membership: Option<Membership>,
    /// The lock on its data directory, when its config has one: held as long as the node
    /// (declared last, so dropped after everything else of it).
    _data_dir: Option<DirLock>,
}

impl Node {
    /// Check `config` against the catalogue and start the node's supervision tree: the
    /// datamanagers (storing the robot's a-priori records), the robot's drivers, then each
    /// operation supervisor with the instances the config names.
    ///
    /// A program built with `panic = "abort"` is refused before anything starts
    /// ([`SupervisorError::PanicsAbort`], displayed as `node supervisor: supervisors need
    /// panics to unwind ...`): its supervisors could not restart a panicking operation.
    pub async fn start(mut config: NodeConfig, options: NodeOptions) -> Result<Node, NodeError> {
        // first: a node that cannot heal itself must not half-start (publish, bridge events)
        marie_supervision::require_unwinding()?;
        add_joined_replicas(&mut config);
        config.validate(&options.catalog)?;
        config.check_replicas_reachable()?;
        if let Some(cluster) = &config.cluster {
            cluster.validate(&config.name)?;
        }
        // before anything starts: a second node on the directory must not get as far as a
        // datamanager (which would wait for the first's journal) or a published module
        let data_dir = config.data_dir.as_deref().map(lock_data_dir).transpose()?;
        // one node per process (ractor's registry and pg are process-wide): its name is the
        // location every module published here shows
        marie_vocabulary::registry::set_local_node_name(&config.name);
        let bus = EventBus::new(config.name.clone(), options.clock.clone());
        // the registry's joins and leaves from the start, so the first publications are seen
        let registry = match bridge_registry(bus.clone(), None).await {
            Ok(bridge) => Some(bridge),
            Err(e) => {
                tracing::warn!("node events without the registry's: {e}");
                None
            }
        };
        let children = tree::children(&config, &options, &bus);
        let (root, _) = tree::start_root(children).await?;
        let mut tasks = events::bridge_supervisors(&bus, &root).await;
        // every datamanager it hosts, those added while it runs too
        if !config.datamanagers.is_empty() || replica_host::hosts_replicas(&config) {
            tasks.push(watchdog::spawn(root.clone()));
        }
        tracing::info!(node = %config.name, "node started");
        let starter = provisioner::Starter {
            node: config.name.clone(),
            operations: config.operations.clone(),
            catalog: options.catalog,
            clock: options.clock,
            root,
            acks: marie_dm::AckSink::publishing_on(bus.clone()),
            events: bus.clone(),
        };
        let mut node = Node {
            config,
            bus,
            _registry: registry,
            tasks,
            robot_tasks: Vec::new(),
            run_tasks: Default::default(),
            starter,
            robot: options.robot,
            runs: AtomicU64::new(0),
            one_run: tokio::sync::Mutex::new(()),
            membership: None,
            _data_dir: data_dir,
        };
        // the runs are dispatched elsewhere: the robot tells what it sees without them
        if let (Some(robot), false) = (&node.robot, node.config.dispatcher) {
            node.robot_tasks = robot.dispatched_elsewhere(&node.bus);
        }
        if !node.config.operations.is_empty() {
            let spec = provisioner::child_spec(node.starter.clone());
            if let Err(e) = node.starter.root.start_child(spec).await {
                tracing::warn!("the node will not start instances on request: {e}");
            }
        }
        node.start_replica_host().await;
        if let Some(role) = node.config.desk {
            let spec = desk::child_spec(desk::DeskArgs {
                node: node.config.name.clone(),
                role,
                clock: node.starter.clock.clone(),
                bus: node.bus.clone(),
                root: node.starter.root.clone(),
            });
            if let Err(e) = node.starter.root.start_child(spec).await {
                node.shutdown().await;
                return Err(e.into());
            }
        }
        // joined last: peers see the node's modules once they all run
        if let Some(cluster) = &node.config.cluster {
            let joined =
                Membership::join(&node.config, cluster, &node.bus, node.starter.root.clone()).await;
            match joined {
                Ok(membership) => node.membership = Some(membership),
                Err(e) => {
                    node.shutdown().await;
                    return Err(e.into());
                }
            }
        }
        Ok(node)
    }

    /// Start the replica host, on a node that hosts replicas on request
    /// ([`crate::replicas`]); a node that cannot still runs, and says so.
    async fn start_replica_host(&self) {
        if !replica_host::hosts_replicas(&self.config) {
            return;
        }
        let spec = replica_host::child_spec(replica_host::Host {
            config: self.config.clone(),
            clock: self.starter.clock.clone(),
            events: self.bus.clone(),
            root: self.starter.root.clone(),
            dropped: Default::default(),
        });
        if let Err(e) = self.starter.root.start_child(spec).await {
            tracing::warn!("the node will not host replicas on request: {e}");
        }
    }

    /// The config the node was built from.
    pub fn config(&self) -> &NodeConfig {
        &self.config
    }

    /// The node's root supervisor (for introspection: `which_children`, events).
    pub fn supervisor(&self) -> &SupervisorRef {
        &self.starter.root
    }

    /// The default supervisor of the node's operations ([`OPERATIONS`]), as it is now (it is
    /// a new actor after it was restarted).
    pub async fn operation_supervisor(&self) -> Result<SupervisorRef, NodeError> {
        self.child_supervisor(OPERATIONS).await
    }

    /// The supervisor of the node's datamanagers, as it is now.
    pub async fn datamanager_supervisor(&self) -> Result<SupervisorRef, NodeError> {
        self.child_supervisor(DATAMANAGERS).await
    }

    /// One of the root's child supervisors by name, as it is now.
    pub async fn child_supervisor(&self, id: &str) -> Result<SupervisorRef, NodeError> {
        tree::child_supervisor(&self.starter.root, id).await
    }

    /// The node's event bus: every dispatcher, binding, supervisor, registry, fault and robot
    /// event of this node, stamped with the mission clock and the node's name
    /// ([`marie_vocabulary::events`] documents the schema). Subscribe before a run to see all of
    /// it.
    pub fn events(&self) -> &EventBus {
        &self.bus
    }

    /// The node's clock.
    pub fn clock(&self) -> &SharedClock {
        &self.starter.clock
    }

    /// The robot the node drives, if any.
    pub fn robot(&self) -> Option<&Arc<dyn Robot>> {
        self.robot.as_ref()
    }

    /// The node's transport, when its config has a cluster
    /// ([`NodeConfig::cluster`], [`NodeBuilder::cluster`]): the address it listens on,
    /// the peers it sees, [`Transport::wait_for_peers`], and the cluster's news as they
    /// come ([`Transport::events`]; they are on the node's bus too).
    pub fn transport(&self) -> Option<&Transport> {
        self.membership.as_ref().map(Membership::transport)
    }

    /// Each time this node restarts its operations as a new incarnation because it was
    /// itself frozen past its peers' deadline (it does so by itself when it joined a
    /// cluster; see [`Node::reincarnate`]); `None` when the node is not in a cluster.
    pub fn reincarnations(&self) -> Option<tokio::sync::broadcast::Receiver<Reincarnation>> {
        self.membership.as_ref().map(Membership::reincarnations)
    }

    /// The live instances of operation `name` (or id) in the registry.
    pub fn instances(&self, name: &str) -> Vec<Instance> {
        registry::lookup(ModuleKind::Operation, name)
    }

    /// Start another instance of operation `name` — of the newest version matching `version`
    /// that the config allows — as a dynamic child (the node's `dynamic` supervisor is OTP's
    /// `simple_one_for_one`: instances of one template, "an operation instance", started on
    /// request, permanent). Failover uses this when no spare runs. Refused when the config
    /// does not host that operation.
    pub async fn start_instance(
        &self,
        name: &str,
        version: &semver::VersionReq,
    ) -> Result<ActorCell, NodeError> {
        self.starter.start(name, version).await
    }

    /// Restart every operation instance this node runs — as a new incarnation: new actors,
    /// no activation, no state — and stop the dynamic ones. What a node does after it was
    /// frozen past its failure detector's deadline: its peers have declared it down and
    /// replaced its operations, so whatever its old instances were doing is stale (the
    /// receivers refuse their commands by epoch anyway). Restarts through the supervisors'
    /// API, which do not count as crashes. Gives how many instances were restarted. A node
    /// that joined a cluster through its config does this by itself when its transport
    /// finds it was frozen ([`Node::reincarnations`] tells each time).
    pub async fn reincarnate(&self) -> Result<usize, NodeError> {
        tree::reincarnate(&self.starter.root, &self.config).await
    }

    /// Read, parse and check a mission against the operations running now.
    pub async fn load_mission(&self, path: &Path) -> Result<Mission, NodeError> {
        let parsed = ParsedMission::parse_file(path).map_err(NodeError::Mission)?;
        self.check_mission(&parsed).await
    }

    /// Check a parsed mission against the operations running now (stage 2 of
    /// [`marie_actors::dispatcher::mission`]). Every live instance of every operation is
    /// asked and chosen among; the mission carries those choices
    /// ([`Mission::checked`]) to its run, which binds them unless an instance changed
    /// since (the chosen one gone, busy or silent, a new one of that operation) — so a
    /// checked mission is not selected again at its run.
    ///
    /// A member of a cluster that finds no answering instance of an operation looks again
    /// for up to [`CHECK_SETTLE`]: it may have joined just now and not heard every node's
    /// modules yet, or still list those of a session of its own that just ended (a kept-up
    /// cluster's soak: one run in 40 was refused "unknown operation `ultrasonic`" with
    /// `ultrasonic` among those it listed).
    pub async fn check_mission(&self, parsed: &ParsedMission) -> Result<Mission, NodeError> {
        let until = Instant::now() + CHECK_SETTLE;
        let mut catalog = RegistryCatalog::for_mission(parsed).await?;
        while !catalog.unanswered().is_empty()
            && Instant::now() < until
            && crate::net::heartbeat::reach().await.is_some()
        {
            tracing::info!(unanswered = ?catalog.unanswered(), "no instance of these answered yet: looking again");
            tokio::time::sleep(CHECK_AGAIN).await;
            catalog = RegistryCatalog::for_mission(parsed).await?;
        }
        let mission = parsed.validate(&catalog).map_err(NodeError::Mission)?;
        // every parameter is known to some instance; one must also take them all, in a
        // version the mission accepts (selection, as the dispatcher will choose)
        let unfit: Vec<_> = catalog
            .unfit()
            .iter()
            .map(|(key, why)| parsed.op_diagnostic(key, why.clone()))
            .collect();
        if unfit.is_empty() {
            Ok(mission)
        } else {
            Err(NodeError::Mission(
                marie_vocabulary::diagnostic::Diagnostics(unfit),
            ))
        }
    }

    /// Abort the robot's reporting of the latest run.
    pub(super) fn abort_run_tasks(&self) {
        let tasks = std::mem::take(&mut *self.run_tasks.lock().unwrap_or_else(|e| e.into_inner()));
        tasks.iter().for_each(tokio::task::JoinHandle::abort);
    }

    /// Leave the cluster if the node joined one (its sessions closed: the peers see its
    /// modules leave at once), then stop the node's supervision tree, children in reverse
    /// start order, and wait for it (a datamanager's journal is written out as it stops);
    /// last, let go of the data directory.
    pub async fn shutdown(mut self) {
        if let Some(membership) = self.membership.take() {
            membership.leave().await;
        }
        for task in &self.robot_tasks {
            task.abort();
        }
        self.abort_run_tasks();
        self.starter.root.stop().await;
        for task in &self.tasks {
            task.abort();
        }
        tracing::info!(node = %self.config.name, "node stopped");
    }
}

/// Add to `config` the replicas added to the node while the cluster ran, which its data
/// directory describes ([`crate::replicas::joined`]), unless the config declares the
/// datamanager itself; only on a node that hosts replicas on request (a data directory and
/// a cluster).
fn add_joined_replicas(config: &mut NodeConfig) {
    let Some(data_dir) = config.data_dir.as_deref() else {
        return;
    };
    if config.cluster.is_none() {
        return;
    }
    for dm in crate::replicas::joined::read_all(data_dir) {
        match config.datamanagers.iter().any(|own| own.name == dm.name) {
            true => {
                tracing::warn!(dm = %dm.name, "a replica added while the cluster ran is declared in the node's config too: the declaration is used")
            }
            false => {
                tracing::info!(node = %config.name, dm = %dm.name, "a replica added while the cluster ran starts again");
                config.datamanagers.push(dm);
            }
        }
    }
}

/// Lock a node's data directory (creating it), or say who holds it.
fn lock_data_dir(dir: &Path) -> Result<DirLock, NodeError> {
    DirLock::acquire(dir).map_err(|e| match e {
        LockError::Held { dir, holder } => NodeError::DataDirInUse { dir, holder },
        LockError::Io { dir, source } => NodeError::DataDir { dir, error: source },
    })
}

/// What is wrong with a data directory that cannot be made or locked, in a user's words:
/// a path that is a file (or under one) says so rather than `File exists (os error 17)`.
fn data_dir_problem(error: &std::io::Error) -> String {
    use std::io::ErrorKind;
    match error.kind() {
        ErrorKind::AlreadyExists | ErrorKind::NotADirectory => {
            "it is a file, not a directory (give a directory, or a path that does not exist \
             yet)"
                .to_string()
        }
        ErrorKind::PermissionDenied => {
            format!("cannot be created or written by this user ({error})")
        }
        _ => error.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A build with `panic = "abort"` cannot be run from a test (tests always unwind; the
    /// refusal itself is tested by marie-supervision's `panic_abort` fixture): this pins what
    /// `Node::start` then returns, as a user reads it.
    #[test]
    fn a_node_refused_for_aborting_panics_says_why_and_how_to_fix_it() {
        let text = NodeError::from(SupervisorError::PanicsAbort).to_string();
        assert!(
            text.starts_with("node supervisor: supervisors need panics to unwind"),
            "{text}"
        );
        assert!(text.contains("panic = \"unwind\""), "{text}");
    }
}
