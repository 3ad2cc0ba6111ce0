//! `NodeConfig`: a node is configured by what it hosts.
//!
//! A node config says the node's name; which operations it hosts — by name, with a version
//! requirement and a number of instances, each under which supervisor and restart policy —;
//! which datamanagers, and how durable each is; whether it runs the simulation (world, seed)
//! and the cart's drivers; whether it runs a dispatcher; where it keeps its files.
//! [`Node::start`](super::Node::start) builds its supervision tree from that and nothing
//! else. The same config is a TOML file (for `marie run --node FILE`, `missions/nodes/*.toml`)
//! and a Rust value (for embedders).
//!
//! ```toml
//! [node]
//! name = "v1-only"
//! dispatcher = true            # default true; "active" or "standby": a dispatcher desk
//!                              # (runs a cluster's missions / takes a lost one's run over)
//! data_dir = "data/v1-only"    # optional, relative to this file: the datamanagers' journals
//!                              # (locked: one node at a time); default none: no file written
//!
//! [[datamanager]]              # the thesis' three by name; another needs an `id`
//! name = "feature"
//! durability = "sync"          # memory | process | sync; default process with a data_dir,
//!                              # memory without (process and sync need the data_dir)
//! [[datamanager]]
//! name = "parameter"
//! [[datamanager]]
//! name = "world"
//!
//! [simulation]                 # optional: a simulated robot
//! world = "../worlds/lab.toml" # relative to this file; default: the mission's world
//! seed = 1                     # default: the command line's --seed
//! drivers = true               # the cart's drivers (default true)
//!
//! [[supervisor]]               # optional: `operations` (one_for_one, 5 in 10 s) always exists
//! name = "sensing"
//! strategy = "one_for_all"     # one_for_one | one_for_all | rest_for_one
//! max_restarts = 3
//! period_s = 5
//!
//! [cluster]                   # optional: a member of a cluster (`marie node --config FILE`)
//! listen = "127.0.0.1:7101"    # where peers reach it
//! peers = ["127.0.0.1:7100"]   # whom to join; any one member is enough
//! cookie = "thesis"            # shared secret: a peer with another cookie is refused
//!
//! [[operation]]
//! name = "wall-follower"
//! version = "1"                # a semver requirement; default "*": every version built in
//! instances = 1                # default 1; 0 hosts none but allows dynamic instances
//! supervisor = "operations"    # default
//! restart = "permanent"        # permanent | transient | temporary
//! pin = false                  # true: a mission's binding to an instance of this entry
//!                              # runs on its version for the rest of the mission (see
//!                              # OperationConfig::pin)
//! fail_first_activations = 0   # a test knob: each instance's first N activations fail at
//!                              # once (default 0; see OperationConfig::fail_first_activations)
//! ```
//!
//! Every problem — unknown key, wrong type, a number out of range, an operation or version
//! the node cannot host, a supervisor nobody declared, a durable datamanager on a node
//! without a `data_dir` — is a diagnostic at its `file:line:column` (the shared
//! [`marie_vocabulary::diagnostic`] reader).

pub(crate) mod load;

pub(crate) use load::socket_addr;

use marie_actors::dispatcher::checkpoint::{CHECKPOINTS_KEPT, CHECKPOINT_CLASS};
use marie_actors::eo::OperationFactory;
use marie_dm::{self as dm, DmSpec, Durability};
use marie_supervision::{Restart, Strategy};
use marie_vocabulary::diagnostic::Diagnostic;
use std::path::PathBuf;
use std::time::Duration;

/// Name of the operation supervisor every node has.
pub const OPERATIONS: &str = "operations";

/// Default restart intensity of a supervisor: restarts per [`DEFAULT_PERIOD`].
pub const DEFAULT_RESTARTS: usize = 5;

/// Default window of a supervisor's restart intensity.
pub const DEFAULT_PERIOD: Duration = Duration::from_secs(10);

/// Most instances one `[[operation]]` may ask for.
pub const MAX_INSTANCES: usize = 64;

/// Most restarts an intensity may allow (beyond that, "never give up" is meant: say so with
/// a long period instead).
pub const MAX_RESTARTS: usize = 10_000;

/// Longest intensity window, seconds.
pub const MAX_PERIOD_S: f64 = 86_400.0;

