//! One entry point for an application that embeds marie: its own operations and
//! datamanagers hosted under supervision, one clock for all of them, optionally a cluster
//! to join, and a [`Node`] handle to run missions on.
//!
//! A [`NodeConfig`] with a catalogue of [`OperationFactory`]s says the same, and the
//! builder makes one; what it adds is what an embedder would otherwise get wrong: every
//! operation is checked before anything starts (on one instance built by its factory: a
//! bad declaration names the operation and the problem, instead of an actor that failed
//! during start-up), duplicate names are refused, and the one clock is the node's, so
//! records stored by one module are found by a query of another.
//!
//! An operation is built by `Default` ([`NodeBuilder::operation`]), by the application's
//! closure ([`NodeBuilder::operation_from`]: how it hands an operation its dependencies)
//! or as a clone of a value ([`NodeBuilder::operation_value`]) — for every instance and
//! every restart alike. Unless it says otherwise ([`Operation::period`]) an operation
//! steps every [`DEFAULT_PERIOD`](marie_actors::eo::DEFAULT_PERIOD), 100 ms of the node's
//! clock. [`NodeBuilder::cluster`] makes the node a cluster member at start;
//! [`NodeBuilder::data_dir`] gives its datamanagers journals on disk.
//!
//! ```
//! use marie_actors::eo::{Identity, OpContext, OpError, Operation, Step};
//! use marie_vocabulary::status::{FlagDecl, StatusFlags};
//! use marie_cluster::node::{Node, RunOptions};
//!
//! #[derive(Default)]
//! struct Ping;
//! impl Operation for Ping {
//!     fn identity(&self) -> Identity {
//!         Identity::new("ping", 4200, "1.0.0", "finishes at once")
//!     }
//!     fn flags(&self) -> Vec<FlagDecl> {
//!         vec![FlagDecl::new("pinged", "it ran")]
//!     }
//!     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> {
//!         Ok(Step::Finish(StatusFlags(1)))
//!     }
//! }
//!
//! # #[tokio::main(flavor = "multi_thread", worker_threads = 2)]
//! # async fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let node = Node::builder("app").operation::<Ping>().start().await?;
//! let report = node
//!     .run(
//!         r#"
//!         [mission]
//!         name = "once"
//!         success = ["pinged"]
//!         [flags]
//!         pinged = 0
//!         [[action]]
//!         name = "ping"
//!         [action.ops.ping]
//!         "#,
//!         RunOptions::new(),
//!     )
//!     .await?;
//! assert!(report.succeeded());
//! node.shutdown().await;
//! # Ok(()) }
//! ```

use super::{
    ConfigError, DatamanagerConfig, Node, NodeConfig, NodeError, NodeOptions, OperationConfig,
    Robot, SupervisorConfig,
};
use crate::net::ClusterConfig;
use marie_actors::eo::{Operation, OperationFactory};
use marie_vocabulary::clock::{RealClock, SharedClock};
use std::any::TypeId;
use std::sync::Arc;

/// Builds a [`Node`] that hosts an application's own operations and datamanagers; see the
/// module docs.
pub struct NodeBuilder {
    config: NodeConfig,
    catalog: Vec<Registered>,
    /// Problems found while building, refused at [`NodeBuilder::start`].
    refused: Vec<ConfigError>,
    clock: Option<SharedClock>,
    robot: Option<Arc<dyn Robot>>,
}

impl std::fmt::Debug for NodeBuilder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("NodeBuilder")
            .field("config", &self.config)
            .field("operations", &self.catalog.len())
            .field("refused", &self.refused)
            .field("robot", &self.robot.as_ref().map(|r| r.describe()))
            .finish_non_exhaustive()
    }
}

/// A factory in the builder's catalogue, and the type whose `Default` builds it (`None`:
/// the application's closure or value): a second registration of the same `name@version`
/// is accepted only when it builds the same way.
struct Registered {
    factory: OperationFactory,
    by_default: Option<TypeId>,
}

