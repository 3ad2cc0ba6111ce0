//! # marie
//!
//! An actor framework for robot control with supervision and self-healing: the control
//! architecture of the MARIE mobile robot (elementary operations, datamanagers, an action
//! dispatcher, a location table) re-created as [ractor] actors.
//!
//! This crate is the facade: it re-exports the member crates — [`actors`] (the interfaces,
//! the registry, the dispatcher), [`supervision`], [`cluster`] (the node, its transport),
//! [`missions`] (the simulated robot) — and offers [`embedded::Embedded`], the
//! single-process node the `marie` command runs.
//!
//! # Embedding marie: operation → node → mission → faults
//!
//! **1. An operation** is a type that implements [`actors::eo::Operation`]: who it is, the
//! parameters and flags it declares, and what it does each step. Declare parameters with
//! [`params!`](actors::params) and flags with [`flags!`](macro@actors::flags): a misspelt name is
//! then a compile error, and the prelude has all an operation needs.
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
//!     async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
//!         self.n += 1;
//!         let p: CountParams = ctx.params().read()?;
//!         Ok(if self.n >= p.to { Step::finish(CountFlag::Counted) } else { Step::Continue })
//!     }
//! }
//! ```
//!
//! **2. A node** hosts the application's operations and datamanagers under supervision,
//! with one clock: [`node::Node::builder`]. Each operation type's declarations are checked
//! before anything starts, and a build whose panics abort is refused (self-healing needs
//! panics to unwind). [`OperationHandle`] then asks an operation about itself by name, with
//! typed calls and no epochs, and follows it across restarts.
//!
//! **3. A mission** — the task tree the dispatcher runs — is a mission file's text or built
//! in code ([`actors::dispatcher::mission::MissionBuilder`]); [`node::Node::run`] checks it
//! against what runs and gives the report.
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
//! #     async fn step(&mut self, ctx: &mut OpContext) -> Result<Step, OpError> {
//! #         self.n += 1;
//! #         let p: CountParams = ctx.params().read()?;
//! #         Ok(if self.n >= p.to { Step::finish(CountFlag::Counted) } else { Step::Continue })
//! #     }
//! # }
//! use marie::actors::dispatcher::mission::{ActionBuilder, MissionBuilder};
//! use marie::node::{Node, RunOptions};
//!
//! # #[tokio::main(flavor = "multi_thread", worker_threads = 2)]
//! # async fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let node = Node::builder("guide").operation::<Counter>().start().await?;
//! let counter = marie::OperationHandle::lookup("counter").await?;
//! assert_eq!(counter.param(CountParams::to()).await?, 3);
//!
//! let mission = MissionBuilder::new("count")
//!     .flags([CountFlag::Counted.name()])
//!     .success([CountFlag::Counted.name()])
//!     .action(ActionBuilder::new("count").op("counter", ParamMap::new().with(CountParams::to(), 5)));
//! let report = node.run(mission, RunOptions::new()).await?;
//! assert!(report.succeeded());
//! node.shutdown().await;
//! # Ok(()) }
//! ```
//!
//! **4. Faults.** A crashed operation is restarted by its supervisor and the dispatcher
//! rebinds the mission to the new instance, restores its parameters and carries on;
//! [`node::RunOptions`] injects kills, panics and hangs at given mission times (or at
//! random: chaos) to test exactly that, and the report lists each fault and rebind.
//! `examples/embedding.rs` puts the four steps together in one application.
//!
//! **5. A cluster from code.** Give the builder a cluster ([`node::NodeBuilder::cluster`]:
//! listen address, peers, cookie, optionally TLS and the failure detector's heartbeat):
//! `start()` joins it, [`node::Node::shutdown`] leaves, and the cluster's news (nodes up,
//! lost, declared down) are on the node's bus. One node per process. Hand operations what
//! they need with [`node::NodeBuilder::operation_from`] (a closure called for every
//! instance and restart) or [`node::NodeBuilder::operation_value`]; each process builds its
//! instances from its own factories — code is not shipped between nodes. A pump hosted
//! with `operation_factory(.., |c| c.with_instances(0))` is a standby: started only when
//! no instance runs anywhere, after the 1 s provisioning grace
//! ([`actors::provision::GRACE`]). `embedding/failover` in the repository is a
//! two-process application built this way whose mission fails over when the process
//! running its operation is killed; its crate docs walk through it.
//!
//! ```no_run
//! # use marie::prelude::*;
//! # #[derive(Clone)] struct Pump;
//! # impl Operation for Pump {
//! #     fn identity(&self) -> Identity { Identity::new("pump", 7400, "1.0.0", "pumps") }
//! #     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> { Ok(Step::Continue) }
//! # }
//! use marie::net::ClusterConfig;
//! # #[tokio::main] async fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let node = marie::node::Node::builder("b")
//!     .operation_value(Pump)
//!     .cluster(ClusterConfig::new("127.0.0.1:7101".parse()?, "secret")
//!         .with_peer("127.0.0.1:7100".parse()?))
//!     .start()
//!     .await?;
//! # node.shutdown().await; Ok(()) }
//! ```
//!
//! **Your own ractor actors** beside marie need [`RactorMessage`] on their message types:
//! marie's cluster transport turns on ractor's `cluster` feature for the whole build (see
//! there for why).
//!
#![warn(missing_docs)]

pub use marie_actors as actors;
pub use marie_cluster as cluster;
pub use marie_missions as missions;
pub use marie_supervision as supervision;

pub use marie_cluster::{fault, layout, net, node, relay};

/// Everything an operation author needs in one import: `use marie::prelude::*;` (see
/// [`actors::prelude`]).
pub use marie_actors::prelude;

/// An application's hold on an operation by name: typed calls, no epochs, restarts followed
/// (the same type as [`actors::eo::OperationHandle`], where its errors live too).
///
/// ```
/// use marie::actors::eo::{self, Identity, OpContext, OpError, Operation, Step};
/// use marie::actors::property::{params, ParamDecl, ParamSchema, Value};
///
/// struct Heater;
/// impl Operation for Heater {
///     fn identity(&self) -> Identity { Identity::new("heater", 7201, "1.0.0", "heats") }
///     fn parameters(&self) -> ParamSchema {
///         ParamSchema::new(vec![ParamDecl::float("target", 20.0).range(5.0, 30.0).unit("°C")])
///     }
///     async fn step(&mut self, _: &mut OpContext) -> Result<Step, OpError> { Ok(Step::Continue) }
/// }
///
/// # #[tokio::main(flavor = "current_thread")] async fn main() {
/// eo::spawn_operation(Heater, Default::default()).await.unwrap();
/// let heater = marie::OperationHandle::lookup("heater").await.unwrap();
/// heater.set(params([("target", Value::Float(22.5))])).await.unwrap();
/// assert_eq!(heater.value::<f64>("target").await.unwrap(), 22.5);
/// # }
/// ```
pub use marie_actors::eo::OperationHandle;

/// Derive [`ractor::Message`] for a message type of your own ractor actors.
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
/// messages get theirs from [`actors::remote_message!`] (rmp-serde); ractor_cluster's
/// `RactorClusterMessage` derive is the other way.
pub use ractor_cluster::RactorMessage;

pub mod embedded;
