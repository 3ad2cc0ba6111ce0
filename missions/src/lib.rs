//! # marie-missions
//!
//! The operations, worlds and missions that marie runs — the framework used the way a user's
//! own robot would use it: the thesis' robot operations ([`ops`]) against a simulated cart
//! ([`hardware`], [`sim`], [`world`]), and the [`demo`] operations (a signal sampler, an
//! averager and a checker that exchange data only through the datamanagers).
//!
//! Operations are offered as [`OperationFactory`]s, so a supervisor can start a fresh
//! instance after every crash; [`spawn_builtin`] starts the demo's unsupervised.
//!
//! ```no_run
//! # #[tokio::main] async fn main() {
//! let clock = marie_vocabulary::clock::RealClock::shared();
//! let names: Vec<&str> = marie_missions::builtin_operations().iter().map(|f| f.name).collect();
//! assert_eq!(names, ["sampler", "averager", "checker"]);
//! let actors = marie_missions::spawn_builtin(clock).await.unwrap();
//! assert_eq!(actors.len(), 3);
//! # }
//! ```

#![warn(missing_docs)]

pub mod algo;
pub mod demo;
pub mod embedded;
pub mod fresh_start;
pub mod geom;
pub mod hardware;
pub mod ops;
pub mod picture;
pub mod robot;
mod robot_report;
pub mod sim;
pub mod telemetry;
pub mod world;

use marie_actors::eo::HostOptions;
pub use marie_actors::eo::{OperationFactory, StartOperation};
use marie_vocabulary::clock::SharedClock;
use ractor::{ActorCell, SpawnErr};

/// The built-in demo operations (sampler, averager, checker).
pub fn builtin_operations() -> Vec<OperationFactory> {
    vec![
        OperationFactory::of::<demo::Sampler>("sampler"),
        OperationFactory::of::<demo::Averager>("averager"),
        OperationFactory::of::<demo::Checker>("checker"),
    ]
}

/// The robot's operations — both versions of the wall follower, so the dispatcher has a
/// choice. They find the cart through the registry, so they need no arguments.
pub fn robot_operations() -> Vec<OperationFactory> {
    vec![
        OperationFactory::of::<ops::Ultrasonic>("ultrasonic"),
        OperationFactory::of::<ops::SegmentExtractor>("segment-extractor"),
        OperationFactory::of::<ops::WallSensor>("wall-sensor"),
        OperationFactory::of::<ops::DockingDetector>("docking-detector"),
        OperationFactory::of::<ops::PathPlanner>("path-planner"),
        OperationFactory::of::<ops::TrajectoryController>("trajectory-controller"),
        OperationFactory::of::<ops::WallFollowerV1>("wall-follower"),
        OperationFactory::of::<ops::WallFollowerV1_1>("wall-follower"),
        OperationFactory::of::<ops::WallFollowerV2>("wall-follower"),
        // the next build's (feature `next-protocol`): the newer version of the two-build tests
        #[cfg(feature = "next-protocol")]
        OperationFactory::of::<ops::WallFollowerV1_2>("wall-follower"),
        OperationFactory::of::<ops::SensorBasedController>("sensor-based-controller"),
        OperationFactory::of::<ops::CollisionAvoidance>("collision-avoidance"),
        OperationFactory::of::<ops::Localizer>("localizer"),
    ]
}

/// Every operation this crate offers — the demo's and the robot's: the catalogue a node
/// picks what it hosts from ([`marie_cluster::node::NodeConfig`]).
pub fn catalog() -> Vec<OperationFactory> {
    let mut all = builtin_operations();
    all.extend(robot_operations());
    all
}

/// Start every operation of `factories` on `clock`, unsupervised.
async fn start_all(
    factories: Vec<OperationFactory>,
    clock: SharedClock,
) -> Result<Vec<ActorCell>, SpawnErr> {
    let opts = HostOptions::with_clock(clock);
    let mut cells = Vec::with_capacity(factories.len());
    for f in factories {
        cells.push((f.start)(opts.clone(), None).await?);
    }
    Ok(cells)
}

/// Spawn one host for each built-in operation, unsupervised, on `clock`.
pub async fn spawn_builtin(clock: SharedClock) -> Result<Vec<ActorCell>, SpawnErr> {
    start_all(builtin_operations(), clock).await
}

/// Spawn the virtual cart driving `world` (noise seeded by `seed`) on `clock`, linked to
/// `supervisor` if given. It publishes itself before this returns.
pub async fn spawn_cart(
    clock: SharedClock,
    world: &world::World,
    seed: u64,
    supervisor: Option<ActorCell>,
) -> Result<ActorCell, SpawnErr> {
    spawn_cart_sampled(clock, world, seed, supervisor, None).await
}

/// [`spawn_cart`], publishing its pose through `poses` (see [`telemetry`]).
pub async fn spawn_cart_sampled(
    clock: SharedClock,
    world: &world::World,
    seed: u64,
    supervisor: Option<ActorCell>,
    poses: Option<telemetry::PoseSampler>,
) -> Result<ActorCell, SpawnErr> {
    let args = hardware::CartArgs {
        sim: sim::Simulation::new(world, seed),
        clock,
        period: std::time::Duration::from_millis(20),
        poses,
    };
    Ok(match supervisor {
        Some(sup) => hardware::spawn_cart_linked(args, sup).await?.0.get_cell(),
        None => hardware::spawn_cart(args).await?.0.get_cell(),
    })
}