impl Node {
    /// A builder for a node named `name` that hosts nothing yet and runs a dispatcher.
    pub fn builder(name: impl Into<String>) -> NodeBuilder {
        let mut config = NodeConfig::new(name);
        config.dispatcher = true;
        NodeBuilder {
            config,
            catalog: Vec::new(),
            refused: Vec::new(),
            clock: None,
            robot: None,
        }
    }
}

impl NodeBuilder {
    /// Host one instance of operation `O` (built by `O::default()`, restarted the same way
    /// by its supervisor when it crashes). An operation that needs something from the
    /// application is built by [`NodeBuilder::operation_from`] or
    /// [`NodeBuilder::operation_value`] instead.
    pub fn operation<O: Operation + Default>(self) -> Self {
        self.instances::<O>(1)
    }

    /// Host `n` instances of operation `O` (spares: when one crashes, the dispatcher takes
    /// another at once while the first restarts).
    ///
    /// ```
    /// # use marie_actors::eo::{Identity, OpContext, OpError, Operation, Step};
    /// # #[derive(Default)] struct Pump;
    /// # impl Operation for Pump {
    /// #     fn identity(&self) -> Identity { Identity::new("i-pump", 4301, "1.0.0", "pumps") }
    /// #     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> { Ok(Step::Continue) }
    /// # }
    /// # #[tokio::main] async fn main() -> Result<(), Box<dyn std::error::Error>> {
    /// let node = marie_cluster::node::Node::builder("spares").instances::<Pump>(2).start().await?;
    /// assert_eq!(node.instances("i-pump").len(), 2);
    /// node.shutdown().await;
    /// # Ok(()) }
    /// ```
    pub fn instances<O: Operation + Default>(self, n: usize) -> Self {
        self.operation_with::<O>(|c| c.with_instances(n))
    }

    /// Host operation `O` as `configure` says: instances, supervisor (declared with
    /// [`NodeBuilder::supervisor`]), restart policy.
    ///
    /// `with_instances(0)` makes a **standby**: the node starts no instance of its own,
    /// but when a mission's operation is lost and no compatible instance runs anywhere in
    /// the cluster, the dispatcher asks the nodes that allow it to start one
    /// ([`marie_actors::provision`]) — after a grace of
    /// [`provision::GRACE`](marie_actors::provision::GRACE) (1 s, or half the mission's
    /// rebind deadline if shorter) in which a supervisor's restart or a spare may appear
    /// first. The standby then runs like any instance.
    ///
    /// ```
    /// # use marie_actors::eo::{Identity, OpContext, OpError, Operation, Step};
    /// # #[derive(Default)] struct Pump;
    /// # impl Operation for Pump {
    /// #     fn identity(&self) -> Identity { Identity::new("b-pump", 4300, "1.0.0", "pumps") }
    /// #     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> { Ok(Step::Continue) }
    /// # }
    /// use marie_cluster::node::{Node, SupervisorConfig};
    /// use std::time::Duration;
    /// let builder = Node::builder("plant")
    ///     .supervisor(SupervisorConfig::new("pumps").with_intensity(3, Duration::from_secs(5)))
    ///     .operation_with::<Pump>(|c| c.with_instances(2).under("pumps"));
    /// assert_eq!(builder.config().operations[0].supervisor, "pumps");
    /// ```
    pub fn operation_with<O: Operation + Default>(
        self,
        configure: impl FnOnce(OperationConfig) -> OperationConfig,
    ) -> Self {
        self.host(
            OperationFactory::new::<O>(),
            Some(TypeId::of::<O>()),
            configure,
        )
    }