/// What one node hosts.
#[derive(Clone, Debug, PartialEq)]
pub struct NodeConfig {
    /// The node's name (shown in the registry's locations and in every event).
    pub name: String,
    /// Whether the node runs missions (a dispatcher per run).
    pub dispatcher: bool,
    /// The node's dispatcher desk, if it runs one (`dispatcher = "active"` or
    /// `"standby"`): it runs missions other members of a cluster dispatch on it, and takes
    /// a lost dispatcher's run over ([`super::desk`]).
    pub desk: Option<super::DeskRole>,
    /// The datamanagers it hosts.
    pub datamanagers: Vec<DatamanagerConfig>,
    /// Operation supervisors besides [`OPERATIONS`], which always exists.
    pub supervisors: Vec<SupervisorConfig>,
    /// The operations it hosts.
    pub operations: Vec<OperationConfig>,
    /// A simulated robot, if the node runs one.
    pub simulation: Option<SimulationConfig>,
    /// Where it listens and whom it joins, when it is a cluster member: [`Node::start`]
    /// joins the cluster with it and [`Node::shutdown`] leaves (`marie node --config FILE`
    /// reads it from the file's `[cluster]` table).
    ///
    /// [`Node::start`]: super::Node::start
    /// [`Node::shutdown`]: super::Node::shutdown
    pub cluster: Option<crate::net::ClusterConfig>,
    /// Where the node keeps what must outlive its process: each durable datamanager's
    /// journal in `DATA_DIR/dm/NAME` ([`marie_dm::journal_dir`]). `None`: the
    /// node writes no file, and its datamanagers are in memory only.
    ///
    /// [`Node::start`](super::Node::start) locks the directory for the node's life, before
    /// anything starts: a second node on it — another process, or a second start by mistake
    /// — is refused at once and by name
    /// ([`NodeError::DataDirInUse`](super::NodeError::DataDirInUse)) instead of half
    /// starting and finding each journal held. Its presence also makes `process` the
    /// default durability of the node's datamanagers ([`NodeConfig::durability_of`]): a
    /// node given a place for its data means to keep it. In a file it is `[node] data_dir`,
    /// relative to the file's directory.
    pub data_dir: Option<PathBuf>,
}

/// One datamanager a node hosts.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DatamanagerConfig {
    /// Registry name.
    pub name: String,
    /// Numeric id (the thesis': feature 1201, parameter 1202, world 1203).
    pub id: u32,
    /// How durable its acknowledged writes are; `None`: the node's default
    /// ([`NodeConfig::durability_of`]: `process` when the node has a
    /// [`data_dir`](NodeConfig::data_dir), else `memory`). Per datamanager because their
    /// data differ: sensor echoes a run recomputes need no disk, a map learned over days
    /// may need `sync` (survives a power loss, at an `fdatasync` per batch). `process` and
    /// `sync` need the node's `data_dir`; a config asking for them without one is refused.
    pub durability: Option<Durability>,
    /// The nodes that keep a replica of it, the preferred leader first, this node among them
    /// (empty: no replicas). Every node named hosts a `[[datamanager]]` of the same name and
    /// the same list; a write is acknowledged once a majority of them hold it, and when the
    /// leader's node is lost another replica takes over ([`marie_dm::Replication`]).
    /// Three or more, with a journal (`process` or `sync`).
    pub replicas: Vec<String>,
    /// With replicas: applied entries the leader keeps in memory to catch a lagging replica
    /// up, beyond which it sends a snapshot of the store (`None`:
    /// [`Replication::DEFAULT_CATCH_UP`](marie_dm::Replication::DEFAULT_CATCH_UP)).
    /// In a file, `catch_up = 10000`.
    pub catch_up: Option<usize>,
    /// Most records kept per class without a bound of its own (`None`:
    /// [`DmConfig::DEFAULT_RETENTION`](marie_dm::DmConfig::DEFAULT_RETENTION), 10 000):
    /// storing one more drops the oldest of that class. The first record a class drops is
    /// told (a warning, and a `dm_retention` event on the node's bus); the counts are in the
    /// datamanager's stats. In a file, `retention = 50000`.
    pub retention: Option<usize>,
    /// Bounds of particular classes (`class → most records kept`). In a file,
    /// `class_retention = { sonar = 100000, wall = 500 }`.
    pub class_retention: std::collections::BTreeMap<String, usize>,
    /// This node's replica was added while the datamanager ran (`marie dm add-replica`,
    /// an automatic replacement), not declared: it starts as a replica that joins
    /// ([`marie_dm::Replication::joining`]) — a learner until the leader promotes it, never
    /// campaigning on the strength of [`replicas`](Self::replicas), which are then only
    /// the voters it first asks (its journal's configuration, once it has one, is what it
    /// follows). See [`crate::replicas`].
    pub joined: bool,
    /// With replicas: how long a replica's node may be gone before the leader replaces
    /// it — adds a replica on a [spare](Self::spares), waits for its promotion, removes the
    /// gone one (`None`: never; `marie dm add-replica`/`remove-replica` do it by hand). In a
    /// file, `replace_after = 30` (seconds).
    pub replace_after: Option<std::time::Duration>,
    /// The nodes that may take a gone replica's place, in the order tried (empty: any live
    /// node that hosts replicas and keeps none of this datamanager). In a file,
    /// `spares = ["spare1", "spare2"]`.
    pub spares: Vec<String>,
}

