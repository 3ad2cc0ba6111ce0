//! # A three-process application that fails over and keeps its log
//!
//! An application on marie whose node joins a cluster from code — [`Node::builder`] with
//! [`NodeBuilder::cluster`], no transport started by hand — whose mission survives the
//! loss of the process that runs its operation, and whose own replicated datamanager, the
//! pump log, loses no record it acknowledged when the process holding its leader is killed.
//! It depends on marie, tokio and serde only.
//!
//! The application pumps water. Each process has its own pump station (here simulated,
//! [`Station`]: how many litres one step moves) and hands it to its [`Pump`] operation
//! through a factory closure ([`NodeBuilder::operation_factory`] with
//! [`OperationFactory::from_fn`]): code is not shipped between processes, so each process
//! builds its pumps from its own factory, with its own station.
//!
//! # The pump log: a datamanager of the application's own, in three replicas
//! Every step of a pump is a record in the datamanager [`PUMP_LOG`] (`pump-log`, the
//! application's name and id), of the application's own record kind [`PUMPED`] (a
//! [`Pumped`] payload, serde-encoded). Each process declares it with the same replicas —
//! three nodes of the application, the first the preferred leader — and a data directory
//! for its replica's journal ([`node`]):
//!
//! ```no_run
//! # use marie::cluster::node::{DatamanagerConfig, Node};
//! # use marie_failover_app::PUMP_LOG;
//! # let dir = std::path::Path::new("/var/lib/pumps/b");
//! let builder = Node::builder("b")
//!     .data_dir(dir) // the replica's journal: Raft's term and vote, and the records
//!     .datamanager(DatamanagerConfig::from(PUMP_LOG).with_replicas(["b", "a", "c"]));
//! ```
//!
//! A pump stores its step with `ctx.dm(PUMP_LOG)?.store_kind(PUMPED, &step)` — the
//! acknowledged road: `Ok` once a majority of the replicas journaled it — wherever the
//! leader runs; any process asks [`DmClient::leader_node`](marie::dm::DmClient::leader_node)
//! which node holds it ([`tell_leaders`]). When the leader's process dies, a replica on
//! another process is elected leader (within about a second of the failure detector's
//! verdict, at once when the process's sessions close), every client follows it, and the
//! records' seqs go on where they were.
//!
//! # The cluster
//! Three processes of the `failover-app` binary (`src/main.rs`) make it:
//!
//! ```text
//! # B: a pump on a slow station (0.1 l per step); the pump log's preferred leader
//! failover-app --name b --rate 0.1 --data-dir /tmp/pumps/b --replicas b,a,c
//!   node b listening on 127.0.0.1:40123
//! # C: a replica of the pump log, and a pump on standby
//! failover-app --name c --peer 127.0.0.1:40123 --standby --data-dir /tmp/pumps/c --replicas b,a,c
//! # A: the dispatcher, a replica, and a pump on standby on a fast station; runs the mission
//! failover-app --name a --peer 127.0.0.1:40123 --standby --rate 10 --run 50 \
//!     --data-dir /tmp/pumps/a --replicas b,a,c
//!   node a listening on 127.0.0.1:40177
//!   pump found on node b
//!   pump-log leader: b
//!   pump runs on node b
//! # (B prints each step its pump logged: `pump-log: b#38 stored as seq 39`)
//! # kill -9 B's process: A's pump takes over, and a replica on A or C leads the log
//!   pump lost: died during action `fill`
//!   pump-log leader: a
//!   pump rebound from node b to node a after 1002 ms
//!   pump-log: a#1 stored as seq 41
//!   …
//!   pump-log: a#5 stored as seq 45
//!   rebind: pump from b to a
//!   pump-log check: 43 of 43 acknowledged held, 0 lost
//!   pump-log holds 43 records: b#1=2 b#2=3 … b#38=39 a#1=41 … a#5=45
//!   outcome: succeeded
//! ```
//!
//! What happens when B is killed, and the numbers behind it:
//!
//! - B's sessions close with its process, so A sees B's pump and the pump log's leader
//!   leave its registry at once (a *frozen* or cut-off B would be declared down by the
//!   failure detector instead: 1.2 s of silence by default,
//!   [`DEFAULT_DEADLINE`](marie::cluster::net::detector::DEFAULT_DEADLINE), with a
//!   heartbeat every 240 ms). The replicas on A and C elect a leader among themselves (two
//!   of three: a majority); it is published under `pump-log`, and A's clients follow it.
//! - A's dispatcher looks for a stand-in. None runs anywhere — A's and C's pumps are
//!   standbys — so after the provisioning grace, [`provision::GRACE`](marie::provision::GRACE)
//!   (1 s, or half the mission's rebind deadline if shorter), it asks the nodes that allow
//!   the pump to start one; A's own node is asked first and starts it from its factory,
//!   with A's station.
//! - The dispatcher adopts the new instance, restores the mission's parameters, resumes
//!   it, and records the rebind in the report. The pump steps every 100 ms
//!   ([`DEFAULT_PERIOD`](marie::eo::DEFAULT_PERIOD)) until the volume is reached, logging
//!   each step in the new leader.
//! - The whole failover must fit in the mission's rebind deadline ([`mission`] sets 30 s,
//!   generous for a loaded machine; the default is 10 s) or the mission fails naming the
//!   pump.
//! - Every step B's pump was told was stored is in the log at the seq it was told (the
//!   run's own check says so too: `pump-log check`). The seqs go on under the new leader
//!   (the gaps, 1 and 40, are each leader's first entry of its term, which holds no record).
//!
//! `tests/failover.rs` runs exactly this with three real processes and `SIGKILL`.

