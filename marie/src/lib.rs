//! # marie
//!
//! An actor framework for robot control with supervision and self-healing: the control
//! architecture of the MARIE mobile robot — elementary operations that sense, reason and
//! act, datamanagers through which alone they exchange data, an action dispatcher that
//! runs missions, a location table where modules publish themselves — on
//! [ractor](https://docs.rs/ractor) actors, in one process or across a cluster of them.
//! (`docs/thesis.md` in the repository tells where the architecture comes from and what
//! marie adds to it.)
//!
//! This crate is the framework an application depends on. Its road:
//!
//! - [`prelude`] — what an operation author needs, in one `use`;
//! - [`Node`] and its [`NodeBuilder`] — a node that hosts an application's operations and
//!   datamanagers under supervision, on one clock, alone or in a cluster;
//!   [`Node::run`] runs a mission on it, with [`RunOptions`];
//! - [`OperationHandle`] — an application's hold on an operation by name;
//! - [`RactorMessage`] — for the application's own ractor actors beside marie's;
//!
//! and, by module, what the crates under it hold: the operations ([`eo`], [`declare`]) and
//! the dispatcher with its missions ([`dispatcher`], [`provision`]); the datamanagers
//! ([`dm`]); the words every layer speaks — a run ([`run`]), its events ([`events`]) and
//! report ([`report`]), properties ([`property`]), status flags ([`status`]), clocks
//! ([`clock`]), the location table ([`registry`]), fencing ([`fence`]), the wire form
//! ([`wire`]) and file diagnostics ([`diagnostic`]); [`supervision`] (supervisors with OTP
//! semantics) and [`cluster`] (the node, fault injection, the
//! transport and failure detector). The `marie` command, its web monitor and its simulated
//! robot are not part of this crate: they are the repository's root package, which uses
//! this one the way an application does.
//!
//! # Embedding marie: operation → node → mission → faults → cluster
//!
//! **1. An operation** is a type that implements [`eo::Operation`]: who it is, the
//! parameters and flags it declares, and what it does each step. Declare parameters with
//! [`params!`](params) and flags with [`flags!`](macro@flags): a misspelt
//! name is then a compile error.
//!
//! ```
//! use marie::prelude::*;
//!
//! params! {
//!     pub struct CountParams {
//!         /// how far to count
//!         to: i64 = 3, range(1, 1000);
//!     }
//! }
//! flags! {
//!     pub enum CountFlag {
//!         /// the count is done
//!         Counted = "counted",
//!     }
//! }
//!
//! #[derive(Default)]
//! pub struct Counter { n: i64 }
//!
//! impl Operation for Counter {
//!     fn identity(&self) -> Identity { Identity::new("counter", 7300, "1.0.0", "counts") }
//!     fn parameters(&self) -> ParamSchema { CountParams::schema() }
//!     fn flags(&self) -> Vec<FlagDecl> { CountFlag::decls() }
//!     async fn activate(&mut self, _: &mut OpContext) -> Result<Step, OpError> {
//!         self.n = 0;
//!         Ok(Step::Continue)
//!     }
//!     async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
//!         self.n += 1;
//!         let p: CountParams = ctx.params().read()?;
//!         Ok(if self.n >= p.to { Step::finish(CountFlag::Counted) } else { Step::Continue })
//!     }
//! }
//! ```
//!
//! An operation steps every [`DEFAULT_PERIOD`](eo::DEFAULT_PERIOD) (100 ms of its
//! node's clock) unless it says otherwise, and must answer any command within
//! [`DEFAULT_DEADLINE`](eo::DEFAULT_DEADLINE) (2 s) or it is taken for hung. What must
//! survive its crash it keeps in a datamanager ([`dm`]). When a datamanager it uses
//! is gone (crashed, killed), the operation's steps wait for the DM's next incarnation, at
//! most [`DATAMANAGER_RETURN`](eo::DATAMANAGER_RETURN) (5 s), and go on.
//!
//! **What a datamanager's `Ok` promises** ([`dm::DmClient`], which an operation's context
//! hands out): `store` answers once the record is stored at the datamanager's durability —
//! with replicas, in a majority of their journals — and `put_all` once every record of many
//! is: a producer that must not drop records stores. `put`, `put_batch` and `put_waiting`
//! answer once the record is handed over, before it is stored: those on their way to an
//! instance that is lost (a crash, its node killed, frozen or cut off) are lost with it;
//! `put_waiting` waits for a credit of flow control, not for the record to be stored. Every
//! road follows a lost instance to the next one published under the datamanager's name, and
//! [`dm::DmClient::leader_node`] says which node holds a replicated datamanager's leader.
//! Each class keeps at most 10 000 records unless the datamanager says otherwise
//! ([`cluster::node::DatamanagerConfig::with_retention`]); the first it drops is told (a
//! `dm_retention` event).
//!
//! **2. A node** hosts the application's operations and datamanagers under supervision,
//! with one clock: [`Node::builder`]. Each operation type's declarations are checked before
//! anything starts, and a build whose panics abort is refused (self-healing needs panics to
//! unwind). An operation is built by `Default`, by a closure of the application's
//! ([`NodeBuilder::operation_from`]) or from a value ([`NodeBuilder::operation_value`]), so
//! it can be handed what it needs. [`OperationHandle`] then asks an operation about itself
//! by name, with typed calls and no epochs, and follows it across restarts. Its
//! datamanagers are in memory unless it has a data directory ([`NodeBuilder::data_dir`]):
//! there they keep journals, so what they acknowledged survives their crash and the
//! process's (`process` by default, `sync` for a power loss too:
//! [`cluster::node::DatamanagerConfig::with_durability`]).
//!
//! **3. A mission** — the task tree the dispatcher runs — is a mission file's text or built
//! in code ([`dispatcher::mission::MissionBuilder`]); [`Node::run`] checks it
//! against what runs, runs it and gives the report: the run's events, folded
//! ([`report`]).
//!
//! ```
//! # use marie::prelude::*;
//! # params! { pub struct CountParams { /// how far
//! #     to: i64 = 3, range(1, 1000); } }
//! # flags! { pub enum CountFlag { /// done
//! #     Counted = "counted", } }
//! # #[derive(Default)] pub struct Counter { n: i64 }
//! # impl Operation for Counter {
//! #     fn identity(&self) -> Identity { Identity::new("counter", 7300, "1.0.0", "counts") }
//! #     fn parameters(&self) -> ParamSchema { CountParams::schema() }
//! #     fn flags(&self) -> Vec<FlagDecl> { CountFlag::decls() }
//! #     async fn activate(&mut self, _: &mut OpContext) -> Result<Step, OpError> { self.n = 0; Ok(Step::Continue) }
//! #     async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
//! #         self.n += 1;
//! #         let p: CountParams = ctx.params().read()?;
//! #         Ok(if self.n >= p.to { Step::finish(CountFlag::Counted) } else { Step::Continue })
//! #     }
//! # }
//! use marie::dispatcher::mission::{ActionBuilder, MissionBuilder};
//! use marie::{Node, OperationHandle, RunOptions};
//!
//! # #[tokio::main(flavor = "multi_thread", worker_threads = 2)]
//! # async fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let node = Node::builder("guide").operation::<Counter>().start().await?;
//! let counter = OperationHandle::lookup("counter").await?;
//! assert_eq!(counter.param(CountParams::to()).await?, 3);
//!
//! let mission = MissionBuilder::new("count")
//!     .flags([CountFlag::Counted.name()])
//!     .success([CountFlag::Counted.name()])
//!     .action(ActionBuilder::new("count").op("counter", ParamMap::new().with(CountParams::to(), 5)));
//! let report = node.run(mission.clone(), RunOptions::new()).await?;
//! assert!(report.succeeded());
//!
//! // 4. the same mission with a fault: a panic 0.1 s in; the run's events as they come
//! let options = RunOptions::new()
//!     .fault("panic:counter@0.1".parse()?)
//!     .observe(|event| tracing::info!(?event.kind, "the run"));
//! let report = node.run(mission, options).await?;
//! assert!(report.succeeded());
//! assert_eq!((report.faults.len(), report.rebinds.len()), (1, 1));
//! node.shutdown().await;
//! # Ok(()) }
//! ```
//!
//! **4. Faults and the run's facts.** A crashed operation is restarted by its supervisor
//! and the dispatcher rebinds the mission to the new instance (or another that fits),
//! restores its parameters and carries on; a hung one is killed first. [`RunOptions`]
//! injects faults at given mission times (`kill`, `panic`, `hang`, `slow` of an operation;
//! `stop-node` of a node process `marie up` started) or at random (chaos), to test exactly
//! that. Every fact of a run — each step of the dispatcher, each binding, choice and
//! rebind, each supervisor's restart, each fault whatever its source, each node's news,
//! the robot's judgement — is an event on the node's bus
//! ([`Node::events`](cluster::node::Node::events), [`events`]); the report is their
//! fold, and an observer ([`RunOptions::observe`]) sees them as they happen.
//!
//! **5. A cluster from code.** Give the builder a cluster ([`NodeBuilder::cluster`]:
//! listen address, peers, cookie, optionally TLS and the failure detector's heartbeat):
//! `start()` joins it, [`Node::shutdown`] leaves, and the cluster's news (nodes up,
//! lost, declared down — within about 1.5 s of silence by default) are on the node's bus.
//! One node per process. Each process builds its instances from its own factories — code is
//! not shipped between nodes. An operation hosted with
//! `operation_with::<O>(|c| c.with_instances(0))` (or `operation_factory`) is a standby:
//! started only when no instance runs anywhere, after the
//! [provisioning grace](provision::GRACE) (1 s).
//!
//! **A replicated datamanager of your own.** A datamanager the application names
//! ([`dm::DmSpec::new`]) can be kept in replicas on three or more of its processes: each
//! declares it with the same replicas, the preferred leader first
//! ([`cluster::node::DatamanagerConfig::with_replicas`]), and gives its node a
//! [data directory](NodeBuilder::data_dir) for the replica's journal. Once a majority of
//! them run, one replica is elected leader; a `store` is acknowledged once a majority
//! journaled it; when the leader's process dies another replica is elected, every client
//! follows it and nothing acknowledged is lost. [`dm::DmClient::leader_node`] says where it
//! is. A declaration that cannot work (fewer than three, no data directory, no cluster) is
//! refused at start; [`NodeBuilder::datamanager`] says more.
//!
//! `embedding/failover` in the repository is a three-process application built this way:
//! its mission fails over when the process running its operation is killed, and its pump
//! log — a replicated datamanager of its own, with its own record kind — keeps every step
//! it acknowledged when that process, which holds the log's leader, is killed; its crate
//! docs walk through it.
//!
//! ```no_run
//! # use marie::prelude::*;
//! # #[derive(Clone)] struct Pump;
//! # impl Operation for Pump {
//! #     fn identity(&self) -> Identity { Identity::new("pump", 7400, "1.0.0", "pumps") }
//! #     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> { Ok(Step::Continue) }
//! # }
//! use marie::cluster::net::ClusterConfig;
//! use marie::cluster::node::DatamanagerConfig;
//! use marie::dm::{DmClient, DmSpec, RecordKind};
//! use std::time::Duration;
//!
//! const PUMP_LOG: DmSpec = DmSpec::new("pump-log", 7410);
//! const PUMPED: RecordKind<f64> = RecordKind::new("pumped");
//!
//! # #[tokio::main] async fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let node = marie::Node::builder("b") // "a" and "c" alike, each in its own process
//!     .operation_value(Pump)
//!     .data_dir("/var/lib/pumps/b")
//!     .datamanager(DatamanagerConfig::from(PUMP_LOG).with_replicas(["b", "a", "c"]))
//!     .cluster(ClusterConfig::new("127.0.0.1:7101".parse()?, "secret")
//!         .with_peer("127.0.0.1:7100".parse()?))
//!     .start()
//!     .await?;
//! let log = DmClient::lookup_within(PUMP_LOG.name, "b", Duration::from_secs(30)).await?;
//! log.store_kind(PUMPED, &0.1).await?; // acknowledged: in a majority of the journals
//! println!("pump-log leader: {}", log.leader_node().await?);
//! # node.shutdown().await; Ok(()) }
//! ```
//!
//! **The low road.** Each piece a node assembles can be had alone, for a test or a tool
//! that wants one: [`eo::spawn_operation`] hosts an operation with no node (and
//! [`eo::spawn_operation_linked`] under a [`supervision::Supervisor`] of your own),
//! and [`dispatcher::run_mission`] runs a checked mission with a bare dispatcher,
//! folding its events into a report. Nothing there checks declarations before start, shares
//! one clock, injects faults or judges a run: a node does, which is why the road above
//! goes through one.
//!
//! The repository's `marie/examples/` are applications on this road: `custom_operation`
//! (an operation hosted, asked about itself, run by a mission), `self_healing` (a panic
//! healed while a mission runs) and `embedding` (an application's own datamanager,
//! supervisor and mission); `cargo run -p marie --example embedding`.
//!
//! **Your own ractor actors** beside marie need [`RactorMessage`] on their message types:
//! marie's cluster transport turns on ractor's `cluster` feature for the whole build (see
//! there for why).

