//! Motion: the path planner (1515), the trajectory controller (1511), the wall follower
//! (1514, versions 1 and 2), the sensor-based controller (1513).
//!
//! Controllers command the virtual cart directly (it is hardware, not an operation) and stop
//! it when suspended.

mod follow;
mod planner;
mod sensor_based;
mod trajectory;
mod wall_follower;

pub use planner::{PathPlanner, PathPlannerFlag, PathPlannerParams, PlanTarget};
pub use sensor_based::{
    SensorBasedController, SensorBasedControllerFlag, SensorBasedControllerParams, SensorBasedMode,
};
pub use trajectory::{TrajectoryController, TrajectoryControllerFlag, TrajectoryControllerParams};
#[cfg(feature = "next-protocol")]
pub use wall_follower::next::{WallFollowerV1_2, NEXT_VERSION as WALL_FOLLOWER_NEXT};
pub use wall_follower::{
    WallFollowerMode, WallFollowerV1, WallFollowerV1Params, WallFollowerV1_1,
    WallFollowerV1_1Params, WallFollowerV2, WallFollowerV2Params,
};

use super::{cart, cart_err};
use crate::algo::parking::Footprint;
use crate::hardware::CartClient;
use marie_actors::eo::{OpContext, OpError};
use std::time::Duration;

/// Control period of every controller.
pub(super) const CONTROL_PERIOD: Duration = Duration::from_millis(50);

/// Stop the cart (speed and steering to zero): what a controller does when it is suspended.
pub(super) fn stop_cart(slot: &mut Option<CartClient>, ctx: &OpContext) -> Result<(), OpError> {
    cart(slot, ctx)?.drive(0.0, 0.0).map_err(cart_err)
}

/// The cart's own outline about its reference point, from its status (its size and where its
/// rear axle sits: the cart's geometry, not where it is).
pub(super) fn footprint_of(status: &crate::hardware::CartStatus) -> Footprint {
    let c = &status.footprint;
    let length = (c[1] - c[0]).norm();
    let width = (c[2] - c[1]).norm();
    let rear = length / 2.0 - status.axle_to_centre;
    Footprint {
        rear,
        front: length - rear,
        half_width: width / 2.0,
    }
}
