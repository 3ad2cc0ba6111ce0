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
