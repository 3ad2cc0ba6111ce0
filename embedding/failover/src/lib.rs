//! # A two-process application that fails over
//!
//! An application on marie whose node joins a cluster from code — [`Node::builder`] with
//! [`NodeBuilder::cluster`], no transport started by hand — and whose mission survives the
//! loss of the process that runs its operation. It depends on marie and tokio only.
//!
//! The application pumps water. Each process has its own pump station (here simulated,
//! [`Station`]: how many litres one step moves) and hands it to its [`Pump`] operation
//! through a factory closure ([`NodeBuilder::operation_factory`] with
//! [`OperationFactory::from_fn`]): code is not shipped between processes, so each process
//! builds its pumps from its own factory, with its own station.
//!
//! Two processes of the `failover-app` binary (`src/main.rs`) make the cluster:
//!
//! ```text
//! # B: hosts a pump on a slow station (0.1 l per step)
//! failover-app --name b --rate 0.1
//!   node b listening on 127.0.0.1:40123
//! # A: the dispatcher, and a pump on standby (instances 0) on a fast station; runs the mission
//! failover-app --name a --peer 127.0.0.1:40123 --standby --rate 10 --run 50
//!   node a listening on 127.0.0.1:40177
//!   pump found on node b
//!   pump runs on node b
//! # kill -9 B's process: A's pump takes over
//!   pump lost: died: its actor is gone
//!   pump rebound from node b to node a after 1001 ms
//!   rebind: pump from b to a
//!   outcome: succeeded
//! ```
//!
//! What happens when B is killed, and the numbers behind it:
//!
//! - B's sessions close with its process, so A sees B's pump leave its registry at once (a
//!   *frozen* or cut-off B would be declared down by the failure detector instead: 1.2 s
//!   of silence by default, [`DEFAULT_DEADLINE`](marie::cluster::net::detector::DEFAULT_DEADLINE),
//!   with a heartbeat every 240 ms).
//! - A's dispatcher looks for a stand-in. None runs anywhere — A's pump is a standby — so
//!   after the provisioning grace, [`provision::GRACE`](marie::provision::GRACE)
//!   (1 s, or half the mission's rebind deadline if shorter), it asks the nodes that allow
//!   the pump to start one; A's own node is asked first and starts it from its factory,
//!   with A's station.
//! - The dispatcher adopts the new instance, restores the mission's parameters, resumes
//!   it, and records the rebind in the report. The pump steps every 100 ms
//!   ([`DEFAULT_PERIOD`](marie::eo::DEFAULT_PERIOD)) until the volume is reached.
//! - The whole failover must fit in the mission's rebind deadline ([`mission`] sets 30 s,
//!   generous for a loaded machine; the default is 10 s) or the mission fails naming the
//!   pump.
//!
//! `tests/failover.rs` runs exactly this with two real processes and `SIGKILL`.

use marie::cluster::net::ClusterConfig;
use marie::cluster::node::{Node, NodeBuilder};
use marie::dispatcher::mission::{ActionBuilder, MissionBuilder};
use marie::eo::OperationFactory;
use marie::prelude::*;
use marie::registry::{self, ModuleKind};
use std::net::SocketAddr;
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// The pump's registry name.
pub const PUMP: &str = "pump";

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

/// A process's pump station: the hardware its pumps drive (simulated: a fixed number of
/// litres per step, and a meter). Each process builds its own and hands it to its pumps.
#[derive(Debug)]
pub struct Station {
    name: String,
    litres_per_step: f64,
    /// Litres moved by this station so far, by any of its pumps.
    meter: Mutex<f64>,
}

impl Station {
    /// A station called `name` that moves `litres_per_step` per step.
    pub fn new(name: impl Into<String>, litres_per_step: f64) -> Arc<Station> {
        Arc::new(Station {
            name: name.into(),
            litres_per_step,
            meter: Mutex::new(0.0),
        })
    }

    /// Its name (the process's node name, in the binary).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Run the pump for one step: the litres moved.
    pub fn pump(&self) -> f64 {
        let mut meter = self.meter.lock().unwrap_or_else(|e| e.into_inner());
        *meter += self.litres_per_step;
        self.litres_per_step
    }

    /// Litres moved so far.
    pub fn metered(&self) -> f64 {
        *self.meter.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// The operation: pumps [`PumpParams::litres`] with its process's [`Station`], then raises
/// [`PumpFlag::Full`]. It is not `Default`: it needs the station, which the application
/// hands it.
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
    async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> {
        self.pumped += self.station.pump();
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
}

/// The node of one process: its station handed to its pumps through a factory closure,
/// one pump running or on standby, a dispatcher if it runs missions, and the cluster —
/// joined when the node starts, left when it shuts down.
///
/// ```no_run
/// use marie_failover_app::{node, Setup};
/// # #[tokio::main] async fn main() -> Result<(), Box<dyn std::error::Error>> {
/// let setup = Setup {
///     name: "b".into(),
///     listen: "127.0.0.1:0".parse()?,
///     peers: Vec::new(),
///     cookie: "failover".into(),
///     litres_per_step: 0.1,
///     standby: false,
///     dispatcher: false,
/// };
/// let node = node(&setup).start().await?;
/// println!("listening on {}", node.transport().expect("joined").listen());
/// node.shutdown().await;
/// # Ok(()) }
/// ```
pub fn node(setup: &Setup) -> NodeBuilder {
    let station = Station::new(&setup.name, setup.litres_per_step);
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
