//! # marie-missions
//!
//! The operations, worlds and missions that marie runs — the framework used the way a user's
//! own robot would use it. Until the simulated robot lands, it holds the [`demo`]
//! operations: a signal sampler, an averager and a checker that exchange data only through
//! the datamanagers, driven by `missions/demo.toml`.
//!
//! ```no_run
//! # #[tokio::main] async fn main() {
//! let clock = marie_actors::clock::RealClock::shared();
//! let actors = marie_missions::spawn_builtin(clock).await.unwrap();
//! assert_eq!(actors.len(), 3);
//! # }
//! ```

#![warn(missing_docs)]

pub mod algo;
pub mod demo;
pub mod geom;
pub mod hardware;
pub mod ops;
pub mod picture;
pub mod sim;
pub mod world;

use marie_actors::clock::SharedClock;
use marie_actors::eo::{spawn_operation, HostOptions};
use ractor::{ActorCell, SpawnErr};

/// Spawn one host for each built-in operation, unsupervised, on `clock`.
pub async fn spawn_builtin(clock: SharedClock) -> Result<Vec<ActorCell>, SpawnErr> {
    let opts = HostOptions::with_clock(clock);
    Ok(vec![
        spawn_operation(demo::Sampler::default(), opts.clone())
            .await?
            .0
            .get_cell(),
        spawn_operation(demo::Averager::default(), opts.clone())
            .await?
            .0
            .get_cell(),
        spawn_operation(demo::Checker, opts).await?.0.get_cell(),
    ])
}

/// Spawn the robot on `clock`: the virtual cart driving `world` (noise seeded by `seed`) and
/// one host for each of the robot's operations — both versions of the wall follower, so the
/// dispatcher has a choice. Unsupervised; the cart publishes itself before this returns.
pub async fn spawn_robot(
    clock: SharedClock,
    world: &world::World,
    seed: u64,
) -> Result<Vec<ActorCell>, SpawnErr> {
    let (cart, _) = hardware::spawn_cart(hardware::CartArgs {
        sim: sim::Simulation::new(world, seed),
        clock: clock.clone(),
        period: std::time::Duration::from_millis(20),
    })
    .await?;
    let opts = HostOptions::with_clock(clock);
    let mut cells = vec![cart.get_cell()];
    macro_rules! host {
        ($($op:expr),* $(,)?) => {
            $( cells.push(spawn_operation($op, opts.clone()).await?.0.get_cell()); )*
        };
    }
    host!(
        ops::Ultrasonic::default(),
        ops::SegmentExtractor::default(),
        ops::WallSensor::default(),
        ops::DockingDetector::default(),
        ops::PathPlanner::default(),
        ops::TrajectoryController::default(),
        ops::WallFollowerV1::default(),
        ops::WallFollowerV2::default(),
        ops::SensorBasedController::default(),
        ops::CollisionAvoidance::default(),
    );
    Ok(cells)
}
