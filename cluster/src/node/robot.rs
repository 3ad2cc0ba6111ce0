//! The plug a robot fits into a node: a node knows no robot.
//!
//! A node hosts datamanagers, operations and a dispatcher; what a *robot* adds — the
//! a-priori knowledge it stores before any operation runs (a map), the drivers of its
//! hardware (a cart), and its own verdict on a run (did the cart end where it should) — comes
//! through the [`Robot`] trait, which `marie-missions` implements for its simulated cart and
//! an embedder implements for theirs. The operations a node can host come separately, as
//! [`OperationFactory`](marie_actors::eo::OperationFactory)s: a catalogue.
//!
//! A robot also gets the node's [`EventBus`]: its drivers when they start
//! ([`Robot::drivers`]) and the robot itself when a run starts ([`Robot::run_starting`]), so
//! it can put what it sees *as it happens* into the node's one event stream
//! ([`EventKind::Robot`](marie_vocabulary::events::EventKind::Robot)) — a live monitor, or a
//! replay of an events file, draws the robot from that stream alone, not from a picture made
//! after the run. Its judgement of a run ([`Robot::judge`]) goes onto the same stream
//! ([`EventKind::Judged`](marie_vocabulary::events::EventKind::Judged)), and so into the report:
//! what it says of itself is a [`RobotSection`] the framework carries without typing.

use marie_dm::NewRecord;
use marie_supervision::ChildSpec;
use marie_vocabulary::clock::SharedClock;
use marie_vocabulary::events::EventBus;
use marie_vocabulary::report::RunReport;
use marie_vocabulary::run::{Outcome, RobotSection};
use std::future::Future;
use std::pin::Pin;
use tokio::task::JoinHandle;

/// A boxed future, as trait objects return them.
pub type BoxFuture<'a, T> = Pin<Box<dyn Future<Output = T> + Send + 'a>>;

/// A record a robot stores in a datamanager before any operation starts (and again after
/// that datamanager restarts empty; a durable one reads it back from its journal instead):
/// a-priori knowledge such as the map of the walls.
#[derive(Clone, Debug)]
pub struct AprioriRecord {
    /// The datamanager's registry name (e.g. `world`).
    pub datamanager: String,
    /// The record.
    pub record: NewRecord,
}

/// A robot a node drives.
pub trait Robot: Send + Sync + 'static {
    /// What it is, for logs and reports (e.g. the world it drives in).
    fn describe(&self) -> String;

    /// Records the node stores in its datamanagers before any operation starts.
    fn apriori(&self) -> Vec<AprioriRecord>;

    /// The drivers of its hardware, started under the node's root supervisor after the
    /// datamanagers and before the operations (the cart), on the node's `clock`, publishing
    /// what they report on the node's `events` bus. Empty when the node runs none.
    fn drivers(&self, clock: &SharedClock, events: &EventBus) -> Vec<ChildSpec>;

    /// A run is about to start on this node (called before its dispatcher starts): publish
    /// on `events` what a viewer of the run needs first (the world), start reporting the
    /// run as it goes, and give the tasks that report it: the node aborts them when its
    /// next run starts (so nothing is told twice) and at its shutdown. Does nothing unless
    /// the robot says otherwise. Publishing never blocks ([`EventBus::publish`]), so this
    /// holds a run back no longer than the robot's own set-up takes.
    fn run_starting<'a>(&'a self, events: &'a EventBus) -> BoxFuture<'a, Vec<JoinHandle<()>>> {
        let _ = events;
        Box::pin(async { Vec::new() })
    }

    /// The node started without a dispatcher: the runs that use this robot are dispatched
    /// from another node, and [`Robot::run_starting`] is never called here — this node is
    /// not told when a run starts. Start telling `events` what a viewer of those runs needs
    /// from this node's part of the robot (for the simulated cart: the world and the cart's
    /// poses, from now on), and give the tasks that keep doing it; the node aborts them at
    /// its shutdown. Called once, after the node's tree (and so its drivers) started, before
    /// it joins a cluster — a viewer may come at any time later, so whatever it needs first
    /// must be told again now and then. Does nothing unless the robot says otherwise.
    fn dispatched_elsewhere(&self, events: &EventBus) -> Vec<JoinHandle<()>> {
        let _ = events;
        Vec::new()
    }

    /// Judge a run the dispatcher ended — `run`, its report so far: its outcome (and
    /// reason, on a failure), and what it bound when (`bound_epochs`, to check the robot's
    /// fences against): the outcome after judgement — a success turned into a failure when
    /// the robot did not end where it should — and what the robot says of the run (for
    /// the simulated cart: final pose, collisions, seed, verdict, commands refused and
    /// obeyed late by epoch), which the node publishes as the run's `judged` event.
    fn judge<'a>(&'a self, run: &'a RunReport) -> BoxFuture<'a, RunJudgement>;
}

/// A robot's judgement of a run ([`Robot::judge`]).
#[derive(Clone, Debug, PartialEq)]
pub struct RunJudgement {
    /// The outcome after judgement.
    pub outcome: Outcome,
    /// Why it failed (empty on success).
    pub reason: String,
    /// What the robot says of the run, written into the report beside its own fields.
    pub robot: RobotSection,
}