use marie::cluster::net::ClusterConfig;
use marie::cluster::node::{DatamanagerConfig, Node, NodeBuilder};
use marie::dispatcher::mission::{ActionBuilder, MissionBuilder};
use marie::dm::{DmClient, DmError, DmSpec, Query, RecordHeader, RecordKind};
use marie::eo::OperationFactory;
use marie::prelude::*;
use marie::registry::{self, ModuleKind, RegistryEvent};
use serde::{Deserialize, Serialize};
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// The pump's registry name.
pub const PUMP: &str = "pump";

/// The pump log: the application's own datamanager (its name and id), kept in replicas on
/// three of its processes.
pub const PUMP_LOG: DmSpec = DmSpec::new("pump-log", 7410);

/// One step of a pump, as the pump log keeps it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Pumped {
    /// The station that pumped (its process's node name).
    pub station: String,
    /// The station's step number: 1 for its first step, by any of its pumps.
    pub step: u64,
    /// Litres the station's meter showed after the step.
    pub metered: f64,
}

impl Pumped {
    /// `station#step`: the step's name in the lines the binary prints.
    pub fn label(&self) -> String {
        format!("{}#{}", self.station, self.step)
    }
}

/// The pump log's records: class `pumped`, a [`Pumped`] each.
pub const PUMPED: RecordKind<Pumped> = RecordKind::new("pumped");

params! {
    /// What a pump is asked to do.
    pub struct PumpParams {
        /// litres to pump
        pub litres: f64 = 10.0, range(0.1, 100000.0), unit("l");
    }
}

flags! {
    /// What a pump reports.
    pub enum PumpFlag {
        /// the volume asked for is pumped
        Full = "full",
    }
}

/// Told of each step the pump log acknowledged: the step and its seq.
type LoggedSink = Box<dyn Fn(&Pumped, u64) + Send + Sync>;

/// A process's pump station: the hardware its pumps drive (simulated: a fixed number of
/// litres per step, and a meter). Each process builds its own and hands it to its pumps.
pub struct Station {
    name: String,
    litres_per_step: f64,
    /// Litres moved by this station so far, by any of its pumps, and its steps.
    meter: Mutex<(f64, u64)>,
    /// Told of each step the pump log acknowledged ([`Station::on_logged`]).
    logged: Mutex<Option<LoggedSink>>,
}

impl std::fmt::Debug for Station {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Station")
            .field("name", &self.name)
            .field("litres_per_step", &self.litres_per_step)
            .field("meter", &self.meter)
            .finish_non_exhaustive()
    }
}

impl Station {
    /// A station called `name` that moves `litres_per_step` per step.
    pub fn new(name: impl Into<String>, litres_per_step: f64) -> Arc<Station> {
        Arc::new(Station {
            name: name.into(),
            litres_per_step,
            meter: Mutex::new((0.0, 0)),
            logged: Mutex::new(None),
        })
    }

    /// Its name (the process's node name, in the binary).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Litres one step moves.
    pub fn litres_per_step(&self) -> f64 {
        self.litres_per_step
    }