impl DatamanagerConfig {
    /// Datamanager `name` with numeric `id`, at the node's default durability.
    pub fn new(name: impl Into<String>, id: u32) -> Self {
        DatamanagerConfig {
            name: name.into(),
            id,
            durability: None,
            replicas: Vec::new(),
            catch_up: None,
            retention: None,
            class_retention: Default::default(),
            joined: false,
            replace_after: None,
            spares: Vec::new(),
        }
    }

    /// How the replica of this datamanager on node `me` replicates (`None`: it keeps no
    /// replicas): one of the declared replicas, or one that [joined](Self::joined).
    pub fn replication(&self, me: &str) -> Option<marie_dm::Replication> {
        if self.replicas.is_empty() {
            return None;
        }
        let r = match self.joined {
            true => marie_dm::Replication::joining(me, self.replicas.clone()),
            false => marie_dm::Replication::new(me, self.replicas.clone()),
        };
        Some(match self.catch_up {
            Some(n) => r.with_catch_up(n),
            None => r,
        })
    }

    /// Keep replicas on the nodes `nodes` (this node among them; the first is the preferred
    /// leader): three or more, each node declaring the datamanager with the same list. The
    /// node needs a data_dir (each replica journals) and a cluster to meet the others in;
    /// [`NodeBuilder::datamanager`](super::NodeBuilder::datamanager) shows an application's
    /// own datamanager so declared.
    ///
    /// ```
    /// use marie_dm::FEATURE;
    /// use marie_cluster::node::DatamanagerConfig;
    /// let dm = DatamanagerConfig::from(FEATURE).with_replicas(["features", "operations", "spare"]);
    /// assert_eq!(dm.replicas.len(), 3);
    /// ```
    pub fn with_replicas(mut self, nodes: impl IntoIterator<Item = impl Into<String>>) -> Self {
        self.replicas = nodes.into_iter().map(Into::into).collect();
        self
    }

    /// Keep at most `n` records of each class without a bound of its own (at least 1);
    /// the default is [`DmConfig::DEFAULT_RETENTION`](marie_dm::DmConfig::DEFAULT_RETENTION).
    ///
    /// ```
    /// use marie_dm::FEATURE;
    /// use marie_cluster::node::DatamanagerConfig;
    /// let dm = DatamanagerConfig::from(FEATURE)
    ///     .with_retention(50_000)
    ///     .with_class_retention("sonar", 200_000);
    /// let limits = dm.limits();
    /// assert_eq!(limits.retention_for("wall"), 50_000);
    /// assert_eq!(limits.retention_for("sonar"), 200_000);
    /// ```
    pub fn with_retention(mut self, n: usize) -> Self {
        self.retention = Some(n);
        self
    }

    /// Keep at most `n` records of `class` (at least 1).
    pub fn with_class_retention(mut self, class: impl Into<String>, n: usize) -> Self {
        self.class_retention.insert(class.into(), n);
        self
    }

    /// The datamanager's limits as its retention settings make them. The run datamanager
    /// ([`RUN`](marie_dm::RUN)) keeps [`CHECKPOINTS_KEPT`] checkpoints unless its
    /// `class_retention` says otherwise.
    pub fn limits(&self) -> marie_dm::DmConfig {
        let mut limits = marie_dm::DmConfig::default();
        if self.name == dm::RUN.name {
            limits = limits.with_retention(CHECKPOINT_CLASS, CHECKPOINTS_KEPT);
        }
        if let Some(n) = self.retention {
            limits = limits.with_default_retention(n);
        }
        for (class, n) in &self.class_retention {
            limits = limits.with_retention(class.clone(), *n);
        }
        limits
    }

