//! # marie-supervision
//!
//! Supervision for marie's actors with Erlang/OTP semantics. ractor links
//! actors and reports a linked child's exit to its parent, but has no strategies, restart
//! types, restart intensity, ordered shutdown or backoff — and its default
//! `handle_supervisor_evt` stops the parent when any child stops. This crate adds a
//! [`Supervisor`] actor that does what OTP's `supervisor` does, so that a robot's operations
//! and datamanagers heal themselves and a fault that keeps recurring escalates up the tree
//! instead of looping forever.
//!
//! * **Strategies** ([`Strategy`]): one-for-one, one-for-all, rest-for-one; children can also
//!   be added, terminated, restarted and deleted at run time ([`SupervisorRef`]).
//! * **Simple-one-for-one** ([`SupervisorSpec::simple_one_for_one`]): one
//!   [`ChildTemplate`] whose start function takes an argument, and any number of instances
//!   started at run time ([`SupervisorRef::start_dynamic`]), each restarted on its own with
//!   its own argument, stopped by actor ([`SupervisorRef::terminate_actor`]), and all stopped
//!   together on shutdown — "start another instance of operation X" for a node's failover.
//! * **Restart types** ([`Restart`]): permanent, transient, temporary, judged by the exit
//!   reason ([`ExitReason`] documents the convention: a clean stop or [`NORMAL`] is normal,
//!   [`SHUTDOWN`] is a shutdown, anything else — panic, `Err`, kill, other reason — is
//!   abnormal). A temporary child leaves nothing behind: neither its spec once it stopped nor
//!   its start parameters once it started.
//! * **Ignore** ([`ChildStart::Ignore`]): a start function may decline to run the child (OTP's
//!   `ignore`); a static child then stays, not running, until `restart_child`.
//! * **Restart intensity**: more than `max_restarts` restarts within a sliding `period`
//!   ([`Intensity`]) and the supervisor stops its children in reverse start order and fails
//!   with [`REACHED_MAX_RESTART_INTENSITY`], which its parent treats as an abnormal exit — so
//!   a fault that keeps recurring climbs the tree, one supervisor at a time.
//! * **Shutdown specs** ([`Shutdown`]): brutal kill, stop-then-kill after a timeout, or wait
//!   forever (child supervisors). Children start in order and stop in reverse order.
//! * **Backoff** ([`Backoff`]): opt-in exponential delays with seeded jitter (xoshiro256**,
//!   the project's one seeded generator) between restart attempts; off by default, as in OTP.
//! * **Validation** ([`SupervisorSpec::validate`], [`ChildSpec::validate`],
//!   [`check_child_specs`]): specs that type-check but cannot work — a zero period, duplicate
//!   or empty ids, a zero shutdown timeout, a simple-one-for-one supervisor without exactly
//!   its template — are refused with a typed [`SpecError`] before anything starts.
//! * **Unwinding required** ([`require_unwinding`]): a supervisor refuses to start in a
//!   build with `panic = "abort"` ([`SupervisorError::PanicsAbort`]), where a panicking child
//!   would end the process instead of being restarted.
//! * **Introspection and events**: [`SupervisorRef::which_children`],
//!   [`SupervisorRef::count_children`], per-child restart counts, and a broadcast of
//!   [`SupervisorEvent`]s ([`SupervisorRef::subscribe`]) to wait on instead of sleeping.
//!
//! The test suite ports Erlang/OTP's `supervisor_SUITE`: its test names are OTP's cases.
//!
//! A child is described by a [`ChildSpec`] whose start function **spawns the child linked to
//! the supervisor cell it is given**; the supervisor calls it again for every restart.
//!
//! ```
//! use marie_supervision::{ChildSpec, Supervisor, SupervisorEvent, SupervisorSpec};
//! use ractor::{Actor, ActorProcessingErr, ActorRef};
//! use std::time::Duration;
//!
//! /// A worker that fails on request.
//! struct Flaky;
//! struct Crash;
//! impl ractor::Message for Crash {}
//!
//! impl Actor for Flaky {
//!     type Msg = Crash;
//!     type State = ();
//!     type Arguments = ();
//!     async fn pre_start(&self, _: ActorRef<Crash>, _: ()) -> Result<(), ActorProcessingErr> {
//!         Ok(())
//!     }
//!     async fn handle(&self, _: ActorRef<Crash>, _: Crash, _: &mut ()) -> Result<(), ActorProcessingErr> {
//!         Err("sensor glitch".into())
//!     }
//! }
//!
//! # #[tokio::main(flavor = "current_thread")]
//! # async fn main() {
//! let spec = SupervisorSpec::one_for_one().with_intensity(3, Duration::from_secs(5));
//! let children = vec![ChildSpec::worker("flaky", |sup| async move {
//!     let (actor, _) = Actor::spawn_linked(None, Flaky, (), sup).await?;
//!     Ok(actor.get_cell())
//! })];
//! let (sup, _) = Supervisor::start(None, spec, children).await.unwrap();
//! let mut events = sup.subscribe().await.unwrap();
//!
//! // crash the worker: the supervisor restarts it as a new actor
//! let first = sup.which_children().await.unwrap()[0].state.actor().unwrap().clone();
//! ActorRef::<Crash>::from(first.clone()).cast(Crash).unwrap();
//! loop {
//!     if let SupervisorEvent::ChildRestarted { id, old, .. } = events.recv().await.unwrap() {
//!         assert_eq!(id, "flaky");
//!         assert_eq!(old, Some(first.get_id()));
//!         break;
//!     }
//! }
//! assert_eq!(sup.which_children().await.unwrap()[0].restarts, 1);
//! sup.stop().await;
//! # }
//! ```
//!
//! A simple-one-for-one supervisor starts instances of one template, each with its argument:
//!
//! ```
//! use marie_supervision::{ChildTemplate, Restart, Supervisor, SupervisorSpec};
//! use ractor::{Actor, ActorProcessingErr, ActorRef};
//!
//! /// One wall follower, keeping `distance` metres from the wall.
//! struct WallFollower;
//!
//! impl Actor for WallFollower {
//!     type Msg = ();
//!     type State = f64;
//!     type Arguments = f64;
//!     async fn pre_start(&self, _: ActorRef<()>, distance: f64) -> Result<f64, ActorProcessingErr> {
//!         Ok(distance)
//!     }
//! }
//!
//! # #[tokio::main(flavor = "current_thread")]
//! # async fn main() {
//! // transient: an instance that finishes its job is not restarted; a crashed one is, with
//! // its own distance
//! let template = ChildTemplate::actor("wall-follower", |distance: f64| (WallFollower, distance))
//!     .with_restart(Restart::Transient);
//! let (sup, _) = Supervisor::start(None, SupervisorSpec::simple_one_for_one(template), vec![])
//!     .await
//!     .unwrap();
//! let near = sup.start_dynamic(0.5_f64).await.unwrap();
//! sup.start_dynamic(1.2_f64).await.unwrap();
//! assert_eq!(sup.count_children().await.unwrap().active, 2);
//! // the argument's type is the template's: anything else is refused, nothing starts
//! assert!(sup.start_dynamic("half a metre").await.is_err());
//! sup.terminate_actor(near.get_id()).await.unwrap();
//! assert_eq!(sup.which_children().await.unwrap().len(), 1);
//! sup.stop().await;
//! # }
//! ```

#![warn(missing_docs)]

mod backoff;
mod child;
mod error;
mod events;
mod exit;
mod handle;
mod info;
mod intensity;
mod messages;
mod nest;
mod simple;
mod spec;
mod start;
mod strategy;
mod supervisor;
mod terminate;
mod unwind;
mod validate;

pub use backoff::Backoff;
pub use child::{ChildKind, ChildSpec, ChildStart, Restart, Shutdown, StartFn, StartFuture};
pub use error::{SpecError, StartError, SupervisorError};
pub use events::{RestartCause, SupervisorEvent};
pub use exit::{ExitReason, NORMAL, REACHED_MAX_RESTART_INTENSITY, SHUTDOWN};
pub use handle::SupervisorRef;
pub use info::{ChildCounts, ChildInfo, ChildState};
pub use intensity::Intensity;
pub use messages::{Internal, SupervisorMsg};
pub use simple::{ChildTemplate, DynamicArg};
pub use spec::{SupervisorSpec, MAX_BACKOFF, MAX_EVENT_CAPACITY};
pub use strategy::Strategy;
pub use supervisor::{Supervisor, SupervisorArgs, SupervisorState};
pub use unwind::{require_unwinding, PANICS_UNWIND};
pub use validate::check_child_specs;
