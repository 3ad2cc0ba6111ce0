//! Where a run starts on a cluster kept up between runs.
//!
//! The cart of a cluster lives as long as its node: the next run finds it where the last
//! one left it — parked in the dock after a docking run — as a real cart would be, and its
//! collisions and path carry on. A mission written for the world's start (docking follows
//! the wall from there) then fails. [`restart_at_world_start`] puts the simulated cart
//! back at the world's start, at rest, its collisions and path started anew, and tells the
//! operations that its odometry starts over there: a correction that is the identity, newer
//! than the last run's (the localizer's correction of the old odometry would misplace
//! everything). [`at_world_start`] says whether a run would start where the first did.

use crate::geom::{wrap_angle, Pose};
use crate::hardware::{CartClient, CartError, CartStatus};
use crate::ops::records::{LocationRecord, LOCATION};
use crate::world::World;
use marie_dm::{DmClient, DmError, WORLD};
use std::time::Duration;

/// How far from the world's start pose the cart may be and still count as there: a
/// centimetre, a degree.
const AT_START: (f64, f64) = (0.01, 1.0);

/// How long the world datamanager may take to be found (a replicated one's leader being
/// elected).
const FIND_WORLD_DM: Duration = Duration::from_secs(10);

/// The datamanagers' `source` of the correction it stores.
const SOURCE: &str = "fresh-start";

/// Why the cart could not be put back at the world's start.
#[derive(Debug, thiserror::Error)]
pub enum FreshStartError {
    /// The cart did not answer (or none runs).
    #[error("the cart could not be put back at the world's start: {0}")]
    Cart(#[from] CartError),
    /// The world datamanager did not take the new odometry correction: the operations
    /// would place the cart with the last run's.
    #[error("the cart is back at the world's start, but the world datamanager did not take its fresh odometry: {0}")]
    Datamanager(#[from] DmError),
}

/// Put the cart back at rest at the world's start pose (its collisions and path started
/// anew) and store in the world datamanager that its odometry starts over there; the cart's
/// status from there. Between runs: a run's operations would see the cart jump.
pub async fn restart_at_world_start() -> Result<CartStatus, FreshStartError> {
    let status = CartClient::lookup()?.restart().await?;
    let fresh = LocationRecord {
        correction: Pose::default(),
        odometry: status.odometry,
        pose: status.pose,
        matched: 0,
    };
    DmClient::lookup_within(WORLD.name, SOURCE, FIND_WORLD_DM)
        .await?
        .store_kind(LOCATION, &fresh)
        .await?;
    Ok(status)
}

/// Whether `pose` is `world`'s start pose (within a centimetre and a degree).
pub fn at_world_start(world: &World, pose: &Pose) -> bool {
    let start = world.start;
    let (metres, degrees) = AT_START;
    (pose.x - start.x).hypot(pose.y - start.y) <= metres
        && wrap_angle(pose.theta - start.theta).abs() <= degrees.to_radians()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_start_is_the_worlds_start_pose_within_a_centimetre_and_a_degree() {
        let world = World::builtin("lab").unwrap();
        let s = world.start;
        assert!(at_world_start(&world, &s));
        let near = Pose::new(s.x + 0.005, s.y - 0.005, s.theta + 0.5f64.to_radians());
        assert!(at_world_start(&world, &near));
        assert!(!at_world_start(
            &world,
            &Pose::new(s.x + 0.02, s.y, s.theta)
        ));
        assert!(!at_world_start(
            &world,
            &Pose::new(s.x, s.y, s.theta + 0.05)
        ));
    }
}