    /// At `durability` rather than the node's default.
    ///
    /// ```
    /// use marie_dm::{Durability, FEATURE};
    /// use marie_cluster::node::DatamanagerConfig;
    /// let dm = DatamanagerConfig::from(FEATURE).with_durability(Durability::Sync);
    /// assert_eq!(dm.durability, Some(Durability::Sync));
    /// ```
    pub fn with_durability(mut self, durability: Durability) -> Self {
        self.durability = Some(durability);
        self
    }
}

impl From<DmSpec> for DatamanagerConfig {
    fn from(spec: DmSpec) -> Self {
        DatamanagerConfig::new(spec.name, spec.id)
    }
}

/// One supervisor of operations.
#[derive(Clone, Debug, PartialEq)]
pub struct SupervisorConfig {
    /// Its name, which `[[operation]]`s refer to.
    pub name: String,
    /// Which children a failure restarts.
    pub strategy: Strategy,
    /// More than this many restarts within [`SupervisorConfig::period`] and it gives up.
    pub max_restarts: usize,
    /// The intensity's window.
    pub period: Duration,
}

impl SupervisorConfig {
    /// A supervisor named `name`: one_for_one, 5 restarts in 10 s (the default intensity).
    pub fn new(name: impl Into<String>) -> Self {
        SupervisorConfig {
            name: name.into(),
            ..SupervisorConfig::operations()
        }
    }

    /// Which children a failure restarts.
    pub fn with_strategy(mut self, strategy: Strategy) -> Self {
        self.strategy = strategy;
        self
    }

    /// More than `max_restarts` within `period` and it gives up (the operations under it
    /// stop; a mission that needs them fails naming them).
    pub fn with_intensity(mut self, max_restarts: usize, period: Duration) -> Self {
        self.max_restarts = max_restarts;
        self.period = period;
        self
    }

    /// The node's default operation supervisor: one_for_one, 5 restarts in 10 s.
    pub fn operations() -> Self {
        SupervisorConfig {
            name: OPERATIONS.to_string(),
            strategy: Strategy::OneForOne,
            max_restarts: DEFAULT_RESTARTS,
            period: DEFAULT_PERIOD,
        }
    }
}

/// Operations a node hosts: every built-in version matching `version`, `instances` times.
#[derive(Clone, Debug, PartialEq)]
pub struct OperationConfig {
    /// Registry name of the operation.
    pub name: String,
    /// Which versions (a semver requirement; `*` for every one the node can build).
    pub version: semver::VersionReq,
    /// Instances started with the node (of each matching version). More may be started
    /// later, on request ([`Node::start_instance`](super::Node::start_instance)).
    pub instances: usize,
    /// The supervisor it runs under.
    pub supervisor: String,
    /// When it is restarted.
    pub restart: Restart,
    /// A mission's binding to an instance of this entry runs on that instance's version
    /// for the rest of the mission: it never moves to a newer version that joins the
    /// cluster, and a stand-in after a loss must be of the same version (issue 44). Where
    /// a node's operator, not each mission, decides that what runs here is not upgraded
    /// mid-mission. A mission's own `[pin]` of the operation wins over it: the mission's
    /// author wrote that for this run and these parameters, a node's pin is a standing
    /// default for whatever runs there. In a file, `pin = true` (default false); the
    /// instances say it through their property interface
    /// ([`HostOptions::pinned`](marie_actors::eo::HostOptions::pinned)).
    pub pin: bool,
    /// A test knob, 0 (off) by default: each instance of this entry fails its first `n`
    /// activations at once, with an error reply naming the knob
    /// ([`HostOptions::fail_first_activations`](marie_actors::eo::HostOptions::fail_first_activations)).
    /// It exists to prove a rollback end to end: a node of a new version whose first
    /// activation fails, and the binding that goes back to the old instance. Counted per
    /// instance (a restarted instance fails its first `n` again). In a file,
    /// `fail_first_activations = 1`; at most [`MAX_FAILING_ACTIVATIONS`].
    pub fail_first_activations: u64,
}

/// Most activations [`OperationConfig::fail_first_activations`] may fail.
pub const MAX_FAILING_ACTIVATIONS: u64 = 1000;