    /// Host one instance of the operation `make` builds — called again for every instance
    /// and every restart after a crash, so what it captures reaches each of them: how an
    /// application hands its operations their dependencies (a driver handle, a channel, a
    /// configuration) instead of having them look for them by a global name.
    ///
    /// `make` runs in this process: on a cluster, each node process builds its instances
    /// from the factories its own program registered (code is not shipped over the
    /// network), and can host — or start on a dispatcher's request — only those.
    ///
    /// ```
    /// use marie_actors::eo::{Identity, OpContext, OpError, Operation, Step};
    /// use std::sync::atomic::{AtomicU64, Ordering};
    /// use std::sync::Arc;
    ///
    /// struct Pump { litres: Arc<AtomicU64> }
    /// impl Operation for Pump {
    ///     fn identity(&self) -> Identity { Identity::new("m-pump", 4302, "1.0.0", "pumps") }
    ///     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> {
    ///         self.litres.fetch_add(1, Ordering::Relaxed);
    ///         Ok(Step::Continue)
    ///     }
    /// }
    ///
    /// # #[tokio::main] async fn main() -> Result<(), Box<dyn std::error::Error>> {
    /// let litres = Arc::new(AtomicU64::new(0));
    /// let meter = litres.clone();
    /// let node = marie_cluster::node::Node::builder("made")
    ///     .operation_from(move || Pump { litres: meter.clone() })
    ///     .start()
    ///     .await?;
    /// assert_eq!(node.instances("m-pump").len(), 1);
    /// node.shutdown().await;
    /// # Ok(()) }
    /// ```
    pub fn operation_from<O, F>(self, make: F) -> Self
    where
        O: Operation,
        F: Fn() -> O + Send + Sync + 'static,
    {
        self.operation_factory(OperationFactory::from_fn(make), |c| c)
    }

    /// Host one instance of operation `op`'s kind, each instance (and each restart) a clone
    /// of `op` — [`NodeBuilder::operation_from`] for an operation that is `Clone`.
    ///
    /// ```
    /// use marie_actors::eo::{Identity, OpContext, OpError, Operation, Step};
    ///
    /// #[derive(Clone)]
    /// struct Valve { line: String }
    /// impl Operation for Valve {
    ///     fn identity(&self) -> Identity { Identity::new("v-valve", 4303, "1.0.0", "opens") }
    ///     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> { Ok(Step::Continue) }
    /// }
    ///
    /// let builder = marie_cluster::node::Node::builder("valves")
    ///     .operation_value(Valve { line: "north".into() });
    /// assert_eq!(builder.config().operations[0].name, "v-valve");
    /// ```
    pub fn operation_value<O: Operation + Clone>(self, op: O) -> Self {
        self.operation_factory(OperationFactory::from_value(op), |c| c)
    }

    /// Host the operations `factory` builds ([`OperationFactory::from_fn`],
    /// [`OperationFactory::from_value`], or any other) as `configure` says — what
    /// [`NodeBuilder::operation_with`] is for `Default` operations.
    ///
    /// A node builds every instance of one `name@version` with one factory: registering
    /// another factory of the same `name@version` (two closures the builder cannot tell
    /// apart) is refused at [`NodeBuilder::start`]; host more instances with
    /// `with_instances(n)` instead.
    ///
    /// ```
    /// # use marie_actors::eo::{Identity, OpContext, OpError, Operation, Step};
    /// # struct Pump { rate: f64 }
    /// # impl Operation for Pump {
    /// #     fn identity(&self) -> Identity { Identity::new("s-pump", 4304, "1.0.0", "pumps") }
    /// #     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> { Ok(Step::Continue) }
    /// # }
    /// use marie_actors::eo::OperationFactory;
    /// // a standby: started only when a mission needs a pump and none runs anywhere
    /// let builder = marie_cluster::node::Node::builder("standby").operation_factory(
    ///     OperationFactory::from_fn(|| Pump { rate: 2.5 }),
    ///     |c| c.with_instances(0),
    /// );
    /// assert_eq!(builder.config().operations[0].instances, 0);
    /// ```
    pub fn operation_factory(
        self,
        factory: OperationFactory,
        configure: impl FnOnce(OperationConfig) -> OperationConfig,
    ) -> Self {
        self.host(factory, None, configure)
    }