#![warn(missing_docs)]

// One path per public name: the modules of the crates under this one, side by side, so an
// application never needs to know which crate holds what (marie-vocabulary, marie-dm,
// marie-actors: ARCHITECTURE.md says why they are apart).
pub use marie_actors::{choice, flags, params};
pub use marie_actors::{declare, dispatcher, eo, provision};
pub use marie_cluster as cluster;
pub use marie_dm as dm;
pub use marie_supervision as supervision;
pub use marie_vocabulary::remote_message;
pub use marie_vocabulary::{
    clock, diagnostic, events, fence, property, registry, replica, report, run, status, wire,
};

/// Everything an operation author needs in one import: `use marie::prelude::*;`.
pub use marie_actors::prelude;

pub use marie_cluster::node::{Node, NodeBuilder, RunOptions};

/// An application's hold on an operation by name: typed calls, no epochs, restarts followed
/// (the same type as [`eo::OperationHandle`], where its errors live too).
///
/// ```
/// use marie::prelude::*;
/// use marie::{Node, OperationHandle};
///
/// params! {
///     pub struct HeatParams {
///         /// the temperature to hold
///         target: f64 = 20.0, range(5, 30), unit("°C");
///     }
/// }
///
/// #[derive(Default)]
/// struct Heater;
/// impl Operation for Heater {
///     fn identity(&self) -> Identity { Identity::new("heater", 7201, "1.0.0", "heats") }
///     fn parameters(&self) -> ParamSchema { HeatParams::schema() }
///     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> { Ok(Step::Continue) }
/// }
///
/// # #[tokio::main(flavor = "current_thread")] async fn main() -> Result<(), Box<dyn std::error::Error>> {
/// let node = Node::builder("house").operation::<Heater>().start().await?;
/// let heater = OperationHandle::lookup("heater").await?;
/// heater.set(ParamMap::new().with(HeatParams::target(), 22.5)).await?;
/// assert_eq!(heater.param(HeatParams::target()).await?, 22.5);
/// // a value out of its range is refused, naming why
/// assert!(heater.set(ParamMap::new().with(HeatParams::target(), 45.0)).await.is_err());
/// node.shutdown().await;
/// # Ok(()) }
/// ```
pub use marie_actors::eo::OperationHandle;