    /// Run the pump for one step: the step, as the pump log keeps it.
    pub fn pump(&self) -> Pumped {
        let mut meter = self.meter.lock().unwrap_or_else(|e| e.into_inner());
        meter.0 += self.litres_per_step;
        meter.1 += 1;
        Pumped {
            station: self.name.clone(),
            step: meter.1,
            metered: meter.0,
        }
    }

    /// Litres moved so far.
    pub fn metered(&self) -> f64 {
        self.meter.lock().unwrap_or_else(|e| e.into_inner()).0
    }

    /// Tell `sink` of every step of this station's pumps that the pump log acknowledged,
    /// with its seq (the binary prints them: what a test later looks up in the log).
    pub fn on_logged(&self, sink: impl Fn(&Pumped, u64) + Send + Sync + 'static) {
        *self.logged.lock().unwrap_or_else(|e| e.into_inner()) = Some(Box::new(sink));
    }

    /// The pump log acknowledged `step` with `seq`.
    fn logged(&self, step: &Pumped, seq: u64) {
        if let Some(sink) = &*self.logged.lock().unwrap_or_else(|e| e.into_inner()) {
            sink(step, seq);
        }
    }
}

/// The operation: pumps [`PumpParams::litres`] with its process's [`Station`], logging each
/// step in the [`PUMP_LOG`] (stored, not put: the step is in a majority of the log's replicas
/// before the pump goes on), then raises [`PumpFlag::Full`]. It is not `Default`: it needs
/// the station, which the application hands it.
#[derive(Debug)]
pub struct Pump {
    station: Arc<Station>,
    pumped: f64,
    target: f64,
}

impl Pump {
    /// A pump driving `station`.
    pub fn new(station: Arc<Station>) -> Pump {
        Pump {
            station,
            pumped: 0.0,
            target: 0.0,
        }
    }
}

impl Operation for Pump {
    fn identity(&self) -> Identity {
        Identity::new(
            PUMP,
            7400,
            "1.0.0",
            "pumps a volume with its process's station",
        )
    }
    fn parameters(&self) -> ParamSchema {
        PumpParams::schema()
    }
    fn flags(&self) -> Vec<FlagDecl> {
        PumpFlag::decls()
    }
    async fn activate(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        let p: PumpParams = ctx.params().read()?;
        self.target = p.litres;
        self.pumped = 0.0;
        Ok(Step::Continue)
    }
    async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
        let step = self.station.pump();
        self.pumped += self.station.litres_per_step();
        // wherever the log's leader runs now; a leader being elected is waited for
        let seq = ctx.dm(PUMP_LOG)?.store_kind(PUMPED, &step).await?;
        self.station.logged(&step, seq);
        Ok(if self.pumped >= self.target {
            Step::finish(PumpFlag::Full)
        } else {
            Step::Continue
        })
    }
    fn property(&self, name: &str) -> Option<Value> {
        match name {
            "station" => Some(Value::Text(self.station.name().to_string())),
            "pumped" => Some(Value::Float(self.pumped)),
            _ => None,
        }
    }
}

/// How one process of the application is set up.
#[derive(Clone, Debug)]
pub struct Setup {
    /// The node's name (unique in the cluster).
    pub name: String,
    /// Where it listens for its peers (port 0: one the system picks).
    pub listen: SocketAddr,
    /// Whom it joins (any one member is enough).
    pub peers: Vec<SocketAddr>,
    /// The cluster's shared secret.
    pub cookie: String,
    /// Litres its station moves per step.
    pub litres_per_step: f64,
    /// Whether its pump is a standby (started only when no pump runs anywhere) rather
    /// than running from the start.
    pub standby: bool,
    /// Whether it runs missions (a dispatcher).
    pub dispatcher: bool,
    /// Where it keeps its files: the journal of its replica of the pump log.
    pub data_dir: PathBuf,
    /// The nodes that keep a replica of the pump log, the preferred leader first — the
    /// same three (or more) in every process, this one among them.
    pub log_replicas: Vec<String>,
}