    /// Add `factory` to the catalogue (once per `name@version`) and host it as `configure`
    /// says, exactly that version.
    fn host(
        mut self,
        factory: OperationFactory,
        by_default: Option<TypeId>,
        configure: impl FnOnce(OperationConfig) -> OperationConfig,
    ) -> Self {
        let name = factory.name.to_string();
        let exact = semver::VersionReq::parse(&format!("={}", factory.version))
            .unwrap_or(semver::VersionReq::STAR);
        match self
            .catalog
            .iter()
            .find(|r| r.factory.key() == factory.key())
        {
            // the same `Default` type again: one factory, more entries
            Some(known) if by_default.is_some() && known.by_default == by_default => {}
            Some(_) => self.refused.push(ConfigError::Duplicate {
                kind: "operation factory",
                name: factory.key(),
            }),
            None => self.catalog.push(Registered {
                factory,
                by_default,
            }),
        }
        self.config
            .operations
            .push(configure(OperationConfig::new(name).with_version(exact)));
        self
    }

    /// Declare a supervisor of operations (strategy, intensity) that
    /// [`NodeBuilder::operation_with`] can put operations under.
    pub fn supervisor(mut self, supervisor: SupervisorConfig) -> Self {
        self.config.supervisors.push(supervisor);
        self
    }

    /// Host a datamanager: one of marie's ([`marie_dm::FEATURE`], `WORLD`,
    /// `PARAMETER`) or the application's own, by name and id — at the node's default
    /// durability (`process` with a [`data_dir`](NodeBuilder::data_dir), else `memory`), or
    /// at its own: `DatamanagerConfig::from(FEATURE).with_durability(Durability::Sync)`
    /// ([`DatamanagerConfig::with_durability`]; `process` and `sync` need the data_dir).
    ///
    /// ```
    /// use marie_dm::{DmClient, DmSpec, FEATURE};
    /// # #[tokio::main] async fn main() -> Result<(), Box<dyn std::error::Error>> {
    /// const TANKS: DmSpec = DmSpec::new("b-tanks", 7901);
    /// let node = marie_cluster::node::Node::builder("dms")
    ///     .datamanager(FEATURE)
    ///     .datamanager(TANKS)
    ///     .start()
    ///     .await?;
    /// assert!(DmClient::lookup("b-tanks", "doc").is_ok());
    /// node.shutdown().await;
    /// # Ok(()) }
    /// ```
    ///
    /// # A replicated datamanager of the application's own
    /// Kept in replicas on three (or more) of the application's processes, each a node
    /// built like this one: every process declares it with the same replicas
    /// ([`DatamanagerConfig::with_replicas`]: node names, the preferred leader first, this
    /// node among them), a [`data_dir`](NodeBuilder::data_dir) for its replica's journal
    /// (Raft's term and vote must outlive the process) and a [`cluster`](NodeBuilder::cluster)
    /// to meet the others in. Once a majority of them run, one replica is elected leader
    /// and published under the datamanager's name: a `store` anywhere in the cluster is
    /// acknowledged once a majority journaled it, and when the leader's process dies another
    /// replica takes over and every client follows it (nothing acknowledged is lost).
    /// [`DmClient::leader_node`](marie_dm::DmClient::leader_node) says which node leads.
    /// A declaration that cannot work — fewer than three replicas, this node not among
    /// them, no data_dir, no cluster — is refused at [`NodeBuilder::start`], naming the
    /// datamanager.
    ///
    /// ```no_run
    /// use marie_cluster::net::ClusterConfig;
    /// use marie_cluster::node::{DatamanagerConfig, Node};
    /// use marie_dm::{DmClient, DmSpec, RecordKind};
    /// use std::time::Duration;
    ///
    /// const PUMP_LOG: DmSpec = DmSpec::new("pump-log", 7410);
    /// const PUMPED: RecordKind<(String, f64)> = RecordKind::new("pumped");
    ///
    /// # #[tokio::main] async fn main() -> Result<(), Box<dyn std::error::Error>> {
    /// // process "b"; "a" and "c" run the same with their own name, data_dir and address
    /// let node = Node::builder("b")
    ///     .data_dir("/var/lib/pumps/b")
    ///     .datamanager(DatamanagerConfig::from(PUMP_LOG).with_replicas(["b", "a", "c"]))
    ///     .cluster(
    ///         ClusterConfig::new("127.0.0.1:7101".parse()?, "secret")
    ///             .with_peer("127.0.0.1:7100".parse()?),
    ///     )
    ///     .start()
    ///     .await?;
    /// // a leader once a majority of the three runs; the client follows it from then on
    /// let log = DmClient::lookup_within(PUMP_LOG.name, "b", Duration::from_secs(30)).await?;
    /// let seq = log.store_kind(PUMPED, &("b".to_string(), 0.1)).await?; // in a majority now
    /// println!("seq {seq}; leader on node {}", log.leader_node().await?);
    /// node.shutdown().await;
    /// # Ok(()) }
    /// ```
    ///
    /// The builder only records the declaration, as the node will start it:
    ///
    /// ```
    /// # use marie_cluster::node::{DatamanagerConfig, Node};
    /// # const PUMP_LOG: marie_dm::DmSpec = marie_dm::DmSpec::new("pump-log", 7410);
    /// let builder = Node::builder("b")
    ///     .data_dir("/var/lib/pumps/b")
    ///     .datamanager(DatamanagerConfig::from(PUMP_LOG).with_replicas(["b", "a", "c"]));
    /// assert_eq!(builder.config().datamanagers[0].replicas, ["b", "a", "c"]);
    /// ```
    pub fn datamanager(mut self, dm: impl Into<DatamanagerConfig>) -> Self {
        self.config.datamanagers.push(dm.into());
        self
    }