impl OperationConfig {
    /// One permanent instance of every version of `name` under [`OPERATIONS`].
    pub fn new(name: impl Into<String>) -> Self {
        OperationConfig {
            name: name.into(),
            version: semver::VersionReq::STAR,
            instances: 1,
            supervisor: OPERATIONS.to_string(),
            restart: Restart::Permanent,
            pin: false,
            fail_first_activations: 0,
        }
    }

    /// A binding to an instance of this entry runs on its version for the rest of the
    /// mission (see [`OperationConfig::pin`]).
    pub fn pinned(mut self) -> Self {
        self.pin = true;
        self
    }

    /// Each instance fails its first `n` activations at once (a test knob, see
    /// [`OperationConfig::fail_first_activations`]).
    pub fn failing_first_activations(mut self, n: u64) -> Self {
        self.fail_first_activations = n;
        self
    }

    /// Only versions matching `req`.
    pub fn with_version(mut self, req: semver::VersionReq) -> Self {
        self.version = req;
        self
    }

    /// `n` instances of each matching version.
    pub fn with_instances(mut self, n: usize) -> Self {
        self.instances = n;
        self
    }

    /// Under the supervisor named `supervisor` (declared in the node's config).
    pub fn under(mut self, supervisor: impl Into<String>) -> Self {
        self.supervisor = supervisor.into();
        self
    }

    /// Restarted as `restart` says when it ends (default: always, [`Restart::Permanent`]).
    pub fn with_restart(mut self, restart: Restart) -> Self {
        self.restart = restart;
        self
    }

    /// Whether the factory `f` is one this entry hosts.
    pub fn allows(&self, f: &OperationFactory) -> bool {
        f.name == self.name && f.semver().is_some_and(|v| self.version.matches(&v))
    }
}

/// A simulated robot on the node.
#[derive(Clone, Debug, PartialEq)]
pub struct SimulationConfig {
    /// The world file; `None`: the mission's world.
    pub world: Option<PathBuf>,
    /// Where the config file names the world (for an error about the world file, which
    /// points first at the line that named it).
    pub world_at: Option<Diagnostic>,
    /// Seed of its noise; `None`: the command line's.
    pub seed: Option<u64>,
    /// Whether the node runs the cart's drivers (the virtual cart).
    pub drivers: bool,
}

/// Why a node config (as a Rust value) cannot be hosted.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ConfigError {
    /// The node has no name.
    #[error("a node needs a name")]
    NoName,
    /// An operation no factory builds.
    #[error(
        "operation `{name}` cannot be hosted: no such operation in this program's catalogue \
         (a node builds only the operations its own program registered; known: {known})"
    )]
    UnknownOperation {
        /// Its name.
        name: String,
        /// The names the node can host.
        known: String,
    },
    /// An operation whose versions do not match.
    #[error("operation `{name}`: no version matches `{req}` (available: {available})")]
    NoVersion {
        /// Its name.
        name: String,
        /// The requirement.
        req: String,
        /// The versions the node can host.
        available: String,
    },
    /// An operation under a supervisor nobody declared.
    #[error("operation `{name}` names supervisor `{supervisor}`, which is not declared")]
    UnknownSupervisor {
        /// The operation.
        name: String,
        /// The supervisor it names.
        supervisor: String,
    },
    /// Two entries of one kind with one name.
    #[error("{kind} `{name}` is declared twice")]
    Duplicate {
        /// `supervisor` or `datamanager`.
        kind: &'static str,
        /// The name.
        name: String,
    },
    /// A number out of range.
    #[error("{what}: {message}")]
    Range {
        /// Which field.
        what: String,
        /// What was expected.
        message: String,
    },
    /// A datamanager asks for a journal on a node that has no place for one.
    #[error(
        "datamanager `{datamanager}`: durability `{durability}` needs the node's data_dir \
         (give the node one, or use `memory`)"
    )]
    NoDataDir {
        /// The datamanager.
        datamanager: String,
        /// The durability it asks for.
        durability: Durability,
    },
}

impl NodeConfig {
    /// A node named `name` hosting nothing yet (no datamanager, no operation, a dispatcher).
    pub fn new(name: impl Into<String>) -> Self {
        NodeConfig {
            name: name.into(),
            dispatcher: true,
            desk: None,
            datamanagers: Vec::new(),
            supervisors: Vec::new(),
            operations: Vec::new(),
            simulation: None,
            cluster: None,
            data_dir: None,
        }
    }

