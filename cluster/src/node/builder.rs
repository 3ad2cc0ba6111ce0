//! One entry point for an application that embeds marie: its own operations and
//! datamanagers hosted under supervision, one clock for all of them, and a [`Node`] handle
//! to run missions on.
//!
//! A [`NodeConfig`] with a catalogue of [`OperationFactory`]s says the same, and the
//! builder makes one; what it adds is what an embedder would otherwise get wrong: every
//! operation *type* is checked before anything starts (a bad declaration names the
//! operation and the problem, instead of an actor that failed during start-up), duplicate
//! names are refused, and the one clock is the node's, so records stored by one module are
//! found by a query of another.
//!
//! ```
//! use marie_actors::eo::{Identity, OpContext, OpError, Operation, Step};
//! use marie_actors::flags::{FlagDecl, StatusFlags};
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
    DatamanagerConfig, Node, NodeConfig, NodeError, NodeOptions, OperationConfig, Robot,
    SupervisorConfig,
};
use marie_actors::clock::{RealClock, SharedClock};
use marie_actors::eo::{check_declaration, Operation, OperationFactory};
use std::sync::Arc;

/// Builds a [`Node`] that hosts an application's own operations and datamanagers; see the
/// module docs.
pub struct NodeBuilder {
    config: NodeConfig,
    catalog: Vec<OperationFactory>,
    /// Each operation type's declarations, checked at [`NodeBuilder::start`].
    checks: Vec<Box<dyn Fn() -> Result<(), NodeError> + Send + Sync>>,
    clock: Option<SharedClock>,
    robot: Option<Arc<dyn Robot>>,
}

impl Node {
    /// A builder for a node named `name` that hosts nothing yet and runs a dispatcher.
    pub fn builder(name: impl Into<String>) -> NodeBuilder {
        let mut config = NodeConfig::new(name);
        config.dispatcher = true;
        NodeBuilder {
            config,
            catalog: Vec::new(),
            checks: Vec::new(),
            clock: None,
            robot: None,
        }
    }
}

impl NodeBuilder {
    /// Host one instance of operation `O` (built by `O::default()`, restarted the same way
    /// by its supervisor when it crashes).
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
        mut self,
        configure: impl FnOnce(OperationConfig) -> OperationConfig,
    ) -> Self {
        let factory = OperationFactory::new::<O>();
        let name = factory.name.to_string();
        if !self
            .catalog
            .iter()
            .any(|f| f.name == factory.name && f.version == factory.version)
        {
            self.catalog.push(factory);
            self.checks.push(Box::new(|| {
                check_declaration(&O::default()).map_err(NodeError::Declaration)
            }));
        }
        let version = O::default().identity().version;
        let exact =
            semver::VersionReq::parse(&format!("={version}")).unwrap_or(semver::VersionReq::STAR);
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

    /// Host a datamanager: one of marie's ([`marie_actors::dm::FEATURE`], `WORLD`,
    /// `PARAMETER`) or the application's own, by name and id.
    ///
    /// ```
    /// use marie_actors::dm::{DmClient, DmSpec, FEATURE};
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
    pub fn datamanager(mut self, dm: impl Into<DatamanagerConfig>) -> Self {
        self.config.datamanagers.push(dm.into());
        self
    }

    /// The clock every actor of the node reads and sleeps on (default: the process's,
    /// [`RealClock::process`], which operations hosted outside the node share too). One
    /// clock for the whole node: records are stamped and queried on it.
    ///
    /// ```
    /// use marie_actors::clock::RealClock;
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

    /// Check every operation type's declarations and the config, then start the node's
    /// supervision tree. Refused: a bad declaration (named), a duplicate datamanager or
    /// supervisor, a build whose panics abort (self-healing needs them to unwind).
    pub async fn start(self) -> Result<Node, NodeError> {
        for check in &self.checks {
            check()?;
        }
        let mut options = NodeOptions::with_catalog(self.catalog)
            .with_clock(self.clock.unwrap_or_else(RealClock::process));
        if let Some(robot) = self.robot {
            options = options.with_robot(robot);
        }
        Node::start(self.config, options).await
    }
}

impl From<(&str, u32)> for DatamanagerConfig {
    fn from((name, id): (&str, u32)) -> Self {
        DatamanagerConfig {
            name: name.to_string(),
            id,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use marie_actors::eo::{Identity, OpContext, OpError, Step};
    use marie_actors::property::{ParamDecl, ParamSchema};

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
        assert!(marie_actors::registry::lookup(
            marie_actors::registry::ModuleKind::Operation,
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

    #[tokio::test]
    async fn a_duplicate_datamanager_is_refused() {
        let err = refused(
            Node::builder("dup")
                .datamanager(marie_actors::dm::FEATURE)
                .datamanager(("feature", 9999))
                .start()
                .await,
        );
        assert!(err.to_string().contains("feature"), "{err}");
    }
}