    /// Keep the node's files in `dir` ([`NodeConfig::data_dir`]): each durable
    /// datamanager's journal in `dir/dm/NAME`, so what it acknowledged survives a crash of
    /// the datamanager and of the process, and a node started again on `dir` finds its
    /// records with their seqs (a replica of a replicated datamanager, its term and vote
    /// too: it needs one). The node locks `dir` while it runs: another node on it is
    /// refused ([`NodeError::DataDirInUse`]). Its datamanagers are at `process` unless they
    /// say otherwise ([`DatamanagerConfig::with_durability`]); without a data_dir they are
    /// in memory and the node writes no file.
    ///
    /// ```
    /// use marie_dm::{DmClient, Durability, FEATURE, WORLD};
    /// use marie_cluster::node::{DatamanagerConfig, Node};
    /// # #[tokio::main] async fn main() -> Result<(), Box<dyn std::error::Error>> {
    /// let dir = tempfile::tempdir()?;
    /// let node = Node::builder("kept")
    ///     .data_dir(dir.path())
    ///     .datamanager(FEATURE) // process: the node's default with a data_dir
    ///     .datamanager(DatamanagerConfig::from(WORLD).with_durability(Durability::Sync))
    ///     .start()
    ///     .await?;
    /// let world = DmClient::lookup("world", "doc")?;
    /// assert_eq!(world.stats().await?.durability, Durability::Sync);
    /// assert!(dir.path().join("dm/feature").is_dir());
    /// node.shutdown().await;
    /// # Ok(()) }
    /// ```
    pub fn data_dir(mut self, dir: impl Into<std::path::PathBuf>) -> Self {
        self.config.data_dir = Some(dir.into());
        self
    }

    /// The clock every actor of the node reads and sleeps on (default: the process's,
    /// [`RealClock::process`], which operations hosted outside the node share too). One
    /// clock for the whole node: records are stamped and queried on it.
    ///
    /// ```
    /// use marie_vocabulary::clock::RealClock;
    /// # #[tokio::main] async fn main() -> Result<(), Box<dyn std::error::Error>> {
    /// let clock = RealClock::shared();
    /// let node = marie_cluster::node::Node::builder("timed").clock(clock.clone()).start().await?;
    /// assert!(std::sync::Arc::ptr_eq(node.clock(), &clock));
    /// node.shutdown().await;
    /// # Ok(()) }
    /// ```
    pub fn clock(mut self, clock: SharedClock) -> Self {
        self.clock = Some(clock);
        self
    }

    /// A robot the node drives (its drivers, its a-priori records, its judgement of a run).
    pub fn robot(mut self, robot: Arc<dyn Robot>) -> Self {
        self.robot = Some(robot);
        self
    }

