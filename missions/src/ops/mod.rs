//! The robot's elementary operations (thesis ids), each an [`Operation`] wrapping an algorithm
//! of [`crate::algo`]. They exchange data only through the datamanagers (see [`records`]) and
//! reach the virtual hardware through the registry.
//!
//! Each declares itself with marie's typed declarations, as a user's operation would: its
//! parameters with `params!` (`…Params`, choice parameters as `choice!` enums), its flags
//! with `flags!` (`…Flag`), the datamanagers by constant and its records as [`records`]'
//! kinds. The declarations are public, so a mission built in code names a parameter by its
//! key (`WallSensorParams::continuous()`) rather than by a string.
//!
//! [`Operation`]: marie_actors::eo::Operation

mod avoidance;
mod localization;
mod motion;
mod perception;
pub mod records;
mod ultrasonic;

pub use avoidance::{
    AvoidanceMode, CollisionAvoidance, CollisionAvoidanceFlag, CollisionAvoidanceParams,
};
pub use localization::{Localizer, LocalizerParams};
pub use motion::{
    PathPlanner, PathPlannerFlag, PathPlannerParams, PlanTarget, SensorBasedController,
    SensorBasedControllerFlag, SensorBasedControllerParams, SensorBasedMode, TrajectoryController,
    TrajectoryControllerFlag, TrajectoryControllerParams, WallFollowerMode, WallFollowerV1,
    WallFollowerV1Params, WallFollowerV1_1, WallFollowerV1_1Params, WallFollowerV2,
    WallFollowerV2Params,
};
/// The next build's wall follower (feature `next-protocol`, issue 44's two-build tests).
#[cfg(feature = "next-protocol")]
pub use motion::{WallFollowerV1_2, WALL_FOLLOWER_NEXT};
pub use perception::{
    Beams, DockingDetector, DockingDetectorFlag, DockingDetectorParams, SegmentExtractor,
    SegmentExtractorParams, WallSensor, WallSensorFlag, WallSensorParams, WallSide,
};
pub use ultrasonic::{Ultrasonic, UltrasonicParams};

use crate::hardware::{CartClient, CART_NAME};
use marie_actors::eo::{OpContext, OpError};
use marie_dm::RecordKind;
use marie_dm::{DmError, DmSpec, WORLD};
use marie_vocabulary::registry::ModuleKind;

/// The cart client, found in the registry on first use and again after the cart restarted,
/// carrying the running activation's fence: the cart obeys only the newest incarnation of
/// an operation ([`marie_vocabulary::fence`]).
pub(crate) fn cart<'s>(
    slot: &'s mut Option<CartClient>,
    ctx: &OpContext,
) -> Result<&'s CartClient, OpError> {
    if !slot.as_ref().is_some_and(CartClient::is_alive) {
        *slot = Some(CartClient::lookup().map_err(cart_err)?);
    }
    let client = slot
        .as_mut()
        .ok_or_else(|| cart_err(crate::hardware::CartError::NotFound))?;
    // the slot is one operation's: only the epoch changes, once per activation
    if client.fence().epoch != ctx.epoch() {
        client.set_fence(ctx.fence());
    }
    Ok(client)
}

/// Turn a cart error into an operation error: the cart could not be reached, so the host
/// holds the operation while the cart is gone from the registry (its node lost, or cut off
/// from this one) and steps on once it is back. A cart absent at the call (none published,
/// or the instance called lost mid-call) is waited for even if it is back by the time the
/// host looks; a cart that runs and does not answer fails the activation.
pub(crate) fn cart_err(e: crate::hardware::CartError) -> OpError {
    use crate::hardware::CartError;
    match e {
        CartError::NotFound | CartError::Gone => {
            OpError::absent(ModuleKind::Hardware, CART_NAME, e.to_string())
        }
        CartError::Unreachable => {
            OpError::unreachable(ModuleKind::Hardware, CART_NAME, e.to_string())
        }
    }
}

/// The newest record of `kind` in datamanager `dm`, decoded; `None` when there is none.
pub(crate) async fn newest<T: marie_dm::PayloadType>(
    ctx: &mut OpContext,
    dm: DmSpec,
    kind: RecordKind<T>,
) -> Result<Option<T>, OpError> {
    Ok(newest_with_seq(ctx, dm, kind).await?.map(|(_, v)| v))
}

/// Like [`newest`], with the record's sequence number.
pub(crate) async fn newest_with_seq<T: marie_dm::PayloadType>(
    ctx: &mut OpContext,
    dm: DmSpec,
    kind: RecordKind<T>,
) -> Result<Option<(u64, T)>, OpError> {
    let newest = ctx.dm(dm)?.newest_kind(kind).await.map_err(dm_err(dm))?;
    Ok(newest.map(|(header, value)| (header.seq, value)))
}

/// Turn a datamanager error into an operation error naming the DM.
pub(crate) fn dm_err(dm: DmSpec) -> impl Fn(DmError) -> OpError {
    move |e| OpError::of_dm(dm.name, &e)
}

/// The localizer's newest odometry correction ([`records::LOCATION`]); the identity when
/// there is none yet (the odometry starts at the world's start pose).
pub(crate) async fn correction(ctx: &mut OpContext) -> Result<crate::geom::Pose, OpError> {
    Ok(newest(ctx, WORLD, records::LOCATION)
        .await?
        .map(|r| r.correction)
        .unwrap_or_default())
}

/// The cart's pose in the map frame: its `odometry` under the localizer's newest correction.
/// Every operation that places things in the world or drives to a place uses this, never the
/// raw odometry, which drifts.
pub(crate) async fn located(
    ctx: &mut OpContext,
    odometry: &crate::geom::Pose,
) -> Result<crate::geom::Pose, OpError> {
    Ok(crate::algo::localize::corrected(
        &correction(ctx).await?,
        odometry,
    ))
}

#[cfg(test)]
mod tests {
    use super::cart_err;
    use crate::hardware::CartError;

    #[test]
    fn a_cart_absent_at_the_call_is_waited_for_and_a_silent_one_is_not() {
        assert!(cart_err(CartError::Gone).is_absent());
        assert!(cart_err(CartError::NotFound).is_absent());
        let silent = cart_err(CartError::Unreachable);
        assert!(!silent.is_absent());
        assert_eq!(silent.to_string(), "the virtual cart did not answer");
    }
}