/// Derive [`ractor::Message`](https://docs.rs/ractor/0.16/ractor/trait.Message.html) for a
/// message type of your own ractor actors.
///
/// marie runs on ractor with its `cluster` feature, which ractor_cluster turns on for the
/// whole build — so for every crate that links marie, too. With that feature ractor drops
/// its blanket `impl<T: Send + 'static> Message for T`: a plain `enum MyMsg { .. }` no
/// longer compiles as an actor's message (`the trait bound `MyMsg: Message` is not
/// satisfied`) until it has its own impl. This derive writes that impl, for messages that
/// stay in the process (the trait's default, local-only methods). It is ractor_cluster's
/// own `RactorMessage`, re-exported so you need no ractor_cluster dependency of your own.
///
/// The derive expands to `impl ractor::Message for MyMsg {}`: the crate using it must
/// depend on `ractor` under that name (the one marie uses, 0.16). The hand-written
/// equivalent, for a type the derive cannot reach, is that same line.
///
/// ```
/// use ractor::{Actor, ActorProcessingErr, ActorRef, RpcReplyPort};
///
/// #[derive(marie::RactorMessage)]
/// enum CounterMsg {
///     Add(i64),
///     Get(RpcReplyPort<i64>),
/// }
///
/// struct Counter;
///
/// impl Actor for Counter {
///     type Msg = CounterMsg;
///     type State = i64;
///     type Arguments = ();
///     async fn pre_start(&self, _: ActorRef<CounterMsg>, _: ()) -> Result<i64, ActorProcessingErr> {
///         Ok(0)
///     }
///     async fn handle(
///         &self,
///         _: ActorRef<CounterMsg>,
///         msg: CounterMsg,
///         total: &mut i64,
///     ) -> Result<(), ActorProcessingErr> {
///         match msg {
///             CounterMsg::Add(n) => *total += n,
///             CounterMsg::Get(reply) => {
///                 let _ = reply.send(*total);
///             }
///         }
///         Ok(())
///     }
/// }
///
/// # #[tokio::main(flavor = "current_thread")] async fn main() {
/// let (counter, handle) = Actor::spawn(None, Counter, ()).await.unwrap();
/// counter.cast(CounterMsg::Add(2)).unwrap();
/// counter.cast(CounterMsg::Add(3)).unwrap();
/// assert_eq!(ractor::call!(counter, CounterMsg::Get).unwrap(), 5);
/// counter.stop(None);
/// handle.await.unwrap();
/// # }
/// ```
///
/// Messages that must cross nodes need an impl that serializes them: marie's own interface
/// messages get theirs from [`remote_message!`] (rmp-serde); ractor_cluster's
/// `RactorClusterMessage` derive is the other way.
pub use ractor_cluster::RactorMessage;