    /// Join a cluster when the node starts, and leave it at [`Node::shutdown`]: listen on
    /// `cluster.listen` (port 0: one the system picks, [`Node::transport`] tells which),
    /// dial `cluster.peers` (any one member is enough: the cluster becomes a full mesh),
    /// prove the cookie, optionally over mutual TLS, and run the failure detector
    /// ([`ClusterConfig::with_heartbeat`]; by default a silent peer is declared down within
    /// about 1.5 s — a 1.2 s deadline, [`DEFAULT_DEADLINE`](crate::net::detector::DEFAULT_DEADLINE),
    /// with a heartbeat every 240 ms). The cluster's news (nodes up, lost, down) are on
    /// the node's bus.
    ///
    /// One node per process: ractor's registry and process groups are process-wide, so two
    /// nodes of one cluster are two processes (`embedding/failover` in marie's repository
    /// is such an application, of three processes, whose mission fails over from one
    /// process to another and whose own datamanager is replicated on all three).
    ///
    /// ```no_run
    /// use marie_cluster::net::ClusterConfig;
    /// use marie_cluster::node::Node;
    /// # #[tokio::main] async fn main() -> Result<(), Box<dyn std::error::Error>> {
    /// let node = Node::builder("beta")
    ///     .cluster(
    ///         ClusterConfig::new("127.0.0.1:7101".parse()?, "secret")
    ///             .with_peer("127.0.0.1:7100".parse()?),
    ///     )
    ///     .start()
    ///     .await?;
    /// let transport = node.transport().expect("joined");
    /// transport.wait_for_peers(1, std::time::Duration::from_secs(10)).await?;
    /// node.shutdown().await; // leaves the cluster
    /// # Ok(()) }
    /// ```
    pub fn cluster(mut self, cluster: ClusterConfig) -> Self {
        self.config.cluster = Some(cluster);
        self
    }

    /// Whether the node runs a dispatcher (default: yes). A node without one only hosts.
    pub fn dispatcher(mut self, on: bool) -> Self {
        self.config.dispatcher = on;
        self
    }

    /// Change anything else of the config it builds (supervisors, restart policies, ...).
    ///
    /// ```
    /// use marie_cluster::node::Node;
    /// let builder = Node::builder("quiet").configure(|c| c.dispatcher = false);
    /// assert!(!builder.config().dispatcher);
    /// ```
    pub fn configure(mut self, change: impl FnOnce(&mut NodeConfig)) -> Self {
        change(&mut self.config);
        self
    }

    /// The config it would start.
    pub fn config(&self) -> &NodeConfig {
        &self.config
    }

    /// Check every operation's declarations (on one instance built by its factory, as
    /// every start builds them) and the config, then start the node's supervision tree —
    /// and join its cluster, if it has one ([`NodeBuilder::cluster`]). Refused: a bad
    /// declaration (named), a duplicate datamanager or supervisor, two factories of one
    /// operation version, a durable datamanager without a data_dir, a data_dir another node
    /// holds, cluster settings that cannot work, a build whose panics abort (self-healing
    /// needs them to unwind).
    pub async fn start(self) -> Result<Node, NodeError> {
        if let Some(problem) = self.refused.into_iter().next() {
            return Err(problem.into());
        }
        for registered in &self.catalog {
            registered
                .factory
                .check_declaration()
                .map_err(NodeError::Declaration)?;
        }
        let catalog = self.catalog.into_iter().map(|r| r.factory).collect();
        let mut options = NodeOptions::with_catalog(catalog)
            .with_clock(self.clock.unwrap_or_else(RealClock::process));
        if let Some(robot) = self.robot {
            options = options.with_robot(robot);
        }
        Node::start(self.config, options).await
    }
}