/// The node of one process: `station` handed to its pumps through a factory closure, one
/// pump running or on standby, a dispatcher if it runs missions, a replica of the
/// [`PUMP_LOG`] with its journal in the data directory, and the cluster — joined when the
/// node starts, left when it shuts down.
///
/// ```no_run
/// use marie_failover_app::{node, Setup, Station};
/// # #[tokio::main] async fn main() -> Result<(), Box<dyn std::error::Error>> {
/// let setup = Setup {
///     name: "b".into(),
///     listen: "127.0.0.1:0".parse()?,
///     peers: Vec::new(),
///     cookie: "failover".into(),
///     litres_per_step: 0.1,
///     standby: false,
///     dispatcher: false,
///     data_dir: "/tmp/pumps/b".into(),
///     log_replicas: vec!["b".into(), "a".into(), "c".into()],
/// };
/// let station = Station::new(&setup.name, setup.litres_per_step);
/// let node = node(&setup, station).start().await?;
/// println!("listening on {}", node.transport().expect("joined").listen());
/// node.shutdown().await;
/// # Ok(()) }
/// ```
pub fn node(setup: &Setup, station: Arc<Station>) -> NodeBuilder {
    // every pump this process starts — at start, after a crash, on a dispatcher's
    // request — is built here, with this process's station
    let pumps = OperationFactory::from_fn(move || Pump::new(station.clone()));
    let instances = if setup.standby { 0 } else { 1 };
    let mut cluster = ClusterConfig::new(setup.listen, setup.cookie.clone());
    for &peer in &setup.peers {
        cluster = cluster.with_peer(peer);
    }
    Node::builder(setup.name.clone())
        .operation_factory(pumps, |c| c.with_instances(instances))
        .dispatcher(setup.dispatcher)
        // the pump log's replica keeps its journal here: what it acknowledged, and Raft's
        // term and vote, survive its process
        .data_dir(&setup.data_dir)
        .datamanager(DatamanagerConfig::from(PUMP_LOG).with_replicas(setup.log_replicas.clone()))
        .cluster(cluster)
}

/// The mission: pump `litres`, with a rebind deadline of 30 s (a failover on a loaded
/// machine has time; the default is 10 s).
pub fn mission(litres: f64) -> MissionBuilder {
    MissionBuilder::new("fill")
        .flags([PumpFlag::Full.name()])
        .success([PumpFlag::Full.name()])
        .rebind_deadline(Duration::from_secs(30))
        .action(
            ActionBuilder::new("fill").op(PUMP, ParamMap::new().with(PumpParams::litres(), litres)),
        )
}

/// Wait until a pump runs somewhere in the cluster (on this node or a peer): the node it
/// runs on, or `None` after `timeout`.
pub async fn wait_for_pump(timeout: Duration) -> Option<String> {
    // watched before looking, so a pump that appears in between is not missed
    let mut watch = registry::watch(Some(ModuleKind::Operation)).await.ok()?;
    if let Some(found) = registry::lookup(ModuleKind::Operation, PUMP)
        .into_iter()
        .next()
    {
        return Some(found.node);
    }
    tokio::time::timeout(timeout, async {
        while let Some(event) = watch.next().await {
            if let registry::RegistryEvent::Joined(i) = event {
                if i.name == PUMP {
                    return Some(i.node);
                }
            }
        }
        None
    })
    .await
    .ok()
    .flatten()
}

/// A client of the [`PUMP_LOG`] storing as `source`, once a leader of it is published
/// (a majority of its replicas up and one elected); `Err` after `timeout`. The client
/// follows the leader from then on, wherever it is elected.
pub async fn pump_log(source: &str, timeout: Duration) -> Result<DmClient, DmError> {
    DmClient::lookup_within(PUMP_LOG.name, source, timeout).await
}

/// Tell `tell` which node holds the pump log's leader — now, and each time another is
/// published — asked of the leader itself ([`DmClient::leader_node`]), until the node's
/// registry closes. A leader that cannot be asked is told as `Err`.
pub async fn tell_leaders(log: DmClient, mut tell: impl FnMut(Result<String, DmError>)) {
    // watched before asking, so a leader published in between is not missed
    let Ok(mut watch) = registry::watch(Some(ModuleKind::Datamanager)).await else {
        return;
    };
    let mut told: Option<String> = None;
    loop {
        match log.leader_node().await {
            Ok(node) if told.as_deref() == Some(node.as_str()) => {}
            Ok(node) => {
                told = Some(node.clone());
                tell(Ok(node));
            }
            Err(e) => {
                told = None;
                tell(Err(e));
            }
        }
        loop {
            match watch.next().await {
                None => return,
                Some(RegistryEvent::Joined(i)) if i.name == PUMP_LOG.name => break,
                Some(_) => {}
            }
        }
    }
}

/// Every step the pump log holds, oldest first, with its header (its seq).
pub async fn logged_steps(log: &DmClient) -> Result<Vec<(RecordHeader, Pumped)>, DmError> {
    log.select_kind(PUMPED, Query::all()).await
}