    /// Join a cluster with `cluster` (listen address, peers, cookie, heartbeat, TLS) when
    /// the node starts ([`Node::start`](super::Node::start)), and leave it at its shutdown.
    pub fn with_cluster(mut self, cluster: crate::net::ClusterConfig) -> Self {
        self.cluster = Some(cluster);
        self
    }

    /// Keep the node's files — its datamanagers' journals — in `dir`
    /// ([`NodeConfig::data_dir`]): locked while the node runs, and its datamanagers at
    /// `process` unless they say otherwise.
    pub fn with_data_dir(mut self, dir: impl Into<PathBuf>) -> Self {
        self.data_dir = Some(dir.into());
        self
    }

    /// How durable datamanager `dm` of this node is: its own
    /// [`durability`](DatamanagerConfig::durability), else `process` when the node has a
    /// [`data_dir`](NodeConfig::data_dir) and `memory` when it has none.
    pub fn durability_of(&self, dm: &DatamanagerConfig) -> Durability {
        dm.durability.unwrap_or(if self.data_dir.is_some() {
            Durability::Process
        } else {
            Durability::Memory
        })
    }

    /// The embedded default: the thesis' three datamanagers, one instance of every operation
    /// of `catalog` under [`OPERATIONS`], a dispatcher — everything a mission may need. This is
    /// what `marie run MISSION` runs without `--node`: no data directory, so its datamanagers
    /// are in memory and it leaves no file behind.
    pub fn everything(name: impl Into<String>, catalog: &[OperationFactory]) -> Self {
        // each name once, in catalogue order (an entry hosts every version of its name)
        let mut seen = std::collections::BTreeSet::new();
        let names: Vec<&str> = catalog
            .iter()
            .map(|f| f.name)
            .filter(|n| seen.insert(*n))
            .collect();
        NodeConfig {
            datamanagers: [dm::FEATURE, dm::PARAMETER, dm::WORLD]
                .into_iter()
                .map(DatamanagerConfig::from)
                .collect(),
            operations: names.into_iter().map(OperationConfig::new).collect(),
            ..NodeConfig::new(name)
        }
    }

    /// Every supervisor of operations: [`OPERATIONS`] (declared or default) and the others.
    pub fn operation_supervisors(&self) -> Vec<SupervisorConfig> {
        let mut out = Vec::with_capacity(self.supervisors.len() + 1);
        if !self.supervisors.iter().any(|s| s.name == OPERATIONS) {
            out.push(SupervisorConfig::operations());
        }
        out.extend(self.supervisors.iter().cloned());
        out
    }