impl From<(&str, u32)> for DatamanagerConfig {
    fn from((name, id): (&str, u32)) -> Self {
        DatamanagerConfig::new(name, id)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use marie_actors::eo::{Identity, OpContext, OpError, Step};
    use marie_dm::DmClient;
    use marie_vocabulary::property::{ParamDecl, ParamSchema};

    #[derive(Default)]
    struct Bad;
    impl Operation for Bad {
        fn identity(&self) -> Identity {
            Identity::new("bad-decl", 4201, "1.0.0", "a default out of its range")
        }
        fn parameters(&self) -> ParamSchema {
            ParamSchema::new(vec![ParamDecl::float("speed", 9.0).range(0.0, 2.0)])
        }
        async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> {
            Ok(Step::Continue)
        }
    }

    fn refused(started: Result<Node, NodeError>) -> NodeError {
        match started {
            Ok(_) => panic!("the node started"),
            Err(e) => e,
        }
    }

    #[tokio::test]
    async fn a_bad_declaration_is_refused_naming_the_operation_before_anything_starts() {
        let err = refused(Node::builder("bad").operation::<Bad>().start().await);
        let text = err.to_string();
        assert!(
            text.contains("operation `bad-decl`") && text.contains("speed"),
            "{text}"
        );
        assert!(marie_vocabulary::registry::lookup(
            marie_vocabulary::registry::ModuleKind::Operation,
            "bad-decl"
        )
        .is_empty());
    }

    #[tokio::test]
    async fn by_default_the_node_and_operations_hosted_outside_it_share_one_clock() {
        let node = Node::builder("one-clock").start().await.expect("starts");
        let outside = marie_actors::eo::HostOptions::default().clock;
        assert!(Arc::ptr_eq(node.clock(), &outside));
        node.shutdown().await;
    }

    /// An application's own datamanager, kept in replicas on the nodes of its processes.
    const LOG: marie_dm::DmSpec = marie_dm::DmSpec::new("t-log", 7990);

    #[tokio::test]
    async fn an_applications_replicated_datamanager_that_cannot_work_is_refused_naming_why() {
        let dir = tempfile::tempdir().expect("a temporary directory");
        let log = |replicas: &[&str]| {
            DatamanagerConfig::from(LOG).with_replicas(replicas.iter().copied())
        };
        let cluster = || ClusterConfig::new("127.0.0.1:0".parse().expect("an address"), "c");
        let cases = [
            (
                Node::builder("x")
                    .cluster(cluster())
                    .datamanager(log(&["x", "y", "z"])),
                "replicas need a journal: give the node a data_dir",
            ),
            (
                Node::builder("x")
                    .data_dir(dir.path())
                    .cluster(cluster())
                    .datamanager(
                        log(&["x", "y", "z"]).with_durability(marie_dm::Durability::Memory),
                    ),
                "replicas need a journal: durability process or sync, not memory",
            ),
            (
                Node::builder("w")
                    .data_dir(dir.path())
                    .cluster(cluster())
                    .datamanager(log(&["x", "y", "z"])),
                r#"this node (w) is not among the replicas ["x", "y", "z"]"#,
            ),
            (
                Node::builder("x")
                    .data_dir(dir.path())
                    .cluster(cluster())
                    .datamanager(log(&["x", "y"])),
                "2 replicas: a majority of them cannot survive the loss of one",
            ),
            // its replicas are on other nodes: without a cluster none is ever reached
            (
                Node::builder("x")
                    .data_dir(dir.path())
                    .datamanager(log(&["x", "y", "z"])),
                r#"its replicas are on the nodes ["x", "y", "z"], and this node joins no cluster: give it one (NodeBuilder::cluster"#,
            ),
        ];
        for (builder, why) in cases {
            let text = refused(builder.start().await).to_string();
            assert!(
                text.contains("datamanager `t-log`: replicas: ") && text.contains(why),
                "{why:?} not in {text:?}"
            );
        }
        // nothing was started or published
        assert!(DmClient::lookup("t-log", "test").is_err());
    }

    #[tokio::test]
    async fn a_duplicate_datamanager_is_refused() {
        let err = refused(
            Node::builder("dup")
                .datamanager(marie_dm::FEATURE)
                .datamanager(("feature", 9999))
                .start()
                .await,
        );
        assert!(err.to_string().contains("feature"), "{err}");
    }
}