    /// The factories of `catalog` this node hosts at start, with their entry: each matching
    /// version of each `[[operation]]`, `instances` times.
    pub fn hosted<'c>(
        &self,
        catalog: &'c [OperationFactory],
    ) -> Vec<(&OperationConfig, &'c OperationFactory)> {
        let mut out = Vec::new();
        for op in &self.operations {
            for f in catalog.iter().filter(|f| op.allows(f)) {
                for _ in 0..op.instances {
                    out.push((op, f));
                }
            }
        }
        out
    }

    /// Check the config against what this build can host (`catalog`): names, versions,
    /// supervisors, duplicates and ranges. A config loaded from a file has been checked the
    /// same way, with positions.
    pub fn validate(&self, catalog: &[OperationFactory]) -> Result<(), ConfigError> {
        if self.name.trim().is_empty() {
            return Err(ConfigError::NoName);
        }
        let mut seen = std::collections::BTreeSet::new();
        for s in &self.supervisors {
            if !seen.insert(s.name.as_str()) {
                return Err(ConfigError::Duplicate {
                    kind: "supervisor",
                    name: s.name.clone(),
                });
            }
            if s.max_restarts > MAX_RESTARTS {
                return Err(ConfigError::Range {
                    what: format!("supervisor `{}`: max_restarts", s.name),
                    message: format!("at most {MAX_RESTARTS}, got {}", s.max_restarts),
                });
            }
            let p = s.period.as_secs_f64();
            if p <= 0.0 || p > MAX_PERIOD_S {
                return Err(ConfigError::Range {
                    what: format!("supervisor `{}`: period", s.name),
                    message: format!("in (0, {MAX_PERIOD_S}] s, got {p} s"),
                });
            }
        }
        let mut dms = std::collections::BTreeSet::new();
        for d in &self.datamanagers {
            if !dms.insert(d.name.as_str()) {
                return Err(ConfigError::Duplicate {
                    kind: "datamanager",
                    name: d.name.clone(),
                });
            }
            match d.durability {
                Some(durability @ (Durability::Process | Durability::Sync))
                    if self.data_dir.is_none() =>
                {
                    return Err(ConfigError::NoDataDir {
                        datamanager: d.name.clone(),
                        durability,
                    });
                }
                _ => {}
            }
            if let Some(replication) = d.replication(&self.name) {
                let durable = self.durability_of(d) != Durability::Memory;
                let problem = replication.check().err().map(|e| e.to_string()).or_else(|| {
                    (!durable).then(|| match self.data_dir {
                        None => "replicas need a journal: give the node a data_dir (durability process or sync)",
                        Some(_) => "replicas need a journal: durability process or sync, not memory",
                    }
                    .to_string())
                });
                if let Some(message) = problem {
                    return Err(ConfigError::Range {
                        what: format!("datamanager `{}`: replicas", d.name),
                        message,
                    });
                }
            }
        }
        let supervisors = self.operation_supervisors();
        for op in &self.operations {
            check_operation(op, catalog).map_err(|e| match e {
                OpProblem::Unknown(known) => ConfigError::UnknownOperation {
                    name: op.name.clone(),
                    known,
                },
                OpProblem::NoVersion(available) => ConfigError::NoVersion {
                    name: op.name.clone(),
                    req: op.version.to_string(),
                    available,
                },
            })?;
            if op.instances > MAX_INSTANCES {
                return Err(ConfigError::Range {
                    what: format!("operation `{}`: instances", op.name),
                    message: format!("at most {MAX_INSTANCES}, got {}", op.instances),
                });
            }
            if op.fail_first_activations > MAX_FAILING_ACTIVATIONS {
                return Err(ConfigError::Range {
                    what: format!("operation `{}`: fail_first_activations", op.name),
                    message: format!(
                        "at most {MAX_FAILING_ACTIVATIONS}, got {}",
                        op.fail_first_activations
                    ),
                });
            }
            if !supervisors.iter().any(|s| s.name == op.supervisor) {
                return Err(ConfigError::UnknownSupervisor {
                    name: op.name.clone(),
                    supervisor: op.supervisor.clone(),
                });
            }
        }
        Ok(())
    }
}

impl NodeConfig {
    /// Refused unless every replicated datamanager can meet its replicas: they are on other
    /// nodes, so the node must join a cluster ([`NodeConfig::cluster`]). Checked when the node
    /// starts, not by [`NodeConfig::validate`]: a node file may leave `[cluster]` to the
    /// command line that starts it. Without it the replica would never find a majority — no
    /// leader, and every client waiting for one.
    pub fn check_replicas_reachable(&self) -> Result<(), ConfigError> {
        if self.cluster.is_some() {
            return Ok(());
        }
        match self.datamanagers.iter().find(|d| !d.replicas.is_empty()) {
            None => Ok(()),
            Some(d) => Err(ConfigError::Range {
                what: format!("datamanager `{}`: replicas", d.name),
                message: format!(
                    "its replicas are on the nodes {:?}, and this node joins no cluster: \
                     give it one (NodeBuilder::cluster, or a [cluster] table)",
                    d.replicas
                ),
            }),
        }
    }
}

/// What is wrong with an operation entry against the catalogue.
enum OpProblem {
    /// No such name; the known names.
    Unknown(String),
    /// No matching version; the versions there are.
    NoVersion(String),
}

fn check_operation(op: &OperationConfig, catalog: &[OperationFactory]) -> Result<(), OpProblem> {
    let versions: Vec<&str> = catalog
        .iter()
        .filter(|f| f.name == op.name)
        .map(|f| f.version.as_str())
        .collect();
    if versions.is_empty() {
        let mut known: Vec<&str> = catalog.iter().map(|f| f.name).collect();
        known.sort_unstable();
        known.dedup();
        return Err(OpProblem::Unknown(known.join(", ")));
    }
    if !catalog.iter().any(|f| op.allows(f)) {
        return Err(OpProblem::NoVersion(versions.join(", ")));
    }
    Ok(())
}
